"""Profile modification (tip and root relief) and manufacturing errors of a spur pair, as per-pair separations.

A relieved or inaccurate flank does not only change a tooth's beam stiffness: it moves the flank away from the
perfect involute, so that a tooth pair touches only once the mesh approach exceeds that pair's *separation*
``e_j`` (Chen & Shao 2013, Mech. Mach. Theory 62, 63-74; Ma, Pang, Feng & Wang 2016, Mech. Mach. Theory 98,
64-80).  The dynamic model therefore carries one separation per pair in contact and lets each pair carry
``k_j (delta - e_j)`` only where that is positive (:mod:`rvdiag.dynamics.model`).

Positions are roll lengths ``s`` along the path of contact, ``0 <= s <= L`` (:meth:`GearPair.contact_state`):
a pair enters at ``s = 0`` (the driven gear's tip on the driver's root) and leaves at ``s = L`` (the driver's tip
on the driven gear's root).

Relief (ISO 21771:2007, section 8.3, "tip relief" / "root relief"; design rule of Walker 1938, The Engineer
166): an amount ``C`` at the tip (root) of a gear, falling to zero over a roll length ``L_C``, linearly or
parabolically:

    e(s) = C * (x / L_C) ** p,  x = distance into the relief zone, p = 1 (linear) or 2 (parabolic).

Manufacturing errors of an ISO 1328-1:2013 flank tolerance grade ``A`` (tolerances in um, ``d`` and ``m`` in
mm, :func:`iso1328_tolerances`): every tooth of the sun gets a single pitch deviation drawn uniformly within
``+- f_pT / 2`` from a seeded generator, and every tooth the same profile slope deviation ``f_Ha / 2``
(linear along the profile; ISO 1328-1 section 3.3.3).  Deviations are drawn at half the tolerance: a gear of
grade A meets its tolerances with margin, not at their limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rvdiag.errors import ParameterError

RELIEF_SHAPES = ("linear", "parabolic")


@dataclass(frozen=True)
class ProfileModification:
    """Tip and root relief of both gears of a pair (amounts and lengths in m, along the line of action).

    Parameters
    ----------
    tip_relief_driver, tip_relief_driven : float
        Relief amount at the tip of the driver (sun) and of the driven gear (planet), m.
    root_relief_driver, root_relief_driven : float
        Relief amount at the start of the active profile near the root, m.
    tip_relief_length, root_relief_length : float
        Roll length over which each relief falls to zero, m (``0`` with a zero amount).
    shape : str
        ``"parabolic"`` (default) or ``"linear"``.
    """

    tip_relief_driver: float = 0.0
    tip_relief_driven: float = 0.0
    root_relief_driver: float = 0.0
    root_relief_driven: float = 0.0
    tip_relief_length: float = 0.0
    root_relief_length: float = 0.0
    shape: str = "parabolic"

    def __post_init__(self) -> None:
        for name in ("tip_relief_driver", "tip_relief_driven", "root_relief_driver", "root_relief_driven",
                     "tip_relief_length", "root_relief_length"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ParameterError(f"{name} must be a number >= 0 (m), got {v!r}")
        if self.shape not in RELIEF_SHAPES:
            raise ParameterError(f"relief shape must be one of {RELIEF_SHAPES}, got {self.shape!r}")
        if (self.tip_relief_driver or self.tip_relief_driven) and self.tip_relief_length <= 0:
            raise ParameterError("a tip relief amount needs tip_relief_length > 0")
        if (self.root_relief_driver or self.root_relief_driven) and self.root_relief_length <= 0:
            raise ParameterError("a root relief amount needs root_relief_length > 0")

    @property
    def is_zero(self) -> bool:
        return not (self.tip_relief_driver or self.tip_relief_driven or self.root_relief_driver
                    or self.root_relief_driven)


def _ramp(x: np.ndarray, length: float, power: int) -> np.ndarray:
    """``(x / length) ** power`` for ``x > 0``, else 0 (x measured into the relief zone)."""
    if length <= 0.0:
        return np.zeros_like(x)
    r = np.clip(x / length, 0.0, None)
    return r**power


def relief_separation(roll: np.ndarray, path_length: float, mod: ProfileModification) -> np.ndarray:
    """Separation (m) of a tooth pair at roll positions ``roll`` on a path of contact of length ``path_length``.

    Driver tip relief acts near the exit ``s = L``, driven tip relief near the entry ``s = 0``; driver root
    relief near the entry and driven root relief near the exit (module docstring).
    """
    s = np.asarray(roll, dtype=float)
    p = 2 if mod.shape == "parabolic" else 1
    L = float(path_length)
    la, lf = mod.tip_relief_length, mod.root_relief_length
    e = mod.tip_relief_driver * _ramp(s - (L - la), la, p)
    e = e + mod.tip_relief_driven * _ramp(la - s, la, p)
    e = e + mod.root_relief_driver * _ramp(lf - s, lf, p)
    e = e + mod.root_relief_driven * _ramp(s - (L - lf), lf, p)
    return e


@dataclass(frozen=True)
class FlankTolerances:
    """ISO 1328-1:2013 flank tolerances of one gear (m): single pitch, total profile, form and slope, and the
    total cumulative pitch and the runout."""

    grade: int
    single_pitch: float
    profile_total: float
    profile_form: float
    profile_slope: float
    total_cumulative_pitch: float = 0.0
    runout: float = 0.0


def iso1328_tolerances(module_m: float, pitch_diameter_m: float, grade: int) -> FlankTolerances:
    """Flank tolerances of ISO 1328-1:2013 (section 5.2, eqs. (1)-(4)) for flank tolerance class ``grade``.

    With ``m`` and ``d`` in mm and the tolerances in um, and the step factor ``sqrt(2) ** (A - 5)``:

    - single pitch ``f_pT = (0.001 d + 0.4 m + 5)``
    - total profile ``F_aT = (3.2 sqrt(m) + 0.22 sqrt(d) + 0.7)``
    - profile form ``f_faT = (2.5 sqrt(m) + 0.17 sqrt(d) + 0.5)``
    - profile slope ``f_HaT = (2 sqrt(m) + 0.14 sqrt(d) + 0.5)``
    - total cumulative pitch ``F_pT = (0.002 d + 0.55 sqrt(d) + 0.7 m + 12)`` and the runout tolerance
      ``F_rT = 0.9 F_pT`` given with it (the planets' runout of :mod:`rvdiag.dynamics.manufacturing`)

    >>> t = iso1328_tolerances(1.25e-3, 13.75e-3, 5)
    >>> round(t.single_pitch * 1e6, 2), round(t.profile_slope * 1e6, 2)
    (5.51, 3.26)
    >>> round(iso1328_tolerances(1.25e-3, 41.25e-3, 5).runout * 1e6, 1)
    14.8
    """
    if isinstance(grade, bool) or int(grade) != grade or not 1 <= grade <= 11:
        raise ParameterError(f"ISO 1328 flank tolerance class must be a whole number 1..11, got {grade!r}")
    m, d = module_m * 1e3, pitch_diameter_m * 1e3
    if not (m > 0 and d > 0):
        raise ParameterError("module and pitch diameter must be > 0")
    step = math.sqrt(2.0) ** (int(grade) - 5)
    um = 1e-6 * step
    return FlankTolerances(
        grade=int(grade),
        single_pitch=(0.001 * d + 0.4 * m + 5.0) * um,
        profile_total=(3.2 * math.sqrt(m) + 0.22 * math.sqrt(d) + 0.7) * um,
        profile_form=(2.5 * math.sqrt(m) + 0.17 * math.sqrt(d) + 0.5) * um,
        profile_slope=(2.0 * math.sqrt(m) + 0.14 * math.sqrt(d) + 0.5) * um,
        total_cumulative_pitch=(0.002 * d + 0.55 * math.sqrt(d) + 0.7 * m + 12.0) * um,
        runout=0.9 * (0.002 * d + 0.55 * math.sqrt(d) + 0.7 * m + 12.0) * um,
    )


def tooth_position_errors(teeth: int, tol: FlankTolerances, seed: int) -> np.ndarray:
    """Position error of every tooth flank along the line of action (m): the running sum of single pitch
    deviations drawn uniformly in ``+- f_pT / 2`` from ``default_rng(seed)``, made to close over one
    revolution (deviations of zero sum) and taken relative to the mean position (a common offset is a
    rotation, not an error)."""
    rng = np.random.default_rng(seed)
    dev = rng.uniform(-0.5, 0.5, size=int(teeth)) * tol.single_pitch
    pos = np.cumsum(dev - dev.mean())
    return pos - pos.mean()


def profile_slope_separation(roll: np.ndarray, path_length: float, tol: FlankTolerances) -> np.ndarray:
    """Separation (m) from a profile slope deviation of ``f_HaT / 2``, the same on every tooth: material missing
    at the entry side and added at the exit side, linear in the roll position, zero mean over the path."""
    s = np.asarray(roll, dtype=float)
    return 0.5 * tol.profile_slope * (0.5 - s / float(path_length))


def corner_contact_coefficient(rho_driver: float, rho_driven: float, base_radius_cornered: float,
                               rho_cornered: float) -> float:
    """Coefficient ``c`` (1/m) of the separation ``c s^2`` of a tooth pair whose contact point has moved a roll
    distance ``s`` off the end of one gear's profile (corner contact, "extended tooth contact").

    Off the end of the path of contact the mating flanks no longer touch on the line of action: the corner of the
    profile that ends (the driven gear's tip at the entry, the driver's tip, or a broken tooth's fracture edge,
    at the exit) meets the mate's involute.  Near the virtual contact point, where the two involutes would be
    tangent, two convex profiles of radii of curvature ``rho_1`` and ``rho_2`` lie ``a^2 (1/rho_1 + 1/rho_2) / 2``
    apart at an arc length ``a`` from it (the Hertz gap geometry, Johnson 1985, Contact Mechanics, sec. 4.1), and
    on an involute of base radius ``r_b`` the arc between roll lengths ``rho`` and ``rho + s`` is
    ``(2 rho s + s^2) / (2 r_b) ~ rho s / r_b``; so ``c = (rho_c / r_b,c)^2 (1/rho_1 + 1/rho_2) / 2`` with the
    cornered gear's roll length ``rho_c`` and base radius ``r_b,c`` at the profile's end.  A loaded pair that
    lags or leads by more than its separation therefore starts before, or ends after, the nominal path, and
    its force builds up over a roll distance instead of switching on with the full interference (the
    premature and prolonged contact of loaded gears, "extended tooth contact": Ma, Pang, Feng, Song & Wen 2015,
    Eng. Fail. Anal. 48, 105-120).  Roll lengths in m, all > 0.
    """
    for name, v in (("rho_driver", rho_driver), ("rho_driven", rho_driven),
                    ("base_radius_cornered", base_radius_cornered), ("rho_cornered", rho_cornered)):
        if not (math.isfinite(v) and v > 0):
            raise ParameterError(f"corner contact: {name} must be > 0 (m), got {v!r}")
    return 0.5 * (rho_cornered / base_radius_cornered) ** 2 * (1.0 / rho_driver + 1.0 / rho_driven)
