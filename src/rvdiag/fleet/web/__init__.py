"""The fleet's dashboard: three pages rendered from a :class:`rvdiag.fleet.Fleet` with Jinja2, served live by
:func:`rvdiag.fleet.api.create_app` or written as a static snapshot by :func:`snapshot`.

- the fleet page (``/``): every joint with its state (coloured), last health index, a trend line of its recent
  indices against its alarm threshold, and how long it has been in its state;
- the joint page (``/joints/{joint}``): the health index over time with the alarm threshold and the events, the most
  probable state with its probability, what changed, the last records' evidence (their spectra, from the kept raw
  records), the records and the events, and acknowledge / maintenance forms; for a joint commissioned with a twin,
  also its crack detector's index over time and its crack alarm (shown, never part of the joint's state);
- the alarms page (``/alarms``): the joints whose alarm is open, each with acknowledge, and the fleet's alarm log.

Everything the pages load comes from this server (or the snapshot's folder): the dashboard's own script and style
(``web/static``) and Plotly's JavaScript from the plotly wheel (``plotly/package_data/plotly.min.js``), never a
CDN, so the dashboard works on a plant network without internet.  The token for writes is entered once in the page
and kept in the tab's ``sessionStorage``.
"""

from __future__ import annotations

import json
import math
import shutil
from dataclasses import dataclass, replace
from datetime import datetime, timedelta, timezone
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import quote

import numpy as np
from jinja2 import Environment, FileSystemLoader, select_autoescape

from rvdiag import __version__
from rvdiag.atomic import staged_directory
from rvdiag.errors import RvdiagError

HERE = Path(__file__).resolve().parent
TEMPLATES = HERE / "templates"
STATIC = HERE / "static"
#: The joint states and the colour each is shown in (also in static/dashboard.css).
STATES = ("no-baseline", "learning", "normal", "alert", "alarm", "sensor-fault")
#: Records shown in the joint page's table and evidence (the fleet page's trend: status()'s ``trend``).
TABLE_RECORDS = 50
EVIDENCE_RECORDS = 3
#: The file that marks a folder as a snapshot written by :func:`snapshot` (which replaces only such a folder).
SNAPSHOT_MARK = ".rvdiag-dashboard-snapshot"

_env = Environment(loader=FileSystemLoader(str(TEMPLATES)), autoescape=select_autoescape(["html"]),
                   trim_blocks=True, lstrip_blocks=True)


def plotly_js_path() -> Path:
    """Plotly's minified JavaScript as shipped in the plotly wheel (the dashboard's only charting script)."""
    path = Path(str(resources.files("plotly") / "package_data" / "plotly.min.js"))
    if not path.is_file():
        raise RvdiagError(f"plotly's JavaScript is missing from the plotly package ({path}); reinstall plotly")
    return path


@dataclass(frozen=True)
class Links:
    """Where a page's links point: the live server (``base='/'``) or a snapshot folder (relative, ``.html``).

    ``api`` is the API's root for the page's scripts (None in a snapshot: nothing can be written there)."""

    base: str = "/"
    suffix: str = ""
    api: str | None = "/api"
    read_needs_token: bool = False

    def fleet(self) -> str:
        return self.base + ("index.html" if self.suffix else "")

    def alarms(self) -> str:
        return self.base + "alarms" + self.suffix

    def joint(self, name: str) -> str:
        return self.base + "joints/" + quote(name, safe="/") + self.suffix

    def static(self, name: str) -> str:
        return self.base + "static/" + name

    def at_depth(self, depth: int) -> "Links":
        """These links from a page ``depth`` folders below the snapshot's root (relative links only)."""
        return replace(self, base="../" * depth or "./") if self.suffix else self


# ---- formatting -----------------------------------------------------------------------------------------------------
def _dt(value) -> datetime | None:
    if value is None or value == "":
        return None
    if isinstance(value, str):
        try:
            value = datetime.fromisoformat(value)
        except ValueError:
            return None
    if isinstance(value, datetime) and value.tzinfo is None:
        value = value.replace(tzinfo=timezone.utc)
    return value


def fmt_number(value, digits: int = 4) -> str:
    """A number as the pages show it: ``digits`` significant digits, '–' for none."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    return f"{float(value):.{digits}g}"


def fmt_time(value) -> str:
    """A time as the pages show it: ``YYYY-MM-DD HH:MM`` UTC."""
    t = _dt(value)
    return "–" if t is None else t.astimezone(timezone.utc).strftime("%Y-%m-%d %H:%M")


def fmt_duration(seconds: float | None) -> str:
    """A duration as ``3 d 4 h``, ``5 h 12 min`` or ``40 min``."""
    if seconds is None or not math.isfinite(seconds):
        return "–"
    s = max(0, int(seconds))
    d, h, m = s // 86400, (s % 86400) // 3600, (s % 3600) // 60
    if d:
        return f"{d} d {h} h"
    if h:
        return f"{h} h {m} min"
    return f"{m} min"


def fmt_probability(value) -> str:
    """A probability as a percentage with no decimal (e.g. ``87 %``)."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    return f"{100 * float(value):.0f} %"


_env.filters.update(num=fmt_number, time=fmt_time, pct=fmt_probability)


def _attr(value) -> str:
    """A value as a ``data-value`` attribute: the full number (``repr``), or empty."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return ""
    return repr(float(value)) if isinstance(value, (int, float)) and not isinstance(value, bool) else str(value)


_env.filters["attr"] = _attr


def _json_script(obj: Any) -> str:
    """``obj`` as JSON safe inside ``<script type="application/json">`` (no ``</script>`` can close it)."""
    text = json.dumps(obj, allow_nan=False, default=str, separators=(",", ":"))
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def _finite_or_none(v):
    return None if v is None or not math.isfinite(float(v)) else float(v)


# ---- pieces ---------------------------------------------------------------------------------------------------------
def sparkline(values: list, threshold: float | None, width: int = 140, height: int = 28) -> str:
    """An inline SVG trend line of ``values`` (None skipped) with the threshold dashed; '' when there are none."""
    pts = [(i, float(v)) for i, v in enumerate(values) if v is not None and math.isfinite(float(v))]
    if not pts:
        return ""
    ys = [y for _, y in pts] + ([threshold] if threshold is not None and math.isfinite(threshold) else [])
    lo, hi = min(ys), max(ys)
    span = hi - lo or 1.0
    n = max(len(values) - 1, 1)

    def xy(i, y):
        return f"{2 + (width - 4) * i / n:.1f},{height - 2 - (height - 4) * (y - lo) / span:.1f}"

    line = " ".join(xy(i, y) for i, y in pts)
    parts = [f'<svg class="spark" width="{width}" height="{height}" viewBox="0 0 {width} {height}" '
             f'role="img" aria-label="health index trend">']
    if threshold is not None and math.isfinite(threshold):
        ty = xy(0, threshold).split(",")[1]
        parts.append(f'<line class="spark-threshold" x1="0" x2="{width}" y1="{ty}" y2="{ty}"/>')
    parts.append(f'<polyline class="spark-line" points="{line}"/>')
    i, y = pts[-1]
    parts.append(f'<circle class="spark-last" cx="{xy(i, y).split(",")[0]}" cy="{xy(i, y).split(",")[1]}" r="2"/>')
    parts.append("</svg>")
    return "".join(parts)


def _status_rows(fleet, now: datetime, joint: str | None = None) -> list[dict]:
    rows = []
    for row in fleet.status(joint):
        row = dict(row)
        since = _dt(row.get("state_since"))
        row["time_in_state"] = fmt_duration((now - since).total_seconds()) if since else "–"
        rows.append(row)
    return rows


def _index_figure(history: list[dict], threshold: float | None, events: list[dict]) -> dict:
    """The joint's health index over time, record alarms in red, unrecognised records in grey, the threshold
    dashed and the events as vertical lines (a Plotly figure as plain JSON)."""
    ok = [h for h in history if not h.get("rejected") and h.get("health_index") is not None]
    groups = {
        "record": [h for h in ok if h.get("recognised", True) and not h.get("record_alarm")],
        "record alarm": [h for h in ok if h.get("recognised", True) and h.get("record_alarm")],
        "not recognised": [h for h in ok if not h.get("recognised", True)],
    }
    style = {"record": dict(color="#1f5fa8", size=6), "record alarm": dict(color="#c62828", size=8),
             "not recognised": dict(color="#8a8a8a", size=7, symbol="x")}
    data = []
    for name, rows in groups.items():
        if rows:
            data.append({"type": "scatter", "mode": "markers", "name": name,
                         "x": [fmt_iso(h["time"]) for h in rows],
                         "y": [_finite_or_none(h["health_index"]) for h in rows],
                         "marker": style[name],
                         "text": [f"{h.get('joint_state', '')} · p={fmt_number(h.get('p_value'), 3)}" for h in rows],
                         "hovertemplate": "%{x}<br>index %{y:.4g}<br>%{text}<extra></extra>"})
    if ok:
        data.insert(0, {"type": "scatter", "mode": "lines", "name": "health index", "showlegend": False,
                        "x": [fmt_iso(h["time"]) for h in ok], "y": [_finite_or_none(h["health_index"]) for h in ok],
                        "line": {"color": "#9bb7d9", "width": 1}, "hoverinfo": "skip"})
    shapes, annotations = [], []
    if threshold is not None and math.isfinite(threshold):
        shapes.append({"type": "line", "xref": "paper", "x0": 0, "x1": 1, "y0": threshold, "y1": threshold,
                       "line": {"color": "#c62828", "dash": "dash", "width": 1.5}})
        annotations.append({"xref": "paper", "x": 1, "y": threshold, "text": f"alarm threshold {threshold:.4g}",
                            "showarrow": False, "xanchor": "right", "yanchor": "bottom",
                            "font": {"color": "#c62828", "size": 11}})
    colours = {"raised": "#c62828", "acknowledged": "#ef6c00", "cleared": "#2e7d32", "maintenance": "#6a1b9a",
               "commissioned": "#555555"}
    for ev in events:
        if ev.get("kind") in colours and ev.get("time"):
            shapes.append({"type": "line", "yref": "paper", "y0": 0, "y1": 1, "x0": fmt_iso(ev["time"]),
                           "x1": fmt_iso(ev["time"]), "line": {"color": colours[ev["kind"]], "width": 1,
                                                               "dash": "dot"}})
    xaxis = {"title": {"text": "record time (UTC)"}}
    times = [_dt(h["time"]) for h in ok]
    if times:  # the records' span (an event long before them, e.g. commissioning, would squeeze them)
        pad = max((max(times) - min(times)) * 0.03, timedelta(hours=1))
        xaxis["range"] = [fmt_iso(min(times) - pad), fmt_iso(max(times) + pad)]
    layout = {"margin": {"l": 55, "r": 15, "t": 10, "b": 40}, "height": 320, "hovermode": "closest",
              "xaxis": xaxis, "yaxis": {"title": {"text": "health index"}},
              "shapes": shapes, "annotations": annotations, "legend": {"orientation": "h", "y": 1.08}}
    return {"data": data, "layout": layout}


def _crack_figure(history: list[dict]) -> dict | None:
    """The crack detector's index over time for a joint commissioned with a twin (None without one): the learning
    records, the records ranked among them, and those whose rank raised the crack alarm (``joint_alarm``), as a
    Plotly figure.  No threshold line: a record's crack alarm is its conformal rank among the learning records of
    its own epoch (:func:`rvdiag.fleet.rules.rank_after_learning`), not one fixed value."""
    rows = [h for h in history if isinstance(h.get("crack"), dict) and not h.get("rejected")
            and _finite_or_none(h["crack"].get("index")) is not None and h.get("recognised", True)]
    if not rows:
        return None
    groups = {"learning": [h for h in rows if h["crack"].get("learning")],
              "ranked": [h for h in rows if not h["crack"].get("learning") and not h["crack"].get("joint_alarm")],
              "crack alarm": [h for h in rows if h["crack"].get("joint_alarm")]}
    style = {"learning": dict(color="#8a8a8a", size=6), "ranked": dict(color="#1f5fa8", size=6),
             "crack alarm": dict(color="#c62828", size=8)}
    data = [{"type": "scatter", "mode": "markers", "name": name, "x": [fmt_iso(h["time"]) for h in g],
             "y": [_finite_or_none(h["crack"]["index"]) for h in g], "marker": style[name],
             "text": [f"p={fmt_number(h['crack'].get('joint_p_value'), 3)}" for h in g],
             "hovertemplate": "%{x}<br>crack index %{y:.4g}<br>%{text}<extra></extra>"}
            for name, g in groups.items() if g]
    layout = {"margin": {"l": 55, "r": 15, "t": 10, "b": 40}, "height": 260, "hovermode": "closest",
              "xaxis": {"title": {"text": "record time (UTC)"}}, "yaxis": {"title": {"text": "crack index"}},
              "legend": {"orientation": "h", "y": 1.1}}
    return {"data": data, "layout": layout}


def fmt_iso(value) -> str | None:
    t = _dt(value)
    return None if t is None else t.astimezone(timezone.utc).isoformat()


def _spectrum(sig, max_points: int = 1500) -> tuple[np.ndarray, np.ndarray, str]:
    """Welch power spectral density of a kept record, in dB, thinned to ``max_points`` (the largest value of each
    bin kept, so that a mesh line is never thinned away)."""
    from scipy.signal import welch

    x = np.asarray(sig.data, dtype=float)
    x = x[np.isfinite(x)]
    fs = getattr(sig, "fs", None) or 1.0
    f, p = welch(x - x.mean(), fs=fs, nperseg=min(4096, len(x)))
    f, p = f[1:], p[1:]  # no 0 Hz on the log frequency axis
    db = 10 * np.log10(np.maximum(p, 1e-30))
    if len(f) > max_points:
        k = int(math.ceil(len(f) / max_points))
        m = len(f) // k * k
        idx = np.arange(m).reshape(-1, k)[np.arange(m // k), np.argmax(db[:m].reshape(-1, k), axis=1)]
        f, db = f[idx], db[idx]
    return f, db, "frequency (Hz)" if getattr(sig, "fs", None) else "frequency (cycles/sample)"


def _evidence(fleet, joint: str, history: list[dict]) -> tuple[dict | None, list[dict], str | None]:
    """The last accepted records' spectra (a Plotly figure), their rows, and a note when they cannot be shown."""
    last = [h for h in history if not h.get("rejected") and h.get("checksum")][-EVIDENCE_RECORDS:]
    if not last:
        return None, [], "no accepted record yet"
    data, xlabel, notes = [], "frequency (Hz)", []
    palette = ["#1f5fa8", "#ef6c00", "#2e7d32"]
    for k, h in enumerate(reversed(last)):
        try:
            f, db, xlabel = _spectrum(fleet.record_signal(joint, h["checksum"]))
        except (RvdiagError, OSError, ValueError, KeyError) as exc:
            notes.append(f"{fmt_time(h['time'])}: {exc}")
            continue
        state = "alarm" if h.get("record_alarm") else ("not recognised" if not h.get("recognised", True) else "")
        data.append({"type": "scatter", "mode": "lines", "name": f"{fmt_time(h['time'])} {state}".strip(),
                     "x": f.tolist(), "y": [round(float(v), 2) for v in db],
                     "line": {"width": 1, "color": palette[k % len(palette)]}})
    layout = {"margin": {"l": 55, "r": 15, "t": 10, "b": 40}, "height": 300, "hovermode": "x",
              "xaxis": {"title": {"text": xlabel}, "type": "log"},
              "yaxis": {"title": {"text": "power spectral density (dB)"}},
              "legend": {"orientation": "h", "y": 1.1}}
    return ({"data": data, "layout": layout} if data else None), list(reversed(last)), "; ".join(notes) or None


# ---- pages ----------------------------------------------------------------------------------------------------------
def _render(name: str, links: Links, now: datetime, **ctx) -> str:
    return _env.get_template(name).render(links=links, version=__version__, generated=fmt_time(now),
                                          states=STATES, json_script=_json_script, **ctx)


def fleet_page(fleet, links: Links = Links(), now: datetime | None = None) -> str:
    """The fleet page's HTML: every joint's state, last index, trend and time in state."""
    now = now or datetime.now(timezone.utc)
    rows = _status_rows(fleet, now)
    for row in rows:
        row["trend"] = sparkline(row.get("trend") or [], row.get("threshold"))
    counts = {s: sum(r.get("state") == s for r in rows) for s in STATES}
    return _render("fleet.html", links, now, rows=rows, counts=counts,
                   open_alarms=sum(bool(r.get("open_alarm")) for r in rows),
                   any_crack=any(r.get("crack") is not None for r in rows))


def joint_page(fleet, joint: str, links: Links = Links(), now: datetime | None = None) -> str:
    """The joint page's HTML: index over time with its threshold and events, state, what changed, evidence."""
    now = now or datetime.now(timezone.utc)
    (row,) = _status_rows(fleet, now, joint)
    history = list(fleet.history(joint))
    events = list(fleet.events(joint))
    last_ok = next((h for h in reversed(history) if not h.get("rejected")), None)
    evidence, evidence_rows, evidence_note = _evidence(fleet, joint, history)
    try:
        stated = fleet.stated_false_alarms_per_year(joint)
    except (RvdiagError, ValueError, KeyError):
        stated = None
    depth = 1 + joint.count("/")
    return _render("joint.html", links.at_depth(depth), now, row=row, joint=joint,
                   history=list(reversed(history[-TABLE_RECORDS:])), n_history=len(history),
                   events=list(reversed(events)), last=last_ok, stated=stated,
                   index_figure=_index_figure(history, row.get("threshold"), events),
                   crack_figure=_crack_figure(history) if row.get("crack") is not None else None,
                   has_crack=any(isinstance(h.get("crack"), dict) for h in history),
                   evidence=evidence, evidence_rows=evidence_rows, evidence_note=evidence_note)


def alarms_page(fleet, links: Links = Links(), now: datetime | None = None) -> str:
    """The alarms page's HTML: the joints with an open alarm (acknowledge each) and the fleet's alarm log."""
    now = now or datetime.now(timezone.utc)
    rows = _status_rows(fleet, now)
    open_rows = [r for r in rows if r.get("open_alarm")]
    log = [e for e in fleet.events(None) if e.get("kind") in ("raised", "acknowledged", "cleared", "maintenance")]
    return _render("alarms.html", links, now, rows=open_rows, log=list(reversed(log))[:500])


def error_page(status: int, message: str, read_needs_token: bool = False) -> str:
    """A small page for an error met while browsing (the API answers JSON instead)."""
    return _render("error.html", Links(read_needs_token=read_needs_token), datetime.now(timezone.utc),
                   status=status, message=message)


def snapshot(fleet, out_dir: str | Path, now: datetime | None = None) -> Path:
    """Write the dashboard as static HTML to ``out_dir`` (its pages, style, script and Plotly's JavaScript
    copied beside them) and return the path of its ``index.html``.  It opens from the file system in any browser,
    with no server and no network; acknowledging needs the live dashboard.

    ``out_dir`` must be a new or empty folder, or an earlier snapshot (which is replaced whole, atomically); any
    other folder is refused, so that nothing else is overwritten."""
    out = Path(out_dir)
    if out.exists() and (not out.is_dir() or (any(out.iterdir()) and not (out / SNAPSHOT_MARK).is_file())):
        raise RvdiagError(f"{out} exists and is not an earlier dashboard snapshot; give a new or empty folder")
    now = now or datetime.now(timezone.utc)
    links = Links(base="./", suffix=".html", api=None)
    with staged_directory(out) as tmp:
        (tmp / "static").mkdir()
        for f in STATIC.iterdir():
            if f.is_file():
                shutil.copyfile(f, tmp / "static" / f.name)
        shutil.copyfile(plotly_js_path(), tmp / "static" / "plotly.min.js")
        (tmp / "index.html").write_text(fleet_page(fleet, links, now), encoding="utf-8")
        (tmp / "alarms.html").write_text(alarms_page(fleet, links, now), encoding="utf-8")
        for name in fleet.joints():
            page = tmp / "joints" / f"{name}.html"
            if not page.resolve().is_relative_to(tmp.resolve()):
                raise RvdiagError(f"joint name {name!r} would leave the snapshot folder")
            page.parent.mkdir(parents=True, exist_ok=True)
            page.write_text(joint_page(fleet, name, links, now), encoding="utf-8")
        (tmp / SNAPSHOT_MARK).write_text(f"rvdiag {__version__} dashboard snapshot, {now.isoformat()}\n")
    return out / "index.html"


__all__ = ["Links", "STATIC", "TEMPLATES", "alarms_page", "error_page", "fleet_page", "joint_page",
           "plotly_js_path", "snapshot", "sparkline"]
