"""The compiled RK4 integrator: agreement with scipy, streaming, determinism, energy, instability."""

from __future__ import annotations

import dataclasses
import os
import tracemalloc

import numpy as np
import pytest
from numpy.testing import assert_array_equal
from scipy.integrate import solve_ivp

from rvdiag.dynamics import ModelSettings, prepare, simulate
from rvdiag.dynamics import model as mdl
from rvdiag.dynamics.integrate import integrate
from rvdiag.dynamics.linear import static_equilibrium, total_energy
from rvdiag.errors import ParameterError, SimulationError
from rvdiag.params import ReducerParams

P0 = ReducerParams.default()


@pytest.fixture(scope="module")
def dop853_reference():
    """Sensor signal of solve_ivp DOP853 (rtol 1e-9) on the compiled right-hand side, 0.05 s at 48 kHz,
    45 deg/s, 100 N m, from the static solution (its own error: 3e-8 against rtol 1e-11)."""
    fs, T = 48000.0, 0.05
    m = prepare(P0, output_speed_deg_s=45.0, load_Nm=100.0)
    q0 = static_equilibrium(m, 0.0)
    y0 = np.concatenate([q0, np.zeros_like(q0)])
    n = int(round(T * fs))
    f = mdl.make_rhs(m)
    te = np.arange(n) / fs
    sol = solve_ivp(f, (0.0, te[-1]), y0, method="DOP853", rtol=1e-9, atol=1e-15, t_eval=te)
    assert sol.status == 0
    acc = np.array([f(t, sol.y[:, k])[m.n_dof:] for k, t in enumerate(te)])
    return y0, fs, n, mdl.sensor_acceleration(m, acc)


def _rel_err(settings: ModelSettings, ref) -> float:
    y0, fs, n, sig_ref = ref
    m = prepare(P0, output_speed_deg_s=45.0, load_Nm=100.0, settings=settings)
    sig, _ = integrate(m, y0, fs, n)
    return float(np.linalg.norm(sig - sig_ref) / np.linalg.norm(sig_ref))


def test_matches_scipy_dop853_over_50ms(dop853_reference):
    """Default settings (48 kHz, Kutta's 3/8 rule, 9 sub-steps) against solve_ivp DOP853, rtol 1e-9, on the
    same right-hand side, with the default tooth-pair separations (relief, ISO 1328 grade 5): relative L2
    error of the sensor signal below 1e-3 (measured 6.2e-4; docs/model.md section 7).  Higher-order and
    low-dispersion schemes do not do better per right-hand side."""
    assert ModelSettings().method == "rk38"
    err = _rel_err(ModelSettings(), dop853_reference)
    assert err < 1e-3, err


def test_rk4_option_matches_scipy_dop853(dop853_reference):
    """Classical RK4 (``method="rk4"``, the same event-cut step grid) at 9 sub-steps: 3.5e-3 here with the
    tooth-pair contacts, 6.2e-4 at 18 (an option for speed at low input speeds, not the default)."""
    err = _rel_err(ModelSettings(method="rk4", substeps=18), dop853_reference)
    assert err < 1e-3, err


def test_method_is_validated():
    with pytest.raises(ParameterError, match="method"):
        ModelSettings(method="euler")


@pytest.mark.parametrize("method", ["rk4", "rk38"])
def test_chunking_and_repetition_give_identical_output(method):
    kw = dict(output_speed_deg_s=30.0, load_Nm=80.0, duration_s=0.01, fs=24000.0)
    a = simulate(P0, settings=ModelSettings(transient_s=0.002, chunk_samples=7, method=method), **kw)
    b = simulate(P0, settings=ModelSettings(transient_s=0.002, chunk_samples=100000, method=method), **kw)
    c = simulate(P0, settings=ModelSettings(transient_s=0.002, chunk_samples=7, method=method), **kw)
    assert a.signal.shape == (2, 240)
    assert_array_equal(a.signal, b.signal)
    assert_array_equal(a.signal, c.signal)
    assert np.std(a.signal) > 0


_FRESH_VS_CACHED = """
import sys
import numpy as np
from rvdiag.dynamics import ModelSettings, simulate
from rvdiag.gears import ToothFaults
fault = ToothFaults.for_state("T6", broken_fraction=0.5, wear_depth=10e-6, crack_depth=1.8e-3)
r = simulate(None, fault, duration_s=0.01, input_speed_rpm=3000.0, load_Nm=50.0,
             settings=ModelSettings(transient_s=0.005))
np.save(sys.argv[1], r.signal)
"""


def test_output_is_identical_from_a_fresh_compile_and_from_the_cache(tmp_path):
    """A process that compiles the kernels and one that loads them from numba's cache give the same bits.

    Without ``model.load_kernels`` (its flags set beforehand) they differ by 2e-12 relative here (T6 at
    3000 rpm: the broken-tooth impacts amplify last-bit differences), because a cache-loaded caller binds
    its calls to its private copy of each callee.  Two fresh interpreters share an empty
    ``NUMBA_CACHE_DIR``: the first compiles (~10 s), the second loads.
    """
    import subprocess
    import sys

    script = tmp_path / "run.py"
    script.write_text(_FRESH_VS_CACHED)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba_cache")}
    outs = []
    for name in ("compiled", "cached"):
        out = tmp_path / f"{name}.npy"
        subprocess.run([sys.executable, str(script), str(out)], env=env, check=True, timeout=600)
        outs.append(np.load(out))
    assert outs[0].shape == (2, 480) and np.std(outs[0]) > 0
    assert_array_equal(outs[0], outs[1])


def test_noise_is_seeded():
    kw = dict(output_speed_deg_s=30.0, duration_s=0.005, fs=12000.0,
              settings=ModelSettings(transient_s=0.001, substeps=20))
    a = simulate(P0, noise_snr_db=10.0, seed=4, **kw)
    b = simulate(P0, noise_snr_db=10.0, seed=4, **kw)
    c = simulate(P0, noise_snr_db=10.0, seed=5, **kw)
    clean = simulate(P0, **kw)
    assert_array_equal(a.signal, b.signal)
    assert not np.array_equal(a.signal, c.signal)
    snr = 10 * np.log10(np.mean(clean.signal**2, axis=1) / np.mean((a.signal - clean.signal) ** 2, axis=1))
    assert np.all(np.abs(snr - 10.0) < 1.0)


def test_memory_stays_flat():
    """No sub-step history: peak allocation is the output plus a small constant, not fs * substeps * state."""
    kw = dict(output_speed_deg_s=30.0, fs=48000.0, settings=ModelSettings(transient_s=0.0, chunk_samples=4800))
    simulate(P0, duration_s=0.001, **kw)
    tracemalloc.start()
    res = simulate(P0, duration_s=0.5, **kw)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    out_bytes = res.signal.nbytes  # 384 kB; a sub-step history would be ~100 MB
    assert peak < 3 * out_bytes + 2_000_000, peak


@pytest.mark.parametrize("method", ["rk4", "rk38"])
def test_too_few_substeps_raise_instability_error_with_remedy(method):
    with pytest.raises(SimulationError, match=r"(?s)unstable.*sub-steps.*Remedy: increase the sub-steps"):
        simulate(P0, output_speed_deg_s=30.0, duration_s=0.01, fs=48000.0,
                 settings=ModelSettings(substeps=1, transient_s=0.0, method=method))


def _energy_drift(substeps: int, method: str = "rk4") -> float:
    """Relative change of the Jacobi integral over 5 ms, damping and time variation off."""
    st = ModelSettings(substeps=substeps, damping=False, excitation=False, transient_s=0.0, method=method)
    m = prepare(P0, output_speed_deg_s=45.0, load_Nm=100.0, settings=st)
    q0 = static_equilibrium(m, 0.0)
    rng = np.random.default_rng(1)
    v0 = 1e-3 * rng.standard_normal(m.n_dof) / np.sqrt(m.mass / m.mass.min())
    y0 = np.concatenate([q0, v0])
    e0 = total_energy(m, 0.0, y0)
    kin0 = 0.5 * np.sum(m.mass * v0**2)
    _, y1 = integrate(m, y0, 48000.0, 240)
    return abs(total_energy(m, 0.005, y1) - e0) / kin0


def test_energy_conserved_without_damping_and_excitation():
    """T + V (rotating frame: Coriolis does no work) is constant to integrator accuracy: the drift falls
    at least as h^4 (RK4's order; measured ~h^5: 4.9e-4, 1.6e-5, 2.6e-7 at 20, 40, 80 sub-steps; the
    random start puts most energy in the 20-34 kHz modes, which RK4 damps numerically at large h)."""
    d20, d40, d80 = (_energy_drift(s) for s in (20, 40, 80))
    # the order is checked between 20 and 40 sub-steps; at 80 the drift (~2.6e-7) is at the level where
    # rounding of the impacting contacts moves it by its own size, so only its magnitude is checked
    assert d20 / d40 > 16, (d20, d40)
    assert d80 < 1e-5 and d80 < d40, (d40, d80)


def test_energy_conserved_with_rk38():
    """The 3/8 rule has RK4's order and stability polynomial: the drift falls at least as h^4 too."""
    d20, d40 = (_energy_drift(s, "rk38") for s in (20, 40))
    assert d20 / d40 > 16, (d20, d40)
    assert d40 < 1e-4, d40


def _rk4_exact_terms(m, y0, fs, n, S):
    """Textbook RK4 on ``make_rhs`` (pin geometry and mesh terms evaluated exactly at every stage) on the
    integrator's step grid (table events included), sensor output read like the integrator's: the
    reference for the per-sample geometry interpolation."""
    from rvdiag.dynamics.integrate import sample_breaks, step_grid

    f = mdl.make_rhs(m)
    dts = 1.0 / fs
    f_rel = m.P[mdl.I_WREL] / (2 * np.pi)
    breaks, grid = np.zeros(64), np.zeros(S + 66)
    y = y0.copy()
    out = np.zeros((m.sensor.shape[0], n))
    for k in range(n):
        t0, t_end = k * dts, (k + 1) * dts
        nb = sample_breaks(t0, dts, f_rel, m.events, 1e-6 * dts / S, breaks)
        M = step_grid(t0, t_end, S, dts / S, breaks, nb, grid)
        for j in range(M):
            t, h = grid[j], grid[j + 1] - grid[j]
            k1 = f(t, y)
            if j == 0:
                out[:, k] = mdl.sensor_acceleration(m, k1[m.n_dof:])
            k2 = f(t + h / 2, y + h / 2 * k1)
            k3 = f(t + h / 2, y + h / 2 * k2)
            k4 = f(t + h, y + h * k3)
            y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return out


@pytest.mark.parametrize("rpm", [1000.0, 3000.0])
def test_interpolated_pin_geometry_changes_the_output_by_less_than_1e6(rpm):
    """The integrator evaluates the pin geometry exactly three times per sample and interpolates it
    (quadratic) at the other stage times; against RK4 with the exact geometry at every stage the
    output moves by < 1e-6 relative (measured 1.5e-8 at 1000 rpm and 1.9e-7 at 3000 rpm over 50 ms;
    linear interpolation gave 1.2e-4 and 5.6e-4, bench/HISTORY.md 2026-11-23)."""
    m = prepare(P0, input_speed_rpm=rpm, load_Nm=50.0, settings=ModelSettings(method="rk4"))
    q0 = static_equilibrium(m, 0.0)
    y0 = np.concatenate([q0, np.zeros_like(q0)])
    fs, n = 48000.0, 96
    ref = _rk4_exact_terms(m, y0, fs, n, m.settings.substeps)
    sig, _ = integrate(m, y0, fs, n)
    err = np.linalg.norm(sig - ref) / np.linalg.norm(ref)
    assert err < 1e-6, err


def test_steps_are_cut_at_the_mesh_table_events():
    """The stiffness ramps (tooth pairs entering and leaving) are known in advance; the integrator puts
    step boundaries there.  Every event falls on a step boundary, the grid is ordered and covers the
    sample, and no step is longer than the nominal one."""
    from rvdiag.dynamics.integrate import sample_breaks, step_grid

    m = prepare(P0, input_speed_rpm=3000.0)
    fs, S = 48000.0, 9
    dts = 1.0 / fs
    f_rel = m.P[mdl.I_WREL] / (2 * np.pi)
    breaks, grid = np.zeros(64), np.zeros(S + 66)
    found = 0
    for k in range(2000):
        t0 = k * dts
        nb = sample_breaks(t0, dts, f_rel, m.events, 1e-6 * dts / S, breaks)
        M = step_grid(t0, (k + 1) * dts, S, dts / S, breaks, nb, grid)
        g = grid[:M + 1]
        assert g[0] == t0 and g[-1] == (k + 1) * dts and np.all(np.diff(g) > 0)
        assert np.diff(g).max() <= dts / S * (1 + 1e-9)
        assert S <= M <= S + nb
        for te in breaks[:nb]:
            assert np.min(np.abs(g - te)) < 1e-15
            phase = (te * f_rel) % 1.0
            assert np.min(np.abs((m.events - phase + 0.5) % 1.0 - 0.5)) < 1e-9
        found += nb
    # every event phase passes once per relative revolution; those on a sample boundary need no cut
    span = 2000 * dts
    times = np.sort(np.concatenate([(c + m.events) / f_rel for c in range(int(span * f_rel) + 2)]))
    times = times[times < span]
    inside = np.abs((times * fs + 0.5) % 1.0 - 0.5) > 1e-6
    assert found == int(inside.sum()) > 50


def test_table_events_are_the_path_ends_and_the_corner_handovers():
    """Healthy RV-20E table: the kinks are where each tooth pair's path of contact starts or ends (the stiffness's
    slope changes there: the extended contact carries the end value on; the last node of the path at each end, 11
    teeth: 22 nodes, each beside a ramp of the table without extended contact), and where a slot hands over from one pair's corner contact
    to the next's, far off the path, at a separation of over 100 um that no mesh approaches; both planets see
    them half a revolution apart; everything else in the table is smooth."""
    m = prepare(P0, input_speed_rpm=1000.0)
    bare = prepare(dataclasses.replace(P0, modification=dataclasses.replace(
        P0.modification, extended_contact_separation=0.0)), input_speed_rpm=1000.0)
    S = int(m.P[mdl.I_NSLOT])
    kbar = m.tvms.mean()
    big_all, ends_all = [], []
    for s_ in range(S):
        k, kb, e = m.tables[s_], bare.tables[s_], m.tables[S + s_]
        d2 = np.abs(np.roll(k, -1) - 2 * k + np.roll(k, 1)) / kbar
        big = np.flatnonzero(d2 > mdl.EVENT_STIFFNESS_KINK)
        assert d2[d2 <= mdl.EVENT_STIFFNESS_KINK].max() < 1e-4
        ends = np.flatnonzero((kb > 0) & ((np.roll(kb, 1) == 0) | (np.roll(kb, -1) == 0)))
        handover = np.setdiff1d(big, ends)
        assert np.all(np.isin(ends, big))
        # a hand-over: the stiffness steps between neighbours, where the separation is large or a pair ends
        near = np.maximum(np.maximum(e[handover], np.roll(e, 1)[handover]), np.roll(e, -1)[handover])
        assert np.all(near > 100e-6), near
        big_all.append(big)
        ends_all.append(ends)
    assert np.unique(np.concatenate(ends_all)).size == 22
    big = np.unique(np.concatenate(big_all))
    n = m.tables.shape[1]
    expect = np.unique(np.concatenate([big / n, (big / n + 0.5) % 1.0]))
    assert_array_equal(m.events, expect)


@pytest.mark.parametrize("method", ["rk38"])
def test_high_speed_matches_scipy_within_1e3(method):
    """4500 rpm, 50 N m: one table cell lasts ~1.3 sub-steps, so a step that straddles a stiffness ramp
    used to cost accuracy (9 sub-steps, before / after the steps were cut at the table events: RK4
    2.6e-3 / 7.3e-4, 3/8 rule 1.7e-3 / 6.7e-4; bench/HISTORY.md 2026-11-23).  With the tooth-pair contacts
    the 3/8 rule (the default) gives 7.3e-4 and RK4 2.2e-3 (RK4 is an option for low speeds: 9.0e-4 at
    1000 rpm; docs/model.md section 7)."""
    m = prepare(P0, input_speed_rpm=4500.0, load_Nm=50.0, settings=ModelSettings(method=method))
    q0 = static_equilibrium(m, 0.0)
    y0 = np.concatenate([q0, np.zeros_like(q0)])
    fs, n = 48000.0, 1200
    f = mdl.make_rhs(m)
    te = np.arange(n) / fs
    sol = solve_ivp(f, (0.0, te[-1]), y0, method="DOP853", rtol=1e-9, atol=1e-15, t_eval=te)
    ref = mdl.sensor_acceleration(m, np.array([f(t, sol.y[:, k])[m.n_dof:] for k, t in enumerate(te)]))
    sig, _ = integrate(m, y0, fs, n)
    err = float(np.linalg.norm(sig - ref) / np.linalg.norm(ref))
    assert err < 1e-3, err
