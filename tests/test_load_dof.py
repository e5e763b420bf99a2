"""The load DOF th_L (docs/model.md sections 1-3): the load's inertia J_L on the output coupling k_out =
``[bearings] output_torsional`` (an elastic joint: Spong 1987, "Modeling and control of elastic joint robots",
J. Dyn. Syst. Meas. Control 109), present only when J_L > 0.

Checked here: without it the model is the one before it (the golden signals of
tests/golden/before_manufacturing_errors.npz, written by an earlier model, to the cross-CPU spread of
``conftest.CROSS_CPU_RTOL``); the layout; the static solution (the
coupling carries the load torque); the new mode against a two-inertia estimate; forces as minus the gradient of the
NumPy potential; the drive's acceleration feed-forward with the load's share; how J_L is chosen (stated, the gravity
arm's M L^2, or none); bad values.  The NumPy right-hand side is compared in tests/test_reference_rhs.py.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from numpy.testing import assert_allclose

from rvdiag.dynamics import LoadProfile, SpeedProfile, prepare, simulate
from rvdiag.dynamics import model as mdl
from rvdiag.dynamics.linear import natural_frequencies, static_equilibrium
from rvdiag.errors import ConfigError, ParameterError
from rvdiag.params import ReducerParams
from conftest import assert_close_across_cpus, potential_gradient

P0 = ReducerParams.default()
OFF = {"planet_runout_grade": 0, "crank_hole_position": 0.0, "crank_phase_arcmin": 0.0, "pin_radius": 0.0,
       "pin_position": 0.0}
#: the cycloid discs unmodified, as in the model the golden file was written by
UNMODIFIED = {"equidistant_modification": 0.0, "offset_modification": 0.0}
GOLDEN = Path(__file__).parent / "golden" / "before_manufacturing_errors.npz"
J_ARM = 15.0 * 0.5**2  # the motor-current rig's 15 kg arm at 0.5 m: 3.75 kg m^2


def test_no_load_inertia_is_the_model_before_it():
    """J_L = 0 (given, or stated in the parameter set) runs the kernels without the load DOF: the signals equal
    those of a model older than the load DOF (the golden file, within the cross-CPU spread: its last bits are those
    of the machine that wrote it), and a stated J_L = 0 equals a given one to the last bit (the same run); a load
    inertia changes them by far more than that spread."""
    g = np.load(GOLDEN)
    p_off = P0.replace(manufacturing=OFF, stage2=UNMODIFIED)
    r = simulate(p_off, output_speed_deg_s=60.0, duration_s=0.02, signal="both", load_inertia_kg_m2=0.0)
    assert_close_across_cpus(r.signal, g["healthy_vibration"])
    assert_close_across_cpus(r.current, g["healthy_current"])
    stated = simulate(p_off.replace(operation={"load_inertia": 0.0}), output_speed_deg_s=60.0, duration_s=0.02,
                      signal="both")
    assert np.array_equal(stated.signal, r.signal) and np.array_equal(stated.current, r.current)
    loaded = simulate(p_off, output_speed_deg_s=60.0, duration_s=0.02, signal="both", load_inertia_kg_m2=J_ARM)
    assert loaded.settings["load_inertia_kg_m2"] == J_ARM and "load_inertia_kg_m2" not in r.settings
    assert np.max(np.abs(loaded.signal - g["healthy_vibration"])) > 1e-3 * np.max(np.abs(g["healthy_vibration"]))


def test_layout_puts_the_load_last():
    m = prepare(P0, output_speed_deg_s=45.0, load_inertia_kg_m2=J_ARM)
    assert m.n_dof == 29 and m.names[-2:] == ["motor.th", "load.th"] and m.has_load and m.rotor_index == 27
    assert m.mass[-1] == J_ARM and m.P[mdl.I_KOUT] == P0.bearings.output_torsional and m.P[mdl.I_COUT] > 0
    assert mdl.dof_layout(2, 2, True, True)["load"] == 28 and mdl.dof_layout(2, 2, False, True)["load"] == 27
    no_rotor = prepare(P0.replace(drive={"speed_loop_bandwidth_hz": 0.0}), output_speed_deg_s=45.0,
                       load_inertia_kg_m2=J_ARM)
    assert no_rotor.n_dof == 28 and no_rotor.names[-1] == "load.th" and not no_rotor.has_motor
    plain = prepare(P0, output_speed_deg_s=45.0)
    assert plain.n_dof == 28 and not plain.has_load and plain.rotor_index == 27


def test_static_solution_the_coupling_carries_the_load():
    """The output coupling twists by T_L / k_out, the rotor stays at its nominal angle (the drive's T_L / i), and the
    carrier's twist is that of the model without the load DOF."""
    m = prepare(P0, output_speed_deg_s=45.0, load_Nm=120.0, load_inertia_kg_m2=J_ARM)
    q = static_equilibrium(m)
    iH = mdl.dof_layout(2, 2)["carrier"] + 2
    assert_allclose(q[iH] - q[-1], 120.0 / P0.bearings.output_torsional, rtol=1e-6)
    assert abs(q[m.rotor_index]) < 1e-9
    q_plain = static_equilibrium(prepare(P0, output_speed_deg_s=45.0, load_Nm=120.0))
    assert_allclose(q[iH], q_plain[iH], rtol=1e-6)


def test_load_mode_against_the_two_inertia_estimate():
    """The load adds a mode near sqrt(k_out / J_L) / 2 pi (28.5 Hz at 3.75 kg m^2): the arm swinging on the output
    coupling and the reducer's torsional stiffness in series, against the rotor side (the rigid train reflected to
    the output, i^2 J_ref, held by the speed loop's spring k_sl i^2).  That two-inertia estimate, with the reducer's
    stiffness k_red from the model's static twist, gives the two lowest modes within 2 %."""
    m = prepare(P0, output_speed_deg_s=45.0, load_inertia_kg_m2=J_ARM)
    fr = natural_frequencies(m).frequencies_hz
    i = m.P[mdl.I_RATIO]
    iH = mdl.dof_layout(2, 2)["carrier"] + 2
    q = static_equilibrium(m)
    k_red = m.P[mdl.I_TLOAD] / -(q[iH] - q[m.rotor_index] / i)  # output torque per carrier twist against the rotor
    k_s = 1.0 / (1.0 / k_red + 1.0 / m.P[mdl.I_KOUT])
    J_R = m.P[mdl.I_JREF_I] * i - J_ARM  # the train (rotor included) reflected to the output, without the load
    k_g = m.P[mdl.I_KSL] * i * i
    K = np.array([[k_g + k_s, -k_s], [-k_s, k_s]])
    est = np.sqrt(scipy.linalg.eigh(K, np.diag([J_R, J_ARM]), eigvals_only=True)) / (2 * np.pi)
    assert_allclose(fr[:2], est, rtol=0.02)
    assert 0.7 < fr[0] / (math.sqrt(m.P[mdl.I_KOUT] / J_ARM) / (2 * np.pi)) < 1.0
    assert fr[2] > 1000.0  # the reducer's own modes stay in the kHz


def test_forces_are_minus_gradient_of_the_potential_with_the_load():
    m = prepare(P0, output_speed_deg_s=45.0, load_Nm=100.0, load_inertia_kg_m2=J_ARM,
                settings=mdl.ModelSettings(damping=False))
    t = 0.21
    q = static_equilibrium(m, t) + 1e-7 * np.random.default_rng(4).standard_normal(m.n_dof)
    q[-1] += 1e-4  # the coupling well away from its static twist
    Ma = mdl.make_rhs(m)(t, np.concatenate([q, np.zeros_like(q)]))[m.n_dof:] * m.mass
    grad = potential_gradient(m, t, q)
    assert_allclose(Ma, -grad, rtol=0, atol=1e-6 * np.max(np.abs(Ma)))
    assert abs(Ma[-1]) > 10.0  # the coupling's torque on the load is in the comparison


def test_feed_forward_carries_the_load_inertia_while_accelerating():
    """Accelerating on a trapezoid, the drive's feed-forward T_L / i + i J_ref dOmega/dt includes the load's
    J_L dOmega/dt / i: at the quasi-static solution the rotor stays at its nominal angle, and the coupling carries
    the gravity load plus J_L dOmega/dt.  Without the load's share the rotor would lag by J_L dOmega/dt / (i k_sl)."""
    prof = SpeedProfile("trapezoid", 45.0, 300.0)
    arm = LoadProfile(15.0, 0.5, 20.0)
    m = prepare(P0, profile=prof, load_profile=arm, load_Nm=20.0, duration_s=1.0)
    assert m.has_load and m.mass[-1] == J_ARM and m.P[mdl.I_ARM_ML2] == 0.0
    t = 0.05  # in the acceleration phase (the trapezoid starts at rest at t = 0)
    mt = mdl.mesh_array(m)
    mdl.mesh_terms(t, m.P, m.tables, mt)
    acc = mt[m.n_planets, 1]
    assert acc == pytest.approx(math.radians(300.0))
    q = static_equilibrium(m, t)
    i = m.P[mdl.I_RATIO]
    lag = J_ARM * acc / (i * m.P[mdl.I_KSL])
    assert abs(q[m.rotor_index]) < 1e-6 * lag
    iH = mdl.dof_layout(2, 2)["carrier"] + 2
    gravity = mt[m.n_planets, 2] - 20.0  # T_L(t) - T0: the arm's M g L cos(...) at t
    assert_allclose(m.P[mdl.I_KOUT] * (q[iH] - q[-1]), 20.0 + gravity + J_ARM * acc, rtol=1e-6)


def test_how_the_load_inertia_is_chosen():
    arm = LoadProfile(15.0, 0.5, 0.0)
    assert prepare(P0, output_speed_deg_s=30.0, load_profile=arm).mass[-1] == J_ARM  # the arm's M L^2
    assert not prepare(P0, output_speed_deg_s=30.0).has_load  # no arm, nothing stated: a pure torque
    stated = P0.replace(operation={"load_inertia": 2.0})
    assert prepare(stated, output_speed_deg_s=30.0, load_profile=arm).mass[-1] == 2.0  # stated wins
    assert not prepare(P0.replace(operation={"load_inertia": 0.0}), output_speed_deg_s=30.0,
                       load_profile=arm).has_load
    assert prepare(stated, output_speed_deg_s=30.0, load_inertia_kg_m2=1.5).mass[-1] == 1.5  # the argument wins
    assert "load_inertia" not in P0.to_dict()["operation"] and stated.to_dict()["operation"]["load_inertia"] == 2.0
    assert ReducerParams.from_dict(stated.to_dict()) == stated


@pytest.mark.parametrize("bad", [-1.0, math.nan, math.inf, "3"])
def test_bad_load_inertia_is_one_error_naming_it(bad):
    with pytest.raises(ParameterError, match="load_inertia_kg_m2 must be a finite number >= 0"):
        prepare(P0, output_speed_deg_s=30.0, load_inertia_kg_m2=bad)
    if isinstance(bad, float):
        with pytest.raises(ConfigError, match=r"\[operation\] load_inertia"):
            P0.replace(operation={"load_inertia": bad})
