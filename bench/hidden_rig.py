"""A measured-like test rig of the same reducer type whose parameters and sensor path the workflow never sees.

The transfer workflow of docs/measured-data.md is judged on it: update the model on the rig's healthy record,
build a library around the updated parameters, train, and classify the rig's fault files.

The rig (``make_rig``): the built-in RV-20E with its stiffnesses scattered by up to +-30 %, its damping ratios by
up to +-40 %, 4-12 kg on the housing, a structural resonance of the sensor path at 2.5-7 kHz and a 6-9 kHz
accelerometer band, all drawn from ``--seed`` and written only to ``RIG_SECRET.json`` beside the files (never read
by the workflow).  As a real rig's separately damaged reducers, each faulty state is its own specimen (its own
``[modification] error_seed``, drawn from ``--seed``); the healthy records (calibration and T1) are the healthy
reducer's.  The sensor and its cabling are the rig's: every record gets the same pink noise floor, 18 dB below the
healthy calibration record's power, and the same 50 Hz mains hum with two harmonics at 2 % of that record's RMS
(a louder fault does not get louder noise).  Files, CSV with the columns ``time_s,acc,angle_in`` at 48 kHz
(``angle_in``: the input shaft's encoder angle in rad, 0 at the first sample; the simulation's ``theta_in``):

- ``calib_T1_45dps_75Nm.csv``: the 8 s healthy calibration record (45 deg/s, 75 N m);
- ``rig_<state>_<speed>dps_<load>Nm.csv``: the six states T1-T6 at 30, 45 and 60 deg/s and 60 and 120 N m, 2 s
  each.

``--run`` then runs the workflow with the ``rvdiag`` command (every step printed):

    rvdiag update RIG/calib_T1_45dps_75Nm.csv --channel acc --fs 48000 --output-speed 45 --load 75 \\
        --out OUT/updated.toml --json
    rvdiag library build configs/transfer.toml --params OUT/updated.toml --out OUT/transfer.zarr
    rvdiag train OUT/transfer.zarr --out OUT/model
    rvdiag dataset from-files RIG --label-regex '^rig_(?P<label>T\\d)_' --channel acc --fs 48000 \\
        --window 4096 --out OUT/rig.zarr
    rvdiag evaluate OUT/model OUT/rig.zarr --json

Usage: ``.venv/bin/python bench/hidden_rig.py --out out/rig [--seed 1] [--run] [--config configs/transfer.toml]``
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np

FS = 48000.0
STATES = ("T1", "T2", "T3", "T4", "T5", "T6")
SPEEDS = (30.0, 45.0, 60.0)
LOADS = (60.0, 120.0)


def rig_parameters(seed: int):
    """The hidden rig: the RV-20E with scattered stiffnesses, damping, mounting and sensor path."""
    from rvdiag.params import ReducerParams

    rng = np.random.default_rng([seed, 1])
    base = ReducerParams.default()
    b, d = base.bearings, base.damping
    bearings = {k: getattr(b, k) * float(rng.uniform(0.7, 1.3)) for k in
                ("sun_support", "crank_carrier", "crank_cycloid", "carrier_support", "pin_wheel_housing",
                 "planet_crank_torsional", "input_torsional")}
    damping = {k: getattr(d, k) * float(rng.uniform(0.6, 1.4)) for k in
               ("mesh_damping_ratio", "bearing_damping_ratio", "pin_damping_ratio")}
    mounting = {"housing_added_mass": float(rng.uniform(4.0, 12.0)),
                "path_resonance_hz": float(rng.uniform(2500.0, 7000.0)),
                "path_damping_ratio": float(rng.uniform(0.03, 0.1)),
                "sensor_cutoff_hz": float(rng.uniform(6000.0, 9000.0))}
    material = {"youngs_modulus": base.material.youngs_modulus * float(rng.uniform(0.95, 1.05))}
    return base.replace(bearings=bearings, damping=damping, mounting=mounting, material=material)


#: the rig's sensor floor: dB below the healthy calibration record's power
FLOOR_DB = 18.0


def specimen_seeds(seed: int) -> dict[str, int]:
    """Each state's ``[modification] error_seed``: the healthy reducer's for T1 (and the calibration record), a
    specimen of its own for each faulty state."""
    from rvdiag.library.specimens import draw_specimen

    return {state: draw_specimen(int(np.random.SeedSequence([seed, 3, i]).generate_state(1)[0]))["error_seed"]
            for i, state in enumerate(STATES)}


def _disturb(x: np.ndarray, rng: np.random.Generator, healthy_power: float) -> np.ndarray:
    """The rig's sensor: pink noise at a fixed floor :data:`FLOOR_DB` below ``healthy_power`` and 50 Hz mains hum
    (fundamental and two harmonics) at 2 % of the healthy RMS, the same whatever the record."""
    from rvdiag.dynamics.noise import add_noise_power

    y = add_noise_power(x, healthy_power * 10.0 ** (-FLOOR_DB / 10.0), 1.0, rng)
    t = np.arange(x.size) / FS
    hum = sum(np.sin(2 * np.pi * 50.0 * h * t + rng.uniform(0, 2 * np.pi)) / h for h in (1, 2, 3))
    return y + 0.02 * np.sqrt(healthy_power) * hum / np.sqrt(np.mean(hum * hum))


def _write_csv(path: Path, x: np.ndarray, angle_in: np.ndarray) -> None:
    """One rig file: ``time_s``, ``acc`` (m/s^2) and ``angle_in`` (the input shaft's encoder angle, rad)."""
    t = np.arange(x.size) / FS
    np.savetxt(path, np.column_stack([t, x, angle_in]), delimiter=",", header="time_s,acc,angle_in", comments="",
               fmt=("%.9g", "%.9g", "%.12g"))


def make_rig(out: Path, seed: int = 1, record_s: float = 2.0, calib_s: float = 8.0, states=STATES, speeds=SPEEDS,
             loads=LOADS) -> Path:
    """Write the rig's files into ``out`` (and its hidden values into ``out/RIG_SECRET.json``); ``states``,
    ``speeds``, ``loads``: a smaller rig (a quick check)."""
    from rvdiag.dynamics import simulate
    from rvdiag.gears import ToothFaults

    out.mkdir(parents=True, exist_ok=True)
    params = rig_parameters(seed)
    specimens = specimen_seeds(seed)
    rng = np.random.default_rng([seed, 2])
    healthy = params.replace(modification={"error_seed": specimens["T1"]})
    res = simulate(healthy, None, output_speed_deg_s=45.0, load_Nm=75.0, duration_s=calib_s, fs=FS)
    x = res.signal[0]
    power = float(np.mean(x * x))
    _write_csv(out / "calib_T1_45dps_75Nm.csv", _disturb(x, rng, power), res.theta_in)
    for state in states:
        fault = None if state == "T1" else ToothFaults.for_state(state)
        reducer = params.replace(modification={"error_seed": specimens[state]})
        for speed in speeds:
            for load in loads:
                res = simulate(reducer, fault, output_speed_deg_s=speed, load_Nm=load, duration_s=record_s, fs=FS)
                _write_csv(out / f"rig_{state}_{speed:.0f}dps_{load:.0f}Nm.csv", _disturb(res.signal[0], rng, power),
                           res.theta_in)
    secret = {"seed": seed, "params": params.to_dict(), "error_seed": specimens, "floor_db": FLOOR_DB,
              "noise_sigma": float(np.sqrt(power * 10.0 ** (-FLOOR_DB / 10.0)))}
    (out / "RIG_SECRET.json").write_text(json.dumps(secret, indent=1), encoding="utf-8")
    return out


def run_workflow(rig: Path, out: Path, config: str) -> dict:
    """The transfer workflow with the ``rvdiag`` command; returns the PCC and the rig accuracy."""
    out.mkdir(parents=True, exist_ok=True)
    exe = [sys.executable, "-m", "rvdiag"]

    def step(*args: str, capture: bool = False) -> str:
        print("$ rvdiag " + " ".join(shlex.quote(a) for a in args), flush=True)
        res = subprocess.run(exe + list(args), check=True, text=True,
                             stdout=subprocess.PIPE if capture else None)
        return res.stdout or ""

    upd = json.loads(step("update", str(rig / "calib_T1_45dps_75Nm.csv"), "--channel", "acc", "--fs", "48000",
                          "--output-speed", "45", "--load", "75", "--out", str(out / "updated.toml"), "--json",
                          capture=True))
    step("library", "build", config, "--params", str(out / "updated.toml"), "--out", str(out / "transfer.zarr"))
    step("train", str(out / "transfer.zarr"), "--out", str(out / "model"))
    step("dataset", "from-files", str(rig), "--label-regex", r"^rig_(?P<label>T\d)_", "--channel", "acc",
         "--fs", "48000", "--window", "4096", "--out", str(out / "rig.zarr"), "--overwrite")
    ev = json.loads(step("evaluate", str(out / "model"), str(out / "rig.zarr"), "--split", "all", "--json",
                         capture=True))
    return {"pcc_before": upd.get("pcc_before"), "pcc_after": upd.get("pcc_after"),
            "rig_accuracy": ev.get("accuracy"), "evaluate": ev}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--run", action="store_true", help="also run the transfer workflow on the rig")
    ap.add_argument("--config", default="configs/transfer.toml")
    ap.add_argument("--small", action="store_true",
                    help="a quick check: 0.3 s records, 1 s calibration, 45 deg/s and 60 N m only")
    a = ap.parse_args()
    small = dict(record_s=0.3, calib_s=1.0, speeds=(45.0,), loads=(60.0,)) if a.small else {}
    rig = make_rig(a.out / "rig", a.seed, **small)
    print(f"rig files in {rig}", flush=True)
    if a.run:
        res = run_workflow(rig, a.out / "work", a.config)
        print(json.dumps({k: v for k, v in res.items() if k != "evaluate"}, indent=1))


if __name__ == "__main__":
    main()
