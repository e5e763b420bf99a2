"""Judging a record for the fleet: the one place that reads records and calls the monitor
(:func:`rvdiag.monitoring.monitor_record`), with a per-process cache of loaded models and baselines, so that a
watcher or a server pays a model's start-up once, not per record.

:class:`Judge` is what :class:`rvdiag.fleet.store.Fleet` calls; a test may hand the fleet another object with the
same methods (``describe``, ``read``, ``make_baseline``, ``judge``).
"""

from __future__ import annotations

import json
import re
import threading
from dataclasses import asdict, dataclass
from pathlib import Path

from rvdiag.errors import FleetError, ParameterError


@dataclass(frozen=True)
class Reading:
    """How a joint's files are read and where its operating point comes from (the options of ``rvdiag fleet
    commission`` / ``ingest``, the form fields of the HTTP route).

    ``output_speed`` (deg/s at the output) and ``load`` (N m): the record's operating point, else from the file name
    by ``meta_regex`` (named groups ``output_speed_deg_s`` or ``speed_dps``, and ``load_Nm``); the speed may be left
    out, then the monitor measures it from the record.  ``time_regex``: a regular expression on the file name whose
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
        """``{"output_speed_deg_s", "load_Nm"}`` of a file: the given values, else those of :attr:`meta_regex`."""
        speed, load = self.output_speed, self.load
        if self.meta_regex:
            try:
                m = re.search(self.meta_regex, Path(filename).name)
            except re.error as exc:
                raise ParameterError(f"--meta-regex {self.meta_regex!r} is not a regular expression: {exc}") from None
            if m is None:
                raise ParameterError(f"{Path(filename).name}: the name does not match --meta-regex "
                                     f"{self.meta_regex!r}")
            g = m.groupdict()
            try:
                if speed is None and (g.get("output_speed_deg_s") or g.get("speed_dps")):
                    speed = float(g.get("output_speed_deg_s") or g.get("speed_dps"))
                if load is None and g.get("load_Nm"):
                    load = float(g["load_Nm"])
            except ValueError as exc:
                raise ParameterError(f"{Path(filename).name}: --meta-regex gives a value that is not a number "
                                     f"({exc})") from None
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

        res = monitor_record(self.model(monitor), signal, self.baseline(monitor, baseline),
                             output_speed=operating_point.get("output_speed_deg_s"),
                             load=operating_point.get("load_Nm"))
        out = res.to_dict() if hasattr(res, "to_dict") else dict(res)
        return json.loads(json.dumps(out, default=_jsonable))


def _jsonable(v):
    import numpy as np

    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, Path):
        return str(v)
    raise TypeError(f"not JSON: {type(v).__name__}")
