"""``rvdiag diagnose MODEL_DIR FILE [--channel C] [--fs HZ] [--json]``: diagnose a measured or simulated signal.

The record is read as ``rvdiag dataset from-files`` reads a file of a store (``--channel``, ``--fs``,
``--angle-channel``, ``--tacho-channel``, ``--ppr``, ``--meta-regex``; :func:`rvdiag.workflows.read_record`) and
diagnosed by :func:`rvdiag.workflows.diagnose` (a classifier: the windows' probabilities, whether the record is
recognised, the warnings that qualify the answer, the gear indicators or motor-current lines) or, for a model whose
card says ``needs_baseline``, judged against ``--baseline`` by :func:`rvdiag.monitoring.monitor_record`; with ``--twin
DIR`` also by the crack detector of the joint's twin (:func:`rvdiag.monitoring.crack.load_twin`; its result under
``crack``).  This module parses the options and prints; ``--json`` prints the result's ``to_dict()``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import List

import typer

from rvdiag.cli import _options as opt
from rvdiag.cli._baseline import not_recognised_line
from rvdiag.errors import ParameterError

MAX_ROWS = 40


def register(app: typer.Typer) -> None:
    @app.command("diagnose")
    def diagnose(
        model_dir: Path = typer.Argument(..., help="Model directory written by 'rvdiag train'."),
        file: Path = typer.Argument(..., help="Signal file: CSV/CSV.gz, MAT, NPY, NPZ, WAV, TDMS."),
        channel: str = opt.channel(),
        fs: float = opt.fs("Sampling rate in Hz (overrides the file's)."),
        json_out: bool = opt.json_flag("Print the result as JSON."),
        output_speed: float = opt.output_speed(),
        load: float = opt.load(),
        meta: List[str] = typer.Option([], "--meta",
                                       help="NAME=VALUE: a metadata value the model reads, e.g. rpm=1797 (default: "
                                            "the file's scalar the training store read, e.g. X105RPM)."),
        baseline: Path = typer.Option(None, "--baseline", metavar="BASE.zarr",
                                      help="A baseline-referenced model: a healthy store of the same machine "
                                           "(docs/monitoring.md)."),
        twin: Path = typer.Option(None, "--twin", metavar="DIR",
                                  help="With --baseline: the joint's twin folder (rvdiag update --specimen ... --out "
                                       "DIR); adds its crack detector's index and alarm (DIR/crack, docs/twin.md)."),
        angle_channel: str = opt.angle_source("angle_channel"),
        tacho_channel: str = opt.angle_source("tacho_channel"),
        ppr: int = opt.angle_source("ppr"),
        meta_regex: str = typer.Option(None, "--meta-regex",
                                       help="Regex whose named groups, searched in the file name, give its speed "
                                            "(speed_dps or rpm) and load (load_Nm or load), as 'dataset from-files' "
                                            "reads them, e.g. '(?P<speed_dps>\\d+)dps_(?P<load>\\d+)Nm'."),
    ) -> None:
        """Diagnose the state of a reducer from one signal file."""
        from rvdiag.workflows import load_model
        from rvdiag.workflows.diagnosis import diagnose as diagnose_record, read_model_record

        reading = {"angle_channel": angle_channel, "tacho_channel": tacho_channel, "ppr": ppr,
                   "meta_regex": meta_regex}
        loaded = load_model(model_dir)
        if _monitor(loaded, file, channel, fs, baseline, meta, output_speed, load, json_out, reading, twin):
            return
        rec = read_model_record(loaded, file, channel=channel, fs=fs, **reading)
        res = diagnose_record(loaded, rec, output_speed=output_speed, load=load,
                              metadata=_given_meta(meta)).to_dict()
        res["file"] = str(file)
        for w in res["warnings"]:
            typer.echo(w, err=True)
        if json_out:
            typer.echo(json.dumps(res, indent=2))
            return
        _print(res)


def _monitor(loaded, file, channel, fs, baseline, meta, output_speed, load, json_out, reading, twin=None) -> bool:
    """Diagnose with a baseline-referenced model (:func:`rvdiag.monitoring.monitor_record`), and with the crack
    detector of the twin ``twin`` if given, and say True; False otherwise."""
    from rvdiag.cli._baseline import print_diagnosis
    from rvdiag.monitoring import monitor_record, needs_baseline, open_baseline
    from rvdiag.monitoring.crack import load_twin
    from rvdiag.workflows import read_record

    if not needs_baseline(loaded):
        if baseline is not None:
            raise ParameterError(f"--baseline applies to a baseline-referenced model; {loaded.path} is not one")
        if twin is not None:
            raise ParameterError(f"--twin applies with a baseline-referenced model and --baseline; {loaded.path} is "
                                 "not one")
        return False
    if baseline is None:
        raise ParameterError(f"the model {loaded.path} is baseline-referenced (its card says needs_baseline): give "
                             "--baseline BASE.zarr, a healthy store of the same machine (docs/monitoring.md)")
    crack_twin = load_twin(twin) if twin is not None else None
    base = open_baseline(baseline, loaded)
    rec = read_record(file, channel=channel, fs=fs, **reading)
    res = monitor_record(loaded, rec, base, output_speed=output_speed, load=load, metadata=_given_meta(meta)).to_dict()
    res.update({"file": str(file), "channel": rec.channel, "model": str(loaded.path)})
    crack = None
    if crack_twin is not None:
        op = res["operating_point"]
        crack = crack_twin.judge(rec.data, rec.fs, op["output_speed_deg_s"], op["load_Nm"], name=str(file))
        res["crack"] = crack.to_dict()
        if crack.warning:
            res["warnings"].append(f"warning: {crack.warning}")
    for w in res["warnings"]:
        typer.echo(w, err=True)
    if json_out:
        typer.echo(json.dumps(res, indent=2))
    else:
        print_diagnosis(res)
        if crack is not None:
            typer.echo(crack.line())
    return True


def _given_meta(items: list[str]) -> dict[str, float]:
    """The values of ``--meta NAME=VALUE``."""
    import math

    given: dict[str, float] = {}
    for item in items:
        name, sep, text = item.partition("=")
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not sep or not name.strip() or not math.isfinite(value):
            raise ParameterError(f"--meta {item!r}: expected NAME=NUMBER, e.g. rpm=1797")
        given[name.strip()] = value
    return given


def _print(res: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    con = Console()
    if not res["recognised"]:
        con.print(not_recognised_line(res), soft_wrap=True)
        return
    classes = list(res["probabilities"])
    t = Table(title=f"{res['file']} [{res['channel']}]: {res['n_windows']} window(s) of {res['window_length']} points")
    t.add_column("window")
    t.add_column("start", justify="right")
    t.add_column("diagnosis")
    for c in classes:
        t.add_column(c, justify="right")
    rows = res["windows"]
    for i, w in enumerate(rows[:MAX_ROWS]):
        t.add_row(str(i), str(w["start"]), w["prediction"], *(f"{w['probabilities'][c]:.3f}" for c in classes))
    if len(rows) > MAX_ROWS:
        t.add_row("...", f"{len(rows) - MAX_ROWS} more (see --json)", "", *([""] * len(classes)))
    t.add_row("overall", "", res["diagnosis"], *(f"{res['probabilities'][c]:.3f}" for c in classes), style="bold")
    con.print(t)
    p = res["probabilities"][res["diagnosis"]]
    recall = res.get("model_recall")
    several = bool(res.get("set")) and res.get("set_state") is None
    if several:  # the answer is the set; the single most probable state is not one the model can stand behind
        con.print(f"diagnosis: [bold]{res['set_text']}[/bold]", soft_wrap=True)
    con.print(f"{'most probable' if several else 'diagnosis'}: [bold]{res['state']}[/bold] (mean probability "
              f"{p:.3f} over {res['n_windows']} windows"
              + ("" if recall is None else f"; the model recognises {100 * recall:.0f} % of its held-out "
                                           f"{res['diagnosis']} samples") + ")", soft_wrap=True)
    if not several:
        con.print(f"prediction set: [bold]{res['set_text']}[/bold]" if res.get("set_text") else res.get("set_note"),
                  soft_wrap=True)
    if res.get("current_lines"):
        cl = res["current_lines"]
        lt = Table(title=f"motor-current lines (output speed {cl['output_speed_deg_s']:.4g} deg/s from "
                         f"{cl['speed_source']}; height over the median of the bins 6-40 away)")
        for col in ("line", "Hz", "amplitude", "height (dB)"):
            lt.add_column(col, justify="left" if col == "line" else "right")
        for name, ln in cl["lines"].items():
            if ln["amplitude"] is None:
                lt.add_row(name, f"{ln['hz']:.2f}", "beyond the spectrum", "")
            else:
                lt.add_row(name, f"{ln['hz']:.2f}", f"{ln['amplitude']:.4g}", f"{ln['height_db']:.1f}")
        con.print(lt)
    if res.get("indicators"):
        src = res["indicators_source"]
        it = Table(title=f"gear condition indicators, {src['shaft']} shaft ({src['shaft_hz']:.4g} Hz from "
                         f"{src['speed_source']}; TSA of {src['n_revolutions']} revolutions)")
        it.add_column("indicator")
        it.add_column("value", justify="right")
        for k, v in res["indicators"].items():
            it.add_row(k, f"{v:.4g}")
        con.print(it)
