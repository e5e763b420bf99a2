"""Motor-current signature analysis: the characteristic lines of a phase current and their heights.

One purpose: read a phase current's spectrum the way the motor-current study does (Li, Zhao et al. 2024,
section 4 and Table 3): the supply line ``f_e`` and the lines the reducer puts around it, ``f_e +- k f1``
(the sun / input shaft; a broken sun tooth raises them), ``|f_e +- f_sp|`` (stage-1 mesh) and ``|f_e +- f_cs|``
(cycloid-pin mesh), and the dead-time line ``5 f_e`` (docs/model.md section 10).

- :func:`line_height`: a line's amplitude (Hann-windowed one-sided amplitude spectrum, so a sinusoid of
  amplitude ``A`` on a bin reads ``A``) and its height in dB over the median of the bins 6 to 40 away on both
  sides (the local floor; Benbouzid 2000, IEEE Trans. Ind. Electron. 47(5), reads fault lines the same way,
  against the neighbouring noise).
- :func:`output_speed_from_current`: the output speed from the strongest line, taken as ``f_e = p f1``, when the
  file states none.  One of three speed estimates of a record, each from its own signal: this one reads a
  motor current's supply line; :func:`rvdiag.io.angles.estimate_shaft_speed` a vibration's stage-1 mesh line
  (then checked by :func:`rvdiag.features.mesh_lines.confirm_speed`); a tachometer or encoder gives the angle
  itself (:func:`rvdiag.io.angles.input_revolutions`).  All turn an input-shaft frequency into the output speed by
  :func:`rvdiag.kinematics.output_speed_from_input_hz`.
- :func:`current_lines`: every line of the table at one operating point.
"""

from __future__ import annotations

import math

import numpy as np

from rvdiag.deprecation import renamed_names
from rvdiag.errors import ParameterError
from rvdiag.spectral import amplitude_spectrum, peak_frequency

#: bins on each side of a line that belong to it (Hann main lobe and leakage), and the floor's outer edge
FLOOR_GAP, FLOOR_EDGE = 6, 40
#: the sideband orders ``f_e +- k f1`` reported
SIDEBAND_ORDERS = (1, 2, 3)


def line_height(amp: np.ndarray, df: float, f0: float) -> tuple[float, float]:
    """(amplitude, height over the local floor in dB) of the line nearest ``f0`` Hz, or (nan, nan) when the
    line or its floor falls outside the spectrum.  The peak is the largest of the 5 bins around ``f0``."""
    k = int(round(f0 / df))
    if k - FLOOR_GAP < 1 or k + FLOOR_GAP + 1 >= amp.size:
        return math.nan, math.nan
    peak = float(amp[k - 2:k + 3].max())
    floor = float(np.median(np.r_[amp[max(k - FLOOR_EDGE, 1):k - FLOOR_GAP], amp[k + FLOOR_GAP + 1:k + FLOOR_EDGE + 1]]))
    if not floor > 0:
        return peak, math.inf if peak > 0 else math.nan
    return peak, 20.0 * math.log10(peak / floor) if peak > 0 else -math.inf


def output_speed_from_current(x: np.ndarray, fs: float, params, min_hz: float = 2.0) -> float:
    """Output speed (deg/s) of a motor phase current: its strongest line above ``min_hz`` taken as the supply
    frequency ``f_e = p f1`` (it is 40-80 dB above everything else under load), at the frequency of its bin
    (not refined: the line table reads lines at bins), then :func:`output_speed_from_fe`.

    Not for a vibration record, whose strongest line is a mesh harmonic: there the speed comes from the stage-1
    mesh line (:func:`rvdiag.io.angles.estimate_shaft_speed`).  The per-window supply frequency of the current
    features, :func:`rvdiag.features.current.electrical_frequency`, reads the same line but refined between bins
    (Grandke 1983) and from 3 bins up, in cycles per sample: the two agree within half a bin."""
    return _output_speed_from_supply_peak(*amplitude_spectrum(x, fs), params, min_hz)


def _output_speed_from_supply_peak(f: np.ndarray, amp: np.ndarray, params, min_hz: float = 2.0) -> float:
    """:func:`output_speed_from_current` on an amplitude spectrum already taken."""
    keep = f >= min_hz
    fe = peak_frequency(f, amp, min_hz, refine=False)
    if fe is None or not np.isfinite(amp[keep]).all() or amp[keep].max() <= 0:
        raise ParameterError("cannot estimate the speed from the current: no line above "
                             f"{min_hz:g} Hz; give the speed (--meta output_speed_deg_s=...)")
    return output_speed_from_fe(fe, params)


def output_speed_from_fe(fe: float, params) -> float:
    """The output speed (deg/s) at which the supply frequency is ``fe`` Hz: ``f_e = p f1`` (``p`` pole pairs,
    ``f1`` the input shaft's rotation frequency, :func:`rvdiag.kinematics.characteristic_frequencies`), the output
    turning ``1 / ratio`` as fast (:func:`rvdiag.kinematics.output_speed_from_input_hz`)."""
    from rvdiag.kinematics import output_speed_from_input_hz

    return output_speed_from_input_hz(params, fe / params.operation.motor_pole_pairs)


def line_frequencies(fr) -> dict[str, float]:
    """The lines of :func:`current_lines` by name, in Hz, at the characteristic frequencies ``fr``
    (:func:`rvdiag.kinematics.characteristic_frequencies`): ``fe``, ``fe-kf1`` / ``fe+kf1`` (k in
    :data:`SIDEBAND_ORDERS`), ``fe-fsp`` / ``fe+fsp``, ``fe-fcs`` / ``fe+fcs`` (absolute values of the differences)
    and ``5fe``."""
    wanted = {"fe": fr.fe}
    for k in SIDEBAND_ORDERS:
        wanted[f"fe-{k}f1"] = abs(fr.fe - k * fr.f1)
        wanted[f"fe+{k}f1"] = fr.fe + k * fr.f1
    wanted.update({"fe-fsp": abs(fr.fe - fr.fsp), "fe+fsp": fr.fe + fr.fsp,
                   "fe-fcs": abs(fr.fe - fr.fcs), "fe+fcs": fr.fe + fr.fcs, "5fe": 5 * fr.fe})
    return wanted


def current_lines(x: np.ndarray, fs: float, params, output_speed_deg_s: float | None = None) -> dict:
    """The characteristic lines of one phase current ``x`` sampled at ``fs`` Hz.

    Returns ``{"output_speed_deg_s", "speed_source", "frequencies": {name: Hz}, "lines": {name: {"hz",
    "amplitude", "height_db"}}}`` with the lines ``fe``, ``fe-kf1`` / ``fe+kf1`` (k in
    :data:`SIDEBAND_ORDERS`), ``fe-fsp`` / ``fe+fsp``, ``fe-fcs`` / ``fe+fcs`` (absolute values of the
    differences) and ``5fe``; a line outside the spectrum has null amplitude and height.
    """
    from rvdiag.kinematics import characteristic_frequencies

    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1 or x.size < 4 * FLOOR_EDGE:
        raise ParameterError(f"a current line table needs one channel of at least {4 * FLOOR_EDGE} points, "
                             f"got shape {x.shape}")
    if not (fs and fs > 0):
        raise ParameterError("the current's sampling rate is unknown: give --fs")
    f, amp = amplitude_spectrum(x, fs)
    source = "given"
    if output_speed_deg_s is None:
        output_speed_deg_s, source = _output_speed_from_supply_peak(f, amp, params), "strongest line taken as f_e"
    fr = characteristic_frequencies(params, output_speed_deg_s=output_speed_deg_s)
    wanted = line_frequencies(fr)
    df = float(f[1] - f[0])
    lines = {}
    for name, hz in wanted.items():
        a, h = line_height(amp, df, hz)
        lines[name] = {"hz": float(hz), "amplitude": None if math.isnan(a) else a,
                       "height_db": None if math.isnan(h) else h}
    return {"output_speed_deg_s": float(output_speed_deg_s), "speed_source": source,
            "frequencies": {k: float(v) for k, v in fr.as_dict().items()}, "lines": lines}


#: old names, served with a DeprecationWarning naming the new one
__getattr__ = renamed_names(__name__, {"estimate_output_speed": "output_speed_from_current"})
