"""Model directories: safetensors + card.json for CNNs, skops for classical models; clear errors."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from rvdiag import __version__
from rvdiag.errors import ModelFileError
from rvdiag.models.persistence import load_model, read_card, save_model
from rvdiag.models.torch_estimator import CNNClassifier


def _data(n=16, L=128, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((2 * n, L)).astype(np.float32)
    X[n:, ::8] += 3.0
    y = np.array(["A"] * n + ["B"] * n)
    return X, y


@pytest.fixture(scope="module")
def cnn_dir(tmp_path_factory):
    X, y = _data()
    m = CNNClassifier(max_epochs=2, device="cpu", random_state=4, input_length=100, long_input="window").fit(X, y)
    d = tmp_path_factory.mktemp("m") / "model"
    save_model(m, d, model="cnn1d-lean", fs=1000.0, seed=4,
               training_store={"path": "/x/lib.zarr", "config_hash": "abc123"},
               metrics={"accuracy": 0.5})
    return d, m, X


def test_cnn_round_trip_gives_identical_predictions(cnn_dir):
    d, m, X = cnn_dir
    assert sorted(p.name for p in d.iterdir()) == ["card.json", "model.safetensors"]
    loaded = load_model(d)
    np.testing.assert_allclose(loaded.estimator.predict_proba(X), m.predict_proba(X), rtol=1e-6)
    assert loaded.estimator.window_starts_.tolist() == [0, 28]
    np.testing.assert_array_equal(loaded.estimator.predict(X), m.predict(X))


def test_card_records_what_the_issue_asks(cnn_dir):
    d, m, _ = cnn_dir
    card = read_card(d)
    assert card["classes"] == ["A", "B"]
    assert card["input_length"] == 128 and card["fs"] == 1000.0
    assert card["preprocessing"]["normalize"] == "window"
    assert card["preprocessing"]["net_input_length"] == 100
    assert card["training_store"] == {"path": "/x/lib.zarr", "config_hash": "abc123"}
    assert card["metrics"] == {"accuracy": 0.5}
    assert card["rvdiag_version"] == __version__ and card["seed"] == 4
    assert card["kind"] == "cnn" and card["model"] == "cnn1d-lean"
    assert len(card["history"]) == m.n_epochs_


def _copy(cnn_dir, tmp_path):
    d = tmp_path / "copy"
    shutil.copytree(cnn_dir[0], d)
    return d


def test_missing_or_foreign_directory(tmp_path):
    with pytest.raises(ModelFileError, match="no model"):
        load_model(tmp_path / "nothing")
    with pytest.raises(ModelFileError, match="no card.json"):
        load_model(tmp_path)
    f = tmp_path / "file.npy"
    f.write_bytes(b"123")
    with pytest.raises(ModelFileError, match="not a model directory"):
        load_model(f)


@pytest.mark.parametrize("mutate, match", [
    (lambda c: "{not json", "unreadable"),
    (lambda c: json.dumps({**c, "format": "something-else"}), "not an rvdiag model card"),
    (lambda c: json.dumps({**c, "version": 99}), "version"),
    (lambda c: json.dumps({k: v for k, v in c.items() if k != "classes"}), "classes"),
    (lambda c: json.dumps({**c, "classes": ["A", "B", "C"]}), "shape"),  # output layer has 2 units
    (lambda c: json.dumps({**c, "params": {**c["params"], "architecture": "spectrum-cnn"}}), "weights do not match"),
    (lambda c: json.dumps({**c, "kind": "forest"}), "unknown model kind"),
])
def test_card_that_does_not_match_is_refused(cnn_dir, tmp_path, mutate, match):
    d = _copy(cnn_dir, tmp_path)
    card = json.loads((d / "card.json").read_text())
    (d / "card.json").write_text(mutate(card))
    with pytest.raises(ModelFileError, match=match):
        load_model(d)


def test_corrupt_or_missing_weights(cnn_dir, tmp_path):
    d = _copy(cnn_dir, tmp_path)
    (d / "model.safetensors").write_bytes(b"\x00garbage")
    with pytest.raises(ModelFileError, match="safetensors"):
        load_model(d)
    (d / "model.safetensors").unlink()
    with pytest.raises(ModelFileError, match="no model.safetensors"):
        load_model(d)


def test_classical_model_round_trip(tmp_path):
    from rvdiag.models.pipelines import make_classical_model

    X, y = _data(L=256)
    m = make_classical_model("svm", "time", seed=0).fit(X.astype(np.float64), y)
    d = save_model(m, tmp_path / "svm", model="svm", features="time", fs=None, seed=0, metrics={"accuracy": 1.0})
    loaded = load_model(d)
    assert loaded.card["kind"] == "classical" and loaded.card["features"] == "time"
    assert loaded.card["classes"] == ["A", "B"] and loaded.input_length == 256
    np.testing.assert_allclose(loaded.estimator.predict_proba(X), m.predict_proba(X))


def test_cnn_features_svm_round_trip(tmp_path):
    """The 'cnn' feature set (motor-current CNN + SVM) saves through skops without torch objects."""
    from rvdiag.models.pipelines import make_classical_model

    X, y = _data(L=256)
    m = make_classical_model("svm", "cnn", seed=0, features_kw={"max_epochs": 2, "device": "cpu"}).fit(X, y)
    assert m[0].transform(X).shape == (len(X), 32)
    d = save_model(m, tmp_path / "cnnsvm", model="svm", features="cnn", seed=0)
    loaded = load_model(d)
    np.testing.assert_allclose(loaded.estimator.predict_proba(X), m.predict_proba(X), rtol=1e-5, atol=1e-7)


def test_model_trained_for_cuda_predicts_on_cpu(cnn_dir, tmp_path):
    d = _copy(cnn_dir, tmp_path)
    card = json.loads((d / "card.json").read_text())
    card["params"]["device"] = "cuda"
    (d / "card.json").write_text(json.dumps(card))
    loaded = load_model(d)
    np.testing.assert_allclose(loaded.estimator.predict_proba(cnn_dir[2][:3]),
                               cnn_dir[1].predict_proba(cnn_dir[2][:3]), rtol=1e-4, atol=1e-6)


_SAVE = """
import sys
import numpy as np
from rvdiag.models.persistence import save_model
from rvdiag.models.pipelines import make_classical_model
from rvdiag.models.torch_estimator import CNNClassifier
model, features, out = sys.argv[1:4]
rng = np.random.default_rng(0)
X = rng.standard_normal((32, 256)); X[16:, ::8] += 3.0
y = np.array(["A"] * 16 + ["B"] * 16)
if features == "-":
    est = CNNClassifier(max_epochs=1, device="cpu", random_state=0).fit(X, y)
    save_model(est, out, model=model, seed=0)
else:
    kw = {"max_epochs": 1, "device": "cpu"} if features == "cnn" else {}
    est = make_classical_model(model, features, features_kw=kw).fit(X, y)
    save_model(est, out, model=model, features=features, seed=0)
np.save(out + "/expected.npy", est.predict_proba(X))
np.save(out + "/X.npy", X)
"""

_LOAD = """
import os, sys
import numpy as np
out = sys.argv[1]
if os.path.exists(out + "/model.skops"):  # a classical model: the low-level loader first, nothing else imported
    from rvdiag.models.pipelines import load_classical
    load_classical(out)
from rvdiag.models.persistence import load_model
m = load_model(out)
np.testing.assert_allclose(m.estimator.predict_proba(np.load(out + "/X.npy")), np.load(out + "/expected.npy"),
                           rtol=1e-5, atol=1e-7)
print(m.card["kind"], m.card["model"], m.card["features"])
"""


@pytest.mark.parametrize("model,features", [("svm", "cnn"), ("kelm", "time"), ("cnn1d-lean", "-")])
def test_a_fresh_interpreter_loads_what_another_saved(tmp_path, model, features):
    """Save in one process, load in another: nothing the loader needs may depend on what was imported before
    (an svm + cnn model was refused as 'untrusted' by a fresh interpreter)."""
    import subprocess
    import sys

    out = str(tmp_path / "m")
    for code, args in ((_SAVE, [model, features, out]), (_LOAD, [out])):
        r = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.split() == [("cnn" if features == "-" else "classical"), model,
                                ("None" if features == "-" else features)]


def test_one_card_format_and_one_reader(cnn_dir, tmp_path):
    """CNN and classical cards share the format, the version and the top-level fields; one function reads both."""
    import rvdiag.models.card as card_mod
    import rvdiag.models.persistence as persistence
    import rvdiag.models.pipelines as pipelines
    from rvdiag.models.pipelines import make_classical_model

    assert persistence.read_card is card_mod.read_card and pipelines.read_card is card_mod.read_card
    X, y = _data(L=64)
    d = save_model(make_classical_model("kelm", "time").fit(X, y), tmp_path / "k", model="kelm", features="time",
                   seed=3)
    cards = [json.loads((p / "card.json").read_text()) for p in (cnn_dir[0], d)]
    common = {"format", "version", "kind", "model", "features", "classes", "input_length", "fs", "preprocessing",
              "training_store", "metrics", "seed", "rvdiag_version", "created"}
    for c, kind in zip(cards, ("cnn", "classical")):
        assert (c["format"], c["version"], c["kind"]) == ("rvdiag-model", 1, kind)
        assert common <= set(c) and "metadata" not in c
    assert cards[1]["classes"] == ["A", "B"] and cards[1]["input_length"] == 64 and cards[1]["seed"] == 3
    assert cards[1]["estimator"] == "sklearn.pipeline.Pipeline" and "skops_version" in cards[1]


def test_former_classical_card_format_is_refused_with_a_remedy(tmp_path):
    d = tmp_path / "old"
    d.mkdir()
    (d / "card.json").write_text(json.dumps({"format": "rvdiag-classical-model", "version": 1,
                                             "metadata": {"kind": "classical", "classes": ["A", "B"]}}))
    with pytest.raises(ModelFileError, match="retrain"):
        load_model(d)


def test_each_loader_refuses_the_other_kind(cnn_dir):
    from rvdiag.models.pipelines import load_classical

    with pytest.raises(ModelFileError, match="not a classical model"):
        load_classical(cnn_dir[0])
