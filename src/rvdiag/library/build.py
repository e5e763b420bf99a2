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

One unit on a worker (:class:`Unit`, :class:`Job`, :func:`run_unit` and the steps it is made of) lives in
:mod:`rvdiag.library.work_units`, below this module and the GPU path; its names are imported here too.
"""

from __future__ import annotations

import os
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping

import numpy as np

from rvdiag import __version__
from rvdiag.datasets import StoreBuilder, config_hash
from rvdiag.errors import ConfigError, RvdiagError, SimulationError, StoreError
from rvdiag.library.config import ARM_KEYS, LEGACY_MODES, LibraryConfig, scaled_keys
from rvdiag.library.specimens import draw_specimen, override_message, specimen_seed
from rvdiag.library.states import STATES, FaultSpec
from rvdiag.library.work_units import (_TWIN_POWERS, Job, Unit, UnitResult, _streams, check_worker,  # noqa: F401
                                  finish_unit, floor_noise_power, kept_signal, needs_twin, project_sensor,
                                  resolve_simulator, run_unit, segment_starts, simulate_unit, simulator_call,
                                  twin_key, twin_power, unit_params, window_angles)

from rvdiag.library.worker_warnings import Caught, caught, reissue

#: Key added to the stored config so that its hash also covers the reducer parameter values.
PARAMS_HASH_KEY = "reducer_params_hash"
#: Key added to the stored config so that its hash also covers the simulator's physics revision
#: (:data:`rvdiag.dynamics.PHYSICS_REVISION`): a store simulated by other physics is never resumed or mixed.
PHYSICS_KEY = "physics_revision"


# ---------------------------------------------------------------------- plan
def unit_seeds(seed: int, n_units: int) -> list[int]:
    """Per-unit 63-bit seeds spawned from the master seed (``SeedSequence(seed).spawn(n_units)``)."""
    out = []
    for child in np.random.SeedSequence(seed).spawn(n_units):
        hi, lo = child.generate_state(2, np.uint32).tolist()
        out.append(((hi << 32) | lo) & 0x7FFF_FFFF_FFFF_FFFF)
    return out


def make_plan(cfg: LibraryConfig) -> list[Unit]:
    """Every unit of the library with its drawn values (deterministic in ``cfg``)."""
    if cfg.baseline is not None:
        return _paired_plan(cfg)
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
            if cfg.mode == "split-by-simulation":
                split = "test" if k >= cfg.simulations_per_state - cfg.test_simulations_per_state else "train"
            # drawn after every earlier draw, so a config without them keeps its units bit for bit
            mounting = {key: float(sw.draw(rng)) for key, sw in cfg.path.items()}
            colour = None if cfg.noise_colour_exponent is None else float(cfg.noise_colour_exponent.draw(rng))
            profile = {} if cfg.profile is None else _draw_profile(cfg.profile, rng)
            sensor = {key: float(sw.draw(rng)) for key, sw in cfg.sensor.items()}  # last: older configs unchanged
            density = None  # after the sensor: drawn only by configs with a density
            if cfg.noise_density_ug_per_rthz is not None:
                density = float(cfg.noise_density_ug_per_rthz.draw(rng))
            # after the density: drawn only by configs with [randomise] pin_wear_depth
            pin_wear = None if cfg.pin_wear_depth is None else float(cfg.pin_wear_depth.draw(rng))
            specimen = draw_specimen(specimen_seed(seeds[u]), cfg.iso1328_grade) if cfg.specimen else {}
            units.append(Unit(u, state, k, seeds[u], severity, speed, load, snr, scales, split,
                              cfg.rows_per_simulation(state), mounting, colour, profile, sensor, specimen, density,
                              pin_wear_depth=pin_wear))
            u += 1
    return units


def _paired_plan(cfg: LibraryConfig) -> list[Unit]:
    """The units of a paired library (:mod:`rvdiag.library.paired`), reducer by reducer, each reducer's records in
    :meth:`BaselineConfig.schedule` order (its commissioning records first).

    What makes the reducer is drawn once, from :func:`rvdiag.library.paired.reducer_seed`
    (:func:`_reducer_draws`).  Each record draws from its own unit's stream: its severities, its operating point
    (monitored records: one of ``operating_points``, equally likely), then its run-to-run factors; its speed and load
    are the point's times the speed and load factors (:func:`_record_unit`).
    The last ``test_reducers`` reducers are the test set, every record of them.

    With ``[history]`` (a life-history library, :mod:`rvdiag.library.life`) each reducer's records are its
    commissioning records, then ``records`` monitored ones every ``interval_days``, along the reducer's drawn life
    (:func:`_life_plan`)."""
    if cfg.history is not None:
        return _life_plan(cfg)
    b = cfg.baseline
    assert b is not None
    schedule = b.schedule(cfg.classes)
    seeds = unit_seeds(cfg.seed, cfg.n_simulations)
    units: list[Unit] = []
    for r in range(b.reducers):
        reducer, _ = _reducer_draws(cfg, r)
        for k, (role, state, point) in enumerate(schedule):
            units.append(_record_unit(cfg, reducer, len(units), seeds[len(units)], k, role, state, point))
    return units


def _reducer_draws(cfg: LibraryConfig, r: int) -> tuple[dict[str, Any], np.random.Generator]:
    """What makes reducer ``r`` of a paired library (the :class:`Unit` fields every record of it shares), and its
    stream, from which a life history goes on drawing (:func:`rvdiag.library.life.draw_life`).

    Drawn once, from :func:`rvdiag.library.paired.reducer_seed`, in the order of :func:`make_plan`'s draws: the noise
    level, the parameter scales, the path, the noise colour, the sensor, the noise density, then its specimen (from
    the reducer seed's specimen stream).  A ``[profile]`` (the gravity arm alone) is drawn once per reducer, after its
    specimen: the joint's arm, the same in every record of it (the load factor scales the constant torque, not the
    arm)."""
    from rvdiag.library.paired import reducer_seed

    b = cfg.baseline
    assert b is not None
    r_seed = reducer_seed(cfg.seed, r)
    rng = np.random.default_rng(_streams(r_seed)[0])
    snr = None if cfg.noise_snr_db is None else cfg.noise_snr_db.draw(rng)
    scales = {f"{s}.{key}": float(1.0 + pct / 100.0 * rng.uniform(-1.0, 1.0)) for s, key, pct in scaled_keys(cfg)}
    mounting = {key: float(sw.draw(rng)) for key, sw in cfg.path.items()}
    colour = None if cfg.noise_colour_exponent is None else float(cfg.noise_colour_exponent.draw(rng))
    sensor = {key: float(sw.draw(rng)) for key, sw in cfg.sensor.items()}
    density = None if cfg.noise_density_ug_per_rthz is None else float(cfg.noise_density_ug_per_rthz.draw(rng))
    specimen = draw_specimen(specimen_seed(r_seed), cfg.iso1328_grade) if cfg.specimen else {}
    # the joint's gravity arm (a [profile] of arm keys only): one per reducer, drawn last, so every record of
    # the reducer, commissioning ones included, repeats one motion from one arm angle
    arm = _draw_profile(cfg.profile, rng) if cfg.profile is not None else {}
    split = "test" if r >= b.reducers - b.test_reducers else "train"
    return dict(noise_snr_db=snr, scales=scales, mounting=mounting, noise_exponent=colour, profile=arm,
                sensor=sensor, specimen=specimen, noise_density=density, reducer=r, split=split), rng


def _record_unit(cfg: LibraryConfig, reducer: Mapping[str, Any], u: int, seed: int, k: int, role: str, state: str,
                 point: int | None, severity: Mapping[str, float] | None = None,
                 life: Mapping[str, Any] | None = None) -> Unit:
    """Record ``k`` of a reducer (``reducer``: :func:`_reducer_draws`) as unit ``u`` of seed ``seed``, from its own
    stream: its severities (drawn from ``[states]`` unless given: a life history's), its operating point (``None``:
    one of ``operating_points``, equally likely; always drawn, so that every record's stream stays aligned), then its
    run-to-run factors (:func:`rvdiag.library.paired.draw_variation`)."""
    from rvdiag.library.paired import draw_variation

    b = cfg.baseline
    assert b is not None
    n_points = len(b.operating_points)
    rng = np.random.default_rng(_streams(seed)[0])
    if severity is None:
        severity = {p: sw.draw(rng) for p, sw in cfg.states[state].items()}
    draw = rng.random()
    if point is None:
        point = min(int(draw * n_points), n_points - 1)
    variation = draw_variation(rng, b.variation)
    speed, load = b.operating_points[point]
    return Unit(u, state, k, seed, dict(severity), speed * variation["speed"], load * variation["load"],
                rows=cfg.rows_per_simulation(state), role=role, operating_point=point, variation=variation,
                life=dict(life or {}), **reducer)


def _life_plan(cfg: LibraryConfig) -> list[Unit]:
    """The units of a life-history library (:mod:`rvdiag.library.life`): reducer by reducer, what makes the reducer
    (:func:`_reducer_draws`), then its life from the same stream (:func:`rvdiag.library.life.draw_life`); its
    commissioning records (role ``"baseline"``, T1, time 0, point by point as a paired library's), then ``records``
    monitored records at ``interval_days * (1 .. records)``, each its own unit and stream (:func:`_record_unit`: no
    severity draw, its operating point, its run-to-run factors), its state and severities those of the life's size
    at its time (:meth:`rvdiag.library.life.Life.record`)."""
    from rvdiag.gears.growth import sun_root_chord
    from rvdiag.library.life import draw_life
    from rvdiag.library.states import SEVERITY_PARAMETERS

    b, h = cfg.baseline, cfg.history
    assert b is not None and h is not None
    params = cfg.reducer_params()
    if "crack" in h.fates and h.fates["crack"] > 0:
        a_fail, hi = h.crack_failure_fraction * sun_root_chord(params), SEVERITY_PARAMETERS["crack_depth"].hi
        if a_fail > hi:
            raise ConfigError(f"{cfg.source}: [history] crack_failure_fraction: {h.crack_failure_fraction:g} of the "
                              f"sun tooth's root chord is {a_fail * 1e3:.3g} mm, deeper than the {hi * 1e3:g} mm a "
                              "root crack may be (crack_depth)")
    seeds = unit_seeds(cfg.seed, cfg.n_simulations)
    commissioning = [i for i in range(len(b.operating_points)) for _ in range(b.records_per_point)]
    units: list[Unit] = []
    for r in range(b.reducers):
        reducer, rng = _reducer_draws(cfg, r)
        life = draw_life(h, rng, params)
        times = [0.0] * len(commissioning) + [h.interval_days * (j + 1) for j in range(h.records)]
        for k, days in enumerate(times):
            base = k < len(commissioning)
            state, severity, truth = life.record(k, days)
            if base:  # commissioning: healthy at its point, whatever the fate
                state, severity = "T1", {}
            units.append(_record_unit(cfg, reducer, len(units), seeds[len(units)], k,
                                      "baseline" if base else "monitored", state,
                                      commissioning[k] if base else None, severity, truth))
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
    """The config the store keeps (and hashes): the canonical library config (its mode in the spelling stores have
    always had, :data:`rvdiag.library.config.LEGACY_MODES`) plus the parameters' hash and the simulator's physics
    revision.  The ``[motor]`` parameters enter the hash only when the simulations use the
    motor's electrical model (``[model] signal = "current"`` or ``electrical = true``): the vibration-only model
    does not read them, so a store built before they existed still resumes."""
    from rvdiag.dynamics import PHYSICS_REVISION

    out = cfg.to_dict()
    # the mode's old spelling, so that the hash of every store built before the rename stays (they resume); the
    # store's `library` attribute and config_from_store give the new one
    out["mode"] = {new: old for old, new in LEGACY_MODES.items()}.get(out["mode"], out["mode"])
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
    if cfg.specimen:
        message = override_message(params, cfg.iso1328_grade)
        if message:
            import warnings

            from rvdiag.errors import RvdiagWarning

            warnings.warn(message, RvdiagWarning, stacklevel=2)
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
