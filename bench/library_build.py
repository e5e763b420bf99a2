"""Library build throughput: samples per second with 1 and 2 Dask workers, and their ratio.

Usage::

    .venv/bin/python bench/library_build.py                      # demo config, 4 simulations per state
    .venv/bin/python bench/library_build.py --sims 2 --synthetic # the analytic stand-in (machinery only)
    .venv/bin/python bench/library_build.py --log                # also append the result to bench/HISTORY.md
    .venv/bin/python bench/library_build.py --specimen-cost --sims 2 --workers 0 --log
                                  # cost per simulated second: specimens + noise floor against one specimen + record
    .venv/bin/python bench/library_build.py --life-cost --reducers 4 --records 6 --log
                                  # cost per simulated second: configs/life.toml against configs/monitoring.toml

Each run builds the same library into a fresh store, end to end as a user sees it: starting the local
cluster, importing (and loading the compiled model) on the workers, simulating, writing.  ``workers = 0``
(in-process, no Dask) is the baseline.  The 1-worker run shows the Dask overhead, the 2-worker run the
parallel speed-up (ideal 2 on 2 free cores; less when other work shares the machine -- the load average
is printed).

``--specimen-cost`` builds the config twice in the same run, in-process: as given with ``[randomise] specimen`` and
``[operation] noise_mode = "floor"`` (each simulation its own specimen, and a healthy twin per reducer for the
floor), and without them (one specimen, noise scaled to each record: the library before issue 26), and prints the
cost per simulated second of each and their ratio (the issue's goal: within 1.2).

``--life-cost`` builds, in-process and in the same run, the life-history config (``configs/life.toml``, issue 35) and
the paired monitoring config (``configs/monitoring.toml``), both cut to ``--reducers`` reducers with one commissioning
record per point, the life config to ``--records`` records over its 420 days with the first seed from its own on
whose reducers every fate falls (so that the cut holds its kinds of records), the monitoring config to 2 healthy and 1
of each fault state monitored records a reducer, and prints the cost per simulated second (wall / records x duration_s, end to end:
plan, simulations, store) of each and their ratio (the issue's goal: a life library within the cost per simulated
second of today's libraries), and what the shipped life config's 200 x 72 records would take on 2 workers at that cost.
"""

from __future__ import annotations

import argparse
import datetime as dt
import os
import shutil
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=str(ROOT / "configs" / "demo.toml"))
    ap.add_argument("--sims", type=int, default=4, help="simulations per state (default 4)")
    ap.add_argument("--synthetic", action="store_true", help="use rvdiag.library.synthetic:simulate")
    ap.add_argument("--workers", default="0,1,2", help="comma-separated worker counts (0 = in-process)")
    ap.add_argument("--log", action="store_true", help="append the result to bench/HISTORY.md")
    ap.add_argument("--rounds", type=int, default=2, help="--specimen-cost: alternated builds of each (default 2)")
    ap.add_argument("--specimen-cost", action="store_true",
                    help="cost per simulated second with specimens + noise floor against without them")
    ap.add_argument("--life-cost", action="store_true",
                    help="cost per simulated second of configs/life.toml against configs/monitoring.toml")
    ap.add_argument("--reducers", type=int, default=4, help="--life-cost: reducers of each library (default 4)")
    ap.add_argument("--records", type=int, default=6, help="--life-cost: records of each life history (default 6)")
    args = ap.parse_args()
    if args.specimen_cost:
        specimen_cost(args)
        return
    if args.life_cost:
        life_cost(args)
        return

    from rvdiag.library import LibraryConfig, build_library

    cfg = LibraryConfig.load(args.config)
    cfg = cfg.replace(split={"simulations_per_state": args.sims,
                             "test_simulations_per_state": max(1, args.sims // 4)})
    if args.synthetic:
        cfg = cfg.replace(simulator="rvdiag.library.synthetic:simulate", model={})
    counts = [int(w) for w in args.workers.split(",")]
    rates: dict[int, float] = {}
    walls: dict[int, float] = {}
    tmp = Path(tempfile.mkdtemp(prefix="rvdiag-bench-"))
    try:
        # warm-up: compile / load the model once in this process so the baseline is not a compile time
        build_library(cfg.replace(split={"simulations_per_state": 2, "test_simulations_per_state": 1},
                                  states={"T1": {}, "T2": {}}), tmp / "warm.zarr", workers=0, progress=False)
        for w in counts:
            t0 = time.perf_counter()
            report = build_library(cfg, tmp / f"w{w}.zarr", workers=w, progress=False)
            walls[w] = time.perf_counter() - t0
            rates[w] = report.n_samples / walls[w]
            print(f"workers={w}: {report.n_samples} samples, {report.n_units} simulations in {walls[w]:.1f} s "
                  f"-> {rates[w]:.1f} samples/s", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    load = os.getloadavg()[0]
    lines = [f"- {w} worker(s){' (in-process, no Dask)' if w == 0 else ''}: {rates[w]:.1f} samples/s "
             f"({walls[w]:.1f} s)" for w in counts]
    if 1 in rates and 2 in rates:
        ratio = rates[2] / rates[1]
        lines.append(f"- ratio 2 workers / 1 worker: {ratio:.2f}")
        print(f"ratio 2/1 workers: {ratio:.2f}")
    print(f"load average at the end: {load:.1f}")
    if args.log:
        sim = "synthetic stand-in" if args.synthetic else "26-DOF dynamic model"
        block = "\n".join([
            "",
            f"## {dt.date.today().isoformat()} library build throughput ({sim})",
            "",
            f"Library: {Path(args.config).name} with {args.sims} simulations per state "
            f"({cfg.n_simulations} simulations of {cfg.transient_s + cfg.duration_s:g} s, "
            f"{cfg.n_samples} samples of {cfg.segment_length} points).  End to end: cluster start, worker "
            f"imports, simulation, store writes.  Load average (1 min) at the end: {load:.1f} on "
            f"{os.cpu_count()} cores.",
            f"Command: `.venv/bin/python bench/library_build.py --sims {args.sims}"
            f"{' --synthetic' if args.synthetic else ''} --log`",
            "",
            *lines,
            "",
        ])
        with open(ROOT / "bench" / "HISTORY.md", "a", encoding="utf-8") as fh:
            fh.write(block)


def specimen_cost(args: argparse.Namespace) -> None:
    """Build the config with and without specimens + floor, in-process, and compare the cost per simulated s."""
    from rvdiag.library import LibraryConfig, build_library
    from rvdiag.library.build import _TWIN_POWERS

    cfg = LibraryConfig.load(args.config)
    cfg = cfg.replace(split={"simulations_per_state": args.sims, "test_simulations_per_state": max(1, args.sims // 4)})
    rnd, op = cfg.to_dict()["randomise"], cfg.to_dict()["operation"]
    if args.synthetic:
        cfg = cfg.replace(simulator="rvdiag.library.synthetic:simulate", model={})
    rnd.pop("iso1328_grade", None)
    rnd.pop("specimen", None)
    op.pop("noise_mode", None)
    data = cfg.to_dict()
    data["randomise"], data["operation"] = rnd, op
    before = LibraryConfig.from_dict(data, source="before")
    after = cfg.replace(randomise={"specimen": True}, operation={"noise_mode": "floor"})
    simulated_s = cfg.n_simulations * cfg.duration_s
    tmp = Path(tempfile.mkdtemp(prefix="rvdiag-bench-"))
    cost = {}
    try:
        build_library(before.replace(split={"simulations_per_state": 2, "test_simulations_per_state": 1},
                                     states={"T1": {}, "T2": {}}), tmp / "warm.zarr", workers=0, progress=False)
        for rnd in range(args.rounds):  # alternated, the fastest of each kept: a shared machine's load varies
            for name, c in (("one specimen, record noise", before), ("specimens + floor", after)):
                _TWIN_POWERS.clear()  # each build simulates its twins: no reuse of an earlier round's
                t0 = time.perf_counter()
                build_library(c, tmp / f"{rnd}-{len(cost)}-{name[:3]}.zarr", workers=0, progress=False)
                took = (time.perf_counter() - t0) / simulated_s
                cost[name] = min(took, cost.get(name, took))
                print(f"{name}: {took:.3f} s per simulated second (kept record; {cfg.n_simulations} simulations)",
                      flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    ratio = cost["specimens + floor"] / cost["one specimen, record noise"]
    load = os.getloadavg()[0]
    print(f"ratio specimens + floor / before: {ratio:.2f}; load average at the end: {load:.1f}")
    if args.log:
        block = "\n".join([
            "",
            f"## {dt.date.today().isoformat()} library cost per simulated second: specimens + noise floor (issue 26)",
            "",
            f"Library: {Path(args.config).name} with {args.sims} simulations per state ({cfg.n_simulations} "
            f"simulations of {cfg.transient_s + cfg.duration_s:g} s), in-process (no Dask), the same run, {args.rounds} "
            f"alternated builds of each, the fastest kept.  Prediction: "
            f"the healthy twin of each reducer adds ({cfg.transient_s:g} + 0.1) / ({cfg.transient_s:g} + "
            f"{cfg.duration_s:g}) of the simulation; a specimen of its own per simulation may miss the mesh-table "
            f"cache.  Load average (1 min) at the end: {load:.1f} on {os.cpu_count()} cores.",
            f"Command: `.venv/bin/python bench/library_build.py --specimen-cost --sims {args.sims} --rounds {args.rounds}"
            f"{' --synthetic' if args.synthetic else ''} --log`",
            "",
            *[f"- {k}: {v:.3f} s per simulated second" for k, v in cost.items()],
            f"- ratio: {ratio:.2f} (goal <= 1.2)",
            "",
        ])
        with open(ROOT / "bench" / "HISTORY.md", "a", encoding="utf-8") as fh:
            fh.write(block)


def life_cost(args: argparse.Namespace) -> None:
    """Build the life config and the monitoring config, cut alike, in-process, and compare the cost per simulated s."""
    from rvdiag.library import LibraryConfig, build_library
    from collections import Counter

    from rvdiag.gears.growth import wear_curve
    from rvdiag.library.build import _TWIN_POWERS, make_plan

    split = {"reducers": args.reducers, "test_reducers": 1}
    full = LibraryConfig.load("life")
    # its records spread over the shipped config's 420 days, and the first seed from the config's on whose reducers
    # every fate falls, so that the cut holds the shipped config's kinds of records
    for seed in range(full.seed, full.seed + 1000):
        life = full.replace(seed=seed, split=split, baseline={"records_per_point": 1}, history={
            "records": args.records, "interval_days": full.history.horizon_days / args.records})
        if {u.life["life.fate"] for u in make_plan(life)} == set(full.history.fates):
            break
    mon = LibraryConfig.load("monitoring").replace(split=split, baseline={
        "records_per_point": 1, "monitored_healthy": 2, "monitored_per_state": 1})
    if args.synthetic:
        life = life.replace(simulator="rvdiag.library.synthetic:simulate", model={})
        mon = mon.replace(simulator="rvdiag.library.synthetic:simulate", model={})
    cases = {"monitoring (paired)": mon, "life histories": life}
    tmp = Path(tempfile.mkdtemp(prefix="rvdiag-bench-"))
    cost: dict[str, float] = {}
    try:
        build_library(mon.replace(split={"reducers": 2, "test_reducers": 1}, states={"T1": {}, "T2": {}}),
                      tmp / "warm.zarr", workers=0, progress=False)  # compile / load the model once
        for rnd in range(args.rounds):  # alternated, the fastest of each kept: a shared machine's load varies
            for name, c in cases.items():
                _TWIN_POWERS.clear()  # each build simulates its own twins ...
                wear_curve.cache_clear()  # ... and integrates its own wear curve (its plan's)
                t0 = time.perf_counter()
                build_library(c, tmp / f"{rnd}-{name[:4]}.zarr", workers=0, progress=False)
                took = (time.perf_counter() - t0) / (c.n_simulations * c.duration_s)
                cost[name] = min(took, cost.get(name, took))
                print(f"{name}: {took:.3f} s per simulated second ({c.n_simulations} simulations)", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    ratio = cost["life histories"] / cost["monitoring (paired)"]
    wear_curve.cache_clear()
    t0 = time.perf_counter()
    make_plan(full)
    plan_s = time.perf_counter() - t0
    hours = cost["life histories"] * full.n_simulations * full.duration_s / 2 / 3600
    load = os.getloadavg()[0]
    print(f"life states: {dict(sorted(Counter(u.state for u in make_plan(life)).items()))}")
    print(f"ratio life / monitoring: {ratio:.2f}; configs/life.toml ({full.n_simulations} simulations) at this cost on "
          f"2 ideal workers: {hours:.1f} h (its plan: {plan_s:.1f} s); load average at the end: {load:.1f}")
    if args.log:
        block = "\n".join([
            "",
            f"## {dt.date.today().isoformat()} library cost per simulated second: life histories (issue 35)",
            "",
            f"configs/life.toml against configs/monitoring.toml, both cut to {args.reducers} reducers with one "
            f"commissioning record per point (life: {args.records} records a history over its "
            f"{full.history.horizon_days:g} days, seed {life.seed}, {life.n_simulations} simulations, states "
            f"{dict(sorted(Counter(u.state for u in make_plan(life)).items()))}; monitoring: 2 healthy and 1 of each of T2-T6 monitored records a reducer, "
            f"{mon.n_simulations} simulations), records of {life.transient_s:g} + {life.duration_s:g} s at "
            f"{life.fs:g} Hz, in-process (no Dask), the same run, {args.rounds} alternated builds of each, the fastest "
            f"kept; cost = wall (plan, simulations, store) / (simulations x {life.duration_s:g} s recorded).  Load "
            f"average (1 min) at the end: {load:.1f} on {os.cpu_count()} cores.",
            f"Command: `.venv/bin/python bench/library_build.py --life-cost --reducers {args.reducers} --records "
            f"{args.records} --rounds {args.rounds}{' --synthetic' if args.synthetic else ''} --log`",
            "",
            *[f"- {k}: {v:.3f} s per simulated second" for k, v in cost.items()],
            f"- ratio life / monitoring: {ratio:.2f} (goal: within today's cost, about 1)",
            f"- configs/life.toml ({full.n_simulations} simulations of {full.duration_s:g} s recorded) at this cost on "
            f"2 ideal workers: {hours:.1f} h; its plan (every reducer's life, the wear curve once): {plan_s:.1f} s",
            "",
        ])
        with open(ROOT / "bench" / "HISTORY.md", "a", encoding="utf-8") as fh:
            fh.write(block)


if __name__ == "__main__":
    main()
