"""Fixed-step RK4 integration of the RV-reducer model, compiled with numba, streamed in chunks.

The classical fourth-order Runge-Kutta method (Hairer, Norsett & Wanner, *Solving ODEs I*, 1993,
section II.1) advances ``substeps`` steps of ``h = 1 / (fs substeps)`` per output sample
(``ModelSettings(method="rk38")``: Kutta's 3/8 rule instead, :func:`rk38_run`).  What depends on
time only is computed once per distinct stage time (t, t + h/2, t + h) and shared by the stages: the mesh
stiffness and profile deviation of each sun-planet mesh (:func:`rvdiag.dynamics.model.mesh_terms`), the
frame rotations (rotated by fixed half-step increments within an output sample and recomputed exactly at
each sample: one sin/cos pair per sample; REFERENCE.md section 5) and the cycloid-pin geometry.  RK4 takes
the geometry exactly at each sample's start, middle and end and interpolates it quadratically at the
inner stage times (:func:`rvdiag.dynamics.model.interpolate_geometry`; output change 1e-8 to 2e-7 relative
against the exact geometry at every stage); the 3/8 rule evaluates it exactly at every stage time.

The sensor output at sample ``k`` is the housing acceleration at ``t_k``, read from the first RK4
stage of the step that starts there (no extra right-hand-side evaluation).  Only the current state
and the output chunk live in memory: memory stays flat for any signal length.

The force kernels (``generalized_forces``, ``accelerations``) are slice-free and inlined into one
compiled right-hand side, :func:`rvdiag.dynamics.model.rhs_with_terms` (bench/HISTORY.md 2026-11-23,
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

from rvdiag.dynamics import model as mdl
from rvdiag.dynamics.numba_cache import drop_stale_cache
from rvdiag.errors import SimulationError

# the kernels below inline model.py's force kernels: recompile them when model.py changes
drop_stale_cache(__file__, [mdl.__file__])

OK, NONFINITE, UNBOUNDED = 0, 1, 2
FASTMATH = mdl.FASTMATH


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def rk4_run(y, k_start, n_samples, substeps, fs, record, P, inv_mass, planet, tvms, cosk, sink, sensor, out,
            geo0, rot0, mt0, geo1, rot1, mt1, geo2, rot2, mt2, geo3, rot3, geo4, rot4, Q, k1, k2, k3, ytmp):
    """Advance ``y`` in place over ``n_samples`` output samples starting at sample index ``k_start``.

    Sample ``k`` is at ``t = k / fs``.  When ``record`` is true, ``out[c, s]`` receives the sensor
    acceleration along direction ``c`` at sample ``k_start + s``.  Returns ``(status, s)``: status 0
    when done, 1 for a non-finite state and 2 for a displacement beyond the limit, at sample ``s``.
    """
    n2 = y.size
    n = n2 // 2
    iR = n - 3
    h = 1.0 / (fs * substeps)
    sx = P[mdl.I_SENSX]
    sy = P[mdl.I_SENSY]
    lim = P[mdl.I_DISPLIM]
    limr = P[mdl.I_ROTLIM]
    nch = sensor.shape[0]
    # every time is an integer number of half steps times h/2, so a chunk boundary changes nothing
    hh = 0.5 * h
    h6 = h / 6.0
    inv_s = 1.0 / substeps
    # pin geometry: exact at the sample's start (gS), middle (gM) and end (gE), interpolated
    # (quadratic) at the half steps (gH) and the inner step ends (gT); gE becomes the next sample's gS
    # by swapping references.  Mesh terms (start, half, end of the step: ma, mb, mc) are exact at every
    # stage time.
    gS, rS, gE, rE, gH, rH, gT, rT, gM, rM = geo0, rot0, geo1, rot1, geo2, rot2, geo3, rot3, geo4, rot4
    ma, mb, mc = mt0, mt1, mt2
    # The frame angles b_0 = beta_0 - Zp Omega t and W = Omega t advance linearly, so within an output
    # sample their cos/sin are rotated by the half-step increments instead of recomputed (issue 3;
    # REFERENCE.md sec. 5); every sample end t_(k+1) is re-anchored with exact cos/sin, so rounding
    # cannot accumulate and a chunk boundary changes nothing.
    frozen = P[mdl.I_TFROZEN] >= 0.0
    db = 0.0 if frozen else -P[mdl.I_ZP] * P[mdl.I_OMEGA] * hh
    dw = 0.0 if frozen else P[mdl.I_OMEGA] * hh
    cdb = math.cos(db)
    sdb = math.sin(db)
    cdw = math.cos(dw)
    sdw = math.sin(dw)
    # half-sample rotation back from the sample's end to its middle
    cdbm = math.cos(-db * substeps)
    sdbm = math.sin(-db * substeps)
    cdwm = math.cos(-dw * substeps)
    sdwm = math.sin(-dw * substeps)
    cb, sb, cw, sw = mdl.frame_angles((2 * k_start * substeps) * hh, P)
    mdl.pin_geometry_cs(cb, sb, cw, sw, P, cosk, sink, gS, rS)
    mdl.mesh_terms((2 * k_start * substeps) * hh, P, tvms, ma)
    ks = k3  # running sum k1 + 2 k2 + 2 k3 (same order of additions as the textbook formula)
    for s in range(n_samples):
        kk = k_start + s
        ce, se, cwe, swe = mdl.frame_angles((2 * (kk + 1) * substeps) * hh, P)
        mdl.pin_geometry_cs(ce, se, cwe, swe, P, cosk, sink, gE, rE)
        cm, sm, cwm, swm = _advance_frames(ce, se, cwe, swe, cdbm, sdbm, cdwm, sdwm)
        mdl.pin_geometry_cs(cm, sm, cwm, swm, P, cosk, sink, gM, rM)
        for sub in range(substeps):
            idx = kk * substeps + sub
            th = (2 * idx + 1) * hh
            t1 = (2 * idx + 2) * hh
            if sub == 0:
                mdl.rhs_with_terms(y, P, inv_mass, planet, ma, gS, rS, Q, k1)
            else:
                mdl.rhs_with_terms(y, P, inv_mass, planet, ma, gT, rT, Q, k1)
            if sub == 0 and record:
                ax = k1[n + iR] - k1[n + iR + 2] * sy
                ay = k1[n + iR + 1] + k1[n + iR + 2] * sx
                for c in range(nch):
                    out[c, s] = sensor[c, 0] * ax + sensor[c, 1] * ay
            cb, sb, cw, sw = _advance_frames(cb, sb, cw, sw, cdb, sdb, cdw, sdw)
            mdl.frame_rotations(cb, sb, cw, sw, P, rH)
            mdl.interpolate_geometry(gS, gM, gE, (sub + 0.5) * inv_s, P, gH)
            mdl.mesh_terms(th, P, tvms, mb)
            for i in range(n2):
                ytmp[i] = y[i] + hh * k1[i]
                ks[i] = k1[i]
            mdl.rhs_with_terms(ytmp, P, inv_mass, planet, mb, gH, rH, Q, k2)
            for i in range(n2):
                ytmp[i] = y[i] + hh * k2[i]
                ks[i] += 2.0 * k2[i]
            mdl.rhs_with_terms(ytmp, P, inv_mass, planet, mb, gH, rH, Q, k2)
            mdl.mesh_terms(t1, P, tvms, mc)
            for i in range(n2):
                ytmp[i] = y[i] + h * k2[i]
                ks[i] += 2.0 * k2[i]
            if sub == substeps - 1:
                cb, sb, cw, sw = ce, se, cwe, swe
                mdl.rhs_with_terms(ytmp, P, inv_mass, planet, mc, gE, rE, Q, k2)
            else:
                cb, sb, cw, sw = _advance_frames(cb, sb, cw, sw, cdb, sdb, cdw, sdw)
                mdl.frame_rotations(cb, sb, cw, sw, P, rT)
                mdl.interpolate_geometry(gS, gM, gE, (sub + 1) * inv_s, P, gT)
                mdl.rhs_with_terms(ytmp, P, inv_mass, planet, mc, gT, rT, Q, k2)
            for i in range(n2):
                y[i] += h6 * (ks[i] + k2[i])
            # the step's end terms are the next step's start terms
            ma, mc = mc, ma
        gS, gE = gE, gS
        rS, rE = rE, rS
        st = _check_state(y, n, lim, limr)
        if st != OK:
            return st, s
    return OK, n_samples


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def rk38_run(y, k_start, n_samples, substeps, fs, record, P, inv_mass, planet, tvms, cosk, sink, sensor, out,
             geo0, rot0, mt0, geo1, rot1, mt1, geo2, rot2, mt2, geo3, rot3, mt3, Q, k1, k2, k3, k4, ytmp):
    """:func:`rk4_run` with Kutta's 3/8-rule fourth-order method (stage times t, t + h/3, t + 2h/3,
    t + h; weights 1/8, 3/8, 3/8, 1/8; Kutta 1901; Hairer, Norsett & Wanner 1993, section II.1).

    Same arguments, outputs and instability checks as :func:`rk4_run`, with a fourth geometry slot.
    Every time is an integer multiple of h/3, so chunking does not change a bit.
    """
    n2 = y.size
    n = n2 // 2
    iR = n - 3
    h = 1.0 / (fs * substeps)
    sx = P[mdl.I_SENSX]
    sy = P[mdl.I_SENSY]
    lim = P[mdl.I_DISPLIM]
    limr = P[mdl.I_ROTLIM]
    nch = sensor.shape[0]
    h3 = h / 3.0
    h8 = h / 8.0
    ga, ra, ma, gb, rb, mb, gc, rc, mc, gd, rd, md = (geo0, rot0, mt0, geo1, rot1, mt1, geo2, rot2, mt2,
                                                      geo3, rot3, mt3)
    frozen = P[mdl.I_TFROZEN] >= 0.0
    db = 0.0 if frozen else -P[mdl.I_ZP] * P[mdl.I_OMEGA] * h3
    dw = 0.0 if frozen else P[mdl.I_OMEGA] * h3
    cdb = math.cos(db)
    sdb = math.sin(db)
    cdw = math.cos(dw)
    sdw = math.sin(dw)
    cb, sb, cw, sw = mdl.frame_angles((3 * k_start * substeps) * h3, P)
    mdl.pin_geometry_cs(cb, sb, cw, sw, P, cosk, sink, ga, ra)
    mdl.mesh_terms((3 * k_start * substeps) * h3, P, tvms, ma)
    for s in range(n_samples):
        kk = k_start + s
        for sub in range(substeps):
            idx = kk * substeps + sub
            ta = (3 * idx + 1) * h3
            tb = (3 * idx + 2) * h3
            t1 = (3 * idx + 3) * h3
            mdl.rhs_with_terms(y, P, inv_mass, planet, ma, ga, ra, Q, k1)
            if sub == 0 and record:
                ax = k1[n + iR] - k1[n + iR + 2] * sy
                ay = k1[n + iR + 1] + k1[n + iR + 2] * sx
                for c in range(nch):
                    out[c, s] = sensor[c, 0] * ax + sensor[c, 1] * ay
            cb, sb, cw, sw = _advance_frames(cb, sb, cw, sw, cdb, sdb, cdw, sdw)
            mdl.pin_geometry_cs(cb, sb, cw, sw, P, cosk, sink, gb, rb)
            mdl.mesh_terms(ta, P, tvms, mb)
            for i in range(n2):
                ytmp[i] = y[i] + h3 * k1[i]
            mdl.rhs_with_terms(ytmp, P, inv_mass, planet, mb, gb, rb, Q, k2)
            cb, sb, cw, sw = _advance_frames(cb, sb, cw, sw, cdb, sdb, cdw, sdw)
            mdl.pin_geometry_cs(cb, sb, cw, sw, P, cosk, sink, gc, rc)
            mdl.mesh_terms(tb, P, tvms, mc)
            for i in range(n2):
                ytmp[i] = y[i] + h * (k2[i] - k1[i] / 3.0)
            mdl.rhs_with_terms(ytmp, P, inv_mass, planet, mc, gc, rc, Q, k3)
            if sub == substeps - 1:
                cb, sb, cw, sw = mdl.frame_angles(t1, P)
            else:
                cb, sb, cw, sw = _advance_frames(cb, sb, cw, sw, cdb, sdb, cdw, sdw)
            mdl.pin_geometry_cs(cb, sb, cw, sw, P, cosk, sink, gd, rd)
            mdl.mesh_terms(t1, P, tvms, md)
            for i in range(n2):
                ytmp[i] = y[i] + h * (k1[i] - k2[i] + k3[i])
            mdl.rhs_with_terms(ytmp, P, inv_mass, planet, md, gd, rd, Q, k4)
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
    for i in range(n, 2 * n):
        if not (abs(y[i]) < math.inf):
            return NONFINITE
    if big > lim or bigr > limr:
        return UNBOUNDED
    return OK


def integrate(
    model: mdl.Model,
    y0: np.ndarray,
    fs: float,
    n_samples: int,
    n_transient: int = 0,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Integrate from sample ``-n_transient`` (state ``y0``) and record ``n_samples`` sensor samples.

    Returns ``(signal, y_end)``, ``signal`` of shape (channels, n_samples) in m/s^2.  ``progress`` is
    called as ``progress(done, total)`` after each chunk (total counts transient samples too).
    """
    st = model.settings
    S = int(st.substeps)
    n = model.n_dof
    y = np.array(y0, dtype=np.float64, copy=True)
    if y.shape != (2 * n,):
        raise SimulationError(f"initial state must have {2 * n} entries, got {y.shape}")
    nd, nz = model.n_discs, model.cosk.size
    rk38 = st.method == "rk38"
    geo = [np.zeros((nd, 3, nz)) for _ in range(4 if rk38 else 5)]
    rot = [np.zeros((nd, 4)) for _ in range(4 if rk38 else 5)]
    mts = [mdl.mesh_array(model) for _ in range(4 if rk38 else 3)]
    work = [np.zeros(n)] + [np.zeros(2 * n) for _ in range(5 if rk38 else 4)]  # Q, k1..k3 (k4), ytmp
    out = np.zeros((model.sensor.shape[0], n_samples))
    chunk = max(1, int(st.chunk_samples))
    cbuf = np.zeros((model.sensor.shape[0], chunk))
    total = n_transient + n_samples
    done = 0
    k = -n_transient
    while done < total:
        m = min(chunk, total - done)
        rec = k >= 0
        if not rec:
            m = min(m, -k)
        slots = [a for triple in zip(geo, rot, mts) for a in triple]
        if not rk38:
            slots += [geo[3], rot[3], geo[4], rot[4]]
        run = rk38_run if rk38 else rk4_run
        status, s = run(y, k, m, S, float(fs), rec, model.P, model.inv_mass, model.planet, model.tables,
                        model.cosk, model.sink, model.sensor, cbuf, *slots, *work)
        if status != OK:
            _raise_unstable(model, status, (k + s) / fs, fs)
        if rec:
            out[:, k:k + m] = cbuf[:, :m]
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
