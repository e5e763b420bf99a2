"""How far each held-out record of a paired motor-current store lies from the alarm threshold of a monitor trained on
it (``rvdiag train PAIRED.zarr -o MODEL``): the health index (squared Mahalanobis distance over the threshold, > 1
raises the alarm) per state, its smallest and largest, and the records per reducer that fall on the wrong side.

The detection and false-alarm rates themselves are ``rvdiag evaluate MODEL PAIRED.zarr --split test --json``; this
adds the margin, which a rate from a few dozen records cannot show (18 of 18 has a 95 % lower bound of 81 %).
The same records and the same computation as ``evaluate`` (:func:`rvdiag.cli._baseline.paired_features`, one row
per record, :func:`rvdiag.cli._baseline.record_means`), so both agree on every alarm.

Usage: ``python bench/current_monitor.py MODEL PAIRED.zarr [--split test] [--json]``
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from rvdiag.cli._baseline import _baseline_records, _per_record, _roles, _subset, paired_features
from rvdiag.datasets import SampleStore
from rvdiag.models.persistence import load_model


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("store")
    ap.add_argument("--split", default="test")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    m = load_model(args.model).estimator
    store = SampleStore.open(args.store)
    mon = store.load(args.split)
    mon = _subset(mon, _roles(mon, "monitored"))
    D, _ = paired_features(m.features, mon, _baseline_records(store), fs=store.fs, baseline_fs=store.fs)
    D, y, reducers, _ = _per_record(D, mon, args.store)
    hi = m.health_index(D)
    out = {"threshold": float(m.threshold_), "alpha": float(m.alpha), "states": {}}
    for s in sorted(set(y.tolist())):
        k = y == s
        wrong = (hi[k] > 1.0) if s == str(m.healthy) else (hi[k] <= 1.0)
        out["states"][s] = {"records": int(k.sum()), "min": float(hi[k].min()), "median": float(np.median(hi[k])),
                            "max": float(hi[k].max()),
                            "wrong_side_by_reducer": {int(r): int(n) for r, n in
                                                      zip(*np.unique(reducers[k][wrong], return_counts=True))}}
    if args.json:
        print(json.dumps(out))
        return
    print(f"alarm threshold {out['threshold']:.4g} (alpha {out['alpha']:g}); health index = distance / threshold")
    for s, v in out["states"].items():
        side = "alarm raised" if s == str(m.healthy) else "alarm not raised"
        print(f"{s}: {v['records']} records, health index min {v['min']:.3g}, median {v['median']:.3g}, max "
              f"{v['max']:.3g}; {side}, by reducer: {v['wrong_side_by_reducer'] or 'none'}")


if __name__ == "__main__":
    main()
