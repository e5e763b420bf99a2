"""Wavelet-packet band energies (PyWavelets).

A level-L wavelet packet decomposition splits [0, fs/2] into 2^L bands of equal width; the energy
(sum of squared coefficients) of each terminal node is one feature.  The motor-current study
(Li, Zhao et al. 2024) feeds the level-4 energies of the 16 bands to an SVM.  The nodes are taken in
**frequency order** (``pywt.WaveletPacket.get_level(L, order="freq")``): the natural (Paley) order of
the tree is not monotone in frequency because high-pass branches mirror their spectra (Wickerhauser,
"Adapted wavelet analysis from theory to software", 1994, ch. 7; PyWavelets docs, "Wavelet Packets").
Band k (k = 0..2^L - 1) then covers roughly [k, k + 1] / 2^(L+1) cycles per sample.
"""

from __future__ import annotations

import numpy as np
import pywt

from rvdiag.errors import ParameterError
from rvdiag.features._base import SignalTransformer


class WaveletPacketEnergy(SignalTransformer):
    """scikit-learn transformer: energies of the 2^level wavelet-packet bands, in frequency order.

    Parameters
    ----------
    wavelet : str
        PyWavelets wavelet name (default ``'db4'``; longer filters separate bands better).
    level : int
        Decomposition level (4 gives the paper's 16 bands).
    mode : str
        Signal extension mode of PyWavelets.
    relative : bool
        Divide by the total energy of the window (features then sum to 1).
    log : bool
        Return log10 of the energies.
    """

    def __init__(self, wavelet: str = "db4", level: int = 4, mode: str = "symmetric",
                 relative: bool = True, log: bool = False):
        self.wavelet = wavelet
        self.level = level
        self.mode = mode
        self.relative = relative
        self.log = log

    def _check_params(self, n_points):
        if self.wavelet not in pywt.wavelist(kind="discrete"):
            raise ParameterError(f"unknown discrete wavelet {self.wavelet!r}")
        if not (isinstance(self.level, (int, np.integer)) and 1 <= self.level <= 10):
            raise ParameterError(f"level must be an integer in 1..10, got {self.level!r}")
        if self.mode not in pywt.Modes.modes:
            raise ParameterError(f"unknown extension mode {self.mode!r}; use one of {pywt.Modes.modes}")
        if n_points < 2**self.level:
            raise ParameterError(f"windows of {n_points} points are too short for level {self.level}")

    def _features(self, X):
        self._check_params(X.shape[1])
        out = np.empty((X.shape[0], 2**self.level))
        for i, x in enumerate(X):
            wp = pywt.WaveletPacket(data=x, wavelet=self.wavelet, mode=self.mode, maxlevel=self.level)
            nodes = wp.get_level(self.level, order="freq")
            out[i] = [np.sum(np.square(n.data)) for n in nodes]
        if self.relative:
            tot = out.sum(axis=1, keepdims=True)
            out = np.divide(out, tot, out=np.zeros_like(out), where=tot > 0)
        if self.log:
            out = np.log10(out + 1e-12)
        return out

    def _feature_names(self):
        return [f"wpd_band{k}" for k in range(2**self.level)]
