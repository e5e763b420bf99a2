"""A library build on a real Dask cluster of separate processes, as docs/library.md ("On a cluster") runs one:
``dask scheduler`` and two ``dask worker`` processes on 127.0.0.1 and ``rvdiag library build --scheduler``.  The
second worker joins after the build has started (as a batch system's jobs do) and must get work; then the first
worker is killed with SIGKILL while it runs a simulation.  The build must finish with every sample, bit-identical
to an in-process build of the same config: the scheduler gives the killed worker's simulation to the other worker
(``distributed.scheduler.allowed-failures``, 3 by default, bounds how often one task may lose its worker).

The workers run without a nanny (``--no-nanny``): with one, the nanny would restart the killed worker and the
test would not show that the build survives losing it.  The simulator is the synthetic stand-in slowed down on the
workers only (``tests/slow_simulator.py``), so that the victim is certainly busy when it dies."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from rvdiag.datasets import SampleStore
from rvdiag.library import LibraryConfig, build_library

from slow_simulator import DELAY_VARIABLE

TESTS = Path(__file__).resolve().parent
SRC = TESTS.parent / "src"
DELAY_S = 1.0  # per simulation, on the workers

#: 4 states x 4 simulations, 0.3 s at 4 kHz each: 16 units of 5 samples
CONFIG = {
    "name": "cluster-test",
    "mode": "split-by-simulation",
    "seed": 2024,
    "simulator": "slow_simulator:simulate",
    "signal": {"fs": 4000.0, "duration_s": 0.3, "transient_s": 0.02, "segment_length": 400, "hop": 200},
    "operation": {"input_speed_rpm": {"min": 1000.0, "max": 2000.0}, "load_Nm": [50.0, 100.0],
                  "noise_snr_db": {"min": 10.0, "max": 30.0}},
    "randomise": {"stiffness_pct": 5.0},
    "split": {"simulations_per_state": 4, "test_simulations_per_state": 1},
    "states": {"T1": {}, "T2": {"broken_fraction": {"min": 0.5, "max": 1.0}}, "T3": {}, "T4": {}},
}


def _env(**extra: str) -> dict[str, str]:
    """This checkout's rvdiag and the tests folder (for ``slow_simulator``) first on the path."""
    env = {k: v for k, v in os.environ.items() if k != DELAY_VARIABLE}
    env["PYTHONPATH"] = os.pathsep.join([str(SRC), str(TESTS), *filter(None, [os.environ.get("PYTHONPATH")])])
    env.update(extra)
    return env


def _tail(path: Path, n: int = 2000) -> str:
    return path.read_text(errors="replace")[-n:] if path.exists() else ""


def _wait(what: str, ok, timeout: float, procs=()) -> None:
    deadline = time.monotonic() + timeout
    while not ok():
        for p, log in procs:
            if p.poll() is not None:
                pytest.fail(f"{what}: {p.args[3]} exited with {p.returncode}:\n{_tail(log)}")
        if time.monotonic() > deadline:
            pytest.fail(f"{what}: not within {timeout:.0f} s")
        time.sleep(0.05)


@pytest.fixture
def dask_cluster(tmp_path):
    """``dask scheduler`` on 127.0.0.1 (a free port, no dashboard); yields its address and ``start_worker(name)``,
    which starts a single-threaded ``dask worker`` process without a nanny and returns (process, log); stops
    whatever is left at the end."""
    procs: list[tuple[subprocess.Popen, Path]] = []

    def start(name: str, *args: str, env: dict[str, str]) -> tuple[subprocess.Popen, Path]:
        log = tmp_path / f"{name}.log"
        with open(log, "wb") as fh:
            p = subprocess.Popen([sys.executable, "-m", "dask", *args], stdout=fh, stderr=subprocess.STDOUT,
                                 env=env, cwd=tmp_path)
        procs.append((p, log))
        return p, log

    sched_file = tmp_path / "scheduler.json"
    try:
        scheduler = start("scheduler", "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                          "--scheduler-file", str(sched_file), env=_env())
        _wait("the scheduler's address file", lambda: sched_file.exists() and sched_file.stat().st_size > 0, 60,
              [scheduler])
        address = json.loads(sched_file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")

        def start_worker(name: str) -> tuple[subprocess.Popen, Path]:
            return start(name, "worker", address, "--name", name, "--nthreads", "1", "--nworkers", "1",
                         "--no-nanny", "--no-dashboard", "--host", "127.0.0.1",
                         env=_env(**{DELAY_VARIABLE: str(DELAY_S)}))

        yield address, start_worker
    finally:
        for p, _ in reversed(procs):
            if p.poll() is None:
                p.terminate()
        for p, _ in reversed(procs):
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def _store_arrays(path: Path) -> dict[str, np.ndarray]:
    s = SampleStore.open(path)
    out = {"signals": np.asarray(s.signals[:]), "label": s.labels}
    out.update({f"meta/{k}": v for k, v in s.meta.items()})
    return out


@pytest.mark.slow  # 30-60 s: process start-ups and 16 simulations of 1 s on the workers
def test_build_on_a_scheduler_takes_new_workers_and_survives_a_killed_one(tmp_path, dask_cluster, monkeypatch):
    from distributed import Client

    address, start_worker = dask_cluster
    cfg_file = tmp_path / "cluster.toml"
    cfg_file.write_text(tomli_w.dumps(CONFIG))
    monkeypatch.syspath_prepend(str(TESTS))
    cfg = LibraryConfig.load(cfg_file)
    n = cfg.n_simulations
    assert n == 16 and cfg.n_samples == 80
    ref = build_library(cfg, tmp_path / "ref.zarr", workers=0, progress=False)  # in process, no delay
    assert ref.built == n

    out = tmp_path / "cluster.zarr"
    units = out / "_units"

    def committed() -> int:
        return len(list(units.glob("*.json"))) if units.is_dir() else 0

    t0 = time.monotonic()
    workers = {"w0": start_worker("w0")}
    with Client(address, timeout=60) as monitor:
        monitor.wait_for_workers(1, timeout=60)
        log = tmp_path / "build.log"
        with open(log, "wb") as fh:
            build = subprocess.Popen([sys.executable, "-m", "rvdiag", "library", "build", str(cfg_file), "--out",
                                      str(out), "--scheduler", address, "--quiet"], stdout=fh,
                                     stderr=subprocess.STDOUT, env=_env(), cwd=tmp_path)
        try:
            # the second worker joins once the build is under way (one simulation committed)
            _wait("the first committed simulation", lambda: committed() >= 1, 60, [(build, log)])
            workers["w1"] = start_worker("w1")
            # both workers busy at once (the build took the newcomer), two simulations committed: kill w0
            lost = None
            deadline = time.monotonic() + 60
            while lost is None:
                if build.poll() is not None:
                    pytest.fail(f"the build ended (exit {build.returncode}) before a worker was killed:\n"
                                f"{_tail(log)}\n{_tail(workers['w1'][1])}")
                if time.monotonic() > deadline:
                    pytest.fail(f"never both workers busy within 60 s ({committed()} committed):\n{_tail(log)}")
                if committed() >= 2:
                    names = {a: w["name"] for a, w in monitor.scheduler_info(n_workers=-1)["workers"].items()}
                    busy = {names.get(a): list(keys) for a, keys in monitor.processing().items() if keys}
                    if set(busy) >= {"w0", "w1"}:
                        lost = busy["w0"]
                        break
                time.sleep(0.02)
            victim = workers["w0"][0]
            os.kill(victim.pid, signal.SIGKILL)
            victim.wait(timeout=10)
            killed_at = committed()
            build.wait(timeout=120)
        finally:
            if build.poll() is None:
                build.kill()
                build.wait()
        assert build.returncode == 0, _tail(log)
        assert victim.returncode == -signal.SIGKILL
        survivors = [w["name"] for w in monitor.scheduler_info(n_workers=-1)["workers"].values()]
    assert survivors == ["w1"]
    assert killed_at < n, "the build had finished before the kill"
    print(f"killed w0 running {lost} with {killed_at} of {n} simulations committed; "
          f"cluster build {time.monotonic() - t0:.1f} s")

    assert f"80 samples from {n} simulations" in log.read_text()
    assert not units.exists()  # finalised
    got, want = _store_arrays(out), _store_arrays(tmp_path / "ref.zarr")
    assert sorted(got) == sorted(want) and got["signals"].shape == (80, 400)
    assert sorted(set(got["meta/unit"].tolist())) == list(range(n))  # every simulation, every sample
    for key, w in want.items():  # bit-identical (NaN: a severity the state does not have)
        assert got[key].dtype == w.dtype and np.array_equal(got[key], w, equal_nan=w.dtype.kind == "f"), key
    assert SampleStore.open(out).attrs["config_hash"] == SampleStore.open(tmp_path / "ref.zarr").attrs["config_hash"]


def test_a_worker_of_another_release_or_physics_refuses_the_units(tmp_path, monkeypatch):
    """A worker compares the client's rvdiag release and physics revision (carried by the job) with its own."""
    import dataclasses

    from rvdiag.errors import ConfigError
    from rvdiag.library import make_plan, run_unit
    from rvdiag.library.build import Job

    monkeypatch.syspath_prepend(str(TESTS))
    cfg = LibraryConfig.from_dict(CONFIG, source="cluster.toml")
    job = Job.from_config(cfg, cfg.reducer_params())
    unit = make_plan(cfg)[0]
    assert job.rvdiag_version and job.physics_revision
    assert run_unit(unit, job).X.shape == (5, 400)
    for change in ({"rvdiag_version": "0.0.1"}, {"physics_revision": "2020-01-01"}):
        with pytest.raises(ConfigError, match=r"this Dask worker runs rvdiag .* install the client's rvdiag"):
            run_unit(unit, dataclasses.replace(job, **change))


def test_a_scheduler_without_rvdiag_is_one_error_line(tmp_path, capsys):
    """Dask's scheduler unpickles the tasks, so it needs rvdiag too: without it, one line and exit code 2."""
    from conftest import run_cli

    blocker = tmp_path / "blocker" / "rvdiag"
    blocker.mkdir(parents=True)
    (blocker / "__init__.py").write_text('raise ImportError("no rvdiag here")\n')
    sched_file = tmp_path / "scheduler.json"
    log = tmp_path / "scheduler.log"
    env = {**os.environ, "PYTHONPATH": str(blocker.parent)}
    with open(log, "wb") as fh:
        scheduler = subprocess.Popen([sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0",
                                      "--no-dashboard", "--scheduler-file", str(sched_file)],
                                     stdout=fh, stderr=subprocess.STDOUT, env=env, cwd=tmp_path)
    try:
        _wait("the scheduler's address file", lambda: sched_file.exists() and sched_file.stat().st_size > 0, 60,
              [(scheduler, log)])
        address = json.loads(sched_file.read_text())["address"]
        with open(tmp_path / "worker.log", "wb") as fh:  # a worker that has rvdiag
            worker = subprocess.Popen([sys.executable, "-m", "dask", "worker", address, "--nthreads", "1",
                                       "--no-nanny", "--no-dashboard", "--host", "127.0.0.1"],
                                      stdout=fh, stderr=subprocess.STDOUT, env=_env(), cwd=tmp_path)
        cfg_file = tmp_path / "synthetic.toml"
        cfg_file.write_text(tomli_w.dumps({**CONFIG, "simulator": "rvdiag.library.synthetic:simulate"}))
        code, _, err = run_cli(["library", "build", cfg_file, "--out", tmp_path / "x.zarr", "--scheduler", address,
                                "--quiet"], capsys)
    finally:
        for p in (locals().get("worker"), scheduler):
            if p is not None and p.poll() is None:
                p.terminate()
                p.wait(timeout=30)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith("error: the Dask scheduler cannot read the simulation tasks") and "rvdiag" in lines[0]
