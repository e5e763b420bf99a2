"""Specimens (``[randomise] specimen``) and the noise floor (``[operation] noise_mode``): draws, records, resume,
today's store without the keys, one floor per reducer, warnings, ``library info``.

The build machinery runs on the synthetic stand-in (it ignores the manufacturing errors, so the specimen reaching the
simulator is checked on the parameters it gets); the floor's twin on the dynamic model is checked in
``test_floor_twin_on_the_dynamic_model``.
"""

import json
import math
import warnings

import numpy as np
import pytest

from rvdiag.cli import main
from rvdiag.datasets import SampleStore
from rvdiag.dynamics.noise import add_awgn, add_coloured_noise, add_noise_power
from rvdiag.errors import ConfigError, RvdiagWarning
from rvdiag.library import LibraryConfig, build_library, make_plan
from rvdiag.library.config import DAMPING_KEYS, STIFFNESS_KEYS
from rvdiag.library.build import Job, _streams, finish_unit, simulator_call, twin_power, unit_params
from rvdiag.library.specimens import count_specimens, draw_specimen, specimen_seed
from rvdiag.params import ReducerParams

SYN = "rvdiag.library.synthetic:simulate"

BASE = {
    "mode": "split-by-simulation", "seed": 42, "simulator": SYN,
    "signal": {"fs": 4000.0, "duration_s": 0.5, "transient_s": 0.05, "segment_length": 500, "hop": 250},
    "operation": {"input_speed_rpm": {"min": 1000.0, "max": 2000.0}, "load_Nm": [50.0, 100.0],
                  "noise_snr_db": {"min": 5.0, "max": 20.0}},
    "randomise": {"stiffness_pct": 10.0, "damping_pct": 10.0, "noise_colour_exponent": {"min": 0.0, "max": 1.0}},
    "split": {"simulations_per_state": 3, "test_simulations_per_state": 1},
    "states": {"T1": {}, "T2": {"broken_fraction": {"min": 0.5, "max": 1.0}}},
}
#: the metadata columns of this config's store before specimens and noise modes existed
TODAY_COLUMNS = {"broken_fraction", "input_speed_rpm", "load_Nm", "noise_colour_exponent", "noise_snr_db", "seed",
                 "segment", "simulation", "split", "state", "t_start_s", "unit"} | \
    {f"scale.{s}.{k}" for s, k in STIFFNESS_KEYS + DAMPING_KEYS}


def cfg(operation=None, randomise=None, **top):
    data = {**BASE, **top}
    data["operation"] = {**BASE["operation"], **(operation or {})}
    data["randomise"] = {**BASE["randomise"], **(randomise or {})}
    return LibraryConfig.from_dict(data, source="spec.toml")


SPEC = {"specimen": True, "iso1328_grade": {"min": 4, "max": 6}}
FLOOR = {"noise_mode": "floor"}


def load(path):
    return SampleStore.open(path).load()


def same_store(a, b):
    xa, xb = load(a), load(b)
    np.testing.assert_array_equal(xa.X, xb.X)
    assert sorted(xa.meta) == sorted(xb.meta)
    for key in xa.meta:
        np.testing.assert_array_equal(xa.meta[key], xb.meta[key], err_msg=key)


# ---------------------------------------------------------------------- the draw
def test_draw_specimen_is_seeded_and_grades_are_whole_classes_in_the_range():
    sweep = cfg(randomise=SPEC).iso1328_grade
    draws = [draw_specimen(s, sweep) for s in range(300)]
    assert draws == [draw_specimen(s, sweep) for s in range(300)]
    assert len({d["error_seed"] for d in draws}) == 300
    grades = [d["iso1328_grade"] for d in draws]
    assert set(grades) == {4, 5, 6} and min(grades.count(g) for g in (4, 5, 6)) > 70
    # a grade sweep draws after the error seed: adding it keeps every error seed
    assert [draw_specimen(s)["error_seed"] for s in range(300)] == [d["error_seed"] for d in draws]
    assert draw_specimen(3, 7)["iso1328_grade"] == 7 and "iso1328_grade" not in draw_specimen(3)


def test_units_draw_their_own_specimens_without_moving_other_draws():
    plain, spec = make_plan(cfg()), make_plan(cfg(randomise=SPEC))
    assert all(u.specimen == {} for u in plain)
    assert len({u.specimen["error_seed"] for u in spec}) == len(spec)
    for a, b in zip(plain, spec):  # the specimen stream is the unit's fifth: nothing else moved
        assert (a.seed, a.severity, a.speed, a.load_Nm, a.noise_snr_db, a.scales, a.noise_exponent) == \
               (b.seed, b.severity, b.speed, b.load_Nm, b.noise_snr_db, b.scales, b.noise_exponent)
        assert b.specimen == draw_specimen(specimen_seed(b.seed), cfg(randomise=SPEC).iso1328_grade)
    unit = spec[1]  # the simulator gets the unit's specimen
    params = simulator_call(unit, Job.from_config(cfg(randomise=SPEC), ReducerParams.default()))[1][0]
    assert params.modification.error_seed == unit.specimen["error_seed"]
    assert params.modification.iso1328_grade == unit.specimen["iso1328_grade"]


def test_config_checks():
    with pytest.raises(ConfigError, match="iso1328_grade: drawn per specimen; add specimen = true"):
        cfg(randomise={"iso1328_grade": 5})
    with pytest.raises(ConfigError, match=r"iso1328_grade: whole ISO 1328 classes in \[0, 11\]"):
        cfg(randomise={"specimen": True, "iso1328_grade": 4.5})
    with pytest.raises(ConfigError, match="specimen: expected true or false"):
        cfg(randomise={"specimen": 1})
    with pytest.raises(ConfigError, match="noise_mode: must be one of record, floor"):
        cfg(operation={"noise_mode": "sensor"})
    with pytest.raises(ConfigError, match="not both"):
        cfg(operation={"noise_mode": "floor", "noise_density_ug_per_rthz": 50.0})
    with pytest.raises(ConfigError, match="a noise density is a floor"):
        cfg(operation={"noise_density_ug_per_rthz": 50.0})
    c = cfg(operation=FLOOR, randomise=SPEC)
    assert LibraryConfig.from_dict(c.to_dict()) == c and c.noise_reference() == (1500.0, 75.0)
    assert "specimen" not in cfg().to_dict()["randomise"] and "noise_mode" not in cfg().to_dict()["operation"]


def test_old_mode_spelling_is_accepted_with_one_warning():
    with pytest.warns(RvdiagWarning, match="mode = 'independent' is now spelled 'split-by-simulation'"):
        old = cfg(mode="independent")
    assert old == cfg()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        LibraryConfig.from_dict({**BASE, "mode": "independent"}, source="<store>")  # an old store: silent


# ---------------------------------------------------------------------- stores
@pytest.fixture(scope="module")
def spec_store(tmp_path_factory):
    path = tmp_path_factory.mktemp("spec") / "spec.zarr"
    build_library(cfg(operation=FLOOR, randomise=SPEC), path, workers=0, progress=False)
    return path


def test_specimens_are_recorded_per_sample_and_repeat_with_the_seed(spec_store, tmp_path):
    d = load(spec_store)
    plan = make_plan(cfg(operation=FLOOR, randomise=SPEC))
    for u in plan:
        rows = d.meta["unit"] == u.index
        assert set(d.meta["error_seed"][rows].tolist()) == {u.specimen["error_seed"]}
        assert set(d.meta["iso1328_grade"][rows].tolist()) == {u.specimen["iso1328_grade"]}
    assert count_specimens(d.meta) == len(plan) == 6
    again = tmp_path / "again.zarr"
    build_library(cfg(operation=FLOOR, randomise=SPEC), again, workers=0, progress=False)
    same_store(spec_store, again)


def test_resume_is_bit_identical(spec_store, tmp_path):
    part = tmp_path / "part.zarr"
    c = cfg(operation=FLOOR, randomise=SPEC)
    import rvdiag.library.build as build

    calls = []
    real = build._run_checked  # the task: the unit's result with its warnings

    def dies_on_the_fourth(unit, job):
        calls.append(unit.index)
        if len(calls) == 4:
            raise KeyboardInterrupt
        return real(unit, job)

    build._run_checked, saved = dies_on_the_fourth, build._run_checked
    build._TWIN_POWERS.clear()  # the resumed process starts without the first one's twins
    try:
        with pytest.raises(KeyboardInterrupt):
            build_library(c, part, workers=0, progress=False)
    finally:
        build._run_checked = saved
    build._TWIN_POWERS.clear()
    report = build_library(c, part, workers=0, progress=False)
    assert report.skipped == 3 and report.built == 3
    same_store(spec_store, part)


def test_a_config_without_the_keys_builds_todays_store(tmp_path):
    """Today's store: the columns it had, and every sample the old code path's record (the simulator's call, then
    add_coloured_noise on the unit's noise stream, as finish_unit did) gives, recomputed here in the same run."""
    c = cfg()
    path = tmp_path / "today.zarr"
    build_library(c, path, workers=0, progress=False)
    d = load(path)
    assert set(d.meta) == TODAY_COLUMNS
    job = Job.from_config(c, ReducerParams.default())
    for u in make_plan(c):
        sim, args, kwargs = simulator_call(u, job)
        assert args[0] == unit_params(u, job) and args[0].modification == ReducerParams.default().modification
        x = np.asarray(sim(*args, **kwargs).signal[0], dtype=np.float64)[: job.samples_per_signal]
        x = add_coloured_noise(x, u.noise_snr_db, u.noise_exponent, np.random.default_rng(_streams(u.seed)[2]))
        rows = np.flatnonzero(d.meta["unit"] == u.index)
        for r in rows:
            s = int(d.meta["segment"][r]) * c.hop
            np.testing.assert_array_equal(d.X[r], x[s: s + c.segment_length].astype(np.float32))


# ---------------------------------------------------------------------- the noise floor
class _Result:
    def __init__(self, x, fs):
        self.signal, self.fs = x[None, :], fs


def _finish(c, unit, x):
    return finish_unit(unit, Job.from_config(c, ReducerParams.default()), _Result(x, c.fs), 0.0)


def test_floor_noise_is_one_level_per_reducer_whatever_the_state():
    """No randomisation: every unit is one reducer; a louder state gets the same noise sigma, not a louder one."""
    c = cfg(operation={**FLOOR, "noise_snr_db": 20.0}, randomise={"stiffness_pct": 0.0, "damping_pct": 0.0,
                                                                    "noise_colour_exponent": 0.0})
    healthy, faulty = make_plan(c)[0], make_plan(c)[3]
    job = Job.from_config(c, ReducerParams.default())
    quiet = np.sin(np.arange(2000) * 0.3)
    res_h, res_f = _finish(c, healthy, quiet), _finish(c, faulty, 10.0 * quiet)  # the fault 20 dB louder
    sigma = twin_power(healthy, job) ** 0.5 * 10.0 ** (-20.0 / 20.0)
    assert res_h.meta["noise_sigma"][0] == res_f.meta["noise_sigma"][0] == pytest.approx(sigma, rel=1e-12)
    assert res_h.meta["noise_mode"][0] == "floor"
    noise_f = res_f.X[0].astype(float) - 10.0 * quiet[:500]
    assert np.std(noise_f) == pytest.approx(sigma, rel=0.15)
    # record mode: the louder state's noise is 10 x louder
    r = cfg(operation={"noise_mode": "record", "noise_snr_db": 20.0}, randomise={"noise_colour_exponent": 0.0})
    rec_h, rec_f = _finish(r, make_plan(r)[0], quiet), _finish(r, make_plan(r)[3], 10.0 * quiet)
    assert rec_f.meta["noise_sigma"][0] == pytest.approx(10.0 * rec_h.meta["noise_sigma"][0], rel=1e-12)


def test_record_mode_named_keeps_the_samples_and_adds_its_columns(tmp_path):
    plain, named = tmp_path / "plain.zarr", tmp_path / "named.zarr"
    build_library(cfg(), plain, workers=0, progress=False)
    build_library(cfg(operation={"noise_mode": "record"}), named, workers=0, progress=False)
    a, b = load(plain), load(named)
    np.testing.assert_array_equal(a.X, b.X)
    assert set(b.meta) - set(a.meta) == {"noise_mode", "noise_sigma"}
    assert np.all(b.meta["noise_mode"] == "record") and np.all(b.meta["noise_sigma"] > 0)


def test_coloured_floor_noise_has_the_stated_power_and_colour():
    rng = np.random.default_rng(0)
    pink = add_noise_power(np.zeros(2**16), 2.5, 1.0, rng)
    assert np.mean(pink**2) == pytest.approx(2.5, rel=1e-12)
    spec = np.abs(np.fft.rfft(pink)) ** 2
    low, high = spec[100:200].mean(), spec[10000:20000].mean()
    assert low / high > 30  # 1/f: ~100 x between these bands
    x = np.sin(np.arange(5000.0))  # the snr functions are add_noise_power at the signal's own power
    p = float(np.mean(x**2)) * 10 ** -1.5
    np.testing.assert_array_equal(add_awgn(x, 15.0, 3), add_noise_power(x, p, 0.0, 3))
    np.testing.assert_allclose(add_coloured_noise(x, 15.0, 1.0, 3), add_noise_power(x, p, 1.0, 3), rtol=1e-12)


def test_density_floor_gives_sigma_from_the_datasheet():
    data = {**BASE, "operation": {"input_speed_rpm": 1500.0, "load_Nm": 60.0, "noise_mode": "floor",
                                  "noise_density_ug_per_rthz": 100.0}}
    c = LibraryConfig.from_dict(data)
    unit = make_plan(c)[0]
    res = _finish(c, unit, np.zeros(2000))
    assert unit.noise_density == 100.0
    assert res.meta["noise_sigma"][0] == pytest.approx(100e-6 * 9.80665 * math.sqrt(2000.0), rel=1e-12)


def test_floor_twin_on_the_dynamic_model():
    """The twin is the same reducer healthy at the reference point: specimen-dependent, state-independent."""
    data = {"mode": "split-by-simulation", "seed": 3, "model": {"substeps": 4},
            "signal": {"fs": 24000.0, "duration_s": 0.05, "transient_s": 0.02, "segment_length": 600},
            "operation": {"output_speed_deg_s": {"min": 30.0, "max": 60.0}, "load_Nm": 80.0, "noise_snr_db": 20.0,
                          "noise_mode": "floor"},
            "randomise": {"specimen": True},
            "split": {"simulations_per_state": 2, "test_simulations_per_state": 1},
            "states": {"T1": {}, "T2": {"broken_fraction": 1.0}}}
    c = LibraryConfig.from_dict(data)
    job = Job.from_config(c, ReducerParams.default())
    units = make_plan(c)
    _, args, kwargs = simulator_call(units[2], job, twin=True)
    assert args[1] is None and kwargs["output_speed_deg_s"] == 45.0 and kwargs["seed"] == 0
    assert kwargs["duration_s"] == 0.05 and args[0].modification.error_seed == units[2].specimen["error_seed"]
    powers = [twin_power(u, job) for u in units]
    assert len(set(powers)) == len(units)  # each specimen its own healthy power
    # the same specimen in another state: the same twin
    other = type(units[0])(**{**units[0].__dict__, "state": "T2", "severity": {"broken_fraction": 1.0}})
    assert twin_power(other, job) == powers[0]


# ---------------------------------------------------------------------- warnings and the CLI
def run(args):
    """Run the CLI; return the exit code (0 when main returns normally)."""
    try:
        main(args)
    except SystemExit as exc:
        return 0 if exc.code is None else exc.code
    return 0


def test_fixed_error_seed_in_params_warns_once(tmp_path, capsys):
    params = tmp_path / "p.toml"
    ReducerParams.default().replace(modification={"error_seed": 7}).save(params)
    c = cfg(operation=FLOOR, randomise=SPEC).replace(params=str(params))
    with pytest.warns(RvdiagWarning, match=r"\[modification\] error_seed = 7 is not used"):
        build_library(c, tmp_path / "a.zarr", workers=0, progress=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        build_library(cfg().replace(params=str(params)), tmp_path / "b.zarr", workers=0, progress=False)
    # the CLI: one warning line
    conf = tmp_path / "c.toml"
    import tomli_w

    conf.write_text(tomli_w.dumps(cfg(operation=FLOOR, randomise=SPEC).to_dict()))
    capsys.readouterr()
    assert run(["library", "build", str(conf), "--params", str(params), "--out", str(tmp_path / "c.zarr"),
                "--workers", "0", "--quiet"]) == 0
    lines = [l for l in capsys.readouterr().err.splitlines() if l.startswith("warning:")]
    assert len(lines) == 1 and "error_seed = 7" in lines[0]


def test_library_info_counts_specimens(spec_store, tmp_path, capsys):
    assert run(["library", "info", str(spec_store), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["specimens"] == 6
    assert run(["library", "info", str(spec_store)]) == 0
    assert "6 specimens" in capsys.readouterr().out
    plain = tmp_path / "plain.zarr"
    build_library(cfg(), plain, workers=0, progress=False)
    capsys.readouterr()
    assert run(["library", "info", str(plain), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["specimens"] == 1


def test_floor_and_specimens_on_the_simulated_gpu_equal_the_cpu_build(tmp_path):
    """--device cuda integrates each unit's healthy twin in the ensemble: the CPU build's store, bit for bit
    (numba's CUDA simulator in a child process, as tests/test_gpu_ensemble.py runs the GPU path)."""
    import os
    import subprocess
    import sys
    import textwrap

    from conftest import REPO

    tiny = {"mode": "split-by-simulation", "seed": 3, "model": {"substeps": 4, "chunk_samples": 80},
            "signal": {"fs": 48000.0, "duration_s": 0.004, "transient_s": 0.002, "segment_length": 64, "hop": 32},
            "operation": {"input_speed_rpm": {"min": 1000.0, "max": 2000.0}, "load_Nm": [50.0, 100.0],
                          "noise_snr_db": 20.0, "noise_mode": "floor"},
            "randomise": {"specimen": True, "noise_colour_exponent": 1.0},
            "split": {"simulations_per_state": 1, "test_simulations_per_state": 0},
            "states": {"T1": {}, "T2": {"broken_fraction": 1.0}}}
    code = f"""
        import json, numpy as np
        import rvdiag.library.build as build
        from rvdiag.datasets import SampleStore
        from rvdiag.library import LibraryConfig, build_library
        c = LibraryConfig.from_dict({tiny!r})
        build_library(c, {str(tmp_path / 'cpu.zarr')!r}, workers=0, progress=False)
        build._TWIN_POWERS.clear()
        rep = build_library(c, {str(tmp_path / 'gpu.zarr')!r}, workers=0, progress=False, device="cuda", ensemble=4)
        a, b = SampleStore.open({str(tmp_path / 'cpu.zarr')!r}).load(), SampleStore.open({str(tmp_path / 'gpu.zarr')!r}).load()
        same = bool(np.array_equal(a.X, b.X) and all(np.array_equal(a.meta[k], b.meta[k],
                                                                 equal_nan=a.meta[k].dtype.kind == "f") for k in a.meta))
        print(json.dumps([rep.device, same, len(set(a.meta["noise_sigma"].tolist()))]))
    """
    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1",
           "PYTHONPATH": os.pathsep.join([str(REPO / "src"), str(REPO / "tests")])}
    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], env=env, cwd=REPO, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-4000:]
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == ["cuda", True, 2], proc.stdout
