"""Static equilibrium and linearisation of the RV-reducer model.

The model's forces are piecewise linear in the displacements (linear springs, contacts that are either
in compression or open, the backlash dead zone).  At a time ``t`` frozen, the stiffness matrix
``K = -dQ/dq`` and damping matrix ``C = -dQ/dv`` are therefore exact central differences of the
compiled force function as long as no contact changes state within the step.  The static equilibrium
under a load torque is found by Newton's method on the piecewise-linear residual (an active-set
iteration: each step solves the linear system of the current contact state).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from rvdiag.dynamics import model as mdl
from rvdiag.errors import SimulationError
from rvdiag.gears.cycloid import modification_clearance
from rvdiag.gears.pin_wear import table_function


def _residual(model: mdl.Model, t: float, q: np.ndarray) -> np.ndarray:
    """M * acceleration at rest: forces plus the constant inertial (centripetal) terms, v = 0."""
    n = model.n_dof
    y = np.concatenate([q, np.zeros(n)])
    f = mdl.make_rhs(model)(t, y)
    return f[n:] * model.mass


def stiffness_matrix(model: mdl.Model, t: float = 0.0, q: np.ndarray | None = None, h: float = 1e-10) -> np.ndarray:
    """Tangent stiffness ``K = -d(M a)/dq`` at ``q`` (central differences, exact for piecewise-linear forces).

    Includes the rotating-frame softening ``-m Omega^2`` when Coriolis terms are on.
    """
    n = model.n_dof
    q = np.zeros(n) if q is None else np.asarray(q, float)
    K = np.empty((n, n))
    for j in range(n):
        dq = np.zeros(n)
        dq[j] = h
        K[:, j] = -(_residual(model, t, q + dq) - _residual(model, t, q - dq)) / (2 * h)
    return K


def bilateral_deflection(model: mdl.Model, t: float = 0.0) -> np.ndarray:
    """Static deflection with every contact closed and no backlash: a linear solve that always exists.

    The meshes sit on the flank the load presses together (the backlash gap taken up).  It is the start
    of :func:`static_equilibrium`'s Newton iteration, and the initial state of a simulation when that
    iteration does not converge (the start-up transient then settles the contacts).
    """
    fm = model.frozen(t)
    lin = fm.with_P(BILATERAL=-1.0 if fm.P[mdl.I_TLOAD] < 0 else 1.0)
    return _solve(stiffness_matrix(lin, t), _residual(lin, t, np.zeros(model.n_dof)))


def static_equilibrium(model: mdl.Model, t: float = 0.0, max_iter: int = 50, tol: float = 1e-9) -> np.ndarray:
    """Static deflection ``q`` with ``M a(t, q, v=0) = 0`` (time-varying terms frozen at ``t``).

    Newton's method on the piecewise-linear residual; converges when the contact states stop
    changing.  Where the full steps keep switching the same contacts on and off (a disc carried across its
    clearance, e.g. the load reversed on a worn cycloid stage), the iteration restarts with steps halved until the
    residual falls (damped Newton with backtracking, Nocedal & Wright 2006, sec. 11.2); a system that converges
    with full steps never reaches it.  Raises SimulationError when neither converges.
    """
    fm = model.frozen(t)
    scale = np.abs(fm.P[mdl.I_TLOAD]) + 1.0
    q = bilateral_deflection(model, t)
    r = _residual(fm, t, q)
    for _ in range(max_iter):
        if np.max(np.abs(r)) <= tol * scale:
            return q
        q = q + _solve(stiffness_matrix(fm, t, q), r)
        r = _residual(fm, t, q)
    if np.max(np.abs(r)) <= tol * scale:
        return q
    q = bilateral_deflection(model, t)
    r = _residual(fm, t, q)
    for _ in range(4 * max_iter):
        if np.max(np.abs(r)) <= tol * scale:
            return q
        dq = _solve(stiffness_matrix(fm, t, q), r)
        norm, lam = np.linalg.norm(r), 1.0
        while lam > 1e-6:
            r_new = _residual(fm, t, q + lam * dq)
            if np.linalg.norm(r_new) < norm:
                break
            lam *= 0.5
        q, r = q + lam * dq, r_new
    if np.max(np.abs(r)) <= tol * scale:
        return q
    raise SimulationError("static equilibrium did not converge (contacts keep changing state)")


def _solve(K: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Solve K dq = r; least squares where K is singular (a free mechanism mode, e.g. open meshes)."""
    try:
        with np.errstate(all="ignore"):
            lu = scipy.linalg.lu_factor(K, check_finite=True)
        if np.min(np.abs(np.diag(lu[0]))) > 1e-12 * np.max(np.abs(np.diag(lu[0]))):
            return scipy.linalg.lu_solve(lu, r)
    except (scipy.linalg.LinAlgError, ValueError):
        pass
    return np.linalg.lstsq(K, r, rcond=1e-12)[0]


@dataclass(frozen=True)
class Modes:
    """Undamped natural frequencies (Hz, ascending) and mode shapes (columns) of the linearised model."""

    frequencies_hz: np.ndarray
    shapes: np.ndarray


def natural_frequencies(model: mdl.Model, t: float = 0.0, q: np.ndarray | None = None) -> Modes:
    """Solve ``K phi = w^2 M phi`` at the (loaded) equilibrium ``q`` (default: static equilibrium)."""
    fm = model.frozen(t)
    if q is None:
        q = static_equilibrium(fm, t)
    K = stiffness_matrix(fm, t, q)
    K = 0.5 * (K + K.T)
    w2, phi = scipy.linalg.eigh(K, np.diag(model.mass))
    return Modes(np.sqrt(np.clip(w2, 0.0, None)) / (2 * np.pi), phi)


def potential_energy(model: mdl.Model, t: float, q: np.ndarray) -> float:
    """Potential of every conservative force at time ``t`` (an independent NumPy implementation).

    Springs ``k d^2 / 2`` (the mesh with its backlash dead zone, the pins only in compression), the
    load torque ``T_L th_H`` (``T_L th_L`` and the output coupling ``k_out (th_H - th_L)^2 / 2`` with a load DOF), the constant inertial forces of the orbiting bodies and, with the
    rotating-frame terms on, the centrifugal potential ``-m Omega^2 (x^2 + y^2) / 2``.  Written from
    docs/model.md without the compiled kernels (numpy sin/cos instead of angle-addition tables), so
    ``Q = -grad V`` checks the force code and ``T + V`` checks the integrator.
    """
    P = model.P
    q = np.asarray(q, float)
    te = P[mdl.I_TFROZEN] if P[mdl.I_TFROZEN] >= 0 else t
    N, D = model.n_planets, model.n_discs
    lay = mdl.dof_layout(N, D)
    s, H, R = lay["sun"], lay["carrier"], lay["pin_wheel"]
    qm = q[model.rotor_index] if model.has_motor else 0.0  # the motor rotor (or the ideal speed source at rest)
    V = 0.5 * P[mdl.I_KSS] * (q[s] ** 2 + q[s + 1] ** 2) + 0.5 * P[mdl.I_KIN] * (q[s + 2] - qm) ** 2
    if model.has_motor:  # the speed loop's spring and the steady drive torque's work on the rotor
        V += 0.5 * P[mdl.I_KSL] * qm**2 - P[mdl.I_TDRIVE] * qm
    V += 0.5 * P[mdl.I_KHS] * (q[H] ** 2 + q[H + 1] ** 2)
    if model.has_load:  # the output coupling to the load DOF (the last coordinate), which carries the load torque
        V += 0.5 * P[mdl.I_KOUT] * (q[H + 2] - q[-1]) ** 2 + P[mdl.I_TLOAD] * q[-1]
    else:
        V += P[mdl.I_TLOAD] * q[H + 2]
    V += 0.5 * P[mdl.I_KRH] * (q[R] ** 2 + q[R + 1] ** 2) + 0.5 * P[mdl.I_KRT] * q[R + 2] ** 2
    alpha, rb1, rb2, hb = P[mdl.I_ALPHA], P[mdl.I_RB1], P[mdl.I_RB2], P[mdl.I_HALF_BACKLASH]
    a, e, Om = P[mdl.I_A], P[mdl.I_E], P[mdl.I_OMEGA]
    Zp, Zc = P[mdl.I_ZP], P[mdl.I_ZC]
    nt = model.tvms.size
    grid = np.arange(nt + 1) * (2 * np.pi / nt)
    ktab = np.append(model.tvms, model.tvms[0])
    etab = np.append(model.tvms_error, model.tvms_error[0])
    pk = np.concatenate([model.pairs[:, 0, :], model.pairs[:, 0, :1]], axis=1)  # per-slot stiffness
    pe = np.concatenate([model.pairs[:, 1, :], model.pairs[:, 1, :1]], axis=1)  # per-slot separation
    bil = P[mdl.I_BILATERAL]
    beta = [P[mdl.I_BETA0] - Zp * Om * te + j * P[mdl.I_DISCPHASE] for j in range(D)]
    # manufacturing errors (rvdiag.dynamics.manufacturing), from the drawn deviations, not the packed tables
    err = model.extra.get("manufacturing")
    zN, zZ = (0.0,) * N, (0.0,) * int(Zp)
    runout, run_ang = (err.runout, err.runout_angle) if err is not None else (zN, zN)
    hole_r, hole_t, dphase = (err.hole_radial, err.hole_tangential, err.crank_phase) if err is not None else (zN,) * 3
    for i in range(N):
        psi = 2 * np.pi * i / N
        p, c = lay[f"planet{i}"], lay[f"crank{i}"]
        phase = np.mod(P[mdl.I_WREL] * te - psi, 2 * np.pi)
        d = (q[s] * np.sin(alpha - psi) + q[s + 1] * np.cos(alpha - psi) + rb1 * q[s + 2]
             - q[p] * np.sin(alpha) - q[p + 1] * np.cos(alpha) + rb2 * q[p + 2])
        # the planet's pitch circle, eccentric by e_i at phi_i to its crank, turns with the eccentric angle beta_0
        d -= runout[i] * np.sin(beta[0] + run_ang[i] + alpha)
        if bil != 0:  # linearised: nominal TVMS, load-shared separation
            V += 0.5 * np.interp(phase, grid, ktab) * (d - np.interp(phase, grid, etab) - bil * hb) ** 2
        else:  # each tooth pair a spring beyond its separation and the half backlash; back flanks nominal
            for ks, es in zip(pk, pe):
                g = d - np.interp(phase, grid, es)
                if g > hb:
                    V += 0.5 * np.interp(phase, grid, ks) * (g - hb) ** 2
            if d < -hb:
                V += 0.5 * np.interp(phase, grid, ktab) * (d + hb) ** 2
        V += 0.5 * P[mdl.I_KPR] * ((q[p] - q[c]) ** 2 + (q[p + 1] - q[c + 1]) ** 2)
        V += 0.5 * P[mdl.I_KPT] * (q[p + 2] - q[c + 2]) ** 2
        Rm = np.array([[np.cos(psi), -np.sin(psi)], [np.sin(psi), np.cos(psi)]])
        uH = q[H:H + 2]
        dcc = q[c:c + 2] - Rm.T @ uH - a * q[H + 2] * np.array([0.0, 1.0]) - np.array([hole_r[i], hole_t[i]])
        V += 0.5 * P[mdl.I_KCC] * dcc @ dcc
        for j in range(D):
            dd = lay[f"disc{j}"]
            tj = e * np.array([-np.sin(beta[j]), np.cos(beta[j])])
            et = np.array([-np.sin(psi), np.cos(psi)])
            dcd = Rm @ q[c:c + 2] + (q[c + 2] + dphase[i]) * tj - q[dd:dd + 2] - q[dd + 2] * a * et
            V += 0.5 * P[mdl.I_KCD] * dcd @ dcd
    # cycloid-pin contacts, written in the carrier frame with explicit pin and pitch-point positions
    Rp = P[mdl.I_RP]
    gam = 2 * np.pi * np.arange(int(Zp)) / Zp - Om * te
    pins = Rp * np.stack([np.cos(gam), np.sin(gam)], axis=1)
    th_c = Om * te  # carrier angle: the pin wheel's fixed-frame displacement seen in the carrier frame
    Rc = np.array([[np.cos(th_c), np.sin(th_c)], [-np.sin(th_c), np.cos(th_c)]])
    ur = Rc @ q[R:R + 2]
    # each pin's radius error and its groove's position error (fixed frame, then in the carrier frame)
    rho = np.asarray(err.pin_radius if err is not None else zZ)
    gk = 2 * np.pi * np.arange(int(Zp)) / Zp
    pr = np.asarray(err.pin_radial if err is not None else zZ)
    pt = np.asarray(err.pin_tangential if err is not None else zZ)
    vpin = np.stack([pr * np.cos(gk) - pt * np.sin(gk), pr * np.sin(gk) + pt * np.cos(gk)], axis=1) @ Rc.T
    for j in range(D):
        dd = lay[f"disc{j}"]
        ehat = np.array([np.cos(beta[j]), np.sin(beta[j])])
        Od = e * ehat
        C = e * Zp * ehat
        n = pins - C
        n /= np.linalg.norm(n, axis=1)[:, None]
        # displacement of the disc point on the line of action minus that of the pin, along n
        cross_d = (C - Od)[0] * n[:, 1] - (C - Od)[1] * n[:, 0]
        cross_r = C[0] * n[:, 1] - C[1] * n[:, 0]
        delta = (n @ (q[dd:dd + 2] - ur) + q[dd + 2] * cross_d - q[R + 2] * cross_r
                 + rho - np.sum(n * vpin, axis=1))
        if P[mdl.I_PINMOD] != 0:  # the modified profile's initial clearance at each pin's phase eta
            cos_eta = pins @ ehat / Rp
            sin_eta = (ehat[0] * pins[:, 1] - ehat[1] * pins[:, 0]) / Rp
            delta -= modification_clearance(cos_eta, sin_eta, e * Zp / Rp, P[mdl.I_DRRP], P[mdl.I_DRP],
                                            P[mdl.I_CLOSE])
            if P[mdl.I_PINWEAR] != 0:  # the worn stage's clearance growth, a table over cos(eta)
                w0 = int(P[mdl.I_PINWEAR])
                delta -= table_function(P[w0:w0 + int(P[mdl.I_NPINWEAR])])(cos_eta)
        if bil == 0:
            delta = np.maximum(delta, 0.0)
        V += 0.5 * P[mdl.I_KPIN] * np.sum(delta**2)
    # constant inertial forces (nominal centripetal accelerations) and centrifugal potential
    m = model.mass
    for i in range(N):
        for body in (f"planet{i}", f"crank{i}"):
            V -= m[lay[body]] * Om**2 * a * q[lay[body]]
    for j in range(D):
        dd = lay[f"disc{j}"]
        V -= m[dd] * e * (Zc * Om) ** 2 * (np.cos(beta[j]) * q[dd] + np.sin(beta[j]) * q[dd + 1])
    if P[mdl.I_CORIOLIS] != 0:
        for b in range(R // 3):
            V -= 0.5 * m[3 * b] * Om**2 * (q[3 * b] ** 2 + q[3 * b + 1] ** 2)
    return float(V)


def total_energy(model: mdl.Model, t: float, y: np.ndarray) -> float:
    """Kinetic energy of the vibratory motion (rotating-frame velocities) plus :func:`potential_energy`.

    With damping off and the time-varying terms frozen this is a constant of motion (the Jacobi
    integral of the rotating frame: the Coriolis forces do no work).
    """
    n = model.n_dof
    v = np.asarray(y[n:], float)
    return 0.5 * float(np.sum(model.mass * v * v)) + potential_energy(model, t, y[:n])
