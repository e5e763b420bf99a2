"""Paired libraries (``[baseline]``): each simulated reducer recorded healthy at commissioning, then in
its states, with run-to-run variation between any two records; split by reducer; one store for both roles."""

from __future__ import annotations

import copy
import hashlib
import sys
from pathlib import Path

import numpy as np
import pytest

from rvdiag.datasets import SampleStore
from rvdiag.monitoring.pairing import is_paired, match_baseline
from rvdiag.errors import ConfigError
from rvdiag.library import LibraryConfig, build_library, make_plan
from rvdiag.library.paired import VARIATION_KEYS, apply_variation, draw_variation
from rvdiag.library.work_units import Job, simulator_call

sys.path.insert(0, str(Path(__file__).parent))
from test_library_build import TINY, assert_same_store, tiny  # noqa: E402

SYN = "rvdiag.library.synthetic:simulate"
POINTS = [[30.0, 50.0], [60.0, 130.0], [45.0, 90.0]]
PAIRED = {
    "mode": "split-by-simulation",
    "seed": 27,
    "simulator": SYN,
    "signal": {"fs": 4000.0, "duration_s": 0.5, "transient_s": 0.05, "segment_length": 500, "hop": 500},
    "operation": {"output_speed_deg_s": {"min": 20.0, "max": 70.0}, "load_Nm": {"min": 30.0, "max": 150.0},
                  "noise_snr_db": 20.0, "noise_mode": "floor"},
    "randomise": {"stiffness_pct": 10.0, "damping_pct": 10.0, "specimen": True,
                  "path_resonance_hz": {"min": 1500.0, "max": 9000.0}},
    "baseline": {"operating_points": POINTS, "monitored_healthy": 2, "monitored_per_state": 1},
    "split": {"reducers": 4, "test_reducers": 2},
    "states": {"T1": {}, "T2": {"broken_fraction": {"min": 0.5, "max": 1.0}}, "T4": {}},
}


def paired(**changes):
    data = copy.deepcopy(PAIRED)
    for key, value in changes.items():
        data[key] = {**data.get(key, {}), **value} if isinstance(value, dict) and key != "states" else value
    return LibraryConfig.from_dict(data, source="paired.toml")


def columns(store, keep=None):
    meta = SampleStore.open(store).load().meta
    return {k: np.asarray(v) if keep is None else np.asarray(v)[keep] for k, v in meta.items()}


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    import rvdiag.library.work_units as work_units

    work_units._TWIN_POWERS.clear()
    path = tmp_path_factory.mktemp("paired") / "paired.zarr"
    report = build_library(paired(), path, workers=0, progress=False)
    assert report.built == report.n_units == 4 * (3 + 2 + 1 + 1)
    return path


# ---------------------------------------------------------------------- the plan
def test_plan_is_reducer_by_reducer_with_its_commissioning_records_first():
    plan = make_plan(paired())
    assert [u.index for u in plan] == list(range(len(plan)))
    per = 3 + 2 + 1 + 1
    for r in range(4):
        mine = plan[r * per:(r + 1) * per]
        assert {u.reducer for u in mine} == {r}
        assert [(u.role, u.state) for u in mine] == [("baseline", "T1")] * 3 + [("monitored", "T1")] * 2 + [
            ("monitored", "T2"), ("monitored", "T4")]
        assert [u.operating_point for u in mine[:3]] == [0, 1, 2]  # one commissioning record per point
        # what makes the reducer is drawn once: specimen, stiffness and damping, path, noise level
        for attr in ("specimen", "scales", "mounting", "noise_snr_db"):
            assert all(getattr(u, attr) == getattr(mine[0], attr) for u in mine), attr
    first = [plan[r * per] for r in range(4)]
    assert len({u.specimen["error_seed"] for u in first}) == 4
    assert len({tuple(sorted(u.scales.items())) for u in first}) == 4
    assert len({u.mounting["path_resonance_hz"] for u in first}) == 4


def test_plan_is_deterministic_for_a_seed():
    a, b, c = make_plan(paired()), make_plan(paired()), make_plan(paired(seed=28))
    assert a == b
    assert [u.seed for u in a] != [u.seed for u in c]
    assert a[0].specimen != c[0].specimen


def test_commissioning_records_are_simulated_once_per_reducer():
    """More states add monitored records only; the commissioning records stay one set per reducer."""
    few, many = paired(), paired(states={"T1": {}, "T2": {}, "T3": {}, "T4": {}, "T5": {}, "T6": {}})
    for cfg in (few, many):
        plan = make_plan(cfg)
        base = [u for u in plan if u.role == "baseline"]
        assert len(base) == 4 * len(POINTS)
        assert sorted((u.reducer, u.operating_point) for u in base) == [(r, i) for r in range(4) for i in range(3)]
        assert all(u.state == "T1" and not u.severity for u in base)
    # records_per_point repeats each point
    plan = make_plan(paired(baseline={"records_per_point": 2}))
    assert sum(u.role == "baseline" for u in plan) == 4 * 3 * 2


def test_variation_is_drawn_per_record_within_its_ranges():
    cfg = paired(baseline={"load_pct": 5.0, "gain_pct": 0.0})
    plan = make_plan(cfg)
    pct = {**VARIATION_KEYS, "load": 5.0, "gain": 0.0}
    for u in plan:
        assert list(u.variation) == list(VARIATION_KEYS)
        for key, f in u.variation.items():
            assert abs(f - 1.0) <= pct[key] / 100.0 + 1e-15, (key, f)
        speed, load = cfg.baseline.operating_points[u.operating_point]
        assert u.speed == speed * u.variation["speed"] and u.load_Nm == load * u.variation["load"]
        assert u.variation["gain"] == 1.0
    # every record its own draw (two records of one reducer differ), spread over the range
    loads = np.array([u.variation["load"] for u in plan])
    assert len(set(loads.tolist())) == len(plan)
    assert loads.min() < 0.97 and loads.max() > 1.03
    # monitored records draw their operating point among the baseline's
    assert {u.operating_point for u in plan if u.role == "monitored"} == {0, 1, 2}


def test_variation_reaches_the_simulator_but_not_the_noise_floors_twin():
    cfg = paired()
    unit = make_plan(cfg)[0]
    job = Job.from_config(cfg, cfg.reducer_params())
    _, (params, _), kwargs = simulator_call(unit, job)
    _, (twin_params, _), twin_kwargs = simulator_call(unit, job, twin=True)
    t, d = unit.variation["temperature"], unit.variation["mesh_damping"]
    assert params.material.youngs_modulus == pytest.approx(twin_params.material.youngs_modulus * t, rel=1e-14)
    assert params.bearings.sun_support == pytest.approx(twin_params.bearings.sun_support * t, rel=1e-14)
    assert params.damping.mesh_damping_ratio == pytest.approx(twin_params.damping.mesh_damping_ratio * d, rel=1e-14)
    assert params.damping.bearing_damping_ratio == twin_params.damping.bearing_damping_ratio
    assert kwargs["output_speed_deg_s"] == unit.speed and twin_kwargs["output_speed_deg_s"] == 45.0


def test_draw_and_apply_variation():
    rng = np.random.default_rng(1)
    f = draw_variation(rng, {"speed": 0.0})
    assert f["speed"] == 1.0 and rng.random() == np.random.default_rng(1).random(6)[5]  # always five draws
    from rvdiag.params import ReducerParams

    p = ReducerParams.default()
    q = apply_variation(p, {"temperature": 1.02, "mesh_damping": 0.9, "gain": 1.03})
    assert q.material.youngs_modulus == pytest.approx(1.02 * p.material.youngs_modulus)
    assert q.bearings.output_torsional == pytest.approx(1.02 * p.bearings.output_torsional)
    assert q.damping.mesh_damping_ratio == pytest.approx(0.9 * p.damping.mesh_damping_ratio)
    assert apply_variation(p, {"temperature": 1.0, "mesh_damping": 1.0}) is p


# ---------------------------------------------------------------------- the store
def test_store_records_reducer_role_and_variation_per_sample(store):
    meta = columns(store)
    plan = make_plan(paired())
    for u in plan:
        rows = meta["unit"] == u.index
        assert rows.sum() == 4  # four 500-point samples of each 2000-point record
        assert np.all(meta["reducer"][rows] == u.reducer) and np.all(meta["role"][rows] == u.role)
        assert np.all(meta["operating_point"][rows] == u.operating_point)
        for key, f in u.variation.items():
            assert np.all(meta["variation." + key][rows] == f)
        assert np.all(meta["output_speed_deg_s"][rows] == u.speed) and np.all(meta["load_Nm"][rows] == u.load_Nm)
    # one noise floor per reducer, whatever each record's variation (gain, temperature, damping, load, speed)
    for r in range(4):
        sig = meta["noise_sigma"][meta["reducer"] == r]
        assert np.all(sig == sig[0])


def test_split_is_by_reducer(store):
    meta = columns(store)
    for r in range(4):
        splits = set(meta["split"][meta["reducer"] == r].tolist())
        assert splits == ({"test"} if r >= 2 else {"train"})


def test_is_paired_and_match_baseline_work_on_the_built_store(store):
    meta = columns(store)
    assert is_paired(meta)
    base = meta["role"] == "baseline"
    mon = {k: v[~base] for k, v in meta.items()}
    ref = {k: v[base] for k, v in meta.items()}
    groups = match_baseline(mon, ref, fs=4000.0, baseline_fs=4000.0)
    assert len(groups) == (~base).sum()
    for i, rows in enumerate(groups):
        assert rows.size >= 1
        assert np.all(ref["reducer"][rows] == mon["reducer"][i])
        assert np.all(ref["operating_point"][rows] == mon["operating_point"][i])
    # one split alone is paired too: each held-out reducer brings its own baseline
    test = meta["split"] == "test"
    assert is_paired({k: v[test] for k, v in meta.items()})


def test_signal_carries_the_records_gain(store, tmp_path):
    """Gain +-0 % against the default: the same record scaled by exactly its drawn gain (noise aside: no noise)."""
    quiet = {"output_speed_deg_s": {"min": 20.0, "max": 70.0}, "load_Nm": {"min": 30.0, "max": 150.0}}
    data = copy.deepcopy(PAIRED)
    data["operation"] = quiet
    data["split"] = {"reducers": 1}
    a = LibraryConfig.from_dict(data)
    data["baseline"] = {**data["baseline"], "gain_pct": 0.0}
    b = LibraryConfig.from_dict(data)
    build_library(a, tmp_path / "a.zarr", workers=0, progress=False)
    build_library(b, tmp_path / "b.zarr", workers=0, progress=False)
    xa, xb = SampleStore.open(tmp_path / "a.zarr").load(), SampleStore.open(tmp_path / "b.zarr").load()
    gain = np.asarray(xa.meta["variation.gain"])
    assert np.all(np.asarray(xb.meta["variation.gain"]) == 1.0) and np.all(gain != 1.0)
    np.testing.assert_allclose(xa.X, xb.X * gain[:, None].astype(np.float32), rtol=1e-6, atol=1e-6 * np.abs(xb.X).max())


def test_resume_is_bit_identical(store, tmp_path):
    import rvdiag.library.build as build
    import rvdiag.library.work_units as work_units

    part = tmp_path / "part.zarr"
    calls = []
    real = build._run_checked  # the task: the unit's result with its warnings

    def dies_on_the_tenth(unit, job):
        calls.append(unit.index)
        if len(calls) == 10:
            raise KeyboardInterrupt
        return real(unit, job)

    build._run_checked, saved = dies_on_the_tenth, build._run_checked
    work_units._TWIN_POWERS.clear()  # each process starts without twins
    try:
        with pytest.raises(KeyboardInterrupt):
            build_library(paired(), part, workers=0, progress=False)
    finally:
        build._run_checked = saved
    work_units._TWIN_POWERS.clear()
    report = build_library(paired(), part, workers=0, progress=False)
    assert report.skipped == 9 and report.built == 28 - 9
    assert_same_store(store, part)


# ---------------------------------------------------------------------- a config without [baseline]
def test_a_config_without_baseline_builds_todays_library():
    """The plan of tests/test_library_build.py's TINY (seeds, operating points, noise, scales, severities, split)
    is the one the library built before paired libraries existed (its digest taken from main at cd74c2b), its
    canonical config has no new key, and its units carry no paired fields (so no paired columns)."""
    cfg = tiny()
    plan = make_plan(cfg)
    digest = hashlib.sha256(repr([(u.seed, u.speed, u.load_Nm, u.noise_snr_db, sorted(u.scales.items()),
                                   sorted(u.severity.items()), u.split) for u in plan]).encode()).hexdigest()
    assert digest == "be70832ad6bd6f2b918f482a5ed0ed41f23b3a2df8306b443000e3b7d68c4762"
    d = cfg.to_dict()
    assert "baseline" not in d and set(d["split"]) == {"simulations_per_state", "test_simulations_per_state"}
    assert not cfg.paired and cfg.n_simulations == 12
    assert all(u.reducer is None and u.role is None and not u.variation for u in plan)
    assert not Job.from_config(cfg, cfg.reducer_params()).paired_columns


ARM = {"arm_mass_kg": 15.0, "arm_length_m": 0.5, "arm_angle_deg": {"min": -60.0, "max": 60.0}}


def test_the_joints_arm_is_drawn_once_per_reducer_and_reaches_every_record():
    """A paired library's [profile] holds the gravity arm alone: one per reducer (the joint repeats one motion, so
    its commissioning and later records start at one arm angle), other reducers their own."""
    cfg = paired(profile=ARM)
    plan = make_plan(cfg)
    per = 3 + 2 + 1 + 1
    angles = []
    job = Job.from_config(cfg, cfg.reducer_params())
    for r in range(4):
        mine = plan[r * per:(r + 1) * per]
        assert all(u.profile == mine[0].profile for u in mine)
        assert mine[0].profile["profile"] == 0 and mine[0].profile["accel_deg_s2"] is None  # constant speed
        angles.append(mine[0].profile["arm_angle_deg"])
        for u in (mine[0], mine[-1]):
            _, _, kwargs = simulator_call(u, job)
            lp = kwargs["load_profile"]
            assert (lp.arm_mass_kg, lp.arm_length_m, lp.arm_angle_deg) == (15.0, 0.5, angles[-1])
            assert "profile" not in kwargs
        assert "load_profile" not in simulator_call(mine[0], job, twin=True)[2]  # the noise floor's twin: no arm
    assert len(set(angles)) == 4 and all(-60.0 <= a <= 60.0 for a in angles)
    # the arm is drawn after everything else of the reducer: the reducers themselves are those without it
    for a, b in zip(plan, make_plan(paired())):
        assert (a.specimen, a.scales, a.seed, a.variation, a.speed) == (b.specimen, b.scales, b.seed, b.variation,
                                                                        b.speed)


@pytest.mark.parametrize("profile", [{"trapezoid_fraction": 0.5, "accel_deg_s2": 1000.0},
                                     {"accel_deg_s2": 100.0, **ARM}])
def test_a_paired_librarys_profile_holds_the_arm_alone(profile):
    with pytest.raises(ConfigError, match=r"\[profile\] may hold only the gravity arm"):
        paired(profile=profile)


def test_shipped_current_monitoring_config_is_paired_current_with_one_arm_per_joint():
    cfg = LibraryConfig.load("monitoring-current")
    assert cfg.paired and cfg.model["signal"] == "current" and cfg.channel == "i_a" and cfg.specimen
    assert cfg.baseline.operating_points == ((45.0, 20.0),) and cfg.baseline.records_per_point >= 2
    assert cfg.classes == ["T1", "T2", "T8"] and set(cfg.profile.arm) == {"arm_mass_kg", "arm_length_m",
                                                                           "arm_angle_deg"}
    mcsa = LibraryConfig.load("mcsa")
    assert cfg.profile.arm == mcsa.profile.arm and cfg.fs == mcsa.fs and cfg.load_Nm == mcsa.load_Nm
    assert cfg.states["T2"] == mcsa.states["T2"] and cfg.states["T8"] == mcsa.states["T8"]


def test_paired_config_round_trips_and_hashes_its_table():
    cfg = paired()
    again = LibraryConfig.from_dict(cfg.to_dict())
    assert again == cfg and make_plan(again) == make_plan(cfg)
    assert cfg.to_dict()["baseline"]["load_pct"] == 3.0 and cfg.to_dict()["split"] == {"reducers": 4,
                                                                                          "test_reducers": 2}
    assert paired(baseline={"speed_pct": 2.0}).to_dict() != cfg.to_dict()
    assert cfg.n_simulations == 28 and cfg.n_samples == 28 * 4


@pytest.mark.parametrize("change, match", [
    ({"mode": "paper", "split": {"train_per_state": 1, "test_per_state": 0}}, "splits by reducer"),
    ({"operation": {"output_speed_deg_s": None}}, None),
    ({"states": {"T2": {}, "T4": {}}}, r"needs \[states.T1\]"),
    ({"baseline": {"operating_points": [[80.0, 50.0]]}}, r"operating_points\[0\].*\[operation\] ranges"),
    ({"baseline": {"operating_points": [[30.0, 50.0], [30.0, 50.0]]}}, "listed twice"),
    ({"baseline": {"operating_points": []}}, "operating_points: missing"),
    ({"baseline": {"gain_pct": 100.0}}, r"gain_pct: must lie in \[0, 100\)"),
    ({"split": {"simulations_per_state": 3}}, "records per reducer"),
    ({"split": {"test_reducers": 4}}, "leaves no training reducer"),
    ({"baseline": {"colour": 1}}, "unknown key 'colour'"),
])
def test_bad_paired_configs_name_the_key(change, match):
    data = copy.deepcopy(PAIRED)
    for key, value in change.items():
        if isinstance(value, dict) and key not in ("states",) and isinstance(data.get(key), dict):
            data[key] = {**data[key], **value}
        else:
            data[key] = value
    if match is None:  # input speed instead of output speed
        data["operation"] = {"input_speed_rpm": 1500.0, "load_Nm": {"min": 30.0, "max": 150.0}}
        match = "matched by output speed"
    if "mode" in change:
        data["split"] = change["split"]
    with pytest.raises(ConfigError, match=match):
        LibraryConfig.from_dict(data, source="paired.toml")


def test_reducers_without_baseline_is_refused():
    with pytest.raises(ConfigError, match=r"reducers: only for a paired library"):
        LibraryConfig.from_dict({**TINY, "split": {**TINY["split"], "reducers": 3}})


def test_shipped_monitoring_config_is_paired():
    cfg = LibraryConfig.load("monitoring")
    b = cfg.baseline
    assert cfg.paired and cfg.specimen and cfg.noise_floor and cfg.noise_snr_db.values == (20.0,)
    assert len(b.operating_points) == 6 and cfg.classes == ["T1", "T2", "T3", "T4", "T5", "T6"]
    assert (cfg.speed.lo, cfg.speed.hi, cfg.load_Nm.lo, cfg.load_Nm.hi) == (20.0, 70.0, 30.0, 150.0)
    # enough healthy monitored records in the held-out reducers to measure a 1 % alarm, and in the training ones to
    # calibrate it by CV+ (ceil(1/0.01) - 1 = 99)
    assert b.test_reducers * b.monitored_healthy >= 99
    assert (b.reducers - b.test_reducers) * b.monitored_healthy >= 99
    # the TSA change's own spread from two commissioning records per point, not the windows of one
    assert b.records_per_point == 2
    demo = LibraryConfig.load("demo-monitoring").baseline
    assert demo.records_per_point == 2 and (demo.reducers - demo.test_reducers) * demo.monitored_healthy >= 19
    # the same fault sweeps as the independent library, except wear: a robot's life of it (3-9 um, docs/library.md)
    for state, sweeps in LibraryConfig.load("independent").states.items():
        assert {k: v for k, v in cfg.states[state].items() if k != "wear_depth"} == \
            {k: v for k, v in sweeps.items() if k != "wear_depth"}
        if "wear_depth" in sweeps:
            w = cfg.states[state]["wear_depth"]
            assert (w.lo, w.hi) == pytest.approx((3e-6, 9e-6)), (state, w)
