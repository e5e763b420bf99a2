"""The generalised matched filter: a known change detected in Gaussian noise whose covariance is not white
(docs/monitoring.md, "The generalised matched filter").

A monitored record ``y`` of a reducer is compared with the mean ``mu`` of its ``n`` healthy baseline records at the
same operating point.  Between any two records of one reducer the healthy signal moves from run to run (load, speed,
temperature, damping, gain): ``y = s(theta) + noise`` with ``s(theta) ~ N(mu_0, Sigma_rr)`` approximately and white
noise of variance ``sigma^2``.  A fault adds the change ``delta``.  The two hypotheses on the difference
``x = y - mu`` are then

    H0: x ~ N(0, C),    H1: x ~ N(delta, C),    C = (1 + 1/n) (Sigma_rr + sigma^2 I),

(the baseline mean carries its own run-to-run and noise variance, ``1/n`` of a record's), and the likelihood-ratio
test is linear: the generalised matched filter ``T(x) = delta^T C^-1 x`` (Kay, *Fundamentals of Statistical Signal
Processing* vol. 2, sec. 4.5, eq. 4.16; Van Trees, *Detection, Estimation and Modulation Theory* Part I, sec. 2.6,
equal covariances).  Its deflection is ``d^2 = delta^T C^-1 delta``; ``T / d`` is ``N(0, 1)`` under H0 and
``N(d, 1)`` under H1.  A correlator that ignores ``Sigma_rr`` (``delta^T x``, the white-noise matched filter) is
dominated by a run-to-run spread many times the change; whitening projects that spread out where it does not share
the change's direction.

``Sigma_rr`` is learned from ``K`` simulated healthy draws of the record (:func:`rvdiag.evaluation.separability.
gmf_reference` simulates them; this module takes arrays and never simulates).  In ``N`` ~ 5e4 points ``K`` draws span
at most ``K - 1`` directions, so the covariance is the sample covariance of the draws shrunk towards a multiple of
the identity (Ledoit & Wolf 2004, J. Multivariate Anal. 88, eq. 14: ``(1 - s) S + s tr(S)/N I``, with the
intensity ``s`` of :func:`sklearn.covariance.ledoit_wolf_shrinkage`, or a fixed ``s``), plus ``sigma^2 I``.  It is
never formed: ``C^-1 delta`` comes from the Woodbury identity in the span of the draws (Golub & Van Loan, *Matrix
Computations*, 4th ed., sec. 2.1.4).

Records are compared on one angle axis: :func:`on_angle_axis` stretches a record made at ``ratio`` times the nominal
speed onto the nominal time axis, ``x(n / ratio)``.  A robot repeating one motion starts each record at the same joint
angle (its encoder gives it), so no lag is searched.
"""

from __future__ import annotations

import math

import numpy as np
from sklearn.base import BaseEstimator

from rvdiag.errors import ParameterError
from rvdiag.validation import positive


def on_angle_axis(x, ratio: float, n_out: int) -> np.ndarray:
    """The record ``x``, made at ``ratio`` times the nominal speed, on the nominal axis: ``x(n / ratio)`` for
    ``n = 0 .. n_out - 1`` (Keys cubic interpolation, :func:`rvdiag.features.orders.cubic_interpolate`).

    Raises :class:`ParameterError` when the stretched axis reaches past the record's end (shorten ``n_out``)."""
    from rvdiag.features.orders import cubic_interpolate

    x = np.asarray(x, dtype=float).ravel()
    ratio = float(ratio)
    if not math.isfinite(ratio) or ratio <= 0:
        raise ParameterError(f"the speed ratio must be a positive number, got {ratio!r}")
    n_out = int(n_out)
    u = np.arange(n_out, dtype=float) / ratio
    if n_out < 1 or u[-1] > x.size - 3:
        raise ParameterError(f"{n_out} points at speed ratio {ratio:.4f} reach past the record of {x.size} points; "
                             f"take at most {int((x.size - 3) * ratio)}")
    return cubic_interpolate(x, u)


def gmf_weights(delta, Z, noise_var: float) -> np.ndarray:
    """``(Z^T Z + noise_var I)^-1 delta`` for ``Z`` (r, n), by the Woodbury identity:
    ``(delta - Z^T (noise_var I_r + Z Z^T)^-1 Z delta) / noise_var``."""
    delta = np.asarray(delta, dtype=float)
    Z = np.asarray(Z, dtype=float).reshape(-1, delta.size)
    positive(noise_var, "the noise variance")
    zd = Z @ delta
    inner = np.linalg.solve(noise_var * np.eye(Z.shape[0]) + Z @ Z.T, zd) if Z.shape[0] else zd
    return (delta - Z.T @ inner) / float(noise_var)


class GeneralisedMatchedFilter(BaseEstimator):
    """The generalised matched filter of a simulated change against a reducer's own baseline (module docstring).

    Parameters
    ----------
    template : array (n,)
        ``delta``, the simulated change of the fault on the angle axis (e.g. cracked minus healthy, noise-free).
    draws : array (K, n)
        Simulated healthy records with run-to-run variation on the same axis; their sample covariance about their
        mean is ``Sigma_rr``.  ``K >= 2``.
    noise_var : float
        ``sigma^2``, the variance of the white noise floor per point.
    n_baseline : int
        Records averaged into the baseline mean (``C`` is scaled by ``1 + 1/n_baseline``).
    shrinkage : float in [0, 1] or ``"ledoit-wolf"``
        Shrinkage of ``Sigma_rr`` towards ``tr(Sigma_rr)/n I``; the default estimates it (Ledoit & Wolf 2004).

    After :meth:`fit`: ``weights_`` (``C^-1 delta``), ``deflection_`` (``d``), ``shrinkage_`` (the intensity used).
    :meth:`score` gives ``T / d``, ``N(0, 1)`` for a healthy record if the Gaussian model holds; the alarm's threshold
    is best calibrated on healthy records (:meth:`calibrate`).
    """

    def __init__(self, template=None, draws=None, noise_var: float = 1.0, n_baseline: int = 3,
                 shrinkage="ledoit-wolf"):
        self.template = template
        self.draws = draws
        self.noise_var = noise_var
        self.n_baseline = n_baseline
        self.shrinkage = shrinkage

    def fit(self, X=None, y=None) -> "GeneralisedMatchedFilter":
        delta = np.asarray(self.template, dtype=float).ravel()
        H = np.asarray(self.draws, dtype=float)
        if H.ndim != 2 or H.shape[1] != delta.size or H.shape[0] < 2:
            raise ParameterError(f"need at least 2 draws of {delta.size} points, got an array {H.shape}")
        if not (np.all(np.isfinite(H)) and np.all(np.isfinite(delta))):
            raise ParameterError("the template and the draws must be finite")
        if isinstance(self.n_baseline, bool) or int(self.n_baseline) < 1:
            raise ParameterError(f"n_baseline must be a whole number >= 1, got {self.n_baseline!r}")
        D = H - H.mean(axis=0)
        if isinstance(self.shrinkage, str):
            if self.shrinkage != "ledoit-wolf":
                raise ParameterError(f"shrinkage must be a number in [0, 1] or 'ledoit-wolf', got {self.shrinkage!r}")
            s = _ledoit_wolf_intensity(D)
        else:
            s = float(self.shrinkage)
            if not 0 <= s <= 1:
                raise ParameterError(f"shrinkage must be in [0, 1], got {s}")
        K, n = D.shape
        sample_var = float(np.sum(D**2)) / (K - 1) / n                     # tr(Sigma_rr) / n
        Z = math.sqrt((1.0 - s) / (K - 1)) * D                              # (1 - s) Sigma_rr = Z^T Z
        sigma2 = float(self.noise_var) + s * sample_var
        scale = 1.0 + 1.0 / int(self.n_baseline)
        w = gmf_weights(delta, Z, sigma2) / scale
        self.weights_ = w
        self.deflection_ = math.sqrt(max(float(delta @ w), 0.0))
        self.shrinkage_ = s
        return self

    def statistic(self, Y, baseline) -> np.ndarray:
        """``T(y) / d`` of each row of ``Y`` (m, n) against the mean of ``baseline`` (n_b, n) or a mean (n,)."""
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        mu = np.asarray(baseline, dtype=float)
        mu = mu.mean(axis=0) if mu.ndim == 2 else mu
        if Y.shape[1] != self.weights_.size or mu.shape != self.weights_.shape:
            raise ParameterError(f"records and baseline must have {self.weights_.size} points, got {Y.shape[1]} "
                                 f"and {mu.shape}")
        return (Y - mu) @ self.weights_ / max(self.deflection_, 1e-300)

    score = statistic

    @staticmethod
    def calibrate(healthy_scores, alpha: float = 0.01) -> float:
        """The split-conformal threshold at false-alarm rate ``alpha`` of held-out healthy scores: the
        ``ceil((m + 1)(1 - alpha))``-th smallest of ``m`` (Vovk et al. 2005; inf when ``m < 1/alpha - 1``)."""
        h = np.sort(np.asarray(healthy_scores, dtype=float).ravel())
        k = math.ceil((h.size + 1) * (1.0 - float(alpha)))
        return float(h[k - 1]) if 1 <= k <= h.size else math.inf


def _ledoit_wolf_intensity(D: np.ndarray) -> float:
    """Ledoit–Wolf shrinkage intensity of centred rows ``D`` (K, n), from the K x K Gram matrix (the same formula as
    :func:`sklearn.covariance.ledoit_wolf_shrinkage`, which forms n x n blocks: too slow at n ~ 5e4)."""
    K, n = D.shape
    G = D @ D.T                                              # K x K
    trace = float(np.trace(G)) / K                           # tr(S), S = D^T D / K
    mu = trace / n
    delta_ = float(np.sum(G**2)) / K**2                      # ||S||_F^2 (= ||D D^T||_F^2 / K^2)
    beta_ = float(np.sum(np.diag(G) ** 2))                   # sum_k ||d_k||^4
    beta = (beta_ / K - delta_) / (n * K)
    delta = (delta_ - 2.0 * mu * trace + n * mu**2) / n      # ||S - mu I||_F^2 / n
    beta = min(beta, delta)
    return 0.0 if beta == 0 else float(beta / delta)


__all__ = ["GeneralisedMatchedFilter", "gmf_weights", "on_angle_axis"]
