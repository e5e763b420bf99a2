"""The shared option vocabulary of the ``rvdiag`` command (a ``_`` module: not a command itself).

One name per concept, and every command that has the concept uses it (``tests/test_cli_options.py``
checks the app):

===============  =====================================================================================
``-o, --out``    the file or folder a command writes
``-q, --quiet``  no progress bar (progress bars, with their ETA, go to stderr)
``--overwrite``  replace an existing output
``--snr-db``     signal-to-noise ratio of added white Gaussian noise, dB (per sample)
``--seed``       random seed
``--params``     reducer parameter file (TOML); default: the built-in RV-20E
``--json``       print the result as JSON on stdout
``--fs``         sampling rate, Hz
``-c, --channel``  regular expression picking one channel of a file
===============  =====================================================================================

Old spellings (:data:`DEPRECATED`) stay accepted as hidden options that print one ``warning:`` line
(:class:`DeprecatedOptionWarning`) and do what the new name does, so scripts keep working.

The ``--model`` names of ``rvdiag train`` come from :mod:`rvdiag.registry` (the lists the estimators themselves
check), never from a copy here.  :func:`option_names` turns the Python parameter names that a library error
names (``duration_s``) into the options the user typed (``--duration``).
"""

from __future__ import annotations

import functools
import inspect
import math
import re
import warnings
from contextlib import contextmanager
from typing import Any, Callable, Iterator, NamedTuple, Optional

import typer

from rvdiag.errors import ParameterError, RvdiagError, RvdiagWarning
from rvdiag.validation import number

#: Concept -> the option strings every command uses for it (long name first).
VOCABULARY: dict[str, tuple[str, ...]] = {
    "out": ("--out", "-o"),
    "quiet": ("--quiet", "-q"),
    "overwrite": ("--overwrite",),
    "snr_db": ("--snr-db",),
    "seed": ("--seed",),
    "params": ("--params",),
    "json": ("--json",),
    "fs": ("--fs",),
    "channel": ("--channel", "-c"),
}

#: Old spelling -> the shared name that replaces it (accepted, hidden, warns).
DEPRECATED: dict[str, str] = {
    "--noise-snr": "--snr-db",
    "--force": "--overwrite",
}


class DeprecatedOptionWarning(RvdiagWarning):
    """An old option spelling was used; it still works, under its new name."""


def out(help: str, default: Any = ...) -> Any:
    """``-o/--out``: what the command writes (required unless ``default`` is given)."""
    return typer.Option(default, *VOCABULARY["out"], help=help)


def quiet() -> Any:
    """``-q/--quiet``: no progress bar."""
    return typer.Option(False, *VOCABULARY["quiet"], help="No progress bar (progress goes to stderr).")


def overwrite(help: str = "Replace an existing output.") -> Any:
    """``--overwrite``."""
    return typer.Option(False, *VOCABULARY["overwrite"], help=help)


def refuse_existing(path: Any, overwrite: bool) -> None:
    """The one rule for outputs: an existing ``--out`` is replaced only with ``--overwrite``
    (:class:`ParameterError`, one line naming the file and the option)."""
    from pathlib import Path

    if not overwrite and Path(path).exists():
        raise ParameterError(f"{path} exists; use --overwrite to replace it")


def snr_db(help: str, default: Any = None) -> Any:
    """``--snr-db``: SNR of added white Gaussian noise, dB."""
    return typer.Option(default, *VOCABULARY["snr_db"], help=help)


def parse_levels(text: str, option: str = "--snr-db") -> list[float]:
    """``"-5,0,5"`` -> [-5.0, 0.0, 5.0] (a list of SNRs in dB); one clear :class:`ParameterError` for anything else."""
    try:
        levels = [float(x) for x in str(text).split(",") if x.strip()]
    except ValueError:
        raise ParameterError(f"{option} must be comma-separated numbers in dB, got {text!r}") from None
    if not levels or not all(math.isfinite(v) for v in levels):
        raise ParameterError(f"{option} must be comma-separated finite numbers in dB, got {text!r}")
    return levels


def seed(help: str) -> Any:
    """``--seed``."""
    return typer.Option(0, *VOCABULARY["seed"], help=help)


def params(help: str = "Reducer parameter TOML (default: built-in RV-20E).") -> Any:
    """``--params``."""
    return typer.Option(None, *VOCABULARY["params"], help=help)


def json_flag(help: str = "Print one JSON object.") -> Any:
    """``--json``."""
    return typer.Option(False, *VOCABULARY["json"], help=help)


def fs(help: str, default: Any = None) -> Any:
    """``--fs``."""
    return typer.Option(default, *VOCABULARY["fs"], help=help)


def output_speed(help: str = "Output (carrier) speed, deg/s.") -> Any:
    """``--output-speed``: the reducer's output speed in deg/s (``orders``, ``diagnose``)."""
    return typer.Option(None, "--output-speed", help=help)


def load(help: str = "Output load torque, N m: checked against the model's training range.") -> Any:
    """``--load``: the output load torque in N m."""
    return typer.Option(None, "--load", help=help)


def channel(help: str = "Regular expression picking one channel (may be left out when the file holds one).") -> Any:
    """``-c/--channel``."""
    return typer.Option(None, *VOCABULARY["channel"], help=help)


#: The angle-source options that ``orders`` and ``dataset from-files`` share (:mod:`rvdiag.io.angles`).
ANGLE_OPTIONS: dict[str, tuple[str, str]] = {
    "angle_channel": ("--angle-channel", "Regex of {whose} input-shaft angle channel (rad, or counts with --ppr){why}."),
    "tacho_channel": ("--tacho-channel", "Regex of {whose} tachometer pulse channel on the input shaft (--ppr pulses "
                                         "per revolution, default 1){why}."),
    "ppr": ("--ppr", "Tachometer pulses per input revolution (default 1); with --angle-channel, the counts per "
                     "revolution of an angle counter."),
    "speed_range": ("--speed-range", "MIN:MAX plausible input speed, rev/min (default 1:10000); {whose_angle} outside "
                                     "it is an error."),
}


def angle_source(key: str, per_file: bool = False) -> Any:
    """One option of :data:`ANGLE_OPTIONS`, its help worded for one record (``orders``) or for each file of a
    folder (``per_file``: ``dataset from-files``, which records each window's speed from it)."""
    name, help = ANGLE_OPTIONS[key]
    help = help.format(whose="each file's" if per_file else "the record's", whose_angle="a file" if per_file else "an angle",
                       why=": record each window's speed" if per_file else "")
    return typer.Option(None, name, help=help)


def deprecated(old: str, *, flag: bool = False) -> Any:
    """A hidden option under the old spelling ``old`` of :data:`DEPRECATED`; pass its value to :func:`resolve`."""
    return typer.Option(False if flag else None, old, hidden=True, help=f"Deprecated: use {DEPRECATED[old]}.")


def renamed(option: str, value: str, old_names: dict[str, str]) -> str:
    """``value`` of ``option``, or the name now of an old spelling in ``old_names`` (with one ``warning:`` line)."""
    if value not in old_names:
        return value
    new = old_names[value]
    with warnings.catch_warnings():
        warnings.simplefilter("always", DeprecatedOptionWarning)
        warnings.warn(f"{option} {value} is the old name of {new}; use {option} {new}", DeprecatedOptionWarning,
                      stacklevel=2)
    return new


def resolve(new_value: Any, old_value: Any, old: str, default: Any = None) -> Any:
    """The value of an option given under its new name or its old spelling ``old`` (which warns once).

    ``default`` is the new option's default: giving both spellings with different values is an error.
    """
    if old_value is None or old_value is False:
        return new_value
    new = DEPRECATED[old]
    with warnings.catch_warnings():
        warnings.simplefilter("always", DeprecatedOptionWarning)  # every run says it, not only the first
        warnings.warn(f"{old} is deprecated; use {new}", DeprecatedOptionWarning, stacklevel=2)
    if new_value != default and new_value != old_value:
        raise ParameterError(f"give {new} or its old spelling {old}, not both")
    return old_value


@contextmanager
def option_names(names: dict[str, str]) -> Iterator[None]:
    """Re-raise an rvdiag error whose message names a Python parameter (a key of ``names``, e.g.
    ``duration_s``) with the command-line option instead (``--duration``); the error class stays."""
    try:
        yield
    except RvdiagError as exc:
        text = str(exc)
        pattern = re.compile(r"(?<![\w-])(" + "|".join(map(re.escape, names)) + r")(?![\w-])")
        new = pattern.sub(lambda m: names[m.group(1)], text)
        new = re.sub(r"(--[\w-]+) \(\1\)", r"\1", new)  # "--x (--x)", where the message named both
        if new == text:
            raise
        raise type(exc)(new) from None


class SeverityOption(NamedTuple):
    """One fault-severity option: its name, its help, the fault kind that uses it (a part of
    :data:`rvdiag.gears.faults.FAULT_KINDS`' names) and whether it is given in mm (the model takes m)."""

    option: str
    help: str
    kind: str
    in_mm: bool


#: The fault-severity options that ``rvdiag simulate``, ``rvdiag tvms`` and ``rvdiag separability`` share, declared
#: once, by their :class:`rvdiag.gears.ToothFaults` keyword (SI).  :func:`fault_severity_options` puts them on a
#: command, :func:`fault_severities` reads them.
FAULT_SEVERITY_OPTIONS: dict[str, SeverityOption] = {k: SeverityOption(*v) for k, v in {
    "wear_depth": ("--wear-depth", "Maximum wear depth (mm).", "wear", True),
    "crack_depth": ("--crack-depth", "Crack depth (mm).", "crack", True),
    "crack_angle_deg": ("--crack-angle", "Crack angle from the tooth centreline (deg).", "crack", False),
    "broken_fraction": ("--broken-fraction", "Lost fraction of the tooth height, (0, 1].", "broken", False),
    "pit_area_fraction": ("--pit-area-fraction", "Pitted fraction of the pitting band, [0, 0.785) (pitting).",
                          "pitting", False),
    "pit_radius": ("--pit-radius", "Pit radius (mm) (pitting).", "pitting", True),
    "pit_depth": ("--pit-depth", "Pit depth (mm) (pitting).", "pitting", True),
    "spall_width_fraction": ("--spall-width-fraction", "Spall width as a fraction of the face width, [0, 1) "
                             "(spalling).", "spalling", False),
    "spall_length_fraction": ("--spall-length-fraction", "Spall length as a fraction of the working flank, (0, 1] "
                              "(spalling).", "spalling", False),
    "spall_depth": ("--spall-depth", "Spall depth (mm) (spalling).", "spalling", True),
}.items()}


def mm_to_m(name: str, value: Optional[float]) -> Optional[float]:
    """Convert a ``--name`` option given in millimetres to metres (``None`` stays ``None``)."""
    return None if value is None else number(value, f"--{name}") * 1e-3


def fault_severities(**given: Optional[float]) -> dict[str, float]:
    """The fault-severity options that were given (``given``: :data:`FAULT_SEVERITY_OPTIONS` key -> the option's
    value or None), in SI, keyed as :class:`rvdiag.gears.ToothFaults` expects."""
    out = {}
    for key, value in given.items():
        spec = FAULT_SEVERITY_OPTIONS[key]
        if value is not None:
            out[key] = mm_to_m(spec.option[2:], value) if spec.in_mm else value
    return out


def fault_severity_options(command: Callable[..., Any]) -> Callable[..., Any]:
    """Decorator of a command function: its parameter ``severities`` becomes the ten options of
    :data:`FAULT_SEVERITY_OPTIONS`, in its place among the command's options (so ``--help`` lists them there), and
    the command is called with ``severities`` = :func:`fault_severities` of them (the given ones, in SI)."""
    signature = inspect.signature(command, eval_str=True)
    options = [inspect.Parameter(key, inspect.Parameter.KEYWORD_ONLY, annotation=Optional[float],
                                 default=typer.Option(None, spec.option, help=spec.help))
               for key, spec in FAULT_SEVERITY_OPTIONS.items()]
    parameters = []
    for p in signature.parameters.values():
        parameters.extend(options if p.name == "severities" else [p.replace(kind=inspect.Parameter.KEYWORD_ONLY)])
    if len(parameters) != len(signature.parameters) + len(options) - 1:
        raise TypeError(f"{command.__name__} has no parameter 'severities' for the fault-severity options")

    @functools.wraps(command)
    def with_severities(**kwargs: Any) -> Any:
        given = {key: kwargs.pop(key) for key in FAULT_SEVERITY_OPTIONS}
        return command(**kwargs, severities=fault_severities(**given))

    with_severities.__signature__ = signature.replace(parameters=parameters)  # type: ignore[attr-defined]
    return with_severities


def save_plot(fig: Any, path: Any, dpi: int = 120) -> None:
    """Write a matplotlib figure for a ``--plot PATH`` option and close it; an unwritable path is one
    :class:`ParameterError` line."""
    import matplotlib.pyplot as plt

    try:
        fig.savefig(path, dpi=dpi)
    except OSError as exc:
        raise ParameterError(f"cannot write --plot {path}: {exc}") from None
    finally:
        plt.close(fig)
