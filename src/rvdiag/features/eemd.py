"""Ensemble empirical mode decomposition (EEMD), compiled with numba, and the EEMD feature transformer.

EMD (Huang et al., "The empirical mode decomposition and the Hilbert spectrum for nonlinear and
non-stationary time series analysis", Proc. R. Soc. Lond. A 454 (1998) 903-995, section 5) peels
intrinsic mode functions (IMFs) off a signal by *sifting*: subtract the mean of the upper and lower
cubic-spline envelopes through the local maxima and minima, repeat.  EEMD (Wu & Huang, "Ensemble
empirical mode decomposition: a noise-assisted data analysis method", Adv. Adapt. Data Anal. 1 (2009)
1-41, section 3) decomposes ``ensemble_size`` copies of the signal, each with added white noise of
standard deviation ``noise_width`` x std(signal), and averages the IMFs; the noise populates the whole
time-frequency plane and so suppresses mode mixing.  Wu & Huang recommend a noise amplitude of about 0.2
std and a fixed number of sifting iterations (they use 10), which is what :func:`eemd` does by default.

Implementation choices (all in :func:`_emd_into`):

- extrema: strict on the left, non-strict on the right (a plateau counts once);
- boundary: the mirror rule of Rilling, Flandrin & Goncalves ("On empirical mode decomposition and its
  algorithms", IEEE-EURASIP NSIP 2003; their ``emd.m`` ``boundary_conditions``), ``nbsym = 2`` mirrored
  extrema at each end; PyEMD's default ``extrema_detection="simple"`` follows the same rule;
- envelopes: natural cubic splines through the (mirrored) extrema, solved by the Thomas algorithm;
- sifting stops after ``n_sifts`` iterations (Wu & Huang 2009), or earlier when a component has fewer
  than three extrema (then it and the remaining IMFs are zero and it stays in the residue).

:class:`EEMDFeatures` gives, per window, the mean absolute value of each of the first six IMFs: the
features of the EEMD-MPA-KELM study (Tu et al. 2023).  The same noise realisations are used for every window (one
seeded ensemble, scaled by each window's std), so a window's features do not depend on the batch it is in.

PyEMD (package EMD-signal, ``PyEMD.EEMD``) is the reference implementation; ``tests/test_eemd.py``
compares both on a two-tone-plus-trend signal and ``bench/eemd_speed.py`` measures the speed ratio.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba as nb
import numpy as np
from joblib import effective_n_jobs

from rvdiag.errors import ParameterError
from rvdiag.features._base import SignalTransformer
from rvdiag.progress import report

_NBSYM = 2


# --------------------------------------------------------------------------- compiled kernels

@nb.njit(cache=True, nogil=True)
def _extrema(h, imax, imin):
    """Fill imax/imin with interior maxima/minima indices; return (n_max, n_min)."""
    n = h.shape[0]
    nmax = 0
    nmin = 0
    for i in range(1, n - 1):
        if h[i] > h[i - 1] and h[i] >= h[i + 1]:
            imax[nmax] = i
            nmax += 1
        elif h[i] < h[i - 1] and h[i] <= h[i + 1]:
            imin[nmin] = i
            nmin += 1
    return nmax, nmin


@nb.njit(cache=True, nogil=True)
def _mirror_left(pmax, vmax, pmin, vmin, x0, tmax, ymax, tmin, ymin):
    """Rilling's boundary rule at the boundary t = 0 (positions ascending from the boundary).

    Writes up to ``_NBSYM`` mirrored maxima into (tmax, ymax) and minima into (tmin, ymin);
    returns (count_max, count_min).
    """
    nmax = pmax.shape[0]
    nmin = pmin.shape[0]
    # Each list is (start, stop) into the extrema arrays, plus a flag "endpoint added".
    if pmax[0] < pmin[0]:
        if x0 > vmin[0]:
            a0, a1 = 1, min(nmax, _NBSYM + 1)
            b0, b1 = 0, min(nmin, _NBSYM)
            end_max, end_min = False, False
            lsym = float(pmax[0])
            sym_is_max = True
        else:
            a0, a1 = 0, min(nmax, _NBSYM)
            b0, b1 = 0, min(nmin, _NBSYM - 1)
            end_max, end_min = False, True
            lsym = 0.0
            sym_is_max = False
    else:
        if x0 < vmax[0]:
            a0, a1 = 0, min(nmax, _NBSYM)
            b0, b1 = 1, min(nmin, _NBSYM + 1)
            end_max, end_min = False, False
            lsym = float(pmin[0])
            sym_is_max = False
        else:
            a0, a1 = 0, min(nmax, _NBSYM - 1)
            b0, b1 = 0, min(nmin, _NBSYM)
            end_max, end_min = True, False
            lsym = 0.0
            sym_is_max = False
    # outermost mirrored points must lie outside the signal, else mirror about the end point
    outer_max = 2 * lsym - (pmax[a1 - 1] if a1 > a0 else (0.0 if end_max else -1.0))
    outer_min = 2 * lsym - (pmin[b1 - 1] if b1 > b0 else (0.0 if end_min else -1.0))
    if lsym > 0 and (outer_max > 0 or outer_min > 0):
        if sym_is_max:
            a0, a1 = 0, min(nmax, _NBSYM)
            end_max = False
        else:
            b0, b1 = 0, min(nmin, _NBSYM)
            end_min = False
        lsym = 0.0
    cm = 0
    for k in range(a0, a1):
        tmax[cm] = 2 * lsym - pmax[k]
        ymax[cm] = vmax[k]
        cm += 1
    if end_max:
        tmax[cm] = 2 * lsym
        ymax[cm] = x0
        cm += 1
    cn = 0
    for k in range(b0, b1):
        tmin[cn] = 2 * lsym - pmin[k]
        ymin[cn] = vmin[k]
        cn += 1
    if end_min:
        tmin[cn] = 2 * lsym
        ymin[cn] = x0
        cn += 1
    return cm, cn


@nb.njit(cache=True, nogil=True)
def _spline_eval(t, y, m, n, out, M, c, d):
    """Natural cubic spline through (t[:m], y[:m]) (t strictly increasing), evaluated at 0..n-1.

    ``M``, ``c``, ``d`` are work arrays of length >= m.  Outside [t_0, t_(m-1)] the end cubics extend.
    """
    if m == 2:
        for j in range(n):
            out[j] = y[0] + (y[1] - y[0]) * (j - t[0]) / (t[1] - t[0])
        return
    # Thomas algorithm for the second derivatives M_1..M_(m-2); M_0 = M_(m-1) = 0 (natural spline)
    M[0] = 0.0
    M[m - 1] = 0.0
    for i in range(1, m - 1):
        h0 = t[i] - t[i - 1]
        h1 = t[i + 1] - t[i]
        b = 2.0 * (h0 + h1)
        rhs = 6.0 * ((y[i + 1] - y[i]) / h1 - (y[i] - y[i - 1]) / h0)
        if i == 1:
            c[i] = h1 / b
            d[i] = rhs / b
        else:
            den = b - h0 * c[i - 1]
            c[i] = h1 / den
            d[i] = (rhs - h0 * d[i - 1]) / den
    M[m - 2] = d[m - 2]
    for i in range(m - 3, 0, -1):
        M[i] = d[i] - c[i] * M[i + 1]
    # piecewise evaluation, interval k covers the integer points j with t_k <= j < t_(k+1)
    j = 0
    for k in range(m - 1):
        h = t[k + 1] - t[k]
        bk = (y[k + 1] - y[k]) / h - h * (2.0 * M[k] + M[k + 1]) / 6.0
        ck = 0.5 * M[k]
        dk = (M[k + 1] - M[k]) / (6.0 * h)
        ak = y[k]
        tk = t[k]
        if k == m - 2:
            stop = n
        else:
            stop = min(n, int(np.floor(t[k + 1])) + 1)
            if float(stop - 1) == t[k + 1]:
                stop -= 1
        while j < stop:
            u = j - tk
            out[j] = ak + u * (bk + u * (ck + u * dk))
            j += 1


@nb.njit(cache=True, nogil=True)
def _envelope(h, idx, cnt, lt, ly, lc, rt, ry, rc, n, out, t, y, M, c, d):
    """Spline through left-mirrored, interior and right-mirrored extrema (sorted, deduplicated)."""
    m = 0
    for k in range(lc - 1, -1, -1):  # left mirrored points, farthest first
        t[m] = lt[k]
        y[m] = ly[k]
        m += 1
    for k in range(cnt):
        t[m] = idx[k]
        y[m] = h[idx[k]]
        m += 1
    for k in range(rc):
        t[m] = rt[k]
        y[m] = ry[k]
        m += 1
    # insertion sort: the sequence is sorted except possibly near its ends, so this is O(m)
    for i in range(1, m):
        ti = t[i]
        yi = y[i]
        j = i - 1
        while j >= 0 and t[j] > ti:
            t[j + 1] = t[j]
            y[j + 1] = y[j]
            j -= 1
        t[j + 1] = ti
        y[j + 1] = yi
    q = 0
    for k in range(m):
        if q == 0 or t[k] > t[q - 1]:
            t[q] = t[k]
            y[q] = y[k]
            q += 1
    _spline_eval(t, y, q, n, out, M, c, d)


@nb.njit(cache=True, nogil=True)
def _sift_once(h, imax, imin, upper, lower, t, y, M, c, d):
    """One sifting step in place; returns False when h has too few extrema to be sifted."""
    n = h.shape[0]
    nmax, nmin = _extrema(h, imax, imin)
    if nmax + nmin < 3 or nmax < 1 or nmin < 1:
        return False
    tmaxL = np.empty(_NBSYM + 1)
    ymaxL = np.empty(_NBSYM + 1)
    tminL = np.empty(_NBSYM + 1)
    yminL = np.empty(_NBSYM + 1)
    tmaxR = np.empty(_NBSYM + 1)
    ymaxR = np.empty(_NBSYM + 1)
    tminR = np.empty(_NBSYM + 1)
    yminR = np.empty(_NBSYM + 1)
    k = min(nmax, _NBSYM + 1)
    j = min(nmin, _NBSYM + 1)
    # left boundary
    pmax = np.empty(k)
    vmax = np.empty(k)
    pmin = np.empty(j)
    vmin = np.empty(j)
    for q in range(k):
        pmax[q] = imax[q]
        vmax[q] = h[imax[q]]
    for q in range(j):
        pmin[q] = imin[q]
        vmin[q] = h[imin[q]]
    lcM, lcm = _mirror_left(pmax, vmax, pmin, vmin, h[0], tmaxL, ymaxL, tminL, yminL)
    # right boundary: same rule in reversed coordinates s = (n - 1) - t
    for q in range(k):
        pmax[q] = (n - 1) - imax[nmax - 1 - q]
        vmax[q] = h[imax[nmax - 1 - q]]
    for q in range(j):
        pmin[q] = (n - 1) - imin[nmin - 1 - q]
        vmin[q] = h[imin[nmin - 1 - q]]
    rcM, rcm = _mirror_left(pmax, vmax, pmin, vmin, h[n - 1], tmaxR, ymaxR, tminR, yminR)
    for q in range(rcM):
        tmaxR[q] = (n - 1) - tmaxR[q]
    for q in range(rcm):
        tminR[q] = (n - 1) - tminR[q]
    _envelope(h, imax, nmax, tmaxL, ymaxL, lcM, tmaxR, ymaxR, rcM, n, upper, t, y, M, c, d)
    _envelope(h, imin, nmin, tminL, yminL, lcm, tminR, yminR, rcm, n, lower, t, y, M, c, d)
    for i in range(n):
        h[i] -= 0.5 * (upper[i] + lower[i])
    return True


@nb.njit(cache=True, nogil=True)
def _emd_into(x, n_imfs, n_sifts, imfs):
    """EMD of x; adds the first n_imfs IMFs into imfs (shape (n_imfs, n)); returns how many exist."""
    n = x.shape[0]
    r = x.copy()
    h = np.empty(n)
    imax = np.empty(n, dtype=np.int64)
    imin = np.empty(n, dtype=np.int64)
    upper = np.empty(n)
    lower = np.empty(n)
    w = n + 2 * _NBSYM + 4
    t = np.empty(w)
    y = np.empty(w)
    M = np.empty(w)
    c = np.empty(w)
    d = np.empty(w)
    for k in range(n_imfs):
        for i in range(n):
            h[i] = r[i]
        ok = True
        for s in range(n_sifts):
            if not _sift_once(h, imax, imin, upper, lower, t, y, M, c, d):
                ok = s > 0
                break
        if not ok:
            return k
        for i in range(n):
            imfs[k, i] += h[i]
            r[i] -= h[i]
    return n_imfs


@nb.njit(cache=True, nogil=True)
def _eemd_core(x, noise, n_imfs, n_sifts):
    """Mean IMFs of x + noise[e] over the ensemble e (noise already scaled)."""
    n_ens, n = noise.shape
    acc = np.zeros((n_imfs, n))
    y = np.empty(n)
    for e in range(n_ens):
        for i in range(n):
            y[i] = x[i] + noise[e, i]
        _emd_into(y, n_imfs, n_sifts, acc)
    for k in range(n_imfs):
        for i in range(n):
            acc[k, i] /= n_ens
    return acc


# --------------------------------------------------------------------------- Python API

def _check(ensemble_size, noise_width, n_imfs, n_sifts):
    if not (isinstance(ensemble_size, (int, np.integer)) and ensemble_size >= 1):
        raise ParameterError(f"ensemble_size must be a positive integer, got {ensemble_size!r}")
    if not (np.isfinite(noise_width) and noise_width >= 0):
        raise ParameterError(f"noise_width must be >= 0 (in units of the signal std), got {noise_width!r}")
    if not (isinstance(n_imfs, (int, np.integer)) and n_imfs >= 1):
        raise ParameterError(f"n_imfs must be a positive integer, got {n_imfs!r}")
    if not (isinstance(n_sifts, (int, np.integer)) and n_sifts >= 1):
        raise ParameterError(f"n_sifts must be a positive integer, got {n_sifts!r}")


def unit_noise(n_points: int, ensemble_size: int = 100, seed: int | None = 0) -> np.ndarray:
    """Standard-normal noise of shape (ensemble_size, n_points) from ``numpy.random.default_rng(seed)``."""
    return np.random.default_rng(seed).standard_normal((ensemble_size, n_points))


def emd(x, n_imfs: int = 6, n_sifts: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Plain EMD (Huang et al. 1998) of a 1-D signal: (imfs (n_imfs, n), residue (n,)).

    IMFs past the last one that exists are zero; ``x == imfs.sum(0) + residue`` exactly.
    """
    _check(1, 0.0, n_imfs, n_sifts)
    x = np.ascontiguousarray(x, dtype=np.float64)
    if x.ndim != 1 or x.size < 4 or not np.all(np.isfinite(x)):
        raise ParameterError("emd needs a finite 1-D signal of at least 4 points")
    imfs = np.zeros((n_imfs, x.size))
    _emd_into(x, n_imfs, n_sifts, imfs)
    return imfs, x - imfs.sum(axis=0)


def eemd(x, n_imfs: int = 6, ensemble_size: int = 100, noise_width: float = 0.2, n_sifts: int = 10,
         seed: int | None = 0, noise: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """EEMD (Wu & Huang 2009) of a 1-D signal.

    Parameters
    ----------
    x : array-like, shape (n,)
    n_imfs : int
        IMFs kept (the rest of the signal is in the residue).
    ensemble_size : int
        Number of noisy copies averaged.
    noise_width : float
        Noise standard deviation relative to std(x) (Wu & Huang suggest 0.2).
    n_sifts : int
        Sifting iterations per IMF (fixed, Wu & Huang 2009).
    seed : int or None
        Seed of the noise (``numpy.random.default_rng``).
    noise : array (ensemble_size, n) or None
        Unit noise to use instead of drawing it (it is scaled by noise_width * std(x)).

    Returns
    -------
    imfs : ndarray (n_imfs, n)
        Ensemble-mean IMFs, highest frequency first.
    residue : ndarray (n,)
        ``x - imfs.sum(0)``.
    """
    _check(ensemble_size, noise_width, n_imfs, n_sifts)
    x = np.ascontiguousarray(x, dtype=np.float64)
    if x.ndim != 1 or x.size < 4 or not np.all(np.isfinite(x)):
        raise ParameterError("eemd needs a finite 1-D signal of at least 4 points")
    if noise is None:
        noise = unit_noise(x.size, ensemble_size, seed)
    imfs = _eemd_core(x, np.ascontiguousarray(noise * (noise_width * x.std())), n_imfs, n_sifts)
    return imfs, x - imfs.sum(axis=0)


def _reported(i: int, n: int, row):
    """``row``, after telling :mod:`rvdiag.progress` that window ``i`` of ``n`` is done."""
    report("EEMD features", i + 1, n)
    return row


class EEMDFeatures(SignalTransformer):
    """scikit-learn transformer: mean ``|IMF|`` of the first ``n_imfs`` EEMD IMFs of each window.

    These are the features of the EEMD-MPA-KELM study of Tu et al. 2023 (first six IMFs, mean absolute value of each).

    Parameters
    ----------
    n_imfs : int
        IMFs used (6 in the paper).
    ensemble_size : int
        EEMD ensemble size.
    noise_width : float
        Added noise std relative to the window std.
    n_sifts : int
        Sifting iterations per IMF.
    random_state : int
        Seed of the noise ensemble (shared by all windows).
    relative : bool
        Divide by the window's mean ``|x|`` (features then describe how the amplitude is shared between the
        scales, independent of the signal level).
    n_jobs : int or None
        Threads over windows (the compiled kernel releases the GIL); scikit-learn's convention: None or 1 is
        one thread, -1 all CPUs, -2 all but one...  The features do not depend on it.
    """

    _min_points = 8

    def __init__(self, n_imfs: int = 6, ensemble_size: int = 100, noise_width: float = 0.2,
                 n_sifts: int = 10, random_state: int = 0, relative: bool = False, n_jobs: int | None = 1):
        self.n_imfs = n_imfs
        self.ensemble_size = ensemble_size
        self.noise_width = noise_width
        self.n_sifts = n_sifts
        self.random_state = random_state
        self.relative = relative
        self.n_jobs = n_jobs

    def _check_params(self, n_points):
        _check(self.ensemble_size, self.noise_width, self.n_imfs, self.n_sifts)
        ok = self.n_jobs is None or (isinstance(self.n_jobs, (int, np.integer)) and not isinstance(self.n_jobs, bool)
                                     and self.n_jobs != 0)
        if not ok:
            raise ParameterError(f"n_jobs must be None or a non-zero integer (-1: all CPUs), got {self.n_jobs!r}")

    def _features(self, X):
        self._check_params(X.shape[1])
        unit = unit_noise(X.shape[1], self.ensemble_size, self.random_state)
        n_imfs, n_sifts, width = int(self.n_imfs), int(self.n_sifts), float(self.noise_width)

        def one(x):
            imfs = _eemd_core(x, np.ascontiguousarray(unit * (width * x.std())), n_imfs, n_sifts)
            return np.mean(np.abs(imfs), axis=1)

        n_jobs = min(effective_n_jobs(self.n_jobs), len(X))
        if n_jobs <= 1:
            F = np.array([_reported(i, len(X), one(x)) for i, x in enumerate(X)])
        else:
            with ThreadPoolExecutor(n_jobs) as ex:
                F = np.array([_reported(i, len(X), f) for i, f in enumerate(ex.map(one, X))])
        if self.relative:
            m = np.mean(np.abs(X), axis=1, keepdims=True)
            F = np.divide(F, m, out=np.zeros_like(F), where=m > 0)
        return F

    def _feature_names(self):
        return [f"eemd_imf{k + 1}_mean_abs" for k in range(self.n_imfs)]
