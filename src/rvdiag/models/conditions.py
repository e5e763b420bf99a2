"""What a model was trained on, and what it does not know: the card's ``operating_range`` and ``limits``.

:func:`operating_range` records, at training time, the range of the operating conditions of the training samples
(output speed or input speed, load, sampling rate) and of their signal level (per-sample RMS, with the unit where
the store says it); :func:`condition_warnings` gives one line for each condition of a record outside it.

:func:`class_limits` reads the model's held-out test (the card's ``metrics``) for the classes it confuses, by a
stated rule (:data:`WEAK_RECALL`, :data:`CONFUSION_SHARE`); :func:`answer_warnings` turns it into the warnings of
one answer.  :func:`untrained_conditions` lists what the model was not trained on (the operating range and what
its training library held fixed), for the report's "What this model cannot do".
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


#: ``[randomise]`` keys of a library config and what each varies between simulations, when the config draws it
VARIED_BY_RANDOMISE = {
    "stiffness_pct": "the stiffnesses", "damping_pct": "the damping",
    "path_resonance_hz": "the transfer path to the sensor", "path_damping_ratio": "the transfer path to the sensor",
    "housing_added_mass": "the housing's added mass", "noise_colour_exponent": "the noise colour",
    "sensor_position_deg": "the sensor's position", "sensor_direction_deg": "the sensor's direction",
}
#: operating conditions of a library config's ``[operation]`` table, with their unit
OPERATION_UNITS = {"output_speed_deg_s": "deg/s", "input_speed_rpm": "rev/min", "load_Nm": "N m",
                   "noise_snr_db": "dB SNR"}


def _span(v) -> str:
    """``45`` or ``15-90`` of a config value (a number or ``{min, max}``)."""
    if isinstance(v, Mapping):
        return f"{_fmt(float(v['min']))}-{_fmt(float(v['max']))}"
    return _fmt(float(v))


def untrained_conditions(rng: Mapping | None, config: Mapping | None) -> list[str]:
    """What a model was not trained on, one sentence each: outside the card's ``operating_range`` ``rng``
    (:func:`operating_range`: the speeds, loads, sampling rate and signal level of its training samples) and,
    from the training library's ``config`` (:meth:`rvdiag.library.config.LibraryConfig.to_dict`, None when not
    known), what the library held fixed: operating conditions, the noise, the randomised parameters, a speed
    profile, the specimen (one parameter set, one draw of its manufacturing errors), the fault states and
    their severity ranges."""
    out = []
    for column, r in (rng or {}).items():
        if column in CONDITION_COLUMNS and isinstance(r, Mapping):
            span = _fmt(r["min"]) if r["min"] == r["max"] else f"{_fmt(r['min'])}-{_fmt(r['max'])}"
            out.append(f"{column}: trained on {span} {r['unit']} only; other operating points are not known to it")
    if rng and rng.get("fs"):
        out.append(f"sampling rate: trained at {rng['fs']:g} Hz only; records at another rate must be "
                   "resampled")
    lv = (rng or {}).get("level") or {}
    if lv.get("rms_p01") is not None and math.isfinite(lv["rms_p01"]):
        unit = f" {lv['unit']}" if lv.get("unit") else ""
        out.append(f"signal level: training samples' RMS {_fmt(lv['rms_p01'])}-{_fmt(lv['rms_p99'])}{unit} "
                   f"(1st-99th percentile); {lv.get('note', '')}")
    if not config:
        return out
    op = config.get("operation") or {}
    for key, unit in OPERATION_UNITS.items():
        if key in op and not isinstance(op[key], Mapping):
            what = "added white noise" if key == "noise_snr_db" else key
            out.append(f"the library held {what} fixed at {_span(op[key])} {unit}")
    rnd = config.get("randomise") or {}
    drawn = {VARIED_BY_RANDOMISE[k] for k, v in rnd.items() if k in VARIED_BY_RANDOMISE and v}
    fixed = sorted({v for v in VARIED_BY_RANDOMISE.values()} - drawn)
    if fixed:
        out.append("the library did not vary " + ", ".join(fixed) + " between simulations")
    if not config.get("profile"):
        out.append("constant speed and load in every simulation: no acceleration, no gravity arm")
    if not any("specimen" in k or "error_seed" in k for k in (*config, *rnd)):
        params = config.get("params") or "the built-in RV-20E"
        out.append(f"one specimen: every simulation is the reducer of {params} with the same manufacturing "
                   "errors (one error_seed); another reducer of the same design was not seen")
    states = config.get("states") or {}
    if states:
        from rvdiag.library.states import SEVERITY_PARAMETERS

        def unit(k):
            u = getattr(SEVERITY_PARAMETERS.get(k), "unit", "")
            return "" if u in ("", "1") else f" {u}"

        sev = "; ".join(f"{s} " + ", ".join(f"{k} {_span(v)}{unit(k)}" for k, v in sw.items())
                        for s, sw in states.items() if sw)
        out.append(f"only the states {', '.join(states)}: any other fault is named as one of them"
                   + (f"; severities trained: {sev}" if sev else ""))
    return out


#: a record's answer is unsure when its mean probability is below this (the other classes together are likelier)
UNSURE_PROBABILITY = 0.5


def record_warnings(probabilities: Mapping[str, float] | None, window_predictions, name=lambda c: c) -> list[str]:
    """The warning of one record's own answer, apart from the model's held-out test: the answer's mean probability
    over the record's windows is below :data:`UNSURE_PROBABILITY`; the line counts the windows' answers (a split
    record may hold a state the model confuses, or one it has not seen, e.g. a severity outside its training)."""
    if not probabilities:
        return []
    answer = max(probabilities, key=probabilities.get)
    p = float(probabilities[answer])
    if p >= UNSURE_PROBABILITY:
        return []
    counts: dict = {}
    for c in window_predictions:
        counts[c] = counts.get(c, 0) + 1
    split = ", ".join(f"{n} {name(c)}" for c, n in sorted(counts.items(), key=lambda kv: -kv[1]))
    return [f"warning: unsure answer: {name(answer)} has a mean probability of only {p:.2f} (below "
            f"{UNSURE_PROBABILITY:g}); the windows say {split}"]
