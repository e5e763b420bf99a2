"""Masses and moments of inertia derived from a parameter set's dimensions.

No public mass or inertia figures exist for the RV-20E's parts, so each body is modelled as a steel
annulus (hollow cylinder) of the dimensions in the ``[bodies]``, ``[stage1]`` and ``[stage2]``
sections: m = rho pi (R^2 - r^2) b and J = m (R^2 + r^2) / 2 about its own axis.  Gear blanks use the
pitch radius as R; the cycloid disc uses the pin circle radius minus the pin radius and has the crank
holes removed.  The sun is the RV-20E's input shaft with the small sun gear cut on it (Nabtesco
RV-E construction: the 11-tooth sun is too small to be a separate gear on a bore), so the sun body
is the gear ring plus a solid steel shaft of ``bodies.input_shaft_radius`` and
``bodies.input_shaft_length``, moving as one rigid body (:func:`input_shaft`).  These are estimates good to perhaps +-30 %; users with drawings should override them
through :func:`body_properties`' result or their own parameter file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rvdiag.params.schema import ReducerParams


@dataclass(frozen=True)
class Body:
    """Mass (kg) and polar moment of inertia about the body's own axis (kg m^2)."""

    mass: float
    inertia: float


def annulus(density: float, outer_radius: float, inner_radius: float, width: float) -> Body:
    """Steel annulus: m = rho pi (R^2 - r^2) b, J = m (R^2 + r^2)/2.

    >>> b = annulus(7850.0, 0.1, 0.0, 0.01)
    >>> round(b.mass, 4), round(b.inertia, 7)
    (2.4662, 0.0123308)
    """
    if not outer_radius > inner_radius >= 0:
        raise ValueError("annulus needs outer_radius > inner_radius >= 0")
    mass = density * math.pi * (outer_radius**2 - inner_radius**2) * width
    return Body(mass, 0.5 * mass * (outer_radius**2 + inner_radius**2))


@dataclass(frozen=True)
class BodyProperties:
    """Derived mass properties of every body of the RV reducer model."""

    sun: Body
    planet: Body
    crank: Body
    cycloid: Body
    carrier: Body
    pin_wheel: Body


def input_shaft(p: ReducerParams) -> Body:
    """Input shaft that carries the sun gear: a solid steel cylinder of radius
    ``bodies.input_shaft_radius`` and length ``bodies.input_shaft_length`` (m = rho pi r^2 L,
    J = m r^2 / 2).  Lumped with the sun gear ring in :func:`body_properties` (rigid shaft: its
    bending and torsion are in ``bearings.sun_support`` and ``bearings.input_torsional``)."""
    b = p.bodies
    return annulus(p.material.density, b.input_shaft_radius, 0.0, b.input_shaft_length)


def body_properties(p: ReducerParams) -> BodyProperties:
    """Estimate masses and inertias of all bodies from the parameter set's dimensions.

    ``sun`` is the sun gear ring plus the input shaft it is cut on (:func:`input_shaft`).
    """
    rho = p.material.density
    s1, s2, b = p.stage1, p.stage2, p.bodies
    sun_pitch = 0.5 * s1.module * s1.sun_teeth
    planet_pitch = 0.5 * s1.module * s1.planet_teeth
    ring = annulus(rho, sun_pitch, min(b.sun_shaft_radius, 0.9 * sun_pitch), s1.face_width)
    shaft = input_shaft(p)
    sun = Body(ring.mass + shaft.mass, ring.inertia + shaft.inertia)
    planet = annulus(rho, planet_pitch, b.crank_shaft_radius, s1.face_width)
    crank = annulus(rho, b.crank_shaft_radius, 0.0, b.crank_shaft_length)
    disc_outer = s2.pin_circle_radius - s2.pin_radius
    disc = annulus(rho, disc_outer, b.cycloid_bore_radius, s2.cycloid_face_width)
    # remove the crank holes (radius = crank journal + needle ring of ~1/3 journal radius)
    hole_r = 1.33 * b.crank_shaft_radius
    hole = annulus(rho, hole_r, 0.0, s2.cycloid_face_width)
    hole_offset = s1.centre_distance
    n = s2.n_cranks
    cyc_mass = disc.mass - n * hole.mass
    cyc_inertia = disc.inertia - n * (hole.inertia + hole.mass * hole_offset**2)
    cycloid = Body(cyc_mass, cyc_inertia)
    carrier = annulus(rho, b.carrier_outer_radius, b.cycloid_bore_radius, b.carrier_width)
    pin_wheel = annulus(rho, b.pin_wheel_outer_radius, s2.pin_circle_radius, b.pin_wheel_width)
    return BodyProperties(sun, planet, crank, cycloid, carrier, pin_wheel)


# ---------------------------------------------------------------------- bearing stiffness estimates
#: Assumed bearing geometry (no RV-20E drawing is public).  The crank-cycloid needle ring fills the
#: gap between the crank journal (r_j = bodies.crank_shaft_radius) and the disc's crank hole of
#: radius 1.33 r_j used above, so the needle diameter is 0.33 r_j and the needles sit side by side
#: on the ring's mid circle with 5 % spacing; their effective length is 80 % of the disc face width
#: (end chamfers).  The crank's carrier bearings are tapered roller bearings, assumed with 12 rollers
#: of effective length 0.6 x the disc face width.
NEEDLE_LENGTH_FRACTION = 0.8
NEEDLE_SPACING = 1.05
CRANK_CARRIER_ROLLERS = 12
CRANK_CARRIER_ROLLER_LENGTH_FRACTION = 0.6


def palmgren_roller_bearing_stiffness(radial_load: float, n_rollers: int, roller_length: float) -> float:
    """Tangent radial stiffness (N/m) of a roller or needle bearing with zero clearance.

    Palmgren's line-contact deflection per raceway contact, delta = 3.84e-5 Q^0.9 / l^0.8 (delta in
    mm, Q in N, l in mm; Palmgren 1959, *Ball and Roller Bearing Engineering*, as given by Harris &
    Kotzalas 2006, *Rolling Bearing Analysis*, 5th ed., vol. 1, ch. 6), two contacts per roller
    (inner and outer ring), and Stribeck's load on the most loaded roller Q_max = 4.08 F_r / Z for
    line contact (Harris & Kotzalas, ch. 7).  Since delta ~ F^0.9 the tangent stiffness is
    k = F_r / (0.9 delta_r).

    >>> round(palmgren_roller_bearing_stiffness(1000.0, 20, 8e-3) / 1e8, 2)
    6.37
    """
    if not (radial_load > 0 and n_rollers > 0 and roller_length > 0):
        raise ValueError("radial_load, n_rollers and roller_length must be > 0")
    q_max = 4.08 * radial_load / n_rollers
    delta_mm = 2.0 * 3.84e-5 * q_max**0.9 / (roller_length * 1e3) ** 0.8
    return radial_load / (0.9 * delta_mm * 1e-3)


def crank_bearing_load(p: ReducerParams) -> float:
    """Radial load (N) on one crank bearing at rated output torque: the output torque passes from
    the discs to the carrier through the crank journals at the crank circle radius a (the stage-1
    centre distance), F = T / (n_discs n_cranks a), one bearing per crank and disc."""
    s1, s2 = p.stage1, p.stage2
    return p.operation.rated_torque / (s2.n_discs * s2.n_cranks * s1.centre_distance)


def bearing_estimates(p: ReducerParams) -> dict[str, float]:
    """Palmgren estimates (N/m) of the crank bearings at rated torque, for ``[bearings]`` values
    ``crank_cycloid`` and ``crank_carrier`` (``rv20e.toml`` holds them rounded to 2 digits)."""
    rj = p.bodies.crank_shaft_radius
    needle_d = 0.33 * rj
    ring_r = rj + 0.5 * needle_d
    n_needles = int(2.0 * math.pi * ring_r // (NEEDLE_SPACING * needle_d))
    load = crank_bearing_load(p)
    width = p.stage2.cycloid_face_width
    return {
        "crank_cycloid": palmgren_roller_bearing_stiffness(load, n_needles, NEEDLE_LENGTH_FRACTION * width),
        "crank_carrier": palmgren_roller_bearing_stiffness(
            load, CRANK_CARRIER_ROLLERS, CRANK_CARRIER_ROLLER_LENGTH_FRACTION * width),
    }
