"""Time the vectorised TVMS against per-angle quadrature baselines, in the same run.

Workload (issue 2): healthy and faulty (T6 = broken + wear + crack) TVMS of the RV-20E sun-planet
pair for 10 mesh cycles x 360 points = 3,600 driver angles.

Baselines, measured now on this machine:
1. ``quad``: the same physics (same tooth table, same terms) evaluated angle by angle with
   ``scipy.integrate.quad`` for the bending, shear and axial integrals of each tooth in contact, as
   ROSS and most published codes do.  Timed on the first ``--baseline-angles`` angles and scaled
   linearly (the work per angle is constant).
2. ``ross``: ROSS 2.3.0 ``Mesh.get_stiffness_for_mesh_period`` on an unshifted 20/40 pair (ROSS has
   no profile shift, so it cannot take the RV-20E pair), scaled the same way.

Usage: ``python bench/tvms_speed.py [--repeat 5] [--baseline-angles 120]``.
"""

from __future__ import annotations

import argparse
import math
import platform
import time
import warnings

import numpy as np


def best_of(fn, repeat):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def quad_baseline(pair, angles):
    """Per-angle scipy.integrate.quad of Tian's integrals over the tooth profile (healthy)."""
    from scipy.integrate import quad

    from rvdiag.gears.tvms import foundation_compliance, hertz_compliance, load_point

    out = np.zeros(len(angles))
    kh = hertz_compliance(pair)
    gears = (pair.driver, pair.driven)
    profs = [g.profile() for g in gears]
    _, roll, inc = pair.contact_state(angles)
    for j in range(len(angles)):
        total = 0.0
        for k in np.flatnonzero(inc[:, j]):
            rho1, rho2 = pair.roll_lengths(roll[k, j])
            comp = kh
            for g, prof, rho in zip(gears, profs, (rho1, rho2)):
                yk, xk, a1, _ = (float(v) for v in load_point(g, np.array(rho)))
                E, L = g.youngs_modulus, g.face_width
                G = E / (2 * (1 + g.poisson_ratio))
                c, s = math.cos(a1), math.sin(a1)

                def h(y):
                    return 2.0 * np.interp(y, prof.y, prof.x)

                kb = quad(lambda y: (c * (yk - y) - xk * s) ** 2 * 12 / (E * h(y) ** 3 * L),
                          prof.y[0], yk, limit=200)[0]
                ks = quad(lambda y: 1.2 * c * c / (G * h(y) * L), prof.y[0], yk, limit=200)[0]
                ka = quad(lambda y: s * s / (E * h(y) * L), prof.y[0], yk, limit=200)[0]
                kf = float(foundation_compliance(g, np.array(yk), np.array(xk), np.array(a1)))
                comp += kb + ks + ka + kf
            total += 1.0 / comp
        out[j] = total
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--baseline-angles", type=int, default=120)
    ap.add_argument("--no-ross", action="store_true")
    args = ap.parse_args()

    from rvdiag.gears import GearPair, ToothFaults, mesh_stiffness
    from rvdiag.params import ReducerParams

    pair = GearPair.sun_planet(ReducerParams.default())
    cycles, ppc = 10, 360
    n = cycles * ppc
    fault = ToothFaults.for_state("T6")
    mesh_stiffness(pair, cycles=1, points_per_cycle=10)  # warm the tooth-table cache (one-off)

    t_healthy = best_of(lambda: mesh_stiffness(pair, cycles=cycles, points_per_cycle=ppc), args.repeat)
    from rvdiag.gears.tvms import _damaged_table

    def cold():
        _damaged_table.cache_clear()
        mesh_stiffness(pair, fault, cycles=cycles, points_per_cycle=ppc)

    t_faulty_cold = best_of(cold, args.repeat)
    t_faulty = best_of(lambda: mesh_stiffness(pair, fault, cycles=cycles, points_per_cycle=ppc),
                       args.repeat)
    print(f"machine: {platform.processor() or platform.machine()}, python {platform.python_version()}")
    print(f"vectorised healthy  {n} angles: {t_healthy * 1e3:8.2f} ms")
    print(f"vectorised T6 cold  {n} angles: {t_faulty_cold * 1e3:8.2f} ms (damaged-tooth tables rebuilt)")
    print(f"vectorised T6 warm  {n} angles: {t_faulty * 1e3:8.2f} ms (tables cached)")

    res = mesh_stiffness(pair, cycles=cycles, points_per_cycle=ppc)
    m = args.baseline_angles
    t = time.perf_counter()
    idx = np.linspace(0, n - 1, m).astype(int)   # spread over the workload: single and double zones
    ref = quad_baseline(pair, res.angle_rad[idx])
    t_quad = (time.perf_counter() - t) * n / m
    err = np.max(np.abs(ref / res.stiffness_N_per_m[idx] - 1.0))
    print(f"quad baseline       {n} angles: {t_quad * 1e3:8.0f} ms (scaled from {m}); "
          f"max rel. difference {err:.1e}")
    print(f"speed-up vs quad: healthy {t_quad / t_healthy:,.0f}x, T6 cold {t_quad / t_faulty_cold:,.0f}x, "
          f"T6 warm {t_quad / t_faulty:,.0f}x")

    if not args.no_ross:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                import ross
                from ross.gear_element import GearElementTVMS, Mesh
        except Exception as exc:  # noqa: BLE001 - ROSS is optional
            print(f"ross baseline skipped: {exc}")
            return
        mat = ross.Material(name="bench_steel", rho=7850, E=2.06e11, Poisson=0.3)
        gears = [GearElementTVMS(n=i, material=mat, width=0.01, bore_diameter=0.02, module=2e-3,
                                 n_teeth=z, pr_angle=math.radians(20)) for i, z in enumerate((20, 40))]
        orig = Mesh.get_stiffness_for_mesh_period
        Mesh.get_stiffness_for_mesh_period = lambda self, n_mesh_period=1, n_points=1000: (
            np.zeros(1), np.zeros(1))
        try:
            mesh = Mesh(*gears)
        finally:
            Mesh.get_stiffness_for_mesh_period = orig
        t = time.perf_counter()
        mesh.get_stiffness_for_mesh_period(n_points=m)  # evenly spread over one mesh period
        t_ross = (time.perf_counter() - t) * n / m
        p2 = GearPair.from_dimensions(20, 40, 2e-3, 0.01, bore_radius1=0.01, bore_radius2=0.01)
        t_ours2 = best_of(lambda: mesh_stiffness(p2, cycles=cycles, points_per_cycle=ppc), args.repeat)
        print(f"ross 2.3.0 (20/40)  {n} angles: {t_ross * 1e3:8.0f} ms (scaled from {m}); "
              f"ours on that pair {t_ours2 * 1e3:.2f} ms; speed-up {t_ross / t_ours2:,.0f}x")


if __name__ == "__main__":
    main()
