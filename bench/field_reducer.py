"""A field reducer that a baseline-referenced monitor never saw: commissioning records at its own operating points,
then later records of each state on the same specimen, as CSV files a robot controller could write.

The reducer is drawn as a reducer of ``configs/monitoring.toml`` is (its own specimen of ISO 1328 grade 4-6, every
stiffness and damping within +-10 %, its own sensor path), but from another master seed (``--seed``, default
2718; the library's is 27), so it is none of the library's reducers.  Its sensor has a fixed noise floor 18 dB
(``--floor-db``) below its healthy power at 45 deg/s and 90 N m.  Every record has the library's run-to-run
variation (load +-3 %, speed +-1 %, temperature +-2 %, mesh damping +-10 %, gain +-3 %).  The records are made by
the library's own units (:func:`rvdiag.library.build.make_plan` of a ``[baseline]`` config,
:func:`rvdiag.library.work_units.simulate_unit`, the gain and floor noise as ``finish_unit`` adds them): the same
physics, drawn the same way.

Files (CSV, columns ``time_s``, ``acc`` in m/s^2, ``angle_in``: the input shaft's encoder angle in rad, 17 bits
per revolution, as a robot controller reports it), named by the commanded (nominal) speed and load:

- ``commissioning/T1_<speed>dps_<load>Nm_<k>.csv``: ``--commissioning`` healthy records at each operating point;
- ``later/<state>_<speed>dps_<load>Nm_<k>.csv``: ``--healthy`` healthy (T1) records and ``--per-state`` records of
  each of T2-T6, each at one of the operating points, drawn;
- ``FIELD_SECRET.json``: every draw (the reducer, each record's variation and severity), never read by the flow.

The operating points (``--points``, default 30 and 60 deg/s x 50 and 130 N m) are the field reducer's own, not
the library's (20, 45 and 70 deg/s x 30 and 150 N m).  Then (docs/monitoring.md, "A field reducer"):

    rvdiag dataset from-files OUT/commissioning --label-regex '^(?P<label>T1)_' --channel acc \\
        --angle-channel angle_in --meta-regex '_(?P<nominal_dps>[\\d.]+)dps_(?P<load_Nm>[\\d.]+)Nm' \\
        --window 12000 -o OUT/base.zarr
    rvdiag dataset from-files OUT/later --label-regex '^(?P<label>T\\d)_' --channel acc --angle-channel angle_in \\
        --meta-regex '_(?P<nominal_dps>[\\d.]+)dps_(?P<load_Nm>[\\d.]+)Nm' --window 12000 -o OUT/later.zarr
    rvdiag evaluate out/mon OUT/later.zarr --baseline OUT/base.zarr --split all --json
    rvdiag diagnose out/mon OUT/later/T2_30dps_50Nm_000.csv --channel acc --angle-channel angle_in \\
        --load 50 --baseline OUT/base.zarr

Usage: ``PYTHONPATH=src nice python bench/field_reducer.py --out out/field [--workers 2] [--small]``
(``--small``: one operating point, one record of T1 and T2 each, 0.3 s: a check that the files are written).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

#: the field reducer's own operating points (output deg/s, output N m)
FIELD_POINTS = [[30.0, 50.0], [30.0, 130.0], [60.0, 50.0], [60.0, 130.0]]
#: counts per revolution of the input shaft's encoder (17 bits)
ENCODER_COUNTS = 2**17


def field_config(*, seed: int, floor_db: float, points, commissioning: int, healthy: int, per_state: int,
                 states, duration_s: float, transient_s: float):
    """The :class:`rvdiag.library.config.LibraryConfig` whose reducer 0 is the field reducer: monitoring.toml's
    draws with another seed, noise floor, operating points and record counts."""
    import tomllib

    from rvdiag.library.config import LibraryConfig, builtin_config_path

    raw = tomllib.loads(builtin_config_path("monitoring").read_text())
    raw["name"], raw["seed"] = "field", int(seed)
    raw["operation"]["noise_snr_db"] = float(floor_db)
    raw["signal"].update(duration_s=float(duration_s), transient_s=float(transient_s))
    raw["baseline"].update(operating_points=[list(map(float, p)) for p in points], records_per_point=commissioning,
                           monitored_healthy=healthy, monitored_per_state=per_state)
    raw["split"] = {"reducers": 2, "test_reducers": 1}  # only reducer 0 is simulated
    raw["states"] = {s: raw["states"][s] for s in ["T1", *states]}
    return LibraryConfig.from_dict(raw, source="<field reducer>")


def record(unit, job) -> tuple[np.ndarray, np.ndarray]:
    """``(acc, angle_in)`` of one unit: the kept channel times the record's gain plus the reducer's floor noise
    (as :func:`rvdiag.library.work_units.finish_unit`), and the input angle quantised to the encoder's counts."""
    from rvdiag.dynamics.noise import add_noise_power
    from rvdiag.library.work_units import _streams, floor_noise_power, kept_signal, simulate_unit

    res = simulate_unit(unit, job)
    n = job.samples_per_signal
    x = kept_signal(unit, job, res, n) * unit.variation["gain"]
    x = add_noise_power(x, floor_noise_power(unit, job), 0.0, np.random.default_rng(_streams(unit.seed)[2]))
    step = 2 * math.pi / ENCODER_COUNTS
    theta = np.round(np.asarray(res.theta_in[:n], dtype=np.float64) / step) * step
    return x, theta


def _write(args) -> dict:
    unit, job, path = args
    x, theta = record(unit, job)
    t = np.arange(x.size) / job.fs
    with open(path, "w") as f:
        f.write("time_s,acc,angle_in\n")
        np.savetxt(f, np.column_stack([t, x, theta]), fmt=["%.8f", "%.7g", "%.10g"], delimiter=",")
    return {"file": str(path.relative_to(path.parent.parent)), "state": unit.state, "role": unit.role,
            "output_speed_deg_s": unit.speed, "load_Nm": unit.load_Nm, "variation": unit.variation,
            "severity": unit.severity, "seed": unit.seed}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--seed", type=int, default=2718)
    ap.add_argument("--floor-db", type=float, default=18.0)
    ap.add_argument("--commissioning", type=int, default=1, help="healthy records per operating point")
    ap.add_argument("--healthy", type=int, default=50, help="later healthy records")
    ap.add_argument("--per-state", type=int, default=10, help="later records of each of T2-T6")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--small", action="store_true", help="one point, one T1 and one T2 record of 0.3 s")
    a = ap.parse_args(argv)
    points, states, duration, transient = FIELD_POINTS, ["T2", "T3", "T4", "T5", "T6"], 1.0, 0.2
    if a.small:
        points, states, duration, transient = [[45.0, 90.0]], ["T2"], 0.3, 0.05
        a.commissioning, a.healthy, a.per_state = 1, 1, 1
    from rvdiag.library.build import make_plan
    from rvdiag.library.work_units import Job

    cfg = field_config(seed=a.seed, floor_db=a.floor_db, points=points, commissioning=a.commissioning,
                       healthy=a.healthy, per_state=a.per_state, states=states, duration_s=duration,
                       transient_s=transient)
    job = Job.from_config(cfg, cfg.reducer_params())
    units = [u for u in make_plan(cfg) if u.reducer == 0]
    for d in ("commissioning", "later"):
        (a.out / d).mkdir(parents=True, exist_ok=True)
    todo, count = [], {}
    for u in units:
        v, ld = cfg.baseline.operating_points[u.operating_point]
        key = ("commissioning" if u.role == "baseline" else "later", u.state, v, ld)
        k = count[key] = count.get(key, -1) + 1
        todo.append((u, job, a.out / key[0] / f"{u.state}_{v:g}dps_{ld:g}Nm_{k:03d}.csv"))
    t0 = time.perf_counter()
    if a.workers > 1:
        with ProcessPoolExecutor(a.workers) as ex:
            rows = list(ex.map(_write, todo))
    else:
        rows = [_write(t) for t in todo]
    u0 = units[0]
    secret = {"seed": a.seed, "floor_db": a.floor_db, "points": points, "duration_s": duration,
              "reducer": {"scales": u0.scales, "mounting": u0.mounting, "specimen": u0.specimen},
              "records": rows, "wall_s": time.perf_counter() - t0}
    (a.out / "FIELD_SECRET.json").write_text(json.dumps(secret, indent=1, default=float) + "\n")
    print(f"{len(rows)} records ({sum(r['role'] == 'baseline' for r in rows)} commissioning) in "
          f"{secret['wall_s']:.0f} s -> {a.out}")
    return secret


if __name__ == "__main__":
    main()
