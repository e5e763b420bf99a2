"""Judging a record for the fleet: the one place that reads records and calls the monitor
(:func:`rvdiag.monitoring.monitor_record`), with a per-process cache of loaded models and baselines, so that a
watcher or a server pays a model's start-up once, not per record.

:class:`Judge` is what :class:`rvdiag.fleet.store.Fleet` calls; a test may hand the fleet another object with the
same methods (``describe``, ``read``, ``make_baseline``, ``judge``; ``twin`` and ``crack`` for a joint commissioned
with a twin).
"""

from __future__ import annotations

import json
import threading
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from rvdiag.errors import FleetError, ParameterError

#: a record is clipped when more than this share of its samples sit at its two extremes (:func:`clipped_reason`)
CLIP_SHARE = 0.01
#: ... and it has more distinct values than this (a coarse quantiser's few levels are not a clipped sensor)
CLIP_MIN_LEVELS = 64


@dataclass(frozen=True)
class Reading:
    """How a joint's files are read and where its operating point comes from (the options of ``rvdiag fleet
    commission`` / ``ingest``, the form fields of the HTTP route).

    ``output_speed`` (deg/s at the output) and ``load`` (N m): the record's operating point, else from the file name
    by ``meta_regex`` (named groups ``output_speed_deg_s`` or ``speed_dps``, and ``load_Nm`` or ``load``); the speed
    may be left out, then the monitor measures it from the record.  ``time_regex``: a regular expression on the file name whose
    group ``time`` (or whole match) is the record's ISO time."""

    channel: str | None = None
    fs: float | None = None
    angle_channel: str | None = None
    output_speed: float | None = None
    load: float | None = None
    meta_regex: str | None = None
    time_regex: str | None = None

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict | None) -> "Reading":
        d = {k: v for k, v in (d or {}).items() if k in cls.__dataclass_fields__}
        return cls(**d)

    def operating_point(self, filename: str) -> dict:
        """``{"output_speed_deg_s", "load_Nm"}`` of a file: the given values, else those :attr:`meta_regex` reads
        from its name (:func:`rvdiag.workflows.records.name_metadata`, as ``read_record`` reads them)."""
        from rvdiag.workflows.records import name_metadata

        speed, load = self.output_speed, self.load
        name = Path(filename).name
        md = name_metadata(self.meta_regex, name)
        if speed is None:
            speed = md.get("output_speed_deg_s", md.get("speed_dps"))
        if load is None:
            load = md.get("load_Nm")
        for v in (speed, load):
            if isinstance(v, str):
                raise ParameterError(f"{name}: --meta-regex gives a value that is not a number ({v!r})")
        return {"output_speed_deg_s": None if speed is None else float(speed),
                "load_Nm": None if load is None else float(load)}


def monitor_card(monitor: Path) -> dict:
    """The card of a monitor model directory, checked to be a baseline-referenced model."""
    from rvdiag.models.card import read_card

    card = read_card(monitor)
    if not card.get("needs_baseline"):
        raise FleetError(f"{monitor} is not a baseline monitor (its card does not say needs_baseline): train one "
                         "with 'rvdiag train' on a paired store (docs/monitoring.md)")
    return card


class Judge:
    """Reads records and judges them with the monitor, loading each model and baseline once per process."""

    def __init__(self):
        self._models: dict = {}
        self._baselines: dict = {}
        self._twins: dict = {}
        self._lock = threading.Lock()

    # ---------------------------------------------------------------- what a joint's monitor is
    def describe(self, monitor: Path) -> dict:
        """``{"alpha", "signal"}`` of a monitor directory (its per-record false-alarm rate, vibration or current)."""
        card = monitor_card(Path(monitor))
        alpha = (card.get("alarm") or {}).get("alpha")
        signal = (card.get("training_store") or {}).get("signal") or "vibration"
        return {"alpha": None if alpha is None else float(alpha), "signal": str(signal)}

    def model(self, monitor: Path):
        from rvdiag.workflows import load_model

        key = str(Path(monitor).resolve())
        stamp = (Path(key) / "card.json").stat().st_mtime_ns if (Path(key) / "card.json").exists() else None
        with self._lock:
            hit = self._models.get(key)
            if hit is None or hit[0] != stamp:
                hit = (stamp, load_model(key))
                self._models[key] = hit
                self._baselines = {k: v for k, v in self._baselines.items() if k[0] != key}
            return hit[1]

    def baseline(self, monitor: Path, path: Path):
        from rvdiag.monitoring import open_baseline

        key = (str(Path(monitor).resolve()), str(Path(path).resolve()))
        model = self.model(monitor)
        with self._lock:
            if key not in self._baselines:
                self._baselines[key] = open_baseline(Path(path), model)
            return self._baselines[key]

    def twin(self, folder: Path):
        """The crack detectors of a twin folder (:func:`rvdiag.monitoring.crack.load_twin`), loaded once per process
        (an epoch's copy never changes)."""
        from rvdiag.monitoring.crack import load_twin

        key = str(Path(folder).resolve())
        with self._lock:
            if key not in self._twins:
                self._twins[key] = load_twin(key)
            return self._twins[key]

    # ---------------------------------------------------------------- reading, baselines, judging
    def read(self, path: Path, reading: Reading, monitor: Path):
        """The record of ``path`` as the joint's monitor reads it (:func:`rvdiag.workflows.read_record`)."""
        from rvdiag.workflows import read_record

        return read_record(Path(path), channel=reading.channel, fs=reading.fs, angle_channel=reading.angle_channel)

    def make_baseline(self, monitor: Path, records: list, operating_points: list[dict], out: Path) -> dict:
        """Write a joint's baseline store from its commissioning records; ``{"n_records", "operating_points"}``."""
        from rvdiag.monitoring import make_baseline

        base = make_baseline(records, model=self.model(monitor), operating_points=operating_points, out=Path(out))
        return {"n_records": int(getattr(base, "n_records", len(records))), "operating_points": operating_points}

    def judge(self, monitor: Path, baseline: Path, signal, reading: Reading, operating_point: dict) -> dict:
        """The monitor's result for one record (``MonitorResult.to_dict()``)."""
        from rvdiag.monitoring import monitor_record

        x = np.asarray(getattr(signal, "data", signal), dtype=np.float64)
        clipped = clipped_reason(x)
        if clipped is not None:
            return not_recognised(clipped, self.describe(monitor)["alpha"], operating_point)
        res = monitor_record(self.model(monitor), signal, self.baseline(monitor, baseline),
                             output_speed=operating_point.get("output_speed_deg_s"),
                             load=operating_point.get("load_Nm"))
        out = res.to_dict() if hasattr(res, "to_dict") else dict(res)
        return json.loads(json.dumps(out, default=_jsonable))


    def crack(self, folder: Path, signal, operating_point: dict) -> dict:
        """The crack detector's result for one record (``CrackResult.to_dict()``) with the twin ``folder``'s
        reference at the record's operating point."""
        x = np.asarray(getattr(signal, "data", signal), dtype=np.float64)
        res = self.twin(folder).judge(x, getattr(signal, "fs", None), operating_point.get("output_speed_deg_s"),
                                      operating_point.get("load_Nm"))
        return json.loads(json.dumps(res.to_dict(), default=_jsonable))


def clipped_reason(x: np.ndarray) -> str | None:
    """Why a record looks clipped (a saturated sensor or amplifier), or None: more than :data:`CLIP_SHARE` of its
    samples at its minimum or maximum (within 1e-6 of its range), among more than :data:`CLIP_MIN_LEVELS` distinct
    values.  A healthy record reaches its extremes in a handful of samples; a clipped one sits there.

    >>> t = np.linspace(0, 20, 24000)
    >>> clipped_reason(np.sin(t)) is None, clipped_reason(np.clip(np.sin(t), -0.5, 0.5))[:5]
    (True, '66.0 ')
    """
    x = np.asarray(x, dtype=np.float64).ravel()
    if x.size == 0 or not np.all(np.isfinite(x)):
        return None
    lo, hi = float(x.min()), float(x.max())
    span = hi - lo
    if span <= 0:
        return None  # constant: the monitor's flat check says so
    tol = 1e-6 * span
    share = (np.count_nonzero(x >= hi - tol) + np.count_nonzero(x <= lo + tol)) / x.size
    if share <= CLIP_SHARE or np.unique(x).size <= CLIP_MIN_LEVELS:
        return None
    return (f"{100 * share:.1f} % of the samples sit at the record's extremes ({lo:.4g}, {hi:.4g}): a clipped "
            "(saturated) sensor or amplifier?")


def not_recognised(reason: str, alpha: float | None, operating_point: dict) -> dict:
    """The monitor's answer (``MonitorResult.to_dict()``'s keys) for a record the fleet's own checks refuse."""
    return {"health_index": None, "p_value": None, "alarm": None, "false_alarm_rate": alpha, "threshold": None,
            "state": None, "state_name": None, "probability": None, "probabilities": {}, "changes": [],
            "recognised": False, "reason": reason, "operating_point": operating_point, "warnings": [],
            "n_windows": 0, "windows": []}


def _jsonable(v):
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, Path):
        return str(v)
    raise TypeError(f"not JSON: {type(v).__name__}")
