"""A machine's baseline: the healthy commissioning records of one joint, at its operating points, that a monitor
compares every later record with (docs/monitoring.md).

- :func:`open_baseline`: a baseline store (its ``role == "baseline"`` records, or all of a store without roles)
  checked against the model: the reducer type (:func:`reducer_type`), the sampling rate, the record length, one
  machine and the operating-point columns.  Returns a :class:`Baseline` to pass to every
  :func:`rvdiag.monitoring.monitor_record` of that joint.
- :func:`make_baseline`: writes such a store from records (:class:`rvdiag.io.readers.MeasuredSignal`) and their
  operating points, cut into the model's windows, as ``rvdiag dataset from-files`` would.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.monitoring.pairing import OPERATING_COLUMNS, baseline_records

#: the reducer-type fields of a parameter set that a baseline must share with the model
TYPE_FIELDS = {"stage1": ("sun_teeth", "planet_teeth", "n_planets"), "stage2": ("cycloid_lobes", "pins")}


def needs_baseline(loaded) -> bool:
    """Whether a loaded model compares a record with a baseline (card ``needs_baseline``)."""
    return bool(loaded.card.get("needs_baseline"))


def reducer_type(attrs) -> dict | None:
    """The reducer type a store holds: the name and tooth counts of its parameter set (a library's ``params``, or a
    measured store's angle-source parameters, ``config.angle.params``), or None when it states none."""
    params = attrs.get("params")
    if not isinstance(params, dict):
        params = ((attrs.get("config") or {}).get("angle") or {}).get("params")
    if not isinstance(params, dict):
        return None
    out = {"name": params.get("name")}
    for stage, fields in TYPE_FIELDS.items():
        for f in fields:
            out[f] = (params.get(stage) or {}).get(f)
    return out


def teeth(kind: dict) -> dict:
    return {k: v for k, v in kind.items() if k != "name"}


@dataclass
class Baseline:
    """A joint's baseline, opened once (:func:`open_baseline`) and reused for each of its records.

    Attributes
    ----------
    path : Path of the baseline store
    n_records : the number of baseline records (windows of the model's length)
    operating_points : the distinct ``{"output_speed_deg_s", "load_Nm"}`` of the records
    fs : the sampling rate in Hz
    samples : the records (:class:`rvdiag.datasets.store.Samples`), the metadata ``reducer`` dropped
    spectra : what the recognition checks read on the baseline's own windows, kept for its later records
        (:func:`rvdiag.monitoring.diagnosis.baseline_spectrum`): a baseline's records do not change once opened
    """

    path: Path
    n_records: int
    operating_points: list[dict]
    fs: float
    samples: Any = field(repr=False, default=None)
    spectra: dict = field(repr=False, default_factory=dict, compare=False)

    def to_dict(self) -> dict:
        """The baseline's description, JSON-ready."""
        return {"path": str(self.path), "n_records": self.n_records, "operating_points": self.operating_points,
                "fs": self.fs}


def open_baseline_store(path: Path, loaded, fs: float | None):
    """The baseline records of ``path`` (its ``role == "baseline"`` records, or all of a store without roles),
    checked against the model: the reducer type, the sampling rate ``fs`` (the model's), the record length and one
    machine; returns ``(samples, store)``."""
    from rvdiag.datasets import SampleStore

    store = SampleStore.open(path)
    want, got = loaded.card.get("reducer"), reducer_type(store.attrs)
    if want and got and want != got:
        raise ParameterError(f"--baseline {path} is of another reducer type ({got.get('name')}: {got}) than the "
                             f"model's ({want.get('name')}: {want})")
    if fs and store.fs and abs(store.fs - float(fs)) > 1e-9 * float(fs):
        raise ParameterError(f"--baseline {path} is sampled at {store.fs:g} Hz, the model at {float(fs):g} Hz: a "
                             "baseline must have the model's sampling rate")
    if not store.fs:
        raise ParameterError(f"--baseline {path} states no sampling rate: rebuild it with 'rvdiag dataset "
                             "from-files --fs HZ'")
    if store.length != loaded.input_length:
        raise ParameterError(f"--baseline {path} holds records of {store.length} points; the model reads "
                             f"{loaded.input_length}: build it with --window {loaded.input_length}")
    s = baseline_records(store)
    if not len(s.y):
        raise ParameterError(f"--baseline {path} holds no baseline records")
    for c in OPERATING_COLUMNS:
        if c not in s.meta:
            raise ParameterError(f"--baseline {path} has no metadata column {c!r} to match operating points by "
                                 "(build it with 'rvdiag dataset from-files --meta-regex' naming groups speed_dps "
                                 "and load_Nm (or load), or with --angle-channel)")
    return s, store


def open_baseline(path, model) -> Baseline:
    """The baseline store ``path`` checked against the loaded monitor ``model``
    (:func:`rvdiag.workflows.load_model`): the reducer type, the model's sampling rate and record length, the
    operating-point columns, one machine.

    Raises
    ------
    ParameterError, StoreError
        A baseline the model cannot use (the message says why and how to build one it can).
    """
    path = Path(path)
    if not needs_baseline(model):
        raise ParameterError(f"the model {model.path} is not baseline-referenced (its card does not say "
                             "needs_baseline): a baseline applies to a monitor")
    s, store = open_baseline_store(path, model, model.fs)
    if "reducer" in s.meta and len(np.unique(s.meta["reducer"])) > 1:
        raise ParameterError(f"--baseline {path} holds records of several reducers; give one machine's")
    from rvdiag.datasets.store import Samples

    s = Samples(X=s.X, y=s.y, meta={c: v for c, v in s.meta.items() if c != "reducer"}, index=s.index)
    ops = np.column_stack([np.asarray(s.meta[c], dtype=np.float64) for c in OPERATING_COLUMNS])
    points = [dict(zip(OPERATING_COLUMNS, map(float, row))) for row in np.unique(ops, axis=0)]
    return Baseline(path=path, n_records=int(len(s.y)), operating_points=points, fs=float(store.fs), samples=s)


def make_baseline(records: Sequence, *, model, operating_points: Sequence[dict], out) -> Baseline:
    """Write a baseline store of one joint from its healthy commissioning records and open it
    (:func:`open_baseline`).

    Parameters
    ----------
    records : the records (:class:`rvdiag.io.readers.MeasuredSignal`, e.g. of
        :func:`rvdiag.workflows.read_record`), each at least one window of the model's input length; each is cut
        into adjacent windows of that length (the tail is dropped), every window one baseline record
    model : the loaded monitor (:func:`rvdiag.workflows.load_model`)
    operating_points : one ``{"output_speed_deg_s": v, "load_Nm": L}`` per record; a speed None is measured from
        the record as ``diagnose`` measures it (:func:`rvdiag.workflows.records.record_speed`)
    out : path of a new store (zarr), written atomically; an existing path is refused

    Returns
    -------
    Baseline
    """
    from rvdiag.datasets.store import write_store
    from rvdiag.errors import StoreError
    from rvdiag.workflows.records import record_speed

    out = Path(out)
    if out.exists():
        raise StoreError(f"{out} already exists (remove it or choose another path)")
    if not needs_baseline(model):
        raise ParameterError(f"the model {model.path} is not baseline-referenced: a baseline applies to a monitor")
    if not records:
        raise ParameterError("a baseline needs at least one record")
    if len(operating_points) != len(records):
        raise ParameterError(f"{len(records)} records but {len(operating_points)} operating points: give one each")
    L, fs = int(model.input_length), float(model.fs)
    blocks, meta = [], {"split": [], "unit": [], "source": [], "start": [], OPERATING_COLUMNS[0]: [],
                        OPERATING_COLUMNS[1]: []}
    for i, (rec, op) in enumerate(zip(records, operating_points)):
        name = str(getattr(rec, "path", f"record {i}"))
        if not rec.fs or abs(float(rec.fs) - fs) > 1e-9 * fs:
            raise ParameterError(f"{name} is sampled at {rec.fs} Hz, the model at {fs:g} Hz")
        x = np.asarray(rec.data, dtype=np.float64)
        k = x.size // L
        if k < 1:
            raise ParameterError(f"{name} has {x.size} points, shorter than one window of {L} points (the model's "
                                 "input length)")
        load = op.get(OPERATING_COLUMNS[1])
        if load is None or not float(load) > 0:
            raise ParameterError(f"{name}: the operating point needs a load_Nm > 0, got {load!r}")
        speed = op.get(OPERATING_COLUMNS[0])
        if speed is None:
            got = record_speed(rec, getattr(rec, "metadata", None))
            if got.get("output_speed_deg_s") is None:
                raise ParameterError(f"{name}: the speed is needed for a baseline: {got.get('error')}")
            speed = got["output_speed_deg_s"]
        blocks.append(x[: k * L].reshape(k, L))
        meta["split"] += ["train"] * k
        meta["unit"] += [i] * k
        meta["source"] += [Path(name).name] * k
        meta["start"] += list(range(0, k * L, L))
        meta[OPERATING_COLUMNS[0]] += [float(speed)] * k
        meta[OPERATING_COLUMNS[1]] += [float(load)] * k
    X = np.concatenate(blocks).astype(np.float32)
    kind = model.card.get("reducer")
    attrs = {}
    if kind:
        attrs["params"] = {"name": kind.get("name"),
                           **{stage: {f: kind.get(f) for f in fields} for stage, fields in TYPE_FIELDS.items()}}
    write_store(out, X, ["T1"] * X.shape[0], {k: np.asarray(v) for k, v in meta.items()}, kind="measured", fs=fs,
                config={"baseline": {"n_records": len(records), "window": L}}, extra_attrs=attrs)
    return open_baseline(out, model)


__all__ = ["Baseline", "TYPE_FIELDS", "make_baseline", "needs_baseline", "open_baseline", "reducer_type"]
