"""Does a motor-current record whose load reverses inside it make a joint's healthy index spread, and hide a broken
tooth from the joint's own rank?  (docs/fleet.md, "Motor current over joint-years": the two joints of 27 that the
broken tooth did not alarm within 3 records were the two whose arm passed the angle where its gravity cancels the
20 N m near the middle of the record.)

The same joints at three start angles of the arm (15 kg at 0.5 m; the load ``20 + M g L cos(theta)`` N m changes
sign at 105.8 deg, and a 2.048 s record at 45 deg/s sweeps 92.2 deg): 0 deg (no reversal in the record), 30 deg
(the reversal at 82 % of the record) and 55 deg (at 55 %, where the Hann window weighs most).  Each angle is a
life-history library of bench/fleet_alarms.py's current design (``life_config``, the same seed, so the same
reducers' draws where the angle does not enter them) with ``--records`` records a joint, the whole sun tooth
broken in the last 3; each reducer is ingested as a joint of a fleet store with the default rules at 5 % and
judged by the monitor of ``bench/fleet_alarms.py --years --signal current`` (``--monitor``).  Prints, per angle,
each joint's healthy index median and 90th percentile, its learning period's largest index, the broken tooth's
indices and whether the joint alarmed within 3 records.

    PYTHONPATH=src nice python research/current_arm_reversal.py --monitor out/years-current/monitor \\
        --out out/arm-reversal [--reducers 6] [--records 40] [--seed 60] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "bench"))
import fleet_alarms as fa  # noqa: E402

ANGLES = (0.0, 30.0, 55.0)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--monitor", type=Path, required=True)
    ap.add_argument("--out", type=Path, default=Path("out/arm-reversal"))
    ap.add_argument("--reducers", type=int, default=6)
    ap.add_argument("--records", type=int, default=40)
    ap.add_argument("--seed", type=int, default=60)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    from rvdiag.datasets import SampleStore
    from rvdiag.fleet import Fleet

    a.out.mkdir(parents=True, exist_ok=True)
    res = {"command": " ".join(sys.argv), "angles": {}}
    for angle in ANGLES:
        name = f"arm{angle:g}"
        cfg = fa.life_config(a.out, "current", name, a.seed, a.reducers, a.records)
        body = cfg.read_text()
        assert "arm_angle_deg = {min = -60.0, max = 60.0}" in body
        cfg.write_text(body.replace("arm_angle_deg = {min = -60.0, max = 60.0}", f"arm_angle_deg = {angle}"))
        fa.run(["library", "build", cfg, "--out", a.out / f"{name}.zarr", "--workers", a.workers],
               a.out / f"{name}.log")
        store = SampleStore.open(a.out / f"{name}.zarr")
        db = a.out / f"{name}.db"
        fa._fresh_db(db)
        fleet = Fleet.init(f"sqlite:///{db}")
        files = a.out / "records"
        files.mkdir(exist_ok=True)
        reducer = np.asarray(store.meta["reducer"])
        rows = []
        for red in np.unique(reducer):
            pj, _, _ = fa._ingest_joint(fleet, f"arm/{name}/r{int(red)}",
                                        fa.records_of(store, np.flatnonzero(reducer == red)), a.monitor,
                                        float(store.fs), files, np.random.default_rng(a.seed), fa.CURRENT["rules"])
            hi = [x for x in pj["health_index"][:-fa.BROKEN_RECORDS] if x is not None]
            rows.append({"joint": pj["joint"], "healthy_median": float(np.median(hi)),
                         "healthy_p90": float(np.percentile(hi, 90)), "learning_max": float(max(hi[:19])),
                         "t2_indices": pj["t2_indices"], "t2_alarm_within_3": pj["t2_alarm_within_3_acknowledged"],
                         "false_alarms": pj["false_alarms"]})
        fleet.close()
        res["angles"][f"{angle:g}"] = rows
        print(f"\narm start {angle:g} deg:")
        print("| joint | healthy index median | 90th percentile | learning max | broken tooth | alarm within 3 |")
        print("|---|---|---|---|---|---|")
        for r in rows:
            print(f"| {r['joint']} | {r['healthy_median']:.4f} | {r['healthy_p90']:.4f} | {r['learning_max']:.4f} | "
                  f"{', '.join(f'{x:.2f}' for x in r['t2_indices'])} | {r['t2_alarm_within_3']} |")
    (a.out / "result.json").write_text(json.dumps(res, indent=1))
    return res


if __name__ == "__main__":
    main()
