"""Compound faults as several labels (rvdiag.models.multilabel, rvdiag train --multilabel): the decoding table,
a synthetic case it must get right, the save/load round trip and the one-line refusals."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from rvdiag.datasets import write_store
from rvdiag.errors import ParameterError
from rvdiag.models.multilabel import (
    FAULT_LABELS,
    STATE_FAULTS,
    CompoundFaultClassifier,
    fault_codes,
    joint_probabilities,
)
from rvdiag.models.persistence import load_model, save_model
from rvdiag.models.pipelines import make_classical_model
from conftest import run_cli as run

STATES = ["T1", "T2", "T3", "T4", "T5", "T6"]


def test_the_states_fault_table():
    assert FAULT_LABELS == ("broken", "worn", "cracked")
    assert STATE_FAULTS == {"T1": (0, 0, 0), "T2": (1, 0, 0), "T3": (0, 1, 0), "T4": (0, 0, 1),
                            "T5": (1, 1, 0), "T6": (1, 1, 1)}
    assert_array_equal(fault_codes(["T6", "T1", "T4"]), [[1, 1, 1], [0, 0, 0], [0, 0, 1]])
    with pytest.raises(ParameterError, match="T7"):
        fault_codes(["T1", "T7"])


@pytest.mark.parametrize("bits", list(itertools.product((0, 1), repeat=3)))
def test_decoding_picks_the_valid_combination_of_largest_joint_probability(bits):
    """Sure per-fault answers decode to their state; the two combinations no state has (worn + cracked,
    broken + cracked without wear) go to the valid state of largest product, computed by brute force."""
    P = np.where(np.array(bits) == 1, 0.8, 0.2)[None, :]
    J = joint_probabilities(P, STATES)
    brute = {s: np.prod([P[0, k] if b else 1 - P[0, k] for k, b in enumerate(STATE_FAULTS[s])]) for s in STATES}
    total = sum(brute.values())
    assert_allclose(J[0], [brute[s] / total for s in STATES], rtol=1e-12)
    state = {v: k for k, v in STATE_FAULTS.items()}.get(bits)
    if state is not None:
        assert STATES[int(np.argmax(J))] == state


def test_decoding_examples():
    P = np.array([[0.9, 0.9, 0.4],    # broken + worn, crack unsure -> T5
                  [0.4, 0.9, 0.9],    # worn + cracked is no state: T6 (.324) beats T3, T4 (.054), T5 (.036)
                  [0.0, 0.0, 0.0],    # exact zeros are clipped, not log(0)
                  [1.0, 1.0, 1.0]])
    J = joint_probabilities(P, STATES)
    assert [STATES[i] for i in J.argmax(1)] == ["T5", "T6", "T1", "T6"]
    assert_allclose(J.sum(1), 1.0)
    assert np.all(np.isfinite(J))
    # only the training states are candidates: without T6, (1, 1, 1) is T5
    assert joint_probabilities([[1.0, 1.0, 1.0]], ["T1", "T2", "T3", "T5"]).argmax() == 3


def _synthetic(n_per: int, seed: int, states=STATES, n=8):
    """Each fault adds its own bump to the first three points (plus noise elsewhere): a sample is its state's
    combination, nothing else, so the three binary labels must find every state, compound ones included."""
    rng = np.random.default_rng(seed)
    y = np.repeat(np.asarray(states), n_per)
    X = 0.3 * rng.standard_normal((y.size, n))
    X[:, :3] += 3.0 * fault_codes(y)
    return X, y


@pytest.fixture(scope="module")
def fitted():
    X, y = _synthetic(20, 0)
    return make_classical_model("svm", "none", seed=0, multilabel=True).fit(X, y)


def test_a_case_it_must_get_right(fitted):
    Xt, yt = _synthetic(10, 1)
    assert isinstance(fitted[-1], CompoundFaultClassifier)
    assert list(fitted.classes_) == STATES
    assert fitted.score(Xt, yt) == 1.0
    P = fitted.predict_proba(Xt)
    assert P.shape == (60, 6)
    assert_allclose(P.sum(1), 1.0)
    F = fitted[-1].fault_probabilities(fitted[:-1].transform(Xt))
    assert_array_equal(F > 0.5, fault_codes(yt).astype(bool))


def test_a_fault_constant_in_training_needs_no_classifier():
    X, y = _synthetic(15, 2, states=["T1", "T2", "T3", "T5"])  # nothing cracked
    m = CompoundFaultClassifier(make_classical_model("kelm", "none")[-1]).fit(X, y)
    assert m.estimators_[2] is None and m.constant_[2] == 0.0
    Xt, yt = _synthetic(5, 3, states=["T1", "T2", "T3", "T5"])
    assert m.score(Xt, yt) == 1.0 and set(m.predict(Xt)) <= {"T1", "T2", "T3", "T5"}


def test_save_load_round_trip(fitted, tmp_path):
    Xt, _ = _synthetic(5, 4)
    save_model(fitted, tmp_path / "m", model="svm", features="none", seed=0)
    card = json.loads((tmp_path / "m" / "card.json").read_text())
    assert card["classes"] == STATES and card["multilabel"]["labels"] == ["broken", "worn", "cracked"]
    loaded = load_model(tmp_path / "m")
    assert isinstance(loaded.estimator[-1], CompoundFaultClassifier)
    assert_array_equal(loaded.estimator.predict(Xt), fitted.predict(Xt))
    assert_allclose(loaded.estimator.predict_proba(Xt), fitted.predict_proba(Xt), rtol=1e-12)


def _store(path, states, n_per=30, seed=0):
    X, y = _synthetic(n_per, seed, states=[s if s in STATE_FAULTS else "T1" for s in states])
    y = np.repeat(np.asarray(states), n_per)
    split = np.tile(["test"] * 6 + ["train"] * (n_per - 6), len(states)).tolist()
    write_store(path, X.astype(np.float32), y.tolist(),
                meta={"split": split, "unit": list(range(y.size))}, kind="simulated", fs=1000.0,
                config={"name": "ml"})
    return path


def test_cli_trains_evaluates_and_diagnoses_a_multilabel_model(tmp_path, capsys):
    store = _store(tmp_path / "s.zarr", STATES)
    out = tmp_path / "m"
    code, _, err = run(["train", store, "--model", "svm", "--features", "none", "--multilabel", "-q",
                        "-o", out], capsys)
    assert code == 0, err
    card = json.loads((out / "card.json").read_text())
    assert card["multilabel"]["labels"] == list(FAULT_LABELS) and card["metrics"]["accuracy"] == 1.0
    code, stdout, err = run(["evaluate", out, store, "--json"], capsys)
    assert code == 0, err
    assert json.loads(stdout)["accuracy"] == 1.0
    x = np.zeros(8)
    x[:3] = 3.0  # broken + worn + cracked
    np.save(tmp_path / "sig.npy", x)
    code, stdout, err = run(["diagnose", out, tmp_path / "sig.npy", "--json"], capsys)
    assert code == 0, err
    assert json.loads(stdout)["diagnosis"] == "T6"


@pytest.mark.parametrize("states, args, message", [
    (["T1", "T2", "T7"], ["--model", "svm"], "T7"),
    (["T1", "T2", "T8", "T3"], ["--model", "kelm"], "T8"),
    (STATES, ["--model", "cnn1d-lean"], "classical models"),
])
def test_cli_refuses_in_one_line(tmp_path, capsys, states, args, message):
    store = _store(tmp_path / "s.zarr", states)
    code, _, err = run(["train", store, *args, "--multilabel", "-q", "-o", tmp_path / "m"], capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], err
    assert not (tmp_path / "m").exists()
