"""The health index of a monitor's held-out records against the size of each fault (docs/monitoring.md,
"Severity and the index" and "At a 10 dB floor").

For every monitored record of a paired store's ``test`` split, the index ``BaselineMonitor.health_index`` of its
windows' mean change against its reducer's baseline, formed as ``rvdiag evaluate`` forms it
(``rvdiag.monitoring.pairing.paired_features``, ``record_means``).  Prints, as JSON: Spearman's rank correlation of the
index with each severity column per state; the false alarms of each held-out reducer (alarms, healthy records);
and each T2 / T3 / T4 record as (severity, index, alarm), sorted by severity.

Usage::

    PYTHONPATH=src python research/monitor_trend.py MODEL_DIR PAIRED.zarr > trend.json
"""

from __future__ import annotations

import json
import sys

import numpy as np
from scipy.stats import spearmanr

from rvdiag.monitoring import pairing as B
from rvdiag.datasets import SampleStore
from rvdiag.models.persistence import load_model

SEVERITY = {"T2": "broken_fraction", "T3": "wear_depth", "T4": "crack_depth"}


def main(model: str, path: str) -> dict:
    loaded = load_model(model)
    m = loaded.estimator
    store = SampleStore.open(path)
    s = store.load(index=store.indices("test", ()))
    s = B.subset(s, B.roles(s, "monitored"))
    D, _ = B.paired_features(m.features, s, B.baseline_records(store), fs=store.fs, baseline_fs=store.fs,
                             card_tolerances=loaded.card.get("baseline"))
    means, first, _ = B.record_means(D, s.meta)
    y = np.asarray(s.y).astype(str)[first]
    meta = {k: np.asarray(v)[first] for k, v in s.meta.items()}
    index, alarm = m.health_index(means), m.alarm(means)
    out: dict = {}
    for col in ("crack_depth", "broken_fraction", "wear_depth"):
        if col not in meta:
            continue
        v = meta[col].astype(float)
        for state in sorted(set(y)):
            k = (y == state) & np.isfinite(v) & (v > 0)
            if k.sum() >= 5:
                r = spearmanr(v[k], index[k])
                out[f"spearman_{state}_{col}"] = [round(float(r.statistic), 3), float(r.pvalue), int(k.sum())]
    healthy, red = y == "T1", meta["reducer"]
    out["fa_per_reducer"] = {int(r): [int(alarm[healthy & (red == r)].sum()), int((healthy & (red == r)).sum())]
                             for r in np.unique(red[healthy])}
    for state, col in SEVERITY.items():
        k = y == state
        out[f"{state}_records"] = sorted([round(float(v), 6), round(float(i), 2), bool(a)]
                                         for v, i, a in zip(meta[col][k], index[k], alarm[k]))
    out["healthy_index_median"] = float(np.median(index[healthy]))
    out["t4_index_median"] = float(np.median(index[y == "T4"])) if (y == "T4").any() else None
    return out


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    print(json.dumps(main(sys.argv[1], sys.argv[2]), indent=1))
