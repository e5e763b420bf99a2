"""The full state of a run at every output sample, and the contact forces it implies.

:func:`rvdiag.dynamics.simulate` returns the sensor signal only.  The plausibility checks of docs/model.md
(dynamic mesh-force factor, tensile contact force, contact loss) need the forces inside the reducer, so this
module integrates with the same compiled kernels (:func:`rvdiag.dynamics.integrate.integrate`, one output
sample per call, so the step grid and therefore the trajectory are those of a normal run) and evaluates the
sun-planet mesh forces from the recorded states with the same contact law as the kernel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rvdiag.dynamics import model as mdl
from rvdiag.dynamics.integrate import integrate


@dataclass(frozen=True)
class Trace:
    """States ``y`` (samples, 2 n), times ``t`` (s) and the sensor signal (channels, samples) of one run."""

    t: np.ndarray
    y: np.ndarray
    signal: np.ndarray


def trace(model: mdl.Model, y0: np.ndarray, fs: float, n_samples: int, n_transient: int = 0) -> Trace:
    """Integrate like :func:`integrate` and keep the state at every recorded sample."""
    y = np.array(y0, dtype=float, copy=True)
    if n_transient:
        _, y = integrate(model, y, fs, 1, n_transient - 1, first_sample=-1)
    ys = np.empty((n_samples, y.size))
    sig = np.empty((model.sensor.shape[0], n_samples))
    for k in range(n_samples):
        ys[k] = y
        s, y = integrate(model, y, fs, 1, 0, first_sample=k)
        sig[:, k] = s[:, 0]
    return Trace(np.arange(n_samples) / fs, ys, sig)


def mesh_forces(model: mdl.Model, t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Force of every tooth-pair slot of every sun-planet mesh, shape (samples, planets, slots), N.

    The contact law of :func:`rvdiag.dynamics.kernels.generalized_forces`, evaluated in NumPy from the states:
    ``max(0, k_s (d - e_s - b) + c_s (d' - e_s'))`` on the drive flank (damper ramped in over the first
    ``MESH_DAMPING_RAMP_M``), and the back flank's nominal-TVMS force (negative) added to slot 0.
    """
    P = model.P
    n = model.n_dof
    N = model.n_planets
    S = int(P[mdl.I_NSLOT])
    hb = P[mdl.I_HALF_BACKLASH]
    out = np.zeros((len(t), N, S))
    mt = mdl.mesh_array(model)
    sa, ca, rb1, rb2 = P[mdl.I_SINA], P[mdl.I_COSA], P[mdl.I_RB1], P[mdl.I_RB2]
    for k, (tk, yk) in enumerate(zip(t, y)):
        mdl.mesh_terms(float(tk), P, model.tables, mt)
        run, run_rate = planet_runout(model, float(tk))
        for i in range(N):
            ip = 3 + 3 * i
            sap, cap = model.planet[i, 2], model.planet[i, 3]
            d = (yk[0] * sap + yk[1] * cap + rb1 * yk[2] - yk[ip] * sa - yk[ip + 1] * ca + rb2 * yk[ip + 2]
                 - run[i])
            dd = (yk[n] * sap + yk[n + 1] * cap + rb1 * yk[n + 2] - yk[n + ip] * sa - yk[n + ip + 1] * ca
                  + rb2 * yk[n + ip + 2] - run_rate[i])
            iramp, cm = P[mdl.I_IRAMP], P[mdl.I_CMESH]
            for s in range(S):
                km, e, ed, c = mt[i, 4 * s:4 * s + 4]
                g, gd = d - e, dd - ed
                if g > hb:
                    out[k, i, s] = max(0.0, km * (g - hb) + c * min((g - hb) * iramp, 1.0) * gd)
            if d < -hb:  # back flank, reported in slot 0
                out[k, i, 0] += min(0.0, mt[i, 4 * S] * (d + hb) - cm * max((d + hb) * iramp, -1.0) * dd)
    return out


def planet_runout(model: mdl.Model, t: float) -> tuple[np.ndarray, np.ndarray]:
    """Each planet's runout transmission error (m) and its rate (m/s) at time ``t``, as the kernels take them from
    their planet table (:mod:`rvdiag.dynamics.manufacturing`): ``A_i cos b_0 + B_i sin b_0``, ``b_0`` the cranks'
    eccentric angle, turning at ``-Zp Omega`` (zeros without errors, or with the time variation frozen)."""
    P = model.P
    N = model.n_planets
    if P[mdl.I_MFG] == 0.0:
        return np.zeros(N), np.zeros(N)
    cb0, sb0 = mdl.frame_angles(float(t), P)[:2]
    A, B = model.planet[:, 4], model.planet[:, 5]
    if P[mdl.I_TFROZEN] >= 0.0:
        w = 0.0
    elif P[mdl.I_PROFILE] != 0.0:
        w = -P[mdl.I_ZP] * float(_profile_speed(model, t))
    else:
        w = -P[mdl.I_ZP] * P[mdl.I_OMEGA]
    return A * cb0 + B * sb0, (B * cb0 - A * sb0) * w


def _profile_speed(model: mdl.Model, t: float) -> float:
    """The carrier's speed Omega(t) on the model's speed profile (the kernels' row ``mt[N, 0]``)."""
    mt = mdl.mesh_array(model)
    mdl.mesh_terms(float(t), model.P, model.tables, mt)
    return float(mt[model.n_planets, 0])


def static_mesh_force(model: mdl.Model) -> float:
    """Static force of one sun-planet mesh (N): the sun torque ``T_L / i`` shared by the planets on the
    base radius."""
    return abs(model.P[mdl.I_TLOAD]) / model.extra["ratio"] / (model.n_planets * model.P[mdl.I_RB1])


def quasi_static_mesh_forces(model: mdl.Model, t: np.ndarray) -> np.ndarray:
    """Mesh forces of the static solution at each time (samples, planets, slots), N: the load each mesh would
    carry at that angle at vanishing speed, with the same tooth-pair separations.  The dynamic mesh-force
    factor compares the dynamic forces with these, so that uneven load sharing between planets (pitch errors
    make one planet carry more at low load) is not counted as dynamics."""
    from rvdiag.dynamics.linear import static_equilibrium

    out = np.zeros((len(t), model.n_planets, int(model.P[mdl.I_NSLOT])))
    for k, tk in enumerate(t):
        q = static_equilibrium(model, float(tk))
        out[k] = mesh_forces(model, np.array([tk]), np.concatenate([q, np.zeros_like(q)])[None, :])[0]
    return out


def dynamic_mesh_factor(model: mdl.Model, tr: Trace, every: int = 8) -> tuple[float, float]:
    """``(factor, smallest)``: the largest ratio of a mesh's dynamic force to its quasi-static force at the same
    time (over samples ``every`` apart, where the quasi-static force exceeds 20 % of the static mean), and the
    smallest dynamic mesh force over the static mean (0: that mesh lost contact; negative: back-flank contact)."""
    F = mesh_forces(model, tr.t, tr.y).sum(axis=2)
    f0 = static_mesh_force(model)
    idx = np.arange(0, len(tr.t), max(1, int(every)))
    Fq = quasi_static_mesh_forces(model, tr.t[idx]).sum(axis=2)
    ok = Fq > 0.2 * f0
    factor = float(np.max(F[idx][ok] / Fq[ok])) if ok.any() else float("nan")
    return factor, float(F.min() / f0)
