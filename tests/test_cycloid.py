"""Cycloid-pin contact: pins in contact, force direction through the pitch point, curvature, stiffness."""

import math

import numpy as np
import pytest

from rvdiag.errors import GeometryError, ParameterError
from rvdiag.gears import pin_contact_state
from rvdiag.gears.cycloid import line_contact_stiffness, pin_contact, theoretical_curvature_radius
from rvdiag.params import ReducerParams


@pytest.fixture(scope="module")
def p():
    return ReducerParams.default()


def test_half_the_pins_carry_load_and_torque_balances(p):
    s2 = p.stage2
    for crank in (0.0, 0.3, 2.0):
        c = pin_contact(s2, p.material, crank, torque_N_m=80.0)
        # phases in (0, pi): half of the 40 pins (19 or 20 depending on the angle)
        assert 19 <= c.in_contact.sum() <= 20
        assert np.all(np.sin(c.phase_rad[c.in_contact]) > 0)
        # torque equilibrium about the disc centre: sum F_i l_i = T (Blagojevic et al. 2011)
        assert np.sum(c.load_N * np.where(c.in_contact, c.arm_m, 0)) == pytest.approx(80.0, rel=1e-12)
    inc_neg, _, _ = pin_contact_state(s2, p.material, 0.3, direction=-1)
    inc_pos, _, _ = pin_contact_state(s2, p.material, 0.3)
    assert not np.any(inc_neg & inc_pos)


def test_force_line_passes_through_pitch_point_and_arm(p):
    s2 = p.stage2
    crank = 0.7
    c = pin_contact(s2, p.material, crank)
    e, zp, rp = s2.eccentricity, s2.pins, s2.pin_circle_radius
    disc_centre = e * np.array([math.cos(crank), math.sin(crank)])
    for i in np.flatnonzero(c.in_contact)[:5]:
        psi = 2 * math.pi * i / zp
        pin = rp * np.array([math.cos(psi), math.sin(psi)])
        u = np.array([math.cos(c.force_angle_rad[i]), math.sin(c.force_angle_rad[i])])
        # moment arm of the force line about the disc centre = |cross(pin - O_c, u)|
        arm = abs(np.cross(pin - disc_centre, u))
        assert arm == pytest.approx(abs(c.arm_m[i]), rel=1e-9)
        pitch = e * zp * np.array([math.cos(crank), math.sin(crank)])
        assert abs(np.cross(pitch - pin, u)) < 1e-12


def test_curvature_formula_matches_numerical_pin_path(p):
    """rho_0 from Chen et al. (2008) equals the curvature of the pin-centre path traced in the
    disc frame (crank turns theta, disc turns -theta/Zc), by finite differences."""
    s2 = p.stage2
    zp, zc, rp, e = s2.pins, s2.cycloid_lobes, s2.pin_circle_radius, s2.eccentricity
    k1 = e * zp / rp
    for i in (0, 3, 10, 20, 30):
        psi = 2 * math.pi * i / zp
        th = np.linspace(-0.02, 0.02, 4001)
        rel = rp * np.array([math.cos(psi), math.sin(psi)])[:, None] - e * np.stack([np.cos(th), np.sin(th)])
        rot = th / zc
        x = np.cos(rot) * rel[0] - np.sin(rot) * rel[1]
        y = np.sin(rot) * rel[0] + np.cos(rot) * rel[1]
        dx, dy = np.gradient(x, th), np.gradient(y, th)
        ddx, ddy = np.gradient(dx, th), np.gradient(dy, th)
        m = len(th) // 2
        rho_num = (dx[m] ** 2 + dy[m] ** 2) ** 1.5 / (dx[m] * ddy[m] - dy[m] * ddx[m])
        rho = theoretical_curvature_radius(np.array([psi]), rp, k1, zp)[0]
        assert rho == pytest.approx(rho_num, rel=1e-4)


def test_line_contact_stiffness_properties(p):
    E, nu = p.material.youngs_modulus, p.material.poisson_ratio
    loads = np.array([0.0, 10.0, 100.0, 1000.0])
    k = line_contact_stiffness(loads, 2.3e-3, 10e-3, 0.01, E, nu)
    assert k[0] == 0.0
    assert np.all(np.diff(k) > 0)            # stiffening with load (Hertz)
    # tangent stiffness equals the numerical derivative of Johnson's approach formula
    c = (1 - nu**2) / E

    def approach(F, r1=2.3e-3, r2=10e-3, b=0.01):
        P = F / b
        a = math.sqrt(4 * P / ((1 / r1 + 1 / r2) * math.pi / (2 * c)))
        return 2 * P / math.pi * c * ((math.log(4 * r1 / a) - 0.5) + (math.log(4 * r2 / a) - 0.5))

    F = 100.0
    dk = 1e-3 / (approach(F + 1e-3 / 2 * 1) - approach(F - 1e-3 / 2 * 1)) * 1
    assert k[2] == pytest.approx(dk, rel=1e-4)
    # a concave partner (negative radius) conforms better and is stiffer than a convex one
    k_conc = line_contact_stiffness(np.array([100.0]), 2.3e-3, -10e-3, 0.01, E, nu)
    assert k_conc[0] > k[2]


def test_rv20e_pin_stiffness_magnitude(p):
    inc, ang, k = pin_contact_state(p.stage2, p.material, 0.0)
    assert k.shape == ang.shape == (40,)
    assert np.all(k[~inc] == 0)
    # loaded pins: 1e8..1e9 N/m, the range of published RV cycloid-pin mesh stiffness per tooth pair
    loaded = k[inc & (k > 0)]
    assert 1e8 < np.median(loaded) < 1e9


def test_bad_inputs(p):
    with pytest.raises(ParameterError):
        pin_contact(p.stage2, p.material, 0.0, torque_N_m=-1.0)
    with pytest.raises(ParameterError):
        pin_contact(p.stage2, p.material, 0.0, direction=2)
    with pytest.raises(ParameterError):
        pin_contact(p.stage2, p.material, float("nan"))
    # a pin larger than the smallest convex radius of the theoretical profile undercuts it
    import dataclasses

    fat = dataclasses.replace(p.stage2, pin_radius=20e-3)
    with pytest.raises(GeometryError, match="undercut"):
        pin_contact(fat, p.material, 0.0)
