"""Monitoring a reducer against its own healthy baseline: a health index with an alarm at a stated false-alarm
rate, the most probable state with its probability, and in words what changed (docs/monitoring.md).

The input of every method is a matrix ``D`` of baseline-referenced features, one row per monitored record (the mean
change of its windows, as ``rvdiag train``, ``evaluate`` and ``diagnose`` give it: the alarm's rate is per record,
and the windows of one record, sharing its run-to-run variation, are not exchangeable records): what
changed since the same reducer's baseline at the nearest operating point
(:class:`rvdiag.features.relative.BaselineReferencedFeatures`; pairing by
:func:`rvdiag.datasets.store.match_baseline`).  :meth:`BaselineMonitor.fit` takes the rows of a paired library,
healthy pairs (label ``healthy``) and faulty ones.

Health index
------------
The squared Mahalanobis distance of the standardised row from the healthy pairs, with a shrunk covariance
(Ledoit & Wolf, "A well-conditioned estimator for large-dimensional covariance matrices", J. Multivar. Anal. 88
(2004) 365-411; :class:`sklearn.covariance.LedoitWolf`, as scikit-learn's novelty detector
:class:`~sklearn.covariance.EllipticEnvelope` uses the robust one: ``detector="elliptic-envelope"``), divided by
the alarm threshold, so the alarm is ``index > 1``.  The threshold is a split-conformal quantile (Vovk, Gammerman
& Shafer, *Algorithmic Learning in a Random World*, 2005; Lei, G'Sell, Rinaldo, Tibshirani & Wasserman,
"Distribution-free predictive inference for regression", JASA 113 (2018) 1094-1111, Eq. 2 and Theorem 2.2): the
healthy pairs are split, by reducer when ``groups`` are given, into a part that fits the detector and a
calibration part of n rows whose scores give the threshold as their ceil((n + 1)(1 - alpha))-th smallest value.
For a new healthy record exchangeable with the calibration records, P(alarm) <= alpha (and >= alpha - 1/(n + 1)).

State
-----
A support-vector classifier on the standardised rows of every state (:class:`sklearn.svm.SVC` with Platt
probabilities by ``CalibratedClassifierCV(method="sigmoid", ensemble=False)``), as the classical pipelines of
:mod:`rvdiag.models.pipelines`.

What changed
------------
Each feature's change as a z-score against the healthy pairs' spread; :meth:`BaselineMonitor.explain` names the
largest, with the change in dB for the log10 band and line powers (10 x the change of log10 power).
"""

from __future__ import annotations

import math

import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.validation import check_is_fitted

from rvdiag.errors import ParameterError

DETECTORS = ("ledoit-wolf", "elliptic-envelope")


def conformal_threshold(scores, alpha: float) -> float:
    """The split-conformal threshold of calibration ``scores`` for a false-alarm rate ``alpha``: their
    ceil((n + 1)(1 - alpha))-th smallest value (Lei et al. 2018, Eq. 2); ``inf`` when that exceeds n (too few
    calibration records for this ``alpha``: no alarm can be guaranteed below it).

    >>> conformal_threshold(np.arange(1.0, 100.0), 0.01)  # n = 99: the 99th smallest
    99.0
    """
    s = np.sort(np.asarray(scores, dtype=np.float64).ravel())
    k = math.ceil((s.size + 1) * (1.0 - float(alpha)))
    return float(s[k - 1]) if 1 <= k <= s.size else math.inf


class BaselineMonitor(ClassifierMixin, BaseEstimator):
    """Health index, alarm and state of baseline-referenced feature rows (module docstring).

    Parameters
    ----------
    alpha : float
        False-alarm rate per record of the alarm (default 1 %).
    healthy : str
        The healthy label (a library's ``T1``).
    calibration_fraction : float
        Share of the healthy pairs (of their groups, when given) that calibrate the threshold.
    detector : {"ledoit-wolf", "elliptic-envelope"}
        Covariance of the healthy pairs for the Mahalanobis distance: shrunk (default; stable with few records per
        feature) or the robust minimum covariance determinant of :class:`sklearn.covariance.EllipticEnvelope`.
    C, gamma : the SVC's parameters.
    feature_names : sequence of str or None
        Names of the columns of ``D`` (for :meth:`explain`; default those of ``features`` when fitted).
    features : fitted :class:`rvdiag.features.relative.BaselineReferencedFeatures` or None
        The transformer that makes ``D`` from windows and their baselines (:meth:`paired_features`), kept with the
        model so that a saved monitor diagnoses raw records.
    random_state : int
        Seed of the calibration split and of the SVC's probability calibration.

    Attributes
    ----------
    classes_, mean_, scale_ (the healthy pairs' per-feature mean and spread), detector_, threshold_,
    n_calibration_, classifier_, n_features_in_
    """

    def __init__(self, alpha: float = 0.01, healthy: str = "T1", calibration_fraction: float = 0.5,
                 detector: str = "ledoit-wolf", C: float = 10.0, gamma: str | float = "scale",
                 feature_names=None, features=None, random_state: int = 0):
        self.alpha = alpha
        self.healthy = healthy
        self.calibration_fraction = calibration_fraction
        self.detector = detector
        self.C = C
        self.gamma = gamma
        self.feature_names = feature_names
        self.features = features
        self.random_state = random_state

    # ---------------------------------------------------------------------------------------------- input
    def input_metadata(self) -> tuple[str, ...]:
        """The metadata columns after each window's points that :meth:`paired_features` reads."""
        from rvdiag.features.combine import input_metadata

        return tuple(input_metadata(self.features)) if self.features is not None else ()

    def paired_features(self, X, baseline, groups) -> np.ndarray:
        """``D`` of windows ``X`` against their baseline rows ``baseline[groups[i]]`` (``features``'s transform)."""
        if self.features is None:
            raise ParameterError("this BaselineMonitor has no features transformer: pass the feature rows D")
        return self.features.transform(X, baseline, groups)

    def _names(self, n: int) -> list[str]:
        if self.feature_names is not None:
            return [str(f) for f in self.feature_names]
        if self.features is not None and hasattr(self.features, "features_"):
            return [str(f) for f in self.features.get_feature_names_out()]
        return [f"x{j}" for j in range(n)]

    # ----------------------------------------------------------------------------------------------- fit
    def _check(self, D, y=None):
        D = np.asarray(D, dtype=np.float64)
        if D.ndim != 2 or D.shape[0] < 1 or not np.all(np.isfinite(D)):
            raise ParameterError(f"the baseline-referenced features must be a finite 2D array, got shape "
                                 f"{D.shape}")
        if hasattr(self, "n_features_in_") and y is None and D.shape[1] != self.n_features_in_:
            raise ParameterError(f"D has {D.shape[1]} features; the monitor was fitted on {self.n_features_in_}")
        return D

    def fit(self, D, y, groups=None):
        """Fit the detector on part of the healthy rows, calibrate its threshold on the rest (whole groups when
        ``groups``, e.g. the reducer ids, are given), and the classifier on every row; returns ``self``."""
        from sklearn.calibration import CalibratedClassifierCV
        from sklearn.covariance import EllipticEnvelope, LedoitWolf
        from sklearn.svm import SVC

        if not 0 < float(self.alpha) < 1:
            raise ParameterError(f"alpha must lie in (0, 1), got {self.alpha!r}")
        if not 0 < float(self.calibration_fraction) < 1:
            raise ParameterError(f"calibration_fraction must lie in (0, 1), got {self.calibration_fraction!r}")
        if self.detector not in DETECTORS:
            raise ParameterError(f"detector must be one of {'|'.join(DETECTORS)}, got {self.detector!r}")
        D = self._check(D, y)
        y = np.asarray(y).astype(str)
        if y.shape != (D.shape[0],):
            raise ParameterError(f"y holds {y.size} labels for {D.shape[0]} rows")
        h = np.flatnonzero(y == str(self.healthy))
        rng = np.random.default_rng(self.random_state)
        if groups is None:
            units = h
            unit_of = h
        else:
            g = np.asarray(groups)
            if g.shape != (D.shape[0],):
                raise ParameterError(f"groups holds {g.size} values for {D.shape[0]} rows")
            units, unit_of = np.unique(g[h]), g[h]
        if units.size < 4:
            raise ParameterError(f"BaselineMonitor needs healthy pairs (label {self.healthy!r}) of at least 4 "
                                 f"{'groups' if groups is not None else 'records'}, got {units.size}")
        n_cal = min(max(1, int(round(float(self.calibration_fraction) * units.size))), units.size - 2)
        cal_units = rng.permutation(units)[:n_cal]
        cal = h[np.isin(unit_of, cal_units)]
        fit_rows = h[~np.isin(unit_of, cal_units)]
        self.n_features_in_ = D.shape[1]
        self.mean_ = D[fit_rows].mean(axis=0)
        sd = D[fit_rows].std(axis=0, ddof=1)
        self.scale_ = np.where(sd > 0, sd, 1.0)
        Z = (D[fit_rows] - self.mean_) / self.scale_
        if self.detector == "ledoit-wolf":
            self.detector_ = LedoitWolf().fit(Z)
        else:
            self.detector_ = EllipticEnvelope(contamination=float(self.alpha), random_state=self.random_state).fit(Z)
        self.calibration_scores_ = self._distance(D[cal])
        self.n_calibration_ = int(cal.size)
        self.threshold_ = conformal_threshold(self.calibration_scores_, float(self.alpha))
        self.classes_ = np.unique(y)
        self.classifier_ = None  # healthy pairs only: a detector without states
        if self.classes_.size > 1:
            svc = SVC(kernel="rbf", C=self.C, gamma=self.gamma, random_state=self.random_state)
            self.classifier_ = CalibratedClassifierCV(svc, method="sigmoid", ensemble=False, cv=3).fit(
                (D - self.mean_) / self.scale_, y)
        return self

    # ------------------------------------------------------------------------------------------- scoring
    def _distance(self, D) -> np.ndarray:
        return np.asarray(self.detector_.mahalanobis((np.asarray(D) - self.mean_) / self.scale_), dtype=np.float64)

    def health_index(self, D) -> np.ndarray:
        """The squared Mahalanobis distance from the healthy pairs over the alarm threshold: > 1 raises the alarm."""
        check_is_fitted(self, "threshold_")
        return self._distance(self._check(D)) / self.threshold_

    def score_samples(self, D) -> np.ndarray:
        """scikit-learn's novelty convention: minus the squared Mahalanobis distance (lower = more abnormal)."""
        check_is_fitted(self, "threshold_")
        return -self._distance(self._check(D))

    def decision_function(self, D) -> np.ndarray:
        """Threshold minus distance: negative for the records that raise the alarm (as ``EllipticEnvelope``)."""
        return self.score_samples(D) + self.threshold_

    def alarm(self, D) -> np.ndarray:
        """Whether each record raises the alarm (false-alarm rate ``alpha`` on healthy records)."""
        return self.health_index(D) > 1.0

    def p_value(self, D) -> np.ndarray:
        """Conformal p-value of each record being healthy: (1 + #calibration scores >= its score) / (n + 1)."""
        s = self._distance(self._check(D))
        c = np.sort(self.calibration_scores_)
        return (1.0 + c.size - np.searchsorted(c, s, side="left")) / (c.size + 1.0)

    def predict_proba(self, D) -> np.ndarray:
        """Probability of each state (columns ``classes_``); a monitor fitted on healthy pairs only gives 1."""
        check_is_fitted(self, "classes_")
        D = self._check(D)
        if self.classifier_ is None:
            return np.ones((D.shape[0], 1))
        return self.classifier_.predict_proba((D - self.mean_) / self.scale_)

    def predict(self, D) -> np.ndarray:
        """The most probable state of each record."""
        return self.classes_[np.argmax(self.predict_proba(D), axis=1)]

    # ------------------------------------------------------------------------------------------- words
    def explain(self, D, top: int = 3) -> list[list[str]]:
        """For each record, the ``top`` features that changed most against the healthy pairs' spread, in words:
        ``"d_order_band5 up 9.1 dB (z 6.2)"`` (log10 powers, ``d_order_band*`` and ``d_env_*``, in dB), else the
        change itself."""
        check_is_fitted(self, "mean_")
        D = self._check(D)
        names = self._names(D.shape[1])
        if len(names) != D.shape[1]:
            raise ParameterError(f"feature_names holds {len(names)} names for {D.shape[1]} features")
        Z = (D - self.mean_) / self.scale_
        out = []
        for d, z in zip(D, Z):
            words = []
            for j in np.argsort(-np.abs(z))[: int(top)]:
                way = "up" if d[j] >= 0 else "down"
                if names[j].startswith(("d_order_band", "d_env_", "d_log10_")):
                    change = f"{abs(10.0 * d[j]):.1f} dB" if not names[j].startswith("d_log10_") \
                        else f"x{10.0 ** abs(d[j]):.2g}"
                else:
                    change = f"{abs(d[j]):.3g}"
                words.append(f"{names[j]} {way} {change} (z {z[j]:+.1f})")
            out.append(words)
        return out

    def diagnose(self, D, top: int = 3) -> list[dict]:
        """Per record: ``health_index``, ``alarm``, ``p_value``, ``state`` (most probable), ``probability`` and
        ``changed`` (:meth:`explain`)."""
        idx, pv, P = self.health_index(D), self.p_value(D), self.predict_proba(D)
        words = self.explain(D, top)
        return [{"health_index": float(i), "alarm": bool(i > 1.0), "p_value": float(p),
                 "state": str(self.classes_[int(np.argmax(q))]), "probability": float(q.max()), "changed": w}
                for i, p, q, w in zip(idx, pv, P, words)]


def save_monitor(monitor: BaselineMonitor, directory, *, model: str = "baseline-monitor",
                 speed_tolerance: float | None = None, load_tolerance: float | None = None,
                 record_windows: int | None = None, **card_fields):
    """Save a fitted monitor as a classical model directory (``model.skops`` + ``card.json``,
    :func:`rvdiag.models.pipelines.save_classical`; loaded back by :func:`rvdiag.models.persistence.load_model`).

    The card says ``needs_baseline: true`` and holds the window length, the metadata columns and the matching
    tolerances a baseline must meet (``baseline``), and the alarm's ``alpha``, threshold, calibration size and
    ``record_windows`` (the windows of a calibration record, whose mean change is one row; ``alarm``); ``card_fields`` go to :func:`rvdiag.models.persistence.base_card` (``fs``, ``training_store``...).
    """
    from rvdiag.datasets.store import LOAD_TOLERANCE, SPEED_TOLERANCE
    from rvdiag.models.card import jsonable
    from rvdiag.models.persistence import base_card
    from rvdiag.models.pipelines import save_classical

    check_is_fitted(monitor, "threshold_")
    feats = monitor.features
    if feats is None or not hasattr(feats, "n_features_in_"):
        raise ParameterError("save_monitor needs a monitor with its fitted features transformer (features=...)")
    meta = list(monitor.input_metadata())
    card = base_card(monitor, model=model, features="baseline-referenced", **card_fields)
    card.update(jsonable({
        "input_length": int(feats.n_features_in_) - len(meta),
        "metadata_columns": meta,
        "needs_baseline": True,
        "baseline": {"columns": ["output_speed_deg_s", "load_Nm"],
                     "speed_tolerance": SPEED_TOLERANCE if speed_tolerance is None else float(speed_tolerance),
                     "load_tolerance": LOAD_TOLERANCE if load_tolerance is None else float(load_tolerance)},
        "alarm": {"alpha": float(monitor.alpha), "threshold": float(monitor.threshold_),
                  "n_calibration": int(monitor.n_calibration_), "detector": monitor.detector,
                  "record_windows": None if record_windows is None else int(record_windows)},
        "preprocessing": {"features": "baseline-referenced",
                          "feature_names": [str(f) for f in feats.get_feature_names_out()]},
    }))
    from pathlib import Path

    from rvdiag.atomic import staged_directory

    with staged_directory(Path(directory)) as tmp:  # replaced whole, as every model directory
        save_classical(monitor, tmp, metadata=card)
    return Path(directory)


__all__ = ["BaselineMonitor", "DETECTORS", "conformal_threshold", "save_monitor"]
