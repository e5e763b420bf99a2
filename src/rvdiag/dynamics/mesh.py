"""Sun-planet mesh stiffness as data: a periodic table over one sun revolution relative to the carrier.

The dynamic model (:mod:`rvdiag.dynamics.model`) does not compute mesh stiffness itself.  It takes the
time-varying mesh stiffness (TVMS) of one sun-planet mesh as a table ``k(phi)``, ``phi`` the sun's rotation
angle relative to the carrier measured from the planet's position, over one full relative revolution
(Z1 mesh cycles, so a fault on one sun tooth appears once per relative revolution).  Planet ``i`` at
angle ``psi_i`` in the carrier looks the table up at ``phi - psi_i``.

Two sources of tables:

- :func:`mesh_table_from_gears`: the potential-energy TVMS of :mod:`rvdiag.gears` (healthy or faulty), the
  physically detailed one (Yang & Lin 1987; Sainsot, Velex & Duverger 2004; Chen & Shao 2011).
- :func:`rectangular_mesh_table`: a stand-in square wave from the contact ratio, single-pair stiffness
  ``k_pair`` in single contact and ``2 k_pair`` in double contact (the classical approximation of the TVMS,
  e.g. Lin & Parker 1999 and Kahraman 1994), with tooth faults as a stiffness factor per sun tooth
  (a broken tooth carries nothing: factor 0, as in the dynamics paper).  Used in tests and when the gears
  package is not installed.

A table may also carry the mesh profile deviation ``error_m`` (wear), which the model subtracts from the
mesh deflection as a transmission-error excitation (docs/model.md, "Fault sensitivity").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.params import ReducerParams

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class MeshTable:
    """Periodic mesh stiffness table of one sun-planet mesh.

    Parameters
    ----------
    angle_rad : array
        Sun angle relative to the carrier, measured from the planet position, increasing, spanning
        less than one period.
    stiffness_N_per_m : array
        Mesh stiffness along the line of action at each angle (N/m), >= 0.
    period_rad : float
        Period of the table (2 pi for one relative sun revolution).
    source : str
        Where the table came from (recorded with simulations).
    error_m : array or None
        Mesh profile deviation along the line of action at each angle (m), same grid as the
        stiffness; ``None`` means zeros (a perfect involute).  Positive where material is missing
        (wear): it reduces the mesh approach, ``delta - e``, and enters the dynamic model as a
        displacement (transmission-error) excitation (Kahraman & Singh 1990, J. Sound Vib. 142;
        for wear, Ding & Kahraman 2007, J. Sound Vib. 307; see docs/model.md, "Fault sensitivity").  :func:`mesh_table_from_gears` fills it from
        ``rvdiag.gears.mesh_stiffness(...).profile_error_m``.
    """

    angle_rad: np.ndarray
    stiffness_N_per_m: np.ndarray
    period_rad: float = TWO_PI
    source: str = "table"
    error_m: np.ndarray | None = None

    def __post_init__(self) -> None:
        a = np.asarray(self.angle_rad, dtype=float)
        k = np.asarray(self.stiffness_N_per_m, dtype=float)
        if a.ndim != 1 or a.shape != k.shape or a.size < 2:
            raise ParameterError("mesh table: angle and stiffness must be 1-D arrays of equal length >= 2")
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(k))):
            raise ParameterError("mesh table: angles and stiffnesses must be finite")
        if np.any(np.diff(a) <= 0):
            raise ParameterError("mesh table: angles must increase strictly")
        if np.any(k < 0):
            raise ParameterError("mesh table: stiffness must be >= 0")
        if not self.period_rad > 0 or a[-1] - a[0] >= self.period_rad + 1e-12:
            raise ParameterError("mesh table: angles must span less than one period")
        e = np.zeros_like(a) if self.error_m is None else np.asarray(self.error_m, dtype=float)
        if e.shape != a.shape:
            raise ParameterError(
                f"mesh table: error_m must have one value per angle ({a.size}), got shape {e.shape}")
        if not np.all(np.isfinite(e)):
            raise ParameterError("mesh table: profile errors (error_m) must be finite")
        object.__setattr__(self, "angle_rad", a)
        object.__setattr__(self, "stiffness_N_per_m", k)
        object.__setattr__(self, "error_m", e)

    @property
    def has_error(self) -> bool:
        """True when the table carries a non-zero profile deviation."""
        return bool(np.any(self.error_m != 0.0))

    def resample(self, n: int) -> np.ndarray:
        """Stiffness on the uniform grid ``phi_j = j * period / n``, j = 0..n-1 (periodic linear interpolation)."""
        grid = np.arange(n) * (self.period_rad / n)
        return np.interp(grid, self.angle_rad, self.stiffness_N_per_m, period=self.period_rad)

    def resample_error(self, n: int) -> np.ndarray:
        """Profile deviation (m) on the same uniform grid as :meth:`resample` (periodic linear interpolation)."""
        grid = np.arange(n) * (self.period_rad / n)
        return np.interp(grid, self.angle_rad, self.error_m, period=self.period_rad)

    def mean(self) -> float:
        """Mean stiffness over the period (N/m)."""
        return float(np.mean(self.resample(4096)))


def contact_ratio(params: ReducerParams) -> float:
    """Transverse contact ratio of the sun-planet pair (ISO 21771, eq. 74).

    eps = [sqrt(ra1^2 - rb1^2) + sqrt(ra2^2 - rb2^2) - a sin(alpha)] / (pi m cos(alpha)), with the tip
    radii ``r + m (ha* + x)`` of the profile-shifted (V-zero) pair.
    """
    s1 = params.stage1
    m, alpha = s1.module, math.radians(s1.pressure_angle_deg)
    r1, r2 = 0.5 * m * s1.sun_teeth, 0.5 * m * s1.planet_teeth
    ra1 = r1 + m * (s1.addendum_coefficient + s1.sun_profile_shift)
    ra2 = r2 + m * (s1.addendum_coefficient + s1.planet_profile_shift)
    rb1, rb2 = r1 * math.cos(alpha), r2 * math.cos(alpha)
    a = s1.centre_distance
    return (math.sqrt(ra1**2 - rb1**2) + math.sqrt(ra2**2 - rb2**2) - a * math.sin(alpha)) / (
        math.pi * m * math.cos(alpha)
    )


def single_pair_stiffness(params: ReducerParams) -> float:
    """Stand-in single-pair mesh stiffness: ISO 6336 ``c' = 14 N/(mm um)`` times the face width (N/m).

    ISO 6336-1 quotes c' of 14-16 N/(mm um) for steel spur gears.
    """
    return 14.0e9 * params.stage1.face_width


def rectangular_mesh_table(
    params: ReducerParams,
    tooth_factors: Sequence[float] | None = None,
    k_pair: float | None = None,
    points_per_cycle: int = 360,
) -> MeshTable:
    """Square-wave TVMS from the contact ratio, with a stiffness factor per sun tooth.

    Sun tooth ``j`` is in mesh with the planet while ``phi - j 2pi/Z1`` lies in ``[0, eps 2pi/Z1)``; the
    mesh stiffness is the sum of ``k_pair * tooth_factors[j]`` over the teeth in mesh.  ``tooth_factors``
    defaults to all ones (healthy); 0 models a broken tooth (the tooth carries nothing).
    """
    z1 = params.stage1.sun_teeth
    eps = contact_ratio(params)
    if not 1.0 <= eps < 2.0:
        raise ParameterError(f"stand-in mesh table needs 1 <= contact ratio < 2, got {eps:.3f}")
    factors = np.ones(z1) if tooth_factors is None else np.asarray(tooth_factors, dtype=float)
    if factors.shape != (z1,) or np.any(factors < 0):
        raise ParameterError(f"tooth_factors must be {z1} values >= 0")
    kp = single_pair_stiffness(params) if k_pair is None else float(k_pair)
    n = z1 * points_per_cycle
    phi = np.arange(n) * (TWO_PI / n)
    pitch = TWO_PI / z1
    k = np.zeros(n)
    for j in range(z1):
        # small offset keeps the contact edges off the grid points
        rel = np.mod(phi - j * pitch + 1e-9, TWO_PI)
        k += np.where(rel < eps * pitch, kp * factors[j], 0.0)
    return MeshTable(phi, k, TWO_PI, source=f"rectangular(eps={eps:.4f}, k_pair={kp:.4g})")


def gears_available() -> bool:
    """True when :func:`rvdiag.gears.mesh_stiffness` can be imported."""
    try:
        from rvdiag.gears import mesh_stiffness  # noqa: F401
    except ImportError:
        return False
    return True


def mesh_table_from_gears(params: ReducerParams, fault: Any = None, points_per_cycle: int = 360) -> MeshTable:
    """Potential-energy TVMS of :mod:`rvdiag.gears` over one relative sun revolution (Z1 mesh cycles).

    ``fault`` is ``None`` (healthy) or a :class:`rvdiag.gears.ToothFaults`; the faults sit on sun teeth.
    The table's ``error_m`` is the load-shared profile deviation ``res.profile_error_m`` (wear depth
    along the line of action, ``sum k_i e_i / sum k_i`` over the pairs in contact; zero when healthy
    and at the pitch point, docs/tvms.md section 3).
    """
    from rvdiag.gears import GearPair, mesh_stiffness

    pair = GearPair.sun_planet(params)
    z1 = params.stage1.sun_teeth
    if fault is not None and getattr(fault, "is_healthy", False):
        fault = None
    res = mesh_stiffness(pair, fault=fault, cycles=z1, points_per_cycle=points_per_cycle)
    angle = np.asarray(res.angle_rad, dtype=float)
    k = np.asarray(res.stiffness_N_per_m, dtype=float)
    err = np.asarray(res.profile_error_m, dtype=float)
    angle = angle - angle[0]
    period = TWO_PI
    keep = angle < period - 1e-12
    return MeshTable(angle[keep], k[keep], period, source="rvdiag.gears.mesh_stiffness", error_m=err[keep])
