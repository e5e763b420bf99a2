"""The compiled (numba) right-hand side of the servo motor's electrical side: a PMSM under i_d = 0 vector
control (docs/model.md section 10; :mod:`rvdiag.motor` derives the gains and checks the operating point).

One purpose: the rates of the motor's electrical states and its air-gap torque, for the integrator.  The
states follow the mechanical ones, ``y = [q, v, x]`` with ``x = (i_d, i_q, z_d, z_q, a, w)``:

- the d-q stator currents (amplitude-invariant Park transform), Krause, Wasynczuk & Sudhoff, *Analysis of
  Electric Machinery* (2002), ch. 15, eqs. 15.4-1 to 15.4-3 (L_d, L_q, R, psi_f, p pole pairs)::

      L_d di_d/dt = v_d - R i_d + w_e L_q i_q
      L_q di_q/dt = v_q - R i_q - w_e (L_d i_d + psi_f)
      T_e = 1.5 p (psi_f i_q + (L_d - L_q) i_d i_q),   w_e = p w_m;

- ``z_d, z_q``: the integrals of the current errors of the two current PIs (gains ``K_p = L w_cc``,
  ``K_i = R w_cc``, pole-zero cancellation, Harnefors & Nee 1998, IEEE Trans. Ind. Appl. 34(1)), with the
  decoupling feed-forward ``-w_e L_q i_q`` and ``w_e (L_d i_d + psi_f)``; the command is limited to the
  inverter's linear range ``|v| <= V_dc / sqrt(3)`` and the integrators stop while it is limited
  (conditional anti-windup);
- ``a, w``: a second-order tracking observer of the rotor's vibratory angle and speed from the encoder's
  quantised angle (Lorenz & Van Patten 1991, IEEE Trans. Ind. Appl. 27(4)); the speed PI acts on them.  The
  encoder reads ``theta + e_enc sin(theta)``: its once-per-revolution error (disc eccentricity and mounting),
  which the speed loop turns into a torque, and so a current, at the rotor's frequency.

The speed PI is the rotor's ``[drive]`` speed loop: the torque command is the feed-forward (steady load
``T_L / i``, friction and the profile's acceleration torque) minus ``K_sl a + C_sl w``, the same PI as the
mechanical-only model's, turned into ``i_q* = T* / (1.5 p psi_f)`` and limited to the motor's peak current.

Inverter dead time (Choi & Sul 1996, IEEE Trans. Power Electron. 11(2)): each phase's average voltage loses
``U_dt sign(i_x)``, ``U_dt = t_d f_pwm V_dc``; the sign is linear below the switches' capacitive commutation
current ``i_0``.  Its sixth harmonic in the d-q frame gives the 5th and 7th harmonics
of the phase current.

The parameters sit at the end of ``P`` (:data:`MOTOR_P_FIELDS`, appended by :mod:`rvdiag.dynamics.kernels`);
the kernels here take ``P`` and the index ``b`` of the first of them, so this file does not import the
kernels file (no import circle).
"""

from __future__ import annotations

import math

import numba

from rvdiag.dynamics.numba_cache import guard_kernel_module

guard_kernel_module(__file__)

#: the motor's entries of ``P``, in order (appended to ``kernels.P_FIELDS``; ``b`` = index of the first)
MOTOR_P_FIELDS = (
    "PMSM",           # 1.0: the electrical states are on
    "M_P",            # pole pairs p ([operation] motor_pole_pairs)
    "M_R", "M_LD", "M_LQ", "M_PSI",  # R, L_d, L_q, psi_f
    "M_B",            # viscous friction of the rotor, N m s/rad
    "M_KPC", "M_KIC",  # current PI gains
    "M_VMAX",         # voltage limit V_dc / sqrt(3)
    "M_UDT", "M_IDT",  # dead-time voltage t_d f_pwm V_dc, its commutation current
    "M_QENC",         # encoder quantum 2 pi / 2^bits (0: ideal)
    "M_L1", "M_L2",   # observer gains
    "M_IMAX",         # peak current limit
    "M_KT",           # 1.5 p psi_f
    "M_EENC",         # encoder's once-per-revolution angle error (mounting eccentricity), rad
)
#: number of electrical states appended to ``y = [q, v]``
N_MOTOR_STATES = 6
_P, _R, _LD, _LQ, _PSI, _B, _KPC, _KIC, _VMAX, _UDT, _IDT, _QENC, _L1, _L2, _IMAX, _KT, _EENC = range(1, 18)

FASTMATH = {"reassoc", "contract", "nsz"}
_C120 = -0.5
_S120 = math.sqrt(3.0) / 2.0


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _soft_sign(x):
    """sign(x), linear over |x| < 1: the dead-time voltage's reversal as the phase current's commutation
    charges the switches' output capacitance (Choi & Sul 1996, section II)."""
    if x > 1.0:
        return 1.0
    if x < -1.0:
        return -1.0
    return x


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def air_gap_torque(P, b, i_d, i_q):
    """T_e = 1.5 p (psi_f i_q + (L_d - L_q) i_d i_q) (Krause et al. 2002, eq. 15.4-10)."""
    return 1.5 * P[b + _P] * (P[b + _PSI] * i_q + (P[b + _LD] - P[b + _LQ]) * i_d * i_q)


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def motor_rates(y, P, b, n, im, theta_nom, omega_nom, t_ff, k_sl, c_sl, dydt):
    """``dydt[2n:2n+6]``: the rates of the electrical states at the rotor's nominal angle ``theta_nom`` and
    speed ``omega_nom`` (rad, rad/s, mechanical), the speed PI's feed-forward torque ``t_ff`` (N m) and its
    gains ``k_sl`` (N m/rad, integral) and ``c_sl`` (N m s/rad, proportional).

    The rotor's vibratory angle and speed are ``y[im]`` and ``y[n + im]`` (``im = n - 1``, or ``n - 2`` when a
    load DOF follows the rotor)."""
    k = 2 * n
    a = y[k + 4]
    w = y[k + 5]
    qm = y[im]
    th = theta_nom + qm
    c1 = math.cos(th)
    s1 = math.sin(th)
    # encoder: the absolute angle with its once-per-revolution error, quantised; the observer tracks its
    # vibratory part
    th_m = th + P[b + _EENC] * s1
    qe = P[b + _QENC]
    meas = (th_m if qe == 0.0 else math.floor(th_m / qe) * qe) - theta_nom
    r = meas - a
    dydt[k + 4] = w + P[b + _L1] * r
    dydt[k + 5] = P[b + _L2] * r
    # the electrical angle p theta as (cos, sin), by complex powers of the mechanical angle's (one libm call)
    c = c1
    s_ = s1
    for _ in range(int(P[b + _P]) - 1):
        c, s_ = c * c1 - s_ * s1, s_ * c1 + c * s1
    # the speed PI on the observed angle and speed, then the current loop
    current_loop_rates(y, P, b, n, im, omega_nom, c, s_, t_ff - k_sl * a - c_sl * w, dydt)


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def current_loop_rates(y, P, b, n, im, omega_nom, c, s_, t_cmd, dydt):
    """The current loop, the inverter and the stator: ``dydt[2n:2n+4]`` for ``(i_d, i_q, z_d, z_q)`` given the
    speed loop's torque command ``t_cmd`` (N m) and the electrical angle's cosine and sine ``c, s_``; see the
    module docstring for the equations."""
    k = 2 * n
    i_d = y[k]
    i_q = y[k + 1]
    z_d = y[k + 2]
    z_q = y[k + 3]
    w_est = y[k + 5]
    p = P[b + _P]
    ld = P[b + _LD]
    lq = P[b + _LQ]
    psi = P[b + _PSI]
    imax = P[b + _IMAX]
    iq_ref = t_cmd / P[b + _KT]
    if iq_ref > imax:
        iq_ref = imax
    elif iq_ref < -imax:
        iq_ref = -imax
    e_d = -i_d
    e_q = iq_ref - i_q
    we_est = p * (omega_nom + w_est)
    kp = P[b + _KPC]
    ki = P[b + _KIC]
    v_d = kp * e_d + ki * z_d - we_est * lq * i_q
    v_q = kp * e_q + ki * z_q + we_est * (ld * i_d + psi)
    vmag = math.sqrt(v_d * v_d + v_q * v_q)
    vmax = P[b + _VMAX]
    if vmag > vmax:  # the inverter's linear range; the integrators hold (anti-windup)
        s = vmax / vmag
        v_d *= s
        v_q *= s
        dydt[k + 2] = 0.0
        dydt[k + 3] = 0.0
    else:
        dydt[k + 2] = e_d
        dydt[k + 3] = e_q
    # the stator sees the true electrical angle and speed
    vm = y[n + im]
    we = p * (omega_nom + vm)
    udt = P[b + _UDT]
    if udt != 0.0:
        # phase currents (inverse Park) and their rotated unit vectors at -120 and +120 degrees
        cb = c * _C120 + s_ * _S120
        sb = s_ * _C120 - c * _S120
        cc = c * _C120 - s_ * _S120
        sc = s_ * _C120 + c * _S120
        i0 = 1.0 / P[b + _IDT]
        ua = -udt * _soft_sign((i_d * c - i_q * s_) * i0)
        ub = -udt * _soft_sign((i_d * cb - i_q * sb) * i0)
        uc = -udt * _soft_sign((i_d * cc - i_q * sc) * i0)
        v_d += (2.0 / 3.0) * (ua * c + ub * cb + uc * cc)
        v_q -= (2.0 / 3.0) * (ua * s_ + ub * sb + uc * sc)
    dydt[k] = (v_d - P[b + _R] * i_d + we * lq * i_q) / ld
    dydt[k + 1] = (v_q - P[b + _R] * i_q - we * (ld * i_d + psi)) / lq
