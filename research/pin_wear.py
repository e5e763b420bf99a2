"""Wear of the cycloid-pin stage: how deep it gets, what lost motion it makes, and what it does to the signals.

Part 1 (no simulation): Archard's law on the discs' flanks and the pins (:func:`rvdiag.gears.pin_wear.pin_wear_history`)

- for the measured endurance test (an RV reducer run 1,550 h: lost motion +12.9 arcsec, +30 %, most of it in the
  first 600 h, 0.0024 arcsec/h after; Lubricants 13(8):362, 2025) at the duty rvdiag assumes for it (rated torque,
  15 rpm output = 90 deg/s, one torque sense), the lost-motion growth against hours at k = 1e-18 m^2/N, the
  coefficient that gives the measured 12.9 arcsec (the depth depends on k and the hours only through their product),
  and the stage-1 share at that k (``research/wear_archard.py``'s ``lost_motion_arcsec``);
- the depth and lost-motion growth a robot's life gives (20,000 h, moving 50 %, 30 deg/s, 50 % rated, the torque
  reversing) at k = 1e-18 and at the anchor's k.

Part 2 (simulation, noise-free, rated load, the model's default reducer, ``[stage2] pin_wear_depth`` on both
flanks): against the depth, at each output speed,

- the housing vibration (channel x, after the model's 0.1 s run-in): RMS, kurtosis, and the energy (+-1 Hz) at the
  stage-2 mesh orders k f_cs (k = 1..3, f_cs = Zc Zp f_H) and their sidebands k f_cs +- f2 and +- 2 f2 (f2 = Zc f_H,
  the cranks' absolute rotation), and at the stage-1 mesh f_sp, as dB over the unworn reducer;
- the motor current (i_a, 1 kHz, without the sensors' 5 mA noise): the lines f_e, f_e -+ f_cs (:func:`rvdiag.motor.lines.current_lines`, height
  over the local floor, dB) and their amplitudes over the unworn reducer;
- the two encoders' difference: the transmission error TE = th_m / i - th_H (output arcsec; the rotor's and the
  carrier's vibratory angles read every 6th sample, an 8 kHz encoder), its mean (the static wind-up) and its
  fluctuation (RMS and peak-to-peak after the mean), its line at f_cs (amplitude); and the lost motion of the static
  hysteresis test, TE(+T) - TE(-T) with T = 3 % of rated torque (the model closed on the + flank and loaded both
  ways, averaged over 5 crank angles across a pin pitch), beside the stage's geometric lost motion
  (:func:`rvdiag.gears.pin_wear.lost_motion`).

    PYTHONPATH=src nice -n 10 .venv/bin/python research/pin_wear.py [--speeds 30,60] [--depths 0,1,2,5,10,20]
        [--duration 4.2] [--json out/pin_wear.json]

Results (2026-11-28) are in research/README.md ("Wear of the cycloid-pin stage") and docs/model.md.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.stats import kurtosis

from rvdiag.dynamics import prepare_simulation
from rvdiag.dynamics.integrate import integrate
from rvdiag.dynamics.linear import static_equilibrium
from rvdiag.gears.pin_wear import lost_motion, pin_wear_history, pin_wear_table
from rvdiag.gears.wear import DutyCycle, wear_depth_profile
from rvdiag.kinematics import characteristic_frequencies
from rvdiag.motor.lines import current_lines
from rvdiag.params import ReducerParams

P0 = ReducerParams.default()
RATED = P0.operation.rated_torque
AS = 180.0 / math.pi * 3600.0                  # rad -> arcsec
ANCHOR_HOURS, ANCHOR_LM, ANCHOR_RATE = 1550.0, 12.9209, 0.0024
ANCHOR_DUTY = DutyCycle(90.0, RATED)           # 15 rpm output, rated torque (assumed: the paper's duty not at hand)
LIFE = ("20,000 h, moving 50 %, 30 deg/s, 50 % rated", 20000.0, DutyCycle(30.0, 0.5 * RATED, 0.5))
ENCODER_EVERY = 6                              # read the two encoders every 6th sample (8 kHz at 48 kHz)


def _stage1_lost_motion_arcsec(k: float) -> float:
    """The sun stage's lost-motion growth over the anchor's test at ``k`` (research/wear_archard.py's measure)."""
    spec = importlib.util.spec_from_file_location("wear_archard", Path(__file__).with_name("wear_archard.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return float(mod.lost_motion_arcsec(wear_depth_profile(P0, ANCHOR_HOURS, ANCHOR_DUTY, k)))


def part1() -> dict:
    """The anchor's lost motion and a robot's life (module docstring)."""
    out: dict = {}
    k_ref = 1e-18
    hours = [0.0, 100.0, 300.0, 600.0, 1000.0, 1550.0, 2500.0, 4000.0, 6000.0]
    lm = {}
    for flanks in (1, 2):
        hist = pin_wear_history(P0, hours, ANCHOR_DUTY, k_ref, flanks=flanks)
        lm[flanks] = [h.lost_motion_growth_rad(P0) * AS for h in hist]
        out[f"anchor_k1e-18_flanks{flanks}"] = [
            {"hours": t, "depth_um": h.max_depth * 1e6, "disc_um": float(h.disc.max() * 1e6),
             "pin_um": float(h.pin.max() * 1e6), "lost_motion_growth_arcsec": g,
             "largest_pin_force_N": float(h.force_N.max()),
             "pins_loaded_per_disc": float(np.count_nonzero(h.force_N > 0) * 2 / h.eta.size * P0.stage2.pins / 2)}
            for t, h, g in zip(hours, hist, lm[flanks])]
    # the k that gives the anchor's growth at 1,550 h: depth(k, t) = depth(k_ref, t k / k_ref)
    for flanks in (1, 2):
        t_star = float(np.interp(ANCHOR_LM, lm[flanks], hours))
        k_fit = k_ref * t_star / ANCHOR_HOURS
        fit = pin_wear_history(P0, [600.0, ANCHOR_HOURS], ANCHOR_DUTY, k_fit, flanks=flanks)
        g600, g1550 = (h.lost_motion_growth_rad(P0) * AS for h in fit)
        out[f"anchor_fit_flanks{flanks}"] = {
            "k_wear": k_fit, "lost_motion_600h_arcsec": g600, "lost_motion_1550h_arcsec": g1550,
            "rate_after_600h_arcsec_per_h": (g1550 - g600) / (ANCHOR_HOURS - 600.0),
            "depth_1550h_um": fit[1].max_depth * 1e6,
            "stage1_lost_motion_arcsec": _stage1_lost_motion_arcsec(k_fit)}
    k_fit = out["anchor_fit_flanks1"]["k_wear"]
    label, life_h, duty = LIFE
    for name, k in (("k1e-18", 1e-18), ("k_anchor", k_fit)):
        w = pin_wear_history(P0, [life_h], duty, k, flanks=2)[0]
        out[f"life_{name}"] = {"duty": label, "k_wear": k, "depth_um": w.max_depth * 1e6,
                               "lost_motion_growth_arcsec": w.lost_motion_growth_rad(P0) * AS}
    out["lost_motion_new_arcsec"] = lost_motion(P0) * AS
    return out


def band_energy(f: np.ndarray, power: np.ndarray, centre: float, half: float = 1.0) -> float:
    """Sum of the power spectrum within ``centre +- half`` Hz."""
    sel = np.abs(f - centre) <= half
    return float(power[sel].sum())


def vibration_lines(x: np.ndarray, fs: float, fr) -> dict:
    """Energies of the stage-2 mesh orders and sidebands and of the stage-1 mesh in the x channel."""
    x = x - x.mean()
    w = np.hanning(x.size)
    power = np.abs(np.fft.rfft(x * w)) ** 2
    f = np.fft.rfftfreq(x.size, 1.0 / fs)
    out = {}
    for k in (1, 2, 3):
        c = k * fr.fcs
        out[f"{k}fcs"] = band_energy(f, power, c)
        out[f"{k}fcs+-f2"] = band_energy(f, power, c - fr.f2) + band_energy(f, power, c + fr.f2)
        out[f"{k}fcs+-2f2"] = band_energy(f, power, c - 2 * fr.f2) + band_energy(f, power, c + 2 * fr.f2)
    out["fsp"] = band_energy(f, power, fr.fsp)
    return out


def run_record(params: ReducerParams, speed: float, duration: float) -> dict:
    """One noise-free record with the motor: vibration, current and the encoders' difference (module docstring)."""
    run = prepare_simulation(params, None, output_speed_deg_s=speed, load_Nm=RATED, duration_s=duration,
                             signal="both")
    m, fs = run.model, run.fs
    im, ih, ratio = m.rotor_index, m.names.index("carrier.th"), params.ratio
    cols = run.columns
    first = -run.margin[0]
    y = run.start_state((first - run.n_transient) / fs)
    rows = np.empty((run.rows, cols))
    te = []
    k = 0
    while k < cols:
        n = min(ENCODER_EVERY, cols - k)
        s, y = integrate(m, y, fs, n, run.n_transient if k == 0 else 0, first_sample=first + k)
        rows[:, k:k + n] = s
        k += n
        if first + k > 0 and first + k <= run.n_samples:
            te.append(y[im] / ratio - y[ih])
    res = run.finish(rows, 1)
    return {"result": res, "te": np.asarray(te) * AS, "te_fs": fs / ENCODER_EVERY}


def static_lost_motion(params: ReducerParams, speed: float, fraction: float = 0.03) -> float:
    """TE(+T) - TE(-T) at T = ``fraction`` of rated (arcsec), the model closed on the + flank, over 5 crank angles."""
    T = fraction * RATED
    run = prepare_simulation(params, None, output_speed_deg_s=speed, load_Nm=T, duration_s=0.01)
    m = run.model
    im, ih, ratio = m.rotor_index, m.names.index("carrier.th"), params.ratio
    fr = characteristic_frequencies(params, output_speed_deg_s=speed)
    vals = []
    for t in np.linspace(0.0, 1.0 / fr.fcs, 5, endpoint=False):
        qa = static_equilibrium(m, t)
        qb = static_equilibrium(m.with_P(TLOAD=-T, TDRIVE=-T / ratio), t)
        vals.append((qa[im] / ratio - qa[ih]) - (qb[im] / ratio - qb[ih]))
    return float(np.mean(vals)) * AS


def part2(speeds, depths, duration) -> dict:
    """The signature against depth at each speed (module docstring)."""
    out: dict = {}
    for v in speeds:
        fr = characteristic_frequencies(P0, output_speed_deg_s=v)
        rows = []
        for d in depths:
            p = P0.replace(stage2={"pin_wear_depth": d * 1e-6}, motor={"current_noise": 0.0})
            t0 = time.process_time()
            r = run_record(p, v, duration)
            res, te = r["result"], r["te"]
            x = res.signal[0]
            cur = current_lines(res.current[0], res.current_fs, p, output_speed_deg_s=v)["lines"]
            fluct = te - te.mean()
            tw = np.hanning(te.size)
            tspec = 2.0 * np.abs(np.fft.rfft(fluct * tw)) / tw.sum()
            tf = np.fft.rfftfreq(te.size, 1.0 / r["te_fs"])
            te_cs = float(tspec[np.argmin(np.abs(tf - fr.fcs))])
            table = pin_wear_table(p) if d > 0 else None
            rows.append({
                "depth_um": d, "rms": float(np.sqrt(np.mean(x ** 2))), "kurtosis": float(kurtosis(x, fisher=False)),
                "lines": vibration_lines(x, res.fs, fr),
                "current": {k: cur[k]["amplitude"] for k in ("fe", "fe-fcs", "fe+fcs", "fe-fsp", "fe+fsp")},
                "current_db": {k: cur[k]["height_db"] for k in ("fe-fcs", "fe+fcs")},
                "te_mean_arcsec": float(te.mean()), "te_rms_arcsec": float(np.sqrt(np.mean(fluct ** 2))),
                "te_pp_arcsec": float(np.ptp(fluct)), "te_fcs_arcsec": te_cs,
                "lost_motion_static_arcsec": static_lost_motion(p, v),
                "lost_motion_geometric_arcsec": lost_motion(p, table) * AS,
                "cpu_s": time.process_time() - t0})
            print(f"  {v} deg/s, {d} um: {rows[-1]['cpu_s']:.1f} s CPU", file=sys.stderr)
        out[str(v)] = rows
    return out


def _db(a, b) -> str:
    return "n/a" if not (a and b) else f"{10 * math.log10(a / b):+.1f}"


def print_part1(p1: dict) -> None:
    print("## Part 1: Archard wear of the cycloid-pin stage")
    print(f"new stage's geometric lost motion: {p1['lost_motion_new_arcsec']:.1f} arcsec")
    for flanks in (1, 2):
        print(f"\nanchor duty (rated, 90 deg/s), k = 1e-18, {flanks} flank(s) worn:")
        print("| hours | depth (um) | disc / pin (um) | lost-motion growth (arcsec) | largest pin force (N) |")
        print("|---|---|---|---|---|")
        for r in p1[f"anchor_k1e-18_flanks{flanks}"]:
            print(f"| {r['hours']:.0f} | {r['depth_um']:.2f} | {r['disc_um']:.2f} / {r['pin_um']:.2f} | "
                  f"{r['lost_motion_growth_arcsec']:.2f} | {r['largest_pin_force_N']:.0f} |")
        f = p1[f"anchor_fit_flanks{flanks}"]
        print(f"k for 12.9 arcsec at 1,550 h: {f['k_wear']:.2e} m^2/N; growth 600 h {f['lost_motion_600h_arcsec']:.1f}, "
              f"1,550 h {f['lost_motion_1550h_arcsec']:.1f} arcsec; rate after 600 h "
              f"{f['rate_after_600h_arcsec_per_h']:.4f} arcsec/h (measured 0.0024); depth {f['depth_1550h_um']:.2f} um;"
              f" stage 1 adds {f['stage1_lost_motion_arcsec']:.2f} arcsec")
    for name in ("k1e-18", "k_anchor"):
        r = p1[f"life_{name}"]
        print(f"life ({r['duty']}), k = {r['k_wear']:.2e}: depth {r['depth_um']:.2f} um, lost motion "
              f"+{r['lost_motion_growth_arcsec']:.1f} arcsec")


def print_part2(p2: dict) -> None:
    print("\n## Part 2: signature against depth (rated load, noise-free)")
    for v, rows in p2.items():
        h = rows[0]
        print(f"\n{v} deg/s (healthy RMS {h['rms']:.3f} m/s^2, kurtosis {h['kurtosis']:.1f}):")
        print("| depth (um) | RMS x | kurtosis | f_cs / 2f_cs / 3f_cs (dB) | f_cs+-f2 / +-2f2 (dB) | f_sp (dB) | "
              "current f_e-+f_cs (x) | TE mean / rms / pp (arcsec) | TE at f_cs (arcsec) | lost motion static / "
              "geometric (arcsec) |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            L, H = r["lines"], h["lines"]
            cur = " / ".join("n/a" if not (r["current"][k] and h["current"][k]) else
                             f"{r['current'][k] / h['current'][k]:.2f}" for k in ("fe-fcs", "fe+fcs"))
            print(f"| {r['depth_um']:g} | {r['rms'] / h['rms']:.2f}x | {r['kurtosis']:.1f} | "
                  f"{_db(L['1fcs'], H['1fcs'])} / {_db(L['2fcs'], H['2fcs'])} / {_db(L['3fcs'], H['3fcs'])} | "
                  f"{_db(L['1fcs+-f2'], H['1fcs+-f2'])} / {_db(L['1fcs+-2f2'], H['1fcs+-2f2'])} | "
                  f"{_db(L['fsp'], H['fsp'])} | {cur} | {r['te_mean_arcsec']:.2f} / {r['te_rms_arcsec']:.3f} / "
                  f"{r['te_pp_arcsec']:.3f} | {r['te_fcs_arcsec']:.4f} | {r['lost_motion_static_arcsec']:.1f} / "
                  f"{r['lost_motion_geometric_arcsec']:.1f} |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--speeds", default="30,60", help="output speeds, deg/s (default 30,60)")
    ap.add_argument("--depths", default="0,1,2,5,10,20", help="pin wear depths, um (default 0,1,2,5,10,20)")
    ap.add_argument("--duration", type=float, default=4.2, help="recorded seconds per run (default 4.2: 4096 "
                    "current samples at 1 kHz)")
    ap.add_argument("--skip-part1", action="store_true")
    ap.add_argument("--json", type=Path, default=None, help="also write the figures to this JSON file")
    a = ap.parse_args(argv)
    speeds = [float(s) for s in a.speeds.split(",")]
    depths = [float(s) for s in a.depths.split(",")]
    if depths[0] != 0.0:
        ap.error("the first depth must be 0 (the unworn reference)")
    t0 = time.time()
    p1 = {} if a.skip_part1 else part1()
    p2 = part2(speeds, depths, a.duration)
    if p1:
        print_part1(p1)
    print_part2(p2)
    if a.json is not None:
        a.json.write_text(json.dumps({"part1": p1, "part2": p2}, indent=1, default=float))
    print(f"\n({time.time() - t0:.0f} s wall)")


if __name__ == "__main__":
    main()
