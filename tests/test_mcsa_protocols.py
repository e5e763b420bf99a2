"""``rvdiag mcsa --protocol``: the study's protocol (one reducer per state, its windows split at random) against the
held-out one (unseen reducers tested), on a designed store where every simulation has a fingerprint of its own and
the state none: the study's protocol learns the fingerprints (near 100 %), the held-out one finds chance."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli as run
from rvdiag.datasets import SampleStore, write_store
from rvdiag.errors import SplitLeakWarning
from rvdiag.evaluation.motor_current_study import (McsaSettings, held_out_split, protocol_splits,
                                                    recall_and_false_alarms, run_mcsa, study_split)

FS = 1000.0
L = 256
CLASSES = ("T1", "T2", "T7")
SIMS = 8  # simulations (reducers) per state
WINDOWS = 10  # windows per simulation


def _fingerprint_store(path, seed: int = 0, sims: int = SIMS):
    """Every simulation a tone of its own level, amplitude, frequency and shape (its 'reducer'); the state changes
    nothing."""
    rng = np.random.default_rng(seed)
    t = np.arange(L) / FS
    X, y, unit = [], [], []
    amps = rng.permutation(0.5 + 0.3 * np.arange(len(CLASSES) * sims))  # no two reducers alike, whatever the state
    for c, state in enumerate(CLASSES):
        for k in range(sims):
            amp, freq = amps[c * sims + k], FS / L * rng.integers(5, 40)  # whole periods in a window
            offset, third = rng.uniform(-1.0, 1.0), rng.uniform(0.0, 0.6)  # its level and waveform shape
            for _ in range(WINDOWS):
                phase = 2 * np.pi * freq * t + rng.uniform(0, 6)
                X.append(offset + amp * (np.sin(phase) + third * np.sin(3 * phase)) + 0.05 * rng.standard_normal(L))
                y.append(state)
                unit.append(100 * c + k)
    meta = {"split": ["train"] * len(y), "unit": unit, "output_speed_deg_s": [45.0] * len(y)}
    write_store(path, np.asarray(X, np.float32), y, meta=meta, kind="simulated", fs=FS,
                config={"name": "fingerprints", "channel": "i_a"})
    return path


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    d = tmp_path_factory.mktemp("protocols")
    return {"many": _fingerprint_store(d / "many.zarr"), "one": _fingerprint_store(d / "one.zarr", 1, sims=1)}


def test_held_out_never_tests_a_reducer_it_trained_on():
    y = np.repeat(np.array(CLASSES), SIMS * WINDOWS)
    units = np.repeat(np.arange(len(CLASSES) * SIMS), WINDOWS)
    for seed in range(20):
        tr, te, unseen = held_out_split(y, units, 0.3, seed)
        assert not set(units[tr]) & set(units[te])
        assert set(units[te]) == set(unseen) and len(tr) + len(te) == len(y)
        for c in CLASSES:  # every state on both sides, round(0.3 * 8) = 2 reducers unseen per state
            assert len(set(units[te][y[te] == c])) == 2 and len(set(units[tr][y[tr] == c])) == 6


def test_study_split_is_one_reducer_per_state_with_its_windows_split_at_random():
    y = np.repeat(np.array(CLASSES), SIMS * WINDOWS)
    units = np.repeat(np.arange(len(CLASSES) * SIMS), WINDOWS)
    tests = set()
    for seed in range(10):
        tr, te, used = study_split(y, units, 0.5, seed)
        assert len(used) == len(CLASSES) and set(units[tr]) == set(units[te]) == set(used)  # one reducer, both sides
        assert [y[units == u][0] for u in used] == list(CLASSES)
        assert np.sum(np.isin(units, used)) == len(tr) + len(te) == len(CLASSES) * WINDOWS
        tests.add(tuple(te))
    assert len(tests) > 5  # reducers and windows drawn anew per split
    # the plain window split mixes the windows of every reducer
    (tr, te, _), = protocol_splits("windows", y, units, 0.3, [0])
    assert len(tr) + len(te) == len(y) and len(set(units[tr]) & set(units[te])) > 10


def test_study_learns_the_reducer_held_out_finds_chance(store):
    with pytest.warns(SplitLeakWarning, match="the held-out protocol's figures are not"):
        res = run_mcsa(SampleStore.open(store["many"]), McsaSettings(feature_sets=("time", "wpt"), repeats=5,
                                                                     protocol="both", tsne_samples=0))
    for name in ("time", "wpt"):
        e = res.report["results"]["45"][name]
        study, held = e["study"], e["held_out_reducers"]
        assert study["accuracy"]["mean"] > 0.95, (name, study["accuracy"])
        assert held["accuracy"]["mean"] < 0.6, (name, held["accuracy"])
        for r in held["repeats"]:
            assert len(r["test_simulations"]) == 2 * len(CLASSES)
        for r in study["repeats"]:
            assert len(r["simulations"]) == len(CLASSES) and r["n_train"] + r["n_test"] == len(CLASSES) * WINDOWS
        assert set(study["recall_per_class"]) == set(CLASSES)
        assert study["false_alarm_rate"] == 1 - study["recall_per_class"]["T1"]
    assert "split" not in res.report["results"]["45"]["time"]


def test_recall_and_false_alarms_of_a_confusion():
    got = recall_and_false_alarms([[8, 2, 0], [0, 5, 5], [0, 0, 0]], ["T1", "T2", "T7"])
    assert got == {"recall_per_class": {"T1": 0.8, "T2": 0.5, "T7": None}, "false_alarm_rate": pytest.approx(0.2)}
    assert recall_and_false_alarms([[1, 0], [0, 1]], ["a", "b"])["false_alarm_rate"] is None


def _mcsa(capsys, store, out, *extra):
    return run(["mcsa", store, "-o", out, "-q", "--feature-sets", "time", "--repeats", "3", "--tsne-samples", "0",
                *extra], capsys)


@pytest.mark.parametrize("protocol, keys", [("windows", {"split"}), ("study", {"study"}),
                                            ("held-out", {"held_out_reducers"}),
                                            ("both", {"study", "held_out_reducers"})])
def test_cli_protocol_values(store, tmp_path, capsys, protocol, keys):
    code, out, err = _mcsa(capsys, store["many"], tmp_path / "o", "--protocol", protocol, "--json")
    assert code == 0, err
    rep = json.loads(out)
    entry = rep["results"]["45"]["time"]
    assert keys <= set(entry) and not ({"split", "study", "held_out_reducers"} - keys) & set(entry)
    assert rep["settings"]["protocol"] == protocol and rep["protocol"].startswith(protocol)
    md = (tmp_path / "o" / "mcsa.md").read_text()
    if protocol == "both":
        assert "| study accuracy | held-out accuracy | leak (points) |" in md
    leak = any("optimistic" in n for n in rep["notes"])
    assert leak == (protocol != "held-out")


@pytest.mark.parametrize("args, message", [
    (["--protocol", "random"], "error: --protocol must be one of windows | study | held-out | both, got 'random'"),
])
def test_cli_bad_protocol_one_line_exit_2(store, tmp_path, capsys, args, message):
    code, out, err = _mcsa(capsys, store["many"], tmp_path / "o", *args)
    assert code == 2 and out == "" and err == message + "\n"


def test_held_out_refuses_one_reducer_per_state(store, tmp_path, capsys):
    code, out, err = _mcsa(capsys, store["one"], tmp_path / "o", "--protocol", "held-out")
    assert code == 2 and len(err.splitlines()) == 1
    assert "state T1 has 1 simulation; the held-out split needs at least 2 per state and speed" in err
    assert _mcsa(capsys, store["one"], tmp_path / "o", "--protocol", "study")[0] == 0  # the study's own case
