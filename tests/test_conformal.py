"""Class-conditional split-conformal prediction sets (:mod:`rvdiag.models.conformal`): the finite-sample coverage
of each class over many seeds, against MAPIE, calibration on held-out groups, and the card round trip."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.stats import binom

from rvdiag.errors import ModelFileError, ParameterError
from rvdiag.models.card import read_card, write_card
from rvdiag.models.conformal import (PredictionSets, conformal_rank, conformal_threshold, describe_set, from_card,
                                     lac_scores, reducer_threshold, set_metrics, split_by_group, stated_coverages)

CLASSES = ["T1", "T2", "T4"]
MEANS = np.array([[0.0, 0.0], [1.2, 0.0], [0.4, 0.3]])  # T4 overlaps T1: the hard pair


def _proba(x: np.ndarray, prior=(1.0, 1.0, 1.0)) -> np.ndarray:
    """A fixed classifier (Gaussian class likelihoods times ``prior``): no fit, so calibration and test samples
    are exchangeable by construction."""
    d = ((x[:, None, :] - MEANS[None, :, :]) ** 2).sum(axis=2)
    e = np.exp(-0.5 * (d - d.min(axis=1, keepdims=True))) * np.asarray(prior)[None, :]
    return e / e.sum(axis=1, keepdims=True)


def _draw(rng, counts: dict[str, int], prior=(1.0, 1.0, 1.0)):
    y = np.concatenate([[c] * n for c, n in counts.items()])
    idx = np.asarray([CLASSES.index(c) for c in y])
    x = MEANS[idx] + rng.normal(size=(y.size, 2))
    return _proba(x, prior), y


def _band(p: float, trials: int, miss: float = 1e-5) -> tuple[float, float]:
    """The central binomial interval, of probability 1 - ``miss``, of a share of ``trials`` independent trials of
    success probability p."""
    lo, hi = binom.interval(1 - miss, trials, p)
    return lo / trials, hi / trials


def test_rank_and_stated_coverages():
    assert conformal_rank(19, 0.05) == 19 and conformal_rank(18, 0.05) == 19  # 18 samples: too few for 95 %
    assert stated_coverages(["T1", "T2"]) == {"T1": 0.95, "T2": 0.90}
    with pytest.raises(ParameterError):
        stated_coverages(["T1"], healthy_coverage=1.0)


def test_each_class_is_covered_exactly_at_its_finite_sample_level_over_many_seeds():
    """For continuous scores, P(c in set) = ceil((n_c + 1)(1 - alpha_c)) / (n_c + 1) exactly (Vovk 2012): one test
    sample per class per seed, 3000 seeds, unequal class counts (T1 95 %, faults 90 %)."""
    counts = {"T1": 40, "T2": 15, "T4": 25}
    cover = stated_coverages(CLASSES)
    seeds = 3000
    hits = {c: 0 for c in CLASSES}
    sizes = []
    for s in range(seeds):
        rng = np.random.default_rng([37, s])
        P, y = _draw(rng, counts)
        ps = PredictionSets.calibrate(P, y, CLASSES, cover)
        Pt, yt = _draw(rng, {c: 1 for c in CLASSES})
        inside = ps.contains(Pt, nonempty=False)
        for i, c in enumerate(yt):
            hits[c] += bool(inside[i, CLASSES.index(c)])
        sizes.append(inside.sum(axis=1).mean())
    for c, n in counts.items():
        exact = conformal_rank(n, 1 - cover[c]) / (n + 1)
        assert exact >= cover[c]
        lo, hi = _band(exact, seeds)
        assert lo <= hits[c] / seeds <= hi, (c, hits[c] / seeds, exact)
    assert 1.0 < np.mean(sizes) < 3.0  # the overlap of T1 and T4 gives sets of two, not every set is full


def test_class_conditional_holds_where_marginal_calibration_fails():
    """A rare hard class (its prior a tenth of the others', as a classifier trained on its share learns): one
    marginal quantile (all classes pooled) under-covers it; Mondrian does not."""
    counts, prior = {"T1": 600, "T2": 600, "T4": 60}, (1.0, 1.0, 0.1)
    rng = np.random.default_rng(5)
    P, y = _draw(rng, counts, prior)
    Pt, yt = _draw(rng, {"T1": 4000, "T2": 4000, "T4": 4000}, prior)
    ps = PredictionSets.calibrate(P, y, CLASSES, {c: 0.9 for c in CLASSES})
    per = set_metrics(ps.contains(Pt), yt, CLASSES, ps.coverage)["per_state"]
    marginal = np.quantile(lac_scores(P, y, CLASSES), conformal_rank(y.size, 0.1) / y.size, method="lower")
    t4 = yt == "T4"
    marginal_t4 = float(np.mean(1 - Pt[t4, 2] <= marginal))
    assert per["T4"]["coverage"] >= 0.9 - 0.03 and marginal_t4 < 0.85, (per["T4"], marginal_t4)


def test_same_sets_as_mapie_split_conformal_per_class():
    """MAPIE's SplitConformalClassifier (LAC, prefit) conformalized on each class's calibration samples alone, at
    that class's level, is the Mondrian set: its membership of class c must be ours."""
    mapie = pytest.importorskip("mapie.classification")  # a test extra (pyproject.toml); present in CI
    from sklearn.base import BaseEstimator, ClassifierMixin

    class Given(ClassifierMixin, BaseEstimator):  # the "model": its input is already the probabilities
        def fit(self, X, y):
            self.classes_ = np.asarray(CLASSES)
            self.n_features_in_ = len(CLASSES)
            return self

        def predict_proba(self, X):
            return np.asarray(X)

        def predict(self, X):
            return self.classes_[np.asarray(X).argmax(axis=1)]

    rng = np.random.default_rng(11)
    P, y = _draw(rng, {"T1": 57, "T2": 33, "T4": 41})
    Pt, _ = _draw(rng, {"T1": 300, "T2": 300, "T4": 300})
    cover = stated_coverages(CLASSES)
    ps = PredictionSets.calibrate(P, y, CLASSES, cover)
    ours = ps.contains(Pt, nonempty=False)

    est = Given().fit(P, y)
    for j, c in enumerate(CLASSES):
        m = mapie.SplitConformalClassifier(estimator=est, confidence_level=cover[c], conformity_score="lac",
                                           prefit=True)
        m.conformalize(P[y == c], y[y == c])
        theirs = m.predict_set(Pt)[1][:, j, 0]
        assert np.array_equal(theirs, ours[:, j]), c


def _reducers(rng, n_reducers: int, windows: int, spread: float):
    """Windows of simulated reducers: each reducer of a class has its own offset (its manufacturing errors), so
    windows of one reducer are alike and unlike another's."""
    xs, ys, gs = [], [], []
    for c_i, c in enumerate(CLASSES):
        for r in range(n_reducers):
            offset = rng.normal(scale=spread, size=2)
            xs.append(MEANS[c_i] * 2.5 + offset + 0.3 * rng.normal(size=(windows, 2)))
            ys += [c] * windows
            gs += [f"{c}-{r}"] * windows
    return np.concatenate(xs), np.asarray(ys), np.asarray(gs)


def test_calibration_on_held_out_reducers_covers_new_reducers_and_on_training_reducers_does_not():
    """A model that learns its training reducers (nearest neighbours) is over-confident on them: calibrated on their
    windows its sets miss on new reducers; calibrated on reducers it did not train on (split_by_group), they cover."""
    from sklearn.neighbors import KNeighborsClassifier

    rng = np.random.default_rng(3)
    X, y, g = _reducers(rng, n_reducers=40, windows=12, spread=1.0)
    cal = split_by_group(y, g, 0.5, seed=0)
    assert not set(g[cal]) & set(g[~cal])  # whole reducers
    knn = KNeighborsClassifier(n_neighbors=5).fit(X[~cal], y[~cal])
    assert list(knn.classes_) == CLASSES
    Xn, yn, _ = _reducers(rng, n_reducers=150, windows=12, spread=1.0)  # reducers nobody trained on
    cover = {c: 0.9 for c in CLASSES}
    held = PredictionSets.calibrate(knn.predict_proba(X[cal]), y[cal], CLASSES, cover, groups=g[cal])
    seen = PredictionSets.calibrate(knn.predict_proba(X[~cal]), y[~cal], CLASSES, cover, groups=g[~cal])
    Pn = knn.predict_proba(Xn)
    got_held = set_metrics(held.contains(Pn), yn, CLASSES, cover)
    got_seen = set_metrics(seen.contains(Pn), yn, CLASSES, cover)
    assert held.n_groups == {c: 20 for c in CLASSES}
    assert got_held["coverage"] >= 0.9 - 0.04, got_held
    assert got_seen["coverage"] < got_held["coverage"] - 0.05, (got_seen, got_held)


def test_a_new_reducer_is_covered_by_the_reducer_rule_and_not_by_the_window_rule():
    """Known answer: K = 12 reducers of N = 20 windows, each reducer's windows sharing its score (a reducer effect,
    continuous, exchangeable across reducers).  A new reducer's window is covered iff its effect is at most the
    threshold's reducer of rank r among the K, probability r / (K + 1).  Window-pooled: rank ceil((N K + 1) 0.9) =
    217 of the windows, the 11th reducer, 11/13 = 0.846 < 0.9; hierarchical (Lee, Barber & Willett 2023): rank
    ceil(N (K + 1) 0.9) = 234, the 12th reducer, 12/13 = 0.923 >= 0.9.  Through PredictionSets over 3000 seeds."""
    K, N, seeds = 12, 20, 3000
    classes = ["T1", "T2"]
    cover = {"T1": 0.95, "T2": 0.9}
    hits = {"windows": 0, "reducers": 0}
    g = np.repeat(np.arange(K), N)
    y = np.full(K * N, "T2")
    for seed in range(seeds):
        rng = np.random.default_rng([38, seed])
        effect = rng.uniform(size=K + 1)
        s = np.repeat(effect[:K], N)
        P = np.column_stack([s, 1.0 - s])  # LAC score of T2: 1 - p_T2 = s
        new = np.array([[effect[K], 1.0 - effect[K]]])
        for rule in hits:
            ps = PredictionSets.calibrate(P, y, classes, cover, groups=g, rule=rule)
            hits[rule] += bool(ps.contains(new, nonempty=False)[0, 1])
    exact = {"windows": 11 / 13, "reducers": 12 / 13}
    for rule, h in hits.items():
        lo, hi = _band(exact[rule], seeds)
        assert lo <= h / seeds <= hi, (rule, h / seeds, exact[rule])
    assert exact["windows"] < 0.9 <= exact["reducers"]


def test_reducer_threshold_is_the_weighted_quantile_with_its_mass_at_infinity():
    """Against the definition, by enumeration: the smallest calibration score t with sum over scores <= t of
    1 / ((K + 1) N_k) >= 1 - alpha, else inf; reducers of unequal sizes; and with equal sizes the rank
    ceil(N (K + 1)(1 - alpha))."""
    rng = np.random.default_rng(2)
    for _ in range(50):
        K = int(rng.integers(3, 30))
        sizes = rng.integers(1, 9, size=K)
        g = np.repeat(np.arange(K), sizes)
        s = rng.normal(size=g.size)
        alpha = float(rng.uniform(0.02, 0.3))
        w = 1.0 / ((K + 1) * sizes[g])
        ok = [t for t in np.sort(s) if w[s <= t].sum() >= 1 - alpha - 1e-12]
        assert reducer_threshold(s, g, alpha) == (ok[0] if ok else math.inf)
    g = np.repeat(np.arange(9), 4)
    s = rng.normal(size=36)
    assert reducer_threshold(s, g, 0.1) == np.sort(s)[math.ceil(4 * 10 * 0.9) - 1]
    assert reducer_threshold(s, np.repeat(np.arange(8), [5, 5, 5, 5, 4, 4, 4, 4]), 0.1) == math.inf  # 8 < 9
    assert conformal_threshold(s, 0.1) < math.inf  # 36 windows would have sufficed for the window rule
    with pytest.raises(ParameterError):
        PredictionSets.calibrate(np.full((2, 2), 0.5), ["T1", "T2"], ["T1", "T2"], rule="reducers")
    with pytest.raises(ParameterError):
        PredictionSets.calibrate(np.full((2, 2), 0.5), ["T1", "T2"], ["T1", "T2"], groups=[0, 1], rule="x")


def test_split_by_group_holds_out_whole_groups_of_each_class_reproducibly():
    y = np.repeat(["T1", "T2", "T3"], [60, 60, 5])
    g = np.concatenate([np.repeat(np.arange(10), 6), np.repeat(np.arange(10), 6), np.zeros(5, int)])
    cal = split_by_group(y, g, 0.2, seed=4)
    assert np.array_equal(cal, split_by_group(y, g, 0.2, seed=4))
    for c in ("T1", "T2"):  # 2 of 10 reducers each; the same reducer name under two classes is two reducers
        m = y == c
        assert np.unique(g[m & cal]).size == 2 and not set(g[m & cal]) & set(g[m & ~cal])
    assert not cal[y == "T3"].any()  # one reducer: kept for training
    with pytest.raises(ParameterError):
        split_by_group(y, g, 0.0, seed=0)


def test_too_few_samples_keep_the_class_in_every_set():
    rng = np.random.default_rng(0)
    P, y = _draw(rng, {"T1": 10, "T2": 10, "T4": 10})
    ps = PredictionSets.calibrate(P, y, CLASSES)  # T1 at 95 % needs 19
    assert ps.too_few() == ["T1"] and ps.contains(P)[:, 0].all()


def test_prediction_set_order_and_words():
    ps = PredictionSets(CLASSES, {"T1": 0.95, "T2": 0.9, "T4": 0.9}, {"T1": 0.8, "T2": 0.5, "T4": 0.9},
                        {c: 50 for c in CLASSES})
    assert ps.prediction_set([0.3, 0.1, 0.6]) == [["T4", "T1"]]
    assert ps.prediction_set([[0.05, 0.9, 0.05]]) == [["T2"]]
    P = np.array([[0.1, 0.45, 0.05], [0.3, 0.1, 0.6]])  # the first passes no threshold: its most probable state
    assert not ps.contains(P, nonempty=False)[0].any() and ps.prediction_set(P) == [["T2"], ["T4", "T1"]]
    names = {"T1": "healthy", "T4": "root crack"}.get
    assert describe_set(["T1", "T4"], 0.95, names) == ("healthy or root crack (95 % set): this model cannot tell "
                                                       "them apart on a reducer it has not seen")
    assert describe_set(["T2"], 0.9) == "T2 (90 % set)"


def test_set_metrics_counts_coverage_and_size_per_state():
    inside = np.array([[1, 0, 1], [0, 1, 0], [1, 1, 1], [0, 0, 1]], dtype=bool)
    m = set_metrics(inside, ["T1", "T2", "T1", "T1"], CLASSES, {"T1": 0.95, "T2": 0.9, "T4": 0.9})
    assert m["coverage"] == 0.75 and m["mean_size"] == 1.75 and m["singletons"] == 0.5
    assert m["per_state"]["T1"] == {"n": 3, "stated_coverage": 0.95, "coverage": 2 / 3, "mean_size": 2.0}
    assert "T4" not in m["per_state"] and math.isclose(m["stated_coverage"], (3 * 0.95 + 0.9) / 4)


def test_card_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    P, y = _draw(rng, {"T1": 10, "T2": 30, "T4": 30})
    ps = PredictionSets.calibrate(P, y, CLASSES, groups=np.arange(y.size) // 5,
                                  source={"method": "split", "held_out_reducers": 3})
    write_card(tmp_path, {"kind": "classical", "classes": CLASSES, "input_length": 8,
                          "prediction_sets": ps.to_card()})
    back = from_card(read_card(tmp_path))
    assert back == ps and math.isinf(back.thresholds["T1"])
    assert json.loads((tmp_path / "card.json").read_text())["prediction_sets"]["thresholds"]["T1"] is None
    assert from_card({"classes": CLASSES}) is None  # a model trained before: no calibration, no failure
    hier = PredictionSets.calibrate(P, y, CLASSES, groups=np.arange(y.size), rule="reducers")
    assert PredictionSets.from_card(hier.to_card()) == hier and hier.to_card()["rule"] == "reducers"
    old = {k: v for k, v in ps.to_card().items() if k != "rule"}  # a card written before the rule was stored
    assert PredictionSets.from_card(old).rule == "windows"
    with pytest.raises(ModelFileError):
        from_card({"classes": ["T1", "T2"], "prediction_sets": ps.to_card()})
    with pytest.raises(ModelFileError):
        from_card({"classes": CLASSES, "prediction_sets": {"classes": CLASSES}})


# --- train -> evaluate -> diagnose (a small classical model on a store of tones, whole reducers per unit) ---

FS, L = 1000.0, 128


def _tone(c: int, rng) -> np.ndarray:
    t = np.arange(L) / FS
    return np.sin(2 * np.pi * (60 + 40 * c) * t + rng.uniform(0, 6)) + 0.8 * rng.standard_normal(L)


@pytest.fixture(scope="module")
def tone_store(tmp_path_factory):
    from rvdiag.datasets import write_store

    rng = np.random.default_rng(0)
    X, y, split, unit = [], [], [], []
    for c in range(3):
        for r in range(44):  # 40 training reducers and 4 test reducers per state, 2 windows each
            for _ in range(2):
                X.append(_tone(c, rng))
                y.append(f"T{c + 1}")
                split.append("test" if r >= 40 else "train")
                unit.append(c * 1000 + r)
    p = tmp_path_factory.mktemp("conformal") / "tones.zarr"
    write_store(p, np.asarray(X, np.float32), y, meta={"split": split, "unit": unit},
                kind="simulated", fs=FS, config={"name": "tones"})
    return p


@pytest.fixture(scope="module")
def tone_model(tone_store, tmp_path_factory):
    from rvdiag.cli import main

    out = tmp_path_factory.mktemp("conformal") / "model"
    try:
        main([str(a) for a in ["train", tone_store, "--model", "svm", "--features", "spectrum", "--out", out,
                               "--seed", "0", "--quiet", "--calibration", "split", "--calibration-fraction", "0.25"]])
    except SystemExit as exc:  # pragma: no cover - a failure shows here
        assert exc.code == 0
    return out


def test_train_calibrates_on_held_out_training_reducers(tone_model, tone_store):
    from rvdiag.datasets import SampleStore

    card = read_card(tone_model)
    ps = from_card(card)
    assert ps.coverage == {"T1": 0.95, "T2": 0.9, "T3": 0.9}
    assert ps.n_groups == {c: 10 for c in ("T1", "T2", "T3")} and ps.n_calibration == {c: 20 for c in ps.classes}
    assert not ps.too_few() and ps.source["refit"] is False
    store = SampleStore.open(tone_store)
    units = np.asarray(store.meta["unit"])
    held = {int(u) for us in ps.source["held_out_reducers"].values() for u in us}
    assert held <= set(units[np.asarray(store.meta["split"]) == "train"].tolist())
    assert card["training_store"]["n_train"] == 3 * 40 * 2  # the training split; the fit saw 30 reducers a state


def test_evaluate_and_diagnose_give_sets(tone_model, tone_store, tmp_path, capsys):
    from conftest import run_cli as run

    from rvdiag.evaluation.report import sets_section

    code, out, err = run(["evaluate", tone_model, tone_store, "--json"], capsys)
    assert code == 0, err
    sets = json.loads(out)["sets"]
    assert set(sets["per_state"]) == {"T1", "T2", "T3"} and sets["n"] == 24
    for v in sets["per_state"].values():
        assert set(v) >= {"stated_coverage", "coverage", "mean_size"} and 0.0 <= v["mean_size"] <= 3.0
    assert math.isclose(sets["stated_coverage"], (0.95 + 0.9 + 0.9) / 3)
    html = sets_section(sets, None)
    assert "Prediction sets" in html and "mean set size" in html and html.count("<tr") == 5  # head, 3 states, all
    assert "trained before" in sets_section(None, "no prediction sets: trained before")
    code, out, err = run(["evaluate", tone_model, tone_store], capsys)
    assert code == 0 and "prediction sets: coverage" in out
    x = np.concatenate([_tone(1, np.random.default_rng(s)) for s in range(4)])
    f = tmp_path / "rec.npy"
    np.save(f, x)
    code, out, err = run(["diagnose", tone_model, str(f), "--fs", str(FS), "--json"], capsys)
    assert code == 0, err
    res = json.loads(out)
    assert res["set"] and res["set_coverage"] == 0.9 and res["set_coverage_per_state"]["T1"] == 0.95
    assert res["set_state"] == (res["set"][0] if len(res["set"]) == 1 else None)
    assert all("set" in w for w in res["windows"]) and "90 % set" in res["set_text"]


def test_a_model_without_calibration_says_so(tone_model, tone_store, tmp_path, capsys):
    import shutil

    from conftest import run_cli as run

    old = tmp_path / "old"
    shutil.copytree(tone_model, old)
    card = json.loads((old / "card.json").read_text())
    del card["prediction_sets"]
    (old / "card.json").write_text(json.dumps(card))
    code, out, err = run(["evaluate", old, tone_store, "--json"], capsys)
    assert code == 0, err
    m = json.loads(out)
    assert m["sets"] is None and "before rvdiag stored a conformal calibration" in m["sets_note"]
    f = tmp_path / "rec.npy"
    np.save(f, _tone(0, np.random.default_rng(1)))
    code, out, err = run(["diagnose", old, str(f), "--fs", str(FS)], capsys)
    assert code == 0 and "no prediction set" in out, err


def test_train_holds_nothing_out_when_a_state_would_get_too_few_calibration_samples():
    from types import SimpleNamespace

    from rvdiag.workflows.training import calibration_split

    y = np.repeat(["T1", "T2"], 40)
    tr = SimpleNamespace(y=y, meta={"unit": np.arange(80) // 2})  # 20 reducers of 2 windows a state
    cover = {"T1": 0.95, "T2": 0.9}
    held, note = calibration_split(tr, 0.2, 0, cover)  # 4 reducers, 8 windows: T1 needs 19
    assert held is None and "8 held-out sample(s) of T1, fewer than the 19" in note
    held, note = calibration_split(tr, 0.5, 0, cover)
    assert note is None and held.sum() == 40
    assert calibration_split(SimpleNamespace(y=y, meta={}), 0.2, 0, cover)[0] is None


def test_group_folds_put_reducers_of_every_class_in_every_fold():
    from rvdiag.models.conformal import group_folds

    y = np.repeat(["T1", "T2"], 30)
    g = np.arange(60) // 3  # 10 reducers a class
    f = group_folds(y, g, 3, seed=1)
    assert np.array_equal(f, group_folds(y, g, 3, seed=1))
    for k in range(3):
        for c in ("T1", "T2"):
            assert 3 <= np.unique(g[(f == k) & (y == c)]).size <= 4
    assert all(np.unique(f[g == r]).size == 1 for r in np.unique(g))  # a reducer never split between folds
    with pytest.raises(ParameterError):
        group_folds(y, g, 11, seed=1)


def test_train_cross_calibrates_on_every_training_reducer(tone_store, tmp_path, capsys):
    from conftest import run_cli as run

    out = tmp_path / "cross"
    code, _, err = run(["train", tone_store, "--model", "svm", "--features", "spectrum", "--out", out, "--seed", "0",
                        "--calibration", "cross", "--calibration-folds", "3"], capsys)
    assert code == 0, err
    card = read_card(out)
    ps = from_card(card)
    assert ps.source["method"] == "cross" and ps.source["refit"] is True and ps.source["folds"] == 3
    assert ps.n_calibration == {c: 80 for c in ps.classes} and ps.n_groups == {c: 40 for c in ps.classes}
    assert card["training_store"]["n_train"] == 240
    code, text, err = run(["evaluate", out, tone_store, "--json"], capsys)
    assert code == 0 and json.loads(text)["sets"]["n"] == 24, err
    code, _, err = run(["train", tone_store, "--out", tmp_path / "x", "--calibration", "both"], capsys)
    assert code == 2 and "--calibration must be split or cross" in err
