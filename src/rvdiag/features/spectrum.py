"""Spectral features: FFT band energies, energies at characteristic frequencies, envelope spectra.

Frequencies are in **cycles per sample** (0 .. 0.5) when the sampling rate ``fs`` is not given, and in Hz
when it is.  A centre can also be given in **orders** (multiples of a shaft frequency) by setting
``shaft_frequency`` (in the same unit as the other frequencies); then ``centers`` are multiplied by it.

Three transformers:

- :class:`SpectrumFeatures` -- the one-sided FFT magnitude, either whole or summed into ``n_bands``
  equal bands (band energies, "plain FFT band energies").
- :class:`CharacteristicBandEnergy` -- energy of the power spectrum in narrow bands around the first
  ``harmonics`` multiples of given characteristic frequencies.  :meth:`CharacteristicBandEnergy.from_operating_point`
  takes them from :func:`rvdiag.kinematics.characteristic_frequencies` (RV reducer: mesh, crank, fault
  frequencies; docs/references.md, Li, Zhao et al. 2024, Table 2).
- :class:`EnvelopeSpectrumFeatures` -- the same band energies, or equal bands, of the squared-envelope
  spectrum of the (optionally band-passed) signal: the classic bearing diagnostic (Randall & Antoni,
  "Rolling element bearing diagnostics -- a tutorial", Mech. Syst. Signal Process. 25 (2011) 485-520,
  section 3.2; the squared envelope is their recommendation, section 3.2.1).

:func:`bearing_defect_frequencies` gives the bearing defect frequencies from geometry and speed
(Randall & Antoni 2011, Eqs. (1)-(4)).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.features._base import SignalTransformer
from rvdiag.validation import positive

_TINY = 1e-300


# --------------------------------------------------------------------------- helpers

def _window(name: str | None, n: int) -> np.ndarray:
    if name in (None, "none", "boxcar", "rect"):
        return np.ones(n)
    if name == "hann":
        return np.hanning(n)
    raise ParameterError(f"unknown window {name!r}; use 'hann' or None")


def power_spectrum(X: np.ndarray, window: str | None = "hann") -> np.ndarray:
    """One-sided power spectrum |FFT|^2 of each mean-removed row, shape (n, N//2 + 1).

    Scaled so that a sine of amplitude A (on a bin) gives a total band power of about A^2/2 with the
    rectangular window (Parseval: sum over the one-sided bins of 2|X_k|^2/N^2 equals the mean square).
    """
    X = np.asarray(X, dtype=np.float64)
    n = X.shape[1]
    w = _window(window, n)
    Xc = (X - X.mean(axis=1, keepdims=True)) * w
    S = np.abs(np.fft.rfft(Xc, axis=1)) ** 2 / (n * np.sum(w**2))
    S[:, 1:] *= 2.0
    if n % 2 == 0:
        S[:, -1] /= 2.0
    return S


#: added to the magnitude before the log of :func:`log_spectrum`
LOGSPEC_EPS = 1e-12


def log_spectrum(windows: np.ndarray) -> np.ndarray:
    """Level-free log-magnitude spectrum of each row: ``log(|rfft(hann * (x - mean))| + eps)`` minus its
    row mean, shape ``(n, W // 2 + 1)``, float32: the input of the ``logspec`` CNNs
    (:class:`rvdiag.models.torch_estimator.CNNClassifier`).  A gain ``g`` adds ``log g`` to every bin, which the
    row mean removes, so the result does not depend on the signal's level."""
    x = np.asarray(windows, dtype=np.float64)
    x = x - x.mean(axis=1, keepdims=True)
    mag = np.abs(np.fft.rfft(x * np.hanning(x.shape[1]), axis=1))
    out = np.log(mag + LOGSPEC_EPS)
    return (out - out.mean(axis=1, keepdims=True)).astype(np.float32)


def squared_envelope(X: np.ndarray, band: tuple[float, float] | None = None) -> np.ndarray:
    """Squared envelope |analytic signal|^2 of each row, band-passed to ``band`` (cycles/sample) first.

    The analytic signal is built in the frequency domain: positive-frequency bins inside ``band`` are
    doubled, all others zeroed (an ideal band-pass combined with the Hilbert transform).
    """
    X = np.asarray(X, dtype=np.float64)
    n = X.shape[1]
    F = np.fft.fft(X - X.mean(axis=1, keepdims=True), axis=1)
    f = np.fft.fftfreq(n)
    h = np.zeros(n)
    h[f > 0] = 2.0
    if n % 2 == 0:
        h[n // 2] = 1.0
    if band is not None:
        lo, hi = band
        h[(f < lo) | (f > hi)] = 0.0
    a = np.fft.ifft(F * h, axis=1)
    return a.real**2 + a.imag**2


def band_energies(S: np.ndarray, edges_cps: np.ndarray) -> np.ndarray:
    """Sum a one-sided spectrum ``S`` (n, N//2+1) over bands ``edges_cps`` (m, 2) in cycles/sample.

    Bin k sits at k/N cycles per sample with N = 2 (S.shape[1] - 1) (even N assumed for the grid; for odd
    N the grid differs by less than one bin).  Every band gets at least the nearest bin.
    """
    nb = S.shape[1]
    n = 2 * (nb - 1)
    cs = np.concatenate([np.zeros((S.shape[0], 1)), np.cumsum(S, axis=1)], axis=1)
    lo = np.clip(np.ceil(edges_cps[:, 0] * n - 1e-9).astype(int), 0, nb - 1)
    hi = np.clip(np.floor(edges_cps[:, 1] * n + 1e-9).astype(int), 0, nb - 1)
    centre = np.clip(np.rint(0.5 * (edges_cps[:, 0] + edges_cps[:, 1]) * n).astype(int), 0, nb - 1)
    empty = hi < lo
    lo = np.where(empty, centre, lo)
    hi = np.where(empty, centre, hi)
    return cs[:, hi + 1] - cs[:, lo]


def bearing_defect_frequencies(
    shaft_frequency: float,
    n_balls: int,
    ball_diameter: float,
    pitch_diameter: float,
    contact_angle_rad: float = 0.0,
) -> dict[str, float]:
    """Rolling-bearing defect frequencies, outer race fixed (Randall & Antoni 2011, Eqs. (1)-(4)).

    Parameters
    ----------
    shaft_frequency : float
        Inner-race (shaft) rotation frequency, in Hz or cycles/sample (the result has the same unit).
    n_balls : int
        Number of rolling elements n.
    ball_diameter, pitch_diameter : float
        d and D, same length unit.
    contact_angle_rad : float
        Contact angle phi.

    Returns
    -------
    dict with ``ftf`` (cage), ``bpfo``, ``bpfi`` and ``bsf`` (ball spin, the ball-fault frequency is 2 bsf).

    Examples
    --------
    CWRU drive-end 6205-2RS JEM SKF bearing (9 balls, d = 0.3126 in, D = 1.537 in) at 1797 rpm; the
    data centre lists BPFI = 5.4152 x shaft speed:

    >>> f = bearing_defect_frequencies(1797 / 60, 9, 0.3126, 1.537)
    >>> round(f["bpfi"], 1), round(f["bpfo"], 1), round(f["bsf"], 1)
    (162.2, 107.4, 70.6)
    """
    if not (shaft_frequency > 0 and n_balls >= 1 and ball_diameter > 0 and pitch_diameter > ball_diameter):
        raise ParameterError("bearing geometry needs f > 0, n >= 1 and pitch diameter > ball diameter > 0")
    r = ball_diameter / pitch_diameter * np.cos(contact_angle_rad)
    f = float(shaft_frequency)
    return {
        "ftf": f / 2 * (1 - r),
        "bpfo": n_balls * f / 2 * (1 - r),
        "bpfi": n_balls * f / 2 * (1 + r),
        "bsf": pitch_diameter / (2 * ball_diameter) * f * (1 - r**2),
    }


def _finish(E: np.ndarray, total: np.ndarray | None, log: bool) -> np.ndarray:
    if total is not None:
        E = E / np.maximum(total, _TINY)[:, None]
    if log:
        E = np.log10(E + 1e-12)
    return E


# --------------------------------------------------------------------------- transformers

class SpectrumFeatures(SignalTransformer):
    """FFT magnitude features: the whole one-sided spectrum or its energy in equal bands.

    Parameters
    ----------
    n_bands : int or None
        Number of equal-width bands over [0, ``fmax``]; each feature is the band's power.  ``None``
        returns the one-sided magnitude spectrum sqrt(power), bin by bin, up to ``fmax``.
    fmax : float
        Upper frequency in cycles per sample (0 < fmax <= 0.5).
    window : {'hann', None}
        Window applied before the FFT.
    log : bool
        Return log10 of the (relative) band powers; robust to the load-dependent amplitude of real data.
    relative : bool
        Divide each band power by the total power of the window (so the features describe the shape
        of the spectrum, not its level).
    """

    def __init__(self, n_bands: int | None = 64, fmax: float = 0.5, window: str | None = "hann",
                 log: bool = True, relative: bool = True):
        self.n_bands = n_bands
        self.fmax = fmax
        self.window = window
        self.log = log
        self.relative = relative

    def _check_params(self, n_points):
        if not 0 < self.fmax <= 0.5:
            raise ParameterError(f"fmax must be in (0, 0.5] cycles/sample, got {self.fmax}")
        if self.n_bands is not None and not (isinstance(self.n_bands, (int, np.integer)) and self.n_bands >= 1):
            raise ParameterError(f"n_bands must be a positive integer or None, got {self.n_bands!r}")
        _window(self.window, 2)

    def _features(self, X):
        self._check_params(X.shape[1])
        S = power_spectrum(X, self.window)
        total = S.sum(axis=1) if self.relative else None
        if self.n_bands is None:
            kmax = int(np.floor(self.fmax * X.shape[1])) + 1
            M = np.sqrt(S[:, :kmax])
            if total is not None:
                M = M / np.sqrt(np.maximum(total, _TINY))[:, None]
            return np.log10(M + 1e-12) if self.log else M
        e = np.linspace(0.0, self.fmax, self.n_bands + 1)
        edges = np.column_stack([e[:-1], e[1:] - 1e-12])
        edges[-1, 1] = e[-1]
        return _finish(band_energies(S, edges), total, self.log)

    def _feature_names(self):
        if self.n_bands is None:
            kmax = int(np.floor(self.fmax * self.n_features_in_)) + 1
            return [f"fft_bin{k}" for k in range(kmax)]
        return [f"fft_band{k}" for k in range(self.n_bands)]


class _CentredBands(SignalTransformer):
    """Band edges (cycles/sample) around harmonics of characteristic frequencies."""

    def _unit_scale(self) -> float:
        s = 1.0
        if self.fs is not None:
            s = 1.0 / positive(self.fs, "fs", unit=" Hz")
        if self.shaft_frequency is not None:
            s *= positive(self.shaft_frequency, "shaft_frequency")
        return s

    def _centres_cps(self) -> np.ndarray:
        c = np.atleast_1d(np.asarray(self.centers, dtype=float))
        if c.size == 0 or not np.all(np.isfinite(c)) or np.any(c <= 0):
            raise ParameterError(f"centers must be positive finite frequencies, got {self.centers!r}")
        return c * self._unit_scale()

    def _edges(self) -> np.ndarray:
        if not (isinstance(self.harmonics, (int, np.integer)) and self.harmonics >= 1):
            raise ParameterError(f"harmonics must be a positive integer, got {self.harmonics!r}")
        if not 0 < self.rel_width < 0.5:
            raise ParameterError(f"rel_width must be in (0, 0.5), got {self.rel_width}")
        c = self._centres_cps()
        h = np.arange(1, self.harmonics + 1)
        f = (c[:, None] * h[None, :]).ravel()
        if np.any(f * (1 + self.rel_width) > 0.5):
            unit = "Hz" if self.fs is not None else "cycles/sample"
            top = f.max() * (float(self.fs) if self.fs is not None else 1.0)
            raise ParameterError(
                f"a characteristic frequency harmonic ({top:.4g} {unit}) lies above the Nyquist frequency; "
                "lower `harmonics` or check fs"
            )
        return np.column_stack([f * (1 - self.rel_width), f * (1 + self.rel_width)])

    def _names(self, prefix):
        keys = self.names if self.names is not None else [f"c{i}" for i in range(len(np.atleast_1d(self.centers)))]
        return [f"{prefix}_{k}_h{h}" for k in keys for h in range(1, self.harmonics + 1)]


class CharacteristicBandEnergy(_CentredBands):
    """Power of the spectrum in bands f_c k (1 -/+ rel_width), k = 1..harmonics, per centre f_c.

    Parameters
    ----------
    centers : sequence of float
        Characteristic frequencies: Hz when ``fs`` is given, else cycles/sample; orders when
        ``shaft_frequency`` is given.
    fs : float or None
        Sampling rate in Hz.
    harmonics : int
        Harmonics per centre.
    rel_width : float
        Half width of each band relative to its centre (0.03 = +-3 %, covering speed fluctuation and
        bearing slip of 1-2 %, Randall & Antoni 2011, section 2.1).
    shaft_frequency : float or None
        Multiply ``centers`` by this (then ``centers`` are orders).
    names : sequence of str or None
        Names of the centres for :meth:`get_feature_names_out`.
    window, log, relative
        As in :class:`SpectrumFeatures`.
    """

    def __init__(self, centers: Sequence[float] = (0.1,), fs: float | None = None, harmonics: int = 3,
                 rel_width: float = 0.03, shaft_frequency: float | None = None,
                 names: Sequence[str] | None = None, window: str | None = "hann",
                 log: bool = True, relative: bool = True):
        self.centers = centers
        self.fs = fs
        self.harmonics = harmonics
        self.rel_width = rel_width
        self.shaft_frequency = shaft_frequency
        self.names = names
        self.window = window
        self.log = log
        self.relative = relative

    @classmethod
    def from_operating_point(cls, params, fs: float, input_speed_rpm: float | None = None,
                             output_speed_deg_s: float | None = None,
                             keys: Sequence[str] = ("f1", "f2", "fsp", "fcs", "f_sun_fault", "f_planet_fault",
                                                    "f_cycloid_fault", "f_pin_fault"),
                             **kw) -> "CharacteristicBandEnergy":
        """Centres from :func:`rvdiag.kinematics.characteristic_frequencies` at a known operating point.

        ``keys`` picks frequencies by their ``rvdiag freqs --json`` names (:mod:`rvdiag.kinematics`).
        """
        from rvdiag.kinematics import characteristic_frequencies

        f = characteristic_frequencies(params, input_speed_rpm=input_speed_rpm,
                                       output_speed_deg_s=output_speed_deg_s).as_dict()
        unknown = [k for k in keys if k not in f]
        if unknown:
            raise ParameterError(f"unknown characteristic frequency keys {unknown}; known: {list(f)}")
        return cls(centers=tuple(float(f[k]) for k in keys), fs=fs, names=tuple(keys), **kw)

    def _check_params(self, n_points):
        self._edges()
        _window(self.window, 2)

    def _features(self, X):
        S = power_spectrum(X, self.window)
        E = band_energies(S, self._edges())
        return _finish(E, S.sum(axis=1) if self.relative else None, self.log)

    def _feature_names(self):
        return self._names("band")


class EnvelopeSpectrumFeatures(_CentredBands):
    """Band powers of the squared-envelope spectrum (Randall & Antoni 2011, section 3.2).

    The window is band-passed to ``band`` (the resonance band excited by the impacts; none = whole
    spectrum), its squared envelope is taken through the analytic signal, and the spectrum of that
    envelope is summed either around harmonics of ``centers`` (e.g. the bearing defect frequencies of
    :func:`bearing_defect_frequencies`) or, when ``centers`` is None, in ``n_bands`` equal bands over
    [0, ``fmax``] -- usable when neither fs nor speed is known.

    Parameters
    ----------
    centers : sequence of float or None
        Defect frequencies (Hz with ``fs``, else cycles/sample; orders with ``shaft_frequency``).
    fs : float or None
        Sampling rate in Hz.
    band : (float, float) or None
        Band-pass before demodulation, in the unit of ``centers`` (Hz with ``fs``, else cycles/sample).
    n_bands, fmax
        Equal bands when ``centers`` is None; ``fmax`` in cycles/sample.
    harmonics, rel_width, shaft_frequency, names, log, relative
        As in :class:`CharacteristicBandEnergy`.
    """

    def __init__(self, centers: Sequence[float] | None = None, fs: float | None = None,
                 band: tuple[float, float] | None = None, n_bands: int = 40, fmax: float = 0.05,
                 harmonics: int = 3, rel_width: float = 0.03, shaft_frequency: float | None = None,
                 names: Sequence[str] | None = None, log: bool = True, relative: bool = True):
        self.centers = centers
        self.fs = fs
        self.band = band
        self.n_bands = n_bands
        self.fmax = fmax
        self.harmonics = harmonics
        self.rel_width = rel_width
        self.shaft_frequency = shaft_frequency
        self.names = names
        self.log = log
        self.relative = relative

    def _band_cps(self):
        if self.band is None:
            return None
        lo, hi = (float(v) for v in self.band)
        s = 1.0 / float(self.fs) if self.fs is not None else 1.0
        lo, hi = lo * s, hi * s
        if not 0 <= lo < hi <= 0.5:
            raise ParameterError(f"band {self.band} must satisfy 0 <= low < high <= Nyquist")
        return lo, hi

    def _check_params(self, n_points):
        self._band_cps()
        if self.centers is None:
            if not 0 < self.fmax <= 0.5:
                raise ParameterError(f"fmax must be in (0, 0.5] cycles/sample, got {self.fmax}")
            if not (isinstance(self.n_bands, (int, np.integer)) and self.n_bands >= 1):
                raise ParameterError(f"n_bands must be a positive integer, got {self.n_bands!r}")
        else:
            self._edges()

    def _features(self, X):
        env = squared_envelope(X, self._band_cps())
        S = power_spectrum(env, "hann")
        if self.centers is None:
            e = np.linspace(0.0, self.fmax, self.n_bands + 1)
            edges = np.column_stack([e[:-1], e[1:] - 1e-12])
            edges[-1, 1] = e[-1]
        else:
            edges = self._edges()
        return _finish(band_energies(S, edges), S.sum(axis=1) if self.relative else None, self.log)

    def _feature_names(self):
        if self.centers is None:
            return [f"env_band{k}" for k in range(self.n_bands)]
        return self._names("env")
