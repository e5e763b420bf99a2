"""What the monitor's level check (``rvdiag.monitoring.diagnosis.level_check_against_baseline``) calls "not
recognised", measured on simulated faulty and healthy records against their own baseline, and on what should not be
recognised: the healthy records in another unit (x9.81 g <-> m/s^2, x1000 m/s^2 <-> mm/s^2), a disconnected sensor
(noise at 1 % of the record's RMS, alone or with a mains hum), and other machines' records fed as a user would
(as they are, x9.81, x1000, and scaled to 20x the baseline's RMS): a bearing rig (CWRU drive end, healthy and an
inner-race fault), a gearbox (SpectraQuest, healthy and a broken tooth), a robot's RV reducer (healthy), each read
at the reducer's 48 kHz as a wrong ``--fs`` would.  Also each T2 record scaled to 20x and 50x the baseline's RMS (a
gain on a faulty record).

Stores: paired libraries (``rvdiag library build``) with ``role`` baseline / monitored; by default
bench/fleet_alarms.py's ``train`` and ``unseen`` (T2, T3 at a 20 dB floor, 45 deg/s) and a small library of
configs/monitoring.toml (3 reducers, T1-T6, 20-70 deg/s, 30-150 N m, one record of each state: 57 simulations,
about 9 min on 2 shared cores), built under ``--out`` if missing.  Each record's first healthy monitored record
gives the units, the disconnected sensor and the other machines.  Prints a Markdown table per case: the records'
RMS over the baseline's largest, the quietest band's ratio, the loudest band over the whole (``shape``), how many
are "more than 10x" and how many are not recognised; ``--json`` writes every row.

Usage::

    PYTHONPATH=src nice python bench/fleet_alarms.py --out out/bench-fleet     # its libraries
    PYTHONPATH=src nice python bench/level_check.py --out out/bench-level \\
        --stores out/bench-fleet/train.zarr out/bench-fleet/unseen.zarr [--data DIR] [--json FILE]

Data: ``--data DIR`` or ``RVDIAG_DATA_DIR`` (docs/real-data.md, "Getting the data").
"""

from __future__ import annotations

import argparse
import collections
import gzip
import json
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

REPO = Path(__file__).resolve().parent.parent
DEFAULT_DATA = Path(os.environ.get("RVDIAG_DATA_DIR") or REPO.parent / "shared" / "data")
MONITORING = REPO / "src" / "rvdiag" / "configs" / "monitoring.toml"
FS, L = 48000.0, 12000
FAULTS = ("T2", "T3", "T4", "T5", "T6")


def small_library(out: Path) -> Path:
    """configs/monitoring.toml with 3 reducers (1 held out), 2 healthy and 1 of each fault per reducer, built under
    ``out`` unless there."""
    text = MONITORING.read_text()
    body = text[text.index('name = "monitoring"'):]
    for a, b in (('name = "monitoring"', 'name = "loudfault-measure"'),
                 ("reducers = 40\ntest_reducers = 14", "reducers = 3\ntest_reducers = 1"),
                 ("monitored_healthy = 8", "monitored_healthy = 2"),
                 ("monitored_per_state = 2", "monitored_per_state = 1")):
        assert a in body, a
        body = body.replace(a, b)
    cfg, store = out / "lib.toml", out / "lib.zarr"
    cfg.write_text(body)
    if not store.exists():
        subprocess.run([sys.executable, "-m", "rvdiag", "library", "build", str(cfg), "--out", str(store),
                        "--workers", "2"], check=True)
    return store


def other_machines(data: Path, n: int) -> dict[str, np.ndarray]:
    """``n`` points of each other machine's record (its mean removed)."""
    import scipy.io

    out = {}
    m = scipy.io.loadmat(data / "cwru-bearing" / "normal_0.mat")
    out["bearing rig, healthy"] = m["X097_DE_time"].ravel()
    m = scipy.io.loadmat(data / "cwru-bearing" / "IR021_1.mat")
    out["bearing rig, inner race"] = m[next(k for k in m if k.endswith("DE_time"))].ravel()
    for f, name in (("h30hz50", "gearbox, healthy"), ("b30hz50", "gearbox, broken tooth")):
        with gzip.open(data / "spectraquest-gearbox" / f"{f}.csv.gz", "rt") as fh:
            out[name] = np.loadtxt(fh, delimiter=",", skiprows=1, max_rows=n)[:, 0]
    z = np.load(data / "rv-robot-healthy" / "windows.npz")
    key = sorted(k for k in z.files if k.endswith("_X"))[0]
    out["robot RV reducer, healthy"] = z[key][:, :, 0].astype(np.float64).ravel()
    return {k: v[:n] - v[:n].mean() for k, v in out.items()}


def judge(x, base, speed, load) -> dict:
    from rvdiag.monitoring.diagnosis import level_check_against_baseline

    out = level_check_against_baseline({"recognised": True, "reason": None, "checks": {}}, x, base, FS, L,
                                       {"output_speed_deg_s": speed}, load)
    lv = out["checks"]["level"]
    bd = lv.get("bands") or {}
    return {"recognised": out["recognised"], "rms_over_hi": lv["rms"] / lv["baseline_rms"][1],
            "band_min": bd.get("min"), "band_max": bd.get("max"), "shape": bd.get("shape"),
            "quietest_hz": bd.get("quietest_hz"), "reason": out.get("reason")}


def measure(path: Path, others: dict, rng) -> list[dict]:
    from rvdiag.datasets import SampleStore

    st = SampleStore.open(path)
    s = st.load(index=np.arange(st.n_samples))
    unit, red, role = (np.asarray(s.meta[c]) for c in ("unit", "reducer", "role"))
    rows = []
    for r in sorted(set(red.tolist())):
        bi = np.flatnonzero((red == r) & (role == "baseline"))
        base = SimpleNamespace(X=np.asarray(s.X[bi], np.float64),
                               meta={c: np.asarray(s.meta[c])[bi] for c in ("output_speed_deg_s", "load_Nm")})
        hi = float(np.sqrt(np.mean(base.X ** 2, axis=1)).max())
        first = True
        for u in dict.fromkeys(unit[(red == r) & (role != "baseline")].tolist()):
            ii = np.flatnonzero(unit == u)
            x = np.concatenate([np.asarray(s.X[i], np.float64) for i in ii])
            sp, ld, y = float(s.meta["output_speed_deg_s"][ii[0]]), float(s.meta["load_Nm"][ii[0]]), str(s.y[ii[0]])

            def add(case, z):
                rows.append({"store": str(path), "reducer": int(r), "case": case, **judge(z, base, sp, ld)})

            add("healthy" if y == "T1" else "faulty, T2-T6", x)
            if y == "T2":
                for t in (20.0, 50.0):
                    add(f"T2 scaled (a gain) to {t:g}x", x * t * hi / float(np.sqrt(np.mean(x ** 2))))
            if y != "T1" or not first:
                continue
            first = False
            for g, name in ((9.81, "x9.81"), (1 / 9.81, "/9.81"), (1000.0, "x1000"), (1e-3, "/1000")):
                add("healthy in another unit (x9.81, /9.81, x1000, /1000)", g * x)
            add("disconnected (noise at 1 %; with a mains hum)", 0.01 * x.std() * rng.standard_normal(x.size))
            add("disconnected (noise at 1 %; with a mains hum)", 0.01 * x.std() * rng.standard_normal(x.size)
                + 0.5 * x.std() * np.sin(2 * np.pi * 50 * np.arange(x.size) / FS))
            for name, f in others.items():
                f = f[: x.size]
                for g in (1.0, 9.81, 1000.0):
                    add(f"another machine ({name}), as is, x9.81, x1000", g * f)
                add(f"another machine ({name}), at 20x the baseline's RMS",
                    20 * f * float(np.sqrt(np.mean(base.X ** 2))) / f.std())
    return rows


def timing(path: Path, n: int = 50) -> dict:
    """Seconds per record of the level check on a record of 2 windows against one reducer's baseline windows of
    ``path``: with the bands (as :func:`rvdiag.monitoring.monitor_record` calls it) and, the baseline in the same
    run, the RMS alone (no ``fs``: the check before its bands)."""
    import time

    from rvdiag.datasets import SampleStore
    from rvdiag.monitoring.diagnosis import level_check_against_baseline

    st = SampleStore.open(path)
    s = st.load(index=np.arange(min(st.n_samples, 200)))
    red, role = np.asarray(s.meta["reducer"]), np.asarray(s.meta["role"])
    bi = np.flatnonzero((red == red[0]) & (role == "baseline"))
    base = SimpleNamespace(X=np.asarray(s.X[bi], np.float64),
                           meta={c: np.asarray(s.meta[c])[bi] for c in ("output_speed_deg_s", "load_Nm")})
    x = np.concatenate([np.asarray(s.X[i], np.float64) for i in bi[:2]])
    ok = {"recognised": True, "reason": None, "checks": {}}
    speed = {"output_speed_deg_s": float(s.meta["output_speed_deg_s"][bi[0]])}
    out = {"baseline_windows": int(bi.size)}
    for name, args in (("rms_only_s", ()), ("bands_s", (FS, L, speed, float(s.meta["load_Nm"][bi[0]])))):
        level_check_against_baseline(ok, x, base, *args)
        t0 = time.perf_counter()
        for _ in range(n):
            level_check_against_baseline(ok, x, base, *args)
        out[name] = (time.perf_counter() - t0) / n
    return out


def table(rows: list[dict]) -> str:
    g = collections.defaultdict(list)
    for r in rows:
        g[r["case"]].append(r)

    def span(rs, k):
        v = [r[k] for r in rs if r[k] is not None]
        return f"{min(v):.3g}-{max(v):.3g}" if v else "-"

    out = ["| records | n | RMS / baseline's largest | quietest band / baseline's | loudest band over the whole "
           "| more than 10x | not recognised |", "|---|---|---|---|---|---|---|"]
    for c, rs in g.items():
        out.append(f"| {c} | {len(rs)} | {span(rs, 'rms_over_hi')} | {span(rs, 'band_min')} | {span(rs, 'shape')} | "
                   f"{sum(r['rms_over_hi'] > 10 for r in rs)} | {sum(not r['recognised'] for r in rs)} of {len(rs)} |")
    return "\n".join(out)


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("out/bench-level"))
    ap.add_argument("--stores", type=Path, nargs="*", default=[Path("out/bench-fleet/train.zarr"),
                                                                 Path("out/bench-fleet/unseen.zarr")])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--json", type=Path)
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    stores = [*a.stores, small_library(a.out)]
    others = other_machines(a.data, 4 * L)
    rng = np.random.default_rng(0)
    rows = [row for p in stores for row in measure(p, others, rng)]
    print(table(rows))
    print("level check per record:", json.dumps(timing(stores[0])))
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1))
    return rows


if __name__ == "__main__":
    main()
