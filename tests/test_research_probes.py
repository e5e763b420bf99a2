"""The accuracy probe behind bench/HISTORY.md's "fifth pass" (``research/pin_events_probe.py``).

Its figures rest on two properties checked here: the mode-locked right-hand side is the model's own when
the mode is the real contact state, and located switches leave the RK4 result where it was (they only
move where steps fall), so a higher-order scheme's numbers in the probe measure that scheme.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from rvdiag.dynamics import prepare
from rvdiag.dynamics import model as mdl
from rvdiag.dynamics.integrate import integrate
from rvdiag.dynamics.linear import static_equilibrium

RESEARCH = Path(__file__).resolve().parents[1] / "research"
PROBE = RESEARCH / "pin_events_probe.py"


@pytest.fixture(scope="module")
def probe():
    spec = importlib.util.spec_from_file_location("pin_events_probe", PROBE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def case():
    m = prepare(input_speed_rpm=1000.0)
    q0 = static_equilibrium(m, 0.0)
    P = m.P.copy()
    P[mdl.I_BILATERAL] = 1.0
    P[mdl.I_GSHARED] = 0.0
    return m, P, np.concatenate([q0, np.zeros_like(q0)])


def test_mode_locked_rhs_is_the_model_rhs_in_the_real_contact_state(probe, case):
    m, P, y0 = case
    rng = np.random.default_rng(3)
    f = mdl.make_rhs(m)
    D, nz = m.n_discs, m.cosk.size
    geo, rot = np.zeros((D, 3, nz)), np.zeros((D, 4))
    d = np.zeros((D, nz))
    n = m.n_dof
    for t in (0.0013, 0.0421, 0.2):
        y = y0 + np.concatenate([1e-7 * rng.standard_normal(n), 1e-3 * rng.standard_normal(n)])
        probe.contact_indicators(t, y, P, m.cosk, m.sink, geo, rot, d)
        mode = (d > 0).astype(np.int64)
        assert 0 < mode.sum() < mode.size  # some pins open, some closed
        out = np.zeros(2 * n)
        probe.rhs_in_mode(t, y, P, m.inv_mass, m.planet, m.tables, m.cosk, m.sink, geo, rot,
                          np.zeros((m.n_planets, 3)), np.zeros(n), out, mode)
        ref = f(t, y)
        assert np.max(np.abs(out - ref)) <= 1e-12 * np.max(np.abs(ref))
        # and a wrong mode is visible: one closed pin opened
        j, k = np.argwhere(mode == 1)[0]
        mode[j, k] = 0
        probe.rhs_in_mode(t, y, P, m.inv_mass, m.planet, m.tables, m.cosk, m.sink, geo, rot,
                          np.zeros((m.n_planets, 3)), np.zeros(n), out, mode)
        assert np.max(np.abs(out - ref)) > 1e-9 * np.max(np.abs(ref))


def test_located_switches_leave_rk4_within_its_own_error(probe, case):
    """RK4 at 9 with the switches located against production RK4 at 9 (not located), 10 ms: both are
    6e-4 from scipy over 50 ms, so they must agree to ~1e-3.  With the detection switched off (every pin
    kept in its starting state) the same run is 5.8e-2 away."""
    m, P, y0 = case
    fs, n = 48000.0, 480
    ref, _ = integrate(m, y0, fs, n)
    A, b, c = probe.tableau("rk4")
    out = np.zeros((m.sensor.shape[0], n))
    n_rhs, located, unlocated = probe.run_located(y0.copy(), n, 9, fs, P, m.inv_mass, m.planet, m.tables,
                                                  m.cosk, m.sink, m.sensor, out, m.events, A, b, c)
    assert located >= 5  # switches happen in 10 ms at 1000 rpm
    assert unlocated <= 1
    assert 36 <= n_rhs / n < 40
    err = np.linalg.norm(out - ref) / np.linalg.norm(ref)
    assert err < 1e-3


def test_research_holds_the_probes_and_bench_only_benchmarks():
    probes = {"pin_events_probe.py", "lane_simd_probe.py", "gpu_ensemble_probe.py"}
    assert probes <= {p.name for p in RESEARCH.glob("*.py")}
    assert not [p.name for p in (RESEARCH.parent / "bench").glob("*probe*.py")]
    readme = (RESEARCH / "README.md").read_text()
    assert all(p in readme for p in probes)


def test_gpu_probe_leaves_numpy_alone_on_import():
    import ast

    tree = ast.parse((RESEARCH / "gpu_ensemble_probe.py").read_text())
    module_level = [n for n in tree.body if not isinstance(n, (ast.FunctionDef, ast.Expr))]
    patched = [ast.unparse(n) for n in module_level if "np." in ast.unparse(n) and isinstance(n, ast.Assign)]
    assert patched == []
    before = dict(vars(np))
    spec = importlib.util.spec_from_file_location("gpu_ensemble_probe", RESEARCH / "gpu_ensemble_probe.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # imports without numba-cuda: nothing runs until main()
    assert module.cuda is None and dict(vars(np)) == before
