"""Monitoring a reducer against its own healthy baseline: a health index with an alarm at a stated false-alarm
rate, the most probable state with its probability, and in words what changed (docs/monitoring.md).

The input of every method is a matrix ``D`` of baseline-referenced features, one row per monitored record (the mean
change of its windows, as ``rvdiag train``, ``evaluate`` and ``diagnose`` give it: the alarm's rate is per record,
and the windows of one record, sharing its run-to-run variation, are not exchangeable records): what
changed since the same reducer's baseline at the nearest operating point
(:class:`rvdiag.features.relative.BaselineReferencedFeatures`; pairing by
:func:`rvdiag.monitoring.pairing.match_baseline`).  :meth:`BaselineMonitor.fit` takes the rows of a paired library,
healthy pairs (label ``healthy``) and faulty ones.

Health index
------------
The squared Mahalanobis distance of the standardised row from the healthy pairs, with a shrunk covariance
(Ledoit & Wolf, "A well-conditioned estimator for large-dimensional covariance matrices", J. Multivar. Anal. 88
(2004) 365-411; :class:`sklearn.covariance.LedoitWolf`, as scikit-learn's novelty detector
:class:`~sklearn.covariance.EllipticEnvelope` uses the robust one: ``detector="elliptic-envelope"``), divided by
the alarm threshold, so the alarm is ``index > 1``.  Its threshold is conformal, calibrated on healthy records that
the detector scoring them never saw, in one of two ways (``calibration``):

- ``"cv+"`` (default): K-fold CV+ (Barber, Candes, Ramdas & Tibshirani, "Predictive inference with the
  jackknife+", Ann. Statist. 49 (2021) 486-507, Sec. 3 and Theorem 4).  The healthy groups (the reducers, when
  ``groups`` are given) are cut into ``calibration_folds`` folds (leave-one-group-out with fewer groups); the
  detector ``d_k`` of fold k is fitted on the healthy rows of the other folds and scores fold k's rows: ``R_i``.
  Every healthy row calibrates (n of them, from every training reducer).  A new record x raises the alarm when
  ``#{i : d_k(i)(x) > R_i} >= ceil((1 - alpha)(n + 1))``, i.e. when its CV+ p-value
  ``(1 + #{i : R_i >= d_k(i)(x)}) / (n + 1)`` is <= alpha; the health index is the ``(n - m + 1)``-th smallest of
  ``d_k(i)(x) / R_i`` (m = ceil((1 - alpha)(n + 1))), which is ``d(x) / threshold`` when every fold is the same
  detector (the split rule below).  The detector that :meth:`explain` and the classifier use is fitted on every
  healthy row.  Guarantee (Theorem 4, for K folds of n/K rows each): for a new record exchangeable with the n
  calibration rows, P(alarm) <= 2 alpha + min(2(1 - 1/K)/(n/K + 1), (1 - K/n)/(K + 1)) <= 2 alpha + sqrt(2/n):
  twice the stated rate in the worst case, not alpha.  The paper shows it near alpha when the fit is stable (a
  covariance of many rows is); tests/test_monitoring.py measures it over 200 seeds.  Folds of whole reducers
  differ in size by up to one reducer's records, which the theorem's equal folds do not cover exactly.
- ``"split"``: split-conformal (Vovk, Gammerman & Shafer, *Algorithmic Learning in a Random World*, 2005; Lei,
  G'Sell, Rinaldo, Tibshirani & Wasserman, "Distribution-free predictive inference for regression", JASA 113
  (2018) 1094-1111, Eq. 2 and Theorem 2.2): a share ``calibration_fraction`` of the healthy groups calibrates, the
  rest fits the detector; the threshold is the ceil((n + 1)(1 - alpha))-th smallest of the n calibration scores.
  For a new record exchangeable with them, alpha - 1/(n + 1) <= P(alarm) <= alpha.

Either needs n >= ceil(1/alpha) - 1 calibration rows (99 for 1 %); with fewer the threshold is infinite and no alarm
is raised.  Both guarantees are per record and assume the records exchangeable.  Records of one reducer are not
exchangeable with another's (each reducer has its own specimen, path and floor), so on new reducers the rate holds
only as well as the training reducers represent them: the exchangeable units are reducers
(docs/monitoring.md, "Measured with the shipped configs").

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
from rvdiag.models.conformal import conformal_rank, conformal_threshold

DETECTORS = ("ledoit-wolf", "elliptic-envelope")
CALIBRATIONS = ("cv+", "split")


class BaselineMonitor(ClassifierMixin, BaseEstimator):
    """Health index, alarm and state of baseline-referenced feature rows (module docstring).

    Parameters
    ----------
    alpha : float
        False-alarm rate per record of the alarm (default 1 %).
    healthy : str
        The healthy label (a library's ``T1``).
    calibration : {"cv+", "split"}
        How the threshold is calibrated (module docstring): K-fold CV+ over the healthy groups, every healthy row
        calibrating (default), or a split of the groups into a fitting and a calibration part.
    calibration_folds : int
        K of ``"cv+"`` (default 5; leave-one-group-out when there are fewer groups).
    calibration_fraction : float
        ``"split"``: share of the healthy pairs (of their groups, when given) that calibrate the threshold.
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
        Seed of the calibration split or folds and of the SVC's probability calibration.

    Attributes
    ----------
    classes_, mean_, scale_ (the healthy pairs' per-feature mean and spread), detector_, threshold_ (the conformal
    quantile of the calibration scores), calibration_scores_, n_calibration_, n_calibration_groups_ (the groups
    they come from), classifier_, n_features_in_; with ``"cv+"`` also fold_means_, fold_scales_, fold_detectors_
    (the detector of each fold) and calibration_fold_ (the fold of each calibration score).
    """

    def __init__(self, alpha: float = 0.01, healthy: str = "T1", calibration: str = "cv+",
                 calibration_folds: int = 5, calibration_fraction: float = 0.5,
                 detector: str = "ledoit-wolf", C: float = 10.0, gamma: str | float = "scale",
                 feature_names=None, features=None, random_state: int = 0):
        self.alpha = alpha
        self.healthy = healthy
        self.calibration = calibration
        self.calibration_folds = calibration_folds
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
    #: parameters added since monitors were first saved, with the value that reproduces such a monitor: it was
    #: calibrated by the split (its threshold, scores and detector are the split's)
    _SAVED_BEFORE = {"calibration": "split", "calibration_folds": 5}

    def __setstate__(self, state):
        # a monitor saved (pickled or by skops) before a parameter existed loads with the value it was fitted with
        super().__setstate__({**self._SAVED_BEFORE, **state})

    def _check(self, D, y=None):
        D = np.asarray(D, dtype=np.float64)
        if D.ndim != 2 or D.shape[0] < 1 or not np.all(np.isfinite(D)):
            raise ParameterError(f"the baseline-referenced features must be a finite 2D array, got shape "
                                 f"{D.shape}")
        if hasattr(self, "n_features_in_") and y is None and D.shape[1] != self.n_features_in_:
            raise ParameterError(f"D has {D.shape[1]} features; the monitor was fitted on {self.n_features_in_}")
        return D

    def fit(self, D, y, groups=None):
        """Fit the detector and calibrate its threshold on the healthy rows (``calibration``: CV+ folds or a split,
        of whole groups when ``groups``, e.g. the reducer ids, are given), and the classifier on every row;
        returns ``self``."""
        from sklearn.calibration import CalibratedClassifierCV
        from sklearn.svm import SVC

        if not 0 < float(self.alpha) < 1:
            raise ParameterError(f"alpha must lie in (0, 1), got {self.alpha!r}")
        if self.calibration not in CALIBRATIONS:
            raise ParameterError(f"calibration must be one of {'|'.join(CALIBRATIONS)}, got {self.calibration!r}")
        if self.calibration == "split" and not 0 < float(self.calibration_fraction) < 1:
            raise ParameterError(f"calibration_fraction must lie in (0, 1), got {self.calibration_fraction!r}")
        if self.calibration == "cv+" and (int(self.calibration_folds) != self.calibration_folds
                                          or int(self.calibration_folds) < 2):
            raise ParameterError(f"calibration_folds must be an integer >= 2, got {self.calibration_folds!r}")
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
        self.n_features_in_ = D.shape[1]
        if self.calibration == "split":
            n_cal = min(max(1, int(round(float(self.calibration_fraction) * units.size))), units.size - 2)
            cal_units = rng.permutation(units)[:n_cal]
            cal = h[np.isin(unit_of, cal_units)]
            fit_rows = h[~np.isin(unit_of, cal_units)]
            self.mean_, self.scale_, self.detector_ = self._fit_detector(D[fit_rows])
            self.calibration_scores_ = self._distance(D[cal])
            self.n_calibration_groups_ = int(n_cal)
        else:
            k = min(int(self.calibration_folds), units.size)
            fold_of_unit = np.empty(units.size, dtype=np.int64)
            fold_of_unit[rng.permutation(units.size)] = np.arange(units.size) % k  # folds of near-equal size
            fold = fold_of_unit[np.searchsorted(units, unit_of)] if groups is not None \
                else fold_of_unit[np.arange(h.size)]
            means, scales, dets, scores = [], [], [], np.empty(h.size)
            for j in range(k):
                mu, sd, det = self._fit_detector(D[h[fold != j]])
                means.append(mu)
                scales.append(sd)
                dets.append(det)
                scores[fold == j] = self._mahalanobis(det, mu, sd, D[h[fold == j]])
            self.fold_means_, self.fold_scales_, self.fold_detectors_ = np.array(means), np.array(scales), dets
            self.calibration_fold_ = fold
            self.calibration_scores_ = scores
            self.mean_, self.scale_, self.detector_ = self._fit_detector(D[h])
            self.n_calibration_groups_ = int(units.size)
        self.n_calibration_ = int(self.calibration_scores_.size)
        self.threshold_ = conformal_threshold(self.calibration_scores_, float(self.alpha))
        self.classes_ = np.unique(y)
        self.classifier_ = None  # healthy pairs only: a detector without states
        if self.classes_.size > 1:
            few = [(c, int(np.sum(y == c))) for c in self.classes_ if np.sum(y == c) < 3]
            if few:
                raise ParameterError(f"the state {few[0][0]} has {few[0][1]} training record(s); the state "
                                     "classifier's 3-fold calibration needs >= 3 of each state: simulate more "
                                     "records or reducers")
            svc = SVC(kernel="rbf", C=self.C, gamma=self.gamma, random_state=self.random_state)
            self.classifier_ = CalibratedClassifierCV(svc, method="sigmoid", ensemble=False, cv=3).fit(
                (D - self.mean_) / self.scale_, y)
        return self

    def _fit_detector(self, F):
        """``(mean, scale, covariance estimator)`` of healthy rows ``F``: standardised, then Ledoit-Wolf or MCD."""
        from sklearn.covariance import EllipticEnvelope, LedoitWolf

        mean = F.mean(axis=0)
        sd = F.std(axis=0, ddof=1)
        scale = np.where(sd > 0, sd, 1.0)
        Z = (F - mean) / scale
        if self.detector == "ledoit-wolf":
            return mean, scale, LedoitWolf().fit(Z)
        return mean, scale, EllipticEnvelope(contamination=float(self.alpha), random_state=self.random_state).fit(Z)

    @staticmethod
    def _mahalanobis(det, mean, scale, D) -> np.ndarray:
        return np.asarray(det.mahalanobis((np.asarray(D) - mean) / scale), dtype=np.float64)

    def _cv_rows(self, D, reduce) -> np.ndarray:
        """CV+: ``reduce(ratios)`` of the ratios ``d_k(i)(x) / R_i`` of records ``x`` (rows) to every calibration
        score (columns), over blocks of rows (a block holds at most ~4 million ratios)."""
        S = np.stack([self._mahalanobis(det, mu, sd, D) for det, mu, sd in
                      zip(self.fold_detectors_, self.fold_means_, self.fold_scales_)], axis=1)
        R = np.maximum(self.calibration_scores_, np.finfo(float).tiny)
        step = max(1, 4_000_000 // max(1, R.size))
        return np.concatenate([reduce(S[a:a + step][:, self.calibration_fold_] / R)
                               for a in range(0, S.shape[0], step)]) if S.shape[0] else np.zeros(0)

    # ------------------------------------------------------------------------------------------- scoring
    def _distance(self, D) -> np.ndarray:
        return self._mahalanobis(self.detector_, self.mean_, self.scale_, D)

    def _cv(self) -> bool:
        return self.calibration == "cv+"

    def health_index(self, D) -> np.ndarray:
        """The squared Mahalanobis distance from the healthy pairs over the alarm threshold (``"split"``), or its
        CV+ form (module docstring): > 1 raises the alarm; 0 when the calibration records are too few."""
        check_is_fitted(self, "threshold_")
        D = self._check(D)
        if math.isinf(self.threshold_):
            return np.zeros(D.shape[0])
        if not self._cv():
            return self._distance(D) / self.threshold_
        n = self.calibration_scores_.size
        m = conformal_rank(n, float(self.alpha))
        return self._cv_rows(D, lambda r: np.partition(r, n - m, axis=1)[:, n - m])

    def score_samples(self, D) -> np.ndarray:
        """scikit-learn's novelty convention: minus the squared Mahalanobis distance (lower = more abnormal)."""
        check_is_fitted(self, "threshold_")
        return -self._distance(self._check(D))

    def decision_function(self, D) -> np.ndarray:
        """Threshold times (1 - health index), threshold minus distance with ``"split"``: negative for the records
        that raise the alarm (as ``EllipticEnvelope``)."""
        return self.threshold_ * (1.0 - self.health_index(D))

    def alarm(self, D) -> np.ndarray:
        """Whether each record raises the alarm (false-alarm rate ``alpha`` on healthy records)."""
        return self.health_index(D) > 1.0

    def p_value(self, D) -> np.ndarray:
        """Conformal p-value of each record being healthy: (1 + #{i : R_i >= its score}) / (n + 1), its score by the
        detector that did not see calibration row i with ``"cv+"``."""
        check_is_fitted(self, "threshold_")
        D = self._check(D)
        n = self.calibration_scores_.size
        if self._cv():
            return (1.0 + self._cv_rows(D, lambda r: (r <= 1.0).sum(axis=1))) / (n + 1.0)
        s = self._distance(D)
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
    from rvdiag.monitoring.pairing import LOAD_TOLERANCE, SPEED_TOLERANCE
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
                  "n_calibration": int(monitor.n_calibration_),
                  "n_calibration_groups": int(getattr(monitor, "n_calibration_groups_", 0)) or None,
                  "calibration": monitor.calibration,
                  "calibration_folds": len(monitor.fold_detectors_) if monitor._cv() else None,
                  "detector": monitor.detector,
                  "record_windows": None if record_windows is None else int(record_windows)},
        "preprocessing": {"features": "baseline-referenced",
                          "feature_names": [str(f) for f in feats.get_feature_names_out()]},
    }))
    from pathlib import Path

    from rvdiag.atomic import staged_directory

    with staged_directory(Path(directory)) as tmp:  # replaced whole, as every model directory
        save_classical(monitor, tmp, metadata=card)
    return Path(directory)


__all__ = ["BaselineMonitor", "CALIBRATIONS", "DETECTORS", "conformal_rank", "conformal_threshold", "save_monitor"]
