"""Which of a reducer's own parameters a commissioning record can identify: the sensitivity (Jacobian) of what the
record holds to each parameter about a healthy operating point, whitened by the record's noise, and its singular
values (docs/twin.md).

What a record holds (:data:`OBSERVATIONS`), each as the complex lines of its synchronous average over the sun's
revolutions relative to the carrier (the period of the sun's tooth errors and of the mesh table; orders 1..K,
``[Re, Im]`` stacked; :func:`sun_synchronous_lines`):

- ``"vibration"``: the housing acceleration (channel 0, through the sensor path), as the angle-domain features
  compute its TSA (:func:`rvdiag.features.orders.resample_to_angle`, :func:`rvdiag.features.orders.tsa`);
- ``"te"``: the transmission error between the motor's encoder and an encoder on the output,
  ``q_m / i - q_H`` (output rad; the vibratory rotor and carrier angles of the model, docs/model.md section 1),
  plus the motor encoder's once-per-revolution error (a parameter of its own, kind ``"encoder"``);
- ``"current"``: the drive's q-axis current ``i_q`` (the d-q current the phase lines ``f_e +- k f1`` carry).

``OperatingPoint(period_revs=3)`` averages over 3 sun revolutions instead, the period of the RV-20E's planets and
cranks too (their runouts and errors lie at a third of a sun order, which the sun's average cancels).  The TE and
the current are torsional and their sensitivities do not depend on the record's length; the housing sensor is fixed
while the planets orbit, so the vibration's do (docs/twin.md, "The checks"): take its Jacobian from a record as long
as the one it stands for.

The model (:func:`observe`) is the simulator's own, noise-free: the same kernels, step grid and start state as
:func:`rvdiag.dynamics.simulate` (the state is recorded at every sample, so the carrier's angle is available; the
sensor rows equal ``simulate``'s to the last bit).  The Jacobian (:func:`jacobian`) is by central differences with
the same seed and all else fixed; its linearity is checked against the differences at twice the step.

The noise of one record of ``T`` seconds (:class:`NoiseModel`): white noise of variance ``sigma^2`` per sample at
rate ``f`` puts ``sigma^2 / (2 f T)`` on the real and the imaginary part of every synchronous line (the average of
``k`` revolutions lowers it by ``1 / k``); the run-to-run variation (load, speed, temperature, mesh damping, gain:
the factors of :func:`rvdiag.library.paired.draw_variation`, uniform in ``1 +- pct / 100``, variance
``(pct / 100)^2 / 3``) moves the record along the columns ``G`` of its own Jacobian, and is shared by every
revolution and every signal of one record.  So one record's observation covariance is

    C = G Sigma_u G^T + diag(sigma_l^2),

and ``n`` records with their own draws give the Fisher information ``n J^T C^-1 J`` (Kay, *Fundamentals of
Statistical Signal Processing* vol. 1, sec. 3.9, eq. 3.31, the linear Gaussian model; Ljung, *System
Identification*, 2nd ed., ch. 7 and 9, the Cramér–Rao bound of a prediction-error estimate).  Parameters are
measured in units of their prior spread (``theta = theta_0 + L z``, ``L L^T`` the prior covariance: the tolerance
the parameter is drawn from), so the whitened Jacobian is ``C^-1/2 J L`` and a direction whose singular value
exceeds 1 is one the record determines better than the manufacturing tolerance already does (the local
identifiability of Bellman & Åström 1970 and of Grewal & Glover 1976, IEEE TAC 21, at a stated noise).  The
posterior covariance with the prior is ``L (F_z + I)^-1 L^T`` and the Cramér–Rao bound without it
``L F_z^-1 L^T`` (:func:`analyse`).

The sun's tooth errors are the positions of :func:`rvdiag.gears.modification.tooth_position_errors` (along the line
of action; their mean, a rotation, is no error), perturbed one tooth at a time through
``mesh_table_from_gears(tooth_errors_m=...)``; the planets' pitch errors are not in the model (their pattern repeats
only every Z2 mesh cycles and is left out of the one-revolution mesh table; their runout is in).  With ``N``
planets equally spaced, a sun-error component at sun order ``n`` reaches the sum of the planets' mesh forces (the
torque: TE and current) with the factor :func:`planet_phase_sum` ``(1/N) sum_i exp(-2 pi j n i / N)``: 1 when
``N`` divides ``n``, else 0 (the sequence-order cancellation of planetary gears: Inalpolat & Kahraman 2009, J. Sound
Vib. 323; Parker 2000, J. Sound Vib. 236), and a tooth-error harmonic ``h`` of a ``Z1``-tooth sun appears at sun
orders ``h + m Z1`` and ``m Z1 - h`` (:func:`torsional_orders`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.params import ReducerParams

#: the signals a commissioning record may hold
OBSERVATIONS = ("vibration", "te", "current")


# --------------------------------------------------------------------------- the harmonics' algebra
def planet_phase_sum(orders, n_planets: int) -> np.ndarray:
    """``|(1/N) sum_i exp(-2 pi j n i / N)|`` for each sun order ``n``: the share of a sun-synchronous component at
    order ``n`` that survives in the sum over ``N`` equally spaced planets (the net torque on the sun); 1 where
    ``N`` divides ``n``, 0 elsewhere (module docstring)."""
    n = np.asarray(orders, dtype=float)
    N = int(n_planets)
    if N < 1:
        raise ParameterError(f"n_planets must be >= 1, got {n_planets!r}")
    i = np.arange(N)
    return np.abs(np.exp(-2j * np.pi * np.multiply.outer(n, i) / N).mean(axis=-1))


def torsional_orders(harmonic: int, sun_teeth: int, n_planets: int, max_order: int) -> list[int]:
    """The sun orders ``<= max_order`` at which the tooth-error harmonic ``harmonic`` (cycles per sun revolution of
    the per-tooth pattern) appears, ``h + m Z1`` and ``m Z1 - h``, that survive in the planets' summed torque
    (``N`` divides the order).  E.g. the RV-20E (Z1 = 11, N = 2): harmonic 1 at orders 10, 12, 32, 34, ...;
    harmonic 2 at 2, 20, 24, ...  When ``Z1`` and ``N`` are coprime every harmonic has such orders (at the mesh's
    sidebands if not below it); when ``N`` divides ``Z1`` (planets meshing in phase) a harmonic that ``N`` does not
    divide has none: it is lost to the torque altogether."""
    h, Z, N = int(harmonic), int(sun_teeth), int(n_planets)
    out = set()
    for m in range(0, max_order // Z + 2):
        for n in (h + m * Z, m * Z - h):
            if 1 <= n <= max_order and n % N == 0:
                out.add(n)
    return sorted(out)


# --------------------------------------------------------------------------- parameters
#: kinds of parameter: where a perturbation acts
KINDS = ("tooth", "planet", "factor", "mounting", "gain", "load", "speed", "encoder")
#: columns of the model's planet table (:func:`rvdiag.dynamics.packing._pack_manufacturing_errors`) by name
PLANET_COLUMNS = {"runout_cos": 4, "runout_sin": 5, "hole_radial": 6, "hole_tangential": 7, "crank_phase": 8}


@dataclass(frozen=True)
class Parameter:
    """One parameter of the sensitivity study.

    ``kind`` (:data:`KINDS`) and ``key`` say where it acts: ``tooth`` (key: the sun tooth's index; m along the
    line of action), ``planet`` (key: ``(column name of PLANET_COLUMNS, planet)``; m or rad), ``factor`` (key: a
    tuple of ``(section, name)`` scaled together by ``1 + value``), ``mounting`` (key: a ``[mounting]`` name;
    absolute), ``gain`` / ``load`` / ``speed`` (factor ``1 + value`` on the vibration, the load torque, the speed),
    ``encoder`` (key ``"cos"`` or ``"sin"``: the motor encoder's once-per-revolution error, rad at the rotor).
    ``step`` is the finite-difference step and ``prior_sd`` the spread of the parameter among reducers (its
    tolerance), both in the parameter's unit.
    """

    name: str
    kind: str
    key: object
    step: float
    prior_sd: float
    unit: str = ""
    group: str = ""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ParameterError(f"parameter kind must be one of {KINDS}, got {self.kind!r}")
        if not (self.step > 0 and self.prior_sd > 0):
            raise ParameterError(f"{self.name}: step and prior_sd must be > 0")


def sun_tooth_prior(params: ReducerParams) -> np.ndarray:
    """The prior covariance (m^2) of the sun teeth's position errors of ``params``' ISO 1328 grade: single pitch
    deviations uniform in ``+- f_pT / 2`` (variance ``f_pT^2 / 12``), made zero-sum, summed and centred
    (:func:`rvdiag.gears.modification.tooth_position_errors`); rank ``Z1 - 1`` (the mean is no error)."""
    from rvdiag.gears.modification import iso1328_tolerances

    z = params.stage1.sun_teeth
    grade = params.modification.iso1328_grade or 5
    tol = iso1328_tolerances(params.stage1.module, params.stage1.module * z, grade)
    Cz = np.eye(z) - 1.0 / z
    A = Cz @ np.tril(np.ones((z, z))) @ Cz
    return A @ A.T * tol.single_pitch**2 / 12.0


def reducer_parameters(params: ReducerParams, *, teeth: bool = True, planets: bool = True, path: bool = True,
                       stiffness: bool = True, damping: bool = True, encoder: bool = True) -> list[Parameter]:
    """The parameters of a reducer that a twin would identify, with their tolerances as the prior spread:

    - every sun tooth's position error (grade ``[modification] iso1328_grade``; step 0.01 um: the model's
      response to a tooth's position bends within 0.1 um, docs/twin.md);
    - each planet's runout as its two components ``A_i, B_i`` (``r_i = A_i cos b_0 + B_i sin b_0``; prior the
      uniform eccentricity in ``[0, F_rT / 4]`` at a uniform angle, ``sd = F_rT / (4 sqrt 6)`` per component),
      its crank hole's radial and tangential position (``+- tol / 2`` uniform) and its crank's phase;
    - the sensor path: its resonance (``path_resonance_hz``, prior 1/6 of the monitoring library's 1.5-9 kHz),
      damping ratio and gain;
    - the stiffness factors of :data:`rvdiag.library.config.STIFFNESS_KEYS` and the mesh and bearing damping
      ratios (each +-10 % uniform, as the monitoring library draws them);
    - the motor encoder's once-per-revolution error (``[motor] encoder_error_arcsec`` as its spread).
    """
    from rvdiag.gears.modification import iso1328_tolerances
    from rvdiag.library.config import DAMPING_KEYS, STIFFNESS_KEYS

    out: list[Parameter] = []
    s1 = params.stage1
    N = s1.n_planets
    mf = params.manufacturing
    um = 1e-6
    if teeth:
        sd = np.sqrt(np.diag(sun_tooth_prior(params)))
        out += [Parameter(f"sun tooth {j}", "tooth", j, 0.01 * um, float(sd[j]), "m", "sun teeth")
                for j in range(s1.sun_teeth)]
    if planets:
        F_rT = iso1328_tolerances(s1.module, s1.module * s1.planet_teeth, mf.planet_runout_grade or 5).runout
        sd_run = F_rT / 4.0 / math.sqrt(6.0)
        sd_hole = max(mf.crank_hole_position, 1e-6) / math.sqrt(12.0)
        sd_phase = math.radians(max(mf.crank_phase_arcmin, 0.1) / 60.0) / math.sqrt(12.0)
        for i in range(N):
            out += [Parameter(f"planet {i} runout A", "planet", ("runout_cos", i), 0.01 * um, sd_run, "m", "runout"),
                    Parameter(f"planet {i} runout B", "planet", ("runout_sin", i), 0.01 * um, sd_run, "m", "runout"),
                    Parameter(f"crank hole {i} radial", "planet", ("hole_radial", i), 0.01 * um, sd_hole, "m",
                              "crank holes"),
                    Parameter(f"crank hole {i} tangential", "planet", ("hole_tangential", i), 0.01 * um, sd_hole, "m",
                              "crank holes"),
                    Parameter(f"crank {i} phase", "planet", ("crank_phase", i), math.radians(0.0025 / 60.0), sd_phase,
                              "rad", "crank phases")]
    if path:
        out += [Parameter("path resonance", "mounting", "path_resonance_hz", 5.0, 7500.0 / 6.0, "Hz", "path"),
                Parameter("path damping ratio", "mounting", "path_damping_ratio", 0.001, 0.13 / math.sqrt(12.0), "",
                          "path"),
                Parameter("path gain", "gain", None, 0.01, 0.1 / math.sqrt(3.0), "", "path")]
    if stiffness:
        out += [Parameter(f"{s}.{k}", "factor", ((s, k),), 0.01, 0.1 / math.sqrt(3.0), "", "stiffness")
                for s, k in STIFFNESS_KEYS]
    if damping:
        out += [Parameter(f"{s}.{k}", "factor", ((s, k),), 0.01, 0.1 / math.sqrt(3.0), "", "damping")
                for s, k in DAMPING_KEYS]
    if encoder:
        e = math.radians(max(params.motor.encoder_error_arcsec, 1.0) / 3600.0)
        out += [Parameter("motor encoder error cos", "encoder", "cos", e / 10.0, e / math.sqrt(2.0), "rad", "encoder"),
                Parameter("motor encoder error sin", "encoder", "sin", e / 10.0, e / math.sqrt(2.0), "rad", "encoder")]
    return out


def run_to_run_parameters(pct: Mapping[str, float] | None = None) -> list[Parameter]:
    """The run-to-run variation of one record (:func:`rvdiag.library.paired.draw_variation`'s keys and ranges,
    ``pct`` overriding :data:`rvdiag.library.config.VARIATION_KEYS`): each factor uniform in ``1 +- pct / 100``,
    ``prior_sd = pct / 100 / sqrt 3``."""
    from rvdiag.library.config import STIFFNESS_KEYS, VARIATION_KEYS

    p = {**VARIATION_KEYS, **(pct or {})}
    sd = {k: max(float(v), 1e-9) / 100.0 / math.sqrt(3.0) for k, v in p.items()}
    return [Parameter("load", "load", None, 0.01, sd["load"], "", "run-to-run"),
            Parameter("speed", "speed", None, 0.002, sd["speed"], "", "run-to-run"),
            Parameter("temperature", "factor", tuple(STIFFNESS_KEYS), 0.01, sd["temperature"], "", "run-to-run"),
            Parameter("mesh damping", "factor", (("damping", "mesh_damping_ratio"),), 0.02, sd["mesh_damping"], "",
                      "run-to-run"),
            Parameter("gain", "gain", None, 0.01, sd["gain"], "", "run-to-run")]


# --------------------------------------------------------------------------- the noise-free observations
@dataclass(frozen=True)
class OperatingPoint:
    """Where and how the sensitivity is taken: the output speed and load, the whole sun revolutions (relative to
    the carrier) recorded after ``transient_s`` of run-in, the sampling rate and the integrator's sub-steps, and
    the highest order kept of each signal (``max_hz`` / the sun's relative frequency): the accelerometer's band
    (10 kHz), the output encoder's read rate's Nyquist (4 kHz of an 8 kHz position loop) and the drive logger's
    (500 Hz of 1 kHz).

    ``period_revs`` is the averaging period in sun revolutions: 1 is the sun's TSA (what the angle-domain features
    compute), whose lines are the sun's whole orders; ``Z2 / Z1`` when that is whole (3 for the RV-20E) is the
    period of the cranks and planets as well (they turn once relative to the carrier per 3 sun revolutions), whose
    average keeps the lines at every third of a sun order too, where the planets' runouts and the cranks' errors
    lie.  ``revolutions`` must be a multiple of it."""

    output_speed_deg_s: float = 45.0
    load_Nm: float = 90.0
    revolutions: int = 3
    transient_s: float = 0.1
    fs: float = 48000.0
    substeps: int = 4
    samples_per_rev: int = 2048
    max_hz: Mapping[str, float] = field(default_factory=lambda: {"vibration": 10000.0, "te": 4000.0,
                                                                 "current": 500.0})
    period_revs: int = 1

    def __post_init__(self) -> None:
        if int(self.period_revs) < 1 or int(self.revolutions) % int(self.period_revs):
            raise ParameterError(f"revolutions ({self.revolutions}) must be a whole multiple of period_revs "
                                 f"({self.period_revs}) >= 1")

    def sun_hz(self, params: ReducerParams, speed: float = 1.0) -> float:
        """The sun's frequency relative to the carrier (Hz) at ``speed`` times the operating point's."""
        from rvdiag.kinematics import sun_speed_hz

        return sun_speed_hz(params, None, self.output_speed_deg_s * speed) * (1.0 - 1.0 / params.ratio)

    def max_order(self, params: ReducerParams, signal: str) -> int:
        """The highest line kept of ``signal``, in orders of the averaging period (``period_revs`` sun
        revolutions)."""
        k = self.period_revs
        return int(min(float(self.max_hz[signal]) * k / self.sun_hz(params), k * self.samples_per_rev // 2 - 1))


def sun_synchronous_lines(x, fs: float, rev_hz: float, samples_per_rev: int, max_order: int) -> np.ndarray:
    """``[Re X_1..X_K, Im X_1..X_K]`` of the synchronous average of ``x`` over the whole revolutions of a shaft
    turning at ``rev_hz`` from the first sample on: ``X_n = (1/M) sum_m t_m exp(-2 pi j n m / M)``, ``t`` the TSA
    of :func:`rvdiag.features.orders.tsa` on :func:`rvdiag.features.orders.resample_to_angle`'s ``M`` angles."""
    from rvdiag.features.orders import resample_to_angle, tsa

    x = np.asarray(x, dtype=float)
    revs = np.arange(x.size) * (float(rev_hz) / float(fs))
    t = tsa(resample_to_angle(x, fs, revs, samples_per_rev), samples_per_rev)
    X = np.fft.rfft(t)[1:max_order + 1] / samples_per_rev
    return np.concatenate([X.real, X.imag])


@dataclass
class Perturbation:
    """A point near the nominal reducer: parameter values (in their units) by :class:`Parameter`."""

    values: dict = field(default_factory=dict)

    def add(self, p: Parameter, v: float) -> "Perturbation":
        out = Perturbation(dict(self.values))
        out.values[p] = out.values.get(p, 0.0) + float(v)
        return out


def _split(pert: Perturbation, base: ReducerParams, teeth0: np.ndarray):
    """The parameter set, tooth errors, planet-table changes and signal factors of a perturbation."""
    changes: dict[str, dict[str, float]] = {}
    mounting: dict[str, float] = {}
    teeth = np.array(teeth0, dtype=float)
    planet: dict[tuple[str, int], float] = {}
    fac = {"gain": 1.0, "load": 1.0, "speed": 1.0}
    enc = np.zeros(2)
    scale: dict[tuple[str, str], float] = {}
    for p, v in pert.values.items():
        if p.kind == "tooth":
            teeth[int(p.key)] += v
        elif p.kind == "planet":
            planet[tuple(p.key)] = planet.get(tuple(p.key), 0.0) + v
        elif p.kind == "factor":
            for sk in p.key:
                scale[tuple(sk)] = scale.get(tuple(sk), 1.0) * (1.0 + v)
        elif p.kind == "mounting":
            mounting[str(p.key)] = mounting.get(str(p.key), getattr(base.mounting, str(p.key))) + v
        elif p.kind == "encoder":
            enc[0 if p.key == "cos" else 1] += v
        else:
            fac[p.kind] *= 1.0 + v
    for (s, k), f in scale.items():
        changes.setdefault(s, {})[k] = getattr(getattr(base, s), k) * f
    params = base.replace(**changes) if changes else base
    if mounting:
        params = params.replace(mounting=mounting)
    return params, teeth, planet, fac, enc


def nominal_tooth_errors(params: ReducerParams) -> np.ndarray:
    """The sun teeth's position errors (m) the simulator uses for ``params``: ``[modification]
    sun_tooth_errors_um`` where stated, else the drawn ones (zeros at grade 0)."""
    from rvdiag.gears.modification import iso1328_tolerances, tooth_position_errors

    z = params.stage1.sun_teeth
    md = params.modification
    if md.sun_tooth_errors_um is not None:
        return np.asarray(md.sun_tooth_errors_um, dtype=float) * 1e-6
    if md.iso1328_grade <= 0:
        return np.zeros(z)
    tol = iso1328_tolerances(params.stage1.module, params.stage1.module * z, md.iso1328_grade)
    return tooth_position_errors(z, tol, md.error_seed)


def simulate_states(params: ReducerParams, op: OperatingPoint, *, teeth=None, planet=None, load: float = 1.0,
                    speed: float = 1.0, pre_s: float = 0.02) -> dict:
    """One noise-free run with the motor's electrical side: the sensor rows (raw housing acceleration), ``i_q``,
    the rotor's and the carrier's vibratory angles at every sample, ``pre_s`` of the run-in included (so that the
    sensor path's causal filter has settled), as :func:`rvdiag.dynamics.simulate` integrates them."""
    from rvdiag.dynamics import ModelSettings, prepare_simulation
    from rvdiag.dynamics.integrate import integrate
    from rvdiag.dynamics.mesh import mesh_table_from_gears

    f_rel = op.sun_hz(params, speed)
    duration = (op.revolutions + 0.05) / f_rel
    table = mesh_table_from_gears(params, None, tooth_errors_m=teeth)
    st = ModelSettings(substeps=op.substeps, transient_s=op.transient_s)
    run = prepare_simulation(params, table, output_speed_deg_s=op.output_speed_deg_s * speed,
                             load_Nm=op.load_Nm * load, duration_s=duration, fs=op.fs, settings=st, signal="both")
    m = run.model
    for (name, i), v in (planet or {}).items():
        if m.P[_mfg_index()] == 0.0:
            raise ParameterError("the planet table's errors are compiled out: give the reducer a nonzero "
                                 "[manufacturing] tolerance")
        m.planet[i, PLANET_COLUMNS[name]] += v
    fs = op.fs
    n_pre = min(int(round(pre_s * fs)), run.n_transient - 1)
    y = run.start_state(-run.n_transient / fs)
    _, y = integrate(m, y, fs, 1, run.n_transient - n_pre - 1, first_sample=-n_pre - 1)  # to sample -n_pre
    n_tot = n_pre + run.n_samples
    names = m.names
    iH = names.index("carrier.th")
    im = m.rotor_index
    rows = np.empty((m.sensor.shape[0] + 4, n_tot))
    ang = np.empty((2, n_tot))
    for k in range(n_tot):
        ang[0, k], ang[1, k] = y[im], y[iH]
        s, y = integrate(m, y, fs, 1, 0, first_sample=k - n_pre)
        rows[:, k] = s[:, 0]
    n_s = m.sensor.shape[0]
    return {"sensor": rows[:n_s], "i_q": rows[n_s + 1], "q_m": ang[0], "q_H": ang[1], "n_pre": n_pre,
            "f_rel": f_rel, "ratio": float(params.ratio), "fs": fs, "speed": speed,
            "motor_hz": f_rel / (1.0 - 1.0 / params.ratio)}


def _mfg_index() -> int:
    from rvdiag.dynamics import kernels as kn

    return kn.I_MFG


def observations(states: dict, params: ReducerParams, op: OperatingPoint, *, gain: float = 1.0,
                 encoder=(0.0, 0.0)) -> dict[str, np.ndarray]:
    """The synchronous lines (:func:`sun_synchronous_lines`) of each signal of :data:`OBSERVATIONS` from
    :func:`simulate_states`' run: the housing acceleration through ``params``' sensor path times ``gain``, the
    transmission error ``(q_m + e_c cos th_m + e_s sin th_m) / i - q_H`` (``encoder = (e_c, e_s)``), and ``i_q``."""
    from rvdiag.dynamics.transfer import apply_path

    fs, n_pre = states["fs"], states["n_pre"]
    f_rel = states["f_rel"] / op.period_revs                   # the averaging period's frequency
    spr = op.samples_per_rev * op.period_revs
    vib = gain * apply_path(states["sensor"][:1], fs, params.mounting)[0, n_pre:]
    t = (np.arange(vib.size)) / fs
    th_m = 2.0 * np.pi * states["motor_hz"] * t
    q_m = states["q_m"][n_pre:] + encoder[0] * np.cos(th_m) + encoder[1] * np.sin(th_m)
    te = q_m / states["ratio"] - states["q_H"][n_pre:]
    out = {}
    for name, x in (("vibration", vib), ("te", te), ("current", states["i_q"][n_pre:])):
        out[name] = sun_synchronous_lines(x, fs, f_rel, spr, op.max_order(params, name))
    out["_vibration_power"] = float(np.mean(vib**2))
    return out


def observe(base: ReducerParams, op: OperatingPoint, pert: Perturbation | None = None, teeth0=None,
            cache: dict | None = None) -> dict[str, np.ndarray]:
    """The noise-free observations of ``base`` moved by ``pert`` (:func:`observations` of
    :func:`simulate_states`).  ``teeth0``: the nominal tooth errors (default the drawn ones).  Runs that differ
    only in the sensor path, the gain or the encoder's error share one integration (``cache``)."""
    pert = pert or Perturbation()
    teeth0 = nominal_tooth_errors(base) if teeth0 is None else np.asarray(teeth0, dtype=float)
    params, teeth, planet, fac, enc = _split(pert, base, teeth0)
    key = (tuple(teeth), tuple(sorted(planet.items())), fac["load"], fac["speed"],
           tuple(sorted((p.name, v) for p, v in pert.values.items() if p.kind == "factor")))
    states = cache.get(key) if cache is not None else None
    if states is None:
        states = simulate_states(params, op, teeth=teeth, planet=planet, load=fac["load"], speed=fac["speed"])
        if cache is not None:
            cache[key] = states
    return observations(states, params, op, gain=fac["gain"], encoder=enc)


# --------------------------------------------------------------------------- the Jacobian
@dataclass
class Jacobian:
    """Central-difference sensitivities of each signal to each parameter (per unit of the parameter).

    ``columns[signal]`` (observations, parameters); ``nominal[signal]`` the noise-free lines at the nominal point;
    ``linearity[signal][j]`` ``||J_h - J_2h|| / ||J_h||`` (differences at the step and at twice it; ``nan`` when not
    checked or where the column is zero); ``vibration_power`` the nominal housing signal's mean square (m^2/s^4)."""

    parameters: list[Parameter]
    columns: dict[str, np.ndarray]
    nominal: dict[str, np.ndarray]
    linearity: dict[str, np.ndarray]
    vibration_power: float


def jacobian(base: ReducerParams, op: OperatingPoint, parameters: Sequence[Parameter], *, check_linearity=True,
             teeth0=None, progress: Callable[[int, int, str], None] | None = None) -> Jacobian:
    """Central differences ``(y(+h) - y(-h)) / 2h`` of :func:`observe` for every parameter (module docstring);
    with ``check_linearity`` (True, or a set of parameter names) also at ``2h``."""
    teeth0 = nominal_tooth_errors(base) if teeth0 is None else np.asarray(teeth0, dtype=float)
    cache: dict = {}
    nom = observe(base, op, None, teeth0, cache)
    sigs = list(OBSERVATIONS)
    cols = {s: np.zeros((nom[s].size, len(parameters))) for s in sigs}
    lin = {s: np.full(len(parameters), np.nan) for s in sigs}
    for j, p in enumerate(parameters):
        h = p.step
        yp = observe(base, op, Perturbation().add(p, h), teeth0, cache)
        ym = observe(base, op, Perturbation().add(p, -h), teeth0, cache)
        for s in sigs:
            cols[s][:, j] = (yp[s] - ym[s]) / (2 * h)
        check = check_linearity is True or (not isinstance(check_linearity, bool) and p.name in check_linearity)
        if check:
            y2p = observe(base, op, Perturbation().add(p, 2 * h), teeth0, cache)
            y2m = observe(base, op, Perturbation().add(p, -2 * h), teeth0, cache)
            for s in sigs:
                d1 = cols[s][:, j]
                n1 = float(np.linalg.norm(d1))
                if n1 > 0:
                    lin[s][j] = float(np.linalg.norm(d1 - (y2p[s] - y2m[s]) / (4 * h))) / n1
        for k in [k for k in cache if k != next(iter(cache))]:
            del cache[k]                                                  # keep the nominal run only
        if progress is not None:
            progress(j + 1, len(parameters), p.name)
    return Jacobian(list(parameters), cols, {s: nom[s] for s in sigs}, lin, nom["_vibration_power"])


def variation_perturbation(factors: Mapping[str, float], pct: Mapping[str, float] | None = None,
                           without: tuple[str, ...] = ()) -> Perturbation:
    """The perturbation of one record's run-to-run factors ``factors`` (:func:`rvdiag.library.paired.draw_variation`'s
    ``{key: factor}``): each factor's excess over 1 on its parameter of :func:`run_to_run_parameters` (``pct``), the
    keys in ``without`` left out."""
    keys = {p.name.replace(" ", "_"): p for p in run_to_run_parameters(pct)}
    return Perturbation({keys[k]: v - 1.0 for k, v in factors.items() if k not in without})


def run_to_run_draws(base: ReducerParams, op: OperatingPoint, draws: int, seed: int = 0,
                     pct: Mapping[str, float] | None = None, teeth0=None) -> dict[str, np.ndarray]:
    """``draws`` noise-free records of ``base``, each with its own run-to-run variation drawn by
    :func:`rvdiag.library.paired.draw_variation` from ``numpy.random.default_rng(seed)`` (the nonlinear spread
    that :func:`analyse`'s ``draws`` takes beside the linearised one); ``{signal: (draws, observations)}``."""
    from rvdiag.library.paired import draw_variation

    rng = np.random.default_rng(seed)
    teeth0 = nominal_tooth_errors(base) if teeth0 is None else teeth0
    out: dict[str, list] = {s: [] for s in OBSERVATIONS}
    for _ in range(int(draws)):
        y = observe(base, op, variation_perturbation(draw_variation(rng, pct), pct), teeth0)
        for s in OBSERVATIONS:
            out[s].append(y[s])
    return {s: np.array(v) for s, v in out.items()}


# --------------------------------------------------------------------------- noise, Fisher information, SVD
@dataclass(frozen=True)
class NoiseModel:
    """The white noise of each signal: variance per sample and the rate it is sampled at.

    Defaults: the housing floor 20 dB below the healthy power (``snr_db``, configs/monitoring.toml), sampled at
    48 kHz; the output encoder's 23-bit quantisation (``(2 pi / 2^23)^2 / 12`` rad^2) read at 8 kHz; the drive's
    current sensors' 5 mA rms (``[motor] current_noise``) at 1 kHz."""

    snr_db: float = 20.0
    vibration_fs: float = 48000.0
    te_sd_rad: float = 2.0 * math.pi / 2**23 / math.sqrt(12.0)
    te_fs: float = 8000.0
    current_sd_A: float = 5e-3
    current_fs: float = 1000.0

    def line_variance(self, signal: str, record_s: float, vibration_power: float) -> float:
        """The variance of the real (or imaginary) part of one synchronous line from a record of ``record_s``:
        ``sigma^2 / (2 f T)``."""
        if signal == "vibration":
            var, f = vibration_power * 10.0 ** (-self.snr_db / 10.0), self.vibration_fs
        elif signal == "te":
            var, f = self.te_sd_rad**2, self.te_fs
        elif signal == "current":
            var, f = self.current_sd_A**2, self.current_fs
        else:
            raise ParameterError(f"unknown signal {signal!r}; use one of {OBSERVATIONS}")
        return var / (2.0 * f * float(record_s))


def prior_square_root(parameters: Sequence[Parameter], tooth_prior: np.ndarray | None = None):
    """``L`` with ``L L^T`` the prior covariance of ``parameters`` and the name of each of its columns: the sun
    teeth's block from ``tooth_prior`` (its eigenvectors with a nonzero eigenvalue, named by the tooth-error
    harmonic that dominates each), every other parameter its ``prior_sd``."""
    n = len(parameters)
    tooth = [j for j, p in enumerate(parameters) if p.kind == "tooth"]
    others = [j for j in range(n) if j not in tooth]
    cols, names = [], []
    if tooth:
        if tooth_prior is None:
            S = np.diag([parameters[j].prior_sd ** 2 for j in tooth])
        else:
            S = np.asarray(tooth_prior, dtype=float)[np.ix_([parameters[j].key for j in tooth],
                                                            [parameters[j].key for j in tooth])]
        w, V = np.linalg.eigh(S)
        keep = w > 1e-9 * w.max()
        z = len(tooth)
        F = np.fft.rfft(V[:, keep], axis=0)
        for k in np.flatnonzero(keep):
            c = np.zeros(n)
            c[tooth] = V[:, k] * math.sqrt(w[k])
            cols.append(c)
        harm = np.argmax(np.abs(F[1:]), axis=0) + 1
        order = np.argsort(harm, kind="stable")
        cols = [cols[i] for i in order]
        names = [f"sun tooth harmonic {int(harm[i])}" for i in order]
    for j in others:
        c = np.zeros(n)
        c[j] = parameters[j].prior_sd
        cols.append(c)
        names.append(parameters[j].name)
    return np.array(cols).T, names


def fisher_information(J: np.ndarray, noise_var: np.ndarray, G: np.ndarray | None = None,
                       var_u: np.ndarray | None = None) -> np.ndarray:
    """``J^T C^-1 J`` with ``C = diag(noise_var) + G diag(var_u) G^T`` (Woodbury: ``C^-1 = D^-1 - D^-1 G (diag(var_u)^-1
    + G^T D^-1 G)^-1 G^T D^-1``; Golub & Van Loan, Matrix Computations, sec. 2.1.4)."""
    J = np.asarray(J, dtype=float)
    d = np.asarray(noise_var, dtype=float)
    if d.shape != (J.shape[0],) or not np.all(d > 0):
        raise ParameterError("noise_var must hold one positive variance per observation")
    DJ = J / d[:, None]
    F = J.T @ DJ
    if G is not None and G.shape[1]:
        DG = G / d[:, None]
        inner = np.diag(1.0 / np.asarray(var_u, dtype=float)) + G.T @ DG
        B = G.T @ DJ
        F = F - B.T @ np.linalg.solve(inner, B)
    return 0.5 * (F + F.T)


@dataclass
class Observability:
    """The whitened sensitivity of one set of signals (:func:`analyse`).

    ``singular_values`` (descending) and ``directions`` (columns, in prior-spread units over ``names``) of
    ``C^-1/2 J L``; ``crb_sd`` and ``posterior_sd`` per column of ``L`` as a share of its prior spread (``inf``
    where the bound is unbounded); ``tooth_crb_m``, ``tooth_posterior_m`` per sun tooth's position error (m),
    ``tooth_prior_m`` its prior RMS and ``tooth_posterior_cov_m2`` the teeth's posterior covariance."""

    signals: tuple[str, ...]
    names: list[str]
    singular_values: np.ndarray
    directions: np.ndarray
    crb_sd: np.ndarray
    posterior_sd: np.ndarray
    tooth_crb_m: np.ndarray
    tooth_posterior_m: np.ndarray
    tooth_prior_m: np.ndarray
    tooth_posterior_cov_m2: np.ndarray | None = None

    def pitch_posterior_m(self) -> np.ndarray:
        """The posterior spread of each sun tooth's single pitch deviation ``f_pt,j = e_j - e_(j-1)`` (m), from the
        teeth's posterior covariance."""
        C = self.tooth_posterior_cov_m2
        z = C.shape[0]
        D = np.eye(z) - np.roll(np.eye(z), -1, axis=1)
        return np.sqrt(np.diag(D @ C @ D.T))

    def identifiable(self, threshold: float = 1.0) -> list[str]:
        """Names whose bound is below ``1 / threshold`` of their prior spread."""
        return [n for n, s in zip(self.names, self.crb_sd) if s < 1.0 / threshold]


def analyse(jac: Jacobian, nuisance: Jacobian | None, signals: Sequence[str], *, record_s: float = 1.0,
            records: int = 1, noise: NoiseModel | None = None, tooth_prior: np.ndarray | None = None,
            draws: Mapping[str, np.ndarray] | None = None) -> Observability:
    """The observability of ``jac``'s parameters from ``records`` records of ``record_s`` each holding
    ``signals``: each record's noise is the white floor of :class:`NoiseModel` plus the run-to-run variation along
    ``nuisance``'s columns (its parameters' ``prior_sd`` as the spread; a new draw per record, shared by the
    record's signals; with ``draws`` (:func:`run_to_run_draws`) also their sample covariance, which holds the
    variation's nonlinear part in up to ``K - 1`` more directions), the Fisher information ``records J^T C^-1 J`` in units of the prior spread ``L``
    (:func:`prior_square_root`), its singular values and the Cramér–Rao and posterior spreads (module docstring)."""
    noise = noise or NoiseModel()
    sig = tuple(signals)
    for s in sig:
        if s not in OBSERVATIONS:
            raise ParameterError(f"unknown signal {s!r}; use {OBSERVATIONS}")
    J = np.vstack([jac.columns[s] for s in sig])
    d = np.concatenate([np.full(jac.columns[s].shape[0], noise.line_variance(s, record_s, jac.vibration_power))
                        for s in sig])
    G = var_u = None
    if nuisance is not None:
        G = np.vstack([nuisance.columns[s] for s in sig])
        var_u = np.array([p.prior_sd ** 2 for p in nuisance.parameters])
    if draws is not None:
        D = np.hstack([np.asarray(draws[s], dtype=float) for s in sig])
        Dc = (D - D.mean(axis=0)).T / math.sqrt(max(D.shape[0] - 1, 1))
        G = Dc if G is None else np.hstack([G, Dc])
        var_u = np.ones(Dc.shape[1]) if var_u is None else np.concatenate([var_u, np.ones(Dc.shape[1])])
    L, names = prior_square_root(jac.parameters, tooth_prior)
    Fz = records * fisher_information(J @ L, d, G, var_u)
    w, V = np.linalg.eigh(Fz)
    w = np.clip(w, 0.0, None)
    order = np.argsort(w)[::-1]
    sv, V = np.sqrt(w[order]), V[:, order]
    pos = np.linalg.inv(Fz + np.eye(Fz.shape[0]))
    null = w[order] <= 1e-12 * max(float(w.max()), 1e-300)
    inv_w = np.where(null, np.inf, 1.0 / np.where(null, 1.0, w[order]))
    crb = np.sqrt(_bounded_sum(V, inv_w))
    tooth = [j for j, p in enumerate(jac.parameters) if p.kind == "tooth"]
    Lt = L[tooth]
    prior_m = np.sqrt(np.sum(Lt**2, axis=1))
    post_m = np.sqrt(np.einsum("ij,jk,ik->i", Lt, pos, Lt))
    crb_m = np.sqrt(_bounded_sum(Lt @ V, inv_w))
    return Observability(sig, names, sv, V, crb, np.sqrt(np.diag(pos)), crb_m, post_m, prior_m, Lt @ pos @ Lt.T)


def _bounded_sum(A: np.ndarray, inv_w: np.ndarray) -> np.ndarray:
    """``sum_k A_ik^2 inv_w_k`` per row, ``inf`` for a row with a share (> 1e-6 of its norm) along an unbounded
    direction (``inv_w = inf``) and that direction ignored otherwise (round-off of an exact zero)."""
    A2 = A**2
    tiny = A2 <= 1e-12 * np.maximum(A2.sum(axis=1, keepdims=True), 1e-300)
    with np.errstate(invalid="ignore"):
        return np.where(tiny, 0.0, A2 * inv_w[None, :]).sum(axis=1)


__all__ = ["Jacobian", "KINDS", "NoiseModel", "OBSERVATIONS", "Observability", "OperatingPoint", "Parameter",
           "Perturbation", "analyse", "fisher_information", "jacobian", "nominal_tooth_errors", "observe",
           "observations", "planet_phase_sum", "prior_square_root", "reducer_parameters", "run_to_run_draws",
           "run_to_run_parameters", "variation_perturbation",
           "simulate_states", "sun_synchronous_lines", "sun_tooth_prior", "torsional_orders"]
