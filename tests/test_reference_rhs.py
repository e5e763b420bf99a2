"""The independent NumPy right-hand side (``tests/oracles/reference_rhs.py``) against the compiled one.

The NumPy version is written from docs/model.md and shares only the model's data with the numba
kernels, so agreement at random states (contacts open and closed, every damper active) checks the
kernels' equations, and makes the scipy-on-NumPy baseline of ``bench/sim_speed.py`` a run of the
same equations.
"""

from __future__ import annotations

import numpy as np
import pytest

from rvdiag.dynamics import ModelSettings, prepare
from rvdiag.dynamics import model as mdl
from rvdiag.dynamics.linear import static_equilibrium
from rvdiag.gears import BrokenTooth, ToothFaults, Wear
from rvdiag.params import ReducerParams

from oracles.reference_rhs import ReferenceRHS

P0 = ReducerParams.default()


def _max_rel_diff(m: mdl.Model, seed: int, trials: int = 8) -> float:
    """Largest |compiled - NumPy| over the accelerations, relative to the largest acceleration of the
    state, at random times and random states around the static solution."""
    f = mdl.make_rhs(m)
    g = ReferenceRHS(m)
    q0 = static_equilibrium(m, 0.0)
    rng = np.random.default_rng(seed)
    worst = 0.0
    n = m.n_dof
    for _ in range(trials):
        # displacements of the static deflection's size (so contacts open and close at random),
        # velocities ~1 mm/s or mrad/s (every damper active)
        q = q0 + 0.5 * (np.abs(q0) + 1e-7) * rng.standard_normal(n)
        v = 1e-3 * rng.standard_normal(n)
        y = np.concatenate([q, v])
        t = float(rng.uniform(0.0, 0.5))
        a, b = f(t, y), g(t, y)
        assert np.array_equal(a[:n], b[:n])
        worst = max(worst, float(np.max(np.abs(a[n:] - b[n:])) / np.max(np.abs(a[n:]))))
    return worst


@pytest.mark.parametrize("fault", [None, ToothFaults({0: (BrokenTooth(0.5),)}), ToothFaults(wear=Wear(20e-6))],
                         ids=["healthy", "broken", "worn"])
def test_reference_rhs_equals_compiled_rhs(fault):
    m = prepare(P0, fault, output_speed_deg_s=45.0, load_Nm=100.0)
    assert np.ptp(m.pairs[:, 1, :]) > 1e-6  # the per-pair separations (relief, errors, wear) are exercised
    assert _max_rel_diff(m, seed=1) < 1e-9


def test_reference_rhs_equals_compiled_rhs_with_large_manufacturing_errors():
    """Every manufacturing error on at several times its default tolerance (planet runout, crank holes, crank
    phases, pins; rvdiag.dynamics.manufacturing), a specimen (seed 12) whose crank phases differ by 8.2 arcmin."""
    p = P0.replace(manufacturing={"planet_runout_grade": 8, "crank_hole_position": 20e-6, "crank_phase_arcmin": 10.0,
                                  "pin_radius": 5e-6, "pin_position": 20e-6}, modification={"error_seed": 12})
    m = prepare(p, output_speed_deg_s=45.0, load_Nm=100.0)
    e = m.extra["manufacturing"]
    assert abs(e.crank_phase[1] - e.crank_phase[0]) > 2e-3 and min(e.runout) > 4e-6 and np.std(e.pin_radial) > 5e-6
    assert _max_rel_diff(m, seed=5) < 1e-9


@pytest.mark.parametrize("pin_errors", [False, True], ids=["worn", "worn_pin_errors"])
def test_reference_rhs_equals_compiled_rhs_with_a_worn_pin_stage(pin_errors):
    """The cycloid-pin stage worn 10 um ([stage2] pin_wear_depth: the clearance table after the modification's,
    docs/model.md section 3), alone and with the pins' own errors (whose values follow the table in P)."""
    p = P0.replace(stage2={"pin_wear_depth": 10e-6},
                   manufacturing={"pin_radius": 1e-6, "pin_position": 3e-6} if pin_errors else {})
    m = prepare(p, output_speed_deg_s=45.0, load_Nm=100.0)
    assert m.P[mdl.I_PINWEAR] != 0 and (m.P[mdl.I_PINERR] > m.P[mdl.I_PINWEAR]) == pin_errors
    assert _max_rel_diff(m, seed=3) < 1e-9


def test_reference_rhs_equals_compiled_rhs_other_settings():
    """1000 rpm, rated load, frozen excitation, no damping, no Coriolis, bilateral contacts."""
    m = prepare(P0, input_speed_rpm=1000.0)
    assert _max_rel_diff(m, seed=2) < 1e-9
    st = ModelSettings(excitation=False, damping=False, coriolis=False)
    assert _max_rel_diff(prepare(P0, output_speed_deg_s=30.0, load_Nm=50.0, settings=st), seed=3) < 1e-9
    assert _max_rel_diff(prepare(P0, output_speed_deg_s=30.0, load_Nm=50.0).with_P(BILATERAL=1.0), seed=4) < 1e-9


def test_random_states_open_and_close_pin_contacts():
    """The random states of the comparison switch pin contacts (so a wrong contact condition or a
    wrong damper gate would show), and the loaded static state has 5-8 of the 40 pins per disc in contact (the
    discs' profile modification; half of them on conjugate discs)."""
    m = prepare(P0, output_speed_deg_s=45.0, load_Nm=100.0)
    q0 = static_equilibrium(m, 0.0)
    g = ReferenceRHS(m)
    closed0 = g.pin_deflections(0.0, q0) > 0.0
    assert closed0.shape == (2, 40)
    assert 5 <= closed0.sum(axis=1).min() and closed0.sum(axis=1).max() <= 8
    rng = np.random.default_rng(1)
    changed = 0
    for _ in range(8):
        q = q0 + 0.5 * (np.abs(q0) + 1e-7) * rng.standard_normal(q0.size)
        changed += int(np.sum((g.pin_deflections(0.0, q) > 0.0) != closed0))
    assert changed > 0


def test_reference_rhs_equals_compiled_rhs_on_a_trapezoid_with_a_gravity_arm():
    """A trapezoid (accelerating, cruising, decelerating) with the motor-current paper's 15 kg arm at 0.5 m: the
    integrated angles, Omega(t), the Euler and tangential terms and T_L(t) of the compiled kernels against the
    NumPy ones at random states in each phase."""
    from rvdiag.dynamics import LoadProfile, SpeedProfile

    prof = SpeedProfile.trapezoid(45.0, 300.0, move_s=0.5, start_s=0.02)
    arm = LoadProfile(15.0, 0.5, 30.0)
    m = prepare(P0, profile=prof, load_profile=arm, load_Nm=20.0)
    f, g = mdl.make_rhs(m), ReferenceRHS(m)
    q0 = static_equilibrium(m, 0.0)
    rng = np.random.default_rng(5)
    n = m.n_dof
    # accelerating (0.02-0.17 s), cruising (0.17-0.37 s), decelerating (0.37-0.52 s), at rest after
    phases = {0.05: 1, 0.1: 1, 0.2: 0, 0.3: 0, 0.4: -1, 0.5: -1, 0.6: 0}
    for t, sign in phases.items():
        assert np.sign(g.kinematics(t)[2]) == sign
        q = q0 + 0.5 * (np.abs(q0) + 1e-7) * rng.standard_normal(n)
        v = 1e-3 * rng.standard_normal(n)
        y = np.concatenate([q, v])
        a, b = f(t, y), g(t, y)
        assert np.array_equal(a[:n], b[:n])
        assert float(np.max(np.abs(a[n:] - b[n:])) / np.max(np.abs(a[n:]))) < 1e-9, t
    th, w, acc = g.kinematics(0.1)
    assert w == pytest.approx(np.radians(300.0) * 0.08) and acc == pytest.approx(np.radians(300.0))


def test_profile_terms_change_the_rhs_where_the_carrier_accelerates():
    """The oracle's profile terms are not vacuous: dropping dOmega/dt from it moves the accelerations."""
    from rvdiag.dynamics import SpeedProfile

    m = prepare(P0, profile=SpeedProfile.trapezoid(45.0, 300.0, move_s=0.5), load_Nm=50.0)
    g = ReferenceRHS(m)
    y = np.concatenate([static_equilibrium(m, 0.0), np.zeros(m.n_dof)])
    base = g(0.05, y)
    g.kinematics = lambda t, _k=g.kinematics: _k(t)[:2] + (0.0,)
    # the sun's nominal angular acceleration alone is i dOmega/dt = 81 x 5.2 rad/s^2
    assert np.max(np.abs(g(0.05, y) - base)) > 100.0


def test_reference_rhs_equals_compiled_rhs_on_an_scurve():
    """The jerk-limited S-curve: the compiled kernels' closed form against the oracle's phase-by-phase integration
    of the piecewise-constant jerk, and the right-hand sides, in each of the seven phases and at rest."""
    from rvdiag.dynamics import LoadProfile, SpeedProfile

    prof = SpeedProfile.scurve(45.0, 300.0, 3000.0, move_s=0.6, start_s=0.02)  # T_j 0.1 s, T_a 0.25 s, T_c 0.1 s
    m = prepare(P0, profile=prof, load_profile=LoadProfile(15.0, 0.5, 30.0), load_Nm=20.0)
    f, g = mdl.make_rhs(m), ReferenceRHS(m)
    q0 = static_equilibrium(m, 0.0)
    rng = np.random.default_rng(6)
    n = m.n_dof
    # phase: jerk +, accel held, jerk -, cruise, jerk -, decel held, jerk +, at rest
    for t in (0.07, 0.17, 0.23, 0.32, 0.42, 0.52, 0.57, 0.7):
        th, w, a = g.kinematics(t)
        th_c, w_c, a_c = prof.state(np.array([t]), 0.0)
        assert (th, w, a) == pytest.approx((th_c[0], w_c[0], a_c[0]), rel=1e-10, abs=1e-12), t
        q = q0 + 0.5 * (np.abs(q0) + 1e-7) * rng.standard_normal(n)
        v = 1e-3 * rng.standard_normal(n)
        y = np.concatenate([q, v])
        a1, b1 = f(t, y), g(t, y)
        assert np.array_equal(a1[:n], b1[:n])
        assert float(np.max(np.abs(a1[n:] - b1[n:])) / np.max(np.abs(a1[n:]))) < 1e-9, t
    # in the middle of the first jerk phase: a = J t, v = J t^2 / 2 (t from the move's start)
    _, w, a = g.kinematics(0.07)
    assert a == pytest.approx(np.radians(3000.0) * 0.05) and w == pytest.approx(np.radians(3000.0) * 0.05**2 / 2)


@pytest.mark.parametrize("case", ["constant", "trapezoid_arm", "no_rotor"])
def test_reference_rhs_equals_compiled_rhs_with_the_load_dof(case):
    """The load DOF th_L (docs/model.md sections 1-3): the output coupling, the load torque on the load, its nominal
    angular acceleration on a trapezoid with a gravity arm (whose inertia M L^2 is the load's), and the rotor's
    index moved by it; also without the rotor (the ideal speed source)."""
    from rvdiag.dynamics import LoadProfile, SpeedProfile

    if case == "constant":
        m = prepare(P0, output_speed_deg_s=45.0, load_Nm=100.0, load_inertia_kg_m2=3.75)
    elif case == "trapezoid_arm":
        m = prepare(P0, profile=SpeedProfile("trapezoid", 45.0, 300.0), load_profile=LoadProfile(15.0, 0.5, 20.0),
                    load_Nm=20.0, duration_s=1.0)
        assert m.P[mdl.I_PROFILE] == 2.0
    else:
        m = prepare(P0.replace(drive={"speed_loop_bandwidth_hz": 0.0}), output_speed_deg_s=45.0, load_Nm=100.0,
                    load_inertia_kg_m2=3.75)
    assert m.has_load and m.names[-1] == "load.th"
    assert _max_rel_diff(m, seed=6) < 1e-9
