#!/usr/bin/env python
"""Prediction sets on a reducer nobody trained on: the calibration rules compared on the same scores.

The coverage a conformal set states holds for a new sample exchangeable with the calibration samples.  The
sets of ``rvdiag train`` are judged on new *reducers* (groups of windows): the held-out reducers of a library's
test split and the rig of bench/hidden_rig.py (each state its own reducer).  This bench keeps the calibration
scores of one training run and recomputes the thresholds by each rule of :data:`RULES` (the window-pooled default
and the hierarchical ``rule="reducers"`` of :mod:`rvdiag.models.conformal`, Dunn et al.'s subsampling and a
reducer-level tolerance rule), so every rule is judged on the same network and the same probabilities:

``capture STORE MODEL``
    trains the default model on STORE exactly as ``rvdiag train STORE --out MODEL --seed S`` does
    (:func:`rvdiag.workflows.training.train`, ``--calibration cross`` by default), and keeps the probabilities its
    calibration used (every training window scored by the fold model that never saw its reducer), their labels
    and reducers in ``MODEL/calibration_scores.npz``;
``compare MODEL EVAL [EVAL ...]``
    scores each evaluation store with the model (``STORE`` its test split, or ``STORE:all`` every row with each
    state its own reducer, as the rig), and gives per rule and store the coverage and mean size per window,
    overall and per state, and the within-reducer coverage (each evaluated reducer's share of windows whose set
    holds its state): the guarantee a user of one reducer reads.

Usage::

    python bench/set_coverage.py capture OUT/transfer.zarr OUT/model-cap --seed 0
    python bench/set_coverage.py compare OUT/model-cap OUT/rig.zarr:all OUT/transfer.zarr --json OUT/sets.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

SCORES = "calibration_scores.npz"


def capture(store: Path, model: Path, seed: int = 0) -> dict:
    """Train as ``rvdiag train`` does and keep the calibration's probabilities, labels and reducers."""
    from rvdiag.models import conformal
    from rvdiag.workflows.training import train

    kept = {}
    original = conformal.PredictionSets.calibrate.__func__

    def recording(cls, proba, y, classes, coverage=None, groups=None, source=None, **kw):
        kept.update(P=np.asarray(proba, float), y=np.asarray(y).astype(str),
                    g=np.asarray(groups).astype(str), classes=np.asarray(classes).astype(str))
        return original(cls, proba, y, classes, coverage, groups=groups, source=source, **kw)

    conformal.PredictionSets.calibrate = classmethod(recording)
    try:
        res = train(store, model, seed=seed, echo=lambda m: print(m, flush=True))
    finally:
        conformal.PredictionSets.calibrate = classmethod(original)
    np.savez(model / SCORES, **kept)
    return {"model": str(model), "n_calibration": int(kept["y"].size), "metrics": res.metrics}


def _evaluation(model: Path, spec: str):
    """Probabilities, labels and reducers of an evaluation store (``PATH`` its test split, ``PATH:all`` every row,
    each state its own reducer)."""
    from rvdiag.datasets import SampleStore
    from rvdiag.evaluation.evaluate import predict_in_chunks
    from rvdiag.models.persistence import load_model

    path, _, what = spec.partition(":")
    store = SampleStore.open(path)
    rows = np.arange(len(store.label_names)) if what == "all" else store.indices("test")
    s = store.load(index=rows)
    loaded = load_model(model)
    P = predict_in_chunks(loaded.estimator, loaded.inputs(s.X, s.meta), method="predict_proba").astype(float)
    y = np.asarray(s.y).astype(str)
    g = y.copy() if what == "all" else np.asarray(s.meta["unit"]).astype(str)
    return P, y, g


def within_group(inside, y, g, classes) -> dict:
    """Each class's within-reducer coverage: min, median and mean over its reducers of the share of their windows
    whose set holds the class."""
    col = {c: i for i, c in enumerate(classes)}
    out = {}
    for c in classes:
        cov = [float(inside[(y == c) & (g == u), col[c]].mean()) for u in np.unique(g[y == c])]
        if cov:
            out[c] = {"reducers": len(cov), "min": min(cov), "median": float(np.median(cov)),
                      "mean": float(np.mean(cov))}
    return out


def windows_threshold(s, g, alpha):
    """The window-pooled rule: the ceil((n + 1)(1 - alpha))-th smallest of the n window scores (every window one
    exchangeable sample)."""
    from rvdiag.models.conformal import conformal_threshold

    return conformal_threshold(s, alpha)


def reducers_threshold(s, g, alpha):
    """Hierarchical conformal (Lee, Barber & Willett 2023): :func:`rvdiag.models.conformal.reducer_threshold`."""
    from rvdiag.models.conformal import reducer_threshold

    return reducer_threshold(s, g, alpha)


def subsample_threshold(s, g, alpha, draws=1000, seed=0):
    """Repeated subsampling (Dunn, Wasserman & Ramdas 2023): one window drawn per reducer, the conformal
    threshold of those K scores; the set of the majority of ``draws`` draws = the median threshold."""
    from rvdiag.models.conformal import conformal_threshold

    rng = np.random.default_rng(seed)
    names, inv = np.unique(g, return_inverse=True)
    members = [np.flatnonzero(inv == k) for k in range(names.size)]
    qs = [conformal_threshold(s[[m[rng.integers(m.size)] for m in members]], alpha) for _ in range(draws)]
    return float(np.median(qs))


def single_subsample_threshold(s, g, alpha, seed=0):
    """Single subsampling (Dunn et al. 2023): one window per reducer, conformal threshold of those K scores."""
    return subsample_threshold(s, g, alpha, draws=1, seed=seed)


def tolerance_threshold(s, g, alpha):
    """Reducer-level tolerance: each reducer's own (1 - alpha) score quantile, and the conformal threshold of those
    K values at 1 - alpha (a new exchangeable reducer then has its windows covered at >= 1 - alpha with
    probability >= 1 - alpha)."""
    from rvdiag.models.conformal import conformal_threshold

    names, inv = np.unique(g, return_inverse=True)
    per = [np.sort(s[inv == k])[max(0, int(np.ceil((inv == k).sum() * (1 - alpha))) - 1)] for k in range(names.size)]
    return conformal_threshold(np.asarray(per), alpha)


RULES = {"windows": windows_threshold, "reducers": reducers_threshold, "subsample1": single_subsample_threshold,
         "subsample": subsample_threshold, "tolerance": tolerance_threshold}


def calibrated(rule, P, y, g, classes, cover):
    from rvdiag.models.conformal import PredictionSets, lac_scores

    s = lac_scores(P, y, classes)
    th = {c: RULES[rule](s[y == c], g[y == c], 1.0 - cover[c]) for c in classes}
    return PredictionSets(classes, dict(cover), th, {c: int((y == c).sum()) for c in classes})


def one_reducer_per_state(inside, y, g, classes, draws: int = 100_000, seed: int = 0) -> dict | None:
    """What a rig of one reducer per state would read: the overall coverage (the mean of the states' within-reducer
    coverages, equal windows per state as on the rig) of ``draws`` rigs drawn from the evaluated reducers, one of each
    state (``numpy.random.default_rng(seed)``): its mean, 5 and 95 % quantiles and the share of rigs within 3 points
    of the stated coverage; None where the store has one reducer per state."""
    col = {c: i for i, c in enumerate(classes)}
    per = []
    for c in classes:
        names = np.unique(g[y == c])
        if names.size < 2:
            return None
        per.append(np.asarray([inside[(y == c) & (g == u), col[c]].mean() for u in names]))
    rng = np.random.default_rng(seed)
    cov = np.mean([p[rng.integers(p.size, size=draws)] for p in per], axis=0)
    return {"mean": float(cov.mean()), "q05": float(np.quantile(cov, 0.05)), "q95": float(np.quantile(cov, 0.95)),
            "sd": float(cov.std())}


def compare(model: Path, evals: list[str]) -> dict:
    from rvdiag.models.conformal import from_card, set_metrics
    from rvdiag.models.persistence import read_card

    z = np.load(model / SCORES)
    classes = [str(c) for c in z["classes"]]
    stored = from_card(read_card(model))
    cover = stored.coverage
    data = {spec: _evaluation(model, spec) for spec in evals}
    out = {"model": str(model), "n_calibration": int(z["y"].size),
           "calibration_reducers": {c: int(np.unique(z["g"][z["y"] == c]).size) for c in classes},
           "card_rule": stored.rule, "card_reproduced": bool(all(
               calibrated(stored.rule, z["P"], z["y"], z["g"], classes, cover).thresholds[c] == stored.thresholds[c]
               for c in classes)), "rules": {}}
    for rule in RULES:
        ps = calibrated(rule, z["P"], z["y"], z["g"], classes, cover)
        # the calibration reducers' own within-reducer coverage (cross scores: each by a model that never saw it)
        lib = within_group(ps.contains(z["P"]), z["y"], z["g"], classes)
        r = {"thresholds": ps.thresholds, "calibration_within_reducer": lib}
        for spec, (P, y, g) in data.items():
            inside = ps.contains(P)
            m = set_metrics(inside, y, classes, cover)
            r[spec] = {"coverage": m["coverage"], "stated": m["stated_coverage"], "mean_size": m["mean_size"],
                       "singletons": m["singletons"],
                       "per_state": {c: (v["coverage"], v["mean_size"]) for c, v in m["per_state"].items()},
                       "within_reducer": within_group(inside, y, g, classes),
                       "rigs_of_one_reducer_per_state": one_reducer_per_state(inside, y, g, classes)}
        out["rules"][rule] = r
    return out


def _table(res: dict) -> str:
    lines = []
    for rule, r in res["rules"].items():
        for spec, v in r.items():
            if spec in ("thresholds", "calibration_within_reducer"):
                continue
            per = " ".join(f"{c} {100 * cv:.1f}" for c, (cv, _) in v["per_state"].items())
            rigs = v["rigs_of_one_reducer_per_state"]
            spread = "" if rigs is None else (f" | rigs of one reducer a state: 90 % between {100 * rigs['q05']:.1f}"
                                              f" and {100 * rigs['q95']:.1f} (sd {100 * rigs['sd']:.1f})")
            lines.append(f"{rule:>10} {spec:>40}: {100 * v['coverage']:.1f} % of {100 * v['stated']:.1f} %, "
                         f"size {v['mean_size']:.2f} | {per}{spread}")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("capture")
    c.add_argument("store", type=Path)
    c.add_argument("model", type=Path)
    c.add_argument("--seed", type=int, default=0)
    m = sub.add_parser("compare")
    m.add_argument("model", type=Path)
    m.add_argument("evals", nargs="+")
    m.add_argument("--json", type=Path, default=None)
    a = ap.parse_args()
    if a.cmd == "capture":
        print(json.dumps(capture(a.store, a.model, a.seed), indent=1, default=float))
        return
    res = compare(a.model, a.evals)
    print(_table(res))
    if a.json is not None:
        a.json.write_text(json.dumps(res, indent=1, default=float))


if __name__ == "__main__":
    main()
