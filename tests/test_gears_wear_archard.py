"""Archard wear depth of the sun-planet stage over a duty cycle (rvdiag.gears.wear): invariants, a hand calculation,
and the simulator's wear fault with the Archard shape."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rvdiag.errors import ParameterError
from rvdiag.gears import GearPair, ToothFaults, Wear, mesh_stiffness
from rvdiag.gears.faults import flank_deviation
from rvdiag.gears.wear import DutyCycle, mesh_force, mesh_passes, pitch_roll, wear_depth_profile
from rvdiag.params import ReducerParams

P = ReducerParams.default()
PAIR = GearPair.sun_planet(P)
DUTY = DutyCycle(30.0, 84.0, 0.5)


@pytest.fixture(scope="module")
def life():
    """20,000 h at 30 deg/s, 84 N m, moving half the time, k = 1e-17 m^2/N, with the run-in load sharing."""
    return wear_depth_profile(P, 20000.0, DUTY, 1e-17)


def _single(w) -> np.ndarray:
    return (w.roll >= PAIR.path_of_contact - PAIR.base_pitch + 1e-9) & (w.roll <= PAIR.base_pitch - 1e-9)


def test_hand_calculation_in_single_contact(life):
    """One pair carries the whole force in single contact, so there h = k (F / L) |1 - v_p / v_s| N whatever the
    run-in: F = 84 / (121 * 2 * r_b1), N = 2 planets * 120 * (30 / 360) rev/s * 3600 s * 20,000 h * 0.5, the sliding
    ratio written here from the roll lengths rho_1 = rho_start + s, rho_2 = g - rho_1."""
    rb1, rb2 = PAIR.driver.base_radius, PAIR.driven.base_radius
    force = 84.0 / (121.0 * 2 * rb1)
    passes = 2 * 120.0 * (30.0 / 360.0) * 3600.0 * 20000.0 * 0.5
    assert mesh_force(P, 84.0) == pytest.approx(force, rel=1e-12)
    assert mesh_passes(P, 20000.0, DUTY, "sun") == pytest.approx(passes, rel=1e-12)
    assert mesh_passes(P, 20000.0, DUTY, "planet") == pytest.approx(passes * 11 / 33 / 2, rel=1e-12)
    on = _single(life)
    rho1 = PAIR.start_roll_length_driver + life.roll[on]
    rho2 = PAIR.line_of_action_length - rho1
    slip_sun = np.abs(1.0 - (rb1 * rho2) / (rb2 * rho1))
    slip_planet = np.abs(1.0 - (rb2 * rho1) / (rb1 * rho2))
    np.testing.assert_allclose(life.sun[on], 1e-17 * force / 0.01 * slip_sun * passes, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(life.planet[on], 1e-17 * force / 0.01 * slip_planet * passes / 6, rtol=1e-9,
                               atol=1e-15)
    # order of magnitude stated in research/README.md: about 20 um at the end of single contact
    assert 15e-6 < life.sun[on].max() < 30e-6


def test_zero_at_the_pitch_point_and_positive_elsewhere(life):
    for w in (life, wear_depth_profile(P, 20000.0, DUTY, 1e-17, run_in=False)):
        at = int(np.argmin(np.abs(w.roll - w.pitch_roll)))
        assert w.roll[at] == pytest.approx(w.pitch_roll, abs=1e-12)
        assert w.sun[at] < 1e-12 and w.planet[at] < 1e-12
        away = np.abs(w.roll - w.pitch_roll) > 0.05e-3
        assert np.all(w.sun[away] > 0) and np.all(w.planet[away] > 0)
    # the pitch point: rho_1 / rho_2 = r_b1 / r_b2 (equal rolling speeds)
    rho1 = PAIR.start_roll_length_driver + pitch_roll(PAIR)
    assert rho1 / (PAIR.line_of_action_length - rho1) == pytest.approx(
        PAIR.driver.base_radius / PAIR.driven.base_radius, rel=1e-12)


def test_approach_and_recess():
    """The sun's flank wears deepest at the start of approach (its root: small roll length, the sliding ratio far
    above 1) and the planet's at the end of recess (its root); on both sides of the pitch point the depth grows
    with the distance from it (in single contact, where the shares do not blur it)."""
    w = wear_depth_profile(P, 1000.0, DutyCycle(30.0, 167.0), 1e-17, run_in=False)
    assert int(np.argmax(w.sun)) == 0 and int(np.argmax(w.planet)) == w.roll.size - 1
    on = _single(w)
    before, after = on & (w.roll < w.pitch_roll), on & (w.roll > w.pitch_roll)
    assert np.all(np.diff(w.sun[before]) < 0) and np.all(np.diff(w.sun[after]) > 0)
    assert np.all(np.diff(w.planet[before]) < 0) and np.all(np.diff(w.planet[after]) > 0)
    assert w.max_depth > 3 * w.planet.max()      # the sun passes 6 times as often


def test_linear_in_hours_and_coefficient_without_run_in():
    a = wear_depth_profile(P, 1000.0, DUTY, 1e-17, run_in=False)
    b = wear_depth_profile(P, 3000.0, DUTY, 1e-17, run_in=False)
    c = wear_depth_profile(P, 1000.0, DUTY, 4e-17, run_in=False)
    np.testing.assert_allclose(b.sun, 3 * a.sun, rtol=1e-12)
    np.testing.assert_allclose(c.planet, 4 * a.planet, rtol=1e-12)
    assert wear_depth_profile(P, 0.0, DUTY, 1e-17).max_depth == 0.0


def test_run_in_shares_the_double_contact_within_a_deflection(life):
    """With the load shares following the worn separations, two pairs in double contact end up worn alike, to
    within about one elastic deflection (the deeper one sheds its load); the fixed equal shares leave the root
    of the sun far deeper than its partner (the sliding ratio 6.7 there)."""
    pb, s = PAIR.base_pitch, life.roll
    enter = s <= s[-1] - pb
    for w, bound in ((life, 1.1 * life.deflection_m),
                     (wear_depth_profile(P, 20000.0, DUTY, 1e-17, run_in=False), None)):
        e = w.sun + w.planet
        gap = np.abs(e[enter] - np.interp(s[enter] + pb, s, e)).max()
        if bound is None:
            assert gap > 50 * life.deflection_m
        else:
            assert gap <= bound


def test_shape_as_a_simulator_fault(life):
    """``to_wear`` gives a Wear whose flank deviation is the Archard profile (to the tabulation's interpolation),
    and the TVMS's loaded transmission error sees its single-contact variation."""
    wear = life.to_wear()
    assert wear.depth == pytest.approx(life.max_depth)
    dev = flank_deviation(PAIR, "driver", (wear,), life.roll)
    np.testing.assert_allclose(dev, life.sun, atol=0.01 * life.max_depth)
    planet = life.to_wear("planet")
    np.testing.assert_allclose(flank_deviation(PAIR, "driven", (planet,), life.roll), life.planet,
                               atol=0.01 * life.planet.max())
    res = mesh_stiffness(PAIR, ToothFaults({}, wear=wear), cycles=1, points_per_cycle=360)
    te, _ = res.loaded_transmission_error(mesh_force(P, 84.0))
    on = _single(life)
    swing = float(life.sun[on].max() + life.planet[on].max())
    assert 0.7 * swing < np.ptp(te) < 1.3 * swing + 2 * life.deflection_m


def test_bad_input():
    with pytest.raises(ParameterError):
        wear_depth_profile(P, -1.0, DUTY, 1e-17)
    with pytest.raises(ParameterError):
        wear_depth_profile(P, 1.0, DUTY, math.nan)
    with pytest.raises(ParameterError):
        DutyCycle(30.0, 84.0, 1.5)
    with pytest.raises(ParameterError):
        Wear(1e-6, shape=((0.0, 0.5), (0.0, 1.0)))       # does not cover the path of contact
    with pytest.raises(ParameterError):
        mesh_passes(P, 1.0, DUTY, "ring")


def test_history_matches_single_profiles(life):
    """One integration through several record times gives each time's profile as a separate call does (to the
    step of the run-in integration, 5 % of a deflection), and the depth never decreases."""
    from rvdiag.gears.wear import wear_depth_history

    hist = wear_depth_history(P, [0.0, 5000.0, 20000.0], DUTY, 1e-17)
    assert hist[0].max_depth == 0.0
    np.testing.assert_allclose(hist[-1].sun, life.sun, atol=0.1 * life.deflection_m)
    single = wear_depth_profile(P, 5000.0, DUTY, 1e-17)
    np.testing.assert_allclose(hist[1].sun, single.sun, atol=0.1 * life.deflection_m)
    assert np.all(hist[2].sun >= hist[1].sun) and np.all(hist[1].planet >= hist[0].planet)
    with pytest.raises(ParameterError):
        wear_depth_history(P, [2.0, 1.0], DUTY, 1e-17)
