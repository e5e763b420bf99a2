"""The housing RMS of the libraries' wear depths, in the simulator's run-in shape and in a life's Archard shape.

Which shape the libraries draw wear in (docs/library.md, "How deep the shipped libraries wear"): the run-in
shape ``Wear(depth)`` (the libraries' ``wear_depth``) against the Archard shape of the 20,000 h life of
``tests/test_plausibility.py`` (``WearDepthProfile.to_wear()``, scaled to the same deepest point), at 3-20 um, as
multiples of the healthy RMS (noise-free, channel x, 0.5 s after the model's run-in) at the three points of the
plausibility tests.

    PYTHONPATH=src .venv/bin/python research/wear_library_depths.py [--depths 3,6,9,12,20]

Results (2026-11-28) in bench/HISTORY.md ("Wear of a robot's life in the libraries").
"""

from __future__ import annotations

import argparse

import numpy as np

from rvdiag.dynamics import simulate
from rvdiag.gears import ToothFaults, Wear
from rvdiag.gears.wear import DutyCycle, wear_depth_profile
from rvdiag.params import ReducerParams

P = ReducerParams.default()
RATED = P.operation.rated_torque


def rms(fault, speed: float, load: float) -> float:
    x = simulate(P, fault, output_speed_deg_s=speed, load_Nm=load, duration_s=0.5).signal[0]
    x = x - x.mean()
    return float(np.sqrt(np.mean(x * x)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--depths", default="3,6,9,12,20", help="deepest points (um)")
    a = ap.parse_args()
    life = wear_depth_profile(P, 20000.0, DutyCycle(30.0, 0.5 * RATED, 0.5), 1e-18).to_wear()
    print("| point | depth (um) | run-in shape: RMS x healthy | life shape: RMS x healthy |")
    print("|---|---|---|---|")
    for speed, load in ((30.0, RATED), (60.0, RATED), (45.0, 0.4 * RATED)):
        healthy = rms(None, speed, load)
        for d in (float(v) * 1e-6 for v in a.depths.split(",")):
            run_in = rms(ToothFaults({}, wear=Wear(d)), speed, load) / healthy
            shaped = rms(ToothFaults({}, wear=Wear(d, shape=life.shape)), speed, load) / healthy
            print(f"| {speed:g} deg/s, {load / RATED:.0%} | {d * 1e6:g} | {run_in:.2f} | {shaped:.2f} |", flush=True)


if __name__ == "__main__":
    main()
