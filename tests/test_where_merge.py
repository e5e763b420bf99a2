"""Selecting samples by their metadata (``SampleStore.indices(where=...)``, ``rvdiag train --where``, ``rvdiag
evaluate --where``) and scoring with merged classes (``rvdiag evaluate --merge``, the crack-free decision)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli

from rvdiag.datasets import SampleStore, parse_where
from rvdiag.datasets.store import write_store
from rvdiag.errors import ParameterError, StoreError


@pytest.fixture()
def store(tmp_path):
    """Four classes, tones at class-dependent frequencies; 'simulation' 0-5 (0-3 train, 4-5 test), an SNR column."""
    rng = np.random.default_rng(0)
    t = np.arange(256) / 256.0
    X, y, sim, snr, split = [], [], [], [], []
    for ci, c in enumerate(("T1", "T2", "T4", "T5")):
        for k in range(6):
            for _ in range(4):
                X.append(np.sin(2 * np.pi * (8 + 10 * ci) * t) + 0.2 * rng.standard_normal(256))
                y.append(c)
                sim.append(k)
                snr.append(10.0 + 3.0 * k)
                split.append("train" if k < 4 else "test")
    p = tmp_path / "s.zarr"
    write_store(p, np.asarray(X, dtype=np.float32), y, kind="library", fs=256.0, config={},
                meta={"split": split, "unit": list(range(len(y))), "simulation": sim, "noise_snr_db": snr,
                      "state": y})
    return p


def test_parse_where():
    assert parse_where("noise_snr_db>=20") == ("noise_snr_db", ">=", 20.0)
    assert parse_where(" simulation < 10 ") == ("simulation", "<", 10.0)
    assert parse_where("state=T4") == ("state", "==", "T4")
    assert parse_where("state!=T4") == ("state", "!=", "T4")
    for bad in ("noise_snr_db", ">=20", "snr>=", "a<=>3"):
        with pytest.raises(ParameterError, match="COLUMN OP VALUE"):
            parse_where(bad)


def test_indices_where(store):
    s = SampleStore.open(store)
    idx = s.indices("train", ["simulation<2"])
    assert idx.size == 4 * 2 * 4 and set(s.meta["simulation"][idx].tolist()) == {0, 1}
    idx = s.indices("all", ["noise_snr_db>=19", "state==T4"])
    assert idx.size == 3 * 4 and set(s.label_names[idx].tolist()) == {"T4"}
    np.testing.assert_array_equal(s.indices("test", []), s.indices("test"))
    with pytest.raises(StoreError, match="no metadata column 'speed'"):
        s.indices("all", ["speed>3"])
    with pytest.raises(StoreError, match="needs a number"):
        s.indices("all", ["state<T4"])


def test_train_and_evaluate_where_and_merge(store, tmp_path, capsys):
    out = tmp_path / "m"
    code, _, err = run_cli(["train", store, "--model", "svm", "--features", "spectrum", "--where", "simulation<2",
                            "--calibration-fraction", "0", "-o", out], capsys)
    assert code == 0, err
    assert "32 training samples" in err  # 4 classes x 2 simulations x 4 windows
    card = json.loads((out / "card.json").read_text())
    assert card["train_where"] == ["simulation<2"] and card["training_store"]["n_train"] == 32
    code, text, err = run_cli(["evaluate", out, store, "--json", "-q", "--where", "noise_snr_db>=25"], capsys)
    assert code == 0, err
    assert json.loads(text)["n_samples"] == 16  # simulation 5 only (25 dB)
    code, text, err = run_cli(["evaluate", out, store, "--json", "-q", "--merge", "T4=T1"], capsys)
    assert code == 0, err
    res = json.loads(text)
    merged = res["merged"]
    assert merged["merge"] == {"T4": "T1"} and merged["labels"] == ["T1", "T2", "T5"]
    cm = np.asarray(res["confusion"])  # rows true, columns predicted, labels T1 T2 T4 T5
    assert merged["confusion"][0][0] == int(cm[np.ix_([0, 2], [0, 2])].sum())
    assert merged["accuracy"] >= res["accuracy"]
    code, _, err = run_cli(["evaluate", out, store, "--merge", "T4=T9"], capsys)
    assert code == 2 and "'T9' is not a class" in err
    code, _, err = run_cli(["evaluate", out, store, "--where", "snr"], capsys)
    assert code == 2 and "COLUMN OP VALUE" in err
    code, _, err = run_cli(["evaluate", out, store, "--where", "noise_snr_db>99"], capsys)
    assert code != 0 and "empty" in err and "noise_snr_db>99" in err
    code, _, err = run_cli(["train", store, "--model", "svm", "--where", "simulation>99", "-o", tmp_path / "x"],
                           capsys)
    assert code == 2 and "no training sample where simulation>99" in err
