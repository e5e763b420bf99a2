"""GPU ensemble probe: numba-cuda compiles the CPU integrator ``rk4_run`` as a device function.

One CUDA thread per simulation calls :func:`rvdiag.dynamics.integrate.rk4_run` on its own views of
ensemble arrays.  Prints the agreement with the CPU integrator and the ensemble throughput (simulated s
per wall s) for two memory layouts, and one CPU core's rate in the same run.  Needs a CUDA GPU and
numba-cuda; on numpy >= 2.5 numba-cuda needs ``np.row_stack`` (:func:`_setup` aliases it, only when the
probe runs).  Results: bench/HISTORY.md
2026-11-23 "GPU ensemble, probed (not built)".

    PYTHONPATH=src python research/gpu_ensemble_probe.py        # writes $OUT/gpu_probe.json (or /tmp)

Environment: ``PROBE_N`` samples of the correctness run (480), ``PROBE_SKIP_SCALING=1`` to skip the
throughput runs.
"""
import json
import os
import time

import numpy as np

from rvdiag.dynamics import model as mdl
from rvdiag.dynamics import prepare
from rvdiag.dynamics.integrate import integrate, rk4_run
from rvdiag.dynamics.linear import static_equilibrium

cuda = kern = kernT = None  # set by _setup(), when the probe runs


def _setup():
    """Import numba-cuda and compile the kernels.  numba-cuda still calls ``np.row_stack``, which numpy >= 2.5
    removed: alias it here, in the probe's own process and only when it is missing, never at import."""
    global cuda, kern, kernT
    if not hasattr(np, "row_stack"):
        np.row_stack = np.vstack
    from numba import cuda as _cuda

    cuda = _cuda

    @cuda.jit
    def kern(Y, k_start, n_samples, S, fs, P, inv_mass, planet, tables, cosk, sink, sensor, events, OUT,
             G0, R0, M0, G1, R1, M1, G2, R2, M2, G3, R3, G4, R4, Q, K1, K2, K3, YT, BR, GR, ST):
        """One simulation per thread; the ensemble index first (each thread's arrays contiguous)."""
        i = cuda.grid(1)
        if i < Y.shape[0]:
            st, s = rk4_run(Y[i], k_start, n_samples, S, fs, True, P[i], inv_mass[i], planet[i], tables[i], cosk, sink,
                            sensor, OUT[i], G0[i], R0[i], M0[i], G1[i], R1[i], M1[i], G2[i], R2[i], M2[i], G3[i], R3[i],
                            G4[i], R4[i], Q[i], K1[i], K2[i], K3[i], YT[i], events, BR[i], GR[i])
            ST[i, 0] = st
            ST[i, 1] = s


    @cuda.jit
    def kernT(Y, k_start, n_samples, S, fs, P, inv_mass, planet, tables, cosk, sink, sensor, events, OUT,
              G0, R0, M0, G1, R1, M1, G2, R2, M2, G3, R3, G4, R4, Q, K1, K2, K3, YT, BR, GR, ST):
        """:func:`kern` with the ensemble index last: neighbouring threads touch neighbouring addresses."""
        i = cuda.grid(1)
        if i < Y.shape[1]:
            st, s = rk4_run(Y[:, i], k_start, n_samples, S, fs, True, P[:, i], inv_mass[:, i], planet[:, :, i],
                            tables[:, :, i], cosk, sink, sensor, OUT[:, :, i], G0[:, :, :, i], R0[:, :, i], M0[:, :, i],
                            G1[:, :, :, i], R1[:, :, i], M1[:, :, i], G2[:, :, :, i], R2[:, :, i], M2[:, :, i],
                            G3[:, :, :, i], R3[:, :, i], G4[:, :, :, i], R4[:, :, i], Q[:, i], K1[:, i], K2[:, i],
                            K3[:, i], YT[:, i], events, BR[:, i], GR[:, i])
            ST[i, 0] = st
            ST[i, 1] = s


def run_ensemble(models, y0s, fs, n, block=64, index_last=False):
    """Integrate ``models`` from ``y0s`` for ``n`` samples, one CUDA thread each; returns the signals
    (models first), the kernel statuses and the kernel's wall time.  All models must share their shapes
    and table events (here: copies of one model)."""
    M = len(models)
    m0 = models[0]
    n2 = 2 * m0.n_dof
    nd, nz, npl = m0.n_discs, m0.cosk.size, m0.n_planets
    S = m0.settings.substeps
    f_rel = abs(m0.P[mdl.I_WREL]) / (2.0 * np.pi)
    nbr = m0.events.size * (int(f_rel / fs) + 2) + 1  # as in rvdiag.dynamics.integrate.integrate

    def put(arrays):
        a = np.asarray(arrays)
        return cuda.to_device(np.ascontiguousarray(np.moveaxis(a, 0, -1) if index_last else a))

    def alloc(*shape):
        return cuda.device_array(shape + (M,) if index_last else (M,) + shape)

    Y = put(y0s)
    P, IM = put([m.P for m in models]), put([m.inv_mass for m in models])
    PL, TB = put([m.planet for m in models]), put([m.tables for m in models])
    OUT = alloc(m0.sensor.shape[0], n)
    G = [alloc(nd, 3, nz) for _ in range(5)]
    R = [alloc(nd, 4) for _ in range(5)]
    MT = [alloc(npl, 3) for _ in range(3)]
    Q = alloc(m0.n_dof)
    K = [alloc(n2) for _ in range(4)]
    BR, GR = alloc(nbr), alloc(S + nbr + 2)
    ST = cuda.device_array((M, 2), dtype=np.int64)
    grid = (M + block - 1) // block
    kernel = kernT if index_last else kern
    shared = [cuda.to_device(a) for a in (m0.cosk, m0.sink, m0.sensor, m0.events)]
    cuda.synchronize()
    t0 = time.perf_counter()
    kernel[grid, block](Y, 0, n, S, fs, P, IM, PL, TB, *shared, OUT, G[0], R[0], MT[0], G[1], R[1], MT[1], G[2], R[2],
                        MT[2], G[3], R[3], G[4], R[4], Q, K[0], K[1], K[2], K[3], BR, GR, ST)
    cuda.synchronize()
    dt = time.perf_counter() - t0
    out = OUT.copy_to_host()
    return (np.moveaxis(out, -1, 0) if index_last else out), ST.copy_to_host(), dt


def main():
    _setup()
    dev = cuda.get_current_device() if hasattr(cuda, "get_current_device") else None
    res = {"device": str(getattr(dev, "name", "simulator"))}
    print(res, flush=True)
    fs = 48000.0
    base = prepare(input_speed_rpm=1000.0)
    q0 = static_equilibrium(base, 0.0); y0 = np.concatenate([q0, np.zeros_like(q0)])
    n = int(os.environ.get("PROBE_N", 480))
    t0 = time.perf_counter()
    try:
        out, st, dt = run_ensemble([base, base], [y0, y0], fs, n, index_last=True)
        res["compile_and_first_run_s"] = time.perf_counter() - t0
        ref, _ = integrate(base, y0, fs, n)
        res["max_rel_diff_vs_cpu"] = float(np.abs(out[0] - ref).max() / np.abs(ref).max())
        res["status"] = st.tolist()
    except Exception as e:
        import traceback; traceback.print_exc()
        res["error"] = repr(e)[:2000]
    print(json.dumps(res), flush=True)
    if "error" not in res and not os.environ.get("PROBE_SKIP_SCALING"):
        n = 2400
        for layout, last, sizes in (("ensemble index first", False, (256, 1024, 4096, 8192)),
                                    ("ensemble index last", True, (1024, 4096, 16384, 32768))):
            for M in sizes:
                block = 32
                out, st, dt = run_ensemble([base] * M, [y0] * M, fs, n, block, index_last=last)
                r = {"layout": layout, "M": M, "block": block, "wall_s": dt, "sim_s_per_wall_s": M * n / fs / dt,
                     "ok": int((st[:, 0] == 0).sum())}
                print(json.dumps(r), flush=True)
                res.setdefault("scaling", []).append(r)
    # CPU reference in the same run, one core
    t0 = time.process_time()
    integrate(base, y0, fs, 24000)
    res["cpu_one_core_sim_s_per_cpu_s"] = 0.5 / (time.process_time() - t0)
    print(json.dumps(res), flush=True)
    out_dir = os.environ.get("OUT", "/tmp")
    json.dump(res, open(os.path.join(out_dir, "gpu_probe.json"), "w"), indent=1)


if __name__ == "__main__":
    main()
