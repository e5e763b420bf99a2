"""``rvdiag separability [--pair T1,T4] [--snr-db=LEVELS] [--run-to-run default|KEY=PCT,...] [--draws K] [--json]
[--out BOUND.json]``: the best accuracy any classifier can reach in telling two states of the simulator apart at each
white-noise SNR, without and with run-to-run variation (:mod:`rvdiag.evaluation.separability`)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from rvdiag.cli import _options as opt
from rvdiag.errors import ParameterError
from rvdiag.validation import finite_number

#: Python parameters of the library calls -> the options of this command (error messages name the option).
SEPARABILITY_OPTION_NAMES = {"duration_s": "--duration", "fs": "--fs", "substeps": "--substeps",
                             "transient_s": "--transient", "load_Nm": "--load",
                             "output_speed_deg_s": "--output-speed"}


def _pair(text: str) -> list[str]:
    from rvdiag.gears.faults import FAULT_KINDS as STATES

    names = [x.strip().upper() for x in str(text).split(",")]
    if len(names) != 2 or not all(names):
        raise ParameterError(f"--pair must name two states, e.g. T1,T4, got {text!r}")
    for n in names:
        if n not in STATES:
            raise ParameterError(f"--pair: unknown state {n!r}; choose among {', '.join(STATES)}")
    return names


def _check_pair_severities(pair: list[str], severities: dict) -> None:
    """Every severity given must apply to a state of the pair, and be valid for it."""
    from rvdiag.cli.simulate import _check_severities
    from rvdiag.gears.faults import FAULT_KINDS as STATES

    kinds = {k for s in pair for k in STATES[s].split("+")}
    for key in severities:
        if opt.FAULT_SEVERITY_OPTIONS[key].kind not in kinds:
            raise ParameterError(f"{opt.FAULT_SEVERITY_OPTIONS[key].option} does not apply to the pair "
                                 f"{','.join(pair)} ({', '.join(STATES[s] for s in pair)})")
    for s in pair:
        used = {k: v for k, v in severities.items() if opt.FAULT_SEVERITY_OPTIONS[k].kind in STATES[s].split("+")}
        _check_severities(s, used)


def register(app: typer.Typer) -> None:
    """Add the ``separability`` command to ``app``."""

    @app.command("separability")
    @opt.fault_severity_options
    def separability_cmd(
        pair: str = typer.Option("T1,T4", "--pair", help="The two states, e.g. T1,T4 (the crack; default) or "
                                 "T5,T6."),
        output_speed: Optional[float] = typer.Option(None, "--output-speed", help="Output (carrier) speed, deg/s "
                                                     "(default: the demo library's, configs/demo.toml)."),
        load: Optional[float] = typer.Option(None, "--load", help="Output load torque, N m (default: the demo "
                                             "library's)."),
        duration: Optional[float] = typer.Option(None, "--duration", help="Simulated record per state, s, after "
                                                 "the transient (default: the demo library's, 1 s)."),
        window: Optional[int] = typer.Option(None, "--window", help="Points per window: the sample length "
                                             "(default: the demo library's segment_length, 4096)."),
        snr_db: str = opt.snr_db("SNRs in dB, comma-separated (per-sample convention of the library's noise); "
                                 "--snr-db=-5,0,5 (the '=' lets the list start with a minus).",
                                 "-5,0,5,10,15,20,30"),
        severities: Optional[dict] = None,  # the ten fault-severity options (opt.fault_severity_options)
        params: Optional[Path] = opt.params(),
        params_b: Optional[Path] = typer.Option(None, "--params-b", help="Reducer parameter TOML of the pair's "
                                                "second state (default: --params): another specimen, e.g. "
                                                "[modification] error_seed = 7, to compare two reducers."),
        fs: Optional[float] = opt.fs("Sampling rate, Hz (default: the demo library's, 48000)."),
        substeps: Optional[int] = typer.Option(None, "--substeps", help="Integrator steps per output sample "
                                               "(default: the demo library's [model] substeps, 4)."),
        run_to_run: Optional[str] = typer.Option(
            None, "--run-to-run", help="Also the bound with run-to-run variation between records: 'default' "
            "(load 3, speed 1, temperature 2, damping 10, gain 3 %) or KEY=PERCENT pairs, e.g. "
            "load=3,speed=1,temperature=2,damping=10,gain=3 (half-ranges, uniform; keys left out: 0)."),
        draws: int = typer.Option(16, "--draws", help="Run-to-run draws simulated in both states (with "
                                  "--run-to-run); the Gaussian figure errs high for few draws."),
        seed: int = opt.seed("Seed of the run-to-run draws (recorded in the output)."),
        json_out: bool = opt.json_flag("Print pair, window, n_windows, snr_db, accuracy_bound, distance_over_rms "
                                       "(and the operating point; with --run-to-run also run_to_run: its ranges, "
                                       "draws, accuracy_bound_known_draw and accuracy_bound_gaussian) as JSON."),
        out: Optional[Path] = opt.out("Also write the JSON here (for 'rvdiag evaluate --plot --bound').", None),
        quiet: bool = opt.quiet(),
    ) -> None:
        """The separability bound: the best accuracy ANY classifier can reach in telling two states apart at
        each white-noise SNR, for the simulator (binary detection of known signals in white Gaussian noise,
        accuracy Phi(d / 2 sigma) per window; rvdiag.evaluation.separability).  Both states are simulated
        noise-free with identical parameters (or the second on --params-b: two specimens), operating point and
        seeds; channel 0 (housing x), as the library.
        With --run-to-run, also the bound when every record varies from run to run: the detector that knows
        each record's draw (an upper bound) and the best detector that does not (Gaussian approximation of the
        draws' spread, Phi(d/2) with d^2 = delta^T (Sigma_rr + sigma^2 I)^-1 delta).  Progress on stderr
        (-q: none)."""
        from rvdiag.cli._progress import progress_bars
        from rvdiag.evaluation.separability import (parse_run_to_run, separability_bound, simulate_pair,
                                                    simulate_varied_pairs, varied_bound)
        from rvdiag.library.config import LibraryConfig
        from rvdiag.params import ReducerParams

        states = _pair(pair)
        levels = opt.parse_levels(snr_db)
        ranges = parse_run_to_run(run_to_run) if run_to_run is not None else None
        if ranges is not None and draws < 2:
            raise ParameterError(f"--draws must be a whole number >= 2 (a spread needs two draws), got {draws}")
        _check_pair_severities(states, severities)
        demo = LibraryConfig.load("demo")
        speed = float(demo.speed.lo) if output_speed is None else float(output_speed)
        load_nm = float(demo.load_Nm.lo) if load is None else float(load)
        duration_s = float(demo.duration_s) if duration is None else float(duration)
        fs_hz = float(demo.fs) if fs is None else float(fs)
        win = int(demo.segment_length) if window is None else int(window)
        model = dict(demo.model)
        if substeps is not None:
            model["substeps"] = substeps
        for option, value in (("--output-speed", speed), ("--duration", duration_s), ("--fs", fs_hz)):
            finite_number(value, option, 0, strict=True, noun="a number")
        finite_number(load_nm, "--load", 0, noun="a number")
        if win < 2:
            raise ParameterError(f"--window must be a whole number of points >= 2, got {win}")
        n_record = int(round(duration_s * fs_hz))
        if win > n_record:
            raise ParameterError(f"--window {win} points is longer than the record: --duration {duration_s:g} s "
                                 f"at {fs_hz:g} Hz gives {n_record} points")
        if out is not None and (out.is_dir() or not out.parent.is_dir()):
            raise ParameterError(f"--out {out}: not a writable file path")
        p = ReducerParams.load(params)
        p_b = p if params_b is None else ReducerParams.load(params_b)
        if params_b is not None and ranges is not None:
            raise ParameterError("--params-b and --run-to-run: give one (two specimens, or one specimen's run-to-run "
                                 "variation)")
        kw = dict(params=p, output_speed_deg_s=speed, load_Nm=load_nm, duration_s=duration_s, fs=fs_hz,
                  transient_s=demo.transient_s, model=model,
                  channel=int(demo.channel) if isinstance(demo.channel, int) else 0, severities=severities)
        with opt.option_names(SEPARABILITY_OPTION_NAMES), progress_bars(quiet):
            if ranges is None:
                a, b = simulate_pair(states, params_b=p_b, **kw)
            else:
                sim = simulate_varied_pairs(states, ranges=ranges, draws=draws, seed=seed, **kw)
                a, b = sim["a"], sim["b"]
        res = separability_bound(a, b, win, levels)
        result = {"pair": states, **res, "output_speed_deg_s": speed, "load_Nm": load_nm, "duration_s": duration_s,
                  "fs": fs_hz, "substeps": model.get("substeps"), "severities_SI": severities,
                  "params_file": str(params) if params is not None else None,
                  "params_file_b": str(params_b) if params_b is not None else None}
        if ranges is not None:
            var = varied_bound(sim, win, levels)
            result["run_to_run"] = {"ranges_pct": {k: 100 * v for k, v in ranges.items()}, "seed": seed,
                                    **{k: var[k] for k in ("draws", "n_windows", "start", "accuracy_bound_known_draw",
                                                           "accuracy_bound_gaussian", "spread_over_distance")},
                                    "factors": sim["factors"], "lags": sim["lags"]}
        text = json.dumps(result, indent=2)
        if out is not None:
            try:
                out.write_text(text + "\n")
            except OSError as exc:
                raise ParameterError(f"cannot write --out {out}: {exc}") from None
        if json_out:
            typer.echo(text)
        else:
            _print(result)
        if out is not None:
            typer.echo(f"wrote {out}", err=json_out)


def _print(result: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    a, b = result["pair"]
    con = Console()
    con.print(f"{a} against {b} at {result['output_speed_deg_s']:g} deg/s, {result['load_Nm']:g} N m: "
              f"{result['n_windows']} windows of {result['window']} points, median ||s_{a} - s_{b}|| / ||s_{a}|| "
              f"= {result['distance_over_rms']:.4g}; the bound is the best accuracy any classifier can reach in "
              f"telling the two apart (chance 50 %)")
    var = result.get("run_to_run")
    if var is not None:
        ranges = ", ".join(f"{k} {v:g} %" for k, v in var["ranges_pct"].items())
        con.print(f"run-to-run variation ({ranges}; {var['draws']} draws, seed {var['seed']}): the healthy "
                  f"draws' spread is {var['spread_over_distance']:.3g} x ||s_{b} - s_{a}||.  'knowing the draw': "
                  f"the detector told each record's variation (an upper bound); 'not knowing it': the best "
                  f"detector against the draws' spread, Gaussian approximation (errs high for few draws)")
    t = Table(title=f"separability bound {a}/{b}")
    t.add_column("SNR (dB)", justify="right")
    t.add_column("accuracy bound" if var is None else "no variation", justify="right")
    if var is not None:
        t.add_column("knowing the draw", justify="right")
        t.add_column("not knowing it", justify="right")
    for i, (s, v) in enumerate(zip(result["snr_db"], result["accuracy_bound"])):
        row = [f"{s:g}", f"{100 * v:.2f} %"]
        if var is not None:
            row += [f"{100 * var['accuracy_bound_known_draw'][i]:.2f} %",
                    f"{100 * var['accuracy_bound_gaussian'][i]:.2f} %"]
        t.add_row(*row)
    con.print(t)
