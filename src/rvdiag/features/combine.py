"""Feature sets side by side (``rvdiag train --features spectrum-abs+bearing-envelope``), and the per-sample
metadata that some feature sets read.

:class:`CombinedFeatures` is scikit-learn's ``FeatureUnion`` for signal windows: each named transformer sees
the same windows and their outputs are concatenated column-wise.  Unlike ``FeatureUnion`` it knows that a
transformer may read metadata columns appended to each window (:func:`input_metadata`; e.g. the shaft speed
of :class:`rvdiag.features.bearing.BearingEnvelopeFeatures` with ``speed_column``) and gives every part its
own columns only.

The model input convention: a fitted pipeline whose first step declares metadata columns ``(c1, c2...)``
takes ``X = [window points | c1 | c2 ...]``; :func:`with_metadata` builds it from a store's metadata and the
model card records the names (``metadata_columns``), so ``evaluate`` and ``diagnose`` supply them.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np
from sklearn.base import clone

from rvdiag.errors import ParameterError, StoreError
from rvdiag.features._base import SignalTransformer, as_signal_matrix


def input_metadata(estimator) -> tuple[str, ...]:
    """Metadata columns that ``estimator`` (a transformer, or a pipeline through its first step) reads after
    each window's points, in order; ``()`` for the plain signal transformers."""
    steps = getattr(estimator, "steps", None)
    if steps:
        estimator = steps[0][1]
    fn = getattr(estimator, "input_metadata", None)
    return tuple(fn()) if callable(fn) else ()


def points_before_metadata(A: np.ndarray, meta, reader: str) -> int:
    """The number of signal points of each row of ``A``, whose last ``len(meta)`` columns are the metadata columns
    ``meta`` (the model input convention above); fewer than one point is a one-line error in which ``reader``, a
    subject and its verb (``"the parts read"``), names who reads them."""
    n = A.shape[1] - len(meta)
    if n < 1:
        raise ParameterError(f"X has {A.shape[1]} columns (n_features = {A.shape[1]}); {reader} {len(meta)} metadata "
                             f"column(s) {list(meta)} after each window's points")
    return n


def with_metadata(X, meta: Mapping[str, np.ndarray] | None, columns, where: str = "the data") -> np.ndarray:
    """``X`` with the metadata ``columns`` appended (float64), the input of a model that reads them.

    Raises
    ------
    StoreError
        ``meta`` lacks a column, or it is not numeric (one line, naming ``where`` and the remedy).
    """
    columns = list(columns)
    if not columns:
        return X
    meta = meta or {}
    cols = []
    for c in columns:
        if c not in meta:
            have = ", ".join(sorted(meta)) or "none"
            raise StoreError(f"{where} has no metadata column {c!r}, which the model reads (each sample's shaft "
                             f"speed in rev/min for bearing-envelope features; columns: {have}); build the store "
                             f"with 'rvdiag dataset from-files --scalar {c}=RPM' or a --meta-regex group {c}")
        try:
            v = np.asarray(meta[c], dtype=np.float64)
        except (TypeError, ValueError):
            raise StoreError(f"{where}: metadata column {c!r} is not numeric") from None
        if v.shape != (len(X),) or not np.all(np.isfinite(v)):
            raise StoreError(f"{where}: metadata column {c!r} must hold one finite number per sample")
        cols.append(v)
    return np.column_stack([np.asarray(X, dtype=np.float64), *cols])


class CombinedFeatures(SignalTransformer):
    """Several feature transformers side by side, their features concatenated (as ``FeatureUnion``).

    Parameters
    ----------
    transformers : sequence of (name, transformer)
        The parts, e.g. ``[("spectrum-abs", SpectrumFeatures(relative=False)), ("bearing-envelope",
        BearingEnvelopeFeatures(speed_column="rpm"))]``.  A part that reads metadata columns
        (:func:`input_metadata`) gets them after the window's points; the others get the points only.

    The input is ``(n_samples, n_points + n_meta)``: the points, then the columns of :meth:`input_metadata`
    (the union of the parts', in order of first use).  Output feature names are ``"<part>__<feature>"``.
    """

    def __init__(self, transformers=()):
        self.transformers = transformers

    def input_metadata(self) -> tuple[str, ...]:
        cols: list[str] = []
        for _, t in self._parts():
            cols += [c for c in input_metadata(t) if c not in cols]
        return tuple(cols)

    def _parts(self):
        parts = list(self.transformers or ())
        if not parts:
            raise ParameterError("CombinedFeatures needs at least one (name, transformer) part")
        names = []
        for p in parts:
            if not (isinstance(p, (tuple, list)) and len(p) == 2 and isinstance(p[0], str)
                    and hasattr(p[1], "transform")):
                raise ParameterError(f"each part must be a (name, transformer) pair, got {p!r}")
            names.append(p[0])
        if len(set(names)) != len(names):
            raise ParameterError(f"part names must be unique, got {names}")
        return [(str(n), t) for n, t in parts]

    def _inputs(self, A):
        """(name, transformer, its input) for each part of the checked matrix ``A``."""
        meta = self.input_metadata()
        n = points_before_metadata(A, meta, "the parts read")
        for name, t in self._parts():
            extra = [n + meta.index(c) for c in input_metadata(t)]
            yield name, t, (A[:, :n] if not extra else np.ascontiguousarray(A[:, list(range(n)) + extra]))

    def fit(self, X, y=None):
        """Fit every part on its columns of ``X``; returns ``self``."""
        A = as_signal_matrix(X, 1)
        self.transformers_ = [(name, clone(t).fit(part, y)) for name, t, part in self._inputs(A)]
        self.n_features_in_ = A.shape[1]
        return self

    def _features(self, A):
        fitted = dict(self.transformers_)
        return np.hstack([np.asarray(fitted[name].transform(part), dtype=np.float64)
                          for name, _, part in self._inputs(A)])

    def _feature_names(self):
        return [f"{name}__{f}" for name, t in self.transformers_ for f in t.get_feature_names_out()]


__all__ = ["CombinedFeatures", "input_metadata", "points_before_metadata", "with_metadata"]
