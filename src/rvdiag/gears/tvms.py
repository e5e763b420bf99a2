"""Time-varying mesh stiffness (TVMS) of a spur gear pair by the potential-energy method.

One tooth pair in contact is a series of springs (Yang & Lin 1987; Tian 2004; docs/references.md):

    1/k = 1/k_h + sum over both gears (1/k_b + 1/k_s + 1/k_a + 1/k_f),

and pairs in double contact act in parallel.  For a load at (y_k, x_k) on the flank, with load
angle alpha_1 (between the line of action and the tooth section, alpha_1 = tan(alpha_k) - theta_b),
and a tooth section of area A(y) = (x_l + x_o) L and second moment I(y) = (x_l + x_o)^3 L / 12
(x_l, x_o the loaded and unloaded half thicknesses):

* bending (Tian 2004, eq. 2.37; Yang & Lin 1987):
  1/k_b = int_{y_0}^{y_k} [cos(a1) (y_k - y) - x_k sin(a1)]^2 / (E I(y)) dy
* shear:  1/k_s = int 1.2 cos^2(a1) / (G A(y)) dy
* axial compression: 1/k_a = int sin^2(a1) / (E A(y)) dy
* Hertz (Yang & Sun 1985): 1/k_h = 2 (1 - nu1^2) / (pi E1 L) + 2 (1 - nu2^2) / (pi E2 L),
  i.e. k_h = pi E L / (4 (1 - nu^2)) for one material
* fillet foundation (Sainsot, Velex & Duverger 2004, eq. (8)):
  1/k_f = cos^2(a1) / (E L) [L* (u_f/S_f)^2 + M* (u_f/S_f) + P* (1 + Q* tan^2(a1))],
  S_f = 2 r_f theta_f, u_f the distance from the root circle to the point where the load line
  crosses the centreline, u_f = y_k - x_k tan(a1) - r_f; L*, M*, P*, Q* from the fitted
  polynomials in h_fi = r_f / r_int and theta_f (Sainsot et al. 2004, Table 1).

The integrals run from the root circle through the trochoidal fillet to the load point, so a root
circle below the base circle (Chen & Shao 2011) is always accounted for.

Pitting and spalling (partial tooth-face loss, :class:`rvdiag.gears.faults.Pitting` and ``Spalling``) make the
width vary along the tooth: a section that a pit or spall cuts has the area A(y) and second moment I(y) of
:func:`rvdiag.gears.faults.cut_section` instead of the rectangle's, and a contact at flank position s touches
L - delta_L(s) of the face, so 1/k_h = sum 2 (1 - nu_i^2) / (pi E_i (L - delta_L(s))) there (Liang, Zhang, Liu &
Zuo 2016; Ma, Li, Feng, Feng & Wen 2016).  The foundation term keeps the full width: the gear body under the
tooth is whole.  A spall through the whole face leaves no intact face on the contact line: the mate touches the
cavity's edge or floor across the whole face (k_h with L) after closing a profile deviation
(:func:`rvdiag.gears.faults.flank_deviation`), which the result reports per pair in ``pair_profile_error_m``
beside wear's.

Vectorisation: the bending integrand expands into moments of 1/I,
[c (u_k - u) - x_k s]^2 = c^2 (u_k^2 - 2 u_k u + u^2) - 2 c s x_k (u_k - u) + s^2 x_k^2, so with the
cumulative integrals C_n(u) = int_0^u t^n / I(t) dt (n = 0, 1, 2) and D(u) = int_0^u 1/A dt
(trapezoidal rule on a fixed 1,600-point table of the tooth) every load point is a handful of
interpolations; there is no loop over angles.  The only loop runs over the few distinct damaged
teeth.
"""

from __future__ import annotations

import functools
import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from rvdiag.errors import ModelRangeWarning, ParameterError
from rvdiag.gears.faults import (DamagedProfile, FlankLoss, ToothFaults, damaged_profile, flank_deviation,
                                 has_flank_deviation)
from rvdiag.gears.geometry import Gear, GearPair
from rvdiag.validation import positive

# Sainsot, Velex & Duverger (2004), Table 1: rows L*, M*, P*, Q*;
# columns A, B, C, D, E, F of X* = A/theta_f^2 + B h_fi^2 + C h_fi/theta_f + D/theta_f + E h_fi + F
SAINSOT_COEFFICIENTS = np.array([
    [-5.574e-5, -1.9986e-3, -2.3015e-4, 4.7702e-3, 0.0271, 6.8045],
    [60.111e-5, 28.100e-3, -83.431e-4, -9.9256e-3, 0.1624, 0.9086],
    [-50.952e-5, 185.50e-3, 0.0538e-4, 53.300e-3, 0.2895, 0.9236],
    [-6.2042e-5, 9.0889e-3, -4.0964e-4, 7.8297e-3, -0.1472, 0.6904],
])
#: validity range of the Sainsot fit: theta_f (rad) and h_fi
SAINSOT_THETA_RANGE = (0.01, 0.12)
SAINSOT_H_RANGE = (1.4, 7.0)


def sainsot_coefficients(theta_f: float, h_fi: float) -> np.ndarray:
    """L*, M*, P*, Q* of Sainsot et al. (2004) at root half angle ``theta_f`` and r_f / r_int."""
    A, B, C, D, E, F = SAINSOT_COEFFICIENTS.T
    return A / theta_f**2 + B * h_fi**2 + C * h_fi / theta_f + D / theta_f + E * h_fi + F


def foundation_in_range(gear: Gear) -> bool:
    """Whether the gear's theta_f and h_fi lie inside the range Sainsot et al. fitted."""
    h = gear.root_radius / gear.bore_radius
    return (SAINSOT_THETA_RANGE[0] <= gear.root_half_angle <= SAINSOT_THETA_RANGE[1]
            and SAINSOT_H_RANGE[0] <= h <= SAINSOT_H_RANGE[1])


def foundation_range_notes(pair: GearPair) -> tuple[str, ...]:
    """One sentence per gear of ``pair`` whose fillet foundation lies outside the fitted range of Sainsot,
    Velex & Duverger (2004), Table 1 (theta_f in [0.01, 0.12] rad, h_fi = r_f / r_int in [1.4, 7]).

    Outside it, their polynomials for L*, M*, P*, Q* are extrapolated and k_f is less certain; the RV-20E
    sun (11 teeth, theta_f = 0.274 rad, h_fi = 1.16) is such a case.  Empty when both gears are in range.
    """
    notes = []
    for role, gear in (("driver", pair.driver), ("driven", pair.driven)):
        theta, h = gear.root_half_angle, gear.root_radius / gear.bore_radius
        out = [f"{name} = {value:.3f}{unit} (fitted {lo}-{hi}{unit})"
               for name, value, (lo, hi), unit in (("theta_f", theta, SAINSOT_THETA_RANGE, " rad"),
                                                   ("h_fi", h, SAINSOT_H_RANGE, ""))
               if not lo <= value <= hi]
        if out:
            notes.append(f"fillet-foundation stiffness of the {role} gear ({gear.teeth} teeth) is extrapolated "
                         f"beyond the fit of Sainsot et al. (2004): {', '.join(out)}")
    return tuple(notes)


_WARNED: set[str] = set()


@functools.cache
def documented_notes() -> frozenset[str]:
    """The range notes of the built-in RV-20E's sun-planet pair: its 11-tooth sun lies outside Sainsot's fit, a
    known property of the default reducer, said once in docs/tvms.md ("Sainsot's fit range") and kept in every
    result's ``notes`` and the HTML report, but not warned about by every command that simulates it."""
    from rvdiag.params import ReducerParams

    return frozenset(foundation_range_notes(GearPair.sun_planet(ReducerParams.default())))


def _warn_once(message: str) -> None:
    """Warn with :class:`rvdiag.errors.ModelRangeWarning` the first time a message occurs in this process (a
    library build computes the same pair's stiffness for every simulation); not for :func:`documented_notes`."""
    if message not in _WARNED and message not in documented_notes():
        _WARNED.add(message)
        warnings.warn(message, ModelRangeWarning, stacklevel=3)


@dataclass(frozen=True)
class _SectionTable:
    """Cumulative compliance integrals of one tooth shape (see module docstring); ``flank_loss`` holds the pits
    and spalls of the flank (their contact width enters the Hertz term), ``None`` without."""

    y0: float
    u: np.ndarray
    c0: np.ndarray
    c1: np.ndarray
    c2: np.ndarray
    d: np.ndarray
    cut_radius: float
    flank_loss: FlankLoss | None = None

    @classmethod
    def build(cls, prof: DamagedProfile, face_width: float) -> "_SectionTable":
        y0 = float(prof.y[0])
        u = prof.y - y0
        t = prof.x_loaded + prof.x_other
        inv_i = 12.0 / (t**3 * face_width)
        inv_a = 1.0 / (t * face_width)
        if prof.area is not None:  # sections cut by pits or a spall: no longer rectangles
            cut = ~np.isnan(prof.area)
            inv_i[cut] = 1.0 / prof.inertia[cut]
            inv_a[cut] = 1.0 / prof.area[cut]

        def cumtrapz(f: np.ndarray) -> np.ndarray:
            out = np.empty_like(f)
            out[0] = 0.0
            np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(u), out=out[1:])
            return out

        return cls(y0, u, cumtrapz(inv_i), cumtrapz(u * inv_i), cumtrapz(u * u * inv_i),
                   cumtrapz(inv_a), prof.cut_radius, prof.flank_loss)

    def compliance(self, gear: Gear, yk: np.ndarray, xk: np.ndarray, a1: np.ndarray) -> dict:
        """1/k_b, 1/k_s, 1/k_a (m/N) at load points (yk, xk) with load angles a1."""
        uk = yk - self.y0
        c0 = np.interp(uk, self.u, self.c0)
        c1 = np.interp(uk, self.u, self.c1)
        c2 = np.interp(uk, self.u, self.c2)
        d = np.interp(uk, self.u, self.d)
        c, s = np.cos(a1), np.sin(a1)
        E = gear.youngs_modulus
        G = E / (2.0 * (1.0 + gear.poisson_ratio))
        bend = (c * c * (uk * uk * c0 - 2.0 * uk * c1 + c2)
                - 2.0 * c * s * xk * (uk * c0 - c1) + (s * xk) ** 2 * c0) / E
        return {"bending": bend, "shear": 1.2 * c * c * d / G, "axial": s * s * d / E}


def load_point(gear: Gear, rho: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Load point on the involute at roll length ``rho`` (m): (y_k, x_k, alpha_1, r_k).

    alpha_1 = rho / r_b - theta_b = tan(alpha_k) - theta_b (Tian 2004, eq. 2.32)."""
    rho = np.asarray(rho, dtype=float)
    r = np.hypot(gear.base_radius, rho)
    yk, xk = gear.involute_point(r)
    return yk, xk, rho / gear.base_radius - gear.base_half_angle, r


def foundation_compliance(gear: Gear, yk: np.ndarray, xk: np.ndarray, a1: np.ndarray) -> np.ndarray:
    """1/k_f of Sainsot, Velex & Duverger (2004), eq. (8) (m/N)."""
    theta_f = gear.root_half_angle
    h_fi = gear.root_radius / gear.bore_radius
    Ls, Ms, Ps, Qs = sainsot_coefficients(theta_f, h_fi)
    rf = gear.root_radius
    sf = 2.0 * rf * theta_f
    uf = yk - xk * np.tan(a1) - rf
    q = uf / sf
    return np.cos(a1) ** 2 / (gear.youngs_modulus * gear.face_width) * (
        Ls * q * q + Ms * q + Ps * (1.0 + Qs * np.tan(a1) ** 2))


def hertz_compliance(pair: GearPair, contact_width: np.ndarray | float | None = None) -> float | np.ndarray:
    """1/k_h = sum 2 (1 - nu_i^2) / (pi E_i L) (Yang & Sun 1985), L the common face width, or the
    ``contact_width`` (m) left by pits or a spall, L - delta_L (Liang, Zhang, Liu & Zuo 2016)."""
    L = min(pair.driver.face_width, pair.driven.face_width) if contact_width is None else contact_width
    return sum(2.0 * (1.0 - g.poisson_ratio**2) / (math.pi * g.youngs_modulus * L)
               for g in (pair.driver, pair.driven))


def _healthy_table(pair: GearPair, which: str) -> _SectionTable:
    gear = pair.driver if which == "driver" else pair.driven
    key = "_healthy_table_cache"
    cache = gear.__dict__.get(key)
    if cache is None:
        cache = _SectionTable.build(damaged_profile(pair, which, ()), gear.face_width)
        object.__setattr__(gear, key, cache)
    return cache


@functools.lru_cache(maxsize=64)
def _damaged_table(pair: GearPair, which: str, faults: tuple) -> _SectionTable:
    """Section table of a damaged tooth, cached: a library at fixed severities asks for the same few shapes again
    and again (GearPair, Gear and the faults are frozen, hashable dataclasses).  A library that draws its severities
    never asks twice, and every entry holds about 0.14 MB for the life of a worker: 64 entries keep that under
    10 MB (512 grew each worker of a 100,000-sample build by tens of MB; bench/HISTORY.md)."""
    gear = pair.driver if which == "driver" else pair.driven
    return _SectionTable.build(damaged_profile(pair, which, faults), gear.face_width)


def tooth_pair_components(pair: GearPair, roll: np.ndarray,
                          tables: tuple[_SectionTable, _SectionTable] | None = None) -> dict:
    """Every compliance term (m/N) of one tooth pair at path positions ``roll`` (m).

    Keys: ``hertz`` and, per gear (``driver_``/``driven_``), ``bending``, ``shear``, ``axial``,
    ``foundation``; plus ``total`` and ``stiffness`` (N/m).  Contact beyond a broken tooth's cut
    gives zero stiffness; contact on a pitted or spalled part of a flank touches only the face width left
    (``contact_width``, m, then among the keys).
    """
    roll = np.asarray(roll, dtype=float)
    rho1, rho2 = pair.roll_lengths(roll)
    if tables is None:
        tables = (_healthy_table(pair, "driver"), _healthy_table(pair, "driven"))
    out: dict = {"hertz": np.full(roll.shape, hertz_compliance(pair))}
    if any(table.flank_loss for table in tables):
        width = np.full(roll.shape, min(pair.driver.face_width, pair.driven.face_width))
        for gear, rho, table in ((pair.driver, rho1, tables[0]), (pair.driven, rho2, tables[1])):
            if table.flank_loss:
                width = width - table.flank_loss.width(rho * rho / (2.0 * gear.base_radius))
        # a spall through the whole face leaves no intact face on the contact line: the mate, once it has closed
        # the profile deviation (flank_deviation), touches the cavity's floor or edge across the whole face
        full = min(pair.driver.face_width, pair.driven.face_width)
        width = np.where(width <= full * 1e-12, full, width)
        out["contact_width"] = width
        out["hertz"] = hertz_compliance(pair, width)
    total = out["hertz"].copy()
    lost = np.zeros(roll.shape, dtype=bool)
    for name, gear, rho, table in (("driver", pair.driver, rho1, tables[0]),
                                   ("driven", pair.driven, rho2, tables[1])):
        yk, xk, a1, rk = load_point(gear, rho)
        comp = table.compliance(gear, yk, xk, a1)
        comp["foundation"] = foundation_compliance(gear, yk, xk, a1)
        for term, value in comp.items():
            out[f"{name}_{term}"] = value
            total = total + value
        lost |= rk > table.cut_radius * (1.0 + 1e-12)
    out["total"] = total
    out["stiffness"] = np.where(lost, 0.0, 1.0 / total)
    return out


@dataclass
class MeshStiffnessResult:
    """TVMS of a gear pair over whole mesh cycles (ROSS-style result that plots itself).

    Attributes
    ----------
    angle_rad : ndarray
        Driver rotation (rad), 0 at the start of the mesh cycle in which driver tooth 0 enters
        contact; uniform, ``cycles * points_per_cycle`` samples, end point excluded.
    stiffness_N_per_m : ndarray
        Mesh stiffness along the line of action (N/m).
    pair_stiffness_N_per_m : ndarray
        Stiffness of each candidate tooth pair, shape (n_candidates, n_angles) (0 when not in
        contact).
    pairs_in_contact : ndarray
        Number of tooth pairs in contact at each angle.
    contact_ratio : float
    foundation_in_range : bool
        False when a gear lies outside the fitted range of the fillet-foundation formula
        (:func:`foundation_range_notes`; a :class:`rvdiag.errors.ModelRangeWarning` was issued).
    notes : tuple of str
        Caveats of the computation, one sentence each (the foundation range above).
    """

    angle_rad: np.ndarray
    stiffness_N_per_m: np.ndarray
    pair_stiffness_N_per_m: np.ndarray
    pairs_in_contact: np.ndarray
    contact_ratio: float
    cycles: int
    points_per_cycle: int
    pair: GearPair = field(repr=False)
    fault: ToothFaults | None = None
    pair_profile_error_m: np.ndarray | None = field(default=None, repr=False)
    foundation_in_range: bool = True
    notes: tuple[str, ...] = ()

    @property
    def profile_error_m(self) -> np.ndarray:
        """Mesh profile deviation (m) along the line of action, one value per angle.

        Pairs in contact share the load as F = sum k_i (delta - e_i) = k (delta - e) with
        e = sum k_i e_i / sum k_i [derived from the force balance, while every pair touches], e_i the flank's
        deviation at pair i's contact point (:func:`rvdiag.gears.faults.flank_deviation`: wear, a spall through
        the face); zero without.  A dynamic model can add it to the mesh deflection as a displacement
        excitation (the transmission error caused by the deviation); where e_i exceeds the deflection a pair
        loses contact, which :meth:`loaded_transmission_error` and the dynamic model's per-pair separations
        resolve and this load-shared mean does not.
        """
        if self.pair_profile_error_m is None:
            return np.zeros_like(self.stiffness_N_per_m)
        k = self.pair_stiffness_N_per_m
        tot = k.sum(axis=0)
        num = (k * self.pair_profile_error_m).sum(axis=0)
        return np.divide(num, tot, out=np.zeros_like(tot), where=tot > 0)

    def loaded_transmission_error(self, force_N: float) -> tuple[np.ndarray, np.ndarray]:
        """Static loaded transmission error (m, mesh approach along the line of action) under a mesh force
        ``force_N`` (N), and the mask of the pairs that touch, shape (n_candidates, n_angles).

        At each angle the approach delta solves sum_i k_i max(delta - e_i, 0) = F over the pairs in contact, e_i
        their profile deviations (``pair_profile_error_m``): a pair whose deviation exceeds delta carries nothing
        (unilateral contact, no tension).  delta = F / k without deviations.  Solved exactly: with the pairs
        sorted by e_i, delta lies in the first interval [e_(j), e_(j+1)) where the force at its upper end reaches
        F.  Infinite where no pair in contact has stiffness.
        """
        force = positive(force_N, "force", unit=" N")
        k = self.pair_stiffness_N_per_m
        e = np.zeros_like(k) if self.pair_profile_error_m is None else self.pair_profile_error_m
        on = k > 0
        e_on = np.where(on, e, np.inf)
        order = np.argsort(e_on, axis=0)
        ks, es = np.take_along_axis(np.where(on, k, 0.0), order, 0), np.take_along_axis(e_on, order, 0)
        ksum, kesum = np.cumsum(ks, axis=0), np.cumsum(ks * np.where(np.isfinite(es), es, 0.0), axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            cand = (force + kesum) / ksum                     # delta if the first j + 1 pairs touch
        upper = np.vstack([es[1:], np.full((1, es.shape[1]), np.inf)])
        ok = (ksum > 0) & (cand <= upper)
        first = np.argmax(ok, axis=0)
        delta = np.where(ok.any(axis=0), np.take_along_axis(cand, first[None, :], 0)[0], np.inf)
        return delta, on & (e < delta[None, :])

    @property
    def mean_N_per_m(self) -> float:
        """Mean mesh stiffness over the computed whole cycles (N/m)."""
        return float(np.mean(self.stiffness_N_per_m))

    @property
    def min_N_per_m(self) -> float:
        """Minimum mesh stiffness (N/m)."""
        return float(np.min(self.stiffness_N_per_m))

    @property
    def max_N_per_m(self) -> float:
        """Maximum mesh stiffness (N/m)."""
        return float(np.max(self.stiffness_N_per_m))

    @property
    def period_rad(self) -> float:
        """Length of the computed curve, cycles * 2 pi / Z_driver (rad); it repeats with it."""
        return self.cycles * self.pair.mesh_period_rad

    def at(self, angle_rad: np.ndarray) -> np.ndarray:
        """Stiffness at arbitrary driver angles by periodic linear interpolation (N/m)."""
        a = np.mod(np.asarray(angle_rad, dtype=float), self.period_rad)
        return np.interp(a, self.angle_rad, self.stiffness_N_per_m, period=self.period_rad)

    def to_dict(self) -> dict:
        """JSON-ready dict: the arrays as lists plus summary figures."""
        return {
            "angle_rad": self.angle_rad.tolist(),
            "stiffness_N_per_m": self.stiffness_N_per_m.tolist(),
            "mean_N_per_m": self.mean_N_per_m,
            "min_N_per_m": self.min_N_per_m,
            "max_N_per_m": self.max_N_per_m,
            "contact_ratio": self.contact_ratio,
            "cycles": self.cycles,
            "points_per_cycle": self.points_per_cycle,
            "fault": None if self.fault is None else self.fault.describe(),
            "profile_error_m": self.profile_error_m.tolist(),
            "foundation_in_range": self.foundation_in_range,
            "notes": list(self.notes),
        }

    def plot(self, ax=None, label: str | None = None, **kwargs):
        """Plot stiffness (N/m) against the driver angle (degrees); returns the axes."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(8, 3.5))
        if label is None:
            label = "healthy" if self.fault is None or self.fault.is_healthy else (
                self.fault.label or "faulty")
        ax.plot(np.degrees(self.angle_rad), self.stiffness_N_per_m, label=label, **kwargs)
        ax.set_xlabel("driver rotation (deg)")
        ax.set_ylabel("mesh stiffness (N/m)")
        ax.grid(True, alpha=0.3)
        return ax


def mesh_stiffness(pair: GearPair, fault: ToothFaults | None = None, cycles: int = 11,
                   points_per_cycle: int = 360) -> MeshStiffnessResult:
    """TVMS of ``pair`` for ``cycles`` mesh cycles of ``points_per_cycle`` driver angles each.

    Parameters
    ----------
    pair : GearPair
    fault : ToothFaults, optional
        Tooth damage on the driver (default) or driven gear; ``None`` is healthy.
    cycles : int
        Number of mesh cycles (driver rotation ``cycles * 2 pi / Z1``).  A fault on driver tooth
        0 recurs every Z1 cycles, on the driven gear every Z2 cycles.
    points_per_cycle : int

    Warns
    -----
    ModelRangeWarning
        Once per process and gear, when a gear lies outside the fitted range of the fillet-foundation formula
        (:func:`foundation_range_notes`), except the built-in RV-20E sun's documented case
        (:func:`documented_notes`); the result records it in ``foundation_in_range`` and ``notes`` in either case.

    Examples
    --------
    >>> pair = GearPair.from_dimensions(20, 40, 2e-3, 0.02)
    >>> res = mesh_stiffness(pair, cycles=1, points_per_cycle=100)
    >>> res.stiffness_N_per_m.shape, 1e8 < res.mean_N_per_m < 1e9
    ((100,), True)
    """
    for name, value in (("cycles", cycles), ("points_per_cycle", points_per_cycle)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ParameterError(f"{name} must be a whole number >= 1, got {value!r}")
    if points_per_cycle < 4:
        raise ParameterError(f"points_per_cycle must be >= 4, got {points_per_cycle}")
    if fault is not None and not isinstance(fault, ToothFaults):
        raise ParameterError(f"fault must be a ToothFaults or None, got {type(fault).__name__}")
    n = cycles * points_per_cycle
    angle = np.arange(n) * (pair.mesh_period_rad / points_per_cycle)
    k_pairs, in_contact = pair_stiffness_at(pair, angle, fault)
    errors = None
    if fault is not None and not fault.is_healthy:
        errors = _profile_errors(pair, angle, fault, in_contact)
    notes = foundation_range_notes(pair)
    for note in notes:
        _warn_once(note)

    return MeshStiffnessResult(
        angle_rad=angle,
        stiffness_N_per_m=k_pairs.sum(axis=0),
        pair_stiffness_N_per_m=k_pairs,
        pairs_in_contact=in_contact.sum(axis=0),
        contact_ratio=pair.contact_ratio,
        cycles=int(cycles),
        points_per_cycle=int(points_per_cycle),
        pair=pair,
        fault=fault,
        pair_profile_error_m=errors,
        foundation_in_range=not notes,
        notes=notes,
    )


def _profile_errors(pair: GearPair, angle: np.ndarray, fault: ToothFaults,
                    in_contact: np.ndarray) -> np.ndarray | None:
    """Profile deviation of the faulty flank at each pair's contact point (m, :func:`flank_deviation`: wear, spalls
    through the face), shape (n_candidates, n_angles), or None when no tooth has one."""
    gear = pair.driver if fault.gear == "driver" else pair.driven
    # one deviation per tooth shape: each tooth with faults of its own, and -1, every other tooth (gear-wide wear)
    shapes = {t: fault.faults_of(t) for t in list(fault.teeth) + [-1]}
    shapes = {t: f for t, f in shapes.items() if has_flank_deviation(pair, fault.gear, f)}
    if not shapes:
        return None
    pair_index, roll, _ = pair.contact_state(angle)
    tooth = np.mod(pair_index, gear.teeth)
    label = np.where(np.isin(tooth, list(fault.teeth)), tooth, -1)
    out = np.zeros_like(roll)
    for t, faults in shapes.items():
        on = in_contact & (label == t)
        out[on] = flank_deviation(pair, fault.gear, faults, roll[on])
    return out


def pair_stiffness_at(pair: GearPair, angle_rad: np.ndarray,
                      fault: ToothFaults | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness (N/m) of every candidate tooth pair at arbitrary driver angles, and the contact mask.

    Both arrays have shape ``(n_candidates, n_angles)``; the mesh stiffness is the sum over axis 0.
    """
    angle = np.asarray(angle_rad, dtype=float)
    pair_index, roll, in_contact = pair.contact_state(angle)

    healthy = (_healthy_table(pair, "driver"), _healthy_table(pair, "driven"))
    k_pairs = np.zeros_like(roll)
    if fault is None or fault.is_healthy:
        k_pairs[in_contact] = tooth_pair_components(pair, roll[in_contact], healthy)["stiffness"]
        return k_pairs, in_contact

    # one section table per distinct tooth shape of the faulty gear: the gear-wide shape (healthy
    # or worn) and one per individually damaged tooth; each angle is evaluated once
    gear = pair.driver if fault.gear == "driver" else pair.driven
    side = 0 if fault.gear == "driver" else 1
    for t in fault.teeth:
        if t >= gear.teeth:
            raise ParameterError(
                f"tooth index {t} out of range for the {gear.name} with {gear.teeth} teeth")
    base_faults = fault.faults_of(-1)  # the gear-wide wear only
    shapes = {-1: _damaged_table(pair, fault.gear, base_faults) if base_faults else healthy[side]}
    for t in fault.teeth:
        shapes[t] = _damaged_table(pair, fault.gear, fault.faults_of(t))
    tooth = np.mod(pair_index, gear.teeth)
    label = np.where(np.isin(tooth, list(fault.teeth)), tooth, -1)
    for key, table in shapes.items():
        mask = in_contact & (label == key)
        if not mask.any():
            continue
        tables = list(healthy)
        tables[side] = table
        k_pairs[mask] = tooth_pair_components(pair, roll[mask], tuple(tables))["stiffness"]
    return k_pairs, in_contact
