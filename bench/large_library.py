"""Memory of a large library: peak RSS of building it and of training on it, at two sizes, and their ratios.

Usage::

    .venv/bin/python bench/large_library.py                           # 10,000 and 100,000 samples
    .venv/bin/python bench/large_library.py --sizes 2000,10000 --log  # smaller; --log appends to bench/HISTORY.md
    .venv/bin/python bench/large_library.py --simulator dynamics --sizes 2000,10000 --build-only  # the real model

The library: six states (T1..T6), independent simulations of 1 s at 48 kHz with random speed, load and SNR, cut
into 4096-point samples every 2048 points (22 per simulation, the layout of configs/demo.toml), simulated by the
**synthetic stand-in** ``rvdiag.library.synthetic:simulate`` (analytic tones and impacts, about 5 ms per
simulation) unless ``--simulator dynamics``.  The dynamic model takes 0.8-1.2 s per simulation of 1.05 s on one
core of the development machine: the 4,548 simulations of 100,000 samples would hold both cores for 30-45 min,
against about 3 min for the stand-in.  What the client holds does not depend on which simulator fills the samples
(each result is one simulation's samples, written and released); the workers' memory does (the dynamic model's
compiled kernels and tables), and ``--simulator dynamics`` at smaller sizes measures it.

For each size, each in a fresh process (so that ``ru_maxrss``, the process's peak resident set, is that phase's):

1. ``build``: ``build_library`` on a local Dask cluster of ``--workers`` worker processes.  Reported: the peak RSS of
   the client (which writes the store) and the peak of the sum over the client and its workers, sampled every
   0.1 s with psutil.
2. ``train-stream``: ``rvdiag train STORE --streaming --epochs 1`` (the recommended spectrum-cnn on log spectra, one
   full epoch, validation and the test split scored block by block).
3. ``train-memory`` (the baseline, at the sizes of ``--memory-sizes``): the same command with ``--no-streaming``,
   which loads the training and test splits.

Printed: every peak, the ratio of the largest size's peak to the smallest's for each phase (flat: near 1; memory that
grows with the store: the size ratio), and streaming / in-memory at the sizes where both ran.  The goal: build and
training of 100,000 samples under 4 GiB.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SIMULATORS = {"synthetic": "rvdiag.library.synthetic:simulate", "dynamics": "rvdiag.library.simulators:dynamics"}
STATES = ("T1", "T2", "T3", "T4", "T5", "T6")
PER_SIMULATION = 22  # 4096-point samples every 2048 points of 1 s at 48 kHz
GIB = 1024 ** 3


def library_config(size: int, simulator: str = SIMULATORS["synthetic"]) -> dict:
    """The library of about ``size`` samples (a whole number of simulations per state)."""
    sims = -(-size // (len(STATES) * PER_SIMULATION))
    return {
        "name": f"large-{size}",
        "mode": "split-by-simulation",
        "seed": 11,
        "simulator": simulator,
        "signal": {"fs": 48000.0, "duration_s": 1.0, "transient_s": 0.05, "segment_length": 4096, "hop": 2048},
        "operation": {"output_speed_deg_s": {"min": 20.0, "max": 60.0}, "load_Nm": {"min": 40.0, "max": 120.0},
                      "noise_snr_db": {"min": 10.0, "max": 30.0}},
        "split": {"simulations_per_state": sims, "test_simulations_per_state": max(1, sims // 5)},
        "states": {"T1": {}, "T2": {"broken_fraction": {"min": 0.5, "max": 1.0}},
                   "T3": {"wear_depth": {"min": 5e-6, "max": 15e-6}},
                   "T4": {"crack_depth": {"min": 1.6e-3, "max": 2.0e-3}},
                   "T5": {"broken_fraction": 1.0, "wear_depth": {"min": 5e-6, "max": 15e-6}},
                   "T6": {"broken_fraction": 1.0, "wear_depth": {"min": 5e-6, "max": 15e-6},
                          "crack_depth": {"min": 1.6e-3, "max": 2.0e-3}}},
    }


class TreeSampler:
    """Peak of the summed RSS of this process and all its descendants, sampled every ``period`` s (psutil)."""

    def __init__(self, period: float = 0.1):
        self.period, self.peak, self._stop = period, 0, threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        import psutil

        me = psutil.Process()
        while not self._stop.is_set():
            total = 0
            for p in [me, *me.children(recursive=True)]:
                try:
                    total += p.memory_info().rss
                except psutil.Error:
                    pass
            self.peak = max(self.peak, total)
            self._stop.wait(self.period)

    def __enter__(self) -> "TreeSampler":
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()


def self_peak() -> int:
    """This process's peak RSS in bytes (``ru_maxrss`` is in KiB on Linux)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


# ---------------------------------------------------------------------- phases (each in its own process)
def phase_build(size: int, out: Path, workers: int, simulator: str) -> dict:
    from rvdiag.library import LibraryConfig, build_library

    cfg = LibraryConfig.from_dict(library_config(size, simulator), source=f"large-{size}")
    t0 = time.perf_counter()
    with TreeSampler() as tree:
        report = build_library(cfg, out, workers=workers, progress=False)
    return {"samples": report.n_samples, "simulations": report.n_units, "wall_s": time.perf_counter() - t0,
            "client_peak": self_peak(), "tree_peak": tree.peak}


def phase_train(store: Path, model: Path, streaming: bool) -> dict:
    from rvdiag.cli import main

    argv = ["train", str(store), "--out", str(model), "--epochs", "1", "--device", "cpu", "--quiet", "--json",
            "--streaming" if streaming else "--no-streaming"]
    t0 = time.perf_counter()
    with TreeSampler() as tree:
        try:
            main(argv)
        except SystemExit as exc:
            if exc.code:
                raise
    card = json.loads((model / "card.json").read_text())
    return {"wall_s": time.perf_counter() - t0, "client_peak": self_peak(), "tree_peak": tree.peak,
            "n_train": card["training_store"]["n_train"]}


def run_phase(args: list[str]) -> dict:
    """Run one phase in a fresh interpreter; its last stdout line is the JSON result."""
    cmd = [sys.executable, __file__, "--phase", *args]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT / "src"), os.environ.get("PYTHONPATH")]))}
    res = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if res.returncode:
        sys.exit(f"phase {' '.join(args)} failed ({res.returncode}):\n{res.stderr[-3000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def gib(b: float) -> str:
    return f"{b / GIB:.2f} GiB"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="10000,100000", help="library sizes in samples, comma-separated")
    ap.add_argument("--memory-sizes", default=None,
                    help="sizes at which to also train in memory (the baseline; default: the smallest)")
    ap.add_argument("--workers", type=int, default=2, help="Dask worker processes of the build (default 2)")
    ap.add_argument("--simulator", choices=sorted(SIMULATORS), default="synthetic",
                    help="synthetic (the stand-in, default) or dynamics (the 26-DOF model)")
    ap.add_argument("--build-only", action="store_true", help="measure the builds only")
    ap.add_argument("--dir", default=None, help="where to build the stores (default: a temporary folder, removed)")
    ap.add_argument("--log", action="store_true", help="append the result to bench/HISTORY.md")
    ap.add_argument("--phase", nargs="+", help=argparse.SUPPRESS)
    args = ap.parse_args()

    if args.phase:  # a child process: one phase, its result as the last line
        kind, *rest = args.phase
        if kind == "build":
            res = phase_build(int(rest[0]), Path(rest[1]), int(rest[2]), rest[3])
        else:
            res = phase_train(Path(rest[0]), Path(rest[1]), kind == "train-stream")
        print(json.dumps(res))
        return

    sizes = sorted(int(s) for s in args.sizes.split(","))
    memory_sizes = [sizes[0]] if args.memory_sizes is None else sorted(int(s) for s in args.memory_sizes.split(","))
    base = Path(args.dir) if args.dir else Path(tempfile.mkdtemp(prefix="rvdiag-large-"))
    base.mkdir(parents=True, exist_ok=True)
    simulator = SIMULATORS[args.simulator]
    what = "the synthetic stand-in, not the dynamic model" if args.simulator == "synthetic" else "the dynamic model"
    print(f"simulator: {simulator} ({what}); Dask workers: {args.workers}; stores in {base}", flush=True)
    results: dict[int, dict] = {}
    try:
        for size in sizes:
            store = base / f"large-{size}.zarr"
            shutil.rmtree(store, ignore_errors=True)
            r = {"build": run_phase(["build", str(size), str(store), str(args.workers), simulator])}
            b = r["build"]
            print(f"{b['samples']} samples ({b['simulations']} simulations): build {b['wall_s']:.0f} s, client peak "
                  f"{gib(b['client_peak'])}, client + workers {gib(b['tree_peak'])}", flush=True)
            r["store_bytes"] = sum(f.stat().st_size for f in store.rglob("*") if f.is_file())
            kinds = [] if args.build_only else ["train-stream"] + (["train-memory"] if size in memory_sizes else [])
            for kind in kinds:
                model = base / f"model-{size}-{kind}"
                shutil.rmtree(model, ignore_errors=True)
                t = r[kind] = run_phase([kind, str(store), str(model)])
                print(f"  {kind}: {t['n_train']} training samples, 1 epoch in {t['wall_s']:.0f} s, peak "
                      f"{gib(t['client_peak'])}", flush=True)
            results[size] = r
            if not args.dir:
                shutil.rmtree(store, ignore_errors=True)
    finally:
        if not args.dir:
            shutil.rmtree(base, ignore_errors=True)

    lo, hi = sizes[0], sizes[-1]
    lines = []
    for size in sizes:
        r = results[size]
        b = r["build"]
        line = (f"- {b['samples']:,} samples ({b['simulations']:,} simulations, store {gib(r['store_bytes'])} on disk): "
                f"build {b['wall_s']:.0f} s, peak RSS client {gib(b['client_peak'])}, client + {args.workers} workers "
                f"{gib(b['tree_peak'])}")
        if "train-stream" in r:
            line += (f"; streaming training (1 epoch, {r['train-stream']['wall_s']:.0f} s) "
                     f"{gib(r['train-stream']['client_peak'])}")
        if "train-memory" in r:
            line += (f"; in-memory training (baseline, {r['train-memory']['wall_s']:.0f} s) "
                     f"{gib(r['train-memory']['client_peak'])}")
        lines.append(line)
    ratios = {
        "build client": results[hi]["build"]["client_peak"] / results[lo]["build"]["client_peak"],
        "build client + workers": results[hi]["build"]["tree_peak"] / results[lo]["build"]["tree_peak"],
    }
    if not args.build_only:
        ratios["streaming training"] = (results[hi]["train-stream"]["client_peak"]
                                        / results[lo]["train-stream"]["client_peak"])
    if "train-memory" in results[hi] and "train-memory" in results[lo]:
        ratios["in-memory training"] = (results[hi]["train-memory"]["client_peak"]
                                        / results[lo]["train-memory"]["client_peak"])
    n_hi, n_lo = results[hi]["build"]["samples"], results[lo]["build"]["samples"]
    lines.append(f"- peak at {n_hi:,} / peak at {n_lo:,} samples (size ratio {n_hi / n_lo:.2f}): "
                 + ", ".join(f"{k} **{v:.2f}**" for k, v in ratios.items()))
    both = [s for s in sizes if "train-memory" in results[s]]
    if both:
        lines.append("- streaming / in-memory training peak: " + ", ".join(
            f"{results[s]['build']['samples']:,} samples "
            f"**{results[s]['train-stream']['client_peak'] / results[s]['train-memory']['client_peak']:.2f}**"
            for s in both))
    top = results[hi]
    worst = max(top["build"]["tree_peak"], top.get("train-stream", {}).get("client_peak", 0))
    lines.append(f"- goal ({'build' if args.build_only else 'build and training'} of {n_hi:,} samples under 4 GiB): "
                 f"largest peak {gib(worst)}: " + ("met" if worst < 4 * GIB else "NOT met"))
    print("\n".join(lines))
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")
    if args.log:
        block = "\n".join([
            "",
            f"## {dt.date.today().isoformat()} — Memory of a large library: build and streaming training",
            "",
            f"Library: 6 states, 4096-point samples (22 per simulation of 1 s at 48 kHz), simulated by `{simulator}` "
            f"({what}).  Training: `rvdiag train STORE --epochs 1` (spectrum-cnn on "
            f"log spectra), `--streaming` against `--no-streaming` (the baseline).  Each phase in a fresh process; "
            f"peak RSS from `ru_maxrss`, the build's client + workers sampled with psutil every 0.1 s.  Load average "
            f"(1 min) at the end: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores.",
            f"Command: `.venv/bin/python bench/large_library.py --sizes {args.sizes}"
            + (f" --simulator {args.simulator}" if args.simulator != "synthetic" else "")
            + (" --build-only" if args.build_only else "")
            + (f" --memory-sizes {args.memory_sizes}" if args.memory_sizes else "") + " --log`",
            "",
            *lines,
            "",
        ])
        with open(ROOT / "bench" / "HISTORY.md", "a", encoding="utf-8") as fh:
            fh.write(block)


if __name__ == "__main__":
    main()
