"""Warnings as a user reads them: one ``warning: ...`` line on stderr each, every distinct message
once per command, no source paths, also for warnings raised in Dask worker processes; the built-in RV-20E's
documented extrapolation is not repeated by every command; sampling rates within 0.1 % are the same rate."""

from __future__ import annotations

import json
import threading
import warnings

import numpy as np
import pytest
import tomli_w

from rvdiag.cli import _show_warning
from rvdiag.errors import ModelRangeWarning
from rvdiag.gears import GearPair, mesh_stiffness, tvms
from rvdiag.library.worker_warnings import caught, reissue
from rvdiag.models.conditions import FS_RTOL, fs_ratio
from rvdiag.params import ReducerParams
from conftest import run_cli as run


@pytest.fixture
def fresh(monkeypatch):
    """A new command: nothing shown yet, no tvms warning issued yet in this process."""
    monkeypatch.setattr("rvdiag.cli._shown", set())
    monkeypatch.setattr(tvms, "_WARNED", set())


def shaft_params(tmp_path):
    """The RV-20E with a 5.5 mm sun shaft: the sun's fillet foundation outside Sainsot's fit, not as documented."""
    p = ReducerParams.default().replace(bodies={"sun_shaft_radius": 5.5e-3})
    path = tmp_path / "shaft55.toml"
    p.save(path)
    return p, path


# ----------------------------------------------------------------------------- the formatter
def test_every_warning_is_one_line_once_per_command_without_its_source(fresh, capsys):
    _show_warning(ModelRangeWarning("fit  extrapolated\n here"), ModelRangeWarning, "/src/x.py", 3)
    _show_warning(ModelRangeWarning("fit extrapolated here"), ModelRangeWarning, "/src/y.py", 9)
    _show_warning(RuntimeWarning("invalid value encountered in divide"), RuntimeWarning, "/np/z.py", 1)
    err = capsys.readouterr().err
    assert err.splitlines() == ["warning: fit extrapolated here",
                                "warning: RuntimeWarning: invalid value encountered in divide"]
    assert ".py" not in err


# ----------------------------------------------------------------------------- warnings of other threads/processes
def test_caught_keeps_each_threads_warnings_apart_and_reissue_warns_them_here():
    barrier = threading.Barrier(2)
    got = {}

    def task(name):
        barrier.wait()
        warnings.warn(f"from {name}", ModelRangeWarning)
        barrier.wait()
        return name

    def runner(name):
        got[name] = caught(task, name)

    with warnings.catch_warnings():
        warnings.simplefilter("always")
        threads = [threading.Thread(target=runner, args=(n,)) for n in ("a", "b")]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    assert got == {"a": ("a", ((ModelRangeWarning, "from a"),)), "b": ("b", ((ModelRangeWarning, "from b"),))}
    with pytest.warns(ModelRangeWarning, match="from a"):
        reissue(got["a"][1])


# ----------------------------------------------------------------------------- the fillet-foundation note
def test_the_built_in_suns_documented_extrapolation_is_noted_not_warned(fresh, tmp_path):
    pair = GearPair.sun_planet(ReducerParams.default())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = mesh_stiffness(pair, cycles=1, points_per_cycle=12)
    assert res.foundation_in_range is False and res.notes and set(res.notes) <= tvms.documented_notes()
    other, _ = shaft_params(tmp_path)
    with pytest.warns(ModelRangeWarning, match=r"h_fi = 1\.057"):
        mesh_stiffness(GearPair.sun_planet(other), cycles=1, points_per_cycle=12)


def test_simulate_with_the_built_in_set_prints_no_warning(fresh, tmp_path, capsys):
    code, _, err = run(["simulate", "--output-speed", "45", "--duration", "0.02", "--transient", "0.01", "-o",
                        tmp_path / "s.npz", "--quiet"], capsys)
    assert code == 0, err
    assert "warning" not in err.lower(), err


def test_library_build_on_two_worker_processes_prints_their_warning_once(fresh, tmp_path, capsys):
    _, params = shaft_params(tmp_path)
    cfg = tmp_path / "lib.toml"
    cfg.write_text(tomli_w.dumps({
        "name": "warn", "mode": "paper", "seed": 1, "model": {"substeps": 4},
        "signal": {"fs": 48000.0, "duration_s": 0.05, "transient_s": 0.02, "segment_length": 1024},
        "operation": {"output_speed_deg_s": 45.0, "load_Nm": 75.0},
        "split": {"train_per_state": 1, "test_per_state": 1},
        "states": {"T1": {}, "T2": {"broken_fraction": 1.0}},
    }))
    code, _, err = run(["library", "build", cfg, "--out", tmp_path / "w.zarr", "--workers", "2", "--quiet",
                        "--params", params], capsys)
    assert code == 0, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("warning: fillet-foundation") and "h_fi = 1.057" in lines[0], err
    assert "ModelRangeWarning" not in err and ".py" not in err


# ----------------------------------------------------------------------------- sampling rates
def test_rates_within_a_tenth_of_a_percent_are_the_same_rate():
    assert fs_ratio(47999.99999994, 48000.0) is None
    assert fs_ratio(48000.768, 48000.0) is None  # a rate from a 9-digit time column
    assert fs_ratio(48000.0 * (1 + 0.9 * FS_RTOL), 48000.0) is None
    assert fs_ratio(48100.0, 48000.0) == pytest.approx(48100 / 48000)


@pytest.fixture(scope="module")
def model_48k(tmp_path_factory):
    from rvdiag.cli import main
    from rvdiag.datasets import write_store

    rng = np.random.default_rng(0)
    t = np.arange(256) / 48000.0
    X = [np.sin(2 * np.pi * (3000 + 4000 * c) * t + rng.uniform(0, 6)) + 0.1 * rng.standard_normal(256)
         for c in range(2) for _ in range(12)]
    y = [f"T{c + 1}" for c in range(2) for _ in range(12)]
    store = tmp_path_factory.mktemp("s") / "s.zarr"
    write_store(store, np.asarray(X, np.float32), y,
                meta={"split": (["test"] * 3 + ["train"] * 9) * 2, "unit": list(range(24))},
                kind="simulated", fs=48000.0, config={"name": "fs"})
    out = tmp_path_factory.mktemp("m") / "model"
    try:
        main([str(a) for a in ["train", store, "--model", "cnn1d-lean", "--out", out, "--epochs", "2",
                               "--batch-size", "8", "--device", "cpu", "--seed", "1", "--quiet",
                               "--representation", "waveform"]])
    except SystemExit as exc:  # pragma: no cover - a failure shows here
        assert exc.code == 0
    sig = tmp_path_factory.mktemp("x") / "x.npy"
    np.save(sig, X[0].tolist() * 3)
    return out, sig


@pytest.mark.parametrize("fs, warned", [("48000.768", False), ("47999.99999994", False), ("48100", True)])
def test_diagnose_warns_of_another_rate_only_beyond_the_tolerance(model_48k, fs, warned, capsys):
    model, sig = model_48k
    code, out, err = run(["diagnose", model, sig, "--fs", fs, "--json"], capsys)
    assert code == 0, err
    said = [w for w in json.loads(out)["warnings"] if "model was trained at" in w]
    assert bool(said) == warned, said
    if warned:
        assert said[0].startswith("warning:") and "off by a factor 1.002" in said[0]
