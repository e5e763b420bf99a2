"""Where a measured record's shaft angle comes from: encoder angles and counters, tachometer pulse trains, speeds
stated in file names, angles stored by ``rvdiag simulate``, and failing those a speed estimated from the spectrum.

Every function returns the *revolutions* of a shaft at each sample (0 at the first sample, increasing), which
:func:`rvdiag.features.orders.resample_to_angle` turns into an angle-domain signal (computed order tracking:
Fyfe & Munck, "Analysis of computed order tracking", Mech. Syst. Signal Process. 11 (1997) 187-205).  Bad angle
data raise one :class:`~rvdiag.errors.ParameterError` line that names the sample or time where it goes wrong:

- an angle that is not strictly increasing (after unwrapping one-revolution wraps) or a counter that goes back;
- a tachometer interval longer than :data:`LONG_INTERVAL` (1.5) times the median of its neighbours (a missing
  pulse doubles one interval: 1.5 is halfway) or shorter than :data:`SHORT_INTERVAL` (0.6) times it (a
  spurious pulse);
- a speed out of the plausible range (:data:`DEFAULT_SPEED_RANGE_RPM` of the input shaft, ``--speed-range``):
  the record's mean speed below the lower bound, or the speed over any block of :data:`SPEED_BLOCK_S` above
  the upper bound (an angle in degrees read as radians is 57 times too fast; a wrong ``--ppr`` scales it).

Tachometer (Fyfe & Munck 1997, section 2; Bonnardot, El Badaoui, Randall, Daniere & Guillet, "Use of the
acceleration signal of a gearbox in order to perform angular resampling (with limited speed fluctuation)",
Mech. Syst. Signal Process. 19 (2005) 766-785, section 2): a pulse is a rising crossing of the level halfway
between the channel's 1st and 99th percentiles (robust to the odd spike), its time interpolated linearly
between the two samples around the crossing; the angle is known at the pulses (k / ppr revolutions at pulse k)
and interpolated between them by a monotone cubic (PCHIP) of time, which keeps the speed continuous where
Fyfe & Munck's quadratic fits over three pulses may overshoot.

Encoder counters: a count c changing between samples k and k + 1 means the shaft crossed the count edges
c_k + 1 .. c_(k+1) in between; their mean, (c_k + 1 + c_(k+1)) / 2 counts, is placed at t = k + 1/2 (exact in
expectation at a constant speed, whether the counter moves less or more than once per sample), and the angle
is interpolated through these points by PCHIP, as for a tachometer.
"""

from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass
from typing import Any, Mapping

import numpy as np

from rvdiag.errors import DataFileError, ParameterError
from rvdiag.spectral import amplitude_spectrum, peak_frequency
from rvdiag.validation import finite_number, positive

#: a tachometer interval longer than this many times the median of its neighbours is a missing pulse
LONG_INTERVAL = 1.5
#: ... shorter than this many times it, a spurious pulse
SHORT_INTERVAL = 0.6
#: plausible input (motor) speeds, rev/min: servo motors of robot joints turn up to about 6000 rpm (the RV-20E's
#: rated input is 15 rev/min at the output x its ratio 105 = 1575 rpm); 10000 rpm leaves room, 1 rpm is a shaft
#: that barely turns in a record
DEFAULT_SPEED_RANGE_RPM = (1.0, 10000.0)
#: the speed limit is checked on the mean speed over blocks of this many seconds (at least 2 samples)
SPEED_BLOCK_S = 0.05
#: output speeds (deg/s) where the stage-1 mesh peak is sought when the speed is estimated from the spectrum
ESTIMATE_OUTPUT_DEG_S = (1.0, 200.0)
#: named groups of ``--meta-regex`` that state a speed: the input speed in rev/min, the output speed in deg/s
SPEED_GROUPS = ("rpm", "speed_dps")
#: the ``angle_source`` keys (the ``--json`` output of ``rvdiag orders``, the ``angle_source`` column of
#: ``rvdiag dataset from-files``)
ANGLE_SOURCES = ("angle-channel", "counter", "tacho", "stored-angle", "meta", "input-speed", "output-speed",
                 "shaft-rpm", "record-speed", "estimate", "cepstrum")


# --------------------------------------------------------------------------- constant speed
def angle_from_speed(n: int, fs: float, rev_per_s: float) -> np.ndarray:
    """Revolutions of a shaft turning at a constant ``rev_per_s`` at each of ``n`` samples."""
    return np.arange(int(n)) * (positive(rev_per_s, "shaft speed", unit=" rev/s") / float(fs))


# --------------------------------------------------------------------------- encoders
def _unwrap_revolution(a: np.ndarray, period: float) -> np.ndarray:
    """``a`` with its one-period wraps undone, when it is a wrapped angle (all values within one period): a
    step down by more than half a period is a wrap (the shaft turning forward); a record already unwrapped
    (spanning more than a period) is returned as it is."""
    lo, hi = float(a.min()), float(a.max())
    if hi - lo > period * (1.0 + 1e-9) or a.size < 2:
        return a
    d = np.diff(a)
    sign = 1.0 if float(np.sum(d[np.abs(d) < 0.5 * period])) >= 0.0 else -1.0  # forward or backward
    wraps = np.concatenate([[0.0], np.cumsum(np.where(sign * d < -0.5 * period, sign * period, 0.0))])
    return a + wraps


def _running_median_ratio(d: np.ndarray, w: int = 4) -> np.ndarray:
    """Each interval over the median of the 2w + 1 intervals around it."""
    pad = np.pad(d, w, mode="reflect" if d.size > w else "edge")
    ref = np.median(np.lib.stride_tricks.sliding_window_view(pad, 2 * w + 1), axis=1)
    return d / ref


def _through_points(t_samples: np.ndarray, revs: np.ndarray, n: int) -> np.ndarray:
    """Revolutions at samples 0..n-1 from known (time in samples, revolutions) points: PCHIP between the
    points, the nearest interval's speed before the first and after the last."""
    from scipy.interpolate import PchipInterpolator

    ts = np.arange(int(n), dtype=np.float64)
    out = np.empty(ts.size)
    inside = (ts >= t_samples[0]) & (ts <= t_samples[-1])
    out[inside] = PchipInterpolator(t_samples, revs)(ts[inside])
    before, after = ts < t_samples[0], ts > t_samples[-1]
    out[before] = revs[0] + (ts[before] - t_samples[0]) * (revs[1] - revs[0]) / (t_samples[1] - t_samples[0])
    out[after] = revs[-1] + (ts[after] - t_samples[-1]) * (revs[-1] - revs[-2]) / (t_samples[-1] - t_samples[-2])
    return out


def angle_from_encoder(angle, fs: float, ratio: float = 1.0, counts_per_rev: int | None = None) -> np.ndarray:
    """Revolutions of the analysed shaft from a measured angle per sample of a shaft turning ``ratio`` times
    slower (analysed speed = ``ratio`` x measured speed), 0 at the first sample.

    ``counts_per_rev`` None: ``angle`` is in radians and must be strictly monotonic.  Given: ``angle`` is an
    encoder counter of that many counts per revolution; it may stay put between samples (a slow shaft), must
    not go back, and is interpolated through its count changes (module docstring).  An angle held within one
    revolution ([0, 2 pi) or [0, counts_per_rev)) that wraps is unwrapped first.  A decreasing angle (a shaft
    turning backwards) is taken with its sign changed."""
    a = np.asarray(angle, dtype=np.float64).ravel()
    if a.size < 2 or not np.all(np.isfinite(a)):
        raise ParameterError("the angle channel must hold at least 2 finite values")
    if counts_per_rev is not None and not (isinstance(counts_per_rev, (int, np.integer)) and counts_per_rev >= 1):
        raise ParameterError(f"counts per revolution must be a positive integer, got {counts_per_rev!r}")
    period = 2 * np.pi if counts_per_rev is None else float(counts_per_rev)
    a = _unwrap_revolution(a, period)
    if a[-1] < a[0]:
        a = -a
    d = np.diff(a)
    if counts_per_rev is None:
        bad = np.flatnonzero(d <= 0)
        if bad.size:
            k = int(bad[0]) + 1
            raise ParameterError(f"the shaft angle is not monotonic: it stops or turns back at sample {k} "
                                 f"(t = {k / fs:.6g} s, {bad.size} such steps); unwrap it, or give a tachometer")
        return (a - a[0]) / (2 * np.pi) * float(ratio)
    back = np.flatnonzero(d < 0)
    if back.size:
        k = int(back[0]) + 1
        raise ParameterError(f"the angle counter goes back at sample {k} (t = {k / fs:.6g} s, from {a[k - 1]:g} to "
                             f"{a[k]:g} counts; {back.size} such steps)")
    k = np.flatnonzero(d > 0)
    if k.size < 3:
        raise ParameterError(f"the angle counter changes {k.size} times: at least 3 changes are needed")
    t = k + 0.5
    c = 0.5 * (a[k] + 1.0 + a[k + 1])
    gap = np.diff(t)
    r = _running_median_ratio(gap)
    stall = np.flatnonzero((r > LONG_INTERVAL) & (gap > LONG_INTERVAL * (gap / r) + 1.0))
    if stall.size:
        j = int(stall[0])
        raise ParameterError(f"the angle counter stands still from t = {t[j] / fs:.6g} s to {t[j + 1] / fs:.6g} s "
                             f"({r[j]:.2g} times its usual interval): a stalled shaft or lost counts")
    revs = _through_points(t, (c - c[0]) / counts_per_rev * float(ratio), a.size)
    return revs - revs[0]


# --------------------------------------------------------------------------- tachometers
def tacho_pulse_times(signal, fs: float, level: float | None = None) -> np.ndarray:
    """Times (s) of the rising edges of a tachometer pulse channel: crossings of ``level`` (default: halfway
    between its 1st and 99th percentiles, the mid-range robust to spikes), interpolated linearly between
    samples (Fyfe & Munck 1997)."""
    x = np.asarray(signal, dtype=np.float64).ravel()
    lo, hi = np.percentile(x, [1, 99])
    if not hi > lo:
        raise ParameterError("the tachometer channel is constant: no pulses")
    lv = 0.5 * (lo + hi) if level is None else float(level)
    k = np.flatnonzero((x[:-1] < lv) & (x[1:] >= lv))
    frac = (lv - x[k]) / (x[k + 1] - x[k])
    return (k + frac) / float(fs)


def angle_from_tacho(pulse_times, n: int, fs: float, ppr: int = 1, ratio: float = 1.0) -> np.ndarray:
    """Revolutions of the analysed shaft at each of ``n`` samples from tachometer pulse times (s), ``ppr`` pulses
    per revolution of a shaft turning 1/``ratio`` times as fast as the analysed one (Fyfe & Munck 1997;
    Bonnardot et al. 2005).

    Between pulses the angle is a monotone cubic (PCHIP) of time; before the first and after the last pulse it
    goes on at the speed of the nearest interval.  An interval longer than :data:`LONG_INTERVAL` or shorter than
    :data:`SHORT_INTERVAL` times the median of its neighbours (a missing or a spurious pulse), pulses that do
    not increase, or fewer than 3 pulses raise ParameterError (one line, with the time)."""
    t = np.asarray(pulse_times, dtype=np.float64).ravel()
    if not (isinstance(ppr, (int, np.integer)) and ppr >= 1):
        raise ParameterError(f"pulses per revolution must be a positive integer, got {ppr!r}")
    if t.size < 3 or not np.all(np.isfinite(t)):
        raise ParameterError(f"the tachometer gives {t.size} pulses: at least 3 finite pulse times are needed")
    d = np.diff(t)
    bad = np.flatnonzero(d <= 0)
    if bad.size:
        raise ParameterError(f"tachometer pulse times do not increase at pulse {int(bad[0]) + 1} "
                             f"(t = {t[bad[0] + 1]:.6g} s)")
    r = _running_median_ratio(d)
    long_, short = np.flatnonzero(r > LONG_INTERVAL), np.flatnonzero(r < SHORT_INTERVAL)
    if long_.size:
        k = int(long_[0])
        raise ParameterError(f"missing tachometer pulse(s) between t = {t[k]:.6g} s and {t[k + 1]:.6g} s (an "
                             f"interval {r[k]:.2g} times its neighbours'; {long_.size} such gaps)")
    if short.size:
        k = int(short[0])
        raise ParameterError(f"spurious tachometer pulse near t = {t[k + 1]:.6g} s (an interval {r[k]:.2g} times "
                             f"its neighbours'; {short.size} such)")
    revs = np.arange(t.size) / ppr * float(ratio)
    out = _through_points(t * float(fs), revs, n)
    return out - out[0]


# --------------------------------------------------------------------------- the spectrum
def estimate_shaft_speed(x, fs: float, order: float, speed_range: tuple[float, float]) -> float:
    """Shaft speed (rev/s) from a vibration spectrum: the highest peak of the Hann-windowed amplitude spectrum of
    ``x`` between ``order`` x ``speed_range`` (rev/s), refined by parabolic interpolation of the log magnitude over
    the peak bin and its two neighbours (:func:`rvdiag.spectral.peak_frequency`), divided by ``order`` (e.g. the
    stage-1 mesh, order Z1 of ``sun``).

    The band matters: a vibration's strongest line anywhere is often a mesh harmonic, so the peak is sought only
    where the mesh of a plausible speed lies, and :func:`rvdiag.features.mesh_lines.confirm_speed` checks it
    against the rest of the mesh's line family.  A motor current's speed comes instead from its supply line,
    the strongest line of the whole spectrum (:func:`rvdiag.motor.lines.output_speed_from_current`)."""
    x = np.asarray(x, dtype=np.float64).ravel()
    lo, hi = (float(v) for v in speed_range)
    if not (0 < lo < hi and order > 0):
        raise ParameterError(f"speed range must be 0 < low < high rev/s and order > 0, got {speed_range}, {order}")
    f_peak = peak_frequency(*amplitude_spectrum(x, fs), order * lo, order * hi)
    if f_peak is None:
        raise ParameterError(f"the mesh band {order * lo:g}-{order * hi:g} Hz lies outside the spectrum "
                             f"(fs {fs:g} Hz, {x.size} points)")
    return f_peak / order


def estimate_period_cepstrum(x, period_range: tuple[int, int | None] = (64, None)) -> tuple[float, int]:
    """``(period, cepstrum peak)`` in samples of the strongest family of equally spaced spectral lines of ``x``
    (harmonics and sidebands of one shaft, or of the common period of several), for a machine whose sampling
    rate or geometry is unknown.

    1. The real cepstrum c(q) = IFFT(log |X(f)|) of the Hann-windowed record (Randall, *Vibration-based
       Condition Monitoring*, Wiley 2011, chapter 3, cepstrum analysis: a family of lines spaced 1/T gives rahmonics at q = k T):
       its highest peak q0 between ``period_range`` (default 64 samples to a 16th of the record, so that a TSA
       averages at least 16 periods).  The peaks of a line family's cepstrum repeat at every multiple of its
       period (rahmonics), so when one at q0 / k (k = 2..16) reaches half the highest peak, q0 / k is taken:
       the fundamental, the shortest synchronous period.
    2. The period refined between q0 - 1 and q0 + 1 samples (the cepstrum's resolution) by harmonic summation:
       the T that maximises sum_m |X(m / T)| over every harmonic m below 0.45 cycles per sample (Hermes,
       "Measurement of pitch by subharmonic summation", J. Acoust. Soc. Am. 83 (1988) 257-264), the
       amplitude read between bins by linear interpolation; every line of the family constrains T, the high
       orders the most."""
    x = np.asarray(x, dtype=np.float64).ravel()
    n = x.size
    lo, hi = period_range
    hi = n // 16 if hi is None else int(hi)
    lo = int(lo)
    if not (2 <= lo < hi <= n // 2):
        raise ParameterError(f"the period range must be 2 <= LO < HI <= {n // 2} samples (half the record), "
                             f"got {lo}:{hi}")
    A = np.abs(np.fft.rfft((x - x.mean()) * np.hanning(n)))
    if not A.max() > 0:
        raise ParameterError("the signal is constant: no period to find")
    c = np.fft.irfft(np.log(A + 1e-12 * A.max()), n)
    q0 = lo + int(np.argmax(c[lo:hi + 1]))
    for k in range(16, 1, -1):  # the fundamental of the rahmonic family: its first rahmonic at q0 / k
        j = int(round(q0 / k))
        if j - 1 >= lo and c[j - 1:j + 2].max() >= 0.5 * c[q0]:
            q0 = j - 1 + int(np.argmax(c[j - 1:j + 2]))
            break
    T = np.linspace(q0 - 1.0, q0 + 1.0, 2001)
    m = np.arange(1, int(0.45 * (q0 - 1)) + 1)
    bins = np.arange(A.size)
    score = np.array([np.interp(m / t * n, bins, A).sum() for t in T])
    return float(T[int(np.argmax(score))]), q0


def parse_period_range(text: str) -> tuple[int, int | None]:
    """``"LO:HI"`` or ``"LO:"`` (samples) -> (LO, HI or None)."""
    lo, sep, hi = str(text).partition(":")
    try:
        out = (int(lo), int(hi) if hi.strip() else None)
    except ValueError:
        out = None
    if not sep or out is None or out[0] < 2 or (out[1] is not None and out[1] <= out[0]):
        raise ParameterError(f"--cepstrum {text!r}: expected LO:HI (or LO:) in samples with 2 <= LO < HI, e.g. 64:")
    return out


# --------------------------------------------------------------------------- checks
def parse_speed_range(text: str | None) -> tuple[float, float]:
    """``"MIN:MAX"`` (input rev/min) -> (MIN, MAX); None gives :data:`DEFAULT_SPEED_RANGE_RPM`."""
    if text is None:
        return DEFAULT_SPEED_RANGE_RPM
    lo, sep, hi = str(text).partition(":")
    try:
        rng = (float(lo), float(hi))
    except ValueError:
        rng = (math.nan, math.nan)
    if not sep or not (0 < rng[0] < rng[1] < math.inf):
        raise ParameterError(f"--speed-range {text!r}: expected MIN:MAX in rev/min with 0 < MIN < MAX, e.g. 10:6000")
    return rng


def check_speed(revs, fs: float, speed_range_rpm: tuple[float, float] = DEFAULT_SPEED_RANGE_RPM,
                what: str = "the input shaft") -> float:
    """The mean speed (rev/s) of ``revs`` (revolutions per sample), after checking it against ``speed_range_rpm``:
    the mean speed must not fall below the lower bound, the speed over any block of :data:`SPEED_BLOCK_S` must
    not exceed the upper bound; else ParameterError (one line, with the time of the first fast block)."""
    r = np.asarray(revs, dtype=np.float64).ravel()
    lo, hi = speed_range_rpm
    n = r.size
    mean = (r[-1] - r[0]) * fs / max(n - 1, 1) * 60.0
    hint = "check the angle's units, --ppr, or --speed-range"
    if not mean >= lo:
        raise ParameterError(f"{what} turns at {mean:.4g} rev/min on average, below the plausible {lo:g} rev/min "
                             f"({hint})")
    b = max(2, int(round(SPEED_BLOCK_S * fs)))
    edges = np.arange(0, n, b)
    if edges[-1] != n - 1:
        edges = np.append(edges, n - 1)
    v = np.diff(r[edges]) * fs / np.diff(edges) * 60.0
    fast = np.flatnonzero(v > hi)
    if fast.size:
        k = int(fast[0])
        raise ParameterError(f"{what} turns at {v[k]:.4g} rev/min near t = {edges[k] / fs:.6g} s, above the "
                             f"plausible {hi:g} rev/min ({hint})")
    return mean / 60.0


# --------------------------------------------------------------------------- file names
def speed_from_groups(groups: Mapping[str, Any], ratio: float, where: str = "--meta-regex") \
        -> tuple[float, str] | None:
    """(input rev/s, description) from the named groups ``rpm`` (input rev/min) or ``speed_dps`` (output deg/s,
    input = output x ``ratio``) of a file-name match, or None when neither took part.  Both, or a value that is
    not a positive number, raise ParameterError."""
    have = {k: groups.get(k) for k in SPEED_GROUPS if groups.get(k) not in (None, "")}
    if not have:
        return None
    if len(have) > 1:
        raise ParameterError(f"{where}: the groups rpm and speed_dps both state a speed: keep one")
    key, text = next(iter(have.items()))
    try:
        value = float(text)
    except (TypeError, ValueError):
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise ParameterError(f"{where}: group {key} gives {text!r}, not a positive number")
    if key == "rpm":
        return value / 60.0, f"{value:g} rev/min of the input from the file name"
    return value / 360.0 * float(ratio), f"{value:g} deg/s of the output from the file name"


def _compile(regex: str, what: str) -> re.Pattern:
    try:
        return re.compile(regex)
    except re.error as exc:
        raise ParameterError(f"invalid {what} {regex!r}: {exc}") from None


# --------------------------------------------------------------------------- one record
@dataclass(frozen=True)
class AngleSpec:
    """How to find the input shaft's angle of a record: at most one of ``angle_channel`` (rad, or counts with
    ``ppr``), ``tacho_channel`` (with ``ppr`` pulses per input revolution), ``input_speed_rpm``,
    ``output_speed_deg_s``, ``meta_regex`` (groups :data:`SPEED_GROUPS` in the file name); else the angles a
    record of ``rvdiag simulate`` stores (``stored``), its stated speed, and with ``estimate`` the stage-1 mesh
    peak of the spectrum (:func:`estimate_shaft_speed`, output speeds :data:`ESTIMATE_OUTPUT_DEG_S`).
    ``speed_range_rpm`` bounds the input speed (:func:`check_speed`)."""

    angle_channel: str | None = None
    tacho_channel: str | None = None
    ppr: int | None = None
    input_speed_rpm: float | None = None
    output_speed_deg_s: float | None = None
    meta_regex: str | None = None
    stored: bool = True
    estimate: bool = True
    speed_range_rpm: tuple[float, float] = DEFAULT_SPEED_RANGE_RPM

    def validate(self) -> "AngleSpec":
        given = [k for k, v in (("--angle-channel", self.angle_channel), ("--tacho-channel", self.tacho_channel),
                                ("--input-speed", self.input_speed_rpm), ("--output-speed", self.output_speed_deg_s),
                                ("--meta-regex", self.meta_regex)) if v is not None]
        if len(given) > 1:
            raise ParameterError(f"give one angle source, not {' and '.join(given)}")
        if self.ppr is not None:
            if self.angle_channel is None and self.tacho_channel is None:
                raise ParameterError("--ppr applies to --tacho-channel (pulses per input revolution) or "
                                     "--angle-channel (counts per revolution of an angle counter)")
            if isinstance(self.ppr, bool) or not isinstance(self.ppr, (int, np.integer)) or self.ppr < 1:
                raise ParameterError(f"--ppr must be a positive integer, got {self.ppr!r}")
        for name, v in (("--input-speed", self.input_speed_rpm), ("--output-speed", self.output_speed_deg_s)):
            if v is not None:
                finite_number(v, name, 0, strict=True, noun="a number")
        if self.meta_regex is not None:
            pat = _compile(self.meta_regex, "--meta-regex")
            if not set(SPEED_GROUPS) & set(pat.groupindex):
                raise ParameterError(f"--meta-regex {self.meta_regex!r} has no group (?P<rpm>...) or "
                                     "(?P<speed_dps>...) to read a speed from")
        lo, hi = self.speed_range_rpm
        if not (0 < lo < hi):
            raise ParameterError(f"the speed range must be 0 < MIN < MAX rev/min, got {lo:g}:{hi:g}")
        return self

    def to_dict(self) -> dict[str, Any]:
        """The spec as plain JSON-able values (a store's config records it)."""
        d = asdict(self)
        d["speed_range_rpm"] = list(self.speed_range_rpm)
        return d

    @property
    def measures_angle(self) -> bool:
        """A channel of the record states the angle (encoder, counter, tachometer)."""
        return self.angle_channel is not None or self.tacho_channel is not None


@dataclass(frozen=True)
class AngleResult:
    """The input shaft's revolutions at each sample of a record and where they came from."""

    revs: np.ndarray  # input (sun) shaft revolutions per sample, 0 at the first
    source: str  # one of ANGLE_SOURCES
    detail: str  # one line for people
    rev_per_s: float  # mean input speed

    @property
    def rpm(self) -> float:
        return 60.0 * self.rev_per_s


def _settings(attrs: Mapping[str, Any]) -> dict | None:
    import json

    s = attrs.get("settings")
    if isinstance(s, str):
        try:
            s = json.loads(s)
        except ValueError:
            return None
    return s if isinstance(s, dict) else None


def _other_channel(sig, regex: str, fs):
    from rvdiag.io.readers import read_signal

    other = read_signal(sig.path, regex, fs)
    if other.data.size != sig.data.size:
        raise DataFileError(f"{sig.path}: channel {other.channel!r} has {other.data.size} samples, "
                            f"the signal {sig.data.size}")
    return other


def input_revolutions(sig, spec: AngleSpec, params=None, fs: float | None = None) -> AngleResult:
    """The input (sun) shaft's revolutions at each sample of the record ``sig`` (a
    :class:`~rvdiag.io.MeasuredSignal` with a sampling rate), from the first source ``spec`` allows, in this
    order: an angle or tachometer channel of the same file; a given speed; a speed in the file name; the input
    angle ``theta_in`` (rad) a record of ``rvdiag simulate`` stores (the simulator's own angles, any speed
    profile); the ``sun_speed_hz`` such a record states; the stage-1 mesh peak.  ``params``: the reducer (ratio
    and sun teeth; default the built-in RV-20E); ``fs`` overrides the rate of the other channels as it did
    ``sig``'s.  The speed is checked against ``spec.speed_range_rpm``."""
    from rvdiag.io.readers import list_channels
    from rvdiag.kinematics import output_speed_from_input_hz, sun_speed_hz
    from rvdiag.params import ReducerParams

    spec.validate()
    p = params if isinstance(params, ReducerParams) else ReducerParams.load(params)
    i = p.ratio
    n, rate = sig.data.size, sig.fs
    if rate is None:
        raise ParameterError(f"{sig.path} states no sampling rate: give --fs")
    res: tuple[np.ndarray, str, str] | None = None
    if spec.angle_channel is not None:
        other = _other_channel(sig, spec.angle_channel, fs)
        if spec.ppr is None:
            res = (angle_from_encoder(other.data, rate), "angle-channel", f"angle channel {other.channel} (rad)")
        else:
            res = (angle_from_encoder(other.data, rate, counts_per_rev=int(spec.ppr)), "counter",
                   f"angle counter {other.channel}, {int(spec.ppr)} counts/rev")
    elif spec.tacho_channel is not None:
        other = _other_channel(sig, spec.tacho_channel, fs)
        ppr = int(spec.ppr or 1)
        res = (angle_from_tacho(tacho_pulse_times(other.data, rate), n, rate, ppr), "tacho",
               f"tachometer {other.channel}, {ppr} pulses/rev")
    elif spec.input_speed_rpm is not None:
        res = (angle_from_speed(n, rate, spec.input_speed_rpm / 60.0), "input-speed",
               f"input {spec.input_speed_rpm:g} rev/min")
    elif spec.output_speed_deg_s is not None:
        res = (angle_from_speed(n, rate, sun_speed_hz(p, output_speed_deg_s=spec.output_speed_deg_s)),
               "output-speed", f"output {spec.output_speed_deg_s:g} deg/s")
    elif spec.meta_regex is not None:
        m = _compile(spec.meta_regex, "--meta-regex").search(sig.path.name)
        if m is None:
            raise ParameterError(f"{sig.path.name}: the name does not match --meta-regex {spec.meta_regex!r}")
        got = speed_from_groups(m.groupdict(), i)
        if got is None:
            raise ParameterError(f"{sig.path.name}: --meta-regex {spec.meta_regex!r} matches but neither group rpm "
                                 "nor speed_dps takes part")
        res = (angle_from_speed(n, rate, got[0]), "meta", got[1])
    else:
        settings = _settings(sig.attrs)
        if spec.stored and settings is not None and "theta_in" in list_channels(sig.path):
            th = _other_channel(sig, "^theta_in$", fs).data
            res = (angle_from_encoder(th, rate), "stored-angle",
                   "the simulated record's own input angle theta_in")
        elif settings is not None and settings.get("sun_speed_hz"):
            res = (angle_from_speed(n, rate, float(settings["sun_speed_hz"])), "record-speed",
                   "the simulated record's stated speed")
        elif spec.estimate:
            mesh = p.stage1.sun_teeth * (1.0 - 1.0 / i)  # stage-1 mesh per input revolution
            band = tuple(sun_speed_hz(p, output_speed_deg_s=v) for v in ESTIMATE_OUTPUT_DEG_S)
            f = estimate_shaft_speed(sig.data, rate, mesh, band)
            res = (angle_from_speed(n, rate, f), "estimate",
                   f"estimated from the stage-1 mesh peak (order {p.stage1.sun_teeth} of the sun; "
                   f"{output_speed_from_input_hz(p, f):.4g} deg/s output)")
        else:
            raise ParameterError(f"{sig.path.name}: no angle source (give --angle-channel, --tacho-channel, a speed "
                                 "or --meta-regex with a group rpm or speed_dps)")
    revs, source, detail = res
    mean = check_speed(revs, rate, spec.speed_range_rpm)
    return AngleResult(revs, source, detail, mean)
