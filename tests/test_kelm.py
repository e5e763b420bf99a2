"""KELM: closed form, sklearn API (check_estimator), behaviour on separable data."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from sklearn.base import clone
from sklearn.datasets import make_blobs
from sklearn.model_selection import GridSearchCV
from sklearn.utils.estimator_checks import check_estimator

from rvdiag.errors import ParameterError
from rvdiag.models.kelm import KELMClassifier, rbf_kernel


def test_check_estimator_passes():
    check_estimator(KELMClassifier())
    check_estimator(KELMClassifier(C=100.0, sigma=3.0))


def test_output_weights_are_the_closed_form_of_huang_2012():
    rng = np.random.default_rng(0)
    X = rng.standard_normal((30, 4))
    y = rng.integers(0, 3, 30)
    m = KELMClassifier(C=7.0, sigma=1.7).fit(X, y)
    Omega = np.exp(-((X[:, None, :] - X[None, :, :]) ** 2).sum(-1) / 1.7**2)
    T = -np.ones((30, 3))
    T[np.arange(30), y] = 1
    beta = np.linalg.inv(np.eye(30) / 7.0 + Omega) @ T
    assert_allclose(m.beta_, beta, rtol=1e-8, atol=1e-10)
    Xn = rng.standard_normal((5, 4))
    K = np.exp(-((Xn[:, None, :] - X[None, :, :]) ** 2).sum(-1) / 1.7**2)
    assert_allclose(m.decision_function(Xn), K @ beta, rtol=1e-8, atol=1e-10)
    assert_allclose(rbf_kernel(Xn, X, 1.7), K, rtol=1e-12)


def test_large_C_interpolates_the_training_targets():
    rng = np.random.default_rng(1)
    X = rng.standard_normal((20, 3))
    y = np.arange(20) % 2
    m = KELMClassifier(C=1e8, sigma=1.0).fit(X, y)
    assert (m.predict(X) == y).all()
    assert_allclose(m.decision_function(X), np.where(y == 1, 2.0, -2.0), atol=1e-3)


def test_sigma_scale_and_probabilities():
    X, y = make_blobs(200, centers=3, n_features=5, random_state=0)
    m = KELMClassifier(C=10, sigma="scale").fit(X, y)
    assert_allclose(m.sigma_, np.sqrt(5 * X.var()))
    P = m.predict_proba(X)
    assert_allclose(P.sum(1), 1.0)
    assert (P.argmax(1) == np.searchsorted(m.classes_, m.predict(X))).all()
    assert m.score(X, y) > 0.95


def test_binary_decision_is_one_dimensional_and_labels_are_kept():
    X, y = make_blobs(60, centers=2, random_state=2)
    labels = np.where(y == 1, "broken", "healthy")
    m = KELMClassifier(C=10, sigma=3).fit(X, labels)
    d = m.decision_function(X)
    assert d.shape == (60,)
    assert set(m.predict(X)) <= {"broken", "healthy"}
    assert ((d > 0) == (m.predict(X) == m.classes_[1])).all()


def test_gridsearch_and_clone_work():
    X, y = make_blobs(90, centers=3, random_state=3)
    g = GridSearchCV(KELMClassifier(), {"C": [0.1, 100], "sigma": [0.5, 5.0]}, cv=3).fit(X, y)
    assert g.best_score_ > 0.9
    assert clone(g.best_estimator_).get_params() == g.best_estimator_.get_params()


@pytest.mark.parametrize("kw", [{"C": 0}, {"C": -1.0}, {"sigma": 0.0}, {"sigma": "wide"}, {"C": np.inf}])
def test_bad_parameters_raise_parameter_error(kw):
    X, y = make_blobs(20, centers=2, random_state=0)
    with pytest.raises(ParameterError):
        KELMClassifier(**kw).fit(X, y)
