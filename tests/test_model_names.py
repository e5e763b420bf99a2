"""The default network's name: ``spectrum-cnn``, once ``mcsa-cnn`` (which read as motor-current
analysis).  The old name still trains, with one ``warning:`` line, and model directories saved under it load."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rvdiag.datasets import SampleStore, write_store
from rvdiag.models.cnn import SpectrumCNN, build_network
from rvdiag.models.persistence import load_model, read_card
from rvdiag.registry import CNN_MODELS, OLD_MODEL_NAMES, RECOMMENDED_TRAINING
from conftest import run_cli as run

L = 256


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    rng = np.random.default_rng(0)
    t = np.arange(L) / 1000.0
    X = [np.sin(2 * np.pi * (50 + 150 * c) * t + rng.uniform(0, 6)) + 0.2 * rng.standard_normal(L)
         for c in range(2) for _ in range(10)]
    y = [f"T{c + 1}" for c in range(2) for _ in range(10)]
    p = tmp_path_factory.mktemp("s") / "s.zarr"
    write_store(p, np.asarray(X, np.float32), y, meta={"split": (["test"] * 3 + ["train"] * 7) * 2,
                                                       "unit": list(range(20))},
                kind="simulated", fs=1000.0, config={"name": "names"})
    return p


def test_the_default_network_is_spectrum_cnn():
    assert RECOMMENDED_TRAINING["model"] == "spectrum-cnn" and "spectrum-cnn" in CNN_MODELS
    assert "mcsa-cnn" not in CNN_MODELS and OLD_MODEL_NAMES == {"mcsa-cnn": "spectrum-cnn"}
    assert isinstance(build_network("mcsa-cnn", 3, 256), SpectrumCNN)


def test_the_old_name_trains_with_one_warning_line_and_its_saved_models_load(store, tmp_path, capsys):
    out = tmp_path / "m"
    code, _, err = run(["train", store, "--model", "mcsa-cnn", "-o", out, "-q", "--input-length", "128",
                        "--epochs", "1", "--device", "cpu"], capsys)
    assert code == 0, err
    said = [ln for ln in err.splitlines() if ln.startswith("warning:")]
    assert said == ["warning: --model mcsa-cnn is the old name of spectrum-cnn; use --model spectrum-cnn"], err
    card = read_card(out)
    assert card["model"] == "spectrum-cnn" and card["params"]["architecture"] == "spectrum-cnn"

    X = SampleStore.open(store).load("test").X
    before = load_model(out).estimator.predict_proba(X)
    # a directory saved before the rename says mcsa-cnn
    path = out / "card.json"
    old = json.loads(path.read_text())
    old["model"] = "mcsa-cnn"
    old["params"]["architecture"] = "mcsa-cnn"
    path.write_text(json.dumps(old))
    loaded = load_model(out)
    np.testing.assert_array_equal(loaded.estimator.predict_proba(X), before)
