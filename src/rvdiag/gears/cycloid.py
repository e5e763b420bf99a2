"""Cycloid-pin contact of the RV reducer's second stage: which pins touch, force directions, stiffness.

Geometry (pin wheel fixed; angles in the fixed frame, pin i at psi_i = 2 pi i / Zp on the pin
circle of radius r_p; the crank's eccentricity e points at theta_e):

* meshing phase of pin i: phi_i = psi_i - theta_e;
* short-amplitude coefficient K1 = e Zp / r_p < 1 and S_i = sqrt(1 + K1^2 - 2 K1 cos(phi_i));
* all contact normals pass through the pitch point P, on the line of centres at e Zp from the
  pin-wheel centre, so the force of pin i on the disc acts along pin_i -> P, and its arm about the
  disc centre is l_i = e Zc sin(phi_i) / S_i (Blagojevic et al. 2011, J. Mech. Des. 133, 085001,
  eq. (9); Chen, Fang, Li & Wang 2008, Sci. China E 51, "Gear geometry of cycloid drives");
* with an unmodified profile and no clearance, the pins with 0 < phi_i < pi (half of them) carry
  the load for the positive torque direction (the other half for the negative one); the load is
  shared in proportion to the arm, F_i = F_max l_i / l_max (Blagojevic et al. 2011, eq. (11)), and
  torque equilibrium sum F_i l_i = T gives F_max = T l_max / sum l_i^2;
* radius of curvature of the theoretical profile (the pin-centre path relative to the disc) at
  pin i (Chen et al. 2008; zhygear.com cycloid profile analysis):
  rho_0 = r_p S^3 / (K1 (1 + Zp) cos(phi) - (1 + Zp K1^2)),
  positive where the profile is convex; the actual profile lies r_rp inside: rho_a = rho_0 - r_rp
  (convex parts need rho_0 > r_rp, otherwise the profile is undercut).

Contact stiffness: Hertz line contact of the pin (radius r_rp) on the disc flank (radius rho_a,
negative when concave), face width b.  With P = F/b the load per length, the half width
a = sqrt(4 P R / (pi E*)), 1/R = 1/r_rp + 1/rho_a, E* = E / (2 (1 - nu^2)), and the approach of
the two bodies' centres delta = (2 P / pi) sum_i (1 - nu_i^2)/E_i (ln(4 R_i / a) - 1/2)
(Johnson 1985, *Contact Mechanics*, sec. 5.6, two cylinders in line contact).  The tangent
stiffness is k = dF/d delta = b / ((2/pi) sum_i (1 - nu^2)/E (ln(4 R_i / a) - 1)); it grows with
load (logarithmically) and vanishes at zero load.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rvdiag.errors import GeometryError, ParameterError
from rvdiag.validation import finite_number, number

#: default torque on one disc about its centre: half the RV-20E rated output torque 167 N m
#: (Nabtesco RV-E catalog, as quoted) for the two discs
DEFAULT_DISC_TORQUE_N_M = 0.5 * 167.0


@dataclass(frozen=True)
class PinContact:
    """Contact state of every pin of one disc at one crank angle (arrays of length Zp)."""

    phase_rad: np.ndarray
    in_contact: np.ndarray
    force_angle_rad: np.ndarray
    arm_m: np.ndarray
    load_N: np.ndarray
    curvature_radius_m: np.ndarray
    stiffness_N_per_m: np.ndarray


def theoretical_curvature_radius(phase: np.ndarray, pin_circle_radius: float, k1: float,
                                 pins: int) -> np.ndarray:
    """Signed radius of curvature rho_0 (m) of the theoretical cycloid profile at meshing phase
    ``phase`` (Chen et al. 2008): r_p S^3 / (K1 (1 + Zp) cos(phi) - (1 + Zp K1^2))."""
    s = np.sqrt(1.0 + k1 * k1 - 2.0 * k1 * np.cos(phase))
    den = k1 * (1.0 + pins) * np.cos(phase) - (1.0 + pins * k1 * k1)
    with np.errstate(divide="ignore"):
        return -pin_circle_radius * s**3 / den


def line_contact_stiffness(load_N: np.ndarray, radius1: float, radius2: np.ndarray, width: float,
                           youngs_modulus: float, poisson_ratio: float) -> np.ndarray:
    """Tangent Hertz line-contact stiffness (N/m) of two cylinders of one material (Johnson 1985,
    sec. 5.6).  ``radius2`` < 0 means a concave surface.  Zero load gives zero stiffness."""
    load = np.asarray(load_N, dtype=float)
    r2 = np.asarray(radius2, dtype=float)
    inv_r = 1.0 / radius1 + 1.0 / r2
    c = (1.0 - poisson_ratio**2) / youngs_modulus
    e_star = 1.0 / (2.0 * c)
    p = np.maximum(load, 0.0) / width
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.sqrt(4.0 * p / (inv_r * math.pi * e_star))
        comp = (2.0 / math.pi) * c * ((np.log(4.0 * radius1 / a) - 1.0)
                                       + (np.log(4.0 * np.abs(r2) / a) - 1.0))
        k = width / comp
    return np.where(p > 0, k, 0.0)


def pin_contact(stage2, material, crank_angle_rad: float, torque_N_m: float = DEFAULT_DISC_TORQUE_N_M,
                disc: int = 0, direction: int = 1) -> PinContact:
    """Full contact state of disc ``disc`` at crank angle ``crank_angle_rad`` (see module doc).

    Parameters
    ----------
    stage2 : rvdiag.params.schema.Stage2
    material : rvdiag.params.schema.Material
    crank_angle_rad : float
        Direction of the crank eccentricity in the fixed frame (rad); disc ``d`` is offset by
        ``d * stage2.disc_phase_deg``.
    torque_N_m : float
        Torque the disc transmits about its own centre (N m).
    direction : {1, -1}
        Sense of the torque; selects which half of the pins carries load.
    """
    if direction not in (1, -1):
        raise ParameterError(f"direction must be 1 or -1, got {direction!r}")
    finite_number(torque_N_m, "torque_N_m", 0)
    number(crank_angle_rad, "crank_angle_rad")
    zp, zc = stage2.pins, stage2.cycloid_lobes
    rp, rrp, e = stage2.pin_circle_radius, stage2.pin_radius, stage2.eccentricity
    k1 = e * zp / rp
    if not 0.0 < k1 < 1.0:
        raise GeometryError(f"short-amplitude coefficient K1 = e Zp / r_p = {k1:.3f} must lie in (0, 1)")
    theta_e = crank_angle_rad + math.radians(stage2.disc_phase_deg) * disc
    psi = 2.0 * math.pi * np.arange(zp) / zp
    phase = np.mod(psi - theta_e, 2.0 * math.pi)
    s = np.sqrt(1.0 + k1 * k1 - 2.0 * k1 * np.cos(phase))
    arm = e * zc * np.sin(phase) / s * direction
    in_contact = arm > 1e-12 * rp
    pins_xy = rp * np.stack([np.cos(psi), np.sin(psi)])
    pitch = e * zp * np.array([math.cos(theta_e), math.sin(theta_e)])[:, None]
    d = pitch - pins_xy
    force_angle = np.arctan2(d[1], d[0])
    arm_c = np.where(in_contact, arm, 0.0)
    denom = float(np.sum(arm_c**2))
    f_max = torque_N_m * arm_c.max() / denom if denom > 0 else 0.0
    load = np.where(in_contact, f_max * arm_c / max(arm_c.max(), 1e-300), 0.0)
    rho0 = theoretical_curvature_radius(phase, rp, k1, zp)
    rho_a = rho0 - rrp
    if np.any((rho0 > 0) & (rho0 <= rrp)):
        raise GeometryError(
            f"cycloid profile undercut: the theoretical profile's smallest convex radius "
            f"{rho0[rho0 > 0].min() * 1e3:.3f} mm is below the pin radius {rrp * 1e3:.3f} mm")
    k = np.where(in_contact, line_contact_stiffness(load, rrp, rho_a, stage2.cycloid_face_width,
                                                    material.youngs_modulus, material.poisson_ratio), 0.0)
    return PinContact(phase, in_contact, force_angle, arm, load, rho_a, k)


def pin_contact_state(stage2, material, crank_angle_rad: float,
                      torque_N_m: float = DEFAULT_DISC_TORQUE_N_M, disc: int = 0,
                      direction: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(in_contact, force_angle_rad, stiffness_N_per_m) per pin, for cross-checks of dynamics.

    >>> from rvdiag.params import ReducerParams
    >>> p = ReducerParams.default()
    >>> inc, ang, k = pin_contact_state(p.stage2, p.material, 0.0)
    >>> int(inc.sum()), bool(k[inc].min() > 1e7)
    (19, True)
    """
    c = pin_contact(stage2, material, crank_angle_rad, torque_N_m, disc, direction)
    return c.in_contact, c.force_angle_rad, c.stiffness_N_per_m


def modification_clearance(cos_eta, sin_eta, k1: float, equidistant: float, offset: float, closing: float):
    """Initial clearance (m) between a pin and a modified disc flank, along the contact normal through the
    pitch point, at pin phase ``eta`` (the pin's angle from the crank's eccentricity; ``phi_i`` of the module
    doc, ``eta_k`` of docs/model.md section 3).

    A disc ground with the pin radius enlarged by ``equidistant`` (Delta r_rp, "equidistant modification")
    and the pin circle radius changed by ``offset`` (Delta r_p, "offset" or "moving-distance modification")
    stands off a pin of the nominal geometry by

        Delta(eta) = Delta r_rp - Delta r_p (1 - K1 cos eta) / S - closing sin(eta) / S,
        S = sqrt(1 + K1^2 - 2 K1 cos eta)

    (the initial clearance of the modified cycloid used throughout the cycloid-drive literature, e.g. Xu & Yang
    2016, Mech. Mach. Theory 104, "Dynamic modeling and contact analysis of a cycloid-pin gear mechanism"; to
    first order in the modifications, derived here): the equidistant term is a uniform offset of the flank
    along its normal; the offset term is the normal component of the generating pin's radial shift (an
    envelope moves by the normal component of its generator's displacement; ``e_r . n = (1 - K1 cos eta) /
    S``); ``closing`` is the disc's rigid rotation that
    takes up the clearance, as a normal displacement at unit arm (``l = e Zc sin(eta) / S``, so a rotation
    ``b`` gives ``closing = e Zc b``); :func:`closing_offset` chooses it so that the tightest pin of the loaded
    half just touches.  Works on floats and arrays alike.
    """
    s = np.sqrt(1.0 + k1 * k1 - 2.0 * k1 * cos_eta)
    return equidistant - offset * (1.0 - k1 * cos_eta) / s - closing * sin_eta / s


def closing_offset(k1: float, equidistant: float, offset: float, sense: int = 1, points: int = 20000,
                   extra=None) -> float:
    """The disc rotation (as ``e Zc b``, m) that closes the modified profile's clearance on the loaded half of
    the pins, those with ``sense * sin(eta) > 0``: the largest ``c`` with ``Delta(eta; c) >= 0`` there, found
    on a grid of ``points`` phases (the clearance is smooth; 20,000 points resolve it to < 1e-12 m here).

    For the usual positive equidistant and negative offset modification this is ``sense (Delta r_rp - Delta r_p
    sqrt(1 - K1^2))``, the pin at ``cos eta = K1`` touching (tests/test_cycloid_modification.py).  Raises
    :class:`~rvdiag.errors.ParameterError` when the flank interferes with the pins where no rotation can free
    it (a negative radial clearance ``Delta r_rp - Delta r_p`` at the tooth tip and root).

    ``extra``, optional, adds a clearance that depends on ``cos eta`` (a callable, m): the worn flanks and pins of
    :mod:`rvdiag.gears.pin_wear`, which the rotation then takes up as well.
    """
    if sense not in (1, -1):
        raise ParameterError(f"sense must be 1 or -1, got {sense!r}")
    if equidistant - offset < 0.0:
        raise ParameterError(
            f"cycloid profile modification: the radial clearance equidistant - offset = "
            f"{(equidistant - offset) * 1e6:.2f} um is negative (the disc would interfere with the pins)")
    if equidistant == 0.0 and offset == 0.0 and extra is None:
        return 0.0
    eta = np.linspace(0.0, 2.0 * math.pi, points, endpoint=False)
    arm = sense * np.sin(eta) / np.sqrt(1.0 + k1 * k1 - 2.0 * k1 * np.cos(eta))
    raw = modification_clearance(np.cos(eta), np.sin(eta), k1, equidistant, offset, 0.0)
    if extra is not None:
        raw = raw + extra(np.cos(eta))
    loaded = arm > 1e-3
    return float(sense * np.min(raw[loaded] / arm[loaded]))


#: Pin stiffness is linearised at ``max(|T_L|, PIN_LOAD_FLOOR_FRACTION * rated torque)``: the Hertz
#: tangent stiffness vanishes (logarithmically) at zero load, where a linearisation means nothing.
PIN_LOAD_FLOOR_FRACTION = 0.01
#: crank angles (over one pin pitch) averaged in :func:`pin_contact_stiffness`
PIN_STIFFNESS_ANGLES = 8


def disc_torque(params, load_Nm: float) -> float:
    """The torque (N m) one disc carries about its own centre at the output torque ``load_Nm``: the pin-wheel
    reaction ``|T_L| (1 - 1/i)`` times the arm ratio ``Zc / Zp``, shared by the ``D`` discs
    (:func:`pin_contact_stiffness`)."""
    s2 = params.stage2
    return abs(float(load_Nm)) * (1.0 - 1.0 / params.ratio) * s2.cycloid_lobes / (s2.pins * s2.n_discs)


def pin_contact_stiffness(params, load_Nm: float) -> float:
    """Cycloid-pin contact stiffness (N/m) linearised at the operating load, one value for every pin.

    The per-pin tangent stiffness is the Hertz line contact of the pin on the disc flank at its share
    of the load (Johnson 1985, *Contact Mechanics*, sec. 5.6; load shared in proportion to the lever
    arm, Blagojevic et al. 2011, J. Mech. Des. 133, eq. 11), as computed by
    :func:`rvdiag.gears.cycloid.pin_contact`.  The torque one disc carries about its own centre is the
    pin-wheel reaction ``T_L (1 - 1/i)`` (docs/model.md, sec. 5) times the arm ratio ``Zc / Zp``
    (arms ``e Zc n_y`` about the disc, ``e Zp n_y`` about the pin wheel), shared by the ``D`` discs:
    ``T_d = |T_L| (1 - 1/i) Zc / (Zp D)``.  The pins in contact act on the disc's rocking in parallel
    through their arms, so the equivalent uniform stiffness is the arm-weighted mean
    ``k = sum k_i l_i^2 / sum l_i^2`` (same disc torsional stiffness), averaged over
    ``PIN_STIFFNESS_ANGLES`` crank angles across one pin pitch (it varies by < 0.5 %).  For the RV-20E
    at rated torque (167 N m) this is 3.4e8 N/m, 2.3e8 at 1 N m: the Hertz stiffness of a loaded pin,
    against the load-independent 1.78e9 of Yang & Sun's ``pi E b / (4 (1 - nu^2))``.
    """
    s2 = params.stage2
    load = max(abs(float(load_Nm)), PIN_LOAD_FLOOR_FRACTION * params.operation.rated_torque)
    t_disc = disc_torque(params, load)
    vals = []
    for ang in np.arange(PIN_STIFFNESS_ANGLES) * (2.0 * math.pi / s2.pins / PIN_STIFFNESS_ANGLES):
        c = pin_contact(s2, params.material, float(ang), t_disc)
        l2 = np.where(c.in_contact, c.arm_m, 0.0) ** 2
        vals.append(float(np.sum(c.stiffness_N_per_m * l2) / np.sum(l2)))
    return float(np.mean(vals))
