"""The crack detector's commissioning end to end (issue 36 step 3; docs/twin.md, "The crack detector in use"): what
one operating point costs, and the detector of the twin it wrote on records of that twin.

    PYTHONPATH=src nice python research/twin_crack_commission.py --out out/twin_crack          # the records
    PYTHONPATH=src nice python -m rvdiag update --specimen out/twin_crack/rec0.csv out/twin_crack/rec1.csv \\
        --angle-channel theta_in --output-angle-channel theta_out --channel acc --load 90 --iterations 2 \\
        --draws 0 --out out/twin_crack/twin -q
    PYTHONPATH=src nice python research/twin_crack_commission.py --out out/twin_crack --judge

The records: two commissioning records of the built-in RV-20E at 45 deg/s and 90 N m, 1 s at 48 kHz, each with its
own run-to-run variation (:func:`rvdiag.library.paired.draw_variation`, seed 1, gain held at 1): both encoder angles
(:func:`rvdiag.updating.specimen.simulated_record`, 23 bits) and the housing vibration (channel 0, white noise 20 dB
below its power) in one CSV each, so that the encoders are read at the vibration's 48 kHz.

``--judge``: 2 healthy and 2 cracked records (1.8 mm at 45 deg) simulated with the twin's parameter set, each with
its own variation (seed 9), white noise 20 dB below the first one's power, judged by the twin's detector with the
noise floor from each estimate (:func:`rvdiag.monitoring.crack.estimate_noise_var`).
"""

from __future__ import annotations

import argparse
import os

import numpy as np

from rvdiag.dynamics import ModelSettings, simulate
from rvdiag.library.paired import apply_variation, draw_variation
from rvdiag.library.states import tooth_faults
from rvdiag.monitoring import crack as ck
from rvdiag.params import ReducerParams
from rvdiag.updating import specimen as sp

FS = 48000.0
SETTINGS = ModelSettings(transient_s=0.2, substeps=4)


def write_records(out: str) -> None:
    p = ReducerParams.default()
    rng = np.random.default_rng(1)
    os.makedirs(out, exist_ok=True)
    for k in range(2):
        d = draw_variation(rng)
        d["gain"] = 1.0
        a_in, a_out = sp.simulated_record(p, 45.0, 90.0, 1.0, FS, variation=d, rng=np.random.default_rng([k, 2]))
        res = simulate(apply_variation(p, d), None, output_speed_deg_s=45.0 * d["speed"], load_Nm=90.0 * d["load"],
                       duration_s=1.0, fs=FS, seed=k, settings=SETTINGS)
        x = np.asarray(res.signal[0], dtype=float)
        x = x + np.sqrt(np.mean(x ** 2) / 100) * rng.standard_normal(x.size)
        n = min(a_in.size, x.size)
        np.savetxt(os.path.join(out, f"rec{k}.csv"), np.column_stack([np.arange(n) / FS, a_in[:n], a_out[:n], x[:n]]),
                   delimiter=",", header="time_s,theta_in,theta_out,acc", comments="", fmt="%.17g")
        print(f"rec{k}.csv: {n} samples at {45.0 * d['speed']:.4f} deg/s")


def judge(out: str) -> None:
    twin = os.path.join(out, "twin")
    ref = ck.CrackReference.load(os.path.join(twin, "crack", "op0.npz"))
    recs = []
    for k in range(2):
        a = np.loadtxt(os.path.join(out, f"rec{k}.csv"), delimiter=",", skiprows=1)
        te = sp.te_record(a[:, 1], a[:, 2], FS, ReducerParams.default(), load_Nm=90.0)
        recs.append(ck.CommissioningRecord(a[:, 3], FS, te.output_speed_deg_s, 90.0, f"rec{k}"))
    p = ReducerParams.load(os.path.join(twin, "params.toml"))
    rng = np.random.default_rng(9)
    X, sig2 = [], None
    for state in ["T1", "T1", "T4", "T4"]:
        d = draw_variation(rng)
        res = simulate(apply_variation(p, d), tooth_faults(state, **(ck.CRACK_SEVERITY if state == "T4" else {})),
                       output_speed_deg_s=45 * d["speed"], load_Nm=90 * d["load"], duration_s=1.0, fs=FS, seed=3,
                       settings=SETTINGS)
        x = d["gain"] * np.asarray(res.signal[0], dtype=float)
        sig2 = sig2 or float(np.mean(x ** 2) / 100)
        X.append((state, x + np.sqrt(sig2) * rng.standard_normal(x.size), 45 * d["speed"]))
    print(f"the floor's variance: {sig2:.4f}")
    for m in ck.NOISE_METHODS:
        det = ck.CrackDetector(ck.attach_baseline(ref, recs, noise_method=m))
        idx = ", ".join(f"{s} {det.judge(x, FS, v).index:.2f}" for s, x, v in X)
        print(f"{m}: noise variance {det.reference.noise_var:.4f}, deflection {det.filter_.deflection_:.2f}, "
              f"threshold at 1 % {det.threshold_:.2f}; index {idx}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/twin_crack")
    ap.add_argument("--judge", action="store_true")
    a = ap.parse_args()
    judge(a.out) if a.judge else write_records(a.out)


if __name__ == "__main__":
    main()
