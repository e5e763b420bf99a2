"""Identify one reducer's own sun tooth errors from its commissioning records' transmission error (docs/twin.md,
"A specimen's tooth errors: ``rvdiag update --specimen``").

What a record gives (:func:`te_record`): the input shaft's (motor encoder's) angle ``theta_in`` and the output
encoder's ``theta_out`` (rad) at the same instants.  Their transmission error ``TE = theta_in / i - theta_out``
(output rad; ``i`` the reducer's ratio) is resampled at ``samples_per_rev`` uniform angles of the sun relative to
the carrier, ``(theta_in - theta_out) / 2 pi`` revolutions, averaged over whole revolutions (a whole number of the
cranks' period, ``Z2 / Z1`` sun revolutions where that is whole, so that the planets' runouts at a third of a sun
order cancel) and kept as its complex lines (:func:`te_lines`; :func:`rvdiag.features.orders.resample_to_angle`,
:func:`rvdiag.features.orders.tsa`).  The model's lines are computed by the same function from the simulated
angles (:func:`rvdiag.updating.observability.simulate_states`: the rigid rotation plus the rotor's and carrier's
vibratory angles), sampled at the record's rate, so that both sides go through one pipeline.

The estimate (:func:`identify_specimen`) is the maximum a posteriori of the sun's ``Z1`` tooth position errors
``theta = L z`` (``L L^T`` the prior covariance of the ISO 1328 grade, :func:`~rvdiag.updating.observability.
sun_tooth_prior`; rank ``Z1 - 1``, the mean is no error):

    min_z  sum_r (y_r - f_p(r)(L z))^T C_r^-1 (y_r - f_p(r)(L z)) + z^T z,

``y_r`` the lines of record ``r``, ``f_p`` the model's at its operating point ``p``, and ``C_r`` its noise: the
white floor of the output encoder, ``sigma^2 / (2 f T)`` per line part (:class:`~rvdiag.updating.observability.
NoiseModel`) plus the run-to-run variation of :func:`rvdiag.library.paired.draw_variation` (load, speed,
temperature, mesh damping: linearised columns ``G`` and ``draws`` drawn records), as
:func:`~rvdiag.updating.observability.analyse` whitens it (Kay, vol. 1, sec. 3.9; Ljung, *System Identification*,
ch. 7 and 9).  It is solved by Levenberg-Marquardt (Nocedal & Wright, *Numerical Optimization*, 2nd ed., sec. 10.3)
with one Jacobian per operating point, taken by central differences at the start (a chord Gauss-Newton: one
simulation per point and iteration; :func:`levenberg_marquardt`).  The posterior covariance is the Gauss-Newton one
at the solution, ``L (sum_r Jz^T C_r^-1 Jz + I)^-1 L^T`` (the Fisher information plus the prior).

Measured in docs/twin.md on held-out simulated specimens; the TE's response to the teeth is close to linear over
the tolerance (a zero pattern is a good start), the run-to-run variation biases the estimate several times beyond
the bound, and the stiffnesses are taken as given (the global update's, :func:`rvdiag.updating.update_parameters`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from rvdiag.errors import DataFileError, ParameterError, RvdiagError
from rvdiag.params import ReducerParams
from rvdiag.updating import observability as ob

#: what an identification leaves as given, stated in every result
NOT_IDENTIFIED = (
    "crank holes' positions and cranks' phases (not identifiable from any signal: docs/twin.md)",
    "planets' runouts (they lie at a third of a sun order, which the sun's average cancels)",
    "planets' tooth pitch errors (not in the model)",
    "stiffness and damping factors and the sensor path (left at the given parameter set's values: the global "
    "update's, rvdiag update)",
    "the motor encoder's once-per-revolution error",
)

#: the model's own rate at least this (Hz): the record's rate times a whole factor (the integrator's step grid)
MODEL_MIN_FS = 40000.0


@dataclass(frozen=True)
class SpecimenSettings:
    """How an identification runs.

    ``iterations``: Levenberg-Marquardt iterations at most; ``draws``: run-to-run records drawn (seed
    ``draw_seed``) beside the linearised variation in each record's covariance; ``revolutions``: sun revolutions
    per model simulation (a multiple of the averaging period); ``samples_per_rev``: angles per revolution of the
    average; ``max_hz``: the highest TE line kept (also at most 0.45 of the record's rate); ``te_noise_rad``: the
    output encoder's white noise per sample (rad; default the 23-bit quantisation, ``2 pi / 2^23 / sqrt 12``);
    ``broyden``: update the chord Jacobian after each step (:func:`levenberg_marquardt`); ``records_spread``: add
    the sample covariance of the lines of an operating point's records (3 or more) to each one's covariance (the
    run-to-run variation as this specimen shows it; it counts the white floor twice);
    ``speed_tolerance``: records whose speeds agree within this share (and with the same load and rate) share one
    operating point, simulated at their mean speed (2.5 %: the run-to-run variation's speed spans +-1 %, which
    the whitening holds)."""

    iterations: int = 15
    draws: int = 8
    draw_seed: int = 0
    revolutions: int = 3
    samples_per_rev: int = 2048
    max_hz: float = 4000.0
    te_noise_rad: float = ob.NoiseModel().te_sd_rad
    speed_tolerance: float = 0.025
    broyden: bool = False
    records_spread: bool = False

    def __post_init__(self) -> None:
        if self.iterations < 0 or self.draws < 0 or self.revolutions < 1:
            raise ParameterError("iterations and draws must be >= 0 and revolutions >= 1")
        if not (self.te_noise_rad > 0 and self.max_hz > 0 and self.speed_tolerance > 0):
            raise ParameterError("te_noise_rad, max_hz and speed_tolerance must be > 0")


def averaging_period(params: ReducerParams) -> int:
    """The sun revolutions (relative to the carrier) after which the planets and cranks are back too: ``Z2 / Z1``
    when whole (3 for the RV-20E), else 1."""
    s1 = params.stage1
    return s1.planet_teeth // s1.sun_teeth if s1.planet_teeth % s1.sun_teeth == 0 else 1


# --------------------------------------------------------------------------- the TE's synchronous lines
def te_lines(input_angle, output_angle, fs: float, ratio: float, *, samples_per_rev: int, period: int,
             revolutions: int | None = None, name: str = "the record") -> tuple[np.ndarray, int]:
    """The complex lines ``X_1..X_(M/2 - 1)`` (``[Re, Im]`` stacked) of the transmission error
    ``input_angle / ratio - output_angle`` averaged over whole revolutions of the sun relative to the carrier,
    ``(input_angle - output_angle) / 2 pi`` (module docstring), and the number of revolutions averaged: the
    largest multiple of ``period`` (at most ``revolutions``, when given) the record holds.  One
    :class:`~rvdiag.errors.DataFileError` line for a record too short, not turning or not at the ratio."""
    from rvdiag.features.orders import resample_to_angle

    a_in = np.asarray(input_angle, dtype=float).ravel()
    a_out = np.asarray(output_angle, dtype=float).ravel()
    if a_in.size != a_out.size or a_in.size < 16:
        raise DataFileError(f"{name}: the input and output angles must hold the same number (>= 16) of samples, "
                            f"got {a_in.size} and {a_out.size}")
    if not (np.all(np.isfinite(a_in)) and np.all(np.isfinite(a_out))):
        raise DataFileError(f"{name}: the angle channels hold NaN or infinite values")
    revs = (a_in - a_out) / (2.0 * np.pi)
    if revs[-1] < revs[0]:
        raise DataFileError(f"{name}: the input turns backwards (its angle falls); the model is simulated turning "
                            "forwards: give a record at a positive speed")
    if not np.all(np.diff(revs) > 0):
        raise DataFileError(f"{name}: the sun's angle relative to the carrier, input - output angle, is not "
                            "monotonic: the record must be at a steady speed (rad channels, unwrapped)")
    te = a_in / float(ratio) - a_out
    turn = a_out[-1] - a_out[0]
    if abs(turn) <= 0 or abs(te[-1] - te[0]) > 1e-3 * abs(turn):
        raise DataFileError(f"{name}: the input angle does not turn at the reducer's ratio {ratio:g} times the "
                            f"output's (transmission error drifts by {te[-1] - te[0]:.3g} rad over "
                            f"{turn:.3g} rad): is the output angle channel the output encoder's, and are both in rad?")
    have = math.floor(revs[-1] - math.ceil(revs[0] - 1e-9) + 1e-9)
    n = (have // period) * period
    if revolutions is not None:
        n = min(n, (int(revolutions) // period) * period)
    if n < period:
        raise DataFileError(f"{name}: the record holds {revs[-1] - revs[0]:.3g} revolutions of the sun relative to "
                            f"the carrier; the sun-synchronous average needs {period} whole ones (the cranks' "
                            f"period): record at least {period + 1} revolutions")
    spr = int(samples_per_rev)
    ta = resample_to_angle(te, fs, revs, spr)[: n * spr]
    t = ta.reshape(n, spr).mean(axis=0)
    X = np.fft.rfft(t)[1: spr // 2] / spr
    return np.concatenate([X.real, X.imag]), n


@dataclass(frozen=True)
class TERecord:
    """One commissioning record's TE lines (:func:`te_lines`, every order up to ``samples_per_rev / 2 - 1``) and
    its operating point: the output speed the encoders measured, the load it was stated at, its rate, and the sun
    revolutions and seconds averaged."""

    name: str
    lines: np.ndarray
    fs: float
    output_speed_deg_s: float
    load_Nm: float
    revolutions: int
    averaged_s: float

    def truncated(self, max_order: int) -> np.ndarray:
        """``[Re X_1..X_K, Im X_1..X_K]`` for ``K = max_order``."""
        return _first_orders(self.lines, max_order)


def _first_orders(lines: np.ndarray, max_order: int) -> np.ndarray:
    """``[Re X_1..X_K, Im X_1..X_K]`` of stacked lines ``[Re..., Im...]`` (:func:`te_lines`), ``K = max_order``."""
    h = lines.size // 2
    return np.concatenate([lines[:max_order], lines[h: h + max_order]])


def te_record(input_angle, output_angle, fs: float, params: ReducerParams, *, load_Nm: float, name: str = "",
              settings: SpecimenSettings | None = None) -> TERecord:
    """A commissioning record (:class:`TERecord`) from its two encoder angles (rad) sampled at ``fs``, at the
    output load ``load_Nm``; its speed is the output encoder's mean."""
    st = settings or SpecimenSettings()
    name = name or "the record"
    if not (fs and fs > 0 and math.isfinite(fs)):
        raise ParameterError(f"{name}: the sampling rate must be > 0, got {fs!r}")
    if not math.isfinite(load_Nm):
        raise ParameterError(f"{name}: the load must be a number, got {load_Nm!r}")
    lines, n = te_lines(input_angle, output_angle, fs, params.ratio, samples_per_rev=st.samples_per_rev,
                        period=averaging_period(params), name=name)
    a_out = np.asarray(output_angle, dtype=float).ravel()
    speed = math.degrees(a_out[-1] - a_out[0]) * fs / (a_out.size - 1)
    f_rel = ob.OperatingPoint(output_speed_deg_s=speed).sun_hz(params)
    return TERecord(name, lines, float(fs), speed, float(load_Nm), n, n / f_rel)


# --------------------------------------------------------------------------- the model at an operating point
@dataclass
class PointModel:
    """The model's TE lines at one operating point and their linearisation there (:func:`linearise`).

    ``nominal``: the lines at the start (``teeth0``); ``J`` (lines, Z1) per m of each tooth's position error;
    ``G`` (lines, 4) per unit of the run-to-run factors ``run_to_run`` (their ``prior_sd`` the spread); ``D``
    (draws, lines) noise-free records with drawn run-to-run variation (or ``None``)."""

    output_speed_deg_s: float
    load_Nm: float
    fs: float
    max_order: int
    teeth0: np.ndarray
    nominal: np.ndarray
    J: np.ndarray
    G: np.ndarray
    run_to_run: list
    D: np.ndarray | None
    simulations: int = 0

    def covariance(self, record: TERecord, settings: SpecimenSettings) -> np.ndarray:
        """The noise covariance of ``record``'s lines: the white floor of its averaged seconds plus the run-to-run
        variation (module docstring)."""
        return te_covariance(self.G, [p.prior_sd ** 2 for p in self.run_to_run], self.D,
                             settings.te_noise_rad ** 2 / (2.0 * record.fs * record.averaged_s))


def te_covariance(G: np.ndarray, var_u, D: np.ndarray | None, white_var: float) -> np.ndarray:
    """``G diag(var_u) G^T + cov(D) + white_var I``: one record's covariance of its lines, the linearised
    run-to-run variation, the drawn records' sample covariance (rows of ``D``) and the white floor
    (:func:`rvdiag.updating.observability.analyse`'s ``C``)."""
    C = G @ np.diag(np.asarray(var_u, dtype=float)) @ G.T
    if D is not None and D.shape[0] > 1:
        Dc = D - D.mean(axis=0)
        C = C + Dc.T @ Dc / (Dc.shape[0] - 1)
    return C + np.eye(C.shape[0]) * float(white_var)


def _simulated_angles(params: ReducerParams, output_speed_deg_s: float, load_Nm: float, fs_rec: float,
                      revolutions: int, teeth, pert: ob.Perturbation, duration_s: float | None = None):
    """The input and output encoder angles (rad) of the model simulated over ``revolutions`` sun revolutions after
    its run-in, with the tooth pattern ``teeth`` and ``pert``, at a multiple ``k`` of the rate ``fs_rec`` high
    enough for the integrator (``MODEL_MIN_FS``), then sampled at ``fs_rec``; their first ``duration_s`` (all by
    default).  Returns ``(a_in, a_out, ratio)``."""
    k = max(1, math.ceil(MODEL_MIN_FS / fs_rec - 1e-9))
    fs = k * fs_rec
    op = ob.OperatingPoint(output_speed_deg_s=output_speed_deg_s, load_Nm=load_Nm, revolutions=revolutions, fs=fs,
                           substeps=max(1, math.ceil(4 * 48000.0 / fs - 1e-9)))
    p, t, planet, fac, _ = ob._split(pert, params, np.asarray(teeth, dtype=float))
    st = ob.simulate_states(p, op, teeth=t, planet=planet, load=fac["load"], speed=fac["speed"])
    n0 = st["n_pre"]
    n = st["q_m"].size - n0
    if duration_s is not None:
        n = min(n, int(round(duration_s * k * fs_rec)))
    tt = np.arange(n) / fs
    a_in = 2.0 * np.pi * st["motor_hz"] * tt + st["q_m"][n0: n0 + n]
    a_out = 2.0 * np.pi * st["motor_hz"] / st["ratio"] * tt + st["q_H"][n0: n0 + n]
    return a_in[::k], a_out[::k], st["ratio"]


def _model_lines(params: ReducerParams, pm_speed: float, load: float, fs_rec: float, max_order: int,
                 settings: SpecimenSettings, teeth, pert: ob.Perturbation | None = None) -> np.ndarray:
    """The model's TE lines (:func:`te_lines` of the simulated angles sampled at ``fs_rec``)."""
    period = averaging_period(params)
    revs = -(-settings.revolutions // period) * period
    a_in, a_out, ratio = _simulated_angles(params, pm_speed, load, fs_rec, revs + 1, teeth,
                                           pert or ob.Perturbation())
    lines, _ = te_lines(a_in, a_out, fs_rec, ratio, samples_per_rev=settings.samples_per_rev,
                        period=period, revolutions=revs, name="the model's record")
    return _first_orders(lines, max_order)


def linearise(params: ReducerParams, output_speed_deg_s: float, load_Nm: float, fs: float,
              settings: SpecimenSettings | None = None, teeth0=None,
              progress: Callable[[str], None] | None = None) -> PointModel:
    """The model at one operating point (:class:`PointModel`): its lines at the tooth pattern ``teeth0`` (default
    zero, the prior's mean), their central differences in each tooth's position (step 0.01 um, as
    :func:`~rvdiag.updating.observability.reducer_parameters`) and in the run-to-run factors, and ``draws``
    records with drawn variation: ``1 + 2 Z1 + 8 + draws`` simulations."""
    from rvdiag.library.paired import draw_variation

    st = settings or SpecimenSettings()
    z = params.stage1.sun_teeth
    teeth0 = np.zeros(z) if teeth0 is None else np.asarray(teeth0, dtype=float)
    f_rel = ob.OperatingPoint(output_speed_deg_s=output_speed_deg_s).sun_hz(params)
    K = int(min(min(st.max_hz, 0.45 * fs) / f_rel, st.samples_per_rev // 2 - 1))
    if K < 1:
        raise ParameterError(f"the record's rate {fs:g} Hz keeps no TE line of the sun's revolution ({f_rel:.3g} Hz)")
    sims = 0

    def lines(teeth, pert=None):
        nonlocal sims
        sims += 1
        return _model_lines(params, output_speed_deg_s, load_Nm, fs, K, st, teeth, pert)

    t0 = time.perf_counter()
    nom = lines(teeth0)
    h = 0.01e-6
    J = np.zeros((nom.size, z))
    for j in range(z):
        e = np.zeros(z)
        e[j] = h
        J[:, j] = (lines(teeth0 + e) - lines(teeth0 - e)) / (2 * h)
        if progress is not None:
            progress(f"tooth {j + 1}/{z} ({time.perf_counter() - t0:.0f} s)")
    rr = [p for p in ob.run_to_run_parameters() if p.kind != "gain"]      # the gain acts on the vibration only
    G = np.zeros((nom.size, len(rr)))
    for j, p in enumerate(rr):
        G[:, j] = (lines(teeth0, ob.Perturbation().add(p, p.step))
                   - lines(teeth0, ob.Perturbation().add(p, -p.step))) / (2 * p.step)
    if progress is not None:
        progress(f"run-to-run columns ({time.perf_counter() - t0:.0f} s)")
    D = None
    if st.draws:
        rng = np.random.default_rng(st.draw_seed)
        rows = [lines(teeth0, ob.variation_perturbation(draw_variation(rng), without=("gain",)))
                for _ in range(st.draws)]
        D = np.array(rows)
        if progress is not None:
            progress(f"{st.draws} run-to-run draws ({time.perf_counter() - t0:.0f} s)")
    return PointModel(float(output_speed_deg_s), float(load_Nm), float(fs), K, teeth0, nom, J, G, rr, D, sims)


def simulated_record(params: ReducerParams, output_speed_deg_s: float, load_Nm: float, duration_s: float,
                     fs: float, *, variation: dict | None = None, encoder_bits: int = 23,
                     rng: np.random.Generator | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A simulated commissioning record's two encoder angles (rad) at ``fs``: ``duration_s`` after the 0.1 s
    run-in, the run-to-run factors ``variation`` (:func:`rvdiag.library.paired.draw_variation`'s keys; none by
    default) applied, both angles quantised to ``encoder_bits`` with a random offset of the code grid drawn from
    ``rng`` (0: ideal).  For tests and the measurement of docs/twin.md."""
    f_rel = ob.OperatingPoint(output_speed_deg_s=output_speed_deg_s).sun_hz(params)
    a_in, a_out, _ = _simulated_angles(params, output_speed_deg_s, load_Nm, fs, max(1, math.ceil(duration_s * f_rel)),
                                       ob.nominal_tooth_errors(params),
                                       ob.variation_perturbation(variation or {}, without=("gain",)),
                                       duration_s=duration_s)
    if encoder_bits:
        q = 2.0 * np.pi / 2.0 ** int(encoder_bits)
        rng = rng or np.random.default_rng(0)
        a_in = (np.floor(a_in / q + rng.uniform()) + 0.5) * q
        a_out = (np.floor(a_out / q + rng.uniform()) + 0.5) * q
    return a_in, a_out


# --------------------------------------------------------------------------- the estimator
@dataclass
class LMResult:
    """:func:`levenberg_marquardt`'s end: the parameters ``z``, the whitened residual there, the cost
    ``||r||^2 + ||z||^2`` at the start and the end, the iterations taken and the cost's history; ``converged``
    is False when the iterations ran out while the cost still fell by more than ``rtol`` a step."""

    z: np.ndarray
    residual: np.ndarray
    cost_start: float
    cost: float
    iterations: int
    history: list = field(default_factory=list)
    evaluations: int = 0
    converged: bool = False


def levenberg_marquardt(residual: Callable[[np.ndarray], np.ndarray], Jw: np.ndarray, z0, iterations: int, *,
                        step: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
                        on_iteration: Callable[[int, np.ndarray, float], None] | None = None,
                        rtol: float = 1e-5, broyden: bool = False) -> LMResult:
    """Minimise ``||r(z)||^2 + ||z||^2`` (a whitened residual and a unit Gaussian prior, the MAP of the module
    docstring) by Levenberg-Marquardt with the fixed (chord) Jacobian ``Jw = -dr/dz`` (Nocedal & Wright, sec.
    10.3; Marquardt's scaling ``diag(A) + 1``).  A step that does not lower the cost is refused and the damping
    raised tenfold (to 1e6 at most, then the search ends); ``residual`` raising :class:`~rvdiag.errors.
    RvdiagError` (e.g. a stiffness below zero) is a refused step.  ``step(z, dz)`` may shorten a step (a trust
    region); it ends when an iteration lowers the cost by less than ``rtol`` of it.  With ``broyden``, each
    accepted step updates the Jacobian by Broyden's rank-one secant formula, ``Jw += (dr_obs - Jw dz) dz^T /
    dz^T dz`` with ``dr_obs = r(z) - r(z + dz)`` (Broyden 1965, Math. Comp. 19; Dennis & Schnabel, *Numerical
    Methods for Unconstrained Optimization*, sec. 8.1), at no simulation's cost."""
    z = np.asarray(z0, dtype=float).copy()
    m = z.size
    Jw = np.array(Jw, dtype=float)
    A = Jw.T @ Jw
    r = residual(z)
    evals = 1
    c = float(r @ r + z @ z)
    c0, lam, hist, it, done = c, 1e-3, [c], 0, False
    for it in range(1, int(iterations) + 1):
        g = Jw.T @ r - z
        cn, rn = np.inf, None
        while lam <= 1e6:
            dz = np.linalg.solve(A + np.eye(m) + lam * np.diag(np.diag(A) + 1.0), g)
            if step is not None:
                dz = step(z, dz)
            evals += 1
            try:
                rn = residual(z + dz)
            except RvdiagError:
                rn = None
            cn = np.inf if rn is None else float(rn @ rn + (z + dz) @ (z + dz))
            if cn < c:
                break
            lam *= 10.0
        if not cn < c:                               # no step lowers the cost: a (local) minimum
            it -= 1
            done = True
            break
        rel = (c - cn) / c
        if broyden:
            Jw += np.outer((r - rn) - Jw @ dz, dz) / float(dz @ dz)
            A = Jw.T @ Jw
        z, r, c = z + dz, rn, cn
        lam = max(lam / 10.0, 1e-6)
        hist.append(c)
        if on_iteration is not None:
            on_iteration(it, z, c)
        if rel < rtol:
            done = True
            break
    return LMResult(z, r, c0, c, it, hist, evals, done)


@dataclass
class SpecimenResult:
    """An identified specimen (:func:`identify_specimen`).

    ``teeth_m``: the sun teeth's position errors (m, mean zero); ``posterior_sd_m`` each one's posterior spread and
    ``posterior_cov_m2`` their covariance (Gauss-Newton at the solution, within the stated noise;
    :attr:`scaled_sd_m` scales it by the fit's residual); ``pitch_sd_m`` the single pitch deviations' ``e_j - e_(j-1)``;
    ``prior_sd_m`` each tooth's prior spread (the grade's); ``records`` one dict per record used (name, speed,
    rate, revolutions, seconds averaged, its lines' parts and their whitened residual's square sum at the end); ``chi2_start``, ``chi2`` the whitened
    residual's square sum over all records' lines at the start and the end, ``n_lines`` their count (a fit within
    its noise has ``chi2 ~ n_lines``); ``residual_rms_rad`` and ``data_rms_rad`` the RMS of the lines' residual and
    of the lines; ``iterations``, ``simulations``, ``seconds``; ``converged`` (False: the iterations ran out while
    the cost still fell) and ``cost_history`` (the MAP cost after each iteration); ``not_identified``
    (:data:`NOT_IDENTIFIED`)."""

    teeth_m: np.ndarray
    posterior_sd_m: np.ndarray
    posterior_cov_m2: np.ndarray
    pitch_sd_m: np.ndarray
    prior_sd_m: np.ndarray
    records: list
    chi2_start: float
    chi2: float
    n_lines: int
    residual_rms_rad: float
    data_rms_rad: float
    iterations: int
    simulations: int
    seconds: float
    settings: SpecimenSettings
    converged: bool = True
    cost_history: list = field(default_factory=list)
    not_identified: tuple = NOT_IDENTIFIED

    @property
    def birge_ratio(self) -> float:
        """``sqrt(chi2 / n_lines)``, at least 1: how far the fit's residual exceeds the noise it was whitened by
        (Birge 1932, Phys. Rev. 40; the scaling of ``scipy.optimize.curve_fit`` with ``absolute_sigma=False``)."""
        return max(1.0, math.sqrt(self.chi2 / max(self.n_lines, 1)))

    @property
    def scaled_sd_m(self) -> np.ndarray:
        """The posterior spread scaled by :attr:`birge_ratio`: the spread to quote when the model does not fit
        the records within their stated noise (unknown planet table, run-to-run variation beyond its
        linearisation); docs/twin.md compares both with the measured error."""
        return self.posterior_sd_m * self.birge_ratio

    def params(self, base: ReducerParams, digits: int = 5) -> ReducerParams:
        """``base`` with ``[modification] sun_tooth_errors_um`` the identified pattern (um, ``digits`` decimals)."""
        return base.replace(modification={"sun_tooth_errors_um": [round(float(v) * 1e6, digits)
                                                                  for v in self.teeth_m]})

    def to_dict(self) -> dict:
        """Plain values (um for the teeth), for JSON and TOML."""
        um = 1e6
        return {
            "sun_tooth_errors_um": [float(v * um) for v in self.teeth_m],
            "posterior_sd_um": [float(v * um) for v in self.posterior_sd_m],
            "scaled_sd_um": [float(v * um) for v in self.scaled_sd_m], "birge_ratio": self.birge_ratio,
            "pitch_deviation_sd_um": [float(v * um) for v in self.pitch_sd_m],
            "prior_sd_um": [float(v * um) for v in self.prior_sd_m],
            "posterior_cov_um2": [[float(v * um * um) for v in row] for row in self.posterior_cov_m2],
            "records": self.records,
            "chi2_start": self.chi2_start, "chi2": self.chi2, "n_lines": self.n_lines,
            "residual_rms_rad": self.residual_rms_rad, "data_rms_rad": self.data_rms_rad,
            "iterations": self.iterations, "converged": self.converged, "cost_history": list(self.cost_history),
            "simulations": self.simulations, "seconds": self.seconds,
            "settings": {k: getattr(self.settings, k) for k in self.settings.__dataclass_fields__},
            "identified": "the sun's tooth position errors (um along the line of action, mean zero)",
            "not_identified": list(self.not_identified),
        }


def group_points(records: Sequence[TERecord], tolerance: float) -> list[list[int]]:
    """Indices of ``records`` grouped by operating point: the same rate and load, speeds within ``tolerance`` of
    the group's first."""
    groups: list[list[int]] = []
    for i, r in enumerate(records):
        for g in groups:
            f = records[g[0]]
            if (f.fs == r.fs and f.load_Nm == r.load_Nm
                    and abs(r.output_speed_deg_s - f.output_speed_deg_s) <= tolerance * f.output_speed_deg_s):
                g.append(i)
                break
        else:
            groups.append([i])
    return groups


def identify_specimen(params: ReducerParams, records: Sequence[TERecord], settings: SpecimenSettings | None = None,
                      *, points: Sequence[PointModel] | None = None,
                      progress: Callable[[str], None] | None = None) -> SpecimenResult:
    """The MAP estimate of the sun teeth's position errors of the specimen whose commissioning ``records``
    (:func:`te_record`) are given, on the model ``params`` (the global update's, or the built-in set), from a zero
    pattern (module docstring).  ``points``: the linearisation of each operating point (:func:`group_points`'
    order), when already computed for these ``params`` (:func:`linearise`); else computed here."""
    st = settings or SpecimenSettings()
    if not records:
        raise ParameterError("identify_specimen needs at least one record")
    t0 = time.perf_counter()
    z1 = params.stage1.sun_teeth
    groups = group_points(records, st.speed_tolerance)
    if points is None:
        points = []
        for g in groups:
            speed = float(np.mean([records[i].output_speed_deg_s for i in g]))
            points.append(linearise(params, speed, records[g[0]].load_Nm, records[g[0]].fs, st, progress=progress))
    elif len(points) != len(groups):
        raise ParameterError(f"{len(points)} linearisations given for {len(groups)} operating points")
    sims = sum(p.simulations for p in points)
    L, _ = ob.prior_square_root(ob.reducer_parameters(params, planets=False, path=False, stiffness=False,
                                                      damping=False, encoder=False), ob.sun_tooth_prior(params))
    # whitening of each record: W_r with W_r^T W_r = C_r^-1 (the Cholesky factor of C_r, inverted)
    W, Y, Jw = [], [], []
    for g, pm in zip(groups, points):
        S = 0.0
        if st.records_spread and len(g) >= 3:     # the records' own spread: the variation at this specimen
            Yg = np.array([records[i].truncated(pm.max_order) for i in g])
            S = np.cov(Yg, rowvar=False)
        for i in g:
            Lc = np.linalg.cholesky(pm.covariance(records[i], st) + S)
            Wi = np.linalg.inv(Lc)
            W.append(Wi)
            Y.append(records[i].truncated(pm.max_order))
            Jw.append(Wi @ pm.J @ L)
    Jw_all = np.vstack(Jw)
    owner = [k for k, g in enumerate(groups) for _ in g]

    seen: dict[bytes, list[np.ndarray]] = {}

    def predict(z) -> list[np.ndarray]:
        nonlocal sims
        key = np.asarray(z, dtype=float).tobytes()
        if key not in seen:
            teeth = L @ z
            out = []
            for pm in points:
                sims += 1
                out.append(_model_lines(params, pm.output_speed_deg_s, pm.load_Nm, pm.fs, pm.max_order, st, teeth))
            seen.clear()
            seen[key] = out
        return seen[key]

    def residual(z) -> np.ndarray:
        f = predict(z)
        return np.concatenate([Wi @ (y - f[k]) for Wi, y, k in zip(W, Y, owner)])

    def report(it, z, c):
        if progress is not None:
            progress(f"iteration {it}: cost {c:.6g} ({time.perf_counter() - t0:.0f} s)")

    z0 = np.zeros(L.shape[1])
    lm = levenberg_marquardt(residual, Jw_all, z0, st.iterations, on_iteration=report, broyden=st.broyden)
    f_end = predict(lm.z)                           # the accepted point's prediction (kept, not simulated again)
    teeth = L @ lm.z
    cov = L @ np.linalg.inv(Jw_all.T @ Jw_all + np.eye(L.shape[1])) @ L.T
    D = np.eye(z1) - np.roll(np.eye(z1), -1, axis=1)           # e_j - e_(j-1), the single pitch deviation
    ordered = [records[i] for g in groups for i in g]
    rec_out, raw, n = [], [], 0
    for rec, y, k in zip(ordered, Y, owner):
        rw = lm.residual[n: n + y.size]
        n += y.size
        raw.append(y - f_end[k])
        rec_out.append({"name": rec.name, "output_speed_deg_s": rec.output_speed_deg_s, "load_Nm": rec.load_Nm,
                        "fs": rec.fs, "revolutions": rec.revolutions, "averaged_s": rec.averaged_s,
                        "line_parts": int(y.size), "chi2": float(rw @ rw)})
    return SpecimenResult(
        teeth, np.sqrt(np.clip(np.diag(cov), 0, None)), cov, np.sqrt(np.clip(np.diag(D @ cov @ D.T), 0, None)),
        np.sqrt(np.diag(L @ L.T)), rec_out, float(lm.cost_start), float(lm.residual @ lm.residual),
        int(sum(y.size for y in Y)), float(np.sqrt(np.mean(np.concatenate(raw) ** 2))),
        float(np.sqrt(np.mean(np.concatenate(Y) ** 2))), lm.iterations, sims, time.perf_counter() - t0, st,
        lm.converged, [float(c) for c in lm.history])


__all__ = ["LMResult", "MODEL_MIN_FS", "NOT_IDENTIFIED", "PointModel", "SpecimenResult", "SpecimenSettings",
           "TERecord", "averaging_period", "group_points", "identify_specimen", "levenberg_marquardt", "linearise",
           "simulated_record", "te_covariance", "te_lines", "te_record"]
