"""Does a record carry the reducer's mesh lines at a speed?  The check behind "not recognised" and behind a
speed estimate that ``rvdiag diagnose`` accepts.

At an output speed the RV reducer meshes at two frequencies (:func:`rvdiag.kinematics.characteristic_frequencies`):
the stage-1 (sun-planet) mesh ``fsp`` and the stage-2 (cycloid-pin) mesh ``fcs``, which turns with the carrier.
Each line's height is its amplitude over the median of the bins 6 to 40 away on both sides of a Hann spectrum
(:func:`rvdiag.motor.lines.line_height`); a line is present when it stands :data:`LINE_DB` above that floor.
"""

from __future__ import annotations

import math

import numpy as np

#: a mesh line is present when it stands this many dB above its local floor
LINE_DB = 10.0


def mesh_lines(x: np.ndarray, fs: float, params, output_speed_deg_s: float) -> dict:
    """``{"stage1": {"hz", "height_db"}, "stage2": {"hz", "height_db"}, "present": [names], "threshold_db"}`` of
    the record ``x`` at ``output_speed_deg_s`` (a line beyond the spectrum has height None)."""
    from rvdiag.kinematics import characteristic_frequencies
    from rvdiag.motor.lines import amplitude_spectrum, line_height

    cf = characteristic_frequencies(params, output_speed_deg_s=float(output_speed_deg_s))
    f, amp = amplitude_spectrum(np.asarray(x, dtype=np.float64), float(fs))
    df = float(f[1] - f[0])
    out: dict = {"threshold_db": LINE_DB, "present": []}
    for name, hz in (("stage1", cf.fsp), ("stage2", cf.fcs)):
        _, h = line_height(amp, df, float(hz))
        h = None if not math.isfinite(h) and h != math.inf else float(h)
        out[name] = {"hz": float(hz), "height_db": h}
        if h is not None and h >= LINE_DB:
            out["present"].append(name)
    return out


#: the stage-2 line must be the strongest within this fraction of its predicted frequency, and lie within
#: :data:`AGREEMENT` of it (plus one spectral bin)
NEIGHBOURHOOD, AGREEMENT = 0.10, 0.005


def confirm_speed(x: np.ndarray, fs: float, params, output_speed_deg_s: float) -> dict:
    """Whether the record's own lines confirm an output speed estimated from the stage-1 mesh peak
    (:func:`rvdiag.io.angles.input_revolutions`): at that speed the stage-2 (cycloid-pin) mesh, which turns with
    the carrier, must show its line ``fcs``: the strongest bin within +-:data:`NEIGHBOURHOOD` of the predicted
    ``fcs`` lies within :data:`AGREEMENT` (and one bin) of it, and stands :data:`LINE_DB` above its floor.  A
    stage-1 "peak" that is a harmonic or a sideband of another line predicts an ``fcs`` where the record has none.

    Returns ``{"confirmed", "output_speed_deg_s", "stage2_hz", "stage2_peak_hz", "stage2_height_db"}``."""
    from rvdiag.kinematics import characteristic_frequencies
    from rvdiag.motor.lines import amplitude_spectrum, line_height

    fcs = float(characteristic_frequencies(params, output_speed_deg_s=float(output_speed_deg_s)).fcs)
    f, amp = amplitude_spectrum(np.asarray(x, dtype=np.float64), float(fs))
    df = float(f[1] - f[0])
    lo, hi = int(np.floor(fcs * (1 - NEIGHBOURHOOD) / df)), int(np.ceil(fcs * (1 + NEIGHBOURHOOD) / df)) + 1
    peak_hz, height = math.nan, math.nan
    if hi < amp.size and lo >= 1:
        peak_hz = float(f[lo + int(np.argmax(amp[lo:hi]))])
        height = line_height(amp, df, peak_hz)[1]
    ok = bool(abs(peak_hz - fcs) <= AGREEMENT * fcs + df and height >= LINE_DB)
    return {"confirmed": ok, "output_speed_deg_s": float(output_speed_deg_s), "stage2_hz": fcs,
            "stage2_peak_hz": peak_hz, "stage2_height_db": float(height)}
