"""How deep an RV-20E's sun flank wears in a robot's life (Archard), and what that wear does to the signal.

Part 1 (no simulation): the Archard depth of the sun and planet flanks (:func:`rvdiag.gears.wear.wear_depth_profile`)
after a life at stated duty cycles, for the span of wear coefficients of lubricated steel gears.

Part 2 (simulation, noise-free, channel x of the housing, 1 s after the model's run-in): against the wear depth
(the simulator's run-in Archard shape, ``Wear(depth)``) and the Archard life profiles of part 1 (``to_wear()``),
at rated load and 30 / 60 deg/s output:

- the static loaded transmission error of one sun-planet mesh (peak-to-peak over a mesh cycle, um along the line
  of action; :meth:`rvdiag.gears.MeshStiffnessResult.loaded_transmission_error`) and what reaches the output:
  the mean of the two meshes, which run half a mesh cycle apart on the 11-tooth sun (so odd mesh harmonics
  cancel), divided by the planet's base radius and the Zp = 40 of the second stage (arcsec);
- RMS and kurtosis of the acceleration, as multiples of healthy;
- energy at the first three stage-1 mesh harmonics (+-2 Hz) and in their sidebands at +-1..3 sun-rotation orders,
  as multiples of healthy (dB).

    PYTHONPATH=src .venv/bin/python research/wear_archard.py [--duration 1.0] [--speeds 30,60]

Results (2026-11-28) are in research/README.md ("Archard wear over a robot's life") and bench/HISTORY.md.
"""

from __future__ import annotations

import argparse
import math

import numpy as np
from scipy.stats import kurtosis

from rvdiag.dynamics import simulate
from rvdiag.gears import GearPair, ToothFaults, Wear, mesh_stiffness
from rvdiag.gears.wear import WEAR_COEFFICIENTS, DutyCycle, mesh_force, wear_depth_profile
from rvdiag.params import ReducerParams

P = ReducerParams.default()
RATED = P.operation.rated_torque
#: robot duties: (label, hours, duty)
LIVES = [
    ("20,000 h, moving 50 %, 30 deg/s, 50 % rated", 20000.0, DutyCycle(30.0, 0.5 * RATED, 0.5)),
    ("30,000 h, moving 50 %, 60 deg/s, 50 % rated", 30000.0, DutyCycle(60.0, 0.5 * RATED, 0.5)),
    ("1,550 h endurance test, 90 deg/s (15 rpm), rated", 1550.0, DutyCycle(90.0, RATED, 1.0)),
]


def life_table() -> list[dict]:
    rows = []
    for label, hours, duty in LIVES:
        for name, k in WEAR_COEFFICIENTS.items():
            w = wear_depth_profile(P, hours, duty, k)
            single = (w.roll >= w.roll[-1] - GearPair.sun_planet(P).base_pitch) & (
                w.roll <= GearPair.sun_planet(P).base_pitch)
            rows.append({"life": label, "k": k, "sun_max_um": w.max_depth * 1e6,
                         "sun_single_max_um": float(w.sun[single].max()) * 1e6,
                         "planet_max_um": float(w.planet.max()) * 1e6,
                         "pitch_um": float(np.interp(w.pitch_roll, w.roll, w.sun)) * 1e6,
                         "deflection_um": w.deflection_m * 1e6, "passes_sun": w.passes[0], "wear": w.to_wear(),
                         "lost_motion_arcsec": lost_motion_arcsec(w)})
    return rows


def lost_motion_arcsec(w) -> float:
    """Growth of the output's lost motion from this stage's wear (arcsec): the clearance along the line of action
    grows by the mean worn depth of sun plus planet on each of the two flanks (a robot joint turns both ways; the
    mean over the path of contact, where the lost-motion measurement may catch the mesh), turned into crank angle
    by the planet's base radius and into output angle by the second stage's Zp."""
    pair = GearPair.sun_planet(P)
    clearance = 2.0 * float(np.mean(w.sun + w.planet))
    return clearance / pair.driven.base_radius / P.stage2.pins * 180 / math.pi * 3600


def static_te(wear: Wear | None, load_Nm: float) -> tuple[float, float]:
    """Peak-to-peak static TE of one mesh (um, line of action) and of the output (arcsec), see module docstring."""
    pair = GearPair.sun_planet(P)
    fault = None if wear is None else ToothFaults({}, wear=wear)
    n = 720
    res = mesh_stiffness(pair, fault, cycles=1, points_per_cycle=n)
    te, _ = res.loaded_transmission_error(mesh_force(P, load_Nm))
    both = 0.5 * (te + np.roll(te, n // 2))             # the second planet, half a mesh cycle later
    out = both / pair.driven.base_radius / P.stage2.pins
    return float(np.ptp(te)) * 1e6, float(np.ptp(out)) * 180 / math.pi * 3600


def spectrum_figures(x: np.ndarray, fs: float, speed: float) -> tuple[float, float]:
    """Energy at the first three mesh harmonics and in their +-1..3 sun-order sidebands (each +-2 Hz)."""
    x = x - x.mean()
    spec = np.abs(np.fft.rfft(x * np.hanning(x.size))) ** 2
    f = np.fft.rfftfreq(x.size, 1 / fs)
    f_h = speed / 360.0
    f_s = P.ratio * f_h
    f_m = P.stage1.sun_teeth * (f_s - f_h)

    def band(fc):
        return float(spec[np.abs(f - fc) <= 2.0].sum())

    mesh = sum(band(n * f_m) for n in (1, 2, 3))
    side = sum(band(n * f_m + s * j * f_s) for n in (1, 2, 3) for j in (1, 2, 3) for s in (-1, 1))
    return mesh, side


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=1.0)
    ap.add_argument("--speeds", default="30,60")
    args = ap.parse_args()

    rows = life_table()
    print("## Archard depth after a life (sun flank, run-in load sharing)\n")
    print("| life | k (m^2/N) | sun max (um) | sun, single contact max (um) | at pitch (um) | planet max (um) "
          "| pair deflection (um) | stage-1 lost motion growth (arcsec) |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['life']} | {r['k']:.0e} | {r['sun_max_um']:.1f} | {r['sun_single_max_um']:.1f} | "
              f"{r['pitch_um']:.2f} | {r['planet_max_um']:.1f} | {r['deflection_um']:.2f} | "
              f"{r['lost_motion_arcsec']:.1f} |")

    cases: list[tuple[str, Wear | None]] = [("healthy", None)]
    cases += [(f"{d:g} um", Wear(d * 1e-6)) for d in (2, 5, 10, 20)]
    for r in rows:
        if r["life"].startswith("20,000") and r["k"] in (1e-18, 1e-17):
            cases.append((f"life 20 kh, k={r['k']:.0e} ({r['sun_max_um']:.1f} um)", r["wear"]))
            if r["k"] == 1e-17:   # the life's shape at the library's default depth: shape alone against Wear(20 um)
                cases.append(("20 um, Archard life shape", Wear(20e-6, shape=r["wear"].shape)))
    fs = 48000.0
    print("\n## Signal against wear (rated load, noise-free, channel x)\n")
    print("| speed | wear | static TE p-p (um, one mesh) | output TE p-p (arcsec) | RMS x healthy "
          "| kurtosis | mesh harmonics 1-3 (dB vs healthy) | sidebands (dB vs healthy) |")
    print("|---|---|---|---|---|---|---|---|")
    for speed in [float(s) for s in args.speeds.split(",")]:
        base = None
        for label, wear in cases:
            fault = None if wear is None else ToothFaults({}, wear=wear)
            x = simulate(P, fault, output_speed_deg_s=speed, load_Nm=RATED, duration_s=args.duration).signal[0]
            x = x - x.mean()
            rms = float(np.sqrt(np.mean(x * x)))
            mesh, side = spectrum_figures(x, fs, speed)
            if base is None:
                base = (rms, mesh, side)
            te, te_out = static_te(wear, RATED)
            print(f"| {speed:g} | {label} | {te:.2f} | {te_out:.2f} | {rms / base[0]:.2f} | "
                  f"{kurtosis(x, fisher=False):.1f} | {10 * np.log10(mesh / base[1]):+.1f} | "
                  f"{10 * np.log10(side / base[2]):+.1f} |", flush=True)


if __name__ == "__main__":
    main()
