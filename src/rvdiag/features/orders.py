"""Angle-domain analysis of the reducer: computed order tracking, time-synchronous averaging (TSA) and the gear
condition indicators (``rvdiag orders``, feature sets ``tsa-ci`` and ``orders``; docs/orders.md).

Angle sources (:mod:`rvdiag.io.angles`, re-exported here; :func:`rvdiag.io.angles.input_revolutions` picks one)
--------------------------------------------------------------------------------------------------------------
- a measured angle per sample (an encoder of the input shaft, rad, or an encoder counter):
  :func:`angle_from_encoder`; it must be monotonic, else a one-line :class:`~rvdiag.errors.ParameterError`;
- tachometer pulse times with ``ppr`` pulses per revolution: :func:`angle_from_tacho` (pulses found in a pulse
  channel by :func:`tacho_pulse_times`); missing, spurious or non-increasing pulses raise ParameterError;
- a constant speed (given, or in the file name), or the angles a record of ``rvdiag simulate`` stores;
- failing those, a speed estimated from the spectrum: :func:`estimate_shaft_speed` takes the highest peak of
  the amplitude spectrum (Hann window) inside the band where a known mesh order can lie, refines its frequency
  by parabolic interpolation of the log magnitude over the three bins around the peak, and divides by the
  order.

Shafts of the RV reducer (:func:`shaft_frequency`; f_s the sun/input speed, i = 1 + Zp Z2 / Z1 the ratio,
f_H = f_s / i the carrier/output speed):

- ``sun``: the sun relative to the carrier, f_s - f_H (theta_in - theta_out): the stage-1 mesh is its order Z1,
  a sun-tooth fault its order N (planets);
- ``crank``: a crank (planet) relative to the carrier, Zp f_H = (Z1 / Z2)(f_s - f_H): the stage-1 mesh is its
  order Z2, the stage-2 (cycloid-pin) mesh its order Zc, a cycloid-lobe fault its order 1;
- ``output``: the carrier, f_H: a pin fault is its order Zc, the stage-2 mesh its order Zc Zp.

Computed order tracking (Fyfe & Munck, "Analysis of computed order tracking", Mech. Syst. Signal Process. 11
(1997) 187-205): the signal is low-pass filtered below the Nyquist order of the angular sampling at the lowest
speed (an FFT filter with a raised-cosine edge), then interpolated at the instants of uniform shaft angle with
the cubic convolution kernel of Keys (a = -1/2), a local cubic whose error Fyfe & Munck found far below that of
linear interpolation once the signal is oversampled.  :func:`resample_to_angle` returns ``samples_per_rev``
points per revolution, starting at the first whole revolution.

TSA and its family (:func:`gear_signals`), per shaft, from the order spectrum of the TSA of one revolution
(bin k = order k): the *regular* signal is the shaft orders 1..``shaft_orders``, the mesh harmonics and their
first-order sidebands; the *residual* signal is the TSA minus the shaft orders and the mesh harmonics; the
*difference* signal is the TSA minus the regular signal (Lebold, McClintic, Campbell et al. 2000; Decker 2002);
the *median tooth* (:func:`median_tooth`) is the point-by-point median of the TSA's tooth-mesh periods, the part
every tooth shares, which one faulty tooth does not move.
The indicators (:func:`condition_indicators`) follow the reviews of Decker ("Crack detection for aerospace
quality spur gears", NASA/TM-2002-211491) and Lebold et al. ("Review of vibration analysis methods for gearbox
diagnostics and prognostics", Proc. 54th MFPT, 2000), Zakrajsek, Townsend & Decker 1993 (NA4, NB4; NASA TM-105950)
and Randall, *Vibration-based Condition Monitoring* (Wiley, 2011), ch. 5.  For a planetary stage the TSA of
the sun relative to the carrier mixes the planets' meshes; McFadden's windowed vibration separation (McFadden,
"Window functions for the calculation of the time domain averages of the vibration of the individual planet
gears and sun gear in an epicyclic gearbox", J. Vib. Acoust. 116 (1994) 179-187) gives one TSA per planet:
:func:`rvdiag.features.planetary.planet_tsa`.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from rvdiag.errors import ParameterError
# the angle sources live in rvdiag.io.angles (the datasets layer uses them too); re-exported here
from rvdiag.io.angles import (angle_from_encoder, angle_from_speed, angle_from_tacho,  # noqa: F401
                              estimate_shaft_speed, tacho_pulse_times)

SHAFTS = ("sun", "crank", "output")

#: The indicators of :func:`condition_indicators`, in order, and the signal each uses.
INDICATORS = {
    "fm0": "TSA (peak-to-peak) and its mesh harmonics",
    "fm4": "difference signal",
    "na4": "residual signal (run of records)",
    "nb4": "envelope of the TSA band-passed around the mesh order (run of records)",
    "m6a": "difference signal",
    "m8a": "difference signal",
    "energy_ratio": "difference and regular signals",
    "sideband_level_factor": "first-order sidebands of the fundamental mesh, TSA",
    "sideband_index": "first-order sidebands of the fundamental mesh",
}


# --------------------------------------------------------------------------- reducer shafts
def _params(params):
    from rvdiag.params import ReducerParams

    if params is None or isinstance(params, (str, bytes)) or hasattr(params, "__fspath__"):
        return ReducerParams.load(params)
    return params


def shaft_ratio(shaft: str, params=None) -> float:
    """Speed of ``shaft`` (:data:`SHAFTS`) per unit of the sun (input) speed."""
    p = _params(params)
    i = p.ratio
    if shaft == "sun":
        return 1.0 - 1.0 / i
    if shaft == "crank":
        return p.stage2.pins / i
    if shaft == "output":
        return 1.0 / i
    raise ParameterError(f"unknown shaft {shaft!r}; use one of {'|'.join(SHAFTS)}")


def shaft_frequency(shaft: str, params=None, *, input_speed_rpm: float | None = None,
                    output_speed_deg_s: float | None = None, sun_speed_hz: float | None = None) -> float:
    """Rotation frequency (Hz) of ``shaft`` from exactly one of the input, output or sun speed."""
    from rvdiag.kinematics import sun_speed_hz as _sun

    p = _params(params)
    if sun_speed_hz is None:
        fs = _sun(p, input_speed_rpm, output_speed_deg_s)
    else:
        if input_speed_rpm is not None or output_speed_deg_s is not None or not sun_speed_hz > 0:
            raise ParameterError("give exactly one positive speed")
        fs = float(sun_speed_hz)
    return fs * shaft_ratio(shaft, p)


def mesh_order(shaft: str, params=None) -> int:
    """The mesh whose harmonics the indicators of ``shaft`` take: stage-1 (Z1) for ``sun``, stage-2 (Zc for
    ``crank``, Zc Zp for ``output``)."""
    p = _params(params)
    s1, s2 = p.stage1, p.stage2
    return {"sun": s1.sun_teeth, "crank": s2.cycloid_lobes,
            "output": s2.cycloid_lobes * s2.pins}[_check_shaft(shaft)]


def fault_orders(shaft: str, params=None) -> dict[str, float]:
    """Orders (frequency / shaft frequency) of the reducer's characteristic and fault frequencies on ``shaft``
    (keys of :data:`rvdiag.kinematics.FREQUENCY_KEYS` except the motor's ``fe``)."""
    from rvdiag.kinematics import characteristic_frequencies

    p = _params(params)
    f = characteristic_frequencies(p, input_speed_rpm=60.0).as_dict()
    fr = shaft_frequency(_check_shaft(shaft), p, input_speed_rpm=60.0)
    return {k: v / fr for k, v in f.items() if k != "fe"}


def _check_shaft(shaft):
    if shaft not in SHAFTS:
        raise ParameterError(f"unknown shaft {shaft!r}; use one of {'|'.join(SHAFTS)}")
    return shaft


# --------------------------------------------------------------------------- resampling
def _lowpass(x: np.ndarray, cutoff_cps: float) -> np.ndarray:
    """FFT low-pass with a raised-cosine edge from 0.85 to 1.0 x ``cutoff_cps`` (cycles/sample).

    The record is first extended at both ends by its point reflection (odd extension, half its length each
    side), which keeps its value and slope continuous, so the FFT's implied period has no jump at the record's
    ends to ring at: without it the first samples after the angle origin of :func:`resample_to_angle` were off
    by up to 60 % of the amplitude."""
    from scipy import fft

    n = x.size
    p = n // 2
    xp = np.pad(x, p, mode="reflect", reflect_type="odd") if p else x
    m = fft.next_fast_len(xp.size, real=True)
    X = fft.rfft(xp, m)
    f = np.arange(X.size) / m
    f0 = 0.85 * cutoff_cps
    g = np.ones(X.size)
    edge = (f > f0) & (f < cutoff_cps)
    g[edge] = 0.5 * (1 + np.cos(np.pi * (f[edge] - f0) / (cutoff_cps - f0)))
    g[f >= cutoff_cps] = 0.0
    return fft.irfft(X * g, m)[p:p + n]


def cubic_interpolate(x: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``x`` (uniform samples) at fractional sample positions ``u`` by Keys' cubic convolution (a = -1/2)."""
    xp = np.concatenate([x[:1], x, x[-1:], x[-1:]])
    i = np.floor(u).astype(np.int64)
    np.clip(i, 0, x.size - 1, out=i)
    s = u - i
    s2 = s * s
    s3 = s2 * s
    return (xp[i] * (-0.5 * s3 + s2 - 0.5 * s) + xp[i + 1] * (1.5 * s3 - 2.5 * s2 + 1.0)
            + xp[i + 2] * (-1.5 * s3 + 2.0 * s2 + 0.5 * s) + xp[i + 3] * (0.5 * s3 - 0.5 * s2))


def resample_to_angle(x, fs: float, revs, samples_per_rev: int, *, antialias: bool = True) -> np.ndarray:
    """``x`` at ``samples_per_rev`` uniform angles per revolution of the shaft whose revolutions at each sample
    are ``revs`` (:func:`angle_from_speed`, :func:`angle_from_encoder`, :func:`angle_from_tacho`), from the first
    whole revolution on, ``floor`` whole revolutions long (computed order tracking, Fyfe & Munck 1997).

    With ``antialias``, ``x`` is first low-passed at 0.9 x the Nyquist order (samples_per_rev / 2) at the lowest
    speed, where that is below fs / 2."""
    x = np.asarray(x, dtype=np.float64).ravel()
    r = np.asarray(revs, dtype=np.float64).ravel()
    spr = int(samples_per_rev)
    if spr < 8:
        raise ParameterError(f"samples per revolution must be >= 8, got {samples_per_rev}")
    if r.shape != x.shape:
        raise ParameterError(f"the angle has {r.size} samples, the signal {x.size}")
    d = np.diff(r)
    if not np.all(d > 0):
        raise ParameterError("the shaft angle is not monotonic increasing")
    first = math.ceil(r[0] - 1e-9)
    n_rev = math.floor(r[-1] - first + 1.0 / spr + 1e-9)  # the last angle, first + n_rev - 1/spr, is recorded
    if n_rev < 1:
        raise ParameterError(f"the record holds {r[-1] - r[0]:.3g} revolutions of the shaft: at least one whole "
                             "revolution is needed (a longer record, or another shaft)")
    if antialias:
        cut = 0.9 * 0.5 * spr * float(d.min())  # cycles/sample at the lowest speed
        if cut < 0.5:
            x = _lowpass(x, cut)
    theta = first + np.arange(n_rev * spr) / spr
    if np.allclose(d, d[0], rtol=1e-9, atol=0):
        u = (theta - r[0]) / d[0]
    else:
        u = np.interp(theta, r, np.arange(r.size, dtype=np.float64))
    return cubic_interpolate(x, u)


def default_samples_per_rev(fs: float, rev_per_s: float, mesh: float, harmonics: int = 4) -> int:
    """A power of two: at most the samples one revolution holds at ``fs`` (no made-up resolution), at least
    enough for ``harmonics`` mesh harmonics and their sidebands below 0.8 x the angular Nyquist order."""
    have = float(fs) / float(rev_per_s)
    need = 2.0 * (harmonics * mesh + 1) / 0.8
    spr = 2 ** int(math.floor(math.log2(max(have, 8.0))))
    return int(max(spr, min(2 ** int(math.ceil(math.log2(need))), 2 ** 16)))


# --------------------------------------------------------------------------- TSA and its family
def tsa(xa, samples_per_rev: int) -> np.ndarray:
    """Time-synchronous average of an angle-domain signal: the mean of its whole revolutions."""
    xa = np.asarray(xa, dtype=np.float64).ravel()
    n = xa.size // int(samples_per_rev)
    if n < 1:
        raise ParameterError("fewer than one revolution to average")
    return xa[: n * samples_per_rev].reshape(n, samples_per_rev).mean(axis=0)


def _orders_of(n: int, mesh: int, shaft_orders: int, mesh_harmonics: int | None, extra_meshes: Sequence[int] = ()):
    """Index arrays of the shaft orders, mesh harmonics (of ``mesh`` and of every ``extra_meshes``) and their
    first-order sidebands below the TSA's Nyquist."""
    top = n // 2 - (1 if n % 2 == 0 else 0)
    parts = []
    for m in (mesh, *extra_meshes):
        H = top // m if mesh_harmonics is None else int(mesh_harmonics)
        parts.append(np.arange(1, H + 1) * m)
    mh = np.unique(np.concatenate(parts))
    mh = mh[mh <= top]
    sh = np.arange(1, int(shaft_orders) + 1)
    sb = np.concatenate([mh - 1, mh + 1])
    sb = sb[(sb >= 1) & (sb <= top)]
    return sh[sh <= top], mh, sb


def gear_signals(t, mesh: int, shaft_orders: int = 2, mesh_harmonics: int | None = None,
                 extra_meshes: Sequence[int] = ()) -> dict:
    """The TSA ``t`` of one revolution and its regular, residual and difference signals (Lebold et al. 2000).

    - regular: shaft orders 1..``shaft_orders``, mesh harmonics k ``mesh`` (k = 1..``mesh_harmonics``, default all
      below the TSA's Nyquist order) and their first-order sidebands k ``mesh`` +- 1, and the same for each of
      ``extra_meshes`` (another mesh on the same shaft, e.g. the stage-2 mesh Zc on a crank);
    - residual: TSA minus the shaft orders and the mesh harmonics (the sidebands stay);
    - difference: TSA minus the regular signal.
    All have their mean removed.  Also returns the one-sided amplitude spectrum ``amplitude`` (index = order).
    """
    t = np.asarray(t, dtype=np.float64).ravel()
    n = t.size
    if not (isinstance(mesh, (int, np.integer)) and 1 <= mesh < n // 2):
        raise ParameterError(f"mesh order must be an integer in 1..{n // 2 - 1} (the TSA has {n} points), got {mesh}")
    T = np.fft.rfft(t)
    T[0] = 0
    sh, mh, sb = _orders_of(n, int(mesh), shaft_orders, mesh_harmonics, tuple(int(m) for m in extra_meshes))
    keep_reg = np.zeros(T.size, bool)
    keep_reg[np.concatenate([sh, mh, sb]).astype(int)] = True
    keep_sm = np.zeros(T.size, bool)
    keep_sm[np.concatenate([sh, mh]).astype(int)] = True
    regular = np.fft.irfft(np.where(keep_reg, T, 0), n)
    residual = np.fft.irfft(np.where(keep_sm, 0, T), n)
    amp = np.abs(T) * 2.0 / n
    return {"tsa": t - t.mean(), "regular": regular, "residual": residual, "difference": (t - t.mean()) - regular,
            "amplitude": amp, "mesh_harmonics": mh, "sidebands": sb}


def tooth_segments(t, teeth: int) -> np.ndarray:
    """The TSA ``t`` of one revolution cut into its ``teeth`` tooth-mesh periods: rows of ``m = ceil(n / teeth)``
    points, after Fourier resampling of the periodic ``t`` (its ``n`` points) to ``teeth * m`` (zero padding of its
    spectrum, exact for a TSA band-limited below its Nyquist order).  The mean of the rows is the TSA's mesh
    harmonics alone (orders k ``teeth``): the average tooth."""
    t = np.asarray(t, dtype=np.float64).ravel()
    n = t.size
    if not (isinstance(teeth, (int, np.integer)) and 2 <= teeth <= n // 4):
        raise ParameterError(f"teeth must be an integer in 2..{n // 4} (the TSA has {n} points), got {teeth!r}")
    m = -(-n // int(teeth))
    L = int(teeth) * m
    T = np.fft.rfft(t)
    if n % 2 == 0 and L > n:
        T[-1] *= 0.5  # the Nyquist bin becomes an interior bin: irfft adds its conjugate half
    return (np.fft.irfft(T, L) * (L / n)).reshape(int(teeth), m)


def median_tooth(t, teeth: int, trim: int = 0) -> dict:
    """The typical tooth of the TSA ``t``: the point-by-point median of its tooth-mesh periods
    (:func:`tooth_segments`), and what each period deviates from it.

    A localised tooth fault (a broken or cracked tooth) acts on the few periods in which the faulty tooth meshes
    (on the sun relative to the carrier, once per planet pass: N impacts per revolution, each falling into one or
    two periods), a distributed one (wear of every flank, Archard) on all of them.  The mean over the periods is the
    TSA's mesh-harmonic part, the "regular" signal less its sidebands and shaft orders (Stewart 1977, Lebold et al.
    2000; :func:`gear_signals`), and takes 1 / teeth of each impact; the median, the robust location estimate
    (Huber, *Robust Statistics*, Wiley 1981), ignores up to ``(teeth - 1) // 2`` outlying periods, so the
    median tooth follows a change of every tooth and not the impacts of one.

    Returns ``segments`` (teeth, m), ``median`` (m,) and ``deviation`` (teeth,): the mean square of each period
    minus the median tooth, and ``trimmed_deviation``: the mean of ``deviation`` over its ``teeth - trim``
    smallest (the periods of the localised fault left out).  The TSA's mean is removed first.
    """
    t = np.asarray(t, dtype=np.float64).ravel()
    S = tooth_segments(t - t.mean(), teeth)
    if not (isinstance(trim, (int, np.integer)) and 0 <= trim < S.shape[0]):
        raise ParameterError(f"trim must be an integer in 0..{S.shape[0] - 1}, got {trim!r}")
    M = np.median(S, axis=0)
    e = ((S - M) ** 2).mean(axis=1)
    return {"segments": S, "median": M, "deviation": e,
            "trimmed_deviation": float(np.sort(e)[: S.shape[0] - int(trim)].mean())}


def normalised_moment(d, k: int) -> float:
    """N^(k/2-1) sum (d - mean)^k / (sum (d - mean)^2)^(k/2): 3 for Gaussian d at k = 4, 15 at 6, 105 at 8."""
    d = np.asarray(d, dtype=np.float64)
    d = d - d.mean()
    m2 = float(np.mean(d * d))
    return float(np.mean(d**k) / m2 ** (k / 2)) if m2 > 0 else 0.0


def run_normalised_kurtosis(records: Sequence[np.ndarray], baseline_variance: float | None = None) -> np.ndarray:
    """NA4-type statistic of each record of a run: N sum (r_M - mean)^4 / [(1/M) sum_j sum_i (r_ij - mean_j)^2]^2
    (Zakrajsek, Townsend & Decker 1993, Eq. for NA4): record M's fourth moment over the square of the average of
    the variances of records 1..M.  Given ``baseline_variance`` (the residual variance of a healthy gearbox at the
    same load), that replaces the running average: NA4* of Decker, Handschuh & Zakrajsek ("An enhancement to the
    NA4 gear vibration diagnostic parameter", NASA TM-106553, 1994), load-normalised as in Dempsey & Zakrajsek
    ("Minimizing load effects on NA4 gear vibration diagnostic parameter", NASA/TM-2001-210671)."""
    out = []
    var_sum = 0.0
    for m, r in enumerate(records, start=1):
        r = np.asarray(r, dtype=np.float64)
        r = r - r.mean()
        v = float(np.mean(r * r))
        var_sum += v
        den = float(baseline_variance) if baseline_variance is not None else var_sum / m
        out.append(float(np.mean(r**4)) / den**2 if den > 0 else 0.0)
    return np.array(out)


def mesh_band_envelope(t, mesh: int) -> np.ndarray:
    """Envelope |analytic signal| of the TSA band-passed to mesh +- floor(mesh/2) orders (the band of NB4, which
    holds the sidebands of the fundamental mesh up to halfway to the neighbouring harmonics)."""
    t = np.asarray(t, dtype=np.float64).ravel()
    n = t.size
    F = np.fft.fft(t)
    k = np.fft.fftfreq(n, 1.0 / n)
    hw = max(1, int(mesh) // 2)
    h = np.where((k >= mesh - hw) & (k <= mesh + hw), 2.0, 0.0)
    return np.abs(np.fft.ifft(F * h))


def condition_indicators(t, mesh: int, shaft_orders: int = 2, mesh_harmonics: int | None = None,
                         history: dict | None = None, extra_meshes: Sequence[int] = ()) -> dict[str, float]:
    """The gear condition indicators of the TSA ``t`` of one revolution (:data:`INDICATORS`).

    ===================== ==================================================== ======================================
    indicator             formula                                              source
    ===================== ==================================================== ======================================
    fm0                   PP(TSA) / sum_h A(h mesh)                            Stewart 1977, via Decker 2002
    fm4                   N sum (d - d_)^4 / (sum (d - d_)^2)^2                Stewart 1977; Decker 2002; Lebold 2000
    m6a                   N^2 sum (d - d_)^6 / (sum (d - d_)^2)^3              Martin 1989, via Decker 2002
    m8a                   N^3 sum (d - d_)^8 / (sum (d - d_)^2)^4              Martin 1989, via Decker 2002
    na4                   N sum (r_M - r_M_)^4 / [mean_j var(r_j)]^2           Zakrajsek et al. 1993; Decker 2002
    nb4                   as na4 on the envelope of the mesh band              Zakrajsek et al. 1993; Decker 2002
    energy_ratio          RMS(d) / RMS(regular)                                Swansson 1980 via Lebold 2000
    sideband_level_factor (A(mesh-1) + A(mesh+1)) / std(TSA)                   Lebold 2000
    sideband_index        (A(mesh-1) + A(mesh+1)) / 2                          Lebold 2000
    ===================== ==================================================== ======================================

    d is the difference signal, r the residual signal, A(k) the one-sided amplitude of order k of the TSA, PP the
    peak-to-peak value.  ``history``: a dict carried across the records of a run (pass the same, initially empty,
    dict for each record) for the running-average denominators of NA4 and NB4; without it both are the
    normalised kurtosis of the one record.  ``extra_meshes``: other meshes whose harmonics are regular too
    (:func:`gear_signals`; FM0 sums the harmonics of every mesh, the sideband indicators use ``mesh``).
    """
    s = gear_signals(t, mesh, shaft_orders, mesh_harmonics, extra_meshes)
    A = s["amplitude"]
    tt, d, r, reg = s["tsa"], s["difference"], s["residual"], s["regular"]
    mh = A[s["mesh_harmonics"]].sum()
    env = mesh_band_envelope(t, mesh)
    if history is None:
        history = {}
    history.setdefault("residual", []).append(float(np.var(r)))
    history.setdefault("envelope", []).append(float(np.var(env)))

    def _run(x, key):
        x = x - x.mean()
        den = float(np.mean(history[key]))
        return float(np.mean(x**4)) / den**2 if den > 0 else 0.0

    rms_reg = float(np.sqrt(np.mean(reg**2)))
    sb = A[mesh - 1] + A[mesh + 1]
    std = float(tt.std())
    return {
        "fm0": float(tt.max() - tt.min()) / mh if mh > 0 else 0.0,
        "fm4": normalised_moment(d, 4),
        "na4": _run(r, "residual"),
        "nb4": _run(env, "envelope"),
        "m6a": normalised_moment(d, 6),
        "m8a": normalised_moment(d, 8),
        "energy_ratio": float(np.sqrt(np.mean(d**2))) / rms_reg if rms_reg > 0 else 0.0,
        "sideband_level_factor": float(sb) / std if std > 0 else 0.0,
        "sideband_index": float(sb) / 2.0,
    }


# --------------------------------------------------------------------------- spectra in orders
def order_spectrum(xa, samples_per_rev: int) -> tuple[np.ndarray, np.ndarray]:
    """(orders, one-sided amplitude) of an angle-domain signal of whole revolutions (Hann window, amplitude
    corrected: a sinusoid of amplitude a at an order on the grid reads a)."""
    xa = np.asarray(xa, dtype=np.float64).ravel()
    n = xa.size
    w = np.hanning(n)
    A = np.abs(np.fft.rfft((xa - xa.mean()) * w)) * 2.0 / w.sum()
    return np.fft.rfftfreq(n, 1.0 / samples_per_rev), A


def envelope_order_spectrum(xa, samples_per_rev: int, band: tuple[float, float] | None = None):
    """(orders, amplitude) of the squared envelope of an angle-domain signal band-passed to ``band`` (orders;
    default: all), mean removed: lines at the orders that modulate it (a local tooth fault: its fault order)."""
    xa = np.asarray(xa, dtype=np.float64).ravel()
    n = xa.size
    F = np.fft.fft(xa - xa.mean())
    k = np.abs(np.fft.fftfreq(n, 1.0 / samples_per_rev))
    h = np.where(np.fft.fftfreq(n) > 0, 2.0, 0.0)
    if band is not None:
        h[(k < band[0]) | (k > band[1])] = 0.0
    a = np.fft.ifft(F * h)
    return order_spectrum(a.real**2 + a.imag**2, samples_per_rev)


def moving_span(revs, fs: float, fraction: float = 0.5) -> tuple[int, int]:
    """``(start, stop)`` sample indices of the longest stretch of a record where the shaft turns at least
    ``fraction`` of its peak speed, speeds averaged over blocks of :data:`rvdiag.io.angles.SPEED_BLOCK_S`: the
    part of a run-up, cruise and run-down worth resampling (near rest the anti-alias low-pass of
    :func:`resample_to_angle`, set by the lowest speed, would remove everything)."""
    from rvdiag.io.angles import SPEED_BLOCK_S

    r = np.asarray(revs, dtype=np.float64).ravel()
    n = r.size
    b = max(2, int(round(SPEED_BLOCK_S * fs)))
    edges = np.arange(0, n, b)
    if edges[-1] != n - 1:
        edges = np.append(edges, n - 1)
    v = np.diff(r[edges]) / np.diff(edges)
    ok = v >= float(fraction) * v.max()
    best, run, start, best_start = 0, 0, 0, 0
    for k, good in enumerate(ok):
        if good:
            if run == 0:
                start = k
            run += 1
            if run > best:
                best, best_start = run, start
        else:
            run = 0
    return int(edges[best_start]), int(edges[best_start + best]) + 1


def analyse(x, fs: float, revs, shaft: str = "sun", params=None, samples_per_rev: int | None = None,
            shaft_orders: int = 2, mesh_harmonics: int | None = None, min_speed_fraction: float = 0.5,
            mesh: int | None = None) -> dict:
    """Resample, average and rate one record: the content of ``rvdiag orders`` (angle ``revs`` of ``shaft``).

    A record whose speed varies is first cut to its :func:`moving_span` at ``min_speed_fraction`` of the peak
    speed (returned as ``span``, sample indices).  ``mesh`` replaces the reducer's mesh order of ``shaft`` (another
    machine: ``revs`` is then the revolutions of its shaft, and no reducer fault orders are listed)."""
    p = _params(params)
    if mesh is not None and not (isinstance(mesh, (int, np.integer)) and mesh >= 1):
        raise ParameterError(f"the mesh order must be a positive integer, got {mesh!r}")
    m = mesh_order(shaft, p) if mesh is None else int(mesh)
    revs = np.asarray(revs, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    span = moving_span(revs, fs, min_speed_fraction) if revs.size > 2 else (0, revs.size)
    x, revs = x[span[0]:span[1]], revs[span[0]:span[1]]
    speed = (revs[-1] - revs[0]) * fs / max(revs.size - 1, 1)
    spr = samples_per_rev or default_samples_per_rev(fs, speed, m)
    xa = resample_to_angle(x, fs, revs, spr)
    t = tsa(xa, spr)
    orders, amp = order_spectrum(xa, spr)
    eo, ea = envelope_order_spectrum(xa, spr)
    return {"shaft": shaft, "shaft_hz": float(speed), "samples_per_rev": int(spr), "n_revolutions": xa.size // spr,
            "span": span,
            "mesh_order": m, "tsa": t, "orders": orders, "amplitude": amp, "envelope_orders": eo,
            "envelope_amplitude": ea, "fault_orders": fault_orders(shaft, p) if mesh is None else {},
            "indicators": condition_indicators(t, m, shaft_orders, mesh_harmonics)}
