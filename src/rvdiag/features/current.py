"""A motor phase current with its supply line removed: what is left for a learned feature extractor to see.

A phase current ``i_a`` of a servo drive is a sinusoid at the electrical frequency ``f_e`` (the supply line),
amplitude-modulated by the load torque (a robot arm's gravity moment changes with its angle), with the lines
the reducer adds around it: ``f_e +- k f1`` for a sun-gear fault (Li, Zhao et al. 2024, Table 3; docs/model.md
section 10; :mod:`rvdiag.motor.lines`).  Those lines are 40-60 dB below the supply line, so a network that sees
the z-scored waveform sees the sinusoid and the load (docs/results.md, "Motor current").  Removing the
fitted supply line leaves them on top:

:func:`fundamental_residual` fits, per window, the supply line at the window's own electrical frequency (the
highest peak of its spectrum, :func:`rvdiag.spectral.peak_frequency`, refined by Grandke's interpolation) by
linear least squares, with the inverter's dead-time lines ``5 f_e`` and ``7 f_e`` (:data:`SUPPLY_HARMONICS`), and
returns the residual.  The fit is the three-parameter sine fit of IEEE Std 1057
(known frequency: in-phase amplitude, quadrature amplitude, offset; IEEE Std 1057-2017, Annex B.1), with each of
the three an algebraic polynomial of degree ``degree`` in time (a Legendre basis over the window), so that the
load's slow amplitude modulation and the small error of the estimated frequency are fitted with the line
(``cos((w + dw) t) = cos(w t) - dw t sin(w t) + ...``: a frequency error is a slowly growing quadrature
amplitude).  A fault's sidebands ``f_e +- f1`` beat ``f1 * T`` times per window (dozens), far beyond what a
low-degree polynomial follows, so they stay in the residual.

:class:`CurrentLineFeatures` reads the reducer's lines around the supply line, each relative to it (the features of a
current monitored against its own baseline, docs/monitoring.md).

:class:`FundamentalResidual` is the transformer (windows in, residual windows of the same length out);
the CNN's ``residual`` input representation (:class:`rvdiag.models.torch_estimator.CNNClassifier`) uses the
function.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.features._base import SignalTransformer
from rvdiag.spectral import amplitude_spectrum, peak_frequency
from rvdiag.validation import finite_number

#: the lines fitted and removed by default: the supply line and the dead-time lines 5 f_e and 7 f_e that a
#: voltage-source inverter adds (docs/model.md section 10); in the simulated current of configs/mcsa.toml
#: these two are the largest lines left once the supply line is gone (20-30 mA against 1-2 mA sidebands)
SUPPLY_HARMONICS = (1, 5, 7)

#: the lowest supply frequency searched, in Hann bins of the window (clear of the DC line's main lobe)
MIN_PEAK_BINS = 3


def electrical_frequency(x: np.ndarray, min_frequency: float | None = None) -> float:
    """The supply frequency of one window in cycles per sample: the highest peak of its Hann amplitude spectrum
    at or above ``min_frequency`` (default :data:`MIN_PEAK_BINS` bins), refined (Grandke 1983).

    The same line as :func:`rvdiag.motor.lines.output_speed_from_current` reads for a record's speed, but refined
    between bins (the residual fits the line's frequency) where that one keeps the peak bin, and per window;
    the two agree within half a bin (tests/test_speed_estimates.py)."""
    x = np.asarray(x, dtype=np.float64)
    f, amp = amplitude_spectrum(x)
    low = MIN_PEAK_BINS / x.size if min_frequency is None else float(min_frequency)
    fe = peak_frequency(f, amp, low)
    if fe is None:
        raise ParameterError(f"no spectral line at or above {low:g} cycles/sample in a window of {x.size} points")
    return fe


def _legendre_basis(n: int, degree: int) -> np.ndarray:
    """(n, degree + 1) Legendre polynomials P_0..P_degree on [-1, 1] over ``n`` points (well conditioned)."""
    tau = np.linspace(-1.0, 1.0, n)
    return np.polynomial.legendre.legvander(tau, degree)


def fundamental_residual(X, *, harmonics: Sequence[int] = SUPPLY_HARMONICS, degree: int = 3,
                         min_frequency: float | None = None, return_frequency: bool = False):
    """Each window of ``X`` (n, N) minus its least-squares supply line (module docstring).

    Parameters
    ----------
    X : array-like (n, N), one window per row
    harmonics : multiples of the window's electrical frequency fitted and removed (default
        :data:`SUPPLY_HARMONICS`: the supply line and the dead-time lines; ``(1,)``: the supply line alone).
        A multiple at or above the Nyquist frequency is skipped.
    degree : degree of the polynomials in time of the offset and of each line's in-phase and quadrature
        amplitudes (0: the plain IEEE 1057 three-parameter fit)
    min_frequency : the lowest supply frequency searched, cycles/sample (default :data:`MIN_PEAK_BINS` bins)
    return_frequency : also return the electrical frequency of each window (cycles/sample)

    Returns
    -------
    residual : ndarray (n, N) float64; with ``return_frequency`` also ``fe`` : ndarray (n,)
    """
    from rvdiag.features._base import as_signal_matrix

    A = as_signal_matrix(X, 8)
    hs = tuple(int(h) for h in harmonics)
    if not hs or any(h < 1 for h in hs):
        raise ParameterError(f"harmonics must be whole numbers >= 1, got {tuple(harmonics)!r}")
    if not (isinstance(degree, (int, np.integer)) and 0 <= degree <= 8):
        raise ParameterError(f"degree must be a whole number in 0..8, got {degree!r}")
    n, N = A.shape
    if N < 3 * (1 + 2 * len(hs)) * (degree + 1):
        raise ParameterError(f"windows of {N} points are too short for a fit of {len(hs)} line(s) of degree {degree}")
    P = _legendre_basis(N, int(degree))
    t = np.arange(N, dtype=np.float64)
    out = np.empty_like(A)
    fes = np.empty(n)
    for i in range(n):
        fe = electrical_frequency(A[i], min_frequency)
        cols = [P]
        for h in hs:
            if h * fe >= 0.5:
                continue
            phase = 2.0 * np.pi * h * fe * t
            cols += [P * np.cos(phase)[:, None], P * np.sin(phase)[:, None]]
        B = np.hstack(cols)
        coef, *_ = np.linalg.lstsq(B, A[i], rcond=None)
        out[i] = A[i] - B @ coef
        fes[i] = fe
    return (out, fes) if return_frequency else out


class FundamentalResidual(SignalTransformer):
    """Windows with their fitted supply line (and offset) removed, same shape: :func:`fundamental_residual`.

    Parameters
    ----------
    harmonics, degree, min_frequency : as :func:`fundamental_residual`
    """

    _min_points = 8

    def __init__(self, harmonics: Sequence[int] = SUPPLY_HARMONICS, degree: int = 3,
                 min_frequency: float | None = None):
        self.harmonics = harmonics
        self.degree = degree
        self.min_frequency = min_frequency

    def _features(self, X):
        return fundamental_residual(X, harmonics=self.harmonics, degree=self.degree,
                                    min_frequency=self.min_frequency)

    def _feature_names(self):
        return [f"residual{k}" for k in range(self.n_features_in_)]


#: the lines of :func:`rvdiag.motor.lines.current_lines` that :class:`CurrentLineFeatures` reads by default: the
#: reducer's lines around the supply line (the sun / input shaft family ``f_e +- k f1``, the stage-1 mesh
#: ``|f_e +- f_sp|`` and the cycloid-pin mesh ``|f_e +- f_cs|``; Li, Zhao et al. 2024, Table 3), not the drive's
#: own dead-time line ``5 f_e``
REDUCER_LINES = ("fe-1f1", "fe+1f1", "fe-2f1", "fe+2f1", "fe-3f1", "fe+3f1", "fe-fsp", "fe+fsp", "fe-fcs", "fe+fcs")


class CurrentLineFeatures(SignalTransformer):
    """The reducer's lines in a phase current, each relative to the supply line: ``log10(A_line / A_fe)``.

    Per window: the supply frequency ``f_e`` is the window's highest spectral peak (:func:`electrical_frequency`,
    refined), the operating point follows from it (``f_e = p f1``, ``p`` the motor's pole pairs), and each line of
    ``lines`` is read from the window's Hann amplitude spectrum at its frequency for that point
    (:func:`rvdiag.motor.lines.current_lines`: the largest of the 5 bins around it).  A sun-gear fault raises the
    ``f_e +- k f1`` family (Li, Zhao et al. 2024, section 4 and Table 3; docs/model.md section 10).  Relative to
    the supply line, the figures do not depend on the sensor's gain; against the same joint's baseline (:class:`rvdiag.features.relative.
    BaselineReferencedFeatures`) the lines the reducer's own manufacturing errors put there cancel to first order.

    Parameters
    ----------
    fs : float
        Sampling rate of the current, Hz.
    lines : names of :func:`rvdiag.motor.lines.current_lines`' lines (default :data:`REDUCER_LINES`); a line
        outside the window's spectrum is refused when it is read.
    params : reducer parameters (str path or ReducerParams; default the built-in RV-20E): the pole pairs, the
        ratio and the tooth counts behind the lines' frequencies.
    """

    _min_points = 256

    def __init__(self, fs: float = 1000.0, lines: Sequence[str] = REDUCER_LINES, params=None):
        self.fs = fs
        self.lines = lines
        self.params = params

    def _params(self):
        from rvdiag.features.orders import _params

        return _params(self.params)

    def _check_params(self, n_points: int) -> None:
        finite_number(self.fs, "fs", 0, strict=True, noun="a number")
        from rvdiag.kinematics import characteristic_frequencies
        from rvdiag.motor.lines import line_frequencies

        known = set(line_frequencies(characteristic_frequencies(self._params(), output_speed_deg_s=1.0))) - {"fe"}
        bad = [ln for ln in self.lines if ln not in known]
        if not len(self.lines) or bad:
            raise ParameterError("lines must name lines of rvdiag.motor.lines.current_lines "
                                 f"({', '.join(sorted(known))}), got {list(self.lines)!r}")

    def _features(self, X):
        from rvdiag.motor.lines import current_lines, output_speed_from_fe

        p = self._params()
        out = np.empty((X.shape[0], len(self.lines)))
        for i, x in enumerate(X):
            fe = electrical_frequency(x) * float(self.fs)
            table = current_lines(x, float(self.fs), p, output_speed_deg_s=output_speed_from_fe(fe, p))["lines"]
            ref = table["fe"]["amplitude"]
            for j, name in enumerate(self.lines):
                a = table[name]["amplitude"]
                if a is None or not ref:
                    raise ParameterError(f"window {i}: the line {name} ({table[name]['hz']:.1f} Hz at f_e = {fe:.1f} "
                                         f"Hz) lies outside the spectrum of {self.fs:g} Hz")
                out[i, j] = np.log10(max(a, 1e-300) / ref)
        return out

    def _feature_names(self):
        return [f"log10_{name}_over_fe" for name in self.lines]


__all__ = ["CurrentLineFeatures", "FundamentalResidual", "MIN_PEAK_BINS", "REDUCER_LINES", "SUPPLY_HARMONICS",
           "electrical_frequency", "fundamental_residual"]
