"""Six exclusive classes against three fault labels (``rvdiag train --multilabel``): the figures of docs/results.md.

    .venv/bin/python bench/multilabel_faults.py STORE.zarr MODEL_DIR [MODEL_DIR ...]

For each model (six-class or ``--multilabel``, trained on STORE) on STORE's ``test`` split, prints

* the accuracy, kappa and recall of T1..T6;
* the crack-free decision: T4 counted as T1 and T6 as T5 in both the truth and the prediction (four classes);
* per fault (broken, worn, cracked), the ROC AUC and the balanced accuracy at p = 0.5 of the model's probability
  of that fault: a ``--multilabel`` model's own per-fault probability, or for a six-class model the sum of the
  probabilities of the states that have the fault;
* for a ``--multilabel`` model, also the accuracy when the decoding divides out each label's training base rate
  and puts in the states' training frequencies (the joint probability that the product of the per-label
  probabilities would be if the labels were independent given the sample; not what ``rvdiag`` does).
"""

from __future__ import annotations

import sys

import numpy as np
from sklearn.metrics import balanced_accuracy_score, cohen_kappa_score, roc_auc_score

from rvdiag.datasets import SampleStore
from rvdiag.models.multilabel import FAULT_LABELS, fault_codes
from rvdiag.models.persistence import load_model

CRACK_FREE = {"T4": "T1", "T6": "T5"}


def _recall(y, pred, classes) -> str:
    return " / ".join(f"{100 * np.mean(pred[y == c] == c):.0f}" for c in classes) + " %"


def main(store_path: str, models: list[str]) -> None:
    store = SampleStore.open(store_path)
    te, ytr = store.load("test"), store.load("train").y.astype(str)
    y = te.y.astype(str)
    B = fault_codes(y)
    print(f"{store_path}: {len(y)} test samples")
    for d in models:
        m = load_model(d)
        est, X = m.estimator, m.inputs(te.X, te.meta)
        cls = np.asarray(est.classes_).astype(str)
        multi = "multilabel" in m.card
        Z = est[:-1].transform(X)
        S = est[-1].predict_proba(Z)
        pred = cls[S.argmax(1)]
        P = est[-1].fault_probabilities(Z) if multi else S @ fault_codes(cls)
        merge = np.vectorize(lambda s: CRACK_FREE.get(s, s))
        print(f"{d} ({'three labels' if multi else 'six classes'}): accuracy {100 * np.mean(pred == y):.1f} %, "
              f"kappa {cohen_kappa_score(y, pred):.3f}, recall T1..T6 {_recall(y, pred, cls)}, crack-free "
              f"{100 * np.mean(merge(pred) == merge(y)):.1f} %")
        print("    " + "; ".join(f"{f}: AUC {roc_auc_score(B[:, k], P[:, k]):.3f}, balanced accuracy "
                                 f"{balanced_accuracy_score(B[:, k], P[:, k] > 0.5):.3f}"
                                 for k, f in enumerate(FAULT_LABELS)))
        if multi:
            C = fault_codes(cls).astype(float)
            p = np.clip(P, 1e-12, 1 - 1e-12)
            pi = fault_codes(ytr).mean(0)
            prior = np.array([np.mean(ytr == c) for c in cls])
            L = (np.log(p) @ C.T + np.log1p(-p) @ (1 - C).T
                 - (np.log(pi) @ C.T + np.log1p(-pi) @ (1 - C).T) + np.log(prior))
            pc = cls[L.argmax(1)]
            print(f"    base rates divided out: accuracy {100 * np.mean(pc == y):.1f} %, recall T1..T6 "
                  f"{_recall(y, pc, cls)}, crack-free {100 * np.mean(merge(pc) == merge(y)):.1f} %")


if __name__ == "__main__":
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    main(sys.argv[1], sys.argv[2:])
