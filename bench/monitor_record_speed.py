"""Time one record judged against its baseline: in-process (:func:`rvdiag.monitoring.monitor_record` with the model
and the baseline loaded once, as a service calls it) against the command line (``rvdiag diagnose --baseline
--json``, a new process per record, as issue 37 measured it), on the same record and baseline.

    python bench/monitor_record_speed.py out/demo-monitor out/demo-monitoring.zarr [--repeat 20] [--cli-repeat 3]

The baseline is the commissioning records of the paired store's first held-out reducer (a store of one machine);
the record is 1 s at the store's rate (48 kHz for the demo): two of that reducer's monitored records end to end.
Prints JSON: the median seconds per record of each path, their ratio, and the first call in-process (imports and
numba compilation included).  Also in-process with the baseline's kept spectra (``Baseline.spectra``, what the
recognition checks read on the baseline's windows) cleared before every record, as each record recomputed them
before they were kept, interleaved with the kept path in the same run: the median wall and CPU (process) seconds
of each and their ratios (the results must be identical; on a shared machine the CPU seconds are the steadier).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("monitor", type=Path)
    ap.add_argument("store", type=Path)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--cli-repeat", type=int, default=3)
    a = ap.parse_args()

    from rvdiag.datasets import SampleStore
    from rvdiag.datasets.store import write_store

    store = SampleStore.open(a.store)
    s = store.load(index=np.arange(store.n_samples))
    meta = {k: np.asarray(v) for k, v in s.meta.items()}
    test = np.flatnonzero(meta["split"].astype(str) == "test")
    reducer = meta["reducer"][test[0]]
    mine = meta["reducer"] == reducer
    base_rows = np.flatnonzero(mine & (meta["role"].astype(str) == "baseline"))
    mon_rows = np.flatnonzero(mine & (meta["role"].astype(str) == "monitored") & (s.y.astype(str) == "T1"))
    point = (meta["output_speed_deg_s"][mon_rows[0]], meta["load_Nm"][mon_rows[0]])
    near = mon_rows[np.abs(meta["load_Nm"][mon_rows] - point[1]) < 0.1 * point[1]]
    units = list(dict.fromkeys(meta["unit"][near].tolist()))[:2]  # two records at one operating point
    x = np.concatenate([s.X[i] for u in units for i in np.flatnonzero(meta["unit"] == u)]).astype(np.float64)
    fs = float(store.fs)
    x = x[: int(fs)]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        bm = {k: meta[k][base_rows] for k in ("output_speed_deg_s", "load_Nm", "unit")}
        bm["split"] = np.array(["train"] * base_rows.size)
        write_store(tmp / "base.zarr", s.X[base_rows], s.y[base_rows], bm, kind="measured", fs=fs,
                    config={"bench": "monitor_record_speed"}, extra_attrs={"params": store.attrs.get("params")})
        rec_path = tmp / "record.npy"
        np.save(rec_path, x)
        speed, load = float(np.mean(meta["output_speed_deg_s"][mon_rows])), float(point[1])

        t0 = time.perf_counter()
        from rvdiag.monitoring import monitor_record, open_baseline
        from rvdiag.workflows import load_model, read_record

        model = load_model(a.monitor)
        base = open_baseline(tmp / "base.zarr", model)
        first = monitor_record(model, read_record(rec_path, fs=fs), base, output_speed=speed, load=load)
        t_first = time.perf_counter() - t0
        times, uncached, cpu, cpu_uncached = [], [], [], []
        for _ in range(a.repeat):
            t, c = time.perf_counter(), time.process_time()
            res = monitor_record(model, read_record(rec_path, fs=fs), base, output_speed=speed, load=load)
            times.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
            base.spectra.clear()
            t, c = time.perf_counter(), time.process_time()
            again = monitor_record(model, read_record(rec_path, fs=fs), base, output_speed=speed, load=load)
            uncached.append(time.perf_counter() - t)
            cpu_uncached.append(time.process_time() - c)
            assert json.dumps(again.to_dict()) == json.dumps(res.to_dict())
        assert res.to_dict() == first.to_dict()
        cli = []
        argv = [sys.executable, "-m", "rvdiag", "diagnose", str(a.monitor), str(rec_path), "--baseline",
                str(tmp / "base.zarr"), "--fs", str(fs), "--output-speed", str(speed), "--load", str(load), "--json"]
        for _ in range(a.cli_repeat):
            t = time.perf_counter()
            r = subprocess.run(argv, capture_output=True, text=True)
            cli.append(time.perf_counter() - t)
            if r.returncode:
                raise SystemExit(r.stderr)
        got = json.loads(r.stdout)
        assert got["health_index"] == first.health_index, (got["health_index"], first.health_index)
    out = {"record_points": int(x.size), "fs": fs, "n_windows": first.n_windows, "recognised": first.recognised,
           "health_index": first.health_index, "in_process_first_s": round(t_first, 3),
           "in_process_median_s": round(statistics.median(times), 4), "in_process_repeat": a.repeat,
           "in_process_spectra_recomputed_median_s": round(statistics.median(uncached), 4),
           "ratio_recomputed_over_kept": round(statistics.median(uncached) / statistics.median(times), 2),
           "in_process_cpu_median_s": round(statistics.median(cpu), 4),
           "in_process_spectra_recomputed_cpu_median_s": round(statistics.median(cpu_uncached), 4),
           "cpu_ratio_recomputed_over_kept": round(statistics.median(cpu_uncached) / statistics.median(cpu), 3),
           "cli_median_s": round(statistics.median(cli), 3), "cli_repeat": a.cli_repeat,
           "ratio_cli_over_in_process": round(statistics.median(cli) / statistics.median(times), 1)}
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
