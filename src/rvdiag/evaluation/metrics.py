"""Classification metrics of a diagnosis, as one JSON-ready dict (scikit-learn underneath).

Keys of :func:`classification_metrics` (also the keys of ``rvdiag evaluate --json``):

``accuracy``
    fraction of samples classified correctly
``precision_macro``
    unweighted mean over classes of TP / (TP + FP)
``recall_macro``
    unweighted mean over classes of TP / (TP + FN) (= mean per-class accuracy, the
    figure Li, Zhao et al. 2024 and the dynamics paper tabulate per state)
``f1_macro``
    unweighted mean of the per-class F1 = 2 P R / (P + R)
``kappa``
    Cohen's kappa (Cohen 1960): (p_o - p_e) / (1 - p_e), agreement beyond chance; the
    EEMD-MPA-KELM study (Tu et al. 2023) reports it (0.82)
``per_class``
    {class: {precision, recall, f1, support}}
``recall``
    {class: recall}: the share of each class's samples diagnosed as that class (None for a
    class absent from ``y_true``)
``healthy_class``
    the healthy state among ``labels`` (:func:`healthy_class`: ``T1``, or a class named
    ``healthy``/``normal``), or None
``healthy_recall``
    the recall of ``healthy_class`` (None without one, or without a healthy sample)
``false_alarm_rate``
    the share of the healthy samples diagnosed as any other (faulty) class, 1 - healthy recall
    (None as ``healthy_recall``).  The same definition holds for whatever is scored: windows,
    whole records (``evaluate --records``) and merged classes (``--merge``: e.g. with ``T4=T1``
    the healthy class holds the cracked samples too, and a false alarm is a crack-free decision
    other than healthy).  An accuracy is never shown without these two figures
    (:func:`headline`): a model that calls every healthy sample faulty can still score 80 %.
``confusion``
    confusion matrix as a list of rows: row = true class, column = predicted, in the
    order of ``labels``
``labels``
    the class order of ``confusion``
``n_samples``
    the number of samples scored
"""

from __future__ import annotations

import warnings
from typing import Sequence

import numpy as np
from sklearn.exceptions import UndefinedMetricWarning
from sklearn.metrics import (
    accuracy_score,
    cohen_kappa_score,
    confusion_matrix,
    precision_recall_fscore_support,
)

METRIC_KEYS = ("accuracy", "precision_macro", "recall_macro", "f1_macro", "kappa", "per_class", "confusion",
               "recall", "healthy_class", "healthy_recall", "false_alarm_rate")

#: class names, besides the library's healthy state (``T1``), read as the healthy class (case ignored)
HEALTHY_NAMES = ("healthy", "normal")



def binomial_interval(k: int, n: int, level: float = 0.95) -> list[float]:
    """The Clopper-Pearson interval of a rate of ``k`` events in ``n`` trials (Clopper & Pearson, Biometrika 26
    (1934) 404-413; :meth:`scipy.stats.binomtest`'s ``proportion_ci(method="exact")``).

    >>> [round(v, 4) for v in binomial_interval(0, 10)]
    [0.0, 0.3085]
    """
    from scipy.stats import binomtest

    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=level, method="exact")
    return [float(ci.low), float(ci.high)]

def healthy_class(labels: Sequence[str]) -> str | None:
    """The healthy state among ``labels``: the library's healthy state (``T1``,
    :data:`rvdiag.gears.faults.FAULT_KINDS`), else the first label named as in :data:`HEALTHY_NAMES`, else None.

    >>> healthy_class(["T1", "T2"]), healthy_class(["normal", "inner race"]), healthy_class(["a", "b"])
    ('T1', 'normal', None)
    """
    from rvdiag.gears.faults import FAULT_KINDS

    labels = [str(c) for c in labels]
    healthy = [k for k, v in FAULT_KINDS.items() if v == "healthy"]
    for c in labels:
        if c in healthy:
            return c
    return next((c for c in labels if c.strip().lower() in HEALTHY_NAMES), None)


def headline(m: dict, pct_digits: int = 2) -> str:
    """``accuracy 72.85 %, healthy (T1) recall 97.7 %, false-alarm rate 2.3 %`` of a metrics dict: the accuracy
    is never printed alone (a model that calls every healthy sample faulty can still score a high accuracy)."""
    acc = f"accuracy {100 * m['accuracy']:.{pct_digits}f} %"
    h = m.get("healthy_class")
    if h is None:
        return acc + " (no healthy class: no false-alarm rate)"
    if m.get("healthy_recall") is None:
        return acc + f", no healthy ({h}) sample: no false-alarm rate"
    return (acc + f", healthy ({h}) recall {100 * m['healthy_recall']:.1f} %, false-alarm rate "
            f"{100 * m['false_alarm_rate']:.1f} %")

def classification_metrics(y_true, y_pred, labels: Sequence[str] | None = None) -> dict:
    """Accuracy, macro precision/recall/F1, Cohen's kappa, per-class figures and the confusion matrix.

    Parameters
    ----------
    y_true, y_pred : array-like of class names
    labels : sequence of str, optional
        Class order (default: sorted union of both).  Classes absent from both still get a row.

    Examples
    --------
    >>> m = classification_metrics(["a", "a", "b", "b"], ["a", "b", "b", "b"])
    >>> m["accuracy"], m["confusion"]
    (0.75, [[1, 1], [0, 2]])
    >>> round(m["kappa"], 3)
    0.5
    """
    yt = np.asarray(y_true).astype(str)
    yp = np.asarray(y_pred).astype(str)
    if yt.shape != yp.shape or yt.ndim != 1:
        raise ValueError(f"y_true and y_pred must be 1-D of equal length, got {yt.shape} and {yp.shape}")
    if labels is None:
        labels = sorted(set(yt.tolist()) | set(yp.tolist()))
    labels = [str(c) for c in labels]
    if yt.size == 0:
        raise ValueError("no samples to score")
    p, r, f, s = precision_recall_fscore_support(yt, yp, labels=labels, zero_division=0)
    present = s > 0  # macro averages over classes that occur in y_true
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UndefinedMetricWarning)
        kappa = cohen_kappa_score(yt, yp, labels=labels)
    if not np.isfinite(kappa):  # one label only in both: agreement is perfect or nil
        kappa = 1.0 if np.all(yt == yp) else 0.0
    healthy = healthy_class(labels)
    h_recall = None
    if healthy is not None and s[labels.index(healthy)] > 0:
        h_recall = float(r[labels.index(healthy)])
    return {
        "accuracy": float(accuracy_score(yt, yp)),
        "precision_macro": float(np.mean(p[present])),
        "recall_macro": float(np.mean(r[present])),
        "f1_macro": float(np.mean(f[present])),
        "kappa": float(kappa),
        "per_class": {
            c: {"precision": float(p[i]), "recall": float(r[i]), "f1": float(f[i]), "support": int(s[i])}
            for i, c in enumerate(labels)
        },
        "confusion": confusion_matrix(yt, yp, labels=labels).astype(int).tolist(),
        "labels": labels,
        "n_samples": int(yt.size),
        "recall": {c: (float(r[i]) if s[i] > 0 else None) for i, c in enumerate(labels)},
        "healthy_class": healthy,
        "healthy_recall": h_recall,
        "false_alarm_rate": None if h_recall is None else 1.0 - h_recall,
    }


def merged_classification_metrics(y_true, y_pred, merge: dict[str, str], labels: Sequence[str]) -> dict:
    """:func:`classification_metrics` with classes merged, true and predicted alike (``{"T4": "T1", "T6": "T5"}``:
    the crack-free decision, a crack counted as its state without the crack), plus the ``merge`` itself."""
    def m(a):
        return np.asarray([merge.get(str(c), str(c)) for c in a])

    kept = list(dict.fromkeys(merge.get(str(c), str(c)) for c in labels))
    return {"merge": dict(merge), **classification_metrics(m(y_true), m(y_pred), labels=kept)}


def repeat_summary(runs: Sequence[dict]) -> dict:
    """Best and mean accuracy per class over repeated runs (the dynamics paper's per-state table).

    Parameters
    ----------
    runs : list of dicts from :func:`classification_metrics`, one per seed

    Returns
    -------
    dict with ``per_class`` {class: {"best", "mean", "worst"}} (per-class accuracy = recall), and
    ``accuracy`` {"best", "mean", "worst", "std"} over runs, ``n_runs``.
    """
    if not runs:
        raise ValueError("no runs to summarise")
    labels = runs[0]["labels"]
    per = {c: np.array([r["per_class"][c]["recall"] for r in runs]) for c in labels}
    acc = np.array([r["accuracy"] for r in runs])
    return {
        "n_runs": len(runs),
        "per_class": {c: {"best": float(v.max()), "mean": float(v.mean()), "worst": float(v.min())}
                      for c, v in per.items()},
        "accuracy": {"best": float(acc.max()), "mean": float(acc.mean()), "worst": float(acc.min()),
                     "std": float(acc.std())},
    }
