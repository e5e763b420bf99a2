"""Sequential change detection on a joint's stream of record scores, with a stated lifetime false-alarm probability.

Conformal test martingale (the detector whose bound holds per joint)
---------------------------------------------------------------------
Each record's score (higher = further from healthy, e.g. the monitor's health index) is ranked among the joint's
own earlier scores, its commissioning records first.  The smoothed conformal p-value of the n-th score ``s_n``
(Vovk, Nouretdinov & Gammerman 2003, "Testing exchangeability on-line", ICML, eq. (2)) is

    p_n = (#{i <= n: s_i > s_n} + theta_n #{i <= n: s_i = s_n}) / n,      theta_n ~ U(0, 1),

so that a large score gets a small p-value.  If the scores are exchangeable (a healthy joint whose records differ
only by run-to-run variation), p_1, p_2, ... are independent and uniform on [0, 1] (ibid., Theorem 1), whatever
the scores' distribution: the reducer's own spread is what the record is ranked against, not a threshold
calibrated on other reducers.

A betting function f >= 0 with integral 1 over [0, 1] turns the p-values into a test martingale
M_n = prod f(p_i) (E[f(p)] = 1 under uniformity).  Ville's inequality (Ville 1939; Vovk et al. 2003, eq. (3))
bounds the probability that it *ever* reaches 1/delta:

    P(sup_n M_n >= 1/delta) <= delta,

so an alarm at M_n >= 1/delta has a false-alarm probability of at most delta over the joint's whole life, however
many records it has (delta = 1 % per joint-life by default).

Betting: a composite jumper.  Vovk et al.'s Simple Jumper (Vovk, Petej, Nouretdinov, Ahlberg, Carlsson &
Gammerman 2021, "Retrain or not retrain: conformal test martingales for change-point detection", COPA, PMLR 152,
Algorithm 1) keeps capital in several betting functions and moves a share ``J`` (the jump rate) of the total
between them at each record, so that the capital of a function that bets on the change is never far below the
total when the change comes.  Its linear betting functions 1 + eps (p - 1/2) gain at most 1.5x per record, and
Vovk et al. 2003's power functions eps p^(eps - 1) at most about n / (e ln n) with n earlier records (about 5 for
n = 50), too slowly for a record every few days.  Here the functions are steps that bet on small p-values (a score
above the joint's earlier ones): f_a(p) = kappa + (1 - kappa) / a for p <= a, kappa otherwise (integral 1), a in
``levels``, beside the function f = 1 that does not bet (the Simple Jumper's eps = 0).  Each record:
C_k <- (1 - J) C_k + J w_k sum_j C_j, then C_k <- C_k f_k(p_n); the total sum_k C_k is a test martingale (each f_k
integrates to 1 over [0, 1] and the redistribution keeps the total), so Ville's bound holds as stated.  The
defaults (levels 0.05, 0.1, 0.2, kappa 0.2, J 0.1, half the redistributed capital to f = 1) were chosen on
the synthetic histories of bench/prognostics.py (bench/HISTORY.md): smaller levels speak a record sooner after a
broken tooth but leave some broken teeth unalarmed for good (below).

How fast it can speak: with n earlier scores a record above all of them gets p ~ U(0, 1/(n + 1)), so no betting
function can gain more than a factor n + 1 from one record, and an alarm needs at least log(1/delta) / log(n + 1)
records after a change (2 for delta = 1 % and n between 10 and 99), more since the k-th record after a step is
ranked among the k - 1 faulty records before it, so that its p-value is about U(0, k / (n + k)): the evidence a
lasting change gives shrinks record by record, and a martingale that has not alarmed within the first several
records after a step may never alarm.  A joint with few commissioning records is slow to alarm.

Onset estimate: the record after the martingale's last minimum before the alarm (where the evidence began rising;
as CUSUM's change-point estimate, Page 1954).

Classical comparison (no lifetime bound; the false-alarm rate grows with the number of records)
-----------------------------------------------------------------------------------------------
Both work on scores standardised by the commissioning records' mean and standard deviation, z = (s - mu0) / sd0.

* CUSUM (Page 1954, Biometrika 41, 100-115): S_n = max(0, S_{n-1} + z_n - k), alarm at S_n > h; k = 0.5 and
  h = 5 (Montgomery, "Introduction to Statistical Quality Control", 6th ed., sec. 9.1.3: in-control ARL about 465
  for Gaussian data, a one-standard-deviation shift detected in about 10 records).
* Page-Hinkley (Page 1954; Hinkley 1971, Biometrika 58, 509-523; as in Gama et al. 2014, ACM Comput. Surv. 46(4),
  sec. 3.2): m_n = sum_{i<=n} (z_i - zbar_i - delta_ph), alarm at m_n - min_{i<=n} m_i > lambda_ph; delta_ph = 0.5,
  lambda_ph = 5 (the same tuning, in standardised units), zbar the running mean over all records so far (the
  commissioning records first).

Each detector is a small class with ``update(score) -> DetectorState`` and ``run(scores) -> Detection``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.validation import finite_array, finite_number

#: default lifetime false-alarm probability per joint
DEFAULT_DELTA = 0.01


@dataclass(frozen=True)
class DetectorState:
    """A detector's state after one record: its statistic, whether it has alarmed (latching: once it alarms it stays
    alarmed), the record index of the first alarm and of the estimated onset (None before an alarm), and the
    record's conformal p-value (None for CUSUM and Page-Hinkley)."""

    index: int
    statistic: float
    alarm: bool
    alarm_index: int | None
    onset_index: int | None
    p_value: float | None = None


@dataclass
class Detection:
    """A detector's run over a stream: the statistic after each record, the first alarm's record index (None if it
    never alarmed) and the estimated onset's record index, and the p-values (conformal martingale only)."""

    statistic: np.ndarray
    threshold: float
    alarm_index: int | None
    onset_index: int | None
    p_values: np.ndarray | None = None
    parameters: dict = field(default_factory=dict)

    @property
    def alarmed(self) -> bool:
        return self.alarm_index is not None


class _Detector:
    """Shared bookkeeping: the statistic's history, the latching alarm and the onset (the record after the
    statistic's last minimum before the alarm)."""

    threshold: float

    def _reset_history(self) -> None:
        self._n = 0
        self._min_value = math.inf
        self._min_index = 0
        self.alarm_index: int | None = None
        self.onset_index: int | None = None

    def _record(self, stat: float, p: float | None = None) -> DetectorState:
        i = self._n
        self._n += 1
        if self.alarm_index is None:
            if stat >= self.threshold:
                self.alarm_index = i
                self.onset_index = self._min_index
            elif stat <= self._min_value:
                # the record after the last minimum is where the evidence began rising
                self._min_value, self._min_index = stat, i + 1
        return DetectorState(i, float(stat), self.alarm_index is not None, self.alarm_index, self.onset_index, p)

    def run(self, scores) -> Detection:
        """Feed every score in order (after the commissioning records given at construction)."""
        stats, ps = [], []
        for s in finite_array(scores, "scores"):
            st = self.update(float(s))
            stats.append(st.statistic)
            ps.append(st.p_value)
        p_values = np.array(ps, dtype=float) if ps and ps[0] is not None else None
        return Detection(np.array(stats), float(self.threshold), self.alarm_index, self.onset_index, p_values,
                         self.parameters())

    def update(self, score: float) -> DetectorState:  # pragma: no cover - abstract
        raise NotImplementedError

    def parameters(self) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError


class ConformalMartingale(_Detector):
    """Conformal test martingale (composite jumper of step betting functions) on a joint's record scores.

    Parameters
    ----------
    baseline_scores : sequence of float
        The commissioning records' scores, in order: the first members of the bag that later records are ranked
        among (no bets are placed on them).
    delta : float
        Lifetime false-alarm probability: alarm when the martingale reaches 1/delta (Ville's inequality).
    levels : tuple of float
        The p-value levels a of the step betting functions (module docstring), each in (0, 1).
    kappa : float
        What a step betting function keeps of its capital when the p-value is above its level, in [0, 1).
    jump : float
        The jump rate J: the share of the total capital redistributed at each record (Vovk et al. 2021).
    stay_weight : float
        The share of the redistributed capital given to the function that does not bet (f = 1); the rest is shared
        equally by the step functions.
    seed : int
        Seed of the smoothing draws theta_n (every random draw from a recorded seed).

    Examples
    --------
    >>> det = ConformalMartingale([1.0, 1.2, 0.9, 1.1, 1.05] * 6, seed=0)
    >>> det.run([1.0, 0.95, 9.0, 9.5, 8.0, 9.9, 9.1]).alarm_index
    6
    """

    def __init__(self, baseline_scores=(), *, delta: float = DEFAULT_DELTA, levels=(0.05, 0.1, 0.2),
                 kappa: float = 0.2, jump: float = 0.1, stay_weight: float = 0.5, seed: int = 0):
        if not 0.0 < float(delta) < 1.0:
            raise ParameterError(f"delta must be in (0, 1), got {delta!r}")
        eps = tuple(float(e) for e in levels)
        if not eps or any(not 0.0 < e < 1.0 for e in eps):
            raise ParameterError(f"levels must be numbers in (0, 1), got {levels!r}")
        if not 0.0 <= float(kappa) < 1.0:
            raise ParameterError(f"kappa must be in [0, 1), got {kappa!r}")
        self.kappa = float(kappa)
        if not 0.0 <= float(jump) <= 1.0 or not 0.0 <= float(stay_weight) < 1.0:
            raise ParameterError("jump must be in [0, 1] and stay_weight in [0, 1)")
        self.delta, self.levels, self.jump, self.stay_weight, self.seed = float(delta), eps, float(jump), \
            float(stay_weight), int(seed)
        self.threshold = 1.0 / self.delta
        self._rng = np.random.default_rng(self.seed)
        self._weights = np.array([self.stay_weight] + [(1.0 - self.stay_weight) / len(eps)] * len(eps))
        self._capital = self._weights.copy()          # the martingale starts at 1
        self._bag = np.sort(finite_array(baseline_scores, "baseline_scores"))
        self.n_baseline = len(self._bag)
        self._reset_history()
        self._min_value = 1.0                          # M_0 = 1: a martingale that only rises has its minimum before
        self._min_index = 0

    def parameters(self) -> dict:
        return {"method": "conformal test martingale (composite jumper, step betting)", "delta": self.delta,
                "threshold": self.threshold, "levels": list(self.levels), "kappa": self.kappa, "jump": self.jump,
                "stay_weight": self.stay_weight, "seed": self.seed, "n_baseline": int(self.n_baseline)}

    def p_value(self, score: float) -> float:
        """The smoothed conformal p-value of ``score`` among the bag and itself, and add it to the bag."""
        lo = np.searchsorted(self._bag, score, side="left")
        hi = np.searchsorted(self._bag, score, side="right")
        n = len(self._bag) + 1
        greater, equal = len(self._bag) - hi, hi - lo + 1
        p = (greater + self._rng.uniform() * equal) / n
        self._bag = np.insert(self._bag, hi, score)
        return float(p)

    def bet(self, p: float) -> float:
        """Update the capital with p-value ``p`` and return the martingale (the total capital)."""
        total = self._capital.sum()
        self._capital = (1.0 - self.jump) * self._capital + self.jump * self._weights * total
        k = self.kappa
        factors = np.array([1.0] + [k + (1.0 - k) / a if p <= a else k for a in self.levels])
        self._capital = self._capital * factors
        return float(self._capital.sum())

    def update(self, score: float) -> DetectorState:
        p = self.p_value(float(score))
        return self._record(self.bet(p), p)


class _Standardised(_Detector):
    def __init__(self, baseline_scores, threshold: float):
        base = finite_array(baseline_scores, "baseline_scores")
        if len(base) < 2:
            raise ParameterError("CUSUM and Page-Hinkley need at least 2 commissioning scores to standardise by")
        sd = float(np.std(base, ddof=1))
        if not sd > 0:
            raise ParameterError("the commissioning scores do not vary: cannot standardise by their spread")
        self.mean0, self.sd0, self.threshold = float(np.mean(base)), sd, float(threshold)
        self._n_base = len(base)
        self._reset_history()
        self._min_value = 0.0


class Cusum(_Standardised):
    """Page's one-sided CUSUM on standardised scores: S_n = max(0, S_{n-1} + z_n - k), alarm at S_n > h.

    >>> Cusum([1.0, 1.1, 0.9, 1.0], k=0.5, h=5.0).run([1.0, 3.0, 3.0, 3.0]).alarm_index
    1
    """

    def __init__(self, baseline_scores, *, k: float = 0.5, h: float = 5.0):
        super().__init__(baseline_scores, h)
        self.k, self._s = float(k), 0.0

    def parameters(self) -> dict:
        return {"method": "CUSUM (Page 1954)", "k": self.k, "h": self.threshold,
                "standardised_by": {"mean": self.mean0, "sd": self.sd0}}

    def update(self, score: float) -> DetectorState:
        self._s = max(0.0, self._s + (float(score) - self.mean0) / self.sd0 - self.k)
        # the CUSUM's onset: the record after it last left zero
        return self._record(self._s)


class PageHinkley(_Standardised):
    """Page-Hinkley test on standardised scores: m_n = sum (z_i - zbar_i - delta), alarm at m_n - min m > lambda.

    >>> PageHinkley([1.0, 1.1, 0.9, 1.0]).run([1.0, 3.0, 3.0, 3.0, 3.0]).alarm_index
    1
    """

    def __init__(self, baseline_scores, *, delta: float = 0.5, lam: float = 5.0):
        super().__init__(baseline_scores, lam)
        base = (finite_array(baseline_scores, "baseline_scores") - self.mean0) / self.sd0
        self.delta_ph, self._sum_z, self._count, self._m, self._m_min = float(delta), float(base.sum()), \
            len(base), 0.0, 0.0

    def parameters(self) -> dict:
        return {"method": "Page-Hinkley (Page 1954; Hinkley 1971)", "delta": self.delta_ph, "lambda": self.threshold,
                "standardised_by": {"mean": self.mean0, "sd": self.sd0}}

    def update(self, score: float) -> DetectorState:
        z = (float(score) - self.mean0) / self.sd0
        self._sum_z += z
        self._count += 1
        self._m += z - self._sum_z / self._count - self.delta_ph
        self._m_min = min(self._m_min, self._m)
        return self._record(self._m - self._m_min)


class Persistence(_Detector):
    """The monitor's own per-record alarm with persistence: alarm when ``k`` of the last ``n`` records have an
    index above ``level`` (ISO 17359's alarm criteria; the fleet's k-of-n rule, :mod:`rvdiag.fleet.rules`).  The
    monitor's health index is its change over its alarm threshold, so ``level`` 1 is its own alarm at its stated
    per-record rate, calibrated across reducers: no lifetime bound, and a reducer whose healthy index runs high
    alarms more often than stated (docs/monitoring.md).  The statistic is the count of alarming records among the
    last ``n``; the onset is the first alarming record of the window that raised the alarm.

    >>> Persistence(k=3, n=3).run([0.5, 2.0, 0.4, 3.0, 5.0, 4.0]).alarm_index
    5
    """

    def __init__(self, *, level: float = 1.0, k: int = 3, n: int = 3):
        if not (isinstance(k, int) and isinstance(n, int) and 1 <= k <= n):
            raise ParameterError(f"persistence k of n needs 1 <= k <= n, got k={k!r}, n={n!r}")
        self.level = finite_number(level, "level")
        self.k, self.n, self.threshold = k, n, float(k)
        self._window: list[bool] = []
        self._reset_history()

    def parameters(self) -> dict:
        return {"method": "the monitor's per-record alarm, k of the last n (ISO 17359)", "level": self.level,
                "k": self.k, "n": self.n}

    def update(self, score: float) -> DetectorState:
        self._window = (self._window + [float(score) > self.level])[-self.n:]
        count = sum(self._window)
        i = self._n
        st = self._record(float(count))
        if st.alarm and self.alarm_index == i:
            first = len(self._window) - self._window.index(True)
            self.onset_index = i - first + 1
            st = DetectorState(st.index, st.statistic, True, self.alarm_index, self.onset_index, None)
        return st
