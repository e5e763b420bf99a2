"""Scoring whole records (``rvdiag evaluate --records``, :func:`rvdiag.evaluation.evaluate.record_metrics`): the
windows of one simulation or file decided together, by mean probability as ``rvdiag diagnose`` decides a file."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import run_cli

from rvdiag.datasets.store import write_store
from rvdiag.errors import StoreError
from rvdiag.evaluation.evaluate import Evaluation, record_metrics


class _Fixed:
    """An 'estimator' whose probabilities of A and B are the first feature: P(A) = x[0]."""

    classes_ = np.asarray(["A", "B"])

    def predict_proba(self, X):
        return np.column_stack([X[:, 0], 1.0 - X[:, 0]])

    def predict(self, X):
        return self.classes_[(X[:, 0] < 0.5).astype(int)]


def _loaded(estimator):
    return SimpleNamespace(card={"classes": ["A", "B"]}, estimator=estimator, inputs=lambda X, meta, where="": X)


def _evaluation(p_a, truth, records, estimator):
    X = np.asarray(p_a, dtype=float)[:, None]
    return Evaluation({}, np.asarray(truth), np.asarray(estimator.predict(X)).astype(str), X,
                      {"unit": np.asarray(records)}, "test")


def test_a_record_is_decided_by_its_mean_probability_not_by_the_count_of_its_windows():
    # record 0 (truly B): two windows lean A a little, one is sure of B -> mean P(A) = 0.45: B, though 2 of 3 say A
    # record 1 (truly A): all windows A
    p_a = [0.6, 0.55, 0.2, 0.9, 0.8]
    ev = _evaluation(p_a, ["B", "B", "B", "A", "A"], [0, 0, 0, 1, 1], _Fixed())
    r = record_metrics(_loaded(_Fixed()), ev)
    assert r["decision"] == "mean probability" and r["n_records"] == 2 and r["windows_per_record"] == [2, 3]
    assert r["accuracy"] == 1.0 and r["confusion"] == [[1, 0], [0, 1]]
    # without probabilities the majority of the windows decides, and record 0 is then called A
    class Votes(_Fixed):
        predict_proba = property()  # no predict_proba

    votes = record_metrics(_loaded(Votes()), _evaluation(p_a, ["B", "B", "B", "A", "A"], [0, 0, 0, 1, 1], Votes()))
    assert votes["decision"] == "majority of the windows" and votes["accuracy"] == 0.5
    assert votes["confusion"] == [[1, 0], [1, 0]]


def test_merged_records_and_a_record_of_two_classes():
    ev = _evaluation([0.9, 0.9, 0.2, 0.2], ["B", "B", "B", "B"], [0, 0, 1, 1], _Fixed())
    r = record_metrics(_loaded(_Fixed()), ev, merge={"B": "A"})
    assert r["accuracy"] == 0.5 and r["merged"]["accuracy"] == 1.0 and r["merged"]["labels"] == ["A"]
    with pytest.raises(StoreError, match="several classes"):
        record_metrics(_loaded(_Fixed()), _evaluation([0.9, 0.2], ["A", "B"], [7, 7], _Fixed()))
    with pytest.raises(StoreError, match="no metadata column 'file'"):
        record_metrics(_loaded(_Fixed()), ev, column="file")


@pytest.fixture()
def store(tmp_path):
    """Three classes of tones, 8 records per class of 5 windows each (records 0-5 train, 6-7 test)."""
    rng = np.random.default_rng(0)
    t = np.arange(256) / 256.0
    X, y, unit, split = [], [], [], []
    for ci, c in enumerate(("T1", "T2", "T3")):
        for k in range(8):
            for _ in range(5):
                X.append(np.sin(2 * np.pi * (8 + 3 * ci) * t) + 1.5 * rng.standard_normal(256))
                y.append(c)
                unit.append(100 * ci + k)
                split.append("train" if k < 6 else "test")
    p = tmp_path / "s.zarr"
    write_store(p, np.asarray(X, dtype=np.float32), y, kind="library", fs=256.0, config={},
                meta={"split": split, "unit": unit})
    return p


def test_evaluate_records_on_the_command_line(store, tmp_path, capsys):
    out = tmp_path / "m"
    code, _, err = run_cli(["train", store, "--model", "svm", "--features", "spectrum", "-o", out, "-q"], capsys)
    assert code == 0, err
    code, text, err = run_cli(["evaluate", out, store, "--records", "--json", "-q"], capsys)
    assert code == 0, err
    res = json.loads(text)
    rec = res["records"]
    assert rec["n_records"] == 6 and rec["windows_per_record"] == [5, 5] and sum(map(sum, rec["confusion"])) == 6
    assert rec["decision"] == "mean probability"
    code, text, err = run_cli(["evaluate", out, store, "--records", "-q"], capsys)
    assert code == 0, err
    assert "records (6 of 5 windows, decided by mean probability): accuracy" in " ".join(text.split())
