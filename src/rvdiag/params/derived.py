"""Masses and moments of inertia derived from a parameter set's dimensions.

No public mass or inertia figures exist for the RV-20E's parts, so each body is modelled as a steel
annulus (hollow cylinder) of the dimensions in the ``[bodies]``, ``[stage1]`` and ``[stage2]``
sections: m = rho pi (R^2 - r^2) b and J = m (R^2 + r^2) / 2 about its own axis.  Gear blanks use the
pitch radius as R; the cycloid disc uses the pin circle radius minus the pin radius and has the crank
holes removed.  These are estimates good to perhaps +-30 %; users with drawings should override them
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


def body_properties(p: ReducerParams) -> BodyProperties:
    """Estimate masses and inertias of all bodies from the parameter set's dimensions."""
    rho = p.material.density
    s1, s2, b = p.stage1, p.stage2, p.bodies
    sun_pitch = 0.5 * s1.module * s1.sun_teeth
    planet_pitch = 0.5 * s1.module * s1.planet_teeth
    sun = annulus(rho, sun_pitch, min(b.sun_shaft_radius, 0.9 * sun_pitch), s1.face_width)
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
