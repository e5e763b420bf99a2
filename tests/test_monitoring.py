"""Monitoring a reducer against its own baseline (docs/monitoring.md): baseline-referenced features, the calibrated alarm,
matching with the baseline, the saved monitor."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rvdiag.monitoring.pairing import is_paired, match_baseline
from rvdiag.errors import ParameterError
from rvdiag.features.orders import shaft_frequency
from rvdiag.features.relative import BaselineReferencedFeatures, relative_features, tsa_change_features
from rvdiag.features.timedomain import TimeDomainFeatures
from rvdiag.monitoring.detector import BaselineMonitor, conformal_threshold, save_monitor

FS = 4000.0


def _paired(n_reducers=40, n_base=4, n_healthy=6, n_fault=6, step=0.10, seed=0):
    """A synthetic paired set: each reducer's level a_r is log-uniform over a factor 2 (the population spread),
    each record's gain varies +-1 % (its run-to-run variation), and the fault raises the level by ``step``: inside
    the population's spread, far outside the reducer's own."""
    rng = np.random.default_rng(seed)
    t = np.arange(800) / FS
    rows, base, groups, y, red = [], [], [], [], []
    for r in range(n_reducers):
        a = 2.0 ** rng.uniform(0, 1)
        f = rng.uniform(90, 110)

        def rec(level):
            g = level * (1 + 0.01 * rng.uniform(-1, 1))
            return g * np.sin(2 * np.pi * f * t) + 0.05 * a * rng.standard_normal(t.size)

        b0 = len(base)
        base += [rec(a) for _ in range(n_base)]
        for state, n, level in (("T1", n_healthy, a), ("T2", n_fault, a * (1 + step))):
            for _ in range(n):
                rows.append(rec(level))
                groups.append(np.arange(b0, b0 + n_base))
                y.append(state)
                red.append(r)
    return np.array(rows), np.array(base), groups, np.array(y), np.array(red)


def test_relative_features_find_a_change_inside_the_population_spread():
    X, B, groups, y, red = _paired()
    fx = BaselineReferencedFeatures(TimeDomainFeatures(), tsa_change=False).fit(X)
    D = fx.transform(X, B, groups)
    A = TimeDomainFeatures().fit(X).transform(X)  # absolute: the same features, not referenced
    train, test = red < 20, red >= 20
    rel = BaselineMonitor(alpha=0.05).fit(D[train], y[train], groups=red[train])
    ab = BaselineMonitor(alpha=0.05).fit(A[train], y[train], groups=red[train])
    det_rel = rel.alarm(D[test & (y == "T2")]).mean()
    det_abs = ab.alarm(A[test & (y == "T2")]).mean()
    assert det_rel >= 0.95, det_rel
    assert det_abs <= 0.30, det_abs
    assert rel.alarm(D[test & (y == "T1")]).mean() <= 0.15


def test_relative_features_subtract_the_baseline_mean():
    F = np.array([[1.0, 5.0]])
    B = np.array([[0.0, 4.0], [2.0, 2.0]])
    np.testing.assert_allclose(relative_features(F, B), [[0.0, 2.0]])
    with pytest.raises(ParameterError):
        relative_features(F, np.ones((2, 3)))


def test_conformal_threshold_is_the_stated_order_statistic():
    s = np.arange(1.0, 100.0)  # n = 99, alpha = 0.01: ceil(100 * 0.99) = 99th smallest
    assert conformal_threshold(s, 0.01) == 99.0
    assert conformal_threshold(s, 0.10) == 90.0
    assert math.isinf(conformal_threshold(np.arange(10.0), 0.01))  # too few records for 1 %


def test_alarm_rate_on_held_out_healthy_pairs_is_alpha():
    """Heavy-tailed healthy rows (Student t, 3 dof): a chi-square threshold would not hold the rate, the
    conformal one does, within a binomial tolerance (4 sigma of calibration and test together)."""
    rng = np.random.default_rng(1)
    k, alpha = 5, 0.01  # the default rate
    D = rng.standard_t(3, size=(10000, k))
    y = np.array(["T1"] * 10000)
    groups = np.repeat(np.arange(1000), 10)
    m = BaselineMonitor(alpha=alpha).fit(D, y, groups=groups)
    held = rng.standard_t(3, size=(20000, k))
    rate = m.alarm(held).mean()
    tol = 4 * math.sqrt(alpha * (1 - alpha) * (1 / held.shape[0] + 1 / m.n_calibration_))
    assert abs(rate - alpha) <= tol, (rate, tol)
    from scipy.stats import chi2

    naive = (m._distance(held) > chi2.ppf(1 - alpha, k)).mean()
    assert abs(naive - alpha) > tol  # the Gaussian threshold misses the stated rate on these tails
    p = m.p_value(held)
    assert np.all((p > 0) & (p <= 1)) and abs((p <= alpha).mean() - rate) < 0.01


def _windows_of_records(rng, n_records: int, k: int, windows: int, noise: float):
    """Window rows of ``n_records`` healthy records: the record's own change (its run-to-run variation, N(0, I))
    shared by its ``windows`` windows, plus each window's own noise (N(0, noise^2 I))."""
    rec = rng.standard_normal((n_records, k))
    W = np.repeat(rec, windows, axis=0) + noise * rng.standard_normal((n_records * windows, k))
    return W, np.repeat(np.arange(n_records), windows)


def test_per_record_calibration_keeps_the_stated_rate_per_record():
    """A designed case: records of 4 windows that share their record's change, and a window noise twice its
    spread.  A record is decided on its windows' mean change (as ``diagnose`` decides a file).  Calibrated on record
    means (``rvdiag train``), the alarm keeps its stated rate on new records, within the binomial interval;
    calibrated on windows, the same records raise it about 70 times less often than stated."""
    from rvdiag.monitoring.pairing import record_means
    from rvdiag.evaluation.metrics import binomial_interval

    rng = np.random.default_rng(3)
    k, windows, alpha = 3, 4, 0.10
    W, unit = _windows_of_records(rng, 2000, k, windows, noise=2.0)
    groups_w = unit // 10  # 10 records per reducer, 200 reducers
    D, first, counts = record_means(W, {"unit": unit})
    assert D.shape == (2000, k) and np.all(counts == windows) and np.array_equal(first, np.arange(0, 8000, 4))
    y = np.array(["T1"] * D.shape[0])
    per_record = BaselineMonitor(alpha=alpha).fit(D, y, groups=groups_w[first])
    per_window = BaselineMonitor(alpha=alpha).fit(W, np.array(["T1"] * W.shape[0]), groups=groups_w)
    assert per_record.n_calibration_ == 2000 and per_window.n_calibration_ == 8000  # CV+: every healthy record
    Wn, un = _windows_of_records(rng, 4000, k, windows, noise=2.0)
    new, _, _ = record_means(Wn, {"unit": un})
    hits = int(per_record.alarm(new).sum())
    lo, hi = binomial_interval(hits, new.shape[0], 0.999)
    spread = 4 * math.sqrt(alpha * (1 - alpha) / per_record.n_calibration_)  # the threshold's own draw
    assert lo - spread <= alpha <= hi + spread, (hits, lo, hi)
    assert per_window.alarm(new).mean() < alpha / 10  # the window threshold on a record's mean: far too few


def test_record_means_keep_the_order_records_first_appear():
    from rvdiag.monitoring.pairing import record_means

    D = np.arange(10.0).reshape(5, 2)
    m, first, n = record_means(D, {"unit": np.array([9, 4, 9, 4, 1])})
    assert m.tolist() == [[2.0, 3.0], [4.0, 5.0], [8.0, 9.0]] and first.tolist() == [0, 1, 4]
    assert n.tolist() == [2, 2, 1]
    m, first, n = record_means(D, {})  # no record column: every window its own record
    assert np.array_equal(m, D) and n.tolist() == [1] * 5


def _grouped(rng, n_groups: int, per_group: int, k: int = 3, shift: float = 1.0):
    """Healthy rows of ``n_groups`` reducers: each reducer's own offset (N(0, shift^2 I), the population spread)
    plus each record's run-to-run variation (N(0, I)); the reducers are exchangeable, their records are not."""
    off = shift * rng.standard_normal((n_groups, k))
    g = np.repeat(np.arange(n_groups), per_group)
    return off[g] + rng.standard_normal((g.size, k)), g


def test_cross_fitted_calibration_scores_every_group_by_a_detector_that_never_saw_it():
    """CV+ (the default): every healthy row of every group calibrates, each scored by the detector of the folds that
    do not hold its group; the split calibrates on half the groups."""
    from sklearn.covariance import LedoitWolf

    rng = np.random.default_rng(4)
    D, g = _grouped(rng, 13, 8)
    y = np.array(["T1"] * D.shape[0])
    cv = BaselineMonitor(alpha=0.05).fit(D, y, groups=g)
    split = BaselineMonitor(alpha=0.05, calibration="split").fit(D, y, groups=g)
    assert cv.calibration == "cv+" and cv.n_calibration_ == 104 and cv.n_calibration_groups_ == 13
    assert split.n_calibration_ in (48, 56) and split.n_calibration_groups_ in (6, 7)
    fold = cv.calibration_fold_
    assert len(cv.fold_detectors_) == 5 and sorted(np.bincount(fold).tolist()) == [16, 16, 24, 24, 24]
    for r in range(13):  # a group lies in one fold
        assert np.unique(fold[g == r]).size == 1
    j = int(fold[0])  # fold j's scores come from a detector fitted on the other folds' rows only
    F = D[fold != j]
    mu, sd = F.mean(axis=0), F.std(axis=0, ddof=1)
    ref = LedoitWolf().fit((F - mu) / sd).mahalanobis((D[fold == j] - mu) / sd)
    np.testing.assert_allclose(cv.calibration_scores_[fold == j], ref, rtol=1e-10)
    # leave-one-group-out with fewer groups than folds
    few = BaselineMonitor(alpha=0.2, calibration_folds=5).fit(D[g < 4], y[g < 4], groups=g[g < 4])
    assert len(few.fold_detectors_) == 4 and few.n_calibration_ == 32
    # the alarm, the p-value and the health index agree: index > 1 exactly when p <= alpha
    new = rng.standard_normal((3000, 3)) * 2.0
    p, idx = cv.p_value(new), cv.health_index(new)
    assert np.array_equal(idx > 1.0, p <= 0.05 + 1e-12) and 0.02 < (idx > 1).mean() < 0.9
    assert np.array_equal(cv.alarm(new), idx > 1.0) and np.array_equal(cv.decision_function(new) < 0, idx > 1.0)


@pytest.mark.parametrize("calibration", ["cv+", "split"])
def test_false_alarm_rate_on_new_exchangeable_records_is_alpha_over_many_seeds(calibration):
    """Exchangeable records (one per group, Student t tails): over 200 seeds the mean false-alarm rate on new records
    lies within 4 standard errors of alpha (CV+ guarantees <= 2 alpha + sqrt(2/n) in the worst case; it is near
    alpha for a stable fit), and no seed's rate exceeds that bound by more than 4 binomial sigma."""
    alpha, n, k = 0.10, 60, 3
    rates = []
    for seed in range(200):
        rng = np.random.default_rng(1000 + seed)
        D = rng.standard_t(4, size=(n, k))
        m = BaselineMonitor(alpha=alpha, calibration=calibration, random_state=seed).fit(
            D, np.array(["T1"] * n), groups=np.arange(n))
        rates.append(m.alarm(rng.standard_t(4, size=(2000, k))).mean())
    rates = np.array(rates)
    se = rates.std(ddof=1) / math.sqrt(rates.size)
    assert abs(rates.mean() - alpha) <= 4 * se + 0.005, (rates.mean(), se)
    bound = 2 * alpha + math.sqrt(2 / n)
    assert rates.max() <= bound + 4 * math.sqrt(bound * (1 - bound) / 2000), rates.max()


def test_a_monitor_saved_before_the_calibration_option_loads_as_the_split_it_was():
    """A monitor pickled before ``calibration`` existed carries neither it nor ``calibration_folds``: it loads as
    the split-calibrated monitor it is, and scores as before."""
    import pickle

    rng = np.random.default_rng(8)
    D, g = _grouped(rng, 12, 4)
    m = BaselineMonitor(alpha=0.1, calibration="split").fit(D, np.array(["T1"] * D.shape[0]), groups=g)
    old = dict(m.__dict__)
    del old["calibration"], old["calibration_folds"]
    saved = BaselineMonitor.__new__(BaselineMonitor)
    saved.__dict__.update(old)
    loaded = pickle.loads(pickle.dumps(saved))
    assert (loaded.calibration, loaded.calibration_folds) == ("split", 5)
    new = rng.standard_normal((50, 3)) * 2.0
    np.testing.assert_array_equal(loaded.health_index(new), m.health_index(new))
    np.testing.assert_array_equal(loaded.p_value(new), m.p_value(new))


def test_cross_fitted_threshold_needs_the_same_calibration_records_as_the_split():
    """ceil(1/alpha) - 1 healthy calibration rows at least: with 98 the 1 % threshold is infinite (no alarm), with
    99 (all of them calibrate under CV+) it is the largest out-of-fold score."""
    rng = np.random.default_rng(5)
    D, g = _grouped(rng, 99, 1)
    y = np.array(["T1"] * 99)
    m = BaselineMonitor(alpha=0.01).fit(D, y, groups=g)
    assert m.n_calibration_ == 99 and m.threshold_ == m.calibration_scores_.max()
    m98 = BaselineMonitor(alpha=0.01).fit(D[:98], y[:98], groups=g[:98])
    assert math.isinf(m98.threshold_) and not m98.alarm(100 * D).any()


def test_monitor_refuses_too_few_healthy_groups_and_bad_alpha():
    D = np.zeros((6, 2))
    y = np.array(["T1"] * 6)
    with pytest.raises(ParameterError, match="at least 4"):
        BaselineMonitor().fit(D, y, groups=np.array([0, 0, 1, 1, 2, 2]))
    with pytest.raises(ParameterError, match="alpha"):
        BaselineMonitor(alpha=1.5).fit(D, y)
    with pytest.raises(ParameterError, match="calibration must be one of cv\\+\\|split"):
        BaselineMonitor(calibration="jackknife").fit(D, y)
    with pytest.raises(ParameterError, match="calibration_folds"):
        BaselineMonitor(calibration_folds=1).fit(D, y)


def test_match_baseline_picks_the_nearest_operating_point_of_the_reducer():
    base = {"reducer": np.array([0, 0, 0, 0, 1]), "output_speed_deg_s": np.array([30.0, 30.2, 60.0, 30.0, 60.1]),
            "load_Nm": np.array([50.0, 51.0, 50.0, 130.0, 50.0]), "role": np.array(["baseline"] * 5)}
    mon = {"reducer": np.array([0, 1, 0]), "output_speed_deg_s": np.array([30.4, 59.5, 60.5]),
           "load_Nm": np.array([49.0, 51.0, 52.0])}
    g = match_baseline(mon, base, fs=48000.0, baseline_fs=48000.0)
    assert [list(x) for x in g] == [[0, 1], [4], [2]]


def test_match_baseline_refuses_beyond_tolerance_and_other_rates():
    base = {"output_speed_deg_s": np.array([30.0]), "load_Nm": np.array([50.0])}
    with pytest.raises(ParameterError, match=r"within 5 % of speed and 10 % of load"):
        match_baseline({"output_speed_deg_s": np.array([45.0]), "load_Nm": np.array([50.0])}, base)
    with pytest.raises(ParameterError, match=r"within 5 % of speed and 10 % of load"):
        match_baseline({"output_speed_deg_s": np.array([30.0]), "load_Nm": np.array([60.0])}, base)
    with pytest.raises(ParameterError, match="same sampling rate"):
        match_baseline({"output_speed_deg_s": np.array([30.0]), "load_Nm": np.array([50.0])}, base,
                       fs=48000.0, baseline_fs=25600.0)
    got = match_baseline({"output_speed_deg_s": np.array([31.0]), "load_Nm": np.array([54.0])}, base)
    assert [list(x) for x in got] == [[0]]  # 3 % and 8 %: inside


def test_is_paired_needs_both_roles():
    assert is_paired({"reducer": [0, 0], "role": ["baseline", "monitored"]})
    assert not is_paired({"reducer": [0], "role": ["monitored"]})
    assert not is_paired({"role": ["baseline", "monitored"]})


def _gear(speed, rng, gain=1.0, fault=0.0, n=24000, fs=48000.0):
    """A mesh at order 11 of the sun shaft, broadband noise, and with ``fault`` a pulse on one tooth at each of the
    two planets (twice per sun revolution)."""
    f = shaft_frequency("sun", output_speed_deg_s=speed)
    th = f * np.arange(n) / fs  # sun revolutions
    x = np.cos(2 * np.pi * 11 * th) + 0.3 * np.cos(2 * np.pi * 22 * th + 0.4)
    ph = (th * 2) % 1.0
    x = x + fault * np.exp(-0.5 * ((ph - 0.3) / 0.01) ** 2)
    return gain * x + 0.2 * rng.standard_normal(n)


def test_tsa_change_sees_a_tooth_pulse_but_not_a_gain_change():
    rng = np.random.default_rng(3)
    base = [_gear(45.0, rng) for _ in range(3)]
    healthy = tsa_change_features(_gear(45.0, rng, gain=1.03), 45.0, base, [45.0] * 3, 48000.0)
    faulty = tsa_change_features(_gear(45.0, rng, fault=0.5), 45.0, base, [45.0] * 3, 48000.0)
    # log10 tooth_peak (index 3): the pulse's slots stand out of the change's median; a 3 % gain changes every
    # tooth alike
    assert faulty[3] - healthy[3] > math.log10(3)
    assert faulty[6] - healthy[6] > math.log10(3)  # and against the baseline's own leave-one-out spread


def test_saved_monitor_round_trip(tmp_path):
    from rvdiag.models.persistence import load_model

    X, B, groups, y, red = _paired(n_reducers=12)
    fx = BaselineReferencedFeatures(TimeDomainFeatures(), tsa_change=False).fit(X)
    D = fx.transform(X, B, groups)
    m = BaselineMonitor(features=fx).fit(D, y, groups=red)
    save_monitor(m, tmp_path / "mon", fs=FS)
    got = load_model(tmp_path / "mon")
    assert got.card["needs_baseline"] is True
    assert got.card["input_length"] == X.shape[1] and got.card["alarm"]["alpha"] == 0.01
    assert got.card["alarm"]["calibration"] == "cv+" and got.card["alarm"]["calibration_folds"] == 5
    assert got.card["alarm"]["n_calibration"] == 72 and got.card["alarm"]["n_calibration_groups"] == 12
    est = got.estimator
    np.testing.assert_allclose(est.health_index(est.paired_features(X, B, groups)), m.health_index(D))
    np.testing.assert_allclose(est.p_value(D), m.p_value(D))
    assert list(est.predict(D)) == list(m.predict(D))
    words = est.diagnose(D[-1:])[0]
    assert set(words) == {"health_index", "alarm", "p_value", "state", "probability", "changed"}
    assert words["changed"][0].startswith("d_")


def test_tsa_change_alone_has_only_the_tsa_change_features():
    from rvdiag.features.relative import TSA_CHANGE_NAMES

    rng = np.random.default_rng(4)
    base = np.array([np.r_[_gear(45.0, rng), 45.0] for _ in range(3)])
    X = np.array([np.r_[_gear(45.0, rng, fault=0.5), 45.0]])
    fx = BaselineReferencedFeatures(features="none", fs=48000.0, median_tooth=False).fit(X)
    assert fx.input_metadata() == ("output_speed_deg_s",)
    assert list(fx.get_feature_names_out()) == list(TSA_CHANGE_NAMES)
    D = fx.transform(X, base, [np.arange(3)])
    np.testing.assert_allclose(D[0], tsa_change_features(X[0, :-1], 45.0, list(base[:, :-1]), [45.0] * 3, 48000.0))
    with pytest.raises(ParameterError, match="needs tsa_change=True"):
        BaselineReferencedFeatures(features="none", tsa_change=False).fit(X)


def test_median_tooth_change_sees_a_uniform_mesh_change_not_the_tooth_pulse():
    from rvdiag.features.relative import MEDIAN_TOOTH_NAMES

    rng = np.random.default_rng(5)
    base = [_gear(45.0, rng) for _ in range(3)]
    pulse = tsa_change_features(_gear(45.0, rng, fault=0.5), 45.0, base, [45.0] * 3, 48000.0, median_tooth=True)
    worn = tsa_change_features(_gear(45.0, rng, gain=1.5), 45.0, base, [45.0] * 3, 48000.0, median_tooth=True)
    plain = tsa_change_features(_gear(45.0, rng, fault=0.5), 45.0, base, [45.0] * 3, 48000.0)
    assert pulse.size == plain.size + len(MEDIAN_TOOTH_NAMES) == 9
    # the pulse is seen by the tooth peak but leaves the median tooth's RMS (index 8) within 5 %; a 1.5 x mesh
    # on every tooth moves it by log10(1.5)
    assert pulse[3] > math.log10(3)
    assert abs(pulse[8]) < math.log10(1.05)
    assert abs(worn[8] - math.log10(1.5)) < 0.03
    assert worn[7] > pulse[7] + 0.5  # the median tooth's change, in decades


def test_baseline_features_append_the_median_tooth_unless_pickled_before_it():
    from rvdiag.features.relative import MEDIAN_TOOTH_NAMES, TSA_CHANGE_NAMES

    rng = np.random.default_rng(6)
    base = np.array([np.r_[_gear(45.0, rng), 45.0] for _ in range(3)])
    X = np.array([np.r_[_gear(45.0, rng, fault=0.5), 45.0]])
    fx = BaselineReferencedFeatures(features="none", fs=48000.0).fit(X)
    assert list(fx.get_feature_names_out()) == list(TSA_CHANGE_NAMES) + list(MEDIAN_TOOTH_NAMES)
    D = fx.transform(X, base, [np.arange(3)])
    np.testing.assert_allclose(D[0], tsa_change_features(X[0, :-1], 45.0, list(base[:, :-1]), [45.0] * 3,
                                                         48000.0, median_tooth=True))
    del fx.median_tooth  # as a model pickled before the option existed
    assert list(fx.get_feature_names_out()) == list(TSA_CHANGE_NAMES)
    np.testing.assert_allclose(fx.transform(X, base, [np.arange(3)])[0], D[0, : len(TSA_CHANGE_NAMES)])


def test_tsa_change_from_tsa_is_tsa_change_features_on_tsas_computed_once():
    from rvdiag.features import orders as _o
    from rvdiag.features.relative import sun_tsa, tsa_change_from_tsa

    rng = np.random.default_rng(7)
    speeds = [45.0, 45.3, 44.8]
    base = [_gear(v, rng) for v in speeds]
    x = _gear(45.1, rng, fault=0.5)
    spr = _o.default_samples_per_rev(48000.0, shaft_frequency("sun", output_speed_deg_s=45.1), 11)
    Tb = [sun_tsa(b, 48000.0, v, spr) for b, v in zip(base, speeds)]
    got = tsa_change_from_tsa(sun_tsa(x, 48000.0, 45.1, spr), Tb, 11, 2, median_tooth=True)
    np.testing.assert_allclose(got, tsa_change_features(x, 45.1, base, speeds, 48000.0, median_tooth=True))
    assert got[3] > math.log10(3)  # the pulse is seen: not a vacuous comparison of two NaN vectors
    with pytest.raises(ParameterError, match=">= 1 baseline TSA"):
        tsa_change_from_tsa(Tb[0], [], 11, 2)
