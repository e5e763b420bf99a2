"""``rvdiag update``: tune the assumed model parameters to a measured healthy record, write the updated TOML; with
``--specimen``, identify a joint's own sun tooth errors from its commissioning records' transmission error and
write its parameter set and their uncertainty to a folder (:mod:`rvdiag.updating.specimen`, docs/twin.md), then the
crack detector's references from the same records' vibration channel (:mod:`rvdiag.monitoring.crack`)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer

from rvdiag.cli import _options as opt
from rvdiag.errors import ConfigError, DataFileError, ParameterError
from rvdiag.validation import finite_number


#: Python parameters of :func:`rvdiag.updating.update_parameters` -> the options that set them.
UPDATE_OPTION_NAMES = {"output_speed_deg_s": "--output-speed", "load_Nm": "--load", "duration_s": "--duration",
                       "max_evals": "--max-evals", "objective": "--objective"}


def register(app: typer.Typer) -> None:
    """Add the ``update`` command to ``app``."""

    @app.command("update")
    def update_cmd(
        measured_files: List[Path] = typer.Argument(..., metavar="FILE", help="Measured healthy record (CSV, MAT, "
                                                    "NPY/NPZ, WAV, TDMS); with --specimen, the joint's commissioning "
                                                    "records (one or more)."),
        specimen: bool = typer.Option(False, "--specimen", help="Identify the joint's own sun tooth errors from the "
                                      "transmission error between its input (--angle-channel) and output "
                                      "(--output-angle-channel) encoders in the records, at --load; write "
                                      "DIR/params.toml, DIR/uncertainty.toml and DIR/specimen.json to --out DIR, "
                                      "then, from the records' --channel, the crack detector's references "
                                      "(DIR/crack)."),
        channel: Optional[str] = opt.channel("Regular expression picking the vibration channel (may be left out "
                                             "when the file holds one); with --specimen, the housing vibration "
                                             "channel of the records, from which the crack detector's references "
                                             "are commissioned (DIR/crack; without it they are not)."),
        fs: Optional[float] = opt.fs("Sampling rate, Hz (default: the one the file states)."),
        output_speed: Optional[float] = typer.Option(None, "--output-speed", help="Output (carrier) speed of the "
                                                     "record, deg/s (with --specimen the output encoder gives it)."),
        load: float = typer.Option(..., "--load", help="Output load torque of the record(s), N m."),
        params: Optional[Path] = opt.params("Base parameter TOML (default: built-in RV-20E); with --specimen, the "
                                            "global update's."),
        out: Path = opt.out("Updated parameter TOML to write; with --specimen, the folder to write."),
        angle_channel: Optional[str] = typer.Option(None, "--angle-channel", metavar="RE", help="--specimen: regex "
                                                    "of the input shaft's (motor encoder's) angle channel, rad."),
        output_angle_channel: Optional[str] = typer.Option(None, "--output-angle-channel", metavar="RE",
                                                           help="--specimen: regex of the output encoder's angle "
                                                           "channel, rad."),
        iterations: int = typer.Option(15, "--iterations", help="--specimen: Levenberg-Marquardt iterations at "
                                       "most (one simulation per operating point each)."),
        draws: int = typer.Option(8, "--draws", help="--specimen: run-to-run records drawn into each record's "
                                  "noise covariance (one simulation per operating point each)."),
        te_noise: Optional[float] = typer.Option(None, "--te-noise", help="--specimen: the output encoder's white "
                                                 "noise per sample, arcsec rms (default: 23-bit quantisation, "
                                                 "0.045 arcsec)."),
        crack_draws: int = typer.Option(32, "--crack-draws", help="--specimen: healthy run-to-run records the twin "
                                        "simulates per operating point for the crack detector (half fit its filter, "
                                        "half set its threshold; >= 4). Costs --crack-draws + 2 x --crack-planet-tables simulations of 1.2 s "
                                        "(1 s after a 0.2 s run-in) per operating point; a point already simulated "
                                        "with the same parameters and settings is kept."),
        crack_planet_tables: int = typer.Option(8, "--crack-planet-tables", help="--specimen: planet tables the "
                                                "crack references span (the planets' runouts, crank holes and "
                                                "phases are not identified; 0: the twin's own table only). "
                                                "--crack-draws must be a multiple, 2 or more a table; each table "
                                                "adds 2 simulations per operating point."),
        no_crack_references: bool = typer.Option(False, "--no-crack-references", help="--specimen: do not "
                                                 "commission the crack detector's references (DIR/crack)."),
        overwrite: bool = opt.overwrite("Overwrite an existing --out file (with --specimen, the files it writes "
                                        "there)."),
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
        each commented.  With --specimen, identify the joint's own sun tooth errors from its commissioning
        records' transmission error instead (docs/twin.md)."""
        from rvdiag.io import read_signal
        from rvdiag.params import ReducerParams
        from rvdiag.updating import OBJECTIVES, update_parameters
        from rvdiag.updating.annotate import annotated_toml, base_text

        overwrite = opt.resolve(overwrite, force, "--force", default=False)
        if specimen:
            _update_specimen(measured_files, params=params, out=out, overwrite=overwrite, fs=fs, load=load,
                             output_speed=output_speed, angle_channel=angle_channel,
                             output_angle_channel=output_angle_channel, iterations=iterations, draws=draws,
                             te_noise=te_noise, as_json=as_json, quiet=quiet,
                             vibration_channel=None if no_crack_references else channel, crack_draws=crack_draws,
                             crack_planet_tables=crack_planet_tables, skip_note=not no_crack_references)
            return
        given = [o for o, v in (("--angle-channel", angle_channel), ("--output-angle-channel", output_angle_channel),
                                ("--te-noise", te_noise), ("--crack-draws", None if crack_draws == 32 else crack_draws),
                                ("--crack-planet-tables", None if crack_planet_tables == 8 else crack_planet_tables),
                                ("--no-crack-references", no_crack_references or None)) if v is not None]
        if given:
            raise ParameterError(f"{given[0]} applies to --specimen")
        if len(measured_files) != 1:
            raise ParameterError(f"the global update reads one record, got {len(measured_files)}; several "
                                 "commissioning records are for --specimen")
        measured_file = measured_files[0]
        if output_speed is None:
            raise ParameterError("give --output-speed, the record's output speed in deg/s")
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


#: what ``--specimen`` writes into its ``--out`` folder
SPECIMEN_FILES = ("params.toml", "uncertainty.toml", "specimen.json")


def _update_specimen(files: list[Path], *, params, out: Path, overwrite: bool, fs, load: float, output_speed,
                     angle_channel, output_angle_channel, iterations: int, draws: int, te_noise, as_json: bool,
                     quiet: bool, vibration_channel: str | None = None, crack_draws: int = 32,
                     crack_planet_tables: int = 8, skip_note: bool = True) -> None:
    """``rvdiag update --specimen``: read each record's two encoder angles, identify the sun's tooth errors
    (:func:`rvdiag.updating.specimen.identify_specimen`), write ``SPECIMEN_FILES`` into ``out``; with
    ``vibration_channel``, commission the crack detector's references from that channel of the same records
    (:func:`rvdiag.monitoring.crack.commission_crack_references`, ``out/crack``)."""
    import math

    import tomli_w

    from rvdiag.atomic import atomic_write
    from rvdiag.io import read_signal
    from rvdiag.params import ReducerParams
    from rvdiag.updating.annotate import annotated_toml, base_text
    from rvdiag.updating.specimen import SpecimenSettings, identify_specimen, te_record

    if angle_channel is None:
        raise ParameterError("--specimen needs --angle-channel, the input shaft's (motor encoder's) angle channel")
    if output_angle_channel is None:
        raise ParameterError("--specimen needs --output-angle-channel, the output encoder's angle channel: the "
                             "tooth errors are identified from the transmission error between the two encoders "
                             "(identification from the housing vibration alone is not built)")
    if fs is not None:
        finite_number(fs, "--fs", 0, strict=True, noun="a number")
    finite_number(load, "--load", 0, noun="a number")
    if output_speed is not None:
        raise ParameterError("--specimen takes each record's speed from its output encoder; leave out --output-speed")
    if iterations < 0 or draws < 0:
        raise ParameterError(f"--iterations and --draws must be >= 0, got {iterations} and {draws}")
    if vibration_channel is not None and crack_draws < 4:
        raise ParameterError(f"--crack-draws must be >= 4 (half fit the crack filter, half set its threshold), got "
                             f"{crack_draws}")
    if vibration_channel is not None and (crack_planet_tables < 0 or (crack_planet_tables and (
            crack_draws % crack_planet_tables or crack_draws // crack_planet_tables < 2))):
        raise ParameterError(f"--crack-draws ({crack_draws}) must be a multiple of --crack-planet-tables "
                             f"({crack_planet_tables}), at least 2 a table (or --crack-planet-tables 0)")
    if te_noise is not None:
        finite_number(te_noise, "--te-noise", 0, strict=True, noun="a number")
    settings = SpecimenSettings(iterations=iterations, draws=draws, **(
        {} if te_noise is None else {"te_noise_rad": math.radians(te_noise / 3600)}))
    if out.suffix.lower() == ".toml":
        raise ParameterError(f"with --specimen, --out names a folder (it gets {', '.join(SPECIMEN_FILES)}), "
                             f"got {out}")
    if out.exists() and not out.is_dir():
        raise ParameterError(f"--out {out} exists and is not a folder")
    if not out.parent.exists():
        raise ParameterError(f"--out's parent folder does not exist: {out.parent}")
    there = [n for n in SPECIMEN_FILES if (out / n).exists()]
    if there and not overwrite:
        raise ConfigError(f"{out / there[0]} exists; use --overwrite to replace it")
    if params is not None and out.resolve() == params.resolve().parent and "params.toml" == params.name:
        raise ParameterError(f"--out {out} holds the base parameter file; write the specimen to another folder")

    base = ReducerParams.load(params)
    text = base_text(base, params)
    records, vibration = [], []
    for f in files:
        sig_in = read_signal(f, angle_channel, fs)
        try:
            sig_out = read_signal(f, output_angle_channel, fs)
        except DataFileError as exc:
            if "no channel matches" not in str(exc):
                raise
            raise DataFileError(f"{f}: no output encoder angle channel matches {output_angle_channel!r}: the "
                                "tooth errors are identified from the transmission error between the input and "
                                "output encoders (identification from the housing vibration alone is not "
                                "built)") from None
        if sig_in.fs is None:
            raise ParameterError(f"{f} states no sampling rate; give --fs")
        if sig_in.channel == sig_out.channel:
            raise ParameterError(f"{f}: --angle-channel and --output-angle-channel pick the same channel "
                                 f"{sig_in.channel!r}")
        records.append(te_record(sig_in.data, sig_out.data, sig_in.fs, base, load_Nm=load, name=str(f),
                                 settings=settings))
        if vibration_channel is not None:
            vibration.append(_vibration_record(f, vibration_channel, fs, records[-1], (sig_in.channel,
                                                                                      sig_out.channel)))

    result = identify_specimen(base, records, settings,
                               progress=None if quiet else (lambda msg: typer.echo(f"specimen: {msg}", err=True)))

    out.mkdir(exist_ok=True)
    names = ", ".join(Path(r["name"]).name for r in result.records)
    comment = (f"identified by rvdiag update --specimen from {names} (posterior sd in uncertainty.toml): was {{was}}")
    after = result.params(base)
    d = result.to_dict()
    unc = {"identified": {"what": d["identified"], "sun_tooth_errors_um": after.modification.sun_tooth_errors_um,
                          "posterior_sd_um": d["posterior_sd_um"], "scaled_sd_um": d["scaled_sd_um"],
                          "birge_ratio": d["birge_ratio"], "pitch_deviation_sd_um": d["pitch_deviation_sd_um"],
                          "prior_sd_um": d["prior_sd_um"], "posterior_cov_um2": d["posterior_cov_um2"]},
           "not_identified": {"what": d["not_identified"]},
           "fit": {k: d[k] for k in ("chi2_start", "chi2", "n_lines", "residual_rms_rad", "data_rms_rad",
                                     "iterations", "converged", "cost_history", "simulations", "seconds")},
           "settings": d["settings"],
           "records": d["records"],
           "base": {"params": str(params) if params is not None else "built-in"}}
    try:
        atomic_write(out / "params.toml", annotated_toml(base, after, text, comment))
        atomic_write(out / "uncertainty.toml", tomli_w.dumps(unc))
        atomic_write(out / "specimen.json", json.dumps(d, indent=1))
    except OSError as exc:
        raise ParameterError(f"cannot write into --out {out}: {exc}") from None
    if not result.converged:
        typer.echo(f"warning: the fit had not converged after {result.iterations} iterations (its cost still fell); "
                   "raise --iterations", err=True)
    crack = None
    if vibration:
        from rvdiag.cli._progress import progress_bars
        from rvdiag.monitoring.crack import commission_crack_references

        twin = ReducerParams.load(out / "params.toml")          # the references are of the set as written
        with progress_bars(quiet):
            crack = commission_crack_references(out, twin, vibration, draws=crack_draws, overwrite=overwrite,
                                                planet_tables=crack_planet_tables)
    elif skip_note:
        typer.echo("note: without --channel the crack detector's references (DIR/crack) are not commissioned; give "
                   "--channel RE, the records' housing vibration channel (or --no-crack-references)", err=True)
    if as_json:
        typer.echo(json.dumps({**d, "out": str(out), **({"crack_references": crack} if crack else {})}, indent=2))
        return
    typer.echo(f"sun tooth errors identified from {len(result.records)} record(s): chi-square {d['chi2_start']:.4g} -> "
               f"{d['chi2']:.4g} over {d['n_lines']} line parts, {result.iterations} iterations, "
               f"{result.simulations} simulations, {result.seconds:.0f} s")
    for j, (e, s_) in enumerate(zip(d["sun_tooth_errors_um"], d["posterior_sd_um"])):
        typer.echo(f"  sun tooth {j:2d}  {e:+8.4f} um  +- {s_:.4f} um (scaled by the residual: "
                   f"+- {s_ * result.birge_ratio:.4f})")
    typer.echo("not identified: " + "; ".join(d["not_identified"]))
    typer.echo(f"wrote {', '.join(str(out / n) for n in SPECIMEN_FILES)}")
    if crack:
        for op in crack["ops"]:
            what = ("kept (simulated before with the same parameters and settings)" if op.get("kept") else
                    f"simulated: {crack['simulations_per_point']} simulations in {op['seconds']:.0f} s")
            typer.echo(f"crack reference {op['file']} at {op['output_speed_deg_s']:.4g} deg/s {op['load_Nm']:g} N m, "
                       f"{len(op['records'])} baseline record(s), {op['duration_s']:g} s: {what}")
        typer.echo(f"wrote {out / 'crack'}")


def _vibration_record(path: Path, channel: str, fs, te, angle_channels: tuple):
    """The commissioning vibration record (:class:`rvdiag.monitoring.crack.CommissioningRecord`) of ``channel`` in
    ``path``, at the speed the output encoder measured (``te``, its :class:`~rvdiag.updating.specimen.TERecord`)."""
    from rvdiag.io import read_signal
    from rvdiag.monitoring.crack import CommissioningRecord

    sig = read_signal(path, channel, fs)
    if sig.channel in angle_channels:
        raise ParameterError(f"{path}: --channel picks the encoder channel {sig.channel!r}; give the housing "
                             "vibration channel")
    if sig.fs is None:
        raise ParameterError(f"{path} states no sampling rate; give --fs")
    return CommissioningRecord(sig.data, float(sig.fs), te.output_speed_deg_s, te.load_Nm, str(path))


def _told_apart(before: float, after: float, digits: int) -> tuple[str, str]:
    """``before`` and ``after`` with the fewest significant digits, at least ``digits``, that tell them apart."""
    for n in range(digits, 18):
        tb, ta = f"{before:.{n}g}", f"{after:.{n}g}"
        if tb != ta or before == after:
            break
    return tb, ta
