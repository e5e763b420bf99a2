"""What `make demo` (examples/demo.py) prints after its evaluation: never an accuracy alone, and the crack-free
decision beside the six states, with one line saying why."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from rvdiag.evaluation.evaluate import Evaluation, merged_metrics
from rvdiag.evaluation.metrics import classification_metrics

ROOT = Path(__file__).resolve().parents[1]
LABELS = ["T1", "T2", "T3", "T4", "T5", "T6"]


def _demo():
    spec = importlib.util.spec_from_file_location("demo_example", ROOT / "examples" / "demo.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _metrics(merge: bool) -> dict:
    # 10 samples per state; half the healthy ones called cracked and half the cracked ones healthy (the crack
    # across specimens), T6 half called T5: the six states score 75 %, the crack-free decision 100 %
    y_true = np.repeat(LABELS, 10)
    y_pred = y_true.copy()
    y_pred[0:5] = "T4"
    y_pred[30:35] = "T1"
    y_pred[50:55] = "T5"
    m = classification_metrics(y_true, y_pred, labels=LABELS)
    if merge:
        ev = Evaluation(metrics=m, y_true=y_true, y_pred=y_pred, X=None, meta={}, split="test")
        m["merged"] = merged_metrics(ev, {"T4": "T1", "T6": "T5"}, LABELS)
    return m


def test_the_demo_prints_healthy_recall_and_the_crack_free_decision_with_its_reason():
    demo = _demo()
    lines = demo.summary_lines(_metrics(merge=True))
    assert lines[0].startswith("six states: accuracy 75.0 %, healthy recall 50.0 %, false-alarm rate 50.0 %")
    assert lines[1] == "recall T1 50.0 %, T2 100.0 %, T3 100.0 %, T4 50.0 %, T5 100.0 %, T6 50.0 %"
    assert lines[2] == ("crack-free decision (T4=T1,T6=T5): accuracy 100.0 %, healthy recall 100.0 %, "
                        "false-alarm rate 0.0 %")
    assert lines[3] == demo.CRACK_FREE_WHY and lines[3].startswith("why the crack-free decision:")
    assert len(lines) == 4


def test_without_the_merge_only_the_six_states_are_printed():
    lines = _demo().summary_lines(_metrics(merge=False))
    assert len(lines) == 2 and "healthy recall 50.0 %" in lines[0]


def test_the_demo_prints_the_prediction_sets_per_state():
    from rvdiag.models.conformal import set_metrics

    m = _metrics(merge=False)
    inside = np.zeros((60, 6), bool)
    inside[np.arange(60), np.repeat(np.arange(6), 10)] = True
    inside[:10, 3] = True  # the healthy samples' sets also hold T4
    m["sets"] = set_metrics(inside, np.repeat(LABELS, 10), LABELS, {c: 0.95 if c == "T1" else 0.9 for c in LABELS})
    lines = _demo().summary_lines(m)
    assert len(lines) == 3 and lines[2].startswith("prediction sets: coverage 100.0 % (stated 90.8 %), mean size 1.17")
    assert "T1 100.0 % of 95 % (size 2.00)" in lines[2]
