"""The one-sided Hann amplitude spectrum and the frequency of its highest peak in a band: the one home of the
spectral speed estimates (a motor current's supply line, :func:`rvdiag.motor.lines.output_speed_from_current`; a
vibration's mesh line, :func:`rvdiag.io.angles.estimate_shaft_speed`) and of the spectra that plots draw.

It sits at the bottom of the package (numpy only), so the motor layer and the io layer both use it.
"""

from __future__ import annotations

import math

import numpy as np


def amplitude_spectrum(x, fs: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies, one-sided Hann amplitude spectrum) of ``x`` with its mean removed: a sinusoid of amplitude
    ``A`` on a bin reads ``A``.  Frequencies in Hz when ``fs`` is given, else in cycles per sample."""
    x = np.asarray(x, dtype=np.float64)
    w = np.hanning(x.size)
    amp = 2.0 * np.abs(np.fft.rfft((x - x.mean()) * w)) / w.sum()
    return np.fft.rfftfreq(x.size, 1.0 / fs if fs else 1.0), amp


def peak_frequency(f: np.ndarray, amp: np.ndarray, low: float, high: float = math.inf,
                   refine: bool = True) -> float | None:
    """Frequency of the highest bin of ``amp`` with ``low <= f <= high`` (``None`` when the band holds no bin).

    ``refine``: the peak refined by a parabola through the log magnitudes of the bin and its two neighbours
    (Grandke 1983, IEEE Trans. Instrum. Meas. 32(2), for the Hann window), at most half a bin either way.
    """
    df = float(f[1] - f[0]) if f.size > 1 else 1.0
    last = amp.size - (2 if refine else 1)  # a refined peak needs a neighbour on each side
    k0 = max(int(math.ceil(low / df)), 1 if refine else 0)
    k1 = last if high == math.inf else min(int(math.floor(high / df)), last)
    if k1 < k0:
        return None
    k = k0 + int(np.argmax(amp[k0:k1 + 1]))
    if not refine:
        return float(f[k])
    a, b, c = np.log(amp[k - 1:k + 2] + 1e-300)
    den = a - 2 * b + c
    delta = 0.5 * (a - c) / den if den < 0 else 0.0
    return (k + float(np.clip(delta, -0.5, 0.5))) * df
