"""The public workflow API (rvdiag.workflows: train -> TrainResult, evaluate -> Evaluation, diagnose -> Diagnosis,
read_record, load_model) on the tiny synthetic store of tests/test_cli_train.py: each result's ``to_dict()`` is what
the command prints with ``--json``, and the one model loaded once answers every record."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli
from rvdiag.errors import ParameterError
from rvdiag.workflows import (Diagnosis, Evaluation, TrainResult, diagnose, evaluate, load_model, read_record,
                              train)
from test_cli_train import FS, L, _signal
from test_cli_train import store  # noqa: F401  (the module-scoped tiny store)


@pytest.fixture(scope="module")
def trained(store, tmp_path_factory):  # noqa: F811
    lines = []
    res = train(store, tmp_path_factory.mktemp("m") / "svm", model="svm", features="time", seed=0, echo=lines.append)
    return res, lines


def test_train_returns_what_the_cli_prints_and_saves_the_model(trained, store, tmp_path, capsys):  # noqa: F811
    res, lines = trained
    assert isinstance(res, TrainResult) and res.model == "svm" and res.n_train == 36
    assert any("36 training samples of 256 points, 3 classes, 12 test samples" in s for s in lines)
    d = res.to_dict()
    assert set(d) == {"model_dir", "metrics", "repeat"} and d["repeat"] is None and 0 <= d["metrics"]["accuracy"] <= 1
    code, out, err = run_cli(["train", store, "--model", "svm", "--features", "time", "--seed", 0, "-o",
                              tmp_path / "cli", "--json"], capsys)
    assert code == 0, err
    cli = json.loads(out)
    assert cli["metrics"] == json.loads(json.dumps(d["metrics"]))  # the same seed, the same model
    card = json.loads((tmp_path / "cli" / "card.json").read_text())
    assert card["model"] == "svm" and card["features"] == "time"


def test_evaluate_returns_what_the_cli_prints(trained, store, capsys):  # noqa: F811
    res, _ = trained
    model = load_model(res.model_dir)
    ev = evaluate(model, store, split="test", merge={"T3": "T1"}, records=True, by="output_speed_deg_s")
    assert isinstance(ev, Evaluation) and ev.split == "test"
    d = ev.to_dict()
    assert d["n_samples"] == 12 and {"merged", "records", "by"} <= set(d) and "snr" not in d
    code, out, err = run_cli(["evaluate", res.model_dir, store, "--merge", "T3=T1", "--records", "--by",
                              "output_speed_deg_s", "--json"], capsys)
    assert code == 0, err
    assert json.loads(out) == json.loads(json.dumps(d))


def test_diagnose_returns_what_the_cli_prints(trained, tmp_path, capsys):
    res, _ = trained
    model = load_model(res.model_dir)
    f = tmp_path / "r.npy"
    np.save(f, _signal(1, 3 * L + 10, np.random.default_rng(0)))
    d = diagnose(model, read_record(f, fs=FS))
    assert isinstance(d, Diagnosis) and d.recognised and d.n_windows == 3 and d.unused_points == 10
    assert d.state.startswith(d.diagnosis) and sum(d.probabilities.values()) == pytest.approx(1.0)
    out_d = d.to_dict()
    assert "current_lines" not in out_d and "indicators" in out_d and "model_recall" in out_d
    code, out, err = run_cli(["diagnose", res.model_dir, f, "--fs", FS, "--json"], capsys)
    assert code == 0, err
    assert json.loads(out) == json.loads(json.dumps(out_d))
    ax = d.plot()
    assert len(ax.lines) == 3  # one line per class


def test_monitoring_refuses_a_classifier_in_one_line(trained, tmp_path):
    from rvdiag.monitoring import monitor_record, open_baseline

    model = load_model(trained[0].model_dir)
    with pytest.raises(ParameterError, match="not baseline-referenced"):
        open_baseline(tmp_path / "b.zarr", model)
    rec = read_record(_npy(tmp_path, np.zeros(L)), fs=FS)
    with pytest.raises(ParameterError, match="judge its records with rvdiag.workflows.diagnose"):
        monitor_record(model, rec, None)


def _npy(tmp_path, x):
    np.save(tmp_path / "x.npy", x)
    return tmp_path / "x.npy"


def test_a_flat_record_is_not_recognised(trained, tmp_path):
    res, _ = trained
    model = load_model(res.model_dir)
    f = tmp_path / "flat.npy"
    np.save(f, np.zeros(2 * L))
    d = diagnose(model, read_record(f, fs=FS)).to_dict()
    assert d["recognised"] is False and d["diagnosis"] is None and d["probabilities"] is None
    assert "model_recall" not in d and "unused_points" not in d


def test_train_refuses_bad_options_in_one_line(store, tmp_path):  # noqa: F811
    with pytest.raises(ParameterError, match="--repeat must be >= 1"):
        train(store, tmp_path / "m", model="svm", repeat=0)
    with pytest.raises(ParameterError, match="unknown model 'nope'"):
        train(store, tmp_path / "m", model="nope")
    assert not (tmp_path / "m").exists()
