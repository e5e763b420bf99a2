"""One unit of a sample library: what it is, and how a worker simulates it and cuts it into samples.

:class:`Unit` is one simulation of the plan (:func:`rvdiag.library.build.make_plan`) with every value drawn for it;
:class:`Job` is what a worker needs besides the unit.  :func:`run_unit` (the Dask task of a CPU build) is
:func:`simulator_call` (the unit's reducer, fault, operating point and seed), the simulator, then
:func:`finish_unit` (channel or sensor projection, noise, segments, metadata).  The GPU path
(:mod:`rvdiag.library.gpu`) prepares each unit with the same :func:`simulator_call` and finishes it with the same
:func:`finish_unit`.  Both the build (:mod:`rvdiag.library.build`) and the GPU path import this module, which
imports neither.

Each unit's output: the kept signal (after ``transient_s``) of the configured channel, plus white Gaussian
noise at the drawn SNR (``awgn(x, snr, 'measured')`` of MATLAB: noise power = mean(x^2) / 10^(SNR/10)),
cut into segments of ``segment_length`` points every ``hop`` points.
"""

from __future__ import annotations

import importlib
import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np

from rvdiag import __version__
from rvdiag.errors import ConfigError, SimulationError
from rvdiag.library.config import NOISE_REFERENCE_S, STANDARD_GRAVITY, LibraryConfig, scaled_keys
from rvdiag.library.paired import apply_variation
from rvdiag.library.specimens import apply_specimen
from rvdiag.library.states import FaultSpec

@dataclass(frozen=True)
class Unit:
    """One simulation of the plan, with every value drawn for it.

    Attributes
    ----------
    index : unit id (row block in the store)
    state : health state ("T1".."T8")
    sim_index : index of the simulation within its state
    seed : the unit's seed (all its random streams derive from it)
    severity : severity parameter -> value
    speed : input speed (rpm) or output speed (deg/s), see ``LibraryConfig.speed_key``
    load_Nm : output load torque (N m)
    noise_snr_db : SNR of the added noise (dB), ``None`` = no noise
    scales : ``"section.key"`` -> factor applied to that reducer parameter
    split : "train"/"test" for the whole unit (independent mode), ``None`` in paper mode (per segment)
    rows : samples the unit writes
    """

    index: int
    state: str
    sim_index: int
    seed: int
    severity: Mapping[str, float]
    speed: float
    load_Nm: float
    noise_snr_db: float | None
    scales: Mapping[str, float]
    split: str | None
    rows: int
    #: ``[mounting]`` key -> value drawn for this unit (``[randomise]`` path keys)
    mounting: Mapping[str, float] = field(default_factory=dict)
    #: colour of the added noise (PSD ~ 1 / f^beta), ``None`` = white
    noise_exponent: float | None = None
    #: ``[profile]`` draws (empty without ``[profile]``): ``profile`` (0 constant, 1 trapezoid, 2 S-curve),
    #: ``accel_deg_s2`` (``None`` at constant speed), ``arm_mass_kg``, ``arm_length_m``, ``arm_angle_deg``, and with
    #: S-curves in the config ``jerk_deg_s3`` (``None`` unless an S-curve)
    profile: Mapping[str, float | None] = field(default_factory=dict)
    #: ``[randomise]`` draws of the accelerometer (:data:`rvdiag.library.config.SENSOR_KEYS`): ``sensor_position_deg``
    #: and/or ``sensor_direction_deg`` (empty without them)
    sensor: Mapping[str, float] = field(default_factory=dict)
    #: ``[randomise] specimen`` draw (:func:`rvdiag.library.specimens.draw_specimen`): ``error_seed`` and, with an
    #: ``iso1328_grade`` sweep, the grade (empty without ``specimen``: the parameter file's specimen)
    specimen: Mapping[str, int] = field(default_factory=dict)
    #: ``noise_density_ug_per_rthz`` drawn for this unit ("floor" noise given as a density), else ``None``
    noise_density: float | None = None
    #: paired libraries (``[baseline]``, :mod:`rvdiag.library.paired`): the simulated reducer's id, the record's
    #: role ("baseline" or "monitored"), the index of its nominal operating point in ``[baseline] operating_points``
    #: and its run-to-run factors (:func:`rvdiag.library.paired.draw_variation`); ``None`` / empty otherwise
    reducer: int | None = None
    role: str | None = None
    operating_point: int | None = None
    variation: Mapping[str, float] = field(default_factory=dict)
    #: a life-history library (``[history]``, :mod:`rvdiag.library.life`): the record's truth, ``life.*`` column ->
    #: value (:data:`rvdiag.library.life.LIFE_COLUMNS`), its ``life.sensor_fault`` applied to the record; else empty
    life: Mapping[str, Any] = field(default_factory=dict)
    #: ``[randomise] pin_wear_depth`` drawn for this unit (m, ``[stage2] pin_wear_depth``), else ``None``
    pin_wear_depth: float | None = None

    def sensor_geometry(self, radius_m: float) -> tuple[tuple[float, float] | None, tuple[float, float]]:
        """``(sensor point (x, y) in m or None for the model's default, unit sensing direction (dx, dy))`` of the
        unit's drawn accelerometer on a housing of outer radius ``radius_m``: the point at the drawn position
        angle phi on that radius, the direction at phi + the drawn direction angle psi (from the outward radial),
        so position 0 and direction 0 / 90 deg give the model's default point and its x / y channel."""
        phi = math.radians(float(self.sensor.get("sensor_position_deg", 0.0)))
        psi = math.radians(float(self.sensor.get("sensor_direction_deg", 0.0)))
        point = None
        if "sensor_position_deg" in self.sensor:
            point = (radius_m * math.cos(phi), radius_m * math.sin(phi))
        return point, (math.cos(phi + psi), math.sin(phi + psi))

    def speed_profile(self, transient_s: float) -> Any:
        """The unit's :class:`rvdiag.dynamics.profile.SpeedProfile` (``None`` at constant speed): a trapezoid or
        an S-curve from rest at the start of the run-in (``-transient_s``) to rest at the end of the record."""
        kind = self.profile.get("profile")
        if not kind:
            return None
        from rvdiag.dynamics.profile import SpeedProfile

        if kind == 2:
            return SpeedProfile("scurve", float(self.speed), float(self.profile["accel_deg_s2"]), None,
                                -float(transient_s), float(self.profile["jerk_deg_s3"]))
        return SpeedProfile("trapezoid", float(self.speed), float(self.profile["accel_deg_s2"]), None,
                            -float(transient_s))

    def load_profile(self) -> Any:
        """The unit's :class:`rvdiag.dynamics.profile.LoadProfile` (``None`` without a gravity arm)."""
        mass, length = self.profile.get("arm_mass_kg") or 0.0, self.profile.get("arm_length_m") or 0.0
        if mass <= 0.0 or length <= 0.0:
            return None
        from rvdiag.dynamics.profile import LoadProfile

        return LoadProfile(float(mass), float(length), float(self.profile.get("arm_angle_deg") or 0.0))


def _streams(unit_seed: int) -> list[np.random.SeedSequence]:
    """The four independent streams of a unit: draws, simulator seed, noise, split (the fifth, the specimen's, is
    :func:`rvdiag.library.specimens.specimen_seed`)."""
    return np.random.SeedSequence(unit_seed).spawn(4)


@dataclass(frozen=True)
class Job:
    """What a worker needs besides the unit: small and picklable."""

    simulator: str
    params: Mapping[str, Any]
    mode: str
    fs: float
    duration_s: float
    transient_s: float
    samples_per_signal: int
    segment_length: int
    hop: int
    channel: int | str
    speed_key: str
    train_per_state: int
    test_per_state: int
    assign: str
    severity_columns: tuple[str, ...]
    scale_columns: tuple[str, ...] = field(default_factory=tuple)
    model: Mapping[str, Any] = field(default_factory=dict)
    #: the config has a ``[profile]`` table: pass the profiles, record their columns
    profile_columns: bool = False
    #: ``[operation] noise_mode`` (``None``: not given, "record" without its columns)
    noise_mode: str | None = None
    #: ``(speed, load_Nm)`` of a "floor" noise level's healthy twin (:meth:`LibraryConfig.noise_reference`)
    noise_reference: tuple[float, float] | None = None
    #: the config draws specimens: record ``error_seed`` and ``iso1328_grade``
    specimen_columns: bool = False
    #: a paired library: record ``reducer``, ``role``, ``operating_point`` and the run-to-run factors
    paired_columns: bool = False
    #: a life-history library: record the ``life.*`` truth columns and apply the records' sensor faults
    life_columns: bool = False
    #: the config draws the cycloid-pin stage's wear: record ``pin_wear_depth``
    pin_wear_column: bool = False
    #: the client's rvdiag release and physics revision: a worker running other code refuses the unit
    #: (``None``: not checked)
    rvdiag_version: str | None = None
    physics_revision: str | None = None

    @classmethod
    def from_config(cls, cfg: LibraryConfig, params: Any) -> "Job":
        return cls(
            simulator=cfg.simulator, params=params.to_dict(), mode=cfg.mode, fs=cfg.fs,
            duration_s=cfg.duration_s, transient_s=cfg.transient_s, samples_per_signal=cfg.samples_per_signal,
            segment_length=cfg.segment_length, hop=cfg.hop, channel=cfg.channel, speed_key=cfg.speed_key,
            train_per_state=cfg.train_per_state, test_per_state=cfg.test_per_state, assign=cfg.assign,
            severity_columns=tuple(cfg.severity_parameters()),
            scale_columns=tuple(f"{s}.{k}" for s, k, _ in scaled_keys(cfg)), model=dict(cfg.model),
            profile_columns=cfg.profile is not None, rvdiag_version=__version__,
            physics_revision=_physics_revision(), noise_mode=cfg.noise_mode,
            noise_reference=cfg.noise_reference() if cfg.noise_floor else None, specimen_columns=cfg.specimen,
            paired_columns=cfg.paired, life_columns=cfg.history is not None,
            pin_wear_column=cfg.pin_wear_depth is not None,
        )


@dataclass
class UnitResult:
    """A unit's samples (float32, rows x segment_length) and metadata columns (one value per row)."""

    index: int
    X: np.ndarray
    labels: list[str]
    meta: dict[str, list[Any]]
    wall_s: float


def resolve_simulator(path: str, model: Mapping[str, Any] | None = None) -> Callable[..., Any]:
    """Import ``"package.module:function"`` (:class:`ConfigError` if it cannot be found); with ``model``,
    also validate the ``[model]`` table with the module's ``check_options`` when it has one."""
    module_name, _, attr = path.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ConfigError(f"simulator {path!r}: cannot import module {module_name!r} ({exc})") from None
    fn = getattr(module, attr, None)
    if not callable(fn):
        raise ConfigError(f"simulator {path!r}: module {module_name!r} has no function {attr!r}")
    check = getattr(module, "check_options", None)
    if model is not None and callable(check):
        check(dict(model))
    return fn


def _channel(result: Any, channel: int | str) -> np.ndarray:
    sig = np.asarray(result.signal, dtype=np.float64)
    if sig.ndim == 1:
        sig = sig[None, :]
    if isinstance(channel, str):
        names = list(getattr(result, "channel_names", None) or [])
        if channel not in names:
            raise ConfigError(f"channel {channel!r}: the simulator's channels are {names}")
        channel = names.index(channel)
    if channel >= sig.shape[0]:
        raise ConfigError(f"channel {channel}: the simulator returned {sig.shape[0]} channel(s)")
    return sig[channel]


def project_sensor(result: Any, direction: tuple[float, float]) -> np.ndarray:
    """The acceleration along the unit vector ``direction`` from the simulator's first two channels, taken as the
    housing acceleration along x and y at the sensor point: ``dx a_x + dy a_y`` (the dynamic model's channel for
    a sensor direction, docs/model.md section 6, is this projection; the sensor path filter is linear, so
    projecting after it is the same)."""
    sig = np.asarray(result.signal, dtype=np.float64)
    if sig.ndim != 2 or sig.shape[0] < 2:
        raise ConfigError("[randomise] sensor_direction_deg needs a simulator that returns the x and y channels "
                          f"(2 or more), got shape {sig.shape}")
    return float(direction[0]) * sig[0] + float(direction[1]) * sig[1]


def segment_starts(n_points: int, length: int, hop: int) -> np.ndarray:
    """Start index of every segment of ``length`` points every ``hop`` points in ``n_points``."""
    return np.arange(0, n_points - length + 1, hop, dtype=np.int64)


def window_angles(unit: Unit, job: Job, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Output (carrier) angle at the first point of each window (deg, 0 at the first recorded sample) and the
    window's mean output speed (deg/s: the angle it turns through over its length), from the unit's speed
    profile in closed form (:meth:`rvdiag.dynamics.profile.SpeedProfile.state`, the simulator's own angles)."""
    from rvdiag.dynamics.profile import SpeedProfile

    if job.speed_key == "output_speed_deg_s":
        omega = np.radians(unit.speed)
    else:  # input rpm -> output rad/s through the reducer's ratio
        from rvdiag.params import ReducerParams

        omega = unit.speed * 2.0 * np.pi / 60.0 / ReducerParams.from_dict(dict(job.params), source="<library>").ratio
    profile = unit.speed_profile(job.transient_s) or SpeedProfile()
    t0 = np.asarray(starts, dtype=np.float64) / job.fs
    th0 = profile.state(t0, omega, job.duration_s)[0]
    th1 = profile.state(t0 + job.segment_length / job.fs, omega, job.duration_s)[0]
    return np.degrees(th0), np.degrees(th1 - th0) * job.fs / job.segment_length


def _physics_revision() -> str:
    from rvdiag.dynamics import PHYSICS_REVISION

    return PHYSICS_REVISION


def check_worker(job: Job) -> None:
    """Refuse to simulate for a client of another rvdiag release or physics revision (:class:`ConfigError`): a
    cluster whose workers run other code would mix two simulators' samples in one store."""
    if job.rvdiag_version is None and job.physics_revision is None:
        return
    mine = (__version__, _physics_revision())
    if mine != (job.rvdiag_version, job.physics_revision):
        raise ConfigError(
            f"this Dask worker runs rvdiag {mine[0]} (physics {mine[1]}) and the client rvdiag {job.rvdiag_version} "
            f"(physics {job.physics_revision}): install the client's rvdiag on every worker"
        )


def run_unit(unit: Unit, job: Job) -> UnitResult:
    """Simulate one unit and cut it into samples (the Dask task; pure function of its arguments):
    :func:`simulate_unit`, then :func:`finish_unit`."""
    check_worker(job)
    t0 = time.perf_counter()
    return finish_unit(unit, job, simulate_unit(unit, job), t0)


def unit_params(unit: Unit, job: Job, varied: bool = True) -> Any:
    """The :class:`rvdiag.params.ReducerParams` of the reducer ``unit`` simulates: the job's, scaled and mounted as
    drawn, with the unit's specimen, and (``varied``, paired libraries) the record's run-to-run temperature and mesh
    damping (:func:`rvdiag.library.paired.apply_variation`)."""
    from rvdiag.params import ReducerParams

    params = ReducerParams.from_dict(dict(job.params), source="<library>")
    if unit.scales:
        changes: dict[str, dict[str, float]] = {}
        for name, factor in unit.scales.items():
            section, key = name.split(".")
            changes.setdefault(section, {})[key] = getattr(getattr(params, section), key) * factor
        params = params.replace(**changes)
    if unit.mounting:
        params = params.replace(mounting=dict(unit.mounting))
    params = apply_specimen(params, unit.specimen)
    if unit.pin_wear_depth is not None:
        params = params.replace(stage2={"pin_wear_depth": unit.pin_wear_depth})
    if varied and unit.variation:
        params = apply_variation(params, unit.variation)
    return params


def simulator_call(unit: Unit, job: Job, twin: bool = False) -> tuple[Callable[..., Any], tuple[Any, ...],
                                                                       dict[str, Any]]:
    """``(simulator, args, kwargs)``: the call of the simulator that simulates ``unit`` (its reducer parameters
    scaled and mounted as drawn, its specimen, fault, speed, load, profiles and the simulator's seed).

    ``twin``: the call of the unit's healthy twin instead, whose power sets a "floor" noise level (docs/library.md,
    "Noise"): the same reducer and sensor, healthy, at the job's reference point (:attr:`Job.noise_reference`) at
    constant speed without a gravity arm, :data:`rvdiag.library.config.NOISE_REFERENCE_S` recorded after the
    job's transient, simulator seed 0 (so the twin depends on the reducer alone, not on the unit's seed, nor on a
    paired record's run-to-run variation: one floor per reducer)."""
    params = unit_params(unit, job, varied=not twin)
    spec = FaultSpec("T1", {}) if twin else FaultSpec(unit.state, unit.severity)
    sim = resolve_simulator(job.simulator)
    fault = spec if getattr(sim, "accepts_fault_spec", False) else spec.to_tooth_faults()
    sim_ss = _streams(unit.seed)[1]
    sim_seed = int(sim_ss.generate_state(1, np.uint32)[0])
    model = dict(job.model)
    if unit.sensor:  # a drawn sensor position moves the model's sensor point; the direction is projected after
        point = unit.sensor_geometry(params.bodies.pin_wheel_outer_radius)[0]
        if point is not None:
            model["sensor_point_m"] = list(point)
    if twin:
        speed, load = job.noise_reference or (unit.speed, unit.load_Nm)
        return sim, (params, fault), {job.speed_key: speed, "load_Nm": load, "transient_s": job.transient_s,
                                      "duration_s": min(NOISE_REFERENCE_S, job.duration_s), "fs": job.fs, "seed": 0,
                                      "model": model}
    profiles: dict[str, Any] = {}
    if unit.profile:  # passed only when drawn: a simulator without profiles keeps working on other configs
        speed_profile, load_profile = unit.speed_profile(job.transient_s), unit.load_profile()
        if speed_profile is not None:
            profiles["profile"] = speed_profile
        if load_profile is not None:
            profiles["load_profile"] = load_profile
    kwargs = {job.speed_key: unit.speed, "load_Nm": unit.load_Nm, "duration_s": job.duration_s,
              "transient_s": job.transient_s, "fs": job.fs, "seed": sim_seed, "model": model, **profiles}
    return sim, (params, fault), kwargs


def simulate_unit(unit: Unit, job: Job) -> Any:
    """The simulation step of :func:`run_unit`: the simulator's result for ``unit`` (:func:`simulator_call`)."""
    sim, args, kwargs = simulator_call(unit, job)
    return sim(*args, **kwargs)


def kept_signal(unit: Unit, job: Job, result: Any, n_points: int) -> np.ndarray:
    """The first ``n_points`` of the signal the unit keeps from the simulator's ``result`` (its channel, or the
    projection on its drawn sensor direction), checked: the rate, the length, finite values."""
    direction = unit.sensor_geometry(1.0)[1] if unit.sensor else None  # the point went to the simulator
    if abs(float(getattr(result, "fs", job.fs)) - job.fs) > 1e-9 * job.fs:
        raise SimulationError(f"simulator returned fs = {result.fs} Hz, asked for {job.fs} Hz")
    x = _channel(result, job.channel) if direction is None else project_sensor(result, direction)
    if x.shape[0] < n_points:
        raise SimulationError(f"simulator returned {x.shape[0]} points, expected {n_points}")
    x = x[:n_points]
    if not np.all(np.isfinite(x)):
        raise SimulationError(f"unit {unit.index} ({unit.state}): the simulated signal contains NaN or Inf")
    return x


#: healthy-twin powers computed in this process, by reducer (:func:`twin_power`); bounded, oldest dropped first
_TWIN_POWERS: dict[str, float] = {}
_TWIN_CACHE_SIZE = 256


def twin_key(unit: Unit, job: Job) -> str:
    """What a unit's healthy twin depends on: the reducer's parameters and specimen, the sensor, the simulator, the
    reference point and the record's rate and transient (not the unit's state, operating point or seed).  Units of a
    config that randomises nothing share one key: one reducer, one noise floor, simulated once per process."""
    import json

    key = [job.simulator, job.params, sorted(unit.scales.items()), sorted(unit.mounting.items()),
           sorted(unit.specimen.items()), sorted(unit.sensor.items()), job.channel, dict(job.model),
           job.noise_reference, job.speed_key, job.fs, job.transient_s, job.duration_s]
    if unit.pin_wear_depth is not None:  # the twin is the same reducer, its stage worn as drawn
        key.append(unit.pin_wear_depth)
    return json.dumps(key, sort_keys=True, default=str)


def twin_power(unit: Unit, job: Job, result: Any = None) -> float:
    """Mean square of the unit's healthy twin (:func:`simulator_call` with ``twin=True``), the reference of a
    "floor" noise level; simulated here unless ``result`` (the twin's simulator result, e.g. from a GPU ensemble)
    is given, and kept per reducer (:func:`twin_key`) for the other units of the same reducer in this process."""
    key = twin_key(unit, job)
    if key in _TWIN_POWERS:
        return _TWIN_POWERS[key]
    if result is None:
        sim, args, kwargs = simulator_call(unit, job, twin=True)
        result = sim(*args, **kwargs)
    x = kept_signal(unit, job, result, int(round(min(NOISE_REFERENCE_S, job.duration_s) * job.fs)))
    power = float(np.mean(x * x))
    if len(_TWIN_POWERS) >= _TWIN_CACHE_SIZE:
        del _TWIN_POWERS[next(iter(_TWIN_POWERS))]
    _TWIN_POWERS[key] = power
    return power


def needs_twin(unit: Unit, job: Job) -> bool:
    """The unit's noise is a floor below its healthy twin's power, and this process has no twin of its reducer."""
    return (job.noise_mode == "floor" and unit.noise_density is None and unit.noise_snr_db is not None
            and twin_key(unit, job) not in _TWIN_POWERS)


def floor_noise_power(unit: Unit, job: Job, twin: Any = None) -> float | None:
    """The mean square of a "floor" unit's noise (``None`` for a unit without noise): the drawn SNR below its
    healthy twin's power (:func:`twin_power`, ``twin`` its simulator result if already simulated), or the drawn
    density ``D`` (ug/sqrt(Hz), one-sided) over the record's band, ``(D 1e-6 g)^2 fs / 2`` (m/s^2 squared)."""
    if unit.noise_density is not None:
        return (unit.noise_density * 1e-6 * STANDARD_GRAVITY) ** 2 * job.fs / 2.0
    if unit.noise_snr_db is None:
        return None
    return twin_power(unit, job, twin) * 10.0 ** (-unit.noise_snr_db / 10.0)


def finish_unit(unit: Unit, job: Job, result: Any, t0: float, twin: Any = None) -> UnitResult:
    """The post-processing step of :func:`run_unit`: the simulator's ``result`` checked, its channel kept, the
    unit's noise added and the record cut into samples with their metadata (``t0``: when the unit started, for
    ``wall_s``; ``twin``: the healthy twin's simulator result of a "floor" unit, when already simulated)."""
    _, _, noise_ss, split_ss = _streams(unit.seed)
    x = kept_signal(unit, job, result, job.samples_per_signal)
    del result  # keep only the one channel
    if unit.variation:  # a paired record's sensor gain, before the sensor's own noise floor
        x = x * unit.variation["gain"]
    sigma = None
    if job.noise_mode == "floor":
        from rvdiag.dynamics.noise import add_noise_power  # here: keep numba out of `import rvdiag.library`

        power = floor_noise_power(unit, job, twin)
        if power is not None:
            sigma = math.sqrt(power)
            x = add_noise_power(x, power, unit.noise_exponent or 0.0, np.random.default_rng(noise_ss))
    elif unit.noise_snr_db is not None:
        from rvdiag.dynamics.noise import add_coloured_noise, snr_power

        if job.noise_mode is not None:
            sigma = math.sqrt(float(snr_power(x, unit.noise_snr_db).item()))
        x = add_coloured_noise(x, unit.noise_snr_db, unit.noise_exponent or 0.0, np.random.default_rng(noise_ss))
    fault = unit.life.get("life.sensor_fault") if job.life_columns else None
    if fault:  # a life history's failed sensor, after the sensor's own noise: what the acquisition records
        from rvdiag.library.life import SENSOR_FAULT_STREAM, apply_sensor_fault

        x = apply_sensor_fault(x, fault, np.random.default_rng(np.random.SeedSequence(
            unit.seed, spawn_key=(SENSOR_FAULT_STREAM,))))
    starts = segment_starts(x.shape[0], job.segment_length, job.hop)
    if job.mode == "paper":
        n = starts.shape[0]
        if job.assign == "random":
            perm = np.random.default_rng(split_ss).permutation(n)
            train_idx, test_idx = perm[: job.train_per_state], perm[job.train_per_state: job.train_per_state + job.test_per_state]
        else:  # "ordered": the first segments train, the last ones test
            train_idx = np.arange(job.train_per_state)
            test_idx = np.arange(n - job.test_per_state, n)
        chosen = np.sort(np.concatenate([train_idx, test_idx])).astype(np.int64)
        test_set = set(test_idx.tolist())
        splits = ["test" if i in test_set else "train" for i in chosen.tolist()]
    else:
        chosen = np.arange(starts.shape[0])
        splits = [unit.split] * chosen.shape[0]
    X = np.stack([x[s: s + job.segment_length] for s in starts[chosen]]).astype(np.float32)
    rows = X.shape[0]
    meta: dict[str, list[Any]] = {
        "split": splits,
        "state": [unit.state] * rows,
        "simulation": [unit.sim_index] * rows,
        "seed": [unit.seed] * rows,
        "segment": chosen.tolist(),
        "t_start_s": (starts[chosen] / job.fs).tolist(),
        job.speed_key: [unit.speed] * rows,
        "load_Nm": [unit.load_Nm] * rows,
        "noise_snr_db": [unit.noise_snr_db] * rows,
    }
    for p in job.severity_columns:
        meta[p] = [unit.severity.get(p)] * rows
    for name in job.scale_columns:
        meta["scale." + name] = [unit.scales[name]] * rows
    for name, value in unit.mounting.items():
        meta["mounting." + name] = [value] * rows
    if unit.noise_exponent is not None:
        meta["noise_colour_exponent"] = [unit.noise_exponent] * rows
    for name, value in unit.sensor.items():
        meta[name] = [value] * rows
    if job.noise_mode is not None:  # only when the config names its mode: older stores keep their columns
        meta["noise_mode"] = [job.noise_mode] * rows
        meta["noise_sigma"] = [sigma] * rows
        if unit.noise_density is not None:
            meta["noise_density_ug_per_rthz"] = [unit.noise_density] * rows
    if job.specimen_columns:
        grade = unit.specimen.get("iso1328_grade", dict(job.params.get("modification") or {}).get("iso1328_grade"))
        meta["error_seed"] = [unit.specimen["error_seed"]] * rows
        meta["iso1328_grade"] = [grade] * rows
    if job.pin_wear_column:
        meta["pin_wear_depth"] = [unit.pin_wear_depth] * rows
    if job.paired_columns:
        meta["reducer"] = [unit.reducer] * rows
        meta["role"] = [unit.role] * rows
        meta["operating_point"] = [unit.operating_point] * rows
        for key, value in unit.variation.items():
            meta["variation." + key] = [value] * rows
    if job.life_columns:
        for key, value in unit.life.items():
            meta[key] = [value] * rows
    if job.profile_columns:
        for key, value in unit.profile.items():
            meta[key] = [value] * rows
        theta0, speed = window_angles(unit, job, starts[chosen])
        meta["theta_out_start_deg"] = theta0.tolist()
        meta["window_speed_deg_s"] = speed.tolist()
    return UnitResult(unit.index, X, [unit.state] * rows, meta, time.perf_counter() - t0)
