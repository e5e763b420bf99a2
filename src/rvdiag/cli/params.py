"""``rvdiag params``: show, check and export reducer parameter sets."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from rvdiag.cli import _options as opt
from rvdiag.errors import ConfigError, ParameterError
from rvdiag.params import ReducerParams, body_properties


def register(app: typer.Typer) -> None:
    params_app = typer.Typer(help="Show, check and export reducer parameter sets (TOML).", no_args_is_help=True)
    app.add_typer(params_app, name="params")

    @params_app.command("show")
    def show(
        params: Optional[Path] = opt.params("Parameter file (default: built-in RV-20E)."),
        as_json: bool = opt.json_flag(),
    ) -> None:
        """Print a parameter set with its derived ratio, masses and inertias."""
        p = ReducerParams.load(params)
        bodies = body_properties(p)
        derived = {
            "ratio": p.ratio,
            "centre_distance_m": p.stage1.centre_distance,
            "short_amplitude_coefficient": p.stage2.short_amplitude_coefficient,
            "masses_kg": {k: getattr(bodies, k).mass for k in bodies.__dataclass_fields__},
            "inertias_kg_m2": {k: getattr(bodies, k).inertia for k in bodies.__dataclass_fields__},
        }
        if as_json:
            typer.echo(json.dumps({"params": p.to_dict(), "derived": derived, "source": p.source}))
            return
        typer.echo(f"# {p.name}  (from {p.source})")
        typer.echo(p.to_toml())
        typer.echo("# derived")
        for key, value in derived.items():
            typer.echo(f"# {key} = {value}")

    @params_app.command("check")
    def check(path: Path = typer.Argument(..., help="Parameter file to validate.")) -> None:
        """Validate a parameter file; exit 0 and print 'ok' when it is valid."""
        p = ReducerParams.load(path)
        typer.echo(f"ok: {p.name}, ratio {p.ratio:g}")

    @params_app.command("export")
    def export(
        target: Optional[Path] = typer.Argument(None, metavar="OUT", help="Where to write the TOML file (or -o)."),
        out_opt: Optional[Path] = opt.out("Where to write the TOML file (the same as the OUT argument).", None),
        params: Optional[Path] = opt.params("Source parameter file (default: built-in)."),
        overwrite: bool = opt.overwrite("Overwrite an existing file."),
        force: bool = opt.deprecated("--force", flag=True),
    ) -> None:
        """Write a parameter set (the built-in RV-20E by default) to a file you can edit."""
        overwrite = opt.resolve(overwrite, force, "--force", default=False)
        if (target is None) == (out_opt is None):
            raise ParameterError("give the file to write once: rvdiag params export OUT, or -o/--out OUT")
        out = target if target is not None else out_opt
        if out.exists() and not overwrite:
            raise ConfigError(f"{out} exists; use --overwrite to replace it")
        p = ReducerParams.load(params)
        if params is None:
            from importlib import resources

            text = resources.files("rvdiag.params").joinpath("rv20e.toml").read_text("utf-8")
            out.write_text(text, encoding="utf-8")  # keep the source comments
        else:
            p.save(out)
        typer.echo(f"wrote {out}")
