"""The demo's monitoring step (``make demo``): a baseline-referenced monitor trained on a small paired library and
measured on reducers it never saw (docs/monitoring.md).

Each held-out reducer's later windows are compared with its own commissioning windows at the nearest operating
point (:func:`rvdiag.datasets.store.match_baseline`): what changed in the order spectrum and in the sun's TSA
(:class:`rvdiag.features.relative.BaselineReferencedFeatures`), scored by :class:`rvdiag.models.monitoring.
BaselineMonitor` (health index, alarm at the stated false-alarm rate, most probable state).  The figures are per
window.  The Python API is used directly: ``rvdiag train`` on a paired store is not in this release yet.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _pairs(store, split: str, fx):
    """``(rows of the monitored windows with their metadata, D, labels, reducer ids)`` of one split."""
    from rvdiag.datasets.store import match_baseline
    from rvdiag.features.combine import with_metadata

    d = store.load(split)
    meta = {k: np.asarray(v) for k, v in d.meta.items()}
    base = meta["role"] == "baseline"
    mon_meta = {k: v[~base] for k, v in meta.items()}
    base_meta = {k: v[base] for k, v in meta.items()}
    groups = match_baseline(mon_meta, base_meta, fs=store.attrs["fs"], baseline_fs=store.attrs["fs"])
    cols = fx.input_metadata()
    A = with_metadata(d.X[~base], mon_meta, cols)
    B = with_metadata(d.X[base], base_meta, cols)
    return A, B, groups, np.asarray(d.meta["state"])[~base], mon_meta["reducer"]


def run(library: Path, alpha: float = 0.05) -> dict:
    """Train on the library's training reducers, measure on its test reducers; returns the figures."""
    from rvdiag.datasets import SampleStore
    from rvdiag.features.relative import BaselineReferencedFeatures
    from rvdiag.models.monitoring import BaselineMonitor

    store = SampleStore.open(library)
    fx = BaselineReferencedFeatures(fs=float(store.attrs["fs"]))
    A, B, groups, y, reducer = _pairs(store, "train", fx)
    fx.fit(A)
    monitor = BaselineMonitor(features=fx, alpha=alpha, random_state=0).fit(fx.transform(A, B, groups), y,
                                                                            groups=reducer)
    At, Bt, gt, yt, rt = _pairs(store, "test", fx)
    D = fx.transform(At, Bt, gt)
    alarm, pred = monitor.alarm(D), monitor.predict(D)
    healthy = yt == monitor.healthy
    return {"alpha": alpha, "n_calibration": int(monitor.n_calibration_), "test_reducers": int(np.unique(rt).size),
            "test_windows": int(yt.size), "accuracy": float(np.mean(pred == yt)),
            "detection_rate": float(np.mean(alarm[~healthy])), "false_alarm_rate": float(np.mean(alarm[healthy])),
            "detection_by_state": {s: float(np.mean(alarm[yt == s])) for s in np.unique(yt[~healthy])}}
