#!/usr/bin/env python
"""Prediction sets on held-out reducers (rvdiag.models.conformal): coverage and size per state, beside accuracy,
per-class recall and false-alarm rate; the same calibration recomputed under generic CPU targets.

A model trained by ``rvdiag train`` (which holds whole training reducers out of the fit and calibrates on them,
card ``prediction_sets``) is scored on the store's test split, whose reducers neither the fit nor the calibration
saw:

- per window (what ``rvdiag evaluate`` gives under ``sets``): coverage and mean size, overall and per state;
- per record (the windows of one simulation together, as ``rvdiag diagnose`` decides a file): the set of the mean
  probability (what diagnose gives) and the union of the windows' sets (whose coverage is at least any one window's);
- ``--baseline-model``: a model trained on every training reducer (``--calibration-fraction 0``), for the accuracy
  that holding reducers out costs;
- ``--generic``: the calibration samples (the card's held-out reducers, read back from the store) and the test
  split scored again in a subprocess with ``NUMBA_CPU_NAME=generic`` and ``ATEN_CPU_CAPABILITY=default`` (numba's and
  PyTorch's kernels for a baseline x86-64), the thresholds recalibrated from those probabilities, and the sets
  compared with this process's.

Usage::

    rvdiag library build configs/demo.toml --out /tmp/demo.zarr
    rvdiag train /tmp/demo.zarr --out /tmp/model --seed 0
    rvdiag train /tmp/demo.zarr --out /tmp/model-all --seed 0 --calibration-fraction 0
    rvdiag train /tmp/demo.zarr --out /tmp/model-cross --seed 0 --calibration cross
    python bench/prediction_sets.py /tmp/demo.zarr /tmp/model --baseline-model /tmp/model-all --generic
    python bench/prediction_sets.py /tmp/demo.zarr /tmp/model-cross --generic

A cross-conformal card (``--calibration cross``) keeps no fold models, so its thresholds are not recomputed here;
``--generic`` then compares the test split's probabilities and sets under the stored thresholds.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np


def _probabilities(model_dir: Path, store_path: Path, rows: np.ndarray) -> np.ndarray:
    from rvdiag.datasets import SampleStore
    from rvdiag.evaluation.evaluate import predict_in_chunks
    from rvdiag.models.persistence import load_model

    loaded = load_model(model_dir)
    s = SampleStore.open(store_path).load(index=rows)
    return predict_in_chunks(loaded.estimator, loaded.inputs(s.X, s.meta), method="predict_proba").astype(float)


def _rows(store, card: dict) -> tuple[np.ndarray, np.ndarray]:
    """The store rows of the card's held-out calibration reducers (none for a cross-conformal card: its scores came
    from fold models that are not kept), and of the test split."""
    held = card["prediction_sets"]["source"].get("held_out_reducers") or {}
    units = np.asarray(store.meta["unit"]).astype(str)
    labels = np.asarray(store.label_names).astype(str)
    train = np.asarray(store.meta["split"]) == "train"
    cal = np.zeros(units.size, bool)
    for c, us in held.items():
        cal |= train & (labels == c) & np.isin(units, us)
    return np.flatnonzero(cal), store.indices("test")


def score(model_dir: Path, store_path: Path, P_cal=None, P_test=None) -> dict:
    from rvdiag.datasets import SampleStore
    from rvdiag.evaluation.metrics import classification_metrics
    from rvdiag.models.conformal import PredictionSets, from_card, set_metrics
    from rvdiag.models.persistence import read_card

    card = read_card(model_dir)
    store = SampleStore.open(store_path)
    stored = from_card(card)
    classes = stored.classes
    cal_rows, test_rows = _rows(store, card)
    labels = np.asarray(store.label_names).astype(str)
    if P_cal is None:
        P_cal = _probabilities(model_dir, store_path, cal_rows) if cal_rows.size else np.zeros((0, len(classes)))
    P_test = _probabilities(model_dir, store_path, test_rows) if P_test is None else P_test
    recal = None if not cal_rows.size else PredictionSets.calibrate(
        P_cal, labels[cal_rows], classes, stored.coverage, groups=np.asarray(store.meta["unit"])[cal_rows],
        rule=stored.rule)
    y = labels[test_rows]
    pred = np.asarray(classes)[P_test.argmax(axis=1)]
    m = classification_metrics(y, pred, labels=classes)
    inside = stored.contains(P_test)
    units = np.asarray(store.meta["unit"])[test_rows]
    keys, inv = np.unique(units, return_inverse=True)
    mean_p = np.zeros((keys.size, len(classes)))
    np.add.at(mean_p, inv, P_test)
    mean_p /= np.bincount(inv)[:, None]
    union = np.zeros((keys.size, len(classes)), bool)
    np.logical_or.at(union, inv, inside)
    y_rec = np.asarray([y[inv == k][0] for k in range(keys.size)])
    return {
        "model": str(model_dir), "store": str(store_path),
        "n_calibration": stored.n_calibration, "n_calibration_reducers": stored.n_groups,
        "thresholds": stored.thresholds,
        "calibration": stored.source.get("method"),
        "recalibrated_equal": None if recal is None else bool(all(recal.thresholds[c] == stored.thresholds[c]
                                                                  for c in classes)),
        "accuracy": m["accuracy"], "healthy_recall": m["healthy_recall"], "false_alarm_rate": m["false_alarm_rate"],
        "recall": {c: v["recall"] for c, v in m["per_class"].items()},
        "windows": set_metrics(inside, y, classes, stored.coverage),
        "records_mean_probability": set_metrics(stored.contains(mean_p), y_rec, classes, stored.coverage),
        "records_union": set_metrics(union, y_rec, classes, stored.coverage),
        "_P_cal": P_cal, "_P_test": P_test, "_inside": inside,
    }


def generic(model_dir: Path, store_path: Path) -> dict:
    """Score the calibration and test rows in a subprocess under generic CPU targets; compare with this process."""
    here = score(model_dir, store_path)
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, NUMBA_CPU_NAME="generic", ATEN_CPU_CAPABILITY="default")
        code = ("import sys, numpy as np; sys.path.insert(0, sys.argv[1]); import prediction_sets as b; "
                "from pathlib import Path; r = b.score(Path(sys.argv[2]), Path(sys.argv[3])); "
                "np.savez(sys.argv[4], cal=r['_P_cal'], test=r['_P_test'])")
        out = Path(tmp) / "p.npz"
        subprocess.run([sys.executable, "-c", code, str(Path(__file__).parent), str(model_dir), str(store_path),
                        str(out)], env=env, check=True)
        z = np.load(out)
        there = score(model_dir, store_path, P_cal=z["cal"], P_test=z["test"])
    from rvdiag.models.conformal import PredictionSets, from_card
    from rvdiag.models.persistence import read_card
    from rvdiag.datasets import SampleStore

    stored = from_card(read_card(model_dir))
    store = SampleStore.open(store_path)
    cal_rows, _ = _rows(store, read_card(model_dir))
    y_cal = np.asarray(store.label_names).astype(str)[cal_rows]
    recal = PredictionSets.calibrate(z["cal"], y_cal, stored.classes, stored.coverage,
                                     groups=np.asarray(store.meta["unit"])[cal_rows], rule=stored.rule) \
        if cal_rows.size else stored
    inside_generic = recal.contains(z["test"])
    diffs = [np.abs(here["_P_test"] - z["test"]).max()] + ([np.abs(here["_P_cal"] - z["cal"]).max()]
                                                             if cal_rows.size else [])
    return {"max_abs_probability_difference": float(max(diffs)),
            "max_abs_threshold_difference": None if not cal_rows.size else float(
                max(abs(recal.thresholds[c] - stored.thresholds[c]) for c in stored.classes)),
            "test_sets_differing": int(np.any(inside_generic != here["_inside"], axis=1).sum()),
            "n_test": int(len(inside_generic)),
            "coverage_generic": there["windows"]["coverage"], "coverage_native": here["windows"]["coverage"]}


def refit_study(store_path: Path, model: str = "svm", features: str = "logspec", folds: int = 5,
                fraction: float = 0.2, seed: int = 0) -> dict:
    """Split against cross-conformal calibration, with a classical model (the CNN costs K + 1 trainings):

    - ``split``: the model fitted on the training reducers less a share ``fraction`` of each state's, calibrated on
      those (what ``rvdiag train`` does; no refit);
    - ``cross``: the training reducers of each state cut into ``folds`` folds; fold k's windows scored by a model
      fitted on the other folds (every training window gets a score from a model that never saw its reducer, as
      the monitor's CV+); thresholds from those pooled scores, applied to the model refitted on every training
      reducer.

    Both scored on the test split (reducers nobody trained or calibrated on)."""
    from sklearn.base import clone

    from rvdiag.datasets import SampleStore
    from rvdiag.evaluation.metrics import classification_metrics, healthy_class
    from rvdiag.models.conformal import PredictionSets, set_metrics, split_by_group, stated_coverages
    from rvdiag.models.pipelines import make_classical_model

    store = SampleStore.open(store_path)
    tr, te = store.load("train"), store.load("test")
    y, g = np.asarray(tr.y).astype(str), np.asarray(tr.meta["unit"])
    base = make_classical_model(model, features, seed=seed)
    classes = sorted(set(y.tolist()))
    cover = stated_coverages(classes, healthy=healthy_class(classes))

    def scored(est, ps):
        P = est.predict_proba(te.X)
        m = classification_metrics(np.asarray(te.y).astype(str), np.asarray(est.classes_)[P.argmax(1)],
                                   labels=classes)
        return {"accuracy": m["accuracy"], "healthy_recall": m["healthy_recall"],
                "false_alarm_rate": m["false_alarm_rate"],
                "recall": {c: v["recall"] for c, v in m["per_class"].items()},
                "sets": set_metrics(ps.contains(P), te.y, classes, cover)}

    cal = split_by_group(y, g, fraction, [seed, 4])
    est = clone(base).fit(tr.X[~cal], y[~cal])
    out = {"model": f"{model} on {features}", "split": scored(est, PredictionSets.calibrate(
        est.predict_proba(tr.X[cal]), y[cal], classes, cover, groups=g[cal]))}
    rng = np.random.default_rng([seed, 5])
    fold = np.zeros(y.size, int)
    for c in classes:
        names = rng.permutation(np.unique(g[y == c]))
        for k, chunk in enumerate(np.array_split(names, folds)):
            fold[(y == c) & np.isin(g, chunk)] = k
    P = np.zeros((y.size, len(classes)))
    for k in range(folds):
        m = clone(base).fit(tr.X[fold != k], y[fold != k])
        P[fold == k] = m.predict_proba(tr.X[fold == k])
    full = clone(base).fit(tr.X, y)
    out["cross"] = scored(full, PredictionSets.calibrate(P, y, classes, cover, groups=g))
    out["cross"]["folds"] = folds
    return out


def _public(r: dict) -> dict:
    return {k: v for k, v in r.items() if not k.startswith("_")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("store", type=Path)
    ap.add_argument("model", type=Path)
    ap.add_argument("--baseline-model", type=Path, default=None)
    ap.add_argument("--generic", action="store_true")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--refit-study", metavar="MODEL:FEATURES", default=None,
                    help="also compare split and cross-conformal calibration with this classical model, e.g. "
                         "svm:logspec (refit_study)")
    a = ap.parse_args()
    out = {"calibrated": _public(score(a.model, a.store))}
    if a.refit_study:
        model, _, features = a.refit_study.partition(":")
        out["refit_study"] = refit_study(a.store, model, features or "logspec")
    if a.baseline_model is not None:
        from rvdiag.datasets import SampleStore
        from rvdiag.evaluation.metrics import classification_metrics
        from rvdiag.models.persistence import read_card

        classes = [str(c) for c in read_card(a.baseline_model)["classes"]]
        store = SampleStore.open(a.store)
        rows = store.indices("test")
        P = _probabilities(a.baseline_model, a.store, rows)
        m = classification_metrics(np.asarray(store.label_names).astype(str)[rows],
                                   np.asarray(classes)[P.argmax(axis=1)], labels=classes)
        out["all_reducers"] = {"accuracy": m["accuracy"], "healthy_recall": m["healthy_recall"],
                               "false_alarm_rate": m["false_alarm_rate"],
                               "recall": {c: v["recall"] for c, v in m["per_class"].items()}}
    if a.generic:
        out["generic_cpu"] = generic(a.model, a.store)
    text = json.dumps(out, indent=2, default=float)
    print(text)
    if a.json is not None:
        a.json.write_text(text)


if __name__ == "__main__":
    main()
