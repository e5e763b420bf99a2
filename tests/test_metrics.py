"""Classification metrics against hand-computed values."""

from __future__ import annotations

import numpy as np
import pytest

from rvdiag.evaluation.metrics import METRIC_KEYS, classification_metrics, repeat_summary


def test_hand_computed_three_class_case():
    y = ["T1"] * 4 + ["T2"] * 4 + ["T3"] * 2
    p = ["T1", "T1", "T1", "T2", "T2", "T2", "T2", "T2", "T3", "T1"]
    m = classification_metrics(y, p, labels=["T1", "T2", "T3"])
    assert set(METRIC_KEYS) <= set(m)
    assert m["confusion"] == [[3, 1, 0], [0, 4, 0], [1, 0, 1]]
    assert m["accuracy"] == pytest.approx(0.8)
    # precision: T1 3/4, T2 4/5, T3 1/1; recall: 3/4, 4/4, 1/2
    assert m["per_class"]["T1"]["precision"] == pytest.approx(0.75)
    assert m["per_class"]["T2"]["precision"] == pytest.approx(0.8)
    assert m["per_class"]["T3"]["recall"] == pytest.approx(0.5)
    assert m["precision_macro"] == pytest.approx((0.75 + 0.8 + 1.0) / 3)
    assert m["recall_macro"] == pytest.approx((0.75 + 1.0 + 0.5) / 3)
    f1 = [2 * 0.75 * 0.75 / 1.5, 2 * 0.8 / 1.8, 2 * 0.5 / 1.5]
    assert m["f1_macro"] == pytest.approx(np.mean(f1))
    # kappa: p_o = 0.8, p_e = sum(row_i * col_i) / n^2 = (4*4 + 4*5 + 2*1) / 100 = 0.38
    assert m["kappa"] == pytest.approx((0.8 - 0.38) / (1 - 0.38))
    assert m["per_class"]["T3"]["support"] == 2 and m["n_samples"] == 10


def test_perfect_and_chance():
    m = classification_metrics(["a", "b"] * 5, ["a", "b"] * 5)
    assert m["accuracy"] == m["kappa"] == m["f1_macro"] == 1.0
    m = classification_metrics(["a", "b"] * 5, ["a"] * 10)
    assert m["kappa"] == pytest.approx(0.0)
    assert m["per_class"]["b"]["precision"] == 0.0  # zero_division=0, no warning


def test_class_absent_from_truth_is_a_row_but_not_in_macro():
    m = classification_metrics(["a", "a"], ["a", "a"], labels=["a", "b"])
    assert m["confusion"] == [[2, 0], [0, 0]]
    assert m["recall_macro"] == 1.0


def test_bad_input():
    with pytest.raises(ValueError):
        classification_metrics(["a"], ["a", "b"])
    with pytest.raises(ValueError):
        classification_metrics([], [])


def test_repeat_summary_best_mean_worst():
    r1 = classification_metrics(["a", "a", "b", "b"], ["a", "a", "b", "b"])
    r2 = classification_metrics(["a", "a", "b", "b"], ["a", "b", "b", "b"])
    s = repeat_summary([r1, r2])
    assert s["n_runs"] == 2
    assert s["per_class"]["a"] == {"best": 1.0, "mean": 0.75, "worst": 0.5}
    assert s["per_class"]["b"]["mean"] == 1.0
    assert s["accuracy"]["mean"] == pytest.approx(0.875)
    with pytest.raises(ValueError):
        repeat_summary([])


def test_accuracy_by_snr_bins():
    from rvdiag.errors import StoreError
    from rvdiag.evaluation.evaluate import Evaluation, accuracy_by

    snr = np.linspace(-5, 20, 26)  # 26 distinct values -> 5 equal-width bins of 5 dB
    y = np.array(["a"] * 26)
    pred = np.where(snr >= 10, "a", "b")
    ev = Evaluation({}, y, pred, np.zeros((26, 2)), {"noise_snr_db": snr, "kind": np.array(["x"] * 26)}, "test")
    g = accuracy_by(ev, "noise_snr_db", n_bins=5)
    assert [(x["lo"], x["hi"], x["n"]) for x in g] == [(-5, 0, 5), (0, 5, 5), (5, 10, 5), (10, 15, 5), (15, 20, 6)]
    assert [x["accuracy"] for x in g] == [0.0, 0.0, 0.0, 1.0, 1.0]
    g = accuracy_by(Evaluation({}, y[:4], pred[:4], None, {"u": np.array([1, 1, 2, 2])}, "t"), "u")
    assert [(x["lo"], x["n"]) for x in g] == [(1.0, 2), (2.0, 2)]
    with pytest.raises(StoreError, match="no metadata column"):
        accuracy_by(ev, "speed")
    with pytest.raises(StoreError, match="not numeric"):
        accuracy_by(ev, "kind")
