"""The path from the housing to the accelerometer, as a linear filter on the simulated housing acceleration.

A real sensor does not see the pin wheel's acceleration itself: the signal passes through the housing structure
and the accelerometer, whose useful band ends near 10 kHz (Lu, Borghesani, Randall et al. 2023, Mech. Syst.
Signal Process. 184, 109714; Matania, Zamir & Bortman 2023, J. Sound Vib. 548, 117560).  The path is linear and
does not load the structure, so it is applied to the output of the integration:

- an optional structural resonance (a single-degree-of-freedom base-excitation filter: natural frequency
  ``f_n``, damping ratio ``zeta``; unit gain at low frequency, ``1 / (2 zeta)`` at resonance), discretised by the
  bilinear transform with the resonance pre-warped;
- the accelerometer's upper band limit: a second-order Butterworth low-pass at ``sensor_cutoff_hz``.

Both filters are causal (as a physical path is), from :mod:`scipy.signal`.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal as sps

from rvdiag.errors import ParameterError


def path_sos(fs: float, path_resonance_hz: float = 0.0, path_damping_ratio: float = 0.05,
             sensor_cutoff_hz: float = 0.0) -> np.ndarray | None:
    """Second-order sections of the path at sampling rate ``fs`` (``None`` when the path is a pass-through).

    A frequency at or above Nyquist is left out (the sampled signal has nothing there to shape).
    """
    nyq = 0.5 * fs
    sections = []
    if 0.0 < path_resonance_hz < nyq:
        if not path_damping_ratio > 0:
            raise ParameterError("[mounting] path_damping_ratio must be > 0 with a path resonance")
        wn = 2.0 * math.pi * path_resonance_hz
        z = path_damping_ratio
        # base excitation: H(s) = (2 z wn s + wn^2) / (s^2 + 2 z wn s + wn^2)
        b, a = sps.bilinear([2.0 * z * wn, wn * wn], [1.0, 2.0 * z * wn, wn * wn], fs=fs)
        sections.append(sps.tf2sos(b, a))
    if 0.0 < sensor_cutoff_hz < nyq:
        sections.append(sps.butter(2, sensor_cutoff_hz, btype="low", fs=fs, output="sos"))
    if not sections:
        return None
    return np.vstack(sections)


def apply_path(x: np.ndarray, fs: float, mounting) -> np.ndarray:
    """Filter every channel of ``x`` (channels, samples) through the path of a ``[mounting]`` section."""
    sos = path_sos(fs, mounting.path_resonance_hz, mounting.path_damping_ratio, mounting.sensor_cutoff_hz)
    if sos is None:
        return x
    return sps.sosfilt(sos, x, axis=-1)
