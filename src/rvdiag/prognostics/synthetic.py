"""Synthetic life histories of a joint's health index with known truth, for validating change detection and
remaining life (not signals: the health index is drawn from a stated model of the monitor's index).

The monitor's health index is a squared Mahalanobis distance of a record's features from the healthy ones over the
alarm threshold (:mod:`rvdiag.models.monitoring`).  Here, for a record with fault size ``a``,

    HI = s * chi'^2_d(lambda(a)) / q,   lambda(a) = lambda_fail (a / a_fail)^2,

chi'^2_d(lambda) a noncentral chi-square with d degrees of freedom (a mean shift of the features growing in
proportion to the fault size), q its healthy 99 % quantile (so that the index is 1 at the monitor's stated 1 % on
the population), and s ~ LogNormal(0, ``scale_spread``) the reducer's own scale: each reducer's healthy index has
its own distribution (run-to-run noise and a reducer-to-reducer offset that cross-reducer calibration cannot remove,
docs/monitoring.md).  The failure threshold on the index is the population's mean index at the failure size,
(d + lambda_fail) / q; the true failure time is when the fault size reaches its failure size.

Growth laws (truth):

* ``wear``: sun flank wear by Archard's law (:func:`rvdiag.gears.wear.wear_depth_history`) over the joint's duty
  from a drawn onset (e.g. lubricant lost), with a wear coefficient drawn log-uniformly from ``k_wear_range``; the
  size is the deepest point of the sun flank, failure at ``wear_fail_m`` (20 um: the plausibility table's heavy
  wear).
* ``crack``: a root crack of ``crack_a0_m`` at onset growing by Paris' law (:mod:`rvdiag.gears.crack_growth`) to
  ``crack_fail_fraction`` of the sun tooth's root chord, when the tooth breaks (the index jumps to the broken-tooth
  level).  The sun's own root stress at the joint's load leaves a crack below the growth threshold
  (:mod:`rvdiag.gears.crack_growth`), so the stress range is the one under which the crack reaches failure in a
  drawn propagation time (``crack_days_range``), and :class:`History` records it.  The growth threshold is left
  out (a threshold would stop these cracks: at the stresses that give 40-200 days, about the sun's own root stress,
  Delta K at 0.1 mm is under 2 MPa sqrt(m)); the histories stand for a crack that grows, not a claim that one
  does.
* ``broken``: a broken tooth at the onset (a step of the index to lambda_broken); failed at onset (detection only).
* ``healthy``: no fault.

Every draw comes from ``numpy.random.default_rng(seed)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from scipy import stats

from rvdiag.errors import ParameterError
from rvdiag.gears.crack_growth import paris_crack_depth, paris_stress_for_cycles, sun_root_stress
from rvdiag.gears.wear import DutyCycle, mesh_passes, wear_depth_history

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


@lru_cache(maxsize=8)
def _wear_curve(params, duty: DutyCycle, k_ref: float, hours_max: float):
    """Deepest sun wear against hours at ``k_ref`` (depth depends on k and hours only through their product)."""
    hours = np.concatenate([[0.0], np.geomspace(1.0, hours_max, 60)])
    depth = np.array([w.max_depth for w in wear_depth_history(params, hours, duty, k_ref)])
    return hours, depth


def _sun_root_chord(params) -> float:
    from rvdiag.gears.geometry import GearPair

    sun = GearPair.sun_planet(params).driver
    return 2.0 * sun.root_radius * math.sin(sun.root_half_angle)


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
    passes_per_day = mesh_passes(params, 24.0, spec.duty, "sun")
    if kind == "wear":
        k = float(np.exp(rng.uniform(*np.log(spec.k_wear_range))))
        k_ref = spec.k_wear_range[0]
        hours, depth = _wear_curve(params, spec.duty, k_ref, 24.0 * 3000.0 * spec.k_wear_range[1] / k_ref)
        fail_hours_ref = float(np.interp(spec.wear_fail_m, depth, hours))
        failure = onset + fail_hours_ref * k_ref / k / 24.0

        def size_at(days):
            h_ref = np.clip(days - onset, 0.0, None) * 24.0 * k / k_ref
            return np.interp(h_ref, hours, depth)
        a_fail = spec.wear_fail_m
        truth.update(k_wear=k)
    elif kind == "crack":
        a_fail = spec.crack_fail_fraction * _sun_root_chord(params)
        prop_days = float(rng.uniform(*spec.crack_days_range))
        dsigma = paris_stress_for_cycles(spec.crack_a0_m, a_fail, prop_days * passes_per_day)
        failure = onset + prop_days

        def size_at(days):
            n = np.clip(days - onset, 0.0, None) * passes_per_day
            a = paris_crack_depth(spec.crack_a0_m, n, dsigma, delta_k_th=0.0)
            return np.where(days >= onset, np.minimum(a, a_fail), 0.0)
        truth.update(stress_range_MPa=dsigma, sun_root_stress_MPa=sun_root_stress(params, spec.duty.load_Nm) / 1e6,
                     propagation_days=prop_days)
    else:
        a_fail, failure = 1.0, (onset if kind == "broken" else None)

        def size_at(days):
            return np.zeros_like(days) if kind == "healthy" else (days >= onset).astype(float)
    lam_broken = float(np.exp(rng.uniform(*np.log(spec.lambda_broken))))
    n = spec.n_records
    if failure is not None and kind in ("wear", "crack"):
        n = min(spec.max_records, max(n, int(math.ceil(failure / spec.interval_days)) + 1))
    days = spec.interval_days * np.arange(1, n + 1, dtype=float)
    size = size_at(days)
    lam = spec.lambda_fail * (size / a_fail) ** 2
    if kind == "crack":
        lam = np.where(days >= failure, np.maximum(lam, lam_broken), lam)
    elif kind == "broken":
        lam = np.where(days >= onset, lam_broken, 0.0)
    baseline = scale * rng.chisquare(spec.dof, spec.n_baseline) / q
    hi = scale * rng.noncentral_chisquare(spec.dof, np.maximum(lam, 1e-12)) / q
    return History(kind, int(seed), baseline, days, hi, size, onset, failure, spec.threshold_index, scale, truth)
