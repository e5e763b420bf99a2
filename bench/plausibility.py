"""Plausibility of the simulated housing vibration against measured gearboxes (docs/model.md, section 9).

For each output speed and load, noise-free, on the signal ``rvdiag simulate`` writes (channel x): RMS, crest
factor and kurtosis of T1 (healthy), a broken tooth (fraction 1.0 and 0.5), wear of 3 and 9 um (the ends of the
monitoring libraries' draws: the sun's Archard depth over a robot's life, docs/model.md), 20 um of wear (late life:
the 20,000 h life at k = 1e-17 m^2/N wears 29 um) and a 2 mm root crack, their ratios to healthy, the share of the
acceleration energy above 10 kHz, and the dynamic mesh-force factor (largest ratio of a mesh force to its
quasi-static value at the same angle, :func:`dynamic_mesh_factor`) with the smallest mesh force over the static
mean (0: contact lost; negative: back-flank contact).

The bounds (docs/model.md): healthy kurtosis 3-25 and crest <= 10 (real RV reducers on a robot: kurtosis median
8-21, crest 5.7-9.1); broken tooth RMS 0.6-2.0x healthy, kurtosis <= 3x healthy, crest <= 12 (a real gearbox
with a broken tooth: RMS ratio 0.6-1.0); half broken RMS <= 1.5x; wear <= 2x (measured at 20 um on gearboxes
whose elastic deflection is 10-20 um); 2 mm crack <= 1.2x; healthy mesh-force factor <= 1.15.

    .venv/bin/python bench/plausibility.py [--speeds 30,45,60] [--loads 0.4,1.0,1.5] [--duration 1.0] [--json]
        [--modification EQ,OFF] [--pin-errors RADIUS,POSITION]    (um; e.g. --modification 0,0: conjugate discs)
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from scipy.stats import kurtosis

from rvdiag.dynamics import ModelSettings, initial_deflection, prepare, simulate
from rvdiag.dynamics.trace import dynamic_mesh_factor, trace
from rvdiag.gears import BrokenTooth, RootCrack, ToothFaults, Wear
from rvdiag.params import ReducerParams

STATES = {
    "T1": None,
    "broken 1.0": ToothFaults({0: (BrokenTooth(1.0),)}),
    "broken 0.5": ToothFaults({0: (BrokenTooth(0.5),)}),
    "wear 3um": ToothFaults.for_state("T3", wear_depth=3e-6),
    "wear 9um": ToothFaults.for_state("T3", wear_depth=9e-6),
    "wear 20um": ToothFaults.for_state("T3", wear_depth=20e-6),
    "crack 2mm": ToothFaults.for_state("T4", crack_depth=2e-3),
}


def stats(x: np.ndarray, fs: float) -> dict:
    x = x - x.mean()
    rms = float(np.sqrt(np.mean(x * x)))
    spec = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(x.size, 1 / fs)
    return {"rms": rms, "crest": float(np.abs(x).max() / rms), "kurtosis": float(kurtosis(x, fisher=False)),
            "above_10kHz": float(spec[f > 10e3].sum() / spec.sum())}


def mesh_factor(params, fault, speed, load, fs=48000.0, seconds=0.1):
    m = prepare(params, fault, output_speed_deg_s=speed, load_Nm=load)
    q0, _ = initial_deflection(m, -0.1)
    tr = trace(m, np.concatenate([q0, 0 * q0]), fs, int(seconds * fs), int(0.1 * fs))
    return dynamic_mesh_factor(m, tr)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", default="30,45,60")
    ap.add_argument("--loads", default="0.4,1.0,1.5", help="fractions of the rated torque")
    ap.add_argument("--duration", type=float, default=1.0)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--modification", default=None, metavar="EQ,OFF",
                    help="the discs' equidistant and offset profile modifications in um (default: the parameter "
                         "set's, +4,-3; 0,0 for conjugate discs)")
    ap.add_argument("--pin-errors", default=None, metavar="RADIUS,POSITION",
                    help="the pins' radius and position tolerances in um (default: the parameter set's, off)")
    a = ap.parse_args()
    params = ReducerParams.default()
    if a.modification is not None:
        eq, off = (float(v) * 1e-6 for v in a.modification.split(","))
        params = params.replace(stage2={"equidistant_modification": eq, "offset_modification": off})
    if a.pin_errors is not None:
        rad, pos = (float(v) * 1e-6 for v in a.pin_errors.split(","))
        params = params.replace(manufacturing={"pin_radius": rad, "pin_position": pos})
    rated = params.operation.rated_torque
    rows = []
    for sp in [float(s) for s in a.speeds.split(",")]:
        for lf in [float(s) for s in a.loads.split(",")]:
            base = None
            for name, fault in STATES.items():
                r = simulate(params, fault, output_speed_deg_s=sp, load_Nm=lf * rated, duration_s=a.duration,
                             settings=ModelSettings())
                s = stats(r.signal[0], r.fs)
                if base is None:
                    base = s
                    s["mesh_factor_max"], s["mesh_factor_min"] = mesh_factor(params, None, sp, lf * rated)
                s.update(state=name, speed_deg_s=sp, load_fraction=lf, rms_ratio=s["rms"] / base["rms"],
                         kurtosis_ratio=s["kurtosis"] / base["kurtosis"])
                rows.append(s)
                if not a.json:
                    extra = (f"  mesh factor {s['mesh_factor_max']:.2f} (min {s['mesh_factor_min']:.2f})"
                             if "mesh_factor_max" in s else "")
                    print(f"{sp:4.0f} deg/s {lf:4.1f}x  {name:11s} RMS {s['rms']:8.3f} ({s['rms_ratio']:6.2f}x)  "
                          f"crest {s['crest']:5.1f}  kurt {s['kurtosis']:6.1f}  >10kHz {s['above_10kHz']:.3f}{extra}",
                          flush=True)
    if a.json:
        print(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
