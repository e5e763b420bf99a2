"""Progress reports of the long library loops (rvdiag.progress): what the command line draws as bars with an ETA."""

from __future__ import annotations

import numpy as np

from rvdiag.progress import report, reporting


def _collect():
    seen = []
    return seen, lambda stage, done, total: seen.append((stage, done, total))


def test_nobody_listening_is_a_no_op_and_listeners_nest():
    report("x", 1, 2)  # no listener: nothing happens, nothing fails
    outer, inner = _collect(), _collect()
    with reporting(outer[1]):
        report("a", 1, 1)
        with reporting(inner[1]):
            report("b", 1, 1)
        report("c", 1, 1)
    assert outer[0] == [("a", 1, 1), ("c", 1, 1)] and inner[0] == [("b", 1, 1)]


def test_eemd_features_report_every_window_in_order_with_threads_too():
    from rvdiag.features.eemd import EEMDFeatures

    X = np.random.default_rng(0).standard_normal((5, 64))
    for n_jobs in (1, 2):
        seen, listener = _collect()
        with reporting(listener):
            F = EEMDFeatures(ensemble_size=4, n_imfs=2, n_jobs=n_jobs).fit_transform(X)
        assert F.shape == (5, 2)
        assert seen == [("EEMD features", k, 5) for k in range(1, 6)]


def test_kelm_tuning_reports_each_evaluation_against_the_mealpy_budget():
    from rvdiag.models.tuning import TunedKELM

    rng = np.random.default_rng(1)
    X = np.vstack([rng.normal(0, 1, (12, 3)), rng.normal(3, 1, (12, 3))])
    y = np.array([0] * 12 + [1] * 12)
    seen, listener = _collect()
    with reporting(listener):
        m = TunedKELM(optimizer="pso", epoch=2, pop_size=10, cv=2).fit(X, y)
    assert {s for s, _, _ in seen} == {"PSO tuning"}
    assert [d for _, d, _ in seen] == list(range(1, m.n_evaluations_ + 1))
    assert seen[-1][1:] == (30, 30) == (m.n_evaluations_, 10 * (2 + 1))


def test_accuracy_against_snr_reports_scoring_and_levels():
    from types import SimpleNamespace

    from rvdiag.evaluation.evaluate import Evaluation, accuracy_against_snr

    class Constant:
        def predict(self, X):
            return np.array(["a"] * len(X))

    X = np.random.default_rng(2).standard_normal((700, 16)).astype(np.float32)
    ev = Evaluation({}, np.array(["a"] * 700), np.array(["a"] * 700), X, {}, "test")
    seen, listener = _collect()
    with reporting(listener):
        loaded = SimpleNamespace(estimator=Constant(), card={"classes": ["a", "b"]},
                                 inputs=lambda X, meta=None, where="": X)  # a model that reads no metadata
        curve = accuracy_against_snr(loaded, ev, [0.0, 10.0])
    assert [r["accuracy"] for r in curve] == [1.0, 1.0]
    scoring = [("scoring", 512, 700), ("scoring", 700, 700)]
    assert seen == scoring + [("SNR levels", 1, 2)] + scoring + [("SNR levels", 2, 2)]
