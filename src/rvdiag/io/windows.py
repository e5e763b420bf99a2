"""Where windows start: fixed-length windows cut from a long signal (the samples of a dataset, :func:`window`,
:func:`window_starts`) and the windows of a network input that cover one sample (:func:`covering_starts`)."""

from __future__ import annotations

import numpy as np

from rvdiag.errors import DataFileError, ParameterError
from rvdiag.validation import integer


def window(signal, length: int, hop: int | None = None) -> np.ndarray:
    """Cut ``signal`` into windows of ``length`` points, one every ``hop`` points.

    Parameters
    ----------
    signal : MeasuredSignal or array-like, 1-D
    length : int
        Points per window (>= 2).
    hop : int, optional
        Step between window starts; default ``length`` (adjacent windows, no overlap).  The tail shorter
        than a window is dropped.

    Returns
    -------
    ndarray, float64, shape (n_windows, length)
        A copy; window ``k`` is ``x[k * hop : k * hop + length]``.

    Raises
    ------
    DataFileError
        The signal is shorter than one window (names the file when ``signal`` is a MeasuredSignal).
    ParameterError
        ``length`` or ``hop`` is not a positive integer.

    Examples
    --------
    >>> window(np.arange(10.0), 4, hop=3)
    array([[0., 1., 2., 3.],
           [3., 4., 5., 6.],
           [6., 7., 8., 9.]])
    """
    data = getattr(signal, "data", signal)
    where = f"{signal.path}: channel {signal.channel!r}" if hasattr(signal, "path") else "signal"
    x = np.asarray(data, dtype=np.float64)
    if x.ndim != 1:
        raise ParameterError(f"window needs a 1-D signal, got shape {x.shape}")
    length = integer(length, "window length", 2)
    hop = length if hop is None else integer(hop, "hop", 1)
    if length > x.size:
        raise DataFileError(f"{where} has {x.size} points, shorter than the window of {length}")
    n = (x.size - length) // hop + 1
    view = np.lib.stride_tricks.sliding_window_view(x, length)[::hop]
    return np.array(view[:n], dtype=np.float64, copy=True)


def window_starts(n_points: int, length: int, hop: int | None = None) -> np.ndarray:
    """Start index of every window :func:`window` cuts from a signal of ``n_points`` points."""
    hop = length if hop is None else hop
    if length > n_points:
        return np.zeros(0, dtype=np.int64)
    return np.arange((n_points - length) // hop + 1, dtype=np.int64) * hop


#: how a sample longer than a network input is covered (:func:`covering_starts`; ``CNNClassifier(long_input=...)``)
COVER_POLICIES = ("window", "crop")


def covering_starts(n_points: int, length: int, policy: str = "window") -> np.ndarray:
    """Start indices of the windows of ``length`` points that a network takes from a sample of ``n_points``.

    ``"window"``: ``k = ceil(n_points / length)`` windows spread evenly from ``0`` to ``n_points - length``, so
    together they cover every point; ``"crop"``: the one centred window.

    >>> covering_starts(8000, 6400).tolist()
    [0, 1600]
    >>> covering_starts(8000, 6400, "crop").tolist()
    [800]
    >>> covering_starts(4096, 4096).tolist()
    [0]
    """
    if length > n_points:
        raise ParameterError(f"samples of {n_points} points are shorter than the network input of {length} points")
    if policy == "crop":
        return np.array([(n_points - length) // 2], dtype=np.int64)
    if policy not in COVER_POLICIES:
        raise ParameterError(f"long_input must be one of {COVER_POLICIES}, got {policy!r}")
    k = -(-n_points // length)
    if k == 1:
        return np.array([0], dtype=np.int64)
    return np.round(np.linspace(0, n_points - length, k)).astype(np.int64)
