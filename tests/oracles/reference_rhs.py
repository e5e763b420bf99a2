"""An independent, vectorised NumPy implementation of the model's equations of motion (no numba).

Written from ``docs/model.md`` (sections 1-4), not from the compiled kernels of
:mod:`rvdiag.dynamics.model`, whose code it does not call: only the model's *data* (the flat
parameter vector ``P`` with its ``I_*`` layout, the masses, the TVMS table and its profile deviation,
the pin count) is shared.  Planet angles, pin angles, frame angles and the contact geometry are
recomputed here.  Two uses:

- a check of the compiled right-hand side (``tests/test_reference_rhs.py``: equal to ~1e-9 relative at
  random states, healthy and faulty, with and without excitation);
- the honest speed baseline of ``bench/sim_speed.py``: scipy's ``solve_ivp`` on a Python/NumPy
  right-hand side of the same equations, which is what a reader gets without the compiled kernels
  (the peer figure in bench/HISTORY.md, 0.0033 simulated s per s for RK45 with a Python RHS, measures this).

Conventions that the documentation leaves open and that this file shares with the kernels (so the
comparison is exact): a damping force is ``c`` times the projection of the relative *velocity* on the
current geometric coefficients (the coefficients' own time variation, e.g. of the crank-cycloid
direction ``t_j`` or of the pin normals, is not differentiated); mesh and pin dampers act only while
the contact is closed (always, with the bilateral flag ``P[I_BILATERAL]``, which also replaces the
dead zone by a shift of ``bilateral * b/2``); with a profile deviation ``e`` the mesh deflection is
``delta - e`` and its rate ``delta' - de/dt``, ``de/dt`` the table slope per grid step times the grid
rate (zero when the time variation is frozen).

Manufacturing errors (``model.extra["manufacturing"]``, the drawn deviations of
:mod:`rvdiag.dynamics.manufacturing`, not the kernels' packed coefficients): each planet's runout e_i at phi_i
takes ``e_i sin(beta_0 + phi_i + alpha)`` off its mesh approach and ``e_i cos(beta_0 + phi_i + alpha) beta_0'``
off its rate; a crank hole's error eps_i shifts the crank-carrier bearing's seat; a crank's eccentric angle error
adds to its rotation in the crank-cycloid bearings; a pin's radius error rho_k and groove error v_k (fixed frame)
compress its contacts by ``rho_k - v_k . n`` (the pins stand still: no rate); a modified disc profile stands each pin
off by its initial clearance (:meth:`ReferenceRHS._clearance`; its rate is left out, as in the kernels).
"""

from __future__ import annotations

import math

import numpy as np

from rvdiag.dynamics import model as mdl

TWO_PI = 2.0 * math.pi


class ReferenceRHS:
    """``f(t, y) -> dy/dt`` for ``y = [q, v]`` of a :class:`rvdiag.dynamics.model.Model`, in NumPy.

    >>> from rvdiag.dynamics import prepare
    >>> m = prepare(output_speed_deg_s=45.0, load_Nm=100.0, mesh_source="rectangular")
    >>> f = ReferenceRHS(m)
    >>> f(0.0, np.zeros(2 * m.n_dof)).shape
    (56,)
    """

    def __init__(self, model: mdl.Model) -> None:
        P = np.asarray(model.P, dtype=float)
        self.P = P
        self.N = int(P[mdl.I_NPL])
        self.D = int(P[mdl.I_NDISC])
        self.n = model.n_dof
        self.mass = np.asarray(model.mass, dtype=float)
        self.k_table = np.asarray(model.tvms, dtype=float)
        self.e_table = np.asarray(model.tvms_error, dtype=float)
        # per tooth-pair slot: stiffness and separation (model.pairs), damping from the mesh damping ratio
        # held per pair, c_s = c_mesh sqrt(k_s / mean(tvms)) (docs/model.md)
        self.k_pairs = np.asarray(model.pairs[:, 0, :], dtype=float)
        self.e_pairs = np.asarray(model.pairs[:, 1, :], dtype=float)
        kmean = float(np.mean(self.k_table)) if np.mean(self.k_table) > 0 else 1.0
        self.c_pairs = P[mdl.I_CMESH] * np.sqrt(np.clip(self.k_pairs, 0.0, None) / kmean)
        self.iramp = P[mdl.I_IRAMP]
        # separation slope at the nodes (per node interval): central where the pair touches on both sides,
        # one-sided at its ends, interpolated linearly so the damper's rate is continuous (docs/model.md)
        slopes = []
        for ks, es in zip(self.k_pairs, self.e_pairs):
            sl = np.zeros_like(es)
            for j in range(es.size):
                jm, jp = (j - 1) % es.size, (j + 1) % es.size
                if ks[j] <= 0.0:
                    continue
                if ks[jm] > 0.0 and ks[jp] > 0.0:
                    sl[j] = 0.5 * (es[jp] - es[jm])
                elif ks[jp] > 0.0:
                    sl[j] = es[jp] - es[j]
                elif ks[jm] > 0.0:
                    sl[j] = es[j] - es[jm]
            slopes.append(sl)
        self.de_pairs = np.array(slopes)
        N, D = self.N, self.D
        psi = TWO_PI * np.arange(N) / N
        self.cps, self.sps = np.cos(psi), np.sin(psi)
        alpha = P[mdl.I_ALPHA]
        self.sa, self.ca = math.sin(alpha), math.cos(alpha)
        # line of action of mesh i on the sun's (x, y): (sin(alpha - psi), cos(alpha - psi))
        self.sap, self.cap = np.sin(alpha - psi), np.cos(alpha - psi)
        Zp = int(round(P[mdl.I_ZP]))
        self.gamma = TWO_PI * np.arange(Zp) / Zp  # pin angles at t = 0 (carrier frame offsets)
        self.ip = 3 + 3 * np.arange(N)  # planets
        self.ic = 3 + 3 * N + 3 * np.arange(N)  # cranks
        self.idisc = 3 + 6 * N + 3 * np.arange(D)  # discs
        self.iH = 3 + 6 * N + 3 * D  # carrier
        self.iR = self.iH + 3  # pin wheel
        # the optional single-coordinate bodies after the pin wheel: the motor rotor, then the load
        self.has_load = P[mdl.I_LOAD] != 0.0
        self.iM = self.iR + 3  # motor rotor (when P[I_MOTOR])
        self.iL = self.n - 1  # load (when P[I_LOAD])
        err = model.extra.get("manufacturing")
        zN, zZ = np.zeros(N), np.zeros(Zp)
        self.run_e = np.asarray(err.runout) if err is not None else zN
        self.run_phi = np.asarray(err.runout_angle) if err is not None else zN
        self.hole = (np.asarray(err.hole_radial), np.asarray(err.hole_tangential)) if err is not None else (zN, zN)
        self.dphase = np.asarray(err.crank_phase) if err is not None else zN
        self.pin_rho = np.asarray(err.pin_radius) if err is not None else zZ
        pr = np.asarray(err.pin_radial) if err is not None else zZ
        pt = np.asarray(err.pin_tangential) if err is not None else zZ
        g = self.gamma
        self.pin_v = (pr * np.cos(g) - pt * np.sin(g), pr * np.sin(g) + pt * np.cos(g))  # fixed frame

    def kinematics(self, t: float) -> tuple[float, float, float]:
        """Carrier angle theta_H, speed Omega and acceleration dOmega/dt at t (docs/model.md section 2): Omega t at
        constant speed; the trapezoid integrated segment by segment from its speed, the S-curve from its
        piecewise-constant jerk; theta_H(0) = 0."""
        P = self.P
        te = self._te(t)
        W = P[mdl.I_OMEGA]
        if P[mdl.I_PROFILE] == 3.0:
            return self._scurve(te)
        if P[mdl.I_PROFILE] != 2.0:
            return W * te, W, 0.0
        acc, t_s, t_a, t_c = P[mdl.I_PR_ACC], P[mdl.I_PR_TS], P[mdl.I_PR_TA], P[mdl.I_PR_TC]
        knots = np.array([t_s, t_s + t_a, t_s + t_a + t_c, t_s + 2 * t_a + t_c])
        rates = np.array([0.0, acc, 0.0, -acc, 0.0])  # acceleration in each of the five phases

        def angle(x: float) -> tuple[float, float, float]:
            """Integrate the piecewise-constant acceleration from rest at t_s up to x."""
            th = w = 0.0
            lo = t_s
            for tk, r in zip(list(knots[1:]) + [np.inf], rates[1:]):
                if x <= lo:
                    break
                dt = min(x, tk) - lo
                th += w * dt + 0.5 * r * dt * dt
                w += r * dt
                lo = tk
            return th, w, rates[int(np.searchsorted(knots, x, side="left"))]

        th, w, a = angle(te)
        return th - angle(0.0)[0], w, a

    def _scurve(self, te: float) -> tuple[float, float, float]:
        """The S-curve's (theta_H, Omega, dOmega/dt): its jerk is J, 0, -J, 0, -J, 0, J over its seven phases
        (Biagiotti & Melchiorri 2008, section 3.4) and 0 at rest; integrated exactly phase by phase from rest."""
        P = self.P
        J, tj, ta, tc, t_s = P[mdl.I_PR_JERK], P[mdl.I_PR_TJ], P[mdl.I_PR_TA], P[mdl.I_PR_TC], P[mdl.I_PR_TS]
        d = [tj, ta - 2 * tj, tj, tc, tj, ta - 2 * tj, tj]
        jerks = [J, 0.0, -J, 0.0, -J, 0.0, J]

        def integrate(x: float) -> tuple[float, float, float]:
            th = w = a = 0.0
            lo = t_s
            for dk, jk in zip(d + [np.inf], jerks + [0.0]):
                if x <= lo:
                    break
                dt = min(x, lo + dk) - lo
                th += w * dt + a * dt**2 / 2 + jk * dt**3 / 6
                w += a * dt + jk * dt**2 / 2
                a += jk * dt
                lo += dk
            return th, w, a

        th, w, a = integrate(te)
        return th - integrate(0.0)[0], w, a

    def load_torque(self, t: float) -> float:
        """T_L(t) = T0 + M g L cos(theta_arm0 + theta_H) + M L^2 dOmega/dt (a gravity arm; T0 without one)."""
        P = self.P
        if P[mdl.I_PROFILE] == 0.0:
            return P[mdl.I_TLOAD]
        th, _, a = self.kinematics(t)
        # with a load DOF the arm's inertia is the DOF's: its acceleration torque is the DOF's nominal angular
        # acceleration, not a term of the load torque (docs/model.md section 2)
        inertial = 0.0 if self.has_load else P[mdl.I_ARM_ML2] * a
        return P[mdl.I_TLOAD] + P[mdl.I_ARM_MGL] * np.cos(P[mdl.I_ARM_TH0] + th) + inertial

    def _te(self, t: float) -> float:
        tf = self.P[mdl.I_TFROZEN]
        return float(tf) if tf >= 0.0 else float(t)

    def forces(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Generalized forces Q(t, q, v): springs, contacts, dampers, load torque (docs/model.md 3-4)."""
        P, N = self.P, self.N
        te = self._te(t)
        frozen = P[mdl.I_TFROZEN] >= 0.0
        Q = np.zeros(self.n)
        ip, ic, idd, iH, iR = self.ip, self.ic, self.idisc, self.iH, self.iR
        a, e = P[mdl.I_A], P[mdl.I_E]
        bil = P[mdl.I_BILATERAL]

        # supports, input coupling, load torque
        Q[0:2] -= P[mdl.I_KSS] * q[0:2] + P[mdl.I_CSS] * v[0:2]
        # input shaft from the motor rotor (after the pin wheel) or an ideal speed source (angle 0)
        iM = self.iM
        qm, vm = (q[iM], v[iM]) if P[mdl.I_MOTOR] != 0.0 else (0.0, 0.0)
        t_shaft = P[mdl.I_KIN] * (q[2] - qm) + P[mdl.I_CIN] * (v[2] - vm)
        Q[2] -= t_shaft
        if P[mdl.I_MOTOR] != 0.0:  # rotor: steady drive torque, speed-loop spring and damper, shaft reaction
            drive = P[mdl.I_TDRIVE]
            if P[mdl.I_PROFILE] != 0.0:  # feed-forward: T_L(t) / i plus i J_ref dOmega/dt
                drive = self.load_torque(t) / P[mdl.I_RATIO] + P[mdl.I_JREF_I] * self.kinematics(t)[2]
            Q[iM] += drive - P[mdl.I_KSL] * qm - P[mdl.I_CSL] * vm + t_shaft
        Q[iH:iH + 2] -= P[mdl.I_KHS] * q[iH:iH + 2] + P[mdl.I_CHS] * v[iH:iH + 2]
        if self.has_load:  # output coupling k_out, c_out between carrier and load; the load torque on the load
            iL = self.iL
            t_out = P[mdl.I_KOUT] * (q[iH + 2] - q[iL]) + P[mdl.I_COUT] * (v[iH + 2] - v[iL])
            Q[iH + 2] -= t_out
            Q[iL] += t_out - self.load_torque(t)
        else:
            Q[iH + 2] -= self.load_torque(t)
        Q[iR:iR + 2] -= P[mdl.I_KRH] * q[iR:iR + 2] + P[mdl.I_CRH] * v[iR:iR + 2]
        Q[iR + 2] -= P[mdl.I_KRT] * q[iR + 2] + P[mdl.I_CRT] * v[iR + 2]

        # sun-planet meshes: TVMS at the sun angle relative to planet i, linear interpolation
        nt = self.k_table.size
        th_H, Om_t, _ = self.kinematics(t)
        phi = P[mdl.I_WREL] * te if P[mdl.I_PROFILE] == 0.0 else (P[mdl.I_RATIO] - 1.0) * th_H
        w_rel = P[mdl.I_WREL] if P[mdl.I_PROFILE] == 0.0 else (P[mdl.I_RATIO] - 1.0) * Om_t
        x = phi / TWO_PI - np.arange(N) / N
        x = (x - np.floor(x)) * nt
        j0 = np.minimum(x.astype(np.int64), nt - 1)
        fr = x - j0
        j1 = (j0 + 1) % nt
        rb1, rb2 = P[mdl.I_RB1], P[mdl.I_RB2]
        d = (q[0] * self.sap + q[1] * self.cap + rb1 * q[2]
             - q[ip] * self.sa - q[ip + 1] * self.ca + rb2 * q[ip + 2])
        dd = (v[0] * self.sap + v[1] * self.cap + rb1 * v[2]
              - v[ip] * self.sa - v[ip + 1] * self.ca + rb2 * v[ip + 2])
        # planet runout: the pitch circle, eccentric by e_i at phi_i, turns with the cranks' eccentric angle beta_0
        beta0 = P[mdl.I_BETA0] - P[mdl.I_ZP] * th_H
        arg = beta0 + self.run_phi + P[mdl.I_ALPHA]
        d = d - self.run_e * np.sin(arg)
        dd = dd - (0.0 if frozen else self.run_e * np.cos(arg) * -P[mdl.I_ZP] * Om_t)
        hb = P[mdl.I_HALF_BACKLASH]
        if bil != 0.0:  # linearised: nominal TVMS and load-shared separation, no damping in the mesh
            km = self.k_table[j0] + fr * (self.k_table[j1] - self.k_table[j0])
            e_ = self.e_table[j0] + fr * (self.e_table[j1] - self.e_table[j0])
            F = km * (d - e_ - bil * hb)
        else:
            F = np.zeros(N)
            for ks, es, cs, ds in zip(self.k_pairs, self.e_pairs, self.c_pairs, self.de_pairs):
                k_ = ks[j0] + fr * (ks[j1] - ks[j0])
                c_ = cs[j0] + fr * (cs[j1] - cs[j0])
                g = d - (es[j0] + fr * (es[j1] - es[j0]))
                gd = dd - (0.0 if frozen else w_rel * nt / TWO_PI * (ds[j0] + fr * (ds[j1] - ds[j0])))
                # the damper grows linearly over the first 1/iramp of approach (Hunt & Crossley), never pulls
                ramp_in = np.minimum((g - hb) * self.iramp, 1.0)
                push = np.maximum(k_ * (g - hb) + c_ * ramp_in * gd, 0.0)  # drive flank: pushes, never pulls
                F += np.where(g > hb, push, 0.0)
            # back flanks: nominal TVMS without relief, the mean mesh damper, never push
            km = self.k_table[j0] + fr * (self.k_table[j1] - self.k_table[j0])
            ramp_back = np.maximum((d + hb) * self.iramp, -1.0)
            pull = np.minimum(km * (d + hb) - P[mdl.I_CMESH] * ramp_back * dd, 0.0)
            F += np.where(d < -hb, pull, 0.0)
        Q[0] -= np.sum(F * self.sap)
        Q[1] -= np.sum(F * self.cap)
        Q[2] -= np.sum(F) * rb1
        Q[ip] += F * self.sa
        Q[ip + 1] += F * self.ca
        Q[ip + 2] -= F * rb2

        # planet-crank splines
        for m in range(2):
            f = P[mdl.I_KPR] * (q[ip + m] - q[ic + m]) + P[mdl.I_CPR] * (v[ip + m] - v[ic + m])
            Q[ip + m] -= f
            Q[ic + m] += f
        f = P[mdl.I_KPT] * (q[ip + 2] - q[ic + 2]) + P[mdl.I_CPT] * (v[ip + 2] - v[ic + 2])
        Q[ip + 2] -= f
        Q[ic + 2] += f

        # crank-carrier bearings, orbiting frame: d = u_c - R(psi)^T u_H - a th_H (0, 1)
        cps, sps = self.cps, self.sps

        def cc(z):
            return (z[ic] - (cps * z[iH] + sps * z[iH + 1]),
                    z[ic + 1] - (-sps * z[iH] + cps * z[iH + 1]) - a * z[iH + 2])

        (dx, dy), (vx, vy) = cc(q), cc(v)
        dx, dy = dx - self.hole[0], dy - self.hole[1]  # the seat of crank bearing i is off by the hole's error
        fx = P[mdl.I_KCC] * dx + P[mdl.I_CCC] * vx
        fy = P[mdl.I_KCC] * dy + P[mdl.I_CCC] * vy
        Q[ic] -= fx
        Q[ic + 1] -= fy
        Q[iH] += np.sum(cps * fx - sps * fy)
        Q[iH + 1] += np.sum(sps * fx + cps * fy)
        Q[iH + 2] += a * np.sum(fy)

        # frame angles: eccentric of disc j at beta_j (carrier frame), B_j = beta_j + Omega t (fixed)
        B, cb, sb, cB, sB = self._frames(t)

        # crank-cycloid bearings (i, j), carrier frame: d = R(psi) u_c + e th_c t_j - u_d - a th_d e_t(psi)
        kcd, ccd = P[mdl.I_KCD], P[mdl.I_CCD]
        tx, ty = -e * sb[None, :], e * cb[None, :]  # (1, D): e t_j

        def ccd_d(z, dph):
            ux = (cps * z[ic] - sps * z[ic + 1])[:, None]
            uy = (sps * z[ic] + cps * z[ic + 1])[:, None]
            th = (z[ic + 2] + dph)[:, None]
            return (ux + th * tx - z[idd][None, :] + z[idd + 2][None, :] * a * sps[:, None],
                    uy + th * ty - z[idd + 1][None, :] - z[idd + 2][None, :] * a * cps[:, None])

        (dx, dy), (vx, vy) = ccd_d(q, self.dphase), ccd_d(v, 0.0)
        fx = kcd * dx + ccd * vx  # (N, D)
        fy = kcd * dy + ccd * vy
        Q[ic] -= np.sum(cps[:, None] * fx + sps[:, None] * fy, axis=1)
        Q[ic + 1] -= np.sum(-sps[:, None] * fx + cps[:, None] * fy, axis=1)
        Q[ic + 2] -= np.sum(tx * fx + ty * fy, axis=1)
        Q[idd] += np.sum(fx, axis=0)
        Q[idd + 1] += np.sum(fy, axis=0)
        Q[idd + 2] += a * np.sum(-sps[:, None] * fx + cps[:, None] * fy, axis=0)

        # cycloid-pin contacts
        nx, ny, lk, delta, rate = self._pin_deflections(B, cb, sb, cB, sB, q, v)
        Fp = P[mdl.I_KPIN] * delta + P[mdl.I_CPIN] * rate
        rr = P[mdl.I_ZP] / P[mdl.I_ZC]
        if bil == 0.0:
            Fp = np.where(delta > 0.0, np.maximum(Fp, 0.0), 0.0)  # compression only; the damper never pulls
        sx, sy, sm = np.sum(Fp * nx, axis=1), np.sum(Fp * ny, axis=1), np.sum(Fp * lk, axis=1)
        Q[idd] -= cb * sx - sb * sy
        Q[idd + 1] -= sb * sx + cb * sy
        Q[idd + 2] -= sm
        Q[iR] += np.sum(cB * sx - sB * sy)
        Q[iR + 1] += np.sum(sB * sx + cB * sy)
        Q[iR + 2] += rr * np.sum(sm)
        return Q

    def _frames(self, t: float):
        P = self.P
        th_H = self.kinematics(t)[0]
        beta = P[mdl.I_BETA0] - P[mdl.I_ZP] * th_H + np.arange(self.D) * P[mdl.I_DISCPHASE]
        B = beta + th_H
        return B, np.cos(beta), np.sin(beta), np.cos(B), np.sin(B)

    def _pin_geometry(self, B: np.ndarray):
        """Unit normals (disc frame) from the pitch point to every pin and the arms, shape (D, Zp):
        eta_k = gamma_k - B_j, n = (R_p cos eta - e Zp, R_p sin eta) / L, l = e Zc n_y."""
        P = self.P
        e, Zp, Zc, Rp = P[mdl.I_E], P[mdl.I_ZP], P[mdl.I_ZC], P[mdl.I_RP]
        eta = self.gamma[None, :] - B[:, None]
        px = Rp * np.cos(eta) - e * Zp
        py = Rp * np.sin(eta)
        L = np.hypot(px, py)
        return px / L, py / L, e * Zc * py / L

    def _clearance(self, B: np.ndarray) -> np.ndarray:
        """The discs' profile modification (docs/model.md section 3), shape (D, Zp): Delta = dr_rp - dr_p (1 - K1
        cos eta) / S - c sin(eta) / S with S = sqrt(1 + K1^2 - 2 K1 cos eta), c the packed closing rotation."""
        P = self.P
        if P[mdl.I_PINMOD] == 0.0:
            return np.zeros((len(B), self.gamma.size))
        k1 = P[mdl.I_E] * P[mdl.I_ZP] / P[mdl.I_RP]
        eta = self.gamma[None, :] - B[:, None]
        S = np.sqrt(1.0 + k1 * k1 - 2.0 * k1 * np.cos(eta))
        out = P[mdl.I_DRRP] - (P[mdl.I_DRP] * (1.0 - k1 * np.cos(eta)) + P[mdl.I_CLOSE] * np.sin(eta)) / S
        if P[mdl.I_PINWEAR] != 0.0:  # the worn stage's clearance growth: its table over cos(eta), interpolated
            w0, nw = int(P[mdl.I_PINWEAR]), int(P[mdl.I_NPINWEAR])
            out = out + np.interp(np.cos(eta), np.linspace(-1.0, 1.0, nw), P[w0:w0 + nw])
        return out

    def _pin_deflections(self, B, cb, sb, cB, sB, q, v):
        P = self.P
        nx, ny, lk = self._pin_geometry(B)
        idd, iR = self.idisc, self.iR
        rr = P[mdl.I_ZP] / P[mdl.I_ZC]

        def rel(z):  # disc minus pin wheel, in the disc's eccentric frame
            ux = cb * z[idd] + sb * z[idd + 1] - (cB * z[iR] + sB * z[iR + 1])
            uy = -sb * z[idd] + cb * z[idd + 1] - (-sB * z[iR] + cB * z[iR + 1])
            return ux[:, None], uy[:, None], (z[idd + 2] - rr * z[iR + 2])[:, None]

        ux, uy, th = rel(q)
        wx, wy, om = rel(v)
        # pin errors: the groove's offset v_k (fixed frame) seen in disc j's eccentric frame, R(-B_j) v_k
        vx, vy = self.pin_v
        px = cB[:, None] * vx[None, :] + sB[:, None] * vy[None, :]
        py = -sB[:, None] * vx[None, :] + cB[:, None] * vy[None, :]
        off = self.pin_rho[None, :] - (px * nx + py * ny) - self._clearance(B)
        return nx, ny, lk, ux * nx + uy * ny + th * lk + off, wx * nx + wy * ny + om * lk

    def pin_deflections(self, t: float, q: np.ndarray) -> np.ndarray:
        """Approach delta_jk of every cycloid-pin contact, shape (D, Zp); > 0 is compression."""
        B, cb, sb, cB, sB = self._frames(t)
        q = np.asarray(q, dtype=float)
        return self._pin_deflections(B, cb, sb, cB, sB, q, np.zeros_like(q))[3]

    def accelerations(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """M^-1 (Q - m a0) + rotating-frame terms (docs/model.md section 2)."""
        P = self.P
        acc = self.forces(t, q, v) / self.mass
        _, Om, dOm = self.kinematics(t)
        acc[self.ip] += Om * Om * P[mdl.I_A]  # nominal centripetal acceleration of the orbiting bodies
        acc[self.ic] += Om * Om * P[mdl.I_A]
        _, cb, sb, _, _ = self._frames(t)
        ue = P[mdl.I_E] * (P[mdl.I_ZC] * Om) ** 2  # disc orbit (unbalance)
        acc[self.idisc] += ue * cb
        acc[self.idisc + 1] += ue * sb
        if P[mdl.I_CORIOLIS] != 0.0:
            ix = np.arange(0, self.iR, 3)  # every body but the pin wheel (fixed frame)
            acc[ix] += 2.0 * Om * v[ix + 1] + Om * Om * q[ix]
            acc[ix + 1] += -2.0 * Om * v[ix] + Om * Om * q[ix + 1]
            # Euler term of a frame whose rate changes: -dOmega/dt z x u
            acc[ix] += dOm * q[ix + 1]
            acc[ix + 1] -= dOm * q[ix]
        # tangential parts of the nominal accelerations: planet and crank origins a dOmega/dt e_t (their y),
        # disc centres -e Zc dOmega/dt e_t(beta_j); minus each body's nominal angular acceleration
        acc[self.ip + 1] -= P[mdl.I_A] * dOm
        acc[self.ic + 1] -= P[mdl.I_A] * dOm
        acc[self.idisc] += P[mdl.I_E] * P[mdl.I_ZC] * dOm * -sb
        acc[self.idisc + 1] += P[mdl.I_E] * P[mdl.I_ZC] * dOm * cb
        spin = np.zeros(self.n)  # nominal angular speed of each body per unit carrier speed
        spin[2] = P[mdl.I_RATIO]
        spin[self.ip + 2] = spin[self.ic + 2] = -P[mdl.I_ZC]
        spin[self.idisc + 2] = 1.0
        spin[self.iH + 2] = 1.0
        if P[mdl.I_MOTOR] != 0.0:
            spin[self.iM] = P[mdl.I_RATIO]
        if self.has_load:  # the load turns with the carrier
            spin[self.iL] = 1.0
        acc -= spin * dOm
        return acc

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        n = self.n
        y = np.asarray(y, dtype=float)
        return np.concatenate([y[n:], self.accelerations(t, y[:n], y[n:])])
