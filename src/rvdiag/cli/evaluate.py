"""``rvdiag evaluate MODEL_DIR DATA.zarr [--split test|train|all] [--where COND]... [--merge A=B,...] [--records] [--json]
[--report FILE.html] [--snr-db=LEVELS [--plot FILE.png] [--bound BOUND.json]] [--baseline BASE.zarr] [--life]``.

A classifier is scored by :func:`rvdiag.workflows.evaluate`, a baseline-referenced model (card ``needs_baseline``)
by :func:`rvdiag.monitoring.evaluate_monitor`; this module parses the options and prints (``--json``: the result's
``to_dict()``)."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from rvdiag.cli import _options as opt
from rvdiag.errors import ParameterError
from rvdiag.evaluation.metrics import headline


def register(app: typer.Typer) -> None:
    @app.command("evaluate")
    def evaluate(
        model_dir: Path = typer.Argument(..., help="Model directory written by 'rvdiag train'."),
        data: Path = typer.Argument(..., help="Sample store (.zarr) to score."),
        split: str = typer.Option("test", "--split", help="test | train | all (or any split of the store)."),
        json_out: bool = opt.json_flag("Print accuracy, precision_macro, recall_macro, f1_macro, kappa, "
                                       "per_class, confusion and the prediction sets (sets: stated_coverage, "
                                       "coverage, mean_size, per_state) as JSON."),
        report: Path = typer.Option(None, "--report", help="Write a self-contained HTML report here."),
        by: str = typer.Option(None, "--by",
                               help="Also give the accuracy per value/bin of a metadata column, e.g. noise_snr_db "
                                    "(accuracy against SNR); JSON key 'by'."),
        snr_db: str = opt.snr_db("Also score the split with white noise added at each of these SNRs, e.g. "
                                 "--snr-db=-5,0,5,10,15,20 (the '=' lets the list start with a minus); "
                                 "accuracy against SNR, JSON key 'snr'."),
        seed: int = opt.seed("Seed of the noise added by --snr-db, and with --life of the change detector's "
                             "smoothing draws and the remaining life's Monte Carlo."),
        plot: Path = typer.Option(None, "--plot", metavar="FILE.png", help="With --snr-db: write the figure of accuracy and per-class "
                                  "recall against SNR here (PNG)."),
        bound: list[Path] = typer.Option(None, "--bound", metavar="BOUND.json", help="With --snr-db: a separability bound written by "
                                         "'rvdiag separability --out' (repeatable): drawn dashed on --plot, copied "
                                         "into the JSON (key 'bound')."),
        where: list[str] = typer.Option(None, "--where", metavar="COND",
                                        help="Score only the samples of the split whose metadata satisfy COND, "
                                             "COLUMN OP VALUE with OP < <= > >= == != (repeatable; all must hold), "
                                             "e.g. --where 'noise_snr_db>=20'."),
        merge: str = typer.Option(None, "--merge", metavar="A=B,...",
                                  help="Also score with classes merged, true and predicted alike: T4=T1,T6=T5 counts "
                                       "a crack as its state without it (the crack-free decision); JSON key 'merged'."),
        records: bool = typer.Option(False, "--records",
                                     help="Also score whole records (each simulation of a library, each file of "
                                          "'dataset from-files': metadata column unit), their windows decided "
                                          "together by mean probability as 'rvdiag diagnose' decides a file; "
                                          "JSON key 'records'."),
        quiet: bool = opt.quiet(),
        life: bool = typer.Option(False, "--life",
                                  help="A baseline-referenced model on a life store ('rvdiag library build life'): "
                                       "also score change detection and remaining life over each held-out "
                                       "reducer's history and pooled (lifetime_false_alarm, "
                                       "detection_delay_records, detected_within_3, rul_coverage_80, alpha_lambda, "
                                       "baseline: linear extrapolation); JSON key 'life' (docs/prognostics.md)."),
        baseline: Path = typer.Option(None, "--baseline", metavar="BASE.zarr",
                                      help="A baseline-referenced model: a healthy store of the same machine, each "
                                           "sample matched with its windows at the nearest operating point (not "
                                           "needed on a paired store; docs/monitoring.md)."),
        twin: Path = typer.Option(None, "--twin", metavar="DIR",
                                  help="With a baseline-referenced model: the joint's twin folder (rvdiag update "
                                       "--specimen ... --out DIR); adds its crack detector over the whole records: "
                                       "crack_detection (share of T4 records alarmed) and crack_false_alarm_rate "
                                       "(share of T1 records alarmed) at its stated rate (docs/twin.md)."),
    ) -> None:
        """Score a saved model on a split of a sample store (progress with an ETA on stderr; -q: none)."""
        from rvdiag.cli._progress import progress_bars
        from rvdiag.datasets import SampleStore
        from rvdiag.datasets import parse_where as parse_condition
        from rvdiag.evaluation.evaluate import report_html
        from rvdiag.evaluation.report import write_report
        from rvdiag.workflows import load_model
        from rvdiag.workflows.evaluation import evaluate as evaluate_model, parse_merge, read_bound

        if report is not None and (report.is_dir() or (report.parent.exists() and not report.parent.is_dir())):
            raise ParameterError(f"--report {report}: not a writable file path")
        levels = opt.parse_levels(snr_db) if snr_db is not None else None
        if plot is not None and levels is None:
            raise ParameterError("--plot draws the accuracy against SNR: give --snr-db=LEVELS too")
        if bound and levels is None:
            raise ParameterError("--bound goes with the accuracy against SNR: give --snr-db=LEVELS too")
        if plot is not None and (plot.is_dir() or not plot.parent.is_dir()):
            raise ParameterError(f"--plot {plot}: not a writable file path")
        bounds = [read_bound(b) for b in bound or ()]
        for w in where or ():
            parse_condition(w)  # a malformed condition fails before the model is loaded
        loaded = load_model(model_dir)
        if _monitor(loaded, data, split, where, baseline, json_out, merge,
                    {"--report": report, "--by": by, "--snr-db": snr_db, "--records": records}, life, seed, twin):
            return
        if life:
            raise ParameterError(f"--life scores a baseline-referenced model (a monitor: 'rvdiag train' on a paired "
                                 f"or life store); {loaded.path} is not one")
        merge_map = parse_merge(merge, loaded.card["classes"]) if merge is not None else None
        store = SampleStore.open(data)
        with progress_bars(quiet):
            res = evaluate_model(loaded, store, split=split, where=where or (), by=by, snr_db=levels, seed=seed,
                                 merge=merge_map, records=records, bounds=bounds)
        ev = res.details
        for w in res.warnings:
            typer.echo(w, err=True)
        if report is not None:
            write_report(report, report_html(loaded, store, ev))
        if plot is not None:
            opt.save_plot(res.plot(title=f"{loaded.card.get('model')} on {Path(data).name} [{ev.split}]"), plot)
        if json_out:
            typer.echo(json.dumps(res.to_dict(), indent=2))
        else:
            _print(ev, loaded, data)
            typer.echo(sets_line(res.sets, res.sets_note))
            if res.merged is not None:
                typer.echo(f"merged {','.join(f'{a}={b}' for a, b in merge_map.items())}: {headline(res.merged)}; "
                           + ", ".join(f"{c} recall {100 * v['recall']:.1f} %"
                                       for c, v in res.merged["per_class"].items()))
            if res.records is not None:
                _print_records(res.records)
            if res.by is not None:
                _print_by(by, res.by["groups"])
            if res.snr is not None:
                _print_snr(res.snr)
        if report is not None:
            typer.echo(f"report: {report.resolve()}", err=json_out)
        if plot is not None:
            typer.echo(f"plot: {plot.resolve()}", err=json_out)


def sets_line(sets: dict | None, note: str | None) -> str:
    """The prediction sets' coverage and size in one line, per state; or why there are none."""
    if sets is None:
        return note or "no prediction sets"
    per = "; ".join(f"{c} {100 * v['coverage']:.1f} % of {100 * v['stated_coverage']:g} % (size {v['mean_size']:.2f})"
                    for c, v in sets["per_state"].items())
    return (f"prediction sets: coverage {100 * sets['coverage']:.1f} % (stated {100 * sets['stated_coverage']:.1f} %), "
            f"mean size {sets['mean_size']:.2f}, {100 * sets['singletons']:.1f} % of one state; per state: {per}")


def _monitor(loaded, data, split, where, baseline, json_out, merge, others: dict, life: bool = False,
             seed: int = 0, twin=None) -> bool:
    """Score a baseline-referenced model (:func:`rvdiag.monitoring.evaluate_monitor`; always per record, ``--merge``
    as for any model; ``life``: also the figures over a life store's lives, key ``life``; ``twin``: also the crack
    detector of that twin, :func:`rvdiag.monitoring.crack.evaluate_crack_on_store`) and say True; False for any
    other model."""
    from rvdiag.monitoring import evaluate_monitor, needs_baseline
    from rvdiag.monitoring.crack import evaluate_crack_on_store, load_twin

    if not needs_baseline(loaded):
        if baseline is not None:
            raise ParameterError(f"--baseline applies to a baseline-referenced model; {loaded.path} is not one")
        if twin is not None:
            raise ParameterError(f"--twin applies to a baseline-referenced model; {loaded.path} is not one")
        return False
    for flag, v in others.items():
        if v:
            raise ParameterError(f"{flag} does not apply to a baseline-referenced model")
    if life and twin is not None:
        raise ParameterError("--twin does not apply with --life")
    from rvdiag.datasets import SampleStore
    from rvdiag.workflows.evaluation import parse_merge

    crack_twin = load_twin(twin) if twin is not None else None
    merge_map = parse_merge(merge, loaded.card["classes"]) if merge is not None else None
    store = SampleStore.open(data)
    res = evaluate_monitor(loaded, store, data, split, where or (), baseline, merge_map, life=life, seed=seed)
    if crack_twin is not None:
        res.update(evaluate_crack_on_store(crack_twin, store, split, where or ()))
    if json_out:
        typer.echo(json.dumps(res, indent=2))
    else:
        from rvdiag.cli._baseline import print_evaluation

        print_evaluation(res, loaded, data)
        if life:
            _print_life(res["life"])
        if crack_twin is not None:
            typer.echo(_crack_line(res))
    return True


def _crack_line(res: dict) -> str:
    """The crack detector's figures of ``rvdiag evaluate --twin`` in one line."""
    n = res["crack_n_records"]

    def share(v, state):
        return "no records" if v is None else f"{100 * v:.3g} % of {n[state]} records"

    return (f"crack detector (twin), alarm at {100 * res['crack_alpha']:g} % false alarms: detection "
            f"{share(res['crack_detection'], 'T4')} (T4), false alarms {share(res['crack_false_alarm_rate'], 'T1')} "
            "(T1)")


def _print_life(life: dict) -> None:
    """The pooled life figures in a few lines (``--life`` without ``--json``)."""
    pct = (lambda v: "-" if v is None else f"{100 * v:.1f} %")
    p = life["pooled"]
    fa = p["lifetime_false_alarm"]
    ci = f" [{pct(fa['ci95'][0])}, {pct(fa['ci95'][1])}]" if fa["ci95"] else ""
    typer.echo(f"life ({p['n_histories']} held-out histories: "
               + ", ".join(f"{n} {f}" for f, n in p["fates"].items()) + "): "
               f"healthy histories ever alarming {pct(fa['rate'])}{ci} of {fa['n']} (bound {pct(fa['bound'])})")
    rec = (lambda v: "never" if v is None else f"{v:g}")
    ma = p["monitor_alarm"]
    for state, d in p["detection_delay_records"].items():
        w, mw = p["detected_within_3"][state], ma["detected_within_3"][state]
        typer.echo(f"  {state}: delay median {rec(d['median'])}, p90 {rec(d['p90'])} records; within 3 records "
                   f"{pct(w['share'])} of {w['n']} (the monitor's alarm, 3 of 3: {pct(mw['share'])})")
    mf = ma["lifetime_false_alarm"]
    typer.echo(f"  the monitor's alarm, 3 of 3 records: healthy histories ever alarming {pct(mf['rate'])} of "
               f"{mf['n']} (no lifetime bound)")
    for name, r in (("remaining life", p), ("linear extrapolation", p["baseline"])):
        c, a = r["rul_coverage_80"], r["alpha_lambda"]
        typer.echo(f"  {name}: 80 % interval holds the truth in {pct(c['rate'])} of {c['n']}, alpha-lambda "
                   f"(0.2, 0.5) {pct(a['rate'])}")


def _print_records(r: dict) -> None:
    lo, hi = r["windows_per_record"]
    windows = f"{lo}" if lo == hi else f"{lo}-{hi}"
    line = (f"records ({r['n_records']} of {windows} windows, decided by {r['decision']}): {headline(r)}; "
            + ", ".join(f"{c} recall {100 * v['recall']:.1f} %" for c, v in r["per_class"].items()))
    if "merged" in r:
        line += f"; merged: {headline(r['merged'])}"
    typer.echo(line)


def _print(ev, loaded, data) -> None:
    from rich.console import Console
    from rich.table import Table

    m = ev.metrics
    con = Console()
    con.print(f"{loaded.card.get('model')} on {data} [{ev.split}], {m['n_samples']} samples: "
              f"{headline(m)}, macro F1 {100 * m['f1_macro']:.2f} %, kappa {m['kappa']:.4f}")
    t = Table()
    for col in ("class", "precision", "recall", "f1", "support"):
        t.add_column(col, justify="left" if col == "class" else "right")
    for c, v in m["per_class"].items():
        t.add_row(c, f"{100 * v['precision']:.2f} %", f"{100 * v['recall']:.2f} %", f"{100 * v['f1']:.2f} %",
                  str(v["support"]))
    con.print(t)
    cm = Table(title="confusion (rows true, columns predicted)")
    cm.add_column("")
    for c in m["labels"]:
        cm.add_column(c, justify="right")
    for c, row in zip(m["labels"], m["confusion"]):
        cm.add_row(c, *map(str, row))
    con.print(cm)


def _print_snr(curve: list[dict]) -> None:
    from rich.console import Console
    from rich.table import Table

    classes = list(curve[0].get("per_class_recall", {})) if curve else []
    t = Table(title="accuracy against added-noise SNR (same samples at every level)",
              caption="SNR in dB; accuracy, macro F1, false alarms (share of the healthy samples called faulty)"
                      + (" and the recall of each class (class columns)" if classes
                                                         else "") + " in %")
    t.add_column("SNR", justify="right")
    t.add_column("accuracy", justify="right")
    t.add_column("F1", justify="right")
    t.add_column("kappa", justify="right")
    t.add_column("false alarms", justify="right")
    for c in classes:
        t.add_column(c, justify="right")
    for row in curve:
        t.add_row(f"{row['snr_db']:g}", f"{100 * row['accuracy']:.2f}", f"{100 * row['f1_macro']:.2f}",
                  f"{row['kappa']:.3f}", _pct_or_dash(row.get("false_alarm_rate")),
                  *(f"{100 * row['per_class_recall'][c]:.1f}" for c in classes))
    Console().print(t)


def _print_by(column: str, groups: list[dict]) -> None:
    from rich.console import Console
    from rich.table import Table

    t = Table(title=f"accuracy by {column}")
    t.add_column(column, justify="right")
    t.add_column("samples", justify="right")
    t.add_column("accuracy", justify="right")
    t.add_column("healthy recall", justify="right")
    t.add_column("false alarms", justify="right")
    for g in groups:
        rng = f"{g['lo']:.4g}" if g["lo"] == g["hi"] else f"{g['lo']:.4g} .. {g['hi']:.4g}"
        t.add_row(rng, str(g["n"]), f"{100 * g['accuracy']:.2f} %", _pct_or_dash(g.get("healthy_recall")),
                  _pct_or_dash(g.get("false_alarm_rate")))
    Console().print(t)


def _pct_or_dash(x) -> str:
    """A share as ``12.3 %``, or ``-`` where it is undefined (no healthy sample in the group)."""
    return "-" if x is None else f"{100 * x:.1f} %"
