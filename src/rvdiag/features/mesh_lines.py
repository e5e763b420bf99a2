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
    from rvdiag.motor.lines import line_height
    from rvdiag.spectral import amplitude_spectrum

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


#: a speed is refused when the record has a cycloid-pin mesh line at ``fcs / k`` for one of these ``k``: it would
#: be the k-th harmonic of a slower speed's mesh
SUBHARMONICS = (2, 3)


def _line(f: np.ndarray, amp: np.ndarray, df: float, hz: float) -> tuple[float, float]:
    """``(peak Hz, height dB)`` of the line at ``hz`` (:func:`rvdiag.motor.lines.line_height`: the largest of
    the 5 bins around it over the median of the bins 6 to 40 away); nan beyond the spectrum."""
    from rvdiag.motor.lines import line_height

    _, h = line_height(amp, df, float(hz))
    k = int(round(hz / df))
    if not math.isfinite(h) and h != math.inf:
        return math.nan, math.nan
    return float(f[k - 2 + int(np.argmax(amp[k - 2:k + 3]))]), float(h)


def confirm_speed(x: np.ndarray, fs: float, params, output_speed_deg_s: float) -> dict:
    """Whether the record's own lines confirm an output speed estimated from the stage-1 mesh peak
    (:func:`rvdiag.io.angles.input_revolutions`), as a vibration analyst reads a mesh's line family.  A check, not
    an estimate: it reads the lines at the speed given and returns that speed unchanged, confirmed or not (the
    estimate itself is :func:`rvdiag.io.angles.estimate_shaft_speed`'s):

    1. the cycloid-pin (stage-2) mesh, which turns with the carrier, shows its line ``fcs`` at that speed,
       :data:`LINE_DB` above its floor;
    2. no line stands at ``fcs / 2`` or ``fcs / 3`` (:data:`SUBHARMONICS`): there, the "mesh line" would be the
       2nd or 3rd harmonic of the mesh of a speed half or a third as fast, and the estimate that multiple of the
       true speed (the harmonics of a mesh are often as strong as its fundamental: on a healthy record simulated
       at 45 deg/s, ``2 fcs`` stands 13 dB above its floor, ``fcs`` 15 dB);
    3. a second line of the same speed stands beside it: the mesh's second harmonic ``2 fcs`` or the stage-1
       mesh ``fsp`` (one line alone can be any line of a busy spectrum).

    A speed half the true one (a subharmonic) fails 1: the record has no line at half the mesh frequency.

    Returns ``{"confirmed", "output_speed_deg_s", "stage2_hz", "stage2_peak_hz", "stage2_height_db",
    "family": {"2 fcs", "fsp"} heights, "subharmonics": {k: height}, "harmonic_of": the speed whose k-th mesh
    harmonic the lines are (the largest k with a line at fcs / k) or None, "reason": None or why not}``.

    Measured on 0.5 s records simulated at 30, 45 and 60 deg/s (75 N m, 40 dB SNR): the true speed is confirmed
    for the healthy and the cracked sun at each speed, 2x, 3x, 1/2 and 1/3 of it never; a broken tooth's impacts
    raise the floor around the mesh lines, so its records are mostly not confirmed (the speed must then be given):
    tests/test_diagnose_trust.py."""
    from rvdiag.kinematics import characteristic_frequencies
    from rvdiag.spectral import amplitude_spectrum

    speed = float(output_speed_deg_s)
    cf = characteristic_frequencies(params, output_speed_deg_s=speed)
    fcs, fsp = float(cf.fcs), float(cf.fsp)
    f, amp = amplitude_spectrum(np.asarray(x, dtype=np.float64), float(fs))
    df = float(f[1] - f[0])
    peak_hz, height = _line(f, amp, df, fcs)
    family = {"2 fcs": _line(f, amp, df, 2 * fcs)[1], "fsp": _line(f, amp, df, fsp)[1]}
    sub = {k: _line(f, amp, df, fcs / k)[1] for k in SUBHARMONICS}
    over = [k for k, h in sub.items() if h >= LINE_DB]
    harmonic_of = speed / max(over) if over else None
    reason = None
    if not height >= LINE_DB:
        reason = f"no cycloid-pin mesh line at {fcs:.5g} Hz"
    elif over:
        reason = (f"a line at {fcs / max(over):.5g} Hz, 1/{max(over)} of the mesh frequency: the lines fit "
                  f"{harmonic_of:.4g} deg/s, of whose mesh the estimate reads a harmonic")
    elif not any(h >= LINE_DB for h in family.values()):
        reason = (f"the line at {fcs:.5g} Hz stands alone: neither its harmonic ({2 * fcs:.5g} Hz) nor the stage-1 "
                  f"mesh ({fsp:.5g} Hz) shows")
    return {"confirmed": reason is None, "output_speed_deg_s": speed, "stage2_hz": fcs,
            "stage2_peak_hz": peak_hz, "stage2_height_db": height, "family": family,
            "subharmonics": {str(k): h for k, h in sub.items()}, "harmonic_of": harmonic_of, "reason": reason}
