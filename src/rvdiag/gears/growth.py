"""A sun-tooth fault's size against time over a joint's life: the growth laws of a life history.

One home for the laws that both the simulated life histories of the library (``[history]``,
:mod:`rvdiag.library.life`) and the synthetic health-index histories (:mod:`rvdiag.prognostics.synthetic`) grow a
fault by.  Time is in days since commissioning; the joint runs a steady :class:`rvdiag.gears.wear.DutyCycle`.
Every law takes its drawn values (onset, coefficient, propagation time) as arguments and draws nothing itself.

* **wear** (:func:`wear_growth`): Archard's law over the duty (:func:`rvdiag.gears.wear.wear_depth_history`, run-in
  load sharing included) from the onset (e.g. the lubricant lost) with wear coefficient ``k_wear`` (m^2/N); the size
  is the deepest point of the sun flank (the severity of :class:`rvdiag.gears.Wear`).  The depth depends on ``k`` and
  the hours only through their product (the law is linear in ``k ds`` and the run-in's load shares follow the depth),
  so one curve at a reference coefficient ``k_ref`` serves every ``k``: ``depth(k, t) = depth(k_ref, t k / k_ref)``.
  Beyond the curve the depth is extended along its last segment (the wear rate of a run-in flank is constant).
* **crack** (:func:`crack_growth`): a root crack of ``a0`` at the onset growing by Paris' law
  (:func:`rvdiag.gears.crack_growth.paris_crack_depth`, BS 7910's design curve, no threshold) to ``failure_m``, when
  the tooth breaks.  The load cycles are the sun tooth's mesh passes (:func:`rvdiag.gears.wear.mesh_passes`).  The
  sun's own Lewis root stress at a robot joint's load leaves a 0.1 mm crack far below the growth threshold
  (:mod:`rvdiag.gears.crack_growth`), so the stress range is the one under which the crack reaches failure in a
  drawn ``propagation_days`` (:func:`rvdiag.gears.crack_growth.paris_stress_for_cycles`), recorded as
  ``stress_range_MPa``: these histories stand for a crack that grows, not a claim that one does at that load.
* **broken** (:func:`broken_step`): a broken tooth of a given fraction from the onset on (failed at onset).
* **healthy** (:class:`Growth`): no fault, size 0, onset and failure NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Mapping

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.gears.crack_growth import paris_crack_depth, paris_stress_for_cycles, sun_root_stress
from rvdiag.gears.wear import DutyCycle, mesh_passes, wear_depth_history

#: the kinds of growth (fates of a joint) this module grows
GROWTH_KINDS = ("healthy", "wear", "crack", "broken")


@dataclass(frozen=True, eq=False)
class Growth:
    """A fault's size against days since commissioning (this class: no fault).

    Attributes
    ----------
    kind : one of :data:`GROWTH_KINDS`
    onset_days : the fault's onset (NaN: healthy)
    failure_days : when the size reaches ``failure_size`` (NaN: healthy; the onset for a broken tooth)
    failure_size : the fate's failure threshold in the size's unit (NaN: healthy)
    truth : the law's drawn or derived values (e.g. ``k_wear``, ``stress_range_MPa``)
    """

    kind: str = "healthy"
    onset_days: float = math.nan
    failure_days: float = math.nan
    failure_size: float = math.nan
    truth: Mapping[str, float] = field(default_factory=dict)

    def size(self, days: Any) -> np.ndarray:
        """The fault's size at ``days`` (an array; 0 before the onset)."""
        return np.zeros_like(np.asarray(days, dtype=float))


@dataclass(frozen=True, eq=False)
class WearGrowth(Growth):
    """Archard wear from the onset: the reference curve ``depth_ref`` (m) against ``hours_ref`` at ``k_ref``."""

    k_wear: float = 0.0
    k_ref: float = 1.0
    hours_ref: np.ndarray = field(default_factory=lambda: np.zeros(2))
    depth_ref: np.ndarray = field(default_factory=lambda: np.zeros(2))

    def size(self, days: Any) -> np.ndarray:
        h = np.clip(np.asarray(days, dtype=float) - self.onset_days, 0.0, None) * 24.0 * self.k_wear / self.k_ref
        return _extend(h, self.hours_ref, self.depth_ref)


@dataclass(frozen=True, eq=False)
class CrackGrowth(Growth):
    """A Paris crack of ``a0_m`` at the onset under the stress range ``stress_range_MPa``, ``passes_per_day`` load
    cycles a day; held at ``failure_size`` from the failure (the tooth has broken) on."""

    a0_m: float = 1e-4
    stress_range_MPa: float = 0.0
    passes_per_day: float = 0.0

    def size(self, days: Any) -> np.ndarray:
        days = np.asarray(days, dtype=float)
        n = np.clip(days - self.onset_days, 0.0, None) * self.passes_per_day
        a = paris_crack_depth(self.a0_m, n, self.stress_range_MPa, delta_k_th=0.0)
        a = np.where(days >= self.failure_days, self.failure_size, np.minimum(a, self.failure_size))
        return np.where(days >= self.onset_days, a, 0.0)


@dataclass(frozen=True, eq=False)
class StepGrowth(Growth):
    """A fault of constant size ``failure_size`` from the onset on (a broken tooth: its broken fraction)."""

    def size(self, days: Any) -> np.ndarray:
        return np.where(np.asarray(days, dtype=float) >= self.onset_days, self.failure_size, 0.0)


def _extend(x: np.ndarray, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    """``np.interp(x, xp, fp)``, continued beyond ``xp[-1]`` along the last segment."""
    y = np.interp(x, xp, fp)
    slope = (fp[-1] - fp[-2]) / (xp[-1] - xp[-2])
    return np.where(x > xp[-1], fp[-1] + slope * (x - xp[-1]), y)


@lru_cache(maxsize=8)
def wear_curve(params: Any, duty: DutyCycle, k_ref: float, hours_max: float) -> tuple[np.ndarray, np.ndarray]:
    """The deepest sun wear (m) against hours in service (0 and 60 hours geometrically spaced from 1 to
    ``hours_max``) at wear coefficient ``k_ref`` under ``duty`` (one integration of
    :func:`rvdiag.gears.wear.wear_depth_history`; cached: a few seconds)."""
    hours = np.concatenate([[0.0], np.geomspace(1.0, hours_max, 60)])
    depth = np.array([w.max_depth for w in wear_depth_history(params, hours, duty, k_ref)])
    return hours, depth


def wear_growth(params: Any, duty: DutyCycle, onset_days: float, k_wear: float, failure_m: float, *,
                k_ref: float, hours_ref_max: float) -> WearGrowth:
    """Archard wear of the sun flank from ``onset_days`` with coefficient ``k_wear`` (m^2/N), failing at the depth
    ``failure_m`` (m), on the curve of :func:`wear_curve` at ``k_ref`` up to ``hours_ref_max`` reference hours
    (module docstring).

    >>> from rvdiag.params import ReducerParams
    >>> g = wear_growth(ReducerParams.default(), DutyCycle(30.0, 120.0, 0.5), 10.0, 2e-17, 20e-6, k_ref=1e-17,
    ...                 hours_ref_max=24 * 3000 * 3.0)
    >>> bool(g.size([5.0])[0] == 0 and abs(g.size([g.failure_days])[0] - 20e-6) < 1e-9)
    True
    """
    if not (k_wear > 0 and k_ref > 0 and failure_m > 0):
        raise ParameterError("the wear coefficients and the failure depth must be > 0")
    hours, depth = wear_curve(params, duty, float(k_ref), float(hours_ref_max))
    if depth[-1] > failure_m:
        fail_hours_ref = float(np.interp(failure_m, depth, hours))
    else:  # beyond the curve: along its last segment
        fail_hours_ref = float(hours[-1] + (failure_m - depth[-1]) * (hours[-1] - hours[-2]) / (depth[-1] - depth[-2]))
    failure = onset_days + fail_hours_ref * k_ref / k_wear / 24.0
    return WearGrowth("wear", float(onset_days), float(failure), float(failure_m), {"k_wear": float(k_wear)},
                      k_wear=float(k_wear), k_ref=float(k_ref), hours_ref=hours, depth_ref=depth)


def crack_growth(params: Any, duty: DutyCycle, onset_days: float, a0_m: float, failure_m: float,
                 propagation_days: float) -> CrackGrowth:
    """A root crack of ``a0_m`` at ``onset_days`` growing by Paris' law to ``failure_m`` in ``propagation_days``
    under the duty's sun mesh passes (module docstring); the truth records the stress range this takes, the sun's own
    Lewis root stress at the duty's load (MPa) and the propagation days.

    >>> from rvdiag.params import ReducerParams
    >>> g = crack_growth(ReducerParams.default(), DutyCycle(30.0, 120.0, 0.5), 20.0, 1e-4, 1.5e-3, 100.0)
    >>> a = g.size([19.0, 20.0, 70.0, 120.0, 200.0])
    >>> bool(a[0] == 0 and abs(a[1] - 1e-4) < 1e-15 and 2e-4 < a[2] < 1.5e-3 and a[3] == a[4] == 1.5e-3)
    True
    """
    if not (0 < a0_m < failure_m and propagation_days > 0):
        raise ParameterError("a crack needs 0 < a0 < its failure depth and a propagation time > 0")
    passes_per_day = mesh_passes(params, 24.0, duty, "sun")
    dsigma = paris_stress_for_cycles(a0_m, failure_m, propagation_days * passes_per_day)
    truth = {"stress_range_MPa": float(dsigma), "sun_root_stress_MPa": sun_root_stress(params, duty.load_Nm) / 1e6,
             "propagation_days": float(propagation_days)}
    return CrackGrowth("crack", float(onset_days), float(onset_days + propagation_days), float(failure_m), truth,
                       a0_m=float(a0_m), stress_range_MPa=float(dsigma), passes_per_day=float(passes_per_day))


def broken_step(onset_days: float, fraction: float = 1.0) -> StepGrowth:
    """A broken tooth of ``fraction`` from ``onset_days`` on: failed at the onset."""
    return StepGrowth("broken", float(onset_days), float(onset_days), float(fraction))


def sun_root_chord(params: Any) -> float:
    """The chord (m) of a sun tooth at its root circle: the scale of a root crack's failure depth."""
    from rvdiag.gears.geometry import GearPair

    sun = GearPair.sun_planet(params).driver
    return 2.0 * sun.root_radius * math.sin(sun.root_half_angle)
