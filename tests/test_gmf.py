"""The generalised matched filter (rvdiag.features.gmf, docs/monitoring.md "The generalised matched
filter"): on a designed case with a known covariance it beats the white-noise correlator and its standardised
statistic is N(0, 1) / N(d, 1); its split-conformal threshold keeps the false-alarm rate; the Ledoit-Wolf intensity
and the Woodbury weights equal their direct forms; records are put on the nominal angle axis; the simulated reference
(rvdiag.evaluation.separability.gmf_reference) has the shapes and draws it states."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rvdiag.errors import ParameterError
from rvdiag.features.gmf import GeneralisedMatchedFilter, _ledoit_wolf_intensity, gmf_weights, on_angle_axis

N = 256


def _designed(rng, draws=400):
    """A change ``delta`` hidden in a run-to-run spread 10x its norm along 3 directions, one of them oblique to
    ``delta``; white noise of unit variance.  Returns (delta, U (3, N) with Sigma_rr = U^T U, draws (draws, N))."""
    t = np.arange(N)
    delta = 4.0 * np.exp(-0.5 * ((t - 100) / 4.0) ** 2) * np.sin(0.9 * t)       # a short burst: one tooth
    U = np.stack([np.sin(2 * np.pi * 5 * t / N), np.cos(2 * np.pi * 7 * t / N),
                  delta / np.linalg.norm(delta) + np.sin(2 * np.pi * 11 * t / N)])
    U *= 10 * np.linalg.norm(delta) / np.linalg.norm(U, axis=1, keepdims=True)
    H = rng.standard_normal((draws, 3)) @ U
    return delta, U, H


def _records(rng, delta, U, m, fault):
    return rng.standard_normal((m, 3)) @ U + rng.standard_normal((m, N)) + (delta if fault else 0.0)


def test_gmf_weights_equal_the_direct_solve():
    rng = np.random.default_rng(0)
    delta, Z = rng.standard_normal(40), rng.standard_normal((5, 40))
    direct = np.linalg.solve(Z.T @ Z + 0.3 * np.eye(40), delta)
    assert np.allclose(gmf_weights(delta, Z, 0.3), direct, rtol=1e-10, atol=1e-12)
    with pytest.raises(ParameterError, match="noise variance"):
        gmf_weights(delta, Z, 0.0)


def test_ledoit_wolf_intensity_equals_scikit_learn():
    from sklearn.covariance import ledoit_wolf_shrinkage

    rng = np.random.default_rng(1)
    X = rng.standard_normal((12, 300)) * np.linspace(0.1, 3, 300) + rng.standard_normal((12, 1)) * np.ones(300)
    assert _ledoit_wolf_intensity(X - X.mean(axis=0)) == pytest.approx(ledoit_wolf_shrinkage(X), rel=1e-10)


def test_gmf_beats_the_white_noise_correlator_with_a_known_covariance():
    """Sigma_rr learned from 400 draws; the baseline is the mean of 3 healthy records.  The standardised GMF is
    N(0, 1) on healthy records and N(d, 1) on faulty ones with d^2 = delta^T C^-1 delta (Kay vol. 2 eq. 4.16), and
    its AUC exceeds the unwhitened correlator's by far (the spread 10x the change dominates that one)."""
    from sklearn.metrics import roc_auc_score

    rng = np.random.default_rng(2)
    delta, U, H = _designed(rng)
    g = GeneralisedMatchedFilter(delta, H, noise_var=1.0, n_baseline=3, shrinkage=0.0).fit()
    C = (1 + 1 / 3) * (U.T @ U + np.eye(N))
    d_exact = math.sqrt(delta @ np.linalg.solve(C, delta))
    assert g.deflection_ == pytest.approx(d_exact, rel=0.05)           # 400 draws estimate Sigma_rr to a few %
    m = 2000
    base = [_records(rng, delta, U, 3, False) for _ in range(2 * m)]
    yh, yc = _records(rng, delta, U, m, False), _records(rng, delta, U, m, True)
    th = np.array([g.statistic(yh[i:i + 1], base[i])[0] for i in range(m)])
    tc = np.array([g.statistic(yc[i:i + 1], base[m + i])[0] for i in range(m)])
    assert abs(th.mean()) < 0.1 and th.std() == pytest.approx(1.0, abs=0.08)
    assert tc.mean() == pytest.approx(d_exact, abs=0.15) and tc.std() == pytest.approx(1.0, abs=0.08)
    ch = np.array([(yh[i] - base[i].mean(0)) @ delta for i in range(m)])
    cc = np.array([(yc[i] - base[m + i].mean(0)) @ delta for i in range(m)])
    y = np.r_[np.zeros(m), np.ones(m)]
    auc_gmf, auc_white = roc_auc_score(y, np.r_[th, tc]), roc_auc_score(y, np.r_[ch, cc])
    assert d_exact > 3.0 and auc_gmf > 0.98 and auc_white < 0.75, (d_exact, auc_gmf, auc_white)


def test_few_draws_with_shrinkage_stay_calibrated_and_whitened():
    """With 8 draws (rank 7) the Ledoit-Wolf shrinkage is estimated in (0, 1] and the detector still beats the
    white-noise correlator."""
    from sklearn.metrics import roc_auc_score

    rng = np.random.default_rng(4)
    delta, U, H = _designed(rng, draws=8)
    g = GeneralisedMatchedFilter(delta, H, noise_var=1.0).fit()
    assert 0.0 < g.shrinkage_ <= 1.0
    m = 500
    base = [_records(rng, delta, U, 3, False).mean(0) for _ in range(2 * m)]
    yh, yc = _records(rng, delta, U, m, False), _records(rng, delta, U, m, True)
    th = np.array([g.statistic(yh[i], base[i])[0] for i in range(m)])
    tc = np.array([g.statistic(yc[i], base[m + i])[0] for i in range(m)])
    ch = np.array([(yh[i] - base[i]) @ delta for i in range(m)])
    cc = np.array([(yc[i] - base[m + i]) @ delta for i in range(m)])
    y = np.r_[np.zeros(m), np.ones(m)]
    auc_gmf, auc_white = roc_auc_score(y, np.r_[th, tc]), roc_auc_score(y, np.r_[ch, cc])
    assert auc_gmf > 0.95 and auc_white < 0.75, (auc_gmf, auc_white)


def test_conformal_threshold_keeps_the_false_alarm_rate():
    rng = np.random.default_rng(5)
    for alpha in (0.01, 0.05):
        fa = []
        for _ in range(200):
            thr = GeneralisedMatchedFilter.calibrate(rng.standard_normal(199), alpha)
            fa.append(np.mean(rng.standard_normal(2000) > thr))
        assert np.mean(fa) == pytest.approx(alpha, abs=0.25 * alpha)       # exchangeable: E[FA] <= alpha, ~alpha
    assert GeneralisedMatchedFilter.calibrate(np.zeros(50), 0.01) == math.inf  # too few for 1 %


def test_on_angle_axis_undoes_a_speed_change():
    fs, f0 = 48000.0, 37.0
    for ratio in (0.99, 1.0, 1.01):
        t = np.arange(4800) / fs
        x = np.sin(2 * np.pi * f0 * ratio * t)              # the same angle progression, ratio times faster
        y = on_angle_axis(x, ratio, 4700)
        assert np.allclose(y, np.sin(2 * np.pi * f0 * np.arange(4700) / fs), atol=1e-6)
    with pytest.raises(ParameterError, match="reach past"):
        on_angle_axis(np.zeros(100), 0.9, 100)


def test_bad_filter_input_is_refused():
    with pytest.raises(ParameterError, match="2 draws"):
        GeneralisedMatchedFilter(np.ones(5), np.ones((1, 5))).fit()
    with pytest.raises(ParameterError, match="shrinkage"):
        GeneralisedMatchedFilter(np.ones(5), np.eye(5), shrinkage="oas").fit()
    g = GeneralisedMatchedFilter(np.ones(5), np.eye(5)).fit()
    with pytest.raises(ParameterError, match="points"):
        g.statistic(np.ones((2, 4)), np.ones(4))


def test_gmf_reference_simulates_the_template_and_aligned_draws():
    from rvdiag.evaluation.separability import RUN_TO_RUN_DEFAULT, gmf_reference

    ref = gmf_reference("T4", ranges=RUN_TO_RUN_DEFAULT, draws=2, output_speed_deg_s=60.0, load_Nm=75.0,
                        duration_s=0.1, fs=48000.0, transient_s=0.05, model={"substeps": 2},
                        severities={"crack_depth": 1.8e-3}, seed=3)
    n = ref["healthy"].size
    assert ref["template"].shape == (n,) and ref["draws"].shape == (2, n) and n == int((4800 - 3) * 0.99)
    assert np.all(np.isfinite(ref["draws"])) and np.linalg.norm(ref["template"]) > 0
    for f in ref["factors"]:
        assert all(abs(f[k] - 1) <= RUN_TO_RUN_DEFAULT[k] for k in RUN_TO_RUN_DEFAULT)
    # each draw lies near the nominal healthy record on the angle axis (a few % of run-to-run change)
    rel = np.linalg.norm(ref["draws"] - ref["healthy"], axis=1) / np.linalg.norm(ref["healthy"])
    assert np.all(rel < 0.5), rel
