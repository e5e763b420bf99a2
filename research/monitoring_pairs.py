"""Paired simulations for monitoring a reducer against its own healthy baseline (issue 27): each simulated reducer
is seen healthy at commissioning, then in each state, with run-to-run variation between any two records.

    PYTHONPATH=src nice python research/monitoring_pairs.py --reducers 10 --out out/monitoring_pairs.npz

Per reducer r (seeded by ``SeedSequence(seed).spawn(reducers)[r]``; every draw is stored in the output):

- specimen: its own ``[modification] error_seed`` and ``iso1328_grade`` (4..7), every stiffness and damping of the
  library's ``[randomise]`` lists (:data:`rvdiag.library.config.STIFFNESS_KEYS`, ``DAMPING_KEYS``) scaled by its own
  factor in 1 +- 10 %, and its own sensor path (``[mounting]`` keys of
  :data:`rvdiag.library.config.PATH_KEYS`: resonance 1.5-9 kHz, damping ratio 0.02-0.15, 0-15 kg on the housing);
- a fixed noise floor: white noise of power 20 dB (``--floor-db``) below the mean power of its first
  commissioning record;
- commissioning (role ``baseline``): ``--baseline-records`` records at each of the operating points
  (speeds x loads);
- monitored: ``--healthy`` records of T1 and ``--per-state`` of each of T2..T6 at a random operating point, with
  severities drawn as configs/independent.toml but wear 5-20 um (crack 1.4-2.2 mm at 30-60 deg, broken 0.3-1.0);
- run-to-run variation of every record (baseline included): load +-3 %, speed +-1 %, temperature +-2 % (every
  stiffness by one factor), mesh damping +-10 %, sensor gain +-3 %, uniform: the library's own
  :func:`rvdiag.library.paired.draw_variation` and :func:`~rvdiag.library.paired.apply_variation` (they were
  written here first; the same draws, so this script's output is unchanged).  A paired library config
  (``[baseline]``, docs/library.md) now builds such data as a sample store; this script stays as the probe
  behind the figures of docs/monitoring.md.

The records are channel 0 (x) of :func:`rvdiag.dynamics.simulate` at 48 kHz after a 0.2 s run-in.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from rvdiag.dynamics import ModelSettings, simulate
from rvdiag.library.config import DAMPING_KEYS, STIFFNESS_KEYS
from rvdiag.library.paired import apply_variation, draw_variation
from rvdiag.library.states import tooth_faults
from rvdiag.params import ReducerParams

SEVERITY = {"broken_fraction": (0.3, 1.0), "wear_depth": (5e-6, 20e-6), "crack_depth": (1.4e-3, 2.2e-3),
            "crack_angle_deg": (30.0, 60.0)}
STATE_KEYS = {"T1": (), "T2": ("broken_fraction",), "T3": ("wear_depth",),
              "T4": ("crack_depth", "crack_angle_deg"), "T5": ("broken_fraction", "wear_depth"),
              "T6": ("broken_fraction", "wear_depth", "crack_depth", "crack_angle_deg")}


def specimen(rng, base: ReducerParams) -> tuple[ReducerParams, dict]:
    scales = {f"{s}.{k}": float(1 + 0.10 * rng.uniform(-1, 1)) for s, k in STIFFNESS_KEYS + DAMPING_KEYS}
    mounting = {"path_resonance_hz": float(rng.uniform(1500, 9000)),
                "path_damping_ratio": float(rng.uniform(0.02, 0.15)),
                "housing_added_mass": float(rng.uniform(0, 15))}
    mod = {"error_seed": int(rng.integers(0, 2**31)), "iso1328_grade": int(rng.integers(4, 8))}
    changes: dict[str, dict] = {}
    for name, f in scales.items():
        s, k = name.split(".")
        changes.setdefault(s, {})[k] = getattr(getattr(base, s), k) * f
    p = base.replace(**changes).replace(mounting=mounting, modification=mod)
    return p, {"scales": scales, "mounting": mounting, "modification": mod}


def run_params(rng, p: ReducerParams) -> tuple[ReducerParams, dict]:
    """One record's run-to-run draw (the library's defaults) applied to the specimen's parameters."""
    d = draw_variation(rng)
    return apply_variation(p, d), d


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--reducers", type=int, default=10)
    ap.add_argument("--seed", type=int, default=27)
    ap.add_argument("--speeds", type=float, nargs="+", default=[30.0, 60.0])
    ap.add_argument("--loads", type=float, nargs="+", default=[50.0, 130.0])
    ap.add_argument("--baseline-records", type=int, default=3)
    ap.add_argument("--healthy", type=int, default=12)
    ap.add_argument("--per-state", type=int, default=4)
    ap.add_argument("--duration", type=float, default=1.0)
    ap.add_argument("--floor-db", type=float, default=20.0)
    ap.add_argument("--out", default="out/monitoring_pairs.npz")
    ap.add_argument("--only", type=int, nargs="+", default=None,
                    help="simulate only these reducers (indices into the --reducers seeds: the same records as the "
                         "whole run gives them; concatenate the outputs with research/tooth_median.py --merge)")
    a = ap.parse_args()
    fs = 48000.0
    settings = ModelSettings(transient_s=0.2, substeps=4)
    base = ReducerParams.default()
    ops = [(v, L) for v in a.speeds for L in a.loads]
    X, meta = [], []
    t0 = time.perf_counter()
    for r, ss in enumerate(np.random.SeedSequence(a.seed).spawn(a.reducers)):
        if a.only is not None and r not in a.only:
            continue
        rng = np.random.default_rng(ss)
        p, spec = specimen(rng, base)
        plan = [("baseline", "T1", i) for i in range(len(ops)) for _ in range(a.baseline_records)]
        plan += [("monitored", "T1", int(rng.integers(len(ops)))) for _ in range(a.healthy)]
        plan += [("monitored", s, int(rng.integers(len(ops)))) for s in ("T2", "T3", "T4", "T5", "T6")
                 for _ in range(a.per_state)]
        sigma = None
        for k, (role, state, op) in enumerate(plan):
            pr, d = run_params(rng, p)
            sev = {key: float(rng.uniform(*SEVERITY[key])) for key in STATE_KEYS[state]}
            speed, load = ops[op][0] * d["speed"], ops[op][1] * d["load"]
            sim_seed = int(rng.integers(0, 2**31))
            res = simulate(pr, tooth_faults(state, **sev), output_speed_deg_s=speed, load_Nm=load,
                           duration_s=a.duration, fs=fs, seed=sim_seed, settings=settings)
            x = d["gain"] * res.signal[0]
            if sigma is None:  # the reducer's fixed floor: floor_db below its first commissioning record
                sigma = float(np.sqrt(np.mean(x**2) * 10 ** (-a.floor_db / 10)))
            x = x + sigma * rng.standard_normal(x.size)
            X.append(x.astype(np.float32))
            meta.append({"reducer": r, "role": role, "state": state, "op": op, "nominal_speed": ops[op][0],
                         "nominal_load": ops[op][1], "output_speed_deg_s": speed, "load_Nm": load,
                         "noise_sigma": sigma, "sim_seed": sim_seed, **{"r2r_" + k2: v for k2, v in d.items()},
                         **sev, **({"specimen": spec} if k == 0 else {})})
        print(f"reducer {r}: {len(plan)} records, {time.perf_counter() - t0:.0f} s", flush=True)
    np.savez_compressed(a.out, X=np.stack(X), meta=json.dumps(meta), args=json.dumps(vars(a)), fs=fs)
    print(f"{len(X)} records in {time.perf_counter() - t0:.0f} s -> {a.out}")


if __name__ == "__main__":
    main()
