"""Library configs and states: parsing, validation messages naming the key, the shipped configs, plans."""

import copy
from pathlib import Path

import numpy as np
import pytest

from rvdiag.errors import ConfigError, ParameterError
from rvdiag.library import STATES, FaultSpec, LibraryConfig, Sweep, make_plan, tooth_faults
from rvdiag.library.build import unit_seeds
from rvdiag.library.config import split_counts

ROOT = Path(__file__).resolve().parents[1]

BASE = {
    "mode": "split-by-simulation",
    "seed": 5,
    "simulator": "rvdiag.library.synthetic:simulate",
    "signal": {"fs": 1000.0, "duration_s": 1.0, "transient_s": 0.1, "segment_length": 200, "hop": 100},
    "operation": {"input_speed_rpm": {"min": 1000.0, "max": 2000.0}, "load_Nm": [50.0, 100.0],
                  "noise_snr_db": 10.0},
    "randomise": {"stiffness_pct": 10.0, "damping_pct": 5.0},
    "split": {"simulations_per_state": 4, "test_simulations_per_state": 1},
    "states": {"T1": {}, "T2": {"broken_fraction": {"min": 0.5, "max": 1.0}}, "T6": {}},
}


def cfg_with(**changes):
    data = copy.deepcopy(BASE)
    for key, value in changes.items():
        section, _, sub = key.partition("__")
        if sub:
            if value is None:
                data[section].pop(sub, None)
            else:
                data[section][sub] = value
        elif value is None:
            data.pop(section, None)
        else:
            data[section] = value
    return LibraryConfig.from_dict(data, source="t.toml")


def test_eight_states_and_their_severities():
    assert list(STATES) == ["T1", "T2", "T3", "T4", "T5", "T6", "T7", "T8"]
    assert STATES["T1"].parameters == ()
    assert set(STATES["T6"].parameters) == set(STATES["T2"].parameters) | set(STATES["T3"].parameters) | set(
        STATES["T4"].parameters)
    assert set(STATES["T5"].parameters) == {"broken_fraction", "wear_depth"}
    with pytest.raises(ParameterError, match="wear_depth = 0.5 m is outside"):
        FaultSpec("T3", {"wear_depth": 0.5})
    with pytest.raises(ParameterError, match="no severity parameter 'wear_depth'"):
        FaultSpec("T2", {"wear_depth": 1e-5})
    with pytest.raises(ParameterError, match="unknown health state"):
        FaultSpec("T9")


def test_states_map_to_gear_faults_by_kind():
    """T2 broken, T3 wear, T4 crack (the library's numbering), whatever the gear module's own labels."""
    from rvdiag.gears import BrokenTooth, RootCrack

    assert tooth_faults("T1") is None
    t2 = tooth_faults("T2", broken_fraction=0.8)
    assert t2.wear is None and t2.teeth[0] == (BrokenTooth(0.8),)
    t3 = tooth_faults("T3", wear_depth=3e-5)
    assert t3.wear.depth == 3e-5 and not any(t3.teeth.values())
    t4 = tooth_faults("T4", crack_depth=4e-4, crack_angle_deg=40.0)
    assert t4.wear is None and t4.teeth[0] == (RootCrack(4e-4, 40.0),)
    t6 = tooth_faults("T6")
    kinds = {type(f).__name__ for faults in t6.teeth.values() for f in faults}
    assert kinds == {"BrokenTooth", "RootCrack"} and t6.wear is not None


def test_sweeps_parse_and_draw():
    rng = np.random.default_rng(0)
    assert Sweep.parse(3.0, "k").draw(rng) == 3.0
    choice = Sweep.parse([1.0, 2.0, 5.0], "k")
    assert {choice.draw(rng) for _ in range(200)} == {1.0, 2.0, 5.0}
    uni = Sweep.parse({"min": 2.0, "max": 4.0}, "k")
    draws = np.array([uni.draw(rng) for _ in range(500)])
    assert 2.0 <= draws.min() < 2.1 and 3.9 < draws.max() <= 4.0
    assert Sweep.parse({"min": 2.0, "max": 2.0}, "k").kind == "fixed"
    for raw in (uni, choice):
        assert Sweep.parse(raw.to_toml(), "k") == raw


@pytest.mark.parametrize(
    "change, message",
    [
        ({"mode": "fast"}, "mode: must be one of paper, split-by-simulation"),
        ({"seed": None}, "seed: missing"),
        ({"seed": -1}, "seed: must be >= 0"),
        ({"signal__fs": -5.0}, r"\[signal\] fs: must be > 0"),
        ({"signal__hop": 0}, r"\[signal\] hop: must be >= 1"),
        ({"signal__segment_length": 5000}, r"\[signal\] segment_length: 5000 points exceed the 1000 points"),
        ({"signal__sample_rate": 1.0}, r"\[signal\] unknown key 'sample_rate'"),
        ({"operation__output_speed_deg_s": 30.0}, "exactly one of input_speed_rpm or output_speed_deg_s"),
        ({"operation__load_Nm": None}, r"\[operation\] load_Nm: missing"),
        ({"operation__load_Nm": {"min": 5.0, "max": 1.0}}, r"load_Nm: min \(5\) must not exceed max \(1\)"),
        ({"operation__load_Nm": []}, "load_Nm: an empty list"),
        ({"operation__noise_snr_db": "loud"}, "noise_snr_db: expected a number"),
        ({"randomise__stiffness_pct": 150.0}, r"\[randomise\] stiffness_pct: must lie in \[0, 100\)"),
        ({"split__test_simulations_per_state": 4}, "test_simulations_per_state: 4 leaves no training"),
        ({"split__train_per_state": 3}, "train_per_state: only for mode = 'paper'"),
        ({"states": {"T1": {}}}, "needs at least two states"),
        ({"states": {"T1": {}, "T9": {}}}, r"\[states.T9\]: unknown state"),
        ({"states": {"T1": {}, "T2": {"crack_depth": 1e-4}}}, r"\[states.T2\] crack_depth: not a severity parameter"),
        ({"states": {"T1": {}, "T3": {"wear_depth": {"min": 0.0, "max": 1e-5}}}}, r"\[states.T3\] wear_depth: .*outside"),
        ({"simulator": "nocolon"}, "simulator: expected 'module.path:function'"),
        ({"colour": "red"}, "unknown key 'colour'"),
    ],
)
def test_bad_configs_name_the_key(change, message):
    with pytest.raises(ConfigError, match=message) as exc:
        cfg_with(**change)
    assert str(exc.value).startswith("t.toml")


def test_paper_mode_split_checks():
    paper = {"train_per_state": 5, "test_per_state": 3}
    cfg = cfg_with(mode="paper", split=paper)
    assert cfg.rows_per_simulation("T1") == 8 and cfg.n_simulations == 3
    with pytest.raises(ConfigError, match="exceeds the 9 segments"):
        cfg_with(mode="paper", split={"train_per_state": 7, "test_per_state": 3})
    with pytest.raises(ConfigError, match="assign: must be one of random, ordered"):
        cfg_with(mode="paper", split={**paper, "assign": "middle"})
    with pytest.raises(ConfigError, match="simulations_per_state: only for mode = 'split-by-simulation'"):
        cfg_with(mode="paper", split={**paper, "simulations_per_state": 2})


def test_load_errors_and_round_trip(tmp_path):
    with pytest.raises(ConfigError, match="library config not found"):
        LibraryConfig.load(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("mode = [", encoding="utf-8")
    with pytest.raises(ConfigError, match="bad.toml: not valid TOML"):
        LibraryConfig.load(bad)
    cfg = cfg_with()
    again = LibraryConfig.from_dict(cfg.to_dict())
    assert again == cfg and again.to_dict() == cfg.to_dict()
    assert cfg.replace(seed=9).seed == 9
    assert cfg.replace(signal={"hop": 50}).segments_per_simulation == 17


def test_relative_params_path_is_relative_to_the_config(tmp_path):
    from rvdiag.params import ReducerParams

    ReducerParams.default().replace(stage1={"face_width": 0.012}).save(tmp_path / "mine.toml")
    text = (ROOT / "configs" / "demo.toml").read_text("utf-8").replace('name = "demo"', 'name = "d"\nparams = "mine.toml"')
    (tmp_path / "c.toml").write_text(text, encoding="utf-8")
    assert LibraryConfig.load(tmp_path / "c.toml").reducer_params().stage1.face_width == 0.012


@pytest.mark.parametrize("name", ["paper", "demo", "independent", "transfer", "experiments/independent20",
                                  "experiments/snr", "experiments/independent-speed"])
def test_shipped_configs_are_valid(name):
    cfg = LibraryConfig.load(ROOT / "configs" / f"{name}.toml")
    assert cfg.classes == ["T1", "T2", "T3", "T4", "T5", "T6"]
    assert len(make_plan(cfg)) == cfg.n_simulations


def test_independent_speed_config_draws_as_independent():
    """experiments/independent-speed records the rotor speed with the draws of independent.toml, unit for unit (its
    fixed 120 dB noise level still takes the SNR's draw)."""
    a = make_plan(LibraryConfig.load(ROOT / "configs" / "independent.toml"))
    cfg = LibraryConfig.load(ROOT / "configs" / "experiments" / "independent-speed.toml")
    b = make_plan(cfg)
    assert cfg.channel == "speed" and cfg.model["signal"] == "current"
    assert len(a) == len(b) == 360
    for u, v in zip(a, b):
        assert (u.state, u.speed, u.load_Nm, u.severity, u.scales, u.split, u.profile, u.mounting) == \
               (v.state, v.speed, v.load_Nm, v.severity, v.scales, v.split, v.profile, v.mounting)
        assert v.noise_snr_db == 120.0


def test_paper_config_is_the_paper():
    cfg = LibraryConfig.load(ROOT / "configs" / "paper.toml")
    assert (cfg.mode, cfg.fs, cfg.duration_s, cfg.segment_length, cfg.hop) == ("paper", 48000.0, 60.0, 8000, 8000)
    assert cfg.segments_per_simulation == 360  # 60 s x 48 kHz / 8000, non-overlapping
    assert split_counts(cfg) == {"train": 260, "test": 100}
    assert cfg.noise_snr_db is not None and cfg.simulations_per_state == 1


def test_demo_config_has_enough_samples_for_a_cnn():
    cfg = LibraryConfig.load(ROOT / "configs" / "demo.toml")
    counts = split_counts(cfg)
    assert cfg.mode == "split-by-simulation" and counts["train"] >= 100 and counts["test"] >= 30
    # simulated seconds: at the ~2 simulated s per CPU-s of 4 sub-steps, about a minute on 2 cores
    assert cfg.n_simulations * (cfg.duration_s + cfg.transient_s) <= 250.0


def test_plan_draws_are_seeded_and_within_ranges():
    cfg = cfg_with()
    plan = make_plan(cfg)
    assert plan == make_plan(cfg)  # deterministic
    assert [u.index for u in plan] == list(range(12))
    assert len({u.seed for u in plan}) == 12 and all(0 <= u.seed < 2**63 for u in plan)
    assert unit_seeds(cfg.seed, 12) == [u.seed for u in plan]
    assert [u.seed for u in make_plan(cfg.replace(seed=6))] != [u.seed for u in plan]
    for u in plan:
        assert 1000.0 <= u.speed <= 2000.0 and u.load_Nm in (50.0, 100.0) and u.noise_snr_db == 10.0
        assert all(0.9 <= f <= 1.1 for k, f in u.scales.items() if not k.startswith("damping"))
        assert all(0.95 <= u.scales[k] <= 1.05 for k in ("damping.mesh_damping_ratio", "damping.bearing_damping_ratio"))
        assert u.split == ("test" if u.sim_index == 3 else "train")
    t2 = [u.severity["broken_fraction"] for u in plan if u.state == "T2"]
    assert len(set(t2)) == 4 and all(0.5 <= v <= 1.0 for v in t2)
    assert len({u.speed for u in plan}) == 12  # each simulation draws its own operating point


def test_default_transient_is_the_models_and_simulates():
    """One transient default.  A config that leaves [signal] transient_s out gets the model's
    run-in (ModelSettings.transient_s, docs/model.md section 7), as `rvdiag simulate` does without --transient
    (tests/test_cli_simulate.py); before, configs took 0 s."""
    import re

    from rvdiag.dynamics import ModelSettings
    from rvdiag.library.config import DEFAULT_TRANSIENT_S

    assert cfg_with(signal__transient_s=None).transient_s == DEFAULT_TRANSIENT_S == ModelSettings().transient_s == 0.1
    assert cfg_with(signal__transient_s=0.0).transient_s == 0.0  # an explicit value is kept
    stated = re.search(r"`transient_s` = ([\d.]+) s by default", (ROOT / "docs" / "model.md").read_text())
    assert float(stated.group(1)) == DEFAULT_TRANSIENT_S
    assert "| `transient_s` | simulated first and discarded: the start-up transient (s) | 0.1 " in (
        ROOT / "docs" / "library.md").read_text()


@pytest.mark.parametrize("path", sorted((ROOT / "configs").rglob("*.toml")), ids=lambda p: p.stem)
def test_shipped_configs_set_their_transient(path):
    """The default changed from 0 to 0.1 s: every shipped config states its transient, so it builds the same bits."""
    import tomllib

    assert "transient_s" in tomllib.loads(path.read_text("utf-8")).get("signal", {}), path
