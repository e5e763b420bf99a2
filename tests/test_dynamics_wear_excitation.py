"""Tooth wear as a transmission-error excitation of the sun-planet meshes (docs/model.md, "Fault sensitivity").

The approach of each tooth pair is ``delta - e(phi)``, ``e`` the pair's separation (here: the wear depth at its
contact point, from ``rvdiag.gears.mesh_stiffness(...).pair_profile_error_m``), with the force
``k g(delta - e) + c (delta' - e')`` (Kahraman & Singh 1990).  The tests run on perfect involutes without
relief (``iso1328_grade = 0``, no relief) and without manufacturing errors so that wear is the only separation; a
table without pair data (``pair_stiffness_N_per_m=None``) is one spring per mesh with ``error_m`` as its separation.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from rvdiag.dynamics import ModelSettings, mesh_table, prepare, simulate
from rvdiag.dynamics import model as mdl
from rvdiag.dynamics.linear import static_equilibrium
from rvdiag.dynamics.mesh import MeshTable, rectangular_mesh_table
from rvdiag.errors import ParameterError
from rvdiag.gears import ToothFaults, Wear
from rvdiag.params import ReducerParams
from conftest import potential_gradient

#: perfect involutes without relief or extended contact, and no manufacturing errors: the wear deviation is then the
#: only separation, which isolates the excitation this module is about
P0 = ReducerParams.default().replace(
    modification={"iso1328_grade": 0, "tip_relief_sun": 0.0, "tip_relief_planet": 0.0,
                  "extended_contact_separation": 0.0},
    manufacturing={"planet_runout_grade": 0, "crank_hole_position": 0.0, "crank_phase_arcmin": 0.0,
                   "pin_radius": 0.0, "pin_position": 0.0})
#: the library engineer's operating point (docs/library.md): 45 deg/s output, 75 N m, no noise
OP = dict(output_speed_deg_s=45.0, load_Nm=75.0)
SIM = dict(duration_s=0.1, fs=48000.0, settings=ModelSettings(transient_s=0.05), **OP)


def _rel_change(s: np.ndarray, h: np.ndarray) -> float:
    """Relative RMS difference ||s - h|| / ||h|| over both channels."""
    return float(np.linalg.norm(s - h) / np.linalg.norm(h))


def _mesh_stiffness_at(model: mdl.Model, t: float, i: int) -> tuple[float, float]:
    """(k, e) of mesh i at time t by NumPy periodic interpolation of the model's tables."""
    P = model.P
    nt = model.tvms.size
    grid = np.arange(nt + 1) * (2 * np.pi / nt)
    phase = np.mod(P[mdl.I_WREL] * t - 2 * np.pi * i / model.n_planets, 2 * np.pi)
    k = np.interp(phase, grid, np.append(model.tvms, model.tvms[0]))
    e = np.interp(phase, grid, np.append(model.tvms_error, model.tvms_error[0]))
    return float(k), float(e)


def _one_spring(tab: MeshTable, error_m=None) -> MeshTable:
    """The table as one spring per mesh (no pair data) with ``error_m`` as its separation."""
    return dataclasses.replace(tab, error_m=error_m, pair_stiffness_N_per_m=None, pair_separation_m=None)


@pytest.fixture(scope="module")
def healthy_signal():
    return simulate(P0, **SIM).signal


# ------------------------------------------------------------------------------------------- tables


def test_healthy_and_crack_tables_have_zero_error_wear_is_zero_at_the_pitch_point():
    for tab in (mesh_table(P0), rectangular_mesh_table(P0), mesh_table(P0, ToothFaults.for_state("T4"))):
        assert tab.error_m.shape == tab.stiffness_N_per_m.shape
        assert not tab.has_error and np.all(tab.error_m == 0.0)
    m = prepare(P0, **OP)
    # no separation: the pair stiffnesses add up to the TVMS and every separation row is zero
    S = int(m.P[mdl.I_NSLOT])
    assert np.all(m.tvms_error == 0.0) and m.tables.shape == (4 * S + 2, m.tvms.size)
    assert_allclose(m.tables[:S].sum(axis=0), m.tvms, rtol=1e-12)
    assert np.all(m.tables[S:2 * S] == 0.0)
    worn = mesh_table(P0, ToothFaults.for_state("T3"))
    e = worn.error_m
    mw = prepare(P0, worn, **OP)
    assert mw.tables.shape == (4 * S + 2, mw.tvms.size) and np.array_equal(mw.tables[-1], mw.tvms_error)
    assert np.array_equal(mw.tables[S:2 * S], mw.pairs[:, 1, :])
    assert worn.has_error and np.all(e >= 0.0)
    # default T3 severity 20 um; the load-shared deviation peaks below it (shared with the other pair)
    assert 1e-6 < e.max() <= 20e-6 + 1e-12
    # Archard: no sliding at the pitch point, so every mesh cycle reaches (almost) zero deviation
    per_cycle = e.reshape(P0.stage1.sun_teeth, -1)
    assert np.all(per_cycle.min(axis=1) < 0.01 * e.max())
    # uniform wear on every sun tooth: the deviation repeats every mesh cycle
    assert_allclose(per_cycle, np.broadcast_to(per_cycle[0], per_cycle.shape), atol=1e-12)


def test_error_table_validation_and_resampling():
    a = np.linspace(0.0, 2 * np.pi, 8, endpoint=False)
    k = np.full(8, 1e8)
    with pytest.raises(ParameterError, match="error_m"):
        MeshTable(a, k, error_m=np.zeros(7))
    with pytest.raises(ParameterError, match="finite"):
        MeshTable(a, k, error_m=np.r_[np.zeros(7), np.nan])
    e = np.sin(a) * 1e-6
    tab = MeshTable(a, k, error_m=e)
    assert_allclose(tab.resample_error(8), e, atol=1e-20)
    # periodic linear interpolation: the midpoint between the last and the first sample
    assert_allclose(tab.resample_error(16)[15], 0.5 * (e[7] + e[0]), rtol=1e-12)
    with pytest.raises(ParameterError, match="tvms_error"):
        m = prepare(P0, **OP)
        dataclasses.replace(m, tvms_error=np.zeros(3))


# -------------------------------------------------------------------------------------- the forces


def test_forces_are_minus_gradient_of_potential_with_wear():
    """Q = -grad V still holds with a non-zero error table (as tests/test_dynamics_model.py does for
    the healthy model), at the static solution of a worn (T3) sun plus a small random offset.  Damping
    off: at v = 0 the mesh damper still sees the rate -de/dt of the deviation (tested below)."""
    m = prepare(P0, ToothFaults.for_state("T3"), output_speed_deg_s=45.0, load_Nm=100.0,
                settings=ModelSettings(damping=False))
    assert np.max(np.abs(m.tvms_error)) > 1e-6
    t = 0.37
    q = static_equilibrium(m, t) + 1e-7 * np.random.default_rng(3).standard_normal(m.n_dof)
    Ma = mdl.make_rhs(m)(t, np.concatenate([q, np.zeros_like(q)]))[m.n_dof:] * m.mass
    grad = potential_gradient(m, t, q)
    assert_allclose(Ma, -grad, rtol=0, atol=1e-6 * np.max(np.abs(Ma)))


def test_missing_material_unloads_the_mesh_and_its_rate_enters_the_damping():
    """At fixed q and v = 0, an error e(phi) changes each mesh force by exactly -(k e + c de/dt):
    positive e (material missing) reduces the approach.  Checked on the sun's torque
    (Q_th,s = -rb1 sum F_i) against NumPy interpolation of the tables, e = A (1 + sin(Z1 phi))."""
    base = mesh_table(P0)
    A = 0.05e-6  # small enough that no mesh leaves contact
    z1 = P0.stage1.sun_teeth
    err = A * (1.0 + np.sin(z1 * base.angle_rad))
    m0 = prepare(P0, base, **OP)
    base = _one_spring(base)
    m1 = prepare(P0, _one_spring(base, err), **OP)
    t = 0.0123
    q = static_equilibrium(m0, t)
    dQ = mdl.forces(m1, t, q) - mdl.forces(m0, t, q)
    P = m0.P
    rb1, cm, w = P[mdl.I_RB1], P[mdl.I_CMESH], P[mdl.I_WREL]
    dF = 0.0
    for i in range(m0.n_planets):
        k, e = _mesh_stiffness_at(m1, t, i)
        phase = w * t - 2 * np.pi * i / m0.n_planets
        edot = A * z1 * math.cos(z1 * phase) * w
        dF += -(k * e + cm * edot)
    assert dF < 0
    # the table's central-difference slope differs from the exact derivative by O(h^2): rel. 1.5e-4 here
    assert_allclose(dQ[2], -rb1 * dF, rtol=3e-4)
    # frozen (modal/static analysis): the same deviation, no rate term
    f0, f1 = m0.frozen(t), m1.frozen(t)
    dQf = mdl.forces(f1, t, q) - mdl.forces(f0, t, q)
    dFf = sum(-_mesh_stiffness_at(m1, t, i)[0] * _mesh_stiffness_at(m1, t, i)[1] for i in range(2))
    assert_allclose(dQf[2], -rb1 * dFf, rtol=1e-9)


# ----------------------------------------------------------------------------------- the vibration


def test_worn_sun_changes_the_signal_clearly(healthy_signal):
    """Default T3 (20 um Archard wear on every sun tooth): measured relative RMS difference from healthy
    12.3 (0.1 s, both channels; RMS x 10.9 / 12.6); with the deviation removed (wear only as lost
    stiffness) it is 3.8e-4.  Bounds: > 2 and < 1e-2."""
    tab = mesh_table(P0, ToothFaults.for_state("T3"))
    worn = simulate(P0, tab, **SIM).signal
    stiff_only = simulate(P0, dataclasses.replace(tab, error_m=None, pair_separation_m=np.zeros_like(
        tab.pair_separation_m)), **SIM).signal
    assert _rel_change(worn, healthy_signal) > 2.0
    assert np.all(np.sqrt(np.mean(worn**2, axis=1)) > 3.0 * np.sqrt(np.mean(healthy_signal**2, axis=1)))
    assert _rel_change(stiff_only, healthy_signal) < 1e-2


def test_change_grows_with_wear_depth(healthy_signal):
    """Measured relative RMS difference for 2 / 5 / 20 um: 2.4 / 5.4 / 12.3; asserted strictly
    increasing by at least 20 % per step."""
    changes = [_rel_change(simulate(P0, ToothFaults(wear=Wear(d)), **SIM).signal, healthy_signal)
               for d in (2e-6, 5e-6, 20e-6)]
    assert changes[0] > 0.5
    assert changes[1] > 1.2 * changes[0] and changes[2] > 1.2 * changes[1], changes


def test_constant_error_only_shifts_the_static_deflection(healthy_signal):
    """A constant deviation c is taken up by a rigid kinematic shift of the train behind the meshes
    (the load is a constant torque): every spring force is unchanged, the mesh deflection of the
    static solution grows by exactly c, and the vibration is the same.  What remains is the rigid
    phase lag of the discs' orbit (measured 6e-4 of the signal for c = 5 um); asserted < 5e-3, while
    an error of the same size that varies once per mesh cycle, c (1 + sin(Z1 phi)) / 2, changes it
    by 3e-2 (asserted > 1e-2)."""
    base = _one_spring(mesh_table(P0))
    c = 5e-6
    const = _one_spring(base, np.full_like(base.stiffness_N_per_m, c))
    m0, m1 = prepare(P0, base, **OP), prepare(P0, const, **OP)
    q0, q1 = static_equilibrium(m0, 0.0), static_equilibrium(m1, 0.0)
    P = m0.P
    for i in range(2):
        ip = 3 + 3 * i
        sap, cap = m0.planet[i, 2], m0.planet[i, 3]

        def d(q):
            return (q[0] * sap + q[1] * cap + P[mdl.I_RB1] * q[2] - q[ip] * P[mdl.I_SINA]
                    - q[ip + 1] * P[mdl.I_COSA] + P[mdl.I_RB2] * q[ip + 2])
        assert_allclose(d(q1) - d(q0), c, rtol=1e-6)
    # the input coupling and the housing carry the same torques (to the static solve's tolerance: 3e-8 with
    # the soft speed-loop spring on the motor rotor)
    assert_allclose(q1[2], q0[2], rtol=1e-7, atol=1e-15)
    i_rt = mdl.dof_layout(2, 2)["pin_wheel"] + 2
    assert_allclose(q1[i_rt], q0[i_rt], rtol=1e-9, atol=1e-15)
    shifted = simulate(P0, const, **SIM).signal
    one = simulate(P0, base, **SIM).signal
    assert _rel_change(shifted, one) < 5e-3
    z1 = P0.stage1.sun_teeth
    varying = _one_spring(base, 0.5 * c * (1.0 + np.sin(z1 * base.angle_rad)))
    assert _rel_change(simulate(P0, varying, **SIM).signal, one) > 1e-2
