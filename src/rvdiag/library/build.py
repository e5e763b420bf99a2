"""Build a sample library: a plan of simulations, run on Dask, written unit by unit into a sample store.

The plan
--------
A *unit* is one simulation.  Units are numbered state by state (T-number order), simulation by
simulation.  Unit ``u`` gets its own seed from the config's master seed::

    children = numpy.random.SeedSequence(seed).spawn(n_units)
    unit_seed = 63-bit integer from children[u].generate_state

and every random draw of the unit comes from ``SeedSequence(unit_seed)``, split into four independent
streams: the draws (severities, operating point, SNR, parameter scales, then the ``[randomise]`` path
and the ``[profile]`` draws, in that fixed order), the
simulator's seed, the noise, and (paper mode) the assignment of segments to train/test.  The recorded
``seed`` column therefore reproduces any one simulation alone, and the arrays do not depend on how many
workers ran the build, nor on the order in which units finished.

Running
-------
By default a :class:`distributed.LocalCluster` with one single-threaded worker process per core runs the
units; ``scheduler=ADDRESS`` sends the same tasks to an existing Dask cluster instead; ``workers=0`` runs
them in this process without Dask (debugging).  The client keeps at most one task per worker thread in
flight and fetches each result as soon as it completes (``as_completed``), so a worker never holds more
than one simulation's signal; the client writes each result with :class:`rvdiag.datasets.StoreBuilder`,
which commits the unit atomically.  Re-running the same build skips committed units (resume after a
crash, SIGKILL or Ctrl-C); a store built from another config is refused.  ``device="cuda"`` integrates the units
in ensembles on a GPU, one task per ensemble, and finishes each unit as here (:mod:`rvdiag.library.gpu`).

Each unit's output: the kept signal (after ``transient_s``) of the configured channel, plus white Gaussian
noise at the drawn SNR (``awgn(x, snr, 'measured')`` of MATLAB: noise power = mean(x^2) / 10^(SNR/10)),
cut into segments of ``segment_length`` points every ``hop`` points.
"""

from __future__ import annotations

import importlib
import math
import os
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping

import numpy as np

from rvdiag import __version__
from rvdiag.datasets import StoreBuilder, config_hash
from rvdiag.errors import ConfigError, RvdiagError, SimulationError, StoreError
from rvdiag.library.config import ARM_KEYS, LibraryConfig, scaled_keys
from rvdiag.library.states import STATES, FaultSpec
from rvdiag.library.worker_warnings import Caught, caught, reissue

#: Key added to the stored config so that its hash also covers the reducer parameter values.
PARAMS_HASH_KEY = "reducer_params_hash"
#: Key added to the stored config so that its hash also covers the simulator's physics revision
#: (:data:`rvdiag.dynamics.PHYSICS_REVISION`): a store simulated by other physics is never resumed or mixed.
PHYSICS_KEY = "physics_revision"


# ---------------------------------------------------------------------- plan
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
    """The four independent streams of a unit: draws, simulator seed, noise, split."""
    return np.random.SeedSequence(unit_seed).spawn(4)


def unit_seeds(seed: int, n_units: int) -> list[int]:
    """Per-unit 63-bit seeds spawned from the master seed (``SeedSequence(seed).spawn(n_units)``)."""
    out = []
    for child in np.random.SeedSequence(seed).spawn(n_units):
        hi, lo = child.generate_state(2, np.uint32).tolist()
        out.append(((hi << 32) | lo) & 0x7FFF_FFFF_FFFF_FFFF)
    return out


def make_plan(cfg: LibraryConfig) -> list[Unit]:
    """Every unit of the library with its drawn values (deterministic in ``cfg``)."""
    seeds = unit_seeds(cfg.seed, cfg.n_simulations)
    keys = scaled_keys(cfg)
    units = []
    u = 0
    for state, sweeps in cfg.states.items():
        for k in range(cfg.simulations_per_state):
            rng = np.random.default_rng(_streams(seeds[u])[0])
            severity = {p: sw.draw(rng) for p, sw in sweeps.items()}
            speed = cfg.speed.draw(rng)
            load = cfg.load_Nm.draw(rng)
            snr = None if cfg.noise_snr_db is None else cfg.noise_snr_db.draw(rng)
            scales = {f"{s}.{key}": float(1.0 + pct / 100.0 * rng.uniform(-1.0, 1.0)) for s, key, pct in keys}
            split = None
            if cfg.mode == "independent":
                split = "test" if k >= cfg.simulations_per_state - cfg.test_simulations_per_state else "train"
            # drawn after every earlier draw, so a config without them keeps its units bit for bit
            mounting = {key: float(sw.draw(rng)) for key, sw in cfg.path.items()}
            colour = None if cfg.noise_colour_exponent is None else float(cfg.noise_colour_exponent.draw(rng))
            profile = {} if cfg.profile is None else _draw_profile(cfg.profile, rng)
            sensor = {key: float(sw.draw(rng)) for key, sw in cfg.sensor.items()}  # last: older configs unchanged
            units.append(Unit(u, state, k, seeds[u], severity, speed, load, snr, scales, split,
                              cfg.rows_per_simulation(state), mounting, colour, profile, sensor))
            u += 1
    return units


def _draw_profile(prof: Any, rng: np.random.Generator) -> dict[str, float | None]:
    """The ``[profile]`` draws of one unit, after every other draw and always the same number of them (the
    acceleration is drawn at constant speed too, and recorded as ``None``), so that streams stay aligned."""
    u = rng.random()  # one draw picks the kind: [0, trapezoid_fraction) a trapezoid, then the S-curve's share
    kind = 1 if u < prof.trapezoid_fraction else (2 if u < prof.trapezoid_fraction + prof.scurve_fraction else 0)
    accel = None if prof.accel_deg_s2 is None else float(prof.accel_deg_s2.draw(rng))
    out: dict[str, float | None] = {"profile": kind, "accel_deg_s2": accel if kind else None}
    for key in ARM_KEYS:
        out[key] = float(prof.arm[key].draw(rng)) if key in prof.arm else 0.0
    if prof.jerk_deg_s3 is not None:  # drawn last, and only by configs with S-curves: older ones keep their units
        jerk = float(prof.jerk_deg_s3.draw(rng))
        out["jerk_deg_s3"] = jerk if kind == 2 else None
    return out


# ---------------------------------------------------------------------- one unit (runs on a worker)
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
            physics_revision=_physics_revision(),
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


def simulator_call(unit: Unit, job: Job) -> tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any]]:
    """``(simulator, args, kwargs)``: the call of the simulator that simulates ``unit`` (its reducer parameters
    scaled and mounted as drawn, its fault, speed, load, profiles and the simulator's seed)."""
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
    spec = FaultSpec(unit.state, unit.severity)
    sim = resolve_simulator(job.simulator)
    fault = spec if getattr(sim, "accepts_fault_spec", False) else spec.to_tooth_faults()
    sim_ss = _streams(unit.seed)[1]
    sim_seed = int(sim_ss.generate_state(1, np.uint32)[0])
    model = dict(job.model)
    if unit.sensor:  # a drawn sensor position moves the model's sensor point; the direction is projected after
        point = unit.sensor_geometry(params.bodies.pin_wheel_outer_radius)[0]
        if point is not None:
            model["sensor_point_m"] = list(point)
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


def finish_unit(unit: Unit, job: Job, result: Any, t0: float) -> UnitResult:
    """The post-processing step of :func:`run_unit`: the simulator's ``result`` checked, its channel kept, the
    unit's noise added and the record cut into samples with their metadata (``t0``: when the unit started, for
    ``wall_s``)."""
    _, _, noise_ss, split_ss = _streams(unit.seed)
    direction = unit.sensor_geometry(1.0)[1] if unit.sensor else None  # the point went to the simulator
    if abs(float(getattr(result, "fs", job.fs)) - job.fs) > 1e-9 * job.fs:
        raise SimulationError(f"simulator returned fs = {result.fs} Hz, asked for {job.fs} Hz")
    x = _channel(result, job.channel) if direction is None else project_sensor(result, direction)
    del result  # keep only the one channel
    if x.shape[0] < job.samples_per_signal:
        raise SimulationError(f"simulator returned {x.shape[0]} points, expected {job.samples_per_signal}")
    x = x[: job.samples_per_signal]
    if not np.all(np.isfinite(x)):
        raise SimulationError(f"unit {unit.index} ({unit.state}): the simulated signal contains NaN or Inf")
    if unit.noise_snr_db is not None:
        from rvdiag.dynamics.noise import add_coloured_noise  # here: keep numba out of `import rvdiag.library`

        x = add_coloured_noise(x, unit.noise_snr_db, unit.noise_exponent or 0.0, np.random.default_rng(noise_ss))
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
    if job.profile_columns:
        for key, value in unit.profile.items():
            meta[key] = [value] * rows
        theta0, speed = window_angles(unit, job, starts[chosen])
        meta["theta_out_start_deg"] = theta0.tolist()
        meta["window_speed_deg_s"] = speed.tolist()
    return UnitResult(unit.index, X, [unit.state] * rows, meta, time.perf_counter() - t0)


# ---------------------------------------------------------------------- the build
@dataclass
class BuildReport:
    """What a build did: units in the plan, built now, found committed, wall time, throughput."""

    path: Path
    n_units: int
    built: int
    skipped: int
    n_samples: int
    samples_built: int
    wall_s: float
    workers: int
    #: where the simulations ran: "cpu" or "cuda"
    device: str = "cpu"

    @property
    def samples_per_s(self) -> float:
        return self.samples_built / self.wall_s if self.wall_s > 0 else float("nan")


def default_workers() -> int:
    """One worker per core available to this process."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def stored_config(cfg: LibraryConfig, params: Any) -> dict[str, Any]:
    """The config the store keeps (and hashes): the canonical library config plus the parameters' hash and the
    simulator's physics revision.  The ``[motor]`` parameters enter the hash only when the simulations use the
    motor's electrical model (``[model] signal = "current"`` or ``electrical = true``): the vibration-only model
    does not read them, so a store built before they existed still resumes."""
    from rvdiag.dynamics import PHYSICS_REVISION

    out = cfg.to_dict()
    pd = params.to_dict()
    model = dict(cfg.model or {})
    if model.get("signal", "vibration") != "current" and not model.get("electrical", False):
        pd.pop("motor", None)
    out[PARAMS_HASH_KEY] = config_hash(pd)
    out[PHYSICS_KEY] = PHYSICS_REVISION
    return out


def config_from_store(attrs: Mapping[str, Any]) -> LibraryConfig:
    """The :class:`LibraryConfig` a library store was built from (``SampleStore.attrs``)."""
    data = dict(attrs["config"])
    data.pop(PARAMS_HASH_KEY, None)
    data.pop(PHYSICS_KEY, None)
    return LibraryConfig.from_dict(data, source="<store>")


@contextmanager
def _dask_client(workers: int, scheduler: str | None) -> Iterator[Any]:
    import logging

    from distributed import Client, LocalCluster

    if scheduler:
        import dask

        # connect timeout: dask's distributed.comm.timeouts.connect (30 s by default; set
        # DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT to change it)
        try:
            client = Client(scheduler, timeout=dask.config.get("distributed.comm.timeouts.connect"))
        except (OSError, TimeoutError) as exc:
            raise RvdiagError(f"cannot reach the Dask scheduler at {scheduler!r} ({type(exc).__name__}: {exc})") from None
        try:
            yield client
        finally:
            client.close()
        return
    cluster = LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
        silence_logs=logging.ERROR,
    )
    try:
        client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
    finally:
        cluster.close()


def check_run_options(workers: int | None, scheduler: str | None, device: str = "cpu",
                      ensemble: int | None = None) -> None:
    """Validate ``--workers`` / ``--scheduler`` / ``--device`` / ``--ensemble`` (:class:`ConfigError`)."""
    from rvdiag.library.gpu import DEFAULT_ENSEMBLE, check_device

    check_device(device, DEFAULT_ENSEMBLE if ensemble is None else ensemble)
    if workers is not None and workers < 0:
        raise ConfigError(f"--workers must be >= 0, got {workers}")
    if scheduler and workers is not None:
        raise ConfigError("give --workers or --scheduler, not both (a scheduler's cluster has its own workers)")


def build_library(
    config: LibraryConfig | str | Path,
    out: str | Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    client: Any = None,
    simulator: str | None = None,
    progress: bool = True,
    console: Any = None,
    device: str = "cpu",
    ensemble: int | None = None,
) -> BuildReport:
    """Build (or resume, or find complete) the library of ``config`` in the store ``out``.

    Parameters
    ----------
    config : a :class:`LibraryConfig` or the path of a library TOML file
    out : the store folder (``PATH.zarr``)
    workers : worker processes of the local cluster (default: one per core); 0 = no Dask, in this process
    scheduler : address of an existing Dask scheduler (``tcp://host:8786``) instead of a local cluster
    client : an existing ``distributed.Client`` to use (then ``workers``/``scheduler`` are ignored)
    simulator : ``"module:function"`` overriding the config's simulator (part of the stored config)
    progress : show a rich progress bar with simulations done and the ETA
    console : the ``rich.console.Console`` to draw on (default: stderr)
    device : ``"cpu"`` (default), ``"cuda"`` (GPU ensembles, :mod:`rvdiag.library.gpu`; without a usable GPU the CPU,
        with one warning) or ``"auto"`` (``cuda`` when this machine has a usable GPU, else ``cpu``).  With ``cuda``
        and no ``scheduler``/``client`` the ensembles run in this process unless ``workers`` is given.
    ensemble : simulations per GPU ensemble (one launch, one task; default
        :data:`rvdiag.library.gpu.DEFAULT_ENSEMBLE`)

    Returns
    -------
    BuildReport
    """
    cfg = config if isinstance(config, LibraryConfig) else LibraryConfig.load(config)
    if simulator is not None:
        cfg = cfg.replace(simulator=simulator)
    check_run_options(workers, scheduler, device, ensemble)
    params = cfg.reducer_params()
    resolve_simulator(cfg.simulator, cfg.model)  # fail early, here, with a clear message
    from rvdiag.library.gpu import DEFAULT_ENSEMBLE, resolve_device

    local = client is None and not scheduler
    device = resolve_device(device, cfg.simulator, check_here=local or device == "auto")
    if device == "cuda" and workers is None and local:
        workers = 0  # one process drives the GPU
    plan = make_plan(cfg)
    for unit in plan:  # validate every drawn severity before anything is written
        FaultSpec(unit.state, unit.severity)
    job = Job.from_config(cfg, params)
    out = Path(out)
    extra = {
        "params": params.to_dict(),
        "library": {
            "mode": cfg.mode, "seed": cfg.seed, "simulator": cfg.simulator,
            "states": {s: STATES[s].description for s in cfg.classes},
            "n_simulations": len(plan), "rvdiag_version": __version__, "device": device,
        },
    }
    builder = StoreBuilder(
        out, unit_rows=[u.rows for u in plan], length=cfg.segment_length, classes=cfg.classes,
        config=stored_config(cfg, params), fs=cfg.fs, kind="simulated", extra_attrs=extra,
    )
    done = builder.committed_units()
    todo = [u for u in plan if u.index not in done]
    if done and todo:
        _check_resume_device(out, builder, device)
    t0 = time.perf_counter()
    n_workers = 0 if (workers == 0 and client is None and not scheduler) else (workers or default_workers())
    built = 0
    samples_built = 0

    def write(res: UnitResult) -> None:
        nonlocal built, samples_built
        builder.write_unit(res.index, res.X, res.labels, res.meta)
        built += 1
        samples_built += res.X.shape[0]

    if device == "cuda":
        size = DEFAULT_ENSEMBLE if ensemble is None else ensemble
        items: list[Any] = [todo[i:i + size] for i in range(0, len(todo), size)]
        from rvdiag.library.gpu import ensemble_task

        task: Callable[..., Any] = ensemble_task
    else:
        items, task = todo, _run_checked
    with _progress(progress, console, len(plan), len(done), cfg.name) as advance:
        handle = _ensemble_handler(write, advance) if device == "cuda" else _unit_handler(write, advance)
        if items:
            if n_workers == 0:
                for item in items:
                    handle(task(item, job))
            elif client is not None:
                n_workers = _run_on_client(client, items, job, task, handle)
            else:
                with _dask_client(n_workers, scheduler) as c:
                    n_workers = _run_on_client(c, items, job, task, handle)
    builder.finalize()
    return BuildReport(
        path=out, n_units=len(plan), built=built, skipped=len(plan) - len(todo), n_samples=builder.n_samples,
        samples_built=samples_built, wall_s=time.perf_counter() - t0, workers=n_workers, device=device,
    )


def _check_resume_device(out: Path, builder: StoreBuilder, device: str) -> None:
    """Refuse to finish on a GPU a build begun on the CPU, or the reverse (:class:`StoreError`, one line): a GPU's
    arithmetic differs from the CPU's in the last bits, which the integration grows to ~1e-8, so one store would
    hold units of two slightly different simulators.  Stores from before the device was recorded were built on
    the CPU."""
    began = (builder.attrs.get("library") or {}).get("device", "cpu")
    if began != device:
        raise StoreError(f"{out} was begun with --device {began}; finish it with --device {began} (units integrated "
                         f"on the {'GPU' if device == 'cuda' else 'CPU'} differ in the last bits), or choose "
                         "another --out")


def _unit_handler(write: Callable[[UnitResult], None],
                  advance: Callable[[], None]) -> Callable[[tuple[UnitResult, Caught]], None]:
    def handle(outcome: tuple[UnitResult, Caught]) -> None:
        res, warned = outcome
        reissue(warned)
        write(res)
        advance()

    return handle


def _ensemble_handler(write: Callable[[UnitResult], None], advance: Callable[[], None]) -> Callable[[Any], None]:
    """Write an ensemble's results, then raise its first error (the committed units are kept); warn once when a
    worker had no usable GPU and ran its ensemble on its CPU."""
    warned = []

    def handle(outcome: tuple[list[Any], str | None]) -> None:
        results, fallback = outcome
        if fallback and not warned:
            import warnings

            from rvdiag.errors import DeviceWarning

            warnings.warn(f"a worker: {fallback}; its simulations ran on its CPU", DeviceWarning, stacklevel=2)
            warned.append(fallback)
        errors = [r for r in results if isinstance(r, BaseException)]
        for res in results:
            if not isinstance(res, BaseException):
                write(res)
                advance()
        if errors:
            raise errors[0]

    return handle


def _run_checked(unit: Unit, job: Job) -> tuple[UnitResult, Caught]:
    """:func:`run_unit` (the task), with the warnings it raised (carried back to the build's process, which
    shows each once: :mod:`rvdiag.library.worker_warnings`)."""
    try:
        return caught(run_unit, unit, job)
    except RvdiagError as exc:
        raise type(exc)(f"simulation {unit.index} ({unit.state} #{unit.sim_index}): {exc}") from None


def _run_on_client(client: Any, todo: list[Any], job: Job, task: Callable[..., Any],
                   handle: Callable[[Any], None]) -> int:
    """Submit ``task(item, job)`` for each item (a unit, or a GPU ensemble of units) with at most one in flight per
    worker thread; ``handle`` each result as it completes.  A GPU ensemble asks for one ``GPU`` resource when the
    cluster's workers declare that resource (``dask worker --resources GPU=1``).

    The number of worker threads is read again (at most once a second) as results come in, so that workers that
    join after the start (a batch system's jobs leaving the queue, ``cluster.scale``) get work, and the window
    shrinks when some leave.  A worker lost in the middle of a simulation loses nothing: the scheduler gives its
    task to another worker, up to ``distributed.scheduler.allowed-failures`` times per task (3 by default), and
    only a task that exceeds it fails the build (every result written so far stays committed).  The job goes
    with every task (about 3 kB), not scattered once, so no worker's death can take the only copy of it."""
    from distributed import KilledWorker, as_completed

    def threads() -> int:
        return sum(client.nthreads().values())

    nthreads = threads()
    if nthreads == 0:
        try:
            client.wait_for_workers(1, timeout=60)
        except TimeoutError:
            raise RvdiagError("the Dask cluster has no workers (none joined within 60 s)") from None
        nthreads = threads()
    window = max(1, nthreads)
    checked = time.monotonic()
    pending = iter(todo)
    futures = as_completed()
    extra: dict[str, Any] = {}
    if task is not _run_checked and any("GPU" in (w.get("resources") or {})
                                        for w in client.scheduler_info().get("workers", {}).values()):
        extra["resources"] = {"GPU": 1}

    def submit_next() -> bool:
        item = next(pending, None)
        if item is None:
            return False
        name = f"unit-{item.index}" if isinstance(item, Unit) else f"ensemble-{item[0].index}"
        futures.add(client.submit(task, item, job, pure=False, key=f"rvdiag-{name}-{time.time_ns()}", **extra))
        return True

    for _ in range(window):
        if not submit_next():
            break
    try:
        for fut in futures:
            try:
                res = fut.result()
            except KilledWorker as exc:
                raise SimulationError(
                    f"Dask workers died running {exc.task} (more often than distributed.scheduler.allowed-failures "
                    "allows: out of memory, or workers without rvdiag installed?); the committed simulations are "
                    "kept: re-run the same command to resume"
                ) from None
            except RuntimeError as exc:
                if "deserialization of the task graph" not in str(exc):
                    raise
                raise RvdiagError(
                    "the Dask scheduler cannot read the simulation tasks: it needs the client's Python packages, "
                    f"rvdiag {__version__} among them, installed where it runs (as the workers do)"
                ) from None
            fut.release()
            handle(res)
            del res
            if time.monotonic() - checked >= 1.0:
                window, checked = max(1, threads()), time.monotonic()
            while futures.count() < window and submit_next():
                pass
    except BaseException:
        for fut in list(futures.futures):
            fut.cancel()
        raise
    return len(client.nthreads())


@contextmanager
def _progress(enabled: bool, console: Any, total: int, completed: int, name: str) -> Iterator[Callable[[], None]]:
    if not enabled:
        yield lambda: None
        return
    from rich.console import Console
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn,
                               TimeRemainingColumn)

    columns = (
        TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(), TextColumn("simulations"),
        TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(),
    )
    with Progress(*columns, console=console or Console(stderr=True)) as prog:
        task = prog.add_task(name, total=total, completed=completed)
        yield lambda: prog.advance(task)
