"""The conformal test martingale and the synthetic histories' scale spread on real simulator outputs: the health
index of the healthy records of held-out reducers of a paired monitoring library (issue 35, item 3).

Usage::

    .venv/bin/python bench/prognostics_real.py MONITOR_DIR LIBRARY.zarr [--split test]

e.g. with the demo's library and monitor (``make demo`` or ``rvdiag library build demo-monitoring`` and
``rvdiag train``).  Per held-out reducer, its healthy monitored records' health index in store order is the
joint's stream (no commissioning scores: the index is itself a change against the commissioning records, so the
first record starts the bag).  Prints the per-reducer median index, the spread of log(median index) between
reducers (the synthetic histories draw the reducer's own scale from LogNormal(0, 0.25)), and the martingale's
largest evidence per reducer (alarm at 1/delta).  A paired library has a handful of healthy records per reducer,
so this measures neither the lifetime rate (that needs hundreds of histories of tens of records: a life-history
library, issue 35 item 2) nor more than whether the evidence stays low on real streams.
"""

from __future__ import annotations

import argparse

import numpy as np

from rvdiag.datasets.store import Samples, SampleStore
from rvdiag.monitoring.pairing import (baseline_records, paired_features, per_record, roles, subset,
                                       with_load_column)
from rvdiag.prognostics import ConformalMartingale
from rvdiag.workflows import load_model


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("library")
    ap.add_argument("--split", default="test")
    ap.add_argument("--delta", type=float, default=0.01)
    args = ap.parse_args()
    loaded = load_model(args.model)
    m = loaded.estimator
    store = SampleStore.open(args.library)
    s = store.load(index=store.indices(args.split, []))
    s = subset(s, roles(s, "monitored"))
    s = Samples(X=s.X, y=s.y, meta=with_load_column(s.meta), index=s.index)
    D, _ = paired_features(m.features, s, baseline_records(store), fs=store.fs, baseline_fs=store.fs,
                           card_tolerances=loaded.card.get("baseline"), where=args.library)
    D, y, reducers, _ = per_record(D, s, args.library)
    hi = m.health_index(D)
    healthy = y == str(m.healthy)
    meds, lines = [], []
    for r in np.unique(reducers):
        x = hi[healthy & (reducers == r)]
        meds.append(np.median(x))
        d = ConformalMartingale([], delta=args.delta, seed=0).run(x)
        lines.append(f"  reducer {r}: {x.size} healthy records, median index {np.median(x):.3f}, "
                     f"max evidence {d.statistic.max():.2f} (alarm at {1 / args.delta:g}), "
                     f"index > 1 on {int(np.sum(x > 1))}")
    print(f"{args.library} split {args.split}: {len(meds)} held-out reducers, {int(healthy.sum())} healthy records")
    print("\n".join(lines))
    print(f"sd of log(median healthy index) between reducers: {np.std(np.log(meds), ddof=1):.3f} "
          f"(synthetic histories: 0.25)")


if __name__ == "__main__":
    main()
