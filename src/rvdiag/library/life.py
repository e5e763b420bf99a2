"""Life histories (``[history]``): each simulated reducer recorded at commissioning, then at many times over its life.

A life config is a paired library config (:mod:`rvdiag.library.paired`) with a ``[history]`` table
(:class:`rvdiag.library.config.HistoryConfig`, docs/library.md "Life histories").  Every reducer is drawn as in a
paired library; then, from the same reducer stream, its life: one fate (:data:`FATES`, by the configured shares),
the fault's onset, the growth law's values (:func:`draw_life`) and a sensor fault.  Its records are its commissioning
records (role ``"baseline"``, T1, time 0) and then ``records`` monitored records, one every ``interval_days``, each
at an operating point drawn among the commissioning ones and with its own run-to-run variation, as a paired
library's.  The fault's size at a record's time follows the fate's growth law (:mod:`rvdiag.gears.growth`, their one
home) and sets the record's state and severities (:meth:`Life.record`).  Each record's truth goes into the
``life.*`` metadata columns (:data:`LIFE_COLUMNS`).

Sensor faults (:func:`apply_sensor_fault`): from a drawn monitored record on, the record's channel is dead (a
constant: its mean), clipped (at 20 % of its peak: a saturated amplifier) or disconnected (1 % of its RMS of white
noise: an open input), applied to the recorded signal after its noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

#: a reducer's fates, and the states each passes through (a crack breaks into a broken tooth, T2).  Pitting and
#: spalling are not grown: no area-growth law is written for them yet (docs/library.md "Life histories").
FATE_STATES: dict[str, tuple[str, ...]] = {"healthy": ("T1",), "wear": ("T3",), "crack": ("T4", "T2"),
                                           "broken": ("T2",)}
FATES = tuple(FATE_STATES)
#: sensor faults a history may draw (:func:`apply_sensor_fault`)
SENSOR_FAULTS = ("dead", "clipped", "disconnected")
#: the per-sample truth columns of a life store, each a record's value (docs/library.md "Life histories")
LIFE_COLUMNS = ("life.record", "life.time_days", "life.load_cycles", "life.fate", "life.onset_days", "life.size",
                "life.failure_days", "life.sensor_fault")
#: the spawn key of a record's sensor-fault stream, ``SeedSequence(unit_seed, spawn_key=(5,))`` (the unit's four
#: streams are its children 0-3, the specimen's is 4)
SENSOR_FAULT_STREAM = 5


def apply_sensor_fault(x: np.ndarray, kind: str, rng: np.random.Generator) -> np.ndarray:
    """``x`` as a faulty channel records it: ``"dead"`` (its mean throughout), ``"clipped"`` (clipped at +-20 % of its
    peak) or ``"disconnected"`` (white noise of 1 % of its standard deviation; draws from ``rng``)."""
    if kind == "dead":
        return np.full_like(x, float(np.mean(x)))
    if kind == "clipped":
        peak = float(np.max(np.abs(x)))
        return np.clip(x, -0.2 * peak, 0.2 * peak)
    if kind == "disconnected":
        return 0.01 * float(np.std(x)) * rng.standard_normal(x.size)
    raise ValueError(f"unknown sensor fault {kind!r}; known: {', '.join(SENSOR_FAULTS)}")


@dataclass(frozen=True, eq=False)
class Life:
    """One reducer's drawn life: its fate's growth (:class:`rvdiag.gears.growth.Growth`), the crack's angle and the
    broken fraction its fault ends in, the sun tooth's load cycles a day, and its sensor fault (kind, from which day
    on; ``""`` / inf for none)."""

    growth: Any
    crack_angle_deg: float
    broken_fraction: float
    passes_per_day: float
    sensor_fault: str = ""
    sensor_fault_days: float = math.inf
    minimum: Mapping[str, float] = field(default_factory=dict)
    maximum: Mapping[str, float] = field(default_factory=dict)

    @property
    def fate(self) -> str:
        return self.growth.kind

    def record(self, index: int, days: float) -> tuple[str, dict[str, float], dict[str, Any]]:
        """``(state, severities, life columns)`` of the record ``index`` at ``days`` since commissioning.

        The state follows the size: T1 before the onset and while the size is below the state's smallest simulable
        severity (``minimum``, the lower end of its validity interval:
        :data:`rvdiag.library.states.SEVERITY_PARAMETERS`; the truth columns keep the size); then wear T3 (``wear_depth`` = the size, capped at its interval's upper end),
        a crack T4 (``crack_depth`` = the size at the drawn angle) until its failure, then T2 at the drawn broken
        fraction, a broken tooth T2 from its onset."""
        g = self.growth
        size = float(g.size(np.array([days]))[0])
        state, severity = "T1", {}
        if g.kind == "broken" and days >= g.onset_days or g.kind == "crack" and days >= g.failure_days:
            state, severity = "T2", {"broken_fraction": self.broken_fraction}
        elif g.kind == "crack" and size >= self.minimum["crack_depth"]:
            state, severity = "T4", {"crack_depth": size, "crack_angle_deg": self.crack_angle_deg}
        elif g.kind == "wear" and size >= self.minimum["wear_depth"]:
            state, severity = "T3", {"wear_depth": min(size, self.maximum["wear_depth"])}
        truth = {"life.record": int(index), "life.time_days": float(days),
                 "life.load_cycles": float(days * self.passes_per_day), "life.fate": g.kind,
                 "life.onset_days": float(g.onset_days), "life.size": size,
                 "life.failure_days": float(g.failure_days),
                 "life.sensor_fault": self.sensor_fault if days >= self.sensor_fault_days else ""}
        return state, severity, truth


def draw_life(history: Any, rng: np.random.Generator, params: Any) -> Life:
    """One reducer's life from its stream ``rng``, after the draws that make the reducer
    (:func:`rvdiag.library.build.make_plan`): always the same nine draws, in this order, so that streams stay aligned
    whatever the fate: the fate (by the shares of ``history.fates``, in :data:`FATES` order), the onset (uniform in
    ``onset_days``), the wear coefficient (log-uniform in ``wear_coefficient``), the crack's angle and its propagation
    days, the broken fraction, then whether the sensor fails (``sensor_fault_share``), its kind (equally likely among
    ``sensor_fault_kinds``) and from which monitored record on (equally likely).

    ``history`` is a :class:`rvdiag.library.config.HistoryConfig`; ``params`` the nominal
    :class:`rvdiag.params.ReducerParams` the growth laws run on (a reducer's own stiffness and damping factors do
    not change its growth)."""
    from rvdiag.gears.growth import Growth, broken_step, crack_growth, sun_root_chord, wear_growth
    from rvdiag.gears.wear import DutyCycle, mesh_passes
    from rvdiag.library.states import SEVERITY_PARAMETERS

    u_fate = rng.random()
    onset = float(history.onset_days.draw(rng))
    k_lo, k_hi = history.wear_coefficient.lo, history.wear_coefficient.hi
    k_wear = float(math.exp(math.log(k_lo) + rng.random() * (math.log(k_hi) - math.log(k_lo))))
    angle = float(history.crack_angle_deg.draw(rng))
    crack_days = float(history.crack_days.draw(rng))
    broken = float(history.broken_fraction.draw(rng))
    u_sensor, u_kind, u_when = rng.random(), rng.random(), rng.random()

    cum, fate = 0.0, FATES[-1]
    shares = [(f, float(history.fates.get(f, 0.0))) for f in FATES]
    for f, share in shares:
        cum += share
        if u_fate < cum:
            fate = f
            break
    else:  # rounding of the shares' sum: the last fate with a share
        fate = [f for f, share in shares if share > 0][-1]
    duty = DutyCycle(history.duty_speed_deg_s, history.duty_load_Nm, history.moving_fraction)
    if fate == "wear":
        growth = wear_growth(params, duty, onset, k_wear, history.wear_failure_m, k_ref=k_lo,
                             hours_ref_max=24.0 * history.horizon_days * k_hi / k_lo)
    elif fate == "crack":
        growth = crack_growth(params, duty, onset, history.crack_initial_m,
                              history.crack_failure_fraction * sun_root_chord(params), crack_days)
    elif fate == "broken":
        growth = broken_step(onset, broken)
    else:
        growth = Growth()
    kind, since = "", math.inf
    if u_sensor < history.sensor_fault_share:
        kinds = history.sensor_fault_kinds
        kind = kinds[min(int(u_kind * len(kinds)), len(kinds) - 1)]
        since = history.interval_days * (min(int(u_when * history.records), history.records - 1) + 1)
    return Life(growth, angle, broken, mesh_passes(params, 24.0, duty, "sun"), kind, since,
                minimum={k: p.lo for k, p in SEVERITY_PARAMETERS.items()},
                maximum={k: p.hi for k, p in SEVERITY_PARAMETERS.items()})


def summarize(meta: Mapping[str, Any]) -> dict[str, Any] | None:
    """What a store's life histories hold (``rvdiag library info``), from its metadata columns; ``None`` for a store
    without them: reducers per fate, records per reducer, the last record's day, the reducers whose fault fails
    (reaches its failure threshold) by their last record, and the reducers with a sensor fault."""
    if "life.fate" not in meta:
        return None
    reducer = np.asarray(meta["reducer"])
    fate, days = np.asarray(meta["life.fate"]).astype(str), np.asarray(meta["life.time_days"], dtype=float)
    failure = np.asarray(meta["life.failure_days"], dtype=float)
    fault = np.asarray(meta["life.sensor_fault"]).astype(str)
    record = np.asarray(meta["life.record"])
    out: dict[str, Any] = {"reducers": int(np.unique(reducer).size), "fates": {}, "failed_by_last_record": {},
                           "records_per_reducer": int(np.unique(record).size), "last_day": float(days.max()),
                           "sensor_faults": {}}
    for f in FATES:
        mine = fate == f
        if not mine.any():
            continue
        out["fates"][f] = int(np.unique(reducer[mine]).size)
        if f != "healthy":
            out["failed_by_last_record"][f] = int(np.unique(reducer[mine & (failure <= days.max())]).size)
    for kind in SENSOR_FAULTS:
        if (fault == kind).any():
            out["sensor_faults"][kind] = int(np.unique(reducer[fault == kind]).size)
    return out
