"""How well change detection and remaining life do over joints' lives: the one home of the life metrics that
``rvdiag evaluate --life`` (:mod:`rvdiag.monitoring.life`) and ``bench/prognostics.py`` report.

:func:`life_metrics` takes one :class:`LifeHistory` per joint (its records' times in days since commissioning, the
monitor's health index per record, its commissioning scores, and the truth: fate, onset, failure time, the fault's
state) and runs on each what the product runs on a joint (:func:`rvdiag.prognostics.joint_prognosis`: the conformal
test martingale on the joint's own records, the remaining-life model after its alarm).  It returns, per joint and
pooled, JSON-ready:

``lifetime_false_alarm``
    ``rate``: the share of healthy histories (fate ``healthy``) in which the martingale ever alarms; ``ci95`` its
    Clopper-Pearson interval (Clopper & Pearson 1934); ``bound``: the stated probability delta (Ville's inequality,
    :mod:`rvdiag.prognostics.change`); ``n`` and ``n_alarmed``.
``detection_delay_records``
    per fault state (the fault's state at its onset: T2 broken tooth, T3 wear, T4 root crack, ...): the delay in
    records from the first record at or after the onset to the martingale's first alarm, ``median`` and ``p90``
    (``inverted_cdf`` quantiles; ``null`` where that quantile is a history never detected: an alarm before the onset
    is a false alarm and counts as never), ``n``, ``n_detected`` and ``detected_before_failure`` (share); with the
    true state per record (:attr:`LifeHistory.true_state`) also ``from_first_faulty_record`` (``median``, ``p90``,
    ``n``): from the first record whose true state is not T1 (a life store keeps a fault below its smallest
    simulated size at T1, the signal healthy).
``detected_within_3``
    per fault state: the share of histories alarmed within 3 records of the onset (delay 0, 1 or 2), ``ci95``.
``rul_coverage_80``
    the share of histories whose 80 % interval (``p10_days`` to ``p90_days``) holds the true remaining life at the
    prediction time lambda = 0.5 (Saxena, Celaya, Saha, Saha & Goebel 2010, "Metrics for offline evaluation of
    prognostic performance", IJPHM 1(1), sec. 5): t_lambda = t_P + 0.5 (EoL - t_P), t_P the alarm and EoL the true
    failure time; the prediction is made at the first record at or after t_lambda (the last record before the
    failure when none is).  Scored on the histories whose fault grows to a failure (not a sudden broken tooth) and
    that alarm before it (an alarm before the onset too: the product predicts from whatever alarm it has); a
    history whose remaining life is then "not estimated" counts as a miss.
``alpha_lambda``
    the share of the same histories that meet alpha-lambda accuracy (Saxena et al. 2010, eq. 11) with alpha 0.2 and
    beta 0.5: at least half the predicted time-of-failure draws lie strictly within +-alpha (EoL - t_lambda) of
    EoL, as ProgPy's ``progpy.metrics.alpha_lambda`` computes it (tests/test_life_metrics.py checks the two agree).
``baseline``
    ``rul_coverage_80`` and ``alpha_lambda`` of linear extrapolation of the index (:func:`rvdiag.prognostics.rul.
    estimate_rul` with ``model="linear"``, the product's ``rul_baseline``) on the same histories and predictions,
    and, where asked (``classical``), the false-alarm and delay figures of CUSUM and Page-Hinkley.
``monitor_alarm``
    the same three figures (``lifetime_false_alarm`` without a bound, ``detection_delay_records``,
    ``detected_within_3``) for the monitor's own per-record alarm (index > 1, at its stated per-record rate,
    calibrated across reducers) held for 3 of the last 3 records (:class:`rvdiag.prognostics.change.Persistence`,
    the fleet's default persistence): how fast the alarm a user sees speaks, beside the martingale's bound.
``rul_models``
    per remaining-life model (the product's choice, or each asked for, and ``linear``): ``rul_coverage_80``,
    ``alpha_lambda``, ``estimated`` (share), the median relative error of the predicted median, the share with the
    median within 20 %, and the median width of the 80 % interval relative to the true remaining life.

Records that are not recognised (a sensor fault, ``score`` not finite) are left out of a joint's stream, as the
fleet leaves them out (:mod:`rvdiag.fleet.rules`): they count neither as healthy nor as faulty records.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.evaluation.metrics import binomial_interval
from rvdiag.prognostics.change import DEFAULT_DELTA, ConformalMartingale, Cusum, PageHinkley, Persistence
from rvdiag.prognostics.prognosis import joint_prognosis, model_for_state

#: the product's remaining-life model: :func:`model_for_state` of the monitor's state at the prediction
AUTO = "auto"
HEALTHY_FATE = "healthy"
#: the true state of a record whose fault is not (yet) simulated
HEALTHY_STATE = "T1"
#: fates that fail at their onset (a sudden broken tooth): detection only, no remaining life
SUDDEN_FATES = ("broken",)
#: Saxena et al. (2010)'s settings the interface states
ALPHA, LAMBDA, BETA, LEVEL = 0.2, 0.5, 0.5, 0.8
#: the monitor's own alarm (its index over its threshold) and the fleet's default persistence, k of n
MONITOR_LEVEL, PERSISTENCE = 1.0, (3, 3)


@dataclass
class LifeHistory:
    """One joint's life for :func:`life_metrics`.

    Parameters
    ----------
    days : sequence of float
        The records after commissioning, days since commissioning, not decreasing.
    score : sequence of float
        The monitor's health index per record (the detector's score and the index whose trend gives the
        remaining life); NaN for a record that is not recognised (left out).
    fate : str
        ``healthy`` or the fault's name (``wear``, ``crack``, ``broken``, ...).
    onset_days, failure_days : float or None
        The fault's onset and the time it reaches its failure threshold (None / NaN for a healthy joint; may lie
        after the last record).
    state : str or None
        The fault's state at its onset (``T3`` ...), the key of the per-state figures; None for a healthy joint.
    baseline_scores : sequence of float
        The commissioning records' scores (the first of the detector's ranking pool); empty: the joint's first
        records fill it, as in the fleet.
    threshold : float, sequence of float, mapping or None
        The health index at the failure threshold, or its population (:func:`rvdiag.prognostics.joint_prognosis`
        draws from it); a mapping picks it by the monitor's state at the prediction (``predicted_state``), with key
        ``"*"`` for any other; None: the remaining life is not estimated.
    reference_level : float, optional
        The median healthy index of the population the threshold was learned on
        (:func:`rvdiag.prognostics.joint_prognosis`: the threshold is scaled to the joint's own level).
    predicted_state : sequence of str, optional
        The monitor's most probable state per record: the product's remaining-life model and its threshold follow
        it (:func:`rvdiag.prognostics.model_for_state`; a broken tooth: not estimated).
    sensor_fault : sequence of bool, optional
        Records with a sensor fault: left out, as the fleet leaves out records it does not recognise.
    true_state : sequence of str, optional
        The true state per record (a life store's ``state``: T1 also after the onset while the fault is below its
        smallest simulated size): the delay is also given from the first record not in ``healthy_state``.
    seed : int
        Seed of the detector's smoothing draws and of the Monte Carlo.
    name : str
        The joint's name in the per-joint figures.
    """

    days: Sequence[float]
    score: Sequence[float]
    fate: str
    onset_days: float | None = None
    failure_days: float | None = None
    state: str | None = None
    baseline_scores: Sequence[float] = ()
    threshold: float | Sequence[float] | Mapping[str, float | Sequence[float]] | None = None
    reference_level: float | None = None
    predicted_state: Sequence[str] | None = None
    sensor_fault: Sequence[bool] | None = None
    true_state: Sequence[str] | None = None
    seed: int = 0
    name: str = ""
    _kept: dict = field(default_factory=dict, init=False, repr=False)

    def stream(self):
        """``(days, score, predicted_state or None)`` of the recognised records."""
        if not self._kept:
            d = np.asarray(self.days, dtype=float).ravel()
            s = np.asarray(self.score, dtype=float).ravel()
            if d.shape != s.shape:
                raise ParameterError(f"history {self.name!r}: {d.size} times for {s.size} scores")
            keep = np.isfinite(s)
            if self.sensor_fault is not None:
                keep &= ~np.asarray(self.sensor_fault, dtype=bool).ravel()
            ps = None if self.predicted_state is None else np.asarray(self.predicted_state).astype(str)[keep]
            ts = None if self.true_state is None else np.asarray(self.true_state).astype(str)[keep]
            self._kept.update(days=d[keep], score=s[keep], predicted=ps, true_state=ts,
                              n_left_out=int((~keep).sum()))
        return self._kept["days"], self._kept["score"], self._kept["predicted"]

    def threshold_for(self, state: str | None):
        """The threshold for the monitor's ``state``: a float, a population of floats (a tuple), or None."""
        t = self.threshold
        if isinstance(t, Mapping):
            t = t.get(state, t.get("*"))
        if t is None:
            return None
        v = np.asarray(t, dtype=float).ravel()
        v = v[np.isfinite(v)]
        return None if v.size == 0 else (float(v[0]) if v.size == 1 and np.ndim(t) == 0 else tuple(v.tolist()))


def _finite_or_none(x) -> float | None:
    return None if x is None or not math.isfinite(float(x)) else float(x)


def alpha_lambda_met(t_prediction: float, rul_samples, eol: float, alpha: float = ALPHA, beta: float = BETA) -> bool:
    """Alpha-lambda accuracy of one prediction (Saxena et al. 2010, eq. 11; ProgPy's ``alpha_lambda``): at least
    ``beta`` of the predicted times of failure ``t_prediction + rul_samples`` lie strictly within
    ``EoL -+ alpha (EoL - t_prediction)``.

    >>> alpha_lambda_met(10.0, [9.0, 10.0, 11.0, 30.0], 20.0)   # true life 10 days: 8-12 holds 3 of 4
    True
    """
    toe = float(t_prediction) + np.asarray(rul_samples, dtype=float)
    half = float(alpha) * (float(eol) - float(t_prediction))
    inside = (toe > float(eol) - half) & (toe < float(eol) + half)
    return bool(np.mean(inside) >= float(beta))


def _detectors(h: LifeHistory, delta: float, classical: bool) -> dict:
    days, s, _ = h.stream()
    out = {"martingale": ConformalMartingale(h.baseline_scores, delta=delta, seed=h.seed).run(s),
           "monitor_alarm": Persistence(level=MONITOR_LEVEL, k=PERSISTENCE[0], n=PERSISTENCE[1]).run(s)}
    if classical:
        out["cusum"] = Cusum(h.baseline_scores).run(s)
        out["page_hinkley"] = PageHinkley(h.baseline_scores).run(s)
    return out


def prediction_index(days, alarm_index: int, failure_days: float, lam: float = LAMBDA) -> int:
    """The record at which the remaining life is scored: the first at or after t_lambda = t_P + lam (EoL - t_P)
    (t_P the alarm's day), or the last before the failure when none is (module docstring).

    >>> prediction_index([7.0, 14.0, 21.0, 28.0, 35.0], 1, 30.0)   # t_lambda = 22: the record of day 28
    3
    """
    days = np.asarray(days, dtype=float)
    t_p = days[alarm_index]
    t_lam = t_p + lam * (failure_days - t_p)
    k = int(np.searchsorted(days, t_lam, side="left"))
    if k >= len(days) or days[k] >= failure_days:
        k = int(np.searchsorted(days, failure_days, side="left")) - 1
    return k


def _history_outcome(h: LifeHistory, *, delta: float, models: Sequence[str], classical: bool, alpha: float,
                     lam: float, beta: float) -> dict:
    """What happened to one joint: the detectors' alarms and delays, and the remaining life at t_lambda."""
    days, s, pred = h.stream()
    onset = _finite_or_none(h.onset_days)
    failure = _finite_or_none(h.failure_days)
    healthy = h.fate == HEALTHY_FATE
    i_on = None if healthy or onset is None else int(np.searchsorted(days, onset, side="left"))
    if i_on is not None and i_on >= len(days):
        i_on = None                                       # the onset lies after the last record
    dets = _detectors(h, delta, classical) if len(days) else {}
    out = {"name": h.name, "fate": h.fate, "healthy": healthy, "state": None if i_on is None else h.state,
           "n_records": int(len(days)), "n_left_out": h._kept.get("n_left_out", 0), "detectors": {}, "rul": {}}
    ts = h._kept.get("true_state")
    faulty = None if ts is None or i_on is None else np.flatnonzero(ts != HEALTHY_STATE)
    i_vis = int(faulty[0]) if faulty is not None and faulty.size else None
    for name, d in dets.items():
        rec = {"alarmed": d.alarmed, "alarm_index": d.alarm_index}
        if i_on is not None:
            ok = d.alarm_index is not None and d.alarm_index >= i_on
            rec["delay"] = float(d.alarm_index - i_on) if ok else math.inf
            if i_vis is not None:
                ok_vis = d.alarm_index is not None and d.alarm_index >= i_vis
                rec["delay_visible"] = float(d.alarm_index - i_vis) if ok_vis else math.inf
            rec["before_failure"] = bool(ok and (h.fate in SUDDEN_FATES or failure is None
                                                 or days[d.alarm_index] < failure))
        out["detectors"][name] = rec
    m = dets.get("martingale")
    if (healthy or i_on is None or h.fate in SUDDEN_FATES or failure is None or m is None or m.alarm_index is None
            or days[m.alarm_index] >= failure):
        return out
    k = prediction_index(days, m.alarm_index, failure, lam)
    true_rul = failure - days[k]
    state_k = None if pred is None else str(pred[k])
    out["prediction"] = {"day": float(days[k]), "record": k, "true_rul_days": float(true_rul),
                         "monitor_state": state_k}
    results = {}
    p = None
    for model in models:
        chosen = (model_for_state(state_k) or "size") if model == AUTO else model
        p = joint_prognosis(days[:k + 1], health_index=s[:k + 1], baseline_scores=h.baseline_scores,
                            threshold=h.threshold_for(state_k), delta=delta, seed=h.seed, model=chosen,
                            fault_state=state_k if model == AUTO else None, reference_level=h.reference_level)
        results[model] = p.rul
    results["linear"] = p.rul_baseline
    for model, r in results.items():
        rec = {"estimated": bool(r.estimated), "model": r.model, "reason": r.reason}
        if r.estimated:
            rec.update(covered=bool(r.p10_days <= true_rul <= r.p90_days),
                       alpha_lambda=alpha_lambda_met(days[k], r.samples_days, failure, alpha, beta),
                       relative_error=abs(r.median_days - true_rul) / true_rul if true_rul > 0 else math.inf,
                       relative_width=(r.p90_days - r.p10_days) / true_rul if true_rul > 0 else math.inf)
        else:
            rec.update(covered=False, alpha_lambda=False)
        out["rul"][model] = rec
    return out


def _rate(k: int, n: int) -> dict:
    return {"rate": k / n if n else None, "ci95": binomial_interval(k, n) if n else None, "n": int(n),
            "n_met": int(k)}


def _quantile(values: np.ndarray, q: float) -> float | None:
    return _finite_or_none(np.quantile(values, q, method="inverted_cdf")) if len(values) else None


def _detection(outcomes: list[dict], detector: str, delta: float | None) -> dict:
    healthy = [o for o in outcomes if o["healthy"] and detector in o["detectors"]]
    k = sum(o["detectors"][detector]["alarmed"] for o in healthy)
    fa = {"rate": k / len(healthy) if healthy else None,
          "ci95": binomial_interval(k, len(healthy)) if healthy else None, "bound": delta, "n": len(healthy),
          "n_alarmed": int(k)}
    delay, within = {}, {}
    for state in sorted({o["state"] for o in outcomes if o["state"] is not None}):
        recs = [o["detectors"][detector] for o in outcomes if o["state"] == state and detector in o["detectors"]]
        dl = np.array([r["delay"] for r in recs])
        delay[state] = {"median": _quantile(dl, 0.5), "p90": _quantile(dl, 0.9), "n": len(dl),
                        "n_detected": int(np.isfinite(dl).sum()),
                        "detected_before_failure": float(np.mean([r["before_failure"] for r in recs]))}
        vis = np.array([r["delay_visible"] for r in recs if "delay_visible" in r])
        if vis.size:
            delay[state]["from_first_faulty_record"] = {"median": _quantile(vis, 0.5), "p90": _quantile(vis, 0.9),
                                                        "n": int(vis.size)}
        w = _rate(int(np.sum(dl <= 2)), len(dl))
        within[state] = {"share": w["rate"], "ci95": w["ci95"], "n": w["n"]}
    return {"lifetime_false_alarm": fa, "detection_delay_records": delay, "detected_within_3": within}


def _rul(outcomes: list[dict], model: str) -> dict:
    recs = [o["rul"][model] for o in outcomes if model in o.get("rul", {})]
    n = len(recs)
    est = [r for r in recs if r["estimated"]]
    err = np.array([r["relative_error"] for r in est])
    cov, al = _rate(sum(r["covered"] for r in recs), n), _rate(sum(r["alpha_lambda"] for r in recs), n)
    return {"rul_coverage_80": cov, "alpha_lambda": al,
            "models_used": dict(Counter(r["model"] for r in recs)),
            "estimated": len(est) / n if n else None,
            "median_relative_error": float(np.median(err)) if len(err) else None,
            "median_within_20": float(np.mean(err <= 0.2)) if len(err) else None,
            "interval_width": float(np.median([r["relative_width"] for r in est])) if est else None}


def score_histories(histories: Sequence[LifeHistory], *, delta: float = DEFAULT_DELTA,
                    models: Sequence[str] = (AUTO,), classical: bool = False, alpha: float = ALPHA,
                    lam: float = LAMBDA, beta: float = BETA) -> list[dict]:
    """What happened to each joint (its detectors' alarms and delays, its remaining life at t_lambda): the
    outcomes that :func:`summarise` turns into figures, for any grouping of the histories (:func:`life_metrics`
    for the parameters)."""
    from rvdiag.prognostics.rul import MODELS

    if not list(models) or any(m not in (AUTO, *MODELS) for m in models):
        raise ParameterError(f"models must be among {(AUTO, *MODELS)}, got {list(models)!r}")
    if not histories:
        raise ParameterError("no histories to score")
    return [_history_outcome(h, delta=delta, models=list(models), classical=classical, alpha=alpha, lam=lam,
                             beta=beta) for h in histories]


def summarise(outcomes: list[dict], *, delta: float, models: Sequence[str], classical: bool,
              alpha: float = ALPHA, lam: float = LAMBDA, beta: float = BETA) -> dict:
    """The figures of :func:`life_metrics` (module docstring) over the outcomes of some histories."""
    out = {"n_histories": len(outcomes), "fates": dict(sorted(Counter(o["fate"] for o in outcomes).items())),
           "n_records_left_out": int(sum(o["n_left_out"] for o in outcomes))}
    out.update(_detection(outcomes, "martingale", delta))
    by_model = {m: _rul(outcomes, m) for m in list(models) + ["linear"]}
    first = by_model[models[0]]
    out["rul_coverage_80"] = dict(first["rul_coverage_80"], level=LEVEL, model=models[0])
    out["alpha_lambda"] = dict(first["alpha_lambda"], alpha=alpha, **{"lambda": lam}, beta=beta)
    base = {"method": "linear extrapolation of the health index (rvdiag.prognostics.rul, model 'linear')",
            "rul_coverage_80": dict(by_model["linear"]["rul_coverage_80"], level=LEVEL),
            "alpha_lambda": dict(by_model["linear"]["alpha_lambda"], alpha=alpha, **{"lambda": lam}, beta=beta)}
    out["monitor_alarm"] = dict(_detection(outcomes, "monitor_alarm", None),
                                method=f"the monitor's per-record alarm (index > {MONITOR_LEVEL:g}), "
                                       f"{PERSISTENCE[0]} of the last {PERSISTENCE[1]} records; no lifetime bound")
    if classical:
        for name in ("cusum", "page_hinkley"):
            base[name] = _detection(outcomes, name, None)
    out["baseline"] = base
    out["rul_models"] = by_model
    return out


def life_metrics(histories: Sequence[LifeHistory], *, delta: float = DEFAULT_DELTA, models: Sequence[str] = (AUTO,),
                 classical: bool = False, per_history: bool = True, alpha: float = ALPHA, lam: float = LAMBDA,
                 beta: float = BETA) -> dict:
    """Change detection and remaining life over joints' lives, per joint and pooled (module docstring).

    Parameters
    ----------
    histories : sequence of :class:`LifeHistory`
    delta : float
        The martingale's lifetime false-alarm probability (1 % per joint-life by default).
    models : sequence of str
        The remaining-life models scored, the first reported as ``rul_coverage_80`` / ``alpha_lambda``:
        ``"auto"`` (the product's: :func:`rvdiag.prognostics.model_for_state` of the monitor's state at the
        prediction, ``size`` without one) or any of :data:`rvdiag.prognostics.rul.MODELS`; linear extrapolation is
        always added (``baseline``).
    classical : bool
        Also CUSUM and Page-Hinkley (under ``baseline``; they need >= 2 commissioning scores per joint).
    per_history : bool
        Also the figures of each joint alone (key ``per_reducer``, by :attr:`LifeHistory.name`).
    alpha, lam, beta : float
        Alpha-lambda's alpha, the prediction time lambda, and the share of the distribution that must lie within.

    Returns
    -------
    dict
        ``pooled`` and ``per_reducer`` figures, and ``settings``.

    Examples
    --------
    >>> h = LifeHistory(days=np.arange(1, 31) * 7.0, score=np.ones(30), fate="healthy",
    ...                 baseline_scores=np.linspace(0.5, 1.5, 20))
    >>> life_metrics([h], per_history=False)["pooled"]["lifetime_false_alarm"]["rate"]
    0.0
    """
    models = list(models)
    kw = dict(delta=delta, models=models, classical=classical, alpha=alpha, lam=lam, beta=beta)
    outcomes = score_histories(histories, **kw)
    out = {"pooled": summarise(outcomes, **kw),
           "settings": {"delta": delta, "detector": "conformal test martingale (rvdiag.prognostics.change)",
                        "delay_from": "the first record at or after the onset", "within": 3,
                        "prediction": f"the first record at or after t_lambda = t_alarm + {lam} (failure - t_alarm)",
                        "rul_interval": [0.1, 0.9], "alpha": alpha, "lambda": lam, "beta": beta,
                        "models": models}}
    if per_history:
        per = {}
        for h, o in zip(histories, outcomes):
            d = summarise([o], **kw)
            d["outcome"] = {k: v for k, v in o.items() if k not in ("detectors", "rul")}
            d["outcome"]["alarm_index"] = o["detectors"].get("martingale", {}).get("alarm_index")
            per[str(h.name)] = d
        out["per_reducer"] = per
    return out


__all__ = ["AUTO", "LifeHistory", "alpha_lambda_met", "life_metrics", "prediction_index", "score_histories",
           "summarise"]
