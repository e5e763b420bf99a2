"""A joint's prognosis from its record history: the change detector's onset and alarm, and the remaining life.

:func:`joint_prognosis` is what the fleet store (``rvdiag.fleet``) calls for ``fleet status --json`` and the joint
page: it runs the conformal test martingale (:mod:`rvdiag.prognostics.change`) on the joint's record scores ranked
among its own earlier ones (commissioning first), and after an alarm fits the degradation model
(:mod:`rvdiag.prognostics.rul`) to the health index since the estimated onset.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.prognostics.change import DEFAULT_DELTA, ConformalMartingale
from rvdiag.prognostics.rul import ASSUMPTION, RulEstimate, estimate_rul
from rvdiag.validation import positive

#: horizons (days after the last record) at which ``p_before`` is given by default
DEFAULT_HORIZONS_DAYS = (30.0, 90.0, 365.0)

#: Monte Carlo draws of the remaining life (and of the threshold, when it is given as a population)
N_DRAWS = 4000

#: the remaining-life model for the monitor's fault state (rvdiag.library.states): Paris' law for a root crack,
#: the implied size's linear law (Archard wear) otherwise; a state with a broken tooth has failed already
MODEL_FOR_STATE = {"T3": "size", "T4": "paris", "T7": "size", "T8": "size"}
FAILED_STATES = ("T2", "T5", "T6")


def model_for_state(state: str | None) -> str | None:
    """The remaining-life model for the monitor's most probable fault state (``None`` for a broken tooth: failed).

    >>> model_for_state("T4"), model_for_state("T3"), model_for_state(None), model_for_state("T2")
    ('paris', 'size', 'size', None)
    """
    if state in FAILED_STATES:
        return None
    return MODEL_FOR_STATE.get(state, "size")


def _as_datetime(value) -> datetime:
    if isinstance(value, datetime):
        return value if value.tzinfo else value.replace(tzinfo=timezone.utc)
    if isinstance(value, str):
        try:
            return _as_datetime(datetime.fromisoformat(value.replace("Z", "+00:00")))
        except ValueError:
            raise ParameterError(f"not an ISO 8601 time: {value!r}") from None
    raise ParameterError(f"times must be all datetimes / ISO strings or all numbers (days), got {value!r}")


class _Clock:
    """Times as days since the first record, and back: datetimes (or ISO strings) or plain numbers of days."""

    def __init__(self, times):
        times = list(times)
        self.dated = bool(times) and not isinstance(times[0], (int, float, np.integer, np.floating))
        if self.dated:
            dts = [_as_datetime(t) for t in times]
            self.origin = dts[0]
            self.days = np.array([(d - self.origin).total_seconds() / 86400.0 for d in dts])
        else:
            self.origin = None
            self.days = np.asarray(times, dtype=float)
            if not np.all(np.isfinite(self.days)):
                raise ParameterError("times must be finite")
        if np.any(np.diff(self.days) < 0):
            raise ParameterError("times must not decrease")

    def to_day(self, value) -> float:
        if self.dated:
            return (_as_datetime(value) - self.origin).total_seconds() / 86400.0
        return float(value)

    def label(self, day: float | None):
        if day is None:
            return None
        return (self.origin + timedelta(days=float(day))).isoformat() if self.dated else float(day)


@dataclass
class Prognosis:
    """A joint's onset, alarm and remaining life.  ``rul`` is the chosen degradation model's estimate,
    ``rul_baseline`` linear extrapolation of the index (the classical comparison); ``p_before`` is given for each
    of ``before`` (times, or days after the last record)."""

    onset_time: object
    alarm_time: object
    onset_index: int | None
    alarm_index: int | None
    evidence: float
    delta: float
    rul: RulEstimate
    rul_baseline: RulEstimate
    before: dict = field(default_factory=dict)
    detector: dict = field(default_factory=dict)

    @property
    def alarmed(self) -> bool:
        return self.alarm_index is not None

    def to_dict(self) -> dict:
        """JSON-ready: ``onset_time``, ``alarm_time`` (None before an alarm), ``evidence`` (the martingale after
        the last record: an alarm at 1/delta), ``lifetime_false_alarm_bound`` (delta), ``rul`` and ``rul_baseline``
        ({``median_days``, ``p10_days``, ``p90_days``, ``p_before``, ...} or {``estimated``: false, ``reason``}),
        ``assumption`` and the detector's parameters."""
        return {"onset_time": self.onset_time, "alarm_time": self.alarm_time, "onset_index": self.onset_index,
                "alarm_index": self.alarm_index, "evidence": float(self.evidence),
                "lifetime_false_alarm_bound": self.delta, "rul": self.rul.to_dict(self.before),
                "rul_baseline": self.rul_baseline.to_dict(self.before), "assumption": ASSUMPTION,
                "detector": self.detector}


def _threshold_draws(threshold, seed: int):
    """One threshold (a float), or ``N_DRAWS`` seeded draws with replacement from a population of them; None."""
    if threshold is None:
        return None
    t = np.asarray(threshold, dtype=float).ravel()
    if t.size == 0 or not np.all(np.isfinite(t)):
        raise ParameterError("threshold must be finite numbers")
    if t.size == 1:
        return float(t[0])
    return np.random.default_rng([seed, 2]).choice(t, size=N_DRAWS, replace=True)


def joint_prognosis(times, scores=None, p_values=None, health_index=None, baseline_scores=(), threshold=None, *,
                    delta: float = DEFAULT_DELTA, model: str | None = None, fault_state: str | None = None,
                    before=None,
                    healthy_level: float | None = None, reference_level: float | None = None,
                    confidence: float = 0.95, min_records: int = 3, seed: int = 0) -> Prognosis:
    """The prognosis of one joint from its records after commissioning, in time order.

    Parameters
    ----------
    times : sequence of datetime, ISO 8601 str, or float (days)
        The records' times (after commissioning).
    scores : sequence of float, optional
        The score the change detector ranks (higher = further from healthy); default the health index, else
        -log10 of the monitor's p-values (the same ranks as 1 - p).
    p_values : sequence of float, optional
        The monitor's per-record p-values (used only when neither scores nor the health index is given).
    health_index : sequence of float, optional
        The monitor's health index per record (the quantity whose trend gives the remaining life).
    baseline_scores : sequence of float
        The commissioning records' scores (the same quantity as ``scores``), in order; the first members of the
        bag later records are ranked among.  With fewer than about 20 the detector needs more records to alarm
        (:mod:`rvdiag.prognostics.change`).  A monitor whose index is a change against the commissioning records
        gives those records no index: pass ``[]`` and the joint's first records fill the bag (its "learning"
        records), or pass those first records here and the rest as ``times`` / ``health_index``.  Without
        commissioning scores the joint's records before the onset stand for its healthy index.
    threshold : float, sequence of float, optional
        The health index at the failure threshold; None: the remaining life is not estimated.  A sequence is the
        threshold's spread over a population (e.g. the index at the failure time of each reducer of a library run
        to failure, :func:`rvdiag.monitoring.life.learn_threshold`): the Monte Carlo draws the threshold from it
        (with replacement, seeded), so that the interval carries how much the index at failure varies between
        reducers, not only the trend's uncertainty.
    delta : float
        Lifetime false-alarm probability of the change detector (1 % per joint-life by default).
    before : sequence, optional
        Times (or days after the last record when ``times`` are numbers) for ``p_before``; default 30, 90 and 365
        days after the last record.
    model : {"size", "exponential", "paris", "linear"}, optional
        The remaining-life model (:func:`rvdiag.prognostics.rul.estimate_rul`); default :func:`model_for_state` of
        ``fault_state``: ``paris`` for a root crack, else ``size`` (the implied fault size's linear trend, wear's
        law, the commonest way a reducer ages).  Linear extrapolation of the index is always given beside it as
        ``rul_baseline``.
    fault_state : str, optional
        The monitor's most probable fault state of the latest records (``T1``..``T8``); with a broken tooth (T2, T5,
        T6) the remaining life is not estimated: the failure has happened.
    healthy_level : float, optional
        phi of the degradation model; default the median of ``baseline_scores`` when the scores are the health
        index (of the records before the onset when none are given), else 0.
    reference_level : float, optional
        The median healthy index of the population the ``threshold`` was set on (e.g. the monitor's calibration
        records).  When given (and the scores are the health index), the threshold is scaled to this joint by its
        own commissioning median over ``reference_level`` (a joint whose healthy index runs at 1.3x the
        population's reaches the failure size at 1.3x the threshold), and the scale's uncertainty (a bootstrap of
        the commissioning median) is carried into the Monte Carlo.
    seed : int
        Seed of the detector's smoothing draws and of the Monte Carlo.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> base = rng.gamma(4.0, 0.1, 30)
    >>> days = np.arange(40.0) * 7
    >>> hi = rng.gamma(4.0, 0.1, 40) * np.where(days > 140, np.exp((days - 140) / 40.0), 1.0)
    >>> p = joint_prognosis(days, health_index=hi, baseline_scores=base, threshold=20.0)
    >>> p.alarmed, p.to_dict()["rul"]["estimated"]
    (True, True)
    """
    clock = _Clock(times)
    n = len(clock.days)
    hi = None if health_index is None else np.asarray(health_index, dtype=float).ravel()
    if scores is not None:
        s = np.asarray(scores, dtype=float).ravel()
    elif hi is not None:
        s = hi
    elif p_values is not None:
        p = np.asarray(p_values, dtype=float).ravel()
        if np.any((p < 0) | (p > 1)):
            raise ParameterError("p_values must be in [0, 1]")
        s = -np.log10(np.maximum(p, 1e-300))
    else:
        raise ParameterError("give scores, health_index or p_values")
    for name, arr in (("scores", s), ("health_index", hi)):
        if arr is not None and len(arr) != n:
            raise ParameterError(f"{name} has {len(arr)} values for {n} times")
    base = np.asarray(baseline_scores, dtype=float).ravel()
    det = ConformalMartingale(base, delta=delta, seed=seed)
    run = det.run(s) if n else None
    alarm, onset = (run.alarm_index, run.onset_index) if run is not None else (None, None)
    # the joint's healthy index: its commissioning records', else its records before the onset
    healthy = np.array([])
    if scores is None and hi is not None:
        healthy = base if len(base) else (hi[:onset] if onset else np.array([]))
    if healthy_level is None:
        healthy_level = float(np.median(healthy)) if len(healthy) else 0.0
    evidence = float(run.statistic[-1]) if n else 1.0
    last = float(clock.days[-1]) if n else 0.0
    if before is None:
        horizons = {f"{int(d)}d": d for d in DEFAULT_HORIZONS_DAYS}
    else:
        horizons = {str(b if not clock.dated else _as_datetime(b).isoformat()): clock.to_day(b) - last
                    if clock.dated else float(b) for b in before}

    thr = _threshold_draws(threshold, seed)
    if thr is not None and reference_level is not None and len(healthy):
        positive(reference_level, "reference_level")
        boot = np.random.default_rng(seed + 1).choice(healthy, size=(N_DRAWS, len(healthy)), replace=True)
        thr = thr * np.median(boot, axis=1) / float(reference_level)

    failed = fault_state in FAILED_STATES
    model = model if model is not None else (model_for_state(fault_state) or "size")

    def rul(model: str) -> RulEstimate:
        if failed:
            return RulEstimate(False, f"the monitor names a broken tooth ({fault_state}): the joint has failed", model,
                               last)
        if alarm is None:
            return RulEstimate(False, "no confirmed onset: the change detector has not alarmed", model, last)
        if hi is None:
            return RulEstimate(False, "no health index given", model, last)
        return estimate_rul(clock.days[onset:], hi[onset:], threshold=thr, healthy_level=healthy_level,
                            model=model, as_of_day=last, confidence=confidence, min_records=min_records, seed=seed,
                            n_samples=N_DRAWS,
                            paris_margin=float(np.max(healthy) - healthy_level) if len(healthy) else 0.0)

    return Prognosis(onset_time=clock.label(clock.days[onset]) if onset is not None else None,
                     alarm_time=clock.label(clock.days[alarm]) if alarm is not None else None,
                     onset_index=onset, alarm_index=alarm, evidence=evidence if math.isfinite(evidence) else 1e300,
                     delta=float(delta), rul=rul(model), rul_baseline=rul("linear"), before=horizons,
                     detector=det.parameters())
