"""Library configs: a typed, validated view of a library TOML file (see ``docs/library.md``).

A config says which health states to simulate with which severities, at which operating points, with
how much noise and parameter randomisation, how each simulated signal is cut into samples and how the
samples are split into training and test sets.  Two modes:

``paper``
    One long simulation per state (the dynamics-model-driven study, docs/references.md: 60 s at 48 kHz per
    state, cut into non-overlapping 8000-point samples, 260 training and 100 test samples per state).
    The split is by segment: training and test samples come from the same simulation.
``split-by-simulation`` (spelled ``independent`` before; still accepted, with a warning)
    ``simulations_per_state`` independent simulations per state, each drawing its own severity, operating
    point, noise level and model parameters.  The split is by simulation: the last
    ``test_simulations_per_state`` simulations of each state form the test set, so no test sample shares
    a simulation with a training sample (the honest test).  The simulations of a state are exchangeable
    (independent draws), so taking the last ones is as random as any other choice.

Sweeps
------
Every severity, operating and noise value may be written three ways:

- a number: fixed, ``load_Nm = 167.0``;
- a list: each simulation draws one element with equal probability, ``input_speed_rpm = [1000, 1500]``;
- a table ``{min = a, max = b}``: each simulation draws uniformly in [a, b].

Every error names the file and the key: ``ConfigError("demo.toml: [signal] hop: must be > 0, got -1")``.

Examples
--------
>>> cfg = LibraryConfig.from_dict({"mode": "paper", "seed": 1, "states": {"T1": {}, "T2": {}},
...     "signal": {"fs": 1000.0, "duration_s": 1.0, "segment_length": 100},
...     "operation": {"input_speed_rpm": 1500.0, "load_Nm": 100.0},
...     "split": {"train_per_state": 7, "test_per_state": 3}})
>>> cfg.segments_per_simulation, cfg.rows_per_simulation("T1")
(10, 10)
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from rvdiag.errors import ConfigError, ParameterError
from rvdiag.library.states import SEVERITY_PARAMETERS, STATES
from rvdiag.tomlfile import read_toml
from rvdiag.validation import number, positive, whole_number

#: ``[signal] transient_s`` when a config leaves it out: the model's run-in (``ModelSettings.transient_s``,
#: docs/model.md section 7), the default of ``rvdiag simulate --transient`` too (tests/test_library_config.py
#: checks that all three agree).  Configs used to default to 0 s (docs/library.md).
DEFAULT_TRANSIENT_S = 0.1


def _configs_dir() -> Path:
    from importlib.resources import files

    return Path(str(files("rvdiag") / "configs"))


def builtin_configs() -> list[str]:
    """Names of the library configs shipped in the package (``rvdiag/configs/``), e.g. ``demo``, ``experiments/snr``."""
    root = _configs_dir()
    return sorted(p.relative_to(root).with_suffix("").as_posix() for p in root.rglob("*.toml"))


def builtin_config_path(name: str) -> Path:
    """The file of the shipped config ``name`` (one of :func:`builtin_configs`)."""
    if name not in builtin_configs():
        raise ConfigError(f"no built-in library config {name!r} (built-in: {', '.join(builtin_configs())})")
    return _configs_dir() / f"{name}.toml"

MODES = ("paper", "split-by-simulation")
#: old spellings of a mode, still accepted with one warning: ``independent`` (the mode's name until 2026-11-26, beside
#: a shipped config of the same name)
LEGACY_MODES = {"independent": "split-by-simulation"}
#: ``[operation] noise_mode``: "record" scales each record's noise to that record's own power (the behaviour of a
#: config without the key); "floor" gives every simulated reducer and sensor one noise level (docs/library.md)
NOISE_MODES = ("record", "floor")
#: seconds recorded (after ``[signal] transient_s``) of the healthy twin whose power sets a "floor" noise level
NOISE_REFERENCE_S = 0.1
#: standard gravity (m/s^2): the ``g`` of ``noise_density_ug_per_rthz`` (ISO 80000-3)
STANDARD_GRAVITY = 9.80665
SPLIT_ASSIGN = ("random", "ordered")
DEFAULT_SIMULATOR = "rvdiag.library.simulators:dynamics"

#: Parameters scaled by ``[randomise] stiffness_pct``: every support stiffness and Young's modulus (the
#: mesh stiffness of the potential-energy method is proportional to E, Yang & Lin 1987; Sainsot et al. 2004).
STIFFNESS_KEYS: tuple[tuple[str, str], ...] = (
    ("material", "youngs_modulus"),
    ("bearings", "sun_support"),
    ("bearings", "crank_carrier"),
    ("bearings", "crank_cycloid"),
    ("bearings", "carrier_support"),
    ("bearings", "pin_wheel_housing"),
    ("bearings", "planet_crank_torsional"),
    ("bearings", "input_torsional"),
    ("bearings", "output_torsional"),
)
#: ``[randomise]`` keys drawn as absolute values of the ``[mounting]`` section (the sensor's transfer path and
#: the mass the housing carries), with the range each must lie in
PATH_KEYS: dict[str, tuple[float, float]] = {
    "path_resonance_hz": (0.0, 24000.0),
    "path_damping_ratio": (1e-3, 1.0),
    "housing_added_mass": (0.0, 200.0),
}
#: ``[randomise]`` keys of the housing accelerometer drawn per simulation (domain randomisation of the sensor),
#: degrees: its position around the housing (on the pin-wheel outer radius, from the model's default point on the
#: x axis, counter-clockwise) and its sensing direction (from the outward radial direction at that point,
#: counter-clockwise: 0 radial, 90 tangential; at position 0 these are x and y)
SENSOR_KEYS: dict[str, tuple[float, float]] = {
    "sensor_position_deg": (-360.0, 360.0),
    "sensor_direction_deg": (-360.0, 360.0),
}
#: run-to-run variation between two records of one reducer, each a factor drawn uniformly in 1 +- pct/100 in this
#: order: ``load`` (output load torque), ``speed`` (output speed), ``temperature`` (every stiffness together),
#: ``mesh_damping`` (the mesh damping ratio) and ``gain`` (the sensor's sensitivity); the defaults (%) of
#: ``[baseline] <key>_pct`` (:mod:`rvdiag.library.paired`)
VARIATION_KEYS: dict[str, float] = {"load": 3.0, "speed": 1.0, "temperature": 2.0, "mesh_damping": 10.0,
                                    "gain": 3.0}
#: Parameters scaled by ``[randomise] damping_pct``.
DAMPING_KEYS: tuple[tuple[str, str], ...] = (
    ("damping", "mesh_damping_ratio"),
    ("damping", "bearing_damping_ratio"),
)

_TOP_KEYS = {"name", "mode", "seed", "simulator", "params", "channel", "model",
             "signal", "operation", "randomise", "profile", "split", "states", "baseline", "history"}
_SECTION_KEYS = {
    "signal": {"fs", "duration_s", "transient_s", "segment_length", "hop"},
    "operation": {"input_speed_rpm", "output_speed_deg_s", "load_Nm", "noise_snr_db", "noise_mode",
                  "noise_density_ug_per_rthz"},
    "randomise": {"stiffness_pct", "damping_pct", "path_resonance_hz", "path_damping_ratio", "housing_added_mass",
                  "noise_colour_exponent", "sensor_position_deg", "sensor_direction_deg", "specimen",
                  "iso1328_grade", "pin_wear_depth"},
    "profile": {"trapezoid_fraction", "scurve_fraction", "accel_deg_s2", "jerk_deg_s3", "arm_mass_kg",
                "arm_length_m", "arm_angle_deg"},
    "split": {"train_per_state", "test_per_state", "assign",
              "simulations_per_state", "test_simulations_per_state", "reducers", "test_reducers"},
    "baseline": {"operating_points", "records_per_point", "monitored_healthy", "monitored_per_state",
                 "load_pct", "speed_pct", "temperature_pct", "mesh_damping_pct", "gain_pct"},
    "history": {"records", "interval_days", "duty_speed_deg_s", "duty_load_Nm", "moving_fraction", "fates",
                "onset_days", "wear_coefficient", "wear_failure_m", "crack_initial_m", "crack_angle_deg",
                "crack_days", "crack_failure_fraction", "broken_fraction", "sensor_fault_share",
                "sensor_fault_kinds"},
}


# ---------------------------------------------------------------------- sweeps
@dataclass(frozen=True)
class Sweep:
    """A value drawn per simulation: fixed, one of a list, or uniform in ``[lo, hi]``.

    ``kind`` is "fixed" (``values`` has one element), "choice" or "uniform" (``values = (lo, hi)``).
    """

    kind: str
    values: tuple[float, ...]

    @classmethod
    def parse(cls, raw: Any, where: str) -> "Sweep":
        """Parse a TOML value (number, list of numbers, or ``{min, max}`` table)."""
        if isinstance(raw, Mapping):
            unknown = set(raw) - {"min", "max"}
            if unknown or not {"min", "max"} <= set(raw):
                raise ConfigError(f"{where}: a range must be a table {{min = ..., max = ...}}, got {dict(raw)!r}")
            lo, hi = _number(raw["min"], f"{where}.min"), _number(raw["max"], f"{where}.max")
            if not lo <= hi:
                raise ConfigError(f"{where}: min ({lo:g}) must not exceed max ({hi:g})")
            return cls("fixed", (lo,)) if lo == hi else cls("uniform", (lo, hi))
        if isinstance(raw, (list, tuple)):
            if not raw:
                raise ConfigError(f"{where}: an empty list gives nothing to draw from")
            vals = tuple(_number(v, f"{where}[{i}]") for i, v in enumerate(raw))
            return cls("fixed", vals) if len(vals) == 1 else cls("choice", vals)
        return cls("fixed", (_number(raw, where),))

    @property
    def lo(self) -> float:
        return min(self.values)

    @property
    def hi(self) -> float:
        return max(self.values)

    def draw(self, rng: np.random.Generator) -> float:
        """One value.  Always consumes exactly one draw of ``rng`` so streams stay aligned."""
        u = rng.random()
        if self.kind == "fixed":
            return float(self.values[0])
        if self.kind == "choice":
            return float(self.values[min(int(u * len(self.values)), len(self.values) - 1)])
        lo, hi = self.values
        return float(lo + u * (hi - lo))

    def to_toml(self) -> Any:
        """The TOML value this sweep was parsed from (canonical form)."""
        if self.kind == "fixed":
            return self.values[0]
        if self.kind == "choice":
            return list(self.values)
        return {"min": self.values[0], "max": self.values[1]}


#: a config key's number checks (rvdiag.validation's, in the ConfigError form "file [section] key: ...")
_number = functools.partial(number, error=ConfigError)
_int = functools.partial(whole_number, error=ConfigError)
_positive = functools.partial(positive, error=ConfigError)


def _bounded_sweeps(raw: Mapping[str, Any], bounds: Mapping[str, tuple[float, float]], w: str) -> dict[str, Sweep]:
    """The sweeps of those keys of ``bounds`` that ``raw`` has, each checked to lie in its ``(lo, hi)``."""
    out = {}
    for key, (lo, hi) in bounds.items():
        if key in raw:
            sweep = out[key] = Sweep.parse(raw[key], f"{w} {key}")
            if not (lo <= sweep.lo and sweep.hi <= hi):
                raise ConfigError(f"{w} {key}: must lie in [{lo:g}, {hi:g}], got {sweep.lo:g}..{sweep.hi:g}")
    return out


def _positive_sweep(raw: Any, where: str) -> Sweep:
    """A sweep whose every value is > 0."""
    sweep = Sweep.parse(raw, where)
    if sweep.lo <= 0:
        raise ConfigError(f"{where}: must be > 0, got {sweep.lo:g}")
    return sweep


#: ``[profile]`` gravity-arm keys, each a sweep, with the range it must lie in
ARM_KEYS: dict[str, tuple[float, float]] = {
    "arm_mass_kg": (0.0, 1000.0),
    "arm_length_m": (0.0, 10.0),
    "arm_angle_deg": (-360.0, 360.0),
}


def ramp_time(speed_deg_s: float, accel_deg_s2: float, jerk_deg_s3: float | None = None) -> float:
    """Time (s) a trapezoid (``jerk_deg_s3`` None) or an S-curve takes from rest to ``speed_deg_s``: the
    acceleration phase T_a of :meth:`rvdiag.dynamics.profile.SpeedProfile.ramp_times` (Biagiotti & Melchiorri
    2008, section 3.4), here without importing the simulator."""
    v, a = float(speed_deg_s), float(accel_deg_s2)
    if jerk_deg_s3 is None:
        return v / a
    j = float(jerk_deg_s3)
    tj = a / j if v * j >= a * a else math.sqrt(v / j)
    return tj + v / (j * tj)


@dataclass(frozen=True)
class ProfileConfig:
    """The ``[profile]`` table: speed and load profiles drawn per simulation (docs/library.md).

    ``trapezoid_fraction`` of the simulations run a trapezoid (from rest at the start of the run-in,
    accelerating at the drawn ``accel_deg_s2`` to the simulation's drawn output speed, cruising, decelerating
    to rest at the end of the record), ``scurve_fraction`` the same move jerk-limited at the drawn
    ``jerk_deg_s3`` (:class:`rvdiag.dynamics.profile.SpeedProfile`, ``kind="scurve"``); the others run at
    constant speed.  Every simulation carries a gravity arm of the drawn ``arm_mass_kg`` at ``arm_length_m``, at
    ``arm_angle_deg`` above the horizontal at the first recorded sample (no arm when the mass or the length is 0).
    """

    trapezoid_fraction: float = 0.0
    accel_deg_s2: Sweep | None = None
    arm: Mapping[str, Sweep] = field(default_factory=dict)
    scurve_fraction: float = 0.0
    jerk_deg_s3: Sweep | None = None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"trapezoid_fraction": self.trapezoid_fraction}
        if self.accel_deg_s2 is not None:
            out["accel_deg_s2"] = self.accel_deg_s2.to_toml()
        for key, sweep in self.arm.items():
            out[key] = sweep.to_toml()
        if self.scurve_fraction > 0 or self.jerk_deg_s3 is not None:  # only then: older configs keep their hash
            out["scurve_fraction"] = self.scurve_fraction
            if self.jerk_deg_s3 is not None:
                out["jerk_deg_s3"] = self.jerk_deg_s3.to_toml()
        return out


def _parse_profile(raw: Mapping[str, Any], w: str, *, speed_key: str, speed: Sweep, move_s: float,
                   model: Mapping[str, Any]) -> ProfileConfig:
    """Validate a ``[profile]`` table (``w``: "FILE: [profile]"; ``move_s``: transient + signal)."""
    frac = _number(raw.get("trapezoid_fraction", 0.0), f"{w} trapezoid_fraction")
    if not 0.0 <= frac <= 1.0:
        raise ConfigError(f"{w} trapezoid_fraction: must lie in [0, 1], got {frac:g}")
    sfrac = _number(raw.get("scurve_fraction", 0.0), f"{w} scurve_fraction")
    if not 0.0 <= sfrac <= 1.0 - frac + 1e-12:
        raise ConfigError(f"{w} scurve_fraction: must lie in [0, 1 - trapezoid_fraction] = [0, {1.0 - frac:g}], "
                          f"got {sfrac:g}")
    accel = None
    if "accel_deg_s2" in raw:
        accel = _positive_sweep(raw["accel_deg_s2"], f"{w} accel_deg_s2")
    jerk = None
    if "jerk_deg_s3" in raw:
        jerk = _positive_sweep(raw["jerk_deg_s3"], f"{w} jerk_deg_s3")
    if sfrac > 0 and jerk is None:
        raise ConfigError(f"{w} jerk_deg_s3: missing (scurve_fraction = {sfrac:g} needs a jerk limit)")
    for key, f_ in (("trapezoid_fraction", frac), ("scurve_fraction", sfrac)):
        if f_ <= 0:
            continue
        what = "a trapezoid" if key == "trapezoid_fraction" else "an S-curve"
        if accel is None:
            raise ConfigError(f"{w} accel_deg_s2: missing ({key} = {f_:g} needs an acceleration)")
        if speed_key != "output_speed_deg_s":
            raise ConfigError(
                f"{w} {key}: {what} cruises at an output speed; give [operation] output_speed_deg_s instead of "
                f"{speed_key}")
        # the slowest ramp: top speed, lowest limits
        need = 2.0 * ramp_time(speed.hi, accel.lo, jerk.lo if key == "scurve_fraction" else None)
        if need > move_s * (1.0 + 1e-12):
            limits = f"{accel.lo:g} deg/s^2" + ("" if key == "trapezoid_fraction" else f" and {jerk.lo:g} deg/s^3")
            raise ConfigError(
                f"{w} accel_deg_s2: at {limits} {what} needs {need:.4g} s to reach "
                f"{speed.hi:g} deg/s and stop again, longer than the {move_s:.4g} s of a simulation "
                f"(transient_s + duration_s): raise the limits or lengthen the simulation")
    arm = _bounded_sweeps(raw, ARM_KEYS, w)
    if (frac > 0 or sfrac > 0 or arm) and float(model.get("segment_s", 0.0) or 0.0) > 0:
        raise ConfigError(f"{w}: a speed or load profile runs as one segment: remove [model] segment_s")
    return ProfileConfig(frac, accel, arm, sfrac, jerk)


@dataclass(frozen=True)
class BaselineConfig:
    """The ``[baseline]`` table of a paired library (:mod:`rvdiag.library.paired`, docs/library.md "Paired
    libraries"), with ``[split] reducers`` and ``test_reducers``.

    Every simulated reducer has ``records_per_point`` healthy commissioning records at each of the
    ``operating_points`` (``(output speed deg/s, load N m)``), then ``monitored_healthy`` T1 records and
    ``monitored_per_state`` records of each other state, at operating points drawn among the same; ``variation``
    gives the run-to-run ranges in percent (keys of :data:`VARIATION_KEYS`).  The last
    ``test_reducers`` reducers form the test set, every record of them (the split is by reducer).
    """

    operating_points: tuple[tuple[float, float], ...]
    reducers: int
    test_reducers: int = 0
    records_per_point: int = 1
    monitored_healthy: int = 1
    monitored_per_state: int = 1
    variation: Mapping[str, float] = field(default_factory=dict)

    def schedule(self, states: Sequence[str]) -> list[tuple[str, str, int | None]]:
        """One reducer's records in order: ``(role, state, operating point index or None = drawn)``; the
        commissioning records first, point by point, then the monitored ones in T-number order."""
        out: list[tuple[str, str, int | None]] = [("baseline", "T1", i) for i in range(len(self.operating_points))
                                                  for _ in range(self.records_per_point)]
        for state in states:
            n = self.monitored_healthy if state == "T1" else self.monitored_per_state
            out += [("monitored", state, None)] * n
        return out

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"operating_points": [list(p) for p in self.operating_points],
                               "records_per_point": self.records_per_point,
                               "monitored_healthy": self.monitored_healthy,
                               "monitored_per_state": self.monitored_per_state}
        out.update({f"{k}_pct": v for k, v in self.variation.items()})
        return out


def _parse_baseline(raw: Mapping[str, Any], spl: Mapping[str, Any], w: str, ws: str, *, speed_key: str, speed: Sweep, load: Sweep, states: Sequence[str]) -> BaselineConfig:
    """Validate a ``[baseline]`` table and the paired ``[split]`` keys (``w``, ``ws``: "FILE: [baseline]",
    "FILE: [split]")."""
    if speed_key != "output_speed_deg_s":
        raise ConfigError(f"{w} operating_points: commissioning records are matched by output speed; give "
                          f"[operation] output_speed_deg_s instead of {speed_key}")
    if "T1" not in states:
        raise ConfigError(f"{w}: a paired library needs [states.T1] (the commissioning records and the healthy "
                          "monitored records the alarm is calibrated on)")
    for key in ("simulations_per_state", "test_simulations_per_state"):
        if key in spl:
            raise ConfigError(f"{ws} {key}: a paired library has records per reducer ([baseline] "
                              "monitored_per_state); give [split] reducers and test_reducers")
    if "reducers" not in spl:
        raise ConfigError(f"{ws} reducers: missing (simulated reducers of the paired library)")
    reducers = _int(spl["reducers"], f"{ws} reducers", minimum=1)
    test = _int(spl.get("test_reducers", 0), f"{ws} test_reducers", minimum=0)
    if test >= reducers:
        raise ConfigError(f"{ws} test_reducers: {test} leaves no training reducer out of reducers = {reducers}")
    pts = raw.get("operating_points")
    if not isinstance(pts, (list, tuple)) or not pts:
        raise ConfigError(f"{w} operating_points: missing; a list of [output speed deg/s, load N m] pairs, e.g. "
                          "[[30.0, 50.0], [60.0, 130.0]]")
    points = []
    for i, p in enumerate(pts):
        if not isinstance(p, (list, tuple)) or len(p) != 2:
            raise ConfigError(f"{w} operating_points[{i}]: expected [output speed deg/s, load N m], got {p!r}")
        v, t = _number(p[0], f"{w} operating_points[{i}][0]"), _number(p[1], f"{w} operating_points[{i}][1]")
        if not (speed.lo <= v <= speed.hi and load.lo <= t <= load.hi) or v <= 0 or t <= 0:
            raise ConfigError(f"{w} operating_points[{i}]: ({v:g} deg/s, {t:g} N m) must be > 0 and lie in the "
                              f"[operation] ranges ({speed.lo:g}..{speed.hi:g} deg/s, {load.lo:g}..{load.hi:g} N m)")
        points.append((v, t))
    if len(set(points)) != len(points):
        raise ConfigError(f"{w} operating_points: an operating point is listed twice")
    variation = {}
    for key, default in VARIATION_KEYS.items():
        variation[key] = _number(raw.get(f"{key}_pct", default), f"{w} {key}_pct")
        if not 0.0 <= variation[key] < 100.0:
            raise ConfigError(f"{w} {key}_pct: must lie in [0, 100) percent, got {variation[key]:g}")
    return BaselineConfig(
        operating_points=tuple(points), reducers=reducers, test_reducers=test,
        records_per_point=_int(raw.get("records_per_point", 1), f"{w} records_per_point", minimum=1),
        monitored_healthy=_int(raw.get("monitored_healthy", 1), f"{w} monitored_healthy", minimum=0),
        monitored_per_state=_int(raw.get("monitored_per_state", 1), f"{w} monitored_per_state", minimum=0),
        variation=variation)


@dataclass(frozen=True)
class HistoryConfig:
    """The ``[history]`` table of a life-history library (:mod:`rvdiag.library.life`, docs/library.md "Life
    histories"): after its commissioning records each reducer has ``records`` monitored records, one every
    ``interval_days``, along one fate drawn by the shares ``fates``, under a steady duty cycle (output speed, load,
    moving share of the hours).  Defaults: those of the synthetic histories (:class:`rvdiag.prognostics.synthetic.
    HistorySpec`): onset 30-200 days, wear coefficient 1e-17..3e-17 m^2/N (log-uniform) failing at 20 um, a 0.1 mm
    root crack at 30-60 deg breaking after 40-200 days at half the sun tooth's root chord, broken fraction 0.3-1."""

    records: int
    interval_days: float
    fates: Mapping[str, float]
    duty_speed_deg_s: float = 30.0
    duty_load_Nm: float = 120.0
    moving_fraction: float = 0.5
    onset_days: Sweep = Sweep("uniform", (30.0, 200.0))
    wear_coefficient: Sweep = Sweep("uniform", (1.0e-17, 3.0e-17))
    wear_failure_m: float = 20.0e-6
    crack_initial_m: float = 1.0e-4
    crack_angle_deg: Sweep = Sweep("uniform", (30.0, 60.0))
    crack_days: Sweep = Sweep("uniform", (40.0, 200.0))
    crack_failure_fraction: float = 0.5
    broken_fraction: Sweep = Sweep("uniform", (0.3, 1.0))
    sensor_fault_share: float = 0.0
    sensor_fault_kinds: tuple[str, ...] = ("dead", "clipped", "disconnected")

    @property
    def horizon_days(self) -> float:
        """The last record's time (days since commissioning)."""
        return self.records * self.interval_days

    def states(self) -> list[str]:
        """The states the configured fates pass through, in T-number order (T1 always)."""
        from rvdiag.library.life import FATE_STATES

        used = {"T1"} | {s for f, share in self.fates.items() if share > 0 for s in FATE_STATES[f]}
        return [s for s in STATES if s in used]

    def to_dict(self) -> dict[str, Any]:
        return {"records": self.records, "interval_days": self.interval_days,
                "duty_speed_deg_s": self.duty_speed_deg_s, "duty_load_Nm": self.duty_load_Nm,
                "moving_fraction": self.moving_fraction, "fates": dict(self.fates),
                "onset_days": self.onset_days.to_toml(), "wear_coefficient": self.wear_coefficient.to_toml(),
                "wear_failure_m": self.wear_failure_m, "crack_initial_m": self.crack_initial_m,
                "crack_angle_deg": self.crack_angle_deg.to_toml(), "crack_days": self.crack_days.to_toml(),
                "crack_failure_fraction": self.crack_failure_fraction,
                "broken_fraction": self.broken_fraction.to_toml(), "sensor_fault_share": self.sensor_fault_share,
                "sensor_fault_kinds": list(self.sensor_fault_kinds)}


def _parse_history(raw: Mapping[str, Any], w: str) -> HistoryConfig:
    """Validate a ``[history]`` table (``w``: "FILE: [history]"); every error names its key."""
    from rvdiag.library.life import FATE_STATES, SENSOR_FAULTS

    for key in ("records", "interval_days", "fates"):
        if key not in raw:
            raise ConfigError(f"{w} {key}: missing")
    d = HistoryConfig(records=1, interval_days=1.0, fates={})
    fates_raw = raw["fates"]
    if not isinstance(fates_raw, Mapping) or not fates_raw:
        raise ConfigError(f"{w} fates: a table of shares per fate, e.g. {{healthy = 0.5, wear = 0.2, crack = 0.2, "
                          "broken = 0.1}")
    fates = {}
    for fate, share in fates_raw.items():
        if fate in ("pitting", "spalling"):
            raise ConfigError(f"{w} fates: {fate!r} is not grown by a life history yet (no area-growth law); "
                              f"known: {', '.join(FATE_STATES)}")
        if fate not in FATE_STATES:
            raise ConfigError(f"{w} fates: unknown fate {fate!r}; known: {', '.join(FATE_STATES)}")
        fates[fate] = _number(share, f"{w} fates.{fate}")
        if fates[fate] < 0:
            raise ConfigError(f"{w} fates.{fate}: a share must be >= 0, got {fates[fate]:g}")
    if abs(sum(fates.values()) - 1.0) > 1e-9:
        raise ConfigError(f"{w} fates: the shares must add up to 1, got {sum(fates.values()):g}")
    fates = {f: fates[f] for f in FATE_STATES if f in fates}  # canonical order

    def positive(key: str, default: float) -> float:
        return _positive(raw.get(key, default), f"{w} {key}")

    def within(key: str, default: Sweep, lo: float, hi: float) -> Sweep:
        sweep = Sweep.parse(raw.get(key, default.to_toml()), f"{w} {key}")
        if not (lo <= sweep.lo and sweep.hi <= hi):
            raise ConfigError(f"{w} {key}: must lie in [{lo:g}, {hi:g}], got {sweep.lo:g}..{sweep.hi:g}")
        return sweep

    moving = positive("moving_fraction", d.moving_fraction)
    if moving > 1:
        raise ConfigError(f"{w} moving_fraction: the share of the hours the joint moves, in (0, 1], got {moving:g}")
    wear_fail = _number(raw.get("wear_failure_m", d.wear_failure_m), f"{w} wear_failure_m")
    wp = SEVERITY_PARAMETERS["wear_depth"]
    if not wp.lo <= wear_fail <= wp.hi:
        raise ConfigError(f"{w} wear_failure_m: must lie in wear_depth's valid range [{wp.lo:g}, {wp.hi:g}] m, "
                          f"got {wear_fail:g}")
    crack_fraction = positive("crack_failure_fraction", d.crack_failure_fraction)
    if crack_fraction >= 1:
        raise ConfigError(f"{w} crack_failure_fraction: the share of the sun tooth's root chord at which the "
                          f"tooth breaks, in (0, 1), got {crack_fraction:g}")
    a0 = positive("crack_initial_m", d.crack_initial_m)
    if a0 >= SEVERITY_PARAMETERS["crack_depth"].hi:
        raise ConfigError(f"{w} crack_initial_m: must be below crack_depth's upper end "
                          f"{SEVERITY_PARAMETERS['crack_depth'].hi:g} m, got {a0:g}")
    share = _number(raw.get("sensor_fault_share", d.sensor_fault_share), f"{w} sensor_fault_share")
    if not 0.0 <= share <= 1.0:
        raise ConfigError(f"{w} sensor_fault_share: the share of reducers whose sensor fails, in [0, 1], got "
                          f"{share:g}")
    kinds = raw.get("sensor_fault_kinds", list(d.sensor_fault_kinds))
    if not isinstance(kinds, (list, tuple)) or not kinds or any(k not in SENSOR_FAULTS for k in kinds) \
            or len(set(kinds)) != len(kinds):
        raise ConfigError(f"{w} sensor_fault_kinds: a list of distinct kinds among {', '.join(SENSOR_FAULTS)}, got "
                          f"{kinds!r}")
    ap, bp = SEVERITY_PARAMETERS["crack_angle_deg"], SEVERITY_PARAMETERS["broken_fraction"]
    return HistoryConfig(
        records=_int(raw["records"], f"{w} records", minimum=1),
        interval_days=positive("interval_days", 1.0),
        fates=fates,
        duty_speed_deg_s=positive("duty_speed_deg_s", d.duty_speed_deg_s),
        duty_load_Nm=positive("duty_load_Nm", d.duty_load_Nm),
        moving_fraction=moving,
        onset_days=_positive_sweep(raw.get("onset_days", d.onset_days.to_toml()), f"{w} onset_days"),
        wear_coefficient=within("wear_coefficient", d.wear_coefficient, 1e-20, 1e-13),
        wear_failure_m=wear_fail,
        crack_initial_m=a0,
        crack_angle_deg=within("crack_angle_deg", d.crack_angle_deg, ap.lo, ap.hi),
        crack_days=_positive_sweep(raw.get("crack_days", d.crack_days.to_toml()), f"{w} crack_days"),
        crack_failure_fraction=crack_fraction,
        broken_fraction=within("broken_fraction", d.broken_fraction, bp.lo, bp.hi),
        sensor_fault_share=share,
        sensor_fault_kinds=tuple(kinds),
    )


def _history_states(raw_states: Any, history: HistoryConfig, source: str) -> dict[str, Any]:
    """The ``[states]`` of a life-history config: those its fates pass through (:meth:`HistoryConfig.states`) when the
    file gives none; else the file's, which must hold them and no severity (a history grows its own)."""
    need = history.states()
    if raw_states is None:
        return {s: {} for s in need}
    if not isinstance(raw_states, Mapping):
        return raw_states
    for sname, raw in raw_states.items():
        if isinstance(raw, Mapping) and raw:
            raise ConfigError(f"{source}: [states.{sname}] {sorted(raw)[0]}: a life history grows its severities by "
                              "[history]; remove it")
    missing = [s for s in need if s not in raw_states]
    if missing:
        raise ConfigError(f"{source}: [history] fates: the fates reach {', '.join(need)}; add [states.{missing[0]}] "
                          "(or leave [states] out)")
    return raw_states


# ---------------------------------------------------------------------- the config
@dataclass(frozen=True)
class LibraryConfig:
    """A validated library config.  Build with :meth:`load` (TOML file) or :meth:`from_dict`.

    Attributes mirror the TOML keys (``docs/library.md`` documents each); ``states`` maps each state
    name, in T-number order, to its severity sweeps (every parameter of the state present).
    """

    name: str
    mode: str
    seed: int
    fs: float
    duration_s: float
    transient_s: float
    segment_length: int
    hop: int
    states: dict[str, dict[str, Sweep]]
    speed_key: str  # "input_speed_rpm" or "output_speed_deg_s"
    speed: Sweep
    load_Nm: Sweep
    noise_snr_db: Sweep | None
    stiffness_pct: float = 0.0
    damping_pct: float = 0.0
    #: ``[randomise]`` draws of ``[mounting]`` values (:data:`PATH_KEYS`), key -> sweep
    path: Mapping[str, Sweep] = field(default_factory=dict)
    #: ``[randomise] noise_colour_exponent``: the added noise's PSD falls as 1 / f^beta (0 white, 1 pink)
    noise_colour_exponent: Sweep | None = None
    #: the ``[profile]`` table, ``None`` when the config has none (constant speed and load)
    profile: ProfileConfig | None = None
    #: ``[randomise]`` draws of the accelerometer's position and direction (:data:`SENSOR_KEYS`), key -> sweep
    sensor: Mapping[str, Sweep] = field(default_factory=dict)
    #: ``[randomise] specimen``: every simulation draws its own manufacturing errors (:mod:`rvdiag.library.specimens`)
    specimen: bool = False
    #: ``[randomise] iso1328_grade``: the tolerance class drawn per specimen (whole numbers), ``None`` = the
    #: parameter file's
    iso1328_grade: Sweep | None = None
    #: ``[randomise] pin_wear_depth``: the cycloid-pin stage's wear drawn per simulation (m, ``[stage2]
    #: pin_wear_depth``, :mod:`rvdiag.gears.pin_wear`), ``None`` = the parameter file's
    pin_wear_depth: Sweep | None = None
    #: ``[operation] noise_mode`` (:data:`NOISE_MODES`); ``None``: not given, which is "record"
    noise_mode: str | None = None
    #: ``[operation] noise_density_ug_per_rthz``: a "floor" given as the sensor's noise density instead of an SNR
    noise_density_ug_per_rthz: Sweep | None = None
    #: the ``[baseline]`` table of a paired library (:class:`BaselineConfig`), ``None``: not paired
    baseline: BaselineConfig | None = None
    #: the ``[history]`` table of a life-history library (:class:`HistoryConfig`, with ``baseline``), else ``None``
    history: HistoryConfig | None = None
    train_per_state: int = 0
    test_per_state: int = 0
    assign: str = "random"
    simulations_per_state: int = 1
    test_simulations_per_state: int = 0
    simulator: str = DEFAULT_SIMULATOR
    params: str = ""
    channel: int | str = 0
    model: Mapping[str, Any] = field(default_factory=dict)
    source: str = field(default="<dict>", compare=False)
    base_dir: str = field(default="", compare=False)  # folder a relative ``params`` path is relative to

    # ------------------------------------------------------------------ derived sizes
    @property
    def classes(self) -> list[str]:
        """Class names in label order (T-number order)."""
        return list(self.states)

    @property
    def samples_per_signal(self) -> int:
        """Points kept per simulation (after the transient): ``round(duration_s * fs)``."""
        return int(round(self.duration_s * self.fs))

    @property
    def segments_per_simulation(self) -> int:
        """Segments cut from one simulation: ``floor((N - L) / hop) + 1``."""
        return (self.samples_per_signal - self.segment_length) // self.hop + 1

    def rows_per_simulation(self, state: str) -> int:
        """Samples a simulation of ``state`` contributes to the store."""
        if self.mode == "paper":
            return self.train_per_state + self.test_per_state
        return self.segments_per_simulation

    @property
    def noise_floor(self) -> bool:
        """The noise is a floor per simulated reducer and sensor (``noise_mode = "floor"``)."""
        return self.noise_mode == "floor"

    def noise_reference(self) -> tuple[float, float]:
        """``(speed, load_Nm)`` of the reference operating point of a "floor" noise level: the middle of the
        configured speed range (in ``speed_key``'s unit) and of the load range, at constant speed."""
        return 0.5 * (self.speed.lo + self.speed.hi), 0.5 * (self.load_Nm.lo + self.load_Nm.hi)

    @property
    def paired(self) -> bool:
        """The config has a ``[baseline]`` table: every reducer recorded healthy first, then in its states."""
        return self.baseline is not None

    @property
    def commissioning_records(self) -> int:
        """Commissioning records per reducer of a paired library (0 otherwise)."""
        if self.baseline is None:
            return 0
        return len(self.baseline.operating_points) * self.baseline.records_per_point

    @property
    def n_simulations(self) -> int:
        if self.history is not None and self.baseline is not None:
            return self.baseline.reducers * (self.commissioning_records + self.history.records)
        if self.baseline is not None:
            return self.baseline.reducers * len(self.baseline.schedule(self.classes))
        return len(self.states) * self.simulations_per_state

    @property
    def n_samples(self) -> int:
        if self.baseline is not None:
            return self.n_simulations * self.segments_per_simulation
        return sum(self.rows_per_simulation(s) * self.simulations_per_state for s in self.states)

    # ------------------------------------------------------------------ construction
    @classmethod
    def load(cls, path: str | Path) -> "LibraryConfig":
        """Read and validate a library TOML file; :class:`ConfigError` names the file and key.

        ``path`` may also name a config shipped with rvdiag (:func:`builtin_configs`): ``demo``, ``paper``,
        ``independent``, ``experiments/snr``, ... when no file of that name exists.
        """
        path = Path(path)
        if not path.exists() and path.suffix == "" and str(path) in builtin_configs():
            path = builtin_config_path(str(path))
        data = read_toml(path, "library config")
        cfg = cls.from_dict(data, source=str(path))
        object.__setattr__(cfg, "base_dir", str(path.resolve().parent))
        return cfg

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "<dict>") -> "LibraryConfig":
        """Validate a nested dict (as read from TOML)."""
        if not isinstance(data, Mapping):
            raise ConfigError(f"{source}: a library config must be a table")
        unknown = set(data) - _TOP_KEYS
        if unknown:
            raise ConfigError(f"{source}: unknown key {sorted(unknown)[0]!r} (known: {', '.join(sorted(_TOP_KEYS))})")
        sections = {}
        for sec, keys in _SECTION_KEYS.items():
            raw = data.get(sec, {})
            if not isinstance(raw, Mapping):
                raise ConfigError(f"{source}: [{sec}] must be a table")
            bad = set(raw) - keys
            if bad:
                raise ConfigError(f"{source}: [{sec}] unknown key {sorted(bad)[0]!r} (known: {', '.join(sorted(keys))})")
            sections[sec] = raw
        sig, op, rnd, spl = sections["signal"], sections["operation"], sections["randomise"], sections["split"]

        mode = data.get("mode", "paper")
        if mode in LEGACY_MODES:
            if source != "<store>":  # a store built before the rename says nothing the user can change
                import warnings

                from rvdiag.errors import RvdiagWarning

                warnings.warn(f"{source}: mode = {mode!r} is now spelled {LEGACY_MODES[mode]!r} (split by simulation: "
                              "no test sample shares a simulation with a training sample)", RvdiagWarning,
                              stacklevel=2)
            mode = LEGACY_MODES[mode]
        if mode not in MODES:
            raise ConfigError(f"{source}: mode: must be one of {', '.join(MODES)}, got {mode!r}")
        if "seed" not in data:
            raise ConfigError(f"{source}: seed: missing (every random draw derives from it)")
        seed = _int(data["seed"], f"{source}: seed", minimum=0)
        name = data.get("name", Path(source).stem if source != "<dict>" else "library")
        if not isinstance(name, str):
            raise ConfigError(f"{source}: name: expected a string, got {name!r}")
        simulator = data.get("simulator", DEFAULT_SIMULATOR)
        if not isinstance(simulator, str) or ":" not in simulator:
            raise ConfigError(f"{source}: simulator: expected 'module.path:function', got {simulator!r}")
        params = data.get("params", "")
        if not isinstance(params, str):
            raise ConfigError(f"{source}: params: expected a path string ('' = built-in RV-20E), got {params!r}")
        channel = data.get("channel", 0)
        if isinstance(channel, bool) or not isinstance(channel, (int, str)) or (isinstance(channel, int) and channel < 0):
            raise ConfigError(f"{source}: channel: expected a channel index >= 0 or name, got {channel!r}")

        model = data.get("model", {})
        if not isinstance(model, Mapping):
            raise ConfigError(f"{source}: [model] must be a table of simulator settings")
        model = dict(model)

        # --- signal
        w = f"{source}: [signal]"
        for key in ("fs", "duration_s", "segment_length"):
            if key not in sig:
                raise ConfigError(f"{w} {key}: missing")
        fs = _positive(sig["fs"], f"{w} fs")
        duration_s = _positive(sig["duration_s"], f"{w} duration_s")
        transient_s = _number(sig.get("transient_s", DEFAULT_TRANSIENT_S), f"{w} transient_s")
        if transient_s < 0:
            raise ConfigError(f"{w} transient_s: must be >= 0, got {transient_s:g}")
        segment_length = _int(sig["segment_length"], f"{w} segment_length", minimum=16)
        hop = _int(sig.get("hop", segment_length), f"{w} hop", minimum=1)
        n_keep = int(round(duration_s * fs))
        if segment_length > n_keep:
            raise ConfigError(
                f"{w} segment_length: {segment_length} points exceed the {n_keep} points of one simulation "
                f"(duration_s x fs = {duration_s:g} x {fs:g})"
            )

        # --- operation
        w = f"{source}: [operation]"
        speeds = [k for k in ("input_speed_rpm", "output_speed_deg_s") if k in op]
        if len(speeds) != 1:
            raise ConfigError(f"{w}: give exactly one of input_speed_rpm or output_speed_deg_s")
        speed_key = speeds[0]
        speed = _positive_sweep(op[speed_key], f"{w} {speed_key}")
        if "load_Nm" not in op:
            raise ConfigError(f"{w} load_Nm: missing (output load torque in N m)")
        load = Sweep.parse(op["load_Nm"], f"{w} load_Nm")
        if load.lo < 0:
            raise ConfigError(f"{w} load_Nm: must be >= 0, got {load.lo:g}")
        noise = None
        if "noise_snr_db" in op:
            noise = Sweep.parse(op["noise_snr_db"], f"{w} noise_snr_db")
            if not (-40.0 <= noise.lo and noise.hi <= 120.0):
                raise ConfigError(f"{w} noise_snr_db: must lie in [-40, 120] dB, got {noise.lo:g}..{noise.hi:g}")
        noise_mode = op.get("noise_mode")
        if noise_mode is not None and noise_mode not in NOISE_MODES:
            raise ConfigError(f"{w} noise_mode: must be one of {', '.join(NOISE_MODES)}, got {noise_mode!r}")
        density = None
        if "noise_density_ug_per_rthz" in op:
            density = _positive_sweep(op["noise_density_ug_per_rthz"], f"{w} noise_density_ug_per_rthz")
            if noise_mode != "floor":
                raise ConfigError(f"{w} noise_density_ug_per_rthz: a noise density is a floor; set noise_mode = "
                                  "\"floor\"")
            if noise is not None:
                raise ConfigError(f"{w} noise_density_ug_per_rthz: give noise_snr_db or a noise density, not both")
            if model.get("signal", "vibration") != "vibration":
                raise ConfigError(f"{w} noise_density_ug_per_rthz: an accelerometer's density (ug/sqrt(Hz)); a "
                                  "motor-current library gives noise_snr_db")
        if noise_mode == "floor" and noise is None and density is None:
            raise ConfigError(f"{w} noise_mode: \"floor\" needs noise_snr_db (below the healthy power) or "
                              "noise_density_ug_per_rthz")

        # --- randomise
        w = f"{source}: [randomise]"
        pct = {}
        for key in ("stiffness_pct", "damping_pct"):
            pct[key] = _number(rnd.get(key, 0.0), f"{w} {key}")
            if not 0.0 <= pct[key] < 100.0:
                raise ConfigError(f"{w} {key}: must lie in [0, 100) percent, got {pct[key]:g}")
        path = _bounded_sweeps(rnd, PATH_KEYS, w)
        sensor = _bounded_sweeps(rnd, SENSOR_KEYS, w)
        if sensor:
            for key in ("sensor_point_m", "sensor_directions"):
                if key in model:
                    raise ConfigError(f"{w} {next(iter(sensor))}: the sensor is drawn per simulation; remove [model] "
                                      f"{key}")
            if model.get("signal", "vibration") != "vibration":
                raise ConfigError(f"{w} {next(iter(sensor))}: a motor-current library has no accelerometer")
            if "channel" in data:
                raise ConfigError(f"{w} {next(iter(sensor))}: the channel is the drawn direction (the projection of "
                                  "the simulator's x and y channels); remove channel")
            if "sensor_position_deg" in sensor and data.get("simulator", DEFAULT_SIMULATOR) != DEFAULT_SIMULATOR:
                raise ConfigError(f"{w} sensor_position_deg: moves the dynamic model's sensor point ([model] "
                                  f"sensor_point_m); the simulator must be {DEFAULT_SIMULATOR}")
        colour = None
        if "noise_colour_exponent" in rnd:
            colour = Sweep.parse(rnd["noise_colour_exponent"], f"{w} noise_colour_exponent")
            if not (0.0 <= colour.lo and colour.hi <= 3.0):
                raise ConfigError(f"{w} noise_colour_exponent: must lie in [0, 3], got {colour.lo:g}..{colour.hi:g}")
            if noise is None and density is None:
                raise ConfigError(f"{w} noise_colour_exponent: needs [operation] noise_snr_db")
        specimen = rnd.get("specimen", False)
        if not isinstance(specimen, bool):
            raise ConfigError(f"{w} specimen: expected true or false, got {specimen!r}")
        grade = None
        if "iso1328_grade" in rnd:
            grade = Sweep.parse(rnd["iso1328_grade"], f"{w} iso1328_grade")
            if any(v != int(v) for v in grade.values) or not (0 <= grade.lo and grade.hi <= 11):
                raise ConfigError(f"{w} iso1328_grade: whole ISO 1328 classes in [0, 11], got {grade.to_toml()!r}")
            if not specimen:
                raise ConfigError(f"{w} iso1328_grade: drawn per specimen; add specimen = true")
        pin_wear = None
        if "pin_wear_depth" in rnd:
            from rvdiag.params.schema import MAX_PIN_WEAR_DEPTH

            pin_wear = Sweep.parse(rnd["pin_wear_depth"], f"{w} pin_wear_depth")
            if not (0.0 <= pin_wear.lo and pin_wear.hi <= MAX_PIN_WEAR_DEPTH):
                raise ConfigError(f"{w} pin_wear_depth: the cycloid-pin stage's wear (m) must lie in [0, "
                                  f"{MAX_PIN_WEAR_DEPTH:g}], got {pin_wear.to_toml()!r}")
            if "baseline" in data or "history" in data:
                raise ConfigError(f"{w} pin_wear_depth: drawn per simulation, which a paired or life-history "
                                  "library does not take (its reducer keeps one stage over its records)")

        # --- profile
        profile = None
        if "profile" in data:
            profile = _parse_profile(sections["profile"], f"{source}: [profile]", speed_key=speed_key, speed=speed,
                                     move_s=transient_s + duration_s, model=model)

        # --- states
        history = None
        if "history" in data:
            if not isinstance(data["history"], Mapping):
                raise ConfigError(f"{source}: [history] must be a table")
            if "baseline" not in data:
                raise ConfigError(f"{source}: [history]: a life history is a paired library (its first records are "
                                  "the commissioning ones); add a [baseline] table with operating_points")
            history = _parse_history(sections["history"], f"{source}: [history]")
        raw_states = data.get("states")
        if history is not None:
            raw_states = _history_states(raw_states, history, source)
        if not isinstance(raw_states, Mapping) or not raw_states:
            raise ConfigError(f"{source}: [states]: missing; add a table per state, e.g. [states.T1]")
        states: dict[str, dict[str, Sweep]] = {}
        for sname in raw_states:
            if sname not in STATES:
                raise ConfigError(f"{source}: [states.{sname}]: unknown state; known: {', '.join(STATES)}")
        for sname, st in STATES.items():  # T-number order = label order
            if sname not in raw_states:
                continue
            raw = raw_states[sname]
            w = f"{source}: [states.{sname}]"
            if not isinstance(raw, Mapping):
                raise ConfigError(f"{w}: must be a table of severity values")
            bad = set(raw) - set(st.parameters)
            if bad:
                raise ConfigError(
                    f"{w} {sorted(bad)[0]}: not a severity parameter of {sname} ({st.description}); "
                    f"it has: {', '.join(st.parameters) or 'none'}"
                )
            sweeps = {}
            for pname in st.parameters:
                sp = SEVERITY_PARAMETERS[pname]
                sweep = Sweep.parse(raw.get(pname, sp.default), f"{w} {pname}")
                for v in (sweep.lo, sweep.hi):
                    try:
                        sp.check(v)
                    except ParameterError as exc:
                        raise ConfigError(f"{w} {pname}: {exc}") from None
                sweeps[pname] = sweep
            states[sname] = sweeps
        if len(states) < 2:
            raise ConfigError(f"{source}: [states]: a classifier library needs at least two states")

        # --- split
        w = f"{source}: [split]"
        n_seg = (n_keep - segment_length) // hop + 1
        kw: dict[str, Any] = {}
        if mode == "paper":
            for key in ("simulations_per_state", "test_simulations_per_state", "reducers", "test_reducers"):
                if key in spl:
                    raise ConfigError(f"{w} {key}: only for mode = 'split-by-simulation' (paper mode has one simulation "
                                      "per state)")
            if "baseline" in data:
                raise ConfigError(f"{source}: [baseline]: a paired library splits by reducer; set mode = "
                                  "\"split-by-simulation\"")
            for key in ("train_per_state", "test_per_state"):
                if key not in spl:
                    raise ConfigError(f"{w} {key}: missing (paper mode splits each state's segments)")
            train = _int(spl["train_per_state"], f"{w} train_per_state", minimum=1)
            test = _int(spl["test_per_state"], f"{w} test_per_state", minimum=0)
            if train + test > n_seg:
                raise ConfigError(
                    f"{w}: train_per_state + test_per_state = {train + test} exceeds the {n_seg} segments of one "
                    f"simulation ({n_keep} points, segment_length {segment_length}, hop {hop}); "
                    f"lengthen [signal] duration_s or shorten the hop"
                )
            assign = spl.get("assign", "random")
            if assign not in SPLIT_ASSIGN:
                raise ConfigError(f"{w} assign: must be one of {', '.join(SPLIT_ASSIGN)}, got {assign!r}")
            kw.update(train_per_state=train, test_per_state=test, assign=assign, simulations_per_state=1)
        elif "baseline" in data:
            for key in ("train_per_state", "test_per_state", "assign"):
                if key in spl:
                    raise ConfigError(f"{w} {key}: a paired library splits by reducer (reducers, test_reducers)")
            if profile is not None and (profile.trapezoid_fraction > 0 or profile.scurve_fraction > 0
                                        or profile.accel_deg_s2 is not None or profile.jerk_deg_s3 is not None):
                raise ConfigError(f"{source}: [profile]: a paired library runs at constant speed (its records are "
                                  "matched by operating point); [profile] may hold only the gravity arm "
                                  f"({', '.join(ARM_KEYS)})")
            kw["baseline"] = _parse_baseline(sections["baseline"], spl, f"{source}: [baseline]", w,
                                             speed_key=speed_key, speed=speed, load=load, states=list(states))
            if history is not None:
                for key in ("monitored_healthy", "monitored_per_state"):
                    if key in sections["baseline"]:
                        raise ConfigError(f"{source}: [baseline] {key}: a life history's monitored records are "
                                          "[history] records; remove it")
                kw["history"] = history
        else:
            for key in ("train_per_state", "test_per_state", "assign"):
                if key in spl:
                    raise ConfigError(
                        f"{w} {key}: only for mode = 'paper'; mode split-by-simulation splits by simulation "
                        f"(simulations_per_state, test_simulations_per_state)"
                    )
            for key in ("reducers", "test_reducers"):
                if key in spl:
                    raise ConfigError(f"{w} {key}: only for a paired library (a [baseline] table)")
            if "simulations_per_state" not in spl:
                raise ConfigError(f"{w} simulations_per_state: missing")
            n_sim = _int(spl["simulations_per_state"], f"{w} simulations_per_state", minimum=1)
            n_test = _int(spl.get("test_simulations_per_state", 0), f"{w} test_simulations_per_state", minimum=0)
            if n_test >= n_sim:
                raise ConfigError(
                    f"{w} test_simulations_per_state: {n_test} leaves no training simulation out of "
                    f"simulations_per_state = {n_sim}"
                )
            kw.update(simulations_per_state=n_sim, test_simulations_per_state=n_test)

        return cls(
            name=name, mode=mode, seed=seed, fs=fs, duration_s=duration_s, transient_s=transient_s,
            segment_length=segment_length, hop=hop, states=states, speed_key=speed_key, speed=speed,
            load_Nm=load, noise_snr_db=noise, stiffness_pct=pct["stiffness_pct"], damping_pct=pct["damping_pct"],
            path=path, noise_colour_exponent=colour, profile=profile, sensor=sensor, specimen=specimen,
            iso1328_grade=grade, pin_wear_depth=pin_wear, noise_mode=noise_mode, noise_density_ug_per_rthz=density,
            simulator=simulator,
            params=params, channel=channel, model=model, source=source, **kw,
        )

    # ------------------------------------------------------------------ output
    def to_dict(self) -> dict[str, Any]:
        """Canonical nested dict (every default filled in); ``from_dict(to_dict())`` is equal.

        This is what the store keeps in its ``config`` attribute, and what its ``config_hash`` covers.
        """
        split: dict[str, Any]
        if self.mode == "paper":
            split = {"train_per_state": self.train_per_state, "test_per_state": self.test_per_state,
                     "assign": self.assign}
        elif self.baseline is not None:
            split = {"reducers": self.baseline.reducers, "test_reducers": self.baseline.test_reducers}
        else:
            split = {"simulations_per_state": self.simulations_per_state,
                     "test_simulations_per_state": self.test_simulations_per_state}
        operation: dict[str, Any] = {self.speed_key: self.speed.to_toml(), "load_Nm": self.load_Nm.to_toml()}
        if self.noise_snr_db is not None:
            operation["noise_snr_db"] = self.noise_snr_db.to_toml()
        if self.noise_mode is not None:  # only when given: older configs keep their hash
            operation["noise_mode"] = self.noise_mode
        if self.noise_density_ug_per_rthz is not None:
            operation["noise_density_ug_per_rthz"] = self.noise_density_ug_per_rthz.to_toml()
        out: dict[str, Any] = {
            "name": self.name,
            "mode": self.mode,
            "seed": self.seed,
            "simulator": self.simulator,
            "params": self.params,
            "channel": self.channel,
            "model": dict(self.model),
            "signal": {"fs": self.fs, "duration_s": self.duration_s, "transient_s": self.transient_s,
                       "segment_length": self.segment_length, "hop": self.hop},
            "operation": operation,
            "randomise": self._randomise_dict(),
            "split": split,
            "states": {s: {k: v.to_toml() for k, v in sw.items()} for s, sw in self.states.items()},
        }
        if self.profile is not None:  # only then: a config without it keeps its hash
            out["profile"] = self.profile.to_dict()
        if self.baseline is not None:  # only then: a config without it keeps its hash
            out["baseline"] = self.baseline.to_dict()
        if self.history is not None:  # only then: a config without it keeps its hash
            out["history"] = self.history.to_dict()
            for key in ("monitored_healthy", "monitored_per_state"):
                out["baseline"].pop(key)
            out["states"] = {s: {} for s in self.states}  # a history grows its severities
        return out

    def _randomise_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"stiffness_pct": self.stiffness_pct, "damping_pct": self.damping_pct}
        for key, sweep in self.path.items():
            out[key] = sweep.to_toml()
        if self.noise_colour_exponent is not None:
            out["noise_colour_exponent"] = self.noise_colour_exponent.to_toml()
        for key, sweep in self.sensor.items():  # only when drawn: older configs keep their hash
            out[key] = sweep.to_toml()
        if self.specimen:  # only when on: older configs keep their hash
            out["specimen"] = True
        if self.iso1328_grade is not None:
            out["iso1328_grade"] = self.iso1328_grade.to_toml()
        if self.pin_wear_depth is not None:  # only when drawn: older configs keep their hash
            out["pin_wear_depth"] = self.pin_wear_depth.to_toml()
        return out

    def replace(self, **changes: Any) -> "LibraryConfig":
        """Copy with top-level or section keys changed, re-validated: ``cfg.replace(seed=2)``,
        ``cfg.replace(signal={"duration_s": 2.0})``.  The tables ``signal``, ``operation``, ``randomise``,
        ``profile`` and ``split`` are updated key by key; ``states`` and ``model`` are replaced whole."""
        data = self.to_dict()
        for key, value in changes.items():
            if key in _SECTION_KEYS and isinstance(value, Mapping):
                data[key] = {**data.get(key, {}), **value}
            else:
                data[key] = value
        new = type(self).from_dict(data, source=self.source)
        object.__setattr__(new, "base_dir", self.base_dir)
        return new

    def reducer_params(self) -> Any:
        """The reducer parameter set: ``params`` (relative to the config file's folder), or the built-in
        RV-20E when ``params`` is empty."""
        from rvdiag.params import ReducerParams

        if not self.params:
            return ReducerParams.default()
        path = Path(self.params)
        if not path.is_absolute() and self.base_dir:
            path = Path(self.base_dir) / path
        return ReducerParams.load(path)

    def severity_parameters(self) -> list[str]:
        """Every severity parameter used by some configured state (metadata columns), in a fixed order."""
        used = {p for sw in self.states.values() for p in sw}
        return [p for p in SEVERITY_PARAMETERS if p in used]

    def describe(self) -> str:
        """One line: mode, states, simulations and samples."""
        if self.history is not None and self.baseline is not None:
            h = self.history
            return (f"{self.name}: life histories of {self.baseline.reducers} reducers, each "
                    f"{self.commissioning_records} commissioning + {h.records} records every {h.interval_days:g} days "
                    f"({self.n_simulations} simulations of {self.transient_s + self.duration_s:g} s, {self.n_samples} "
                    f"samples of {self.segment_length} points at {self.fs:g} Hz); fates "
                    + ", ".join(f"{f} {v:g}" for f, v in h.fates.items()))
        return (
            f"{self.name}: mode {self.mode}, {len(self.states)} states, {self.n_simulations} simulations of "
            f"{self.transient_s + self.duration_s:g} s, {self.n_samples} samples of {self.segment_length} points "
            f"at {self.fs:g} Hz"
        )


def split_counts(cfg: LibraryConfig) -> dict[str, int]:
    """Samples per state in each split (the same for every state)."""
    if cfg.mode == "paper":
        return {"train": cfg.train_per_state, "test": cfg.test_per_state}
    n = cfg.segments_per_simulation
    return {
        "train": n * (cfg.simulations_per_state - cfg.test_simulations_per_state),
        "test": n * cfg.test_simulations_per_state,
    }


def scaled_keys(cfg: LibraryConfig) -> Sequence[tuple[str, str, float]]:
    """``(section, key, pct)`` of every parameter the config randomises."""
    out = []
    if cfg.stiffness_pct > 0:
        out += [(s, k, cfg.stiffness_pct) for s, k in STIFFNESS_KEYS]
    if cfg.damping_pct > 0:
        out += [(s, k, cfg.damping_pct) for s, k in DAMPING_KEYS]
    return out
