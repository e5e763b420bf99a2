"""Change detection and remaining life over joints' lives (rvdiag.prognostics.metrics) and ``rvdiag evaluate --life``
on a small life store written by hand with the life-store columns (docs/prognostics.md)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli
from rvdiag.datasets.store import write_store
from rvdiag.errors import ParameterError
from rvdiag.evaluation.metrics import binomial_interval
from rvdiag.features.orders import shaft_frequency
from rvdiag.params import ReducerParams
from rvdiag.prognostics import ConformalMartingale, Cusum, Persistence, joint_prognosis
from rvdiag.prognostics.metrics import LifeHistory, alpha_lambda_met, life_metrics, prediction_index
from rvdiag.prognostics.synthetic import HistorySpec, draw_history
from test_monitoring_cli import FS, L, OPS, fingerprint, params_attrs, record, vary


# ------------------------------------------------------------------------------------------- the metrics module
def _synthetic(kind, seed, spec=HistorySpec(n_records=40)):
    h = draw_history(kind, seed, ReducerParams.default(), spec)
    return h, LifeHistory(days=h.days, score=h.health_index, fate=kind, onset_days=h.onset_day,
                          failure_days=h.failure_day, state={"wear": "T3", "broken": "T2"}.get(kind),
                          baseline_scores=h.baseline, threshold=h.threshold_index,
                          reference_level=spec.reference_level, seed=seed, name=f"{kind}{seed}")


def test_healthy_histories_that_never_alarm_give_rate_zero_with_its_exact_interval():
    hs = [_synthetic("healthy", s)[1] for s in range(12)]
    out = life_metrics(hs, classical=True)
    fa = out["pooled"]["lifetime_false_alarm"]
    assert fa["n"] == 12 and fa["n_alarmed"] == 0 and fa["rate"] == 0.0 and fa["bound"] == 0.01
    # Clopper-Pearson for 0 of n: [0, 1 - 0.025^(1/n)]
    assert fa["ci95"][0] == 0.0 and fa["ci95"][1] == pytest.approx(1 - 0.025 ** (1 / 12), rel=1e-9)
    assert out["pooled"]["detection_delay_records"] == {} and out["pooled"]["rul_coverage_80"]["n"] == 0
    assert out["pooled"]["rul_coverage_80"]["rate"] is None
    # per reducer: the same keys, one history each; the classical detectors (no lifetime bound) beside
    assert set(out["per_reducer"]) == {f"healthy{s}" for s in range(12)}
    assert out["per_reducer"]["healthy0"]["lifetime_false_alarm"]["n"] == 1
    assert out["pooled"]["baseline"]["cusum"]["lifetime_false_alarm"]["bound"] is None
    json.dumps(out, allow_nan=False)


def test_alarm_of_a_healthy_history_counts_and_matches_the_detector():
    """A healthy joint whose index drifts upward alarms: the rate counts it, as the martingale run alone says."""
    base = np.linspace(0.5, 1.5, 20)
    days = 7.0 * np.arange(1, 41)
    drift = LifeHistory(days=days, score=1.0 + 0.5 * np.arange(40), fate="healthy", baseline_scores=base, name="a")
    flat = LifeHistory(days=days, score=np.full(40, 1.0), fate="healthy", baseline_scores=base, name="b")
    out = life_metrics([drift, flat])
    assert ConformalMartingale(base, seed=0).run(drift.score).alarmed
    fa = out["pooled"]["lifetime_false_alarm"]
    assert (fa["n_alarmed"], fa["rate"]) == (1, 0.5)
    assert fa["ci95"] == pytest.approx(binomial_interval(1, 2))
    assert out["per_reducer"]["a"]["lifetime_false_alarm"]["rate"] == 1.0
    assert out["per_reducer"]["b"]["lifetime_false_alarm"]["rate"] == 0.0


def test_a_huge_step_is_detected_on_its_third_record_and_cusum_at_once():
    """200 commissioning scores, then a step of 1000 sd from the first record on.  Every faulty record then gets a
    p-value below 0.05, so each step function multiplies its capital by kappa + (1 - kappa) / a (16.2, 8.2, 4.2 for
    a = 0.05, 0.1, 0.2), the jumper first moving 10 % of the total to the weights (0.5, 1/6, 1/6, 1/6): the
    martingale is 5.27 after the first record, 55.3 after the second and 715 after the third, so it passes 1/delta =
    100 on the third (delay 2).  CUSUM passes h = 5 on the first (delay 0)."""
    rng = np.random.default_rng(3)
    hs = [LifeHistory(days=7.0 * np.arange(1, 21), score=rng.normal(100.0, 0.1, 20), fate="broken", onset_days=7.0,
                      failure_days=7.0, state="T2", baseline_scores=rng.normal(1.0, 0.1, 200), seed=s, name=str(s))
          for s in range(5)]
    out = life_metrics(hs, classical=True)["pooled"]
    d = out["detection_delay_records"]["T2"]
    assert d["median"] == 2 and d["p90"] == 2 and d["n_detected"] == 5 and d["detected_before_failure"] == 1.0
    assert out["detected_within_3"]["T2"]["share"] == 1.0
    run = ConformalMartingale(hs[0].baseline_scores, seed=0).run(hs[0].score)
    assert run.statistic[:3] == pytest.approx([5.27, 55.3, 715], rel=2e-3)
    assert out["baseline"]["cusum"]["detection_delay_records"]["T2"]["median"] == 0
    assert Cusum(hs[0].baseline_scores).run(hs[0].score).alarm_index == 0
    # a sudden broken tooth has failed at onset: no remaining life is scored
    assert out["rul_coverage_80"]["n"] == 0
    # the monitor's own alarm (index > 1) held for 3 of 3 records: its third faulty record (delay 2)
    m = out["monitor_alarm"]
    assert m["detection_delay_records"]["T2"]["median"] == 2 and m["detected_within_3"]["T2"]["share"] == 1.0
    assert m["lifetime_false_alarm"]["bound"] is None


def test_the_monitors_persistence_alarm_counts_k_of_n_and_its_false_alarms():
    """Persistence: alarms once k of the last n indices exceed the level, onset at the window's first alarming
    record; over lives, a healthy history whose index runs above 1 in three records running is a false alarm (no
    bound), and one above 1 in two records of three is not (3 of 3)."""
    assert Persistence(k=2, n=3).run([0.1, 2.0, 0.1, 2.0, 0.1]).alarm_index == 3
    run = Persistence(k=3, n=3).run([0.1, 2.0, 0.1, 2.0, 2.0, 2.0, 0.1])
    assert run.alarm_index == 5 and run.onset_index == 3 and list(run.statistic) == [0, 1, 1, 2, 2, 3, 2]
    with pytest.raises(ParameterError, match="1 <= k <= n"):
        Persistence(k=4, n=3)
    days = 7.0 * np.arange(1, 11)
    runs_high = np.array([0.2] * 4 + [1.5] * 3 + [0.2] * 3)
    two_of_three = np.array([0.2] * 4 + [1.5, 0.2, 1.5] + [0.2] * 3)
    hs = [LifeHistory(days, runs_high, "healthy", name="a"), LifeHistory(days, two_of_three, "healthy", name="b")]
    out = life_metrics(hs)
    fa = out["pooled"]["monitor_alarm"]["lifetime_false_alarm"]
    assert fa["n"] == 2 and fa["n_alarmed"] == 1 and fa["rate"] == 0.5
    assert out["per_reducer"]["a"]["monitor_alarm"]["lifetime_false_alarm"]["n_alarmed"] == 1


def test_delay_from_the_first_record_whose_true_state_is_faulty():
    """The huge step's martingale alarms on its third record (delay 2 from the onset); the same history whose first
    two faulty records are still T1 in truth (a fault below its smallest simulated size) alarms 0 records after its
    first T3 record."""
    rng = np.random.default_rng(3)
    h = LifeHistory(days=7.0 * np.arange(1, 21), score=rng.normal(100.0, 0.1, 20), fate="wear", onset_days=7.0,
                    failure_days=1e4, state="T3", baseline_scores=rng.normal(1.0, 0.1, 200),
                    true_state=["T1", "T1"] + ["T3"] * 18)
    d = life_metrics([h], per_history=False)["pooled"]["detection_delay_records"]["T3"]
    assert d["median"] == 2 and d["from_first_faulty_record"] == {"median": 0.0, "p90": 0.0, "n": 1}


def test_delay_never_and_alarms_before_onset_are_misses():
    base = np.linspace(0.5, 1.5, 20)
    days = 7.0 * np.arange(1, 21)
    never = LifeHistory(days=days, score=np.ones(20), fate="wear", onset_days=35.0, failure_days=500.0, state="T3",
                        baseline_scores=base, name="never")
    out = life_metrics([never])["pooled"]
    d = out["detection_delay_records"]["T3"]
    assert d["median"] is None and d["p90"] is None and d["n_detected"] == 0
    assert out["detected_within_3"]["T3"]["share"] == 0.0


def test_sensor_fault_records_are_left_out_of_the_stream():
    base = np.linspace(0.5, 1.5, 20)
    days = 7.0 * np.arange(1, 31)
    score = np.ones(30)
    score[10:] = 1e6                                        # a dead channel's nonsense, flagged
    h = LifeHistory(days=days, score=score, fate="healthy", baseline_scores=base,
                    sensor_fault=np.arange(30) >= 10, name="s")
    nan = LifeHistory(days=days, score=np.where(np.arange(30) >= 10, np.nan, 1.0), fate="healthy",
                      baseline_scores=base, name="n")
    out = life_metrics([h, nan])
    assert out["pooled"]["lifetime_false_alarm"]["n_alarmed"] == 0
    assert out["pooled"]["n_records_left_out"] == 40
    assert out["per_reducer"]["s"]["outcome"]["n_records"] == 10


def test_alpha_lambda_agrees_with_progpy():
    progpy = pytest.importorskip("progpy")
    from progpy.metrics import alpha_lambda
    from progpy.predictors import ToEPredictionProfile
    from progpy.uncertain_data import UnweightedSamples

    rng = np.random.default_rng(0)
    met = []
    for _ in range(40):
        t, eol = rng.uniform(0, 100), rng.uniform(110, 300)
        rul = (eol - t) * rng.lognormal(rng.normal(0, 0.2), rng.uniform(0.05, 0.4), 200)
        profile = ToEPredictionProfile()
        profile.add_prediction(t, UnweightedSamples([{"f": float(t + v)} for v in rul]))
        ref = bool(alpha_lambda(profile, {"f": eol}, t, 0.2, 0.5)["f"])
        assert alpha_lambda_met(t, rul, eol) == ref
        met.append(ref)
    assert 0 < sum(met) < len(met)  # both outcomes were compared
    assert progpy.__version__


def test_remaining_life_outcomes_are_the_products_at_t_lambda():
    """Each scored wear history's coverage and alpha-lambda are those of joint_prognosis at the record that
    prediction_index names (an independent re-run), and linear extrapolation is its rul_baseline."""
    hs = [_synthetic("wear", 20_000 + s) for s in range(4)]
    out = life_metrics([lh for _, lh in hs], models=("size",))
    n = 0
    for h, lh in hs:
        m = ConformalMartingale(h.baseline, seed=lh.seed).run(h.health_index)
        per = out["per_reducer"][lh.name]
        if m.alarm_index is None or h.days[m.alarm_index] >= h.failure_day:
            assert per["rul_coverage_80"]["n"] == 0
            continue
        n += 1
        k = prediction_index(h.days, m.alarm_index, h.failure_day)
        assert h.days[k] >= h.days[m.alarm_index] + 0.5 * (h.failure_day - h.days[m.alarm_index]) - 7.0
        p = joint_prognosis(h.days[:k + 1], health_index=h.health_index[:k + 1], baseline_scores=h.baseline,
                            threshold=h.threshold_index, seed=lh.seed, model="size",
                            reference_level=lh.reference_level)
        true = h.failure_day - h.days[k]
        for key, r in ((per, p.rul), (per["baseline"], p.rul_baseline)):
            assert key["rul_coverage_80"]["rate"] == float(r.estimated and r.p10_days <= true <= r.p90_days)
            assert key["alpha_lambda"]["rate"] == float(
                r.estimated and alpha_lambda_met(h.days[k], r.samples_days, h.failure_day))
    assert n >= 3
    assert out["pooled"]["rul_coverage_80"]["n"] == n and out["pooled"]["rul_coverage_80"]["model"] == "size"


def test_coverage_of_a_straight_line_degradation_is_near_its_stated_80_percent():
    """An index far above the commissioning scores from the first record on, growing on a straight line with
    Gaussian noise: the martingale's onset is the first record, and linear extrapolation is the true model, so its
    80 % interval should hold the true failure time in about 80 % of histories (binomial sd 6 % over 40), and with
    small noise the median lies within 20 % of it (alpha-lambda met) always."""
    rng = np.random.default_rng(11)
    hs = []
    for s in range(40):
        days = 7.0 * np.arange(1, 61)
        slope, thr = rng.uniform(0.05, 0.1), 40.0
        score = 31.0 + slope * (days - 7.0) + rng.normal(0, 0.05, 60)
        failure = 7.0 + (thr - 31.0) / slope
        hs.append(LifeHistory(days=days, score=score, fate="wear", onset_days=7.0, failure_days=failure,
                              state="T3", baseline_scores=rng.normal(1.0, 0.05, 20), threshold=thr, seed=s,
                              name=str(s)))
    out = life_metrics(hs, models=("linear",), per_history=False)["pooled"]
    cov = out["baseline"]["rul_coverage_80"]
    assert cov["n"] == 40 and 0.6 <= cov["rate"] <= 0.95, cov
    assert out["baseline"]["alpha_lambda"]["rate"] == 1.0
    assert out["rul_models"]["linear"]["estimated"] == 1.0


def test_bad_models_and_no_histories_are_refused():
    h = _synthetic("healthy", 1)[1]
    with pytest.raises(ParameterError, match="models must be among"):
        life_metrics([h], models=("quadratic",))
    with pytest.raises(ParameterError, match="no histories"):
        life_metrics([])


# ------------------------------------------------------------------------------ rvdiag evaluate --life on a store
N_REDUCERS, TRAIN = 12, 8
N_MON, INTERVAL = 14, 7.0
#: per reducer: (fate, onset day, failure day) -- train 0-7, test 8-11
FATES = [("healthy", None, None), ("wear", 30.0, 90.0), ("broken", 40.0, 40.0), ("wear", 20.0, 70.0),
         ("healthy", None, None), ("broken", 50.0, 50.0), ("wear", 25.0, 80.0), ("healthy", None, None),
         ("healthy", None, None), ("wear", 28.0, 85.0), ("broken", 45.0, 45.0), ("healthy", None, None)]
#: reducer -> the monitored record from which its channel is dead (one training, one held-out reducer)
SENSOR_FAULT_FROM = {7: 12, 11: 10}


def _life_record(rng, fp, speed, load, fate, size):
    x = record(rng, fp, speed, load, "T2" if fate == "broken" and size > 0 else "T1")
    if fate == "wear" and size > 0:   # wear's signature (T3 of the paired store) growing with its size
        th = shaft_frequency("sun", output_speed_deg_s=speed) * np.arange(L) / FS + rng.uniform(0, 1)
        a, p = fp["mesh"][1]
        x = x + size * (2 * a * np.cos(2 * np.pi * 22 * th + p) + 0.3 * np.cos(2 * np.pi * 7 * th + p))
    return x


def life_store_records(seed: int = 0):
    """A life store's signals, labels and columns: 12 commissioning records a reducer, then 14 weekly records over
    its fate, each reducer's records written in a shuffled order (life.record gives the order)."""
    rng = np.random.default_rng(seed)
    X, y = [], []
    meta = {k: [] for k in ("reducer", "role", "output_speed_deg_s", "load_Nm", "split", "unit", "life.record",
                            "life.time_days", "life.fate", "life.onset_days", "life.failure_days",
                            "life.sensor_fault", "life.size", "life.load_cycles")}
    for r, (fate, onset, failure) in enumerate(FATES):
        fp = fingerprint(rng)
        rows = [("baseline", op, 0.0) for op in OPS for _ in range(3)]
        rows += [("monitored", OPS[int(rng.integers(len(OPS)))], INTERVAL * (i + 1)) for i in range(N_MON)]
        for i in rng.permutation(len(rows)):
            role, (v0, l0), day = rows[i]
            size = 0.0 if onset is None or day < onset else (1.0 if fate == "broken" else
                                                             min(1.0, (day - onset) / (failure - onset)))
            state = "T1" if size == 0 else ("T2" if fate == "broken" else "T3")
            v, ld = vary(rng, v0, l0)
            dead = role == "monitored" and r in SENSOR_FAULT_FROM and i - 12 >= SENSOR_FAULT_FROM[r]
            X.append(np.zeros(L) if dead else _life_record(rng, fp, v, ld, fate, size))
            y.append(state)
            vals = (r, role, v, ld, "train" if r < TRAIN else "test", len(X) - 1, int(i), day, fate,
                    np.nan if onset is None else onset, np.nan if failure is None else failure,
                    "dead" if dead else "", size, day * 1e4)
            for k, val in zip(meta, vals):
                meta[k].append(val)
    return np.array(X), y, {k: np.array(v) for k, v in meta.items()}


@pytest.fixture(scope="module")
def life(tmp_path_factory):
    from rvdiag.datasets import SampleStore
    from rvdiag.monitoring import train_monitor

    d = tmp_path_factory.mktemp("life")
    X, y, meta = life_store_records()
    write_store(d / "life.zarr", X, y, meta, kind="simulated", fs=FS, config={"synthetic": "life"},
                extra_attrs=params_attrs())
    plain = {k: v for k, v in meta.items() if not k.startswith("life.")}
    write_store(d / "paired.zarr", X, y, plain, kind="simulated", fs=FS,
                config={"synthetic": "paired"}, extra_attrs=params_attrs())
    said = []
    train_monitor(SampleStore.open(d / "life.zarr"), d / "life.zarr", d / "monitor", features=None, alpha=0.05,
                  seed=0, echo=said.append)
    return {"dir": d, "store": d / "life.zarr", "paired": d / "paired.zarr", "model": d / "monitor", "meta": meta,
            "said": said}


def test_training_leaves_sensor_fault_records_out(life):
    n = N_MON - SENSOR_FAULT_FROM[7]
    assert f"on {TRAIN * N_MON - n} monitored records" in life["said"][0]
    assert f"{n} window(s) with a sensor fault (life.sensor_fault) left out" in life["said"][0]


def test_evaluate_life_gives_per_reducer_and_pooled_figures(life, capsys):
    code, out, err = run_cli(["evaluate", life["model"], life["store"], "--split", "test", "--life", "--json"],
                             capsys)
    assert code == 0, err
    res = json.loads(out)
    lf = res["life"]
    assert set(lf["per_reducer"]) == {"8", "9", "10", "11"} and lf["split"] == "test"
    p = lf["pooled"]
    assert p["fates"] == {"broken": 1, "healthy": 2, "wear": 1}
    for key in ("lifetime_false_alarm", "detection_delay_records", "detected_within_3", "rul_coverage_80",
                "alpha_lambda", "baseline"):
        assert key in p and key in lf["per_reducer"]["9"]
    assert p["lifetime_false_alarm"]["n"] == 2 and p["lifetime_false_alarm"]["bound"] == 0.01
    assert set(p["detection_delay_records"]) == {"T2", "T3"}
    assert p["alpha_lambda"]["alpha"] == 0.2 and p["alpha_lambda"]["lambda"] == 0.5
    # reducer 9's wear starts on its record of day 28 at size 0 (state T1): its first T3 record is the next one
    t3 = p["detection_delay_records"]["T3"]
    assert t3["from_first_faulty_record"]["n"] == 1 and t3["from_first_faulty_record"]["median"] == t3["median"] - 1
    assert set(p["baseline"]) >= {"rul_coverage_80", "alpha_lambda", "method"}
    # the sensor-fault records of reducer 11 are left out, of the life figures and of the per-record ones
    assert p["n_records_left_out"] == N_MON - SENSOR_FAULT_FROM[11]
    assert lf["per_reducer"]["11"]["outcome"]["n_records"] == SENSOR_FAULT_FROM[11]
    assert res["n_sensor_fault_samples_left_out"] == N_MON - SENSOR_FAULT_FROM[11]
    assert res["n_samples"] == 4 * N_MON - (N_MON - SENSOR_FAULT_FROM[11])
    # the threshold: learned from the training reducers of each fate that reach their failure time
    t = lf["threshold"]
    assert set(t["per_state"]) == {"T3"} and t["per_state"]["T3"]["fate"] == "wear"
    assert t["per_state"]["T3"]["n_reducers"] == 3 and t["per_state"]["T3"]["index"] > t["reference_level"] > 0
    # the population the remaining life draws from, and its median
    assert len(t["per_state"]["T3"]["values"]) == 3
    assert t["per_state"]["T3"]["index"] == pytest.approx(float(np.median(t["per_state"]["T3"]["values"])))
    assert "train split" in t["source"]
    json.dumps(res, allow_nan=False)
    # the CLI hands evaluate_life the records evaluate_monitor has already scored: the same figures as its own
    from rvdiag.datasets import SampleStore
    from rvdiag.monitoring import evaluate_life
    from rvdiag.workflows import load_model

    own = evaluate_life(load_model(life["model"]), SampleStore.open(life["store"]), life["store"])
    assert json.loads(json.dumps(own)) == lf


def test_evaluate_life_follows_life_record_order(life):
    """The health index per reducer comes out in life.record order although the store holds each reducer's records
    shuffled: the broken reducer's index is low on every record before its onset and high on every one after."""
    from rvdiag.datasets import SampleStore
    from rvdiag.monitoring.life import _monitored, _records, life_histories
    from rvdiag.monitoring.pairing import baseline_records
    from rvdiag.workflows import load_model

    model, store = load_model(life["model"]), SampleStore.open(life["store"])
    rec = _records(model.estimator, _monitored(store, "test", "s"), baseline_records(store), FS, FS,
                   model.card.get("baseline"), "s")
    h = {x.name: x for x in life_histories(rec, None, None)}["10"]
    assert h.fate == "broken" and h.state == "T2" and h.onset_days == 45.0
    days, score, _ = h.stream()
    assert np.all(np.diff(days) == INTERVAL)
    before, after = score[days < 45.0], score[days >= 45.0]
    assert len(before) == 6 and before.max() < after.min(), (before, after)


def test_evaluate_life_human_output(life, capsys):
    code, out, err = run_cli(["evaluate", life["model"], life["store"], "--life"], capsys)
    assert code == 0, err
    assert "life (4 held-out histories" in out and "healthy histories ever alarming" in out
    assert "linear extrapolation: 80 % interval" in out and "the monitor's alarm, 3 of 3 records" in out


@pytest.mark.parametrize("extra, msg", [
    ([], "has no life-history columns (life.record, life.time_days, life.fate"),
    (["--where", "load_Nm>0"], "--life scores whole histories of a life store against its own commissioning "
                               "records: drop --where"),
])
def test_evaluate_life_refuses_in_one_line(life, capsys, extra, msg):
    store = life["paired"] if not extra else life["store"]
    code, out, err = run_cli(["evaluate", life["model"], store, "--life", *extra], capsys)
    assert code == 2 and err.startswith("error: ") and msg in err and err.count("\n") == 1, err


def test_evaluate_life_refuses_a_baseline_store(life, capsys):
    code, out, err = run_cli(["evaluate", life["model"], life["store"], "--life", "--baseline", life["paired"]],
                             capsys)
    assert code == 2 and "drop --baseline" in err and err.count("\n") == 1


# ------------------------------------------------------------------- a life store built by the library's plan
LIFE_CONFIG = {
    "mode": "split-by-simulation", "seed": 4, "simulator": "rvdiag.library.synthetic:simulate",
    "signal": {"fs": 4000.0, "duration_s": 0.5, "transient_s": 0.05, "segment_length": 1000, "hop": 1000},
    "operation": {"output_speed_deg_s": 45.0, "load_Nm": {"min": 50.0, "max": 130.0}, "noise_snr_db": 20.0,
                  "noise_mode": "floor"},
    "randomise": {"stiffness_pct": 10.0, "damping_pct": 10.0, "specimen": True,
                  "path_resonance_hz": {"min": 1500.0, "max": 9000.0}},
    "baseline": {"operating_points": [[45.0, 50.0], [45.0, 130.0]], "records_per_point": 3},
    "split": {"reducers": 10, "test_reducers": 4},
    "history": {"records": 12, "interval_days": 14.0, "sensor_fault_share": 0.3, "onset_days": {"min": 7, "max": 35},
                "crack_days": {"min": 40, "max": 80}, "wear_coefficient": {"min": 1e-16, "max": 2e-16},
                "fates": {"healthy": 0.3, "wear": 0.3, "crack": 0.2, "broken": 0.2}},
}


def test_evaluate_life_on_a_store_the_library_builds(tmp_path, capsys):
    """``rvdiag library`` life plan (synthetic simulator) -> ``train`` -> ``evaluate --life``: the life figures of
    each held-out reducer, its fate and its sensor-fault records as the store's columns say, and the threshold of
    the training reducers that reach failure (seed 4 draws: held out a crack and a healthy reducer whose sensors
    fail, a broken tooth, a healthy reducer; in training wear and a crack that reach failure; about 20 s)."""
    from rvdiag.datasets import SampleStore
    from rvdiag.library import LibraryConfig, build_library

    path = tmp_path / "life.zarr"
    build_library(LibraryConfig.from_dict(LIFE_CONFIG, source="life.toml"), path, workers=0, progress=False)
    code, out, err = run_cli(["train", path, "-o", tmp_path / "m", "--alpha", "0.05", "-q"], capsys)
    assert code == 0, err
    code, out, err = run_cli(["evaluate", tmp_path / "m", path, "--split", "test", "--life", "--json"], capsys)
    assert code == 0, err
    life = json.loads(out)["life"]
    m = SampleStore.open(path).meta
    test = (m["split"] == "test") & (m["role"] == "monitored")
    reducers = {str(r) for r in np.unique(m["reducer"][test])}
    assert set(life["per_reducer"]) == reducers and len(reducers) == 4
    for r in reducers:
        rows = test & (m["reducer"].astype(str) == r)
        assert life["per_reducer"][r]["fates"] == {str(m["life.fate"][rows][0]): 1}
        dead = len(np.unique(m["unit"][rows & (m["life.sensor_fault"].astype(str) != "")]))
        assert life["per_reducer"][r]["n_records_left_out"] == dead
        assert life["per_reducer"][r]["outcome"]["n_records"] == 12 - dead
    p = life["pooled"]
    assert p["n_histories"] == 4 and p["lifetime_false_alarm"]["bound"] == 0.01
    assert p["fates"] == {"broken": 1, "crack": 1, "healthy": 2} and p["n_records_left_out"] > 0
    assert set(p["detection_delay_records"]) == {"T2", "T4"}
    t = life["threshold"]
    assert {"T3", "T4"} <= set(t["per_state"]) and t["*"]["n_reducers"] >= 2 and t["reference_level"] > 0


def test_a_state_with_too_few_training_records_is_refused_in_words():
    """A state with 2 training records (e.g. once a life store's sensor-fault records are left out) cannot be
    calibrated 3-fold: a ParameterError naming it, not scikit-learn's traceback."""
    from rvdiag.monitoring import BaselineMonitor

    rng = np.random.default_rng(0)
    D = rng.normal(size=(24, 3))
    y = np.array(["T1"] * 18 + ["T2"] * 4 + ["T3"] * 2)
    with pytest.raises(ParameterError, match="the state T3 has 2 training record"):
        BaselineMonitor(alpha=0.1).fit(D, y, groups=np.arange(24) % 6)


def test_evaluate_life_refuses_a_classifier(life, capsys, tmp_path):
    """A classifier has no health index to watch over a life."""
    X, y, meta = life_store_records()
    plain = {k: v for k, v in meta.items() if k in ("output_speed_deg_s", "load_Nm", "split", "unit")}
    write_store(tmp_path / "plain.zarr", X, y, plain, kind="simulated", fs=FS, config={"synthetic": "plain"},
                extra_attrs=params_attrs())
    code, out, err = run_cli(["train", tmp_path / "plain.zarr", "-o", tmp_path / "clf", "--model", "svm",
                              "--features", "time", "-q"], capsys)
    assert code == 0, err
    code, out, err = run_cli(["evaluate", tmp_path / "clf", life["store"], "--life"], capsys)
    assert code == 2 and "--life scores a baseline-referenced model" in err and err.count("\n") == 1, err
