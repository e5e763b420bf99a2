"""Rolling-bearing envelope features: squared-envelope spectrum peaks at the defect frequencies.

The classic bearing diagnostic (Randall & Antoni, "Rolling element bearing diagnostics -- a tutorial",
Mech. Syst. Signal Process. 25 (2011) 485-520): a local defect makes an impact each time a rolling element
passes it; the impacts excite structural resonances, so the *squared envelope* of the signal, band-passed
around an excited resonance, has a spectrum with lines at the defect frequency and its harmonics
(section 3.2).  Which band carries the impacts is not known in advance (the kurtogram idea of Antoni,
"Fast computation of the kurtogram for the detection of transient faults", Mech. Syst. Signal Process.
21 (2007) 108-124): every dyadic band of levels 1..``levels`` of the kurtogram's binary tree (2 + 4 bands
of [0, Nyquist] by default) is demodulated with the ideal FFT band-pass of
:func:`rvdiag.features.spectrum.squared_envelope`, and each line keeps its strongest band.

Defect frequencies (outer race fixed, shaft frequency f_r; Randall & Antoni 2011, Eqs. (1)-(4)), computed
by :func:`rvdiag.features.spectrum.bearing_defect_frequencies`:

    FTF  = f_r/2 (1 - d/D cos phi)              BPFO = n f_r/2 (1 - d/D cos phi)
    BPFI = n f_r/2 (1 + d/D cos phi)            BSF  = D/(2d) f_r (1 - (d/D cos phi)^2)

A ball defect strikes both races once per spin, so its line is at 2 BSF (Randall & Antoni 2011, section 2.1).

Features of one window (dimensionless, so independent of the sensor's gain and the load level): the
strength of the BPFO, BPFI and 2 BSF lines of the squared envelope relative to the envelope's total
energy (log10), and the same minus their mean -- which line dominates says *where* the defect is,
whatever its size (:class:`BearingEnvelopeFeatures`).  The lines are evaluated exactly at k f (1 + s)
rather than on the FFT grid: with 2048-point windows at 12 kHz the grid step (5.9 Hz) is as wide as the
gap between BPFO and the second lower sideband BPFI - 2 f_r of an inner-race defect.

Speed per window: with ``speed_column`` set (``rvdiag train --features bearing-envelope`` sets it to the
``--rpm-column`` metadata column), the last input column holds each window's shaft speed in rev/min and the
defect frequencies follow it window by window (f_r = RPM / 60), so one model serves several speeds; the
model card records the column's name (:func:`rvdiag.features.combine.input_metadata`).

The defaults describe the CWRU drive-end bearing, a 6205-2RS JEM SKF deep-groove ball bearing: 9 balls,
d = 0.3126 in, D = 1.537 in (CWRU Bearing Data Center, "Bearing information" page); the data centre lists
defect frequencies as multiples of shaft speed BPFI 5.4152, BPFO 3.5848, FTF 0.39828, BSF 2.357.
"""

from __future__ import annotations

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.features._base import SignalTransformer
from rvdiag.features.spectrum import bearing_defect_frequencies, squared_envelope
from rvdiag.validation import positive

#: CWRU drive-end bearing 6205-2RS JEM SKF (inches; only the ratio d/D matters)
BEARING_6205 = {"n_balls": 9, "ball_diameter": 0.3126, "pitch_diameter": 1.537, "contact_angle_rad": 0.0}

_LINES = ("bpfo", "bpfi", "bsf2")


def kurtogram_bands(levels: int = 3) -> list[tuple[float, float]]:
    """The dyadic bands (cycles/sample) of levels 1..``levels`` of the kurtogram's binary tree."""
    bands = []
    for level in range(1, levels + 1):
        n = 2**level
        bands += [(0.5 * k / n, 0.5 * (k + 1) / n) for k in range(n)]
    return bands


def spectral_kurtosis(X: np.ndarray, band: tuple[float, float]) -> np.ndarray:
    """Spectral kurtosis of each row in ``band``: E|c|^4 / (E|c|^2)^2 - 2 of its complex envelope c.

    For a complex envelope, stationary Gaussian noise gives 0 and impulsive signals give > 0 (Antoni 2007,
    Eq. (2)).  |c|^2 is the squared envelope of :func:`squared_envelope`.
    """
    e = squared_envelope(X, band)
    m2 = e.mean(axis=1)
    m4 = (e * e).mean(axis=1)
    out = np.zeros(X.shape[0])
    np.divide(m4, m2 * m2, out=out, where=m2 > 0)
    return out - 2.0


class BearingEnvelopeFeatures(SignalTransformer):
    """Squared-envelope line strengths at BPFO, BPFI and 2 BSF, and their contrasts (see module doc).

    For each dyadic band of kurtogram levels 1..``levels`` (:func:`kurtogram_bands`) the window's squared
    envelope e (band-passed, mean removed, Hann-weighted) is formed, and for each defect line f and
    harmonic k = 1..``harmonics`` the amplitude of its Fourier sum at k f (1 + s) is evaluated exactly
    (not on the FFT grid), s on a grid of ``n_slip`` values in [-``slip``, +``slip``] (bearing slip and
    speed uncertainty, 1-2 %, Randall & Antoni 2011, section 2.1); the largest over s, divided by ||e||, is
    averaged over the harmonics.  The feature of a line is log10 of its largest value over the bands.
    Six features: ``bpfo``, ``bpfi``, ``bsf2`` and the same minus their mean (``*_contrast``: which line
    dominates, the location of the defect, whatever its severity).

    The defect frequencies are those of Randall & Antoni 2011, Eqs. (1)-(4) (module doc): BPFO =
    n f_r/2 (1 - d/D cos phi), BPFI = n f_r/2 (1 + d/D cos phi), 2 BSF = D/d f_r (1 - (d/D cos phi)^2).

    Parameters
    ----------
    shaft_frequency : float
        Shaft (inner-race) rotation frequency: in Hz when ``fs`` is given, else in cycles per sample.
        (CWRU: RPM / 60 Hz with fs = 12 kHz.)  Not used when ``speed_column`` is set.
    fs : float or None
        Sampling rate in Hz.
    n_balls, ball_diameter, pitch_diameter, contact_angle_rad
        Bearing geometry (defaults: the 6205 of the CWRU drive end, :data:`BEARING_6205`); the diameters in
        any one unit (only d/D matters).
    harmonics : int
        Harmonics of each defect line.
    slip : float
        Largest relative deviation of the line searched.
    n_slip : int
        Grid points over [-slip, slip].
    levels : int
        Kurtogram levels whose bands are demodulated (1..5).
    speed_column : str or None
        Name of the metadata column that holds each window's shaft speed in rev/min.  When set, ``X`` is
        ``(n_windows, n_points + 1)``: the window's points, then its speed (``fs`` is then required).
        Windows of equal speed are transformed together.
    """

    _min_points = 64

    def __init__(self, shaft_frequency: float = 1797 / 60, fs: float | None = 12000.0,
                 n_balls: int = 9, ball_diameter: float = 0.3126, pitch_diameter: float = 1.537,
                 contact_angle_rad: float = 0.0, harmonics: int = 3, slip: float = 0.02, n_slip: int = 5,
                 levels: int = 2, speed_column: str | None = None):
        self.shaft_frequency = shaft_frequency
        self.fs = fs
        self.n_balls = n_balls
        self.ball_diameter = ball_diameter
        self.pitch_diameter = pitch_diameter
        self.contact_angle_rad = contact_angle_rad
        self.harmonics = harmonics
        self.slip = slip
        self.n_slip = n_slip
        self.levels = levels
        self.speed_column = speed_column

    # ------------------------------------------------------------------ parameters
    def input_metadata(self) -> tuple[str, ...]:
        """Metadata columns appended to each window of ``X``: ``(speed_column,)`` or none."""
        return () if self.speed_column is None else (str(self.speed_column),)

    def _shaft_cps(self, shaft_frequency: float | None = None) -> float:
        f = float(self.shaft_frequency if shaft_frequency is None else shaft_frequency)
        if self.fs is not None:
            f = f / positive(self.fs, "fs", unit=" Hz")
        if not 0 < f < 0.5:
            shown = self.shaft_frequency if shaft_frequency is None else shaft_frequency
            raise ParameterError(
                f"shaft frequency must lie between 0 and Nyquist, got {shown} (fs {self.fs})"
            )
        return f

    def defect_frequencies_cps(self, shaft_frequency: float | None = None) -> dict[str, float]:
        """Shaft ``fr``, FTF, BPFO, BPFI and 2 BSF in cycles per sample (at ``shaft_frequency``, in the unit of
        the parameter of that name, else at the parameter)."""
        fr = self._shaft_cps(shaft_frequency)
        f = bearing_defect_frequencies(fr, int(self.n_balls), float(self.ball_diameter),
                                       float(self.pitch_diameter), float(self.contact_angle_rad))
        return {"fr": fr, "ftf": f["ftf"], "bpfo": f["bpfo"], "bpfi": f["bpfi"], "bsf2": 2.0 * f["bsf"]}

    def _check_params(self, n_points, shaft_frequency: float | None = None):
        if self.speed_column is not None:
            if not (isinstance(self.speed_column, str) and self.speed_column):
                raise ParameterError(f"speed_column must be a metadata column name, got {self.speed_column!r}")
            if self.fs is None:
                raise ParameterError("a shaft speed in rev/min per window (speed_column) needs the sampling rate fs")
            n_points -= 1
        if not (isinstance(self.harmonics, (int, np.integer)) and self.harmonics >= 1):
            raise ParameterError(f"harmonics must be a positive integer, got {self.harmonics!r}")
        if not 0 <= self.slip < 0.25:
            raise ParameterError(f"slip must be in [0, 0.25), got {self.slip}")
        if not (isinstance(self.n_slip, (int, np.integer)) and self.n_slip >= 1):
            raise ParameterError(f"n_slip must be a positive integer, got {self.n_slip!r}")
        if not (isinstance(self.levels, (int, np.integer)) and 1 <= self.levels <= 5):
            raise ParameterError(f"levels must be an integer in 1..5, got {self.levels!r}")
        if self.speed_column is not None and shaft_frequency is None:
            return  # the lines are checked at each window's own speed in transform
        f = self.defect_frequencies_cps(shaft_frequency)
        top = max(f[k] for k in _LINES) * self.harmonics * (1 + self.slip)
        if top >= 0.5:
            raise ParameterError("defect-line harmonics above Nyquist: lower `harmonics` or check fs and speed")
        if n_points * f["bpfo"] < 2:
            raise ParameterError(f"windows of {n_points} points hold fewer than 2 periods of BPFO "
                                 f"({f['bpfo']:.3g} cycles/sample): use at least {int(np.ceil(2 / f['bpfo']))}")

    # ------------------------------------------------------------------ features
    def _features(self, X):
        if self.speed_column is None:
            return self._lines(X, None)
        W, rpm = X[:, :-1], X[:, -1]
        if W.shape[1] < self._min_points:
            raise ParameterError(f"signal windows need at least {self._min_points} points, got {W.shape[1]} "
                                 f"(plus the {self.speed_column!r} column)")
        if not np.all(rpm > 0):
            raise ParameterError(f"the shaft speed column {self.speed_column!r} holds values <= 0 rev/min "
                                 f"(e.g. {rpm[~(rpm > 0)][0]:g})")
        out = np.empty((X.shape[0], 2 * len(_LINES)))
        for value in np.unique(rpm):
            rows = rpm == value
            out[rows] = self._lines(np.ascontiguousarray(W[rows]), float(value) / 60.0)
        return out

    def _lines(self, X, shaft_frequency):
        """The features of windows ``X`` (points only) at one shaft frequency (None: the parameter)."""
        self._check_params(X.shape[1] + (self.speed_column is not None), shaft_frequency)
        n = X.shape[1]
        f = self.defect_frequencies_cps(shaft_frequency)
        t = np.arange(n)
        w = np.hanning(n)
        slips = np.linspace(-self.slip, self.slip, int(self.n_slip)) if self.n_slip > 1 else np.zeros(1)
        # one complex exponential per (line, harmonic, slip): (n, n_lines * harmonics * n_slip)
        freqs = np.array([[[k * f[name] * (1 + s) for s in slips] for k in range(1, int(self.harmonics) + 1)]
                          for name in _LINES])
        basis = np.exp(-2j * np.pi * np.outer(t, freqs.ravel()))
        best = np.full((X.shape[0], len(_LINES)), -np.inf)
        for band in kurtogram_bands(int(self.levels)):
            e = squared_envelope(X, band)
            e = (e - e.mean(axis=1, keepdims=True)) * w
            norm = np.sqrt((e * e).sum(axis=1))
            amp = np.abs(e @ basis).reshape(X.shape[0], *freqs.shape)  # windows x lines x harmonics x slips
            rel = np.zeros(amp.shape[:2])
            np.divide(amp.max(axis=3).mean(axis=2), norm[:, None], out=rel, where=norm[:, None] > 0)
            best = np.maximum(best, np.log10(rel + 1e-12))
        return np.column_stack([best, best - best.mean(axis=1, keepdims=True)])

    def _feature_names(self):
        return list(_LINES) + [f"{name}_contrast" for name in _LINES]


def geometry_from_mm(text: str) -> dict:
    """``"N_BALLS,D_BALL_MM,D_PITCH_MM,CONTACT_DEG"`` (``rvdiag train --bearing-geometry``) -> the geometry
    parameters of :class:`BearingEnvelopeFeatures` (diameters in mm, contact angle in radians).

    E.g. the CWRU 6205: ``"9,7.94,39.04,0"`` (d = 0.3126 in, D = 1.537 in).
    """
    parts = [p.strip() for p in str(text).split(",")]
    try:
        if len(parts) != 4:
            raise ValueError
        n, d, D, phi = int(parts[0]), float(parts[1]), float(parts[2]), float(parts[3])
    except ValueError:
        raise ParameterError(f"--bearing-geometry {text!r}: expected N_BALLS,D_BALL_MM,D_PITCH_MM,CONTACT_DEG, "
                             "e.g. 9,7.94,39.04,0") from None
    if n < 3 or not (np.isfinite(d) and np.isfinite(D) and 0 < d < D) or not (np.isfinite(phi) and 0 <= phi < 90):
        raise ParameterError(f"--bearing-geometry {text!r}: need at least 3 balls, 0 < ball diameter < pitch "
                             "diameter (mm) and a contact angle in [0, 90) degrees")
    return {"n_balls": n, "ball_diameter": d, "pitch_diameter": D, "contact_angle_rad": float(np.deg2rad(phi))}
