"""Classical pipelines: every model x feature combination fits, and the safe save/load round trip."""

import json
import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose
from sklearn.pipeline import Pipeline

from rvdiag.errors import ModelFileError, ParameterError
from rvdiag.models.pipelines import (
    MODEL_NAMES,
    TRUSTED_TYPES,
    load_classical,
    make_classical_model,
    save_classical,
)

FEATURES = ("time", "spectrum", "wpd", "eemd", "none")
FAST = {"eemd": {"ensemble_size": 4}}
TUNE = {"epoch": 2, "pop_size": 10, "cv": 3}


def toy(n_per=24, n=256, seed=0):
    """Three classes: noise, noise + tone, louder impulsive noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    X = rng.standard_normal((3 * n_per, n))
    y = np.repeat(np.array(["healthy", "tone", "impulse"]), n_per)
    X[y == "tone"] += 1.5 * np.sin(2 * np.pi * 0.11 * t + rng.uniform(0, 6, (n_per, 1)))
    X[y == "impulse", ::32] += 8.0
    return X, y


@pytest.fixture(scope="module")
def split():
    X, y = toy()
    Xt, yt = toy(n_per=10, seed=1)
    return X, y, Xt, yt


@pytest.mark.parametrize("features", FEATURES)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_every_pipeline_fits_and_predicts(model, features, split):
    X, y, Xt, yt = split
    p = make_classical_model(model, features, features_kw=FAST.get(features),
                             model_kw=TUNE if "-" in model else None, seed=0)
    assert isinstance(p, Pipeline) and [s for s, _ in p.steps] == ["features", "scale", "clf"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", FutureWarning)  # no deprecated sklearn API on the way
        p.fit(X, y)
    P = p.predict_proba(Xt)
    assert P.shape == (30, 3)
    assert_allclose(P.sum(1), 1.0, atol=1e-9)
    assert set(p.predict(Xt)) <= set(y)
    if features != "none":  # hand-built features separate these classes easily
        assert p.score(Xt, yt) >= 0.8, (model, features)


def test_svm_grid_option(split):
    X, y, Xt, yt = split
    p = make_classical_model("svm", "spectrum", grid=True).fit(X, y)
    assert p.named_steps["clf"].calibrated_classifiers_[0].estimator.best_params_["C"] in (1.0, 10.0, 100.0, 1000.0)
    assert p.score(Xt, yt) > 0.9


def test_unknown_names_and_options():
    with pytest.raises(ParameterError, match="unknown model"):
        make_classical_model("rf", "time")
    with pytest.raises(ParameterError, match="unknown feature set"):
        make_classical_model("svm", "mfcc")
    with pytest.raises(ParameterError, match="bad options"):
        make_classical_model("kelm", "time", model_kw={"gamma": 1})


@pytest.mark.parametrize("model", ["svm", "kelm-pso"])
def test_save_load_round_trip(tmp_path, split, model):
    X, y, Xt, _ = split
    p = make_classical_model(model, "wpd", model_kw=TUNE if "-" in model else None).fit(X, y)
    save_classical(p, tmp_path / "m", metadata={"labels": sorted(set(y)), "window": 256})
    q = load_classical(tmp_path / "m")
    assert_allclose(q.predict_proba(Xt), p.predict_proba(Xt))
    card = json.loads((tmp_path / "m" / "card.json").read_text())
    assert card["window"] == 256 and card["estimator"] == "sklearn.pipeline.Pipeline"
    assert (card["format"], card["version"], card["kind"]) == ("rvdiag-model", 1, "classical")
    assert card["classes"] == sorted(set(y)) and card["input_length"] == 256
    assert not [f for f in (tmp_path / "m").iterdir() if f.name.startswith(".")]  # no temp files left


def test_load_refuses_bad_files(tmp_path, split):
    X, y, _, _ = split
    with pytest.raises(ModelFileError, match="no model at"):
        load_classical(tmp_path / "nothing")
    d = tmp_path / "m"
    save_classical(make_classical_model("kelm", "time").fit(X, y), d)
    (d / "model.skops").write_bytes(b"not a zip file")
    with pytest.raises(ModelFileError, match="skops"):
        load_classical(d)
    (d / "card.json").write_text("{]")
    with pytest.raises(ModelFileError):
        load_classical(d)
    (d / "card.json").write_text(json.dumps({"format": "something-else"}))
    with pytest.raises(ModelFileError, match="not an rvdiag"):
        load_classical(d)


class Sneaky:  # a type that is not on the trusted list
    def __init__(self):
        self.payload = "x"


def test_load_refuses_untrusted_types(tmp_path, split):
    import skops.io as sio

    X, y, _, _ = split
    d = tmp_path / "m"
    p = make_classical_model("kelm", "time").fit(X, y)
    save_classical(p, d)
    p.sneaky_ = Sneaky()
    (d / "model.skops").write_bytes(sio.dumps(p))
    with pytest.raises(ModelFileError, match="untrusted"):
        load_classical(d)
    assert not any("Sneaky" in t for t in TRUSTED_TYPES)
