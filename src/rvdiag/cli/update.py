"""``rvdiag update``: tune the assumed model parameters to a measured healthy record, write the updated TOML."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from rvdiag.cli import _options as opt
from rvdiag.errors import ConfigError, ParameterError
from rvdiag.validation import finite_number


#: Python parameters of :func:`rvdiag.updating.update_parameters` -> the options that set them.
UPDATE_OPTION_NAMES = {"output_speed_deg_s": "--output-speed", "load_Nm": "--load", "duration_s": "--duration",
                       "max_evals": "--max-evals", "objective": "--objective"}


def register(app: typer.Typer) -> None:
    """Add the ``update`` command to ``app``."""

    @app.command("update")
    def update_cmd(
        measured_file: Path = typer.Argument(..., help="Measured healthy record (CSV, MAT, NPY/NPZ, WAV, TDMS)."),
        channel: Optional[str] = opt.channel(),
        fs: Optional[float] = opt.fs("Sampling rate, Hz (default: the one the file states)."),
        output_speed: float = typer.Option(..., "--output-speed", help="Output (carrier) speed of the record, deg/s."),
        load: float = typer.Option(..., "--load", help="Output load torque of the record, N m."),
        params: Optional[Path] = opt.params("Base parameter TOML (default: built-in RV-20E)."),
        out: Path = opt.out("Updated parameter TOML to write."),
        overwrite: bool = opt.overwrite("Overwrite an existing --out file."),
        force: bool = opt.deprecated("--force", flag=True),
        objective: str = typer.Option("logspec", "--objective", help="logspec (PCC of log power spectra, default), "
                                      "envelope (PCC of envelope spectra) or time (PCC of the records; only for "
                                      "records phase-locked to the simulation)."),
        tune: Optional[str] = typer.Option(None, "--tune", help="Comma-separated parameters to tune (default all): "
                                           "sun_support, pin_wheel_housing, crank_cycloid, mesh_damping_ratio, "
                                           "bearing_damping_ratio, housing_added_mass, path_resonance_hz, "
                                           "path_damping_ratio."),
        direction: str = typer.Option("x", "--direction", help="Simulated channel compared with the record: x or y."),
        duration: float = typer.Option(0.5, "--duration", help="Simulated record per evaluation, s (after a 0.1 s "
                                       "run-in); the measured record must be at least this long."),
        max_evals: int = typer.Option(150, "--max-evals", help="Simulations allowed in all (~0.4 s of CPU each "
                                      "for 0.5 s at 48 kHz)."),
        seed: int = opt.seed("Seed of the search; the result depends on nothing else."),
        plot: Optional[Path] = typer.Option(None, "--plot", help="Write a before/after figure of the spectra (PNG)."),
        as_json: bool = opt.json_flag("Print the result as JSON on stdout."),
        quiet: bool = opt.quiet(),
    ) -> None:
        """Tune stiffnesses, damping and mounting of the model so that its healthy signal matches a measured one
        (Pearson correlation of log spectra by default); write the base parameters with the updated values,
        each commented."""
        from rvdiag.io import read_signal
        from rvdiag.params import ReducerParams
        from rvdiag.updating import OBJECTIVES, update_parameters
        from rvdiag.updating.annotate import annotated_toml, base_text

        overwrite = opt.resolve(overwrite, force, "--force", default=False)
        if objective not in OBJECTIVES:
            raise ParameterError(f"--objective must be one of {', '.join(OBJECTIVES)}, got {objective!r}")
        if direction not in ("x", "y"):
            raise ParameterError(f"--direction must be x or y, got {direction!r}")
        for option, value in (("--fs", fs), ("--output-speed", output_speed), ("--duration", duration)):
            if value is not None:
                finite_number(value, option, 0, strict=True, noun="a number")
        finite_number(load, "--load", 0, noun="a number")
        if max_evals < 3:
            raise ParameterError(f"--max-evals must be >= 3, got {max_evals}")
        if out.suffix.lower() != ".toml":
            raise ParameterError(f"--out must name a .toml file, got {out}")
        if params is not None and out.resolve() == params.resolve():
            raise ParameterError(f"--out {out} is the base parameter file; write the update to another file")
        if out.exists() and not overwrite:
            raise ConfigError(f"{out} exists; use --overwrite to replace it")
        if not out.parent.exists():
            raise ParameterError(f"--out directory does not exist: {out.parent}")
        if plot is not None and plot.suffix.lower() != ".png":
            raise ParameterError(f"--plot must name a .png file, got {plot}")
        if plot is not None and not plot.parent.exists():
            raise ParameterError(f"--plot directory does not exist: {plot.parent}")
        names = None if tune is None else [n.strip() for n in tune.split(",") if n.strip()]
        if names is not None and not names:
            raise ParameterError("--tune names no parameter")

        base = ReducerParams.load(params)
        text = base_text(base, params)
        sig = read_signal(measured_file, channel, fs)
        if sig.fs is None:
            raise ParameterError(f"{measured_file} states no sampling rate; give --fs")
        if sig.n_samples < duration * sig.fs:
            raise ParameterError(f"{measured_file}: the record lasts {sig.n_samples / sig.fs:.3g} s; model updating "
                                 f"needs at least {duration:g} s (--duration)")

        kw = dict(output_speed_deg_s=output_speed, load_Nm=load, objective=objective, names=names,
                  duration_s=duration, channel=0 if direction == "x" else 1, max_evals=max_evals, seed=seed)
        if quiet:
            with opt.option_names(UPDATE_OPTION_NAMES):
                result = update_parameters(base, sig.data, sig.fs, **kw)
        else:
            from rich.console import Console
            from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

            with Progress(TextColumn("updating"), BarColumn(), TextColumn("{task.completed}/{task.total} sims"),
                          TextColumn("best PCC {task.fields[best]}"), TimeRemainingColumn(), transient=True,
                          console=Console(stderr=True)) as bar:
                task = bar.add_task("update", total=max_evals, best="-")

                def progress(done: int, total: int, best: float) -> None:
                    bar.update(task, completed=done, total=total, best=f"{best:.4f}")

                with opt.option_names(UPDATE_OPTION_NAMES):
                    result = update_parameters(base, sig.data, sig.fs, progress=progress, **kw)

        pcc_b, pcc_a = _told_apart(result.pcc_before, result.pcc_after, 4)
        comment = (f"updated by rvdiag update from {measured_file.name}: was {{was}}, {objective} PCC before/after "
                   f"{pcc_b}/{pcc_a}")
        toml_text = annotated_toml(base, result.params_after, text, comment)
        try:
            out.write_text(toml_text, encoding="utf-8")
        except OSError as exc:
            raise ParameterError(f"cannot write --out {out}: {exc}") from None
        if plot is not None:
            from rvdiag.updating.plot import before_after_figure

            before_after_figure(result, plot, title=f"{measured_file.name}: model updating ({objective})")

        if as_json:
            typer.echo(json.dumps({
                "pcc_before": result.pcc_before, "pcc_after": result.pcc_after, "objective": objective,
                "parameters": {k: [b, a] for k, (b, a) in result.values.items()},
                "updated": list(result.updated), "best_gain": result.best_gain, "min_gain": result.min_gain,
                "evaluations": result.evaluations, "seed": seed, "out": str(out),
            }, indent=2))
            return
        runs = f"{result.evaluations} simulations, seed {seed}"
        if result.updated:
            typer.echo(f"{objective} PCC {pcc_b} -> {pcc_a} ({runs})")
        elif result.best_gain == 0.0:
            typer.echo(f"{objective} PCC {pcc_b}: no set found matches better than the base set; its values are "
                       f"kept ({runs})")
        else:
            typer.echo(f"{objective} PCC {pcc_b}: the best set found raises it by {result.best_gain:+.2g}, not more "
                       f"than {result.min_gain:g}; the base values are kept ({runs})")
        for name, (b, a) in result.values.items():
            if name in result.updated:
                tb, ta = _told_apart(b, a, 5)
                typer.echo(f"  {name:24s} {tb:>12s} -> {ta:>12s}  (updated)")
            else:
                typer.echo(f"  {name:24s} {b:12.5g}    (unchanged)")
        typer.echo(f"wrote {out}" + (f" and {plot}" if plot is not None else ""))


def _told_apart(before: float, after: float, digits: int) -> tuple[str, str]:
    """``before`` and ``after`` with the fewest significant digits, at least ``digits``, that tell them apart."""
    for n in range(digits, 18):
        tb, ta = f"{before:.{n}g}", f"{after:.{n}g}"
        if tb != ta or before == after:
            break
    return tb, ta
