"""Library builds: determinism across workers, resume (also after SIGKILL), refusal of other configs,
the --scheduler path on a Dask cluster on 127.0.0.1, metadata, and a build on the real dynamic model.

Most tests use the synthetic stand-in simulator (``rvdiag.library.synthetic``): they test the build
machinery, which does not depend on the physics.  ``test_real_simulator_library`` uses the dynamic model.
"""

import logging
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rvdiag.datasets import SampleStore, StoreBuilder
from rvdiag.errors import ConfigError, StoreError
from rvdiag.library import LibraryConfig, build_library, config_from_store, make_plan, run_unit
from rvdiag.dynamics.noise import add_awgn
from rvdiag.library.build import Job

SYN = "rvdiag.library.synthetic:simulate"

TINY = {
    "mode": "split-by-simulation",
    "seed": 42,
    "simulator": SYN,
    "signal": {"fs": 4000.0, "duration_s": 0.5, "transient_s": 0.05, "segment_length": 500, "hop": 250},
    "operation": {"input_speed_rpm": {"min": 1000.0, "max": 2000.0}, "load_Nm": [50.0, 100.0],
                  "noise_snr_db": {"min": 5.0, "max": 20.0}},
    "randomise": {"stiffness_pct": 10.0, "damping_pct": 10.0},
    "split": {"simulations_per_state": 3, "test_simulations_per_state": 1},
    "states": {"T1": {}, "T2": {"broken_fraction": {"min": 0.5, "max": 1.0}}, "T3": {},
               "T6": {"crack_depth": [3e-4, 6e-4]}},
}


def tiny(**changes):
    data = {**TINY, **changes}
    return LibraryConfig.from_dict(data, source="tiny.toml")


def assert_same_store(a, b):
    sa, sb = SampleStore.open(a), SampleStore.open(b)
    assert sa.attrs["config_hash"] == sb.attrs["config_hash"]
    xa, xb = sa.load(), sb.load()
    assert xa.X.dtype == np.float32 and xa.X.shape == xb.X.shape
    np.testing.assert_array_equal(xa.X, xb.X)  # bit-identical
    np.testing.assert_array_equal(xa.y, xb.y)
    assert sorted(xa.meta) == sorted(xb.meta)
    for key in xa.meta:
        np.testing.assert_array_equal(xa.meta[key], xb.meta[key], err_msg=key)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The tiny library built serially in this process (no Dask)."""
    path = tmp_path_factory.mktemp("ref") / "ref.zarr"
    report = build_library(tiny(), path, workers=0, progress=False)
    assert report.built == report.n_units == 12
    return path


@pytest.fixture(scope="module")
def cluster():
    """A two-worker process cluster on 127.0.0.1, shared by the tests that need one."""
    from distributed import LocalCluster

    c = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                     dashboard_address=":0", silence_logs=logging.ERROR)
    yield c
    c.close()


def test_store_contents_and_metadata(reference):
    s = SampleStore.open(reference)
    cfg = tiny()
    assert s.classes == ["T1", "T2", "T3", "T6"] and s.length == 500 and s.fs == 4000.0
    assert s.n_samples == 4 * 3 * cfg.segments_per_simulation == 4 * 3 * 7
    assert s.summary()["counts"]["T2"] == {"train": 14, "test": 7}
    assert s.attrs["params"]["name"] == "RV-20E" and s.attrs["rvdiag_version"]
    assert config_from_store(s.attrs) == cfg  # the full config is kept
    m = s.meta
    for col in ("state", "split", "unit", "seed", "simulation", "segment", "t_start_s", "input_speed_rpm",
                "load_Nm", "noise_snr_db", "broken_fraction", "wear_depth", "crack_depth", "crack_angle_deg",
                "scale.material.youngs_modulus", "scale.damping.mesh_damping_ratio"):
        assert col in m, col
    np.testing.assert_array_equal(m["state"], s.label_names)
    plan = make_plan(cfg)
    for u in plan:  # every row carries its unit's drawn values
        rows = m["unit"] == u.index
        assert rows.sum() == 7 and set(m["seed"][rows]) == {u.seed} and set(m["split"][rows]) == {u.split}
        assert np.all(m["input_speed_rpm"][rows] == u.speed) and np.all(m["load_Nm"][rows] == u.load_Nm)
        for p in ("broken_fraction", "wear_depth", "crack_depth", "crack_angle_deg"):
            want = u.severity.get(p, np.nan)
            np.testing.assert_array_equal(m[p][rows], np.full(7, want))
    np.testing.assert_allclose(m["t_start_s"][m["unit"] == 0], np.arange(7) * 250 / 4000.0)


def test_split_is_by_simulation(reference):
    m = SampleStore.open(reference).meta
    train = {(s, k) for s, k, sp in zip(m["state"], m["simulation"], m["split"]) if sp == "train"}
    test = {(s, k) for s, k, sp in zip(m["state"], m["simulation"], m["split"]) if sp == "test"}
    assert train and test and not train & test  # no test sample shares a simulation with a training one
    assert len(test) == 4 and len(train) == 8


def test_a_unit_is_reproduced_from_the_plan_alone(reference):
    """The stored seed is enough: re-running one unit gives its rows bit for bit."""
    cfg = tiny()
    s = SampleStore.open(reference)
    unit = make_plan(cfg)[7]
    res = run_unit(unit, Job.from_config(cfg, cfg.reducer_params()))
    np.testing.assert_array_equal(res.X, s.load(index=np.flatnonzero(s.meta["unit"] == 7)).X)


def test_seed_changes_the_data(tmp_path, reference):
    build_library(tiny(seed=43), tmp_path / "other.zarr", workers=0, progress=False)
    a, b = SampleStore.open(reference).load().X, SampleStore.open(tmp_path / "other.zarr").load().X
    assert a.shape == b.shape and not np.array_equal(a, b)


def test_one_worker_equals_serial_and_holds_one_result_at_a_time(tmp_path, reference, monkeypatch):
    from distributed import Client, LocalCluster

    seen = []
    original = StoreBuilder.write_unit

    def spy(self, unit, *args, **kwargs):
        seen.append(sum(1 for k in client.futures if str(k).startswith("rvdiag-unit")))
        return original(self, unit, *args, **kwargs)

    monkeypatch.setattr(StoreBuilder, "write_unit", spy)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as c, \
            Client(c) as client:
        report = build_library(tiny(), tmp_path / "one.zarr", client=client, progress=False)
    assert report.workers == 1 and report.built == 12
    # when a result is written, no other simulation is pending: at most one in flight per worker thread
    assert seen and max(seen) <= 1
    assert_same_store(reference, tmp_path / "one.zarr")


def test_two_workers_on_a_scheduler_equal_serial(tmp_path, reference, cluster):
    """The --scheduler path: the CLI runs the same job on an existing cluster (127.0.0.1)."""
    from rvdiag.cli import main

    cfg_file = tmp_path / "tiny.toml"
    _write_toml(tiny(), cfg_file)
    try:
        main(["library", "build", str(cfg_file), "--out", str(tmp_path / "two.zarr"),
              "--scheduler", cluster.scheduler_address, "--quiet"])
    except SystemExit as exc:  # main() exits only on errors
        pytest.fail(f"rvdiag exited with {exc.code}")
    assert len(cluster.scheduler_info["workers"]) == 2
    assert_same_store(reference, tmp_path / "two.zarr")


def test_worker_errors_reach_the_client_typed_and_keep_committed_units(tmp_path, cluster):
    from distributed import Client

    bad = tiny(channel=3)  # the synthetic simulator has one channel
    with Client(cluster.scheduler_address) as client, pytest.raises(ConfigError, match=r"simulation \d+ \(T\d #\d\): channel 3"):
        build_library(bad, tmp_path / "bad.zarr", client=client, progress=False)
    with pytest.raises(StoreError, match="unfinished build"):
        SampleStore.open(tmp_path / "bad.zarr")


def interrupted_build(cfg, path, monkeypatch, after: int) -> None:
    """Build ``cfg`` serially into ``path`` and stop it (Ctrl-C) once ``after`` simulations are written."""
    original = StoreBuilder.write_unit
    calls = []

    def interrupt(self, *args, **kwargs):
        if len(calls) == after:
            raise KeyboardInterrupt
        calls.append(1)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(StoreBuilder, "write_unit", interrupt)
    with pytest.raises(KeyboardInterrupt):
        build_library(cfg, path, workers=0, progress=False)
    monkeypatch.setattr(StoreBuilder, "write_unit", original)
    with pytest.raises(StoreError, match="unfinished build"):
        SampleStore.open(path)


def test_resume_after_interrupt_equals_uninterrupted(tmp_path, reference, monkeypatch):
    path = tmp_path / "resumed.zarr"
    interrupted_build(tiny(), path, monkeypatch, after=4)
    report = build_library(tiny(), path, workers=0, progress=False)
    assert (report.skipped, report.built) == (4, 8)
    assert_same_store(reference, path)
    again = build_library(tiny(), path, workers=0, progress=False)  # complete: nothing to do
    assert again.built == 0 and again.skipped == 12


def test_store_of_another_config_is_refused(tmp_path, reference, monkeypatch):
    with pytest.raises(StoreError, match="different config"):
        build_library(tiny(seed=1), reference, workers=0, progress=False)
    # an unfinished store is refused just the same, and left untouched
    path = tmp_path / "partial.zarr"
    original = StoreBuilder.write_unit
    monkeypatch.setattr(StoreBuilder, "write_unit",
                        lambda self, u, *a, **k: (_ for _ in ()).throw(KeyboardInterrupt) if u == 2 else original(self, u, *a, **k))
    with pytest.raises(KeyboardInterrupt):
        build_library(tiny(), path, workers=0, progress=False)
    monkeypatch.setattr(StoreBuilder, "write_unit", original)
    before = sorted(p.name for p in (path / "_units").iterdir())
    with pytest.raises(StoreError, match="different config"):
        build_library(tiny(signal={**TINY["signal"], "hop": 500}), path, workers=0, progress=False)
    # a different reducer parameter set is a different config too
    params = tmp_path / "params.toml"
    from rvdiag.params import ReducerParams

    ReducerParams.default().replace(damping={"mesh_damping_ratio": 0.05}).save(params)
    with pytest.raises(StoreError, match="different config"):
        build_library(tiny(params=str(params)), path, workers=0, progress=False)
    assert sorted(p.name for p in (path / "_units").iterdir()) == before


def test_sigkill_mid_build_then_resume_equals_uninterrupted(tmp_path):
    """Kill the whole build (client and its Dask workers) with SIGKILL part-way, re-run the same command."""
    cfg = tiny(
        signal={"fs": 16000.0, "duration_s": 4.0, "transient_s": 0.1, "segment_length": 4000, "hop": 4000},
        split={"simulations_per_state": 8, "test_simulations_per_state": 2},
    )
    cfg_file = tmp_path / "kill.toml"
    _write_toml(cfg, cfg_file)
    out = tmp_path / "killed.zarr"
    cmd = [sys.executable, "-m", "rvdiag", "library", "build", str(cfg_file), "--out", str(out),
           "--workers", "2", "--quiet"]
    proc = subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    units = out / "_units"
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            if units.is_dir() and any(units.glob("*.json")):
                break
            time.sleep(0.01)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert proc.returncode == -signal.SIGKILL, proc.stderr.read().decode()
    committed = len(list(units.glob("*.json")))
    assert 1 <= committed < cfg.n_simulations == 32
    with pytest.raises(StoreError, match="unfinished build"):
        SampleStore.open(out)
    # the same command again (in this interpreter, to save a start-up): it skips the committed units
    from rvdiag.cli import main

    t0 = time.monotonic()
    try:
        main(cmd[3:])
    except SystemExit as exc:
        pytest.fail(f"resume exited with {exc.code}")
    assert not units.exists()  # finalised
    print(f"resumed {32 - committed} units in {time.monotonic() - t0:.1f} s")
    build_library(cfg, tmp_path / "straight.zarr", workers=0, progress=False)
    assert_same_store(tmp_path / "straight.zarr", out)


def test_paper_mode_splits_segments_of_one_simulation(tmp_path):
    cfg = tiny(mode="paper", split={"train_per_state": 5, "test_per_state": 2})
    build_library(cfg, tmp_path / "p.zarr", workers=0, progress=False)
    s = SampleStore.open(tmp_path / "p.zarr")
    assert s.summary()["counts"]["T1"] == {"train": 5, "test": 2}
    m = s.meta
    assert set(m["simulation"]) == {0} and len(set(m["unit"])) == 4
    for u in range(4):
        seg = m["segment"][m["unit"] == u]
        assert len(set(seg)) == 7 and np.all(np.diff(seg) > 0) and seg.max() < cfg.segments_per_simulation
    ordered = cfg.replace(split={"assign": "ordered", "train_per_state": 4})
    build_library(ordered, tmp_path / "o.zarr", workers=0, progress=False)
    mo = SampleStore.open(tmp_path / "o.zarr").meta
    first = mo["unit"] == 0
    np.testing.assert_array_equal(mo["segment"][first], [0, 1, 2, 3, 5, 6])  # segment 4 dropped: a gap
    np.testing.assert_array_equal(mo["split"][first], ["train"] * 4 + ["test"] * 2)
    # overlapping segments of one simulation share their samples: the signal is cut, not re-simulated
    X = SampleStore.open(tmp_path / "o.zarr").load(index=np.flatnonzero(first)).X
    np.testing.assert_array_equal(X[0, 250:], X[1, :250])


def test_library_noise_is_add_awgn_at_each_units_snr(tmp_path, monkeypatch):
    """Every unit's signal gets its noise from rvdiag.dynamics.noise.add_awgn at the unit's SNR."""
    from rvdiag.dynamics import noise
    from rvdiag.library.build import make_plan

    seen = []

    def spy(x, snr_db, rng):
        seen.append(snr_db)
        return add_awgn(x, snr_db, rng)

    monkeypatch.setattr(noise, "add_awgn", spy)
    build_library(tiny(), tmp_path / "n.zarr", workers=0, progress=False)
    assert sorted(seen) == sorted(u.noise_snr_db for u in make_plan(tiny()))


def test_noise_has_the_requested_snr():
    """add_awgn is MATLAB's ``awgn(x, snr, 'measured')``."""
    rng = np.random.default_rng(0)
    x = np.sin(np.linspace(0, 400 * np.pi, 200_000)) * 3.0
    for snr in (0.0, 10.0, 20.0):
        noisy = add_awgn(x, snr, rng)
        measured = 10 * np.log10(np.mean(x**2) / np.mean((noisy - x) ** 2))
        assert abs(measured - snr) < 0.05


def test_bad_build_arguments(tmp_path):
    with pytest.raises(ConfigError, match="--workers must be >= 0"):
        build_library(tiny(), tmp_path / "x.zarr", workers=-1, progress=False)
    with pytest.raises(ConfigError, match="not both"):
        build_library(tiny(), tmp_path / "x.zarr", workers=2, scheduler="tcp://127.0.0.1:1", progress=False)
    with pytest.raises(ConfigError, match="cannot import module 'nowhere'"):
        build_library(tiny(simulator="nowhere:sim"), tmp_path / "x.zarr", workers=0, progress=False)
    with pytest.raises(ConfigError, match=r"\[model\]"):
        build_library(tiny(model={"substeps": 8}), tmp_path / "x.zarr", workers=0, progress=False)
    assert not (tmp_path / "x.zarr").exists()


def test_real_simulator_library(tmp_path):
    """A small paper-mode library on the 26-DOF dynamic model: six states, faults change the signal."""
    data = {
        "mode": "paper", "seed": 1, "model": {"substeps": 4},
        "signal": {"fs": 48000.0, "duration_s": 0.09, "transient_s": 0.02, "segment_length": 1080, "hop": 1080},
        "operation": {"output_speed_deg_s": 45.0, "load_Nm": 73.6, "noise_snr_db": 30.0},
        "split": {"train_per_state": 3, "test_per_state": 1},
        "states": {s: {} for s in ("T1", "T2", "T3", "T4", "T5", "T6")},
    }
    cfg = LibraryConfig.from_dict(data)
    assert cfg.simulator == "rvdiag.library.simulators:dynamics"
    build_library(cfg, tmp_path / "real.zarr", workers=0, progress=False)
    s = SampleStore.open(tmp_path / "real.zarr")
    assert s.summary()["counts"] == {k: {"train": 3, "test": 1} for k in cfg.classes}
    X = s.load().X
    assert np.all(np.isfinite(X)) and X.std() > 0
    rms = {c: float(np.sqrt(np.mean(X[s.label_names == c] ** 2))) for c in cfg.classes}
    assert rms["T2"] > 1.5 * rms["T1"]  # a missing tooth makes the housing ring (periodic impact)
    assert not np.array_equal(X[s.label_names == "T1"], X[s.label_names == "T3"])
    unit = make_plan(cfg)[4]  # T5 again, alone, from the plan: bit-identical
    res = run_unit(unit, Job.from_config(cfg, cfg.reducer_params()))
    np.testing.assert_array_equal(res.X, s.load(index=np.flatnonzero(s.meta["unit"] == 4)).X)


def _write_toml(cfg, path: Path) -> None:
    import tomli_w

    path.write_text(tomli_w.dumps(cfg.to_dict()), encoding="utf-8")


def test_a_store_simulated_by_other_physics_is_never_resumed(tmp_path, monkeypatch):
    """The physics revision is part of the stored, hashed config: a store built before a deliberate physics change
    is refused by name (resuming it would mix old and new signals), and the same revision resumes."""
    import rvdiag.dynamics as dyn
    from rvdiag.errors import StoreError

    cfg = tiny(states={"T1": {}, "T2": {}})
    path = tmp_path / "lib.zarr"
    build_library(cfg, path, workers=0, progress=False)
    assert SampleStore.open(path).attrs["config"]["physics_revision"] == dyn.PHYSICS_REVISION
    assert build_library(cfg, path, workers=0, progress=False).built == 0  # complete: nothing to do
    stored = dyn.PHYSICS_REVISION
    monkeypatch.setattr(dyn, "PHYSICS_REVISION", "2099-01-01")
    with pytest.raises(StoreError, match=rf"physics of {re.escape(stored)} .* that of 2099-01-01"):
        build_library(cfg, path, workers=0, progress=False)


def test_a_build_is_finished_on_the_device_it_began_on(tmp_path, monkeypatch):
    """The store records the device it was begun on; finishing it on the other one is one StoreError line (a GPU's
    units differ from the CPU's in the last bits).  Older stores, which record none, were built on the CPU."""
    from types import SimpleNamespace

    from rvdiag.library.build import _check_resume_device

    path = tmp_path / "begun.zarr"
    interrupted_build(tiny(), path, monkeypatch, after=4)
    import zarr

    began = dict(zarr.open_group(str(path), mode="r").attrs)["library"]["device"]
    assert began == "cpu"
    builder = SimpleNamespace(attrs={"library": {"device": began}})
    _check_resume_device(path, builder, "cpu")  # the same device: fine
    with pytest.raises(StoreError, match="begun with --device cpu; finish it with --device cpu"):
        _check_resume_device(path, builder, "cuda")
    with pytest.raises(StoreError, match="begun with --device cpu"):
        _check_resume_device(path, SimpleNamespace(attrs={"library": {}}), "cuda")  # no record: the CPU
    with pytest.raises(StoreError, match="begun with --device cuda"):
        _check_resume_device(path, SimpleNamespace(attrs={"library": {"device": "cuda"}}), "cpu")
    assert build_library(tiny(), path, workers=0, progress=False).built == 8  # resumed on the CPU
