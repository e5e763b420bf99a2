"""Throughput of the GPU ensemble (``rvdiag library build --device cuda``) against one CPU core, same run.

On a machine with an NVIDIA GPU and numba's CUDA target (``pip install numba-cuda``): for each layout (ensemble
index ``first`` / ``last``, :mod:`rvdiag.dynamics.gpu`) and ensemble size, ``M`` simulations of ``--samples``
samples (healthy RV-20E, 1000 rpm, rated load, 48 kHz, the default method and sub-steps unless ``--substeps``),
integrated by :func:`rvdiag.dynamics.ensemble.integrate_ensemble` (end to end: stacking, transfers, launches;
the kernel's compilation excluded by a warm-up launch, its time reported as ``compile_s``).  Reports simulated s
per wall s of the ensemble, one CPU core's rate on the same record (:func:`rvdiag.dynamics.integrate.integrate`,
wall time of that call alone), their ratio, the largest difference of the ensemble from the CPU (relative to the
signal's peak), and an estimate of the fraction of the GPU's FP64 peak used: floating-point operations per
right-hand side ~1360 (bench/HISTORY.md 2026-11-23, operation count: ~960 in the pin loop, ~400 else), times 4
right-hand sides per step (the 3/8 rule and RK4), times the steps per sample, against SMs x FP64 units per SM x 2
x clock (FP64 units per SM by compute capability from NVIDIA's CUDA C++ Programming Guide, "Arithmetic
Instructions" throughput table).  The operation count leaves out the stage-time work (geometry, mesh terms), so
the fraction is a lower bound.

Without a usable GPU it prints why and exits with code 2.  ``--ptx`` instead compiles the four kernels (two
methods x two layouts) to PTX for ``--cc`` (default 9.0) without a GPU: the check that numba's CUDA target accepts
the integrator as device code (needs numba-cuda and NVIDIA's NVVM and NVRTC, e.g. the wheels
``nvidia-cuda-nvcc-cu12`` and ``nvidia-cuda-nvrtc-cu12`` with their library folders on ``LD_LIBRARY_PATH``).

    PYTHONPATH=src python bench/gpu_ensemble.py [--sizes 1024,4096,16384] [--layouts last,first] [--samples 2400]
    PYTHONPATH=src python bench/gpu_ensemble.py --ptx [--cc 9.0]

Writes ``$OUT/gpu_ensemble.json`` when ``$OUT`` is set.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

#: FP64 units per SM by compute capability (CUDA C++ Programming Guide, arithmetic instruction throughput)
FP64_PER_SM = {(6, 0): 32, (7, 0): 32, (8, 0): 32, (9, 0): 64}
#: flops of one right-hand side (bench/HISTORY.md 2026-11-23, operation count)
RHS_FLOPS = 1360


def _model(substeps: int | None, n: int):
    from rvdiag.dynamics import ModelSettings, initial_deflection, prepare

    kw = {"chunk_samples": n} if substeps is None else {"chunk_samples": n, "substeps": substeps}
    m = prepare(input_speed_rpm=1000.0, settings=ModelSettings(**kw))
    q0, _ = initial_deflection(m, 0.0)
    return m, m.initial_state(q0, 0.0)


def fp64_peak(cuda) -> float | None:
    """Estimated FP64 peak (flop/s) of the current GPU, or None for an unlisted compute capability."""
    dev = cuda.get_current_device()
    per_sm = FP64_PER_SM.get(tuple(dev.compute_capability), 2 if dev.compute_capability[0] >= 6 else None)
    if per_sm is None:
        return None
    return dev.MULTIPROCESSOR_COUNT * per_sm * 2.0 * dev.CLOCK_RATE * 1e3


def throughput(args) -> dict:
    from rvdiag.dynamics import gpu
    from rvdiag.dynamics.ensemble import IntegrationRequest, integrate_ensemble
    from rvdiag.dynamics.integrate import integrate

    try:
        cuda = gpu.load_cuda()
    except gpu.DeviceUnavailable as exc:
        print(f"bench/gpu_ensemble.py needs a CUDA GPU: {exc} (--ptx compiles the kernels without one)",
              file=sys.stderr)
        sys.exit(2)
    fs, n = 48000.0, args.samples
    m, y0 = _model(args.substeps, n)
    S = int(m.settings.substeps)
    res: dict = {"device": gpu.device_name(cuda), "method": m.settings.method, "substeps": S, "samples": n,
                 "fs": fs, "rows": []}
    peak = None if gpu.is_simulator() else fp64_peak(cuda)
    res["fp64_peak_flops_estimate"] = peak
    integrate(m, y0, fs, 10)  # loads the CPU kernels
    t0 = time.perf_counter()
    ref, _ = integrate(m, y0, fs, n)
    res["cpu_one_core_sim_s_per_s"] = n / fs / (time.perf_counter() - t0)
    print(json.dumps({k: v for k, v in res.items() if k != "rows"}), flush=True)
    for layout in args.layouts.split(","):
        t0 = time.perf_counter()
        integrate_ensemble([IntegrationRequest(m, y0, fs, 1)], layout=layout)  # compiles the kernel
        res[f"compile_s_{layout}"] = time.perf_counter() - t0
        for M in (int(x) for x in args.sizes.split(",")):
            reqs = [IntegrationRequest(m, y0, fs, n)] * M
            t0 = time.perf_counter()
            out = integrate_ensemble(reqs, layout=layout, block=args.block)
            dt = time.perf_counter() - t0
            ok = [o for o in out if not isinstance(o, Exception)]
            diff = max(float(np.abs(o[0] - ref).max()) for o in ok[:4]) / float(np.abs(ref).max()) if ok else None
            rate = M * n / fs / dt
            row = {"layout": layout, "M": M, "block": args.block, "wall_s": dt, "sim_s_per_wall_s": rate,
                   "ratio_to_one_core": rate / res["cpu_one_core_sim_s_per_s"], "ok": len(ok),
                   "max_rel_diff_vs_cpu": diff}
            if peak:  # steps per sample: the sub-steps (the few extra steps at mesh-table events left out)
                row["fp64_fraction_estimate"] = rate * fs * S * 4 * RHS_FLOPS / peak
            res["rows"].append(row)
            print(json.dumps(row), flush=True)
    return res


def ptx(args) -> dict:
    """Compile the four kernels to PTX for compute capability ``args.cc`` without a GPU."""
    from rvdiag.dynamics import gpu
    from rvdiag.dynamics.ensemble import _work_shapes

    if not hasattr(np, "row_stack"):
        np.row_stack = np.vstack
    from numba import cuda, types

    try:  # numba-cuda types an njit function called from a kernel for the current device's compute capability
        import numba.cuda.dispatcher as dispatcher

        cc = tuple(int(x) for x in args.cc.split("."))
        dispatcher.get_current_device = lambda: type("Device", (), {"compute_capability": cc})()
    except (ImportError, AttributeError) as exc:
        print(f"cannot set the target without a GPU ({exc})", file=sys.stderr)
        sys.exit(2)
    gpu.load_cuda = lambda: cuda  # compile only: no device needed
    res: dict = {"cc": args.cc, "kernels": []}
    for method in ("rk38", "rk4"):
        from rvdiag.dynamics import ModelSettings, prepare

        m = prepare(input_speed_rpm=1000.0, settings=ModelSettings(method=method))
        shapes = [(m.n_state,), m.P.shape, m.inv_mass.shape, m.planet.shape, m.tables.shape, m.cosk.shape,
                  m.sink.shape, m.sensor.shape, (m.sensor.shape[0], 8)] + _work_shapes(m)
        for layout in gpu.LAYOUTS:
            kern = gpu._make_kernel(method, layout)
            sig = ((types.int64, types.int64, types.int64, types.float64, types.boolean)
                   + tuple(types.Array(types.float64, len(s) + 1, "C") for s in shapes)
                   + (types.float64[:, ::1], types.int64[::1]) * 3 + (types.int64[:, ::1],))
            t0 = time.perf_counter()
            try:
                code, _ = cuda.compile_ptx(kern.py_func, sig, cc=cc)
                row = {"method": method, "layout": layout, "ptx_chars": len(code),
                       "compile_s": time.perf_counter() - t0}
            except Exception as exc:  # noqa: BLE001 - report and go on with the other kernels
                row = {"method": method, "layout": layout, "error": " ".join(str(exc).split())[:2000]}
            res["kernels"].append(row)
            print(json.dumps(row), flush=True)
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1024,4096,16384", help="ensemble sizes (comma-separated)")
    ap.add_argument("--layouts", default="last,first", help="ensemble index last and/or first")
    ap.add_argument("--samples", type=int, default=2400, help="samples per simulation (48 kHz)")
    ap.add_argument("--substeps", type=int, default=None, help="sub-steps per sample (default: ModelSettings')")
    ap.add_argument("--block", type=int, default=64, help="threads per block")
    ap.add_argument("--ptx", action="store_true", help="compile the kernels to PTX only (no GPU needed)")
    ap.add_argument("--cc", default="9.0", help="--ptx: compute capability to compile for")
    args = ap.parse_args()
    res = ptx(args) if args.ptx else throughput(args)
    out = os.environ.get("OUT")
    if out:
        with open(os.path.join(out, "gpu_ensemble.json"), "w") as f:
            json.dump(res, f, indent=1)
    if not args.ptx and res["rows"]:
        best = max(res["rows"], key=lambda r: r["sim_s_per_wall_s"])
        print(f"best: {best['sim_s_per_wall_s']:.1f} simulated s per s ({best['layout']}, M = {best['M']}), "
              f"{best['ratio_to_one_core']:.1f}x one core ({res['cpu_one_core_sim_s_per_s']:.2f})"
              + (f", ~{100 * best['fp64_fraction_estimate']:.1f} % of the FP64 peak (lower bound)"
                 if "fp64_fraction_estimate" in best else ""))


if __name__ == "__main__":
    main()
