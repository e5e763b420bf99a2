"""The joint-state rules (:mod:`rvdiag.fleet.rules`): properties of the replay (hypothesis), the conformal p-value
within a joint, and the stated false-alarm rate against closed forms and a simulation of the replay itself."""

from __future__ import annotations

import math
from datetime import datetime, timedelta, timezone

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rvdiag.errors import FleetError
from rvdiag.fleet.rules import (Item, Rules, conformal_p_value, false_alarms_per_year, raise_probability_per_record,
                                replay)

T0 = datetime(2026, 1, 1, tzinfo=timezone.utc)


def items_of(scores, recognised=None, acks=()):
    """Records of the given health indices, one an hour (None: not recognised), and acknowledgements at hours."""
    out = [Item(time=T0 + timedelta(hours=i), key=i, health_index=s, monitor_alarm=s is not None and s > 3,
                recognised=s is not None) for i, s in enumerate(scores)]
    out += [Item(time=T0 + timedelta(hours=h, minutes=30), kind="ack", key=f"ack{h}") for h in acks]
    return out


rules_st = st.builds(lambda k, extra, m, learning: Rules(alpha=0.2, k=k, n=k + extra, m=m, learning=learning),
                     st.integers(1, 4), st.integers(0, 3), st.integers(1, 5), st.integers(4, 12))
scores_st = st.lists(st.one_of(st.none(), st.floats(0, 10, allow_nan=False)), min_size=0, max_size=60)


@settings(max_examples=150, deadline=None)
@given(rules_st, scores_st)
def test_a_record_not_recognised_never_counts_either_way(rules, scores):
    """Leaving the unrecognised records out gives the recognised ones the same steps."""
    steps = replay(items_of(scores), rules)
    kept = [s for s in scores if s is not None]
    alone = replay(items_of(kept), rules)
    mixed = [st_ for st_, s in zip(steps, scores) if s is not None]
    assert [(a.state, a.record_alarm, a.events) for a in mixed] == [(b.state, b.record_alarm, b.events) for b in alone]
    assert all(st_.state == "sensor-fault" and st_.record_alarm is None for st_, s in zip(steps, scores) if s is None)


@settings(max_examples=150, deadline=None)
@given(rules_st, scores_st, st.sets(st.integers(0, 60), max_size=5))
def test_alarm_needs_k_of_n_and_latches_until_acknowledged(rules, scores, acks):
    """A model of the rules beside the replay: raised only on k of the last n, acknowledged only when open,
    cleared only once acknowledged, and the state is ``alarm`` exactly while raised and not cleared."""
    window, in_alarm, acked = [], False, False
    for s in replay(items_of(scores, acks=sorted(acks)), rules):
        if s.record_alarm is not None and not s.learning:
            window = (window + [s.record_alarm])[-rules.n:]
        if "raised" in s.events:
            assert sum(window) >= rules.k and not in_alarm
            in_alarm, acked = True, False
        if "acknowledged" in s.events:
            assert in_alarm and not acked
            acked = True
        if "cleared" in s.events:
            assert in_alarm and acked
            in_alarm, window = False, []
        if s.kind == "record" and s.record_alarm is not None:
            assert (s.state == "alarm") == in_alarm
            assert s.open_alarm == (in_alarm and not acked)
            if not in_alarm and sum(window) >= rules.k:
                raise AssertionError("k of n alarmed and no alarm is raised")


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-5, 5, allow_nan=False), min_size=1, max_size=40), st.floats(-6, 6, allow_nan=False))
def test_the_conformal_p_value_is_a_rank(calib, s):
    p = conformal_p_value(calib, s)
    n = len(calib)
    assert 1 / (n + 1) <= p <= 1
    assert p == pytest.approx((1 + sum(c >= s for c in calib)) / (n + 1))
    assert conformal_p_value(calib, s + 1) <= p  # a larger index is never less surprising


def test_learning_uses_the_monitor_then_the_joint_ranks_its_own():
    r = Rules(alpha=0.25, k=1, n=1, m=1, learning=3)
    steps = replay(items_of([4.0, 1.0, 2.0, 2.5, 5.0]), r)  # 4.0 alarms by the monitor during learning
    assert [s.learning for s in steps] == [True, True, True, False, False]
    assert [s.record_alarm for s in steps] == [True, False, False, False, True]
    assert [s.joint_p_value for s in steps] == [None, None, None, 0.5, 0.25]
    # the monitor's alarm in the learning period raises an alert, never an alarm; the joint's own one does
    assert [s.state for s in steps] == ["alert", "learning", "normal", "normal", "alarm"]


def test_states_alert_then_alarm_then_hysteresis():
    r = Rules(alpha=0.25, k=2, n=3, m=2, learning=3)
    scores = [1.0, 1.1, 1.2] + [0.5, 9, 0.5, 9, 0.5, 0.5, 0.5]
    steps = replay(items_of(scores, acks=[7]), r)
    rec = [s.state for s in steps if s.kind == "record"]
    # the third learning record completes the learning period; acknowledged after the 8th, cleared on the 9th
    assert rec == ["learning"] * 2 + ["normal", "normal", "alert", "alert", "alarm", "alarm", "normal", "normal"]
    assert [e for s in steps for e in s.events] == ["raised", "acknowledged", "cleared"]


def test_rules_are_checked():
    with pytest.raises(FleetError, match="k <= n"):
        Rules(k=3, n=2).check()
    with pytest.raises(FleetError, match="learn at least 19"):
        Rules(alpha=0.05, learning=10).check()
    with pytest.raises(FleetError, match="unknown rule"):
        Rules.from_dict({"kk": 1})
    assert Rules().resolved(0.05).learning == 19 and Rules().resolved(0.01).learning == 99


# ------------------------------------------------------------------------------------------ the stated rate
@pytest.mark.parametrize("f", [0.01, 0.1, 0.4])
def test_the_chain_matches_closed_forms(f):
    # k = n = 1, m = 1: an alarming record raises when the one before was normal
    assert raise_probability_per_record(Rules(alpha=0.1, k=1, n=1, m=1, learning=9), f) == pytest.approx(f * (1 - f))
    # k = n = 2, m large: a raise needs two alarms after a clear, which takes m normal records in a row
    r = Rules(alpha=0.1, k=2, n=2, m=1, learning=9)
    # states: after a raise (11), one normal clears; raise = P(prev alarm, not in alarm) * f; solved by hand:
    # in alarm <=> last record alarming and a raise happened on a run of >= 2 alarms.  Runs of alarms of length
    # L >= 2 raise exactly once; the rate of such runs starting is (1-f) f^2 per record
    assert raise_probability_per_record(r, f) == pytest.approx((1 - f) * f * f)


def test_the_stated_rate_averages_over_the_joints_calibration():
    """k = n = 3, m large enough that raises are runs of >= 3 alarms: per record (1-F) F^3; its mean over
    F ~ Beta(j, N-j+1) is a ratio of Beta functions."""
    from scipy.special import beta as B

    r = Rules(alpha=0.05, k=3, n=3, m=1, learning=39)
    j, N = 2, 39
    want = (B(j + 3, N - j + 1) - B(j + 4, N - j + 1)) / B(j, N - j + 1) * 4 * 365.25
    assert false_alarms_per_year(r, 4) == pytest.approx(want, rel=1e-6)
    indep = raise_probability_per_record(r, 0.05) * 4 * 365.25
    assert false_alarms_per_year(r, 4) > 2 * indep  # one joint's alarms share its calibration


@pytest.mark.parametrize("alpha", [0.05, 0.01])
def test_the_default_rules_state_at_most_one_false_alarm_per_joint_year(alpha):
    stated = false_alarms_per_year(Rules().resolved(alpha), 4)
    assert 0 < stated <= 1


def test_the_stated_rate_matches_the_replay_on_simulated_healthy_joints():
    """Many joints, each with its own calibration scores and i.i.d. healthy records (uniform scores): the raises
    the replay counts per record agree with the stated rate within 4 standard errors.  Generous rules (alpha 0.2)
    make raises common enough to count in a second."""
    r = Rules(alpha=0.2, k=2, n=3, m=2, learning=9)
    rng = np.random.default_rng(7)
    joints, per = 150, 400
    raises = []
    for _ in range(joints):
        steps = replay(items_of(rng.uniform(size=r.learning + per).tolist()), r, acknowledge_at_once=True)
        raises.append(sum("raised" in s.events for s in steps[r.learning:]))
    per_record = np.array(raises) / per
    stated = false_alarms_per_year(r, 1) / 365.25
    se = per_record.std(ddof=1) / math.sqrt(joints)
    assert abs(per_record.mean() - stated) < 4 * se, (per_record.mean(), stated, se)


@pytest.mark.parametrize("module", ["rvdiag.fleet.rules", "rvdiag.fleet.blobs", "rvdiag.fleet.judge"])
def test_the_docstring_examples_hold(module):
    import doctest
    import importlib

    res = doctest.testmod(importlib.import_module(module))
    assert res.attempted > 0 and res.failed == 0


def test_the_stated_rates_in_docs_fleet_md_are_the_functions():
    import re

    from conftest import REPO

    text = (REPO / "docs" / "fleet.md").read_text()
    rows = re.findall(r"\| alpha (\d+) %, (\d) of (\d), clear after (\d), learning (\d+)[^|]*\| ([\d.]+) \|", text)
    assert len(rows) == 3
    for a, k, n, m, N, stated in rows:
        r = Rules(alpha=int(a) / 100, k=int(k), n=int(n), m=int(m), learning=int(N))
        assert f"{false_alarms_per_year(r, 4):.{len(stated.split('.')[1])}f}" == stated
