"""The RV-reducer model's equations: forces from a potential, static torque balance, contact geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from rvdiag.dynamics import ModelSettings, mesh_table, prepare
from rvdiag.dynamics.trace import planet_runout
from rvdiag.dynamics import model as mdl
from rvdiag.dynamics.linear import natural_frequencies, stiffness_matrix, static_equilibrium
from rvdiag.dynamics.mesh import MeshTable, contact_ratio, rectangular_mesh_table, single_pair_stiffness
from rvdiag.errors import ParameterError
from rvdiag.params import ReducerParams
from conftest import potential_gradient

P0 = ReducerParams.default()


@pytest.fixture(scope="module")
def loaded():
    m = prepare(P0, output_speed_deg_s=45.0, load_Nm=120.0)
    return m, static_equilibrium(m, 0.0)


def test_dof_layout_27_named_coordinates_and_the_motor_rotor():
    names = mdl.dof_names(2, 2)
    assert len(names) == 27 and len(set(names)) == 27
    assert names[:3] == ["sun.x", "sun.y", "sun.th"] and names[-1] == "pin_wheel.th"
    m = prepare(P0, input_speed_rpm=1000.0)
    # the default [drive] puts the servo rotor on the input shaft as a 28th coordinate
    assert m.n_dof == 28 and m.names[-1] == "motor.th" and np.all(m.mass > 0)
    assert m.mass[-1] == P0.drive.motor_inertia
    ideal = prepare(P0.replace(drive={"speed_loop_bandwidth_hz": 0.0}), input_speed_rpm=1000.0)
    assert ideal.n_dof == 27 and not ideal.has_motor


def test_the_speed_loop_holds_the_rotor_at_its_static_angle(loaded):
    """The steady drive torque is T_L / i, which the input shaft passes on, so the speed loop's spring is
    unloaded at the static solution: the rotor sits at its nominal angle (measured 1.5e-7 of the sun's wind-up,
    the static solve's tolerance on a 13 N m/rad speed-loop spring)."""
    m, q = loaded
    assert m.has_motor
    assert abs(q[-1]) < 1e-6 * abs(q[2])
    assert_allclose(m.P[mdl.I_TDRIVE], 120.0 / P0.ratio, rtol=1e-12)


def test_forces_are_minus_gradient_of_independent_potential():
    """M a(v=0) of the compiled kernel equals -dV/dq of the NumPy potential (docs/model.md), with every tooth
    pair's separation (relief, ISO 1328 errors) in it.  Damping off: at v = 0 a damper still sees the
    separations' rate, which no potential holds."""
    m = prepare(P0, output_speed_deg_s=45.0, load_Nm=100.0, settings=mdl.ModelSettings(damping=False))
    assert np.ptp(m.pairs[:, 1, :]) > 1e-6  # the separations are exercised
    q0 = static_equilibrium(m, 0.37)
    rng = np.random.default_rng(3)
    q = q0 + 1e-7 * rng.standard_normal(m.n_dof)
    t = 0.37
    f = mdl.make_rhs(m)(t, np.concatenate([q, np.zeros_like(q)]))
    Ma = f[m.n_dof:] * m.mass
    grad = potential_gradient(m, t, q)
    assert_allclose(Ma, -grad, rtol=0, atol=1e-6 * np.max(np.abs(Ma)))


def test_static_torque_balance(loaded):
    """Rigid-kinematics torque balance at the static solution: the input coupling carries T_L / i and the
    housing (pin wheel) reacts T_L (1 - 1/i); both follow from virtual work, exact for this model."""
    m, q = loaded
    i = P0.ratio
    lay = mdl.dof_layout(2, 2)
    t_in = -P0.bearings.input_torsional * q[lay["sun"] + 2]
    t_housing = -m.P[mdl.I_KRT] * q[lay["pin_wheel"] + 2]
    assert_allclose(t_in, 120.0 / i, rtol=1e-6)
    assert_allclose(t_housing, 120.0 * (1 - 1 / i), rtol=1e-6)


def test_static_meshes_loaded_and_pins_half_in_contact(loaded):
    m, q = loaded
    P = m.P
    # every sun-planet mesh is loaded: some tooth pair's approach exceeds its separation plus half the backlash
    mt = mdl.mesh_array(m)
    mdl.mesh_terms(0.0, P, m.tables, mt)
    S = int(P[mdl.I_NSLOT])
    runout = planet_runout(m, 0.0)[0]  # the planets' runout transmission error (manufacturing errors)
    for i, row in enumerate(m.planet):
        ip = 3 + 3 * i
        sap, cap = row[2], row[3]
        d = (q[0] * sap + q[1] * cap + P[mdl.I_RB1] * q[2] - q[ip] * P[mdl.I_SINA]
             - q[ip + 1] * P[mdl.I_COSA] + P[mdl.I_RB2] * q[ip + 2] - runout[i])
        loaded_pairs = [s for s in range(S) if mt[i, 4 * s] > 0 and d - mt[i, 4 * s + 1] > P[mdl.I_HALF_BACKLASH]]
        assert loaded_pairs, (i, d, mt[i])
    geo, rot, _ = mdl.work_arrays(m)
    mdl.pin_geometry(0.0, P, m.cosk, m.sink, geo, rot)
    lay = mdl.dof_layout(2, 2)
    e = m.extra["manufacturing"]  # the pins' radius and groove errors (rvdiag.dynamics.manufacturing)
    rho, vx, vy = e.pin_offsets_fixed_frame()
    for j in range(2):
        idd = lay[f"disc{j}"]
        cb, sb = rot[j, 0], rot[j, 1]
        ux = cb * q[idd] + sb * q[idd + 1]
        uy = -sb * q[idd] + cb * q[idd + 1]
        g = 0  # shared geometry (180 deg = 20 pin pitches): index k is pin k + 20 j
        # pin wheel displacement is ~1e-10 m here; include it properly
        iR = lay["pin_wheel"]
        cB, sB = rot[j, 2], rot[j, 3]
        ux -= cB * q[iR] + sB * q[iR + 1]
        uy -= -sB * q[iR] + cB * q[iR + 1]
        th = q[idd + 2] - P[mdl.I_ZP] / P[mdl.I_ZC] * q[iR + 2]
        k = (np.arange(40) + 20 * j) % 40
        off = rho[k] - ((cB * vx[k] + sB * vy[k]) * geo[g, 0] + (cB * vy[k] - sB * vx[k]) * geo[g, 1])
        delta = ux * geo[g, 0] + uy * geo[g, 1] + th * geo[g, 2] + off
        n_loaded = int(np.sum(delta > 0))
        assert 14 <= n_loaded <= 26, n_loaded


def test_pin_geometry_matches_closed_form_and_gears_contact_state():
    """Lever arm e Zc sin(eta)/sqrt(1 + K1^2 - 2 K1 cos eta) (Blanche & Yang 1989) and the normal through
    the pitch point, against rvdiag.gears.cycloid.pin_contact_state (force directions) at t = 0."""
    from rvdiag.gears.cycloid import pin_contact_state

    m = prepare(P0, output_speed_deg_s=30.0, load_Nm=100.0)
    geo, rot, _ = mdl.work_arrays(m)
    t = 0.0123
    mdl.pin_geometry(t, m.P, m.cosk, m.sink, geo, rot)
    s2 = P0.stage2
    e, zp, zc, rp = s2.eccentricity, s2.pins, s2.cycloid_lobes, s2.pin_circle_radius
    k1 = e * zp / rp
    big_b = math.atan2(rot[0, 3], rot[0, 2])  # eccentric angle of disc 0 in the fixed frame
    eta = 2 * np.pi * np.arange(zp) / zp - big_b
    arm = e * zc * np.sin(eta) / np.sqrt(1 + k1**2 - 2 * k1 * np.cos(eta))
    assert_allclose(geo[0, 2], arm, rtol=0, atol=1e-14)
    inc, ang, _ = pin_contact_state(s2, P0.material, big_b, direction=1)
    # force on the disc acts along -n; rotate our eccentric-frame normal to the fixed frame
    nx = np.cos(big_b) * geo[0, 0] - np.sin(big_b) * geo[0, 1]
    ny = np.sin(big_b) * geo[0, 0] + np.cos(big_b) * geo[0, 1]
    assert_allclose(np.arctan2(-ny, -nx), ang, atol=1e-12)
    assert np.array_equal(geo[0, 2] > 1e-12 * rp, inc)


def test_loaded_pins_are_the_gears_contact_half(loaded):
    """Pins in compression at the static solution = rvdiag.gears' loaded half for the positive torque sense."""
    from rvdiag.gears.cycloid import pin_contact_state

    m, q = loaded
    geo, rot, _ = mdl.work_arrays(m)
    mdl.pin_geometry(0.0, m.P, m.cosk, m.sink, geo, rot)
    lay = mdl.dof_layout(2, 2)
    idd = lay["disc0"]
    cb, sb = rot[0, 0], rot[0, 1]
    ux = cb * q[idd] + sb * q[idd + 1]
    uy = -sb * q[idd] + cb * q[idd + 1]
    delta = ux * geo[0, 0] + uy * geo[0, 1] + q[idd + 2] * geo[0, 2]
    big_b = math.atan2(rot[0, 3], rot[0, 2])
    inc, _, _ = pin_contact_state(P0.stage2, P0.material, big_b, direction=-1)
    # the two sets agree except possibly the pins next to the arm's zero crossings (eta ~ 0, pi)
    mismatch = np.flatnonzero((delta > 0) != inc)
    assert mismatch.size <= 4
    assert np.all(np.abs(geo[0, 2][mismatch]) < 0.2 * np.max(np.abs(geo[0, 2])))


def test_stiffness_matrix_symmetric_and_positive_definite(loaded):
    m, q = loaded
    K = stiffness_matrix(m.frozen(0.0).with_P(CORIOLIS=0.0), 0.0, q)
    assert np.max(np.abs(K - K.T)) <= 1e-9 * np.max(np.abs(K))
    assert np.min(np.linalg.eigvalsh(0.5 * (K + K.T))) > 0
    f = natural_frequencies(m, q=q).frequencies_hz
    # 28 with the motor rotor; its mode on the speed loop and the input shaft is the lowest (~50 Hz)
    assert f.size == 28 and 10.0 < f[0] < 100.0 < f[1] < f[-1] < 2e5


def test_rectangular_table_mean_is_contact_ratio_times_pair_stiffness():
    t = rectangular_mesh_table(P0)
    eps = contact_ratio(P0)
    assert 1.3 < eps < 1.6
    assert_allclose(t.mean(), eps * single_pair_stiffness(P0), rtol=2e-3)
    broken = rectangular_mesh_table(P0, tooth_factors=[0.0] + [1.0] * 10)
    assert broken.stiffness_N_per_m.min() == 0.0


def test_mesh_table_validation():
    with pytest.raises(ParameterError):
        MeshTable(np.array([0.0, 1.0]), np.array([1.0, -1.0]))
    with pytest.raises(ParameterError):
        MeshTable(np.array([0.0, 0.0]), np.array([1.0, 1.0]))
    with pytest.raises(ParameterError):
        MeshTable(np.linspace(0, 7, 5), np.ones(5))


def test_gears_tvms_is_the_default_mesh_and_broken_tooth_zeroes_it():
    from rvdiag.gears import ToothFaults

    healthy = mesh_table(P0)
    assert healthy.source == "rvdiag.gears.mesh_stiffness"
    assert 1e8 < healthy.mean() < 5e8
    broken = mesh_table(P0, ToothFaults.from_name("broken"))
    assert broken.stiffness_N_per_m.min() == 0.0 < healthy.stiffness_N_per_m.min()


def test_settings_validation():
    from rvdiag.gears.cycloid import closing_offset

    with pytest.raises(ParameterError):
        ModelSettings(substeps=0)
    with pytest.raises(ParameterError):
        ModelSettings(sensor_directions=((0.0, 0.0),))
    with pytest.raises(ParameterError):
        prepare(P0, input_speed_rpm=-5.0)
    with pytest.raises(ParameterError):
        prepare(P0, input_speed_rpm=100.0, output_speed_deg_s=30.0)
    with pytest.raises(ParameterError, match="radial clearance"):
        closing_offset(0.82, 1e-6, 3e-6)


def test_pin_stiffness_is_gears_hertz_contact_linearised_at_the_load():
    """k_pin = sum k_i l_i^2 / sum l_i^2 of rvdiag.gears.cycloid's Hertz tangent stiffnesses at the disc
    torque T_L (1 - 1/i) Zc / (Zp D), averaged over crank angles; grows (logarithmically) with load;
    a zero load uses the 1 % rated-torque floor.  RV-20E at 167 N m: 3.4e8 N/m (not the flat 1.78e9)."""
    from rvdiag.gears.cycloid import pin_contact

    s2 = P0.stage2
    t_disc = 100.0 * (1 - 1 / P0.ratio) * s2.cycloid_lobes / (s2.pins * s2.n_discs)
    c = pin_contact(s2, P0.material, 0.3 * 2 * math.pi / s2.pins, t_disc)
    l2 = np.where(c.in_contact, c.arm_m, 0.0) ** 2
    direct = np.sum(c.stiffness_N_per_m * l2) / np.sum(l2)
    k100 = mdl.pin_contact_stiffness(P0, 100.0)
    assert k100 == pytest.approx(direct, rel=0.01)  # varies < 0.5 % over the crank angle
    assert c.stiffness_N_per_m[c.in_contact].min() < k100 < c.stiffness_N_per_m.max()
    k_rated = mdl.pin_contact_stiffness(P0, 167.0)
    assert 3.0e8 < k_rated < 4.0e8
    assert mdl.pin_contact_stiffness(P0, 10.0) < k100 < k_rated
    assert mdl.pin_contact_stiffness(P0, 0.0) == mdl.pin_contact_stiffness(P0, 0.01 * 167.0) > 1e8
    assert mdl.pin_contact_stiffness(P0, -100.0) == k100
    m = prepare(P0, output_speed_deg_s=45.0, load_Nm=100.0)
    assert m.P[mdl.I_KPIN] == k100 and m.extra["k_pin_N_per_m"] == k100


def test_bearing_and_damping_fields_come_from_the_parameter_set():
    """One source of truth: the spline's radial stiffness, the pin wheel's torsional support and the pin
    damping ratio are parameter-file values (not model settings)."""
    base = prepare(P0, output_speed_deg_s=45.0, load_Nm=100.0)
    p2 = P0.replace(bearings={"planet_crank_radial": 2.5e9, "pin_wheel_torsional": 1.0e7},
                    damping={"pin_damping_ratio": 0.14})
    m = prepare(p2, output_speed_deg_s=45.0, load_Nm=100.0)
    assert base.P[mdl.I_KPR] == P0.bearings.planet_crank_radial and m.P[mdl.I_KPR] == 2.5e9
    assert base.P[mdl.I_KRT] == P0.bearings.pin_wheel_torsional and m.P[mdl.I_KRT] == 1.0e7
    assert m.P[mdl.I_CPIN] == pytest.approx(2 * base.P[mdl.I_CPIN], rel=1e-12)
    for gone in ("planet_crank_radial_N_per_m", "pin_wheel_torsional_Nm_per_rad", "pin_damping_ratio"):
        assert not hasattr(ModelSettings(), gone)


def test_stiffest_modes_after_lumping_the_input_shaft():
    """With the input shaft lumped with the sun and the loaded Hertz pin stiffness, the highest natural
    frequency of the RV-20E is ~34 kHz (crank shafts on their bearings), down from 56 kHz (sun as a bare
    5.5 g ring, discs on 1.78e9 N/m pins); docs/model.md tabulates both."""
    m = prepare(P0, input_speed_rpm=1000.0)
    f = natural_frequencies(m).frequencies_hz
    assert 30e3 < f[-1] < 36e3
    bare = P0.replace(bodies={"input_shaft_length": 1e-9})
    assert natural_frequencies(prepare(bare, input_speed_rpm=1000.0)).frequencies_hz[-1] > 40e3


def test_interpolated_pin_geometry_is_within_1e8_of_the_exact_one():
    """Quadratic interpolation through the exact geometries at a sample's start, middle and end
    (``interpolate_geometry``) against ``pin_geometry`` at inner times, 1000 rpm and 48 kHz."""
    m = prepare(P0, input_speed_rpm=1000.0)
    dt = 1.0 / 48000.0
    t0 = 0.0123

    def exact(t):
        geo, rot, _ = mdl.work_arrays(m)
        mdl.pin_geometry(t, m.P, m.cosk, m.sink, geo, rot)
        return geo

    g0, gm, g1 = exact(t0), exact(t0 + dt / 2), exact(t0 + dt)
    out = np.zeros_like(g0)
    for s in (0.0, 1 / 18, 0.25, 0.5, 0.9, 1.0):
        mdl.interpolate_geometry(g0, gm, g1, s, m.P, out)
        assert np.abs(out[0] - exact(t0 + s * dt)[0]).max() < 1e-8
    assert np.abs(g1[0] - g0[0]).max() > 1e-3  # the geometry does move within the sample


def test_mesh_terms_interpolate_the_table_at_each_planets_phase():
    """``mesh_terms``: every tooth-pair slot's stiffness, separation, damping and the separation's rate linear in
    the table at the sun angle relative to each planet, against numpy.interp on the periodic table."""
    from rvdiag.library.states import tooth_faults

    m = prepare(P0, tooth_faults("T3", wear_depth=10e-6), output_speed_deg_s=45.0, load_Nm=100.0)
    S = int(m.P[mdl.I_NSLOT])
    assert S == 3 and m.tables.shape[0] == 4 * S + 2
    nt = m.tables.shape[1]
    grid = np.arange(nt + 1) / nt

    def at(row, x):
        return np.interp(x, grid, np.append(m.tables[row], m.tables[row, 0]))

    mt = mdl.mesh_array(m)
    checked = 0
    for t in (0.0, 0.00123, 0.0471):
        mdl.mesh_terms(t, m.P, m.tables, mt)
        for i in range(m.n_planets):
            x = (m.P[mdl.I_WREL] * t / (2 * np.pi) - i / m.n_planets) % 1.0
            for s in range(S):
                assert mt[i, 4 * s] == pytest.approx(at(s, x), rel=1e-12, abs=1e-3)
                assert mt[i, 4 * s + 1] == pytest.approx(at(S + s, x), rel=1e-9, abs=1e-18)
                assert mt[i, 4 * s + 3] == pytest.approx(at(2 * S + s, x), rel=1e-9, abs=1e-12)
                rate = m.P[mdl.I_WREL] * nt / (2 * np.pi) * at(3 * S + s, x)
                assert mt[i, 4 * s + 2] == pytest.approx(rate, rel=1e-9, abs=1e-15)
                checked += mt[i, 4 * s + 2] != 0.0
            assert mt[i, 4 * S] == pytest.approx(at(4 * S, x), rel=1e-12)
    assert checked > 0  # the separation's rate is exercised


def test_separation_slopes_are_central_differences_inside_a_pair_and_zero_outside():
    k = np.array([[0.0, 1.0, 1.0, 1.0, 0.0, 0.0]])
    e = np.array([[9.0, 1.0, 3.0, 7.0, 9.0, 9.0]])
    sl = mdl.separation_slopes(np.stack([k, e], axis=1))
    np.testing.assert_allclose(sl[0], [0.0, 2.0, 3.0, 4.0, 0.0, 0.0])


