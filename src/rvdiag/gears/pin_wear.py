"""Wear of the cycloid-pin stage: Archard's law on the disc flanks and the pins, and the clearance it opens.

The RV reducer's lost motion grows where its second stage wears: an RV reducer run 1,550 h kept its transmission
error "relatively stable" while its lost motion grew 30 % (12.9 arcsec), and its cycloid flanks wore mainly on
their convex parts, its pins most at the edge of their contact area (Lubricants 13(8):362, 2025, docs/references.md).
This module grows that wear by Archard's law over a duty cycle and gives the simulator the clearance it opens along
each contact normal (``[stage2] pin_wear_depth``, docs/model.md section 3, "Wear of the cycloid-pin stage").

Geometry (docs/model.md section 3; :mod:`rvdiag.gears.cycloid`).  A pin at phase ``eta`` (its angle from the
crank's eccentric) touches the disc on the normal through the pitch point C, at ``L = R_p S`` from C,
``S = sqrt(1 + K1^2 - 2 K1 cos eta)``; its arm about the disc centre is ``e Zc sin(eta) / S``.  The disc turns at
the output speed Omega about C, its instantaneous centre, so the disc's material point at the contact moves at
``Omega (L - r_rp)`` along the tangent.

Sliding.  The pins are taken not to turn in their grooves, so that the disc slides over them at
``v_s = Omega (L - r_rp)`` (an RV reducer's pins sit in half-round grooves of the case; a pin that rolled would
move the sliding to its groove, which this module does not model).  The contact moves over the disc's flank at
``v_d = Omega L (rho_0 - r_rp) / rho_0`` (the pin centre runs along the theoretical profile at ``Omega L``, the
flank is its parallel curve ``r_rp`` inside; ``rho_0`` the signed radius of curvature of the theoretical profile,
:func:`rvdiag.gears.cycloid.theoretical_curvature_radius`), and over the pin at ``r_rp |d psi / dt|``, ``psi`` the
angle of the normal from the pin's radial line, ``tan psi = K1 sin eta / (1 - K1 cos eta)``: it runs out to
``asin K1`` (at ``cos eta = K1``, the pin of the largest arm) and back, so the pin's contact point dwells at the
edge of its arc.

Archard's law (``dh = k p ds``, Archard 1953; Flodin & Andersson 1997, Wear 207, eq. (2), the law of
:mod:`rvdiag.gears.wear`) over one passage of the Hertz contact, whose pressure integrates to ``F / b`` across it:

* a disc flank point wears ``k (F / b) v_s / v_d = k (F / b) (L - r_rp) rho_0 / (L (rho_0 - r_rp))`` per pass, and
  every point of a lobe is passed ``Zp`` times per output revolution;
* a pin's surface wears ``k v_s p(x) dt`` summed over the contact's sweep with the Hertz pressure ``p`` (half
  width ``a = sqrt(4 (F / b) R / (pi E*))``, Johnson 1985 sec. 5.6), which keeps the dwell at the arc's edge
  finite: ``sum_eta k (L - r_rp) p(x - r_rp psi(eta)) d eta`` per output revolution (each disc's part of a pin is
  swept ``Zc`` times, ``d t = d eta / (Zc Omega)``).

The clearance along the normal at phase ``eta`` grows by the disc's depth there plus the pin's at the point it
touches, ``h(eta) = h_d(eta) + h_p(r_rp psi(eta))``.  The loads are those of the worn, modified stage, recomputed
as the wear grows (the run-in, as :mod:`rvdiag.gears.wear` does for the sun): per crank angle the disc turns until
``sum_k k_pin (x a_k - g_k)+ a_k = T_d / (e Zc)``, ``g_k`` each pin's clearance (the profile modification's,
:func:`rvdiag.gears.cycloid.modification_clearance`, plus the wear), ``a_k = sin(eta_k) / S_k``, ``k_pin`` the
model's linearised pin stiffness (:func:`rvdiag.gears.cycloid.pin_contact_stiffness`) and ``T_d`` the torque one
disc carries about its centre, ``|T| (1 - 1/i) Zc / (Zp D)`` (docs/model.md section 3).

Lost motion.  The disc's rotation that takes the clearance up on one flank is ``c / (e Zc)``,
``c = min (g(eta) / a(eta))`` over the flank's pins (:func:`rvdiag.gears.cycloid.closing_offset`); the stage's
geometric lost motion is the sum over the two flanks (1.0 arcmin for the default modification).  Wear raises
``c`` by about its depth at the pin of the largest arm, where it is deepest: 1 um on both flanks adds 2 um / (e Zc),
10.6 arcsec on the RV-20E.

Wear coefficient: the span of :data:`rvdiag.gears.wear.WEAR_COEFFICIENTS` (lubricated, hardened steel in mild
wear), the same for this stage's contacts as for the sun's.  :func:`pin_wear_profile` gives the depth and the lost
motion for a duty; ``research/pin_wear.py`` compares the lost motion with the measured 12.9 arcsec over 1,550 h,
which bounds ``k`` (docs/model.md).

Assumptions a user must know: the static load (no dynamic factor), no losses, the discs sharing the torque equally,
non-rotating pins, a steady duty, and both flanks worn alike when the torque reverses (``flanks=2``: each flank
carries the load half the hours; the simulator's state).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.gears.cycloid import (closing_offset, disc_torque, modification_clearance, pin_contact_stiffness,
                                  theoretical_curvature_radius)
from rvdiag.gears.wear import DEFAULT_WEAR_COEFFICIENT, DutyCycle, history_arguments
from rvdiag.params.schema import MAX_PIN_WEAR_DEPTH
from rvdiag.validation import is_number

#: points of the clearance table over cos(eta) in [-1, 1] that the simulator interpolates
PIN_WEAR_TABLE_POINTS = 1025
#: crank angles per pin pitch at which the load distribution is solved (the phase grid is Zp times finer)
_POINTS_PER_PITCH = 64
#: the pin surface grid's spacing (m) and the largest clearance growth per integration step, as a fraction of the
#: most loaded pin's elastic approach (as rvdiag.gears.wear's run-in)
_PIN_GRID = 1.0e-6
_STEP = 0.05


@dataclass(frozen=True)
class PinWearProfile:
    """Wear of the cycloid-pin stage along the pin phase ``eta`` (rad, the loaded flank's half, 0..pi).

    ``disc`` and ``pin`` are the depths (m, along the contact normal) of the disc flank at the contact of phase
    ``eta`` and of the pin at the point it touches there; ``pin_arc``/``pin_depth`` the pin's wear along its
    surface (m of arc from its radial line); ``force_N`` the pin force at each phase under the worn stage at the
    duty's load; ``revolutions`` the output revolutions each flank carried the load; ``flanks`` 1 or 2.
    """

    eta: np.ndarray
    disc: np.ndarray
    pin: np.ndarray
    pin_arc: np.ndarray
    pin_depth: np.ndarray
    force_N: np.ndarray
    revolutions: float
    k_wear: float
    flanks: int

    @property
    def clearance(self) -> np.ndarray:
        """The clearance growth along the normal at each phase: ``disc + pin`` (m)."""
        return self.disc + self.pin

    @property
    def max_depth(self) -> float:
        """The largest clearance growth on a flank (m): the simulator's ``[stage2] pin_wear_depth``."""
        return float(self.clearance.max())

    def table(self, points: int = PIN_WEAR_TABLE_POINTS) -> np.ndarray:
        """The clearance growth on ``points`` equally spaced values of ``cos eta`` from -1 to 1 (both flanks
        alike: a function of ``cos eta`` alone)."""
        return clearance_table(self.eta, self.clearance, points)

    def lost_motion_growth_rad(self, params) -> float:
        """How much this wear adds to the stage's geometric lost motion (rad at the output): the growth of the
        closing rotation on each worn flank (:func:`lost_motion`)."""
        return self.flanks / 2.0 * (lost_motion(params, self.table()) - lost_motion(params))


def clearance_table(eta: np.ndarray, clearance: np.ndarray, points: int = PIN_WEAR_TABLE_POINTS) -> np.ndarray:
    """A flank's clearance growth at phases ``eta`` (0..pi) on ``points`` equally spaced ``cos eta`` in [-1, 1]."""
    c = np.linspace(-1.0, 1.0, int(points))
    order = np.argsort(np.cos(eta))
    return np.interp(c, np.cos(eta)[order], np.asarray(clearance, dtype=float)[order], left=0.0, right=0.0)


def table_function(table: np.ndarray):
    """The clearance (m) at ``cos eta`` of a table of :func:`clearance_table` (linear interpolation, as the
    compiled kernels read it)."""
    table = np.asarray(table, dtype=float)
    c = np.linspace(-1.0, 1.0, table.size)
    return lambda cos_eta: np.interp(cos_eta, c, table)


def lost_motion(params, table: np.ndarray | None = None) -> float:
    """The cycloid-pin stage's geometric lost motion (rad at the output): the closing rotations of the two flanks,
    ``(c_+ - c_-) / (e Zc)`` (:func:`rvdiag.gears.cycloid.closing_offset`), with the profile modification and the
    wear ``table`` (:func:`clearance_table`; ``None``: none)."""
    s2 = params.stage2
    k1 = s2.short_amplitude_coefficient
    extra = None if table is None else table_function(table)
    c = [closing_offset(k1, s2.equidistant_modification, s2.offset_modification, sense, extra=extra)
         for sense in (1, -1)]
    return (c[0] - c[1]) / (s2.eccentricity * s2.cycloid_lobes)


class _Stage:
    """The phase grid of one flank and everything on it that does not change as the stage wears."""

    def __init__(self, params, load_Nm: float, points_per_pitch: int):
        s2, mat = params.stage2, params.material
        self.zp, self.zc = s2.pins, s2.cycloid_lobes
        self.m = int(points_per_pitch)
        rp, self.r = s2.pin_circle_radius, s2.pin_radius
        k1 = s2.short_amplitude_coefficient
        self.e_zc = s2.eccentricity * s2.cycloid_lobes
        self.b = s2.cycloid_face_width
        n = self.zp * self.m
        self.deta = 2.0 * math.pi / n
        self.eta = np.arange(n) * self.deta                      # the whole circle; pins at m + k M
        ce, se = np.cos(self.eta), np.sin(self.eta)
        s = np.sqrt(1.0 + k1 * k1 - 2.0 * k1 * ce)
        self.arm = se / s                                         # the lever arm over e Zc
        self.loaded = self.arm > 1e-9
        self.base = modification_clearance(ce, se, k1, s2.equidistant_modification, s2.offset_modification, 0.0)
        rho0 = theoretical_curvature_radius(self.eta, rp, k1, self.zp)
        if np.any((rho0 > 0) & (rho0 <= self.r)):
            raise ParameterError("cycloid profile undercut: the pin-stage wear needs an unundercut disc")
        length = rp * s
        self.slide_disc = (length - self.r) * rho0 / (length * (rho0 - self.r))   # v_s / v_d
        self.slide_pin = length - self.r                                          # v_s / Omega
        self.arc = self.r * np.arctan2(k1 * se, 1.0 - k1 * ce)                    # contact point on the pin
        e_star = mat.youngs_modulus / (2.0 * (1.0 - mat.poisson_ratio ** 2))
        self.hertz = 4.0 * (1.0 / (1.0 / self.r + 1.0 / (rho0 - self.r))) / (math.pi * e_star)  # a^2 per N/m
        self.k_pin = pin_contact_stiffness(params, load_Nm)
        self.torque = disc_torque(params, load_Nm) / self.e_zc  # sum F_k a_k
        top = self.r * math.asin(k1)
        self.pin_arc = np.arange(-20e-6, top + 20e-6, _PIN_GRID)

    def loads(self, wear: np.ndarray) -> np.ndarray:
        """Each phase's pin force (N) under the stage with ``wear`` (m, on the whole grid)."""
        gap = (self.base + wear).reshape(self.zp, self.m).T           # (crank angle, pin)
        arm = self.arm.reshape(self.zp, self.m).T
        on = arm > 1e-9
        a = np.where(on, arm, 0.0)
        ratio = np.where(on, gap / np.where(on, arm, 1.0), np.inf)
        lo = ratio.min(axis=1)
        hi = np.where(on, ratio, -np.inf).max(axis=1) + self.torque / (self.k_pin * np.sum(a * a, axis=1))
        for _ in range(60):                                           # the carried torque rises with x
            x = 0.5 * (lo + hi)
            t = np.sum(self.k_pin * np.maximum(x[:, None] * a - gap, 0.0) * a, axis=1)
            big = t > self.torque
            hi = np.where(big, x, hi)
            lo = np.where(big, lo, x)
        x = 0.5 * (lo + hi)
        force = np.where(on, self.k_pin * np.maximum(x[:, None] * a - gap, 0.0), 0.0)
        return force.T.reshape(-1)

    def clearance(self, disc: np.ndarray, pin: np.ndarray) -> np.ndarray:
        """The clearance growth at each phase: the disc's depth there plus the pin's (``pin`` along ``pin_arc``) at
        the point it touches."""
        return disc + np.interp(self.arc, self.pin_arc, pin)

    def advance(self, disc: np.ndarray, pin: np.ndarray, k_wear: float, most: float) -> tuple:
        """One step of the run-in: ``(disc, pin, revolutions)`` after at most ``most`` output revolutions, fewer
        where the clearance would grow by more than ``_STEP`` of the most loaded pin's elastic approach."""
        force = self.loads(self.clearance(disc, pin))
        d_rate, p_rate = self.rates(force, k_wear)
        step = min(most, _STEP * force.max() / self.k_pin / float(self.clearance(d_rate, p_rate).max()))
        return disc + d_rate * step, pin + p_rate * step, step

    def rates(self, force: np.ndarray, k_wear: float) -> tuple[np.ndarray, np.ndarray]:
        """Depth per output revolution (m) of the disc at each phase and of the pin along ``pin_arc``."""
        w = force / self.b
        disc = self.zp * k_wear * w * self.slide_disc
        idx = np.flatnonzero(w > 0.0)
        pin = np.zeros_like(self.pin_arc)
        for chunk in np.array_split(idx, max(1, idx.size // 256)):
            a2 = self.hertz[chunk] * w[chunk]
            dx = self.pin_arc[None, :] - self.arc[chunk, None]
            p = 2.0 * w[chunk, None] / (math.pi * a2[:, None]) * np.sqrt(np.maximum(a2[:, None] - dx * dx, 0.0))
            pin += np.sum(k_wear * self.slide_pin[chunk, None] * p, axis=0) * self.deta
        return disc, pin


def _revolutions(hours: float, duty: DutyCycle, flanks: int) -> float:
    """Output revolutions each flank carries the load in ``hours`` of ``duty``."""
    return duty.output_speed_deg_s / 360.0 * 3600.0 * hours * duty.moving_fraction / flanks


def pin_wear_history(params, hours, duty: DutyCycle, k_wear: float = DEFAULT_WEAR_COEFFICIENT, *, flanks: int = 2,
                     points_per_pitch: int = _POINTS_PER_PITCH) -> list[PinWearProfile]:
    """:func:`pin_wear_profile` at each of the increasing ``hours`` (a sequence), from one integration."""
    hours = history_arguments(hours, duty, k_wear)
    if flanks not in (1, 2):
        raise ParameterError(f"flanks must be 1 or 2, got {flanks!r}")
    st = _Stage(params, duty.load_Nm, points_per_pitch)
    disc = np.zeros_like(st.eta)
    pin = np.zeros_like(st.pin_arc)
    done, out = 0.0, []
    for t in hours:
        target = _revolutions(t, duty, flanks)
        while done < target and k_wear > 0.0 and duty.load_Nm != 0.0:
            disc, pin, step = st.advance(disc, pin, k_wear, target - done)
            done += step
        force = st.loads(st.clearance(disc, pin))
        half = st.loaded
        out.append(PinWearProfile(eta=st.eta[half], disc=disc[half].copy(),
                                  pin=(st.clearance(disc, pin) - disc)[half], pin_arc=st.pin_arc.copy(),
                                  pin_depth=pin.copy(), force_N=force[half], revolutions=float(target),
                                  k_wear=float(k_wear), flanks=int(flanks)))
    return out


def pin_wear_profile(params, hours: float, duty: DutyCycle, k_wear: float = DEFAULT_WEAR_COEFFICIENT, *,
                     flanks: int = 2, points_per_pitch: int = _POINTS_PER_PITCH) -> PinWearProfile:
    """Archard wear of the cycloid discs' flanks and the pins after ``hours`` of ``duty`` (module docstring).

    Parameters
    ----------
    params : rvdiag.params.ReducerParams
    hours : float
        Hours in service (the duty's moving share of them turns the stage).
    duty : rvdiag.gears.wear.DutyCycle
    k_wear : float
        Dimensional wear coefficient (m^2/N), :data:`rvdiag.gears.wear.WEAR_COEFFICIENTS`.
    flanks : {2, 1}
        2 (default): the torque reverses, each flank carrying it half the hours (the simulator's state, both flanks
        alike); 1: one sense throughout (the other flank stays new).

    Returns
    -------
    PinWearProfile
        ``max_depth`` the largest clearance growth on a worn flank; ``lost_motion_growth_rad(params)`` what it adds
        to the lost motion.

    Examples
    --------
    >>> from rvdiag.params import ReducerParams
    >>> p = ReducerParams.default()
    >>> w = pin_wear_profile(p, 1000.0, DutyCycle(90.0, 167.0), 1e-18)
    >>> 0.1e-6 < w.max_depth < 10e-6, bool(w.lost_motion_growth_rad(p) > 0)
    (True, True)
    """
    return pin_wear_history(params, [hours], duty, k_wear, flanks=flanks, points_per_pitch=points_per_pitch)[0]


def check_pin_wear_depth(depth, name: str = "[stage2] pin_wear_depth", scale: float = 1.0, unit: str = "m") -> float:
    """``depth`` (m) as a float when it is a finite number in ``[0, MAX_PIN_WEAR_DEPTH]``, else a one-line
    :class:`~rvdiag.errors.ParameterError` naming ``name`` (the value shown divided by ``scale``, in ``unit``)."""
    if not is_number(depth) or not 0.0 <= float(depth) <= MAX_PIN_WEAR_DEPTH:
        shown = f"{depth / scale:g} {unit}" if is_number(depth) else repr(depth)
        raise ParameterError(f"{name} must be between 0 and {MAX_PIN_WEAR_DEPTH / scale:g} {unit} (ten times the "
                             f"stage's radial clearance), got {shown}")
    return float(depth)


class _RunIn:
    """One stage's run-in at its rated torque, integrated as far as a table has asked for and kept (the clearance
    profile after each step), so that every depth up to there is an interpolation between two kept steps."""

    def __init__(self, params):
        self.stage = _Stage(params, float(params.operation.rated_torque), _POINTS_PER_PITCH)
        self.disc = np.zeros_like(self.stage.eta)
        self.pin = np.zeros_like(self.stage.pin_arc)
        self.profiles = [np.zeros_like(self.stage.eta)]
        self.depths = [0.0]

    def table(self, depth: float, points: int) -> np.ndarray:
        st = self.stage
        while self.depths[-1] < depth:
            self.disc, self.pin, _ = st.advance(self.disc, self.pin, DEFAULT_WEAR_COEFFICIENT, math.inf)
            self.profiles.append(st.clearance(self.disc, self.pin))
            self.depths.append(float(self.profiles[-1].max()))
        i = int(np.searchsorted(self.depths, depth))           # the step that crossed the depth, linearly
        lo, hi = self.profiles[i - 1], self.profiles[i]
        clearance = lo + (depth - self.depths[i - 1]) / (self.depths[i] - self.depths[i - 1]) * (hi - lo)
        table = clearance_table(st.eta[st.loaded], clearance[st.loaded], points)
        return table * (depth / table.max())                   # its deepest node the depth


@lru_cache(maxsize=8)
def _run_in(stage1, stage2, material, rated: float) -> _RunIn:
    """The run-in of a stage: what its shape depends on (the two stages, whose teeth give the ratio, the material
    and the rated torque), not the depth, so that a library drawing a depth per simulation integrates it once."""
    from rvdiag.params import ReducerParams

    base = ReducerParams.default()
    return _RunIn(dataclasses.replace(base, stage1=stage1, stage2=stage2, material=material,
                                      operation=dataclasses.replace(base.operation, rated_torque=rated)))


def pin_wear_table(params, depth: float | None = None, points: int = PIN_WEAR_TABLE_POINTS) -> np.ndarray:
    """The clearance growth (m) on ``points`` equally spaced ``cos eta`` in [-1, 1] of a stage worn ``depth`` deep
    (default the parameter set's ``[stage2] pin_wear_depth``, :func:`stage_wear_depth`) on both flanks: the shape
    Archard's law gives it at the parameter set's rated torque (run-in load sharing included; the speed and the coefficient change only how long it takes),
    scaled to ``depth`` at its deepest.  Zeros for ``depth = 0``.  The run-in is kept per stage (the last 8), so another
depth of the same stage costs only the steps beyond the deepest asked for so far.

    >>> from rvdiag.params import ReducerParams
    >>> t = pin_wear_table(ReducerParams.default(), 2e-6)
    >>> float(t.max()), float(t[0]), float(t[-1])
    (2e-06, 0.0, 0.0)
    """
    depth = check_pin_wear_depth(stage_wear_depth(params) if depth is None else depth)
    if depth == 0.0:
        return np.zeros(int(points))
    run_in = _run_in(params.stage1, dataclasses.replace(params.stage2, pin_wear_depth=None), params.material,
                     float(params.operation.rated_torque))
    return run_in.table(float(depth), int(points))


def stage_wear_depth(params) -> float:
    """The parameter set's ``[stage2] pin_wear_depth`` (m; 0 where it is not stated)."""
    return float(params.stage2.pin_wear_depth or 0.0)
