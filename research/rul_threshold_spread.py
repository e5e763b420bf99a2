"""What limits the remaining life on simulated lives: the failure threshold's spread between reducers, the index's
growth with the fault's size, and its record-to-record scatter.

On a built life store and its monitor (``rvdiag library build`` of configs/demo-life.toml or a larger copy,
``rvdiag train``), the monitor scores every record of the train and test splits (cached in ``--cache``), then:

1. **Threshold spread.** The index at the failure time of each train reducer whose history reaches it (the
   population :func:`rvdiag.monitoring.life.learn_threshold` returns): the standard deviation of its log, raw and
   scaled by each reducer's own healthy level (what :func:`rvdiag.prognostics.joint_prognosis` does with
   ``reference_level``).
2. **Index against size.** The exponent gamma of ``HI - phi ~ size^gamma`` over the train wear histories (fixed
   effects per reducer, records between onset and failure whose excess is over 3 phi): the ``size`` model assumes
   gamma = 2 (a squared Mahalanobis distance of features shifted in proportion to the size); and the scatter of
   the log excess about that fit, record to record.
3. **Remaining life on the test split** (``evaluate --life``'s metrics, :func:`rvdiag.prognostics.metrics.life_metrics`)
   with the threshold as (a) the population's median, (b) the population (the product's default), and (c) the
   oracle: each test reducer's own index at its failure time, to tell the threshold's share of the error from the
   trend's.

Usage::

    PYTHONPATH=src python research/rul_threshold_spread.py MODEL_DIR LIFE.zarr [--cache out/rul_records.pkl]
"""

from __future__ import annotations

import argparse
import pickle
from pathlib import Path

import numpy as np

from rvdiag.datasets.store import SampleStore
from rvdiag.monitoring import life as L
from rvdiag.monitoring.pairing import baseline_records
from rvdiag.prognostics.metrics import life_metrics
from rvdiag.workflows import load_model


def scored_records(model_dir, data, cache: Path | None) -> dict:
    """The monitor's health index of every monitored record of the train and test splits (cached)."""
    if cache is not None and cache.exists():
        return pickle.loads(cache.read_bytes())
    loaded = load_model(model_dir)
    store = SampleStore.open(data)
    base, fs, tol = baseline_records(store), store.fs, loaded.card.get("baseline")
    out = {}
    for split in ("train", "test"):
        s = L._monitored(store, split, data)
        out[split] = L._records(loaded.estimator, s, base, fs, fs, tol, f"the store {data}")
        m = store.meta
        _, first = np.unique(np.asarray(m["unit"]), return_index=True)
        size = {(str(m["reducer"][i]), int(m["life.record"][i])): float(m["life.size"][i]) for i in first}
        out[split]["life.size"] = np.array([size.get((str(r), int(k)), np.nan)
                                            for r, k in zip(out[split]["reducer"], out[split]["life.record"])])
    if cache is not None:
        cache.parent.mkdir(parents=True, exist_ok=True)
        cache.write_bytes(pickle.dumps(out))
    return out


def per_history(rec: dict, fate: str):
    """(reducer, days, index, size, onset, failure, healthy level) of each history of ``fate``."""
    for r, rows in L._by_reducer(rec):
        if str(L._first(rec["life.fate"], rows)) != fate:
            continue
        days = np.asarray(rec["life.time_days"], float)[rows]
        hi = np.asarray(rec["health_index"], float)[rows]
        on, fa = L._float(L._first(rec["life.onset_days"], rows)), L._float(L._first(rec["life.failure_days"], rows))
        ok = np.isfinite(hi)
        yield str(r), days, hi, np.asarray(rec["life.size"], float)[rows], on, fa, float(np.median(hi[ok & (days < on)]))


def index_at_failure(days, hi, fa):
    ok = np.isfinite(hi)
    before = np.flatnonzero(ok & (days < fa))
    return float(hi[before[-1]]) if before.size and (ok & (days >= fa)).any() else None


def size_exponent(rec: dict) -> tuple[float, float]:
    """gamma of HI - phi ~ size^gamma over the wear histories of ``rec`` (fixed effects per reducer) and the
    standard deviation of the log excess about that fit (the record-to-record scatter)."""
    x, y, g = [], [], []
    for r, days, hi, size, on, fa, phi in per_history(rec, "wear"):
        ok = np.isfinite(hi) & (size > 0) & (hi - phi > 3 * phi) & (days < fa)
        x += list(np.log(size[ok])); y += list(np.log(hi[ok] - phi)); g += [r] * int(ok.sum())
    x, y, g = np.array(x), np.array(y), np.array(g)
    for k in np.unique(g):
        m = g == k
        x[m] -= x[m].mean(); y[m] -= y[m].mean()
    gamma = float(x @ y / (x @ x))
    return gamma, float(np.std(y - gamma * x, ddof=len(np.unique(g)) + 1))


def rul_figures(out: dict) -> str:
    q = out["pooled"]["rul_models"]["auto"]
    return (f"80 % interval holds the truth {q['rul_coverage_80']['n_met']} of {q['rul_coverage_80']['n']}, "
            f"alpha-lambda {q['alpha_lambda']['n_met']}, median relative error {q['median_relative_error']:.2f}, "
            f"interval width / true life {q['interval_width']:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("data")
    ap.add_argument("--cache", type=Path, default=None)
    a = ap.parse_args()
    rec = scored_records(a.model, a.data, a.cache)
    tr, te = rec["train"], rec["test"]
    for fate in ("wear", "crack"):
        pairs = [(index_at_failure(d, h, fa), phi) for _, d, h, _, _, fa, phi in per_history(tr, fate)]
        v = np.array([(x, p) for x, p in pairs if x is not None])
        if len(v) > 1:
            print(f"{fate}: index at failure over {len(v)} train reducers {np.min(v[:, 0]):.3g}-{np.max(v[:, 0]):.3g}, "
                  f"sd of log raw {np.std(np.log(v[:, 0]), ddof=1):.2f}, scaled by the reducer's healthy level "
                  f"{np.std(np.log(v[:, 0] / v[:, 1]), ddof=1):.2f}")
    gamma, scatter = size_exponent(tr)
    print(f"wear: HI - phi ~ size^gamma over the train histories, gamma = {gamma:.2f} (the size model assumes 2); "
          f"scatter about it: sd of log(HI - phi) {scatter:.2f}")
    th = L.learn_threshold(tr)
    population = L._threshold_map(th)
    median = {k: float(np.median(v)) for k, v in population.items()}
    own = {r: index_at_failure(d, h, fa) for fate in ("wear", "crack")
           for r, d, h, _, _, fa, _ in per_history(te, fate)}
    for name, thr in (("median threshold", median), ("population (default)", population)):
        print(f"test, {name}: " + rul_figures(life_metrics(L.life_histories(te, thr, th["reference_level"], 0))))
    hists = L.life_histories(te, None, None, 0)
    for h in hists:
        h.threshold = own.get(h.name)
    print("test, each reducer's own index at failure (oracle, unscaled): " + rul_figures(life_metrics(hists)))


if __name__ == "__main__":
    main()
