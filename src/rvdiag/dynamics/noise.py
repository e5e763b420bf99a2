"""Additive Gaussian noise at a stated signal-to-noise ratio: white, or coloured (power ~ 1 / f^beta).

SNR in dB is ``10 log10(P_signal / P_noise)`` with ``P`` the mean square (power) of each channel; the
noise of each channel is drawn from ``N(0, P_signal 10^(-SNR/10))`` by a seeded
:class:`numpy.random.Generator`, so a seed repeats the noise exactly.  :func:`add_noise_power` adds noise of a
stated absolute mean square instead (a sensor's fixed noise floor, the same whatever the signal):
:func:`add_awgn` and :func:`add_coloured_noise` are it with the power taken from the signal itself.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.validation import finite_number


def add_awgn(signal: np.ndarray, snr_db: float, rng: np.random.Generator | int | None = 0) -> np.ndarray:
    """Return ``signal`` plus white Gaussian noise at ``snr_db`` per channel (last axis = time).

    >>> x = np.sin(np.linspace(0, 200 * np.pi, 100000))
    >>> y = add_awgn(x, 10.0, np.random.default_rng(1))
    >>> round(10 * np.log10(np.mean(x**2) / np.mean((y - x)**2)), 1)
    10.0
    """
    finite_number(snr_db, "SNR", noun="a finite number of dB")
    x = np.asarray(signal, dtype=float)
    if x.size == 0:
        raise ParameterError("cannot add noise to an empty signal")
    return _add_white(x, snr_power(x, snr_db), rng)


def snr_power(signal: np.ndarray, snr_db: float) -> np.ndarray:
    """The noise mean square that puts each channel of ``signal`` at ``snr_db``: ``mean(x^2) 10^(-SNR/10)``
    (kept dims, last axis = time)."""
    x = np.asarray(signal, dtype=float)
    return np.mean(x**2, axis=-1, keepdims=True) * 10.0 ** (-snr_db / 10.0)


def _add_white(x: np.ndarray, noise_power: np.ndarray | float,
               rng: np.random.Generator | int | None) -> np.ndarray:
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    return x + np.sqrt(noise_power) * gen.standard_normal(x.shape)


def add_noise_power(signal: np.ndarray, noise_power: float, exponent: float = 0.0,
                    rng: np.random.Generator | int | None = 0) -> np.ndarray:
    """Return ``signal`` plus Gaussian noise of mean square ``noise_power`` (in the signal's units squared), white
    (``exponent`` 0) or with its PSD falling as ``1 / f^exponent`` (shaped as :func:`add_coloured_noise` shapes it,
    Kasdin 1995): the noise of a sensor whose floor does not depend on what it measures.  The same ``rng`` draws as
    :func:`add_coloured_noise`, so a signal at the same noise power gets the same noise.

    >>> y = add_noise_power(np.zeros(100000), 4.0, 1.0, np.random.default_rng(1))
    >>> round(float(np.mean(y**2)), 6)
    4.0
    """
    finite_number(noise_power, "noise power", 0)
    return _add_shaped(np.asarray(signal, dtype=float), float(noise_power), exponent, rng)


def _add_shaped(x: np.ndarray, noise_power: Any, exponent: float,
                rng: np.random.Generator | int | None) -> np.ndarray:
    """``x`` plus noise of mean square ``noise_power`` (a number, or one per channel with kept dims)."""
    if not isinstance(exponent, (int, float)) or isinstance(exponent, bool) or not 0.0 <= exponent <= 3.0:
        raise ParameterError(f"noise colour exponent must lie in [0, 3], got {exponent!r}")
    if x.size == 0:
        raise ParameterError("cannot add noise to an empty signal")
    if exponent == 0.0:
        return _add_white(x, noise_power, rng)
    if x.shape[-1] < 2:
        raise ParameterError("coloured noise needs at least 2 samples")
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    white = gen.standard_normal(x.shape)
    spec = np.fft.rfft(white, axis=-1)
    f = np.arange(spec.shape[-1], dtype=float)
    f[0] = 1.0
    shape = (f / f[-1]) ** (-0.5 * exponent)
    shape[0] = 0.0
    noise = np.fft.irfft(spec * shape, n=x.shape[-1], axis=-1)
    noise *= np.sqrt(noise_power / np.mean(noise**2, axis=-1, keepdims=True))
    return x + noise


def add_coloured_noise(signal: np.ndarray, snr_db: float, exponent: float,
                       rng: np.random.Generator | int | None = 0) -> np.ndarray:
    """Return ``signal`` plus Gaussian noise whose power spectral density falls as ``1 / f^exponent``, at
    ``snr_db`` per channel (last axis = time): 0 is white (the same draws as :func:`add_awgn`), 1 pink,
    2 brown.  The white draws are shaped in the frequency domain (amplitude ``f^(-exponent / 2)`` relative to
    Nyquist; the DC bin is set to zero) and the result scaled to the stated SNR (Kasdin 1995, Proc. IEEE 83(5),
    "Discrete simulation of colored noise and stochastic processes and 1/f^alpha power law noise generation").

    >>> x = np.sin(np.linspace(0, 200 * np.pi, 100000))
    >>> y = add_coloured_noise(x, 10.0, 1.0, np.random.default_rng(1))
    >>> round(10 * np.log10(np.mean(x**2) / np.mean((y - x)**2)), 1)
    10.0
    """
    if not isinstance(exponent, (int, float)) or isinstance(exponent, bool) or not 0.0 <= exponent <= 3.0:
        raise ParameterError(f"noise colour exponent must lie in [0, 3], got {exponent!r}")
    if exponent == 0.0:
        return add_awgn(signal, snr_db, rng)
    finite_number(snr_db, "SNR", noun="a finite number of dB")
    x = np.asarray(signal, dtype=float)
    if x.shape[-1] < 2:
        raise ParameterError("coloured noise needs at least 2 samples")
    return _add_shaped(x, snr_power(x, snr_db), exponent, rng)
