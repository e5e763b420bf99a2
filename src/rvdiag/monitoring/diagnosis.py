"""Judging one record against its machine's baseline: :func:`monitor_record` -> :class:`MonitorResult` (the health
index, the alarm at the monitor's stated false-alarm rate, the most probable state and what changed; or "not
recognised" with the reason).  ``rvdiag diagnose --baseline`` prints it; a service calls it in-process with the
model and the baseline loaded once (:func:`rvdiag.workflows.load_model`, :func:`rvdiag.monitoring.open_baseline`).

The record is cut into adjacent windows of the model's input length; each window's change against the baseline
records at the record's operating point (:func:`rvdiag.monitoring.pairing.paired_features`) is one row, and the
record is decided on the mean of its rows, as the alarm was calibrated.  Before that the record must be recognised:
not flat, with the reducer's mesh lines where the baseline shows them (:func:`mesh_check_against_baseline`), and
with the machine's level and spectrum as the baseline's measuring chain records them: not a disconnected sensor,
not the baseline's spectrum at another gain or unit, not another machine's spectrum
(:func:`level_check_against_baseline`).
"Not recognised" never means "too faulty": a machine far louder than its baseline is judged by its health index.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.monitoring.baseline import Baseline, needs_baseline
from rvdiag.monitoring.pairing import OPERATING_COLUMNS, paired_features


@dataclass
class MonitorResult:
    """One record judged against its machine's baseline (:func:`monitor_record`).

    ``health_index`` is the distance of the record's mean change from the healthy changes over the alarm's
    threshold, so the alarm (``alarm``) is ``health_index > threshold`` with ``threshold`` 1 (None when the monitor's
    calibration records are too few for any alarm); ``p_value`` its conformal p-value, at most ``false_alarm_rate``
    (the monitor's ``alpha``) when the alarm is raised.  ``state``/``state_name``/``probability``/``probabilities``:
    the most probable state and every state's probability; ``changes``: what changed, in words.  A record that is not
    ``recognised`` (``reason``) gets none of these (None, empty).  ``windows``: each window's ``start`` and
    ``health_index``.  :meth:`to_dict` is what ``rvdiag diagnose --baseline --json`` prints.
    """

    health_index: float | None = None
    alarm: bool | None = None
    false_alarm_rate: float = 0.0
    p_value: float | None = None
    threshold: float | None = None
    state: str | None = None
    state_name: str | None = None
    probability: float | None = None
    changes: list[str] = field(default_factory=list)
    n_windows: int = 0
    window_length: int = 0
    fs: float | None = None
    windows: list[dict] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    unused_points: int = 0
    recognised: bool = False
    reason: str | None = None
    checks: dict = field(default_factory=dict)
    operating_point: dict = field(default_factory=dict)
    probabilities: dict = field(default_factory=dict)
    #: the baseline records the record was compared with: path, n_records, their mean speed and load
    baseline: dict | None = None
    file: str | None = None
    channel: str | None = None
    model: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """The result as JSON-ready values (``rvdiag diagnose --baseline --json``)."""
        return asdict(self)

    def plot(self, ax=None):
        """The windows' health index against the alarm's threshold (matplotlib); returns the axes."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(6, 3))
        t = [w["start"] / self.fs if self.fs else w["start"] for w in self.windows if "health_index" in w]
        h = [w["health_index"] for w in self.windows if "health_index" in w]
        ax.plot(t, h, "o-", label="window health index")
        if self.health_index is not None:
            ax.axhline(self.health_index, color="k", lw=1, label=f"record {self.health_index:.3g}")
        if self.threshold is not None:
            ax.axhline(self.threshold, color="r", ls="--", label=f"alarm threshold ({100 * self.false_alarm_rate:g} %"
                                                                   " false alarms)")
        ax.set_xlabel("window start (s)" if self.fs else "window start (points)")
        ax.set_ylabel("health index")
        title = f"{self.file or 'record'}: " + ("ALARM" if self.alarm else "no alarm" if self.recognised
                                                else f"not recognised ({self.reason})")
        ax.set_title(title, fontsize="small")
        ax.legend(fontsize="small")
        return ax


def monitor_record(model, rec, base: Baseline, *, output_speed: float | None = None, load: float | None = None,
                   metadata: dict | None = None) -> MonitorResult:
    """Judge one record against its machine's baseline (module docstring).

    Parameters
    ----------
    model : the loaded monitor (:func:`rvdiag.workflows.load_model`), loaded once
    rec : the record (:func:`rvdiag.workflows.read_record`, or any :class:`rvdiag.io.readers.MeasuredSignal`)
    base : the machine's baseline (:func:`rvdiag.monitoring.open_baseline` of the same ``model``), opened once
    output_speed : the output speed in deg/s (None: the record's ``metadata``, its angle source, the speed a
        simulated record states, or the confirmed stage-1 mesh peak; :func:`rvdiag.workflows.records.record_speed`)
    load : the output torque in N m (None: the record's ``metadata["load_Nm"]``)
    metadata : further values such as ``--meta NAME=VALUE`` (``output_speed_deg_s``, ``input_speed_rpm``,
        ``load_Nm``), over the record's own

    Returns
    -------
    MonitorResult

    Raises
    ------
    ParameterError
        A record of another sampling rate, shorter than a window, without a load, or with no baseline records at
        its operating point.
    """
    from rvdiag.datasets.store import Samples
    from rvdiag.workflows.diagnosis import is_current_model
    from rvdiag.workflows.records import SPEED_META, flat_reason, recognition, record_speed, state_name

    if not needs_baseline(model):
        raise ParameterError(f"the model {model.path} is not baseline-referenced (its card does not say "
                             "needs_baseline): judge its records with rvdiag.workflows.diagnose")
    if not isinstance(base, Baseline):
        raise ParameterError(f"monitor_record needs a Baseline (rvdiag.monitoring.open_baseline), got "
                             f"{type(base).__name__}")
    est = model.estimator
    if not rec.fs:
        raise ParameterError("the file states no sampling rate: give --fs")
    if model.fs and abs(float(rec.fs) - model.fs) > 1e-9 * model.fs:
        raise ParameterError(f"the record is sampled at {float(rec.fs):g} Hz, the model and its baseline at "
                             f"{model.fs:g} Hz")
    L = model.input_length
    x = np.asarray(rec.data, dtype=np.float64)
    k = x.size // L
    if k < 1:
        raise ParameterError(f"the signal has {x.size} points, shorter than one window of {L} points (the model's "
                             "input length)")
    values = {**(getattr(rec, "metadata", None) or {}), **(metadata or {})}
    values = {c: v for c, v in values.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
    if output_speed is not None:
        values = {**values, SPEED_META[0]: float(output_speed)}
    load = values.get(OPERATING_COLUMNS[1]) if load is None else float(load)
    alpha = float((model.card.get("alarm") or {}).get("alpha", est.alpha))
    threshold = 1.0 if math.isfinite(float(getattr(est, "threshold_", math.inf))) else None
    res = MonitorResult(false_alarm_rate=alpha, threshold=threshold, n_windows=k, window_length=L,
                        fs=float(rec.fs), unused_points=int(x.size - k * L),
                        file=None if getattr(rec, "path", None) is None else str(rec.path),
                        channel=getattr(rec, "channel", None), model=str(model.path))
    n_cal = (model.card.get("alarm") or {}).get("record_windows")
    if n_cal and int(n_cal) != k:
        res.warnings.append(f"warning: the alarm's rate is calibrated on records of {int(n_cal)} window(s) of "
                            f"{L} points, decided on their mean change; this record has {k}: the stated rate "
                            f"holds for records of {int(n_cal)}")
    if load is None:
        raise ParameterError("the record's load is needed to find its baseline: give --load N_M (output torque)")
    speed = record_speed(rec, values)
    flat = flat_reason(x, L)
    rec_ok = recognition(model, x, rec.fs, {"novelty": None}, speed, is_current_model(model)) if flat is None else \
        {"recognised": False, "reason": flat, "checks": {}}
    bs = base.samples
    rec_ok = mesh_check_against_baseline(rec_ok, x, bs, float(rec.fs), speed, L, load,
                                        model.card.get("baseline"), cache=base.spectra)
    rec_ok = level_check_against_baseline(rec_ok, x, bs, float(rec.fs), L, speed, load, model.card.get("baseline"),
                                          cache=base.spectra)
    res.recognised, res.reason, res.checks = rec_ok["recognised"], rec_ok["reason"], rec_ok["checks"]
    res.operating_point = {"output_speed_deg_s": speed.get("output_speed_deg_s"),
                           "speed_source": speed.get("detail") or speed.get("error"), "load_Nm": load}
    if not res.recognised:
        return res
    if speed.get("output_speed_deg_s") is None:
        raise ParameterError(f"the record's speed is needed to find its baseline: {speed.get('error')}")
    X = x[: k * L].reshape(k, L)
    meta = {OPERATING_COLUMNS[0]: np.full(k, float(speed["output_speed_deg_s"])),
            OPERATING_COLUMNS[1]: np.full(k, load)}
    mon = Samples(X=X, y=np.array(["?"] * k), meta=meta, index=np.arange(k))
    D, groups = paired_features(est.features, mon, bs, fs=float(rec.fs), baseline_fs=base.fs,
                                card_tolerances=model.card.get("baseline"), where="the record")
    mean = D.mean(axis=0, keepdims=True)
    d = est.diagnose(mean)[0]
    res.health_index, res.alarm, res.p_value = d["health_index"], d["alarm"], d["p_value"]
    res.state, res.state_name, res.probability = d["state"], state_name(d["state"]), d["probability"]
    res.probabilities = {str(c): float(p) for c, p in zip(est.classes_, est.predict_proba(mean)[0])}
    res.changes = d["changed"]
    res.windows = [{"start": i * L, "health_index": float(h)} for i, h in enumerate(est.health_index(D))]
    res.baseline = {"path": str(base.path), "n_records": int(len(groups[0])),
                    "output_speed_deg_s": float(np.mean(bs.meta[OPERATING_COLUMNS[0]][groups[0]])),
                    "load_Nm": float(np.mean(bs.meta[OPERATING_COLUMNS[1]][groups[0]]))}
    return res


#: a record's mesh line missing where the baseline shows it is "masked", not gone, when the record's amplitude at
#: the line is at most this many dB below the baseline's line and its floor there has risen above the baseline's
MASK_DB = 6.0
#: a record's mesh line missing where the baseline shows it is *lost* only when the record's amplitude at the line
#: lies more than this many dB below the baseline's line: the mesh's vibration no longer reaches the sensor.
#: Measured (bench/HISTORY.md, 2026-11-28 "the mesh-line check: a line lost is a line whose energy is gone"):
#: the healthy records of 360 simulated joints whose reading missed a line the baseline shows stood -5.4 to +0.4 dB
#: from it (26 records of 6 joints: the baseline's line 10-12 dB above its floor, the record's reading of fewer
#: windows scattering across the 10 dB mark), their broken-tooth records -0.5 to +15.2 dB (31), a disconnected
#: sensor -16.0 to -25.5 dB
LOST_DB = 10.0


def _mean_power_spectrum(X: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies, the mean over the rows of ``X`` of their squared Hann amplitude spectra): Welch's averaged
    periodogram (Welch 1967) of windows of equal length, adjacent, without overlap."""
    from rvdiag.spectral import amplitude_spectrum

    X = np.atleast_2d(np.asarray(X, dtype=np.float64))
    f = amplitude_spectrum(X[0], fs)[0]
    return f, np.mean([np.square(amplitude_spectrum(w, fs)[1]) for w in X], axis=0)


def baseline_spectrum(base, rows: np.ndarray, fs: float, cache: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_mean_power_spectrum` of the baseline windows ``rows`` of ``base`` (a Samples), kept in ``cache``
    (:attr:`rvdiag.monitoring.baseline.Baseline.spectra`: a baseline opened once, reused for each of its records)
    under the rows and ``fs``, so that a joint's records read its operating point's baseline spectrum once.
    Without ``cache``, computed each time; either way the same numbers."""
    rows = np.asarray(rows, dtype=np.int64)
    key = ("power", float(fs), np.asarray(base.X).shape, rows.tobytes())
    if cache is not None and key in cache:
        return cache[key]
    out = _mean_power_spectrum(np.asarray(base.X, dtype=np.float64)[rows], fs)
    if cache is not None:
        cache[key] = out
    return out


def _mesh_lines_mean(spectrum: tuple, fs: float, n: int, speed: float) -> dict:
    """The two mesh lines (:func:`rvdiag.features.mesh_lines.mesh_lines`) read on ``spectrum``, the mean power
    spectrum ``(f, p)`` of windows of ``n`` points (:func:`_mean_power_spectrum`, or :func:`baseline_spectrum`;
    Welch 1967, the averaged periodogram): ``{name: {"hz", "height_db", "amplitude", "floor"}, "present":
    [names]}``.  Averaging the windows' power steadies the floor and the line (one window's bins scatter by about
    5.6 dB, a chi-square of 2 degrees of freedom) that one window reads."""
    from rvdiag.features.mesh_lines import LINE_DB
    from rvdiag.kinematics import characteristic_frequencies
    from rvdiag.motor.lines import line_height
    from rvdiag.params import ReducerParams

    amp = np.sqrt(spectrum[1])
    df = fs / n
    cf = characteristic_frequencies(ReducerParams.default(), output_speed_deg_s=float(speed))
    out: dict = {"present": []}
    for name, hz in (("stage1", cf.fsp), ("stage2", cf.fcs)):
        peak, h = line_height(amp, df, float(hz))
        ok = math.isfinite(h)
        out[name] = {"hz": float(hz), "height_db": float(h) if ok else None,
                     "amplitude": float(peak) if ok else None,
                     "floor": float(peak / 10.0 ** (h / 20.0)) if ok else None}
        if ok and h >= LINE_DB:
            out["present"].append(name)
    return out


def _baseline_rows(base, speed: float, load: float | None, tolerances: dict | None) -> np.ndarray:
    """The baseline windows of the record's operating point (:func:`rvdiag.monitoring.pairing.match_baseline`, at the
    card's tolerances; a ParameterError when none lies within them, as the record's scoring would raise); without a
    load, those at the nearest speed."""
    from rvdiag.monitoring.pairing import match_baseline

    if load is not None and all(c in base.meta for c in OPERATING_COLUMNS):
        tol = {k: float(t) for k, t in (tolerances or {}).items() if k in ("speed_tolerance", "load_tolerance")}
        return match_baseline({OPERATING_COLUMNS[0]: [speed], OPERATING_COLUMNS[1]: [float(load)]},
                              {c: base.meta[c] for c in OPERATING_COLUMNS}, **tol)[0]
    speeds = np.asarray(base.meta[OPERATING_COLUMNS[0]], dtype=float)
    return np.flatnonzero(np.isclose(speeds, speeds[int(np.argmin(np.abs(speeds - speed)))]))


def mesh_check_against_baseline(rec: dict, x: np.ndarray, base, fs: float, speed: dict, L: int,
                                load: float | None = None, tolerances: dict | None = None,
                                cache: dict | None = None) -> dict:
    """The mesh-line check of :func:`rvdiag.workflows.records.recognition`, judged against the machine's own baseline.

    A record without the reducer's mesh lines is "not recognised" only when the baseline shows a line that the
    record has lost.  Both are read the same way, on the mean power spectrum of windows of the model's ``L``
    points (:func:`_mesh_lines_mean`): all the record's windows against the baseline windows of its operating point
    (:func:`_baseline_rows`; ``tolerances`` the card's ``baseline`` table).  Where the baseline
    shows no line either (a quiet mesh behind a noisy path or a sensor floor), the lines say nothing about this
    machine and the record goes on to its health index (``checks["mesh_lines"]["baseline"]`` says so).
    ``cache``: the baseline's spectra kept between records (:func:`baseline_spectrum`).

    The record is "not recognised" when it has *lost* a line the baseline shows: the line is missing from the
    record's reading and the record's amplitude at the line lies more than :data:`LOST_DB` below the baseline's
    line (the mesh's vibration no longer reaches the sensor: a dead or disconnected sensor, or another machine's
    signal with little energy at the reducer's orders).  A missing line whose amplitude stays within
    :data:`LOST_DB` is not lost: it is *masked* when the amplitude stands at most :data:`MASK_DB` below the
    baseline's line while the floor around the line has risen above the baseline's (a changed machine: a broken
    tooth's impacts raise the floor around the mesh lines; :func:`rvdiag.features.mesh_lines.confirm_speed`), and
    *weaker* otherwise (a line the baseline shows just above the reading's threshold, which a record's reading of
    fewer windows scatters across it).  Either way the record goes on to its health index, which judges the
    change.  Measured on bench/fleet_alarms.py (bench/HISTORY.md, 2026-11-28 "the mesh-line check ..." and "the
    mesh-line check: a line lost is a line whose energy is gone"; docs/fleet.md)."""
    lines = rec.get("checks", {}).get("mesh_lines")
    if rec["recognised"] or lines is None or lines["present"]:
        return rec
    v = float(speed["output_speed_deg_s"])
    near = _baseline_rows(base, v, load, tolerances)
    k = max(x.size // L, 1)
    in_base = _mesh_lines_mean(baseline_spectrum(base, near, fs, cache), fs, np.shape(base.X)[1], v)
    in_record = _mesh_lines_mean(_mean_power_spectrum(x[: k * L].reshape(k, L), fs), fs, L, v)
    lost, masked, weaker = [], [], []
    for name in in_base["present"]:
        if name in in_record["present"]:
            continue
        b, r = in_base[name], in_record[name]
        if r["amplitude"] is None or r["amplitude"] < b["amplitude"] * 10.0 ** (-LOST_DB / 20.0):
            lost.append(name)
        elif r["amplitude"] >= b["amplitude"] * 10.0 ** (-MASK_DB / 20.0) and r["floor"] > b["floor"]:
            masked.append(name)
        else:
            weaker.append(name)
    checks = {**rec["checks"], "mesh_lines": {**lines, "baseline": in_base["present"],
                                              "record_windows": in_record["present"], "masked": masked,
                                              "weaker": weaker,
                                              "baseline_lines": {n: in_base[n] for n in ("stage1", "stage2")},
                                              "record_lines": {n: in_record[n] for n in ("stage1", "stage2")}}}
    if lost:
        return {**rec, "checks": checks, "reason": rec["reason"] + f"; the machine's baseline shows {', '.join(lost)}"}
    return {"recognised": True, "reason": None, "checks": checks}


#: a record whose RMS lies more than this factor below every baseline window's is "not recognised" (a disconnected
#: sensor, another gain or unit); one more than this factor above (a "loud" record) is recognised only with the
#: machine's spectrum, louder (:func:`level_check_against_baseline`)
LEVEL_FACTOR = 10.0
#: every third-octave band of a record more than this factor (amplitude) above the baseline's, or every band more
#: than this factor below, is the baseline's spectrum at another gain or unit when the bands stand within
#: :data:`SPREAD_FACTOR` of one another, or when the record is loud.  Measured (bench/HISTORY.md, 2026-11-28 "a loud
#: fault is a fault"): the quietest band of 49 simulated faulty records (T2-T6, up to 18.9x the baseline's RMS)
#: stood 0.66-1.01x the baseline's, of 274 healthy records 0.52-0.96x, of the same healthy records converted
#: from g to m/s^2 (x9.81) 6.6-8.9x
GAIN_FACTOR = 2.5
#: a gain moves every band alike: the loudest band's ratio over the quietest's (``max / min``) of the 274 healthy
#: records stood at most 2.3, that of the 21 faulty records more than 3x the baseline's RMS 6.7-79
SPREAD_FACTOR = 4.0
#: a loud record whose loudest band gained more than this factor over its bands together (:func:`band_ratios`'
#: ``shape``) puts its energy where the machine's baseline has little: another machine or sensor.  Measured (as
#: :data:`GAIN_FACTOR`): the 49 faulty records 1.0-5.4; other machines' records (a bearing rig, a gearbox, a
#: robot's RV reducer) 10-22000x louder than the baseline 4.3-50, those of them that keep a band within
#: :data:`GAIN_FACTOR` of the baseline's 6.5 (2 records) and 14.6-50
SHAPE_FACTOR = 8.0
#: a third-octave band counts when it holds at least this many spectral lines: a noise-like signal's power in it
#: then has at most 16 degrees of freedom in one window (fewer, as the Hann window's neighbouring lines overlap),
#: and the narrow low bands of a few lines, which scatter most, are left out
BAND_MIN_LINES = 8


def band_ratios(X: np.ndarray, B: np.ndarray, fs: float) -> dict:
    """The amplitude ratio of the windows ``X`` to the windows ``B`` (rows of equal length) in each base-ten
    third-octave band (IEC 61260-1:2014: midband frequencies ``1000 * 10**(n/10)`` Hz, edges a twentieth of a
    decade either side; the top band cut at ``fs / 2``) that holds at least :data:`BAND_MIN_LINES` lines: the square
    root of the ratio of the band powers read on the mean power spectra (:func:`_mean_power_spectrum`).

    Returns ``{"hz": midbands, "ratio": ratios, "min", "median", "max", "overall", "shape", "quietest_hz",
    "loudest_hz"}`` (empty arrays and None when no band holds enough lines): ``overall`` the ratio of the bands
    together, ``shape`` the loudest band's ratio over ``overall`` (1 for the baseline's spectrum at any gain).

    A gain (a unit, a sensor of another sensitivity, an amplifier setting) multiplies every band by the same factor,
    the measuring chain's own floor with it; a machine's change adds vibration in the bands it excites and leaves
    the others where they were.  So ``min`` far above 1 says "the baseline's spectrum at another gain", not "a
    louder machine"; ``shape`` far above 1 says that one band gained far more than the whole: energy where the
    baseline has little, another machine's spectrum rather than this one's.
    """
    f, px = _mean_power_spectrum(X, fs)
    return _band_ratios_of(f, px, _mean_power_spectrum(B, fs)[1], fs)


def _band_ratios_of(f: np.ndarray, px: np.ndarray, pb: np.ndarray, fs: float) -> dict:
    """:func:`band_ratios` on the mean power spectra ``px`` (the record's) and ``pb`` (the baseline's) at ``f``."""
    n = np.arange(math.floor(10 * math.log10(max(f[1], 1e-12) / 1000.0)), math.ceil(10 * math.log10(fs / 2000.0)) + 1)
    hz, bx, bb = [], [], []
    for m in 1000.0 * 10.0 ** (n / 10.0):
        lo, hi = m * 10.0 ** -0.05, min(m * 10.0 ** 0.05, fs / 2.0)
        sel = (f >= lo) & (f < hi)
        if lo >= fs / 2.0 or np.count_nonzero(sel) < BAND_MIN_LINES or not pb[sel].sum() > 0:
            continue
        hz.append(float(m))
        bx.append(float(px[sel].sum()))
        bb.append(float(pb[sel].sum()))
    if not hz:
        return {"hz": np.asarray(hz), "ratio": np.asarray([]), **dict.fromkeys(
            ("min", "median", "max", "overall", "shape", "quietest_hz", "loudest_hz"))}
    r = np.sqrt(np.asarray(bx) / np.asarray(bb))
    overall = math.sqrt(sum(bx) / sum(bb))
    return {"hz": np.asarray(hz), "ratio": r, "min": float(r.min()), "median": float(np.median(r)),
            "max": float(r.max()), "overall": overall, "shape": float(r.max()) / overall if overall > 0 else math.inf,
            "quietest_hz": hz[int(np.argmin(r))], "loudest_hz": hz[int(np.argmax(r))]}


def level_check_against_baseline(rec: dict, x: np.ndarray, base, fs: float | None = None, L: int | None = None,
                                 speed: dict | None = None, load: float | None = None,
                                 tolerances: dict | None = None, cache: dict | None = None) -> dict:
    """Is the record's level this machine's as the baseline records it?  "Not recognised" means that the record
    does not look like the reducer through the baseline's measuring chain (a disconnected sensor, another sensor,
    gain or unit, another machine), never that it is too faulty: a machine far louder than its baseline that keeps
    the machine's spectrum is recognised, and its health index judges it.

    Its RMS more than :data:`LEVEL_FACTOR` below every baseline window's is not recognised.  Otherwise its
    third-octave band levels are read against those of the baseline windows at its operating point
    (:func:`band_ratios` on windows of ``L`` points; :func:`_baseline_rows` at the card's ``tolerances``, all the
    baseline windows without a speed or where none lies within them).  A gain multiplies every band alike, the
    measuring chain's floor with it; a fault adds vibration in the bands it excites and leaves the others at the
    baseline's level (a simulated broken tooth at 18.9x the baseline's RMS kept its top band, the sensor's floor,
    at 0.98x).  Not recognised:

    - every band more than :data:`GAIN_FACTOR` below the baseline's (another gain or unit, a disconnected sensor
      that picks up a hum);
    - every band more than :data:`GAIN_FACTOR` above the baseline's, and either the bands within
      :data:`SPREAD_FACTOR` of one another (the baseline's spectrum at a gain: g for m/s^2 is 9.81x) or the record
      loud, more than :data:`LEVEL_FACTOR` above the baseline's RMS range (no band left at the machine's level);
    - a loud record whose loudest band gained more than :data:`SHAPE_FACTOR` over its spectrum as a whole
      (``shape``): energy where the machine's baseline has little, another machine or sensor.

    A loud record that passes is recognised as the machine, louder (``checks["level"]["louder"]``).  Without ``fs``,
    ``L`` or a band of enough lines, the RMS alone decides: a loud record is not recognised either.  ``cache``: the
    baseline's RMS range and spectra kept between records (:func:`baseline_spectrum`).
    """
    if not rec["recognised"]:
        return rec
    rms = float(np.sqrt(np.mean(np.square(x))))
    key = ("rms", np.asarray(base.X).shape)
    if cache is None or key not in cache:
        b = np.sqrt(np.mean(np.square(np.asarray(base.X, dtype=np.float64)), axis=1))
        lo, hi = float(b.min()), float(b.max())
        if cache is not None:
            cache[key] = (lo, hi)
    else:
        lo, hi = cache[key]
    level = {"rms": rms, "baseline_rms": [lo, hi], "factor": LEVEL_FACTOR, "gain_factor": GAIN_FACTOR,
             "spread_factor": SPREAD_FACTOR, "shape_factor": SHAPE_FACTOR}
    checks = {**rec.get("checks", {}), "level": level}
    span = f"the baseline's range ({lo:.4g}-{hi:.4g})"

    def refused(reason: str) -> dict:
        return {"recognised": False, "checks": checks, "reason": reason}

    if lo > 0 and rms < lo / LEVEL_FACTOR:
        return refused(f"its level (RMS {rms:.4g}) lies {lo / rms if rms > 0 else math.inf:.3g}x below {span}: a "
                       "disconnected sensor, or another sensor, gain or unit than the baseline's?")
    loud = lo > 0 and rms > hi * LEVEL_FACTOR
    bands = None
    if fs and L and x.size >= L:
        near = np.arange(np.asarray(base.X).shape[0])
        v = (speed or {}).get("output_speed_deg_s")
        if v is not None:
            try:
                near = _baseline_rows(base, float(v), load, tolerances)
            except ParameterError:  # no baseline at its operating point: the record's scoring says so
                pass
        k = x.size // L
        f, px = _mean_power_spectrum(x[: k * L].reshape(k, L), float(fs))
        bands = _band_ratios_of(f, px, baseline_spectrum(base, near, float(fs), cache)[1], float(fs))
        level["bands"] = {key: bands[key] for key in ("min", "median", "max", "overall", "shape", "quietest_hz",
                                                      "loudest_hz")}
    if bands is None or bands["min"] is None:
        if loud:
            return refused(f"its level (RMS {rms:.4g}) lies {rms / hi:.3g}x above {span}: another sensor, gain or "
                           "unit than the baseline's?")
        return {**rec, "checks": checks}
    lo_b, hi_b = bands["min"], bands["max"]
    if hi_b < 1.0 / GAIN_FACTOR:
        return refused(f"every third-octave band of its spectrum stands {1 / hi_b:.3g}-{1 / lo_b:.3g}x below the "
                       "baseline's: a disconnected sensor, or another sensor, gain or unit than the baseline's?")
    if lo_b > GAIN_FACTOR and (loud or hi_b / lo_b <= SPREAD_FACTOR):
        why = (f"with its RMS {rms / hi:.3g}x above {span}: no band left at the machine's level" if loud else
               "alike")
        return refused(f"every third-octave band of its spectrum stands {lo_b:.3g}-{hi_b:.3g}x above the "
                       f"baseline's, {why} (a fault adds vibration in the bands it excites and leaves the others): "
                       "another sensor, gain or unit than the baseline's?")
    if loud and bands["shape"] > SHAPE_FACTOR:
        return refused(f"its level (RMS {rms:.4g}) lies {rms / hi:.3g}x above {span} and its {bands['loudest_hz']:.4g} "
                       f"Hz band gained {bands['shape']:.3g}x more than its spectrum as a whole: energy where the "
                       "machine's baseline has little, another machine or sensor?")
    level["louder"] = loud
    return {**rec, "checks": checks}


__all__ = ["BAND_MIN_LINES", "GAIN_FACTOR", "LEVEL_FACTOR", "LOST_DB", "MASK_DB", "SHAPE_FACTOR", "SPREAD_FACTOR",
           "MonitorResult", "band_ratios", "baseline_spectrum", "level_check_against_baseline", "mesh_check_against_baseline",
           "monitor_record"]
