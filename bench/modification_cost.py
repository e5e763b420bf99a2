"""Cost of the cycloid discs' profile modification and of the pins' errors (docs/model.md section 3).

2 s at 45 deg/s output, rated load, vibration only, default settings; the baseline is the same model with conjugate
discs (modification 0) in the same run.  Best of ``--repeat`` runs, CPU time of this process (the machine is shared).

    .venv/bin/python bench/modification_cost.py [--repeat 3] [--duration 2.0]
"""

from __future__ import annotations

import argparse
import time
import warnings

from rvdiag.dynamics import simulate
from rvdiag.params import ReducerParams


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--duration", type=float, default=2.0)
    a = ap.parse_args()
    warnings.filterwarnings("ignore")
    p0 = ReducerParams.default()
    variants = {
        "conjugate discs (baseline)": p0.replace(stage2={"equidistant_modification": 0.0, "offset_modification": 0.0}),
        "modified +4/-3 um (default)": p0,
        "modified + pins' errors 1/3 um": p0.replace(manufacturing={"pin_radius": 1e-6, "pin_position": 3e-6}),
    }
    for p in variants.values():  # compile (or load from the cache) outside the timing
        simulate(p, output_speed_deg_s=45.0, duration_s=0.05)
    best = {}
    for _ in range(a.repeat):
        for name, p in variants.items():
            t = time.process_time()
            simulate(p, output_speed_deg_s=45.0, duration_s=a.duration)
            best[name] = min(best.get(name, float("inf")), time.process_time() - t)
    base = best["conjugate discs (baseline)"]
    for name, s in best.items():
        print(f"{name:32s} {s:6.3f} s CPU  ratio {s / base:5.2f}")


if __name__ == "__main__":
    main()
