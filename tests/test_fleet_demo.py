"""The demo's fleet (examples/demo_fleet.py): the records it exports from the demo-fleet library are named so that
``--time-regex`` and ``--meta-regex`` read them, one joint keeps its broken-tooth records last, the dead-sensor
joint's constant records differ from each other (else the store would keep one), and the config it builds is the
shipped one."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _demo_fleet():
    spec = importlib.util.spec_from_file_location("demo_fleet", ROOT / "examples" / "demo_fleet.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_exported_records_tell_their_time_and_operating_point(tmp_path):
    from rvdiag.datasets.store import write_store
    from rvdiag.library.config import LibraryConfig

    demo = _demo_fleet()
    cfg = LibraryConfig.load(demo.CONFIG)
    assert cfg.paired and cfg.baseline.monitored_healthy == 22 and cfg.baseline.monitored_per_state == 3
    rng = np.random.default_rng(0)
    X, y, meta = [], [], {k: [] for k in ("reducer", "role", "output_speed_deg_s", "load_Nm", "split", "unit")}
    for r in range(3):
        rows = [("baseline", "T1")] * 4 + [("monitored", "T1")] * 22 + [("monitored", "T2")] * 3
        for role, state in rows:
            unit, speed = len(X) // 2, 45 + rng.uniform(-0.5, 0.5)
            for _ in range(2):  # two windows per record
                X.append(rng.standard_normal(32))
                y.append(state)
                for k, v in zip(meta, (r, role, speed, 50.0, "test", unit)):
                    meta[k].append(v)
    write_store(tmp_path / "lib.zarr", np.array(X), y, {k: np.array(v) for k, v in meta.items()}, kind="simulated",
                fs=48000.0, config={"synthetic": "demo-fleet"})
    files = demo.export_records(tmp_path / "lib.zarr", tmp_path / "records")
    assert list(files) == ["plant/r1/j1", "plant/r1/j2", "plant/r2/j1"]
    counts = {j: (len(f["commissioning"]), len(f["records"])) for j, f in files.items()}
    assert counts == {"plant/r1/j1": (4, 22), "plant/r1/j2": (4, 25), "plant/r2/j1": (4, 22)}
    for f in files.values():
        for p in f["commissioning"] + f["records"]:
            m = re.search(demo.META_REGEX, p.name)
            assert m and 44 < float(m["speed_dps"]) < 46 and float(m["load_Nm"]) == 50.0
            assert re.search(demo.TIME_REGEX, p.name)
    dead = [np.load(p) for i, p in enumerate(files["plant/r2/j1"]["records"]) if i in demo.DEAD]
    assert len(dead) == 4 and all(np.ptp(x) == 0 for x in dead) and len({float(x[0]) for x in dead}) == 4
    assert "incoming" in str(files["plant/r2/j1"]["records"][0])  # the watcher's folder tree: .../site/robot/joint
    assert files["plant/r2/j1"]["records"][0].parent.relative_to(tmp_path / "records" / "incoming") == \
        Path("plant/r2/j1")
