"""Shared input validation for the feature transformers.

Every extractor in :mod:`rvdiag.features` takes ``X`` of shape ``(n_samples, n_points)``: one signal
window per row, float, finite.  Bad input raises :class:`rvdiag.errors.ParameterError` (a
``ValueError``, as scikit-learn expects).
"""

from __future__ import annotations

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin

from rvdiag.errors import ParameterError


class SignalTypeError(ParameterError, TypeError):
    """Signals of a non-numeric type (a ParameterError that is also a TypeError, as scikit-learn expects)."""


def as_signal_matrix(X, min_points: int = 2) -> np.ndarray:
    """Return ``X`` as a C-contiguous float64 matrix of signal windows, or raise ParameterError.

    Parameters
    ----------
    X : array-like, shape (n_samples, n_points)
        One window per row.
    min_points : int
        Shortest window accepted.
    """
    from sklearn.utils import check_array

    try:
        A = check_array(X, dtype=np.float64, ensure_2d=True, ensure_min_samples=1)
    except TypeError as exc:
        raise SignalTypeError(f"signals must be numeric: {exc}") from None
    except ValueError as exc:
        raise ParameterError(f"signals must be a finite 2D array (n_samples, n_points): {exc}") from None
    if A.shape[1] < min_points:
        raise ParameterError(
            f"signal windows need at least {min_points} points, got n_features = {A.shape[1]}"
        )
    if not np.all(np.isfinite(A)):
        raise ParameterError("signals contain NaN or Inf")
    return np.ascontiguousarray(A)


class SignalTransformer(TransformerMixin, BaseEstimator):
    """Base of the stateless signal-to-feature transformers.

    ``fit`` only records ``n_features_in_`` (the window length) so that ``transform`` can refuse
    windows of another length; subclasses implement :meth:`_features` and :meth:`_feature_names`.
    """

    _min_points = 2

    def fit(self, X, y=None):
        """Check ``X`` and the parameters; learn nothing else.  Returns ``self``."""
        A = as_signal_matrix(X, self._min_points)
        self._check_params(A.shape[1])
        self.n_features_in_ = A.shape[1]
        return self

    def transform(self, X):
        """Features of each window, shape (n_samples, n_features)."""
        from sklearn.utils.validation import check_is_fitted

        check_is_fitted(self, "n_features_in_")
        A = as_signal_matrix(X, 1)
        if A.shape[1] != self.n_features_in_:
            raise ParameterError(
                f"X has {A.shape[1]} features, but {type(self).__name__} is expecting "
                f"{self.n_features_in_} features as input (windows of {A.shape[1]} points, "
                f"fitted on {self.n_features_in_} points)"
            )
        return self._features(A)

    def get_feature_names_out(self, input_features=None):
        """Names of the output features."""
        return np.asarray(self._feature_names(), dtype=object)

    def _check_params(self, n_points: int) -> None:  # pragma: no cover - overridden where needed
        return None

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.requires_fit = True
        return tags
