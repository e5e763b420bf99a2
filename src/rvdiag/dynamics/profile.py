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
from rvdiag.validation import finite_number

#: standard gravity, m/s^2
G = 9.80665


#: the speed profiles: constant speed, the trapezoid (piecewise-constant acceleration) and the jerk-limited
#: S-curve (piecewise-constant jerk, the 7-segment double-S profile)
PROFILE_KINDS = ("constant", "trapezoid", "scurve")


@dataclass(frozen=True)
class SpeedProfile:
    """Output (carrier) speed against time.

    ``kind="constant"``: ``theta_H = Omega t`` at the operating point's speed (the default model).
    ``kind="trapezoid"``: at rest until ``start_s``, then a constant acceleration ``accel_deg_s2`` up to
    ``output_speed_deg_s``, a cruise, and a deceleration at the same rate to rest, ``move_s`` after the start
    (``move_s=None``: the move ends with the record).  ``start_s`` may be negative (the move began before the
    record).
    ``kind="scurve"``: the same move with the jerk limited to ``jerk_deg_s3`` (Biagiotti & Melchiorri,
    *Trajectory Planning for Automatic Machines and Robots*, Springer 2008, section 3.4, the double-S velocity
    profile from rest to rest): the acceleration ramps at the jerk J to the acceleration limit A, holds, and
    ramps back to zero as the speed reaches V; the speed and the acceleration are continuous (the trapezoid's
    acceleration jumps).  With T_j the jerk time and A_lim the acceleration reached (section 3.4's case test):

        T_j = A / J and A_lim = A          when V J >= A^2 (the limit A is reached),
        T_j = sqrt(V / J) and A_lim = J T_j  otherwise,
        T_a = T_j + V / A_lim              (the acceleration phase; the deceleration mirrors it)

    and over the acceleration phase (tau from the move's start)

        tau in [0, T_j]:            a = J tau,   v = J tau^2 / 2,            s = J tau^3 / 6
        tau in [T_j, T_a - T_j]:    a = A_lim,   v = A_lim (tau - T_j / 2),  s = A_lim (3 tau^2 - 3 T_j tau + T_j^2) / 6
        tau in [T_a - T_j, T_a]:    u = T_a - tau,  a = J u,  v = V - J u^2 / 2,  s = V T_a / 2 - V u + J u^3 / 6

    (Biagiotti & Melchiorri 2008, eqs. of section 3.4 with q0 = v0 = 0).  The move covers V (T_a + T_c), T_c the
    cruise.

    >>> p = SpeedProfile.trapezoid(45.0, 90.0, move_s=2.0)
    >>> [round(float(v), 3) for v in p.omega_deg_s(np.array([0.25, 1.0, 1.75]))]
    [22.5, 45.0, 22.5]
    >>> s = SpeedProfile.scurve(45.0, 90.0, 900.0, move_s=2.0)   # T_j = 0.1 s, T_a = 0.6 s
    >>> [round(float(v), 3) for v in s.omega_deg_s(np.array([0.1, 0.3, 1.0, 1.9]))]
    [4.5, 22.5, 45.0, 4.5]
    """

    kind: str = "constant"
    output_speed_deg_s: float | None = None
    accel_deg_s2: float | None = None
    move_s: float | None = None
    start_s: float = 0.0
    jerk_deg_s3: float | None = None

    @classmethod
    def constant(cls) -> "SpeedProfile":
        return cls()

    @classmethod
    def trapezoid(cls, output_speed_deg_s: float, accel_deg_s2: float, move_s: float | None = None,
                  start_s: float = 0.0) -> "SpeedProfile":
        p = cls("trapezoid", output_speed_deg_s, accel_deg_s2, move_s, start_s)
        p.validate()
        return p

    @classmethod
    def scurve(cls, output_speed_deg_s: float, accel_deg_s2: float, jerk_deg_s3: float,
               move_s: float | None = None, start_s: float = 0.0) -> "SpeedProfile":
        p = cls("scurve", output_speed_deg_s, accel_deg_s2, move_s, start_s, jerk_deg_s3)
        p.validate()
        return p

    @property
    def is_constant(self) -> bool:
        return self.kind == "constant"

    def validate(self, duration_s: float | None = None) -> None:
        """Raise :class:`ParameterError` for a profile that cannot run (``duration_s``: the record's length,
        which a trapezoid or S-curve without ``move_s`` fills)."""
        if self.kind not in PROFILE_KINDS:
            raise ParameterError(f"speed profile must be one of {', '.join(PROFILE_KINDS)}, got {self.kind!r}")
        if self.is_constant:
            return
        v = finite_number(self.output_speed_deg_s, "output speed (deg/s)", 0.0, strict=True, type_first=True)
        a = finite_number(self.accel_deg_s2, "acceleration (deg/s^2)", 0.0, strict=True, type_first=True)
        finite_number(self.start_s, "profile start (s)", type_first=True)
        if self.kind == "scurve":
            finite_number(self.jerk_deg_s3, "jerk (deg/s^3)", 0.0, strict=True, type_first=True)
        elif self.jerk_deg_s3 is not None:
            raise ParameterError("a jerk limit applies to the S-curve profile only")
        if self.move_s is not None:
            finite_number(self.move_s, "move duration (s)", 0.0, strict=True, type_first=True)
        move = self.move_time(duration_s)
        ramp = self.ramp_times()[1]
        if move is not None and 2.0 * ramp > move * (1.0 + 1e-12):
            what = (f"a trapezoid at {a:g} deg/s^2" if self.kind == "trapezoid"
                    else f"an S-curve at {a:g} deg/s^2 and {self.jerk_deg_s3:g} deg/s^3")
            raise ParameterError(
                f"{what} needs {2.0 * ramp:.4g} s to reach {v:g} deg/s and stop again, "
                f"longer than its move of {move:.4g} s: raise the acceleration{'' if self.kind == 'trapezoid' else ' or the jerk'} "
                "or lengthen the move")

    def ramp_times(self) -> tuple[float, float, float]:
        """``(T_j, T_a, A_lim)``: the jerk time (0 for a trapezoid), the acceleration phase's length (s) and the
        acceleration reached (deg/s^2)."""
        v, a = float(self.output_speed_deg_s), float(self.accel_deg_s2)
        if self.kind != "scurve":
            return 0.0, v / a, a
        j = float(self.jerk_deg_s3)
        tj = a / j if v * j >= a * a else math.sqrt(v / j)
        alim = j * tj
        return tj, tj + v / alim, alim

    def move_time(self, duration_s: float | None = None) -> float | None:
        """Length of the move (s): ``move_s``, or from ``start_s`` to the record's end."""
        if self.move_s is not None:
            return float(self.move_s)
        if duration_s is None:
            return None
        return float(duration_s) - float(self.start_s)

    def segments(self, duration_s: float | None = None) -> tuple[float, float, float, float, float]:
        """``(start, t_accel, t_cruise, accel, cruise speed)`` in s and rad/s^2, rad/s (trapezoid and S-curve;
        the S-curve's ``accel`` is the acceleration it reaches, A_lim, and its jerk time is :meth:`jerk_segment`)."""
        w = math.radians(float(self.output_speed_deg_s))
        move = self.move_time(duration_s)
        if move is None:
            raise ParameterError(f"a {self.kind} needs move_s or the record's duration")
        _, ta, alim = self.ramp_times()
        return float(self.start_s), ta, max(move - 2.0 * ta, 0.0), math.radians(alim), w

    def jerk_segment(self) -> tuple[float, float]:
        """``(T_j, J)`` of an S-curve in s and rad/s^3 (``(0, 0)`` for the others)."""
        if self.kind != "scurve":
            return 0.0, 0.0
        tj, _, alim = self.ramp_times()
        return tj, math.radians(alim) / tj

    def _cumulative(self, t: np.ndarray, duration_s: float | None):
        """Angle since the move's start, speed and acceleration (the closed form)."""
        if self.kind == "scurve":
            return self._cumulative_scurve(t, duration_s)
        ts, ta, tc, a, w = self.segments(duration_s)
        tau = np.asarray(t, dtype=float) - ts
        s = tau - ta - tc
        F = np.select([tau <= 0.0, tau < ta, tau < ta + tc, tau < 2.0 * ta + tc],
                      [0.0, 0.5 * a * tau**2, w * (0.5 * ta + (tau - ta)), w * (0.5 * ta + tc + s) - 0.5 * a * s**2],
                      w * (ta + tc))
        W = np.select([tau <= 0.0, tau < ta, tau < ta + tc, tau < 2.0 * ta + tc], [0.0, a * tau, w, w - a * s], 0.0)
        A = np.select([tau <= 0.0, tau < ta, tau < ta + tc, tau < 2.0 * ta + tc], [0.0, a, 0.0, -a], 0.0)
        return F, W, A

    def _cumulative_scurve(self, t: np.ndarray, duration_s: float | None):
        """The S-curve's angle since the move's start, speed and acceleration (the closed form of the class
        docstring; the deceleration mirrors the acceleration: s(tau) = S - s_acc(T - tau))."""
        ts, ta, tc, alim, w = self.segments(duration_s)
        tj, J = self.jerk_segment()
        T = 2.0 * ta + tc
        tau = np.asarray(t, dtype=float) - ts

        def acc_phase(x):
            u = ta - x
            F = np.select([x <= 0.0, x < tj, x < ta - tj, x < ta],
                          [0.0, J * x**3 / 6.0, alim * (3.0 * x * x - 3.0 * tj * x + tj * tj) / 6.0,
                           w * ta / 2.0 - w * u + J * u**3 / 6.0], w * ta / 2.0)
            W = np.select([x <= 0.0, x < tj, x < ta - tj, x < ta], [0.0, 0.5 * J * x * x, alim * (x - tj / 2.0),
                                                                      w - 0.5 * J * u * u], w)
            A = np.select([x <= 0.0, x < tj, x < ta - tj, x < ta], [0.0, J * x, alim, J * u], 0.0)
            return F, W, A

        Fa, Wa, Aa = acc_phase(np.minimum(tau, ta))
        Fd, Wd, Ad = acc_phase(np.maximum(T - tau, 0.0))
        total = w * (ta + tc)
        up, down = tau <= ta, tau >= T - ta
        F = np.where(up, Fa, np.where(down, total - Fd, w * ta / 2.0 + w * (tau - ta)))
        W = np.where(up, Wa, np.where(down, Wd, w))
        A = np.where(up, Aa, np.where(down, -Ad, 0.0))
        F = np.where(tau >= T, total, F)
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
        """Output speed (deg/s) at times ``t`` of a trapezoid or S-curve."""
        return np.degrees(self.state(t, 0.0, duration_s)[1])

    def to_dict(self) -> dict:
        d = asdict(self)
        if d["jerk_deg_s3"] is None:  # as before the S-curve: records of the other profiles keep their settings
            del d["jerk_deg_s3"]
        return d


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
        finite_number(self.arm_mass_kg, "arm mass (kg)", 0.0, type_first=True)
        finite_number(self.arm_length_m, "arm length (m)", 0.0, type_first=True)
        finite_number(self.arm_angle_deg, "arm angle (deg)", type_first=True)

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
