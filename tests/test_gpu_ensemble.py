"""The GPU path of the library build (``rvdiag library build --device cuda``), checked without a GPU.

numba's CUDA simulator is chosen when numba's CUDA target is first imported, so the checks that launch kernels run
in a child process with ``NUMBA_ENABLE_CUDASIM=1`` (:func:`_in_simulator`).  Under the simulator the kernel and the
ensemble code around it run as written, and the integrator runs as its CPU build on each thread's views
(:mod:`rvdiag.dynamics.gpu`), so the ensemble must equal the CPU path bit for bit: that checks the kernel's
indexing in both layouts, the stacking and padding, the grouping, the chunk loop, the instability status and the
library's post-processing.  It does not check the integrator's device compilation (``bench/gpu_ensemble.py
--ptx``) nor a GPU's arithmetic (``bench/gpu_ensemble.py`` on a GPU reports the difference).

The fallback, option and error checks run in this process, where no simulator is on.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from conftest import REPO, run_cli

from rvdiag.errors import ConfigError, DeviceWarning
from rvdiag.library import LibraryConfig, build_library, make_plan, run_unit
from rvdiag.library.build import Job

#: a tiny library on the dynamic model: three states (their mesh tables have different event counts), 4 ms each
TINY = {
    "mode": "split-by-simulation", "seed": 3, "model": {"substeps": 4, "chunk_samples": 80},
    "signal": {"fs": 48000.0, "duration_s": 0.004, "transient_s": 0.002, "segment_length": 64, "hop": 32},
    "operation": {"input_speed_rpm": {"min": 1000.0, "max": 2000.0}, "load_Nm": [50.0, 100.0],
                  "noise_snr_db": 20.0},
    "randomise": {"stiffness_pct": 10.0},
    "split": {"simulations_per_state": 1, "test_simulations_per_state": 0},
    "states": {"T1": {}, "T2": {"broken_fraction": 1.0}, "T6": {}},
}
SYN = "rvdiag.library.synthetic:simulate"


def _in_simulator(code: str, timeout: float = 300.0) -> dict:
    """Run ``code`` in a child Python with numba's CUDA simulator on; it prints one JSON line, returned."""
    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1",
           "PYTHONPATH": os.pathsep.join([str(REPO / "src"), str(REPO / "tests")])}
    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], env=env, cwd=REPO, capture_output=True,
                          text=True, timeout=timeout)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_ensemble_equals_integrate_in_both_layouts_and_methods():
    """Every integrate() call of an ensemble: equal signal and end state; an unstable simulation gives integrate's
    own error and does not stop the others; a request with another first sample runs in its own group."""
    res = _in_simulator("""
        import json
        import numpy as np
        from rvdiag.dynamics import ModelSettings, prepare
        from rvdiag.dynamics.ensemble import IntegrationRequest, integrate_ensemble
        from rvdiag.dynamics.integrate import integrate
        from rvdiag.dynamics.linear import static_equilibrium
        from rvdiag.errors import SimulationError
        from rvdiag.library.states import FaultSpec

        fs = 48000.0
        report = {}
        for method in ("rk38", "rk4"):
            st = ModelSettings(substeps=4, chunk_samples=40, method=method)
            broken = FaultSpec("T2", {"broken_fraction": 1.0}).to_tooth_faults()
            models = [prepare(input_speed_rpm=1000.0, settings=st),
                      prepare(None, broken, input_speed_rpm=1500.0, load_Nm=60.0, settings=st),
                      prepare(input_speed_rpm=1200.0, settings=ModelSettings(substeps=4, chunk_samples=40,
                                                                             method=method, max_displacement_m=1e-12))]
            reqs = []
            for m in models:
                t = -30 / fs
                reqs.append(IntegrationRequest(m, m.initial_state(static_equilibrium(m, t), t), fs, 100, 30))
            reqs.append(IntegrationRequest(models[0], reqs[0].y0, fs, 50, 30, first_sample=20))
            for layout in ("first", "last"):
                got = integrate_ensemble(reqs, layout=layout)
                same = []
                for r, g in zip(reqs, got):
                    try:
                        ref = integrate(r.model, r.y0, r.fs, r.n_samples, r.n_transient, first_sample=r.first_sample)
                    except SimulationError as exc:
                        same.append(isinstance(g, SimulationError) and str(g) == str(exc))
                        continue
                    same.append(bool(np.array_equal(g[0], ref[0]) and np.array_equal(g[1], ref[1])
                                     and np.abs(ref[0]).max() > 0))
                report[f"{method}/{layout}"] = same
        report["events"] = sorted({int(m.events.size) for m in models})
        print(json.dumps(report))
    """)
    assert len(res.pop("events")) > 1  # the padded event tables are exercised
    assert res == {k: [True, True, True, True] for k in ("rk38/first", "rk38/last", "rk4/first", "rk4/last")}


def test_library_on_the_simulated_gpu_equals_the_cpu_build():
    """`rvdiag library build --device cuda` (ensembles of 2, in this process and as Dask tasks on one worker) writes
    the CPU build's store: the same samples bit for bit and the same metadata; also for a motor-current library
    (record margins, motor rows)."""
    res = _in_simulator(f"""
        import json, time
        import numpy as np
        from rvdiag.cli import main
        from rvdiag.datasets import SampleStore
        from rvdiag.library import LibraryConfig, build_library
        import tomli_w, tempfile, pathlib

        def same(a, b):
            sa, sb = SampleStore.open(a).load(), SampleStore.open(b).load()
            meta = sorted(sa.meta) == sorted(sb.meta) and all(
                np.array_equal(sa.meta[k], sb.meta[k], equal_nan=sa.meta[k].dtype.kind == "f") for k in sa.meta)
            return bool(sa.X.shape == sb.X.shape and np.array_equal(sa.X, sb.X) and meta and np.abs(sa.X).max() > 0)

        tiny = {TINY!r}
        current = {{**tiny, "model": {{"substeps": 4, "signal": "current"}},
                   "signal": {{"fs": 1000.0, "duration_s": 0.064, "transient_s": 0.02, "segment_length": 32,
                              "hop": 16}}, "states": {{"T1": {{}}, "T2": {{"broken_fraction": 1.0}}}}}}
        tmp = pathlib.Path(tempfile.mkdtemp())
        out = {{}}
        t0 = time.perf_counter()
        cfg = tmp / "tiny.toml"
        cfg.write_text(tomli_w.dumps(LibraryConfig.from_dict(tiny).to_dict()))
        build_library(cfg, tmp / "cpu.zarr", workers=0, progress=False)
        try:
            main(["library", "build", str(cfg), "-o", str(tmp / "gpu.zarr"), "--device", "cuda", "--ensemble", "2",
                  "-q"])
        except SystemExit as exc:
            out["exit"] = exc.code
        out["cli"] = same(tmp / "cpu.zarr", tmp / "gpu.zarr")
        rep = build_library(cfg, tmp / "dask.zarr", workers=1, progress=False, device="cuda", ensemble=2)
        out["dask"] = [rep.device, rep.workers, same(tmp / "cpu.zarr", tmp / "dask.zarr")]
        c = LibraryConfig.from_dict(current)
        build_library(c, tmp / "ccpu.zarr", workers=0, progress=False)
        rep = build_library(c, tmp / "cgpu.zarr", workers=0, progress=False, device="cuda", ensemble=4)
        out["current"] = [rep.device, same(tmp / "ccpu.zarr", tmp / "cgpu.zarr")]
        out["s"] = time.perf_counter() - t0
        print(json.dumps(out))
    """)
    assert "exit" not in res, res
    assert res["cli"] is True
    assert res["dask"] == ["cuda", 1, True]
    assert res["current"] == ["cuda", True]


def test_cuda_import_aliases_row_stack_only_when_loaded_and_missing():
    """numba-cuda calls np.row_stack (gone in numpy >= 2.5): load_cuda() aliases it to np.vstack when it is
    missing, and leaves numpy alone otherwise; importing rvdiag's GPU modules does not touch it."""
    res = _in_simulator("""
        import json
        import numpy as np
        import rvdiag.dynamics.ensemble, rvdiag.library.gpu
        from rvdiag.dynamics.gpu import load_cuda, unavailable_reason

        def own(*a):
            return None

        np.row_stack = own
        load_cuda()
        kept = np.row_stack is own
        del np.row_stack
        import rvdiag.dynamics.gpu  # already imported: nothing happens
        before = hasattr(np, "row_stack")
        cuda = load_cuda()
        print(json.dumps({"kept": kept, "before": before, "after": np.row_stack is np.vstack,
                          "reason": unavailable_reason(), "sim": bool(cuda.is_available())}))
    """)
    assert res == {"kept": True, "before": False, "after": True, "reason": None, "sim": True}


@pytest.mark.parametrize("load_inertia", [None, 3.75], ids=["torque_load", "load_dof"])
def test_segmented_motor_current_simulation_on_the_simulated_gpu_equals_simulate(load_inertia):
    """A simulation recorded in two time segments with the motor current (several integrator calls, record
    margins, motor rows), integrated as an ensemble and finished by PreparedSimulation.finish, equals simulate();
    also with the load DOF (the rotor then not the last coordinate)."""
    res = _in_simulator("""
        import json
        import numpy as np
        from rvdiag.dynamics import ModelSettings, prepare_simulation, simulate
        from rvdiag.dynamics.ensemble import IntegrationRequest, integrate_ensemble

        kw = dict(input_speed_rpm=1500.0, load_Nm=80.0, duration_s=0.03, fs=48000.0, signal="both", current_fs=1000.0,
                  seed=5, noise_snr_db=30.0, settings=ModelSettings(substeps=4, transient_s=0.015, segment_s=0.015),
                  load_inertia_kg_m2=LOAD)
        ref = simulate(**kw)
        run = prepare_simulation(**kw)
        calls = run.segment_calls()
        got = integrate_ensemble([IntegrationRequest(run.model, run.start_state(c.t_start), run.fs, c.n_samples,
                                                     c.n_transient, c.first_sample) for c in calls])
        rows = np.zeros((run.rows, run.columns))
        for c, (sig, _) in zip(calls, got):
            rows[:, c.column:c.column + c.n_samples] = sig
        res = run.finish(rows, len(calls))
        print(json.dumps({"calls": len(calls), "margin": list(run.margin), "rows": run.rows,
                          "signal": bool(np.array_equal(res.signal, ref.signal)),
                          "current": bool(np.array_equal(res.current, ref.current)),
                          "record": res.settings == ref.settings, "n_dof": run.model.n_dof}))
    """.replace("LOAD", repr(load_inertia)))
    assert res["calls"] == 2 and res["margin"][0] > 0 and res["rows"] == 2 + 4
    assert res["signal"] and res["current"] and res["record"]
    assert res["n_dof"] == (29 if load_inertia else 28)


# ------------------------------------------------------------------ this process: no simulator

def _gpu_here() -> bool:
    from rvdiag.dynamics.gpu import unavailable_reason

    return unavailable_reason() is None


needs_no_gpu = pytest.mark.skipif("NUMBA_ENABLE_CUDASIM" in os.environ or _gpu_here(),
                                  reason="this process has a usable GPU (or numba's simulator): no fallback to test")


@needs_no_gpu
def test_cuda_without_a_gpu_falls_back_to_the_cpu_with_one_warning(tmp_path, capsys):
    cfg = LibraryConfig.from_dict({**TINY, "states": {"T1": {}, "T6": {}}})
    path = tmp_path / "tiny.toml"
    import tomli_w

    path.write_text(tomli_w.dumps(cfg.to_dict()))
    code, out, err = run_cli(["library", "build", path, "-o", tmp_path / "gpu.zarr", "--device", "cuda",
                              "--workers", "0", "-q"], capsys)
    assert code == 0, err
    lines = err.splitlines()
    assert all(line.startswith("warning: ") for line in lines), err  # one line each, no traceback
    device = [line for line in lines if "CPU" in line or "CUDA" in line]  # the rest: the model's range caveat
    assert len(device) == 1, err
    assert device[0].startswith(("warning: no CUDA GPU found (numba: ", "warning: numba has no CUDA support ("))
    assert device[0].endswith("; building on the CPU")
    assert "on the GPU" not in out
    code, out, err = run_cli(["library", "build", path, "-o", tmp_path / "auto.zarr", "--device", "auto",
                              "--workers", "0", "-q"], capsys)
    assert code == 0 and err == ""  # auto falls back silently
    from rvdiag.datasets import SampleStore

    a, b = SampleStore.open(tmp_path / "gpu.zarr").load(), SampleStore.open(tmp_path / "auto.zarr").load()
    assert np.array_equal(a.X, b.X) and a.X.size > 0


@needs_no_gpu
def test_the_dask_task_without_a_gpu_runs_its_units_on_the_cpu():
    from rvdiag.library.gpu import ensemble_task

    cfg = LibraryConfig.from_dict({**TINY, "simulator": SYN, "model": {}})
    job = Job.from_config(cfg, cfg.reducer_params())
    units = make_plan(cfg)
    results, reason = ensemble_task(units, job)
    assert reason and reason.startswith(("no CUDA GPU found", "numba has no CUDA support"))
    for unit, res in zip(units, results):
        np.testing.assert_array_equal(res.X, run_unit(unit, job).X)


@pytest.mark.parametrize("args, message", [
    (["--device", "tpu"], "error: --device must be one of cpu, cuda, auto, got 'tpu'"),
    (["--device", "cuda", "--ensemble", "0"], "error: --ensemble must be a whole number >= 1, got 0"),
])
def test_bad_device_options_are_one_line_and_exit_2(tmp_path, capsys, args, message):
    code, _, err = run_cli(["library", "build", REPO / "src/rvdiag/configs/demo.toml", "-o", tmp_path / "x.zarr",
                            *args, "-q"], capsys)
    assert code == 2 and err == message + "\n"
    assert not (tmp_path / "x.zarr").exists()


def test_cuda_needs_a_simulator_with_a_gpu_path(tmp_path):
    cfg = LibraryConfig.from_dict({**TINY, "simulator": SYN, "model": {}})
    with pytest.raises(ConfigError, match="has no GPU path"):
        build_library(cfg, tmp_path / "x.zarr", workers=0, progress=False, device="cuda")
    assert not (tmp_path / "x.zarr").exists()
    import warnings

    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        rep = build_library(cfg, tmp_path / "y.zarr", workers=0, progress=False, device="auto")
    assert rep.device == "cpu" and rep.built == 3  # auto: the CPU, silently
    assert not [w for w in rec if issubclass(w.category, DeviceWarning)]


def test_cli_default_ensemble_is_the_librarys():
    import typer

    from rvdiag.cli import build_app
    from rvdiag.library.gpu import DEFAULT_ENSEMBLE

    cmd = typer.main.get_command(build_app()).commands["library"].commands["build"]
    opts = {p.name: p for p in cmd.params}
    assert opts["ensemble"].default == DEFAULT_ENSEMBLE and opts["device"].default == "cpu"
