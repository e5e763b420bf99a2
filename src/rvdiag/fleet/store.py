"""The fleet: joints watched over their life, each against its own baseline (docs/fleet.md).

:class:`Fleet` is the one code path behind ``rvdiag fleet ...``, the folder watcher (:mod:`rvdiag.fleet.watch`) and
the HTTP API (:mod:`rvdiag.fleet.api`).  What it keeps is in :mod:`rvdiag.fleet.db`; a joint's state is derived
from its records by :func:`rvdiag.fleet.rules.replay`, replaying the current epoch's records in time order, so that
records may arrive out of order and the history is appended, never rewritten.

Ingesting a record:

1. the joint must exist and have a baseline at the record's time (else :class:`FleetError`, nothing stored);
2. the bytes' SHA-256 names the record: the same file twice for one joint is one record (``duplicate``);
3. the raw bytes are kept content-addressed (:mod:`rvdiag.fleet.blobs`);
4. the record is read and judged by the joint's monitor against the epoch's baseline (:mod:`rvdiag.fleet.judge`);
   a file that cannot be read or judged is stored as ``rejected`` with its reason and reaches nothing else.  An
   epoch commissioned with a twin (``rvdiag fleet commission ... --twin DIR``: its crack references, copied beside
   the baseline) also runs its crack detector (:mod:`rvdiag.monitoring.crack`), kept under ``crack`` in the
   record's result (its error instead where the record cannot be judged by it).  Its index is ranked among the
   crack indices of the joint's own learning records as the health index is (:func:`rvdiag.fleet.rules.
   rank_after_learning`, computed when read, so out-of-order records are ranked as the replay orders them):
   ``joint_p_value``, ``joint_alarm`` (``joint_p_value <= alpha``) and ``learning`` are added to ``crack`` in the
   answers (ingest, ``history``, ``status``), never stored; it does not enter the alarm rules;
5. the joint's state is replayed; alarms raised or cleared become events.
"""

from __future__ import annotations

import math
import os
import re
import secrets
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path

from sqlalchemy import event as sa_event
from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import sessionmaker

from rvdiag.errors import FleetError, RvdiagError
from rvdiag.fleet import auth, db, rules as R
from rvdiag.fleet.blobs import BlobStore, checksum
from rvdiag.fleet.judge import Judge, Reading

#: a part of a joint's name: letters, digits, ``_ . -``, not starting with a dot (never ``..``)
_PART = re.compile(r"^[A-Za-z0-9_-][A-Za-z0-9_.-]{0,99}$")
#: how many of a joint's last records ``status()`` gives as its ``trend`` (the dashboard's trend line)
TREND_RECORDS = 40
#: the suffix of an epoch's twin folder beside its baseline store (``epoch-N-XXXX.zarr`` -> ``epoch-N-XXXX.twin``)
TWIN_SUFFIX = ".twin"
#: the result keys kept in a record's ``result`` (the windows are left out: they are recomputed from the raw record)
_DROP = ("windows",)


def now() -> datetime:
    return datetime.now(timezone.utc)


def parse_time(text: str, where: str = "--time") -> datetime:
    """An ISO 8601 time (``2026-11-28T08:00:00Z``, ``20261128T080000``); without a zone it is UTC."""
    try:
        t = datetime.fromisoformat(str(text).strip().replace("Z", "+00:00").replace("z", "+00:00"))
    except ValueError:
        raise FleetError(f"{where} {text!r} is not an ISO 8601 time (e.g. 2026-11-28T08:00:00Z)") from None
    return t.replace(tzinfo=timezone.utc) if t.tzinfo is None else t.astimezone(timezone.utc)


def time_from_name(filename: str, regex: str) -> datetime:
    """The time in a file name by ``--time-regex``: its group ``time``, else the whole match."""
    try:
        m = re.search(regex, Path(filename).name)
    except re.error as exc:
        raise FleetError(f"--time-regex {regex!r} is not a regular expression: {exc}") from None
    if m is None:
        raise FleetError(f"{Path(filename).name}: the name does not match --time-regex {regex!r}")
    text = m.groupdict().get("time") or m.group(0)
    return parse_time(text, where=f"{Path(filename).name}: --time-regex gives")


def split_joint(name: str) -> tuple[str, str, str]:
    """``site/robot/joint`` -> its three parts, each checked (:data:`_PART`)."""
    parts = str(name).strip().strip("/").split("/")
    if len(parts) != 3 or not all(_PART.match(p) for p in parts):
        raise FleetError(f"a joint is named site/robot/joint (letters, digits, _ . -), e.g. plant/r1/j3; got {name!r}")
    return parts[0], parts[1], parts[2]


def _iso(t: datetime | None) -> str | None:
    return None if t is None else t.astimezone(timezone.utc).isoformat()


class Fleet:
    """A fleet store (module docstring).  Open one with :meth:`open` (an existing store) or :meth:`init` (create or
    migrate)."""

    def __init__(self, url: str, engine, blobs: BlobStore, judge=None):
        self.url = url
        self.engine = engine
        self.blobs = blobs
        self.judge = judge if judge is not None else Judge()
        self._sessions = sessionmaker(engine, expire_on_commit=False)
        self._writes = sessionmaker(engine.execution_options(fleet_write=True), expire_on_commit=False)

    # ------------------------------------------------------------------------------------------- opening
    @classmethod
    def _engine(cls, url: str | None):
        url = db.resolve_url(url)
        engine = db.make_engine(url)
        if engine.dialect.name == "sqlite":
            _immediate_writes(engine)
        return url, engine

    @classmethod
    def open(cls, url: str | None = None, *, judge=None) -> "Fleet":
        """Open an existing fleet store (``url``, else ``$RVDIAG_FLEET_DB``, else ``sqlite:///fleet.db``); refuses
        one of a newer or older schema, or none (:class:`FleetError`)."""
        url, engine = cls._engine(url)
        path = db.sqlite_path(url)
        if path is not None and not path.exists():
            raise FleetError(f"no fleet store at {path}: create it with 'rvdiag fleet init --db {url}'")
        db.check_schema(engine)
        return cls(url, engine, BlobStore.for_url(url), judge)

    @classmethod
    def init(cls, url: str | None = None, *, judge=None) -> "Fleet":
        """Create the fleet store at ``url`` or migrate it to this rvdiag's schema (a newer one is refused)."""
        url, engine = cls._engine(url)
        blobs = BlobStore.for_url(url)
        db.migrate(engine)
        blobs.root.mkdir(parents=True, exist_ok=True)
        return cls(url, engine, blobs, judge)

    def close(self) -> None:
        self.engine.dispose()

    # ------------------------------------------------------------------------------------------- joints
    def _joint(self, s, name: str, lock: bool = False) -> db.Joint:
        split_joint(name)
        q = select(db.Joint).where(db.Joint.path == str(name).strip().strip("/"))
        if lock and self.engine.dialect.name != "sqlite":
            q = q.with_for_update()
        j = s.scalar(q)
        if j is None:
            raise FleetError(f"unknown joint {name!r}: add it with 'rvdiag fleet add {name} --monitor MODEL_DIR'")
        return j

    def add_joint(self, joint: str, monitor: Path, params: Path | dict | None = None,
                  rules: dict | R.Rules | None = None) -> dict:
        """Add a joint ``site/robot/joint`` watched by the monitor model ``monitor``; ``params`` its reducer's
        parameter set (a TOML file or its dict; default the built-in), ``rules`` its alarm rules
        (:class:`rvdiag.fleet.rules.Rules`; defaults otherwise)."""
        site, robot, name = split_joint(joint)
        monitor = Path(monitor).resolve()
        info = self.judge.describe(monitor)
        rl = rules if isinstance(rules, R.Rules) else R.Rules.from_dict(rules)
        rl.check(info["alpha"])
        if isinstance(params, (str, Path)):
            from rvdiag.params import ReducerParams

            params = ReducerParams.load(Path(params)).to_dict()
        with self._writes() as s, s.begin():
            st = s.scalar(select(db.Site).where(db.Site.name == site))
            if st is None:
                st = db.Site(name=site)
                s.add(st)
                s.flush()
            rb = s.scalar(select(db.Robot).where(db.Robot.site_id == st.id, db.Robot.name == robot))
            if rb is None:
                rb = db.Robot(site_id=st.id, name=robot)
                s.add(rb)
                s.flush()
            if s.scalar(select(db.Joint).where(db.Joint.path == f"{site}/{robot}/{name}")) is not None:
                raise FleetError(f"the joint {joint!r} exists already")
            j = db.Joint(robot_id=rb.id, name=name, path=f"{site}/{robot}/{name}", monitor=str(monitor),
                         signal_kind=info["signal"], params=params, rules=rl.to_dict(), created=now())
            s.add(j)
        return self._joint_dict(j, info["alpha"])

    def _joint_dict(self, j: db.Joint, alpha: float | None) -> dict:
        rl = R.Rules.from_dict(j.rules)
        return {"joint": j.path, "monitor": j.monitor, "signal": j.signal_kind,
                "params": (j.params or {}).get("name") if j.params else None, "rules": rl.to_dict(),
                "alpha": alpha}

    def joints(self) -> list[str]:
        with self._sessions() as s:
            return list(s.scalars(select(db.Joint.path).order_by(db.Joint.path)))

    # ------------------------------------------------------------------------------------------- epochs
    def commission(self, joint: str, files: list[Path], reading: Reading, time: datetime | None = None,
                   operating_points: list[dict] | None = None, twin: Path | None = None) -> dict:
        """Make the joint's baseline from its commissioning records ``files`` (healthy, at the joint's operating
        points): a new epoch starting at ``time`` (default now); earlier epochs are kept.  Every file must read; a
        bad one refuses the whole commissioning (nothing is stored).  Each file's operating point is ``reading``'s
        (``output_speed``, ``load`` or ``meta_regex`` on its name), or the matching one of ``operating_points``
        (``{"output_speed_deg_s", "load_Nm"}`` per file).  ``twin``: the joint's twin folder (``rvdiag update
        --specimen ... --out DIR``); its crack references are checked and copied beside the epoch's baseline, and
        every record of the epoch is also judged by its crack detector."""
        files = [Path(f) for f in files]
        if not files:
            raise FleetError("commissioning needs at least one record file")
        if operating_points is not None and len(operating_points) != len(files):
            raise FleetError(f"{len(operating_points)} operating points for {len(files)} commissioning files")
        reading = reading or Reading()
        t = now() if time is None else _aware(time)
        if twin is not None:
            try:
                self.judge.twin(Path(twin))
            except RvdiagError as exc:
                raise FleetError(f"--twin {twin}: {exc}") from None
        with self._sessions() as s:
            j = self._joint(s, joint)
            jid, monitor = j.id, Path(j.monitor)
            eps = self._epochs(s, jid)
            number = eps[-1].number + 1 if eps else 1
            if eps and t <= eps[-1].started:
                raise FleetError(f"{joint}'s epoch {eps[-1].number} started at {_iso(eps[-1].started)}: a new "
                                 f"baseline must start later (--time), not at {_iso(t)}")
        signals, ops, kept = [], [], []
        for i, f in enumerate(files):
            data = _read_bytes(f)
            try:
                sig = self.judge.read(f, reading, monitor)
                op = reading.operating_point(f.name) if operating_points is None else \
                    {"output_speed_deg_s": operating_points[i].get("output_speed_deg_s"),
                     "load_Nm": operating_points[i].get("load_Nm")}
            except RvdiagError as exc:
                raise FleetError(f"{f}: {exc}") from None
            if op["load_Nm"] is None:
                raise FleetError(f"{f}: the commissioning record's load is needed: give --load N_M or --meta-regex "
                                 "with a group load_Nm")
            digest, _ = self.blobs.put(data, f.name)
            signals.append(sig)
            ops.append(op)
            kept.append((digest, f.name, op))
        out = self.blobs.baseline_dir(jid, number).with_name(f"epoch-{number}-{secrets.token_hex(4)}.zarr")
        out.parent.mkdir(parents=True, exist_ok=True)
        try:
            info = self.judge.make_baseline(monitor, signals, ops, out)
        except RvdiagError as exc:
            raise FleetError(f"cannot commission {joint}: {exc}") from None
        if twin is not None:
            _copy_twin(Path(twin), out.with_suffix(TWIN_SUFFIX))
        alpha = self.judge.describe(monitor)["alpha"]
        with self._writes() as s, s.begin():
            j = self._joint(s, joint, lock=True)
            ep = db.Epoch(joint_id=j.id, number=number, started=t, baseline=str(out.relative_to(self.blobs.root)),
                          n_records=int(info.get("n_records", len(files))), operating_points=ops, alpha=alpha)
            s.add(ep)
            try:
                s.flush()
            except IntegrityError:
                raise FleetError(f"{joint} was commissioned by another process at the same time; try again") from None
            for digest, name, op in kept:
                s.add(db.CommissioningRecord(epoch_id=ep.id, checksum=digest, filename=name, operating_point=op))
            s.add(db.Event(joint_id=j.id, kind="commissioned", time=t, epoch_id=ep.id,
                           note=f"epoch {number}: baseline of {len(files)} records"))
        return {"joint": joint, "epoch": number, "started": _iso(t), "n_records": len(files),
                "operating_points": ops, "baseline": str(out),
                "twin": None if twin is None else str(out.with_suffix(TWIN_SUFFIX))}

    def _epochs(self, s, jid: int) -> list[db.Epoch]:
        return list(s.scalars(select(db.Epoch).where(db.Epoch.joint_id == jid).order_by(db.Epoch.number)))

    def _maintenances(self, s, ep: db.Epoch) -> list[datetime]:
        """The times of the maintenance events that ended the epoch ``ep`` (recorded while it was current)."""
        return list(s.scalars(select(db.Event.time).where(db.Event.epoch_id == ep.id, db.Event.kind == "maintenance")
                              .order_by(db.Event.time)))

    def _epoch_at(self, s, jid: int, t: datetime) -> db.Epoch | None:
        """The epoch whose baseline judges a record of time ``t``: the last commissioned at or before ``t``, unless
        the maintenance that ended it lies before ``t`` (then none: the joint awaited its new baseline)."""
        eps = [e for e in self._epochs(s, jid) if e.started <= t]
        if not eps:
            return None
        ep = eps[-1]
        if any(m <= t for m in self._maintenances(s, ep)):
            return None
        return ep

    # ------------------------------------------------------------------------------------------- ingest
    def ingest(self, joint: str, data: bytes | Path, *, filename: str | None = None, reading: Reading | None = None,
               time: datetime | None = None, client_id: str | None = None) -> dict:
        """Store and judge one record of ``joint`` (module docstring); returns ``{"record_id", "duplicate",
        "rejected", "result", "joint_state", "time"}``.  ``data`` is the file's bytes or its path; ``time`` the
        record's time, else by ``reading.time_regex`` on ``filename``, else the file's modification time (bytes
        without either: now)."""
        reading = reading or Reading()
        if isinstance(data, (str, Path)):
            path = Path(data)
            filename = filename or path.name
            raw = _read_bytes(path)
            mtime = datetime.fromtimestamp(path.stat().st_mtime, timezone.utc)
        else:
            raw, mtime, path = bytes(data), None, None
        filename = Path(str(filename or "record").replace("\\", "/")).name or "record"
        digest = checksum(raw)
        with self._sessions() as s:
            j = self._joint(s, joint)
            jid, monitor = j.id, Path(j.monitor)
            if time is not None:
                t = _aware(time)
            elif reading.time_regex:
                t = time_from_name(filename, reading.time_regex)
            else:
                t = mtime or now()
            dup = s.scalar(select(db.Record).where(db.Record.joint_id == jid, db.Record.checksum == digest))
            if dup is not None:
                return self._ingest_answer(s, j, dup, duplicate=True)
            ep = self._epoch_at(s, jid, t)
            if ep is None:
                raise FleetError(f"the joint {joint} has no baseline at {_iso(t)}: commission it first ('rvdiag "
                                 f"fleet commission {joint} FILE...')")
            ep_id, base = ep.id, self.blobs.root / ep.baseline
        _, kept = self.blobs.put(raw, filename)
        rejected, result, op = None, None, None
        try:
            op = reading.operating_point(filename)
            sig = self.judge.read(kept, reading, monitor)
            result = self.judge.judge(monitor, base, sig, reading, op)
        except RvdiagError as exc:
            # the reader read the kept copy: name the file as the user knows it
            text = str(exc).replace(str(kept), filename).replace(kept.name, filename)
            rejected = " ".join(text.split()) or type(exc).__name__
        twin = base.with_suffix(TWIN_SUFFIX)
        if result is not None and twin.is_dir():
            try:
                result["crack"] = self.judge.crack(twin, sig, result.get("operating_point") or op)
            except RvdiagError as exc:
                result["crack"] = {"error": " ".join(str(exc).replace(str(kept), filename).split())}
        rec = db.Record(joint_id=jid, epoch_id=ep_id, time=t, received=now(), checksum=digest, filename=filename,
                        client_id=client_id, reading=reading.to_dict(), rejected=rejected)
        if result is not None:
            rec.operating_point = result.get("operating_point") or op
            rec.health_index = _num(result.get("health_index"))
            rec.p_value = _num(result.get("p_value"))
            rec.record_alarm = result.get("alarm")
            rec.fault_state = result.get("state")
            rec.probability = _num(result.get("probability"))
            rec.changes = list(result.get("changes") or [])
            rec.recognised = bool(result.get("recognised", True))
            rec.reason = result.get("reason")
            rec.result = {k: v for k, v in result.items() if k not in _DROP}
            if "file" in rec.result:
                rec.result["file"] = filename  # the reader read the kept copy
        else:
            rec.operating_point = op
        try:
            with self._writes() as s, s.begin():
                j = self._joint(s, joint, lock=True)
                s.add(rec)
                s.flush()
                d = self._derive_events(s, j)
        except IntegrityError:  # the same file, ingested at the same time by another process
            with self._sessions() as s:
                j = self._joint(s, joint)
                dup = s.scalar(select(db.Record).where(db.Record.joint_id == jid, db.Record.checksum == digest))
                return self._ingest_answer(s, j, dup, duplicate=True)
        return self._ingest_answer(None, None, rec, duplicate=False, derived=d)

    def _ingest_answer(self, s, j: db.Joint | None, rec: db.Record, duplicate: bool, derived: dict | None = None
                       ) -> dict:
        d = self._derive(s, j) if derived is None else derived
        result = rec.result
        if result is not None and (d["crack"] or {}).get(rec.id) is not None:
            result = {**result, "crack": d["crack"][rec.id]}
        return {"record_id": rec.id, "duplicate": duplicate, "rejected": rec.rejected, "result": result,
                "joint_state": d["state"], "time": _iso(rec.time), "checksum": rec.checksum}

    # ------------------------------------------------------------------------------------------- the state
    def _derive(self, s, j: db.Joint) -> dict:
        """The joint's current epoch replayed (:func:`rvdiag.fleet.rules.replay`): ``{"state", "epoch", "rules",
        "steps", "records" (id -> row), "since", "threshold", "crack"}``; ``crack``: :meth:`_crack_ranks` (None
        without a twin)."""
        eps = self._epochs(s, j.id)
        out = {"state": "no-baseline", "epoch": None, "rules": None, "steps": [], "records": {}, "since": j.created,
               "threshold": None, "calibration": [], "crack": None}
        if not eps:
            return out
        ep = eps[-1]
        maint = self._maintenances(s, ep)
        rl, recs, steps = self._replay_epoch(s, j, ep)
        out.update(epoch=ep, rules=rl, steps=steps, records={r.id: r for r in recs}, since=ep.started,
                   crack=self._crack_ranks(s, ep, rl, steps))
        if maint:
            out.update(state="no-baseline", since=maint[0])
            return out
        state = "learning"
        for st in steps:
            if st.state != state:
                state, out["since"] = st.state, st.time
        out["state"] = state
        calib = sorted(r.health_index for st in steps if st.learning
                       for r in [out["records"][st.key]] if r.health_index is not None
                       and math.isfinite(r.health_index))
        out["calibration"] = calib
        jrank = int(math.floor(rl.alpha * (rl.learning + 1) + 1e-9))
        if len(calib) >= rl.learning and jrank >= 1:
            out["threshold"] = calib[-jrank]  # a record alarms when its index exceeds this (conformal rank)
        return out

    def _derive_events(self, s, j: db.Joint) -> dict:
        """Append the ``raised`` / ``cleared`` events the replay shows beyond those already stored for the epoch
        (an out-of-order record may move an alarm; stored events are never rewritten); returns :meth:`_derive`'s
        answer."""
        d = self._derive(s, j)
        ep = d["epoch"]
        if ep is None:
            return d
        for kind in ("raised", "cleared"):
            derived = [st for st in d["steps"] if kind in st.events]
            stored = s.scalar(select(func.count()).select_from(db.Event)
                              .where(db.Event.epoch_id == ep.id, db.Event.kind == kind))
            for st in derived[stored:]:
                rid = st.key if st.kind == "record" else None
                note = None if rid is not None else "cleared when acknowledged: the last records were normal"
                if kind == "raised":
                    r = d["records"][rid]
                    note = f"{d['rules'].k} of the last {d['rules'].n} records alarmed (health index " \
                           f"{r.health_index:.3g})" if r.health_index is not None else None
                s.add(db.Event(joint_id=j.id, kind=kind, time=st.time, record_id=rid, epoch_id=ep.id, note=note))
        return d

    def _crack_ranks(self, s, ep: db.Epoch, rl: R.Rules, steps) -> dict | None:
        """For an epoch commissioned with a twin: record id -> its stored ``crack`` result with ``joint_p_value``,
        ``joint_alarm`` and ``learning`` added (:func:`rvdiag.fleet.rules.rank_after_learning` on the crack index,
        among the same learning records as the health index; a crack error or a record not recognised is no
        calibration score).  None for an epoch without a twin."""
        if not (self.blobs.root / ep.baseline).with_suffix(TWIN_SUFFIX).is_dir():
            return None
        rows = s.execute(select(db.Record.id, db.Record.result)
                         .where(db.Record.epoch_id == ep.id, db.Record.rejected.is_(None))).all()
        cracks = {r.id: r.result["crack"] for r in rows if isinstance((r.result or {}).get("crack"), dict)}
        scores = {rid: _num(c.get("index")) if "error" not in c else None for rid, c in cracks.items()}
        ranks = R.rank_after_learning(steps, scores, rl.alpha)
        return {rid: {**c, **ranks.get(rid, {"joint_p_value": None, "joint_alarm": None, "learning": False})}
                for rid, c in cracks.items()}

    def status(self, joint: str | None = None) -> list[dict]:
        """One row per joint (``joint``: that joint's only): ``joint, state, last_index, last_record_time,
        state_since, threshold, n_records, last_fault_state, last_probability, open_alarm`` (and ``epoch``,
        ``signal``, ``learning_left``, ``trend``: the health indices of the current epoch's last
        :data:`TREND_RECORDS` recognised records, oldest first; ``failure_index``; and the prognosis of
        :func:`prognosis_of`: ``onset_time``, ``change_evidence``, ``rul``).  A joint whose epoch has a twin also has
        ``crack``: ``last_index`` and ``joint_alarm`` of its last recognised record with a crack index (None
        before one), and ``learning_left`` (as the joint's)."""
        rows = []
        with self._sessions() as s:
            q = select(db.Joint).order_by(db.Joint.path)
            if joint is not None:
                q = q.where(db.Joint.id == self._joint(s, joint).id)
            for j in s.scalars(q):
                d = self._derive(s, j)
                recs = sorted(d["records"].values(), key=lambda r: (r.time, r.id))
                last = recs[-1] if recs else None
                judged = [r for r in recs if r.recognised]
                lastj = judged[-1] if judged else None
                n_all = s.scalar(select(func.count()).select_from(db.Record).where(db.Record.joint_id == j.id))
                learn = None
                failure_index = R.Rules.from_dict(j.rules).failure_index
                if d["rules"] is not None:
                    learn = max(0, d["rules"].learning - sum(st.learning for st in d["steps"]))
                row = {
                    "joint": j.path, "state": d["state"], "last_index": None if lastj is None else lastj.health_index,
                    "last_record_time": _iso(last.time) if last else None, "state_since": _iso(d["since"]),
                    "threshold": d["threshold"], "n_records": int(n_all),
                    "last_fault_state": None if lastj is None else lastj.fault_state,
                    "last_probability": None if lastj is None else lastj.probability,
                    "open_alarm": bool(d["steps"][-1].open_alarm) if d["steps"] and d["state"] != "no-baseline"
                    else False,
                    "epoch": None if d["epoch"] is None else d["epoch"].number, "signal": j.signal_kind,
                    "learning_left": learn, "trend": [r.health_index for r in judged[-TREND_RECORDS:]],
                    "failure_index": failure_index, **prognosis_of(judged, lastj, failure_index)}
                if d["crack"] is not None:
                    cr = [d["crack"][r.id] for r in judged if _num(d["crack"].get(r.id, {}).get("index")) is not None]
                    row["crack"] = {"last_index": cr[-1]["index"] if cr else None,
                                    "joint_alarm": cr[-1]["joint_alarm"] if cr else None, "learning_left": learn}
                rows.append(row)
        return rows

    def history(self, joint: str, limit: int | None = None) -> list[dict]:
        """The joint's records in time order (the last ``limit``): ``time, checksum, health_index, p_value,
        record_alarm, joint_state, fault_state, probability, recognised, reason, changes, epoch, rejected`` and
        ``joint_p_value`` (the record's rank among the joint's own), ``learning``, ``filename``, ``record_id``,
        ``crack`` (an epoch with a twin: the crack detector's result with its rank, :meth:`_crack_ranks`; else
        None).
        ``record_alarm`` is the alarm the joint's rules count (the monitor's in the learning period, the joint's
        own rank after); ``monitor_alarm`` the monitor's at its alpha.  ``joint_state`` is the state after the
        record, replayed; records of earlier epochs keep their epoch's."""
        with self._sessions() as s:
            j = self._joint(s, joint)
            eps = {e.id: e for e in self._epochs(s, j.id)}
            steps: dict = {}
            cracks: dict = {}
            for ep in eps.values():  # replay every epoch, so old records show the state they led to
                rl, _, ep_steps = self._replay_epoch(s, j, ep)
                steps.update({st.key: st for st in ep_steps if st.kind == "record"})
                cracks.update(self._crack_ranks(s, ep, rl, ep_steps) or {})
            q = select(db.Record).where(db.Record.joint_id == j.id).order_by(db.Record.time, db.Record.id)
            recs = list(s.scalars(q))
            if limit is not None:
                recs = recs[-int(limit):] if int(limit) > 0 else []
            out = []
            for r in recs:
                st = steps.get(r.id)
                out.append({
                    "record_id": r.id, "time": _iso(r.time), "checksum": r.checksum, "filename": r.filename,
                    "health_index": r.health_index, "p_value": r.p_value,
                    "joint_p_value": None if st is None else st.joint_p_value,
                    "record_alarm": None if st is None else st.record_alarm, "monitor_alarm": r.record_alarm,
                    "joint_state": None if st is None else st.state, "fault_state": r.fault_state,
                    "probability": r.probability, "recognised": r.recognised, "reason": r.reason,
                    "changes": r.changes or [], "epoch": eps[r.epoch_id].number if r.epoch_id in eps else None,
                    "rejected": r.rejected, "learning": None if st is None else st.learning,
                    "operating_point": r.operating_point, "crack": cracks.get(r.id)})
            return out

    def _replay_epoch(self, s, j: db.Joint, ep: db.Epoch):
        """``(rules, records, steps)`` of one epoch: its judged records and acknowledgements replayed
        (:func:`rvdiag.fleet.rules.replay`); a record's step has its id as ``key``."""
        rl = R.Rules.from_dict(j.rules).resolved(ep.alpha if ep.alpha is not None else R.FALLBACK_ALPHA)
        cols = (db.Record.id, db.Record.time, db.Record.health_index, db.Record.record_alarm, db.Record.recognised,
                db.Record.fault_state, db.Record.probability)  # what the state and status need: no JSON columns
        recs = s.execute(select(*cols).where(db.Record.epoch_id == ep.id, db.Record.rejected.is_(None))).all()
        acks = list(s.scalars(select(db.Event).where(db.Event.epoch_id == ep.id, db.Event.kind == "acknowledged")))
        items = [R.Item(time=r.time, key=r.id, health_index=r.health_index, monitor_alarm=r.record_alarm,
                        recognised=bool(r.recognised)) for r in recs]
        items += [R.Item(time=a.time, kind="ack", key=None) for a in acks]
        return rl, recs, R.replay(items, rl)

    def events(self, joint: str | None = None, kind: str | None = None) -> list[dict]:
        """Events in time order (of one joint, of one kind): ``joint, kind, time, by, note, record_id, epoch``."""
        if kind is not None and kind not in db.EVENT_KINDS:
            raise FleetError(f"unknown event kind {kind!r}; one of {', '.join(db.EVENT_KINDS)}")
        with self._sessions() as s:
            q = select(db.Event, db.Joint.path).join(db.Joint, db.Event.joint_id == db.Joint.id)
            if joint is not None:
                q = q.where(db.Event.joint_id == self._joint(s, joint).id)
            if kind is not None:
                q = q.where(db.Event.kind == kind)
            eps = {e.id: e.number for e in s.scalars(select(db.Epoch))}
            return [{"id": e.id, "joint": path, "kind": e.kind, "time": _iso(e.time), "by": e.by, "note": e.note,
                     "record_id": e.record_id, "epoch": eps.get(e.epoch_id)}
                    for e, path in s.execute(q.order_by(db.Event.time, db.Event.id))]

    # ------------------------------------------------------------------------------------------- people
    def acknowledge(self, joint: str, by: str, note: str, time: datetime | None = None) -> dict:
        """Acknowledge the joint's open alarm (who, a note); it clears once the last ``m`` records are normal."""
        t = now() if time is None else _aware(time)
        with self._writes() as s, s.begin():
            j = self._joint(s, joint, lock=True)
            d = self._derive(s, j)
            if d["state"] == "no-baseline" or not d["steps"] or not any(st.open_alarm for st in d["steps"][-1:]):
                raise FleetError(f"the joint {joint} has no open alarm to acknowledge (state {d['state']})")
            e = db.Event(joint_id=j.id, kind="acknowledged", time=t, by=_who(by), note=str(note or ""),
                         epoch_id=d["epoch"].id)
            s.add(e)
            s.flush()
            self._derive_events(s, j)
            state = self._derive(s, j)["state"]
        return {"joint": joint, "kind": "acknowledged", "time": _iso(t), "by": e.by, "note": e.note,
                "joint_state": state}

    def maintenance(self, joint: str, by: str, note: str, time: datetime | None = None) -> dict:
        """Record maintenance on the joint: its baseline no longer holds, the joint is ``no-baseline`` until it is
        commissioned again (a new epoch), and an open alarm closes with the epoch."""
        t = now() if time is None else _aware(time)
        with self._writes() as s, s.begin():
            j = self._joint(s, joint, lock=True)
            d = self._derive(s, j)
            s.add(db.Event(joint_id=j.id, kind="maintenance", time=t, by=_who(by), note=str(note or ""),
                           epoch_id=None if d["epoch"] is None else d["epoch"].id))
        return {"joint": joint, "kind": "maintenance", "time": _iso(t), "by": _who(by), "note": str(note or ""),
                "joint_state": "no-baseline"}

    def set_failure_index(self, joint: str, value: float | None, by: str | None = None, note: str = "",
                          time: datetime | None = None) -> dict:
        """Set the joint's failure index (:class:`rvdiag.fleet.rules.Rules` ``failure_index``: the health index its
        remaining life is counted to; None removes it), recorded as a ``failure-index`` event with who and why.
        It changes no alarm and no state."""
        t = now() if time is None else _aware(time)
        with self._writes() as s, s.begin():
            j = self._joint(s, joint, lock=True)
            old = R.Rules.from_dict(j.rules)
            rl = replace(old, failure_index=None if value is None else float(value)).check()
            j.rules = rl.to_dict()
            ep = self._epochs(s, j.id)
            text = (f"failure index {_fmt_index(old.failure_index)} -> {_fmt_index(rl.failure_index)}"
                    + (f": {note}" if note else ""))
            s.add(db.Event(joint_id=j.id, kind="failure-index", time=t, by=_who(by), note=text,
                           epoch_id=ep[-1].id if ep else None))
        return {"joint": joint, "kind": "failure-index", "time": _iso(t), "by": _who(by), "note": text,
                "failure_index": rl.failure_index}

    # ------------------------------------------------------------------------------------------- tokens
    def create_token(self, name: str, read_only: bool) -> str:
        """A new API token (returned once; the store keeps its hash)."""
        with self._writes() as s, s.begin():
            return auth.create(s, name, read_only)

    def check_token(self, token: str | None, write: bool) -> str:
        """The token's name; :class:`rvdiag.errors.AuthError` when missing, unknown, or read-only for a write."""
        with self._sessions() as s:
            return auth.check(s, token, write)

    # ------------------------------------------------------------------------------------------- evidence
    def record_signal(self, joint: str, checksum: str):
        """The kept raw record of ``joint`` with that checksum, read as it was ingested (for plotting evidence)."""
        with self._sessions() as s:
            j = self._joint(s, joint)
            r = s.scalar(select(db.Record).where(db.Record.joint_id == j.id, db.Record.checksum == str(checksum)))
            if r is None:
                raise FleetError(f"the joint {joint} has no record {str(checksum)[:12]}...")
            monitor, reading = Path(j.monitor), Reading.from_dict(r.reading)
        return self.judge.read(self.blobs.find(r.checksum), reading, monitor)

    def rules(self, joint: str) -> R.Rules:
        """The joint's rules, resolved with its current epoch's (or its monitor's) alpha."""
        with self._sessions() as s:
            j = self._joint(s, joint)
            eps = self._epochs(s, j.id)
            alpha = eps[-1].alpha if eps and eps[-1].alpha is not None else None
            monitor, raw = Path(j.monitor), j.rules
        if alpha is None:
            alpha = self.judge.describe(monitor)["alpha"] or R.FALLBACK_ALPHA
        return R.Rules.from_dict(raw).resolved(alpha)

    def stated_false_alarms_per_year(self, joint: str, records_per_day: float | None = None) -> float:
        """The joint's stated false alarms per joint-year after learning
        (:func:`rvdiag.fleet.rules.false_alarms_per_year`)."""
        return R.false_alarms_per_year(self.rules(joint), records_per_day)


# ------------------------------------------------------------------------------------------------ helpers
def _immediate_writes(engine) -> None:
    """SQLite: a write session begins ``BEGIN IMMEDIATE`` (it takes the write lock at once and waits for it), so
    that two writers never fail on a stale read snapshot; reads begin as usual (WAL lets them run beside a write)."""

    @sa_event.listens_for(engine, "connect")
    def _no_implicit(dbapi_conn, _rec):  # noqa: ANN001
        dbapi_conn.isolation_level = None

    @sa_event.listens_for(engine, "begin")
    def _begin(conn):  # noqa: ANN001
        conn.exec_driver_sql("BEGIN IMMEDIATE" if conn.get_execution_options().get("fleet_write") else "BEGIN")


def _aware(t: datetime | str) -> datetime:
    if isinstance(t, str):
        return parse_time(t)
    return t.replace(tzinfo=timezone.utc) if t.tzinfo is None else t.astimezone(timezone.utc)


def _num(v):
    try:
        v = float(v)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _who(by: str | None) -> str:
    by = str(by or "").strip() or os.environ.get("USER") or "unknown"
    return by[:200]


def _read_bytes(path: Path) -> bytes:
    try:
        return Path(path).read_bytes()
    except FileNotFoundError:
        raise FleetError(f"no file {path}") from None
    except IsADirectoryError:
        raise FleetError(f"{path} is a folder, not a record file") from None
    except OSError as exc:
        raise FleetError(f"cannot read {path}: {exc.strerror or exc}") from None


def _fmt_index(v: float | None) -> str:
    return "none" if v is None else f"{v:g}"


def prognosis_of(judged: list, last, failure_index: float | None = None) -> dict:
    """The onset and remaining life of a joint from its current epoch's recognised records in time order
    (:func:`rvdiag.prognostics.joint_prognosis`): ``onset_time`` and ``change_alarm_time`` (None before the change
    detector alarms), ``change_evidence`` (the conformal test martingale's value; it alarms at 1/delta, so a
    healthy joint ever alarms with probability at most delta, 1 % per joint-life), and ``rul``: ``{"estimated":
    false, "reason"}`` or the remaining life's ``median_days``, ``p10_days``, ``p90_days``, ``p_before``, counted to the joint's
    ``failure_index`` (its rules; without one ``rul`` says how to set it).  The joint's first records fill the
    detector's ranking pool (its commissioning records have no index against themselves)."""
    from rvdiag.errors import ParameterError
    from rvdiag.prognostics import joint_prognosis
    from rvdiag.prognostics.rul import NO_THRESHOLD

    recs = [r for r in judged if r.health_index is not None and math.isfinite(float(r.health_index))]
    if not recs:
        return {"onset_time": None, "change_alarm_time": None, "change_evidence": None,
                "rul": {"estimated": False, "reason": "no recognised record with a health index yet"}}
    try:
        p = joint_prognosis([r.time for r in recs], health_index=[float(r.health_index) for r in recs],
                            baseline_scores=[], threshold=failure_index,
                            fault_state=None if last is None else last.fault_state).to_dict()
    except ParameterError as exc:
        return {"onset_time": None, "change_alarm_time": None, "change_evidence": None,
                "rul": {"estimated": False, "reason": str(exc)}}
    rul = p["rul"]
    if rul.get("reason") == NO_THRESHOLD:
        rul = {**rul, "reason": "the joint has no failure index (the health index its remaining life is counted "
                                "to): set one with 'rvdiag fleet set JOINT --failure-index X'"}
    return {"onset_time": p["onset_time"], "change_alarm_time": p["alarm_time"], "change_evidence": p["evidence"],
            "rul": rul}


def _copy_twin(twin: Path, out: Path) -> None:
    """Copy a twin folder's crack references (``crack/``) and its ``params.toml`` to ``out`` (whole or not at all:
    :func:`rvdiag.atomic.staged_directory`), so that the epoch keeps them as the fleet keeps its records."""
    import shutil

    from rvdiag.atomic import staged_directory

    with staged_directory(out) as tmp:
        shutil.copytree(twin / "crack", tmp / "crack")
        if (twin / "params.toml").is_file():
            shutil.copy2(twin / "params.toml", tmp / "params.toml")
