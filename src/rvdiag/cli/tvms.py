"""``rvdiag tvms``: time-varying mesh stiffness of a gear pair, healthy or faulty."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from rvdiag.cli import _options as opt
from rvdiag.cli._options import mm_to_m
from rvdiag.errors import ParameterError

FAULTS = ("healthy", "wear", "crack", "broken", "broken+wear", "broken+wear+crack", "pitting", "spalling")


def register(app: typer.Typer) -> None:
    """Add the ``tvms`` command to ``app``."""

    @app.command("tvms")
    @opt.fault_severity_options
    def tvms(
        params: Optional[Path] = opt.params(),
        pair: str = typer.Option("sun-planet", "--pair", help="Gear pair of the parameter set: sun-planet."),
        z1: Optional[int] = typer.Option(None, "--z1", help="Driver teeth (custom pair; needs --z2 and --module)."),
        z2: Optional[int] = typer.Option(None, "--z2", help="Driven teeth (custom pair)."),
        module_mm: Optional[float] = typer.Option(None, "--module", help="Module (mm) of a custom pair."),
        pressure_angle: float = typer.Option(20.0, "--pressure-angle", help="Pressure angle (deg) of a custom pair."),
        face_width_mm: float = typer.Option(10.0, "--face-width", help="Face width (mm) of a custom pair."),
        youngs_modulus: float = typer.Option(2.06e11, "--youngs-modulus", help="Young's modulus (Pa) of a custom pair."),
        poisson: float = typer.Option(0.3, "--poisson", help="Poisson ratio of a custom pair."),
        x1: float = typer.Option(0.0, "--x1", help="Profile shift coefficient of the driver (custom pair)."),
        x2: float = typer.Option(0.0, "--x2", help="Profile shift coefficient of the driven gear (custom pair)."),
        fault: str = typer.Option("healthy", "--fault", help=f"{'|'.join(FAULTS)} (or T1..T8)."),
        severities: Optional[dict] = None,  # the ten fault-severity options (opt.fault_severity_options)
        cycles: int = typer.Option(0, "--cycles", help="Mesh cycles (default: Z1, one driver revolution)."),
        points: int = typer.Option(360, "--points", help="Points per mesh cycle."),
        as_json: bool = opt.json_flag("Print one JSON object instead of a summary."),
        plot: Optional[Path] = typer.Option(None, "--plot", help="Write a PNG figure of the stiffness."),
    ) -> None:
        """Time-varying mesh stiffness (potential-energy method) of a spur gear pair."""
        from rvdiag.gears import GearPair, ToothFaults, mesh_stiffness
        from rvdiag.params import ReducerParams

        custom = [v is not None for v in (z1, z2, module_mm)]
        if any(custom):
            if not all(custom):
                raise ParameterError("a custom pair needs all of --z1, --z2 and --module")
            if params is not None:
                raise ParameterError("give either --params or a custom pair (--z1/--z2/--module), not both")
            gp = GearPair.from_dimensions(
                z1, z2, mm_to_m("module", module_mm), mm_to_m("face-width", face_width_mm),
                pressure_angle_deg=pressure_angle, youngs_modulus=youngs_modulus,
                poisson_ratio=poisson, x1=x1, x2=x2)
        else:
            if pair != "sun-planet":
                raise ParameterError(f"unknown --pair {pair!r}; the only involute pair is sun-planet")
            gp = GearPair.sun_planet(ReducerParams.load(params))
        faults = ToothFaults.from_name(fault, **severities)
        if cycles == 0:
            cycles = gp.driver.teeth
        if cycles < 1:
            raise ParameterError(f"--cycles must be >= 1, got {cycles}")
        if points < 4:
            raise ParameterError(f"--points must be >= 4, got {points}")
        if cycles * points > 5_000_000:
            raise ParameterError("--cycles x --points exceeds 5,000,000 samples")
        res = mesh_stiffness(gp, None if faults.is_healthy else faults, cycles=cycles,
                             points_per_cycle=points)
        if plot is not None:
            import matplotlib

            matplotlib.use("Agg")
            import matplotlib.pyplot as plt

            fig, ax = plt.subplots(figsize=(9, 3.8))
            res.plot(ax=ax, label=fault)
            ax.set_title(f"{gp.name}: Z1 = {gp.driver.teeth}, Z2 = {gp.driven.teeth}, "
                         f"eps = {gp.contact_ratio:.3f}")
            ax.legend()
            fig.tight_layout()
            opt.save_plot(fig, plot)
        if as_json:
            out = res.to_dict()
            typer.echo(json.dumps(out))
        else:
            typer.echo(f"pair            {gp.name} (Z1 = {gp.driver.teeth}, Z2 = {gp.driven.teeth})")
            typer.echo(f"fault           {fault}")
            typer.echo(f"contact ratio   {res.contact_ratio:.4f}")
            typer.echo(f"mean stiffness  {res.mean_N_per_m:.4e} N/m")
            typer.echo(f"min / max       {res.min_N_per_m:.4e} / {res.max_N_per_m:.4e} N/m")
            typer.echo(f"samples         {len(res.angle_rad)} ({cycles} cycles x {points})")
