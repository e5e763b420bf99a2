"""A baseline monitor over simulated lives: ``rvdiag evaluate MONITOR LIFE.zarr --life`` (:func:`evaluate_life`).

A life store (``rvdiag library build life``; its columns :data:`rvdiag.library.life.LIFE_COLUMNS`) records each reducer at commissioning
and then every ``interval_days`` over one drawn fate.  Each held-out reducer's monitored records, in ``life.record``
order, get the monitor's health index against the reducer's own commissioning records (the store's baseline
records, matched at the nearest operating point as :func:`rvdiag.monitoring.evaluate_monitor` matches them) and its
most probable state; the history is then scored as the fleet watches a joint (:mod:`rvdiag.prognostics.metrics`):

- the change detector is the conformal test martingale of :func:`rvdiag.prognostics.joint_prognosis`, with the
  fleet's ranking pool: the commissioning records have no index against themselves, so the joint's first monitored
  records fill it (:func:`rvdiag.fleet.store.prognosis_of`);
- the remaining life is the product's: the model the monitor's state at the prediction names
  (:func:`rvdiag.prognostics.model_for_state`; a broken tooth: not estimated), linear extrapolation beside it;
- a record with a sensor fault (``life.sensor_fault`` not empty) is left out, as the fleet leaves out a record it
  does not recognise; it is not scored as a fault (this takes the fleet's recognition checks to catch every
  drawn sensor fault).

The failure threshold on the index (:func:`learn_threshold`) is learned from the ``train`` split's reducers of the
same store: for each fault state, the index of their last recognised record before ``life.failure_days`` of each
training reducer of that fate whose history reaches its failure time; ``*`` (any other state the monitor names)
pools all of them.  The index at failure varies between reducers (each has its own sensitivity to the fault: on
configs/demo-life.toml the standard deviation of its log is about 0.3, a factor 1.35), so the remaining life draws the
threshold from that population (:func:`rvdiag.prognostics.joint_prognosis`), not from its median alone; the output
gives the median (``index``) and the values.  Its reference level is the median index of the training reducers'
records before their onset, so that :func:`rvdiag.prognostics.joint_prognosis` scales the threshold to each joint's
own healthy level.  Both are in the output (``threshold``).
"""

from __future__ import annotations

import numpy as np

from rvdiag.datasets.store import Samples
from rvdiag.errors import ParameterError, StoreError
from rvdiag.monitoring.baseline import reducer_type
from rvdiag.monitoring.pairing import (baseline_records, is_paired, paired_features, per_record, record_ids, roles,
                                       subset, with_load_column)

#: the life columns :func:`evaluate_life` reads (``life.sensor_fault`` absent: no sensor faults)
NEEDED_COLUMNS = ("life.record", "life.time_days", "life.fate", "life.onset_days", "life.failure_days")
SENSOR_FAULT = "life.sensor_fault"


def fault_state(fate: str) -> str | None:
    """A fate's fault state at its onset (:data:`rvdiag.library.life.FATE_STATES`: a crack is T4 until it breaks
    the tooth), the key of the per-state figures; None for a healthy reducer.

    >>> fault_state("crack"), fault_state("healthy")
    ('T4', None)
    """
    from rvdiag.library.life import FATE_STATES

    return None if fate == "healthy" else FATE_STATES.get(fate, (fate,))[0]


def is_life_store(meta) -> bool:
    """Whether a store's metadata has the life columns :func:`evaluate_life` needs."""
    return all(c in meta for c in NEEDED_COLUMNS)


def sensor_faulty(meta) -> np.ndarray:
    """Which samples carry a sensor fault (``life.sensor_fault`` not empty; none without the column)."""
    n = len(next(iter(meta.values()))) if meta else 0
    if SENSOR_FAULT not in meta:
        return np.zeros(n, bool)
    v = np.asarray(meta[SENSOR_FAULT]).astype(str)
    return (v != "") & (v != "nan") & (v != "None")


def check_life_store(store, data) -> None:
    """Refuse a store without the life columns or without commissioning records (one line, exit 2 in the CLI)."""
    if not is_life_store(store.meta):
        missing = [c for c in NEEDED_COLUMNS if c not in store.meta]
        raise ParameterError(f"--life: {data} has no life-history columns ({', '.join(missing)}): build a life "
                             "store with 'rvdiag library build life'")
    if not is_paired(store.meta):
        raise ParameterError(f"--life: {data} has no commissioning (role 'baseline') records to score against")


def _records(m, s: Samples, base: Samples, fs, bfs, tolerances, where: str, scored=None) -> dict:
    """One row per monitored record of ``s``: reducer, record, time, truth, the monitor's health index and most
    probable state (NaN / "" for a record with a sensor fault, not scored).  ``scored``: ``(record ids, rows)`` of
    the records without a sensor fault, already computed (:func:`rvdiag.monitoring.training.record_rows`)."""
    faulty = sensor_faulty(s.meta)
    units = np.asarray(s.meta["unit"])
    _, first = np.unique(units, return_index=True)
    first = np.sort(first)                               # each record's first window, in store order
    ids = units[first]
    rec = {k: np.asarray(s.meta[k])[first] for k in ("reducer", *NEEDED_COLUMNS)}
    rec["label"] = np.asarray(s.y).astype(str)[first]
    rec["sensor_fault"] = faulty[first]
    rec["health_index"] = np.full(first.size, np.nan)
    rec["state"] = np.full(first.size, "", dtype=object)
    ok = ~faulty
    if ok.any():
        if scored is None:
            good = subset(s, ok)
            means, _, _, _ = per_record(paired_features(m.features, good, base, fs=fs, baseline_fs=bfs,
                                                        card_tolerances=tolerances, where=where)[0], good, where)
            scored = (record_ids(good.meta), means)
        order, means = scored
        pos = {u: i for i, u in enumerate(ids)}
        at = np.array([pos[u] for u in order])
        rec["health_index"][at] = m.health_index(means)
        rec["state"][at] = m.predict(means).astype(str)
    return rec


def _by_reducer(rec: dict):
    """``(reducer, rows in life.record order)`` for each reducer, in reducer order."""
    red = rec["reducer"]
    for r in np.unique(red):
        rows = np.flatnonzero(red == r)
        yield r, rows[np.argsort(np.asarray(rec["life.record"])[rows], kind="stable")]


def _first(values, rows):
    v = np.asarray(values)[rows]
    return v[0] if v.size else None


def _float(x) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return float("nan")


def learn_threshold(rec: dict) -> dict:
    """The failure threshold on the index and its reference level from the training reducers' records ``rec``
    (module docstring).  Returns ``{"per_state": {state: {"fate", "index", "n_reducers"}}, "*": {...},
    "reference_level", "source"}``, each state with ``index`` (the median), ``values`` and ``n_reducers``; ``index``
    None where no training reducer of that fate reaches failure."""
    at_failure: dict[str, list[float]] = {}
    healthy: list[float] = []
    for _, rows in _by_reducer(rec):
        days = np.asarray(rec["life.time_days"], dtype=float)[rows]
        hi = np.asarray(rec["health_index"], dtype=float)[rows]
        fate = str(_first(rec["life.fate"], rows))
        onset, failure = _float(_first(rec["life.onset_days"], rows)), _float(_first(rec["life.failure_days"], rows))
        ok = np.isfinite(hi)
        healthy += hi[ok & ((days < onset) if np.isfinite(onset) else True)].tolist()
        if fate == "healthy" or fate == "broken" or not np.isfinite(failure) or not (ok & (days >= failure)).any():
            continue                       # no growth to a failure, or the history ends before it
        before = np.flatnonzero(ok & (days < failure))
        if before.size:
            at_failure.setdefault(fate, []).append(float(hi[before[-1]]))
    per_state = {fault_state(f): {"fate": f, "index": float(np.median(v)), "n_reducers": len(v), "values": v}
                 for f, v in sorted(at_failure.items())}
    pooled = [x for v in at_failure.values() for x in v]
    return {"per_state": per_state,
            "*": {"index": float(np.median(pooled)) if pooled else None, "n_reducers": len(pooled),
                  "values": pooled},
            "reference_level": float(np.median(healthy)) if healthy else None,
            "source": "the train split's reducers of this store: per fault state, the health index of the last "
                      "recognised record before life.failure_days of each reducer of that fate whose history reaches "
                      "its failure time (values; index: their median; '*': over all fates, for any other state the "
                      "monitor names); the remaining life draws the threshold from the values; reference_level: the "
                      "median index of their records before onset"}


def _threshold_map(t: dict) -> dict | None:
    """State -> the training reducers' indices at failure (the population the remaining life draws from)."""
    out = {s: tuple(v["values"]) for s, v in t["per_state"].items()}
    if t["*"]["values"]:
        out["*"] = tuple(t["*"]["values"])
    return out or None


def life_histories(rec: dict, threshold: dict | None, reference_level: float | None, seed: int = 0):
    """One :class:`rvdiag.prognostics.metrics.LifeHistory` per reducer of the records ``rec``."""
    from rvdiag.prognostics.metrics import LifeHistory

    out = []
    for i, (r, rows) in enumerate(_by_reducer(rec)):
        fate = str(_first(rec["life.fate"], rows))
        out.append(LifeHistory(
            days=np.asarray(rec["life.time_days"], dtype=float)[rows],
            score=np.asarray(rec["health_index"], dtype=float)[rows], fate=fate,
            onset_days=_float(_first(rec["life.onset_days"], rows)),
            failure_days=_float(_first(rec["life.failure_days"], rows)),
            state=fault_state(fate), baseline_scores=(),
            threshold=threshold, reference_level=reference_level,
            predicted_state=np.asarray(rec["state"]).astype(str)[rows],
            sensor_fault=np.asarray(rec["sensor_fault"], dtype=bool)[rows],
            true_state=np.asarray(rec["label"]).astype(str)[rows], seed=seed + i, name=str(r)))
    return out


def _monitored(store, split: str, data) -> Samples:
    s = store.load(index=store.indices(split))
    s = subset(s, roles(s, "monitored"))
    return Samples(X=s.X, y=s.y, meta=with_load_column(s.meta), index=s.index)


def evaluate_life(loaded, store, data, split: str = "test", *, seed: int = 0, scored=None) -> dict:
    """Change detection and remaining life over the lives of ``split``'s reducers of the life store ``store``
    (module docstring), per reducer and pooled: :func:`rvdiag.prognostics.metrics.life_metrics`'s figures
    (``lifetime_false_alarm``, ``detection_delay_records``, ``detected_within_3``, ``rul_coverage_80``,
    ``alpha_lambda``, ``baseline``) with the ``threshold`` they used and ``split``.  ``scored``: ``(record ids,
    rows)`` of the split's monitored records without a sensor fault, when :func:`rvdiag.monitoring.evaluate_monitor`
    has computed them (their change against the commissioning records is not computed twice).

    Raises
    ------
    ParameterError
        When the store has no life columns, or is not paired.
    """
    from rvdiag.prognostics.metrics import life_metrics

    check_life_store(store, data)
    want, got = loaded.card.get("reducer"), reducer_type(store.attrs)
    if want and got and want != got:
        raise ParameterError(f"{data} holds a reducer of another type ({got}) than the model's ({want})")
    m = loaded.estimator
    base, fs = baseline_records(store), store.fs
    tol = loaded.card.get("baseline")
    where = f"the store {data}"
    test = _monitored(store, split, data)
    if not len(test.y):
        raise StoreError(f"the split {split!r} of {data} holds no monitored records")
    rec = _records(m, test, base, fs, fs, tol, where, scored)
    train_split = "train" if split != "train" else None
    threshold = {"per_state": {}, "*": {"index": None, "n_reducers": 0, "values": []}, "reference_level": None,
                 "source": "no train split to learn it from: the remaining life is not estimated"}
    if train_split and train_split in store.splits():
        tr = _monitored(store, train_split, data)
        if len(tr.y):
            threshold = learn_threshold(_records(m, tr, base, fs, fs, tol, where))
    hists = life_histories(rec, _threshold_map(threshold), threshold["reference_level"], seed)
    out = life_metrics(hists)
    out["threshold"] = threshold
    out["split"] = split
    out["settings"]["ranking_pool"] = ("the reducer's own monitored records in life.record order (the fleet's: "
                                       "commissioning records have no index against themselves)")
    out["settings"]["sensor_faults"] = "records with life.sensor_fault are left out, as the fleet leaves them out"
    return out


__all__ = ["check_life_store", "evaluate_life", "fault_state", "is_life_store", "learn_threshold", "life_histories",
           "sensor_faulty"]
