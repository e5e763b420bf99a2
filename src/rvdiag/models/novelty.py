"""Is a record like the ones the model was trained on?  A calibrated out-of-distribution score.

A classifier names one of its classes for anything it is given (white noise, a sine, a dead sensor).  Before a
diagnosis names a fault, ``rvdiag diagnose`` asks whether the record's windows lie where the training windows lay
in the model's own feature space (:func:`learned_features`: a CNN's last hidden layer, a classical pipeline's
standardised features).  The score of a window is its Mahalanobis distance

    d(f) = sqrt((f - mu)^T S^-1 (f - mu))

(Mahalanobis 1936) from the mean ``mu`` of the training windows' features, with ``S`` their covariance shrunk by
Ledoit & Wolf (2004, J. Multivariate Anal. 88(2), eq. 14; :class:`sklearn.covariance.LedoitWolf`), which stays
invertible when the features outnumber the windows.  This is scikit-learn's ``EllipticEnvelope`` with a
shrunk instead of a minimum-covariance-determinant estimate, which needs far more samples than dimensions.
The threshold is the ``1 - rate`` quantile of the distances of the held-out windows (the training store's test
split; the training windows themselves when the store has none, which the card says): a window of the training
distribution lies beyond it with probability about ``rate`` (:data:`DEFAULT_RATE`, 1 %).

The location and precision matrix are stored beside the model in ``novelty.safetensors`` (plain arrays, nothing
executed); the card's ``novelty`` entry holds the threshold, the rate and how they were found.  Models written
before this check have neither: they load, and ``diagnose`` says in one line that the check is unavailable.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rvdiag.errors import ModelFileError

NOVELTY_FILE = "novelty.safetensors"
#: the share of held-out windows of the training distribution that lie beyond the threshold
DEFAULT_RATE = 0.01
#: a record is not recognised when more than this share of its windows lie beyond the threshold
RECORD_SHARE = 0.5


def learned_features(estimator, X: np.ndarray) -> np.ndarray:
    """The model's internal representation of samples: CNN last hidden layer, or the standardised
    features of a classical pipeline (every step but the classifier)."""
    if hasattr(estimator, "embed"):
        return np.asarray(estimator.embed(X), dtype=np.float64)
    if hasattr(estimator, "steps") and len(estimator.steps) > 1:
        return np.asarray(estimator[:-1].transform(X), dtype=np.float64)
    return np.asarray(X, dtype=np.float64)


@dataclass
class NoveltyDetector:
    """Mahalanobis distance to the training windows' features, with its calibrated threshold (module docstring)."""

    location: np.ndarray
    precision: np.ndarray
    threshold: float
    rate: float
    calibration: str
    n_fit: int
    n_calibration: int

    def distances(self, F: np.ndarray) -> np.ndarray:
        """The Mahalanobis distance of each row of the features ``F``; ``inf`` for a row that is not finite."""
        D = np.asarray(F, dtype=np.float64) - self.location
        d2 = np.einsum("ij,jk,ik->i", D, self.precision, D)
        d = np.sqrt(np.maximum(d2, 0.0))
        d[~np.all(np.isfinite(D), axis=1)] = np.inf
        return d

    def card(self) -> dict:
        """The card's ``novelty`` entry."""
        return {"method": "Mahalanobis distance, Ledoit-Wolf covariance (sklearn.covariance.LedoitWolf)",
                "space": "the model's learned features (CNN: last hidden layer; classical: standardised features)",
                "threshold": float(self.threshold), "rate": float(self.rate), "calibration": self.calibration,
                "n_fit": int(self.n_fit), "n_calibration": int(self.n_calibration),
                "record_rule": f"not recognised when more than {RECORD_SHARE:.0%} of a record's windows lie beyond "
                               "the threshold", "file": NOVELTY_FILE}

    def save(self, directory: str | Path) -> None:
        from safetensors.numpy import save

        from rvdiag.atomic import atomic_write

        atomic_write(Path(directory) / NOVELTY_FILE, save({"location": np.ascontiguousarray(self.location),
                                                           "precision": np.ascontiguousarray(self.precision)}))


def fit_novelty(estimator, X_fit: np.ndarray, X_calibration: np.ndarray | None = None,
                rate: float = DEFAULT_RATE) -> NoveltyDetector:
    """Fit the detector on the model inputs ``X_fit`` (the training windows) and set its threshold at the
    ``1 - rate`` quantile of the distances of ``X_calibration`` (held out; the training windows when None)."""
    from sklearn.covariance import LedoitWolf

    F = learned_features(estimator, X_fit)
    lw = LedoitWolf().fit(F)
    det = NoveltyDetector(lw.location_.astype(np.float64), np.asarray(lw.precision_, dtype=np.float64), 0.0,
                          float(rate), "held-out test split", int(len(F)), 0)
    held_out = X_calibration is not None and len(X_calibration) > 0
    d = det.distances(learned_features(estimator, X_calibration) if held_out else F)
    det.threshold = float(np.quantile(d[np.isfinite(d)], 1.0 - rate, method="higher"))
    det.n_calibration = int(len(d))
    if not held_out:
        det.calibration = "training split (no test split: in-sample, the rate is optimistic)"
    return det


def load_novelty(directory: str | Path, card: dict) -> NoveltyDetector | None:
    """The detector of a model directory, or None for a model written without one (card without ``novelty``)."""
    info = card.get("novelty")
    if not info:
        return None
    from safetensors import SafetensorError
    from safetensors.numpy import load_file

    path = Path(directory) / NOVELTY_FILE
    try:
        arrays = load_file(str(path))
        return NoveltyDetector(arrays["location"], arrays["precision"], float(info["threshold"]),
                               float(info["rate"]), str(info.get("calibration", "")), int(info.get("n_fit", 0)),
                               int(info.get("n_calibration", 0)))
    except (OSError, SafetensorError, KeyError, TypeError, ValueError) as exc:
        raise ModelFileError(f"{path}: the card names an out-of-distribution check this file does not hold "
                             f"({type(exc).__name__}: {exc})") from None
