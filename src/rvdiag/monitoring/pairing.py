"""Pairing monitored records with their baseline: which store is paired, each record's baseline records at the
nearest operating point (:func:`match_baseline`), the baseline-referenced features of the pairs
(:func:`paired_features`) and one row per record (:func:`record_means`).

A paired store (:mod:`rvdiag.datasets.store`, "Paired stores") carries ``reducer`` and ``role`` per sample
(:data:`rvdiag.datasets.store.PAIRED_COLUMNS`); a baseline store of one machine carries only the operating point
(:data:`OPERATING_COLUMNS`).  Everything here takes arrays and metadata mappings; opening stores is
:mod:`rvdiag.monitoring.baseline`.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from rvdiag.datasets.store import PAIRED_COLUMNS, ROLES, Samples
from rvdiag.errors import ParameterError, StoreError

#: the metadata columns a baseline is matched by: the output speed (deg/s) and the load (N m)
OPERATING_COLUMNS = ("output_speed_deg_s", "load_Nm")
#: the metadata column naming a window's record (every store has it): a library's simulation, a file of
#: ``rvdiag dataset from-files``.  A monitor decides a record on the mean change of its windows, as ``diagnose``
#: decides a file, and its alarm is calibrated and scored per record: the windows of one record share its run-to-run
#: variation and are not exchangeable with each other's records
RECORD_COLUMN = "unit"
#: the other spelling of the load column: a store built with ``dataset from-files --meta-regex`` and a group ``load``
#: (not ``load_Nm``) is matched by it, in the unit of its file names (matching compares relative distances)
LOAD_ALIAS = "load"


def with_load_column(meta: Mapping[str, Any]) -> dict:
    """``meta`` with the load column ``load_Nm`` (:data:`OPERATING_COLUMNS`) taken from :data:`LOAD_ALIAS` when it
    has only that spelling: one load for baseline matching, whichever way the store's file names spelled it.

    >>> sorted(with_load_column({"load": [50.0]}))
    ['load', 'load_Nm']
    """
    meta = dict(meta)
    if OPERATING_COLUMNS[1] not in meta and LOAD_ALIAS in meta:
        meta[OPERATING_COLUMNS[1]] = np.asarray(meta[LOAD_ALIAS], dtype=np.float64)
    return meta
#: default tolerances of :func:`match_baseline`: relative distance of the output speed and of the load
SPEED_TOLERANCE = 0.05
LOAD_TOLERANCE = 0.10


def is_paired(meta: Mapping[str, Any]) -> bool:
    """Whether metadata ``meta`` (a store's or a selection's columns) has the paired columns :data:`PAIRED_COLUMNS`
    with both roles present."""
    if not all(c in meta for c in PAIRED_COLUMNS):
        return False
    return set(np.asarray(meta["role"]).astype(str).tolist()) >= set(ROLES)


def _operating_point(meta: Mapping[str, Any], columns: tuple[str, str], where: str) -> np.ndarray:
    missing = [c for c in columns if c not in meta]
    if missing:
        raise ParameterError(f"{where} has no metadata column {missing[0]!r} to match operating points by")
    v = np.column_stack([np.asarray(meta[c], dtype=np.float64) for c in columns])
    if not np.all(np.isfinite(v)) or np.any(v <= 0):
        raise ParameterError(f"{where}: the operating-point columns {list(columns)} must be finite and > 0")
    return v


def match_baseline(monitored: Mapping[str, Any], baseline: Mapping[str, Any], *, fs: float | None = None,
                   baseline_fs: float | None = None, speed_tolerance: float = SPEED_TOLERANCE,
                   load_tolerance: float = LOAD_TOLERANCE,
                   columns: tuple[str, str] = ("output_speed_deg_s", "load_Nm")) -> list[np.ndarray]:
    """Each monitored sample's baseline samples: those of its reducer at the operating point nearest to its own.

    Parameters
    ----------
    monitored, baseline : mappings of metadata columns (e.g. :attr:`Samples.meta`), one row per sample
        Both need the operating-point ``columns`` (output speed, load).  When both have ``reducer``, a monitored
        sample is matched only with baseline samples of the same reducer (a paired store); a baseline without it
        (a healthy store of one machine) serves every monitored sample.
    fs, baseline_fs : sampling rates of the two; refused when they differ (by more than 1e-9 relative).
    speed_tolerance, load_tolerance : float
        Largest relative distance ``|v - v_b| / v_b`` of the speed and of the load.

    Returns
    -------
    list of int arrays, one per monitored sample: row indices into ``baseline``.  The nearest baseline sample
    (by ``max(|dv| / (speed_tolerance v_b), |dL| / (load_tolerance L_b))``) defines the operating point; every baseline
    sample of the reducer within both tolerances of that sample's speed and load belongs to it (the run-to-run
    scatter of the records of one operating point).

    Raises
    ------
    ParameterError
        When the rates differ, or no baseline sample of the reducer lies within the tolerances (the message names
        them and the nearest operating point).
    """
    if fs is not None and baseline_fs is not None and abs(float(fs) - float(baseline_fs)) > 1e-9 * float(fs):
        raise ParameterError(f"the baseline is sampled at {float(baseline_fs):g} Hz, the monitored samples at "
                             f"{float(fs):g} Hz: a baseline must have the same sampling rate")
    if not (speed_tolerance > 0 and load_tolerance > 0):
        raise ParameterError(f"tolerances must be > 0, got speed {speed_tolerance!r} and load {load_tolerance!r}")
    m = _operating_point(monitored, columns, "the monitored data")
    b = _operating_point(baseline, columns, "the baseline")
    tol = np.array([speed_tolerance, load_tolerance], dtype=np.float64)
    paired = "reducer" in monitored and "reducer" in baseline
    mr = np.asarray(monitored["reducer"]) if paired else None
    br = np.asarray(baseline["reducer"]) if paired else None
    out = []
    for i in range(m.shape[0]):
        rows = np.flatnonzero(br == mr[i]) if paired else np.arange(b.shape[0])
        if rows.size == 0:
            raise ParameterError(f"monitored sample {i} (reducer {mr[i]}) has no baseline samples of its reducer")
        dist = np.max(np.abs(m[i] - b[rows]) / (tol * b[rows]), axis=1)
        k = rows[int(np.argmin(dist))]
        if dist.min() > 1.0:
            raise ParameterError(
                f"no baseline within {100 * speed_tolerance:g} % of speed and {100 * load_tolerance:g} % of load of "
                f"sample {i} ({columns[0]} {m[i, 0]:g}, {columns[1]} {m[i, 1]:g}); the nearest is at "
                f"{b[k, 0]:g}, {b[k, 1]:g}")
        near = np.all(np.abs(b[rows] - b[k]) <= tol * b[k], axis=1)
        out.append(rows[near])
    return out


def roles(samples: Samples, role: str) -> np.ndarray:
    """Which samples have ``role`` (all of them when the samples carry no ``role``)."""
    r = samples.meta.get("role")
    return np.ones(len(samples.y), bool) if r is None else np.asarray(r).astype(str) == role


def subset(s: Samples, keep) -> Samples:
    """The samples ``s[keep]`` with their metadata."""
    return Samples(X=s.X[keep], y=s.y[keep], meta={k: v[keep] for k, v in s.meta.items()}, index=s.index[keep])


def baseline_records(store) -> Samples:
    """The ``role == "baseline"`` records of a store (all of a store without roles), loaded."""
    role = store.meta.get("role")
    idx = np.arange(store.n_samples) if role is None else np.flatnonzero(np.asarray(role).astype(str) == "baseline")
    s = store.load(index=idx)
    return Samples(X=s.X, y=s.y, meta=with_load_column(s.meta), index=s.index)


def paired_features(fx, mon: Samples, base: Samples, *, fs, baseline_fs, card_tolerances=None, where="the data"):
    """``D``: each monitored record's change against its baseline records (:func:`match_baseline`, then ``fx``, a
    :class:`rvdiag.features.relative.BaselineReferencedFeatures`).  Refuses a match of one baseline record when
    ``fx`` needs the baseline's own spread (the TSA change).  Returns ``(D, groups)``."""
    from rvdiag.features.combine import with_metadata

    tol = card_tolerances or {}
    groups = match_baseline(mon.meta, base.meta, fs=fs, baseline_fs=baseline_fs,
                            speed_tolerance=float(tol.get("speed_tolerance", SPEED_TOLERANCE)),
                            load_tolerance=float(tol.get("load_tolerance", LOAD_TOLERANCE)),
                            columns=OPERATING_COLUMNS)
    if fx.tsa_change:
        few = [i for i, g in enumerate(groups) if len(g) < 2]
        if few:
            i = few[0]
            raise ParameterError(f"{where}: record {i} has one baseline record at its operating point "
                                 f"({mon.meta['output_speed_deg_s'][i]:g} deg/s, {mon.meta['load_Nm'][i]:g} N m); "
                                 "the TSA change needs >= 2 to know the reducer's run-to-run spread")
    cols = list(fx.input_metadata())
    X = with_metadata(mon.X, mon.meta, cols, where=where)
    used = np.unique(np.concatenate(groups))  # only the matched baseline records: each row's features are its own
    B = with_metadata(base.X[used], {k: np.asarray(v)[used] for k, v in base.meta.items()}, cols,
                      where="the baseline")
    D = fx.transform(X, B, [np.searchsorted(used, g) for g in groups])
    if not np.all(np.isfinite(D)):
        raise ParameterError(f"{where}: the baseline-referenced features are not finite (records shorter than one "
                             "sun revolution, or a flat baseline?)")
    return D, groups


def record_means(D, meta, column: str = RECORD_COLUMN):
    """Each record's mean row of ``D`` (the windows' changes), in the order records first appear.

    Returns ``(means, first, counts)``: ``first`` indexes each record's first window (its label, reducer and
    operating point), ``counts`` its number of windows.  Without ``column`` every window is its own record.

    >>> m, first, n = record_means(np.array([[1.0], [3.0], [5.0]]), {"unit": np.array([7, 7, 2])})
    >>> m.ravel().tolist(), first.tolist(), n.tolist()
    ([2.0, 5.0], [0, 2], [2, 1])
    """
    D = np.asarray(D, dtype=np.float64)
    ids = np.asarray(meta[column]) if column in meta else np.arange(D.shape[0])
    _, first, inv = np.unique(ids, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")  # records in the order they first appear
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    inv = rank[inv.ravel()]
    counts = np.bincount(inv, minlength=order.size)
    means = np.zeros((order.size, D.shape[1]))
    np.add.at(means, inv, D)
    return means / counts[:, None], first[order], counts


def record_ids(meta, column: str = RECORD_COLUMN) -> np.ndarray:
    """The records' ids (metadata ``column``) in the order they first appear: the order of :func:`record_means`'s
    rows.

    >>> record_ids({"unit": np.array([7, 7, 2, 7])}).tolist()
    [7, 2]
    """
    ids = np.asarray(meta[column])
    _, first = np.unique(ids, return_index=True)
    return ids[np.sort(first)]


def per_record(D, s: Samples, where: str):
    """``(means, labels, reducers or None, counts)`` of the records of samples ``s`` (:func:`record_means`); a
    record whose windows carry different labels is refused."""
    means, first, counts = record_means(D, s.meta)
    y = np.asarray(s.y).astype(str)
    ids = np.asarray(s.meta[RECORD_COLUMN]) if RECORD_COLUMN in s.meta else np.arange(y.size)
    mixed = [i for i in np.unique(ids) if np.unique(y[ids == i]).size > 1] if counts.max() > 1 else []
    if mixed:
        raise StoreError(f"{where}: the windows of record {RECORD_COLUMN}={mixed[0]} carry different labels")
    red = np.asarray(s.meta["reducer"])[first] if "reducer" in s.meta else None
    return means, y[first], red, counts


__all__ = ["LOAD_TOLERANCE", "OPERATING_COLUMNS", "PAIRED_COLUMNS", "RECORD_COLUMN", "ROLES", "SPEED_TOLERANCE",
           "baseline_records", "is_paired", "match_baseline", "paired_features", "per_record", "record_ids",
           "record_means", "roles", "subset", "with_load_column"]
