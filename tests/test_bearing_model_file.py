"""A classical model that uses the bearing envelope features saves and loads without unpickling."""

import numpy as np
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC

from rvdiag.features.bearing import BearingEnvelopeFeatures
from rvdiag.models.pipelines import load_classical, save_classical


def test_bearing_pipeline_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    X = rng.normal(size=(12, 1024))
    y = np.array(["a", "b"] * 6)
    model = make_pipeline(BearingEnvelopeFeatures(shaft_frequency=29.95, fs=12000.0), StandardScaler(), SVC())
    model.fit(X, y)
    save_classical(model, tmp_path / "m", {})
    loaded = load_classical(tmp_path / "m")
    np.testing.assert_array_equal(loaded.predict(X), model.predict(X))
