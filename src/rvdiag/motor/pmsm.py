"""The servo motor's design side: controller gains, operating-point checks and the phase currents.

One purpose: everything about the PMSM under i_d = 0 vector control that is not the integration itself
(the compiled rates are :mod:`rvdiag.dynamics.motor_kernel`; docs/model.md section 10 derives both).

- :func:`controller_gains`: current PIs by pole-zero cancellation, ``K_p = L w_cc``, ``K_i = R w_cc``, which
  make the closed current loop first order at ``w_cc`` (Harnefors & Nee 1998, IEEE Trans. Ind. Appl. 34(1),
  eq. 12); the speed observer's gains ``l_1 = 2 zeta w_o``, ``l_2 = w_o^2`` (zeta = 1: critically damped;
  Lorenz & Van Patten 1991); the inverter's linear range ``V_dc / sqrt(3)`` (space-vector modulation) and the
  dead-time voltage ``U_dt = t_d f_pwm V_dc`` (Choi & Sul 1996, IEEE Trans. Power Electron. 11(2), eq. 1).
- :func:`check_operating_point`: the steady voltage and current an operating point needs, refused with one
  line naming the limit.
- :func:`phase_currents`: the inverse (amplitude-invariant) Park transform.
- :func:`sample_current`: the drive's current record at a chosen sampling rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.params.schema import Motor
from rvdiag.validation import finite_number


@dataclass(frozen=True)
class ControllerGains:
    """The derived constants of the motor and its drive (SI units)."""

    torque_constant: float  #: K_t = 1.5 p psi_f, N m per A peak (i_q)
    kp_current: float  #: V/A
    ki_current: float  #: V/(A s)
    voltage_limit: float  #: V_dc / sqrt(3), V peak per phase
    dead_time_voltage: float  #: t_d f_pwm V_dc, V
    encoder_quantum: float  #: 2 pi / 2^bits, rad (0: ideal)
    observer_l1: float  #: 1/s
    observer_l2: float  #: 1/s^2


def controller_gains(motor: Motor, pole_pairs: int) -> ControllerGains:
    """The gains and limits of the drive for ``motor`` with ``pole_pairs`` pole pairs (module docstring)."""
    w_cc = 2.0 * math.pi * motor.current_loop_bandwidth_hz
    w_o = 2.0 * math.pi * motor.speed_observer_hz
    return ControllerGains(
        torque_constant=1.5 * pole_pairs * motor.flux_linkage,
        kp_current=max(motor.inductance_d, motor.inductance_q) * w_cc,
        ki_current=motor.resistance * w_cc,
        voltage_limit=motor.dc_link_voltage / math.sqrt(3.0),
        dead_time_voltage=motor.dead_time_s * motor.pwm_frequency_hz * motor.dc_link_voltage,
        encoder_quantum=0.0 if motor.encoder_bits == 0 else 2.0 * math.pi / 2.0 ** motor.encoder_bits,
        observer_l1=2.0 * w_o,
        observer_l2=w_o * w_o,
    )


def check_operating_point(motor: Motor, pole_pairs: int, rotor_speed_rad_s: float, rotor_torque_Nm: float) -> None:
    """Refuse an operating point the motor and its drive cannot hold (one line naming the limit).

    ``rotor_speed_rad_s`` and ``rotor_torque_Nm`` are the largest speed and torque the rotor must give (the
    load reflected through the reducer, friction and acceleration included).  The steady i_d = 0 voltage is
    ``v_d = -w_e L_q i_q``, ``v_q = R i_q + w_e psi_f``; it must stay inside the inverter's linear range with
    the dead-time loss as margin (Krause et al. 2002, eq. 15.4-1 to 15.4-3 at d/dt = 0).
    """
    g = controller_gains(motor, pole_pairs)
    if motor.dead_time_s * motor.pwm_frequency_hz >= 0.25:
        raise ParameterError(f"[motor] dead_time_s = {motor.dead_time_s:g} s is a quarter or more of the PWM period "
                             f"at {motor.pwm_frequency_hz:g} Hz: the inverter could not switch")
    i_q = abs(rotor_torque_Nm) / g.torque_constant
    if i_q > motor.max_current:
        raise ParameterError(
            f"the motor current saturates: the load needs i_q = {i_q:.3g} A (torque {abs(rotor_torque_Nm):.3g} N m at "
            f"the rotor), over the limit [motor] max_current = {motor.max_current:g} A")
    w_e = pole_pairs * abs(rotor_speed_rad_s)
    v_d = w_e * motor.inductance_q * i_q
    v_q = motor.resistance * i_q + w_e * motor.flux_linkage
    need = math.hypot(v_d, v_q) + g.dead_time_voltage
    if need > g.voltage_limit:
        rpm = abs(rotor_speed_rad_s) * 60.0 / (2.0 * math.pi)
        raise ParameterError(
            f"the speed controller cannot reach {rpm:.0f} rpm: it needs {need:.1f} V per phase, over the inverter's "
            f"V_dc / sqrt(3) = {g.voltage_limit:.1f} V ([motor] dc_link_voltage = {motor.dc_link_voltage:g} V)")


def phase_currents(i_d: np.ndarray, i_q: np.ndarray, theta_e: np.ndarray) -> np.ndarray:
    """``(3, n)`` phase currents i_a, i_b, i_c from the d-q currents at electrical angle ``theta_e`` (inverse,
    amplitude-invariant Park transform; Krause et al. 2002, eq. 3.3-6)."""
    i_d, i_q, th = (np.asarray(x, dtype=float) for x in (i_d, i_q, theta_e))
    return np.stack([i_d * np.cos(th - k) - i_q * np.sin(th - k) for k in (0.0, 2 * math.pi / 3, -2 * math.pi / 3)])


def sample_current(x: np.ndarray, fs: float, fs_out: float) -> np.ndarray:
    """Resample channels ``x`` (last axis, rate ``fs``) to ``fs_out``: the drive's current record.

    A polyphase FIR filter (``scipy.signal.resample_poly``, Kaiser window) limits the band to ``fs_out / 2``
    before the rate change, as the drive's anti-aliasing filter and averaging over the PWM period do.
    ``fs / fs_out`` must be a ratio of small integers (e.g. 48 kHz to 1 kHz: 48)."""
    from scipy.signal import resample_poly

    r = current_rate_ratio(fs, fs_out)
    if r == 1:
        return np.array(x, dtype=float, copy=True)
    return resample_poly(np.asarray(x, dtype=float), r.numerator, r.denominator, axis=-1)


def current_rate_ratio(fs: float, fs_out: float) -> Fraction:
    """``fs_out / fs`` as a fraction of small integers, or a one-line error naming the rate."""
    finite_number(fs_out, "current sampling rate (Hz)", 0, strict=True, noun="a number")
    if fs_out > fs:
        raise ParameterError(f"current sampling rate {fs_out:g} Hz is above the simulation's {fs:g} Hz")
    r = Fraction(float(fs_out) / float(fs)).limit_denominator(1000)
    if abs(r.numerator / r.denominator * fs - fs_out) > 1e-9 * fs_out:
        raise ParameterError(f"current sampling rate {fs_out:g} Hz is not a simple fraction of {fs:g} Hz")
    return r
