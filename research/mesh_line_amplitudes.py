"""How far does a record's amplitude at a mesh line fall when its reading misses a line that the joint's baseline
shows?  Read from the fleet stores of a ``bench/fleet_alarms.py --years`` run (vibration): for every record whose
mesh-line check ran against the baseline (``checks.mesh_lines.baseline_lines``), and every line the baseline shows
that the record's reading (the mean of its windows) misses, the record's amplitude at the line over the
baseline's line, in dB; healthy records apart from the broken-tooth ones (each joint's last 3).  This is what
``rvdiag.monitoring.diagnosis.LOST_DB`` is set from (a disconnected sensor: -16.0 to -25.5 dB, bench/HISTORY.md
2026-11-28 "the mesh-line check of a baseline monitor").

    PYTHONPATH=src python research/mesh_line_amplitudes.py out/years-bt [--broken 3]
"""

from __future__ import annotations

import argparse
import glob
import json
import math
import sqlite3
from pathlib import Path

import numpy as np


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path, help="the --out folder of a bench/fleet_alarms.py --years run")
    ap.add_argument("--broken", type=int, default=3, help="broken-tooth records ending each joint's history")
    a = ap.parse_args(argv)
    drops: dict = {"healthy": [], "broken tooth": []}
    joints: dict = {"healthy": set(), "broken tooth": set()}
    refused = 0
    for db in sorted(glob.glob(str(a.out / "life*.db"))):
        con = sqlite3.connect(db)
        for jid, path in con.execute("select id, path from joints"):
            recs = list(con.execute("select recognised, result from records where joint_id = ? order by time, id",
                                    (jid,)))
            for i, (recognised, result) in enumerate(recs):
                kind = "broken tooth" if i >= len(recs) - a.broken else "healthy"
                lines = ((json.loads(result) if result else {}).get("checks") or {}).get("mesh_lines") or {}
                base, rec = lines.get("baseline_lines"), lines.get("record_lines")
                if not base or not rec:
                    continue
                for name in lines.get("baseline") or []:
                    if name in (lines.get("record_windows") or []) or rec[name]["amplitude"] is None:
                        continue
                    drops[kind].append(20 * math.log10(rec[name]["amplitude"] / base[name]["amplitude"]))
                    joints[kind].add(path)
                    refused += kind == "healthy" and not recognised
        con.close()
    out = {}
    for kind, v in drops.items():
        q = np.percentile(v, [0, 5, 50, 95, 100]).round(1).tolist() if v else None
        out[kind] = {"lines": len(v), "joints": len(joints[kind]), "min_5_50_95_max_db": q}
        print(f"{kind}: {len(v)} lines missed of {len(joints[kind])} joints; amplitude over the baseline's line, dB "
              f"(min, 5, 50, 95 %, max): {q}")
    print(f"healthy records of these not recognised: {refused}")
    out["healthy_not_recognised"] = refused
    return out


if __name__ == "__main__":
    main()
