"""A joint's state from its records: the rules, as pure functions (no database, no clock).

States: ``no-baseline`` (never commissioned, or maintained since), ``learning`` (commissioned, its learning
period not yet full), ``normal``, ``alert``, ``alarm``, ``sensor-fault``.

**The record alarm.**  Each recognised record has the monitor's health index ``s`` (its change against the joint's
baseline; higher is further from it) and the monitor's own alarm at its stated per-record rate ``alpha``, calibrated
across reducers.  That calibration does not hold for every reducer (at a 10 dB floor, docs/monitoring.md: the worst held-out reducer alarmed on
6.2 % of its healthy records at a stated 1 %), so a joint calibrates itself (Vovk, Gammerman & Shafer, *Algorithmic
Learning in a Random World*, 2005, ch. 2; the inductive conformal p-value): its first ``learning`` recognised records
after commissioning (the learning period; they are taken to be healthy) are its own calibration scores
``s_1..s_N``, and each later record gets the conformal p-value within the joint

    p = (1 + #{i : s_i >= s}) / (N + 1)

and alarms when ``p <= alpha``. If the joint's healthy records are exchangeable, ``P(p <= alpha) <= alpha`` for that
joint, whatever its reducer. During the learning period the record alarm is the monitor's own (its cross-reducer
p-value), and it can raise an ``alert`` but never an ``alarm``: its rate is not this joint's (bench/fleet_alarms.py
measured 20 % on healthy records of unseen reducers at a stated 5 %). The two are not combined after learning: the
joint's ranking replaces the monitor's cross-reducer calibration, whose rate is not that joint's; the health index
itself is the monitor's. ``alpha`` defaults to the monitor's. With ``N`` calibration records the smallest p-value is
``1/(N+1)``, so ``learning`` must be at least ``1/alpha - 1`` for any alarm to be possible (:meth:`Rules.check`).
:func:`rank_after_learning` ranks another score of the same records (the crack detector's index) among the same
learning records by the same p-value; the rules do not count its alarm.

**Persistence, hysteresis, latching** (ISO 17359 alarm criteria; ThingsBoard / Grafana practice).  ``alert`` from
the first alarming record; ``alarm`` when ``k`` of the last ``n`` recognised records alarm; an alert clears after
``m`` consecutive normal records.  An alarm latches: it stays ``alarm`` until acknowledged, and clears (event
``cleared``) once acknowledged and ``m`` consecutive records are normal; while it is raised no second one is, and
once cleared the count of ``k`` of ``n`` starts afresh.

**Sensor faults.**  A record that is not recognised (flat, clipped, no mesh line, out of distribution) shows the
joint as ``sensor-fault`` until the next recognised one; it counts neither as an alarming nor as a normal record
(it leaves the persistence window and the hysteresis count as they were).  A rejected file reaches nothing.

The joint-level false-alarm rate these rules imply is :func:`false_alarms_per_year`.
"""

from __future__ import annotations

import functools
import math
from collections import deque
from dataclasses import asdict, dataclass, field, replace
from datetime import datetime

import numpy as np

from rvdiag.errors import FleetError
from rvdiag.validation import finite_number, positive

STATES = ("no-baseline", "learning", "normal", "alert", "alarm", "sensor-fault")
DAYS_PER_YEAR = 365.25
#: the per-record rate when neither the rules nor the monitor's card state one (rvdiag train's default alpha)
FALLBACK_ALPHA = 0.01


@dataclass(frozen=True)
class Rules:
    """A joint's alarm rules (module docstring).

    Parameters
    ----------
    alpha : float or None
        The per-record alarm rate; None: the monitor's (its card's ``alarm.alpha``).
    k, n : int
        ``alarm`` when ``k`` of the last ``n`` recognised records alarm (``1 <= k <= n <= 12``).
    m : int
        An alert clears, and an acknowledged alarm clears, after ``m`` consecutive normal records.
    learning : int or None
        The learning period in recognised records after commissioning; None: :meth:`default_learning`, enough for
        ``CALIBRATION_RANK`` calibration scores above the alarm's threshold.
    records_per_day : float
        How many records a day the joint is expected to send (for the stated rate per year).
    failure_index : float or None
        The health index at which the joint counts as failed: the maintenance limit its remaining life is counted
        to (:func:`rvdiag.prognostics.joint_prognosis`'s ``threshold``); None: the remaining life is not
        estimated.  It changes no alarm.
    """

    alpha: float | None = None
    k: int = 3
    n: int = 3
    m: int = 3
    learning: int | None = None
    records_per_day: float = 4.0
    failure_index: float | None = None

    #: the default learning period puts the threshold at the CALIBRATION_RANK-th largest calibration score
    CALIBRATION_RANK = 1

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict | None) -> "Rules":
        d = dict(d or {})
        unknown = set(d) - set(cls.__dataclass_fields__)
        if unknown:
            raise FleetError(f"unknown rule setting(s) {sorted(unknown)}; known: "
                             f"{', '.join(cls.__dataclass_fields__)}")
        return cls(**d).check()

    def check(self, alpha: float | None = None) -> "Rules":
        """Validate; with ``alpha`` (the monitor's) also that the learning period allows an alarm at all."""
        a = self.alpha if self.alpha is not None else alpha
        if a is not None and not 0 < float(a) < 1:
            raise FleetError(f"the rules' alpha must lie in (0, 1), got {a}")
        if not (isinstance(self.k, int) and isinstance(self.n, int) and 1 <= self.k <= self.n <= 12):
            raise FleetError(f"persistence k of n needs 1 <= k <= n <= 12, got k={self.k}, n={self.n}")
        if not (isinstance(self.m, int) and 1 <= self.m <= 100):
            raise FleetError(f"the hysteresis m (consecutive normal records to clear) must be 1-100, got {self.m}")
        positive(self.records_per_day, "records_per_day", error=FleetError)
        if self.failure_index is not None:
            finite_number(self.failure_index, "the failure index", 0.0, strict=True, error=FleetError)
        if self.learning is not None:
            if not (isinstance(self.learning, int) and self.learning >= 1):
                raise FleetError(f"the learning period must be a whole number of records >= 1, got {self.learning}")
            if a is not None and math.floor(float(a) * (self.learning + 1) + 1e-9) < 1:
                raise FleetError(f"a learning period of {self.learning} records cannot give a p-value <= {a:g} "
                                 f"(the smallest is 1/{self.learning + 1}): learn at least {math.ceil(1 / a) - 1}")
        return self

    @classmethod
    def default_learning(cls, alpha: float) -> int:
        """The smallest ``N`` with ``floor(alpha (N+1)) = CALIBRATION_RANK``: the alarm threshold is then the
        ``CALIBRATION_RANK``-th largest of the joint's own scores.

        >>> Rules.default_learning(0.05), Rules.default_learning(0.01)
        (19, 99)
        """
        return int(math.ceil(cls.CALIBRATION_RANK / float(alpha) - 1e-9)) - 1

    def resolved(self, monitor_alpha: float) -> "Rules":
        """These rules with ``alpha`` and ``learning`` filled in from the monitor's alpha."""
        a = float(self.alpha if self.alpha is not None else monitor_alpha)
        out = replace(self, alpha=a, learning=self.learning if self.learning is not None else self.default_learning(a))
        return out.check()


# ------------------------------------------------------------------------------------------------------ replay
@dataclass(frozen=True)
class Item:
    """One thing that happened to a joint within an epoch, for :func:`replay`: a record (``kind="record"``) with its
    health index, the monitor's alarm and whether it was recognised, or an acknowledgement (``kind="ack"``)."""

    time: datetime
    kind: str = "record"
    key: object = None  # the record's or event's id, handed back in the steps
    health_index: float | None = None
    monitor_alarm: bool | None = None
    recognised: bool = True


@dataclass
class Step:
    """The joint after one item: its state, whether the record alarmed for the joint (``record_alarm``), its
    conformal p-value within the joint (None in the learning period), whether it was a learning record, and the
    events it caused (``raised``, ``cleared``, ``acknowledged``)."""

    key: object
    time: datetime
    kind: str
    state: str
    record_alarm: bool | None = None
    joint_p_value: float | None = None
    learning: bool = False
    open_alarm: bool = False
    events: list = field(default_factory=list)


def conformal_p_value(calibration, score: float) -> float:
    """``(1 + #{s_i >= score}) / (N + 1)`` (Vovk et al. 2005, eq. 2.17 without the random tie-break): the rank of
    ``score`` among the joint's own calibration scores, conservative under ties.

    >>> conformal_p_value([0.1, 0.2, 0.3], 0.25), conformal_p_value([0.1, 0.2, 0.3], 9.0)
    (0.5, 0.25)
    """
    c = np.asarray(calibration, dtype=float)
    return float((1 + np.count_nonzero(c >= score)) / (c.size + 1))


def joint_alarm(p: float, alpha: float) -> bool:
    """Whether a record alarms for the joint: its conformal p-value ``p <= alpha`` (module docstring)."""
    return bool(p <= alpha + 1e-12)


def rank_after_learning(steps, scores: dict, alpha: float) -> dict:
    """Another score of the joint's records ranked as :func:`replay` ranks the health index: its calibration scores
    are the finite ``scores`` of the records :func:`replay` took as learning records (the same ones, so the same
    time order, out-of-order records included), and each recognised record after learning gets
    :func:`conformal_p_value` among them and :func:`joint_alarm` at ``alpha``.

    Parameters
    ----------
    steps : list of Step
        :func:`replay`'s steps of one epoch.
    scores : dict
        A record's ``key`` -> its score; None or not finite (an error, no score): not a calibration score and not
        ranked.
    alpha : float
        The rules' per-record rate.

    Returns
    -------
    dict
        For each record step whose key is in ``scores``: ``{"joint_p_value", "joint_alarm", "learning"}`` (the
        first two None in the learning period, for a record not recognised, and for a record without a score).

    >>> from datetime import datetime
    >>> t = datetime(2026, 1, 1)
    >>> st = [Step(1, t, "record", "learning", learning=True), Step(2, t, "record", "learning", learning=True),
    ...       Step(3, t, "record", "normal", record_alarm=False)]
    >>> rank_after_learning(st, {1: 0.1, 2: 0.3, 3: 0.2}, 0.4)[3]
    {'joint_p_value': 0.6666666666666666, 'joint_alarm': False, 'learning': False}
    """
    def usable(v):
        return v is not None and math.isfinite(v)

    calib = [scores[st.key] for st in steps
             if st.kind == "record" and st.learning and st.key in scores and usable(scores[st.key])]
    out = {}
    for st in steps:
        if st.kind != "record" or st.key not in scores:
            continue
        p = None
        if not st.learning and st.record_alarm is not None and usable(scores[st.key]):
            p = conformal_p_value(calib, float(scores[st.key]))
        out[st.key] = {"joint_p_value": p, "joint_alarm": None if p is None else joint_alarm(p, alpha),
                       "learning": bool(st.learning)}
    return out


def replay(items, rules: Rules, *, acknowledge_at_once: bool = False) -> list[Step]:
    """The joint's state after each item of one epoch, in time order (ties: records before acknowledgements, then
    as given).  ``rules`` must be :meth:`Rules.resolved`.  Pure: the same items give the same steps.
    ``acknowledge_at_once``: every alarm is taken as acknowledged when raised (as :func:`false_alarms_per_year`
    states the rate; for simulations)."""
    if rules.alpha is None or rules.learning is None:
        raise ValueError("replay needs resolved rules (Rules.resolved)")
    order = sorted(range(len(items)), key=lambda i: (items[i].time, items[i].kind != "record", i))
    calib: list[float] = []
    window: deque = deque(maxlen=rules.n)
    normal_run = rules.m  # consecutive normal records; m at the start: no alert
    in_alarm = acked = sensor = False
    out = []
    for i in order:
        it = items[i]
        events = []
        rec_alarm = p = None
        learning = False
        if it.kind == "ack":
            if in_alarm and not acked:
                acked = True
                events.append("acknowledged")
                if normal_run >= rules.m:
                    in_alarm = False
                    window.clear()
                    events.append("cleared")
        elif not it.recognised or it.health_index is None and it.monitor_alarm is None:
            sensor = True
        else:
            sensor = False
            if len(calib) < rules.learning:
                learning = True
                rec_alarm = bool(it.monitor_alarm)
                if it.health_index is not None and math.isfinite(it.health_index):
                    calib.append(float(it.health_index))
            else:
                p = conformal_p_value(calib, float(it.health_index))
                rec_alarm = joint_alarm(p, rules.alpha)
            if not learning:  # the monitor's own alarm, in the learning period, can raise an alert only
                window.append(rec_alarm)
            normal_run = 0 if rec_alarm else normal_run + 1
            if not in_alarm and sum(window) >= rules.k:
                in_alarm, acked = True, acknowledge_at_once
                events.append("raised")
            elif in_alarm and acked and normal_run >= rules.m:
                in_alarm = False
                window.clear()  # a fresh start: the alarms before the clear do not raise the next one
                events.append("cleared")
        if sensor:
            state = "sensor-fault"
        elif in_alarm:
            state = "alarm"
        elif normal_run < rules.m:
            state = "alert"
        elif len(calib) < rules.learning:
            state = "learning"
        else:
            state = "normal"
        out.append(Step(key=it.key, time=it.time, kind=it.kind, state=state, record_alarm=rec_alarm,
                        joint_p_value=p, learning=learning, open_alarm=in_alarm and not acked, events=events))
    return out


# --------------------------------------------------------------------------------------- the stated false alarms
def _chain(rules: Rules):
    """The persistence/hysteresis machine of :func:`replay` after learning, as a Markov chain on (the last ``n``
    record alarms, raised, consecutive normal records capped at ``m``), with the alarm acknowledged at once.
    Returns the states, and for each state its successor after a normal and after an alarming record, and whether
    that alarming record raises the alarm."""
    n, k, m = rules.n, rules.k, rules.m
    states = [(w, a, c) for w in range(2 ** n) for a in (0, 1) for c in range(m + 1)]
    index = {s: i for i, s in enumerate(states)}
    mask = 2 ** n - 1
    nxt = np.zeros((len(states), 2), dtype=np.int64)
    raise_on_alarm = np.zeros(len(states), dtype=bool)
    for i, (w, a, c) in enumerate(states):
        for bit in (0, 1):
            w2 = ((w << 1) | bit) & mask
            c2 = 0 if bit else min(c + 1, m)
            a2 = a
            if not a and bin(w2).count("1") >= k:
                a2 = 1
                if bit:
                    raise_on_alarm[i] = True
            elif a and c2 >= m:
                a2, w2 = 0, 0
            nxt[i, bit] = index[(w2, a2, c2)]
    return states, nxt, raise_on_alarm


def raise_probability_per_record(rules: Rules, f: float) -> float:
    """The long-run probability that a record raises the joint's alarm when each record alarms independently with
    probability ``f`` (the stationary distribution of :func:`_chain`; exact).  A raise happens only on an alarming
    record (a normal one cannot complete ``k`` of ``n``)."""
    f = float(f)
    if f <= 0:
        return 0.0
    if f >= 1:
        return 0.0 if rules.m >= 1 else 1.0  # always alarming: raised once, never cleared
    states, nxt, raises = _chain(rules)
    S = len(states)
    P = np.zeros((S, S))
    np.add.at(P, (np.arange(S), nxt[:, 0]), 1 - f)
    np.add.at(P, (np.arange(S), nxt[:, 1]), f)
    # stationary pi: pi (P - I) = 0, sum pi = 1 (the chain is irreducible on the states reachable from the start)
    A = np.vstack([(P - np.eye(S)).T, np.ones(S)])
    b = np.zeros(S + 1)
    b[-1] = 1.0
    pi = np.linalg.lstsq(A, b, rcond=None)[0]
    return float(np.sum(pi[raises]) * f)


def false_alarms_per_year(rules: Rules, records_per_day: float | None = None) -> float:
    """The joint's stated false alarms per year (:func:`_false_alarms_per_year`, remembered per rules: a page that
    shows it for every joint computes it once)."""
    R = float(records_per_day if records_per_day is not None else rules.records_per_day)
    return _false_alarms_per_year(rules, R)


@functools.lru_cache(maxsize=256)
def _false_alarms_per_year(rules: Rules, records_per_day: float) -> float:
    """The joint's stated false alarms per year: alarms raised on a healthy joint after its learning period.

    Derivation.  Let the joint's healthy records be exchangeable with continuous scores, and its ``N`` learning
    scores the calibration set.  A later record alarms when its conformal p-value is ``<= alpha``, i.e. when its
    score exceeds the ``j``-th largest calibration score, ``j = floor(alpha (N+1))``.  Given the calibration set,
    later healthy records alarm independently with probability ``F = 1 - G(s_(N-j+1))`` (``G`` the scores' CDF);
    ``G(s_(N-j+1))`` is the ``(N-j+1)``-th of ``N`` uniform order statistics, so ``F ~ Beta(j, N-j+1)`` with mean
    ``j/(N+1) <= alpha`` (the conformal guarantee).  Given ``F``, the persistence/hysteresis machine is a finite
    Markov chain (:func:`_chain`) whose stationary distribution gives the raises per record ``r(F)``
    (:func:`raise_probability_per_record`).  The stated rate is

        E[r(F)] * R * 365.25,   F ~ Beta(j, N - j + 1)

    integrated numerically (Gauss-Jacobi quadrature on the Beta weight).  Averaging over ``F`` matters: alarms of
    one joint share its calibration set, so they are positively correlated; with ``k = n = 3``, ``E[F^3]`` is
    ``(j+2)(j+1)j / ((N+3)(N+2)(N+1))``, several times ``alpha^3``.  The alarm is taken as acknowledged at once (a
    later acknowledgement only keeps the joint longer in ``alarm``, when no new alarm can be raised).  Records that
    are not recognised are left out of the chain, as :func:`replay` leaves them out.

    Parameters
    ----------
    rules : Rules
        Resolved rules (:meth:`Rules.resolved`).
    records_per_day : float, optional
        ``R``; default ``rules.records_per_day``.

    Examples
    --------
    >>> r = Rules(alpha=0.05, k=1, n=1, m=1, learning=19)   # every alarming record raises; F ~ Beta(1, 19)
    >>> round(false_alarms_per_year(r, 1.0) / 365.25, 6)     # E[F (1 - F)] = 1/20 - 2/(20*21)
    0.045238
    """
    from scipy.special import roots_jacobi

    if rules.alpha is None or rules.learning is None:
        raise ValueError("false_alarms_per_year needs resolved rules (Rules.resolved)")
    R = float(records_per_day if records_per_day is not None else rules.records_per_day)
    N = int(rules.learning)
    j = int(math.floor(rules.alpha * (N + 1) + 1e-9))
    if j < 1:
        return 0.0
    if j > N:
        return raise_probability_per_record(rules, 1.0) * R * DAYS_PER_YEAR
    # F ~ Beta(a=j, b=N-j+1): with x = 2F - 1, weight (1-x)^(b-1) (1+x)^(a-1) is Gauss-Jacobi's
    x, w = roots_jacobi(64, N - j, j - 1)
    F = (x + 1) / 2
    rate = sum(wi * raise_probability_per_record(rules, fi) for fi, wi in zip(F, w)) / w.sum()
    return float(rate * R * DAYS_PER_YEAR)
