"""The fleet's HTTP API and dashboard server: :func:`create_app` wraps one :class:`rvdiag.fleet.Fleet` in a FastAPI
application (served by ``rvdiag fleet serve``; its OpenAPI schema at ``/openapi.json``; no ``/docs`` page, whose
scripts would come from a CDN).

The joint's name stands in the path with its slashes (``/api/joints/plant/r1/j3/history``).  Every route under
``/api`` answers JSON; an error is ``{"error": "one line"}`` with its status code: 400 bad input, 401 no or an
unknown token, 403 a read-only token writing, 404 an unknown joint or route, 413 an upload over the limit, 422 a
request that misses a field or a record the joint's monitor refused (stored as rejected, with its reason).

==============================================  =====================================================================
``GET  /api/health``                            liveness: ``{"ok": true, "version", "joints"}``
``GET  /api/joints``                            every joint's status row (:meth:`Fleet.status`)
``GET  /api/joints/{joint}/status``             one joint's status row
``GET  /api/joints/{joint}/history``            its records, oldest first (``?limit=N``: the last N; ``?format=csv``)
``GET  /api/joints/{joint}/events``             its events (``?kind=raised|acknowledged|cleared|maintenance|...``)
``GET  /api/events``, ``GET /api/alarms``        every joint's events; the joints with an open alarm
``POST /api/joints/{joint}/records``            ingest one record (multipart, below): 201 new, 200 the same record
                                                again, 422 rejected with its reason
``POST /api/joints/{joint}/ack``                acknowledge its alarm: JSON ``{"note": "..."}``
``POST /api/joints/{joint}/maintenance``        record maintenance: JSON ``{"note": "..."}``
``POST /api/joints/{joint}/failure-index``      set its failure index: JSON ``{"failure_index": 8.0, "note": "..."}``
``GET  /``, ``/joints/{joint}``, ``/alarms``    the dashboard's pages (:mod:`rvdiag.fleet.web`)
==============================================  =====================================================================

A record is posted as ``multipart/form-data``: ``file`` (the record file; its name's suffix tells the format), and
optional form fields ``time`` (ISO 8601; else the file's own or ``time_regex`` on its name), ``output_speed``
(deg/s), ``load`` (N m), ``channel``, ``fs`` (Hz), ``angle_channel``, ``meta_regex``, ``time_regex`` (the reading
options of ``rvdiag fleet ingest``) and ``client_id``, or the header ``Idempotency-Key``: a key the client chooses
per record, so that a client that resends after losing the answer gets the record it sent, never a second one
(the file's checksum dedupes per joint too).  Bodies over ``max_upload`` bytes are refused with 413 from their
``Content-Length`` before any of the body is read, or as soon as a body without one passes the limit.

Tokens: a write (ingest, acknowledge, maintenance) needs ``Authorization: Bearer TOKEN`` of a read-write token
(``rvdiag fleet token create``); the token's name is recorded as who acknowledged.  Reads are open by default (the
server binds to 127.0.0.1 unless told otherwise); with ``read_needs_token=True`` (env ``RVDIAG_FLEET_READ_TOKEN=1``)
every read needs a token too, read-only ones included, sent as the same header or as the ``rvdiag_token`` cookie
that the dashboard's token field sets.  The cookie is never accepted for a write, so no other site can make a
browser write.  Joint names and file names from requests are checked against a strict pattern before anything
else sees them; nothing from a request is unpickled.
"""

from __future__ import annotations

import functools
import math
import os
import re
from pathlib import Path
from typing import Annotated, Any, Literal

from fastapi import FastAPI, File, Form, Header, Query, Request, UploadFile
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, Response
from fastapi.staticfiles import StaticFiles
from pydantic import BaseModel, Field
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException as StarletteHTTPException

from rvdiag import __version__
from rvdiag.errors import RvdiagError
from rvdiag.fleet import AuthError, FleetError, Reading, history_csv
from rvdiag.fleet import web
from rvdiag.fleet.store import parse_time, split_joint
from rvdiag.validation import finite_number

#: Default upload limit, bytes (a 10 s record of 8 float64 channels at 48 kHz is 31 MiB as NPY).
DEFAULT_MAX_UPLOAD = 64 * 1024 * 1024
#: Environment variables read when :func:`create_app` is not given the setting.
ENV_MAX_UPLOAD = "RVDIAG_FLEET_MAX_UPLOAD_MB"
ENV_READ_TOKEN = "RVDIAG_FLEET_READ_TOKEN"
#: The cookie the dashboard sets for reads when ``read_needs_token`` (never accepted for writes).
TOKEN_COOKIE = "rvdiag_token"

#: An uploaded file's name (only its last path component is kept): letters, digits, space and ``_ . + - = , @``,
#: not starting with a dot.
FILENAME_PATTERN = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_ .+=,@-]{0,199}")

#: Security headers of every answer: the pages load scripts and styles from this server only (Plotly from the
#: wheel, the dashboard's own), never another site; none may be framed.
SECURITY_HEADERS = {
    "Content-Security-Policy": "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
                               "img-src 'self' data:; connect-src 'self'; frame-ancestors 'none'; base-uri 'none'; "
                               "form-action 'self'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
}


class ApiError(Exception):
    """An error answered as ``{"error": message}`` with ``status``."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status
        self.message = message


class Note(BaseModel):
    """The body of an acknowledgement or a maintenance entry."""

    note: str = Field(min_length=1, max_length=2000, description="what was seen or done (kept in the event log)")


class FailureIndex(BaseModel):
    """The body of a change of the joint's failure index."""

    failure_index: float | None = Field(description="the health index the joint's remaining life is counted to; "
                                                    "null removes it", gt=0, allow_inf_nan=False)
    note: str = Field("", max_length=2000, description="why (kept in the event log)")


def check_joint_name(joint: str) -> str:
    """``joint`` if it is a joint's name exactly as the store spells it (site/robot/joint, each part letters,
    digits, ``_ . -`` not starting with a dot: :func:`rvdiag.fleet.store.split_joint`), else :class:`ApiError`
    400.  No ``..``, no leading ``/``, no backslash can pass."""
    try:
        parts = split_joint(joint)
    except FleetError as exc:
        raise ApiError(400, str(exc)) from None
    if "/".join(parts) != joint:
        raise ApiError(400, f"a joint is named site/robot/joint with no extra '/' or space; got {joint[:80]!r}")
    return joint


def _check_filename(name: str | None) -> str:
    base = (name or "").replace("\\", "/").rsplit("/", 1)[-1]
    if not FILENAME_PATTERN.fullmatch(base):
        raise ApiError(400, f"invalid file name {base[:80]!r}: letters, digits, space and '_.+=,@-' only, "
                            "with the format's suffix (.npy, .csv, .wav...)")
    return base


def _finite(name: str, value: float | None) -> float | None:
    """A form's number as given (None: not given), else a 400 naming it (:func:`rvdiag.validation.finite_number`)."""
    return None if value is None else finite_number(value, name, error=functools.partial(ApiError, 400))




def _clean(obj: Any) -> Any:
    """JSON-ready: datetimes as ISO strings, NaN and infinities as null (JSON has neither)."""
    obj = jsonable_encoder(obj)

    def walk(o):
        if isinstance(o, float) and not math.isfinite(o):
            return None
        if isinstance(o, dict):
            return {k: walk(v) for k, v in o.items()}
        if isinstance(o, list):
            return [walk(v) for v in o]
        return o

    return walk(obj)


def _json(obj: Any, status: int = 200) -> JSONResponse:
    return JSONResponse(_clean(obj), status_code=status)


def _one_line(text: str) -> str:
    return " ".join(str(text).split())[:500]


def _fleet_error_status(exc: Exception) -> int:
    """The HTTP status of an error the fleet raised: its own ``status`` if it states one (:class:`AuthError`), 404
    for an unknown joint, 400 otherwise."""
    status = getattr(exc, "status", None)
    if isinstance(status, int) and 400 <= status < 500:
        return status
    if isinstance(exc, LookupError) or str(exc).lower().startswith("unknown joint"):
        return 404
    return 400


def _env_max_upload() -> int:
    raw = os.environ.get(ENV_MAX_UPLOAD)
    if not raw:
        return DEFAULT_MAX_UPLOAD
    try:
        mib = float(raw)
    except ValueError:
        raise RvdiagError(f"{ENV_MAX_UPLOAD}={raw!r} is not a number of MiB") from None
    if not (mib > 0 and math.isfinite(mib)):
        raise RvdiagError(f"{ENV_MAX_UPLOAD} must be a positive number of MiB, not {raw!r}")
    return int(mib * 1024 * 1024)


def create_app(fleet, *, max_upload: int | None = None, read_needs_token: bool | None = None) -> FastAPI:
    """The FastAPI application serving ``fleet``'s API and dashboard.

    Parameters
    ----------
    fleet : rvdiag.fleet.Fleet
        An open fleet store; the app calls only its public methods, from worker threads.
    max_upload : int, optional
        Largest request body accepted, bytes; default env ``RVDIAG_FLEET_MAX_UPLOAD_MB`` (MiB), else
        :data:`DEFAULT_MAX_UPLOAD` (64 MiB).
    read_needs_token : bool, optional
        Whether reads (API and pages) need a token too; default env ``RVDIAG_FLEET_READ_TOKEN`` is ``1``, else
        False (writes always need a read-write token).
    """
    limit = _env_max_upload() if max_upload is None else int(max_upload)
    if limit <= 0:
        raise RvdiagError(f"max_upload must be a positive number of bytes, not {max_upload}")
    if read_needs_token is None:
        read_needs_token = os.environ.get(ENV_READ_TOKEN, "") in ("1", "true", "yes")

    app = FastAPI(title="rvdiag fleet", version=__version__, docs_url=None, redoc_url=None,  # their pages load a CDN
                  description="Joints' states, records, alarms and acknowledgements of an rvdiag fleet store. "
                              "Writes need `Authorization: Bearer TOKEN` (a read-write token); reads "
                              + ("need a token too." if read_needs_token else "are open."))
    app.state.fleet = fleet
    app.state.max_upload = limit
    app.state.read_needs_token = read_needs_token

    # ---- errors: one JSON line under /api, a small page elsewhere -------------------------------------------------
    def error_response(request: Request, status: int, message: str) -> Response:
        message = _one_line(message)
        if request.url.path.startswith("/api") or request.method != "GET":
            return JSONResponse({"error": message}, status_code=status, headers=SECURITY_HEADERS)
        html = web.error_page(status, message, read_needs_token=read_needs_token)
        return HTMLResponse(html, status_code=status, headers=SECURITY_HEADERS)

    @app.exception_handler(ApiError)
    async def _api_error(request: Request, exc: ApiError):
        return error_response(request, exc.status, exc.message)

    @app.exception_handler(RvdiagError)
    async def _rvdiag_error(request: Request, exc: RvdiagError):
        return error_response(request, _fleet_error_status(exc), str(exc))

    @app.exception_handler(StarletteHTTPException)
    async def _http_error(request: Request, exc: StarletteHTTPException):
        message = {404: "no such route", 405: "method not allowed", 413: f"upload over the limit of {limit} bytes"}
        text = message.get(exc.status_code, exc.detail) if exc.status_code in message else str(exc.detail)
        if exc.status_code == 404 and exc.detail not in (None, "Not Found"):
            text = str(exc.detail)
        return error_response(request, exc.status_code, text)

    @app.exception_handler(RequestValidationError)
    async def _validation_error(request: Request, exc: RequestValidationError):
        parts = []
        for err in exc.errors():
            where = ".".join(str(x) for x in err.get("loc", ()) if x not in ("body", "query", "path", "header"))
            parts.append(f"{where}: {err.get('msg', 'invalid')}" if where else str(err.get("msg", "invalid")))
        return error_response(request, 422, "; ".join(parts) or "invalid request")

    @app.middleware("http")
    async def _headers(request: Request, call_next):
        if request.method == "POST" and request.url.path.startswith("/api/"):
            # refuse an upload over the limit by its Content-Length, and a write without a valid read-write token,
            # before the body is read (a body without Content-Length is cut at the limit by the route's
            # max_body_size; the route checks the token again)
            length = request.headers.get("content-length")
            if length is not None and (not length.isdigit() or int(length) > limit):
                return error_response(request, 413 if length.isdigit() else 400,
                                      f"upload of {length} bytes over the limit of {limit} bytes"
                                      if length.isdigit() else "invalid Content-Length")
            try:
                await run_in_threadpool(writer, request.headers.get("authorization"))
            except ApiError as exc:
                return error_response(request, exc.status, exc.message)
        response = await call_next(request)
        for k, v in SECURITY_HEADERS.items():
            response.headers.setdefault(k, v)
        return response

    # ---- tokens --------------------------------------------------------------------------------------------------
    def bearer(authorization: str | None) -> str | None:
        if not authorization:
            return None
        scheme, _, token = authorization.partition(" ")
        if scheme.lower() != "bearer" or not token.strip():
            raise ApiError(401, "the Authorization header must be 'Bearer TOKEN'")
        return token.strip()

    def checked(token: str | None, write: bool, missing: str) -> str:
        """The token's name: 401 without one (``missing`` says why) or for an unknown one, 403 for a read-only one
        writing (:class:`AuthError`'s ``status``)."""
        if not token:
            raise ApiError(401, missing)
        try:
            return fleet.check_token(token, write=write)
        except AuthError as exc:
            raise ApiError(getattr(exc, "status", 401), str(exc)) from None

    def writer(authorization: str | None) -> str:
        """The name of the read-write token in ``authorization``."""
        return checked(bearer(authorization), True, "writing needs a token: send 'Authorization: Bearer TOKEN' "
                                                    "(rvdiag fleet token create)")

    def reader(request: Request) -> None:
        if read_needs_token:
            checked(bearer(request.headers.get("authorization")) or request.cookies.get(TOKEN_COOKIE), False,
                    "reading this fleet needs a token: send 'Authorization: Bearer TOKEN' or enter it in the "
                    "dashboard")

    def known(joint: str) -> str:
        check_joint_name(joint)
        if joint not in fleet.joints():
            raise ApiError(404, f"unknown joint {joint!r}")
        return joint

    # ---- API: reads ----------------------------------------------------------------------------------------------
    @app.get("/api/health", tags=["service"])
    def health(request: Request):
        """Liveness: the store answers (no token needed)."""
        return _json({"ok": True, "version": __version__, "joints": len(fleet.joints())})

    @app.get("/api/joints", tags=["read"])
    def joints(request: Request):
        """Every joint's status row: joint, state, last_index, last_record_time, state_since, threshold,
        n_records, last_fault_state, last_probability, open_alarm."""
        reader(request)
        return _json(fleet.status())

    @app.get("/api/joints/{joint:path}/status", tags=["read"])
    def joint_status(request: Request, joint: str):
        """One joint's status row."""
        reader(request)
        return _json(fleet.status(known(joint))[0])

    @app.get("/api/joints/{joint:path}/history", tags=["read"])
    def history(request: Request, joint: str, limit: Annotated[int | None, Query(ge=1, le=100000)] = None,
                format: Annotated[Literal["json", "csv"], Query(description="json, or csv: one row a record "
                                                                           "(rvdiag.fleet.export)")] = "json"):
        """The joint's records, oldest first; ``limit`` keeps the last N; ``format=csv`` as CSV."""
        reader(request)
        rows = fleet.history(known(joint), limit=limit)
        if format == "csv":
            name = re.sub(r"[^A-Za-z0-9_.-]", "_", joint)
            return Response(history_csv(rows), media_type="text/csv; charset=utf-8",
                            headers={"Content-Disposition": f'attachment; filename="{name}-history.csv"'})
        return _json(rows)

    @app.get("/api/joints/{joint:path}/events", tags=["read"])
    def joint_events(request: Request, joint: str, kind: str | None = None):
        """The joint's events (raised, acknowledged, cleared, maintenance, commissioned), oldest first."""
        reader(request)
        return _json(fleet.events(known(joint), kind=kind))

    @app.get("/api/events", tags=["read"])
    def all_events(request: Request, kind: str | None = None):
        """Every joint's events, oldest first."""
        reader(request)
        return _json(fleet.events(None, kind=kind))

    @app.get("/api/alarms", tags=["read"])
    def alarms(request: Request):
        """The status rows of the joints whose alarm is open (raised and not yet acknowledged)."""
        reader(request)
        return _json([row for row in fleet.status() if row.get("open_alarm")])

    # ---- API: writes ---------------------------------------------------------------------------------------------
    @app.post("/api/joints/{joint:path}/records", tags=["write"], status_code=201, max_body_size=limit,
              responses={200: {"description": "the same record again (by checksum or client id)"},
                         422: {"description": "the record was refused by the joint's monitor; stored as rejected "
                                              "with its reason"}})
    def ingest(
        joint: str,
        file: Annotated[UploadFile, File(description="the record file")],
        time: Annotated[str | None, Form(description="ISO 8601 time of the record")] = None,
        output_speed: Annotated[float | None, Form(description="output speed, deg/s")] = None,
        load: Annotated[float | None, Form(description="output load, N m")] = None,
        channel: Annotated[str | None, Form(max_length=200)] = None,
        fs: Annotated[float | None, Form(gt=0, description="sampling rate, Hz")] = None,
        angle_channel: Annotated[str | None, Form(max_length=200)] = None,
        meta_regex: Annotated[str | None, Form(max_length=500)] = None,
        time_regex: Annotated[str | None, Form(max_length=500)] = None,
        client_id: Annotated[str | None, Form(max_length=200)] = None,
        authorization: Annotated[str | None, Header()] = None,
        idempotency_key: Annotated[str | None, Header(max_length=200)] = None,
    ):
        """Ingest one record of the joint and judge it; the answer is the ingest result (record_id, duplicate,
        rejected, result, joint_state, time)."""
        writer(authorization)
        check_joint_name(joint)
        if client_id and idempotency_key and client_id != idempotency_key:
            raise ApiError(400, "client_id and the Idempotency-Key header differ; send one")
        filename = _check_filename(file.filename)
        reading = Reading(channel=channel or None, fs=_finite("fs", fs), angle_channel=angle_channel or None,
                          output_speed=_finite("output_speed", output_speed), load=_finite("load", load),
                          meta_regex=meta_regex or None, time_regex=time_regex or None)
        when = parse_time(time, where="time") if time else None
        data = file.file.read()
        out = fleet.ingest(joint, data, filename=filename, reading=reading, time=when,
                           client_id=client_id or idempotency_key or None)
        if out.get("rejected"):
            return _json({"error": _one_line(f"record rejected: {out['rejected']}"), **out}, status=422)
        return _json(out, status=200 if out.get("duplicate") else 201)

    @app.post("/api/joints/{joint:path}/ack", tags=["write"])
    def acknowledge(joint: str, body: Note, authorization: Annotated[str | None, Header()] = None):
        """Acknowledge the joint's open alarm (the token's name is recorded as who)."""
        who = writer(authorization)
        check_joint_name(joint)
        return _json(fleet.acknowledge(joint, by=who, note=body.note))

    @app.post("/api/joints/{joint:path}/maintenance", tags=["write"])
    def maintenance(joint: str, body: Note, authorization: Annotated[str | None, Header()] = None):
        """Record maintenance on the joint (it is then re-commissioned before it is judged again)."""
        who = writer(authorization)
        check_joint_name(joint)
        return _json(fleet.maintenance(joint, by=who, note=body.note))

    @app.post("/api/joints/{joint:path}/failure-index", tags=["write"])
    def failure_index(joint: str, body: FailureIndex, authorization: Annotated[str | None, Header()] = None):
        """Set or remove the joint's failure index (the health index its remaining life is counted to)."""
        who = writer(authorization)
        check_joint_name(joint)
        return _json(fleet.set_failure_index(joint, body.failure_index, by=who, note=body.note))

    # ---- dashboard -----------------------------------------------------------------------------------------------
    links = web.Links(base="/", suffix="", api="/api", read_needs_token=read_needs_token)

    def page(html: str) -> HTMLResponse:
        return HTMLResponse(html, headers={"Cache-Control": "no-store"})

    @app.get("/", response_class=HTMLResponse, include_in_schema=False)
    def fleet_page(request: Request):
        reader(request)
        return page(web.fleet_page(fleet, links))

    @app.get("/alarms", response_class=HTMLResponse, include_in_schema=False)
    def alarms_page(request: Request):
        reader(request)
        return page(web.alarms_page(fleet, links))

    @app.get("/joints/{joint:path}", response_class=HTMLResponse, include_in_schema=False)
    def joint_page(request: Request, joint: str):
        reader(request)
        known(joint)
        return page(web.joint_page(fleet, joint, links))

    @app.get("/static/plotly.min.js", include_in_schema=False)
    def plotly_js():
        return FileResponse(web.plotly_js_path(), media_type="text/javascript",
                            headers={"Cache-Control": "public, max-age=86400"})

    app.mount("/static", StaticFiles(directory=Path(web.STATIC)), name="static")
    return app


__all__ = ["DEFAULT_MAX_UPLOAD", "ApiError", "check_joint_name", "create_app"]
