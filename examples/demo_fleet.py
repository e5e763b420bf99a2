"""The demo's last step (``make demo``, examples/demo.py): a small simulated fleet watched by the demo's monitor.

Three reducers that the monitor never saw (configs/demo-fleet.toml) become three joints of a plant, each
commissioned, then recorded twice a day for about two weeks:

- ``plant/r1/j1`` stays healthy;
- ``plant/r1/j2`` degrades: its last three records have a broken tooth (0.5-1.0 of the tooth), its alarm is raised
  and then acknowledged;
- ``plant/r2/j1`` has a dead sensor for a while (four records in a row read a constant), which shows as
  ``sensor-fault`` and never as a gear fault.

Every step is an ordinary ``rvdiag fleet`` command, printed before it runs; two joints are ingested with ``rvdiag
fleet ingest``, the third by the folder watcher (``rvdiag fleet watch --once``).  The store is out/fleet.db; the
state table is printed, and a static snapshot of the dashboard is written to out/fleet-dashboard/ where the
dashboard (``rvdiag.fleet.web``) is installed.
"""

from __future__ import annotations

import json
import shutil
import sys
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "configs" / "demo-fleet.toml"
START = datetime(2026, 11, 1, tzinfo=timezone.utc)
RECORDS_PER_DAY = 2
#: which library reducer is which joint, and what happens to it
JOINTS = {2: ("plant/r1/j1", "healthy"), 1: ("plant/r1/j2", "degrades"), 0: ("plant/r2/j1", "dead sensor")}
#: the records of the dead-sensor joint that read a constant (monitored records, counted from 0)
DEAD = range(14, 18)
NAME = "{time}_{speed:.4f}dps_{load:.4f}Nm.npy"
META_REGEX = r"_(?P<speed_dps>[\d.]+)dps_(?P<load_Nm>[\d.]+)Nm"
TIME_REGEX = r"^\d{8}T\d{6}"


def export_records(library: Path, folder: Path) -> dict:
    """Write each joint's commissioning and monitored records as .npy files named by time and operating point;
    returns ``{joint: {"commissioning": [paths], "records": [paths]}}``."""
    from rvdiag.datasets import SampleStore

    store = SampleStore.open(library)
    s = store.load(index=np.arange(store.n_samples))
    unit = np.asarray(s.meta["unit"])
    out = {}
    for red, (joint, story) in JOINTS.items():
        rows = np.flatnonzero(np.asarray(s.meta["reducer"]) == red)
        units = list(dict.fromkeys(unit[rows].tolist()))  # records in the library's order
        base_dir = folder / "commissioning" / joint
        rec_dir = folder / ("incoming" if story == "dead sensor" else "records") / joint
        for d in (base_dir, rec_dir):
            shutil.rmtree(d, ignore_errors=True)
            d.mkdir(parents=True)
        files = {"commissioning": [], "records": []}
        k = 0
        for u in units:
            idx = rows[unit[rows] == u]
            i = idx[0]
            role, state = str(s.meta["role"][i]), str(s.y[i])
            x = np.concatenate([np.asarray(s.X[j], dtype=np.float64) for j in idx])
            sp, ld = float(s.meta["output_speed_deg_s"][i]), float(s.meta["load_Nm"][i])
            if role == "baseline":
                t = START - timedelta(hours=1) + timedelta(minutes=len(files["commissioning"]))
                p = base_dir / NAME.format(time=t.strftime("%Y%m%dT%H%M%S"), speed=sp, load=ld)
                files["commissioning"].append(p)
            else:
                if state != "T1" and story != "degrades":
                    continue
                t = START + timedelta(hours=24 / RECORDS_PER_DAY * (k + 1))
                if story == "dead sensor" and k in DEAD:
                    x = np.full_like(x, 0.013 + 0.001 * k)  # a dead channel: a constant offset (drifting)
                p = rec_dir / NAME.format(time=t.strftime("%Y%m%dT%H%M%S"), speed=sp, load=ld)
                files["records"].append(p)
                k += 1
            np.save(p, x.astype(np.float32))
        out[joint] = files
    return out


def run(out: Path, monitor: Path, step) -> None:
    """The fleet steps of the demo, after its monitor is trained (``step(title, args, stdout_file=None)`` runs one
    rvdiag command)."""
    library = out / "demo-fleet.zarr"
    step("9. a small simulated fleet: three reducers the monitor never saw",
         ["library", "build", str(CONFIG), "--out", str(library)])
    folder = out / "fleet-records"
    files = export_records(library, folder)
    db = out / "fleet.db"
    for p in (db, Path(f"{db}-wal"), Path(f"{db}-shm")):
        p.unlink(missing_ok=True)
    shutil.rmtree(Path(f"{db}.blobs"), ignore_errors=True)
    url = ["--db", str(db)]
    reading = ["--fs", "48000", "--meta-regex", META_REGEX]
    step("10. the fleet store", ["fleet", "init", *url])
    for joint in files:
        step(f"    add {joint}", ["fleet", "add", joint, "--monitor", str(monitor), "--records-per-day",
                                   str(RECORDS_PER_DAY), *url])
    for joint, f in files.items():
        step(f"    commission {joint} ({len(f['commissioning'])} healthy records)",
             ["fleet", "commission", joint, *map(str, f["commissioning"]), *reading, "--time",
              START.isoformat(), *url])
    for joint, (red, story) in zip(files, JOINTS.values()):
        if story == "dead sensor":
            continue
        step(f"11. ingest {joint} ({story}, {len(files[joint]['records'])} records, {RECORDS_PER_DAY} a day)",
             ["fleet", "ingest", joint, *map(str, files[joint]["records"]), "--time-regex", TIME_REGEX, *reading,
              *url], out / f"fleet-ingest-{joint.replace('/', '-')}.txt")
    step("    the folder watcher ingests plant/r2/j1 (a dead sensor for a while)",
         ["fleet", "watch", str(folder / "incoming"), "--once", "--time-regex", TIME_REGEX, *reading, *url],
         out / "fleet-watch.txt")
    step("12. the fleet's state", ["fleet", "status", *url])
    step("    acknowledge the degraded joint's alarm",
         ["fleet", "ack", "plant/r1/j2", "--note", "broken tooth suspected: inspection booked", "--by", "demo", *url])
    step("    events", ["fleet", "events", *url])
    step("    the state table as JSON", ["fleet", "status", "--json", *url], out / "fleet-status.json")
    rows = json.loads((out / "fleet-status.json").read_text())
    for r in rows:
        print(f"   {r['joint']}: {r['state']} since {r['state_since']}, last index "
              f"{'-' if r['last_index'] is None else format(r['last_index'], '.3g')}, {r['n_records']} records")
    snapshot(db, out / "fleet-dashboard")


def snapshot(db: Path, target: Path) -> None:
    """A static snapshot of the dashboard (``rvdiag.fleet.web.snapshot``) where the dashboard is installed."""
    try:
        from rvdiag.fleet.web import snapshot as write_snapshot
    except ImportError:
        print("   (no dashboard in this rvdiag: no snapshot written)")
        return
    from rvdiag.fleet import Fleet

    fleet = Fleet.open(f"sqlite:///{db}")
    write_snapshot(fleet, target)
    print(f"   wrote a static snapshot of the dashboard to {target}")


if __name__ == "__main__":  # the fleet step alone, on a demo run's out/ (its monitor trained)
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "out")
    a = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from demo import step  # noqa: E402

    run(a.out, a.out / "demo-monitor", step)
