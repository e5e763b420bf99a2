"""An independent NumPy statement of the servo motor's electrical rates (the check of
``rvdiag.dynamics.motor_kernel``), written from the textbook equations with no shared code: the d-q stator
equations and torque (Krause, Wasynczuk & Sudhoff 2002, eqs. 15.4-1 to 15.4-3, 15.4-10), PI current control with
decoupling and a voltage limit with conditional anti-windup, the encoder's error and quantum, a second-order
tracking observer, and the dead-time voltage per phase through the amplitude-invariant Park transform.  The
electrical angle is taken with ``np.cos(p * theta)`` directly (the kernel uses complex powers of the mechanical
angle's cosine and sine)."""

from __future__ import annotations

import numpy as np


def reference_motor_rates(x, qm, vm, theta_nom, omega_nom, t_ff, k_sl, c_sl, m):
    """Rates of ``x = (i_d, i_q, z_d, z_q, a, w)``; ``m`` a dict of the motor's constants (names as the
    kernel's ``M_*`` fields, lower case without the prefix)."""
    i_d, i_q, z_d, z_q, a, w = x
    th = theta_nom + qm
    th_m = th + m["eenc"] * np.sin(th)
    if m["qenc"] > 0:
        th_m = np.floor(th_m / m["qenc"]) * m["qenc"]
    r = (th_m - theta_nom) - a
    da = w + m["l1"] * r
    dw = m["l2"] * r
    t_cmd = t_ff - k_sl * a - c_sl * w
    iq_ref = np.clip(t_cmd / m["kt"], -m["imax"], m["imax"])
    e = np.array([-i_d, iq_ref - i_q])
    we_est = m["p"] * (omega_nom + w)
    v = m["kpc"] * e + m["kic"] * np.array([z_d, z_q]) + np.array([-we_est * m["lq"] * i_q,
                                                                      we_est * (m["ld"] * i_d + m["psi"])])
    dz = e.copy()
    if np.hypot(*v) > m["vmax"]:
        v = v * m["vmax"] / np.hypot(*v)
        dz[:] = 0.0
    th_e = m["p"] * th
    shifts = np.array([0.0, -2 * np.pi / 3, 2 * np.pi / 3])
    i_abc = i_d * np.cos(th_e + shifts) - i_q * np.sin(th_e + shifts)
    u_abc = -m["udt"] * np.clip(i_abc / m["idt"], -1.0, 1.0)
    v = v + (2.0 / 3.0) * np.array([np.sum(u_abc * np.cos(th_e + shifts)), -np.sum(u_abc * np.sin(th_e + shifts))])
    we = m["p"] * (omega_nom + vm)
    did = (v[0] - m["r"] * i_d + we * m["lq"] * i_q) / m["ld"]
    diq = (v[1] - m["r"] * i_q - we * (m["ld"] * i_d + m["psi"])) / m["lq"]
    return np.array([did, diq, dz[0], dz[1], da, dw])


def reference_torque(i_d, i_q, m):
    """T_e = 1.5 p (psi_f i_q + (L_d - L_q) i_d i_q)."""
    return 1.5 * m["p"] * (m["psi"] * i_q + (m["ld"] - m["lq"]) * i_d * i_q)
