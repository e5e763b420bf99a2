"""``rvdiag orders FILE --shaft sun|crank|output``: order spectrum, envelope order spectrum, TSA and gear condition
indicators of one channel (:mod:`rvdiag.features.orders`; docs/orders.md).

The angle comes from the first of (:func:`rvdiag.io.angles.input_revolutions`): ``--angle-channel`` (the input
shaft's angle, rad, or an angle counter of ``--ppr`` counts per revolution), ``--tacho-channel`` with ``--ppr``
(pulses per input revolution), ``--rpm`` (the analysed shaft itself, rev/min), ``--input-speed`` (rpm),
``--output-speed`` (deg/s), ``--meta-regex`` (a group ``rpm`` or ``speed_dps`` in the file name), the input
angle ``theta_in`` a record of ``rvdiag simulate`` stores (its true angles, any speed profile), the speed such a
record states, and failing those the stage-1 mesh peak of the spectrum
(:func:`rvdiag.io.angles.estimate_shaft_speed`, output speeds 1-200 deg/s).  ``--json`` names the source under
``angle_source`` (:data:`rvdiag.io.angles.ANGLE_SOURCES`) and describes it under ``angle_detail``.  For a machine
of unknown rate or geometry, ``--cepstrum LO:HI`` takes the analysed shaft's period from the real cepstrum
(:func:`rvdiag.io.angles.estimate_period_cepstrum`) and ``--mesh-order`` replaces the reducer's mesh order.

Besides the nine indicators, the output has the modulation of the mesh (sideband asymmetry, phase demodulation;
``modulation``) and the windowed TSA of each stage-1 planet (McFadden 1994; ``planets``), from
:mod:`rvdiag.features.planetary`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import numpy as np
import typer

from rvdiag.cli import _options as opt
from rvdiag.errors import ParameterError
from rvdiag.validation import finite_number


def _angle(sig, shaft, p, *, output_speed, input_speed, rpm, tacho_channel, ppr, angle_channel, meta_regex,
           speed_range, fs, cepstrum=None):
    """(revolutions of ``shaft`` per sample, angle source key, how the angle was found)."""
    from rvdiag.features import orders as o
    from rvdiag.io.angles import (AngleSpec, angle_from_speed, estimate_period_cepstrum, input_revolutions,
                                  parse_period_range, parse_speed_range)

    ratio = o.shaft_ratio(shaft, p)  # analysed shaft per input revolution
    if cepstrum is not None:
        if any(v is not None for v in (output_speed, input_speed, rpm, tacho_channel, angle_channel, meta_regex,
                                       speed_range)):
            raise ParameterError("--cepstrum is an angle source of its own: give it alone (its period range is its "
                                 "plausibility check)")
        rng = parse_period_range(cepstrum)
        period, q0 = estimate_period_cepstrum(sig.data, rng)
        return (angle_from_speed(sig.data.size, sig.fs, sig.fs / period), "cepstrum",
                f"one revolution = {period:.6g} samples: the real cepstrum's highest peak between {rng[0]} and "
                f"{rng[1] or sig.data.size // 16} samples ({q0}), refined by harmonic summation")
    if rpm is not None:
        if any(v is not None for v in (output_speed, input_speed, tacho_channel, angle_channel, meta_regex)):
            raise ParameterError("give one angle source: --rpm or another")
        finite_number(rpm, "--rpm", 0, strict=True, noun="a number")
        input_speed = rpm / ratio
    spec = AngleSpec(angle_channel=angle_channel, tacho_channel=tacho_channel, ppr=ppr, input_speed_rpm=input_speed,
                     output_speed_deg_s=output_speed, meta_regex=meta_regex,
                     speed_range_rpm=parse_speed_range(speed_range))
    got = input_revolutions(sig, spec, p, fs)
    if rpm is not None:
        return got.revs * ratio, "shaft-rpm", f"{rpm:g} rev/min of the {shaft} shaft"
    return got.revs * ratio, got.source, got.detail


def _planetary(sig, input_revs, res, shaft, p, sensor_angle, planet_window, generic=False):
    """(modulation indicators and phase of the shaft's TSA, planet TSAs or None, why None) of ``rvdiag orders``;
    ``generic``: another machine (``--mesh-order``): sidebands at +- 1 order, no planets."""
    from rvdiag.features import planetary as pl

    spacing = 1 if generic else pl.sideband_spacing(shaft, p)
    mod = pl.modulation_indicators(res["tsa"], res["mesh_order"], spacing)
    mod.update(harmonic=1, sideband_spacing=spacing, phase=pl.phase_demodulation(res["tsa"], res["mesh_order"])[0])
    a, b = res["span"]
    if planet_window is not None and not 0 < planet_window <= 360:
        raise ParameterError(f"--planet-window must lie in (0, 360] deg, got {planet_window:g}")
    if generic:
        return mod, None, "--mesh-order: another machine than the reducer's planetary stage"
    try:
        planets = pl.planet_tsa(sig.data[a:b], sig.fs, input_revs[a:b], p, sensor_angle_deg=sensor_angle,
                                width_deg=planet_window)
    except ParameterError as exc:
        return mod, None, f"the record is too short for the planets' crank ({exc})"
    planets.update(sensor_angle_deg=float(sensor_angle),
                   window_deg=float(planet_window if planet_window is not None else 720.0 / planets["n_planets"]))
    missing = [q["planet"] for q in planets["planets"] if q["tsa"] is None]
    note = (f"planet(s) {', '.join(map(str, missing))} never reach one revolution of window weight: a longer record "
            "(the carrier must bring each planet past the sensor)") if missing else None
    return mod, planets, note


def _plot(res, path: Path, title: str, top: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(9, 8.5))
    marks = {k: v for k, v in res["fault_orders"].items() if k.startswith("f_") and v <= top}
    for ax, (o_, a_), what, lim in (
            (axes[0], (res["orders"], res["amplitude"]), "order spectrum", top),
            (axes[1], (res["envelope_orders"], res["envelope_amplitude"]), "envelope order spectrum",
             min(top, 4 * max(marks.values(), default=top / 4) + 1))):
        keep = o_ <= lim
        ax.plot(o_[keep], a_[keep], lw=0.7)
        for k, v in marks.items():
            if v <= lim:
                ax.axvline(v, color="r", ls="--", lw=0.6)
                ax.text(v, ax.get_ylim()[1] * 0.9, k, rotation=90, fontsize=7, color="r", va="top")
        ax.axvline(res["mesh_order"], color="g", ls=":", lw=0.8)
        ax.set_xlabel("order (cycles per revolution)")
        ax.set_title(what)
    t = res["tsa"]
    axes[2].plot(np.arange(t.size) * 360.0 / t.size, t, lw=0.7)
    axes[2].set_xlabel("shaft angle (deg)")
    axes[2].set_title(f"TSA over {res['n_revolutions']} revolutions")
    fig.suptitle(title)
    fig.tight_layout()
    opt.save_plot(fig, path, dpi=110)


def register(app: typer.Typer) -> None:
    """Add the ``orders`` command to ``app``."""

    @app.command("orders")
    def orders(
        file: Path = typer.Argument(..., help="Signal file: CSV/CSV.gz, MAT, NPY, NPZ, WAV, TDMS."),
        shaft: str = typer.Option("sun", "--shaft", help="sun (relative to the carrier: stage-1 mesh) | crank "
                                  "(relative to the carrier: stage-2 mesh) | output (the carrier)."),
        output_speed: Optional[float] = opt.output_speed(),
        input_speed: Optional[float] = typer.Option(None, "--input-speed", help="Motor (sun) speed, rpm."),
        rpm: Optional[float] = typer.Option(None, "--rpm", help="Speed of the analysed shaft itself, rev/min."),
        tacho_channel: Optional[str] = opt.angle_source("tacho_channel"),
        ppr: Optional[int] = opt.angle_source("ppr"),
        angle_channel: Optional[str] = opt.angle_source("angle_channel"),
        meta_regex: Optional[str] = typer.Option(None, "--meta-regex",
                                                 help="Regex on the file name with a group (?P<rpm>...) (input "
                                                      "rev/min) or (?P<speed_dps>...) (output deg/s)."),
        speed_range: Optional[str] = opt.angle_source("speed_range"),
        channel: str = opt.channel(),
        fs: float = opt.fs("Sampling rate in Hz (overrides the file's)."),
        params: Optional[Path] = opt.params(),
        samples_per_rev: Optional[int] = typer.Option(None, "--samples-per-rev",
                                                      help="Angular samples per revolution (default: automatic)."),
        cepstrum: Optional[str] = typer.Option(None, "--cepstrum",
                                               help="LO:HI (or LO:) samples: the analysed shaft's period is the "
                                                    "real cepstrum's highest peak in that range, refined by harmonic "
                                                    "summation (a machine of unknown rate or geometry; with --fs 1 "
                                                    "orders are cycles per sample)."),
        mesh_order: Optional[int] = typer.Option(None, "--mesh-order",
                                                 help="Mesh order of the analysed shaft for the indicators, instead "
                                                      "of the reducer's (another machine: no reducer fault orders, "
                                                      "no planets)."),
        sensor_angle: float = typer.Option(0.0, "--sensor-angle",
                                           help="The sensor's angle around the housing from planet 0's position at "
                                                "the record's first sample, deg (a simulated record: from the x "
                                                "axis), for the planet windows."),
        planet_window: Optional[float] = typer.Option(None, "--planet-window",
                                                      help="Width of each planet's Hann window in carrier angle, deg "
                                                           "(default 720 / planets: the windows sum to 1)."),
        plot: Optional[Path] = typer.Option(None, "--plot", help="Write a PNG: spectra with fault orders, TSA."),
        as_json: bool = opt.json_flag("Print shaft, orders, amplitude, indicators (and more) as JSON."),
    ) -> None:
        """Order spectrum, envelope order spectrum, TSA and gear condition indicators (FM0, FM4, NA4...)."""
        from rvdiag.features import orders as o
        from rvdiag.io import read_signal
        from rvdiag.params import ReducerParams

        o._check_shaft(shaft)
        if plot is not None and plot.suffix.lower() != ".png":
            raise ParameterError(f"--plot must name a .png file, got {plot}")
        p = ReducerParams.load(params)
        sig = read_signal(file, channel, fs)
        if sig.fs is None:
            raise ParameterError(f"{file} states no sampling rate: give --fs")
        revs, source_key, source = _angle(sig, shaft, p, output_speed=output_speed, input_speed=input_speed, rpm=rpm,
                                          tacho_channel=tacho_channel, ppr=ppr, angle_channel=angle_channel,
                                          meta_regex=meta_regex, speed_range=speed_range, fs=fs,
                                          cepstrum=cepstrum)
        res = o.analyse(sig.data, sig.fs, revs, shaft, p, samples_per_rev, mesh=mesh_order)
        mod, planets, planets_note = _planetary(sig, revs / o.shaft_ratio(shaft, p), res, shaft, p, sensor_angle,
                                                planet_window, generic=mesh_order is not None)
        top = min(4.5 * res["mesh_order"], res["samples_per_rev"] * 0.45)
        keep = res["orders"] <= top
        what = "the shaft" if mesh_order is not None else f"{shaft} shaft"
        title = f"{file.name} [{sig.channel}], {what} {res['shaft_hz']:.4g} Hz ({source})"
        if plot is not None:
            _plot(res, plot, title, top)
        if as_json:
            ekeep = res["envelope_orders"] <= top
            typer.echo(json.dumps({
                "shaft": shaft, "shaft_hz": res["shaft_hz"], "angle_source": source_key, "angle_detail": source,
                "span_s": [res["span"][0] / sig.fs, res["span"][1] / sig.fs],
                "samples_per_rev": res["samples_per_rev"], "n_revolutions": res["n_revolutions"],
                "mesh_order": res["mesh_order"], "fault_orders": res["fault_orders"],
                "orders": res["orders"][keep].tolist(), "amplitude": res["amplitude"][keep].tolist(),
                "envelope_orders": res["envelope_orders"][ekeep].tolist(),
                "envelope_amplitude": res["envelope_amplitude"][ekeep].tolist(),
                "tsa": res["tsa"].tolist(), "indicators": res["indicators"],
                "modulation": {**mod, "phase": mod["phase"].tolist()},
                "planets": None if planets is None else {**planets, "planets": [
                    {**q, "tsa": None if q["tsa"] is None else q["tsa"].tolist()} for q in planets["planets"]]},
                "planets_note": planets_note}))
            return
        from rich.console import Console
        from rich.table import Table

        from rvdiag.features.orders import INDICATORS
        from rvdiag.features.planetary import MODULATION_INDICATORS

        con = Console(width=110)
        con.print(title)
        if res["span"] != (0, sig.data.size):
            con.print(f"analysed {res['span'][0] / sig.fs:.4g}-{res['span'][1] / sig.fs:.4g} s, where the shaft "
                      "turns at half its peak speed or more")
        con.print(f"{res['n_revolutions']} revolutions x {res['samples_per_rev']} samples; mesh order "
                  f"{res['mesh_order']}")
        fo = Table(title="fault orders")
        fo.add_column("key")
        fo.add_column("order", justify="right")
        fo.add_column("envelope amplitude", justify="right")
        for k, v in res["fault_orders"].items():
            fo.add_row(k, f"{v:.4g}", f"{np.interp(v, res['envelope_orders'], res['envelope_amplitude']):.3g}")
        if res["fault_orders"]:
            con.print(fo)
        table = Table(title="condition indicators")
        table.add_column("indicator")
        table.add_column("value", justify="right")
        table.add_column("signal")
        for k, v in res["indicators"].items():
            table.add_row(k, f"{v:.4g}", INDICATORS[k])
        for k, v in mod.items():
            if k in MODULATION_INDICATORS:
                table.add_row(k, f"{v:.4g}", MODULATION_INDICATORS[k] + f" (harmonic {mod['harmonic']}, +- "
                              f"{mod['sideband_spacing']} orders)")
        con.print(table)
        if planets is None:
            con.print(f"no planet TSA: {planets_note}")
        else:
            pt = Table(title=f"planet TSA (McFadden 1994 windows; stage-1 mesh order {planets['mesh_order']} of the "
                             f"crank, {planets['n_revolutions']} crank revolutions)")
            shown = ("fm0", "fm4", "na4", "nb4", "m6a", "energy_ratio")  # all of them in --json
            for col in ("planet", "passes", "weight (rev)", *shown):
                pt.add_column(col, justify="right", no_wrap=True)
            for q in planets["planets"]:
                vals = ["-"] * len(shown) if q["indicators"] is None else \
                    [f"{q['indicators'][k]:.4g}" for k in shown]
                pt.add_row(f"planet {q['planet']}", str(q["passes"]), f"{q['weight_revs']:.3g}", *vals)
            con.print(pt)
        if plot is not None:
            con.print(f"wrote {plot}")
