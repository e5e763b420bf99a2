"""The main job of rvdiag on the built-in RV-20E default (``make demo``).

Steps, each an ordinary ``rvdiag`` command printed before it runs, so you can repeat any of them:

1. mesh stiffness of the RV-20E sun-planet pair, healthy and with each fault  -> out/tvms.png, out/tvms_summary.json
2. characteristic frequencies at the demo operating point                   -> out/freqs.json
3. the demo fault-sample library (six states, simulated on Dask)             -> out/demo.zarr
4. train the recommended classifier on its training split                   -> out/model/
   (its prediction sets calibrated cross-conformally: 3 more fits over folds of the training reducers)
5. evaluate on the held-out simulated test split, with the HTML report       -> out/report.html, out/metrics.json
   (six states, and the crack-free decision: a crack counted as its state without the crack, T4=T1, T6=T5)
6. a small paired library: each reducer healthy at commissioning, then later -> out/demo-monitoring.zarr
7. train a baseline-referenced monitor on it (rvdiag train on a paired store) -> out/demo-monitor/
8. evaluate it on held-out reducers, per record, with the false alarms' interval -> out/monitoring.json
9-12. a small simulated fleet watched by that monitor (examples/demo_fleet.py)  -> out/fleet.db, the state table,
   three joints over two weeks: one healthy, one degrading (its alarm raised and acknowledged), one with a dead
   sensor for a while; a static snapshot of the dashboard                     -> out/fleet-dashboard/

Re-running resumes: a finished library is reused, an interrupted one is completed.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RVDIAG = [sys.executable, "-m", "rvdiag"]

# The demo's choices.  The classifier is `rvdiag train`'s default, the setup docs/results.md recommends
# (spectrum-cnn on log spectra, 40 epochs, lr 3e-3, patience 6: rvdiag.registry.RECOMMENDED_TRAINING).
# The prediction sets are calibrated with --calibration cross: every training reducer scored by a model that never
# saw it, the thresholds applied to the model fitted on all; on the demo's held-out reducers that met the stated
# coverage where holding 5 reducers a state out of the fit did not (bench/HISTORY.md, 2026-11-28).
DEMO_CONFIG = ROOT / "configs" / "demo.toml"
DEMO_MONITORING_CONFIG = ROOT / "configs" / "demo-monitoring.toml"
#: the monitoring demo's false-alarm rate per record: its small library calibrates on 48 healthy records (CV+ over
#: its 6 training reducers), enough for 5 % (1 % needs 99: configs/monitoring.toml)
DEMO_ALPHA = 0.05
DEMO_SPEED_RPM = "1500"
#: the crack-free decision (``rvdiag evaluate --merge``): a root crack counted as the state without it
CRACK_FREE = "T4=T1,T6=T5"
#: why the demo prints it (docs/results.md, "The crack across specimens")
CRACK_FREE_WHY = ("why the crack-free decision: a root crack changes the housing signal less than one reducer's "
                  "manufacturing errors differ from another's, so across reducers T4 is told from T1 (and T6 from T5) "
                  "barely better than by chance (docs/results.md)")


def step(title: str, args: list[str], stdout_file: Path | None = None) -> None:
    """Run one rvdiag command, echoing it; stop the demo with its exit code if it fails."""
    shown = " ".join(["rvdiag", *args])
    print(f"\n== {title}\n$ {shown}", flush=True)
    t0 = time.perf_counter()
    if stdout_file is None:
        proc = subprocess.run([*RVDIAG, *args])
    else:
        proc = subprocess.run([*RVDIAG, *args], stdout=subprocess.PIPE, text=True)
        if proc.returncode == 0:
            stdout_file.write_text(proc.stdout)
    if proc.returncode != 0:
        print(f"demo stopped: '{shown}' exited with {proc.returncode}", file=sys.stderr)
        sys.exit(proc.returncode)
    print(f"   ({time.perf_counter() - t0:.1f} s)", flush=True)


def summary_lines(metrics: dict) -> list[str]:
    """The figures the demo prints from ``rvdiag evaluate --json --merge T4=T1,T6=T5``: the six states (accuracy
    with the healthy recall and false-alarm rate beside it, and each state's recall), the prediction sets' coverage
    and size per state (key ``sets``, when the model has a calibration), the crack-free decision
    (key ``merged``) and, in one line, why it is printed."""
    def pct(v) -> str:
        return "-" if v is None else f"{100 * v:.1f} %"

    lines = [f"six states: accuracy {pct(metrics['accuracy'])}, healthy recall {pct(metrics['healthy_recall'])}, "
             f"false-alarm rate {pct(metrics['false_alarm_rate'])} (macro F1 {metrics['f1_macro']:.3f}, "
             f"kappa {metrics['kappa']:.3f})",
             "recall " + ", ".join(f"{c} {pct(v)}" for c, v in metrics["recall"].items())]
    sets = metrics.get("sets")
    if sets is not None:
        lines.append(f"prediction sets: coverage {pct(sets['coverage'])} (stated {pct(sets['stated_coverage'])}), "
                     f"mean size {sets['mean_size']:.2f}; per state "
                     + ", ".join(f"{c} {pct(v['coverage'])} of {100 * v['stated_coverage']:g} % (size "
                                 f"{v['mean_size']:.2f})" for c, v in sets["per_state"].items()))
    merged = metrics.get("merged")
    if merged is not None:
        lines += [f"crack-free decision ({CRACK_FREE}): accuracy {pct(merged['accuracy'])}, healthy recall "
                  f"{pct(merged['healthy_recall'])}, false-alarm rate {pct(merged['false_alarm_rate'])}",
                  CRACK_FREE_WHY]
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=ROOT / "out", help="output folder (default: out/)")
    parser.add_argument("--config", type=Path, default=DEMO_CONFIG,
                        help="library config (default: configs/demo.toml; configs/paper.toml for paper scale)")
    parser.add_argument("--model", default=None,
                        help="classifier to train (default: rvdiag train's, the recommended spectrum-cnn on log spectra)")
    args = parser.parse_args()
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()

    sys.path.insert(0, str(HERE))
    import demo_tvms  # noqa: E402  (examples/demo_tvms.py)

    print("== 1. mesh stiffness (TVMS) of the RV-20E sun-planet pair, healthy and faulty")
    summary = demo_tvms.run(out)
    print(f"   wrote {out / 'tvms.png'} and {out / 'tvms_summary.json'}")
    for state, row in summary["states"].items():
        print(f"   {state} {row['name']:<18} mean {row['mean_N_per_m']:.3e} N/m, min {row['min_N_per_m']:.3e} N/m")

    step("2. characteristic frequencies", ["freqs", "--input-speed", DEMO_SPEED_RPM, "--json"], out / "freqs.json")
    print(f"   wrote {out / 'freqs.json'}")

    library = out / f"{args.config.stem}.zarr"
    step("3. the fault-sample library", ["library", "build", str(args.config), "--out", str(library)])

    model_dir = out / "model"
    if model_dir.exists():
        shutil.rmtree(model_dir)
    step("4. train the classifier", ["train", str(library), "--out", str(model_dir), "--seed", "0",
                                     "--calibration", "cross",
                                     *(["--model", args.model] if args.model else [])])

    report = out / "report.html"
    step("5. evaluate on the held-out test split", ["evaluate", str(model_dir), str(library), "--split", "test",
                                                     "--merge", CRACK_FREE, "--json", "--report", str(report)],
         out / "metrics.json")
    for line in summary_lines(json.loads((out / "metrics.json").read_text())):
        print("   " + line)

    paired = out / "demo-monitoring.zarr"
    step("6. a paired library (each reducer healthy at commissioning, then later)",
         ["library", "build", str(DEMO_MONITORING_CONFIG), "--out", str(paired)])
    monitor_dir = out / "demo-monitor"
    if monitor_dir.exists():
        shutil.rmtree(monitor_dir)
    step(f"7. train the baseline-referenced monitor (alarm at {100 * DEMO_ALPHA:g} % per record)",
         ["train", str(paired), "--out", str(monitor_dir), "--alpha", str(DEMO_ALPHA), "--seed", "0"])
    step("8. evaluate it on the held-out reducers", ["evaluate", str(monitor_dir), str(paired), "--split", "test",
                                                     "--json"], out / "monitoring.json")
    mon = json.loads((out / "monitoring.json").read_text())
    lo, hi = mon["false_alarm_ci95"]
    print(f"   {mon['n_reducers']} held-out reducers, {mon['n_records']} records: accuracy {mon['accuracy']:.4f}; "
          "detection rate " + ", ".join(f"{s} {v:.3f}" for s, v in mon["detection_rate_per_state"].items())
          + f"; false-alarm rate {mon['false_alarm_rate']:.3f} ({mon['n_false_alarms']} of "
          f"{mon['n_healthy_records']} healthy records, 95 % interval {lo:.3f}-{hi:.3f}; stated "
          f"{mon['alarm']['alpha']:g} per record)")
    import demo_fleet  # noqa: E402  (examples/demo_fleet.py)

    t_fleet = time.perf_counter()
    demo_fleet.run(out, monitor_dir, step)
    print(f"   (the fleet steps: {time.perf_counter() - t_fleet:.0f} s)")
    print(f"\nDemo finished in {time.perf_counter() - t_start:.0f} s. Report: {report.resolve()}")


if __name__ == "__main__":
    main()
