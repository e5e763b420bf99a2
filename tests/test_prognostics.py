"""rvdiag.prognostics: the conformal test martingale's lifetime bound and p-values, CUSUM / Page-Hinkley, the
Bayesian degradation model's intervals, joint_prognosis, Paris' law and the synthetic histories."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import numpy as np
import pytest
from scipy import integrate, stats

from rvdiag.errors import ParameterError
from rvdiag.gears.crack_growth import (paris_crack_depth, paris_cycles, paris_stress_for_cycles,
                                       stress_intensity_range, threshold_crack_depth)
from rvdiag.prognostics import ConformalMartingale, Cusum, PageHinkley, estimate_rul, joint_prognosis
from rvdiag.prognostics.synthetic import HistorySpec, draw_history


def _stream(seed, n=80, n_base=20):
    rng = np.random.default_rng(seed)
    x = rng.gamma(3.0, size=n_base + n)
    return x[:n_base], x[n_base:]


def test_ville_bound_holds_on_exchangeable_streams():
    # delta = 0.1 so that a broken bound shows in 300 streams: alarms <= the binomial 99.9 % quantile of 300 x 0.1
    alarms = sum(ConformalMartingale(b, delta=0.1, seed=s).run(x).alarmed
                 for s in range(300) for b, x in [_stream(s)])
    assert alarms <= stats.binom.ppf(0.999, 300, 0.1)


def test_ville_bound_test_sees_a_liberal_p_value():
    # p-values half what they should be (a two-sided p-value halved, a rank off by one in a small bag) break the
    # bound: the test above would see it
    class Liberal(ConformalMartingale):
        def p_value(self, score):
            return 0.5 * super().p_value(score)

    alarms = sum(Liberal(b, delta=0.1, seed=s).run(x).alarmed for s in range(100) for b, x in [_stream(s)])
    assert alarms > stats.binom.ppf(0.999, 100, 0.1)


def test_p_values_uniform_under_exchangeability_with_ties():
    rng = np.random.default_rng(5)
    x = rng.poisson(3.0, size=1500).astype(float)        # many ties: the smoothing must make them uniform
    d = ConformalMartingale(x[:10], seed=1).run(x[10:])
    assert stats.kstest(d.p_values, "uniform").pvalue > 1e-3
    # and without smoothing they would not be: ties make the unsmoothed p-values lumpy
    assert np.unique(np.round(d.p_values, 12)).size > 0.9 * d.p_values.size


def test_step_change_detected_within_six_records():
    delays = []
    for s in range(100):
        b, x = _stream(1000 + s)
        x = x.copy()
        x[30:] += 20.0                                    # a broken tooth: a step far above the healthy spread
        d = ConformalMartingale(b, seed=s).run(x)
        delays.append(np.inf if d.alarm_index is None else d.alarm_index - 30)
        if d.alarmed:
            assert 0 <= d.onset_index <= 31 and d.alarm_index >= 30
    delays = np.array(delays)
    assert np.mean(delays <= 5) >= 0.95                  # measured: median 3, 99 % within 5 (bench/HISTORY.md)


def test_martingale_deterministic_for_a_seed():
    b, x = _stream(7)
    a1, a2 = ConformalMartingale(b, seed=3).run(x), ConformalMartingale(b, seed=3).run(x)
    np.testing.assert_array_equal(a1.statistic, a2.statistic)
    assert not np.array_equal(a1.p_values, ConformalMartingale(b, seed=4).run(x).p_values)


def test_martingale_rejects_bad_parameters():
    with pytest.raises(ParameterError):
        ConformalMartingale([1.0], delta=0.0)
    with pytest.raises(ParameterError):
        ConformalMartingale([1.0], levels=(1.5,))
    with pytest.raises(ParameterError):
        ConformalMartingale([1.0]).run([1.0, np.nan])


def test_cusum_and_page_hinkley_follow_their_recursions():
    base = np.array([0.0, 1.0, 2.0, 1.0])
    mu, sd = base.mean(), base.std(ddof=1)
    x = np.array([1.0, 3.0, 0.5, 4.0, 4.0, 4.0])
    z = (x - mu) / sd
    s, ref = 0.0, []
    for v in z:
        s = max(0.0, s + v - 0.5)
        ref.append(s)
    np.testing.assert_allclose(Cusum(base).run(x).statistic, ref)
    zs, m, mmin, ref = list((base - mu) / sd), 0.0, 0.0, []
    for v in z:
        zs.append(v)
        m += v - np.mean(zs) - 0.5
        mmin = min(mmin, m)
        ref.append(m - mmin)
    np.testing.assert_allclose(PageHinkley(base).run(x).statistic, ref)
    with pytest.raises(ParameterError):
        Cusum([1.0, 1.0])


def _exp_history(rng, beta=0.02, sigma=0.1, n=15):
    t = np.arange(n) * 7.0
    y = np.log(0.5) + beta * t + rng.normal(0.0, sigma, n)
    t_fail = (np.log(20.0) - np.log(0.5)) / beta
    return t, np.exp(y), t_fail - t[-1]


def test_exponential_model_intervals_cover_when_the_model_holds():
    rng = np.random.default_rng(0)
    hits = []
    for s in range(200):
        t, hi, true_rul = _exp_history(rng)
        r = estimate_rul(t, hi, threshold=20.0, healthy_level=0.0, seed=s, n_samples=2000)
        assert r.estimated
        hits.append(r.p10_days <= true_rul <= r.p90_days)
    assert 0.72 <= np.mean(hits) <= 0.88                 # 80 % nominal; binomial sd 2.8 % at n = 200


def test_linear_model_recovers_a_straight_line():
    t = np.arange(10.0)
    hi = 1.0 + 0.5 * t + np.random.default_rng(1).normal(0.0, 0.01, 10)
    r = estimate_rul(t, hi, threshold=11.0, model="linear")
    assert r.median_days == pytest.approx(11.0, abs=0.2)  # 1 + 0.5 t = 11 at t = 20, 11 days after t = 9
    assert r.p_before(5.0) == 0.0 and r.p_before(100.0) == 1.0


@pytest.mark.parametrize("kwargs, reason", [
    ({"threshold": None}, "no failure threshold"),
    ({"threshold": 20.0, "min_records": 30}, "needed"),
])
def test_rul_not_estimated_with_reason(kwargs, reason):
    rng = np.random.default_rng(2)
    t, hi, _ = _exp_history(rng)
    r = estimate_rul(t, hi, **kwargs)
    assert not r.estimated and reason in r.reason
    assert r.to_dict() == {"estimated": False, "reason": r.reason, "model": "exponential"}


def test_rul_not_estimated_when_the_trend_does_not_hold():
    rng = np.random.default_rng(3)
    r = estimate_rul(np.arange(12.0), 1.0 + rng.normal(0.0, 0.2, 12), threshold=5.0, model="linear")
    assert not r.estimated and "trend does not hold" in r.reason


def _joint(seed=1):
    rng = np.random.default_rng(seed)
    base = rng.gamma(4.0, 0.1, 30)
    days = np.arange(40.0) * 7
    hi = rng.gamma(4.0, 0.1, 40) * np.where(days > 140, np.exp((days - 140) / 40.0), 1.0)
    return base, days, hi


def test_joint_prognosis_interface():
    base, days, hi = _joint()
    t = [datetime(2026, 1, 1, tzinfo=timezone.utc) + timedelta(days=float(d)) for d in days]
    p = joint_prognosis(t, health_index=hi, baseline_scores=base, threshold=20.0, before=["2027-01-01T00:00:00+00:00"])
    d = p.to_dict()
    assert p.alarmed and d["alarm_time"] >= d["onset_time"] >= t[0].isoformat()
    assert set(d["rul"]) >= {"median_days", "p10_days", "p90_days", "p_before", "assumption"}
    assert d["rul"]["p10_days"] <= d["rul"]["median_days"] <= d["rul"]["p90_days"]
    assert list(d["rul"]["p_before"]) == ["2027-01-01T00:00:00+00:00"]
    assert "duty cycle" in d["assumption"]
    import json
    assert json.loads(json.dumps(d)) == d
    # without commissioning scores the first records fill the bag, and those before the onset are the healthy ones
    e = joint_prognosis(np.arange(70.0) * 7, health_index=np.concatenate([base, hi]), baseline_scores=[],
                        threshold=20.0)
    assert e.alarmed and e.onset_index >= 30 and e.rul.parameters["healthy_level"] > 0
    # the same history as numbers of days gives the same onset and alarm
    q = joint_prognosis(days, health_index=hi, baseline_scores=base, threshold=20.0).to_dict()
    assert (q["onset_index"], q["alarm_index"]) == (d["onset_index"], d["alarm_index"])


def test_joint_prognosis_before_onset_and_bad_input():
    base, days, hi = _joint()
    d = joint_prognosis(days[:15], health_index=hi[:15], baseline_scores=base, threshold=20.0).to_dict()
    assert d["alarm_time"] is None and d["rul"] == {"estimated": False, "model": "size",
                                                    "reason": "no confirmed onset: the change detector has not alarmed"}
    # p-values alone drive the detector (ranked as 1 - p)
    assert joint_prognosis(days[:5], p_values=[0.5] * 5, baseline_scores=[0.3] * 5).alarm_index is None
    # a broken tooth has failed: no remaining life; a crack gets Paris' law
    d = joint_prognosis(days, health_index=hi, baseline_scores=base, threshold=20.0, fault_state="T5").to_dict()
    assert d["alarm_time"] is not None and "broken tooth" in d["rul"]["reason"]
    assert joint_prognosis(days, health_index=hi, baseline_scores=base, threshold=20.0, fault_state="T4").rul.model \
        == "paris"
    with pytest.raises(ParameterError):
        joint_prognosis(days, health_index=hi[:-1], baseline_scores=base)
    with pytest.raises(ParameterError):
        joint_prognosis(["2026-01-01", "yesterday"], health_index=[1.0, 2.0], baseline_scores=base)


def test_paris_closed_form_matches_integration():
    a0, ds = 1e-4, 200.0
    n_end = 0.9 * paris_cycles(a0, 1e-2, ds)
    sol = integrate.solve_ivp(lambda n, a: 1.65e-11 * stress_intensity_range(a, ds) ** 3, (0.0, n_end), [a0],
                              rtol=1e-10, atol=1e-14)
    assert paris_crack_depth(a0, n_end, ds, delta_k_th=0.0) == pytest.approx(sol.y[0, -1], rel=1e-6)
    assert paris_stress_for_cycles(a0, 2e-3, paris_cycles(a0, 2e-3, ds)) == pytest.approx(ds)
    assert stress_intensity_range(threshold_crack_depth(ds), ds) == pytest.approx(2.0)
    # below the threshold the crack does not grow
    assert paris_crack_depth(a0, 1e9, 10.0) == pytest.approx(a0)


@pytest.fixture(scope="module")
def params():
    from rvdiag.params import ReducerParams
    return ReducerParams.default()


def test_synthetic_histories_truth_and_determinism(params):
    spec = HistorySpec()
    h = draw_history("wear", 11, params, spec)
    i = int(np.searchsorted(h.days, h.failure_day))
    assert h.size[i - 1] < spec.wear_fail_m <= h.size[i]            # failure day = the size's crossing
    np.testing.assert_array_equal(h.health_index, draw_history("wear", 11, params, spec).health_index)
    c = draw_history("crack", 11, params, spec)
    j = int(np.searchsorted(c.days, c.failure_day))
    assert c.size[j - 1] < c.size[j] and c.health_index[j:].min() > 5 * spec.threshold_index / 10
    healthy = np.concatenate([draw_history("healthy", s, params, spec).health_index for s in range(40)])
    assert np.quantile(healthy, 0.5) < 1.0 and not np.any(draw_history("healthy", 1, params, spec).size)
    with pytest.raises(ParameterError):
        draw_history("pitting", 0, params)


def test_size_model_intervals_cover_when_wear_grows_linearly():
    # the index is phi + z^2 with the implied size z growing linearly (Archard wear at a steady duty) plus noise
    rng = np.random.default_rng(4)
    hits = []
    for s in range(150):
        t = np.arange(12) * 7.0
        z = 0.05 * t + rng.normal(0.0, 0.3, t.size)
        hi = 1.0 + np.sign(z) * z ** 2
        true_rul = (np.sqrt(20.0 - 1.0) / 0.05) - t[-1]
        r = estimate_rul(t, hi, threshold=20.0, healthy_level=1.0, model="size", seed=s, n_samples=2000)
        hits.append(r.estimated and r.p10_days <= true_rul <= r.p90_days)
    assert 0.70 <= np.mean(hits) <= 0.90


def test_paris_model_follows_the_closed_form_growth():
    # a crack by Paris' law (m = 3): a^(-1/2) falls linearly; the index excess grows as a^2, so (HI - phi)^(-1/4)
    # falls linearly to the threshold's
    t = np.arange(10) * 5.0
    a = (1.0 - 0.01 * t) ** -2.0                      # unstable at t = 100; a = 16 at t = 75
    hi = 0.5 + a ** 2 * (1.0 + np.random.default_rng(0).normal(0.0, 1e-4, t.size))
    r = estimate_rul(t, hi, threshold=0.5 + 16.0 ** 2, healthy_level=0.5, model="paris")
    assert r.median_days == pytest.approx(75.0 - t[-1], abs=0.5)


def test_threshold_draws_and_the_joints_own_scale():
    base, days, hi = _joint()
    with pytest.raises(ParameterError):
        estimate_rul(days, hi, threshold=np.ones(7))
    kw = dict(threshold=20.0, model="size", reference_level=float(np.median(base)))
    p1 = joint_prognosis(days, health_index=hi, baseline_scores=base, **kw)
    p3 = joint_prognosis(days, health_index=3.0 * hi, baseline_scores=3.0 * base, **kw)
    # a joint whose index runs at 3x reaches the same fault size at 3x the threshold: the same remaining life
    assert p1.rul.estimated and p3.rul.median_days == pytest.approx(p1.rul.median_days, rel=1e-9)
    p3_fixed = joint_prognosis(days, health_index=3.0 * hi, baseline_scores=3.0 * base, threshold=20.0, model="size")
    assert p3_fixed.rul.median_days < 0.8 * p1.rul.median_days


def test_a_threshold_population_widens_the_interval_by_its_spread():
    """A threshold given as a population (the index at failure of reducers run to it) is drawn from in the Monte
    Carlo: the interval is wider than with its median alone, holds the median's when the population is one value
    repeated, and follows the population's median; the draws are seeded."""
    base, days, hi = _joint()
    one = joint_prognosis(days, health_index=hi, baseline_scores=base, threshold=20.0, model="size")
    same = joint_prognosis(days, health_index=hi, baseline_scores=base, threshold=[20.0] * 5, model="size")
    assert one.rul.estimated and same.rul.p90_days == pytest.approx(one.rul.p90_days, rel=1e-12)
    pop = [12.0, 15.0, 20.0, 26.0, 33.0]
    wide = joint_prognosis(days, health_index=hi, baseline_scores=base, threshold=pop, model="size")
    again = joint_prognosis(days, health_index=hi, baseline_scores=base, threshold=pop, model="size")
    assert wide.rul.p90_days - wide.rul.p10_days > 1.5 * (one.rul.p90_days - one.rul.p10_days)
    assert wide.rul.p10_days < one.rul.p10_days and wide.rul.p90_days > one.rul.p90_days
    assert np.array_equal(wide.rul.samples_days, again.rul.samples_days)
    with pytest.raises(ParameterError):
        joint_prognosis(days, health_index=hi, baseline_scores=base, threshold=[20.0, float("nan")])
