"""Fixed-step RK4 integration of the RV-reducer model, compiled with numba, streamed in chunks.

The classical fourth-order Runge-Kutta method (Hairer, Norsett & Wanner, *Solving ODEs I*, 1993,
section II.1) advances ``substeps`` steps of ``h = 1 / (fs substeps)`` per output sample
(``ModelSettings(method="rk38")``: Kutta's 3/8 rule instead, :func:`rk38_run`).  Both cut a sample
at the kinks of the mesh table that fall inside it (:func:`sample_breaks`, :func:`step_grid`; the kinks,
``Model.events``, are known in advance because the mesh terms depend on time only), so no step straddles
a stiffness ramp: 6.0e-4 instead of 8.6e-4 against scipy at 9 sub-steps, and the 1e-3 criterion holds up
to 4500 rpm instead of ~2500 (bench/HISTORY.md 2026-11-23).

What depends on time only is computed once per distinct stage time and shared by the stages: the mesh
stiffness and profile deviation of each sun-planet mesh (:func:`rvdiag.dynamics.kernels.mesh_terms`), the
frame rotations (rotated by half-step increments from exact values at each sample's start;
by angle addition) and the cycloid-pin geometry.  RK4 takes the geometry exactly at each sample's
start, middle and end and interpolates it quadratically at the inner stage times
(:func:`rvdiag.dynamics.kernels.interpolate_geometry`; output change 1e-8 to 2e-7 relative against the
exact geometry at every stage); the 3/8 rule evaluates it exactly at every stage time.

The sensor output at sample ``k`` is the housing acceleration at ``t_k``, read from the first RK4
stage of the step that starts there (no extra right-hand-side evaluation).  Only the current state
and the output chunk live in memory: memory stays flat for any signal length.

The force kernels (``generalized_forces``, ``accelerations``) are slice-free and inlined into one
compiled right-hand side, :func:`rvdiag.dynamics.kernels.rhs_with_terms` (bench/HISTORY.md 2026-11-23,
"speed at the same accuracy" and "slice-free force kernels": 368 -> 271 -> 173 ns per evaluation).

Instability (a non-finite state, or a vibratory displacement beyond ``max_displacement_m``, or a
rotation beyond ``max_rotation_rad``) stops
the kernel, which reports the sample; :func:`integrate` raises :class:`SimulationError` naming the
likely cause (step too large for the stiffest mode) and the remedy (more sub-steps).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numba
import numpy as np

from rvdiag.dynamics import kernels as kn
from rvdiag.dynamics import model as mdl
from rvdiag.dynamics.numba_cache import guard_kernel_module
from rvdiag.errors import SimulationError

# the kernels below inline kernels.py's force kernels and read its indices: recompile them when a kernel file changes
guard_kernel_module(__file__)

OK, NONFINITE, UNBOUNDED = 0, 1, 2
FASTMATH = kn.FASTMATH


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def sample_breaks(t0, dt, f_rel, events, tol, out):
    """Times of the mesh-table events strictly inside the sample ``(t0, t0 + dt)``, ascending, in ``out``;
    returns their number.

    ``events`` are the event phases in [0, 1) of a relative sun revolution (``Model.events``); phase
    ``p`` occurs at ``t = (c + p) / f_rel`` for every whole ``c``.  Events within ``tol`` (s) of a sample
    boundary are dropped (the boundary is a step boundary anyway).  Computed from the sample alone, so
    chunking cannot change the step grid.
    """
    ne = events.size
    if ne == 0 or f_rel <= 0.0:
        return 0
    p0 = f_rel * t0
    c = math.floor(p0)
    p1 = f_rel * (t0 + dt)
    j = np.searchsorted(events, p0 - c, side="right")
    m = 0
    while m < out.size:
        if j >= ne:
            j = 0
            c += 1.0
        pe = c + events[j]
        if pe >= p1:
            break
        te = pe / f_rel
        if te > t0 + tol and te < t0 + dt - tol:
            out[m] = te
            m += 1
        j += 1
    return m


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def sample_breaks_profile(t0, dt, P, events, tol, out):
    """:func:`sample_breaks` under a speed profile (``P[I_PROFILE] != 0``): the relative sun phase is
    ``(i - 1) theta_H(t) / 2 pi``, no longer linear in t, so each event's time is found by Newton's method on
    the closed-form angle (safeguarded by bisection; the angle is piecewise quadratic, so a few iterations reach
    the rounding level).  No events when the carrier stands still or the model is frozen."""
    ne = events.size
    if ne == 0 or P[kn.I_TFROZEN] >= 0.0:
        return 0
    g = (P[kn.I_RATIO] - 1.0) / (2.0 * math.pi)
    p0 = g * kn.profile_state(t0, P)[0]
    p1 = g * kn.profile_state(t0 + dt, P)[0]
    if not p1 > p0:
        return 0
    # the event phases c + events[j] in (p0, p1), in order: k counts events from the first after p0
    k0 = np.searchsorted(events, p0 - math.floor(p0), side="right")
    m = 0
    for k in range(k0, k0 + out.size):
        pe = math.floor(p0) + (k // ne) + events[k % ne]
        if pe >= p1:
            break
        te = _profile_event_time(t0, dt, P, g, p0, p1, pe)
        if te > t0 + tol and te < t0 + dt - tol:
            out[m] = te
            m += 1
    return m


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _profile_event_time(t0, dt, P, g, p0, p1, pe):
    """The time in ``[t0, t0 + dt]`` at which ``g theta_H(t) = pe`` (Newton from the linear guess, kept in the
    bracket by bisection)."""
    lo = t0
    hi = t0 + dt
    te = t0 + dt * (pe - p0) / (p1 - p0)
    for _ in range(30):
        th, w, _a = kn.profile_state(te, P)
        r = g * th - pe
        if r > 0.0:
            hi = te
        else:
            lo = te
        tn = te - r / (g * w) if w > 0.0 else 0.5 * (lo + hi)
        if not (tn > lo and tn < hi):
            tn = 0.5 * (lo + hi)
        if abs(tn - te) <= 1e-15 * dt:
            return tn
        te = tn
    return te


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def step_grid(t0, t_end, substeps, hnom, breaks, nb, grid):
    """Step boundaries of one sample in ``grid[0..M]`` (returns M): the sample cut at the ``nb`` event
    times in ``breaks``, each piece into ``ceil(length / hnom)`` equal steps (``substeps`` equal steps
    when there is no event)."""
    if nb == 0:
        for j in range(substeps):
            grid[j] = t0 + j * hnom
        grid[substeps] = t_end
        return substeps
    M = 0
    for piece in range(nb + 1):
        pa = t0 if piece == 0 else breaks[piece - 1]
        pb = t_end if piece == nb else breaks[piece]
        m = max(1, int(math.ceil((pb - pa) / hnom - 1e-9)))
        h = (pb - pa) / m
        for j in range(m):
            grid[M + j] = pa + j * h
        M += m
    grid[M] = t_end
    return M


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _time_rates(P):
    """``(f_rel, rate_b, rate_w)``: relative sun revolutions per second (the mesh table's period) and the
    rates of the frame angles b_0 = beta_0 - Zp Omega t and W = Omega t; all zero for a frozen model."""
    if P[kn.I_TFROZEN] >= 0.0:
        return 0.0, 0.0, 0.0
    return P[kn.I_WREL] / (2.0 * math.pi), -P[kn.I_ZP] * P[kn.I_OMEGA], P[kn.I_OMEGA]


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _rotation_increments(angle_b, angle_w):
    """(cos, sin) of the two frame-angle increments, for :func:`_advance_frames`."""
    return math.cos(angle_b), math.sin(angle_b), math.cos(angle_w), math.sin(angle_w)


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _record_sensor(dydt, n, iR, sx, sy, sensor, out, s):
    """``out[c, s]``: the housing acceleration at the sensor point ``(sx, sy)`` (pin-wheel translation
    plus its rotation's tangential part, docs/model.md section 6; ``iR`` its first coordinate) along each
    sensor direction ``c``."""
    ax = dydt[n + iR] - dydt[n + iR + 2] * sy
    ay = dydt[n + iR + 1] + dydt[n + iR + 2] * sx
    for c in range(sensor.shape[0]):
        out[c, s] = sensor[c, 0] * ax + sensor[c, 1] * ay


#: rows the motor adds to the output after the sensor channels (:func:`_record_motor`)
MOTOR_CHANNELS = ("i_d", "i_q", "theta_e", "speed")


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _record_motor(y, n, P, mt, c0, out, s):
    """With the motor's electrical side on: ``out[c0:c0 + 4, s]`` = i_d, i_q (A), the electrical angle
    ``p (theta_nom + q_m)`` wrapped to [0, 2 pi) and the rotor's speed ``omega_nom + v_m`` (rad/s) at the
    sample (:data:`MOTOR_CHANNELS`; ``mt`` holds the mesh terms at the sample's time)."""
    if P[kn.I_PMSM] == 0.0:
        return
    N = int(P[kn.I_NPL])
    out[c0, s] = y[2 * n]
    out[c0 + 1, s] = y[2 * n + 1]
    im = n - 2 if P[kn.I_LOAD] != 0.0 else n - 1  # the rotor (a load DOF comes after it)
    th = P[kn.I_M_P] * (mt[N, 4] + y[im])
    out[c0 + 2, s] = th - 2.0 * math.pi * math.floor(th / (2.0 * math.pi))
    out[c0 + 3, s] = mt[N, 5] + y[n + im]


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", nogil=True)
def rk4_run(y, k_start, n_samples, substeps, fs, record, P, inv_mass, planet, tvms, cosk, sink, sensor, out,
            geo0, rot0, mt0, geo1, rot1, mt1, geo2, rot2, mt2, geo3, rot3, geo4, rot4, Q, k1, k2, k3, ytmp,
            events, breaks, grid):
    """Advance ``y`` in place over ``n_samples`` output samples starting at sample index ``k_start``.

    Sample ``k`` is at ``t = k / fs``.  When ``record`` is true, ``out[c, s]`` receives the sensor
    acceleration along direction ``c`` at sample ``k_start + s``.  Returns ``(status, s)``: status 0
    when done, 1 for a non-finite state and 2 for a displacement beyond the limit, at sample ``s``.

    Step grid: a sample is cut at the mesh-table events inside it (``events`` = ``Model.events``;
    :func:`sample_breaks`), and each piece into equal RK4 steps no longer than ``1 / (fs substeps)``
    (:func:`step_grid`), so the stiffness ramps and deviation steps of the table, known in advance, fall
    on step boundaries.  Without events inside a sample this is ``substeps`` equal steps.  ``breaks``
    and ``grid`` are work space.
    """
    n2 = y.size  # [q, v] and the motor's electrical states when on
    n = Q.size
    dts = 1.0 / fs
    hnom = dts / substeps
    iR = 6 + 6 * int(P[kn.I_NPL]) + 3 * int(P[kn.I_NDISC])  # the pin wheel's first coordinate
    sx = P[kn.I_SENSX]
    sy = P[kn.I_SENSY]
    lim = P[kn.I_DISPLIM]
    limr = P[kn.I_ROTLIM]
    tol = 1e-6 * hnom
    # frame angles b_0 = beta_0 - Zp Omega t and W = Omega t advance linearly: within a sample their
    # cos/sin are rotated by half-step increments (angle addition) from the exact
    # values at the sample's start; libm's sincos at every stage time would cost ~8 % of the run
    f_rel, rate_b, rate_w = _time_rates(P)
    cdb0, sdb0, cdw0, sdw0 = _rotation_increments(0.5 * rate_b * hnom, 0.5 * rate_w * hnom)
    prof = P[kn.I_PROFILE] != 0.0  # a speed profile: the frame angles are exact (closed form) at every stage time
    # pin geometry: exact at the sample's start (gS), middle (gM) and end (gE), interpolated
    # (quadratic) at the half steps (gH) and the inner step ends (gT); gE becomes the next sample's gS
    # by swapping references.  Mesh terms (start, half, end of the step: ma, mb, mc) are exact at every
    # stage time.
    gS, rS, gE, rE, gH, rH, gT, rT, gM, rM = geo0, rot0, geo1, rot1, geo2, rot2, geo3, rot3, geo4, rot4
    ma, mb, mc = mt0, mt1, mt2
    t0 = k_start * dts
    cS = kn.frame_angles(t0, P)
    kn.pin_geometry_cs(cS[0], cS[1], cS[2], cS[3], P, cosk, sink, gS, rS)
    kn.mesh_terms(t0, P, tvms, ma)
    ks = k3  # running sum k1 + 2 k2 + 2 k3 (same order of additions as the textbook formula)
    for s in range(n_samples):
        kk = k_start + s
        t0 = kk * dts
        t_end = (kk + 1) * dts
        cE = kn.frame_angles(t_end, P)
        kn.pin_geometry_cs(cE[0], cE[1], cE[2], cE[3], P, cosk, sink, gE, rE)
        cb, sb, cw, sw = kn.frame_angles(t0 + 0.5 * dts, P)
        kn.pin_geometry_cs(cb, sb, cw, sw, P, cosk, sink, gM, rM)
        if prof:
            nb = sample_breaks_profile(t0, dts, P, events, tol, breaks)
        else:
            nb = sample_breaks(t0, dts, f_rel, events, tol, breaks)
        M = step_grid(t0, t_end, substeps, hnom, breaks, nb, grid)
        cb, sb, cw, sw = cS
        cdb, sdb, cdw, sdw = cdb0, sdb0, cdw0, sdw0
        for j in range(M):
            ta = grid[j]
            t1 = grid[j + 1]
            h = t1 - ta
            hh = 0.5 * h
            th = ta + hh
            if nb > 0:  # unequal steps in this sample: their own increments
                cdb, sdb, cdw, sdw = _rotation_increments(rate_b * hh, rate_w * hh)
            if j == 0:
                kn.rhs_with_terms(y, P, inv_mass, planet, ma, gS, rS, Q, k1)
                if record:
                    _record_sensor(k1, n, iR, sx, sy, sensor, out, s)
                    _record_motor(y, n, P, ma, sensor.shape[0], out, s)
            else:
                kn.rhs_with_terms(y, P, inv_mass, planet, ma, gT, rT, Q, k1)
            if prof:
                cb, sb, cw, sw = kn.frame_angles(th, P)
            else:
                cb, sb, cw, sw = _advance_frames(cb, sb, cw, sw, cdb, sdb, cdw, sdw)
            kn.frame_rotations(cb, sb, cw, sw, P, rH)
            kn.interpolate_geometry(gS, gM, gE, (th - t0) * fs, P, gH)
            kn.mesh_terms(th, P, tvms, mb)
            for i in range(n2):
                ytmp[i] = y[i] + hh * k1[i]
                ks[i] = k1[i]
            kn.rhs_with_terms(ytmp, P, inv_mass, planet, mb, gH, rH, Q, k2)
            for i in range(n2):
                ytmp[i] = y[i] + hh * k2[i]
                ks[i] += 2.0 * k2[i]
            kn.rhs_with_terms(ytmp, P, inv_mass, planet, mb, gH, rH, Q, k2)
            kn.mesh_terms(t1, P, tvms, mc)
            for i in range(n2):
                ytmp[i] = y[i] + h * k2[i]
                ks[i] += 2.0 * k2[i]
            if prof:
                cb, sb, cw, sw = kn.frame_angles(t1, P)
            else:
                cb, sb, cw, sw = _advance_frames(cb, sb, cw, sw, cdb, sdb, cdw, sdw)
            if j == M - 1:
                kn.rhs_with_terms(ytmp, P, inv_mass, planet, mc, gE, rE, Q, k2)
            else:
                kn.frame_rotations(cb, sb, cw, sw, P, rT)
                kn.interpolate_geometry(gS, gM, gE, (t1 - t0) * fs, P, gT)
                kn.rhs_with_terms(ytmp, P, inv_mass, planet, mc, gT, rT, Q, k2)
            h6 = h / 6.0
            for i in range(n2):
                y[i] += h6 * (ks[i] + k2[i])
            # the step's end terms are the next step's start terms
            ma, mc = mc, ma
        gS, gE = gE, gS
        rS, rE = rE, rS
        cS = cE
        st = _check_state(y, n, lim, limr)
        if st != OK:
            return st, s
    return OK, n_samples


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", nogil=True)
def rk38_run(y, k_start, n_samples, substeps, fs, record, P, inv_mass, planet, tvms, cosk, sink, sensor, out,
             geo0, rot0, mt0, geo1, rot1, mt1, geo2, rot2, mt2, geo3, rot3, mt3, Q, k1, k2, k3, k4, ytmp,
             events, breaks, grid):
    """:func:`rk4_run` with Kutta's 3/8-rule fourth-order method (stage times t, t + h/3, t + 2h/3,
    t + h; weights 1/8, 3/8, 3/8, 1/8; Kutta 1901; Hairer, Norsett & Wanner 1993, section II.1).

    Same arguments, outputs, step grid (cut at the mesh-table events) and instability checks as
    :func:`rk4_run`, with a fourth geometry slot; the pin geometry is exact at every stage time.
    """
    n2 = y.size  # [q, v] and the motor's electrical states when on
    n = Q.size
    dts = 1.0 / fs
    hnom = dts / substeps
    iR = 6 + 6 * int(P[kn.I_NPL]) + 3 * int(P[kn.I_NDISC])  # the pin wheel's first coordinate
    sx = P[kn.I_SENSX]
    sy = P[kn.I_SENSY]
    lim = P[kn.I_DISPLIM]
    limr = P[kn.I_ROTLIM]
    ga, ra, ma, gb, rb, mb, gc, rc, mc, gd, rd, md = (geo0, rot0, mt0, geo1, rot1, mt1, geo2, rot2, mt2,
                                                      geo3, rot3, mt3)
    tol = 1e-6 * hnom
    f_rel, rate_b, rate_w = _time_rates(P)
    cdb0, sdb0, cdw0, sdw0 = _rotation_increments(rate_b * hnom / 3.0, rate_w * hnom / 3.0)
    prof = P[kn.I_PROFILE] != 0.0  # a speed profile: the frame angles are exact (closed form) at every stage time
    cb, sb, cw, sw = kn.frame_angles(k_start * dts, P)
    kn.pin_geometry_cs(cb, sb, cw, sw, P, cosk, sink, ga, ra)
    kn.mesh_terms(k_start * dts, P, tvms, ma)
    for s in range(n_samples):
        kk = k_start + s
        t0 = kk * dts
        t_end = (kk + 1) * dts
        if prof:
            nb = sample_breaks_profile(t0, dts, P, events, tol, breaks)
        else:
            nb = sample_breaks(t0, dts, f_rel, events, tol, breaks)
        M = step_grid(t0, t_end, substeps, hnom, breaks, nb, grid)
        cdb, sdb, cdw, sdw = cdb0, sdb0, cdw0, sdw0
        for j in range(M):
            t1 = grid[j + 1]
            h = t1 - grid[j]
            h3 = h / 3.0
            ta = grid[j] + h3
            tb = grid[j] + 2.0 * h3
            if nb > 0:  # unequal steps in this sample: their own increments
                cdb, sdb, cdw, sdw = _rotation_increments(rate_b * h3, rate_w * h3)
            kn.rhs_with_terms(y, P, inv_mass, planet, ma, ga, ra, Q, k1)
            if j == 0 and record:
                _record_sensor(k1, n, iR, sx, sy, sensor, out, s)
                _record_motor(y, n, P, ma, sensor.shape[0], out, s)
            if prof:
                cb, sb, cw, sw = kn.frame_angles(ta, P)
            else:
                cb, sb, cw, sw = _advance_frames(cb, sb, cw, sw, cdb, sdb, cdw, sdw)
            kn.pin_geometry_cs(cb, sb, cw, sw, P, cosk, sink, gb, rb)
            kn.mesh_terms(ta, P, tvms, mb)
            for i in range(n2):
                ytmp[i] = y[i] + h3 * k1[i]
            kn.rhs_with_terms(ytmp, P, inv_mass, planet, mb, gb, rb, Q, k2)
            if prof:
                cb, sb, cw, sw = kn.frame_angles(tb, P)
            else:
                cb, sb, cw, sw = _advance_frames(cb, sb, cw, sw, cdb, sdb, cdw, sdw)
            kn.pin_geometry_cs(cb, sb, cw, sw, P, cosk, sink, gc, rc)
            kn.mesh_terms(tb, P, tvms, mc)
            for i in range(n2):
                ytmp[i] = y[i] + h * (k2[i] - k1[i] / 3.0)
            kn.rhs_with_terms(ytmp, P, inv_mass, planet, mc, gc, rc, Q, k3)
            if j == M - 1:  # re-anchored exactly at every sample's end
                cb, sb, cw, sw = kn.frame_angles(t_end, P)
            elif prof:
                cb, sb, cw, sw = kn.frame_angles(t1, P)
            else:
                cb, sb, cw, sw = _advance_frames(cb, sb, cw, sw, cdb, sdb, cdw, sdw)
            kn.pin_geometry_cs(cb, sb, cw, sw, P, cosk, sink, gd, rd)
            kn.mesh_terms(t1, P, tvms, md)
            for i in range(n2):
                ytmp[i] = y[i] + h * (k1[i] - k2[i] + k3[i])
            kn.rhs_with_terms(ytmp, P, inv_mass, planet, md, gd, rd, Q, k4)
            h8 = h / 8.0
            for i in range(n2):
                y[i] += h8 * (k1[i] + 3.0 * (k2[i] + k3[i]) + k4[i])
            ga, gd = gd, ga
            ra, rd = rd, ra
            ma, md = md, ma
        st = _check_state(y, n, lim, limr)
        if st != OK:
            return st, s
    return OK, n_samples


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _advance_frames(cb, sb, cw, sw, cdb, sdb, cdw, sdw):
    """Rotate the frame angles' (cos, sin) pairs by one fixed increment each (angle addition)."""
    return cb * cdb - sb * sdb, sb * cdb + cb * sdb, cw * cdw - sw * sdw, sw * cdw + cw * sdw


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _check_state(y, n, lim, limr):
    """NONFINITE for a NaN/inf entry, UNBOUNDED for a displacement or rotation beyond its limit."""
    big = 0.0
    bigr = 0.0
    for i in range(n):
        a = abs(y[i])
        if not (a < math.inf):
            return NONFINITE
        if i % 3 == 2:
            if a > bigr:
                bigr = a
        elif a > big:
            big = a
    for i in range(n, y.size):  # velocities and the motor's electrical states
        if not (abs(y[i]) < math.inf):
            return NONFINITE
    if big > lim or bigr > limr:
        return UNBOUNDED
    return OK


_step_kernels_loaded = False


def _load_step_kernels(model: mdl.Model) -> None:
    """Load the kernels ``rk4_run`` and ``rk38_run`` call before them, callees first, once per process
    (:func:`rvdiag.dynamics.model.load_kernels` says why: the same bits from a fresh compile and from the
    cache)."""
    global _step_kernels_loaded
    mdl.load_kernels(model)
    if _step_kernels_loaded:
        return
    with mdl._kernels_lock:
        out = np.zeros(4)
        nb = sample_breaks(0.0, 1.0, 0.5, np.array([0.25]), 1e-9, out)
        sample_breaks_profile(0.0, 1.0, model.P, np.array([0.25]), 1e-9, out)
        step_grid(0.0, 1.0, 2, 0.5, out, nb, np.zeros(8))
        _step_kernels_loaded = True


def integrate(
    model: mdl.Model,
    y0: np.ndarray,
    fs: float,
    n_samples: int,
    n_transient: int = 0,
    progress: Callable[[int, int], None] | None = None,
    first_sample: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """Integrate from sample ``first_sample - n_transient`` (state ``y0``) and record ``n_samples`` sensor
    samples from sample ``first_sample`` on (time ``first_sample / fs``).

    Returns ``(signal, y_end)``, ``signal`` of shape (channels, n_samples) in m/s^2; with the motor's electrical
    side on (``model.has_pmsm``), the rows :data:`MOTOR_CHANNELS` follow the sensor channels.  ``progress`` is
    called as ``progress(done, total)`` after each chunk (total counts transient samples too).
    """
    _load_step_kernels(model)
    st = model.settings
    S = int(st.substeps)
    n = model.n_dof
    n_state = model.n_state
    y = np.array(y0, dtype=np.float64, copy=True)
    if y.shape != (n_state,):
        raise SimulationError(f"initial state must have {n_state} entries, got {y.shape}")
    nd, nz = model.n_discs, model.cosk.size
    rk38 = st.method == "rk38"
    geo = [np.zeros((nd, kn.GEO_ROWS, nz)) for _ in range(4 if rk38 else 5)]
    rot = [np.zeros((nd, 4)) for _ in range(4 if rk38 else 5)]
    mts = [mdl.mesh_array(model) for _ in range(4 if rk38 else 3)]
    work = [np.zeros(n)] + [np.zeros(n_state) for _ in range(5 if rk38 else 4)]  # Q, k1..k3 (k4), ytmp
    # table events inside one sample (at most all of them, once per relative revolution it spans)
    f_rel = abs(model.P[kn.I_WREL]) / (2.0 * math.pi)
    breaks = np.zeros(model.events.size * (int(f_rel / fs) + 2) + 1)
    grid = np.zeros(S + breaks.size + 2)  # step boundaries of one sample
    n_out = model.sensor.shape[0] + (len(MOTOR_CHANNELS) if model.has_pmsm else 0)
    out = np.zeros((n_out, n_samples))
    chunk = max(1, int(st.chunk_samples))
    cbuf = np.zeros((n_out, chunk))
    slots = [a for triple in zip(geo, rot, mts) for a in triple]
    if not rk38:
        slots += [geo[3], rot[3], geo[4], rot[4]]
    run = rk38_run if rk38 else rk4_run
    total = n_transient + n_samples
    done = 0
    k = first_sample - n_transient
    while done < total:
        m = min(chunk, total - done)
        rec = k >= first_sample
        if not rec:
            m = min(m, first_sample - k)
        status, s = run(y, k, m, S, float(fs), rec, model.P, model.inv_mass, model.planet, model.tables,
                        model.cosk, model.sink, model.sensor, cbuf, *slots, *work, model.events, breaks, grid)
        if status != OK:
            _raise_unstable(model, status, (k + s) / fs, fs)
        if rec:
            out[:, k - first_sample:k - first_sample + m] = cbuf[:, :m]
        k += m
        done += m
        if progress is not None:
            progress(done, total)
    return out, y


def _raise_unstable(model: mdl.Model, status: int, t: float, fs: float) -> None:
    S = int(model.settings.substeps)
    h = 1.0 / (fs * S)
    what = "the state became NaN/inf" if status == NONFINITE else (
        f"a vibratory displacement exceeded {model.settings.max_displacement_m:g} m or a rotation "
        f"{model.settings.max_rotation_rad:g} rad (growth without bound)")
    hint = ""
    try:
        from rvdiag.dynamics.linear import natural_frequencies

        f_max = float(natural_frequencies(model).frequencies_hz[-1])
        s_min = math.ceil(2.0 * math.pi * f_max / (2.78 * fs))
        hint = (f" The stiffest mode is near {f_max / 1e3:.1f} kHz; RK4 (and the 3/8 rule) needs "
                f"omega*h < 2.78, "
                f"i.e. at least {s_min} sub-steps at fs = {fs:g} Hz.")
    except Exception:  # noqa: BLE001 - the hint is optional, the error is not
        pass
    raise SimulationError(
        f"integration unstable at t = {t:.6g} s: {what} with {S} sub-steps per sample "
        f"(step {h:.3g} s). Likely cause: the step is too large for the stiffest mode.{hint} "
        f"Remedy: increase the sub-steps (e.g. substeps={2 * S}) or lower the contact stiffness."
    )
