"""How much each tooth fault changes the simulated housing vibration, with and without wear as a
transmission-error (profile-deviation) excitation.

Operating point of the fault library engineer's table (docs/library.md, "How visible are the
faults?"): output 45 deg/s, load 75 N m, x acceleration, no noise, 0.3 s after the default 0.1 s
transient, 48 kHz, default model settings; faults from ``rvdiag.library.states.tooth_faults`` (the
library's own mapping: broken and cracked tooth 0 of the sun, wear on every sun tooth).

Columns, each against the healthy signal ``h`` of the same model:

- ``rel_diff``: relative RMS difference ``||s - h|| / ||h||`` (the library engineer's metric);
- ``rms_ratio``: ``rms(s) / rms(h)``;
- ``mesh_dB``: mean absolute change (dB) of the Hann-windowed amplitude at the first 40 stage-1
  mesh harmonics ``n f_sp`` (largest bin within +-1 bin).

``stiffness only`` is the model before the profile deviation entered (the table's ``error_m`` set
to zero: wear only as lost stiffness); ``with TE`` is the current model (``MeshTable.error_m`` from
``rvdiag.gears.mesh_stiffness(...).profile_error_m``).  The last row ``wear 20 um, least-worn pair``
replaces the load-shared deviation ``sum k_i e_i / sum k_i`` by the smallest deviation of the pairs
in contact (the pair that actually touches when the deviations differ by far more than the static
deflection), to show how much the load-sharing assumption matters.  Below the table, T5 and T6 are
compared with T2 (whole tooth missing) by the same ``rel_diff``.

Usage: ``python bench/fault_sensitivity.py [--duration S] [--json]``  (about 30-60 s on one core).
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from rvdiag.dynamics import mesh_table, simulate  # noqa: E402
from rvdiag.dynamics.mesh import TWO_PI, MeshTable  # noqa: E402
from rvdiag.gears import GearPair, mesh_stiffness  # noqa: E402
from rvdiag.kinematics import sun_speed_hz  # noqa: E402
from rvdiag.library.states import tooth_faults  # noqa: E402
from rvdiag.params import ReducerParams  # noqa: E402

SPEED_DEG_S = 45.0
LOAD_NM = 75.0
FS = 48000.0

CASES = [
    ("wear 20 um", "T3", {"wear_depth": 20e-6}),
    ("wear 100 um", "T3", {"wear_depth": 100e-6}),
    ("crack 0.5 mm at 45 deg", "T4", {"crack_depth": 0.5e-3, "crack_angle_deg": 45.0}),
    ("crack 1 mm at 30 deg", "T4", {"crack_depth": 1.0e-3, "crack_angle_deg": 30.0}),
    ("crack 1.6 mm at 45 deg", "T4", {"crack_depth": 1.6e-3, "crack_angle_deg": 45.0}),
    ("crack 2 mm at 45 deg", "T4", {"crack_depth": 2.0e-3, "crack_angle_deg": 45.0}),
    ("broken fraction 0.3", "T2", {"broken_fraction": 0.3}),
    ("whole tooth missing", "T2", {"broken_fraction": 1.0}),
    ("broken + wear 20 um (T5)", "T5", {"broken_fraction": 1.0, "wear_depth": 20e-6}),
    ("broken + wear + crack (T6)", "T6", {"broken_fraction": 1.0, "wear_depth": 20e-6,
                                          "crack_depth": 0.8e-3, "crack_angle_deg": 45.0}),
]
#: pairs (case, reference case) also compared with each other: can T5/T6 be told from T2?
VERSUS = [("broken + wear 20 um (T5)", "whole tooth missing"), ("broken + wear + crack (T6)", "whole tooth missing")]


def least_worn_pair_table(params: ReducerParams, fault) -> MeshTable:
    """Mesh table whose deviation is the smallest wear depth of the pairs in contact at each angle."""
    pair = GearPair.sun_planet(params)
    z1 = params.stage1.sun_teeth
    res = mesh_stiffness(pair, fault=fault, cycles=z1, points_per_cycle=360)
    k = res.pair_stiffness_N_per_m
    e = np.where(k > 0, res.pair_profile_error_m, np.inf).min(axis=0)
    e = np.where(np.isfinite(e), e, 0.0)
    angle = res.angle_rad - res.angle_rad[0]
    return MeshTable(angle, res.stiffness_N_per_m, TWO_PI, "least-worn pair", error_m=e)


def mesh_harmonic_change_db(s: np.ndarray, h: np.ndarray, f_mesh: float, n_harm: int = 40) -> float:
    """Mean |20 log10(A_s / A_h)| over the first ``n_harm`` mesh harmonics (Hann window, +-1 bin)."""
    w = np.hanning(s.size)
    A_s = np.abs(np.fft.rfft(s * w))
    A_h = np.abs(np.fft.rfft(h * w))
    df = FS / s.size
    out = []
    for n in range(1, n_harm + 1):
        b = int(round(n * f_mesh / df))
        if b + 1 >= A_h.size:
            break
        a_s = A_s[b - 1:b + 2].max()
        a_h = A_h[b - 1:b + 2].max()
        out.append(abs(20 * np.log10(a_s / a_h)))
    return float(np.mean(out))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=0.3, help="recorded seconds per simulation")
    ap.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    args = ap.parse_args()
    P0 = ReducerParams.default()
    kw = dict(output_speed_deg_s=SPEED_DEG_S, duration_s=args.duration, fs=FS)
    fsun = sun_speed_hz(P0, None, SPEED_DEG_S)
    f_mesh = P0.stage1.sun_teeth * fsun * (1 - 1 / P0.ratio)
    t0 = time.perf_counter()

    def x(table, load=LOAD_NM) -> np.ndarray:
        return simulate(P0, table, load_Nm=load, **kw).signal[0]

    healthy = x(mesh_table(P0))
    rows = []

    def row(name: str, s_old: np.ndarray | None, s_new: np.ndarray) -> None:
        r = {"case": name}
        for tag, s in (("stiffness_only", s_old), ("with_te", s_new)):
            if s is None:
                continue
            r[tag] = {
                "rel_diff": float(np.linalg.norm(s - healthy) / np.linalg.norm(healthy)),
                "rms_ratio": float(np.sqrt(np.mean(s**2)) / np.sqrt(np.mean(healthy**2))),
                "mesh_dB": mesh_harmonic_change_db(s, healthy, f_mesh),
            }
        rows.append(r)

    sigs = {}
    for name, state, sev in CASES:
        tab = mesh_table(P0, tooth_faults(state, **sev))
        s_new = x(tab)
        s_old = x(dataclasses.replace(tab, error_m=None)) if tab.has_error else s_new
        sigs[name] = (s_old, s_new)
        row(name, s_old, s_new)
    versus = []
    for a, b in VERSUS:
        versus.append({"case": a, "reference": b, **{
            tag: float(np.linalg.norm(sigs[a][j] - sigs[b][j]) / np.linalg.norm(sigs[b][j]))
            for j, tag in enumerate(("stiffness_only", "with_te"))}})
    row("load 75 -> 90 N m (healthy)", None, x(mesh_table(P0), 90.0))
    row("wear 20 um, least-worn pair", None, x(least_worn_pair_table(P0, tooth_faults("T3", wear_depth=20e-6))))
    wall = time.perf_counter() - t0
    if args.json:
        print(json.dumps({"rows": rows, "versus": versus, "wall_s": wall, "f_mesh_hz": f_mesh}, indent=1))
        return
    print(f"output {SPEED_DEG_S} deg/s, {LOAD_NM} N m, x channel, {args.duration} s, fs {FS:g} Hz, "
          f"f_sp = {f_mesh:.2f} Hz; wall {wall:.1f} s")
    hdr = f"{'case':32s} | {'stiffness only':^30s} | {'with TE (current)':^30s}"
    print(hdr)
    print(f"{'':32s} | {'rel diff':>10s} {'RMS x':>8s} {'mesh dB':>9s} | {'rel diff':>10s} {'RMS x':>8s} {'mesh dB':>9s}")
    print("-" * len(hdr))
    for r in rows:
        def cells(tag: str) -> str:
            if tag not in r:
                return f"{'-':>10s} {'-':>8s} {'-':>9s}"
            v = r[tag]
            return f"{100 * v['rel_diff']:9.3g}% {v['rms_ratio']:8.3g} {v['mesh_dB']:9.3g}"
        print(f"{r['case']:32s} | {cells('stiffness_only')} | {cells('with_te')}")
    for v in versus:
        print(f"{v['case']} vs {v['reference']}: rel diff {100 * v['stiffness_only']:.3g} % (stiffness only), "
              f"{100 * v['with_te']:.3g} % (with TE)")


if __name__ == "__main__":
    main()
