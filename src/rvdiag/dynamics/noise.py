"""Additive white Gaussian noise at a stated signal-to-noise ratio.

SNR in dB is ``10 log10(P_signal / P_noise)`` with ``P`` the mean square (power) of each channel; the
noise of each channel is drawn from ``N(0, P_signal 10^(-SNR/10))`` by a seeded
:class:`numpy.random.Generator`, so a seed repeats the noise exactly.
"""

from __future__ import annotations

import math

import numpy as np

from rvdiag.errors import ParameterError


def add_awgn(signal: np.ndarray, snr_db: float, rng: np.random.Generator | int | None = 0) -> np.ndarray:
    """Return ``signal`` plus white Gaussian noise at ``snr_db`` per channel (last axis = time).

    >>> x = np.sin(np.linspace(0, 200 * np.pi, 100000))
    >>> y = add_awgn(x, 10.0, np.random.default_rng(1))
    >>> round(10 * np.log10(np.mean(x**2) / np.mean((y - x)**2)), 1)
    10.0
    """
    if not isinstance(snr_db, (int, float)) or isinstance(snr_db, bool) or not math.isfinite(snr_db):
        raise ParameterError(f"SNR must be a finite number of dB, got {snr_db!r}")
    x = np.asarray(signal, dtype=float)
    if x.size == 0:
        raise ParameterError("cannot add noise to an empty signal")
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    power = np.mean(x**2, axis=-1, keepdims=True)
    sigma = np.sqrt(power * 10.0 ** (-snr_db / 10.0))
    return x + sigma * gen.standard_normal(x.shape)
