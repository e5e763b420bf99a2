"""``rvdiag library build`` and ``rvdiag library info``: build a fault-sample library, describe a store."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from rvdiag.cli import _options as opt
from rvdiag.errors import StoreError


def _unfinished_message(path: Path) -> str | None:
    """'k of n simulations committed' for an unfinished build, else None."""
    try:
        import zarr

        attrs = dict(zarr.open_group(str(path), mode="r").attrs)
    except Exception:
        return None
    if attrs.get("format") is None or attrs.get("complete", True) or "unit_rows" not in attrs:
        return None
    done = len(list((path / "_units").glob("*.json")))
    return (f"{path} is an unfinished build ({done} of {len(attrs['unit_rows'])} simulations committed): "
            f"re-run the same 'rvdiag library build' command to finish it")


def _remove_store(path: Path) -> None:
    """Remove the sample store at ``path`` for ``--overwrite``; anything there that is not a sample store is refused
    (a mistyped --out must not delete a folder of other files)."""
    import shutil

    from rvdiag.datasets.store import STORE_FORMAT

    if not path.exists():
        return
    try:
        import zarr

        fmt = dict(zarr.open_group(str(path), mode="r").attrs).get("format")
    except Exception:
        fmt = None
    if fmt != STORE_FORMAT:
        raise StoreError(f"{path} exists and is not a sample store; --overwrite replaces only a store: choose "
                         "another --out")
    shutil.rmtree(path)


def register(app: typer.Typer) -> None:
    lib = typer.Typer(
        help="Simulated fault-sample libraries: build one from a config, describe a store.",
        no_args_is_help=True,
    )

    @lib.command("build")
    def build(
        config: Path = typer.Argument(..., help="Library config (TOML), e.g. configs/demo.toml."),
        out: Path = opt.out("Store to write (PATH.zarr); an unfinished one of the same config resumes."),
        overwrite: bool = opt.overwrite("Start afresh: remove an existing store at --out (finished, unfinished or of "
                                        "another config) before building."),
        workers: Optional[int] = typer.Option(
            None, "--workers", "-w",
            help="Worker processes of the local Dask cluster (default: one per core; 0 = no Dask, in this process).",
        ),
        scheduler: Optional[str] = typer.Option(
            None, "--scheduler", help="Address of an existing Dask scheduler (tcp://host:8786) to run on instead.",
        ),
        device: str = typer.Option(
            "cpu", "--device",
            help="cpu | cuda | auto. cuda: ensembles of --ensemble simulations, one GPU thread each (needs an NVIDIA "
                 "GPU and numba-cuda; without them: the CPU, with a warning); auto: cuda when this machine has one. "
                 "docs/library.md, 'On a GPU'.",
        ),
        ensemble: int = typer.Option(
            1024, "--ensemble", help="--device cuda: simulations per GPU launch (and per Dask task).",
        ),
        quiet: bool = opt.quiet(),
        params: Optional[Path] = opt.params(
            "Reducer parameter file (TOML) to build from instead of the config's `params` (e.g. what "
            "`rvdiag update` wrote); recorded in the store."),
        seed: Optional[int] = typer.Option(
            None, "--seed",
            help="Seed instead of the config's: the same library drawn anew, e.g. a held-out test store of "
                 "unseen simulations; recorded in the store."),
    ) -> None:
        """Build (or resume) the library of CONFIG into --out, in parallel on Dask.

        Deterministic: the same config gives bit-identical arrays whatever the workers.

        Resumable: re-running the same command after a crash or Ctrl-C skips committed simulations.

        A store built from another config is refused; --overwrite replaces it (or any store at --out) afresh.  Fields of CONFIG: docs/library.md.
        """
        from rvdiag.library.build import build_library, check_run_options
        from rvdiag.library.config import LibraryConfig

        check_run_options(workers, scheduler, device, ensemble)
        cfg = LibraryConfig.load(config)
        if params is not None:
            from rvdiag.params import ReducerParams

            ReducerParams.load(params)  # a bad file fails here, before anything is written
            cfg = cfg.replace(params=str(Path(params).resolve()))
        if seed is not None:
            cfg = cfg.replace(seed=seed)  # validated there: a negative seed is one ConfigError line
        if overwrite:
            _remove_store(out)
        if not quiet:
            typer.echo(cfg.describe(), err=True)
        try:
            report = build_library(cfg, out, workers=workers, scheduler=scheduler, progress=not quiet, device=device,
                                   ensemble=ensemble)
        except KeyboardInterrupt:
            msg = _unfinished_message(out)
            typer.echo(f"interrupted: {msg}" if msg else "interrupted", err=True)
            raise typer.Exit(130) from None
        if report.built == 0:
            typer.echo(f"{out}: already complete ({report.n_units} simulations, {report.n_samples} samples)")
        else:
            resumed = f", {report.skipped} were already committed" if report.skipped else ""
            where = " on the GPU" if report.device == "cuda" else ""
            typer.echo(
                f"{out}: {report.n_samples} samples from {report.n_units} simulations "
                f"({report.built} built{where} in {report.wall_s:.1f} s, {report.samples_per_s:.1f} samples/s{resumed})"
            )

    @lib.command("info")
    def info(
        path: Path = typer.Argument(..., help="A sample store (PATH.zarr)."),
        as_json: bool = opt.json_flag("Print the summary as JSON."),
    ) -> None:
        """Counts per state and split, sample length, fs and the config of a sample store."""
        from rvdiag.datasets import SampleStore

        try:
            store = SampleStore.open(path)
        except StoreError:
            msg = _unfinished_message(path)
            if msg:
                raise StoreError(msg) from None
            raise
        summary = store.summary()
        library = store.attrs.get("library") or {}
        summary["library"] = library
        if store.attrs.get("kind") == "simulated":
            from rvdiag.library.specimens import count_specimens

            summary["specimens"] = count_specimens(store.meta)
            from rvdiag.library.life import summarize

            life = summarize(store.meta)
            if life is not None:
                summary["life"] = life
        if as_json:
            typer.echo(json.dumps(summary, indent=2, sort_keys=True, default=str))
            return
        _print_summary(summary)

    app.add_typer(lib, name="library")


def _print_summary(summary: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console(soft_wrap=True)
    fs = summary["fs"]
    lib = summary.get("library") or {}
    cfg = summary.get("config") or {}
    head = (f"[bold]{summary['path']}[/bold]  {summary['kind']}, {summary['n_samples']} samples of "
            f"{summary['length']} points" + (f" at {fs:g} Hz ({summary['length'] / fs * 1e3:.1f} ms)" if fs else ""))
    console.print(head)
    if lib:
        specimens = summary.get("specimens")
        drawn = " (drawn: \\[randomise] specimen)" if specimens and specimens > 1 else " (the parameter file's)"
        console.print(f"mode {lib.get('mode')}, seed {lib.get('seed')}, {lib.get('n_simulations')} simulations, "
                      f"simulator {lib.get('simulator')}"
                      + (f", {specimens} specimen{'s' if specimens != 1 else ''}{drawn}" if specimens else ""))
    life = summary.get("life")
    if life:
        h = cfg.get("history") or {}
        console.print(f"life histories: {life['reducers']} reducers, {life['records_per_reducer']} records each "
                      f"(commissioning first, then one every {h.get('interval_days', '?')} days to day "
                      f"{life['last_day']:g}); fates: " + ", ".join(f"{f} {n}" for f, n in life["fates"].items())
                      + "; failed by the last record: "
                      + (", ".join(f"{f} {n}" for f, n in life["failed_by_last_record"].items()) or "none")
                      + "; sensor faults: "
                      + (", ".join(f"{k} {n}" for k, n in life["sensor_faults"].items()) or "none"))
    splits = summary["splits"]
    table = Table("state", "description", *splits, "total")
    descriptions = lib.get("states", {})
    for cls_name in summary["classes"]:
        counts = summary["counts"].get(cls_name, {})
        table.add_row(cls_name, descriptions.get(cls_name, ""), *[str(counts.get(s, 0)) for s in splits],
                      str(sum(counts.values())))
    console.print(table)
    if cfg:
        op = cfg.get("operation", {})
        console.print("operation: " + ", ".join(f"{k} = {v}" for k, v in op.items()))
        if "randomise" in cfg:
            r = cfg["randomise"]
            console.print(f"randomise: stiffness +-{r.get('stiffness_pct')} %, damping +-{r.get('damping_pct')} %"
                          + (f", iso1328_grade {r['iso1328_grade']}" if "iso1328_grade" in r else ""))
    console.print(f"config hash {summary['config_hash']}, rvdiag {summary['rvdiag_version']}; "
                  f"metadata: {', '.join(summary['meta_columns'])}")
