"""Life-history libraries (``[history]``): each simulated reducer recorded at commissioning, then every
``interval_days`` along one drawn fate, with the truth per record in the ``life.*`` columns; a paired store that
``rvdiag train`` accepts; deterministic, resumable; a paired config without ``[history]`` plans as before."""

from __future__ import annotations

import copy
import hashlib
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from rvdiag.datasets import SampleStore
from rvdiag.errors import ConfigError
from rvdiag.gears.growth import crack_growth, sun_root_chord, wear_growth
from rvdiag.gears.wear import DutyCycle, mesh_passes
from rvdiag.library import LibraryConfig, build_library, make_plan
from rvdiag.library.life import FATE_STATES, LIFE_COLUMNS, apply_sensor_fault
from rvdiag.library.states import SEVERITY_PARAMETERS
from rvdiag.params import ReducerParams

sys.path.insert(0, str(Path(__file__).parent))
from conftest import run_cli  # noqa: E402
from test_library_build import assert_same_store, interrupted_build  # noqa: E402
from test_paired_library import ARM, PAIRED, paired  # noqa: E402

HISTORY = {"records": 4, "interval_days": 60.0, "fates": {"healthy": 0.25, "wear": 0.25, "crack": 0.25,
                                                           "broken": 0.25},
           "onset_days": {"min": 65.0, "max": 150.0}, "sensor_fault_share": 0.5}
# seed 286: every fate, a dead sensor, >= 3 training records of every state without a sensor fault (rvdiag train
# leaves those out, and its calibration needs 3), healthy records of 4 training reducers
LIFE = {**copy.deepcopy(PAIRED), "history": HISTORY, "seed": 286,
        "baseline": {"operating_points": PAIRED["baseline"]["operating_points"][:2]},
        "split": {"reducers": 5, "test_reducers": 1}}
LIFE.pop("states")


def life(**changes) -> LibraryConfig:
    data = copy.deepcopy(LIFE)
    for key, value in changes.items():
        data[key] = {**data.get(key, {}), **value} if isinstance(value, dict) and key in data else value
    return LibraryConfig.from_dict(data, source="life.toml")


def plan_digest(plan) -> str:
    return hashlib.sha256(repr(plan).encode()).hexdigest()


UNIT_FIELDS = ("index", "state", "sim_index", "seed", "severity", "speed", "load_Nm", "noise_snr_db", "scales", "split",
               "rows", "mounting", "noise_exponent", "profile", "sensor", "specimen", "noise_density", "reducer",
               "role", "operating_point", "variation")


def _demo_monitoring_as_at_f4e6d32() -> LibraryConfig:
    """configs/demo-monitoring.toml with the wear draws it had at f4e6d32 (10-80 um; 3-9 um since 2026-11-28,
    docs/library.md), so that its plan's digest still compares the planner with that commit's."""
    data = LibraryConfig.load("demo-monitoring").to_dict()
    data["states"]["T3"]["wear_depth"] = {"min": 10.0e-6, "max": 80.0e-6}
    return LibraryConfig.from_dict(data, source="demo-monitoring.toml")


# ---------------------------------------------------------------------- a paired config without [history]
@pytest.mark.parametrize("cfg, digest", [
    (lambda: paired(), "c50e1b75517576d0300a2a5bb8e0b08fe04375cd36cff2c85e0a5fd87b1f6306"),
    (lambda: paired(profile=ARM), "1df2d4061c460883066798a2bb37e01935186fb21c1391b8e35b87e7ca5bf735"),
    (lambda: _demo_monitoring_as_at_f4e6d32(), "39ce4bce216041edd33be1d197ccd0f6a630f59c8b1ff1b63e798b5e04b1b54a"),
])
def test_a_paired_config_without_history_plans_as_before(cfg, digest):
    """Every field of every unit as main planned them before life histories existed (digests taken at f4e6d32)."""
    plan = make_plan(cfg())
    assert hashlib.sha256(repr([[getattr(u, f) for f in UNIT_FIELDS] for u in plan]).encode()).hexdigest() == digest
    assert all(not u.life for u in plan)
    assert "history" not in cfg().to_dict()


# ---------------------------------------------------------------------- the plan
def test_plan_is_deterministic_for_a_seed_and_another_seed_draws_other_lives():
    a, b, c = make_plan(life()), make_plan(life()), make_plan(life(seed=287))
    assert plan_digest(a) == plan_digest(b)
    assert [u.seed for u in a] != [u.seed for u in c]
    onsets = lambda p: [u.life["life.onset_days"] for u in p]  # noqa: E731
    assert repr(onsets(a)) != repr(onsets(c))


def test_plan_layout_reducer_by_reducer_commissioning_first():
    cfg = life()
    plan = make_plan(cfg)
    per = 2 + 4
    assert len(plan) == cfg.n_simulations == 5 * per and [u.index for u in plan] == list(range(len(plan)))
    for r in range(5):
        mine = plan[r * per:(r + 1) * per]
        assert [u.life["life.record"] for u in mine] == list(range(per)) == [u.sim_index for u in mine]
        assert [u.role for u in mine] == ["baseline"] * 2 + ["monitored"] * 4
        assert [u.operating_point for u in mine[:2]] == [0, 1]
        assert [u.life["life.time_days"] for u in mine] == [0.0, 0.0, 60.0, 120.0, 180.0, 240.0]
        assert all(u.state == "T1" and not u.severity for u in mine[:2])
        for attr in ("specimen", "scales", "mounting", "noise_snr_db", "split"):
            assert all(getattr(u, attr) == getattr(mine[0], attr) for u in mine), attr
        assert len({u.life["life.fate"] for u in mine}) == 1 and len({repr(u.variation) for u in mine}) == per
    assert [plan[r * per].split for r in range(5)] == ["train"] * 4 + ["test"]


def test_the_reducers_are_those_of_the_paired_library_without_history():
    """What makes a reducer is drawn as a paired library draws it; its life comes after, from the same stream."""
    with_h, without = make_plan(life()), make_plan(_without_history())
    for a in with_h:
        b = next(u for u in without if u.reducer == a.reducer)
        assert (a.specimen, a.scales, a.mounting, a.noise_snr_db) == (b.specimen, b.scales, b.mounting, b.noise_snr_db)


def _without_history() -> LibraryConfig:
    data = copy.deepcopy(LIFE)
    data.pop("history")
    data["states"] = {"T1": {}, "T2": {}}
    return LibraryConfig.from_dict(data)


def test_truth_columns_are_consistent_with_the_states():
    """Over many reducers (the plan alone): size 0 before the onset and non-decreasing after; the state follows the
    size; a crack is T2 from its failure on; a broken tooth T2 from its onset; healthy has NaN onset and failure;
    load cycles are the duty's sun mesh passes; a sensor fault holds from its first record to the last."""
    cfg = life(split={"reducers": 40, "test_reducers": 10}, history={"records": 8, "interval_days": 30.0})
    plan = make_plan(cfg)
    h = cfg.history
    passes = mesh_passes(cfg.reducer_params(), 24.0, DutyCycle(h.duty_speed_deg_s, h.duty_load_Nm, h.moving_fraction))
    seen = set()
    for r in range(40):
        mine = [u for u in plan if u.reducer == r]
        lf = [u.life for u in mine]
        fate, onset, failure = lf[0]["life.fate"], lf[0]["life.onset_days"], lf[0]["life.failure_days"]
        seen.add(fate)
        assert all(x["life.fate"] == fate and repr(x["life.onset_days"]) == repr(onset)
                   and repr(x["life.failure_days"]) == repr(failure) for x in lf)
        days = np.array([x["life.time_days"] for x in lf])
        size = np.array([x["life.size"] for x in lf])
        np.testing.assert_allclose([x["life.load_cycles"] for x in lf], days * passes, rtol=1e-12)
        assert np.all(np.diff(size) >= 0)
        if fate == "healthy":
            assert math.isnan(onset) and math.isnan(failure) and not size.any()
            assert all(u.state == "T1" for u in mine)
            continue
        assert np.all(size[days < onset] == 0) and np.all(size[days >= onset] > 0)
        for u, d, s in zip(mine, days, size):
            if u.role == "baseline":
                assert u.state == "T1"
            elif fate == "broken":
                assert failure == onset
                assert (u.state, u.severity.get("broken_fraction")) == (("T2", s) if d >= onset else ("T1", None))
            elif fate == "crack":
                lo = SEVERITY_PARAMETERS["crack_depth"].lo
                want = "T2" if d >= failure else ("T4" if s >= lo else "T1")
                assert u.state == want, (d, s, failure)
                if want == "T4":
                    assert u.severity["crack_depth"] == s and 30.0 <= u.severity["crack_angle_deg"] <= 60.0
                if want == "T2":
                    assert s == pytest.approx(0.5 * sun_root_chord(cfg.reducer_params()))
            else:
                lo = SEVERITY_PARAMETERS["wear_depth"].lo
                assert u.state == ("T3" if s >= lo else "T1") and u.severity.get("wear_depth", s) == s
        if fate in FATE_STATES and fate != "broken":
            assert failure > onset
        faults = [x["life.sensor_fault"] for x in lf]
        first = next((i for i, f in enumerate(faults) if f), None)
        if first is not None:
            assert first >= 2 and len(set(faults[first:])) == 1 and not any(faults[:first])
    assert seen == {"healthy", "wear", "crack", "broken"}
    assert any(u.life["life.sensor_fault"] for u in plan)


def test_growth_laws_reach_their_failure_size_at_their_failure_time():
    p, duty = ReducerParams.default(), DutyCycle(30.0, 120.0, 0.5)
    w = wear_growth(p, duty, 50.0, 2e-17, 20e-6, k_ref=1e-17, hours_ref_max=24 * 500 * 2.0)
    assert w.size(np.array([w.failure_days]))[0] == pytest.approx(20e-6, rel=1e-9)
    # twice the coefficient, half the time (one curve)
    w2 = wear_growth(p, duty, 50.0, 4e-17, 20e-6, k_ref=1e-17, hours_ref_max=24 * 500 * 2.0)
    assert w2.failure_days - 50.0 == pytest.approx((w.failure_days - 50.0) / 2, rel=1e-12)
    # and the Archard integration depends on k t alone: a curve integrated at 2e-17 itself agrees (to the
    # interpolation between the curves' 60 points)
    w3 = wear_growth(p, duty, 50.0, 2e-17, 20e-6, k_ref=2e-17, hours_ref_max=24 * 500.0)
    assert w3.failure_days == pytest.approx(w.failure_days, rel=2e-3)
    c = crack_growth(p, duty, 10.0, 1e-4, 1.5e-3, 80.0)
    a = c.size(np.linspace(0.0, 120.0, 241))
    assert c.failure_days == 90.0 and np.all(np.diff(a) >= 0) and a[-1] == 1.5e-3
    assert c.truth["stress_range_MPa"] > 0


def test_sensor_faults():
    rng = np.random.default_rng(0)
    x = np.sin(np.linspace(0, 20, 1000))
    assert np.all(apply_sensor_fault(x, "dead", rng) == np.mean(x))
    assert np.max(np.abs(apply_sensor_fault(x, "clipped", rng))) == pytest.approx(0.2 * np.max(np.abs(x)))
    assert np.std(apply_sensor_fault(x, "disconnected", rng)) == pytest.approx(0.01 * np.std(x), rel=0.1)


# ---------------------------------------------------------------------- the config
def test_life_config_round_trips_and_derives_its_states():
    cfg = life()
    assert cfg.classes == ["T1", "T2", "T3", "T4"] and cfg.history.records == 4
    again = LibraryConfig.from_dict(cfg.to_dict())
    assert again == cfg and plan_digest(make_plan(again)) == plan_digest(make_plan(cfg))
    assert life(history={"fates": {"healthy": 0.5, "wear": 0.5}}).classes == ["T1", "T3"]
    assert life(history={"sensor_fault_share": 0.1}).to_dict() != cfg.to_dict()


@pytest.mark.parametrize("change, match", [
    ({"history": {"records": 0}}, r"\[history\] records: must be >= 1"),
    ({"history": {"fates": {"healthy": 0.5, "wear": 0.4}}}, r"\[history\] fates: the shares must add up to 1"),
    ({"history": {"fates": {"healthy": 0.5, "pitting": 0.5}}}, r"\[history\] fates: 'pitting' is not grown"),
    ({"history": {"fates": {"healthy": 0.5, "rust": 0.5}}}, r"\[history\] fates: unknown fate 'rust'"),
    ({"history": {"interval_days": -1.0}}, r"\[history\] interval_days: must be > 0"),
    ({"history": {"moving_fraction": 2.0}}, r"\[history\] moving_fraction"),
    ({"history": {"wear_failure_m": 1.0}}, r"\[history\] wear_failure_m: must lie in wear_depth's"),
    ({"history": {"crack_angle_deg": {"min": 5.0, "max": 60.0}}}, r"\[history\] crack_angle_deg: must lie in"),
    ({"history": {"broken_fraction": 1.5}}, r"\[history\] broken_fraction: must lie in"),
    ({"history": {"sensor_fault_kinds": ["smoke"]}}, r"\[history\] sensor_fault_kinds"),
    ({"history": {"sensor_fault_share": 1.5}}, r"\[history\] sensor_fault_share"),
    ({"history": {"colour": 1}}, r"\[history\] unknown key 'colour'"),
    ({"baseline": {"monitored_healthy": 3}}, r"\[baseline\] monitored_healthy: a life history's monitored records"),
    ({"states": {"T1": {}, "T3": {}}}, r"\[history\] fates: the fates reach T1, T2, T3, T4; add \[states.T2\]"),
    ({"states": {"T1": {}, "T2": {}, "T3": {"wear_depth": 1e-5}, "T4": {}}}, r"\[states.T3\] wear_depth: a life"),
])
def test_bad_history_configs_name_the_key(change, match):
    with pytest.raises(ConfigError, match=match):
        life(**change)


def test_history_needs_a_baseline():
    data = copy.deepcopy(LIFE)
    data.pop("baseline")
    with pytest.raises(ConfigError, match=r"\[history\]: a life history is a paired library"):
        LibraryConfig.from_dict(data)


def test_a_crack_deeper_than_the_model_admits_is_refused_at_plan_time():
    with pytest.raises(ConfigError, match=r"\[history\] crack_failure_fraction: 0.9 of the sun tooth's root chord"):
        make_plan(life(history={"crack_failure_fraction": 0.9}))


def test_shipped_life_config_is_the_issues_bench_size():
    cfg = LibraryConfig.load("life")
    assert cfg.history is not None and cfg.baseline.reducers == 200 and cfg.history.records == 60
    mon = LibraryConfig.load("monitoring")
    assert (cfg.fs, cfg.duration_s, cfg.transient_s, cfg.segment_length) == (mon.fs, mon.duration_s, mon.transient_s,
                                                                             mon.segment_length)
    assert cfg.baseline.operating_points == mon.baseline.operating_points and cfg.model == mon.model
    assert cfg.classes == ["T1", "T2", "T3", "T4"]


def test_cli_config_errors_are_one_line_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    import tomli_w

    data = copy.deepcopy(LIFE)
    data["history"]["fates"] = {"healthy": 0.7}
    bad.write_bytes(tomli_w.dumps(data).encode())
    code, out, err = run_cli(["library", "build", bad, "--out", tmp_path / "x.zarr", "--workers", "0", "--quiet"],
                             capsys)
    assert code == 2 and err.strip().count("\n") == 0 and "[history] fates: the shares must add up to 1" in err
    assert not (tmp_path / "x.zarr").exists()


# ---------------------------------------------------------------------- the store
@pytest.fixture(scope="module")
def store(tmp_path_factory):
    import rvdiag.library.work_units as work_units

    work_units._TWIN_POWERS.clear()
    path = tmp_path_factory.mktemp("life") / "life.zarr"
    report = build_library(life(), path, workers=0, progress=False)
    assert report.built == report.n_units == 30
    return path


def test_store_carries_each_records_truth(store):
    data = SampleStore.open(store).load()
    meta = {k: np.asarray(v) for k, v in data.meta.items()}
    assert set(LIFE_COLUMNS) <= set(meta)
    for u in make_plan(life()):
        rows = meta["unit"] == u.index
        assert rows.sum() == 4
        for key, value in u.life.items():
            got = meta[key][rows]
            assert all((isinstance(value, float) and math.isnan(value) and math.isnan(g)) or g == value for g in got)
        assert np.all(meta["state"][rows] == u.state) and np.all(meta["role"][rows] == u.role)
        fault = u.life["life.sensor_fault"]
        if fault == "dead":
            x = data.X[rows]
            assert np.all(x == x[0, 0])
    assert set(meta["life.sensor_fault"]) > {""}
    from rvdiag.library import config_from_store

    assert plan_digest(make_plan(config_from_store(SampleStore.open(store).attrs))) == plan_digest(make_plan(life()))


def test_train_accepts_a_life_store(store, tmp_path, capsys):
    code, out, err = run_cli(["train", store, "-o", tmp_path / "m"], capsys)
    assert code == 0, err
    assert "paired store: training a baseline-referenced monitor" in err
    card = json.loads((tmp_path / "m" / "card.json").read_text())
    assert card["needs_baseline"] is True


def test_library_info_describes_a_life_store(store, capsys):
    code, out, err = run_cli(["library", "info", store, "--json"], capsys)
    assert code == 0, err
    info = json.loads(out)["life"]
    assert info["reducers"] == 5 and info["records_per_reducer"] == 6 and info["last_day"] == 240.0
    assert sum(info["fates"].values()) == 5
    code, out, err = run_cli(["library", "info", store], capsys)
    assert "life histories: 5 reducers, 6 records each" in out


def test_resume_after_an_interruption_gives_the_same_store(store, tmp_path, monkeypatch):
    import rvdiag.library.work_units as work_units

    path = tmp_path / "part.zarr"
    work_units._TWIN_POWERS.clear()
    interrupted_build(life(), path, monkeypatch, after=7)
    work_units._TWIN_POWERS.clear()  # a new process: no healthy twins kept
    report = build_library(life(), path, workers=0, progress=False)
    assert (report.skipped, report.built) == (7, 30 - 7)
    assert_same_store(store, path)
