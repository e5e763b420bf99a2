"""``rvdiag dataset``: build sample stores from measured files, list a file's channels, describe a store."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer

from rvdiag.cli import _options as opt
from rvdiag.errors import ParameterError


def _parse_scalars(items: list[str]) -> dict[str, str]:
    out: dict[str, str] = {}
    for item in items:
        name, sep, regex = item.partition("=")
        if not sep or not name or not regex:
            raise ParameterError(f"--scalar {item!r}: expected NAME=REGEX, e.g. rpm=RPM")
        out[name.strip()] = regex
    return out


def _angle_spec(angle_channel, tacho_channel, ppr, meta_regex, estimate_speed, speed_range, params):
    """The :class:`rvdiag.io.angles.AngleSpec` of ``dataset from-files``' options, or None (no speed columns)."""
    import re

    from rvdiag.io.angles import SPEED_GROUPS, AngleSpec, parse_speed_range

    rng = parse_speed_range(speed_range)
    try:
        named = set(re.compile(meta_regex).groupindex) if meta_regex is not None else set()
    except re.error:
        named = set()  # select_files reports the bad regex
    meta_speed = bool(named & set(SPEED_GROUPS))
    if angle_channel is not None or tacho_channel is not None:
        return AngleSpec(angle_channel=angle_channel, tacho_channel=tacho_channel, ppr=ppr,
                         speed_range_rpm=rng).validate()
    if ppr is not None:
        raise ParameterError("--ppr applies to --tacho-channel or --angle-channel")
    if meta_speed:
        return AngleSpec(meta_regex=meta_regex, speed_range_rpm=rng).validate()
    if estimate_speed:
        return AngleSpec(estimate=True, speed_range_rpm=rng).validate()
    if speed_range is not None or params is not None:
        raise ParameterError("--speed-range and --params apply to an angle source: give --angle-channel, "
                             "--tacho-channel, --estimate-speed or --meta-regex with a group rpm or speed_dps")
    return None


def register(app: typer.Typer) -> None:
    ds_app = typer.Typer(help="Measured datasets: build a sample store from files, describe stores.",
                         no_args_is_help=True)
    app.add_typer(ds_app, name="dataset")

    @ds_app.command("from-files")
    def from_files(
        folder: Path = typer.Argument(..., help="Folder holding the measured files (not searched recursively)."),
        label_regex: str = typer.Option(..., "--label-regex",
                                        help="Regex with a named group (?P<label>...) matched against each file name."),
        channel: Optional[str] = opt.channel("Regex matching exactly one channel (column, variable) per file."),
        window: int = typer.Option(..., "--window", help="Window length in samples (one sample per window)."),
        hop: Optional[int] = typer.Option(None, "--hop", help="Step between windows in samples (default: --window)."),
        fs: Optional[float] = opt.fs("Sampling rate in Hz (default: from the files; a file that states none needs "
                                     "it, or --unknown-fs)."),
        unknown_fs: bool = typer.Option(False, "--unknown-fs", help="The files state no sampling rate and none is "
                                        "known (e.g. the SpectraQuest gearbox set): store the windows without one "
                                        "(frequencies in cycles per sample)."),
        meta_regex: Optional[str] = typer.Option(None, "--meta-regex",
                                                 help="Regex whose named groups become metadata columns, e.g. 'hz(?P<load>\\d+)'."),
        include: Optional[str] = typer.Option(None, "--include", help="Keep only files whose names match this regex."),
        test_fraction: Optional[float] = typer.Option(None, "--test-fraction",
                                                      help="Put this fraction of each class's files in split 'test' "
                                                           "(default: all 'train')."),
        split_by: str = typer.Option("unit", "--split-by",
                                     help="unit: --test-fraction holds out whole files (no recording on both sides) "
                                          "| window: draws windows, so neighbouring windows of one recording land "
                                          "on both sides (optimistic; warns)."),
        seed: int = opt.seed("Seed of the --test-fraction split."),
        test_include: Optional[str] = typer.Option(None, "--test-include",
                                                   help="Put the windows of the files whose names match this regex "
                                                        "in split 'test' (e.g. one load: '_0\\.mat$')."),
        test_block: Optional[str] = typer.Option(None, "--test-block",
                                                 help="REGEX=K/N: cut each matching file in time into N blocks of "
                                                      "windows; block K goes to 'test', the others to 'train'."),
        scalar: List[str] = typer.Option([], "--scalar",
                                         help="NAME=REGEX: record the file's scalar matching REGEX as column NAME (e.g. rpm=RPM)."),
        angle_channel: Optional[str] = opt.angle_source("angle_channel", per_file=True),
        tacho_channel: Optional[str] = opt.angle_source("tacho_channel", per_file=True),
        ppr: Optional[int] = opt.angle_source("ppr"),
        estimate_speed: bool = typer.Option(False, "--estimate-speed",
                                            help="Without an angle channel, tachometer or speed group in "
                                                 "--meta-regex: take each file's stored angles (rvdiag simulate "
                                                 "records) or estimate its speed from the stage-1 mesh peak."),
        speed_range: Optional[str] = opt.angle_source("speed_range", per_file=True),
        params: Optional[Path] = opt.params("Reducer parameter TOML for the angle source (ratio, sun teeth; "
                                            "default: built-in RV-20E)."),
        out: Path = opt.out("Store to write (PATH.zarr)."),
        overwrite: bool = opt.overwrite("Replace an existing store."),
        force: bool = opt.deprecated("--force", flag=True),
        as_json: bool = opt.json_flag("Print the summary as one JSON object."),
        quiet: bool = opt.quiet(),
    ) -> None:
        """Window, label and store every matching file of FOLDER (kind "measured", written atomically).

        With --test-fraction, whole files go to the test split (--split-by unit, the default).  With an angle
        source (--angle-channel, --tacho-channel, a group rpm or speed_dps in --meta-regex, --estimate-speed) every
        window also records input_speed_rpm, output_speed_deg_s, input_rev_start and angle_source."""
        from rich.progress import Progress, TextColumn

        from rvdiag.cli._progress import bar_columns, stderr_console
        from rvdiag.datasets.from_files import build_from_files

        overwrite = opt.resolve(overwrite, force, "--force", default=False)
        scalars = _parse_scalars(scalar)
        angle = _angle_spec(angle_channel, tacho_channel, ppr, meta_regex, estimate_speed, speed_range, params)
        with Progress(TextColumn("[bold]reading[/bold]"), *bar_columns(), transient=True, console=stderr_console(),
                      disable=quiet) as bar:
            task = bar.add_task("", total=None)

            def progress(done: int, total: int, name: str) -> None:
                bar.update(task, completed=done, total=total, description=name)

            summary = build_from_files(
                folder, out, label_regex=label_regex, channel=channel, window_length=window, hop=hop, fs=fs,
                meta_regex=meta_regex, include=include, test_fraction=test_fraction, seed=seed, split_by=split_by,
                scalars=scalars, overwrite=overwrite, unknown_fs=unknown_fs, progress=progress,
                test_include=test_include,
                test_block=test_block, angle=angle, params=params,
            )
        if as_json:
            typer.echo(json.dumps(summary))
            return
        counts = ", ".join(f"{c}: {n}" for c, n in summary["counts"].items())
        fs_text = "not stated" if summary["fs"] is None else f"{summary['fs']:g} Hz"
        typer.echo(f"wrote {summary['path']}: {summary['n_samples']} windows of {summary['length']} "
                   f"from {summary['files']} file(s), fs {fs_text}")
        typer.echo(f"classes: {counts}")
        for name, what in summary["angle_sources"].items():
            typer.echo(f"  {name}: angle from {what}")
        if summary["skipped"]:
            typer.echo(f"skipped {len(summary['skipped'])} file(s) not matching --label-regex: "
                       + ", ".join(summary["skipped"][:5]) + (" ..." if len(summary["skipped"]) > 5 else ""))

    @ds_app.command("info")
    def info(
        path: Path = typer.Argument(..., help="Sample store (PATH.zarr)."),
        as_json: bool = opt.json_flag(),
    ) -> None:
        """Describe a sample store: kind, classes, counts per split, length, fs, metadata columns."""
        from rvdiag.datasets import SampleStore

        s = SampleStore.open(path).summary()
        if as_json:
            typer.echo(json.dumps(s, default=str))
            return
        fs_text = "not stated" if s["fs"] is None else f"{s['fs']:g} Hz"
        typer.echo(f"{s['path']}: {s['kind']} store, {s['n_samples']} samples of {s['length']} points, fs {fs_text}")
        for cls_name, per_split in s["counts"].items():
            typer.echo(f"  {cls_name}: " + ", ".join(f"{k} {v}" for k, v in per_split.items()))
        typer.echo("metadata: " + ", ".join(s["meta_columns"]))

    @ds_app.command("channels")
    def channels(path: Path = typer.Argument(..., help="A measured file.")) -> None:
        """List the channels of a measured file (the names --channel is matched against)."""
        from rvdiag.io import list_channels

        for name in list_channels(path):
            typer.echo(name)
