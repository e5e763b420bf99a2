"""Wear of the cycloid-pin stage (rvdiag.gears.pin_wear; docs/model.md section 3, "Wear of the cycloid-pin stage").

Checked here: the Archard depth of the discs' flanks and of the pins against a hand calculation (Blagojevic's load
sharing of an unmodified stage, the sliding over the contact's travel); the kernels' clearance row against the
modification formula plus the table; a zero table run through the wear's code path gives the unworn model to the
bit; Q = -grad V of the NumPy potential with wear; the lost motion grows monotonically with the depth, in the
geometry and in the model's static hysteresis test; bad depths as one-line errors (API, parameter file, CLI); the GPU
ensemble under numba's CUDA simulator.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from scipy.optimize import brentq

from rvdiag.dynamics import kernels as kn
from rvdiag.dynamics import model as mdl
from rvdiag.dynamics import prepare
from rvdiag.dynamics.linear import static_equilibrium
from rvdiag.errors import ConfigError, ParameterError
from rvdiag.gears.cycloid import closing_offset, modification_clearance, theoretical_curvature_radius
from rvdiag.gears.pin_wear import (MAX_PIN_WEAR_DEPTH, lost_motion, pin_wear_profile, pin_wear_table,
                                   table_function)
from rvdiag.gears.wear import DutyCycle
from rvdiag.params import ReducerParams

from conftest import REPO, assert_forces_are_minus_gradient, run_cli

P0 = ReducerParams.default()
S2 = P0.stage2
ZP, ZC, RP, E, R = S2.pins, S2.cycloid_lobes, S2.pin_circle_radius, S2.eccentricity, S2.pin_radius
K1 = E * ZP / RP
AS = 180.0 / math.pi * 3600.0
WORN = P0.replace(stage2={"pin_wear_depth": 5e-6})


@pytest.fixture(autouse=True, scope="module")
def _kernels_loaded_callees_first():
    """Load the kernels the way a simulation does first (as tests/test_cycloid_modification.py), so that later
    test files in the same process keep their bits."""
    mdl.load_kernels(prepare(P0, output_speed_deg_s=45.0))


def test_archard_depth_against_a_hand_calculation():
    """Unmodified discs (every pin of the loaded half touches): the load is shared in proportion to the arm,
    F = T_d a / (e Zc sum a^2) (Blagojevic et al. 2011, eq. 11); after N output revolutions, too few for the run-in
    to move the loads, a disc flank point has worn N Zp k (F / b) (L - r) rho_0 / (L (rho_0 - r)) and the pin, away
    from the edge of its arc, N k (F / b) (L - r) / (r |dpsi/deta|) from each of the two phases that touch its point
    (psi = atan2(K1 sin eta, 1 - K1 cos eta)).  A reversing duty (2 flanks) gives each flank half of it."""
    p = P0.replace(stage2={"equidistant_modification": 0.0, "offset_modification": 0.0})
    k, hours, duty = 1e-18, 1.0, DutyCycle(90.0, 167.0)
    w = pin_wear_profile(p, hours, duty, k, flanks=1, points_per_pitch=256)  # the light loads' Hertz patches are
    # narrow: the default 64 phases per pin pitch sum the pin's wear within 2 % here, 256 within 0.3 %
    n_rev = 90.0 / 360.0 * 3600.0 * hours
    t_d = 167.0 * (1.0 - 1.0 / p.ratio) * ZC / (ZP * S2.n_discs)
    b = S2.cycloid_face_width

    def arm(eta):
        return math.sin(eta) / math.sqrt(1.0 + K1 * K1 - 2.0 * K1 * math.cos(eta))

    def force(eta):  # the pins of eta's crank angle: eta + 2 pi j / Zp on the loaded half
        etas = (eta + 2.0 * math.pi * np.arange(ZP) / ZP) % (2.0 * math.pi)
        a = np.array([arm(x) for x in etas])
        return t_d * arm(eta) / (E * ZC * np.sum(a[a > 0] ** 2))

    def psi(eta):
        return math.atan2(K1 * math.sin(eta), 1.0 - K1 * math.cos(eta))

    def pin_pass(eta):  # one crossing of the pin point touched at eta, per output revolution
        h = 1e-6
        dpsi = abs(psi(eta + h) - psi(eta - h)) / (2 * h)
        return k * force(eta) / b * (RP * math.sqrt(1 + K1 * K1 - 2 * K1 * math.cos(eta)) - R) / (R * dpsi)

    eta_edge = math.acos(K1)
    for deg in (18.0, 54.0, 81.0):  # on the phase grid (360 / (Zp 256) = 0.03515625 deg)
        eta = math.radians(deg)
        s = math.sqrt(1.0 + K1 * K1 - 2.0 * K1 * math.cos(eta))
        rho0 = float(theoretical_curvature_radius(np.array([eta]), RP, K1, ZP)[0])
        disc = n_rev * ZP * k * force(eta) / b * (RP * s - R) * rho0 / (RP * s * (rho0 - R))
        lo, hi = (eta_edge, math.pi - 1e-9) if eta < eta_edge else (1e-9, eta_edge)
        twin = brentq(lambda x: psi(x) - psi(eta), lo, hi)  # the other phase that touches the same pin point
        pin = n_rev * (pin_pass(eta) + pin_pass(twin))
        i = int(np.argmin(np.abs(w.eta - eta)))
        assert abs(w.eta[i] - eta) < 1e-9  # the grid holds these phases
        assert w.disc[i] == pytest.approx(disc, rel=1e-6)
        assert w.pin[i] == pytest.approx(pin, rel=0.01)  # the Hertz patch smooths the pin's wear (a ~ 10 um)
    w2 = pin_wear_profile(p, hours, duty, k, flanks=2, points_per_pitch=256)
    np.testing.assert_allclose(w2.disc, 0.5 * w.disc, rtol=1e-6)


def test_the_pin_wears_most_at_the_edge_of_its_arc():
    """The contact dwells where the pin's arc turns back (cos eta = K1): the pin's deepest wear is there, the edge
    of its contact area, as measured on an RV reducer (Lubricants 13(8):362, 2025); the disc's stays below it."""
    w = pin_wear_profile(P0, 600.0, DutyCycle(90.0, 167.0), 1e-18, flanks=1)
    edge = R * math.asin(K1)
    assert abs(w.pin_arc[np.argmax(w.pin_depth)] - edge) < 30e-6
    assert w.pin_depth.max() > 1.5 * w.disc.max()


def test_lost_motion_grows_monotonically_with_the_depth():
    """The stage's geometric lost motion (the closing rotations of both flanks) grows strictly with the depth, by at
    most 2 depth / (e Zc) (the depth at the pin of the largest arm), and the model's own static hysteresis test
    (TE at +T minus TE at -T, the disc carried across the clearance) grows with it by that and up to 20 % more (the
    worn stage's elastic twist at +-T: 13.1 against 11.6 arcsec at 2 um)."""
    depths = [0.0, 0.5e-6, 1e-6, 2e-6, 5e-6, 10e-6]
    geo = [lost_motion(P0, pin_wear_table(P0, d)) for d in depths]
    assert geo[0] == pytest.approx(lost_motion(P0)) and geo[0] * AS == pytest.approx(60.6, abs=0.1)
    assert np.all(np.diff(geo) > 0)
    assert np.all(np.array(geo) - geo[0] <= 2.0 * np.array(depths) / (E * ZC) + 1e-15)

    def static_lm(depth):
        m = prepare(P0.replace(stage2={"pin_wear_depth": depth}), output_speed_deg_s=45.0, load_Nm=5.0)
        im, ih, i = m.rotor_index, m.names.index("carrier.th"), P0.ratio
        qa = static_equilibrium(m, 0.0)
        qb = static_equilibrium(m.with_P(TLOAD=-5.0, TDRIVE=-5.0 / i), 0.0)
        return (qa[im] / i - qa[ih]) - (qb[im] / i - qb[ih])

    lm = [static_lm(d) for d in (0.0, 2e-6, 5e-6)]
    assert lm[0] < lm[1] < lm[2]
    for d, got in zip((2e-6, 5e-6), lm[1:]):
        want = lost_motion(P0, pin_wear_table(P0, d)) - geo[0]
        assert want < got - lm[0] < 1.2 * want  # and a little more: fewer pins touch at +-5 N m, a softer stage


def test_kernel_clearance_row_adds_the_table():
    """geo[g, 3, k] of a worn stage is the modification's clearance (closed with the wear) plus the table at
    cos(eta_k), and the closing rotation takes the worn clearance up on the loaded half."""
    m = prepare(WORN, output_speed_deg_s=45.0, load_Nm=100.0)
    table = pin_wear_table(WORN)
    w0 = int(m.P[kn.I_PINWEAR])
    np.testing.assert_array_equal(m.P[w0:w0 + int(m.P[kn.I_NPINWEAR])], table)
    close = -closing_offset(K1, 4e-6, -3e-6, 1, extra=table_function(table))
    assert m.P[kn.I_CLOSE] == pytest.approx(close) and abs(close) > abs(closing_offset(K1, 4e-6, -3e-6, 1)) + 1e-7
    geo, rot, _ = mdl.work_arrays(m)
    for t in (0.0, 0.0123, 0.31):
        kn.pin_geometry(t, m.P, m.cosk, m.sink, geo, rot)
        for j in range(1 if m.P[kn.I_GSHARED] else m.n_discs):
            eta = 2.0 * math.pi * np.arange(ZP) / ZP - math.atan2(rot[j, 3], rot[j, 2])
            want = (modification_clearance(np.cos(eta), np.sin(eta), K1, 4e-6, -3e-6, m.P[kn.I_CLOSE])
                    + table_function(table)(np.cos(eta)))
            np.testing.assert_allclose(geo[j, 3], want, rtol=0, atol=1e-14)
            assert geo[j, 3].min() > -1e-12  # no pin interferes


def test_zero_wear_is_the_unworn_model_to_the_bit():
    """A zero depth packs nothing (the same P as the default reducer), and a table of zeros forced through the wear's
    code path gives the unworn model's signal to the last bit in the same run; 5 um changes it.  Unstated, the depth
    stays out of the parameters' dict (every earlier store's parameter hash stays)."""
    assert "pin_wear_depth" not in P0.to_dict()["stage2"] and P0.stage2.pin_wear_depth is None
    kw = dict(output_speed_deg_s=45.0, load_Nm=167.0)
    m0 = prepare(P0, **kw)
    np.testing.assert_array_equal(prepare(P0.replace(stage2={"pin_wear_depth": 0.0}), **kw).P, m0.P)
    assert m0.P[kn.I_PINWEAR] == 0.0
    zeros = mdl._replace_P(m0, np.concatenate([m0.P, np.zeros(9)]))
    zeros.P[kn.I_PINWEAR], zeros.P[kn.I_NPINWEAR] = float(m0.P.size), 9.0
    from rvdiag.dynamics.integrate import integrate

    y0 = m0.initial_state(static_equilibrium(m0, 0.0), 0.0)
    a, _ = integrate(m0, y0, 48000.0, 480)
    b, _ = integrate(zeros, y0, 48000.0, 480)
    np.testing.assert_array_equal(a, b)
    c, _ = integrate(prepare(WORN, **kw), y0, 48000.0, 480)
    assert np.max(np.abs(c - a)) > 1e-3 * np.max(np.abs(a))


def test_forces_are_minus_gradient_of_the_potential_with_wear():
    """M a(v = 0) of the compiled kernels equals -dV/dq of the NumPy potential (linear.potential_energy reads the
    table with numpy's interpolation) for a stage worn 20 um, for both load senses, and the wear changes the
    forces."""
    rng = np.random.default_rng(7)
    st = mdl.ModelSettings(damping=False)
    worn = P0.replace(stage2={"pin_wear_depth": 20e-6})
    for load in (100.0, -100.0):
        m = prepare(worn, output_speed_deg_s=45.0, load_Nm=load, settings=st)
        assert_forces_are_minus_gradient(m, prepare(P0, output_speed_deg_s=45.0, load_Nm=load, settings=st), 0.21,
                                         rng, rtol=2e-6)  # the differences' rounding: up to 1.1e-6 at 20 um


def test_bad_depths_are_one_line_errors(tmp_path):
    for bad in (-1e-6, math.nan, math.inf, 2 * MAX_PIN_WEAR_DEPTH):
        with pytest.raises((ParameterError, ConfigError)) as exc:
            prepare(P0.replace(stage2={"pin_wear_depth": bad}), output_speed_deg_s=45.0)
        assert "pin_wear_depth" in str(exc.value) and "\n" not in str(exc.value)
    with pytest.raises(ParameterError, match="flanks"):
        pin_wear_profile(P0, 10.0, DutyCycle(30.0, 100.0), 1e-18, flanks=3)
    with pytest.raises(ParameterError, match="hours"):
        pin_wear_profile(P0, -1.0, DutyCycle(30.0, 100.0), 1e-18)


def test_cli_route(tmp_path, capsys):
    """``rvdiag simulate --pin-wear-depth MM`` records the depth in the result's parameters; a bad value, or a bad
    ``[stage2] pin_wear_depth`` in a parameter file, is one ``error:`` line with exit code 2 and writes nothing."""
    out = tmp_path / "r.npz"
    base = ["simulate", "--output-speed", "45", "--duration", "0.005", "--transient", "0.005", "--quiet", "-o", out]
    code, _, err = run_cli(base + ["--pin-wear-depth", "0.002"], capsys)
    assert code == 0, err
    with np.load(out) as z:
        assert json.loads(str(z["settings"]))["params"]["stage2"]["pin_wear_depth"] == pytest.approx(2e-6)
    out.unlink()
    bad = tmp_path / "bad.toml"
    text = P0.to_toml()
    assert "pin_wear_depth" not in text and text.count("[stage2]\n") == 1
    for extra, value in ((["--pin-wear-depth", "-0.001"], None), (["--pin-wear-depth", "0.5"], None),
                         (["--pin-wear-depth", "nan"], None), (["--params", bad], "-1e-6"), (["--params", bad], "1.0")):
        name = "--pin-wear-depth" if value is None else "pin_wear_depth"
        if value is not None:
            bad.write_text(text.replace("[stage2]\n", f"[stage2]\npin_wear_depth = {value}\n"))
        code, _, err = run_cli(base + extra, capsys)
        assert code == 2 and err.startswith("error:") and err.count("\n") == 1 and name in err, err
        assert not out.exists()


def test_gpu_ensemble_carries_the_wear():
    """The GPU ensemble (``rvdiag library build --device cuda``) under numba's CUDA simulator, in a child process (as
    tests/test_gpu_ensemble.py): worn and unworn models in one call equal integrate() bit for bit, the worn P (with
    its table) in a group of its own.  A GPU's own arithmetic is bench/gpu_ensemble.py's to report."""
    code = textwrap.dedent("""
        import json
        import numpy as np
        from rvdiag.dynamics import ModelSettings, prepare
        from rvdiag.dynamics.ensemble import IntegrationRequest, integrate_ensemble
        from rvdiag.dynamics.integrate import integrate
        from rvdiag.dynamics.linear import static_equilibrium
        from rvdiag.params import ReducerParams

        fs, st, p = 48000.0, ModelSettings(substeps=4, chunk_samples=20), ReducerParams.default()
        reqs = []
        for d in (0.0, 5e-6, 2e-6):
            m = prepare(p.replace(stage2={"pin_wear_depth": d}), output_speed_deg_s=45.0, settings=st)
            reqs.append(IntegrationRequest(m, m.initial_state(static_equilibrium(m, -10 / fs), -10 / fs), fs, 40, 10))
        out = integrate_ensemble(reqs)
        equal = [bool(np.array_equal(integrate(r.model, r.y0, fs, 40, 10)[0], o[0])) for r, o in zip(reqs, out)]
        print(json.dumps({"equal": equal, "differs": bool(np.max(np.abs(out[1][0] - out[0][0])) > 0)}))
    """)
    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1", "PYTHONPATH": str(REPO / "src")}
    proc = subprocess.run([sys.executable, "-c", code], env=env, cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-4000:]
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    assert res == {"equal": [True, True, True], "differs": True}


def _library(randomise=None, **top):
    """A small synthetic-simulator library config (the draws and columns do not depend on the simulator)."""
    from rvdiag.library import LibraryConfig

    data = {"mode": "split-by-simulation", "seed": 5, "simulator": "rvdiag.library.synthetic:simulate",
            "signal": {"fs": 4000.0, "duration_s": 0.2, "transient_s": 0.02, "segment_length": 400, "hop": 400},
            "operation": {"input_speed_rpm": {"min": 1000.0, "max": 2000.0}, "load_Nm": [50.0, 100.0]},
            "randomise": {"stiffness_pct": 5.0, **(randomise or {})},
            "split": {"simulations_per_state": 3, "test_simulations_per_state": 1},
            "states": {"T1": {}, "T2": {}}, **top}
    return LibraryConfig.from_dict(data, source="pins.toml")


def test_library_draws_the_stage_wear_per_simulation(tmp_path):
    """``[randomise] pin_wear_depth`` draws the stage's wear per simulation after every other draw (a config
    without it plans the same units and keeps its hash), puts it into the unit's reducer and records the column;
    out of range, or in a paired library, it is one ConfigError line."""
    from rvdiag.datasets import SampleStore
    from rvdiag.library import build_library, make_plan
    from rvdiag.library.build import Job, stored_config, unit_params

    plain, worn = _library(), _library({"pin_wear_depth": {"min": 0.0, "max": 5e-6}})
    assert "pin_wear_depth" not in plain.to_dict()["randomise"]
    a, b = make_plan(plain), make_plan(worn)
    depths = [u.pin_wear_depth for u in b]
    assert all(u.pin_wear_depth is None for u in a) and all(0.0 <= d <= 5e-6 for d in depths)
    assert len(set(depths)) == len(depths)
    for ua, ub in zip(a, b):  # every other draw as before
        assert (ua.severity, ua.speed, ua.load_Nm, ua.scales) == (ub.severity, ub.speed, ub.load_Nm, ub.scales)
    params = unit_params(b[0], Job.from_config(worn, worn.reducer_params()))
    assert params.stage2.pin_wear_depth == depths[0]
    assert stored_config(plain, plain.reducer_params()) != stored_config(worn, worn.reducer_params())
    build_library(worn, tmp_path / "w.zarr", workers=0, progress=False)
    d = SampleStore.open(tmp_path / "w.zarr").load()
    for u in b:
        assert set(d.meta["pin_wear_depth"][d.meta["unit"] == u.index].tolist()) == {u.pin_wear_depth}
    for bad, match in (({"pin_wear_depth": {"min": 0.0, "max": 1e-3}}, "must lie in"),
                       ({"pin_wear_depth": -1e-6}, "must lie in")):
        with pytest.raises(ConfigError, match=match) as exc:
            _library(bad)
        assert "\n" not in str(exc.value) and "[randomise] pin_wear_depth" in str(exc.value)
    with pytest.raises(ConfigError, match="paired or life-history"):
        _library({"pin_wear_depth": 1e-6}, mode="split-by-simulation",
                 operation={"output_speed_deg_s": 45.0, "load_Nm": 90.0},
                 baseline={"operating_points": [[45.0, 90.0]]}, split={"reducers": 4, "test_reducers": 2})


def test_the_load_reversed_static_solution_converges_at_every_crank_angle():
    """The static hysteresis test carries the disc across its clearance; where full Newton steps keep switching the
    same pins (5.0 * 1e-6 m, one unit in the last place from 5e-6, at +-5.01 N m did at the second of these angles on
    the development machine, where 5e-6 or +-5 N m did not), the
    damped restart of linear.static_equilibrium converges: the lost motion at 5 crank angles across a pin pitch is
    one value within 3 arcsec (100.3 arcsec)."""
    p = P0.replace(stage2={"pin_wear_depth": 5.0 * 1e-6})
    T = 0.03 * 167.0  # 3 % of the rated torque, research/pin_wear.py's test load
    m = prepare(p, output_speed_deg_s=30.0, load_Nm=T)
    im, ih, i = m.rotor_index, m.names.index("carrier.th"), P0.ratio
    f_cs = ZC * ZP * 30.0 / 360.0
    lm = []
    for t in np.linspace(0.0, 1.0 / f_cs, 5, endpoint=False):
        qa = static_equilibrium(m, t)
        qb = static_equilibrium(m.with_P(TLOAD=-T, TDRIVE=-T / i), t)
        lm.append(((qa[im] / i - qa[ih]) - (qb[im] / i - qb[ih])) * AS)
    assert np.ptp(lm) < 3.0 and np.mean(lm) == pytest.approx(100.3, abs=1.0)
