"""The motor current's characteristic lines with and without the reducer's manufacturing errors (docs/model.md
section 10).

For each output speed (rated load, default parameters): ``simulate(..., duration_s=4.2, signal="current")``, the
last 4096 points of i_a at 1 kHz, Hann window, each line's height over the median of the bins 6-40 away from it
(:func:`rvdiag.motor.lines.current_lines`).  Goals: (a) healthy f_e, f_e +- f1, |f_e +- f_sp| and |f_e +- f_cs| at
least 10 dB above the floor; (b) a broken sun tooth (T2) raises the f1 sidebands at least 2x over healthy
(f_e +- 2 f1 amplitudes, and the rms of f_e +- k f1, k = 1..5); (c) pitting (T7) raises them less than spalling
(T8), and spalling less than a broken tooth.  Each case runs twice: with the ``[manufacturing]`` errors of the
parameter set (``errors on``, the default) and with every tolerance 0 (``errors off``, the model before them).
``--vibration`` adds the housing vibration (channel x, noise-free, 1 s after the 0.1 s run-in, 60 deg/s rated):
RMS, kurtosis and crest factor of T1 and T2, errors on and off.

    .venv/bin/python bench/current_lines.py [--speeds 30,45,60] [--states T1,T2,T7,T8] [--errors on,off]
        [--seed 0] [--set manufacturing.crank_phase_arcmin=2] [--vibration] [--vibration-states T1,T2]
        [--severity spall_width_fraction=1] [--load-inertia J] [--json FILE]

``--severity key=value`` sets a fault severity of ``ToothFaults.for_state`` (e.g. ``spall_width_fraction=1``: a
spall through the face, whose profile deviation lifts the contact, docs/model.md section 10).

``--load-inertia J`` puts a load of J kg m^2 on the output coupling, the model's load DOF
(``simulate(load_inertia_kg_m2=J)``; docs/model.md sections 1, 3 and 10: 3.75 is the motor-current rig's 15 kg arm
at 0.5 m); without it the load is the parameter set's (a pure torque by default).

About 4 s of wall time per 4.2-s run on one free core (24 runs for the whole table).
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np
from scipy.stats import kurtosis

from rvdiag.dynamics import simulate
from rvdiag.gears import ToothFaults
from rvdiag.kinematics import characteristic_frequencies
from rvdiag.motor.lines import amplitude_spectrum, current_lines, line_height
from rvdiag.params import ReducerParams

OFF = {"planet_runout_grade": 0, "crank_hole_position": 0.0, "crank_phase_arcmin": 0.0, "pin_radius": 0.0,
       "pin_position": 0.0}
N_WINDOW = 4096
DURATION_S = 4.2
FAMILY = (1, 2, 3, 4, 5)
GOAL_LINES = ("fe", "fe-1f1", "fe+1f1", "fe-fsp", "fe+fsp", "fe-fcs", "fe+fcs")


def params_for(errors: str, seed: int, sets: list[str]) -> ReducerParams:
    p = ReducerParams.default()
    changes: dict[str, dict] = {"modification": {"error_seed": seed}}
    if errors == "off":
        changes["manufacturing"] = dict(OFF)
    for item in sets:
        key, val = item.split("=")
        sec, name = key.split(".")
        changes.setdefault(sec, {})[name] = float(val)
    return p.replace(**changes)


def family(x: np.ndarray, fs: float, params: ReducerParams, speed: float) -> dict:
    """Amplitudes of f_e -+ k f1, k = 1..5 (A)."""
    fr = characteristic_frequencies(params, output_speed_deg_s=speed)
    f, amp = amplitude_spectrum(x, fs)
    df = float(f[1] - f[0])
    return {f"{s}{k}f1": line_height(amp, df, abs(fr.fe + (k if s == "+" else -k) * fr.f1))[0]
            for k in FAMILY for s in "-+"}


SEVERITY: dict = {}


def fault_of(state: str):
    """The state's faults at the default severities, changed by ``--severity``."""
    return None if state == "T1" else ToothFaults.for_state(state, **SEVERITY)


def current_case(params: ReducerParams, state: str, speed: float, duration: float,
                 load_inertia: float | None = None) -> dict:
    fault = fault_of(state)
    r = simulate(params, fault, output_speed_deg_s=speed, duration_s=duration, signal="current",
                 load_inertia_kg_m2=load_inertia)
    x = r.signal[0][-N_WINDOW:]
    lines = current_lines(x, r.fs, params, speed)["lines"]
    return {"lines": lines, "family": family(x, r.fs, params, speed)}


def vibration_case(params: ReducerParams, state: str, speed: float = 60.0, load_inertia: float | None = None) -> dict:
    fault = fault_of(state)
    x = simulate(params, fault, output_speed_deg_s=speed, duration_s=1.0, load_inertia_kg_m2=load_inertia).signal[0]
    x = x - x.mean()
    rms = float(np.sqrt(np.mean(x * x)))
    return {"rms": rms, "kurtosis": float(kurtosis(x, fisher=False)), "crest": float(np.abs(x).max() / rms)}


def family_rms_ratio(faulty: dict, healthy: dict) -> float:
    """rms of the f_e -+ k f1 amplitudes, faulty over healthy; a line the spectrum does not resolve (|f_e - 5 f1|
    lies at 0.4 Hz: f_e = p f_rotor and f1 = f_rotor (1 - 1/i)) is left out of both."""
    fam_f = np.array(list(faulty.values()), dtype=float)
    fam_h = np.array(list(healthy.values()), dtype=float)
    ok = np.isfinite(fam_f) & np.isfinite(fam_h)
    return float(np.sqrt(np.mean(fam_f[ok] ** 2)) / np.sqrt(np.mean(fam_h[ok] ** 2)))


def ratios(faulty: dict, healthy: dict) -> dict:
    return {"fe-2f1": faulty["family"]["-2f1"] / healthy["family"]["-2f1"],
            "fe+2f1": faulty["family"]["+2f1"] / healthy["family"]["+2f1"],
            "family_rms": family_rms_ratio(faulty["family"], healthy["family"])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", default="30,45,60")
    ap.add_argument("--states", default="T1,T2,T7,T8")
    ap.add_argument("--errors", default="on,off")
    ap.add_argument("--seed", type=int, default=0, help="[modification] error_seed: the specimen")
    ap.add_argument("--set", action="append", default=[], help="section.key=value of the parameter set")
    ap.add_argument("--duration", type=float, default=DURATION_S)
    ap.add_argument("--vibration", action="store_true")
    ap.add_argument("--vibration-states", default="T1,T2", help="states of the --vibration figures")
    ap.add_argument("--severity", action="append", default=[], metavar="KEY=VALUE",
                    help="a fault severity of ToothFaults.for_state, e.g. spall_width_fraction=1")
    ap.add_argument("--json", default=None, help="write every figure to this file")
    ap.add_argument("--load-inertia", type=float, default=None, metavar="J",
                    help="the load's inertia on the output coupling, kg m^2 (the model's load DOF; default: the "
                         "parameter set's, a pure load torque)")
    a = ap.parse_args()
    SEVERITY.update({k: float(v) for k, v in (item.split("=") for item in a.severity)})
    speeds = [float(s) for s in a.speeds.split(",")]
    states = a.states.split(",")
    out: dict = {"current": {}, "vibration": {}}
    t0 = time.time()
    for errors in a.errors.split(","):
        params = params_for(errors, a.seed, a.set)
        for sp in speeds:
            res = {st: current_case(params, st, sp, a.duration, a.load_inertia) for st in states}
            out["current"][f"{errors} {sp:g}"] = res
            h = res["T1"]["lines"]
            print(f"errors {errors:3s} {sp:4.0f} deg/s T1: " + "  ".join(
                f"{k} {h[k]['height_db']:5.1f} dB ({1e3 * h[k]['amplitude']:.3f} mA)" for k in GOAL_LINES),
                flush=True)
            for st in states:
                if st == "T1":
                    continue
                r = ratios(res[st], res["T1"])
                res[st]["ratios"] = r
                print(f"    {st} over T1: f_e-2f1 {r['fe-2f1']:5.2f}x  f_e+2f1 {r['fe+2f1']:5.2f}x  "
                      f"f_e+-k f1 (k=1..5) rms {r['family_rms']:5.2f}x", flush=True)
        if a.vibration:
            for st in a.vibration_states.split(","):
                v = vibration_case(params, st, load_inertia=a.load_inertia)
                out["vibration"][f"{errors} {st}"] = v
                print(f"errors {errors:3s} 60 deg/s rated {st} vibration x: RMS {v['rms']:.3f} m/s^2  "
                      f"kurtosis {v['kurtosis']:.1f}  crest {v['crest']:.1f}", flush=True)
    print(f"# {time.time() - t0:.0f} s", flush=True)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1, default=lambda o: None if isinstance(o, float) and math.isnan(o) else o)


if __name__ == "__main__":
    main()
