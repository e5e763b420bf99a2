"""``rvdiag mcsa``: the motor-current study's protocol (per speed, per feature set, repeated stratified splits and
an SVM; a held-out store) on tiny synthetic stores, its outputs, its seeds, and its one-line errors (exit 2)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli as run
from rvdiag.datasets import SampleStore, write_store
from rvdiag.errors import SplitLeakWarning, StoreError
from rvdiag.evaluation.motor_current_study import METRICS, McsaSettings, pick_channel, run_mcsa, sample_channels, split_seeds

FS = 1000.0
L = 128
SPEEDS = (30.0, 60.0)
PER_CLASS = 12  # samples per class and speed


def _signal(c: int, speed: float, rng) -> np.ndarray:
    """Class c: a supply-like tone at a speed-dependent frequency, a class tone whose amplitude and frequency grow
    with c, and impulses for c = 2 (the time statistics and the band energies both see the classes)."""
    t = np.arange(L) / FS
    x = np.sin(2 * np.pi * (speed / 3.0) * t + rng.uniform(0, 6))
    x += (0.5 + 0.8 * c) * np.sin(2 * np.pi * (90.0 + 120.0 * c) * t + rng.uniform(0, 6))
    if c == 2:
        x[rng.integers(0, 16)::16] += 4.0
    return x + 0.1 * rng.standard_normal(L)


def _make(path, seed: int, *, shuffle: bool = False, per_class: int = PER_CLASS, channels=None, extra_meta=None):
    rng = np.random.default_rng(seed)
    X, y, speed, unit = [], [], [], []
    for s in SPEEDS:
        for c in range(3):
            for i in range(per_class):
                X.append(_signal(c, s, rng))
                y.append(f"T{c + 1}")
                speed.append(s)
                unit.append(int(s) * 100 + c * 10 + i // 3)  # 3 windows per simulation
    if shuffle:  # labels independent of the signals, within each speed: only chance is left to find
        y = np.asarray(y, dtype=object)
        for s in SPEEDS:
            m = np.asarray(speed) == s
            y[m] = rng.permutation(y[m])
        y = y.tolist()
    meta = {"split": ["train"] * len(y), "unit": unit, "output_speed_deg_s": speed}
    if channels is not None:
        meta["channel"] = channels(len(y))
    meta.update(extra_meta or {})
    write_store(path, np.asarray(X, np.float32), y, meta=meta, kind="simulated", fs=FS,
                config={"name": f"mcsa-{seed}", "channel": "i_a"})
    return path


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    d = tmp_path_factory.mktemp("mcsa")
    return {"a": _make(d / "a.zarr", 0), "b": _make(d / "b.zarr", 1), "shuffled": _make(d / "s.zarr", 2, shuffle=True),
            "tiny": _make(d / "tiny.zarr", 3, per_class=1),
            "two": _make(d / "two.zarr", 4, channels=lambda n: ["i_a" if k % 2 else "vibration" for k in range(n)])}


def _mcsa(capsys, store, out, *extra):
    return run(["mcsa", store, "-o", out, "-q", "--feature-sets", "time,wpt", "--repeats", "3", *extra], capsys)


def _figures(report, protocol="split"):
    for speed, sets in report["results"].items():
        for name, e in sets.items():
            yield speed, name, e[protocol]


def test_writes_json_markdown_and_tsne_with_high_scores_on_separable_data(stores, tmp_path, capsys):
    out = tmp_path / "out"
    code, stdout, err = _mcsa(capsys, stores["a"], out, "--test", stores["b"], "--seed", "3")
    assert code == 0, err
    assert {p.name for p in out.iterdir()} == {"mcsa.json", "mcsa.md", "tsne_time.png", "tsne_wpt.png"}
    rep = json.loads((out / "mcsa.json").read_text())
    assert rep["speeds"] == ["30", "60"] and rep["speed_unit"] == "deg/s"
    assert rep["store"]["channel"] == "i_a" and rep["store"]["n_used"] == 2 * 3 * PER_CLASS
    assert rep["settings"]["seed"] == 3 and rep["split_seeds"] == split_seeds(3, 3)
    assert rep["svm"]["kernel"] == "rbf" and len(rep["time_features"]) == 10
    for speed, name, split in _figures(rep):
        assert len(split["repeats"]) == 3
        assert [r["seed"] for r in split["repeats"]] == rep["split_seeds"]
        for r in split["repeats"]:  # stratified 70/30: 36 samples -> 25 / 11
            assert (r["n_train"], r["n_test"]) == (25, 11)
            assert all(0.0 <= r[k] <= 1.0 for k in METRICS if k != "kappa") and -1.0 <= r["kappa"] <= 1.0
        for k in METRICS:
            assert 0.0 <= split[k]["std"] <= 0.5
        assert split["accuracy"]["mean"] >= 0.9 and split["kappa"]["mean"] >= 0.85, (speed, name, split)
    for speed, name, held in _figures(rep, "held_out"):  # fitted on a.zarr, scored on the unseen b.zarr
        assert held["n_test"] == 3 * PER_CLASS and held["accuracy"] >= 0.9, (speed, name)
    md = (out / "mcsa.md").read_text()
    assert md == stdout.split("wrote ")[0]
    assert "| 30 | time-domain statistics (10) |" in md and "| 60 | wavelet-packet energies (level 4) |" in md
    assert "Held out" in md and "<= 83.75 %" in md
    assert (out / "tsne_time.png").read_bytes()[:4] == b"\x89PNG"


def test_label_shuffled_data_scores_near_chance(stores, tmp_path, capsys):
    out = tmp_path / "out"
    code, _, err = _mcsa(capsys, stores["shuffled"], out, "--repeats", "5", "--tsne-samples", "0")
    assert code == 0, err
    rep = json.loads((out / "mcsa.json").read_text())
    assert not (out / "tsne_time.png").exists()  # --tsne-samples 0: no figures
    for speed, name, split in _figures(rep):
        assert split["accuracy"]["mean"] < 0.6 and abs(split["kappa"]["mean"]) < 0.35, (speed, name, split)


def test_the_seed_makes_results_reproducible(stores, tmp_path, capsys):
    reps = []
    for k, seed in enumerate((5, 5, 6)):
        out = tmp_path / f"o{k}"
        code, _, err = _mcsa(capsys, stores["a"], out, "--seed", str(seed), "--feature-sets", "time",
                             "--tsne-samples", "0")
        assert code == 0, err
        reps.append(json.loads((out / "mcsa.json").read_text()))
    assert reps[0]["results"] == reps[1]["results"] and reps[0]["split_seeds"] == reps[1]["split_seeds"]
    assert reps[0]["split_seeds"] != reps[2]["split_seeds"]
    confusions = [[r["confusion"] for _, _, s in _figures(rep) for r in s["repeats"]] for rep in reps]
    n_test = [[r["n_test"] for _, _, s in _figures(rep) for r in s["repeats"]] for rep in reps]
    assert n_test[0] == n_test[2] and confusions[0] == confusions[1]


def test_cnn_features_run_tiny(stores, tmp_path, capsys):
    out = tmp_path / "out"
    code, _, err = run(["mcsa", stores["a"], "-o", out, "-q", "--feature-sets", "cnn", "--repeats", "1",
                        "--cnn-epochs", "2", "--cnn-batch-size", "16", "--cnn-lr", "0.005", "--device", "cpu",
                        "--json"], capsys)
    assert code == 0, err
    rep = json.loads((out / "mcsa.json").read_text())
    assert list(rep["feature_sets"]) == ["cnn"] and rep["settings"]["cnn_epochs"] == 2
    # the default representation: the log spectrum, which finds what the spectrum finds (docs/results.md)
    assert rep["settings"]["cnn_representation"] == "logspec"
    assert "The CNN sees each window as `logspec`" in (out / "mcsa.md").read_text()
    for _, _, split in _figures(rep):
        assert 0.0 <= split["accuracy"]["mean"] <= 1.0 and split["repeats"][0]["n_test"] == 11
        assert set(split["recall_per_class"]) == {"T1", "T2", "T3"}
    assert (out / "tsne_cnn.png").is_file()


def test_cnn_representation_is_chosen_and_recorded(stores, tmp_path, capsys, monkeypatch):
    from rvdiag.models import cnn_features

    seen = []
    fit = cnn_features.CNNFeatures.fit
    monkeypatch.setattr(cnn_features.CNNFeatures, "fit",
                        lambda self, X, y=None: (seen.append(self.representation), fit(self, X, y))[1])
    out = tmp_path / "out"
    code, _, err = run(["mcsa", stores["a"], "-o", out, "-q", "--feature-sets", "cnn", "--repeats", "1",
                        "--cnn-epochs", "1", "--device", "cpu", "--tsne-samples", "0",
                        "--cnn-representation", "residual"], capsys)
    assert code == 0, err
    assert json.loads((out / "mcsa.json").read_text())["settings"]["cnn_representation"] == "residual"
    assert seen and set(seen) == {"residual"}


def test_class_recalls_read_the_confusion_rows():
    from rvdiag.evaluation.motor_current_study import class_recalls

    assert class_recalls([[3, 1], [0, 0]], ["T1", "T2"]) == {"T1": 0.75, "T2": None}


def test_channel_default_and_choice():
    assert pick_channel(["vibration", "i_a"], None, "s") == "i_a"
    assert pick_channel(["x", "y"], None, "s") == "x"
    assert pick_channel(["X105_DE_time", "X105_FE_time"], "DE", "s") == "X105_DE_time"
    with pytest.raises(StoreError, match=r"no channel match --channel 'i_b' \(channels: x, y\)"):
        pick_channel(["x", "y"], "i_b", "s")
    with pytest.raises(StoreError, match="2 channels"):
        pick_channel(["x_time", "y_time"], "time", "s")


def test_picks_the_rows_of_the_channel(stores):
    store = SampleStore.open(stores["two"])
    assert sorted(set(sample_channels(store).tolist())) == ["i_a", "vibration"]
    with pytest.warns(SplitLeakWarning, match="windows of one simulation on both sides"):
        res = run_mcsa(store, McsaSettings(feature_sets=("time",), repeats=1, tsne_samples=0))
    assert res.report["store"]["channel"] == "i_a" and res.report["store"]["n_used"] == 3 * PER_CLASS
    assert "the split scores are optimistic" in res.report["notes"][0]
    with pytest.warns(SplitLeakWarning):
        res = run_mcsa(store, McsaSettings(feature_sets=("time",), repeats=1, channel="vib", tsne_samples=0))
    assert res.report["store"]["channel"] == "vibration"
    assert sample_channels(SampleStore.open(stores["a"])).tolist()[:2] == ["i_a", "i_a"]  # the config's channel
    a = SampleStore.open(stores["a"])
    with pytest.warns(SplitLeakWarning) as caught:  # the same simulations on both sides
        res = run_mcsa(a, McsaSettings(feature_sets=("time",), repeats=1, tsne_samples=0), test_store=a)
    assert any("the same config" in str(w.message) for w in caught)
    assert any("held-out figures are optimistic" in n for n in res.report["notes"])


@pytest.mark.parametrize("args, message", [
    (["--feature-sets", "time,fft"], "error: unknown feature set 'fft'; use one or more of time,wpt,cnn, "
                                     "comma-separated"),
    (["--channel", "i_b"], "no channel match --channel 'i_b' (channels: i_a)"),
    (["--speed-column", "rpm"], "has no metadata column 'rpm' to group the samples by speed"),
    (["--test-size", "1.5"], "error: --test-size must be a fraction in (0, 1), got 1.5"),
    (["--repeats", "0"], "error: --repeats must be a whole number >= 1, got 0"),
    (["--seed", "-1"], "error: --seed must be a whole number >= 0, got -1"),
    (["--feature-sets", "cnn", "--cnn-input-length", "4096"],
     "error: --cnn-input-length 4096 is longer than the samples of"),
    (["--cnn-epochs", "0"], "error: --cnn-epochs must be >= 1, got 0"),
    (["--cnn-representation", "orders"], "error: --cnn-representation must be one of waveform, logspec, residual"),
])
def test_bad_options_give_one_line_and_exit_2(stores, tmp_path, capsys, args, message):
    code, out, err = _mcsa(capsys, stores["a"], tmp_path / "out", *args)
    assert code == 2 and out == "" and len(err.splitlines()) == 1 and message in err, err
    assert err.startswith("error: ") and not (tmp_path / "out" / "mcsa.json").exists()


def test_bad_stores_give_one_line_and_exit_2(stores, tmp_path, capsys):
    code, _, err = _mcsa(capsys, tmp_path / "missing.zarr", tmp_path / "o")
    assert code == 2 and err == f"error: no sample store at {tmp_path / 'missing.zarr'}\n"
    code, _, err = _mcsa(capsys, stores["tiny"], tmp_path / "o")  # one sample per class and speed
    assert code == 2 and len(err.splitlines()) == 1 and "too few samples for a stratified 70/30 split" in err
    assert "at 30 deg/s" in err
    code, _, err = _mcsa(capsys, stores["a"], tmp_path / "o", "--test", tmp_path / "none.zarr")
    assert code == 2 and err.startswith("error: no sample store at")
    out = tmp_path / "done"
    assert _mcsa(capsys, stores["a"], out, "--feature-sets", "time", "--repeats", "1", "--tsne-samples", "0")[0] == 0
    code, _, err = _mcsa(capsys, stores["a"], out, "--feature-sets", "time")
    assert code == 2 and err == f"error: {out} already holds the results of a run; use --overwrite to replace them\n"
    assert _mcsa(capsys, stores["a"], out, "--feature-sets", "time", "--repeats", "1", "--tsne-samples", "0",
                 "--overwrite")[0] == 0
