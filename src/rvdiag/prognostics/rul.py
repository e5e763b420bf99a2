"""Remaining useful life after a confirmed onset, as a distribution: a Bayesian degradation model of the health index
and Monte Carlo to the failure threshold.

Exponential degradation model (Gebraeel, Lawley, Li & Ryan 2005, IIE Transactions 37, 543-557, their model with
i.i.d. errors; as MATLAB's ``exponentialDegradationModel``):

    HI(t) = phi + theta exp(beta t + e(t)),   e(t) ~ N(0, sigma^2) i.i.d.,

phi the healthy level (the median of the commissioning records' index), so that y = log(HI - phi) is linear in t:
y = log theta + beta t + e.  The linear baseline is the same regression on y = HI itself (linear extrapolation of
the index).  Both are fitted to the records since the estimated onset by Bayesian linear regression with unknown
noise variance (Gelman et al., "Bayesian Data Analysis", 3rd ed., sec. 14.2): under the reference prior
p(b, sigma^2) ~ 1/sigma^2, or a conjugate normal-inverse-gamma prior where one is given (Gebraeel et al. 2005
take theirs from a population of units run to failure; no such population exists for a reducer yet), the posterior
is sigma^2 ~ Inv-Gamma, b | sigma^2 ~ Normal.  Monte Carlo draws of (log theta, beta) give the time at which the
model's mean path reaches the failure threshold, t_f = (y_thr - log theta) / beta for beta > 0 (never for
beta <= 0); the remaining life is t_f minus the prediction time, floored at zero.  The result is the draws'
median, 10 % and 90 % quantiles, and P(t_f <= a date).

The fault size the index implies (``model="size"``): the index is a squared Mahalanobis distance, which grows with
the square of a mean shift of the features, and a small fault shifts them in proportion to its size, so
z = sqrt(HI - phi) is proportional to the fault size; its linear trend is Archard wear's (a constant wear rate under
a steady duty), fitted as above with z in place of y.  On simulated lives of the dynamic model the index grows about
linearly in the wear depth instead (HI - phi ~ depth^1.08, research/rul_threshold_spread.py), so z bends over as
the flank wears and the model's extrapolation comes early.  (The exponential model's log(HI - phi) is 2 log z, so it is
the same model for the index and for the size.)

A root crack by Paris' law (``model="paris"``): with m = 3 (:mod:`rvdiag.gears.crack_growth`) a^(1 - m/2) = a^(-1/2)
falls linearly in the load cycles (and so in time under a steady duty) until the growth becomes unstable, so
-z^(-1/2) = -(HI - phi)^(-1/4) is fitted linearly, on the records whose index is above ``phi + paris_margin``
(:func:`rvdiag.prognostics.joint_prognosis` uses the commissioning records' largest index: a near-zero excess
would blow up the transform).  Which model suits a joint follows from its fault: ``size`` for wear, ``paris``
for a root crack; ``exponential`` is the general-purpose choice of Gebraeel et al. and MATLAB.  Measured on
synthetic histories with known truth in ``bench/prognostics.py`` (bench/HISTORY.md).

"Not estimated" (with the reason): before an onset, with fewer than ``min_records`` usable records since it, when
the slope is not positive at the stated ``confidence`` (posterior P(beta > 0) < confidence: the trend does not
hold), or when no failure threshold is set.

Assumption a user must know: the prediction extrapolates the trend since onset, so it assumes the joint's duty
cycle (speed, load and hours in motion) stays as it was since the onset; a heavier duty shortens the life, a
lighter one lengthens it, and a fault that changes its nature (wear that starts pitting, a crack that breaks the
tooth) is not foreseen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from rvdiag.errors import ParameterError
from rvdiag.gears.crack_growth import PARIS_M

ASSUMPTION = ("Assumes the joint's duty cycle (speed, load and hours in motion) stays as it was since the onset; a "
              "heavier duty shortens the life, a lighter one lengthens it, and a change in the fault's nature is not "
              "foreseen.")

MODELS = ("exponential", "size", "paris", "linear")
#: the reason a remaining life is not estimated when no failure threshold is given
NO_THRESHOLD = "no failure threshold on the health index is set"


@dataclass
class RulEstimate:
    """Remaining life (days from ``as_of_day``) as Monte Carlo draws, or not estimated with a reason.

    ``samples_days`` holds ``inf`` for draws whose path never reaches the threshold.
    """

    estimated: bool
    reason: str | None
    model: str
    as_of_day: float | None = None
    samples_days: np.ndarray | None = None
    p_slope_positive: float | None = None
    n_records: int = 0
    parameters: dict = field(default_factory=dict)

    def quantile(self, q: float) -> float | None:
        if not self.estimated:
            return None
        return float(np.quantile(self.samples_days, q))

    @property
    def median_days(self) -> float | None:
        return self.quantile(0.5)

    @property
    def p10_days(self) -> float | None:
        return self.quantile(0.1)

    @property
    def p90_days(self) -> float | None:
        return self.quantile(0.9)

    def p_before(self, days: float) -> float | None:
        """P(the failure threshold is reached within ``days`` of the prediction time)."""
        if not self.estimated:
            return None
        return float(np.mean(self.samples_days <= float(days)))

    def to_dict(self, p_before_days=None) -> dict:
        """``{"estimated": False, "reason": ...}``, or the median, 10 % and 90 % quantiles (days; ``None`` where
        the quantile is beyond any finite time: the path never reaches the threshold) and ``p_before`` for each of
        ``p_before_days`` (a mapping of label -> days from the prediction time)."""
        if not self.estimated:
            return {"estimated": False, "reason": self.reason, "model": self.model}
        fin = (lambda v: None if v is None or not math.isfinite(v) else round(v, 3))
        out = {"estimated": True, "model": self.model, "median_days": fin(self.median_days),
               "p10_days": fin(self.p10_days), "p90_days": fin(self.p90_days),
               "p_slope_positive": round(float(self.p_slope_positive), 4), "n_records": self.n_records,
               "assumption": ASSUMPTION}
        out["p_before"] = {str(k): round(self.p_before(v), 4) for k, v in (p_before_days or {}).items()}
        return out


def _posterior(x: np.ndarray, y: np.ndarray, prior: dict | None):
    """Normal-inverse-gamma posterior of y = b0 + b1 x + e: (mean, scale matrix V, a, b) with b | s2 ~ N(mean,
    s2 V) and s2 ~ Inv-Gamma(a, b).  ``prior``: {"mean", "cov_scale", "a", "b"} or None for the reference prior."""
    X = np.column_stack([np.ones_like(x), x])
    if prior is None:
        V = np.linalg.inv(X.T @ X)
        mean = V @ X.T @ y
        resid = y - X @ mean
        return mean, V, 0.5 * (len(y) - 2), 0.5 * float(resid @ resid)
    m0, V0 = np.asarray(prior["mean"], float), np.asarray(prior["cov_scale"], float)
    P0 = np.linalg.inv(V0)
    V = np.linalg.inv(P0 + X.T @ X)
    mean = V @ (P0 @ m0 + X.T @ y)
    a = float(prior["a"]) + 0.5 * len(y)
    b = float(prior["b"]) + 0.5 * float(y @ y + m0 @ P0 @ m0 - mean @ np.linalg.inv(V) @ mean)
    return mean, V, a, b


def estimate_rul(t_days, health_index, *, threshold: float | None, healthy_level: float = 0.0,
                 model: str = "exponential", as_of_day: float | None = None, confidence: float = 0.95,
                 min_records: int = 3, prior: dict | None = None, n_samples: int = 4000,
                 paris_margin: float = 0.0, seed: int = 0) -> RulEstimate:
    """Remaining life from the health index of the records since onset (``t_days`` in days, increasing).

    Parameters
    ----------
    t_days, health_index : sequences of float
        The records since the estimated onset and their index.
    threshold : float, array of ``n_samples`` floats, or None
        The index at the failure threshold (the index that the fault size at failure gives), or draws of it (its
        uncertainty, e.g. from the joint's own scale, carried into the Monte Carlo).  None: not estimated.
    healthy_level : float
        phi of the exponential model (the commissioning records' median index); the records at or below it are left
        out of the exponential fit (log of a non-positive excess).
    model : {"exponential", "size", "paris", "linear"}
        The exponential degradation model; a linear trend of the fault size the index implies (wear); Paris' law
        of the implied size (a root crack); or linear extrapolation of the index (the baseline).
    paris_margin : float
        ``model="paris"`` fits only the records whose index is above ``healthy_level + paris_margin``.
    as_of_day : float, optional
        The prediction time (default: the last record's).
    confidence : float
        The posterior probability of a positive slope needed to estimate (the trend must hold).
    prior : dict, optional
        A normal-inverse-gamma prior {"mean": [b0, b1], "cov_scale": 2x2, "a", "b"} on the regression (time in days
        since the first record used); default the reference prior.
    seed : int
        Seed of the Monte Carlo draws.
    """
    if model not in MODELS:
        raise ParameterError(f"model must be one of {MODELS}, got {model!r}")
    t = np.asarray(t_days, dtype=float).ravel()
    h = np.asarray(health_index, dtype=float).ravel()
    if t.shape != h.shape:
        raise ParameterError("t_days and health_index must have the same length")
    keep = np.isfinite(t) & np.isfinite(h)
    t, h = t[keep], h[keep]
    if np.any(np.diff(t) < 0):
        raise ParameterError("t_days must not decrease")
    as_of = float(t[-1]) if as_of_day is None and len(t) else (float(as_of_day) if as_of_day is not None else None)
    thr = None if threshold is None else np.asarray(threshold, dtype=float).ravel()
    params = {"threshold": None if thr is None else float(np.median(thr)), "healthy_level": float(healthy_level),
              "confidence": float(confidence), "seed": int(seed),
              "prior": "reference (1/sigma^2)" if prior is None else "normal-inverse-gamma"}
    if thr is None or not np.all(np.isfinite(thr)) or thr.size == 0:
        return RulEstimate(False, NO_THRESHOLD, model, as_of,
                           parameters=params)
    if thr.size not in (1, n_samples):
        raise ParameterError(f"threshold must be one number or {n_samples} draws")
    if model != "linear" and np.any(thr <= healthy_level):
        return RulEstimate(False, "the failure threshold is not above the healthy level", model, as_of,
                           parameters=params)
    if model == "exponential":
        use = h > healthy_level
        t, y, y_thr = t[use], np.log(h[use] - healthy_level), np.log(thr - healthy_level)
    elif model == "size":
        y, y_thr = np.sqrt(np.clip(h - healthy_level, 0.0, None)), np.sqrt(thr - healthy_level)
    elif model == "paris":
        use = h > healthy_level + paris_margin
        exponent = 0.5 * (1.0 - PARIS_M / 2.0)          # z^(1 - m/2), z = (HI - phi)^(1/2)
        t, y, y_thr = t[use], -((h[use] - healthy_level) ** exponent), -((thr - healthy_level) ** exponent)
    else:
        y, y_thr = h, thr
    n = len(t)
    if n < max(3, int(min_records)):
        return RulEstimate(False, f"{n} usable record(s) since onset, {max(3, int(min_records))} needed", model,
                           as_of, n_records=n, parameters=params)
    if np.ptp(t) <= 0:
        return RulEstimate(False, "the records since onset share one time", model, as_of, n_records=n,
                           parameters=params)
    t0 = float(t[0])
    mean, V, a, b = _posterior(t - t0, y, prior)
    if not (a > 0 and b > 0):
        return RulEstimate(False, "the trend is fitted exactly (no residual spread to judge it by)", model, as_of,
                           n_records=n, parameters=params)
    # posterior of the slope: Student t with 2a degrees of freedom, location mean[1], scale sqrt(b / a V11)
    scale = math.sqrt(b / a * V[1, 1])
    p_pos = float(stats.t.sf(0.0, df=2 * a, loc=mean[1], scale=scale))
    if p_pos < confidence:
        return RulEstimate(False, f"the trend does not hold: the slope is positive with probability {p_pos:.2f}, "
                           f"{confidence:.2f} needed", model, as_of, p_slope_positive=p_pos, n_records=n,
                           parameters=params)
    rng = np.random.default_rng(seed)
    s2 = b / rng.gamma(a, 1.0, size=n_samples)
    L = np.linalg.cholesky(V)
    coef = mean[None, :] + np.sqrt(s2)[:, None] * (rng.standard_normal((n_samples, 2)) @ L.T)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_fail = np.where(coef[:, 1] > 0, t0 + (y_thr - coef[:, 0]) / coef[:, 1], np.inf)
    rul = np.maximum(t_fail - as_of, 0.0)
    return RulEstimate(True, None, model, as_of, rul, p_pos, n, params)
