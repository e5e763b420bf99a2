"""Measured signals in: readers for CSV/CSV.gz, MATLAB v5/v7.3, NPY/NPZ, WAV and TDMS, and windowing.

>>> import tempfile, pathlib, numpy as np
>>> from rvdiag.io import read_signal, list_channels, window
>>> path = pathlib.Path(tempfile.mkdtemp()) / "rig.npz"
>>> np.savez(path, acc=np.sin(np.arange(5000) / 10), tach=np.zeros(5000))
>>> list_channels(path)
['acc', 'tach']
>>> sig = read_signal(path, channel_regex="^acc$", fs=12000)
>>> sig.fs, sig.channel, window(sig.data, 2048).shape
(12000.0, 'acc', (2, 2048))
>>> import shutil; shutil.rmtree(path.parent)
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
