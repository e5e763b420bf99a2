"""Manufacturing errors of the reducer (``[manufacturing]``, :mod:`rvdiag.dynamics.manufacturing`; docs/model.md
sections 3 and 10): the parameters and their draws, the model without them (to the cross-CPU spread), each error's physical
signature, and the motor current's line goals.

The goals (docs/model.md section 10; rated load, default parameters with the motor-current rig's arm on the output,
15 kg at 0.5 m, as the load DOF's 3.75 kg m^2, last 4096 points of i_a at 1 kHz, Hann window, a line's height over
the median of the bins 6-40 away): (a) f_e, f_e +- f1, |f_e +- f_sp| and |f_e +- f_cs| at least
10 dB above the floor at 30, 45 and 60 deg/s; (b) a broken sun tooth raises the f1 sidebands at least 2x over
healthy; (c) pitting raises them less than spalling, spalling less than a broken tooth.  The goals not met are
strict expected failures with the measured figures (``bench/current_lines.py`` measures all of them at the three
speeds, with the errors on and off).

Cost: the six 4.2-s current runs of the module fixture (healthy at 30, 45 and 60 deg/s; broken, pitting and
spalling at 60), three 1.2-s runs and ~150 static solves: the module took 25.7 s with the numba cache warm (a first
run compiles the kernels for about a minute more).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

import rvdiag.dynamics.packing as packing
from rvdiag.dynamics import prepare, prepare_simulation, simulate
from rvdiag.dynamics import model as mdl
from rvdiag.dynamics.linear import static_equilibrium
from rvdiag.dynamics.manufacturing import ManufacturingErrors, draw_manufacturing_errors
from rvdiag.dynamics.trace import mesh_forces, planet_runout
from rvdiag.errors import ConfigError
from rvdiag.gears import ToothFaults
from rvdiag.gears.modification import iso1328_tolerances
from rvdiag.kinematics import characteristic_frequencies
from rvdiag.motor.lines import amplitude_spectrum, current_lines, line_height
from rvdiag.params import ReducerParams

from conftest import CROSS_CPU_RTOL, assert_close_across_cpus, potential_gradient, run_cli

P0 = ReducerParams.default()
OFF = {"planet_runout_grade": 0, "crank_hole_position": 0.0, "crank_phase_arcmin": 0.0, "pin_radius": 0.0,
       "pin_position": 0.0}
#: the cycloid discs unmodified, as in the model the golden file was written by
UNMODIFIED = {"equidistant_modification": 0.0, "offset_modification": 0.0}
P_OFF = P0.replace(manufacturing=OFF, stage2=UNMODIFIED)
GOLDEN = Path(__file__).parent / "golden" / "before_manufacturing_errors.npz"
SPEEDS = (30.0, 45.0, 60.0)
ARCMIN = math.radians(1.0 / 60.0)
ZN, ZP = (0.0, 0.0), (0.0,) * 40


def errors(runout=ZN, runout_angle=ZN, hole_r=ZN, hole_t=ZN, phase=ZN, pin_rho=ZP, pin_r=ZP, pin_t=ZP):
    return ManufacturingErrors(tuple(runout), tuple(runout_angle), tuple(hole_r), tuple(hole_t), tuple(phase),
                               tuple(pin_rho), tuple(pin_r), tuple(pin_t))


@pytest.fixture
def given_errors(monkeypatch):
    """``given_errors(e)``: every model built afterwards carries the deviations ``e`` instead of the drawn ones."""
    def use(e: ManufacturingErrors) -> None:
        monkeypatch.setattr(packing, "draw_manufacturing_errors", lambda params: e)
    return use


# ------------------------------------------------------------------------------------------ parameters and draws
def test_defaults_tolerances_and_draws():
    mf = P0.manufacturing
    assert (mf.planet_runout_grade, mf.crank_hole_position, mf.crank_phase_arcmin, mf.pin_radius,
            mf.pin_position) == (5, 3.0e-6, 1.0, 0.0, 0.0)  # the pins' errors need profile modifications: off
    assert P_OFF.manufacturing.is_zero and draw_manufacturing_errors(P_OFF).is_zero
    assert draw_manufacturing_errors(P0).pins_zero and not draw_manufacturing_errors(P0).planets_zero
    e = draw_manufacturing_errors(P0.replace(manufacturing={"pin_radius": 1e-6, "pin_position": 3e-6}))
    assert e.runout == draw_manufacturing_errors(P0).runout  # deterministic for the specimen's seed
    assert e != draw_manufacturing_errors(P0.replace(modification={"error_seed": 1},
                                                     manufacturing={"pin_radius": 1e-6, "pin_position": 3e-6}))
    f_rT = iso1328_tolerances(1.25e-3, 41.25e-3, 5).runout
    assert f_rT == pytest.approx(14.84e-6, rel=1e-3)  # ISO 1328-1 grade 5, the 33-tooth planet
    # each deviation within half its tolerance (an eccentricity is half a runout), means taken out
    assert 0 < max(e.runout) <= f_rT / 4 and len(e.runout) == 2
    assert max(map(abs, e.hole_radial)) <= 1.5e-6 and max(map(abs, e.hole_tangential)) <= 1.5e-6
    assert abs(sum(e.hole_tangential)) < 1e-18 and abs(sum(e.crank_phase)) < 1e-18
    assert max(map(abs, e.crank_phase)) <= 0.5 * ARCMIN
    assert max(map(abs, e.pin_radius)) <= 1.0e-6 and len(e.pin_radius) == 40
    assert abs(sum(e.pin_radius)) < 1e-18 and abs(sum(e.pin_radial)) < 1e-18 and abs(sum(e.pin_tangential)) < 1e-18
    assert 0.5e-6 < np.std(e.pin_radial) < 1.5e-6
    # one stream per kind: turning the pins on or off leaves the planets' draws as they were
    e2 = draw_manufacturing_errors(P0)
    assert e2.runout == e.runout and e2.crank_phase == e.crank_phase and e2.hole_radial == e.hole_radial


@pytest.mark.parametrize("key, value, message", [
    ("crank_hole_position", -1e-6, "[manufacturing] crank_hole_position: must be >= 0"),
    ("planet_runout_grade", 12, "[manufacturing] planet_runout_grade must be 0 (none) or 1..11"),
    ("pin_position", 1e-3, "[manufacturing] pin_position must be at most"),
    ("crank_phase_arcmin", 90.0, "[manufacturing] crank_phase_arcmin must be at most"),
])
def test_bad_values_are_one_line_config_errors(tmp_path, capsys, key, value, message):
    with pytest.raises(ConfigError, match=re.escape(message)):
        P0.replace(manufacturing={key: value})
    from importlib import resources

    bad = tmp_path / "bad.toml"
    bad.write_text(resources.files("rvdiag.params").joinpath("rv20e.toml").read_text()
                   + f"\n[manufacturing]\n{key} = {value}\n")
    code, _, err = run_cli(["params", "check", str(bad)], capsys)
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1


# ------------------------------------------------------------------------------------ the model without errors
def test_zero_errors_reproduce_the_model_before_them():
    """With every tolerance 0 the kernels run a copy compiled without the errors' terms, whose signals are those of
    the model before them (tests/golden, written by that model at commit c53110f).  The golden file holds the last
    bits of the machine that wrote it, so the comparison allows the cross-CPU spread (``conftest.CROSS_CPU_RTOL``,
    measured 1.7e-13 with ``NUMBA_CPU_NAME=generic``); a real change of the model moves the signal by > 1e-3."""
    g = np.load(GOLDEN)
    r = simulate(P_OFF, output_speed_deg_s=60.0, duration_s=0.02, signal="both")
    b = simulate(P_OFF, ToothFaults.for_state("T2"), output_speed_deg_s=45.0, duration_s=0.02)
    assert_close_across_cpus(r.signal, g["healthy_vibration"])
    assert_close_across_cpus(r.current, g["healthy_current"])
    assert_close_across_cpus(b.signal, g["broken_vibration"])
    # the default errors do change the signal (so the comparison above can fail)
    on = simulate(P0, output_speed_deg_s=60.0, duration_s=0.02).signal
    assert np.max(np.abs(on - g["healthy_vibration"])) > 1e-3 * np.max(np.abs(g["healthy_vibration"]))


def test_the_kernels_copy_with_the_error_terms_at_zero_is_the_copy_without_them():
    """Two code paths in one run: the kernels' copy compiled with the manufacturing errors' terms, switched on
    (``P[I_MFG]``) with every error 0, against the copy compiled without them.  They agree within the ULP-level
    spread of ``conftest.CROSS_CPU_RTOL`` (measured 1.9e-13: the compiler contracts and orders the two copies'
    arithmetic differently), which a real error term exceeds by orders of magnitude."""
    def run(errors_path: bool):
        ps = prepare_simulation(P_OFF, output_speed_deg_s=60.0, duration_s=0.02, signal="both")
        if errors_path:
            ps.model.P[mdl.I_MFG] = 1.0
        return ps.finish(*ps.integrate())

    plain, switched = run(False), run(True)
    assert_close_across_cpus(switched.signal, plain.signal)
    assert_close_across_cpus(switched.current, plain.current)
    assert np.std(plain.signal) > 0
    # one real error (the planets' runout at ISO 1328 grade 5) moves it far beyond that spread
    given = dict(OFF, planet_runout_grade=5)
    err = simulate(P0.replace(manufacturing=given, stage2=UNMODIFIED), output_speed_deg_s=60.0, duration_s=0.02)
    assert np.max(np.abs(err.signal - plain.signal)) > 1e3 * CROSS_CPU_RTOL * np.max(np.abs(plain.signal))


def test_forces_are_minus_gradient_of_the_potential_with_large_errors(given_errors):
    """M a(v = 0) of the compiled kernels equals -dV/dq of the NumPy potential (linear.potential_energy, which
    writes the errors from the drawn deviations, the kernels from their packed tables) with every error on at ~10x
    the default tolerances.  Damping off: at v = 0 the mesh damper still sees the runout's rate."""
    rng = np.random.default_rng(3)
    st = mdl.ModelSettings(damping=False)
    t = 0.37
    m_off = prepare(P_OFF, output_speed_deg_s=45.0, load_Nm=100.0, settings=st)
    given_errors(errors(runout=(20e-6, 12e-6), runout_angle=(1.0, 4.0), hole_r=(8e-6, -5e-6), hole_t=(6e-6, -6e-6),
                        phase=(-5 * ARCMIN, 5 * ARCMIN), pin_rho=rng.uniform(-5e-6, 5e-6, 40),
                        pin_r=rng.uniform(-15e-6, 15e-6, 40), pin_t=rng.uniform(-15e-6, 15e-6, 40)))
    m = prepare(P0, output_speed_deg_s=45.0, load_Nm=100.0, settings=st)
    q = static_equilibrium(m, t) + 1e-7 * rng.standard_normal(m.n_dof)
    y = np.concatenate([q, np.zeros_like(q)])
    Ma = mdl.make_rhs(m)(t, y)[m.n_dof:] * m.mass
    Ma_off = mdl.make_rhs(m_off)(t, y)[m.n_dof:] * m.mass
    assert np.max(np.abs(Ma - Ma_off)) > 1e-2 * np.max(np.abs(Ma))  # the errors act
    grad = potential_gradient(m, t, q)
    np.testing.assert_allclose(Ma, -grad, rtol=0, atol=1e-6 * np.max(np.abs(Ma)))


# ------------------------------------------------------------------------------------------ physical signatures
def _static_mesh_forces(p: ReducerParams, ts: np.ndarray) -> np.ndarray:
    """Quasi-static force of each planet's mesh (samples, planets) at 30 deg/s rated."""
    m = prepare(p, output_speed_deg_s=30.0)
    out = []
    for t in ts:
        q = static_equilibrium(m, float(t))
        out.append(mesh_forces(m, np.array([t]), np.concatenate([q, 0 * q])[None, :])[0].sum(axis=1))
    return np.array(out)


def test_planet_runout_is_a_transmission_error_once_per_planet_revolution():
    """The runout's transmission error is e_i sin(b_0 + phi_i + alpha), and it shifts load between the planets at the
    planet's rotation order: over one planet revolution (36 quasi-static samples at 30 deg/s; f1 = 3 f_p, so the
    sun's own errors fall on every third order only), the change it makes in the planets' load difference lies at
    order 1 (more than twice any other order; the next is order 3, f1: the runout also changes how the planets share
    the sun's pitch errors), grows in proportion to the runout (grade 5 -> 7 doubles it), and leaves the sum, which
    the input torque sets, all but unchanged (< 1 % of the change: the speed loop's soft spring lets the rotor
    follow the sun's mean rotation a little)."""
    m = prepare(P0, output_speed_deg_s=30.0)
    e = m.extra["manufacturing"]
    t = np.linspace(0.0, 0.3, 7)
    b0 = -40.0 * m.P[mdl.I_OMEGA] * t  # the cranks' eccentric angle (beta_0 = 0)
    want = np.array(e.runout)[:, None] * np.sin(b0[None, :] + np.array(e.runout_angle)[:, None] + math.radians(20))
    got = np.array([planet_runout(m, float(tk))[0] for tk in t]).T
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    f_p = 40.0 / 12.0  # planet rotation relative to the carrier at 30 deg/s, Hz
    ts = np.arange(36) / 36 / f_p
    base = {"crank_hole_position": 0.0, "crank_phase_arcmin": 0.0, "pin_radius": 0.0, "pin_position": 0.0}
    F_off = _static_mesh_forces(P_OFF, ts)
    change = {}
    for grade in (5, 7):
        F = _static_mesh_forces(P0.replace(manufacturing=dict(base, planet_runout_grade=grade)), ts)
        d = np.fft.rfft((F[:, 0] - F[:, 1]) - (F_off[:, 0] - F_off[:, 1])) / 18
        s = np.fft.rfft(F.sum(axis=1) - F_off.sum(axis=1)) / 18
        change[grade] = d
        assert abs(d[1]) > 2.0 * np.max(np.abs(np.delete(d, [0, 1])))
        assert np.max(np.abs(s)) < 1e-2 * abs(d[1])
    assert abs(change[7][1]) == pytest.approx(2.0 * abs(change[5][1]), rel=0.05)
    assert abs(change[5][1]) > 1.0  # N, of a 107 N static mesh force


def test_crank_phase_and_hole_errors_shift_the_static_load_sharing(given_errors):
    """A crank's eccentric angle error and a crank hole's tangential error make one planet carry more of the sun's
    torque, linearly in the error and with its sign (the sum stays the sun torque)."""
    ts = np.array([0.0, 0.0311])
    F0 = _static_mesh_forces(P_OFF, ts)
    for kind in ("phase", "hole_t"):
        shift = {}
        for size in (-1.0, 1.0, 2.0):
            if kind == "phase":
                given_errors(errors(phase=(-0.5 * size * ARCMIN, 0.5 * size * ARCMIN)))
            else:
                given_errors(errors(hole_t=(-1.5e-6 * size, 1.5e-6 * size)))
            F = _static_mesh_forces(P0, ts)
            np.testing.assert_allclose(F.sum(axis=1), F0.sum(axis=1), rtol=1e-6)
            shift[size] = (F[:, 0] - F[:, 1]) - (F0[:, 0] - F0[:, 1])
        assert np.all(np.abs(shift[1.0]) > 2.0)  # N: 1 arcmin, or +-1.5 um, moves a few percent of 107 N
        np.testing.assert_allclose(shift[-1.0], -shift[1.0], rtol=0.05)
        np.testing.assert_allclose(shift[2.0], 2.0 * shift[1.0], rtol=0.05)


def test_pin_errors_add_the_eccentric_rotation_orders(given_errors):
    """Pin k's radius and position errors act whenever a lobe meets it: the housing's quasi-static position gains
    lines at every order of the eccentric's rotation relative to the pins (f_cs / Zp), not only at multiples of the
    pin count (f_cs); 40 samples over one eccentric revolution, the change the errors make."""
    rng = np.random.default_rng(7)
    f_B = 39.0 / 12.0  # eccentric rotation relative to the pins at 30 deg/s, Hz
    ts = np.arange(40) / 40 / f_B
    m_off = prepare(P_OFF, output_speed_deg_s=30.0)
    iR = mdl.dof_layout(2, 2)["pin_wheel"]
    x_off = np.array([static_equilibrium(m_off, float(t))[iR] for t in ts])
    given_errors(errors(pin_rho=rng.uniform(-0.5e-6, 0.5e-6, 40), pin_r=rng.uniform(-1.5e-6, 1.5e-6, 40),
                        pin_t=rng.uniform(-1.5e-6, 1.5e-6, 40)))
    m = prepare(P0, output_speed_deg_s=30.0)
    x = np.array([static_equilibrium(m, float(t))[iR] for t in ts])
    d = np.abs(np.fft.rfft(x - x_off))
    assert np.count_nonzero(d[1:20] > 0.1 * d[1:20].max()) >= 5  # many orders, not one
    assert d[1:20].max() > 1e-9  # m: the housing moves by nanometres


@pytest.mark.parametrize("stage2, back_expected_with_errors", [(UNMODIFIED, True), ({}, False)])
def test_pin_errors_make_the_unloaded_half_of_unmodified_discs_touch(stage2, back_expected_with_errors):
    """Why the pins' errors need the discs' profile modification: on conjugate discs the pins of the unloaded half
    stand off by less than 1 um under load, and errors of a G2 / IT4 pin ring (1 um radius, 3 um position) make
    some of them touch and push against the loaded half; the default modification (+4 / -3 um) stands them off by
    up to 11.5 um, and none touches (docs/model.md section 3).  Rated load, 45 deg/s, three static solutions."""
    from oracles.reference_rhs import ReferenceRHS

    for pins, back_expected in (({"pin_radius": 0.0, "pin_position": 0.0}, False),
                                ({"pin_radius": 1e-6, "pin_position": 3e-6}, back_expected_with_errors)):
        m = prepare(P0.replace(manufacturing=pins, stage2=stage2), output_speed_deg_s=45.0)
        g = ReferenceRHS(m)
        back = []
        for t in (0.0, 0.0137, 0.05):
            q = static_equilibrium(m, t)
            d = g.pin_deflections(t, q)
            lk = g._pin_geometry(g._frames(t)[0])[2]
            back.append(int(np.sum((d > 0) & (lk > 0))))  # in contact with the arm of the unloaded sense
        assert (min(back) >= 2) if back_expected else (max(back) == 0), back


def test_crank_phase_and_hole_errors_put_fsp_back_into_the_motor_current(given_errors):
    """With two planets 180 deg apart and an 11-tooth sun the two meshes' f_sp torques cancel on the sun; a crank
    phase error of 1 arcmin, or crank holes +-1.5 um off tangentially, break the symmetry: the noise-free i_q gains an
    f_sp line (30 deg/s, 1.2 s, last 1024 points).  Measured: 0.11 uA without errors (the neighbouring lines' leakage
    at 1 Hz resolution; < 0.05 uA over 4096 points), 1.7 and 2.5 uA with them; so small because the model's output is
    a pure torque without inertia (docs/model.md section 10)."""
    p = P0.replace(motor={"current_noise": 0.0})
    fsp = characteristic_frequencies(p, output_speed_deg_s=30.0).fsp
    amp = {}
    for name, e in (("off", errors()), ("phase", errors(phase=(-0.5 * ARCMIN, 0.5 * ARCMIN))),
                    ("hole", errors(hole_t=(-1.5e-6, 1.5e-6)))):
        given_errors(e)
        r = simulate(p, output_speed_deg_s=30.0, duration_s=1.2, signal="current")
        f, a = amplitude_spectrum(r.signal[3][-1024:], r.fs)
        amp[name] = line_height(a, float(f[1] - f[0]), fsp)[0]
    assert amp["off"] < 0.3e-6
    assert amp["phase"] > 5 * amp["off"] and amp["phase"] > 1.0e-6
    assert amp["hole"] > 5 * amp["off"] and amp["hole"] > 1.0e-6


# ----------------------------------------------------------------------------------------- the current's goals
#: the motor-current rig's 15 kg arm at 0.5 m as the load DOF's inertia (kg m^2; configs/mcsa.toml)
RIG_LOAD_INERTIA = 15.0 * 0.5**2


@pytest.fixture(scope="module")
def runs():
    """The current's line table at rated load, default parameters (errors on) with the rig's arm inertia on the
    output coupling (the load DOF, :data:`RIG_LOAD_INERTIA`): healthy at 30, 45 and 60 deg/s, broken tooth (T2),
    pitting (T7) and spalling (T8) at 60 deg/s."""
    out = {}
    for speed, state in [(30.0, "T1"), (45.0, "T1"), (60.0, "T1"), (60.0, "T2"), (60.0, "T7"), (60.0, "T8")]:
        fault = None if state == "T1" else ToothFaults.for_state(state)
        r = simulate(P0, fault, output_speed_deg_s=speed, duration_s=4.2, signal="current",
                     load_inertia_kg_m2=RIG_LOAD_INERTIA)
        x = r.signal[0][-4096:]
        fr = characteristic_frequencies(P0, output_speed_deg_s=speed)
        f, a = amplitude_spectrum(x, r.fs)
        fam = [line_height(a, float(f[1] - f[0]), abs(fr.fe + s * k * fr.f1))[0] for k in range(1, 6) for s in (-1, 1)]
        out[speed, state] = {"lines": current_lines(x, r.fs, P0, speed)["lines"], "family": np.array(fam)}
    return out


def _height(runs, speed, name):
    return runs[speed, "T1"]["lines"][name]["height_db"]


def _family_ratio(runs, state, speed=60.0):
    """rms of f_e -+ k f1, k = 1..5 (|f_e - 5 f1| = 0.4 Hz is not resolved and left out), over healthy."""
    a, b = runs[speed, state]["family"], runs[speed, "T1"]["family"]
    ok = np.isfinite(a) & np.isfinite(b)
    return float(np.sqrt(np.mean(a[ok] ** 2) / np.mean(b[ok] ** 2)))


@pytest.mark.parametrize("speed", SPEEDS)
def test_goal_a_supply_and_sun_lines_stand_10_dB_above_the_floor(runs, speed):
    """Met: f_e (83-87 dB) and f_e +- f1 (12.8-25.4 dB, the encoder's once-per-revolution error)."""
    for name in ("fe", "fe-1f1", "fe+1f1"):
        assert _height(runs, speed, name) >= 10.0, (name, _height(runs, speed, name))


@pytest.mark.xfail(strict=True, reason=(
    "goal (a) not met: with the rig's arm on the output coupling |f_e -+ f_sp| 0.2 / 5.9, 4.6 / 7.5, 2.0 / -0.5 dB "
    "and |f_e -+ f_cs| -1.0 / 3.5, 2.5 / 3.1, 7.5 / 2.9 dB at 30 / 45 / 60 deg/s, within 0.5 dB of the pure-torque "
    "load: with two cranks 180 deg apart the planets' mesh torques at f_sp cancel on the sun, and the manufacturing "
    "errors break that symmetry by microamperes where ~1 mA is needed (docs/model.md 10)"))
@pytest.mark.parametrize("speed", SPEEDS)
def test_goal_a_mesh_lines_stand_10_dB_above_the_floor(runs, speed):
    heights = {n: _height(runs, speed, n) for n in ("fe-fsp", "fe+fsp", "fe-fcs", "fe+fcs")}
    assert min(heights.values()) >= 10.0, heights


def test_goal_b_broken_tooth_doubles_the_f1_sidebands(runs):
    """Met with the rig's arm on the output coupling (the load DOF): a broken tooth raises f_e -+ k f1 (k = 1..5)
    by 3.36x rms at 60 deg/s (5.16x and 4.22x at 30 and 45 deg/s; bench/current_lines.py --load-inertia 3.75),
    where the pure-torque load gave 1.42x."""
    assert _family_ratio(runs, "T2") >= 2.0


@pytest.mark.xfail(strict=True, reason=(
    "goal (c) not met: pitting and spalling change the f1 sidebands by < 0.5 % (1.00x; their TVMS changes are "
    "-0.07 % and -0.34 % of the mean stiffness), against 3.36x for a broken tooth at 60 deg/s"))
def test_goal_c_pitting_below_spalling_below_broken(runs):
    pit, spall, broken = (_family_ratio(runs, s) for s in ("T7", "T8", "T2"))
    assert pit >= 1.1 and spall >= 1.1 * pit and broken >= 1.1 * spall, (pit, spall, broken)


def test_goal_fixture_sees_the_faults(runs):
    """The fixture's runs are what the goals read: the broken tooth moves the sidebands, pitting and spalling
    leave them within 1 %, and the healthy f_e line is the drive's current (> 80 dB)."""
    assert _family_ratio(runs, "T2") > 1.2
    assert abs(_family_ratio(runs, "T7") - 1.0) < 0.01 and abs(_family_ratio(runs, "T8") - 1.0) < 0.01
    assert all(_height(runs, s, "fe") > 80.0 for s in SPEEDS)
