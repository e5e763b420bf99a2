"""How far each held-out record of a paired motor-current store lies from the alarm threshold of a monitor trained on
it (``rvdiag train PAIRED.zarr -o MODEL``): the health index (squared Mahalanobis distance over the threshold, > 1
raises the alarm) per state, its smallest and largest, and the records per reducer that fall on the wrong side.

The detection and false-alarm rates themselves are ``rvdiag evaluate MODEL PAIRED.zarr --split test --json``; this
adds the margin, which a rate from a few dozen records cannot show (18 of 18 has a 95 % lower bound of 81 %).
The same records and the same computation as ``evaluate`` (:func:`rvdiag.monitoring.pairing.paired_features`, one row
per record, :func:`rvdiag.monitoring.pairing.record_means`), so both agree on every alarm.

With ``--pair K`` (a ``current-lines`` monitor) it also gives, per joint, the level of its own f_e +- K f1 pair in its
baseline records (log10 over the supply line, the mean of the two lines) and the mean change of that pair over its
broken-tooth (T2) records, the joints ranked by level, the median level, and the correlation of the two across
the joints.

Usage: ``python bench/current_monitor.py MODEL PAIRED.zarr [--split test] [--pair K] [--json]``
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from rvdiag.monitoring.pairing import baseline_records, paired_features, per_record, roles, subset
from rvdiag.datasets import SampleStore
from rvdiag.models.persistence import load_model


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("store")
    ap.add_argument("--split", default="test")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--pair", type=int, default=None, help="also the f_e +- K f1 pair per joint (current-lines)")
    args = ap.parse_args()
    m = load_model(args.model).estimator
    store = SampleStore.open(args.store)
    mon = store.load(args.split)
    mon = subset(mon, roles(mon, "monitored"))
    D, _ = paired_features(m.features, mon, baseline_records(store), fs=store.fs, baseline_fs=store.fs)
    D, y, reducers, _ = per_record(D, mon, args.store)
    hi = m.health_index(D)
    out = {"threshold": float(m.threshold_), "alpha": float(m.alpha), "states": {}}
    for s in sorted(set(y.tolist())):
        k = y == s
        wrong = (hi[k] > 1.0) if s == str(m.healthy) else (hi[k] <= 1.0)
        out["states"][s] = {"records": int(k.sum()), "min": float(hi[k].min()), "median": float(np.median(hi[k])),
                            "max": float(hi[k].max()),
                            "wrong_side_by_reducer": {int(r): int(n) for r, n in
                                                      zip(*np.unique(reducers[k][wrong], return_counts=True))}}
    if args.pair is not None:
        out["pair"] = _pair(args.pair, m, store, D, y, reducers)
    if args.json:
        print(json.dumps(out))
        return
    print(f"alarm threshold {out['threshold']:.4g} (alpha {out['alpha']:g}); health index = distance / threshold")
    for s, v in out["states"].items():
        side = "alarm raised" if s == str(m.healthy) else "alarm not raised"
        print(f"{s}: {v['records']} records, health index min {v['min']:.3g}, median {v['median']:.3g}, max "
              f"{v['max']:.3g}; {side}, by reducer: {v['wrong_side_by_reducer'] or 'none'}")
    if "pair" in out:
        p = out["pair"]
        print(f"f_e +- {args.pair} f1 per joint (level in its baseline, decades over f_e; mean change of its T2 "
              f"records), by level: " + ", ".join(f"{r} {lv:.2f} / {c:+.2f}" for r, lv, c in p["by_level"]))
        print(f"median level {p['median_level']:.2f}; correlation of level and change across "
              f"{len(p['by_level'])} joints {p['correlation']:.2f}")


def _pair(k: int, m, store, D, y, reducers) -> dict:
    """Per joint: its baseline level of the f_e +- k f1 pair and the mean change of its T2 records (module doc)."""
    names = [f"d_log10_fe-{k}f1_over_fe", f"d_log10_fe+{k}f1_over_fe"]
    all_names = list(m.features.get_feature_names_out())
    if not all(n in all_names for n in names):
        raise SystemExit(f"error: --pair {k} needs a current-lines monitor with the f_e +- {k} f1 lines")
    cols = [all_names.index(n) for n in names]
    inner = m.features.features_
    base = baseline_records(store)
    Fb = inner.transform(base.X)[:, [list(inner.get_feature_names_out()).index(n[2:]) for n in names]].mean(axis=1)
    rb = np.asarray(base.meta["reducer"])
    rows = []
    for r in np.unique(reducers[y == "T2"]):
        rows.append((int(r), float(Fb[rb == r].mean()), float(D[(reducers == r) & (y == "T2")][:, cols].mean())))
    rows.sort(key=lambda t: -t[1])
    lv, ch = np.array([t[1] for t in rows]), np.array([t[2] for t in rows])
    return {"by_level": rows, "median_level": float(np.median(lv)),
            "correlation": float(np.corrcoef(lv, ch)[0, 1]) if len(rows) > 2 else float("nan")}


if __name__ == "__main__":
    main()
