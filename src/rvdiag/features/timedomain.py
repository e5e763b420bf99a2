"""Ten time-domain statistics of a vibration or current window.

The set is the one of the motor-current study (Li, Zhao et al. 2024, time-domain features fed to an
SVM): peak-to-peak, mean, variance, RMS, square-root amplitude, kurtosis, pulse (impulse) factor, margin
(clearance) factor, peak (crest) factor and waveform (shape) factor.  The definitions below are the
standard ones of the condition-monitoring literature, e.g. Lei, He & Zi, "Application of an intelligent
classification method to mechanical fault diagnosis", Expert Syst. Appl. 36 (2009) 9941-9948, Table 1
(features p1..p11), and Samanta & Al-Balushi, Mech. Syst. Signal Process. 17 (2003) 317-328.

With x_1..x_N one window, mu its mean, sigma^2 its (population) variance:

====================  =======================================  =====================
name                  formula                                   pure sine, amplitude A
====================  =======================================  =====================
peak_to_peak          max x - min x                             2A
mean                  mu = (1/N) sum x                          0
variance              sigma^2 = (1/N) sum (x - mu)^2            A^2/2
rms                   x_rms = sqrt((1/N) sum x^2)               A/sqrt(2)
sqrt_amplitude        x_r = ((1/N) sum sqrt|x|)^2               A (Gamma(3/4)/(sqrt(pi) Gamma(5/4)))^2
kurtosis              (1/N) sum (x - mu)^4 / sigma^4            3/2 (Pearson, not excess)
pulse_factor          max|x| / ((1/N) sum |x|)                  pi/2
margin_factor         max|x| / x_r
crest_factor          max|x| / x_rms                            sqrt(2)
shape_factor          x_rms / ((1/N) sum |x|)                   pi/(2 sqrt(2))
====================  =======================================  =====================

A constant-zero window has undefined ratios; they are returned as 0 (and kurtosis as 0) so that a
pipeline does not break on a dead channel.
"""

from __future__ import annotations

import numpy as np

from rvdiag.features._base import SignalTransformer

TIME_FEATURE_NAMES = (
    "peak_to_peak", "mean", "variance", "rms", "sqrt_amplitude", "kurtosis",
    "pulse_factor", "margin_factor", "crest_factor", "shape_factor",
)


def _ratio(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    out = np.zeros_like(num)
    np.divide(num, den, out=out, where=den > 0)
    return out


def time_features(X: np.ndarray) -> np.ndarray:
    """The ten statistics of each row of ``X`` (shape (n, N)) as an (n, 10) array.

    Examples
    --------
    >>> t = np.arange(1000) / 1000
    >>> f = time_features(np.sin(2 * np.pi * 5 * t)[None, :])
    >>> [round(float(v), 3) for v in f[0, [3, 5, 8, 9]]]   # rms, kurtosis, crest, shape
    [0.707, 1.5, 1.414, 1.111]
    """
    X = np.asarray(X, dtype=np.float64)
    mu = X.mean(axis=1)
    xc = X - mu[:, None]
    var = np.mean(xc**2, axis=1)
    rms = np.sqrt(np.mean(X**2, axis=1))
    absx = np.abs(X)
    mean_abs = absx.mean(axis=1)
    peak = absx.max(axis=1)
    x_r = np.mean(np.sqrt(absx), axis=1) ** 2
    kurt = _ratio(np.mean(xc**4, axis=1), var**2)
    return np.column_stack([
        X.max(axis=1) - X.min(axis=1),
        mu,
        var,
        rms,
        x_r,
        kurt,
        _ratio(peak, mean_abs),
        _ratio(peak, x_r),
        _ratio(peak, rms),
        _ratio(rms, mean_abs),
    ])


class TimeDomainFeatures(SignalTransformer):
    """scikit-learn transformer: the ten time-domain statistics of each window.

    See the module docstring for the definitions and their sources.  Stateless: ``fit`` only checks
    the input.  Output shape (n_samples, 10), columns in the order of :data:`TIME_FEATURE_NAMES`.
    """

    def _features(self, X):
        return time_features(X)

    def _feature_names(self):
        return list(TIME_FEATURE_NAMES)
