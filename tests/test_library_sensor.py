"""Domain randomisation of the accelerometer in library configs (``[randomise] sensor_position_deg`` and
``sensor_direction_deg``): parsing, draws after every earlier draw, the recorded columns, the projection of the
simulator's x and y channels (0 deg gives x, 90 deg y), and the moved sensor point on the dynamic model."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from rvdiag.datasets import SampleStore
from rvdiag.errors import ConfigError
from rvdiag.library import LibraryConfig, build_library, make_plan, run_unit
from rvdiag.library.build import Job
from test_library_build import TINY, assert_same_store

FS = 4000.0


def xy_simulator(params, fault=None, *, duration_s, transient_s, fs, seed, model, **operating):
    """A two-channel stand-in: x a 100 Hz sine, y a 130 Hz cosine (each seeded in phase), known exactly."""
    n = int(round(duration_s * fs))
    t = np.arange(n) / fs
    ph = np.random.default_rng(seed).uniform(0, 2 * np.pi, 2)
    return SimpleNamespace(signal=np.stack([np.sin(2 * np.pi * 100 * t + ph[0]), np.cos(2 * np.pi * 130 * t + ph[1])]),
                           fs=float(fs), channel_names=["x", "y"])


XY = {**TINY, "simulator": "test_library_sensor:xy_simulator",
      "operation": {"input_speed_rpm": 1500.0, "load_Nm": 50.0},
      "randomise": {"sensor_direction_deg": {"min": 0.0, "max": 360.0}}}
NO_SENSOR = {**XY, "randomise": {}}


def cfg_of(data, **changes):
    return LibraryConfig.from_dict({**data, **changes}, source="sensor.toml")


@pytest.mark.parametrize("randomise, extra, match", [
    ({"sensor_direction_deg": {"min": 0.0, "max": 400.0}}, {}, r"sensor_direction_deg: must lie in \[-360, 360\]"),
    ({"sensor_direction_deg": 30.0}, {"channel": 1}, r"sensor_direction_deg: the channel is the drawn direction"),
    ({"sensor_position_deg": 30.0}, {"simulator": "rvdiag.library.synthetic:simulate"},
     r"sensor_position_deg: moves the dynamic model's sensor point"),
    ({"sensor_direction_deg": 30.0}, {"simulator": "rvdiag.library.simulators:dynamics",
                                      "model": {"sensor_directions": [[1.0, 0.0]]}},
     r"remove \[model\] sensor_directions"),
    ({"sensor_direction_deg": 30.0}, {"simulator": "rvdiag.library.simulators:dynamics",
                                      "model": {"signal": "current"}}, r"a motor-current library has no accelerometer"),
])
def test_bad_sensor_keys_are_one_line_errors(randomise, extra, match):
    with pytest.raises(ConfigError, match=match) as exc:
        cfg_of(XY, randomise=randomise, **extra)
    assert str(exc.value).startswith("sensor.toml: [randomise]") and "\n" not in str(exc.value)


def test_the_geometry_0_deg_is_x_90_deg_is_y():
    unit = make_plan(cfg_of(XY))[0]
    R = 0.1
    for pos, dirn, point, d in ((None, 0.0, None, (1, 0)), (None, 90.0, None, (0, 1)), (None, 210.0, None,
                                (math.cos(math.radians(210)), math.sin(math.radians(210)))),
                                (90.0, 0.0, (0, R), (0, 1)),     # radial at the top of the housing: y
                                (90.0, 90.0, (0, R), (-1, 0)),   # tangential there: -x
                                (180.0, None, (-R, 0), (-1, 0))):
        sensor = {k: v for k, v in (("sensor_position_deg", pos), ("sensor_direction_deg", dirn)) if v is not None}
        got_point, got_dir = type(unit)(**{**unit.__dict__, "sensor": sensor}).sensor_geometry(R)
        assert got_dir == pytest.approx(d, abs=1e-15)
        assert (got_point is None) if point is None else got_point == pytest.approx(point, abs=1e-15)


def test_the_draws_are_recorded_reproducible_and_come_last(tmp_path):
    cfg = cfg_of(XY)
    plan, plain = make_plan(cfg), make_plan(cfg_of(NO_SENSOR))
    for a, b in zip(plan, plain):  # every other draw as without the sensor keys
        assert (a.seed, a.severity, a.speed, a.load_Nm, a.noise_snr_db, a.scales, a.profile) == \
               (b.seed, b.severity, b.speed, b.load_Nm, b.noise_snr_db, b.scales, b.profile)
        assert set(a.sensor) == {"sensor_direction_deg"} and 0.0 <= a.sensor["sensor_direction_deg"] <= 360.0
        assert b.sensor == {}
    assert make_plan(cfg) == plan and make_plan(cfg_of(XY, seed=7)) != plan
    assert len({u.sensor["sensor_direction_deg"] for u in plan}) == len(plan)  # drawn per simulation
    assert "sensor_direction_deg" not in cfg_of(NO_SENSOR).to_dict()["randomise"]  # older configs keep their hash
    build_library(cfg, tmp_path / "a.zarr", workers=0, progress=False)
    build_library(cfg, tmp_path / "b.zarr", workers=0, progress=False)
    assert_same_store(tmp_path / "a.zarr", tmp_path / "b.zarr")
    d = SampleStore.open(tmp_path / "a.zarr").load("all")
    job = Job.from_config(cfg, cfg.reducer_params())
    for u in plan:
        rows = np.flatnonzero(d.meta["unit"] == u.index)
        assert np.all(d.meta["sensor_direction_deg"][rows] == u.sensor["sensor_direction_deg"])
        # every sample is cos(psi) x + sin(psi) y of the simulator's own channels
        res = xy_simulator(None, duration_s=cfg.duration_s, transient_s=cfg.transient_s, fs=cfg.fs,
                           seed=int(np.random.SeedSequence(u.seed).spawn(4)[1].generate_state(1, np.uint32)[0]),
                           model={})
        psi = math.radians(u.sensor["sensor_direction_deg"])
        want = math.cos(psi) * res.signal[0] + math.sin(psi) * res.signal[1]
        for r in rows:
            s = int(round(d.meta["t_start_s"][r] * cfg.fs))
            np.testing.assert_allclose(d.X[r], want[s:s + cfg.segment_length], atol=1e-6)
    # direction 0 is the x channel, 90 the y channel, exactly as the unit without the key reads channels 0 and 1
    u = plan[0]
    x0 = run_unit(type(u)(**{**u.__dict__, "sensor": {"sensor_direction_deg": 0.0}}), job).X
    y90 = run_unit(type(u)(**{**u.__dict__, "sensor": {"sensor_direction_deg": 90.0}}), job).X
    plain_job = Job.from_config(cfg_of(NO_SENSOR), cfg.reducer_params())
    chan1 = Job(**{**plain_job.__dict__, "channel": 1})
    np.testing.assert_array_equal(x0, run_unit(type(u)(**{**u.__dict__, "sensor": {}}), plain_job).X)
    np.testing.assert_allclose(y90, run_unit(type(u)(**{**u.__dict__, "sensor": {}}), chan1).X, atol=1e-7)


def test_a_moved_sensor_on_the_dynamic_model(tmp_path):
    """The dynamic model with the sensor at 90 deg around the housing: a radial sensor there reads the model's y
    channel at that point (simulate with ModelSettings(sensor_point_m=(0, R))); the rotation of the housing makes it
    differ from the y channel at the default point."""
    from rvdiag.dynamics import ModelSettings, simulate

    data = {"mode": "split-by-simulation", "seed": 3, "model": {"substeps": 4},
            "signal": {"fs": 24000.0, "duration_s": 0.03, "transient_s": 0.02, "segment_length": 240},
            "operation": {"output_speed_deg_s": 45.0, "load_Nm": 80.0},
            "randomise": {"sensor_position_deg": 90.0, "sensor_direction_deg": 0.0},
            "split": {"simulations_per_state": 1}, "states": {"T1": {}, "T2": {}}}
    cfg = LibraryConfig.from_dict(data)
    unit = make_plan(cfg)[0]
    assert unit.state == "T1" and unit.sensor == {"sensor_position_deg": 90.0, "sensor_direction_deg": 0.0}
    params = cfg.reducer_params()
    got = run_unit(unit, Job.from_config(cfg, params))
    assert got.meta["sensor_position_deg"] == [90.0] * got.X.shape[0]
    R = params.bodies.pin_wheel_outer_radius
    kw = dict(output_speed_deg_s=45.0, load_Nm=80.0, duration_s=0.03, fs=24000.0)
    at_top = simulate(params, None, settings=ModelSettings(substeps=4, transient_s=0.02, sensor_point_m=(0.0, R)), **kw)
    at_side = simulate(params, None, settings=ModelSettings(substeps=4, transient_s=0.02), **kw)
    want = at_top.signal[1, :240 * got.X.shape[0]].reshape(got.X.shape)
    np.testing.assert_allclose(got.X, want, rtol=1e-5, atol=1e-6 * np.abs(want).max())
    assert np.max(np.abs(at_side.signal[1] - at_top.signal[1])) > 0.01 * np.abs(at_top.signal[1]).max()


def test_sensor_and_scurve_library_on_the_simulated_gpu_equals_the_cpu_build():
    """The GPU path (`--device cuda`, under numba's CUDA simulator) prepares and finishes each unit as the CPU does:
    a config with S-curves and a drawn sensor position and direction writes the CPU build's store, bit for bit."""
    from test_gpu_ensemble import _in_simulator

    data = {"mode": "split-by-simulation", "seed": 5, "model": {"substeps": 4, "chunk_samples": 80},
            "signal": {"fs": 48000.0, "duration_s": 0.004, "transient_s": 0.002, "segment_length": 64, "hop": 32},
            "operation": {"output_speed_deg_s": {"min": 30.0, "max": 60.0}, "load_Nm": 50.0},
            "randomise": {"sensor_position_deg": {"min": 0.0, "max": 360.0}, "sensor_direction_deg": [0.0, 90.0]},
            "profile": {"scurve_fraction": 1.0, "accel_deg_s2": 1e5, "jerk_deg_s3": 1e8},
            "split": {"simulations_per_state": 2}, "states": {"T1": {}, "T2": {"broken_fraction": 1.0}}}
    res = _in_simulator(f"""
        import json
        import numpy as np
        from rvdiag.datasets import SampleStore
        from rvdiag.library import LibraryConfig, build_library
        import tempfile, pathlib

        tmp = pathlib.Path(tempfile.mkdtemp())
        cfg = LibraryConfig.from_dict({data!r})
        build_library(cfg, tmp / "cpu.zarr", workers=0, progress=False)
        rep = build_library(cfg, tmp / "gpu.zarr", workers=0, progress=False, device="cuda", ensemble=4)
        a, b = SampleStore.open(tmp / "cpu.zarr").load(), SampleStore.open(tmp / "gpu.zarr").load()
        same = bool(np.array_equal(a.X, b.X) and sorted(a.meta) == sorted(b.meta) and all(
            np.array_equal(a.meta[k], b.meta[k], equal_nan=a.meta[k].dtype.kind == "f") for k in a.meta))
        print(json.dumps({{"device": rep.device, "same": same, "profiles": sorted(set(a.meta["profile"].tolist())),
                          "positions": len(set(a.meta["sensor_position_deg"].tolist()))}}))
    """)
    assert res == {"device": "cuda", "same": True, "profiles": [2], "positions": 4}
