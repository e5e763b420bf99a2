"""Option parsing shared by several commands (a ``_`` module: not a command itself)."""

from __future__ import annotations

import math
from typing import Optional

from rvdiag.errors import ParameterError


def mm_to_m(name: str, value: Optional[float]) -> Optional[float]:
    """Convert a ``--name`` option given in millimetres to metres (``None`` stays ``None``)."""
    if value is None:
        return None
    if not math.isfinite(value):
        raise ParameterError(f"--{name} must be finite, got {value}")
    return value * 1e-3


def fault_severities(
    wear_depth_mm: Optional[float],
    crack_depth_mm: Optional[float],
    crack_angle_deg: Optional[float],
    broken_fraction: Optional[float],
) -> dict[str, float]:
    """The fault-severity options that were given, in SI, keyed as :class:`rvdiag.gears.ToothFaults` expects."""
    values = (
        ("wear_depth", mm_to_m("wear-depth", wear_depth_mm)),
        ("crack_depth", mm_to_m("crack-depth", crack_depth_mm)),
        ("crack_angle_deg", crack_angle_deg),
        ("broken_fraction", broken_fraction),
    )
    return {key: value for key, value in values if value is not None}
