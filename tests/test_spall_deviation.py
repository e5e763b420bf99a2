"""A spall through the face lifts the contact (rvdiag.gears.faults.flank_deviation): the peak against the chord sag
of the public BGU model, the floor's limit, the static loaded transmission error and the contact it loses, the
dynamic model's per-pair separation, and everything else unchanged against the code path without the deviation."""

import math

import numpy as np
import pytest

from rvdiag.gears import GearPair, Pitting, Spalling, ToothFaults, mesh_stiffness
from rvdiag.gears import faults as gf
from rvdiag.params import ReducerParams

CYCLES, PPC = 11, 360


@pytest.fixture(scope="module")
def params():
    return ReducerParams.default()


@pytest.fixture(scope="module")
def pair(params):
    return GearPair.sun_planet(params)


def _without_spall_deviation(monkeypatch):
    """The code path without a spall's deviation: no run of the flank counts as spalled through the face."""
    monkeypatch.setattr(gf.FlankLoss, "through_face", lambda self, contact_width: [])


def _arc_sag(gear, rho_a, rho_b, n=2001):
    """Largest distance (m) of the involute arc between roll lengths rho_a, rho_b from its chord: the deviation
    of one flank in the BGU model (calcDeviationFromCurve of genToothFaceFaultProfile.m), computed from the
    involute's points, independently of the x^2 / (2 R) of rvdiag."""
    rho = np.linspace(rho_a, rho_b, n)
    y, x = gear.involute_point(np.hypot(gear.base_radius, rho))
    p = np.stack([x, y], axis=1)
    chord = p[-1] - p[0]
    normal = np.array([-chord[1], chord[0]]) / np.linalg.norm(chord)
    dist = (p - p[0]) @ normal
    return float(np.max(np.abs(dist)))


@pytest.mark.parametrize("length, centre", [(0.05, None), (0.10, None)])
def test_peak_deviation_is_the_sum_of_both_flanks_arc_sags(pair, length, centre):
    """Deep floor, a spall centred on the pitch point: the deviation peaks at the sum of the two flanks' sags under
    the chords of the spall's edges and of their conjugate points on the mate (BGU ThroughFaceFault), here
    measured on the involutes themselves.  (At the pitch point rolling is pure and the conjugate arcs are as
    long as the spall; away from it the mate's conjugate arc is shorter or longer by the sliding ratio and the BGU
    sag differs from the instantaneous gap x^2 / (2 R) that rvdiag uses: 1.5-2x on the RV-20E sun's flank at half
    its height.)"""
    spall = Spalling(1.0, length, depth=1e-3, centre_fraction=centre)
    (lo, hi, _, _), = spall.flank_loss(pair, "driver").spalls
    rb1 = pair.driver.base_radius
    rho1_lo, rho1_hi = math.sqrt(2 * rb1 * lo), math.sqrt(2 * rb1 * hi)
    # the mate's conjugate points: the same path positions
    roll = np.array([rho1_lo, rho1_hi]) - pair.start_roll_length_driver
    _, rho2 = pair.roll_lengths(roll)
    sag = _arc_sag(pair.driver, rho1_lo, rho1_hi) + _arc_sag(pair.driven, *sorted(rho2))
    roll_grid = np.linspace(roll[0], roll[1], 4001)
    e = gf.flank_deviation(pair, "driver", (spall,), roll_grid)
    assert e.max() == pytest.approx(sag, rel=0.02)   # 0.3 % and 1.1 % measured
    # both ends: the flank re-enters, the deviation is zero at the edges and outside
    assert e[0] == pytest.approx(0.0, abs=1e-15) and e[-1] == pytest.approx(0.0, abs=1e-15)
    outside = gf.flank_deviation(pair, "driver", (spall,), np.array([roll[0] - 1e-5, roll[1] + 1e-5]))
    np.testing.assert_array_equal(outside, 0.0)


def test_closed_form_and_the_floor(pair):
    """e = min(d, x^2 / (2 R)), x the distance to the nearer edge, 1/R = 1/rho_1 + 1/rho_2: a shallow floor caps it
    exactly at d over the middle of the span."""
    d = 5e-6
    spall = Spalling(1.0, 0.33, depth=d)
    (lo, hi, _, _), = spall.flank_loss(pair, "driver").spalls
    rb1 = pair.driver.base_radius
    roll = np.linspace(math.sqrt(2 * rb1 * lo), math.sqrt(2 * rb1 * hi), 3001) - pair.start_roll_length_driver
    rho1, rho2 = pair.roll_lengths(roll)
    s = rho1**2 / (2 * rb1)
    R = rho1 * rho2 / (rho1 + rho2)
    closed = np.minimum(d, np.minimum(s - lo, hi - s) ** 2 / (2 * R))
    e = gf.flank_deviation(pair, "driver", (spall,), roll)
    np.testing.assert_allclose(e, closed, rtol=1e-12, atol=1e-18)
    assert e.max() == d and np.mean(e == d) > 0.5


def test_partial_face_spalls_and_pits_lift_nothing(pair):
    """Over part of the face the intact part carries the contact (BGU PartialFaceFault): no deviation at all."""
    for fault in (Spalling(0.999), Spalling(0.5), Pitting(0.3), (Pitting(0.1), Spalling(0.5))):
        faults = fault if isinstance(fault, tuple) else (fault,)
        assert not gf.has_flank_deviation(pair, "driver", faults)
        res = mesh_stiffness(pair, ToothFaults({0: faults}), cycles=CYCLES, points_per_cycle=36)
        assert res.pair_profile_error_m is None
        np.testing.assert_array_equal(res.profile_error_m, 0.0)
    # two half-face spalls side by side over the same span are a spall through the face
    loss = Spalling(0.5).flank_loss(pair, "driver") + Spalling(0.5).flank_loss(pair, "driver")
    assert loss.through_face(pair.driver.face_width)


def test_loaded_te_and_the_contact_lost_over_the_span(pair):
    """Static loaded TE under a mesh force F (unilateral contact): healthy delta = F / k; with a through-face spall,
    where the spalled pair is alone delta = e + F / k (the TE rises by the geometric deviation); where another pair
    touches, the spalled pair carries nothing exactly where its deviation exceeds that pair's deflection F / k_o,
    and otherwise both touch with F = sum k_i (delta - e_i)."""
    F = 500.0
    healthy = mesh_stiffness(pair, cycles=CYCLES, points_per_cycle=PPC)
    d0, _ = healthy.loaded_transmission_error(F)
    np.testing.assert_allclose(d0, F / healthy.stiffness_N_per_m, rtol=1e-13)

    res = mesh_stiffness(pair, ToothFaults({0: (Spalling(1.0, 0.5),)}), cycles=CYCLES, points_per_cycle=PPC)
    k, e = res.pair_stiffness_N_per_m, res.pair_profile_error_m
    delta, touch = res.loaded_transmission_error(F)
    lifted = (e > 0).any(axis=0)
    n_in = (k > 0).sum(axis=0)
    alone = lifted & (n_in == 1)
    shared = lifted & (n_in == 2)
    assert alone.sum() > 20 and shared.sum() > 20
    np.testing.assert_allclose(delta[alone], (e.sum(axis=0) + F / k.sum(axis=0))[alone], rtol=1e-12)
    # force balance everywhere
    np.testing.assert_allclose((k * np.maximum(delta - e, 0.0)).sum(axis=0), F, rtol=1e-10)
    for j in np.flatnonzero(shared):
        sp, other = np.flatnonzero((k[:, j] > 0) & (e[:, j] > 0)), np.flatnonzero((k[:, j] > 0) & (e[:, j] == 0))
        if sp.size != 1 or other.size != 1:
            continue
        deflection = F / k[other[0], j]
        assert touch[sp[0], j] == (e[sp[0], j] < deflection)
        if not touch[sp[0], j]:
            assert delta[j] == pytest.approx(deflection, rel=1e-12)
    # the TE over the span: up to the deviation's peak above the healthy TE, never below it
    assert np.all(delta >= d0 * (1 - 1e-9))
    assert (delta - d0).max() == pytest.approx(e.max(), rel=0.05)


def test_dynamic_separation_carries_the_deviation(params, monkeypatch):
    """The dynamic model's per-pair separations: a through-face spall adds its deviation to its pair's slot, and
    only there; the load-shared error_m of the table follows."""
    from rvdiag.dynamics.mesh import mesh_table_from_gears

    fault = ToothFaults({0: (Spalling(1.0, 0.33),)})
    pair = GearPair.sun_planet(params)
    with_dev = mesh_table_from_gears(params, fault)
    res = mesh_stiffness(pair, fault, cycles=params.stage1.sun_teeth, points_per_cycle=360)
    with monkeypatch.context() as m:
        _without_spall_deviation(m)
        without = mesh_table_from_gears(params, fault)
    np.testing.assert_array_equal(with_dev.pair_stiffness_N_per_m, without.pair_stiffness_N_per_m)
    added = with_dev.pair_separation_m - without.pair_separation_m
    assert added.max() == pytest.approx(res.pair_profile_error_m.max(), rel=1e-9)
    assert np.all(added >= -1e-18)
    # one slot, tooth 0's
    assert np.count_nonzero(np.abs(added).max(axis=1) > 0) == 1
    assert np.any(with_dev.error_m != without.error_m)


@pytest.mark.parametrize("state", ["T1", "T2", "T3", "T4", "T5", "T6", "T7", "T8"])
def test_other_states_unchanged_against_the_path_without_spall_deviation(params, state, monkeypatch):
    """T1..T6 and the default pitting and (half-face) spalling: the mesh tables, pair separations included, are
    bit for bit those of the code path without a spall's deviation."""
    from rvdiag.dynamics.mesh import mesh_table_from_gears

    fault = None if state == "T1" else ToothFaults.for_state(state)
    a = mesh_table_from_gears(params, fault, points_per_cycle=90)
    with monkeypatch.context() as m:
        _without_spall_deviation(m)
        b = mesh_table_from_gears(params, fault, points_per_cycle=90)
    for name in ("stiffness_N_per_m", "error_m", "pair_stiffness_N_per_m", "pair_separation_m"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


@pytest.mark.parametrize("state", ["T3", "T8"])
def test_signals_unchanged_against_the_path_without_spall_deviation(params, state, monkeypatch):
    """Short simulations of wear (T3) and the default half-face spall (T8): the same signal, bit for bit, with the
    spall deviation's code path and without it (same run, same machine)."""
    from rvdiag.dynamics import simulate

    kw = dict(output_speed_deg_s=30.0, duration_s=0.05)
    a = simulate(params, ToothFaults.for_state(state), **kw).signal
    with monkeypatch.context() as m:
        _without_spall_deviation(m)
        b = simulate(params, ToothFaults.for_state(state), **kw).signal
    np.testing.assert_array_equal(a, b)


def test_through_face_spall_changes_the_signal(params, monkeypatch):
    """And the deviation does reach the signal: a through-face spall's record differs from the same spall
    without its deviation."""
    from rvdiag.dynamics import simulate

    fault = ToothFaults({0: (Spalling(1.0, 0.33),)})
    kw = dict(output_speed_deg_s=60.0, duration_s=0.1)
    a = simulate(params, fault, **kw).signal
    with monkeypatch.context() as m:
        _without_spall_deviation(m)
        b = simulate(params, fault, **kw).signal
    assert np.sqrt(np.mean((a - b) ** 2)) > 0.05 * np.sqrt(np.mean(b**2))
