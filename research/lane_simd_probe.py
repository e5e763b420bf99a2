"""Probe: would SIMD across simulations ("lanes") on one core beat the scalar right-hand side?

An idea for issue 3's one-core goal: integrate L = 4 time segments of one record (or 4 simulations) in
lock-step, with the lane index innermost in every array, so that AVX2 computes the four in one
instruction.  This probe times the kernel that decides it, the cycloid-pin contact sum (40 pins), in
three forms, each best of 5 over 200,000 calls:

- ``scalar``: one simulation, the production loop shape (``model._pin_sums``);
- ``lanes, loop``: four simulations, the lane loop innermost (``for k: for l in range(4)``);
- ``lanes, unrolled``: four simulations, the lane loop written out with scalar locals (generated code),
  so that LLVM's SLP vectoriser can pack the lanes.

It prints ns per call, ns per simulation and the gain per simulation against ``scalar`` in the same
run, and counts the packed (``ymm``) and scalar fused multiply-adds in each kernel's assembly.
Results: bench/HISTORY.md, "fifth pass".

    .venv/bin/python research/lane_simd_probe.py
"""

from __future__ import annotations

import re
import time

import numba
import numpy as np

from rvdiag.dynamics.model import FASTMATH

LANES = 4
CALLS = 200_000


@numba.njit(fastmath=FASTMATH, error_model="numpy")
def scalar(geo, fr, out, calls):
    for _ in range(calls):
        sx = sy = sm = 0.0
        ux, uy, th, wx, wy, om = fr[0, 0], fr[1, 0], fr[2, 0], fr[3, 0], fr[4, 0], fr[5, 0]
        for k in range(geo.shape[1]):
            nx, ny, lk = geo[0, k, 0], geo[1, k, 0], geo[2, k, 0]
            d = ux * nx + uy * ny + th * lk
            f = 1e9 * d + 1e3 * (wx * nx + wy * ny + om * lk)
            f = f if d > 0.0 else 0.0
            sx += f * nx
            sy += f * ny
            sm += f * lk
        out[0, 0], out[1, 0], out[2, 0] = sx, sy, sm
        fr[0, 0] += 1e-20  # a dependency, so the calls are not hoisted


@numba.njit(fastmath=FASTMATH, error_model="numpy")
def lanes_loop(geo, fr, out, calls):
    for _ in range(calls):
        for c in range(3):
            for lane in range(LANES):
                out[c, lane] = 0.0
        for k in range(geo.shape[1]):
            for lane in range(LANES):
                nx, ny, lk = geo[0, k, lane], geo[1, k, lane], geo[2, k, lane]
                d = fr[0, lane] * nx + fr[1, lane] * ny + fr[2, lane] * lk
                f = 1e9 * d + 1e3 * (fr[3, lane] * nx + fr[4, lane] * ny + fr[5, lane] * lk)
                f = f if d > 0.0 else 0.0
                out[0, lane] += f * nx
                out[1, lane] += f * ny
                out[2, lane] += f * lk
        fr[0, 0] += 1e-20


def _unrolled_source() -> str:
    """The lane loop written out: every lane's quantities in scalar locals, statement by statement."""
    lines = ["def pin_sums_unrolled(geo, fr, out):"]
    for i in range(LANES):
        lines.append(f"    ux{i}, uy{i}, th{i} = fr[0, {i}], fr[1, {i}], fr[2, {i}]")
        lines.append(f"    wx{i}, wy{i}, om{i} = fr[3, {i}], fr[4, {i}], fr[5, {i}]")
        lines.append(f"    sx{i} = sy{i} = sm{i} = 0.0")
    lines.append("    for k in range(geo.shape[1]):")
    for template in ("nx{i}, ny{i}, lk{i} = geo[0, k, {i}], geo[1, k, {i}], geo[2, k, {i}]",
                     "d{i} = ux{i} * nx{i} + uy{i} * ny{i} + th{i} * lk{i}",
                     "f{i} = 1e9 * d{i} + 1e3 * (wx{i} * nx{i} + wy{i} * ny{i} + om{i} * lk{i})",
                     "f{i} = f{i} if d{i} > 0.0 else 0.0",
                     "sx{i} += f{i} * nx{i}", "sy{i} += f{i} * ny{i}", "sm{i} += f{i} * lk{i}"):
        lines += ["        " + template.format(i=i) for i in range(LANES)]
    lines += [f"    out[0, {i}], out[1, {i}], out[2, {i}] = sx{i}, sy{i}, sm{i}" for i in range(LANES)]
    return "\n".join(lines) + "\n"


_namespace: dict = {}
exec(_unrolled_source(), _namespace)  # noqa: S102 - generated from the fixed template above
_pin_sums_unrolled = numba.njit(fastmath=FASTMATH, error_model="numpy", inline="always")(
    _namespace["pin_sums_unrolled"])


@numba.njit(fastmath=FASTMATH, error_model="numpy")
def lanes_unrolled(geo, fr, out, calls):
    for _ in range(calls):
        _pin_sums_unrolled(geo, fr, out)
        fr[0, 0] += 1e-20


def main() -> None:
    rng = np.random.default_rng(0)
    geo = rng.standard_normal((3, 40, LANES))
    fr = rng.standard_normal((6, LANES))
    out = np.zeros((3, LANES))
    rows = []
    for name, kernel, sims in (("scalar", scalar, 1), ("lanes, loop", lanes_loop, LANES),
                               ("lanes, unrolled", lanes_unrolled, LANES)):
        kernel(geo, fr, out, 10)
        best = min(_timed(kernel, geo, fr, out) for _ in range(5))
        asm = next(iter(kernel.inspect_asm().values()))
        packed = len(re.findall(r"vfmadd\w+pd\s+%ymm", asm))
        scalar_fma = len(re.findall(r"vfmadd\w+sd", asm))
        rows.append((name, best, best / sims, packed, scalar_fma))
    base = rows[0][2]
    for name, ns, per_sim, packed, scalar_fma in rows:
        print(f"{name:16s} {ns:7.1f} ns per call, {per_sim:6.1f} ns per simulation, gain {base / per_sim:4.2f}x"
              f"  (fma: {packed} packed ymm, {scalar_fma} scalar)")


def _timed(kernel, geo, fr, out) -> float:
    t = time.process_time()
    kernel(geo, fr, out, CALLS)
    return (time.process_time() - t) / CALLS * 1e9


if __name__ == "__main__":
    main()
