"""The compiled (numba) kernels of the model's equations of motion and the layout of ``P`` that they read.

One purpose: evaluate the right-hand side.  The time-varying terms (:func:`mesh_terms`, :func:`pin_geometry`;
docs/model.md sections 3 and 7), the generalized forces of every spring, contact and damper
(:func:`generalized_forces`; section 3, damping section 4) and the accelerations with the rotating-frame terms
(:func:`accelerations`; section 2).  Everything comes in as flat float64 arrays (``P``, ``inv_mass``, ``planet``,
the mesh ``tables``, ``cosk``, ``sink``), so the kernels hold no global state; :mod:`rvdiag.dynamics.packing` fills
those arrays and :mod:`rvdiag.dynamics.model` wraps them; the kernels' ``tvms`` argument is ``Model.tables``.

Forces: sun-planet meshes along the line of action, one compression-only spring-damper per tooth-pair slot with
a backlash dead zone (Kahraman & Singh 1990); planet-crank spline (radial + torsional); crank-carrier and
crank-cycloid bearings (isotropic linear springs); every cycloid-pin contact (Hertz line contact stiffness
linearised at the operating load, Johnson 1985, from :mod:`rvdiag.gears.cycloid`; compression only, normal through
the pitch point: Litvin & Feng 1996; lever arm e Zc sin(eta) / sqrt(1 + K1^2 - 2 K1 cos(eta)), Blanche & Yang
1989); pin wheel and carrier supports; input shaft to the motor rotor (or an ideal speed source); load torque on
the carrier, or, with a load inertia, on the load DOF that the output coupling joins to the carrier (an elastic
joint: Spong 1987, J. Dyn. Syst. Meas. Control 109).  Rotating-frame terms ``m (u'' + 2 Omega z x u' - Omega^2 u)`` and the nominal centripetal
accelerations of orbiting bodies are included.  Viscous damping ``c = 2 zeta sqrt(k m_eq)``.

The ``I_*`` indices into ``P`` are generated here from :data:`P_FIELDS`, beside the kernels that read them: numba
freezes a global integer into the machine code at compile time and keys its cache on this file only, so the
indices must live in a kernel file.  Every kernel file is watched by :mod:`rvdiag.dynamics.numba_cache`
(docs/model.md section 7), which drops the cache of all of them when any one changes.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from rvdiag.dynamics.motor_kernel import MOTOR_P_FIELDS, air_gap_torque, motor_rates
from rvdiag.dynamics.numba_cache import guard_kernel_module

guard_kernel_module(__file__)

# ---------------------------------------------------------------------------------------- P layout
#: The entries of the flat parameter vector ``P``, in order; ``I_<NAME>`` is the index of ``<NAME>``
#: (generated below; :func:`rvdiag.dynamics.packing.pack_parameters` fills them, docs/model.md section 3).
P_FIELDS = (
    "NPL", "NDISC", "ZP", "ZC", "Z1",           # planets N, discs D, pins Zp, lobes Zc, sun teeth Z1
    "OMEGA", "WREL", "A", "E", "RP",            # carrier speed, sun's relative to it, crank circle, eccentricity,
                                                # pin circle radius
    "ALPHA", "RB1", "RB2", "HALF_BACKLASH",     # pressure angle, base radii of sun and planet, half the backlash
    "KSS", "CSS", "KIN", "CIN",                 # sun support; input shaft (torsional)
    "KCC", "CCC", "KCD", "CCD",                 # crank-carrier and crank-cycloid bearings
    "KPR", "CPR", "KPT", "CPT",                 # planet-crank spline, radial and torsional
    "KHS", "CHS", "KRH", "CRH", "KRT", "CRT",   # carrier support; pin wheel on the housing, radial and torsional
    "KPIN", "CPIN", "CMESH", "TLOAD",           # cycloid-pin contact; mean mesh damper; load torque
    "TFROZEN", "CORIOLIS", "BETA0", "DISCPHASE",  # frozen time (< 0: not frozen); rotating-frame terms on; disc angles
    "NTVMS", "SENSX", "SENSY", "NCH",           # mesh table points; sensor point; output channels
    "DISPLIM",                                  # instability: displacement limit
    "BILATERAL",                                # linearised (bilateral) contacts
    "GSHARED",                                  # 1.0: every disc sees the same pin geometry
    "SINA", "COSA",                             # sin and cos of the pressure angle
    "ROTLIM",                                   # instability: rotation limit
    "CPH", "SPH",                               # cos and sin of the disc phase
    "NSLOT",  # tooth-pair slots of each sun-planet mesh (rows of Model.tables: k, e, c per slot)
    "IRAMP",  # 1 / MESH_DAMPING_RAMP_M
    "MOTOR",  # 1.0: a motor rotor DOF (after the pin wheel; last but the load) on the input shaft, held by the speed loop
    "KSL", "CSL", "TDRIVE",  # speed-loop spring and damper on the rotor, its steady drive torque
    # speed and load profile (docs/model.md section 2; rvdiag.dynamics.profile): PROFILE 0 the constant-speed
    # model (the kernels' original path), 1 constant speed with a time-varying load, 2 a trapezoid, 3 an S-curve
    "PROFILE",
    "PR_TS", "PR_TA", "PR_TC", "PR_ACC", "PR_F0",  # trapezoid: start, accel and cruise times, accel, angle at t=0
    "PR_TJ", "PR_JERK",                         # S-curve: jerk time and jerk (PR_ACC its acceleration reached)
    "RATIO",                                    # i: sun speed / carrier speed
    "ARM_MGL", "ARM_ML2", "ARM_TH0",            # gravity arm: M g L, M L^2, its angle at t = 0
    "JREF_I",                                   # i J_ref: drive torque per unit carrier acceleration
    # manufacturing errors (rvdiag.dynamics.manufacturing; docs/model.md section 3): MFG 1.0 when the planet table
    # carries planet runout, crank-hole or crank-phase errors (its columns 4-8); PINERR the index in P where the
    # pins' errors start (0: none), PINSHIFT the pin index of disc 1's pin 0 when the discs share one geometry
    "MFG", "PINERR", "PINSHIFT",
    # the load DOF th_L (docs/model.md sections 1, 3): LOAD 1.0 when the output drives a load inertia J_L through
    # the output coupling k_out (the last coordinate, after the motor rotor's); KOUT, COUT its spring and damper
    "LOAD", "KOUT", "COUT",
    # the cycloid discs' profile modification (docs/model.md section 3; rvdiag.gears.cycloid.modification_clearance):
    # PINMOD 1.0 when modified; DRRP, DRP the equidistant and offset modifications; CLOSE the disc rotation that
    # takes up the clearance on the loaded half, as a normal displacement at unit arm (m)
    "PINMOD", "DRRP", "DRP", "CLOSE",
    # wear of the cycloid-pin stage (rvdiag.gears.pin_wear; docs/model.md section 3): PINWEAR the index in P where
    # the clearance table over cos(eta) starts (0: none; PINMOD is then 1), NPINWEAR its length
    "PINWEAR", "NPINWEAR",
    # the servo motor's electrical side (rvdiag.dynamics.motor_kernel; docs/model.md section 10), last
    *MOTOR_P_FIELDS,
)
#: ``{"NPL": 0, "NDISC": 1, ...}``: the index of each field of ``P``
P_INDEX = {name: i for i, name in enumerate(P_FIELDS)}
#: length of ``P``
N_P = len(P_FIELDS)
#: ``{"I_NPL": 0, "I_NDISC": 1, ...}``, made module globals here: plain ints that numba compiles into the kernels
#: as constants (frozen at compile time; ``tests/test_numba_cache.py`` checks it)
INDEX_CONSTANTS = {f"I_{name}": i for name, i in P_INDEX.items()}
globals().update(INDEX_CONSTANTS)

TWO_PI = 2.0 * math.pi

#: rows of the pin geometry ``geo[g, :, k]``: the contact normal (2), the lever arm about the disc centre, and the
#: modified profile's initial clearance (:func:`pin_geometry_cs`)
GEO_ROWS = 4

#: LLVM fast-math flags of the compiled kernels: reassociation (vectorised reductions), fused
#: multiply-add contraction and signed-zero freedom only.  No ``nnan``/``ninf``: the integrator's
#: instability check must still see NaN and inf.  Results stay deterministic (same code, same order).
FASTMATH = {"reassoc", "contract", "nsz"}


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def eval_time(t, P):
    """Time at which the time-varying terms are evaluated (``t``, or the frozen time)."""
    if P[I_TFROZEN] >= 0.0:
        return P[I_TFROZEN]
    return t


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def scurve_ramp(x, w, ta, tj, jerk, alim):
    """``(angle, speed, acceleration)`` at ``x`` s into the acceleration phase of the S-curve (Biagiotti &
    Melchiorri 2008, section 3.4; :class:`rvdiag.dynamics.profile.SpeedProfile`): jerk ``jerk`` for ``tj``, the
    acceleration ``alim``, jerk ``-jerk`` for the last ``tj`` of ``ta``, cruise speed ``w``."""
    if x <= 0.0:
        return 0.0, 0.0, 0.0
    if x < tj:
        return jerk * x * x * x / 6.0, 0.5 * jerk * x * x, jerk * x
    if x < ta - tj:
        return alim * (3.0 * x * x - 3.0 * tj * x + tj * tj) / 6.0, alim * (x - 0.5 * tj), alim
    if x < ta:
        u = ta - x
        return 0.5 * w * ta - w * u + jerk * u * u * u / 6.0, w - 0.5 * jerk * u * u, jerk * u
    return 0.5 * w * ta, w, 0.0


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def profile_state(te, P):
    """``(theta_H, Omega, dOmega/dt)`` of the carrier at time ``te`` on the profile path (``P[I_PROFILE] != 0``):
    constant speed (1), the trapezoid (2) or the S-curve (3) of :class:`rvdiag.dynamics.profile.SpeedProfile`, in
    closed form (docs/model.md section 2): at rest until PR_TS, accelerating at PR_ACC for PR_TA (the S-curve
    ramping its acceleration at PR_JERK for PR_TJ at either end of PR_TA), cruising at OMEGA for PR_TC,
    decelerating for PR_TA (the mirror image), at rest; theta_H(0) = 0 (PR_F0 is the angle the move has covered
    at t = 0)."""
    w = P[I_OMEGA]
    if P[I_PROFILE] == 1.0:
        return w * te, w, 0.0
    ac = P[I_PR_ACC]
    ta = P[I_PR_TA]
    tc = P[I_PR_TC]
    tau = te - P[I_PR_TS]
    if P[I_PROFILE] == 3.0:
        tj = P[I_PR_TJ]
        jk = P[I_PR_JERK]
        T = 2.0 * ta + tc
        if tau <= ta:
            F, W, A = scurve_ramp(tau, w, ta, tj, jk, ac)
        elif tau < T - ta:
            F, W, A = w * (0.5 * ta + (tau - ta)), w, 0.0
        else:
            Fd, Wd, Ad = scurve_ramp(T - tau, w, ta, tj, jk, ac)
            F, W, A = w * (ta + tc) - Fd, Wd, -Ad
        return F - P[I_PR_F0], W, A
    if tau <= 0.0:
        F, W, A = 0.0, 0.0, 0.0
    elif tau < ta:
        F, W, A = 0.5 * ac * tau * tau, ac * tau, ac
    elif tau < ta + tc:
        F, W, A = w * (0.5 * ta + (tau - ta)), w, 0.0
    elif tau < 2.0 * ta + tc:
        s = tau - ta - tc
        F, W, A = w * (0.5 * ta + tc + s) - 0.5 * ac * s * s, w - ac * s, -ac
    else:
        F, W, A = w * (ta + tc), 0.0, 0.0
    return F - P[I_PR_F0], W, A


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def pin_geometry(t, P, cosk, sink, geo, rot):
    """Normal (in each disc's eccentric frame) and lever arm of every cycloid-pin contact at time t.

    ``geo[g, 0, k], geo[g, 1, k]`` is the unit normal from the pitch point C to pin k and
    ``geo[g, 2, k] = e Zc n_y`` the lever arm about the disc centre (struct-of-arrays so the contact
    loop vectorises); ``geo[g, 3, k]`` the initial clearance of a modified profile (written only when
    ``P[I_PINMOD]`` is set; :func:`rvdiag.gears.cycloid.modification_clearance`), plus the worn stage's
    clearance growth (``P[I_PINWEAR]``, :func:`rvdiag.gears.pin_wear.pin_wear_table`); ``rot[j] = (cos b, sin b, cos B, sin B)``, ``b`` the eccentric angle of disc j in
    the carrier frame and ``B = b + Omega t`` in the fixed frame.  The pin angles relative to the
    eccentric are ``eta_k = eta_0 + 2 pi k / Zp``: one sin/cos per disc, the rest by angle addition
    with the precomputed ``cosk, sink`` (measured: the same output as per-pin sin/cos, ~10x cheaper; bench/HISTORY.md).  When the discs' phase is a whole
    number of pin pitches (``P[I_GSHARED]``; 180 deg with an even pin count) every disc sees the same
    set of pin angles, only relabelled, and one geometry ``g = 0`` serves all discs.
    """
    cb0, sb0, cw, sw = frame_angles(t, P)
    pin_geometry_cs(cb0, sb0, cw, sw, P, cosk, sink, geo, rot)


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def frame_angles(t, P):
    """``(cos b_0, sin b_0, cos W, sin W)`` at time t: b_0 = beta_0 - Zp Omega t the eccentric angle of
    disc 0 in the carrier frame, W = Omega t the carrier angle (time-varying terms frozen: at the
    frozen time)."""
    te = eval_time(t, P)
    if P[I_PROFILE] != 0.0:  # W = theta_H(t), the integrated carrier angle
        th = profile_state(te, P)[0]
        b0 = P[I_BETA0] - P[I_ZP] * th
        return math.cos(b0), math.sin(b0), math.cos(th), math.sin(th)
    Om = P[I_OMEGA]
    b0 = P[I_BETA0] - P[I_ZP] * Om * te
    return math.cos(b0), math.sin(b0), math.cos(Om * te), math.sin(Om * te)


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def frame_rotations(cb0, sb0, cw, sw, P, rot):
    """``rot[j] = (cos b_j, sin b_j, cos B_j, sin B_j)`` of every disc from the cosines and sines of
    :func:`frame_angles`: ``b_j = b_0 + j phi`` and ``B_j = b_j + Omega t`` by angle addition."""
    cph = P[I_CPH]
    sph = P[I_SPH]
    cb = cb0
    sb = sb0
    for j in range(rot.shape[0]):
        rot[j, 0] = cb
        rot[j, 1] = sb
        rot[j, 2] = cb * cw - sb * sw
        rot[j, 3] = sb * cw + cb * sw
        c = cb * cph - sb * sph
        sb = sb * cph + cb * sph
        cb = c


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def pin_geometry_cs(cb0, sb0, cw, sw, P, cosk, sink, geo, rot):
    """:func:`pin_geometry` from the cosines and sines of :func:`frame_angles` (no trigonometry:
    the integrator advances them by rotation within an output sample)."""
    Zp = P[I_ZP]
    Zc = P[I_ZC]
    e = P[I_E]
    Rp = P[I_RP]
    eZp = e * Zp
    eZc = e * Zc
    K1 = eZp / Rp
    nz = cosk.size
    frame_rotations(cb0, sb0, cw, sw, P, rot)
    ng = 1 if P[I_GSHARED] != 0.0 else rot.shape[0]
    for j in range(ng):
        # eta_0 = Zc Omega t - beta0 - j phi = -B_j
        c0 = rot[j, 2]
        s0 = -rot[j, 3]
        for k in range(nz):
            dx = Rp * (c0 * cosk[k] - s0 * sink[k]) - eZp
            dy = Rp * (s0 * cosk[k] + c0 * sink[k])
            inv = 1.0 / math.sqrt(dx * dx + dy * dy)
            geo[j, 0, k] = dx * inv
            geo[j, 1, k] = dy * inv
            geo[j, 2, k] = eZc * dy * inv
    # the modified profile's clearance (rvdiag.gears.cycloid.modification_clearance), in a loop of its own: folded
    # into the loop above (a branch per pin), the normals of unmodified discs compiled to other last bits (measured)
    if P[I_PINMOD] != 0.0:
        drrp = P[I_DRRP]
        drp = P[I_DRP]
        close = P[I_CLOSE]
        for j in range(ng):
            c0 = rot[j, 2]
            s0 = -rot[j, 3]
            for k in range(nz):
                ce = c0 * cosk[k] - s0 * sink[k]
                se = s0 * cosk[k] + c0 * sink[k]
                inv_s = 1.0 / math.sqrt(1.0 + K1 * K1 - 2.0 * K1 * ce)
                geo[j, 3, k] = drrp - (drp * (1.0 - K1 * ce) + close * se) * inv_s
    # the worn stage's clearance growth, a table over cos(eta) (rvdiag.gears.pin_wear.pin_wear_table), linearly
    # interpolated; in a loop of its own, so that an unworn stage runs the code before it
    if P[I_PINWEAR] != 0.0:
        w0 = int(P[I_PINWEAR])
        half = 0.5 * (P[I_NPINWEAR] - 1.0)
        last = int(P[I_NPINWEAR]) - 2
        for j in range(ng):
            c0 = rot[j, 2]
            s0 = -rot[j, 3]
            for k in range(nz):
                x = (c0 * cosk[k] - s0 * sink[k] + 1.0) * half
                i = min(max(int(x), 0), last)
                f = x - i
                geo[j, 3, k] += P[w0 + i] + f * (P[w0 + i + 1] - P[w0 + i])


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def interpolate_geometry(g0, gm, g1, s, P, out):
    """Pin geometry at a fraction ``s`` of an output sample: the quadratic through the exact geometries
    ``g0, gm, g1`` at the sample's start, middle and end (Lagrange, nodes 0, 1/2, 1; only the used
    geometries: one when ``P[I_GSHARED]``).

    The pin angles advance by ``(Zp - 1) Omega / fs`` per sample (1e-3 rad at 1000 rpm), so the
    interpolation error is ~7e-10 of the unit normals at 1000 rpm and 3e-8 at 3000 rpm, against 1e-6
    and 1e-5 for linear interpolation.  Linear is not enough: the pin forces carry the whole output
    torque while the vibration is a small part of them, so 1e-6 in the normals moved the output by 1e-4
    (bench/HISTORY.md 2026-11-23, "slice-free kernels").  An exact evaluation costs 40 square roots
    per stage time (72 ns); this costs two per sample.
    """
    c0 = 2.0 * (s - 0.5) * (s - 1.0)
    cm = -4.0 * s * (s - 1.0)
    c1 = 2.0 * s * (s - 0.5)
    ng = 1 if P[I_GSHARED] != 0.0 else g0.shape[0]
    nz = g0.shape[2]
    nr = 4 if P[I_PINMOD] != 0.0 else 3  # the clearance row only where the profile is modified
    for j in range(ng):
        for r in range(nr):
            for k in range(nz):
                out[j, r, k] = c0 * g0[j, r, k] + cm * gm[j, r, k] + c1 * g1[j, r, k]


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def mesh_terms(t, P, tvms, mt):
    """Stiffness, separation and damping of every tooth-pair slot of every sun-planet mesh at time t (they
    depend on time only).

    ``mt[i, 4 s + (0, 1, 2, 3)] = (k, e, e', c)`` of slot s of planet i's mesh: the pair stiffness (N/m),
    separation (m), the separation's rate ``de/dt = w_rel de/dphi`` (from the node slopes of
    :func:`separation_slopes`; 0 when the time-varying terms are frozen) and the pair's damping coefficient,
    linearly interpolated in ``tvms`` (``Model.tables``, rows ``k, e, c, e'`` per slot, then the nominal
    TVMS) at the sun angle relative to planet i,
    ``phi = w_rel t - 2 pi i / N``; ``mt[i, 4 S]`` and ``mt[i, 4 S + 1]`` are the nominal TVMS and the
    load-shared separation (bilateral model).  With a speed or load profile (``P[I_PROFILE] != 0``) the phase is
    ``(i - 1) theta_H(t) - 2 pi i / N`` and the rate ``(i - 1) Omega(t)``, and the extra row ``mt[N]`` holds
    ``(Omega, dOmega/dt, T_L, drive torque)`` at t (:func:`profile_state`).  Computed once per
    distinct stage time by the integrator and shared by the stages that use it.
    """
    te = eval_time(t, P)
    N = int(P[I_NPL])
    nt = tvms.shape[1]
    if P[I_PROFILE] != 0.0:  # the sun's angle relative to the carrier is (i - 1) theta_H(t), its rate (i - 1) Omega(t)
        th, W, A = profile_state(te, P)
        x0 = (P[I_RATIO] - 1.0) * th * (1.0 / TWO_PI)
        erate = (P[I_RATIO] - 1.0) * W * nt * (1.0 / TWO_PI) if P[I_TFROZEN] < 0.0 else 0.0
        # row N: the profile's time terms Omega, dOmega/dt, T_L(t) and the drive torque T_L / i + i J_ref dOmega/dt
        tl = P[I_TLOAD] + P[I_ARM_MGL] * math.cos(P[I_ARM_TH0] + th) + P[I_ARM_ML2] * A
        mt[N, 0] = W
        mt[N, 1] = A
        mt[N, 2] = tl
        mt[N, 3] = tl / P[I_RATIO] + P[I_JREF_I] * A
        if P[I_PMSM] != 0.0:  # the rotor's nominal angle and speed, for the motor's electrical side
            mt[N, 4] = P[I_RATIO] * th
            mt[N, 5] = P[I_RATIO] * W
        _mesh_interpolate(x0, erate, N, P, tvms, mt)
        return
    if P[I_PMSM] != 0.0:
        mt[N, 4] = P[I_RATIO] * P[I_OMEGA] * te
        mt[N, 5] = P[I_RATIO] * P[I_OMEGA]
    x0 = P[I_WREL] * te * (1.0 / TWO_PI)
    erate = P[I_WREL] * nt * (1.0 / TWO_PI) if P[I_TFROZEN] < 0.0 else 0.0
    _mesh_interpolate(x0, erate, N, P, tvms, mt)


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _mesh_interpolate(x0, erate, N, P, tvms, mt):
    """The table lookup of :func:`mesh_terms` at relative sun phase ``x0`` (revolutions) and table rate
    ``erate`` (nodes per second)."""
    S = int(P[I_NSLOT])
    nt = tvms.shape[1]
    inv_n = 1.0 / N
    for i in range(N):
        x = x0 - i * inv_n
        x = (x - math.floor(x)) * nt
        j0 = int(x)
        fr = x - j0
        if j0 >= nt:
            j0 = 0
        j1 = j0 + 1
        if j1 >= nt:
            j1 = 0
        for sl in range(S):
            mt[i, 4 * sl] = tvms[sl, j0] + fr * (tvms[sl, j1] - tvms[sl, j0])
            mt[i, 4 * sl + 1] = tvms[S + sl, j0] + fr * (tvms[S + sl, j1] - tvms[S + sl, j0])
            mt[i, 4 * sl + 2] = erate * (tvms[3 * S + sl, j0] + fr * (tvms[3 * S + sl, j1] - tvms[3 * S + sl, j0]))
            mt[i, 4 * sl + 3] = tvms[2 * S + sl, j0] + fr * (tvms[2 * S + sl, j1] - tvms[2 * S + sl, j0])
        mt[i, 4 * S] = tvms[4 * S, j0] + fr * (tvms[4 * S, j1] - tvms[4 * S, j0])
        mt[i, 4 * S + 1] = tvms[4 * S + 1, j0] + fr * (tvms[4 * S + 1, j1] - tvms[4 * S + 1, j0])


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _pin_sums(geo, g, ux, uy, th, wx, wy, om, kp, cp, dlim, flo, clear):
    """Sums of F n_x, F n_y and F l over the pins of one disc, F = max(k d + c d', flo) where d > dlim,
    else 0; with ``clear`` (a constant at each call) the approach d is less the modified profile's clearance
    ``geo[g, 3, k]``.

    ``geo[g, 0..2, k]`` is pin k's normal and lever arm (:func:`pin_geometry`); ``dlim`` and ``flo`` are 0
    for compression-only contacts whose damper never pulls (Modelica ElastoBacklash: the contact force is
    zero when spring + damper <= 0) and -inf for the bilateral check.  The sums are plain reductions that the
    kernels' ``reassoc`` fast-math flag lets LLVM vectorise; the order is fixed by the compiled code, so
    results are deterministic.
    """
    sx = sy = sm = 0.0
    for k in range(geo.shape[2]):
        nx = geo[g, 0, k]
        ny = geo[g, 1, k]
        lk = geo[g, 2, k]
        d = ux * nx + uy * ny + th * lk
        if clear:
            d -= geo[g, 3, k]
        f = max(kp * d + cp * (wx * nx + wy * ny + om * lk), flo)
        f = f if d > dlim else 0.0
        sx += f * nx
        sy += f * ny
        sm += f * lk
    return sx, sy, sm


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _pin_sums_pair(geo, ux, uy, th, wx, wy, om, vx, vy, ph, zx, zy, ps, kp, cp, dlim, flo, clear):
    """:func:`_pin_sums` for two discs that share pin geometry 0, in one fused pass (one load of the
    geometry for both discs)."""
    s0x = s0y = s0m = s1x = s1y = s1m = 0.0
    for k in range(geo.shape[2]):
        nx = geo[0, 0, k]
        ny = geo[0, 1, k]
        lk = geo[0, 2, k]
        d = ux * nx + uy * ny + th * lk
        d2 = vx * nx + vy * ny + ph * lk
        if clear:
            d -= geo[0, 3, k]
            d2 -= geo[0, 3, k]
        f = max(kp * d + cp * (wx * nx + wy * ny + om * lk), flo)
        f = f if d > dlim else 0.0
        f2 = max(kp * d2 + cp * (zx * nx + zy * ny + ps * lk), flo)
        f2 = f2 if d2 > dlim else 0.0
        s0x += f * nx
        s0y += f * ny
        s0m += f * lk
        s1x += f2 * nx
        s1y += f2 * ny
        s1m += f2 * lk
    return s0x, s0y, s0m, s1x, s1y, s1m


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _pin_sums_err(geo, g, ux, uy, th, wx, wy, om, kp, cp, dlim, flo, P, pb, nz, h, cB, sB):
    """:func:`_pin_sums` with the pins' manufacturing errors (:mod:`rvdiag.dynamics.manufacturing`; Blanche & Yang
    1989): geometry index k is pin ``m = k + h``, whose radius error ``rho_m`` and groove position error ``v_m``
    (fixed frame) compress the contact by ``rho_m - (R(-B) v_m) . n_k`` more (``cB, sB`` the cosine and sine of the
    disc's eccentric angle B in the fixed frame), and less the modified profile's clearance ``geo[g, 3, k]`` (0 for
    unmodified discs).  ``P[pb:]`` holds ``rho``, ``v_x``, ``v_y``, each twice over
    (``2 Zp`` values), so ``k + h`` needs no wrap.  The pins stand still, so the rate is unchanged."""
    sx = sy = sm = 0.0
    bx = pb + 2 * nz
    by = pb + 4 * nz
    for k in range(nz):
        nx = geo[g, 0, k]
        ny = geo[g, 1, k]
        lk = geo[g, 2, k]
        m = k + h
        vx = P[bx + m]
        vy = P[by + m]
        o = P[pb + m] - ((cB * vx + sB * vy) * nx + (cB * vy - sB * vx) * ny)
        d = ux * nx + uy * ny + th * lk + o - geo[g, 3, k]
        f = max(kp * d + cp * (wx * nx + wy * ny + om * lk), flo)
        f = f if d > dlim else 0.0
        sx += f * nx
        sy += f * ny
        sm += f * lk
    return sx, sy, sm


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def generalized_forces(y, P, planet, mt, geo, rot, Q):
    """Generalized forces Q(t, q, v) of all springs, contacts, dampers and the external torques
    (:func:`_generalized_forces`): a model without manufacturing errors runs a copy compiled without their terms,
    so that its arithmetic, and its output to the last bit, is that of the model before them."""
    if P[I_MFG] != 0.0 or P[I_PINERR] != 0.0 or P[I_PINMOD] != 0.0:
        _generalized_forces(y, P, planet, mt, geo, rot, Q, True)
    else:
        _generalized_forces(y, P, planet, mt, geo, rot, Q, False)


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _generalized_forces(y, P, planet, mt, geo, rot, Q, errors):
    """Generalized forces Q(t, q, v) of all springs, contacts, dampers and the external torques; ``errors``
    (a constant at each call) compiles the manufacturing errors' terms in or out.

    ``y = [q, v]`` (the first-order state; ``Q`` has ``n = y.size / 2`` entries).  ``mt`` must hold
    :func:`mesh_terms` and ``geo, rot`` :func:`pin_geometry` at the same ``t``.  The equations are in
    docs/model.md.  Each sun-planet mesh force is ``k g(delta - e) + c (delta' - e')`` with the
    deviation ``e`` (transmission-error excitation, Kahraman & Singh 1990).

    Manufacturing errors (:mod:`rvdiag.dynamics.manufacturing`; docs/model.md section 3), only when ``P[I_MFG]``
    / ``P[I_PINERR]`` are set, so that a model without them runs the original code: ``planet[i, 4:6] = (A_i,
    B_i)`` the runout's transmission error ``r_i = A_i cos b_0 + B_i sin b_0`` (``b_0`` the cranks' eccentric
    angle, ``rot[0]``; its rate ``-Zp Omega`` times the derivative), lost by mesh i's approach; ``planet[i, 6:8]``
    the crank hole's position error (radial, tangential) in the crank-carrier bearing; ``planet[i, 8]`` the crank's
    eccentric angle error in the crank-cycloid bearings; and the pins' errors in :func:`_pin_sums_err`.

    Written for speed (bench/HISTORY.md 2026-11-23, "slice-free force kernels": 271 -> 173 ns with the
    changes of that entry): no array views, the forces of the sun, planets, cranks, carrier and pin wheel
    are summed in local variables and stored once, and only the discs' are accumulated in ``Q``.
    """
    # the masks are no-ops that let LLVM prove every index below non-negative (no wraparound code)
    N = int(P[I_NPL]) & 255
    D = int(P[I_NDISC]) & 255
    n = Q.size & 65535
    iC0 = 3 + 3 * N
    iD0 = 3 + 6 * N
    iH = iD0 + 3 * D
    iR = iH + 3
    a = P[I_A]
    e = P[I_E]
    for i in range(iD0, iH):
        Q[i] = 0.0
    # ---- sun: support and input coupling (motor at constant speed), th_s relative to the motor angle
    kss = P[I_KSS]
    css = P[I_CSS]
    S0 = -(kss * y[0] + css * y[n])
    S1 = -(kss * y[1] + css * y[n + 1])
    mot = P[I_MOTOR] != 0.0
    ld = P[I_LOAD] != 0.0
    iM = iR + 3  # the motor rotor, after the pin wheel; the load DOF after it (docs/model.md section 1)
    qm = y[iM] if mot else 0.0
    vm = y[n + iM] if mot else 0.0
    # input shaft between the motor rotor (or the ideal speed source) and the sun
    T_sh = P[I_KIN] * (y[2] - qm) + P[I_CIN] * (y[n + 2] - vm)
    S2 = -T_sh
    prof = P[I_PROFILE] != 0.0
    mfg = errors and P[I_MFG] != 0.0
    if mfg:  # the planets turn with the cranks' eccentrics: angle b_0 (disc 0's eccentric), rate -Zp Omega
        cr0 = rot[0, 0]
        sr0 = rot[0, 1]
        wb = 0.0 if P[I_TFROZEN] >= 0.0 else -P[I_ZP] * (mt[N, 0] if prof else P[I_OMEGA])
    if mot and P[I_PMSM] != 0.0 and y.size > 2 * n:  # the PMSM's air-gap torque and friction on the rotor
        Q[iM] = (air_gap_torque(P, I_PMSM, y[2 * n], y[2 * n + 1]) - P[I_M_B] * (mt[N, 5] + vm) + T_sh)
    elif mot:  # the rotor: drive torque, speed loop, and the shaft's reaction
        Q[iM] = (mt[N, 3] if prof else P[I_TDRIVE]) - P[I_KSL] * qm - P[I_CSL] * vm + T_sh
    # ---- carrier: support, load torque
    qH0 = y[iH]
    qH1 = y[iH + 1]
    qH2 = y[iH + 2]
    vH0 = y[n + iH]
    vH1 = y[n + iH + 1]
    vH2 = y[n + iH + 2]
    H0 = -(P[I_KHS] * qH0 + P[I_CHS] * vH0)
    H1 = -(P[I_KHS] * qH1 + P[I_CHS] * vH1)
    if ld:  # the output coupling to the load DOF, which carries the load torque (Spong 1987's elastic joint)
        iL = n - 1
        T_out = P[I_KOUT] * (qH2 - y[iL]) + P[I_COUT] * (vH2 - y[n + iL])
        H2 = -T_out
        Q[iL] = T_out - (mt[N, 2] if prof else P[I_TLOAD])
    else:
        H2 = -(mt[N, 2] if prof else P[I_TLOAD])
    # ---- pin wheel on the housing (fixed frame)
    R0 = -(P[I_KRH] * y[iR] + P[I_CRH] * y[n + iR])
    R1 = -(P[I_KRH] * y[iR + 1] + P[I_CRH] * y[n + iR + 1])
    R2 = -(P[I_KRT] * y[iR + 2] + P[I_CRT] * y[n + iR + 2])
    # ---- sun-planet meshes, planet-crank splines, crank bearings
    sa = P[I_SINA]
    ca = P[I_COSA]
    kpr = P[I_KPR]
    cpr = P[I_CPR]
    kpt = P[I_KPT]
    cpt = P[I_CPT]
    kcc = P[I_KCC]
    ccc = P[I_CCC]
    kcd = P[I_KCD]
    ccd = P[I_CCD]
    rb1 = P[I_RB1]
    rb2 = P[I_RB2]
    hb = P[I_HALF_BACKLASH]
    S = int(P[I_NSLOT]) & 255
    iramp = P[I_IRAMP]
    cm = P[I_CMESH]
    bil = P[I_BILATERAL]
    for i in range(N):
        ip = 3 + 3 * i
        ic = iC0 + 3 * i
        cps = planet[i, 0]
        sps = planet[i, 1]
        sap = planet[i, 2]
        cap = planet[i, 3]
        qp0 = y[ip]
        qp1 = y[ip + 1]
        qp2 = y[ip + 2]
        vp0 = y[n + ip]
        vp1 = y[n + ip + 1]
        vp2 = y[n + ip + 2]
        qc0 = y[ic]
        qc1 = y[ic + 1]
        qc2 = y[ic + 2]
        vc0 = y[n + ic]
        vc1 = y[n + ic + 1]
        vc2 = y[n + ic + 2]
        # mesh approach along the line of action; each tooth pair s touches once it exceeds the pair's
        # separation e_s (relief, errors, wear) plus half the backlash, and then pushes, never pulls:
        # F_s = max(0, k_s (d - e_s - b) + c_s (d' - e_s')) (Modelica ElastoBacklash; docs/model.md); the back
        # flanks meet at d < -b with the nominal TVMS and the mean mesh damper
        d = y[0] * sap + y[1] * cap + rb1 * y[2] - qp0 * sa - qp1 * ca + rb2 * qp2
        dd = y[n] * sap + y[n + 1] * cap + rb1 * y[n + 2] - vp0 * sa - vp1 * ca + rb2 * vp2
        if mfg:  # the planet's runout: a transmission error once per planet revolution (Inalpolat & Kahraman 2009)
            ra = planet[i, 4]
            rb = planet[i, 5]
            d -= ra * cr0 + rb * sr0
            dd -= (rb * cr0 - ra * sr0) * wb
        F = 0.0
        if bil != 0.0:  # linearised: nominal TVMS, load-shared separation (bilateral start and modal analysis)
            F = mt[i, 4 * S] * (d - mt[i, 4 * S + 1] - bil * hb)
        for sl in range(S):
            if bil != 0.0:
                break
            km = mt[i, 4 * sl]
            g = d - mt[i, 4 * sl + 1]
            gd = dd - mt[i, 4 * sl + 2]
            cs = mt[i, 4 * sl + 3]
            if g > hb:
                x = g - hb
                f = km * x + cs * min(x * iramp, 1.0) * gd
                if f > 0.0:
                    F += f
        if bil == 0.0 and d < -hb:  # back flank: the nominal TVMS, no relief (that is on the drive flank)
            x = d + hb
            f = mt[i, 4 * S] * x - cm * max(x * iramp, -1.0) * dd
            if f < 0.0:
                F += f
        S0 -= F * sap
        S1 -= F * cap
        S2 -= F * rb1
        # planet-crank spline (radial and torsional), both in the orbiting frame
        fr0 = kpr * (qp0 - qc0) + cpr * (vp0 - vc0)
        fr1 = kpr * (qp1 - qc1) + cpr * (vp1 - vc1)
        ft = kpt * (qp2 - qc2) + cpt * (vp2 - vc2)
        Q[ip] = F * sa - fr0
        Q[ip + 1] = F * ca - fr1
        Q[ip + 2] = -F * rb2 - ft
        # crank-carrier bearing: d = u_c - R^T u_H - a th_H e_t (orbiting frame)
        dx = qc0 - (cps * qH0 + sps * qH1)
        dy = qc1 - (-sps * qH0 + cps * qH1) - a * qH2
        qe2 = qc2
        if mfg:  # the crank hole's position error (radial, tangential), the crank's eccentric angle error
            dx -= planet[i, 6]
            dy -= planet[i, 7]
            qe2 = qc2 + planet[i, 8]
        vx = vc0 - (cps * vH0 + sps * vH1)
        vy = vc1 - (-sps * vH0 + cps * vH1) - a * vH2
        fx = kcc * dx + ccc * vx
        fy = kcc * dy + ccc * vy
        C0 = fr0 - fx
        C1 = fr1 - fy
        C2 = ft
        H0 += cps * fx - sps * fy
        H1 += sps * fx + cps * fy
        H2 += a * fy
        # crank-cycloid bearings (carrier frame): d = R u_c + th_c e t_j - u_d - th_d a e_t(psi)
        ucx = cps * qc0 - sps * qc1
        ucy = sps * qc0 + cps * qc1
        vcx = cps * vc0 - sps * vc1
        vcy = sps * vc0 + cps * vc1
        asp = a * sps
        acp = a * cps
        for jd in range(D):
            idd = iD0 + 3 * jd
            tx = -e * rot[jd, 1]
            ty = e * rot[jd, 0]
            qd2 = y[idd + 2]
            vd2 = y[n + idd + 2]
            dx = ucx + qe2 * tx - y[idd] + qd2 * asp
            dy = ucy + qe2 * ty - y[idd + 1] - qd2 * acp
            vx = vcx + vc2 * tx - y[n + idd] + vd2 * asp
            vy = vcy + vc2 * ty - y[n + idd + 1] - vd2 * acp
            fx = kcd * dx + ccd * vx
            fy = kcd * dy + ccd * vy
            C0 -= cps * fx + sps * fy
            C1 -= -sps * fx + cps * fy
            C2 -= tx * fx + ty * fy
            Q[idd] += fx
            Q[idd + 1] += fy
            Q[idd + 2] += asp * -fx + acp * fy
        Q[ic] = C0
        Q[ic + 1] = C1
        Q[ic + 2] = C2
    # ---- cycloid-pin contacts, in each disc's eccentric frame
    kp = P[I_KPIN]
    cp = P[I_CPIN]
    rr = P[I_ZP] / P[I_ZC]
    dlim = -np.inf if bil != 0.0 else 0.0
    gsh = P[I_GSHARED] != 0.0
    qR0 = y[iR]
    qR1 = y[iR + 1]
    qR2 = y[iR + 2]
    vR0 = y[n + iR]
    vR1 = y[n + iR + 1]
    vR2 = y[n + iR + 2]
    pb = (int(P[I_PINERR]) & 1048575) if errors else 0  # the pins' errors in P from here (0: none)
    clear = errors and P[I_PINMOD] != 0.0  # the discs' profile modification: each pin's initial clearance
    nz = geo.shape[2] & 65535
    jd = 0
    while jd < D:
        a0, a1, a2, a3, a4, a5 = _disc_frame(jd, y, n, rot, iD0, qR0, qR1, qR2, vR0, vR1, vR2, rr)
        if gsh and jd + 1 < D:
            b0, b1, b2, b3, b4, b5 = _disc_frame(jd + 1, y, n, rot, iD0, qR0, qR1, qR2, vR0, vR1, vR2, rr)
            if pb != 0:  # geometry index k is pin k + jd PINSHIFT of disc jd (mod Zp)
                h0 = (jd * int(P[I_PINSHIFT])) % nz
                h1 = ((jd + 1) * int(P[I_PINSHIFT])) % nz
                s0x, s0y, s0m = _pin_sums_err(geo, 0, a0, a1, a2, a3, a4, a5, kp, cp, dlim, dlim, P, pb, nz, h0,
                                              rot[jd, 2], rot[jd, 3])
                s1x, s1y, s1m = _pin_sums_err(geo, 0, b0, b1, b2, b3, b4, b5, kp, cp, dlim, dlim, P, pb, nz, h1,
                                              rot[jd + 1, 2], rot[jd + 1, 3])
            else:
                s0x, s0y, s0m, s1x, s1y, s1m = _pin_sums_pair(
                    geo, a0, a1, a2, a3, a4, a5, b0, b1, b2, b3, b4, b5, kp, cp, dlim, dlim, clear)
            r0, r1, r2 = _apply_pin_sums(jd, s0x, s0y, s0m, iD0, rr, rot, Q)
            R0 += r0
            R1 += r1
            R2 += r2
            r0, r1, r2 = _apply_pin_sums(jd + 1, s1x, s1y, s1m, iD0, rr, rot, Q)
            jd += 2
        elif pb != 0:
            h0 = (jd * int(P[I_PINSHIFT])) % nz if gsh else 0
            sx, sy, sm = _pin_sums_err(geo, 0 if gsh else jd, a0, a1, a2, a3, a4, a5, kp, cp, dlim, dlim, P, pb, nz,
                                       h0, rot[jd, 2], rot[jd, 3])
            r0, r1, r2 = _apply_pin_sums(jd, sx, sy, sm, iD0, rr, rot, Q)
            jd += 1
        else:
            sx, sy, sm = _pin_sums(geo, 0 if gsh else jd, a0, a1, a2, a3, a4, a5, kp, cp, dlim, dlim, clear)
            r0, r1, r2 = _apply_pin_sums(jd, sx, sy, sm, iD0, rr, rot, Q)
            jd += 1
        R0 += r0
        R1 += r1
        R2 += r2
    Q[0] = S0
    Q[1] = S1
    Q[2] = S2
    Q[iH] = H0
    Q[iH + 1] = H1
    Q[iH + 2] = H2
    Q[iR] = R0
    Q[iR + 1] = R1
    Q[iR + 2] = R2


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _disc_frame(jd, y, n, rot, iD0, qR0, qR1, qR2, vR0, vR1, vR2, rr):
    """Disc-minus-pin-wheel displacement, rotation and their rates in disc jd's eccentric frame."""
    idd = iD0 + 3 * jd
    cb = rot[jd, 0]
    sb = rot[jd, 1]
    cB = rot[jd, 2]
    sB = rot[jd, 3]
    ux = cb * y[idd] + sb * y[idd + 1] - (cB * qR0 + sB * qR1)
    uy = -sb * y[idd] + cb * y[idd + 1] - (-sB * qR0 + cB * qR1)
    th = y[idd + 2] - rr * qR2
    wx = cb * y[n + idd] + sb * y[n + idd + 1] - (cB * vR0 + sB * vR1)
    wy = -sb * y[n + idd] + cb * y[n + idd + 1] - (-sB * vR0 + cB * vR1)
    om = y[n + idd + 2] - rr * vR2
    return ux, uy, th, wx, wy, om


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _apply_pin_sums(jd, sx, sy, sm, iD0, rr, rot, Q):
    """Disc jd gets -sum F n and -sum F l; returns the pin wheel's +sum F n and +sum F l Zp/Zc (rotated
    back to the fixed frame)."""
    idd = iD0 + 3 * jd
    cb = rot[jd, 0]
    sb = rot[jd, 1]
    cB = rot[jd, 2]
    sB = rot[jd, 3]
    Q[idd] -= cb * sx - sb * sy
    Q[idd + 1] -= sb * sx + cb * sy
    Q[idd + 2] -= sm
    return cB * sx - sB * sy, sB * sx + cB * sy, rr * sm


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def accelerations(y, P, inv_mass, planet, mt, geo, rot, Q, dydt):
    """``dydt[n:] = M^-1 (Q + rotating-frame and nominal inertial terms)`` (``inv_mass`` = diag M^-1), the second-order equations
    (``y = [q, v]``; the time-varying terms come in through ``mt``, ``geo`` and ``rot``)."""
    generalized_forces(y, P, planet, mt, geo, rot, Q)
    N = int(P[I_NPL]) & 255
    D = int(P[I_NDISC]) & 255
    n = Q.size & 65535
    iR = 6 + 6 * N + 3 * D
    prof = P[I_PROFILE] != 0.0
    Om = mt[N, 0] if prof else P[I_OMEGA]
    for i in range(n):
        dydt[n + i] = Q[i] * inv_mass[i]
    # nominal centripetal accelerations of orbiting bodies (moved to the right-hand side)
    oa = Om * Om * P[I_A]
    for i in range(N):
        dydt[n + 3 + 3 * i] += oa
        dydt[n + 3 + 3 * N + 3 * i] += oa
    iD0 = 3 + 6 * N
    wz = P[I_ZC] * Om
    ue = P[I_E] * wz * wz
    for jd in range(D):
        idd = n + iD0 + 3 * jd
        dydt[idd] += ue * rot[jd, 0]
        dydt[idd + 1] += ue * rot[jd, 1]
    if P[I_CORIOLIS] != 0.0:
        O2 = Om * Om
        tO = 2.0 * Om
        for b in range(iR // 3):
            i = 3 * b
            dydt[n + i] += tO * y[n + i + 1] + O2 * y[i]
            dydt[n + i + 1] += -tO * y[n + i] + O2 * y[i + 1]
    if prof:
        _euler_terms(y, P, mt, rot, dydt, N, D, n, iR)


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _euler_terms(y, P, mt, rot, dydt, N, D, n, iR):
    """The terms of an accelerating carrier (dOmega/dt = ``mt[N, 1]``; docs/model.md section 2): the tangential
    parts of the nominal accelerations of the orbiting bodies' origins (planets and cranks a dOmega/dt, discs
    e Zc dOmega/dt e_t(beta_j)), the nominal angular accelerations of every body (sun and rotor i, planets and
    cranks -Zc, discs, carrier and load 1, times dOmega/dt), and the Euler term -dOmega/dt z x u of the rotating frame
    (with the Coriolis terms)."""
    dO = mt[N, 1]
    if dO == 0.0:
        return
    ad = P[I_A] * dO
    zd = P[I_ZC] * dO
    for i in range(N):
        dydt[n + 4 + 3 * i] -= ad
        dydt[n + 4 + 3 * N + 3 * i] -= ad
        dydt[n + 5 + 3 * i] += zd
        dydt[n + 5 + 3 * N + 3 * i] += zd
    ez = P[I_E] * zd
    iD0 = 3 + 6 * N
    for jd in range(D):
        idd = n + iD0 + 3 * jd
        dydt[idd] -= ez * rot[jd, 1]
        dydt[idd + 1] += ez * rot[jd, 0]
        dydt[idd + 2] -= dO
    ri = P[I_RATIO] * dO
    dydt[n + 2] -= ri
    dydt[n + iR - 1] -= dO
    if P[I_MOTOR] != 0.0:
        dydt[n + iR + 3] -= ri
    if P[I_LOAD] != 0.0:  # the load turns with the carrier
        dydt[2 * n - 1] -= dO
    if P[I_CORIOLIS] != 0.0:
        for b in range(iR // 3):
            i = 3 * b
            dydt[n + i] += dO * y[i + 1]
            dydt[n + i + 1] -= dO * y[i]


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def speed_loop_feed_forward(P, mt):
    """The speed PI's feed-forward torque on the rotor with the motor's electrical side on (N m): the steady drive
    torque ``T_L / i`` (or the profile's, with its acceleration term, ``mt[N, 3]``) plus the rotor's viscous
    friction at its nominal speed ``mt[N, 5]`` (:mod:`rvdiag.dynamics.motor_kernel`)."""
    N = int(P[I_NPL]) & 255
    return (mt[N, 3] if P[I_PROFILE] != 0.0 else P[I_TDRIVE]) + P[I_M_B] * mt[N, 5]


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def rhs_with_terms(y, P, inv_mass, planet, mt, geo, rot, Q, dydt):
    """First-order right-hand side dy/dt, y = [q, v] (and the motor's electrical states after them when
    ``P[I_PMSM]`` is on, :mod:`rvdiag.dynamics.motor_kernel`), from the time-varying terms precomputed at the
    stage time (:func:`mesh_terms`, :func:`pin_geometry`); ``inv_mass`` is ``Model.inv_mass``."""
    n = Q.size & 65535
    for i in range(n):
        dydt[i] = y[n + i]
    accelerations(y, P, inv_mass, planet, mt, geo, rot, Q, dydt)
    if P[I_PMSM] != 0.0 and y.size > 2 * n:
        N = int(P[I_NPL]) & 255
        im = n - 2 if P[I_LOAD] != 0.0 else n - 1  # the rotor (the load DOF, when there, comes after it)
        motor_rates(y, P, I_PMSM, n, im, mt[N, 4], mt[N, 5], speed_loop_feed_forward(P, mt), P[I_KSL], P[I_CSL], dydt)


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def rhs(t, y, P, inv_mass, planet, tvms, cosk, sink, geo, rot, mt, Q, dydt):
    """First-order right-hand side dy/dt computing the time-varying terms itself (for scipy and checks)."""
    pin_geometry(t, P, cosk, sink, geo, rot)
    mesh_terms(t, P, tvms, mt)
    rhs_with_terms(y, P, inv_mass, planet, mt, geo, rot, Q, dydt)


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def _forces_at(t, y, P, planet, tvms, cosk, sink, geo, rot, mt, Q):
    """:func:`generalized_forces` at time t, the time-varying terms computed here (for
    :func:`rvdiag.dynamics.model.forces`)."""
    pin_geometry(t, P, cosk, sink, geo, rot)
    mesh_terms(t, P, tvms, mt)
    generalized_forces(y, P, planet, mt, geo, rot, Q)
