"""Fault models: monotonicity, broken-tooth zeros, crack cases, combinations, validation."""

import numpy as np
import pytest

from rvdiag.errors import GeometryError, ParameterError
from rvdiag.gears import BrokenTooth, GearPair, RootCrack, ToothFaults, Wear, mesh_stiffness
from rvdiag.gears.faults import T6_CRACK_OFFSET, archard_wear_profile, damaged_profile
from rvdiag.params import ReducerParams


@pytest.fixture(scope="module")
def pair():
    return GearPair.sun_planet(ReducerParams.default())


def test_stiffness_falls_monotonically_with_crack_depth(pair):
    depths = [0.0, 0.2e-3, 0.4e-3, 0.8e-3, 1.2e-3, 1.6e-3, 2.0e-3]
    curves = [mesh_stiffness(pair, ToothFaults({0: (RootCrack(q, 45.0),)}), cycles=2,
                             points_per_cycle=180).stiffness_N_per_m for q in depths]
    for a, b in zip(curves, curves[1:]):
        assert np.all(b <= a + 1e-6)        # pointwise never stiffer
        assert b.mean() < a.mean()          # strictly softer on average
    assert curves[-1].mean() < 0.97 * curves[0].mean()


def test_stiffness_falls_monotonically_with_wear_depth(pair):
    depths = [0.0, 5e-6, 20e-6, 50e-6, 100e-6, 200e-6]
    curves = [mesh_stiffness(pair, ToothFaults(wear=Wear(d)), cycles=1,
                             points_per_cycle=180).stiffness_N_per_m for d in depths]
    for a, b in zip(curves, curves[1:]):
        assert np.all(b <= a + 1e-6)
        assert b.mean() < a.mean()


def test_archard_profile_zero_at_pitch_point_and_max_equals_severity(pair):
    s = np.linspace(0.0, pair.path_of_contact, 4001)
    h = archard_wear_profile(pair, "driver", s, 30e-6)
    assert h.max() == pytest.approx(30e-6, rel=1e-3)
    rho_pitch = pair.driver.base_radius * np.tan(pair.operating_pressure_angle)
    s_pitch = rho_pitch - pair.start_roll_length_driver
    assert np.interp(s_pitch, s, h) < 0.01 * h.max()
    # the driver's dedendum (start of contact) wears most, as observed for pinions
    assert np.argmax(h) < len(s) // 2


def test_broken_tooth_zero_exactly_where_it_is_the_only_pair(pair):
    ppc = 360
    healthy = mesh_stiffness(pair, cycles=11, points_per_cycle=ppc)
    res = mesh_stiffness(pair, ToothFaults({0: (BrokenTooth(1.0),)}), cycles=11, points_per_cycle=ppc)
    _, _, inc = pair.contact_state(res.angle_rad)
    pidx = pair.contact_state(res.angle_rad)[0]
    tooth0 = (np.mod(pidx, 11) == 0) & inc
    only_broken = tooth0.any(axis=0) & (inc.sum(axis=0) == 1)
    assert only_broken.sum() > 0
    assert np.all(res.stiffness_N_per_m[only_broken] == 0.0)
    assert np.all(res.stiffness_N_per_m[~only_broken] > 0.0)
    # in double contact with the broken tooth, the partner carries alone
    shared = tooth0.any(axis=0) & (inc.sum(axis=0) == 2)
    partner = np.where(tooth0, 0.0, res.pair_stiffness_N_per_m).sum(axis=0)
    np.testing.assert_allclose(res.stiffness_N_per_m[shared], partner[shared])
    # elsewhere it equals the healthy curve
    untouched = ~tooth0.any(axis=0)
    np.testing.assert_allclose(res.stiffness_N_per_m[untouched], healthy.stiffness_N_per_m[untouched])


def test_partial_break_only_removes_tip_contact(pair):
    full = mesh_stiffness(pair, ToothFaults({0: (BrokenTooth(1.0),)}), cycles=2)
    part = mesh_stiffness(pair, ToothFaults({0: (BrokenTooth(0.3),)}), cycles=2)
    healthy = mesh_stiffness(pair, cycles=2)
    assert full.mean_N_per_m < part.mean_N_per_m < healthy.mean_N_per_m
    assert np.all(part.stiffness_N_per_m >= full.stiffness_N_per_m - 1e-6)


def test_crack_four_cases(pair):
    sun = pair.driver
    y_c, h_c = RootCrack(0.5e-3).start(sun)
    shallow, deep = RootCrack(0.5e-3, 45.0), RootCrack(2.0e-3, 45.0)
    y_t_shallow, hq_shallow = shallow.tip(sun)
    y_t_deep, hq_deep = deep.tip(sun)
    assert hq_shallow > 0 > hq_deep
    assert shallow.case(sun, y_t_shallow + 1e-4) == 1
    assert shallow.case(sun, y_t_shallow - 1e-5) == 2
    assert deep.case(sun, y_t_deep + 1e-4) == 3
    assert deep.case(sun, y_t_deep - 1e-5) == 4
    # the crack starts at the base circle because the sun's root circle lies below it
    assert np.hypot(y_c, h_c) == pytest.approx(sun.base_radius, rel=1e-6)
    prof = damaged_profile(pair, "driver", (deep,))
    zone = (prof.y >= y_c) & (prof.y <= y_t_deep)
    np.testing.assert_allclose(prof.x_loaded[zone], hq_deep)


def test_combinations_t5_t6(pair):
    h = mesh_stiffness(pair, cycles=11).mean_N_per_m
    means = {s: mesh_stiffness(pair, ToothFaults.for_state(s), cycles=11).mean_N_per_m
             for s in ("T4", "T5", "T6")}
    assert means["T6"] < means["T5"] < means["T4"] < h
    t6 = ToothFaults.for_state("T6")
    assert t6.wear is not None and isinstance(t6.teeth[0][0], BrokenTooth)
    assert isinstance(t6.teeth[T6_CRACK_OFFSET][0], RootCrack)
    assert ToothFaults.for_state("T1").is_healthy
    assert ToothFaults.from_name("wear+broken").label == "T5"


def test_fault_on_driven_gear_repeats_every_z2_cycles(pair):
    f = ToothFaults({0: (BrokenTooth(1.0),)}, gear="driven")
    res = mesh_stiffness(pair, f, cycles=66, points_per_cycle=36)
    zeros = np.flatnonzero(res.stiffness_N_per_m == 0.0)
    cycles_hit = np.unique(zeros // 36)
    assert list(cycles_hit) == [0, 33]


@pytest.mark.parametrize("make, exc, match", [
    (lambda: Wear(-1e-6), ParameterError, "wear depth must be >= 0"),
    (lambda: RootCrack(-1e-3), ParameterError, "crack depth"),
    (lambda: RootCrack(1e-3, 95.0), ParameterError, "crack angle"),
    (lambda: BrokenTooth(0.0), ParameterError, "broken fraction"),
    (lambda: BrokenTooth(1.5), ParameterError, "broken fraction"),
    (lambda: ToothFaults({-1: (Wear(1e-6),)}), ParameterError, "tooth index"),
    (lambda: ToothFaults({0: (Wear(1e-6), Wear(2e-6))}), ParameterError, "one fault of each kind"),
    (lambda: ToothFaults(gear="ring"), ParameterError, "driver"),
    (lambda: ToothFaults.for_state("T9"), ParameterError, "unknown fault state"),
])
def test_fault_validation(make, exc, match):
    with pytest.raises(exc, match=match):
        make()


def test_geometry_dependent_validation(pair):
    with pytest.raises(GeometryError, match="crack deeper than the sun tooth"):
        mesh_stiffness(pair, ToothFaults({0: (RootCrack(2.4e-3, 60.0),)}), cycles=1)
    with pytest.raises(GeometryError, match="above the sun tooth tip"):
        mesh_stiffness(pair, ToothFaults({0: (RootCrack(5e-3, 45.0),)}), cycles=1)
    with pytest.raises(GeometryError, match="wear deeper"):
        mesh_stiffness(pair, ToothFaults(wear=Wear(2e-3)), cycles=1)
    with pytest.raises(ParameterError, match="out of range"):
        mesh_stiffness(pair, ToothFaults({11: (BrokenTooth(),)}), cycles=1)


def test_wear_profile_error_output(pair):
    """Wear gives a load-shared profile deviation; zero at the pitch point, bounded by the depth."""
    healthy = mesh_stiffness(pair, cycles=1)
    assert np.all(healthy.profile_error_m == 0)
    res = mesh_stiffness(pair, ToothFaults(wear=Wear(30e-6)), cycles=1, points_per_cycle=720)
    e = res.profile_error_m
    assert 0 <= e.min() and e.max() <= 30e-6 * (1 + 1e-9)
    # single contact: the error is that pair's wear depth at its contact point
    single = res.pairs_in_contact == 1
    k = res.pair_stiffness_N_per_m
    i = np.argmax(k[:, single], axis=0)
    np.testing.assert_allclose(e[single], res.pair_profile_error_m[:, single][i, np.arange(single.sum())])
    # the pitch point lies in the single zone of the RV-20E mesh: error near zero there
    rho_p = pair.driver.base_radius * np.tan(pair.operating_pressure_angle)
    s_p = rho_p - pair.start_roll_length_driver
    _, roll, inc = pair.contact_state(res.angle_rad)
    j = np.argmin(np.abs(np.where(inc, roll, np.inf) - s_p).min(axis=0))
    assert e[j] < 0.02 * 30e-6
    assert "profile_error_m" in res.to_dict()


def test_run_in_wear_evens_the_pairs_of_a_double_contact_zone():
    """Archard wear grown with load shares that follow the worn separations (Wear.run_in_deflection d0): in double
    contact the two pairs' wear depths end within d0 of each other, so both carry load (measured 0.94 um for d0 =
    1 um at 20 um of wear), where fixed 1/2 shares leave them up to 18.1 um apart; both profiles reach the depth and
    vanish at the pitch point (no sliding)."""
    import numpy as np

    from rvdiag.gears import GearPair
    from rvdiag.gears.faults import archard_wear_profile
    from rvdiag.params import ReducerParams

    pair = GearPair.sun_planet(ReducerParams.default())
    L, pb = pair.path_of_contact, pair.base_pitch
    s = np.linspace(0.0, L, 4001)
    enter = s <= L - pb
    spread = {}
    for d0 in (0.0, 1e-6):
        h = archard_wear_profile(pair, "driver", s, 20e-6, d0)
        assert h.max() == pytest.approx(20e-6, rel=1e-12)
        assert h.min() < 0.01 * 20e-6
        spread[d0] = np.abs(h[enter] - np.interp(s[enter] + pb, s, h)).max()
    assert spread[1e-6] <= 1.2e-6 and spread[0.0] > 10e-6, spread
    with pytest.raises(ParameterError, match="run-in"):
        Wear(20e-6, -1e-6)
