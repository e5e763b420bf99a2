"""What a model was trained on, and what it does not know: the card's ``operating_range`` and ``limits``.

:func:`operating_range` records, at training time, the range of the operating conditions of the training samples
(output speed or input speed, load, sampling rate) and of their signal level (per-sample RMS, with the unit where
the store says it); :func:`condition_warnings` gives one line for each condition of a record outside it.

:func:`class_limits` reads the model's held-out test (the card's ``metrics``) for the classes it confuses, by a
stated rule (:data:`WEAK_RECALL`, :data:`CONFUSION_SHARE`); :func:`answer_warnings` turns it into the warnings of
one answer.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

#: metadata columns of a store that give the operating point, with their unit
CONDITION_COLUMNS = {"output_speed_deg_s": "deg/s", "input_speed_rpm": "rev/min", "load_Nm": "N m"}
#: a record's level this many times (or this fraction of) the training samples' RMS range is "orders of
#: magnitude outside" it
LEVEL_FACTOR = 10.0
#: a class whose held-out recall is below this is weak
WEAK_RECALL = 0.9
#: a class b confused with a: at least this share of b's held-out samples diagnosed a
CONFUSION_SHARE = 0.1
#: sampling rates closer than this (relative) are the same rate: a rate read from a time column is off by far
#: less (48000.768 Hz from 9-digit times), and 0.1 % moves a 4 kHz line by 4 Hz, less than a 4096-point bin
FS_RTOL = 1e-3


def signal_rms(X: np.ndarray) -> np.ndarray:
    """RMS of each row of ``X`` about its mean."""
    X = np.asarray(X, dtype=np.float64)
    return np.sqrt(np.mean((X - X.mean(axis=-1, keepdims=True)) ** 2, axis=-1))


def operating_range(meta: Mapping[str, np.ndarray], X: np.ndarray, fs: float | None, *, unit: str | None,
                    normalize: str | None) -> dict:
    """The card's ``operating_range``: ``{column: {"min", "max", "unit"}}`` for each operating condition column of
    the training samples' metadata (:data:`CONDITION_COLUMNS`), ``fs`` and ``level`` (the 1st, 50th and 99th
    percentiles of the samples' RMS, ``unit``, and what the model does with the level)."""
    out: dict = {}
    for column, u in CONDITION_COLUMNS.items():
        if column in meta:
            v = np.asarray(meta[column], dtype=np.float64)
            v = v[np.isfinite(v)]
            if v.size:
                out[column] = {"min": float(v.min()), "max": float(v.max()), "unit": u}
    out["fs"] = None if fs is None else float(fs)
    rms = signal_rms(X)
    p01, p50, p99 = np.percentile(rms, [1, 50, 99]) if rms.size else (math.nan,) * 3
    scaled = {"window": "each window is z-scored: the answer does not depend on the record's scale (unit, "
                        "gain); a level orders of magnitude outside this range still suggests another sensor",
              "global": "windows are scaled by the training mean and deviation: the record must have the "
                        "training level and unit",
              "none": "windows are used as they are: the record must have the training level and unit"}
    out["level"] = {"rms_p01": float(p01), "rms_median": float(p50), "rms_p99": float(p99), "unit": unit,
                    "note": scaled.get(normalize or "", "the features are standardised from the training samples: "
                                                       "the record should have the training unit")}
    return out


def _fmt(x: float) -> str:
    return f"{x:.4g}"


def condition_warnings(rng: Mapping | None, *, conditions: Mapping[str, float | None], fs: float | None,
                       level_rms: float | None) -> list[str]:
    """One ``warning:`` line for each condition of a record outside the training ``rng`` (the card's
    ``operating_range``): ``conditions`` {column: value or None} (:data:`CONDITION_COLUMNS`), its ``fs`` and
    its RMS ``level_rms``.  Speeds and loads outside [min, max]; the level outside [p01 / 10, p99 x 10]."""
    if not rng:
        return []
    out = []
    for column, value in conditions.items():
        r = rng.get(column)
        if value is None or not r:
            continue
        tol = 1e-6 * max(abs(r["min"]), abs(r["max"]), 1.0)  # a speed computed back from revolutions
        if not r["min"] - tol <= value <= r["max"] + tol:
            span = _fmt(r["min"]) if r["min"] == r["max"] else f"{_fmt(r['min'])}-{_fmt(r['max'])}"
            out.append(f"warning: {column} {_fmt(value)} {r['unit']} lies outside the training range {span} "
                       f"{r['unit']}: the model has not seen this operating point")
    lv = rng.get("level") or {}
    if level_rms is not None and lv.get("rms_p01") is not None and math.isfinite(lv["rms_p01"]):
        lo, hi = lv["rms_p01"] / LEVEL_FACTOR, lv["rms_p99"] * LEVEL_FACTOR
        if not lo <= level_rms <= hi:
            unit = f" {lv['unit']}" if lv.get("unit") else ""
            out.append(f"warning: the record's RMS {_fmt(level_rms)}{unit} is orders of magnitude outside the "
                       f"training samples' {_fmt(lv['rms_p01'])}-{_fmt(lv['rms_p99'])}{unit} (another unit or "
                       f"sensor?); {lv.get('note', '')}")
    return out


def fs_ratio(fs: float, train_fs: float) -> float | None:
    """``fs / train_fs`` when the two rates differ by more than :data:`FS_RTOL`, else None (the same rate)."""
    ratio = float(fs) / float(train_fs)
    return None if abs(ratio - 1.0) <= FS_RTOL else ratio


def class_limits(metrics: Mapping | None) -> dict:
    """The classes the model confuses on its held-out test (the card's ``metrics``): ``{"rule", "recall":
    {class: recall}, "weak": [classes with recall < WEAK_RECALL], "confused": [{"true", "predicted",
    "share"}]}`` (each pair where at least :data:`CONFUSION_SHARE` of a class's samples were diagnosed as
    another), or ``{}`` without a held-out test."""
    if not metrics or "per_class" not in metrics:
        return {}
    labels = list(metrics.get("labels") or metrics["per_class"])
    recall = {c: float(v["recall"]) for c, v in metrics["per_class"].items() if v.get("support", 0) > 0}
    confused = []
    cm = np.asarray(metrics.get("confusion") or [], dtype=float)
    if cm.shape == (len(labels), len(labels)):
        for i, t in enumerate(labels):
            n = cm[i].sum()
            for j, p in enumerate(labels):
                if i != j and n > 0 and cm[i, j] / n >= CONFUSION_SHARE:
                    confused.append({"true": t, "predicted": p, "share": float(cm[i, j] / n)})
    return {"rule": f"weak: held-out recall < {WEAK_RECALL:g}; confused: at least {CONFUSION_SHARE:.0%} of a "
                    "class's held-out samples diagnosed as another",
            "recall": recall, "weak": [c for c, r in recall.items() if r < WEAK_RECALL], "confused": confused}


def answer_warnings(limits: Mapping, answer: str, name=lambda c: c) -> list[str]:
    """The warnings of the answer ``answer`` under :func:`class_limits` ``limits``: its own recall is weak; other
    classes are diagnosed as it.  ``name`` labels a class (e.g. ``T4 (crack)``)."""
    if not limits:
        return []
    out = []
    r = limits["recall"].get(answer)
    if r is not None and r < WEAK_RECALL:
        out.append(f"warning: the model recognises {name(answer)} in only {100 * r:.0f} % of its held-out "
                   f"{name(answer)} samples")
    for c in limits["confused"]:
        if c["predicted"] == answer:
            out.append(f"warning: the model diagnosed {100 * c['share']:.0f} % of its held-out {name(c['true'])} "
                       f"samples as {name(answer)}: this answer may be {name(c['true'])}")
    return out
