"""Speed and load profiles of the output (carrier): :class:`SpeedProfile` and :class:`LoadProfile` (one purpose).

A robot joint does not turn at one speed: it accelerates, cruises and decelerates (a trapezoidal speed
profile), and its gravity load follows the arm's angle.  These objects give the carrier angle
``theta_H(t)``, its speed ``Omega(t)`` and acceleration ``dOmega/dt(t)`` in closed form, and the load torque
``T_L(t)``; :func:`rvdiag.dynamics.packing.pack_model_arrays` writes their parameters into ``P`` and the compiled
kernels evaluate the same closed form (docs/model.md section 2).  Times are those of the record: the first
recorded sample is at ``t = 0`` (the run-in lies at negative times), and ``theta_H(0) = 0`` for every profile.

The constant profile (the default) is the model as it always was, bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from rvdiag.errors import ParameterError

#: standard gravity, m/s^2
G = 9.80665


def _number(name: str, val: object, lo: float | None = None, strict: bool = False) -> float:
    if isinstance(val, bool) or not isinstance(val, (int, float, np.integer, np.floating)):
        raise ParameterError(f"{name} must be a number, got {val!r}")
    x = float(val)
    if not math.isfinite(x) or (lo is not None and (x <= lo if strict else x < lo)):
        bound = "" if lo is None else (f" > {lo:g}" if strict else f" >= {lo:g}")
        raise ParameterError(f"{name} must be a finite number{bound}, got {val!r}")
    return x


@dataclass(frozen=True)
class SpeedProfile:
    """Output (carrier) speed against time.

    ``kind="constant"``: ``theta_H = Omega t`` at the operating point's speed (the default model).
    ``kind="trapezoid"``: at rest until ``start_s``, then a constant acceleration ``accel_deg_s2`` up to
    ``output_speed_deg_s``, a cruise, and a deceleration at the same rate to rest, ``move_s`` after the start
    (``move_s=None``: the move ends with the record).  ``start_s`` may be negative (the move began before the
    record).

    >>> p = SpeedProfile.trapezoid(45.0, 90.0, move_s=2.0)
    >>> [round(float(v), 3) for v in p.omega_deg_s(np.array([0.25, 1.0, 1.75]))]
    [22.5, 45.0, 22.5]
    """

    kind: str = "constant"
    output_speed_deg_s: float | None = None
    accel_deg_s2: float | None = None
    move_s: float | None = None
    start_s: float = 0.0

    @classmethod
    def constant(cls) -> "SpeedProfile":
        return cls()

    @classmethod
    def trapezoid(cls, output_speed_deg_s: float, accel_deg_s2: float, move_s: float | None = None,
                  start_s: float = 0.0) -> "SpeedProfile":
        p = cls("trapezoid", output_speed_deg_s, accel_deg_s2, move_s, start_s)
        p.validate()
        return p

    @property
    def is_constant(self) -> bool:
        return self.kind == "constant"

    def validate(self, duration_s: float | None = None) -> None:
        """Raise :class:`ParameterError` for a profile that cannot run (``duration_s``: the record's length,
        which a trapezoid without ``move_s`` fills)."""
        if self.kind not in ("constant", "trapezoid"):
            raise ParameterError(f"speed profile must be 'constant' or 'trapezoid', got {self.kind!r}")
        if self.is_constant:
            return
        v = _number("output speed (deg/s)", self.output_speed_deg_s, 0.0, strict=True)
        a = _number("acceleration (deg/s^2)", self.accel_deg_s2, 0.0, strict=True)
        _number("profile start (s)", self.start_s)
        if self.move_s is not None:
            _number("move duration (s)", self.move_s, 0.0, strict=True)
        move = self.move_time(duration_s)
        if move is not None and 2.0 * v / a > move * (1.0 + 1e-12):
            raise ParameterError(
                f"a trapezoid at {a:g} deg/s^2 needs {2.0 * v / a:.4g} s to reach {v:g} deg/s and stop again, "
                f"longer than its move of {move:.4g} s: raise the acceleration or lengthen the move")

    def move_time(self, duration_s: float | None = None) -> float | None:
        """Length of the move (s): ``move_s``, or from ``start_s`` to the record's end."""
        if self.move_s is not None:
            return float(self.move_s)
        if duration_s is None:
            return None
        return float(duration_s) - float(self.start_s)

    def segments(self, duration_s: float | None = None) -> tuple[float, float, float, float, float]:
        """``(start, t_accel, t_cruise, accel, cruise speed)`` in s and rad/s^2, rad/s (trapezoid only)."""
        w = math.radians(float(self.output_speed_deg_s))
        a = math.radians(float(self.accel_deg_s2))
        move = self.move_time(duration_s)
        if move is None:
            raise ParameterError("a trapezoid needs move_s or the record's duration")
        ta = w / a
        return float(self.start_s), ta, max(move - 2.0 * ta, 0.0), a, w

    def _cumulative(self, t: np.ndarray, duration_s: float | None):
        """Angle since the move's start, speed and acceleration of a trapezoid (the closed form)."""
        ts, ta, tc, a, w = self.segments(duration_s)
        tau = np.asarray(t, dtype=float) - ts
        s = tau - ta - tc
        F = np.select([tau <= 0.0, tau < ta, tau < ta + tc, tau < 2.0 * ta + tc],
                      [0.0, 0.5 * a * tau**2, w * (0.5 * ta + (tau - ta)), w * (0.5 * ta + tc + s) - 0.5 * a * s**2],
                      w * (ta + tc))
        W = np.select([tau <= 0.0, tau < ta, tau < ta + tc, tau < 2.0 * ta + tc], [0.0, a * tau, w, w - a * s], 0.0)
        A = np.select([tau <= 0.0, tau < ta, tau < ta + tc, tau < 2.0 * ta + tc], [0.0, a, 0.0, -a], 0.0)
        return F, W, A

    def state(self, t: np.ndarray, omega_rad_s: float, duration_s: float | None = None):
        """``(theta_H rad, Omega rad/s, dOmega/dt rad/s^2)`` at times ``t`` (record time, ``theta_H(0) = 0``);
        ``omega_rad_s`` is the constant profile's speed."""
        t = np.asarray(t, dtype=float)
        if self.is_constant:
            return omega_rad_s * t, np.full_like(t, omega_rad_s), np.zeros_like(t)
        F, W, A = self._cumulative(t, duration_s)
        F0 = self._cumulative(np.zeros(1), duration_s)[0][0]
        return F - F0, W, A

    def omega_deg_s(self, t: np.ndarray, duration_s: float | None = None) -> np.ndarray:
        """Output speed (deg/s) at times ``t`` of a trapezoid."""
        return np.degrees(self.state(t, 0.0, duration_s)[1])

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class LoadProfile:
    """Load torque on the output: the operating point's constant torque ``T0`` plus, optionally, a point-mass
    arm of ``arm_mass_kg`` at ``arm_length_m`` whose gravity and inertia the joint carries:

        T_L(t) = T0 + M g L cos(theta_arm0 + theta_H(t)) + M L^2 dOmega/dt

    (``theta_arm0 = arm_angle_deg``, the arm's angle above the horizontal at ``t = 0``; the motor-current
    paper's rig: 15 kg at 0.5 m).  No arm: the constant torque (the default model).
    """

    arm_mass_kg: float = 0.0
    arm_length_m: float = 0.0
    arm_angle_deg: float = 0.0

    def validate(self) -> None:
        _number("arm mass (kg)", self.arm_mass_kg, 0.0)
        _number("arm length (m)", self.arm_length_m, 0.0)
        _number("arm angle (deg)", self.arm_angle_deg)

    @property
    def has_arm(self) -> bool:
        return self.arm_mass_kg > 0.0 and self.arm_length_m > 0.0

    def torque(self, T0: float, theta_H: np.ndarray, domega: np.ndarray) -> np.ndarray:
        """``T_L`` (N m) at carrier angles ``theta_H`` (rad) and accelerations ``domega`` (rad/s^2)."""
        M, L = float(self.arm_mass_kg), float(self.arm_length_m)
        return (T0 + M * G * L * np.cos(math.radians(self.arm_angle_deg) + np.asarray(theta_H))
                + M * L * L * np.asarray(domega))

    def to_dict(self) -> dict:
        return asdict(self)
