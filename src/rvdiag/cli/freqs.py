"""``rvdiag freqs``: characteristic and fault frequencies of the reducer at one speed."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from rvdiag.cli import _options as opt
from rvdiag.errors import ParameterError

DESCRIPTIONS = {
    "fe": "motor electrical frequency p*f1",
    "f1": "sun (input) rotation",
    "f2": "crank shaft rotation (absolute)",
    "f3": "carrier (output) rotation",
    "fsp": "stage-1 mesh (sun-planet)",
    "fcs": "stage-2 mesh (cycloid-pin)",
    "f_sun_fault": "local sun-tooth fault",
    "f_planet_fault": "local planet-tooth fault",
    "f_cycloid_fault": "local cycloid-lobe fault",
    "f_pin_fault": "local pin fault",
}


def register(app: typer.Typer) -> None:
    """Add the ``freqs`` command to ``app``."""

    @app.command("freqs")
    def freqs(
        input_speed: Optional[float] = typer.Option(None, "--input-speed", help="Motor (sun) speed, rpm."),
        output_speed: Optional[float] = typer.Option(None, "--output-speed", help="Output (carrier) speed, deg/s."),
        params: Optional[Path] = opt.params(),
        pole_pairs: Optional[int] = typer.Option(None, "--pole-pairs", help="Motor pole pairs (default: the parameter set's)."),
        as_json: bool = opt.json_flag(),
    ) -> None:
        """Characteristic frequencies (Hz): fe, f1, f2, f3, fsp, fcs and the fault frequencies."""
        from rvdiag.kinematics import characteristic_frequencies
        from rvdiag.params import ReducerParams

        if input_speed is not None and output_speed is not None:
            raise ParameterError("give either --input-speed or --output-speed, not both")
        if input_speed is None and output_speed is None:
            raise ParameterError("give --input-speed RPM or --output-speed DEG_S")
        p = ReducerParams.load(params)
        f = characteristic_frequencies(p, input_speed_rpm=input_speed, output_speed_deg_s=output_speed,
                                       pole_pairs=pole_pairs).as_dict()
        if as_json:
            typer.echo(json.dumps(f))
            return
        from rich.console import Console
        from rich.table import Table

        speed = f"input {input_speed:g} rpm" if input_speed is not None else f"output {output_speed:g} deg/s"
        table = Table(title=f"{p.name}, {speed}, ratio {p.ratio:g}")
        table.add_column("key")
        table.add_column("Hz", justify="right")
        table.add_column("meaning")
        for key, val in f.items():
            table.add_row(key, f"{val:.6g}", DESCRIPTIONS[key])
        Console(width=100).print(table)
