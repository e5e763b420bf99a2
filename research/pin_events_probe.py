"""Probe: does locating the pin-contact switches let a higher-order fixed-step scheme take fewer steps?

Issue 3's one-core speed goal needs about 15 right-hand sides (RHS) per output sample instead of RK4's
36 at the 1e-3 accuracy.  Earlier passes (bench/HISTORY.md, docs/model.md section 7) found that the
higher-order schemes stall on the model's non-smooth events.  The mesh-table kinks are now step
boundaries in production; this probe also **locates the cycloid-pin contact switches**:

- each step holds the contact state of every pin fixed (a "mode": the pin's geometry is zeroed when
  out of contact, and every contact in the mode is treated as closed), so the right-hand side is smooth
  within the step;
- after a step the contact indicators ``d_k`` (docs/model.md section 4) are evaluated at its end; if
  one disagrees with the mode, the earliest crossing (linear estimate) is located by a safeguarded
  secant iteration on ``d_k(t)`` with the same scheme, the step is cut there and the pin's mode
  flipped.

Every scheme runs in a generic Butcher-tableau loop on the compiled kernels (exact geometry and mesh
terms at every stage time, on production's event-cut step grid).  The mesh is made bilateral (the
healthy, loaded mesh never separates at these operating points).  The baseline in the same run is
production's ``integrate()`` (RK4, 9 sub-steps).  Each is compared with scipy DOP853 (rtol 1e-9,
atol 1e-15) over 0.05 s by the relative L2 error of the sensor signal, as
``tests/test_integrator.py::test_matches_scipy_dop853_over_50ms``.

    .venv/bin/python research/pin_events_probe.py [--cases 45,1000,3000] [--schemes rk4:9,dop853:1,...]
        [--cache out/probe_refs]

The references are cached (a few seconds each to recompute).  Results: bench/HISTORY.md, "fifth pass".
This is an accuracy probe; its loop is not a speed measurement.
"""

from __future__ import annotations

import argparse
import math
import os

import numba
import numpy as np
from scipy.integrate import solve_ivp
from scipy.integrate._ivp import dop853_coefficients
from scipy.integrate._ivp.rk import RK45

from rvdiag.dynamics import prepare
from rvdiag.dynamics import model as mdl
from rvdiag.dynamics.integrate import integrate, sample_breaks, step_grid
from rvdiag.dynamics.linear import static_equilibrium

FM = mdl.FASTMATH
CASES = {
    "45": ("45 deg/s 100 N m", dict(output_speed_deg_s=45.0, load_Nm=100.0)),
    "1000": ("1000 rpm rated", dict(input_speed_rpm=1000.0)),
    "3000": ("3000 rpm 50 N m", dict(input_speed_rpm=3000.0, load_Nm=50.0)),
}


def tableau(name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, b, c) of classical RK4, Dormand-Prince 5 (scipy's RK45), Butcher's 6th order (1964) or DOP853."""
    if name == "rk4":
        A = np.array([[0, 0, 0, 0], [.5, 0, 0, 0], [0, .5, 0, 0], [0, 0, 1, 0]], float)
        b, c = np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]), np.array([0, .5, .5, 1])
    elif name == "dp5":
        A = np.zeros((6, 6))
        A[:, :5] = RK45.A
        b, c = RK45.B, RK45.C
    elif name == "butcher6":
        A, c = np.zeros((7, 7)), np.array([0, 1 / 3, 2 / 3, 1 / 3, 1 / 2, 1 / 2, 1])
        A[1, 0] = 1 / 3
        A[2, 1] = 2 / 3
        A[3, :3] = [1 / 12, 1 / 3, -1 / 12]
        A[4, :4] = [-1 / 16, 9 / 8, -3 / 16, -3 / 8]
        A[5, :5] = [0, 9 / 8, -3 / 8, -3 / 4, 1 / 2]
        A[6, :6] = [9 / 44, -9 / 11, 63 / 44, 18 / 11, 0, -16 / 11]
        b = np.array([11 / 120, 0, 27 / 40, 27 / 40, -4 / 15, -4 / 15, 11 / 120])
    elif name == "dop853":
        s = dop853_coefficients.N_STAGES
        A, b, c = dop853_coefficients.A[:s, :s], dop853_coefficients.B, dop853_coefficients.C[:s]
    else:
        raise SystemExit(f"unknown scheme {name!r}: use rk4, dp5, butcher6 or dop853")
    return np.ascontiguousarray(A, float), np.ascontiguousarray(b, float), np.ascontiguousarray(c, float)


@numba.njit(fastmath=FM)
def rhs_in_mode(t, y, P, invm, planet, tv, cosk, sink, geo, rot, mt, Q, out, mode):
    """The model's right-hand side with pin k of disc j in contact iff ``mode[j, k]`` (P bilateral)."""
    mdl.pin_geometry(t, P, cosk, sink, geo, rot)
    for j in range(geo.shape[0]):
        for k in range(geo.shape[2]):
            if mode[j, k] == 0:
                geo[j, 0, k] = 0.0
                geo[j, 1, k] = 0.0
                geo[j, 2, k] = 0.0
    mdl.mesh_terms(t, P, tv, mt)
    mdl.rhs_with_terms(y, P, invm, planet, mt, geo, rot, Q, out)


@numba.njit(fastmath=FM)
def contact_indicators(t, y, P, cosk, sink, geo, rot, d):
    """``d[j, k]``: the approach of pin k and disc j (> 0: in contact), docs/model.md section 4."""
    mdl.pin_geometry(t, P, cosk, sink, geo, rot)
    n = y.size // 2
    iD0 = 3 + 6 * int(P[mdl.I_NPL])
    iR = n - 3
    rr = P[mdl.I_ZP] / P[mdl.I_ZC]
    for j in range(int(P[mdl.I_NDISC])):
        a = mdl._disc_frame(j, y, n, rot, iD0, y[iR], y[iR + 1], y[iR + 2], y[n + iR], y[n + iR + 1],
                            y[n + iR + 2], rr)
        for k in range(geo.shape[2]):
            d[j, k] = a[0] * geo[j, 0, k] + a[1] * geo[j, 1, k] + a[2] * geo[j, 2, k]


@numba.njit(fastmath=FM)
def rk_step(ta, h, y, ynew, K, yt, A, b, c, P, invm, planet, tv, cosk, sink, geo, rot, mt, Q, mode):
    """One explicit Runge-Kutta step of the tableau (A, b, c) in a fixed contact mode; returns the RHS count."""
    n2 = y.size
    ns = b.size
    for st in range(ns):
        for i in range(n2):
            acc = 0.0
            for m in range(st):
                acc += A[st, m] * K[m, i]
            yt[i] = y[i] + h * acc
        rhs_in_mode(ta + c[st] * h, yt, P, invm, planet, tv, cosk, sink, geo, rot, mt, Q, K[st], mode)
    for i in range(n2):
        acc = 0.0
        for m in range(ns):
            acc += b[m] * K[m, i]
        ynew[i] = y[i] + h * acc
    return ns


@numba.njit(fastmath=FM)
def run_located(y, n_samples, S, fs, P, invm, planet, tv, cosk, sink, sensor, out, events, A, b, c):
    """Integrate with pin switches located; returns (RHS evaluations, located switches, switches found
    unlocated beside a located one)."""
    n2 = y.size
    n = n2 // 2
    iR = n - 3
    D = int(P[mdl.I_NDISC])
    nz = cosk.size
    geo = np.zeros((D, 3, nz))
    rot = np.zeros((D, 4))
    mt = np.zeros((planet.shape[0], 3))
    Q = np.zeros(n)
    K = np.zeros((b.size, n2))
    yt = np.zeros(n2)
    ynew = np.zeros(n2)
    ytry = np.zeros(n2)
    d0 = np.zeros((D, nz))
    d1 = np.zeros((D, nz))
    mode = np.zeros((D, nz), np.int64)
    dts = 1.0 / fs
    hnom = dts / S
    f_rel = P[mdl.I_WREL] / (2 * math.pi)
    breaks = np.zeros(200)
    grid = np.zeros(S + 210)
    sx = P[mdl.I_SENSX]
    sy = P[mdl.I_SENSY]
    n_rhs = 0
    located = 0
    unlocated = 0
    contact_indicators(0.0, y, P, cosk, sink, geo, rot, d0)
    for j in range(D):
        for k in range(nz):
            mode[j, k] = 1 if d0[j, k] > 0 else 0
    for s in range(n_samples):
        t0 = s * dts
        nb = sample_breaks(t0, dts, f_rel, events, 1e-6 * hnom, breaks)
        M = step_grid(t0, (s + 1) * dts, S, hnom, breaks, nb, grid)
        for jg in range(M):
            pos = grid[jg]
            t1 = grid[jg + 1]
            first = jg == 0
            d0_current = False  # d0 holds the indicators at pos
            while True:
                h = t1 - pos
                n_rhs += rk_step(pos, h, y, ynew, K, yt, A, b, c, P, invm, planet, tv, cosk, sink, geo, rot,
                                 mt, Q, mode)
                if first:  # the sensor at the sample's start, from the first stage
                    ax = K[0, n + iR] - K[0, n + iR + 2] * sy
                    ay = K[0, n + iR + 1] + K[0, n + iR + 2] * sx
                    for ch in range(sensor.shape[0]):
                        out[ch, s] = sensor[ch, 0] * ax + sensor[ch, 1] * ay
                    first = False
                contact_indicators(t1, ynew, P, cosk, sink, geo, rot, d1)
                best = 2.0
                bj = -1
                bk = -1
                for j in range(D):
                    for k in range(nz):
                        if (d1[j, k] > 0) != (mode[j, k] == 1):
                            if not d0_current:
                                contact_indicators(pos, y, P, cosk, sink, geo, rot, d0)
                                d0_current = True
                            fr = d0[j, k] / (d0[j, k] - d1[j, k]) if d0[j, k] != d1[j, k] else 0.5
                            fr = min(max(fr, 0.0), 1.0)
                            if fr < best:
                                best, bj, bk = fr, j, k
                if bj < 0:
                    y[:] = ynew
                    break
                # safeguarded secant for the crossing of pin (bj, bk) in (pos, t1)
                ta, ga, tb, gb = 0.0, d0[bj, bk], h, d1[bj, bk]
                tau = best * h
                for it in range(8):
                    n_rhs += rk_step(pos, tau, y, ytry, K, yt, A, b, c, P, invm, planet, tv, cosk, sink, geo,
                                     rot, mt, Q, mode)
                    contact_indicators(pos + tau, ytry, P, cosk, sink, geo, rot, d1)
                    g = d1[bj, bk]
                    if (g > 0) == (ga > 0):
                        ta, ga = tau, g
                    else:
                        tb, gb = tau, g
                    nxt = tau - g * (tb - ta) / (gb - ga) if gb != ga else 0.5 * (ta + tb)
                    if not (ta < nxt < tb):
                        nxt = 0.5 * (ta + tb)
                    if g == 0.0 or abs(nxt - tau) < 1e-14 * dts or it == 7:
                        break  # ytry holds the step to pos + tau
                    tau = nxt
                y[:] = ytry
                pos += tau
                mode[bj, bk] = 1 - mode[bj, bk]
                located += 1
                contact_indicators(pos, y, P, cosk, sink, geo, rot, d0)
                d0_current = True
                for j in range(D):
                    for k in range(nz):
                        if not (j == bj and k == bk) and (d0[j, k] > 0) != (mode[j, k] == 1):
                            mode[j, k] = 1 - mode[j, k]
                            unlocated += 1
                if t1 - pos < 1e-9 * dts:
                    break
    return n_rhs, located, unlocated


def reference(key: str, cache: str, fs: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(initial state, scipy DOP853 sensor signal) for a case; cached as .npz in ``cache``."""
    fn = os.path.join(cache, f"ref_{key}.npz")
    if os.path.exists(fn):
        z = np.load(fn)
        return z["y0"], z["ref"]
    m = prepare(**CASES[key][1])
    q0 = static_equilibrium(m, 0.0)
    y0 = np.concatenate([q0, np.zeros_like(q0)])
    f = mdl.make_rhs(m)
    te = np.arange(n) / fs
    sol = solve_ivp(f, (0, te[-1]), y0, method="DOP853", rtol=1e-9, atol=1e-15, t_eval=te)
    ref = mdl.sensor_acceleration(m, np.array([f(t, sol.y[:, k])[m.n_dof:] for k, t in enumerate(te)]))
    os.makedirs(cache, exist_ok=True)
    np.savez(fn, y0=y0, ref=ref)
    return y0, ref


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default="45,1000,3000", help="comma list of " + ", ".join(CASES))
    ap.add_argument("--schemes", default="rk4:9,rk4:8,dp5:4,butcher6:4,dop853:1,dop853:2",
                    help="comma list of scheme:steps-per-sample")
    ap.add_argument("--cache", default="out/probe_refs", help="folder for the cached scipy references")
    a = ap.parse_args()
    fs, n = 48000.0, 2400
    for key in a.cases.split(","):
        if key not in CASES:
            raise SystemExit(f"unknown case {key!r}: use {', '.join(CASES)}")
        label, op = CASES[key]
        y0, ref = reference(key, a.cache, fs, n)
        m = prepare(**op)
        sig, _ = integrate(m, y0, fs, n)
        base = np.linalg.norm(sig - ref) / np.linalg.norm(ref)
        print(f"{label}: production RK4, 9 sub-steps, switches not located: error {base:.2e} (36 RHS per sample)")
        P = m.P.copy()
        P[mdl.I_BILATERAL] = 1.0  # every contact of the mode is closed; the mode masks the pins
        P[mdl.I_GSHARED] = 0.0  # one geometry per disc: the discs' modes differ
        for spec in a.schemes.split(","):
            name, steps = spec.split(":")
            A, b, c = tableau(name)
            out = np.zeros((m.sensor.shape[0], n))
            y = y0.copy()
            with np.errstate(all="ignore"):
                n_rhs, located, unlocated = run_located(y, n, int(steps), fs, P, m.inv_mass, m.planet, m.tables,
                                                        m.cosk, m.sink, m.sensor, out, m.events, A, b, c)
            err = np.linalg.norm(out - ref) / np.linalg.norm(ref)
            print(f"  {name} x{steps}, switches located: error {err:.2e} ({err / base:.2f}x the baseline), "
                  f"{n_rhs / n:.1f} RHS per sample, {located} switches located, {unlocated} beside them",
                  flush=True)


if __name__ == "__main__":
    main()
