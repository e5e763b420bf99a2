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
  (a broken tooth carries nothing: factor 0, as in the dynamics paper).  Used in tests and only when asked
  for: the gears package is part of rvdiag and imported unconditionally, so the physics never falls back
  to this stand-in silently.

Each pair's contact is carried off the ends of its path of contact as a corner contact (extended tooth contact,
:func:`extend_off_path`), so that a pair lagging by more than its separation touches before, or leaves after, the
nominal path instead of meeting the whole interference at a fixed angle.

A table may also carry the mesh profile deviation ``error_m`` (wear, a spall through the face), which the model
subtracts from the mesh deflection as a transmission-error excitation (docs/model.md, "Fault sensitivity").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.gears import GearPair, mesh_stiffness
from rvdiag.gears.modification import (ProfileModification, corner_contact_coefficient, iso1328_tolerances,
                                       profile_slope_separation, relief_separation, tooth_position_errors)
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
        (wear, a spall through the face: :func:`rvdiag.gears.faults.flank_deviation`): it reduces the mesh approach, ``delta - e``, and enters the dynamic model as a
        displacement (transmission-error) excitation (Kahraman & Singh 1990, J. Sound Vib. 142;
        for wear, Ding & Kahraman 2007, J. Sound Vib. 307; see docs/model.md, "Fault sensitivity").  :func:`mesh_table_from_gears` fills it from
        ``rvdiag.gears.mesh_stiffness(...).profile_error_m``.
    """

    angle_rad: np.ndarray
    stiffness_N_per_m: np.ndarray
    period_rad: float = TWO_PI
    source: str = "table"
    error_m: np.ndarray | None = None
    pair_stiffness_N_per_m: np.ndarray | None = None
    pair_separation_m: np.ndarray | None = None

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
        if (self.pair_stiffness_N_per_m is None) != (self.pair_separation_m is None):
            raise ParameterError("mesh table: give both pair stiffnesses and pair separations, or neither")
        if self.pair_stiffness_N_per_m is not None:
            kp = np.atleast_2d(np.asarray(self.pair_stiffness_N_per_m, dtype=float))
            ep = np.atleast_2d(np.asarray(self.pair_separation_m, dtype=float))
            if kp.shape != ep.shape or kp.shape[1] != a.size or kp.shape[0] < 1:
                raise ParameterError("mesh table: pair stiffnesses and separations must have shape (slots, angles)")
            if not (np.all(np.isfinite(kp)) and np.all(np.isfinite(ep))) or np.any(kp < 0):
                raise ParameterError("mesh table: pair stiffnesses must be finite and >= 0, separations finite")
            object.__setattr__(self, "pair_stiffness_N_per_m", kp)
            object.__setattr__(self, "pair_separation_m", ep)

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

    @property
    def slots(self) -> int:
        """Number of tooth-pair slots the dynamic model carries (1 for a table without pair data)."""
        return 1 if self.pair_stiffness_N_per_m is None else int(self.pair_stiffness_N_per_m.shape[0])

    def resample_pairs(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Per-slot stiffness (N/m) and separation (m) on the uniform grid of :meth:`resample`, shape
        ``(slots, n)``.  A table without pair data is one slot: the mesh stiffness and ``error_m``."""
        if self.pair_stiffness_N_per_m is None:
            return self.resample(n)[None, :], self.resample_error(n)[None, :]
        grid = np.arange(n) * (self.period_rad / n)
        k = np.stack([np.interp(grid, self.angle_rad, row, period=self.period_rad)
                      for row in self.pair_stiffness_N_per_m])
        e = np.stack([np.interp(grid, self.angle_rad, row, period=self.period_rad)
                      for row in self.pair_separation_m])
        return k, e

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


def _runs(on: np.ndarray) -> list[tuple[int, int]]:
    """``(first, last)`` node of every run of True in the periodic boolean row ``on`` (``last`` may wrap below
    ``first``); none when the row is all False or all True."""
    if not on.any() or on.all():
        return []
    starts = np.flatnonzero(on & ~np.roll(on, 1))
    ends = np.flatnonzero(on & ~np.roll(on, -1))
    if ends[0] < starts[0]:  # the first run wraps around the table's end
        ends = np.roll(ends, -1)
    return list(zip(starts.tolist(), ends.tolist()))


def extend_off_path(k_slots: np.ndarray, e_slots: np.ndarray, droll: float, pair: GearPair,
                    limit: float) -> None:
    """Carry each tooth pair's contact off the ends of its path of contact, in place (extended tooth contact).

    In the nodes where a slot holds no pair, each neighbouring pair gets its stiffness at the end it left or has
    yet to reach, and its separation there plus ``c s^2`` at a roll distance ``s`` off that end
    (:func:`rvdiag.gears.modification.corner_contact_coefficient`: at the entry the driven gear's tip corner, at
    the exit the driver's tip, or the fracture edge of a broken tooth, which ends its pair's path early).  Of two
    candidates at a node the one with the smaller separation is kept (the pair that touches first); up to a
    separation of ``limit`` (m).  Within the path nothing changes.  Without it a pair meets the full interference of
    a lagging gear at a fixed angle and its force steps, and a planet whose sun tooth is missing swings into the gap
    until the next pair switches on against it (docs/model.md section 9).

    ``k_slots``, ``e_slots``: ``(slots, n)`` over one relative sun revolution on a uniform grid of ``droll`` (m of roll
    along the path per node); each slot's runs of ``k > 0`` start at roll 0 of their pair.
    """
    n = k_slots.shape[1]
    L = pair.path_of_contact
    rb1, rb2 = pair.driver.base_radius, pair.driven.base_radius
    rho1_in, rho2_in = pair.roll_lengths(np.array(0.0))
    c_in = corner_contact_coefficient(float(rho1_in), float(rho2_in), rb2, float(rho2_in))
    steps_in = int(math.sqrt(limit / c_in) / droll)
    for s_ in range(k_slots.shape[0]):
        runs = _runs(k_slots[s_] > 0)
        best_e = np.full(n, np.inf)
        best_k = np.zeros(n)
        for first, last in runs:
            length = (last - first) % n
            roll_end = min(length * droll, L)
            rho1, rho2 = pair.roll_lengths(np.array(roll_end))
            c_out = corner_contact_coefficient(float(rho1), float(rho2), rb1, float(rho1))
            steps_out = int(math.sqrt(limit / c_out) / droll)
            for end, c, steps, sign in ((first, c_in, steps_in, -1), (last, c_out, steps_out, 1)):
                j = np.arange(1, steps + 1)
                idx = (end + sign * j) % n
                blocked = np.flatnonzero(k_slots[s_, idx] > 0)
                if blocked.size:
                    j, idx = j[:blocked[0]], idx[:blocked[0]]
                cand = e_slots[s_, end] + c * (j * droll) ** 2
                better = cand < best_e[idx]
                best_e[idx[better]] = cand[better]
                best_k[idx[better]] = k_slots[s_, end]
        fill = np.isfinite(best_e)
        k_slots[s_, fill] = best_k[fill]
        e_slots[s_, fill] = best_e[fill]


def mesh_table_from_gears(params: ReducerParams, fault: Any = None, points_per_cycle: int = 360,
                          tooth_errors_m: Any = None) -> MeshTable:
    """Potential-energy TVMS of :mod:`rvdiag.gears` over one relative sun revolution (Z1 mesh cycles), with
    the separation of every tooth pair.

    ``fault`` is ``None`` (healthy) or a :class:`rvdiag.gears.ToothFaults`; the faults sit on sun teeth.

    The pairs in contact are kept apart in slots: the pair of sun tooth ``j`` in slot ``j mod ceil(eps)``, so
    that pairs of one slot never overlap in contact, and the ``Z1 mod ceil(eps)`` last teeth in a slot each of
    their own, so that the assignment is periodic over the revolution (3 slots for the RV-20E's 11 teeth).  Each slot carries its pair's stiffness
    and *separation* (m, :mod:`rvdiag.gears.modification`): the tip and root relief of ``params.modification``
    at the pair's roll position, the profile slope deviation and the sun tooth's position error of its
    ISO 1328 grade, and the faulty flank's profile deviation at the contact point
    (:func:`rvdiag.gears.faults.flank_deviation`: the Archard wear depth, docs/tvms.md section 3, and the lift of
    a spall through the face, where the mate touches the cavity's edges or floor).  The
    planet's pitch errors repeat only every Z2 mesh cycles and are left out of this one-revolution table (its
    runout, the once-per-revolution part, is a manufacturing error of :mod:`rvdiag.dynamics.manufacturing`).
    The table's ``error_m`` is the load-shared separation ``sum k_j e_j / sum k_j`` (the profile deviation a
    single-spring model would use).

    ``tooth_errors_m`` (one per sun tooth, m along the line of action), when given, replaces the sun teeth's
    position errors drawn from ``[modification] error_seed`` (the profile slope deviation of the grade stays): a
    specimen's measured or identified pattern, or a perturbed one (a sensitivity study).  Without it, the
    pattern of ``[modification] sun_tooth_errors_um`` replaces the drawn one where the parameter file states it.
    """
    pair = GearPair.sun_planet(params)
    z1 = params.stage1.sun_teeth
    if fault is not None and getattr(fault, "is_healthy", False):
        fault = None
    res = mesh_stiffness(pair, fault=fault, cycles=z1, points_per_cycle=points_per_cycle)
    angle = np.asarray(res.angle_rad, dtype=float)
    pair_index, roll, in_contact = pair.contact_state(angle)
    kp = np.asarray(res.pair_stiffness_N_per_m, dtype=float)
    deviation = res.pair_profile_error_m
    if deviation is not None:
        deviation = np.asarray(deviation, dtype=float)
    L = pair.path_of_contact
    n_slots = int(math.ceil(pair.contact_ratio - 1e-9))
    md = params.modification
    mod = ProfileModification(
        tip_relief_driver=md.tip_relief_sun, tip_relief_driven=md.tip_relief_planet,
        root_relief_driver=md.root_relief_sun, root_relief_driven=md.root_relief_planet,
        tip_relief_length=md.tip_relief_length, root_relief_length=md.root_relief_length,
        shape="parabolic" if md.relief_exponent == 2 else "linear")
    sep = relief_separation(roll, L, mod)
    teeth = None
    if md.iso1328_grade > 0:
        tol = iso1328_tolerances(params.stage1.module, params.stage1.module * z1, md.iso1328_grade)
        sep = sep + profile_slope_separation(roll, L, tol)
        teeth = tooth_position_errors(z1, tol, md.error_seed)
    if tooth_errors_m is None and md.sun_tooth_errors_um is not None:   # a specimen's own pattern
        tooth_errors_m = np.asarray(md.sun_tooth_errors_um, dtype=float) * 1e-6
    if tooth_errors_m is not None:
        teeth = np.asarray(tooth_errors_m, dtype=float).ravel()
        if teeth.size != z1 or not np.all(np.isfinite(teeth)):
            raise ParameterError(f"tooth_errors_m must hold {z1} finite values (one per sun tooth), got {teeth.size}")
    if teeth is not None:
        sep = sep + teeth[np.mod(pair_index, z1)]
    if deviation is not None:
        sep = sep + deviation
    # slot of each pair, periodic over one revolution (the table wraps from sun tooth Z1 - 1 to tooth 0): pairs
    # alternate over ceil(eps) slots, and the Z1 mod ceil(eps) last teeth of the revolution get a slot each of
    # their own (an odd Z1 = 11 with eps < 2: teeth 0..9 alternate over slots 0 and 1, tooth 10 has slot 2)
    tooth = np.mod(pair_index, z1)
    rest = z1 % n_slots
    slot = np.where(tooth < z1 - rest, np.mod(tooth, n_slots), n_slots + tooth - (z1 - rest))
    n_slots += rest
    k_slots = np.zeros((n_slots, angle.size))
    e_slots = np.zeros((n_slots, angle.size))
    for s_ in range(n_slots):
        on = in_contact & (slot == s_)
        k_slots[s_] = np.where(on, kp, 0.0).sum(axis=0)
        e_slots[s_] = np.where(on, sep, 0.0).sum(axis=0)
    k = k_slots.sum(axis=0)
    err = np.divide((k_slots * e_slots).sum(axis=0), k, out=np.zeros_like(k), where=k > 0)
    if md.extended_contact_separation > 0:
        droll = pair.driver.base_radius * (angle[1] - angle[0])
        extend_off_path(k_slots, e_slots, droll, pair, md.extended_contact_separation)
    angle = angle - angle[0]
    period = TWO_PI
    keep = angle < period - 1e-12
    return MeshTable(angle[keep], k[keep], period, source="rvdiag.gears.mesh_stiffness", error_m=err[keep],
                     pair_stiffness_N_per_m=k_slots[:, keep], pair_separation_m=e_slots[:, keep])
