"""Synthetic life histories of a joint's health index with known truth, for validating change detection and
remaining life (not signals: the health index is drawn from a stated model of the monitor's index).

The monitor's health index is a squared Mahalanobis distance of a record's features from the healthy ones over the
alarm threshold (:mod:`rvdiag.monitoring.detector`).  Here, for a record with fault size ``a``,

    HI = s * chi'^2_d(lambda(a)) / q,   lambda(a) = lambda_fail (a / a_fail)^2,

chi'^2_d(lambda) a noncentral chi-square with d degrees of freedom (a mean shift of the features growing in
proportion to the fault size), q its healthy 99 % quantile (so that the index is 1 at the monitor's stated 1 % on
the population), and s ~ LogNormal(0, ``scale_spread``) the reducer's own scale: each reducer's healthy index has
its own distribution (run-to-run noise and a reducer-to-reducer offset that cross-reducer calibration cannot remove,
docs/monitoring.md).  The failure threshold on the index is the population's mean index at the failure size,
(d + lambda_fail) / q; the true failure time is when the fault size reaches its failure size.

Growth laws (truth), from :mod:`rvdiag.gears.growth` (their one home, shared with the library's simulated life
histories, :mod:`rvdiag.library.life`):

* ``wear``: sun flank wear by Archard's law (:func:`rvdiag.gears.growth.wear_growth`) over the joint's duty from a
  drawn onset (e.g. lubricant lost), with a wear coefficient drawn log-uniformly from ``k_wear_range``; the size is
  the deepest point of the sun flank, failure at ``wear_fail_m`` (20 um: the plausibility table's heavy wear).
* ``crack``: a root crack of ``crack_a0_m`` at onset growing by Paris' law (:func:`rvdiag.gears.growth.crack_growth`)
  to ``crack_fail_fraction`` of the sun tooth's root chord in a drawn propagation time (``crack_days_range``), when
  the tooth breaks (the index jumps to the broken-tooth level); :class:`History` records the stress range this
  takes.  The growth threshold is left out (a threshold would stop these cracks: at the stresses that give 40-200
  days, about the sun's own root stress, Delta K at 0.1 mm is under 2 MPa sqrt(m)); the histories stand for a crack
  that grows, not a claim that one does.
* ``broken``: a broken tooth at the onset (a step of the index to lambda_broken); failed at onset (detection only).
* ``healthy``: no fault.

Every draw comes from ``numpy.random.default_rng(seed)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from rvdiag.errors import ParameterError
from rvdiag.gears.growth import Growth, broken_step, crack_growth, sun_root_chord, wear_growth
from rvdiag.gears.wear import DutyCycle

KINDS = ("healthy", "wear", "crack", "broken")


@dataclass(frozen=True)
class HistorySpec:
    """How the synthetic histories are drawn (module docstring)."""

    n_baseline: int = 20
    n_records: int = 60
    interval_days: float = 7.0
    dof: int = 8
    lambda_fail: float = 200.0
    lambda_broken: tuple = (300.0, 3000.0)
    scale_spread: float = 0.25
    onset_days: tuple = (30.0, 200.0)
    duty: DutyCycle = DutyCycle(30.0, 120.0, 0.5)
    k_wear_range: tuple = (1.0e-17, 3.0e-17)
    wear_fail_m: float = 20e-6
    crack_a0_m: float = 0.1e-3
    crack_fail_fraction: float = 0.5
    crack_days_range: tuple = (40.0, 200.0)
    max_records: int = 200

    @property
    def quantile99(self) -> float:
        return float(stats.chi2.ppf(0.99, self.dof))

    @property
    def reference_level(self) -> float:
        """The population's median healthy index."""
        return float(stats.chi2.median(self.dof)) / self.quantile99

    @property
    def threshold_index(self) -> float:
        """The population's mean index at the failure size."""
        return (self.dof + self.lambda_fail) / self.quantile99


@dataclass
class History:
    """One joint's synthetic life: commissioning indices, then records (days after commissioning) with their index
    and fault size, and the truth."""

    kind: str
    seed: int
    baseline: np.ndarray
    days: np.ndarray
    health_index: np.ndarray
    size: np.ndarray
    onset_day: float | None
    failure_day: float | None
    threshold_index: float
    scale: float
    truth: dict = field(default_factory=dict)

    @property
    def onset_index(self) -> int | None:
        """The first record at or after the onset."""
        if self.onset_day is None:
            return None
        i = int(np.searchsorted(self.days, self.onset_day, side="left"))
        return i if i < len(self.days) else None


def draw_history(kind: str, seed: int, params, spec: HistorySpec = HistorySpec()) -> History:
    """One synthetic history of ``kind`` (``KINDS``) for the reducer ``params`` (module docstring).

    >>> from rvdiag.params import ReducerParams
    >>> h = draw_history("wear", 3, ReducerParams.default())
    >>> bool(h.failure_day > h.onset_day and h.size[-1] >= 20e-6 > h.size[0])
    True
    """
    if kind not in KINDS:
        raise ParameterError(f"kind must be one of {KINDS}, got {kind!r}")
    rng = np.random.default_rng(seed)
    scale = float(np.exp(rng.normal(0.0, spec.scale_spread)))
    onset = float(rng.uniform(*spec.onset_days)) if kind != "healthy" else None
    q = spec.quantile99
    truth: dict = {}
    if kind == "wear":
        k = float(np.exp(rng.uniform(*np.log(spec.k_wear_range))))
        k_ref = spec.k_wear_range[0]
        growth = wear_growth(params, spec.duty, onset, k, spec.wear_fail_m, k_ref=k_ref,
                             hours_ref_max=24.0 * 3000.0 * spec.k_wear_range[1] / k_ref)
    elif kind == "crack":
        a_fail = spec.crack_fail_fraction * sun_root_chord(params)
        growth = crack_growth(params, spec.duty, onset, spec.crack_a0_m, a_fail,
                              float(rng.uniform(*spec.crack_days_range)))
    elif kind == "broken":
        growth = broken_step(onset, 1.0)
    else:
        growth = Growth()
    truth.update(growth.truth)
    a_fail = 1.0 if kind in ("healthy", "broken") else growth.failure_size
    failure = None if kind == "healthy" else growth.failure_days
    lam_broken = float(np.exp(rng.uniform(*np.log(spec.lambda_broken))))
    n = spec.n_records
    if failure is not None and kind in ("wear", "crack"):
        n = min(spec.max_records, max(n, int(math.ceil(failure / spec.interval_days)) + 1))
    days = spec.interval_days * np.arange(1, n + 1, dtype=float)
    size = growth.size(days)
    lam = spec.lambda_fail * (size / a_fail) ** 2
    if kind == "crack":
        lam = np.where(days >= failure, np.maximum(lam, lam_broken), lam)
    elif kind == "broken":
        lam = np.where(days >= onset, lam_broken, 0.0)
    baseline = scale * rng.chisquare(spec.dof, spec.n_baseline) / q
    hi = scale * rng.noncentral_chisquare(spec.dof, np.maximum(lam, 1e-12)) / q
    return History(kind, int(seed), baseline, days, hi, size, onset, failure, spec.threshold_index, scale, truth)
