"""The parameters that model updating tunes, their bounds, and the map between them and the unit cube.

Only values that are assumed, not derived from geometry or catalogue figures, are tuned (see ``rv20e.toml``):
the support and joint stiffnesses whose order of magnitude is all that is known, the damping ratios taken as
common choices, and the mounting (housing mass and sensor path) that differs from one test rig to the next.
The mesh stiffness is computed from the tooth geometry (potential-energy TVMS) and is not tuned.

The optimiser works on the unit cube: ``u = 0`` is the lower bound, ``u = 1`` the upper one, linear or
logarithmic in between.  Bounds are widened, where needed, to hold the base value, so the base parameter set is
always a point of the search space.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rvdiag.errors import ParameterError
from rvdiag.params import ReducerParams


@dataclass(frozen=True)
class Tunable:
    """One tuned parameter.

    ``lower``/``upper`` are factors of the base value when ``relative`` is true, absolute values otherwise.
    ``path`` marks a parameter of the sensor path, a linear filter applied after the integration
    (:mod:`rvdiag.dynamics.transfer`): it is fitted without a new simulation.
    """

    name: str
    section: str
    key: str
    lower: float
    upper: float
    relative: bool
    scale: str  # "log" or "linear"
    why: str
    path: bool = False


#: name, [section] key, bounds, scale and reason of every tunable parameter
TUNABLES: tuple[Tunable, ...] = (
    Tunable("sun_support", "bearings", "sun_support", 0.3, 3.0, True, "log",
            "assumed order of magnitude (no ball geometry public); sets the input-shaft lateral modes"),
    Tunable("pin_wheel_housing", "bearings", "pin_wheel_housing", 0.3, 3.0, True, "log",
            "assumed bolted-joint stiffness (1e9..1e10 N/m); sets the housing mode the sensor sees. "
            "pin_wheel_torsional is scaled by the same factor (it is k R^2 of this stiffness)"),
    Tunable("crank_cycloid", "bearings", "crank_cycloid", 0.3, 3.0, True, "log",
            "Palmgren estimate at one load; needle-ring stiffness depends on clearance and preload"),
    Tunable("mesh_damping_ratio", "damping", "mesh_damping_ratio", 0.01, 0.2, False, "linear",
            "common choice in gear dynamics (0.03..0.17 in the literature); sets the resonance widths"),
    Tunable("bearing_damping_ratio", "damping", "bearing_damping_ratio", 0.01, 0.2, False, "linear",
            "common choice for rolling-element supports; no RV-specific figure"),
    Tunable("housing_added_mass", "mounting", "housing_added_mass", 0.0, 30.0, False, "linear",
            "housing shell, flanges and the robot link bolted to the reducer: differs per installation"),
    Tunable("path_resonance_hz", "mounting", "path_resonance_hz", 1000.0, 12000.0, False, "log",
            "structural resonance between housing and accelerometer (mounting, bracket): per test rig; "
            "0 (none) is also tried", path=True),
    Tunable("path_damping_ratio", "mounting", "path_damping_ratio", 0.01, 0.2, False, "linear",
            "damping of that path resonance", path=True),
)
TUNABLE_NAMES: tuple[str, ...] = tuple(t.name for t in TUNABLES)
_BY_NAME = {t.name: t for t in TUNABLES}


def get_value(params: ReducerParams, t: Tunable) -> float:
    """Current value of a tunable parameter in a parameter set."""
    return float(getattr(getattr(params, t.section), t.key))


@dataclass(frozen=True)
class Bound:
    """A tunable with its absolute bounds for one base parameter set (and, for the path resonance, one fs)."""

    tunable: Tunable
    base: float
    lower: float
    upper: float

    @property
    def name(self) -> str:
        return self.tunable.name

    def to_value(self, u: float) -> float:
        """Unit-cube coordinate -> parameter value."""
        u = min(max(float(u), 0.0), 1.0)
        if self.tunable.scale == "log":
            return math.exp(math.log(self.lower) + u * (math.log(self.upper) - math.log(self.lower)))
        return self.lower + u * (self.upper - self.lower)

    def to_unit(self, value: float) -> float:
        """Parameter value -> unit-cube coordinate (clipped to [0, 1])."""
        if self.upper == self.lower:
            return 0.0
        if self.tunable.scale == "log":
            if value <= 0:
                return 0.0
            u = (math.log(value) - math.log(self.lower)) / (math.log(self.upper) - math.log(self.lower))
        else:
            u = (value - self.lower) / (self.upper - self.lower)
        return min(max(u, 0.0), 1.0)


def bounds_for(params: ReducerParams, names: list[str] | tuple[str, ...] | None = None,
               fs: float | None = None) -> list[Bound]:
    """Absolute bounds of the named tunables (all when ``names`` is None) around ``params``.

    The path resonance's upper bound is kept below 0.45 ``fs`` (a resonance at or above Nyquist does nothing).
    A base value outside the stated bounds widens them to hold it (a base path resonance of 0, "none", is kept
    as the base but not as a bound: "none" is always tried besides the range).
    """
    if names is None:
        names = TUNABLE_NAMES
    out = []
    seen = set()
    for name in names:
        if name not in _BY_NAME:
            raise ParameterError(f"unknown tuned parameter {name!r}; choose from {', '.join(TUNABLE_NAMES)}")
        if name in seen:
            raise ParameterError(f"tuned parameter {name!r} given twice")
        seen.add(name)
        t = _BY_NAME[name]
        base = get_value(params, t)
        lo, hi = (t.lower * base, t.upper * base) if t.relative else (t.lower, t.upper)
        if t.name == "path_resonance_hz" and fs is not None:
            hi = min(hi, 0.45 * fs)
            if hi <= lo:
                raise ParameterError(f"fs {fs:g} Hz is too low to tune a path resonance above {lo:g} Hz")
        if not (t.name == "path_resonance_hz" and base == 0.0):
            lo, hi = min(lo, base), max(hi, base)
        if t.scale == "log" and lo <= 0:
            raise ParameterError(f"{t.section}.{t.key} = {base} cannot be tuned on a log scale (must be > 0)")
        out.append(Bound(t, base, lo, hi))
    return out


def apply_values(params: ReducerParams, values: dict[str, float]) -> ReducerParams:
    """Copy of ``params`` with tunable values set (``pin_wheel_torsional`` follows ``pin_wheel_housing``)."""
    changes: dict[str, dict[str, float]] = {}
    for name, value in values.items():
        t = _BY_NAME[name]
        changes.setdefault(t.section, {})[t.key] = float(value)
        if name == "pin_wheel_housing":
            factor = float(value) / params.bearings.pin_wheel_housing
            changes["bearings"]["pin_wheel_torsional"] = params.bearings.pin_wheel_torsional * factor
    return params.replace(**changes)

