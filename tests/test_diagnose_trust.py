"""Answers a user can trust: "not recognised", the model's per-class
recall and confusions, the training operating range, refused speed estimates, and healthy recall / false-alarm
rate beside every accuracy.  A tiny synthetic store (three tones) and a small CNN, as tests/test_cli_train.py."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli as run
from rvdiag.datasets import write_store

FS = 1000.0
L = 256


def _signal(c: int, n: int, rng) -> np.ndarray:
    t = np.arange(n) / FS
    return np.sin(2 * np.pi * (50 + 60 * c) * t + rng.uniform(0, 6)) + 0.2 * rng.standard_normal(n)


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    rng = np.random.default_rng(0)
    X, y, split = [], [], []
    for c in range(3):
        for i in range(16):
            X.append(_signal(c, L, rng))
            y.append(f"T{c + 1}")
            split.append("test" if i < 4 else "train")
    d = tmp_path_factory.mktemp("trust")
    store = d / "tiny.zarr"
    write_store(store, np.asarray(X, np.float32), y,
                meta={"split": split, "unit": list(range(len(y))), "output_speed_deg_s": [45.0] * len(y),
                      "load_Nm": [60.0] * 16 + [120.0] * 32},
                kind="measured", fs=FS, config={"name": "tiny"})
    out = d / "model"
    code, _, err = run(["train", store, "--model", "cnn1d-lean", "--out", out, "--epochs", "8", "--lr", "0.01",
                        "--batch-size", "8", "--device", "cpu", "--seed", "1", "--quiet", "--representation",
                        "waveform", "--patience", "5"], _Cap())
    assert code == 0, err
    return out, store


class _Cap:
    """capsys stand-in for a module fixture: nothing captured."""

    def readouterr(self):
        from types import SimpleNamespace

        return SimpleNamespace(out="", err="")


def _diagnose(model_dir, x, tmp_path, capsys, *extra):
    f = tmp_path / "sig.npy"
    np.save(f, x)
    code, out, err = run(["diagnose", model_dir, f, "--fs", str(FS), "--json", *extra], capsys)
    assert code == 0, err
    return json.loads(out), err


def test_the_card_holds_the_ood_check_and_the_operating_range(model):
    card = json.loads((model[0] / "card.json").read_text())
    assert card["novelty"]["rate"] == 0.01 and card["novelty"]["calibration"] == "held-out test split"
    assert card["novelty"]["threshold"] > 0 and (model[0] / "novelty.safetensors").is_file()
    r = card["operating_range"]
    assert r["load_Nm"] == {"min": 60.0, "max": 120.0, "unit": "N m"} and r["fs"] == FS
    assert 0.5 < r["level"]["rms_median"] < 1.0 and "z-scored" in r["level"]["note"]


@pytest.mark.parametrize("what", ["noise", "sine", "zeros"])
def test_noise_a_sine_and_zeros_are_not_recognised(model, tmp_path, capsys, what):
    rng = np.random.default_rng(3)
    t = np.arange(4 * L) / FS
    x = {"noise": rng.standard_normal(4 * L), "sine": np.sin(2 * np.pi * 400 * t) + 0.01 * rng.standard_normal(4 * L),
         "zeros": np.zeros(4 * L)}[what]
    res, _ = _diagnose(model[0], x, tmp_path, capsys)
    assert res["recognised"] is False and res["diagnosis"] is None and res["probabilities"] is None
    assert res["reason"] and ("constant" in res["reason"] if what == "zeros" else "outside the training" in res["reason"])
    code, out, _ = run(["diagnose", model[0], tmp_path / "sig.npy", "--fs", str(FS)], capsys)
    assert code == 0 and "not recognised" in out and "diagnosis:" not in out


def test_a_record_like_the_training_data_is_named_with_its_fault_and_recall(model, tmp_path, capsys):
    rng = np.random.default_rng(5)
    res, _ = _diagnose(model[0], np.concatenate([_signal(1, L, rng) for _ in range(4)]), tmp_path, capsys)
    assert res["recognised"] is True and res["diagnosis"] == "T2" and res["state"] == "T2 (broken tooth)"
    assert res["model_recall"] == 1.0
    code, out, _ = run(["diagnose", model[0], tmp_path / "sig.npy", "--fs", str(FS)], capsys)
    assert code == 0 and "diagnosis: T2 (broken tooth)" in out


def test_an_old_model_without_the_ood_check_loads_and_says_so(model, tmp_path, capsys):
    import shutil

    old = tmp_path / "old"
    shutil.copytree(model[0], old)
    card = json.loads((old / "card.json").read_text())
    del card["novelty"], card["operating_range"]
    (old / "card.json").write_text(json.dumps(card))
    (old / "novelty.safetensors").unlink()
    rng = np.random.default_rng(5)
    res, err = _diagnose(old, np.concatenate([_signal(0, L, rng) for _ in range(4)]), tmp_path, capsys)
    assert res["recognised"] is True and res["novelty"] is None
    assert sum("out-of-distribution check" in line for line in err.splitlines()) == 1


def test_operating_point_and_level_outside_the_training_range_warn(model, tmp_path, capsys):
    rng = np.random.default_rng(5)
    x = np.concatenate([_signal(0, L, rng) for _ in range(4)])
    res, err = _diagnose(model[0], 1000 * x, tmp_path, capsys, "--load", "300", "--output-speed", "45")
    assert "load_Nm 300 N m lies outside the training range 60-120 N m" in err
    assert "output_speed_deg_s" not in err  # 45 deg/s is the training speed
    assert "orders of magnitude outside" in err
    assert res["operating_point"]["load_Nm"] == 300.0


def test_a_confused_answer_warns_with_the_rule(model, tmp_path, capsys):
    """A card whose held-out test called half the T1 samples T3: a T3 answer says it may be T1."""
    import shutil

    d = tmp_path / "confused"
    shutil.copytree(model[0], d)
    card = json.loads((d / "card.json").read_text())
    card["metrics"]["confusion"] = [[2, 0, 2], [0, 4, 0], [0, 0, 4]]
    card["metrics"]["per_class"]["T1"]["recall"] = 0.5
    (d / "card.json").write_text(json.dumps(card))
    rng = np.random.default_rng(5)
    res, err = _diagnose(d, np.concatenate([_signal(2, L, rng) for _ in range(4)]), tmp_path, capsys)
    assert res["diagnosis"] == "T3"
    assert "50 % of its held-out T1 (healthy) samples as T3" in err


def test_an_estimated_speed_the_carrier_mesh_does_not_confirm_is_refused():
    """A stage-1 'peak' that is not the mesh (here the cycloid-pin mesh's second harmonic) gives a
    speed whose cycloid-pin line is absent; at the true speed both lines are there."""
    from rvdiag.features.mesh_lines import confirm_speed, mesh_lines
    from rvdiag.kinematics import characteristic_frequencies
    from rvdiag.params import ReducerParams

    p = ReducerParams.default()
    fs, n = 48000.0, 48000
    cf = characteristic_frequencies(p, output_speed_deg_s=45.0)
    t = np.arange(n) / fs
    x = (np.sin(2 * np.pi * cf.fsp * t) + 2 * np.sin(2 * np.pi * cf.fcs * t) + np.sin(2 * np.pi * 2 * cf.fcs * t)
         + 0.01 * np.random.default_rng(0).standard_normal(n))
    assert confirm_speed(x, fs, p, 45.0)["confirmed"]
    wrong = 45.0 * 2 * cf.fcs / cf.fsp  # 2 fcs read as the stage-1 mesh
    assert not confirm_speed(x, fs, p, wrong)["confirmed"]
    assert mesh_lines(x, fs, p, 45.0)["present"] == ["stage1", "stage2"]
    assert mesh_lines(np.random.default_rng(1).standard_normal(n), fs, p, 45.0)["present"] == []


def test_evaluate_json_text_and_report_give_healthy_recall_and_false_alarms(model, tmp_path, capsys):
    model_dir, store = model
    rep = tmp_path / "r.html"
    code, out, err = run(["evaluate", model_dir, store, "--json", "--records", "--merge", "T3=T1", "--report", rep,
                          "-q"], capsys)
    assert code == 0, err
    m = json.loads(out)
    assert set(m["recall"]) == {"T1", "T2", "T3"} and m["healthy_class"] == "T1"
    assert m["false_alarm_rate"] == pytest.approx(1 - m["recall"]["T1"])
    assert m["records"]["false_alarm_rate"] is not None and m["merged"]["false_alarm_rate"] is not None
    html = rep.read_text()
    assert "false-alarm rate" in html and "healthy recall (T1)" in html
    code, out, _ = run(["evaluate", model_dir, store, "--records", "--merge", "T3=T1", "--by", "load_Nm", "-q"], capsys)
    assert code == 0
    import re

    text = " ".join(out.split())  # rich wraps long lines
    n_accuracies = len(re.findall(r"accuracy \d", text))
    # overall, merged, records, records merged: each with its false-alarm rate
    assert n_accuracies == 4 and text.count("false-alarm rate") == n_accuracies
    assert "false alarms" in out


def test_false_alarm_rate_is_the_share_of_healthy_samples_called_faulty():
    from rvdiag.evaluation.metrics import classification_metrics

    m = classification_metrics(["T1"] * 4 + ["T2"] * 4, ["T1", "T2", "T3", "T1"] + ["T2"] * 4, labels=["T1", "T2", "T3"])
    assert m["healthy_recall"] == 0.5 and m["false_alarm_rate"] == 0.5 and m["recall"]["T3"] is None
    assert classification_metrics(["a", "b"], ["a", "a"])["false_alarm_rate"] is None


@pytest.fixture(scope="module")
def healthy_records():
    """0.5 s healthy records simulated at 30, 45 and 60 deg/s (75 N m, 40 dB SNR, the demo library's model)."""
    from rvdiag.dynamics import ModelSettings, simulate
    from rvdiag.gears import ToothFaults

    return {sp: simulate(fault=ToothFaults.for_state("T1"), output_speed_deg_s=sp, load_Nm=75.0, duration_s=0.5,
                         noise_snr_db=40.0, settings=ModelSettings(substeps=4)).signal[0]
            for sp in (30.0, 45.0, 60.0)}


@pytest.mark.parametrize("speed", [30.0, 45.0, 60.0])
def test_the_true_speed_is_confirmed_and_its_harmonics_and_subharmonics_are_refused(healthy_records, speed):
    """Twice the true speed put the cycloid-pin mesh's 2nd harmonic where the mesh line should be, and
    was accepted (90 deg/s for records at 45 deg/s).  The line at half the mesh frequency now gives it away."""
    from rvdiag.features.mesh_lines import confirm_speed
    from rvdiag.params import ReducerParams

    p, x = ReducerParams.default(), healthy_records[speed]
    ok = confirm_speed(x, 48000.0, p, speed)
    assert ok["confirmed"] and ok["reason"] is None and ok["harmonic_of"] is None
    twice = confirm_speed(x, 48000.0, p, 2 * speed)
    assert twice["stage2_height_db"] >= 10.0  # the mesh's 2nd harmonic stands where the mesh line should be
    assert not twice["confirmed"] and twice["harmonic_of"] == pytest.approx(speed)
    assert f"the lines fit {speed:.4g} deg/s" in twice["reason"]
    assert not confirm_speed(x, 48000.0, p, 3 * speed)["confirmed"]
    for k in (0.5, 1 / 3):
        wrong = confirm_speed(x, 48000.0, p, k * speed)
        assert not wrong["confirmed"] and wrong["reason"].startswith("no cycloid-pin mesh line")


def test_an_unsure_answer_warns_with_the_windows_split():
    """A record whose answer the other classes together outweigh (a T5 record with wear beyond the training
    range gave T6 at 0.39, windows 5 T5 / 4 T6 / 2 T2) says so, whatever the held-out test."""
    from rvdiag.workflows.records import state_name
    from rvdiag.models.conditions import record_warnings

    p = {"T2": 0.2, "T5": 0.38, "T6": 0.42}
    (line,) = record_warnings(p, ["T5"] * 5 + ["T6"] * 4 + ["T2"] * 2, state_name)
    assert line.startswith("warning: unsure answer: T6 (broken tooth + wear + root crack)") and "0.42" in line
    assert line.endswith("5 T5 (broken tooth + wear), 4 T6 (broken tooth + wear + root crack), 2 T2 (broken tooth)")
    assert record_warnings({"T1": 0.5, "T4": 0.5}, ["T1", "T4"]) == []  # one half: not below
    assert record_warnings(None, []) == []  # not recognised: no answer
