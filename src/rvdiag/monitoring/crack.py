"""The crack detector with a joint's twin: the generalised matched filter of a sun-tooth root crack, its template
and run-to-run covariance simulated with the joint's identified parameter set (docs/twin.md, "The crack detector in
use"; docs/monitoring.md, "The generalised matched filter").

A joint's twin is the parameter set ``rvdiag update --specimen`` wrote (its sun tooth errors identified from the
joint's commissioning records).  Per operating point the twin is simulated once, at commissioning
(:func:`simulate_reference`, :func:`rvdiag.evaluation.separability.gmf_reference`): the change a root crack makes
(the T1/T4 pair, noise-free: the *template*) and ``K`` healthy records with the run-to-run variation
(:data:`rvdiag.evaluation.separability.RUN_TO_RUN_DEFAULT`: load, speed, temperature, mesh damping, gain; the
*draws*).  That costs ``K + 2`` simulations per operating point.  The joint's own commissioning vibration records
at that point give the baseline mean on the same angle axis and the white noise floor (:func:`attach_baseline`,
:func:`estimate_noise_var`).  Everything is kept in one :class:`CrackReference` per point (``.npz``, no pickle).

A monitored record is judged (:class:`CrackDetector`) by the statistic the study research/twin_gmf.py measures:

- the filter :class:`rvdiag.features.gmf.GeneralisedMatchedFilter` from the first ``K // 2`` draws, the noise
  variance and the number of baseline records, and its index ``T / d`` of the record against the baseline mean;
- the alarm threshold at the false-alarm rate ``alpha`` from the other ``m = K - K // 2`` draws, which the filter
  has not seen (:func:`model_threshold`): a Gaussian prediction bound on the index of a new healthy record.

Assumptions, stated wherever the detector is described:

- every record (commissioning and monitored) starts at the joint angle at which the simulated records start: the
  model's zero, where the input and output angles are both zero (the run-in is simulated before it).  That is the
  frame in which ``rvdiag update --specimen`` identified the sun teeth from the encoders' angles (the sun at a
  whole revolution relative to the carrier).  A robot repeating one motion starts each record at the same joint
  angle; no lag is searched (:func:`rvdiag.features.gmf.on_angle_axis`), and the records are not cut at the
  encoders' zero.
- the joint's run-to-run variation is the one the model draws (:data:`~rvdiag.evaluation.separability.
  RUN_TO_RUN_DEFAULT`); the threshold comes from the model's own draws, not from the joint's healthy records.
- the noise floor is white: the baseline records vary by the run-to-run variation plus the floor, the draws by the
  variation alone; its variance is what of the records' spread the draws do not span (:func:`estimate_noise_var`).
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from rvdiag.errors import DataFileError, ParameterError

#: the crack simulated for the template: a 1.8 mm root crack at 45 deg on sun tooth 0 (the T4 state)
CRACK_SEVERITY = {"crack_depth": 1.8e-3, "crack_angle_deg": 45.0}
#: planet tables the references span by default (:func:`simulate_reference`): the twin does not know its own
PLANET_TABLES = 8
#: what the model's threshold keeps where the twin does not know the joint's planet table (every joint a
#: ``--specimen`` twin is made for): measured on 12 simulated joints never used to develop it, 20 dB floor, teeth
#: identified on the global parameters, 8 planet tables, the floor estimated (docs/twin.md, "The crack detector
#: measured on held-out specimens": research/twin_gmf.py --evaluate --estimate-noise)
THRESHOLD_WARNING = ("the crack threshold comes from the twin's own draws; on 12 simulated joints whose planet table "
                     "the twin did not know it raised 13 % false alarms at a stated 1 % (26 % at 5 %): read the index "
                     "against the joint's own healthy records (docs/twin.md)")
#: the default false-alarm rate of an alarm
ALPHA = 0.01
#: the run-in simulated before each record (s), as in research/twin_gmf.py
TRANSIENT_S = 0.2
#: the integrator's rate (Hz): ``substeps = ceil(STEP_RATE / fs)``, 4 at 48 kHz as in research/twin_gmf.py
STEP_RATE = 192000.0
#: records within this share of an operating point's speed (and at its load) belong to it, as the sun teeth's
#: identification groups them (:class:`rvdiag.updating.specimen.SpecimenSettings`)
SPEED_TOLERANCE = 0.025
#: a monitored record within this share of a reference's load is judged with it: the load's run-to-run variation
#: that the draws cover (:data:`rvdiag.evaluation.separability.RUN_TO_RUN_DEFAULT`)
LOAD_TOLERANCE = 0.03
#: the noise variance is at least this share of the baseline records' mean power (60 dB below)
NOISE_FLOOR_SHARE = 1e-6
#: what the folder ``DIR/crack`` holds besides the references
MANIFEST = "manifest.json"
#: the file format of a reference (its ``meta["format"]``)
FORMAT = "rvdiag crack reference 1"

ASSUMPTIONS = (
    "every record starts at the joint angle at which the simulated records start: where the input and output "
    "encoders both read zero, the frame in which the sun teeth were identified; no lag is searched",
    "the joint's run-to-run variation is the one the model draws (load 3 %, speed 1 %, temperature 2 %, mesh "
    "damping 10 %, gain 3 %); the alarm threshold comes from the model's own draws, not from healthy records of "
    "the joint",
    "the noise floor is white; its variance is what of the baseline records' spread the draws do not span "
    "(unless given)",
)


def params_digest(params) -> str:
    """The SHA-256 of a parameter set's TOML text (:meth:`rvdiag.params.ReducerParams.to_toml`): two sets with the
    same values have the same digest."""
    return hashlib.sha256(params.to_toml().encode("utf-8")).hexdigest()


@dataclass
class CrackReference:
    """What the crack detector needs at one operating point of a joint.

    ``template`` (n,) and ``draws`` (K, n) are simulated with the twin (:func:`simulate_reference`), float32 on the
    angle axis of ``output_speed_deg_s``; ``baseline_mean`` (n,) is the mean of the joint's ``n_baseline``
    commissioning records on that axis and ``noise_var`` the white floor's variance per point
    (:func:`attach_baseline`).  ``simulation`` holds the simulation's settings (run-in, sub-steps, run-to-run
    ranges, channel); ``params_digest`` identifies the parameter set (:func:`params_digest`)."""

    output_speed_deg_s: float
    load_Nm: float
    fs: float
    duration_s: float
    n_points: int
    template: np.ndarray
    draws: np.ndarray
    seed: int
    severity: dict
    params_digest: str
    seconds: float
    simulation: dict = field(default_factory=dict)
    baseline_mean: np.ndarray | None = None
    n_baseline: int = 0
    noise_var: float = math.nan
    noise_var_source: str = ""
    baseline_records: list = field(default_factory=list)

    def simulation_key(self) -> dict:
        """Everything the simulated arrays depend on: equal keys, equal arrays (on one machine)."""
        return {"output_speed_deg_s": self.output_speed_deg_s, "load_Nm": self.load_Nm, "fs": self.fs,
                "duration_s": self.duration_s, "draws": int(self.draws.shape[0]), "seed": self.seed,
                "severity": dict(self.severity), "params_digest": self.params_digest,
                "simulation": dict(self.simulation)}

    def meta(self) -> dict:
        """The reference's scalars (JSON), as saved beside its arrays."""
        return {"format": FORMAT, **self.simulation_key(), "n_points": self.n_points, "seconds": self.seconds,
                "n_baseline": self.n_baseline, "noise_var": self.noise_var, "noise_var_source": self.noise_var_source,
                "baseline_records": list(self.baseline_records)}

    def save(self, path) -> Path:
        """Write the reference to ``path`` (``.npz``: the arrays and the scalars as a JSON string; no pickle) through
        :func:`rvdiag.atomic.atomic_file` (the old file stays whole until the new one is)."""
        from rvdiag.atomic import atomic_file

        arrays = {"template": np.asarray(self.template, dtype=np.float32),
                  "draws": np.asarray(self.draws, dtype=np.float32),
                  "baseline_mean": (np.zeros(0) if self.baseline_mean is None
                                    else np.asarray(self.baseline_mean, dtype=np.float64)),
                  "meta": np.array(json.dumps(self.meta()))}
        path = Path(path)
        with atomic_file(path, "wb") as fh:
            np.savez(fh, **arrays)
        return path

    @classmethod
    def load(cls, path) -> "CrackReference":
        """Read a reference :meth:`save` wrote (``allow_pickle=False``); a file that is not one is refused with one
        :class:`~rvdiag.errors.DataFileError` line."""
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                template, draws, mean = z["template"], z["draws"], z["baseline_mean"]
        except (OSError, ValueError, KeyError, json.JSONDecodeError) as exc:
            raise DataFileError(f"{path} is not a crack reference ({type(exc).__name__}: {exc})") from None
        if not isinstance(meta, dict) or meta.get("format") != FORMAT:
            raise DataFileError(f"{path} is not a crack reference (format {meta.get('format')!r}, expected "
                                f"{FORMAT!r})" if isinstance(meta, dict) else f"{path} is not a crack reference")
        try:
            n = int(meta["n_points"])
            ref = cls(output_speed_deg_s=float(meta["output_speed_deg_s"]), load_Nm=float(meta["load_Nm"]),
                      fs=float(meta["fs"]), duration_s=float(meta["duration_s"]), n_points=n, template=template,
                      draws=draws, seed=int(meta["seed"]), severity=dict(meta["severity"]),
                      params_digest=str(meta["params_digest"]), seconds=float(meta["seconds"]),
                      simulation=dict(meta["simulation"]), baseline_mean=mean if mean.size else None,
                      n_baseline=int(meta["n_baseline"]), noise_var=float(meta["noise_var"]),
                      noise_var_source=str(meta["noise_var_source"]),
                      baseline_records=list(meta["baseline_records"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise DataFileError(f"{path}: its metadata lack or garble {exc}") from None
        if template.shape != (n,) or draws.ndim != 2 or draws.shape[1] != n or mean.size not in (0, n):
            raise DataFileError(f"{path}: the arrays do not match its {n} points")
        return ref


def _planet_tables(draws: int, planet_tables: int) -> int:
    """``planet_tables`` as a whole number, with ``draws`` checked: at least 4 (half fit the filter, half set its
    threshold), and ``planet_tables`` 0 (the twin's own table) or a divisor of ``draws`` with at least 2 draws a
    table (:func:`simulate_reference`)."""
    if isinstance(draws, bool) or not isinstance(draws, (int, np.integer)) or draws < 4:
        raise ParameterError(f"the crack detector needs at least 4 run-to-run draws (half fit the filter, half set "
                             f"its threshold), got {draws!r}")
    J = int(planet_tables)
    if J < 0 or (J and (draws % J or draws // J < 2)):
        raise ParameterError(f"the draws ({draws}) must be a multiple of the planet tables ({J}), at least 2 a table "
                             "(or 0 planet tables: the twin's own)")
    return J


def simulate_reference(params, output_speed_deg_s: float, load_Nm: float, fs: float, duration_s: float,
                       draws: int = 32, seed: int = 0, *, severity: Mapping[str, float] | None = None,
                       transient_s: float = TRANSIENT_S, substeps: int | None = None,
                       ranges: Mapping[str, float] | None = None, channel: int = 0,
                       planet_tables: int = PLANET_TABLES) -> CrackReference:
    """Simulate a joint's crack reference at one operating point with its twin ``params``
    (:func:`rvdiag.evaluation.separability.gmf_reference`, seed ``seed``): the template of the crack ``severity``
    (default :data:`CRACK_SEVERITY`) and ``draws`` healthy draws with the run-to-run variation ``ranges`` (default
    :data:`~rvdiag.evaluation.separability.RUN_TO_RUN_DEFAULT`), each ``duration_s`` after a run-in of
    ``transient_s``, on channel ``channel`` (0: the housing's x).  ``draws + 2`` simulations; ``substeps`` default
    ``ceil(STEP_RATE / fs)`` (4 at 48 kHz).  ``draws >= 4``: half fit the filter, the other half set its threshold.
    The baseline is attached afterwards (:func:`attach_baseline`).

    ``planet_tables`` (``J``, default :data:`PLANET_TABLES`; 0: the twin's own table alone): the planets' runouts,
    crank holes and phases are not identified (:data:`rvdiag.updating.specimen.NOT_IDENTIFIED`), so the twin's
    table is one guess.  With ``J`` tables (``[modification] error_seed`` the twin's plus 1..J, its sun teeth kept)
    the template is the mean of their templates, and the draws are ``draws / J`` per table, each table's centred on
    its own mean (a joint's baseline removes its own table's static signal; what is left is how the run-to-run
    variation acts under each table) and scaled by ``sqrt((K - 1) / (K - J))`` so that the filter's ``K - 1``
    divisor gives the pooled within-table covariance (the nuisance parameters' spread taken into the covariance:
    Kay, vol. 2, sec. 4.5).  The tables are interleaved, so that each half of the draws holds every table.
    ``J (draws / J + 2)`` simulations; ``draws`` must be a multiple of ``J`` with at least 2 per table."""
    from rvdiag.evaluation.separability import RUN_TO_RUN_DEFAULT, gmf_reference
    from rvdiag.validation import finite_number

    J = _planet_tables(draws, planet_tables)
    for name, v in (("the output speed", output_speed_deg_s), ("the sampling rate", fs),
                    ("the duration", duration_s)):
        finite_number(v, name, 0, strict=True, noun="a number")
    finite_number(load_Nm, "the load", noun="a number")
    finite_number(transient_s, "the run-in", 0, noun="a number")
    sev = dict(CRACK_SEVERITY if severity is None else severity)
    rr = dict(RUN_TO_RUN_DEFAULT if ranges is None else ranges)
    sub = int(substeps) if substeps is not None else max(1, math.ceil(STEP_RATE / float(fs)))
    t0 = time.perf_counter()

    def simulate(p, n_draws, s):
        return gmf_reference("T4", ranges=rr, draws=n_draws, params=p, output_speed_deg_s=float(output_speed_deg_s),
                             load_Nm=float(load_Nm), duration_s=float(duration_s), fs=float(fs),
                             transient_s=float(transient_s), model={"substeps": sub}, channel=int(channel),
                             severities=sev, seed=s)

    if J == 0:
        ref = simulate(params, int(draws), int(seed))
    else:
        per = int(draws) // J
        refs = [simulate(params.replace(modification={"error_seed": params.modification.error_seed + 1 + j}), per,
                         int(seed) + 100 * (j + 1)) for j in range(J)]
        H = np.concatenate([r["draws"] - r["draws"].mean(axis=0) for r in refs])
        H *= math.sqrt((draws - 1) / (draws - J))
        order = np.argsort(np.tile(np.arange(per), J), kind="stable")
        ref = {"template": np.mean([r["template"] for r in refs], axis=0), "draws": H[order]}
    template = ref["template"].astype(np.float32)
    return CrackReference(output_speed_deg_s=float(output_speed_deg_s), load_Nm=float(load_Nm), fs=float(fs),
                          duration_s=float(duration_s), n_points=int(template.size), template=template,
                          draws=ref["draws"].astype(np.float32), seed=int(seed), severity=sev,
                          params_digest=params_digest(params), seconds=time.perf_counter() - t0,
                          simulation={"transient_s": float(transient_s), "substeps": sub, "ranges": rr,
                                      "channel": int(channel), "planet_tables": J})


# --------------------------------------------------------------------------- the joint's baseline on the axis
@dataclass(frozen=True)
class CommissioningRecord:
    """One commissioning vibration record of a joint: the signal (one channel, whole), its rate, the output speed its
    encoder measured (deg/s), the load it ran at (N m) and a name for messages."""

    data: np.ndarray
    fs: float
    output_speed_deg_s: float
    load_Nm: float
    name: str = ""


def _required_samples(reference: CrackReference, output_speed_deg_s: float) -> int:
    """The samples a record at ``output_speed_deg_s`` needs to cover the reference's axis
    (:func:`rvdiag.features.gmf.on_angle_axis` reaches ``(n - 1) / ratio`` and its kernel 2 beyond)."""
    ratio = float(output_speed_deg_s) / reference.output_speed_deg_s
    return math.ceil((reference.n_points - 1) / ratio) + 3


def on_reference_axis(x, fs: float, output_speed_deg_s: float, reference: CrackReference,
                      name: str = "the record") -> np.ndarray:
    """A whole record ``x`` at ``fs`` made at ``output_speed_deg_s`` on the reference's angle axis: its first
    ``n_points`` points stretched by the speed ratio (:func:`rvdiag.features.gmf.on_angle_axis`), from the record's
    first sample (module docstring: every record starts at the reference angle).  One
    :class:`~rvdiag.errors.ParameterError` line for another rate, a speed that is not a positive number, or a record
    too short."""
    from rvdiag.features.gmf import on_angle_axis

    x = np.asarray(x, dtype=float)
    if x.ndim != 1:
        raise ParameterError(f"{name}: the crack detector takes one channel, got an array of shape {x.shape}")
    if not (fs and math.isfinite(fs) and math.isclose(float(fs), reference.fs, rel_tol=1e-9)):
        raise ParameterError(f"{name} is sampled at {fs:g} Hz, the crack reference at "
                             f"{reference.output_speed_deg_s:.4g} deg/s {reference.load_Nm:g} N m at "
                             f"{reference.fs:g} Hz" if isinstance(fs, (int, float)) else
                             f"{name} states no sampling rate (give --fs)")
    v = float(output_speed_deg_s)
    if not (math.isfinite(v) and v > 0):
        raise ParameterError(f"{name}: the output speed must be a positive number, got {output_speed_deg_s!r}")
    need = _required_samples(reference, v)
    if x.size < need:
        raise ParameterError(f"{name} holds {x.size / fs:.4g} s; the crack reference at "
                             f"{reference.output_speed_deg_s:.4g} deg/s needs {need / fs:.4g} s at {v:.4g} deg/s "
                             f"({reference.duration_s:g} s simulated)")
    return on_angle_axis(x, v / reference.output_speed_deg_s, reference.n_points)


#: the ways :func:`estimate_noise_var` estimates the floor
NOISE_METHODS = ("projection", "difference")


def estimate_noise_var(aligned_baseline, draws, floor: float | None = None, method: str = "projection") -> float:
    """The white noise floor's variance per point, from a joint's commissioning records and the twin's draws.

    A baseline record on the reference's axis is ``x_b = s(theta_b) + e_b``: the healthy signal at its run-to-run
    factors ``theta_b`` plus white noise ``e_b`` of variance ``sigma^2``, independent of each other.  The simulated
    draws ``h_k = s(theta_k)`` are noise-free: they hold the run-to-run variation alone (as far as the model draws
    the joint's).  Two estimates:

    - ``"projection"`` (default): the records' deviations from their mean, ``D = x_b - mean_b x``, less their
      projection onto the span of the draws' deviations (rank ``r <= K - 1``, ``P`` its orthogonal projector)::

          sigma^2 = ||(I - P) D||_F^2 / ((n_b - 1) (n - r))

      The run-to-run deviations lie in that span as far as the draws span the variation; white noise is isotropic,
      so ``(n_b - 1)(n - r)`` of its degrees of freedom remain.  Variation the draws do not span stays in and
      raises the estimate: it errs towards a larger floor, a lower deflection and fewer alarms.
    - ``"difference"``: the method of moments on the points' sample variances (``ddof = 1``), averaged over the
      ``n`` points: ``sigma^2 = mean_i var_b(x_i) - mean_i var_k(h_i)``.  Unbiased, but where the run-to-run
      variation dominates the floor its spread is that of the variation estimated from ``n_b - 1`` and ``K - 1``
      degrees of freedom: several times the floor itself with 2-3 records.

    Either is at least ``floor`` (default :data:`NOISE_FLOOR_SHARE` times the records' mean power).  The estimate is
    the floor's variance on the reference's axis: the stretch's interpolation (:func:`on_reference_axis`) lowers a
    white floor's variance a little, as it does the monitored record's.  Needs at least 2 baseline records.

    Parameters
    ----------
    aligned_baseline : array (n_b, n), the baseline records on the reference's axis (:func:`on_reference_axis`)
    draws : array (K, n), the twin's healthy draws on the same axis
    floor : float, optional
    method : ``"projection"`` or ``"difference"``
    """
    return _noise_var(aligned_baseline, draws, floor, method)[0]


def _noise_var(aligned_baseline, draws, floor: float | None = None,
               method: str = "projection") -> tuple[float, bool]:
    """:func:`estimate_noise_var` and whether the floor set it."""
    B = np.asarray(aligned_baseline, dtype=float)
    H = np.asarray(draws, dtype=float)
    if method not in NOISE_METHODS:
        raise ParameterError(f"the noise estimate's method must be one of {', '.join(NOISE_METHODS)}, got {method!r}")
    if B.ndim != 2 or B.shape[0] < 2:
        raise ParameterError(f"estimating the noise floor needs at least 2 baseline records at the operating point, "
                             f"got {B.shape[0] if B.ndim == 2 else B.ndim}; commission more records or give the "
                             "noise variance")
    if H.ndim != 2 or H.shape[0] < 2 or H.shape[1] != B.shape[1]:
        raise ParameterError(f"need at least 2 draws of {B.shape[1]} points, got an array {H.shape}")
    if floor is None:
        floor = NOISE_FLOOR_SHARE * float(np.mean(B ** 2))
    floor = max(float(floor), np.finfo(float).tiny)
    if method == "difference":
        est = float(np.mean(np.var(B, axis=0, ddof=1))) - float(np.mean(np.var(H, axis=0, ddof=1)))
    else:
        D = B - B.mean(axis=0)
        U, sv, _ = np.linalg.svd((H - H.mean(axis=0)).T, full_matrices=False)     # the draws' span: U's columns
        r = int(np.sum(sv > sv.max() * max(H.shape) * np.finfo(float).eps)) if sv.size and sv.max() > 0 else 0
        R = D - (D @ U[:, :r]) @ U[:, :r].T
        est = float(np.sum(R ** 2)) / ((B.shape[0] - 1) * (B.shape[1] - r))
    return max(est, floor), est <= floor


def attach_baseline(reference: CrackReference, records: Sequence[CommissioningRecord],
                    noise_var: float | None = None, noise_method: str = "projection") -> CrackReference:
    """``reference`` with the joint's baseline at its operating point: the mean of the commissioning ``records``
    (each whole, from its first sample, on the reference's axis: :func:`on_reference_axis`), their number, and the
    noise variance: ``noise_var`` when given, else :func:`estimate_noise_var` by ``noise_method`` (2 records or
    more)."""
    if not records:
        raise ParameterError(f"no commissioning record at {reference.output_speed_deg_s:.4g} deg/s "
                             f"{reference.load_Nm:g} N m")
    A = np.array([on_reference_axis(r.data, r.fs, r.output_speed_deg_s, reference, name=r.name or "a record")
                  for r in records])
    if noise_var is None:
        nv, floored = _noise_var(A, reference.draws, method=noise_method)
        source = (f"the floor ({noise_method}: the records spread no more than the draws)" if floored
                  else f"estimated ({noise_method}) from {len(records)} baseline records")
    else:
        nv = float(noise_var)
        if not (math.isfinite(nv) and nv > 0):
            raise ParameterError(f"the noise variance must be a positive number, got {noise_var!r}")
        source = "given"
    return replace(reference, baseline_mean=A.mean(axis=0), n_baseline=len(records), noise_var=nv,
                   noise_var_source=source, baseline_records=[r.name for r in records])


# --------------------------------------------------------------------------- the detector
def model_threshold(g, fresh: np.ndarray, noise_var: float, n_baseline: int,
                    alphas: Sequence[float] = (0.01, 0.05)) -> dict:
    """The alarm thresholds of ``T / d`` at each false-alarm rate of ``alphas`` from the model alone.

    ``g`` is a fitted :class:`~rvdiag.features.gmf.GeneralisedMatchedFilter` (weights ``w``, deflection ``d``) and
    ``fresh`` (m, n) healthy draws it was not fitted on.  Under H0 the index of a new record is
    ``w^T (y - mu) / d``; its variance is the spread of ``w^T h`` over the draws plus the noise's ``sigma^2 w^T w``,
    times ``1 + 1/n_b`` for the baseline mean of ``n_b`` records.  With that variance estimated from ``m`` draws,
    the Gaussian prediction bound for one new record is the Student-t quantile of ``m - 1`` degrees of freedom
    times ``sqrt(1 + 1/m)`` (Geisser, *Predictive Inference*, 1993, sec. 2.1; Hahn & Meeker, *Statistical
    Intervals*, 1991, sec. 4.7)::

        threshold(alpha) = t_{m-1}(1 - alpha) sqrt(1 + 1/m) sqrt((1 + 1/n_b) (var(w^T h_j) + sigma^2 w^T w)) / d

    Returns ``{alpha: threshold}``.  The one home of the study research/twin_gmf.py's threshold."""
    from scipy.stats import t as student

    sd, m = _healthy_spread(g, fresh, noise_var, n_baseline)
    return {al: float(student.ppf(1 - al, m - 1) * np.sqrt(1 + 1 / m) * sd) for al in alphas}


def model_p_value(index: float, g, fresh: np.ndarray, noise_var: float, n_baseline: int) -> float:
    """The false-alarm rate at which ``index`` would just alarm under :func:`model_threshold`'s bound: ``P(t_{m-1} >
    index / (sqrt(1 + 1/m) sd))``, ``sd`` its healthy spread (the inverse of :func:`model_threshold`)."""
    from scipy.stats import t as student

    sd, m = _healthy_spread(g, fresh, noise_var, n_baseline)
    return float(student.sf(float(index) / (np.sqrt(1 + 1 / m) * sd), m - 1))


def _healthy_spread(g, fresh: np.ndarray, noise_var: float, n_baseline: int) -> tuple[float, int]:
    """The standard deviation of a healthy record's ``T / d`` that :func:`model_threshold` takes, and ``m``."""
    w = g.weights_
    m = fresh.shape[0]
    s2 = float(np.var(fresh @ w, ddof=1)) + noise_var * float(w @ w)
    return np.sqrt((1 + 1 / n_baseline) * s2) / g.deflection_, m


@dataclass
class CrackResult:
    """One record judged by the crack detector: ``index`` (``T / d``), the ``threshold`` at the false-alarm rate
    ``alpha``, ``alarm`` (index above it), the filter's ``deflection`` ``d``, ``p_value`` (the rate at which the
    index would just alarm), the record's operating point and the reference it was judged with; ``warning``
    (:data:`THRESHOLD_WARNING`): what the threshold was measured to keep."""

    index: float
    threshold: float
    alarm: bool
    alpha: float
    deflection: float
    p_value: float
    output_speed_deg_s: float
    load_Nm: float
    reference: dict
    warning: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {"index": self.index, "threshold": self.threshold, "alarm": self.alarm, "alpha": self.alpha,
                "deflection": self.deflection, "p_value": self.p_value,
                "output_speed_deg_s": self.output_speed_deg_s, "load_Nm": self.load_Nm,
                "reference": dict(self.reference), "warning": self.warning}

    def line(self) -> str:
        """One line for people: the index, the threshold and whether it alarms."""
        return (f"crack detector (twin): index {self.index:.3g}, threshold {self.threshold:.3g} at "
                f"{100 * self.alpha:g} % false alarms: {'alarm' if self.alarm else 'no alarm'}")


class CrackDetector:
    """The crack detector at one operating point (module docstring): the filter from the first ``K // 2`` draws of
    ``reference``, its threshold at ``alpha`` from the other ``K - K // 2`` (:func:`model_threshold`).

    Parameters
    ----------
    reference : CrackReference with its baseline attached (:func:`attach_baseline`)
    alpha : the false-alarm rate of the alarm (default :data:`ALPHA`)
    path : where the reference was read from (reported in each result)
    """

    def __init__(self, reference: CrackReference, alpha: float = ALPHA, path: str | None = None):
        from rvdiag.features.gmf import GeneralisedMatchedFilter

        if reference.baseline_mean is None or reference.n_baseline < 1:
            raise ParameterError(f"the crack reference at {reference.output_speed_deg_s:.4g} deg/s "
                                 f"{reference.load_Nm:g} N m has no baseline (attach_baseline)")
        alpha = float(alpha)
        if not 0 < alpha < 1:
            raise ParameterError(f"the false-alarm rate must lie in (0, 1), got {alpha}")
        K = reference.draws.shape[0]
        if K < 4:
            raise ParameterError(f"the crack reference holds {K} draws; the detector needs at least 4")
        half = K // 2
        self.reference, self.alpha, self.path = reference, alpha, path
        draws = reference.draws.astype(float)
        self.fresh_ = draws[half:]
        self.filter_ = GeneralisedMatchedFilter(reference.template.astype(float), draws[:half], reference.noise_var,
                                                reference.n_baseline).fit()
        self.threshold_ = model_threshold(self.filter_, self.fresh_, reference.noise_var, reference.n_baseline,
                                          (alpha,))[alpha]

    def index(self, aligned) -> np.ndarray:
        """``T / d`` of records already on the reference's axis (rows of ``aligned``) against the baseline mean."""
        return self.filter_.statistic(aligned, self.reference.baseline_mean)

    def judge(self, x, fs: float, output_speed_deg_s: float, name: str = "the record") -> CrackResult:
        """Judge one whole record ``x`` (one channel at ``fs``, starting at the reference angle) made at
        ``output_speed_deg_s``."""
        r = self.reference
        y = on_reference_axis(x, fs, output_speed_deg_s, r, name=name)
        t = float(self.index(y[None])[0])
        p = model_p_value(t, self.filter_, self.fresh_, r.noise_var, r.n_baseline)
        return CrackResult(index=t, threshold=self.threshold_, alarm=bool(t > self.threshold_), alpha=self.alpha,
                           deflection=float(self.filter_.deflection_), p_value=p, warning=THRESHOLD_WARNING,
                           output_speed_deg_s=float(output_speed_deg_s), load_Nm=r.load_Nm,
                           reference={"file": self.path, "output_speed_deg_s": r.output_speed_deg_s,
                                      "load_Nm": r.load_Nm, "fs": r.fs, "n_points": r.n_points,
                                      "draws": int(r.draws.shape[0]), "n_baseline": r.n_baseline,
                                      "noise_var": r.noise_var, "noise_var_source": r.noise_var_source,
                                      "seed": r.seed, "severity": dict(r.severity), "params_digest": r.params_digest})


# --------------------------------------------------------------------------- commissioning and the twin's folder
def _crack_dir(folder) -> Path:
    return Path(folder) / "crack"


def operating_points(records: Sequence[CommissioningRecord], tolerance: float = SPEED_TOLERANCE) -> list[list[int]]:
    """Indices of ``records`` grouped by operating point: the same rate and load, speeds within ``tolerance`` of the
    group's first (:func:`rvdiag.updating.specimen.group_points`, as the sun teeth's identification groups them)."""
    from rvdiag.updating.specimen import group_points

    return group_points(records, tolerance)


def commission_crack_references(folder, params, records: Sequence[CommissioningRecord], *, draws: int = 32,
                                seed: int = 0, alpha: float = ALPHA, duration_s: float = 1.0,
                                noise_var: float | None = None, noise_method: str = "projection",
                                overwrite: bool = False,
                                severity: Mapping[str, float] | None = None, transient_s: float = TRANSIENT_S,
                                substeps: int | None = None, planet_tables: int = PLANET_TABLES,
                                progress=None) -> dict:
    """Simulate a joint's crack references, one per operating point of its commissioning ``records``, into
    ``folder/crack/op{k}.npz`` with ``folder/crack/manifest.json``.

    The records are grouped by :func:`operating_points`; each point is simulated at its records' mean speed and
    their load (:func:`simulate_reference` over ``planet_tables`` planet tables, ``planet_tables (draws /
    planet_tables + 2)`` simulations, or ``draws + 2`` with ``planet_tables`` 0; seed ``seed + k``) for ``duration_s`` (at
    most what the point's every record covers on the axis, and what a record as long as the shortest covers at
    :data:`SPEED_TOLERANCE` below the point's speed), and gets the baseline of its records
    (:func:`attach_baseline`).  Resumable: a point whose file already holds the same simulation (the same
    parameter digest, operating point, rate, duration, draws, seed, crack and settings) is not simulated again (its
    baseline is refreshed from the records); a file there that holds another is refused with one
    :class:`~rvdiag.errors.ParameterError` line unless ``overwrite``.  Each finished point is written at once
    (atomically), and the manifest after each, marked ``complete`` at the end.  ``progress(stage, done, total)``
    (default :func:`rvdiag.progress.report`) is told of each point.

    Returns the manifest (``ops``: per point its file, speed, load, records, seconds, and whether it was
    ``simulated`` now or ``kept``)."""
    from rvdiag.atomic import atomic_write
    from rvdiag.evaluation.separability import RUN_TO_RUN_DEFAULT
    from rvdiag.progress import report

    progress = progress or report
    if not records:
        raise ParameterError("the crack references need at least one commissioning vibration record")
    J = _planet_tables(draws, planet_tables)
    if not 0 < float(alpha) < 1:
        raise ParameterError(f"the false-alarm rate must lie in (0, 1), got {alpha}")
    if noise_method not in NOISE_METHODS:
        raise ParameterError(f"the noise estimate's method must be one of {', '.join(NOISE_METHODS)}, got "
                             f"{noise_method!r}")
    if noise_var is not None and not (math.isfinite(float(noise_var)) and float(noise_var) > 0):
        raise ParameterError(f"the noise variance must be a positive number, got {noise_var!r}")
    for r in records:
        x = np.asarray(r.data)
        if x.ndim != 1 or not np.all(np.isfinite(x)):
            raise DataFileError(f"{r.name or 'a record'}: the vibration must be one channel of finite values")
        if not (r.output_speed_deg_s > 0 and r.fs > 0):
            raise ParameterError(f"{r.name or 'a record'}: the speed and the rate must be > 0")
    groups = operating_points(records)
    if noise_var is None:
        few = [g for g in groups if len(g) < 2]
        if few:
            r0 = records[few[0][0]]
            raise ParameterError(f"the operating point {r0.output_speed_deg_s:.4g} deg/s {r0.load_Nm:g} N m has one "
                                 "commissioning record; the noise floor is estimated from 2 or more (give the noise "
                                 "variance, or more records)")
    sev = dict(CRACK_SEVERITY if severity is None else severity)
    crack = _crack_dir(folder)
    crack.mkdir(parents=True, exist_ok=True)
    digest = params_digest(params)
    manifest: dict[str, Any] = {"format": "rvdiag crack references 1", "complete": False, "params_digest": digest,
                                "draws": int(draws), "seed": int(seed), "alpha": float(alpha),
                                "severity": sev, "transient_s": float(transient_s),
                                "noise": "given" if noise_var is not None else noise_method,
                                "run_to_run": dict(RUN_TO_RUN_DEFAULT),
                                "planet_tables": J,
                                "simulations_per_point": int(draws) + 2 * max(J, 1),
                                "assumptions": list(ASSUMPTIONS), "ops": []}
    total = len(groups)
    for k, g in enumerate(groups):
        progress("crack references", k, total)
        recs = [records[i] for i in g]
        speed = float(np.mean([r.output_speed_deg_s for r in recs]))
        load, fs = recs[0].load_Nm, recs[0].fs
        # every record of the point must cover the axis, (fs D - 3)(1 - speed range) / ratio + 3 <= its samples, and
        # so must a monitored record as long as the shortest, down to SPEED_TOLERANCE slower than the point
        span = min((np.asarray(r.data).size - 4) * min(r.output_speed_deg_s / speed, 1 - SPEED_TOLERANCE)
                   for r in recs) / fs
        dur = min(float(duration_s), math.floor(1000 * span) / 1000)
        if dur <= 0:
            raise ParameterError(f"the records at {speed:.4g} deg/s are too short for a crack reference")
        path = crack / f"op{k}.npz"
        sub = int(substeps) if substeps is not None else max(1, math.ceil(STEP_RATE / float(fs)))
        want = {"output_speed_deg_s": speed, "load_Nm": float(load), "fs": float(fs), "duration_s": dur,
                "draws": int(draws), "seed": int(seed) + k, "severity": sev, "params_digest": digest,
                "simulation": {"transient_s": float(transient_s), "substeps": sub, "ranges": dict(RUN_TO_RUN_DEFAULT),
                               "channel": 0, "planet_tables": J}}
        ref = None
        if path.exists():
            old = CrackReference.load(path)
            if json.loads(json.dumps(old.simulation_key())) == json.loads(json.dumps(want)):
                ref = old
            elif not overwrite:
                diff = [key for key in want if json.dumps(old.simulation_key()[key]) != json.dumps(want[key])]
                raise ParameterError(f"{path} holds a crack reference simulated otherwise ({', '.join(diff)} "
                                     "differ); use --overwrite to simulate it again")
        kept = ref is not None
        if ref is None:
            ref = simulate_reference(params, speed, load, fs, dur, int(draws), int(seed) + k, severity=sev,
                                     transient_s=transient_s, substeps=sub, planet_tables=J)
        ref = attach_baseline(ref, recs, noise_var, noise_method)
        CrackDetector(ref, alpha)  # refuse here, not at the first monitored record, a reference that cannot judge
        ref.save(path)
        manifest["ops"].append({"file": path.name, "output_speed_deg_s": speed, "load_Nm": float(load),
                                "fs": float(fs), "duration_s": dur, "seed": int(seed) + k,
                                "records": [r.name for r in recs], "noise_var": ref.noise_var,
                                "noise_var_source": ref.noise_var_source, "seconds": ref.seconds,
                                "kept" if kept else "simulated": True})
        atomic_write(crack / MANIFEST, json.dumps(manifest, indent=1))
    progress("crack references", total, total)
    manifest["complete"] = True
    atomic_write(crack / MANIFEST, json.dumps(manifest, indent=1))
    return manifest


class CrackTwin:
    """A joint's crack detectors, one per commissioned operating point (:func:`load_twin`)."""

    def __init__(self, folder: Path, detectors: list[CrackDetector], manifest: dict):
        self.folder, self.detectors, self.manifest = folder, detectors, manifest

    def points(self) -> str:
        return ", ".join(f"{d.reference.output_speed_deg_s:.4g} deg/s {d.reference.load_Nm:g} N m"
                         for d in self.detectors)

    def detector(self, output_speed_deg_s: float, load_Nm: float) -> CrackDetector:
        """The detector of the operating point within :data:`SPEED_TOLERANCE` of ``output_speed_deg_s`` and
        :data:`LOAD_TOLERANCE` of ``load_Nm`` (the nearest if several, by the larger of the two distances in units
        of their tolerances); one :class:`~rvdiag.errors.ParameterError` line naming the commissioned points
        otherwise."""
        v, L = float(output_speed_deg_s), float(load_Nm)

        def distance(d: CrackDetector) -> float:
            r = d.reference
            return max(abs(v - r.output_speed_deg_s) / (SPEED_TOLERANCE * r.output_speed_deg_s),
                       abs(L - r.load_Nm) / max(LOAD_TOLERANCE * abs(r.load_Nm), 1e-9))

        best = min(self.detectors, key=distance)
        if not distance(best) <= 1:
            raise ParameterError(f"the twin in {self.folder} has no crack reference at {v:.4g} deg/s {L:g} N m "
                                 f"(within {100 * SPEED_TOLERANCE:g} % of speed and {100 * LOAD_TOLERANCE:g} % of "
                                 f"load); it has {self.points()}")
        return best

    def judge(self, x, fs: float, output_speed_deg_s: float, load_Nm: float, name: str = "the record") -> CrackResult:
        """Judge one whole record with the detector of its operating point."""
        if output_speed_deg_s is None or load_Nm is None:
            raise ParameterError("the crack detector needs the record's output speed and load to pick its reference")
        return self.detector(output_speed_deg_s, load_Nm).judge(x, fs, output_speed_deg_s, name=name)


def load_twin(folder, alpha: float | None = None) -> CrackTwin:
    """The crack detectors of the twin folder ``folder`` (what ``rvdiag update --specimen`` wrote to ``--out``): one
    per reference listed in ``folder/crack/manifest.json``, at the manifest's false-alarm rate unless ``alpha``.
    One :class:`~rvdiag.errors.ParameterError` line for a missing folder, no references, or an unfinished
    commissioning."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ParameterError(f"the twin folder {folder} does not exist (rvdiag update --specimen ... --out DIR "
                             "writes it)")
    crack = _crack_dir(folder)
    mpath = crack / MANIFEST
    if not mpath.exists():
        raise ParameterError(f"{folder} holds no crack references ({mpath} is missing): commission them with "
                             "rvdiag update --specimen FILE... --channel RE --out DIR")
    try:
        manifest = json.loads(mpath.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise DataFileError(f"{mpath} cannot be read: {exc}") from None
    if not isinstance(manifest, dict):
        raise DataFileError(f"{mpath} is not a crack references' manifest")
    if not manifest.get("complete"):
        raise ParameterError(f"the crack references in {crack} are unfinished (the commissioning was interrupted): "
                             "run it again; the points already simulated are kept")
    if not manifest.get("ops"):
        raise ParameterError(f"{mpath} lists no crack reference")
    if not all(isinstance(op, dict) and isinstance(op.get("file"), str) for op in manifest["ops"]):
        raise DataFileError(f"{mpath}: every point must name its file")
    a = float(manifest.get("alpha", ALPHA)) if alpha is None else float(alpha)
    dets = [CrackDetector(CrackReference.load(crack / op["file"]), a, str(crack / op["file"]))
            for op in manifest["ops"]]
    return CrackTwin(folder, dets, manifest)


# --------------------------------------------------------------------------- a store of a joint's records
def whole_records(X: np.ndarray, meta: Mapping[str, Any],
                  hop: int | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each record (metadata ``unit``) of windows ``X`` (n, L) as one signal from its first sample: ``(rows, x)``.

    With a ``start`` column (``rvdiag dataset from-files``), the windows starting at 0, L, 2L, ... are joined while
    they follow on; without one the record's windows are joined in row order, as a library writes them when its
    ``hop`` is the window's length (``hop``, from the store's config; another hop is refused).  A record without a
    window at its first sample is refused."""
    X = np.asarray(X)
    L = X.shape[1]
    units = np.asarray(meta["unit"])
    starts = meta.get("start")
    if starts is None and hop is not None and int(hop) != L:
        raise ParameterError(f"the store's windows overlap or leave gaps (hop {hop}, window {L}) and carry no "
                             "start: its records cannot be joined whole for the crack detector")
    out = []
    _, first = np.unique(units, return_index=True)
    for u in units[np.sort(first)]:
        rows = np.flatnonzero(units == u)
        if starts is not None:
            at = {int(starts[i]): i for i in rows}
            if 0 not in at:
                raise ParameterError(f"record {u} of the store has no window at its first sample")
            keep, pos = [], 0
            while pos in at:
                keep.append(at[pos])
                pos += L
            rows = np.array(keep)
        out.append((rows, X[rows].astype(float).ravel()))
    return out


def evaluate_crack(twin: CrackTwin, samples, fs: float, *, healthy: str = "T1", cracked: str = "T4",
                   hop: int | None = None) -> dict:
    """The crack detector of ``twin`` over the records of ``samples`` (:class:`rvdiag.datasets.store.Samples` of
    one joint, at ``fs``; each record whole: :func:`whole_records`), each at its metadata's speed and load.

    Returns ``crack_detection`` (the share of ``cracked`` records alarmed; None without any),
    ``crack_false_alarm_rate`` (the share of ``healthy`` records alarmed; None without any), the rate they were
    alarmed at (``crack_alpha``), the share alarmed and the count of every state, and each record's index."""
    from rvdiag.monitoring.pairing import OPERATING_COLUMNS, with_load_column

    meta = with_load_column(samples.meta)
    missing = [c for c in OPERATING_COLUMNS if c not in meta]
    if missing:
        raise ParameterError(f"the crack detector needs each record's {' and '.join(missing)} (store metadata)")
    per_state: dict[str, list[bool]] = {}
    records = []
    for rows, x in whole_records(samples.X, meta, hop):
        labels = set(np.asarray(samples.y)[rows].astype(str))
        if len(labels) != 1:
            raise ParameterError(f"record {meta['unit'][rows[0]]} carries several labels: {sorted(labels)}")
        label = labels.pop()
        v, ld = float(meta[OPERATING_COLUMNS[0]][rows[0]]), float(meta[OPERATING_COLUMNS[1]][rows[0]])
        res = twin.judge(x, fs, v, ld, name=f"record {meta['unit'][rows[0]]}")
        per_state.setdefault(label, []).append(res.alarm)
        records.append({"unit": meta["unit"][rows[0]].item(), "label": label, "index": res.index,
                        "alarm": res.alarm})
    share = {k: float(np.mean(v)) for k, v in per_state.items()}
    return {"crack_detection": share.get(cracked), "crack_false_alarm_rate": share.get(healthy),
            "crack_alpha": twin.detectors[0].alpha,
            "crack_alarm_rate_per_state": share, "crack_n_records": {k: len(v) for k, v in per_state.items()},
            "crack_records": records}


def evaluate_crack_on_store(twin: CrackTwin, store, split: str = "all", where: Sequence[str] = ()) -> dict:
    """:func:`evaluate_crack` over the monitored records of ``split`` of a sample store (those ``rvdiag evaluate``
    scores with the monitor: :func:`rvdiag.monitoring.training.monitored_records`), whole."""
    from rvdiag.monitoring.training import monitored_records

    s, _ = monitored_records(store.load(index=store.indices(split, list(where))))
    hop = ((store.attrs.get("config") or {}).get("signal") or {}).get("hop")
    return evaluate_crack(twin, s, float(store.fs), hop=hop)


__all__ = ["ALPHA", "ASSUMPTIONS", "CRACK_SEVERITY", "NOISE_METHODS", "CommissioningRecord", "CrackDetector",
           "CrackReference", "CrackResult", "CrackTwin", "attach_baseline", "commission_crack_references",
           "estimate_noise_var", "evaluate_crack", "evaluate_crack_on_store", "load_twin", "model_p_value",
           "model_threshold", "on_reference_axis", "operating_points", "params_digest", "simulate_reference",
           "whole_records"]
