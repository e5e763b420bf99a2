"""Simulation speed of the compiled integrator against scipy's solve_ivp on the same equations.

Healthy RV-20E, 48 kHz output, default model settings (``ModelSettings().substeps`` sub-steps of ``ModelSettings().method``
per sample unless ``--substeps``), 1000 rpm input, rated load, one CPU core (NUMBA_NUM_THREADS=1).
``sim_s_per_wall_s`` is recorded signal seconds per wall second of a whole ``simulate()`` call
(gears TVMS, static solve, 0.1 s transient and output included, compilation excluded; best of
``--repeat`` runs, since the development machine is shared).

Two scipy baselines, both ``solve_ivp`` (RK45, rtol 1e-6, atol 1e-12) from the same initial state
(the static solution):

- ``scipy_sim_s_per_wall_s``: on the independent pure-NumPy right-hand side
  (``tests/oracles/reference_rhs.py``, ``ReferenceRHS``, the same equations written in vectorised
  NumPy, no numba).  This is "scipy's solve_ivp on the same equations" of the issue and what
  REFERENCE.md's peer figure (0.0033 simulated s/s, RK45 with a Python right-hand side) measures;
  **``ratio`` = sim_s_per_wall_s / scipy_sim_s_per_wall_s uses this baseline**.
- ``scipy_compiled_rhs_sim_s_per_wall_s``: on the compiled right-hand side of rvdiag itself (the strict
  baseline: only the integrator differs); ``ratio_compiled_rhs`` uses it.

The development machine is shared, so the CPU time of this process (``time.process_time``) is reported
beside the wall time: ``sim_s_per_cpu_s``, ``scipy_sim_s_per_cpu_s``,
``scipy_compiled_rhs_sim_s_per_cpu_s``, ``ratio_cpu`` and ``ratio_compiled_rhs_cpu`` (JSON keys too).

With ``--workers N`` (N > 1) the same record is also simulated in N time segments on N threads
(``ModelSettings.segment_s`` = ``--segment``, default duration / N; :mod:`rvdiag.dynamics.segments`):
``parallel_sim_s_per_wall_s``, ``parallel_speedup`` (over the one-core continuous run of this same run)
and ``parallel_seam_error`` (relative L2 difference from that continuous run).  The headline
``sim_s_per_wall_s`` stays the one-core continuous figure.

``motor_cost_ratio`` (and ``_cpu``): wall (CPU) time of the same run with the servo motor's electrical side on
(``simulate(signal="both")``: PMSM, current loop, dead time, encoder) over the vibration-only run, same settings.
``motor_cost_ratio_mcsa`` (and ``_cpu``): the same at the operating point of configs/mcsa.toml, the coupled
model as the motor-current library runs it: 45 deg/s at the output, 20 N m plus the 15 kg arm at 0.5 m (its
load DOF; arm at 0 deg), 4 sub-steps, integrated at 48 kHz; ``simulate(signal="current", current_fs=1000)``
against ``simulate(signal="vibration")`` of the same reducer and load.  The goal of the coupled model is
<= 1.3x.  ``pin_wear_cost_ratio`` (and ``_cpu``): the reducer with its cycloid-pin stage worn 5 um deep
(``[stage2] pin_wear_depth``) over the unworn one, same run.  At both points the two runs alternate (best of ``--repeat`` each), so a load change on the shared
machine falls on both.

Usage: ``python bench/sim_speed.py [--json] [--duration S] [--scipy-duration S] [--numpy-duration S]
[--workers N [--segment S]]``
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

from rvdiag.dynamics import ModelSettings, prepare, simulate  # noqa: E402
from rvdiag.dynamics.linear import static_equilibrium  # noqa: E402
from rvdiag.dynamics.profile import LoadProfile  # noqa: E402
from rvdiag.dynamics.model import make_rhs  # noqa: E402
from rvdiag.params import ReducerParams  # noqa: E402
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the NumPy oracle lives with the tests
from oracles.reference_rhs import ReferenceRHS  # noqa: E402


def _paired_timing(duration: float, repeat: int, st: ModelSettings, kw_a: dict, kw_b: dict
                   ) -> tuple[tuple[float, float], tuple[float, float]]:
    """Best (wall, CPU) seconds of ``simulate(**kw_a)`` and of ``simulate(**kw_b)`` over ``repeat`` runs each,
    the two alternating (a short run of each compiles first)."""
    warm = ModelSettings(transient_s=0.0, substeps=st.substeps)
    best = [[float("inf")] * 2, [float("inf")] * 2]
    for kw in (kw_a, kw_b):
        simulate(duration_s=0.01, settings=warm, **kw)
    for _ in range(max(1, repeat)):
        for i, kw in enumerate((kw_a, kw_b)):
            t0, c0 = time.perf_counter(), time.process_time()
            simulate(duration_s=duration, settings=st, **kw)
            best[i] = [min(best[i][0], time.perf_counter() - t0), min(best[i][1], time.process_time() - c0)]
    return (best[0][0], best[0][1]), (best[1][0], best[1][1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--duration", type=float, default=2.0, help="simulated seconds for rvdiag (default 2)")
    ap.add_argument("--scipy-duration", type=float, default=0.004,
                    help="simulated seconds for scipy on the compiled right-hand side")
    ap.add_argument("--numpy-duration", type=float, default=0.002,
                    help="simulated seconds for scipy on the NumPy right-hand side")
    ap.add_argument("--mesh-source", default="auto")
    ap.add_argument("--substeps", type=int, default=None, help="sub-steps (default: ModelSettings')")
    ap.add_argument("--repeat", type=int, default=3, help="best of this many rvdiag runs")
    ap.add_argument("--workers", type=int, default=1, help="also time N segments on N threads (N > 1)")
    ap.add_argument("--segment", type=float, default=None, help="segment length, s (default duration / N)")
    args = ap.parse_args()
    st = ModelSettings() if args.substeps is None else ModelSettings(substeps=args.substeps)
    kw = dict(input_speed_rpm=1000.0, fs=48000.0, mesh_source=args.mesh_source)
    simulate(duration_s=0.01, settings=ModelSettings(transient_s=0.0, substeps=st.substeps), **kw)  # compile
    wall = cpu = float("inf")
    for _ in range(max(1, args.repeat)):
        t0, c0 = time.perf_counter(), time.process_time()
        res = simulate(duration_s=args.duration, settings=st, **kw)
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    rate = args.duration / wall
    # the servo motor's electrical side on (signal="both": the vibration and the current of the same run), the
    # same operating point and settings: its cost per simulated second against the vibration-only run above
    (vwall, vcpu), (mwall, mcpu) = _paired_timing(args.duration, args.repeat, st, dict(kw), dict(kw, signal="both"))
    wall, cpu = min(wall, vwall), min(cpu, vcpu)
    # the same at the motor-current library's operating point (configs/mcsa.toml)
    mst = ModelSettings(substeps=4)
    mkw = dict(output_speed_deg_s=45.0, load_Nm=20.0, fs=48000.0, mesh_source=args.mesh_source,
               load_profile=LoadProfile(arm_mass_kg=15.0, arm_length_m=0.5, arm_angle_deg=0.0))
    (awall, acpu), (bwall, bcpu) = _paired_timing(args.duration, args.repeat, mst, dict(mkw),
                                                  dict(mkw, signal="current", current_fs=1000.0))

    # the cycloid-pin stage worn 5 um deep ([stage2] pin_wear_depth: a clearance table read once per pin and
    # sample), the same operating point and settings, against the unworn reducer
    worn = ReducerParams.default().replace(stage2={"pin_wear_depth": 5e-6})
    (uwall, ucpu), (wwall, wcpu) = _paired_timing(args.duration, args.repeat, st, dict(kw), dict(kw, params=worn))

    model = prepare(input_speed_rpm=1000.0, mesh_source=args.mesh_source, settings=st)
    q0 = static_equilibrium(model, 0.0)
    y0 = np.concatenate([q0, np.zeros_like(q0)])

    def scipy_rate(f, duration):
        f(0.0, y0)
        t0, c0 = time.perf_counter(), time.process_time()
        sol = solve_ivp(f, (0.0, duration), y0, method="RK45", rtol=1e-6, atol=1e-12)
        wall_s, cpu_s = time.perf_counter() - t0, time.process_time() - c0
        return duration / wall_s, duration / cpu_s, sol.nfev, wall_s

    crate_c, ccrate_c, nfev_c, swall_c = scipy_rate(make_rhs(model), args.scipy_duration)
    srate, scrate, nfev_n, swall_n = scipy_rate(ReferenceRHS(model), args.numpy_duration)
    crate = args.duration / cpu
    out = {"sim_s_per_wall_s": rate, "scipy_sim_s_per_wall_s": srate, "ratio": rate / srate,
           "sim_s_per_cpu_s": crate, "scipy_sim_s_per_cpu_s": scrate, "ratio_cpu": crate / scrate,
           "scipy_compiled_rhs_sim_s_per_wall_s": crate_c, "ratio_compiled_rhs": rate / crate_c,
           "scipy_compiled_rhs_sim_s_per_cpu_s": ccrate_c, "ratio_compiled_rhs_cpu": crate / ccrate_c,
           "substeps": int(model.settings.substeps),
           "motor_sim_s_per_wall_s": args.duration / mwall, "motor_cost_ratio": mwall / wall,
           "motor_cost_ratio_cpu": mcpu / cpu,
           "mcsa_vibration_sim_s_per_wall_s": args.duration / awall,
           "mcsa_current_sim_s_per_wall_s": args.duration / bwall,
           "motor_cost_ratio_mcsa": bwall / awall, "motor_cost_ratio_mcsa_cpu": bcpu / acpu,
           "pin_wear_cost_ratio": wwall / uwall, "pin_wear_cost_ratio_cpu": wcpu / ucpu}
    if args.workers > 1:
        seg = args.segment or args.duration / args.workers
        pst = dataclasses.replace(st, segment_s=seg)
        pwall = float("inf")
        for _ in range(max(1, args.repeat)):
            t0 = time.perf_counter()
            par = simulate(duration_s=args.duration, settings=pst, workers=args.workers, **kw)
            pwall = min(pwall, time.perf_counter() - t0)
        out.update({"workers": args.workers, "segment_s": seg, "segments": par.settings["segments"],
                    "parallel_sim_s_per_wall_s": args.duration / pwall, "parallel_speedup": wall / pwall,
                    "parallel_seam_error": float(np.linalg.norm(par.signal - res.signal)
                                                 / np.linalg.norm(res.signal))})
    if args.json:
        print(json.dumps(out))
    else:
        print(f"rvdiag {model.settings.method} (numba, {model.settings.substeps} sub-steps, {res.signal.shape[1]} samples): "
              f"{rate:.3f} simulated s per wall s ({wall:.2f} s for {args.duration:g} s)")
        print(f"scipy solve_ivp RK45 rtol 1e-6, NumPy right-hand side ({nfev_n} evaluations): {srate:.5f} "
              f"simulated s per wall s ({swall_n:.2f} s for {args.numpy_duration:g} s); ratio {rate / srate:.0f}x")
        print(f"scipy solve_ivp RK45 rtol 1e-6, compiled right-hand side ({nfev_c} evaluations): {crate_c:.5f} "
              f"simulated s per wall s ({swall_c:.2f} s for {args.scipy_duration:g} s); "
              f"ratio {rate / crate_c:.0f}x")
        print(f"with the servo motor's electrical side (signal='both'): {args.duration / mwall:.3f} simulated s per "
              f"wall s; cost {mwall / wall:.2f}x the vibration-only run per simulated second "
              f"({mcpu / cpu:.2f}x in CPU time)")
        print(f"at configs/mcsa.toml's operating point (45 deg/s, 20 N m + 15 kg arm at 0.5 m, 4 sub-steps, 48 kHz): "
              f"vibration-only {args.duration / awall:.3f}, with the motor (signal='current', 1 kHz) "
              f"{args.duration / bwall:.3f} simulated s per wall s; cost {bwall / awall:.2f}x per simulated second "
              f"({bcpu / acpu:.2f}x in CPU time; goal <= 1.3x)")
        print(f"with the cycloid-pin stage worn 5 um ([stage2] pin_wear_depth): cost {wwall / uwall:.2f}x the unworn "
              f"reducer per simulated second ({wcpu / ucpu:.2f}x in CPU time)")
        print(f"per CPU second (this process; the machine may be shared): rvdiag {crate:.3f}, "
              f"scipy NumPy RHS {scrate:.5f} (ratio {crate / scrate:.0f}x), scipy compiled RHS {ccrate_c:.5f} "
              f"(ratio {crate / ccrate_c:.0f}x)")
        if args.workers > 1:
            print(f"{out['segments']} segments of {out['segment_s']:g} s on {args.workers} threads: "
                  f"{out['parallel_sim_s_per_wall_s']:.3f} simulated s per wall s "
                  f"({out['parallel_speedup']:.2f}x the one-core run; seam error {out['parallel_seam_error']:.1e})")


if __name__ == "__main__":
    main()
