"""Measured signals in: readers for CSV/CSV.gz, MATLAB v5/v7.3, NPY/NPZ, WAV and TDMS, and windowing.

>>> from rvdiag.io import read_signal, list_channels, window   # doctest: +SKIP
>>> sig = read_signal("IR007_0.mat", channel_regex="DE_time", fs=12000)   # doctest: +SKIP
>>> X = window(sig, 2048)                                           # doctest: +SKIP
"""

from rvdiag.io.readers import (
    SUPPORTED_SUFFIXES,
    MeasuredSignal,
    detect_format,
    list_channels,
    read_signal,
)
from rvdiag.io.windows import window, window_starts

__all__ = [
    "SUPPORTED_SUFFIXES",
    "MeasuredSignal",
    "detect_format",
    "list_channels",
    "read_signal",
    "window",
    "window_starts",
]
