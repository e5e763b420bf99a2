"""The separability bound: the best accuracy ANY classifier can reach in telling two states apart at an SNR.

Method (binary detection of a known signal in white Gaussian noise; Van Trees, *Detection, Estimation and
Modulation Theory*, Part I, sec. 2.6; Kay, *Fundamentals of Statistical Signal Processing* vol. 2, sec. 4.3).
Two states ``a`` and ``b`` are simulated noise-free with identical parameters, operating point, settings and
seeds, so that they differ by the fault alone, and both records are cut into the same aligned windows of
``window`` points (non-overlapping, from the first sample).  In window ``k`` the two hypotheses are

    H_a: y = s_a + n,    H_b: y = s_b + n,    n ~ N(0, sigma_k^2 I),

with equal priors.  The detector with the smallest error probability (the likelihood-ratio test; with equal
priors and equal noise the minimum-distance, or matched-filter, detector: decide ``a`` when
``||y - s_a|| < ||y - s_b||``) errs with probability ``Q(d_k / (2 sigma_k))``, ``d_k = ||s_a - s_b||_2``, so its
accuracy is ``Phi(d_k / (2 sigma_k))``.  No classifier does better on that window; the bound reported is the
mean over windows, ``mean_k Phi(d_k / (2 sigma_k))``.

The noise follows the SNR convention of :func:`rvdiag.dynamics.noise.add_awgn` (what the library, ``rvdiag
train --snr-db`` and ``rvdiag evaluate --snr-db`` add): SNR = mean power of the sample over the noise variance,
per sample (window) and per channel.  Here ``sigma_k^2 = P_k / 10^(snr/10)`` with ``P_k`` the mean power of the
pair, ``(mean(s_a^2) + mean(s_b^2)) / 2`` over the window: one noise level for both hypotheses, as the test
needs.  ``add_awgn`` scales each sample to its own power, so the two hypotheses' noise differs by the power
ratio of the pair (1.0x for a crack, docs/model.md section 9); the bound takes their mean.

Across specimens (``params_b``: the second state simulated on another reducer, e.g. another ``[modification]
error_seed``), the same bound says how far two reducers are apart: the bound of specimen A healthy against
specimen B healthy, beside that of A healthy against A cracked, tells whether the difference between two reducers
is larger than the fault's effect (then a classifier that does not know the reducer's healthy signal meets the
crack inside the spread of healthy reducers).

It is an upper bound: the ideal detector knows both signals, their phase in the window and the noise level,
whereas a classifier trained on a library meets the state at any phase, any severity of its range and any
draw of the other parameters.  A classifier near the bound has nothing left to learn; one far below it has.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.progress import report


def aligned_windows(a: np.ndarray, b: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Cut two records of the same length into aligned, non-overlapping windows: two arrays (n_windows, window).

    The tail shorter than a window is dropped.  Raises :class:`ParameterError` when the records differ in
    length or are shorter than one window."""
    a = np.asarray(a, dtype=float).ravel()
    b = np.asarray(b, dtype=float).ravel()
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 1:
        raise ParameterError(f"the window must be a whole number of points >= 1, got {window!r}")
    if a.shape != b.shape:
        raise ParameterError(f"the two records differ in length ({a.size} and {b.size} points)")
    n = a.size // int(window)
    if n < 1:
        raise ParameterError(f"the window of {window} points is longer than the record ({a.size} points); "
                             f"lengthen the duration or shorten the window")
    return a[:n * window].reshape(n, window), b[:n * window].reshape(n, window)


def bound_from_windows(A: np.ndarray, B: np.ndarray, snr_db: Sequence[float]) -> dict:
    """The separability bound of aligned window pairs ``A[k]``, ``B[k]`` (arrays (n_windows, window)).

    Returns ``{"window", "n_windows", "snr_db", "accuracy_bound", "distance_over_rms"}``: for each level,
    ``mean_k Phi(d_k / (2 sigma_k))`` with ``d_k = ||A_k - B_k||`` and ``sigma_k^2`` the pair's mean power over
    ``10^(snr/10)`` (module docstring); ``distance_over_rms`` is the median over windows of ``d_k / ||A_k||``
    (the relative L2 difference of the two states, independent of the noise)."""
    from scipy.special import ndtr

    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    if A.ndim != 2 or A.shape != B.shape or A.shape[0] < 1:
        raise ParameterError(f"need two arrays (n_windows, window) of one shape, got {A.shape} and {B.shape}")
    levels = [float(s) for s in snr_db]
    if not levels or not all(math.isfinite(s) for s in levels):
        raise ParameterError(f"SNR levels must be finite numbers of dB, got {list(snr_db)!r}")
    d = np.linalg.norm(A - B, axis=1)
    power = 0.5 * (np.mean(A**2, axis=1) + np.mean(B**2, axis=1))
    norm_a = np.linalg.norm(A, axis=1)
    bound = []
    for s in levels:
        sigma = np.sqrt(power * 10.0 ** (-s / 10.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            arg = np.where(sigma > 0, d / (2.0 * np.where(sigma > 0, sigma, 1.0)), np.where(d > 0, np.inf, 0.0))
        bound.append(float(np.mean(ndtr(arg))))
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(norm_a > 0, d / np.where(norm_a > 0, norm_a, 1.0), np.where(d > 0, np.inf, 0.0))
    return {"window": int(A.shape[1]), "n_windows": int(A.shape[0]), "snr_db": levels, "accuracy_bound": bound,
            "distance_over_rms": float(np.median(rel))}


def separability_bound(a: np.ndarray, b: np.ndarray, window: int, snr_db: Sequence[float]) -> dict:
    """:func:`bound_from_windows` of two records cut by :func:`aligned_windows`."""
    return bound_from_windows(*aligned_windows(a, b, window), snr_db)


def simulate_pair(pair: Sequence[str], *, params=None, output_speed_deg_s: float, load_Nm: float,
                  duration_s: float, fs: float, transient_s: float, model: Mapping | None = None, channel: int = 0,
                  severities: Mapping[str, float] | None = None, seed: int = 0,
                  params_b=None) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free records of the two states of ``pair`` (``rvdiag.gears.ToothFaults.for_state`` names), one channel.

    Both come from :func:`rvdiag.dynamics.simulate` with the same parameters, operating point, settings
    (``model``: :class:`rvdiag.dynamics.ModelSettings` keywords, as a library config's ``[model]`` table) and
    seed; ``severities`` (SI, keyed as ``for_state`` takes them) go to both, each state using those of its
    faults.  ``params_b`` (default: ``params``) are the second state's parameters: two specimens, e.g. two
    ``[modification] error_seed``, so that the pair differs by the reducer (and the fault, if the states differ).
    Each simulation is reported to :mod:`rvdiag.progress` (stage ``simulating STATE``)."""
    from rvdiag.dynamics import ModelSettings, simulate
    from rvdiag.gears import ToothFaults

    settings = ModelSettings(**dict(model or {}), transient_s=float(transient_s))
    out = []
    for state, p in zip(pair, (params, params if params_b is None else params_b)):
        fault = ToothFaults.for_state(state, **dict(severities or {}))
        stage = f"simulating {fault.label or str(state).upper()}"

        def progress(done: int, total: int, stage: str = stage) -> None:
            report(stage, done, total)

        res = simulate(p, None if fault.is_healthy else fault, output_speed_deg_s=output_speed_deg_s,
                       load_Nm=load_Nm, duration_s=duration_s, fs=fs, noise_snr_db=None, seed=seed,
                       settings=settings, progress=progress)
        if not 0 <= channel < res.signal.shape[0]:
            raise ParameterError(f"channel {channel} out of range: the simulation has {res.signal.shape[0]}")
        out.append(np.asarray(res.signal[channel], dtype=float))
    return out[0], out[1]


__all__ = ["aligned_windows", "bound_from_windows", "separability_bound", "simulate_pair"]
