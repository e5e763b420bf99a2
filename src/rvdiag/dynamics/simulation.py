"""``simulate``: one simulation of the reducer, from a parameter set and a fault to a :class:`SimulationResult`.

The steps: the mesh table of the fault (:func:`mesh_table`), the compiled model (:func:`prepare`), the start state
(:func:`initial_deflection`), the integration with the model's integrator (``ModelSettings.method``: Kutta's 3/8 rule
by default, classical RK4 on request; :mod:`rvdiag.dynamics.integrate`), then the sensor path, the noise and, with
the motor, the current record (:class:`PreparedSimulation`, which the GPU ensemble shares).

>>> from rvdiag.dynamics import simulate, ModelSettings
>>> res = simulate(output_speed_deg_s=30.0, load_Nm=50.0, duration_s=0.01, fs=12000.0,
...                settings=ModelSettings(transient_s=0.005, substeps=16))
>>> res.signal.shape
(2, 120)
"""

from __future__ import annotations

import dataclasses
import inspect
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from rvdiag.dynamics.mesh import MeshTable, mesh_table_from_gears, rectangular_mesh_table
from rvdiag.dynamics.model import I_TLOAD, Model, ModelSettings, build_model
from rvdiag.dynamics.noise import add_awgn
from rvdiag.dynamics.profile import LoadProfile, SpeedProfile
from rvdiag.dynamics.results import SimulationResult
from rvdiag.dynamics.transfer import apply_path
from rvdiag.errors import ParameterError
from rvdiag.kinematics import sun_speed_hz
from rvdiag.params import ReducerParams
from rvdiag.validation import finite_number, number

#: what :func:`simulate` can record
SIGNALS = ("vibration", "current", "both")
#: the motor-current channels of a result (``SimulationResult.current``) and their units
CURRENT_CHANNELS = ("i_a", "i_b", "i_c", "i_q", "speed")
CURRENT_UNITS = ("A", "A", "A", "A", "rpm")


def current_record_margin(fs: float, current_fs: float, n_transient: int) -> tuple[int, int]:
    """Samples ``(lead, tail)`` recorded beyond the ends of a motor-current record (at ``fs``), so that the rate
    change's FIR filter (half length ``10 max(up, down)``, :func:`scipy.signal.resample_poly`) does not reach past
    the simulated record: whole numbers of output samples, at least 12 max(up, down) input samples, the lead
    within the ``n_transient`` run-in samples (a run without run-in has filtered start-up edges)."""
    from rvdiag.motor import current_rate_ratio

    r = current_rate_ratio(float(fs), current_fs)
    m = r.denominator * math.ceil(12 * max(r.numerator, r.denominator) / r.denominator)
    return min(m, (n_transient // r.denominator) * r.denominator), m


def motor_current_record(motor_rows: np.ndarray, fs: float, current_fs: float,
                         margin: tuple[int, int] = (0, 0)) -> np.ndarray:
    """The drive's current record from the integrator's motor rows (i_d, i_q, electrical angle, rotor speed in
    rad/s, :data:`rvdiag.dynamics.integrate.MOTOR_CHANNELS`): i_a, i_b, i_c, i_q (A) and the speed (rpm),
    sampled at ``current_fs`` (:func:`rvdiag.motor.sample_current`); the ``margin = (lead, tail)`` input samples
    (:func:`current_record_margin`) are filtered with the record and then dropped."""
    from rvdiag.motor import current_rate_ratio, phase_currents, sample_current

    i_d, i_q, theta_e, speed = motor_rows
    rows = np.vstack([phase_currents(i_d, i_q, theta_e), i_q[None, :], speed[None, :] * (60.0 / (2.0 * math.pi))])
    x = sample_current(rows, fs, current_fs)
    r = current_rate_ratio(float(fs), current_fs)
    cut = margin[0] * r.numerator // r.denominator
    n_out = math.ceil((motor_rows.shape[1] - margin[0] - margin[1]) * r.numerator / r.denominator)
    return np.ascontiguousarray(x[:, cut:cut + n_out])



def mesh_table(params: ReducerParams, fault: Any = None, source: str = "auto") -> MeshTable:
    """The sun-planet TVMS table for a fault.

    ``fault`` is ``None`` (healthy), a :class:`MeshTable` (used as is) or a fault object of
    :mod:`rvdiag.gears` (``ToothFaults``).  ``source`` is ``"gears"`` (potential-energy TVMS of
    :mod:`rvdiag.gears`), ``"rectangular"`` (square-wave stand-in; healthy only, or a MeshTable) or
    ``"auto"`` (the same as ``"gears"``: the stand-in is used only when asked for).
    """
    if isinstance(fault, MeshTable):
        return fault
    if fault is not None and getattr(fault, "is_healthy", False):
        fault = None
    if source not in ("auto", "gears", "rectangular"):
        raise ParameterError(f"mesh source must be auto, gears or rectangular, got {source!r}")
    if source in ("auto", "gears"):
        return mesh_table_from_gears(params, fault)
    if fault is not None:
        raise ParameterError("tooth faults need the rvdiag.gears TVMS (mesh source 'gears') or a MeshTable")
    return rectangular_mesh_table(params)


def _describe(obj: Any) -> Any:
    if obj is None:
        return None
    if isinstance(obj, MeshTable):
        return {"mesh_table": obj.source, "points": int(obj.angle_rad.size)}
    for name in ("to_dict", "as_dict"):
        if callable(getattr(obj, name, None)):
            return getattr(obj, name)()
    if dataclasses.is_dataclass(obj):
        return dataclasses.asdict(obj)
    return repr(obj)


def prepare(
    params: ReducerParams | None = None,
    fault: Any = None,
    *,
    input_speed_rpm: float | None = None,
    output_speed_deg_s: float | None = None,
    load_Nm: float | None = None,
    settings: ModelSettings | None = None,
    mesh_source: str = "auto",
    profile: SpeedProfile | None = None,
    load_profile: LoadProfile | None = None,
    duration_s: float | None = None,
    load_inertia_kg_m2: float | None = None,
) -> Model:
    """Build the model of one operating point (validating every input) without integrating.

    A trapezoidal ``profile`` cruises at its own ``output_speed_deg_s``, which then needs no speed argument.
    """
    params = ReducerParams.default() if params is None else params
    if not isinstance(params, ReducerParams):
        raise ParameterError("params must be a ReducerParams")
    params = with_load_inertia(params, load_inertia_kg_m2)
    if profile is not None and not isinstance(profile, SpeedProfile):
        raise ParameterError("profile must be a SpeedProfile")
    if load_profile is not None and not isinstance(load_profile, LoadProfile):
        raise ParameterError("load_profile must be a LoadProfile")
    if profile is not None and not profile.is_constant:
        profile.validate(duration_s)
        if input_speed_rpm is None and output_speed_deg_s is None:
            output_speed_deg_s = profile.output_speed_deg_s
        elif output_speed_deg_s != profile.output_speed_deg_s:
            raise ParameterError("a trapezoid cruises at its own output_speed_deg_s: give no other speed")
    fsun = sun_speed_hz(params, input_speed_rpm, output_speed_deg_s)
    load = params.operation.rated_torque if load_Nm is None else number(load_Nm, "load torque")
    return build_model(params, mesh_table(params, fault, mesh_source), fsun, load, settings or ModelSettings(),
                       profile, load_profile, duration_s)


def with_load_inertia(params: ReducerParams, load_inertia_kg_m2: float | None) -> ReducerParams:
    """``params`` with ``[operation] load_inertia`` set to ``load_inertia_kg_m2`` (kg m^2; ``None``: unchanged).
    Raises ParameterError naming the argument for a value that is not a finite number >= 0."""
    if load_inertia_kg_m2 is None:
        return params
    J = finite_number(load_inertia_kg_m2, "load_inertia_kg_m2", 0)
    if params.operation.load_inertia is not None and float(params.operation.load_inertia) == J:
        return params
    return params.replace(operation={"load_inertia": J})


def initial_deflection(model: Model, t0: float) -> tuple[np.ndarray, str]:
    """Initial displacements of a run and how they were found.

    The static equilibrium at ``t0`` when its Newton iteration converges; otherwise (contacts that keep
    switching, as with a partly broken, heavily worn tooth) the bilateral linear deflection, which always
    exists.  Either way the start-up transient is discarded, so the choice only shortens the settling.
    """
    from rvdiag.dynamics.linear import bilateral_deflection, static_equilibrium
    from rvdiag.errors import SimulationError

    try:
        return static_equilibrium(model, t0), "static equilibrium"
    except SimulationError:
        return bilateral_deflection(model, t0), "bilateral linear deflection (static iteration did not converge)"


@dataclasses.dataclass(frozen=True)
class SimulationRequest:
    """One simulation of the reducer: every argument of :func:`simulate` and :func:`prepare_simulation`, said once.

    ``simulate(params, fault, **keywords)`` is ``SimulationRequest(params, fault, **keywords).run()``, and
    ``prepare_simulation(...)`` is ``SimulationRequest(...).prepare()``; the library's simulator
    (:func:`rvdiag.library.simulators.dynamics`) builds one request for both.  Nothing is checked until
    :meth:`prepare` (an unknown keyword is a ``TypeError`` at once, as for any function).

    Parameters
    ----------
    params : ReducerParams, optional
        Reducer parameter set (default: the built-in RV-20E).
    fault : None, MeshTable or rvdiag.gears fault object
        Sun-tooth fault entered through the mesh stiffness (see :func:`mesh_table`).
    input_speed_rpm, output_speed_deg_s : float
        Exactly one: the motor (sun) speed or the output (carrier) speed.
    load_Nm : float, optional
        Load torque on the output (default ``params.operation.rated_torque``).
    duration_s : float
        Length of the recorded signal after the transient (s).
    fs : float
        Output sampling rate (Hz).
    noise_snr_db : float, optional
        Adds white Gaussian noise at this SNR (per channel) from ``numpy.random.default_rng(seed)``.
    seed : int
        Seed of the noise; the simulation itself is deterministic.
    settings : ModelSettings
        Sub-steps, transient length, sensor, damping and the other model settings.
    mesh_source : str
        ``"auto"``, ``"gears"`` or ``"rectangular"`` (see :func:`mesh_table`).
    workers : int
        Threads integrating time segments at once when ``settings.segment_s > 0``
        (:mod:`rvdiag.dynamics.segments`); the output does not depend on it.
    profile : SpeedProfile, optional
        The output's speed against time (default constant; a trapezoid gives its own cruise speed, and no
        speed argument is needed).  :mod:`rvdiag.dynamics.profile`.
    load_profile : LoadProfile, optional
        A gravity arm on the output (default: the constant ``load_Nm``).
    signal : {"vibration", "current", "both"}
        What is recorded.  ``"current"`` and ``"both"`` add the servo motor's electrical side (``[motor]``, a
        PMSM under i_d = 0 vector control; ``settings.electrical``; docs/model.md section 10), which also
        changes the vibration a little (the drive's current loop and dead time act on the rotor).
    current_fs : float
        Sampling rate of the motor-current record (Hz; the drive's logger: 1 kHz in the motor-current study);
        ``fs / current_fs`` must be a ratio of small integers (:func:`rvdiag.motor.sample_current`).
    current_snr_db : float, optional
        More white Gaussian noise on each current channel, at this SNR.  The current always carries the
        sensors' noise, ``[motor] current_noise`` (A rms).  Both come from ``numpy.random.default_rng([seed, 1])``
        (the vibration's noise stream is unchanged).
    load_inertia_kg_m2 : float, optional
        The load's polar inertia J_L on the output coupling ``[bearings] output_torsional``, a DOF of the model
        (docs/model.md sections 1 and 3; an elastic joint, Spong 1987); 0: a pure load torque on the carrier, the
        model without the load DOF.  ``None``: ``params``' ``[operation] load_inertia`` when it states one, else the
        gravity arm's point-mass inertia ``M L^2`` of ``load_profile`` (no arm: 0).
    """

    params: ReducerParams | None = None
    fault: Any = None
    _: dataclasses.KW_ONLY
    input_speed_rpm: float | None = None
    output_speed_deg_s: float | None = None
    load_Nm: float | None = None
    duration_s: float = 1.0
    fs: float = 48000.0
    noise_snr_db: float | None = None
    seed: int = 0
    settings: ModelSettings | None = None
    mesh_source: str = "auto"
    workers: int = 1
    profile: SpeedProfile | None = None
    load_profile: LoadProfile | None = None
    signal: str = "vibration"
    current_fs: float = 1000.0
    current_snr_db: float | None = None
    load_inertia_kg_m2: float | None = None

    def prepare(self) -> "PreparedSimulation":
        """The simulation up to the integration: every argument validated, the model built."""
        from rvdiag.dynamics.segments import check_workers

        params, fault, fs, duration_s, seed, signal = (self.params, self.fault, self.fs, self.duration_s, self.seed,
                                                       self.signal)
        current_fs, settings, workers, profile, load_profile = (self.current_fs, self.settings, self.workers,
                                                                self.profile, self.load_profile)
        if signal not in SIGNALS:
            raise ParameterError(f"signal must be one of {', '.join(SIGNALS)}, got {signal!r}")
        if signal != "vibration":
            from rvdiag.motor import current_rate_ratio

            current_rate_ratio(float(fs), current_fs)
        st = settings or ModelSettings()
        if signal != "vibration" and not st.electrical:
            st = dataclasses.replace(st, electrical=True)
        for name, val in (("duration_s", duration_s), ("fs", fs)):
            finite_number(val, name, 0, strict=True, noun="a number")
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ParameterError(f"seed must be a whole number >= 0, got {seed!r}")
        check_workers(workers)
        n_samples = int(round(duration_s * fs))
        if n_samples < 1:
            raise ParameterError(f"duration {duration_s} s at {fs} Hz gives no sample")
        params = ReducerParams.default() if params is None else params
        if not isinstance(params, ReducerParams):
            raise ParameterError("params must be a ReducerParams")
        params = with_load_inertia(params, self.load_inertia_kg_m2)
        model = prepare(params, fault, input_speed_rpm=self.input_speed_rpm,
                        output_speed_deg_s=self.output_speed_deg_s, load_Nm=self.load_Nm, settings=st,
                        mesh_source=self.mesh_source, profile=profile,
                        load_profile=load_profile, duration_s=float(duration_s))
        n_tr = int(round(st.transient_s * fs))
        margin = current_record_margin(fs, current_fs, n_tr) if model.has_pmsm else (0, 0)
        return PreparedSimulation(model, params, fault, st, fs, duration_s, n_samples, n_tr, margin, workers,
                                  profile or SpeedProfile(), load_profile or LoadProfile(), self)

    def run(self, progress: Callable[[int, int], None] | None = None) -> SimulationResult:
        """The simulation: :meth:`prepare`, then its :meth:`~PreparedSimulation.integrate` (``progress(done_samples,
        total_samples)`` after each chunk) and :meth:`~PreparedSimulation.finish`."""
        run = self.prepare()
        out, n_segments = run.integrate(progress)
        return run.finish(out, n_segments)


def _request_signature(*extra: inspect.Parameter) -> inspect.Signature:
    """The signature of a function that takes :class:`SimulationRequest`'s fields (``params`` and ``fault``
    positional, the rest keyword-only) and ``extra``, for ``help()`` and IDEs."""
    kinds = {"params": inspect.Parameter.POSITIONAL_OR_KEYWORD, "fault": inspect.Parameter.POSITIONAL_OR_KEYWORD}
    fields = [inspect.Parameter(f.name, kinds.get(f.name, inspect.Parameter.KEYWORD_ONLY), default=f.default,
                                annotation=f.type)
              for f in dataclasses.fields(SimulationRequest)]
    return inspect.Signature([*fields, *extra])


def simulate(params: ReducerParams | None = None, fault: Any = None, *,
             progress: Callable[[int, int], None] | None = None, **keywords: Any) -> SimulationResult:
    """Simulate the housing vibration of an RV reducer at constant speed and load, or under a speed and load
    profile: ``SimulationRequest(params, fault, **keywords).run(progress)``.

    Parameters
    ----------
    params, fault, **keywords
        The fields of :class:`SimulationRequest` (the reducer, the fault, the operating point, the record, the
        noise and its seed, the model settings, the motor current), documented there.
    progress : callable, optional
        ``progress(done_samples, total_samples)`` after each chunk.

    Returns
    -------
    SimulationResult
        ``signal`` of shape (channels, samples) in m/s^2: the housing acceleration at the sensor point seen
        through the sensor path of ``params.mounting`` (:mod:`rvdiag.dynamics.transfer`); ``theta_out`` and
        ``theta_in``, the carrier's and the sun's nominal angles at each sample (rad, 0 at the first sample).
        With the motor current (``signal`` "current" or "both"): ``current`` of shape (5, samples at
        ``current_fs``) with the channels ``i_a``, ``i_b``, ``i_c``, ``i_q`` (A) and ``speed`` (the rotor's, rpm);
        for ``signal="current"`` the result's ``signal``, ``fs`` and ``channel_names`` are those of the current.
    """
    return SimulationRequest(params, fault, **keywords).run(progress)


def prepare_simulation(params: ReducerParams | None = None, fault: Any = None,
                       **keywords: Any) -> PreparedSimulation:
    """:func:`simulate` (the same arguments, less ``progress``) up to the integration: every argument validated,
    the model built (``SimulationRequest(params, fault, **keywords).prepare()``).  ``simulate(...)`` is
    ``prepare_simulation(...)`` then its :meth:`~PreparedSimulation.integrate` and
    :meth:`~PreparedSimulation.finish`."""
    return SimulationRequest(params, fault, **keywords).prepare()


simulate.__signature__ = _request_signature(  # type: ignore[attr-defined]
    inspect.Parameter("progress", inspect.Parameter.KEYWORD_ONLY, default=None,
                      annotation="Callable[[int, int], None] | None"))
prepare_simulation.__signature__ = _request_signature()  # type: ignore[attr-defined]


@dataclasses.dataclass
class PreparedSimulation:
    """A :func:`simulate` call up to its integration (:func:`prepare_simulation`): the model, the record's length
    and run-in, and what :meth:`finish` needs to turn the integrator's rows into the result.

    :meth:`integrate` integrates it on the CPU (what :func:`simulate` does).  Another runner (the GPU ensemble,
    :mod:`rvdiag.dynamics.ensemble`) makes the integrator calls of :meth:`segment_calls` itself, each from
    ``start_state(call.t_start)``, writes each call's rows at its ``column`` of a ``(rows, columns)`` array
    (:attr:`rows`, :attr:`columns`) and passes that to :meth:`finish`: the same rows give the same result.
    """

    model: Model
    params: ReducerParams
    fault: Any
    settings: ModelSettings
    fs: float
    duration_s: float
    n_samples: int
    n_transient: int
    margin: tuple[int, int]
    workers: int
    profile: SpeedProfile
    load_profile: LoadProfile
    #: the request it was prepared from: the result reads the speeds, noise, seed, signal and current rate there
    request: SimulationRequest
    #: how each start state was found (:func:`initial_deflection`), one entry per :meth:`start_state` call
    starts: list[str] = dataclasses.field(default_factory=list)

    @property
    def rows(self) -> int:
        """Rows of the integrator's output: the sensor channels, then the motor's (with its electrical side)."""
        from rvdiag.dynamics.integrate import MOTOR_CHANNELS

        return self.model.sensor.shape[0] + (len(MOTOR_CHANNELS) if self.model.has_pmsm else 0)

    @property
    def columns(self) -> int:
        """Columns of the integrator's output: the record with its margins (:func:`current_record_margin`)."""
        return self.margin[0] + self.n_samples + self.margin[1]

    def start_state(self, t0: float) -> np.ndarray:
        """The state a run starts from at ``t0``: the static deflection at rest (:func:`initial_deflection`)."""
        q0, how = initial_deflection(self.model, t0)
        self.starts.append(how)
        return self.model.initial_state(q0, t0)

    def segment_calls(self) -> list[Any]:
        """The integrator calls of the record (:func:`rvdiag.dynamics.segments.segment_calls`)."""
        from rvdiag.dynamics.segments import segment_calls

        return segment_calls(self.model, self.fs, self.n_samples, self.n_transient, self.margin)

    def integrate(self, progress: Callable[[int, int], None] | None = None) -> tuple[np.ndarray, int]:
        """The integrator's rows and the number of segments, on the CPU
        (:func:`rvdiag.dynamics.segments.integrate_segments`)."""
        from rvdiag.dynamics.segments import integrate_segments

        return integrate_segments(self.model, self.fs, self.n_samples, self.n_transient, self.start_state,
                                  self.workers, progress, self.margin)

    def finish(self, out: np.ndarray, n_segments: int) -> SimulationResult:
        """The :class:`SimulationResult` from the integrator's rows ``out`` (:attr:`rows` x :attr:`columns`)."""
        model, params, fs, n_samples, margin = self.model, self.params, self.fs, self.n_samples, self.margin
        req = self.request
        seed, current_fs, signal_kind = req.seed, req.current_fs, req.signal
        n_sens = model.sensor.shape[0]
        signal = apply_path(out[:n_sens, margin[0]:margin[0] + n_samples], fs, params.mounting)
        starts = self.starts
        initial_state = starts[0] if len(set(starts)) == 1 else "; ".join(sorted(set(starts)))
        if req.noise_snr_db is not None:
            signal = add_awgn(signal, req.noise_snr_db, np.random.default_rng(seed))
        names = [f"accel[{d[0]:.3g},{d[1]:.3g}]" for d in model.sensor]
        current = None
        if model.has_pmsm:
            current = motor_current_record(out[n_sens:], fs, current_fs, margin)
            rng = np.random.default_rng([int(seed), 1])
            current[:4] += params.motor.current_noise * rng.standard_normal(current[:4].shape)
            if req.current_snr_db is not None:
                current = add_awgn(current, req.current_snr_db, rng)
        theta_out = self.profile.state(np.arange(n_samples) / float(fs), float(model.P[5]), float(self.duration_s))[0]
        record = {
            "initial_state": initial_state,
            "segments": n_segments,
            "workers": int(self.workers),
            "input_speed_rpm": req.input_speed_rpm,
            "output_speed_deg_s": req.output_speed_deg_s,
            "sun_speed_hz": float(model.P[5] + model.P[6]) / (2 * math.pi),
            "load_Nm": float(model.P[I_TLOAD]),
            "duration_s": float(self.duration_s),
            "fs": float(fs),
            "noise_snr_db": req.noise_snr_db,
            "seed": int(seed),
            "fault": _describe(self.fault),
            "mesh_source": model.mesh_source,
            "speed_profile": self.profile.to_dict(),
            "load_profile": self.load_profile.to_dict(),
            "model_settings": self.settings.to_dict(),
            "params": params.to_dict(),
        }
        if model.has_load:  # the load DOF's inertia (stated, or the gravity arm's M L^2)
            record["load_inertia_kg_m2"] = float(model.mass[-1])
        if current is None:
            return SimulationResult(signal, float(fs), record, names, theta_out, params.ratio * theta_out)
        record.update(signal=signal_kind, current_fs=float(current_fs), current_snr_db=req.current_snr_db,
                      current_units=dict(zip(CURRENT_CHANNELS, CURRENT_UNITS)))
        res = SimulationResult(signal, float(fs), record, names, theta_out, params.ratio * theta_out,
                               current=current, current_fs=float(current_fs), current_names=list(CURRENT_CHANNELS))
        return res.current_only() if signal_kind == "current" else res


