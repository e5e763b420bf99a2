"""train -> evaluate -> diagnose on a tiny synthetic store, and the one-line errors (exit 2)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rvdiag.cli import main
from rvdiag.datasets import write_store
from conftest import run_cli as run

FS = 1000.0
L = 256


def _signal(c: int, n: int, rng) -> np.ndarray:
    t = np.arange(n) / FS
    x = np.sin(2 * np.pi * (50 + 60 * c) * t + rng.uniform(0, 6)) + 0.2 * rng.standard_normal(n)
    if c == 1:
        x[rng.integers(0, 20)::20] += 4.0
    return x


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    rng = np.random.default_rng(0)
    X, y, split, unit = [], [], [], []
    for c in range(3):
        for i in range(16):
            X.append(_signal(c, L, rng))
            y.append(f"T{c + 1}")
            split.append("test" if i < 4 else "train")
            unit.append(c * 100 + i // 2)
    p = tmp_path_factory.mktemp("s") / "tiny.zarr"
    write_store(p, np.asarray(X, np.float32), y,
                meta={"split": split, "unit": unit, "output_speed_deg_s": [45.0] * len(y)},
                kind="simulated", fs=FS, config={"name": "tiny"})
    return p


@pytest.fixture(scope="module")
def cnn_model(store, tmp_path_factory):
    out = tmp_path_factory.mktemp("m") / "model"
    main_args = ["train", store, "--model", "cnn1d-lean", "--out", out, "--epochs", "8", "--lr", "0.01",
                 "--batch-size", "8", "--device", "cpu", "--seed", "1", "--quiet", "--representation", "waveform",
                 "--patience", "5"]
    try:
        main([str(a) for a in main_args])
    except SystemExit as exc:  # pragma: no cover - a failure shows here
        assert exc.code == 0
    return out


def test_train_writes_a_model_directory(cnn_model):
    assert (cnn_model / "card.json").is_file() and (cnn_model / "model.safetensors").is_file()
    card = json.loads((cnn_model / "card.json").read_text())
    assert card["classes"] == ["T1", "T2", "T3"] and card["seed"] == 1 and card["fs"] == FS
    assert card["training_store"]["config_hash"] and card["training_store"]["path"].endswith("tiny.zarr")
    # three clearly different tones, seed 1: the card's held-out metrics are perfect (4 windows per class)
    assert card["metrics"]["accuracy"] == 1.0 and card["metrics"]["kappa"] == 1.0
    assert {c: v["support"] for c, v in card["metrics"]["per_class"].items()} == {"T1": 4, "T2": 4, "T3": 4}


def test_evaluate_json_and_report(cnn_model, store, tmp_path, capsys):
    rep = tmp_path / "report.html"
    code, out, err = run(["evaluate", cnn_model, store, "--split", "test", "--json", "--report", rep], capsys)
    assert code == 0, err
    m = json.loads(out)
    for key in ("accuracy", "precision_macro", "recall_macro", "f1_macro", "kappa", "per_class", "confusion"):
        assert key in m
    assert np.sum(m["confusion"]) == 12
    assert m["accuracy"] >= 0.75  # three clearly different tones
    text = rep.read_text()
    assert "t-SNE" in text and "data:image/png;base64," in text
    code, out, _ = run(["evaluate", cnn_model, store, "--split", "all", "--by", "output_speed_deg_s"], capsys)
    assert code == 0 and "48 samples" in out and "T3" in out and "accuracy by output_speed_deg_s" in out
    code, out, err = run(["evaluate", cnn_model, store, "--json", "--by", "unit"], capsys)
    assert code == 0, err
    groups = json.loads(out)["by"]["groups"]
    assert sum(g["n"] for g in groups) == 12 and len(groups) == 6  # 12 test samples in 6 units, by value
    code, _, err = run(["evaluate", cnn_model, store, "--by", "snr"], capsys)
    assert code == 2 and "no metadata column 'snr'" in err


def test_diagnose_windows_a_signal(cnn_model, tmp_path, capsys):
    rng = np.random.default_rng(5)
    x = np.concatenate([_signal(2, L, rng) for _ in range(3)])[: 3 * L - 10]
    f = tmp_path / "sig.npy"
    np.save(f, x)
    code, out, err = run(["diagnose", cnn_model, f, "--json"], capsys)
    assert code == 0, err
    res = json.loads(out)
    assert res["n_windows"] == 2 and len(res["windows"]) == 2 and res["window_length"] == L
    assert sum(res["probabilities"].values()) == pytest.approx(1.0, abs=1e-5)
    assert res["diagnosis"] == "T3"
    assert "no sampling rate" in err and res["unused_points"] == 246 and "not used" not in err
    code, out, err = run(["diagnose", cnn_model, f, "--fs", "2000"], capsys)
    assert code == 0 and "2000 Hz but the model was trained at 1000 Hz" in err
    assert "diagnosis: T3" in out and "overall" in out


@pytest.mark.parametrize("args, message", [
    (["diagnose", "{tmp}/nope", "{sig}"], "no model at"),
    (["diagnose", "{store}", "{sig}"], "not an rvdiag model directory"),
    (["diagnose", "{model}", "{short}"], "shorter than one window"),
    (["evaluate", "{model}", "{model}"], "sample store"),
    (["evaluate", "{model}", "{store}", "--split", "valid"], "no split"),
    (["train", "{store}", "--model", "resnet", "--out", "{tmp}/x"], "unknown model"),
    (["train", "{store}", "--model", "cnn1d-lean", "--features", "wpd", "--out", "{tmp}/x"], "--features"),
    (["train", "{store}", "--model", "cnn1d", "--out", "{tmp}/x", "--quiet"], "6400"),
    (["train", "{tmp}/missing.zarr", "--out", "{tmp}/x"], "no sample store"),
    (["train", "{store}", "--device", "tpu", "--out", "{tmp}/x"], "unknown device"),
    (["train", "{store}", "--model", "svm", "--features", "fft", "--out", "{tmp}/x"], "unknown feature set"),
    (["evaluate", "{model}", "{store}", "--report", "{sig}/r.html"], "not a writable file path"),
])
def test_bad_input_is_one_line_exit_2(cnn_model, store, tmp_path, capsys, args, message):
    short = tmp_path / "short.npy"
    np.save(short, np.zeros(100))
    sig = tmp_path / "sig.npy"
    np.save(sig, np.zeros(1000))
    subst = {"{tmp}": str(tmp_path), "{model}": str(cnn_model), "{store}": str(store),
             "{short}": str(short), "{sig}": str(sig)}
    argv = []
    for a in args:
        for k, v in subst.items():
            a = a.replace(k, v)
        argv.append(a)
    code, out, err = run(argv, capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], err


def test_evaluate_refuses_a_store_of_other_length(cnn_model, tmp_path, capsys):
    p = tmp_path / "long.zarr"
    write_store(p, np.zeros((4, 2 * L), np.float32), ["T1", "T2", "T1", "T2"],
                meta={"split": ["test"] * 4, "unit": [0, 1, 2, 3]}, kind="measured", fs=FS, config={})
    code, _, err = run(["evaluate", cnn_model, p], capsys)
    assert code == 2 and "takes samples of 256 points" in err


def test_classical_model_and_repeat(store, tmp_path, capsys):
    out = tmp_path / "svm"
    code, stdout, err = run(["train", store, "--model", "svm", "--features", "time", "--out", out,
                             "--repeat", "2", "--quiet"], capsys)
    assert code == 0, err
    assert "over 2 seeds" in stdout and "overall" in stdout
    summary = json.loads((out / "repeat.json").read_text())
    assert summary["n_runs"] == 2 and set(summary["per_class"]) == {"T1", "T2", "T3"}
    code, stdout, err = run(["evaluate", out, store, "--json"], capsys)
    assert code == 0, err
    assert json.loads(stdout)["accuracy"] >= 0.5


def test_validation_split_is_by_segment_without_overlap_and_by_simulation_with_it():
    """Paper mode (one simulation per state, hop = segment length) must still get a validation set: split
    by segment there; with overlapping segments, whole simulations move (no leak)."""
    from types import SimpleNamespace

    from rvdiag.workflows.training import validation_groups

    units = np.array([0, 0, 1, 1])
    samples = SimpleNamespace(meta={"unit": units})

    def store(hop, seg):
        return SimpleNamespace(attrs={"config": {"signal": {"hop": hop, "segment_length": seg}}})

    assert validation_groups(store(8000, 8000), samples) is None
    assert validation_groups(store(2048, 4096), samples) is units
    assert validation_groups(SimpleNamespace(attrs={}), samples) is units      # measured-data stores
    assert validation_groups(store(2048, 4096), SimpleNamespace(meta={})) is None
    # several simulations (reducers) of a state: whole reducers move, whatever the hop (an independent-mode library
    # with hop = segment length validated on its training reducers' windows and stopped on their fingerprints)
    several = SimpleNamespace(meta={"unit": np.array([0, 0, 1, 1, 2, 2, 3, 3])}, y=np.array([0, 0, 0, 0, 1, 1, 1, 1]))
    assert validation_groups(store(8000, 8000), several) is several.meta["unit"]
    one_each = SimpleNamespace(meta={"unit": units}, y=np.array([0, 0, 1, 1]))
    assert validation_groups(store(8000, 8000), one_each) is None


def test_evaluate_accuracy_against_added_noise(cnn_model, store, capsys):
    """--snr-db scores the same samples at each added-noise level: seeded, reproducible, and accuracy falls
    to chance when the noise swamps the tones (-30 dB) while it holds at +30 dB."""
    args = ["evaluate", cnn_model, store, "--json", "--snr-db", "-30,30", "--seed", "3"]
    code, out, err = run(args, capsys)
    assert code == 0, err
    curve = json.loads(out)["snr"]
    assert [r["snr_db"] for r in curve] == [-30.0, 30.0] and all(r["n"] == 12 for r in curve)
    clean = json.loads(out)["accuracy"]
    assert curve[1]["accuracy"] >= clean - 1 / 12
    assert curve[0]["accuracy"] <= 0.6
    assert run(args, capsys)[1] == out                                  # same seed, same noise
    code, out, _ = run(["evaluate", cnn_model, store, "--snr-db", "0,10"], capsys)
    assert code == 0 and "accuracy against added-noise SNR" in out
    code, _, err = run(["evaluate", cnn_model, store, "--snr-db", "loud"], capsys)
    assert code == 2 and "--snr-db" in err


def test_evaluate_shows_progress_on_stderr_unless_quiet(cnn_model, store, capsys):
    """Scoring and the --snr-db levels report progress (bars with an ETA on a terminal; in a log, one line per
    finished stage) on stderr, never on stdout; -q turns it off."""
    code, out, err = run(["evaluate", cnn_model, store, "--json", "--snr-db", "0,10"], capsys)
    assert code == 0 and json.loads(out)["snr"]
    lines = err.splitlines()
    assert [ln.split(" in ")[0] for ln in lines] == ["scoring: 12/12", "scoring: 12/12", "scoring: 12/12",
                                                    "SNR levels: 2/2"], err
    code, out, err = run(["evaluate", cnn_model, store, "--json", "--snr-db", "0,10", "-q"], capsys)
    assert code == 0 and err == ""


def test_train_defaults_train_the_recommended_setup(store, tmp_path, capsys):
    """With no model options `train` builds the recommended network (spectrum-cnn on logspec) and says so in the
    card; the tiny store's 256-point samples are shorter than its 4096-point input, hence the named option."""
    code, _, err = run(["train", store, "-o", tmp_path / "m", "-q"], capsys)
    assert code == 2 and err == ("error: spectrum-cnn takes windows of 4096 points but the samples have only 256; give a "
                                 "shorter --input-length or use cnn1d-lean\n")
    code, _, err = run(["train", store, "-o", tmp_path / "m", "-q", "--input-length", "128", "--epochs", "1",
                        "--device", "cpu"], capsys)
    assert code == 0, err
    from rvdiag.models.persistence import read_card

    card = read_card(tmp_path / "m")
    assert card["model"] == "spectrum-cnn" and card["params"]["representation"] == "logspec"
    assert card["params"]["learning_rate"] == 3e-3 and card["params"]["n_iter_no_change"] == 6


def test_train_with_added_noise_is_recorded_and_seeded(store, tmp_path, capsys):
    from rvdiag.models.persistence import read_card

    """--snr-db adds seeded noise to the training and test samples; the card records it; at -30 dB the tones
    drown and the test accuracy falls towards chance."""
    def train(out, snr):
        args = ["train", store, "--model", "svm", "--features", "spectrum", "--out", out, "--json", "--seed", "2"]
        code, text, err = run(args + (["--snr-db", snr] if snr is not None else []), capsys)
        assert code == 0, err
        return json.loads(text)["metrics"]["accuracy"], read_card(out)

    clean, card0 = train(tmp_path / "a", None)
    noisy, card = train(tmp_path / "b", "-30")
    again, _ = train(tmp_path / "c", "-30")
    assert "added_noise" not in card0 and card["added_noise"]["snr_db"] == -30.0
    assert noisy == again and noisy < clean and noisy <= 0.6


def test_snr_curve_example_trains_one_model_per_level(store, tmp_path):
    """examples/snr_curve.py: one train per level, JSON with the curve, and a PNG figure."""
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "examples" / "snr_curve.py"
    out = tmp_path / "snr"
    proc = subprocess.run([sys.executable, str(script), str(store), "--levels=-30,30", "--out", str(out),
                           "--model", "svm", "--features", "spectrum"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    rows = json.loads((out / "snr_curve.json").read_text())
    assert [r["snr_db"] for r in rows] == [-30.0, 30.0]
    assert rows[0]["accuracy"] < rows[1]["accuracy"] and "--snr-db -30" in rows[0]["command"]
    assert (out / "snr_curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_classical_fit_shows_the_tuning_progress_unless_quiet(store, tmp_path, capsys):
    """A tuned KELM reports every objective evaluation (mealpy's budget: pop_size x (epoch + 1) = 20 x 21); in a
    log (not a terminal) one line per finished stage; -q: nothing."""
    args = ["train", store, "--model", "kelm-pso", "--features", "time", "--json"]
    code, out, err = run(args + ["-o", tmp_path / "a"], capsys)
    assert code == 0 and err == ""  # --json is quiet
    code, out, err = run(args[:-1] + ["-o", tmp_path / "b"], capsys)
    assert code == 0, err
    stages = [ln.split(" in ")[0] for ln in err.splitlines() if " in " in ln and ": " in ln]
    assert "PSO tuning: 420/420" in stages and "seed 0: fitting" in err
    code, out, err = run(args[:-1] + ["-o", tmp_path / "c", "-q"], capsys)
    assert code == 0 and "PSO tuning" not in err


def test_angle_domain_features_take_the_stores_rate_and_each_windows_speed(store, tmp_path, capsys):
    """``--features tsa-ci`` reads the store's sampling rate (1 kHz here, not the transformer's 48 kHz default) and
    each window's speed from the library's ``output_speed_deg_s`` column (recorded in the card, supplied again by
    ``evaluate``); a store without the column is refused with one line."""
    from rvdiag.models.persistence import load_model

    out = tmp_path / "m"
    code, _, err = run(["train", store, "--model", "svm", "--features", "tsa-ci", "--out", out, "-q"], capsys)
    assert code == 0, err
    loaded = load_model(out)
    assert loaded.card["metadata_columns"] == ["output_speed_deg_s"]
    feats = loaded.estimator.steps[0][1] if hasattr(loaded.estimator, "steps") else None
    assert feats is not None and feats.fs == FS and feats.speed_column == "output_speed_deg_s"
    code, out_json, err = run(["evaluate", out, store, "--json", "-q"], capsys)
    assert code == 0, err
    assert json.loads(out_json)["n_samples"] == 12
    code, _, err = run(["train", store, "--model", "svm", "--features", "tsa-ci", "--speed-column", "rpm_x",
                        "--out", tmp_path / "m2", "-q"], capsys)
    assert code == 2 and err.count("\n") == 1 and "rpm_x" in err, err
