"""Condition indicators normalised against the healthy machine at the same operating point (feature sets
``tsa-ci-z`` and ``tsa-mod-z``).

A gear condition indicator (FM4, NA4, M6A...) is dimensionless, so it cancels the sensor's gain and much of the
transfer path, but its healthy value still moves with speed and load: a healthy gear at 90 deg/s and 160 N m is not
a healthy gear at 15 deg/s and 20 N m.  NASA's load-normalised NA4* (Dempsey & Zakrajsek 2001, "Minimizing load
effects on NA4 gear vibration diagnostic parameter", NASA/TM-2001-210671) divides the indicator by the healthy
machine's statistics at the same load; :class:`HealthyBaselineFeatures` does the same for every feature of a
feature transformer and for two operating-point columns at once:

    z = (x - mean_bin) / std_bin,

mean and standard deviation taken over the *healthy* training samples (label ``healthy``, ``T1`` in a library)
whose metadata columns (by default the output speed and the load) fall into the same bin.  The bins are quantiles
of the healthy samples' values (``n_bins`` per column, so each holds about as many); a bin holding fewer than
``min_count`` healthy samples borrows from its neighbours (every bin within 1, then 2... bins in each column) until
it has enough, and at worst (fewer than ``min_count`` healthy samples in all) takes the statistics of all healthy
samples.  A value outside the training range falls
into the first or last bin.

The input follows :mod:`rvdiag.features.combine`: each row is a window's points followed by the metadata columns of
:meth:`HealthyBaselineFeatures.input_metadata` (the inner transformer's, then the bin columns it lacks).  ``fit``
needs the labels ``y`` (it picks the healthy rows); ``transform`` does not.
"""

from __future__ import annotations

import itertools

import numpy as np
from sklearn.base import clone

from rvdiag.errors import ParameterError
from rvdiag.features._base import SignalTransformer, as_signal_matrix
from rvdiag.features.combine import input_metadata, points_before_metadata
from rvdiag.validation import integer


class HealthyBaselineFeatures(SignalTransformer):
    """The features of ``features`` as z-scores against the healthy training samples of the same operating-point bin
    (Dempsey & Zakrajsek 2001's load-normalised NA4*, over speed and load; module docstring).

    Parameters
    ----------
    features : transformer
        The feature transformer whose output is normalised (e.g. :class:`rvdiag.features.tsa.TSAIndicatorFeatures`).
    columns : sequence of str
        Metadata columns that define the operating-point bins (default the output speed and the load).
    healthy : str
        Label of the healthy class in ``y`` (a library's ``T1``).
    n_bins : int
        Bins per column, at quantiles of the healthy training samples' values.
    min_count : int
        Fewest healthy samples a bin's statistics may rest on; thinner bins pool their neighbours.

    Attributes
    ----------
    features_ : the fitted inner transformer
    edges_ : list of arrays, the inner bin edges of each column (``n_bins - 1`` values or fewer)
    mean_, scale_ : arrays of shape (bins of column 1, bins of column 2, ..., n_features)
    count_ : array of the healthy samples each bin's statistics rest on (after pooling)
    """

    _min_points = 2

    def __init__(self, features=None, columns=("output_speed_deg_s", "load_Nm"), healthy: str = "T1",
                 n_bins: int = 3, min_count: int = 24):
        self.features = features
        self.columns = columns
        self.healthy = healthy
        self.n_bins = n_bins
        self.min_count = min_count

    # ----------------------------------------------------------------------------------------------- input
    def _inner(self):
        if self.features is None or not hasattr(self.features, "transform"):
            raise ParameterError(f"HealthyBaselineFeatures needs a feature transformer, got {self.features!r}")
        return self.features

    def _columns(self) -> tuple[str, ...]:
        cols = tuple(self.columns or ())
        if not cols or not all(isinstance(c, str) and c for c in cols) or len(set(cols)) != len(cols):
            raise ParameterError(f"columns must name distinct metadata columns, got {self.columns!r}")
        return cols

    def input_metadata(self) -> tuple[str, ...]:
        """The inner transformer's metadata columns, then the bin columns it does not read already."""
        inner = tuple(input_metadata(self._inner()))
        return inner + tuple(c for c in self._columns() if c not in inner)

    def _split(self, A):
        """(the inner transformer's input, the bin columns' values) of the checked matrix ``A``."""
        meta = self.input_metadata()
        n = points_before_metadata(A, meta, "HealthyBaselineFeatures reads")
        inner = input_metadata(self._inner())
        part = A[:, : n + len(inner)]
        values = np.column_stack([A[:, n + meta.index(c)] for c in self._columns()])
        return np.ascontiguousarray(part), values

    def _check(self):
        integer(self.n_bins, "n_bins", 1)
        integer(self.min_count, "min_count", 2)

    # ------------------------------------------------------------------------------------------------- fit
    def fit(self, X, y=None):
        """Fit the inner transformer and the healthy statistics of every bin; returns ``self``."""
        self.fit_transform(X, y)
        return self

    def fit_transform(self, X, y=None, **fit_params):
        """:meth:`fit`, then :meth:`transform` of the same ``X``, computing the inner features once."""
        self._check()
        if y is None:
            raise ParameterError("HealthyBaselineFeatures needs the labels y to find the healthy samples")
        A = as_signal_matrix(X, 1)
        part, values = self._split(A)
        y = np.asarray(y).astype(str)
        if y.shape != (A.shape[0],):
            raise ParameterError(f"y holds {y.shape} labels for {A.shape[0]} samples")
        healthy = y == str(self.healthy)
        if healthy.sum() < 2:
            raise ParameterError(f"HealthyBaselineFeatures needs at least 2 healthy samples (label {self.healthy!r}); "
                                 f"y has {int(healthy.sum())} of n_samples = {A.shape[0]}")
        self.features_ = clone(self._inner())
        F = np.asarray(self.features_.fit_transform(part, y), dtype=np.float64)
        self.n_features_in_ = A.shape[1]
        self._fit_bins(F[healthy], values[healthy])
        return self._z(F, values)

    def _fit_bins(self, F, V):
        k = int(self.n_bins)
        self.edges_ = [np.unique(np.quantile(V[:, j], np.arange(1, k) / k)) for j in range(V.shape[1])]
        shape = tuple(e.size + 1 for e in self.edges_)
        cell = self._cells(V)
        n_f = F.shape[1]
        g_mean, g_std = F.mean(axis=0), F.std(axis=0, ddof=1)
        floor = np.where(g_std > 0, 1e-6 * g_std, 1e-12)
        self.mean_ = np.empty(shape + (n_f,))
        self.scale_ = np.empty(shape + (n_f,))
        self.count_ = np.empty(shape, dtype=np.int64)
        for idx in itertools.product(*(range(s) for s in shape)):
            for r in range(max(shape)):  # widen the neighbourhood until it holds min_count samples (at most all)
                rows = np.all(np.abs(cell - np.asarray(idx)) <= r, axis=1)
                if rows.sum() >= int(self.min_count):
                    break
            self.mean_[idx] = F[rows].mean(axis=0) if rows.any() else g_mean
            self.scale_[idx] = np.maximum(F[rows].std(axis=0, ddof=1), floor) if rows.sum() > 1 else g_std
            self.count_[idx] = int(rows.sum())

    def _cells(self, V) -> np.ndarray:
        return np.column_stack([np.searchsorted(e, V[:, j], side="right") for j, e in enumerate(self.edges_)])

    def _z(self, F, V):
        idx = tuple(self._cells(V).T)
        return (F - self.mean_[idx]) / self.scale_[idx]

    # ------------------------------------------------------------------------------------------- transform
    def _features(self, A):
        part, values = self._split(A)
        if not np.all(np.isfinite(values)):
            raise ParameterError(f"the bin columns {list(self._columns())} must be finite")
        F = np.asarray(self.features_.transform(part), dtype=np.float64)
        return self._z(F, values)

    def _feature_names(self):
        return [f"{f}_z" for f in self.features_.get_feature_names_out()]


def healthy_tsa_features(*, load_column: str = "load_Nm", healthy: str = "T1", n_bins: int = 3,
                         min_count: int = 24, **kw) -> HealthyBaselineFeatures:
    """The TSA condition indicators (:class:`rvdiag.features.tsa.TSAIndicatorFeatures`, arguments ``kw``) as
    z-scores against the healthy training samples of the same speed and load bin (feature set ``tsa-ci-z``): the
    bins are those of ``speed_column`` (``output_speed_deg_s`` when not given) and ``load_column``."""
    from rvdiag.features.tsa import TSAIndicatorFeatures

    inner = TSAIndicatorFeatures(**kw)
    speed = inner.speed_column or "output_speed_deg_s"
    return HealthyBaselineFeatures(inner, columns=(speed, load_column), healthy=healthy, n_bins=n_bins,
                                   min_count=min_count)


def healthy_modulation_features(**kw) -> HealthyBaselineFeatures:
    """``tsa-mod`` (the TSA and modulation indicators) as healthy-baseline z-scores (feature set ``tsa-mod-z``)."""
    return healthy_tsa_features(**{"modulation": True, **kw})


__all__ = ["HealthyBaselineFeatures", "healthy_modulation_features", "healthy_tsa_features"]
