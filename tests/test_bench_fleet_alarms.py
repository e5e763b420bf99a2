"""bench/fleet_alarms.py's long-history mode (``--years``) without simulating: its life-history config plans healthy
records ending in a broken tooth, and a joint's records go through the fleet store (tests/fleet_fakes.py's judge)
into the figures the bench reports: false alarms after learning and where, the broken tooth within 3 records with
the alarms acknowledged at once, and the summary's intervals."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from fleet_fakes import FakeJudge
from rvdiag.fleet import Fleet
from rvdiag.library import LibraryConfig, make_plan

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("fleet_alarms_under_test", ROOT / "bench" / "fleet_alarms.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("signal", ["vibration", "current"])
def test_the_life_config_is_the_monitors_design_healthy_then_a_broken_tooth(bench, tmp_path, signal):
    name, seed = bench.LIFE[signal][0]
    cfg = LibraryConfig.load(bench.life_config(tmp_path, signal, name, seed, reducers=2, records=8))
    assert cfg.history.records == 8 and cfg.history.interval_days == 1 / bench.RECORDS_PER_DAY
    d = cfg.to_dict()
    assert d["signal"]["fs"] == (48000.0 if signal == "vibration" else 1000.0)
    assert d["operation"]["noise_snr_db"] == (20.0 if signal == "vibration" else 60.0)
    units = make_plan(cfg)
    for reducer in (0, 1):
        mine = [u for u in units if u.reducer == reducer]
        base = [u for u in mine if u.role == "baseline"]
        later = sorted((u for u in mine if u.role == "monitored"), key=lambda u: u.life["life.record"])
        assert len(later) == 8 and {u.state for u in base} == {"T1"}
        assert [u.state for u in later] == ["T1"] * (8 - bench.BROKEN_RECORDS) + ["T2"] * bench.BROKEN_RECORDS
        lo = 0.5 if signal == "vibration" else 1.0
        assert all(lo <= u.severity["broken_fraction"] <= 1.0 for u in later if u.state == "T2")
        # each record its own run-to-run draw
        assert len({u.variation["load"] for u in later}) == 8


@pytest.mark.parametrize("signal", ["vibration", "current"])
def test_the_short_benchs_configs_derive_from_the_shipped_ones(bench, tmp_path, signal):
    """The short bench's libraries (``bench/fleet_alarms.py [--signal current]``) are edits of the shipped configs:
    each edit must still apply (an edit that no longer matches stops the bench), the unseen joints hold healthy
    records then the broken tooth only (vibration from half the tooth, current the whole tooth)."""
    paths = bench.configs(tmp_path, 6, 2) if signal == "vibration" else bench.current_configs(tmp_path)
    assert set(paths) == ({"train", "unseen", "unseen2"} if signal == "vibration" else {"train", "unseen"})
    for name, path in paths.items():
        cfg = LibraryConfig.load(path)
        d = cfg.to_dict()
        if name == "train":
            assert d["split"]["reducers"] == 8
            continue
        assert set(d["states"]) == {"T1", "T2"}
        units = [u for u in make_plan(cfg) if u.role == "monitored" and u.state == "T2"]
        lo = 0.5 if signal == "vibration" else 1.0
        assert units and all(lo <= u.severity["broken_fraction"] <= 1.0 for u in units)


def _records(means, states):
    rng = np.random.default_rng(1)
    out = [{"reducer": 0, "role": "baseline", "state": "T1", "speed": 45.0, "load": 50.0, "record": i,
            "x": 0.1 + 0.1 * rng.standard_normal(16)} for i in range(2)]
    for i, (m, s) in enumerate(zip(means, states)):
        out.append({"reducer": 0, "role": "monitored", "state": s, "speed": 45.0, "load": 50.0,
                    "record": 2 + i, "x": m + 0.01 * rng.standard_normal(16)})
    return out[::-1]  # in any order: the joint takes them in record order


def test_a_joints_history_gives_its_false_alarms_and_the_broken_tooth(bench, tmp_path):
    fleet = Fleet.init(f"sqlite:///{tmp_path / 'f.db'}", judge=FakeJudge())
    (tmp_path / "monitor").mkdir()
    (tmp_path / "files").mkdir()
    # 19 learning records, 20 healthy, a run of three loud healthy records (below the monitor's alarm), 10 healthy,
    # then 3 broken-tooth records
    learn = list(np.linspace(0.1, 0.5, 19))
    means = learn + [0.2] * 20 + [1.0] * 3 + [0.2] * 10 + [10.0] * 3
    states = ["T1"] * 52 + ["T2"] * 3
    pj, seconds, n = bench._ingest_joint(fleet, "bench/life/r0", _records(means, states), tmp_path / "monitor",
                                         1000.0, tmp_path / "files", np.random.default_rng(0))
    assert n == 55 and seconds > 0 and not list((tmp_path / "files").iterdir())
    assert pj["learning"] == 19 and pj["healthy_records"] == 49  # 52 healthy, three of them turned sensor faults
    assert pj["false_alarms"] == 1 and pj["baseline_false_alarms"] == 0
    assert [means[i] for i in pj["false_alarms_at"]] == [1.0]
    assert pj["t2_alarm_within_3_acknowledged"] and pj["t2_raised_within_3_acknowledged"]
    assert not pj["in_alarm_before_t2_acknowledged"]
    # the store never acknowledges: the false alarm latches through the broken tooth there
    assert pj["in_alarm_before_t2"]
    s = bench._summary([pj, pj], 0.766, fleet.rules("bench/life/r0").to_dict(), seconds / n, 1.0)
    assert s["false_alarms_after_learning"] == 2 and s["broken_tooth_alarm_within_3_acknowledged"] == "2 of 2"
    lo, hi = s["false_alarms_per_joint_year_ci95"]
    assert lo < s["false_alarms_per_joint_year"] < hi
    assert s["broken_tooth_acknowledged_ci95"][0] == pytest.approx(0.025 ** 0.5)  # Clopper-Pearson, 2 of 2
    assert s["joints_later_above_learning"] == {} and s["record_alarm_rate_per_joint"]["bench/life/r0"] > 0
    drifted = {**pj, "health_index": [v if v is None or i < 19 else v + 5.0 for i, v in enumerate(pj["health_index"])]}
    assert list(bench._summary([drifted], 0.766, fleet.rules("bench/life/r0").to_dict(), 0.1, 1.0)[
        "joints_later_above_learning"]) == ["bench/life/r0"]
    pooled = s["record_alarms_pooled"]  # two joints of 30 judged records each: mean 30 / 20 each
    assert pooled["alarms"] == 2 * pj["record_alarms"] and pooled["expected"] == pytest.approx(2 * 30 / 20)
    # one operating point: read point by point is the joint's own rank
    one = {**pj, "operating_points": [0] * len(pj["health_index"])}
    by = bench._summary([one], 0.766, fleet.rules("bench/life/r0").to_dict(), 0.1, 1.0)["by_operating_point"]
    assert by["above_own_point"] == pj["record_alarms"] == by["alarms_at_point"]["0"]
    assert by["expected"] == pytest.approx(30 / 20)
