"""Packing of the flat arrays the compiled kernels take, from a reducer's parameters at one operating point.

One purpose: turn :class:`rvdiag.params.ReducerParams`, a mesh table and the operating point into numbers the
kernels read: ``P`` (its fields are :data:`rvdiag.dynamics.kernels.P_FIELDS`), the masses, the planet and pin
angle tables, the sensor directions (:func:`pack_model_arrays`; parameters and damping, docs/model.md sections 3
and 4; sensor, section 6), the linearised pin stiffness (:func:`pin_contact_stiffness`, section 3) and the mesh
table's damping rows, separation slopes and kink events that the integrator steps on (:func:`separation_slopes`,
:func:`table_events`; section 7).  :func:`rvdiag.dynamics.model.build_model` wraps the result in a ``Model``.
"""

from __future__ import annotations

import math

import numpy as np

from rvdiag.dynamics import kernels as kn
from rvdiag.dynamics.layout import dof_layout
from rvdiag.dynamics.manufacturing import ManufacturingErrors, draw_manufacturing_errors
from rvdiag.dynamics.mesh import MeshTable
from rvdiag.dynamics.profile import G, LoadProfile, SpeedProfile
from rvdiag.dynamics.settings import ModelSettings
from rvdiag.errors import ParameterError
from rvdiag.gears.cycloid import (  # noqa: F401 (re-exported: rvdiag.dynamics.model's names)
    PIN_LOAD_FLOOR_FRACTION, PIN_STIFFNESS_ANGLES, pin_contact_stiffness)
from rvdiag.params import ReducerParams, body_properties
from rvdiag.validation import number, positive

TWO_PI = kn.TWO_PI

#: approach (m) over which a tooth pair's damper grows from nothing to its full value once the flanks touch
#: (a penetration-dependent damper, Hunt & Crossley 1975, J. Appl. Mech. 42, in its simplest, linear-ramp form):
#: the contact force then starts from zero as the flanks meet, instead of jumping by c * (approach rate), so a
#: pair touching or leaving within a step costs RK4 much less accuracy (docs/model.md section 7)
MESH_DAMPING_RAMP_M = 0.1e-6

#: a table node is an event where the stiffness's second difference exceeds this fraction of its mean
#: (single/double tooth contact changes: ~0.55; elsewhere below 4e-5 for every fault state) ...
EVENT_STIFFNESS_KINK = 1e-3
#: ... or the profile deviation's exceeds this fraction of its largest value (the load-share steps of an
#: Archard wear profile: up to ~1; the smooth parts below 1e-3)
EVENT_DEVIATION_KINK = 1e-2


def table_events(tables: np.ndarray, n_planets: int) -> np.ndarray:
    """Phases (fractions of a relative sun revolution, sorted, in [0, 1)) at which a planet's mesh passes
    a kink of the linearly interpolated mesh table: the ends of the stiffness ramps where the number of
    tooth pairs in contact changes, and the steps of a wear deviation.

    The mesh terms depend on time only, so these instants are known before integrating; the RK4 kernel
    cuts its steps there (a fixed step that straddles a kink loses an order of accuracy).  Planet i sees
    table phase ``x`` at relative phase ``x + i / N``.  Choosing the nodes changes no equation, only where
    the steps fall.
    """
    S = (tables.shape[0] - 2) // 4
    ks = tables[:S]
    kbar = max(float(np.abs(ks.sum(axis=0)).mean()), 1e-300)
    kink = np.zeros(tables.shape[1], dtype=bool)
    for k in ks:
        kink |= np.abs(np.roll(k, -1) - 2.0 * k + np.roll(k, 1)) > EVENT_STIFFNESS_KINK * kbar
    for k, e in zip(ks, tables[S:2 * S]):
        e = np.where(k > 0, e, 0.0)
        emax = np.abs(e).max()
        if emax > 0.0:
            kink |= np.abs(np.roll(e, -1) - 2.0 * e + np.roll(e, 1)) > EVENT_DEVIATION_KINK * emax
    nodes = np.flatnonzero(kink) / tables.shape[1]
    phases = (nodes[None, :] + np.arange(n_planets)[:, None] / n_planets) % 1.0
    return np.unique(phases)


def separation_slopes(pairs: np.ndarray) -> np.ndarray:
    """Slope of each slot's separation at the table nodes, per node interval, shape ``(S, n)``.

    Central differences where the pair is in contact on both sides of a node, one-sided at the ends of a
    pair's contact, zero outside it.  The kernel interpolates these linearly, so the separation's rate in
    the dampers is continuous in time; the rate of the linearly interpolated separation itself would jump at
    every node (every ~17 us at 45 deg/s) and cost RK4 an order of accuracy (docs/model.md section 7).
    """
    k, e = pairs[:, 0, :], pairs[:, 1, :]
    on = k > 0.0
    on_prev, on_next = np.roll(on, 1, axis=1), np.roll(on, -1, axis=1)
    fwd = np.roll(e, -1, axis=1) - e
    bwd = e - np.roll(e, 1, axis=1)
    out = np.where(on_prev & on_next, 0.5 * (fwd + bwd), np.where(on_next, fwd, np.where(on_prev, bwd, 0.0)))
    return np.where(on, out, 0.0)



def _linearisation_load(profile: SpeedProfile, load: LoadProfile, T0: float, Omega: float,
                        duration_s: float | None) -> float:
    """The load at which the pin stiffness is linearised: ``T0``, or with a gravity arm the mean of
    ``|T_L(t)|`` over the record (``duration_s``, else one output revolution)."""
    return float(np.mean(np.abs(_load_over_record(profile, load, T0, Omega, duration_s))))


def _load_over_record(profile: SpeedProfile, load: LoadProfile, T0: float, Omega: float,
                      duration_s: float | None) -> np.ndarray:
    """The load torque at 512 instants of the record (``duration_s``, else one output revolution); ``[T0]``
    without a gravity arm."""
    if not load.has_arm:
        return np.array([T0])
    span = duration_s if duration_s else 2.0 * math.pi / Omega
    t = np.linspace(0.0, span, 512)
    th, _, dw = profile.state(t, Omega, duration_s)
    return load.torque(T0, th, dw)


def _mean_load(profile: SpeedProfile, load: LoadProfile, T0: float, Omega: float, duration_s: float | None) -> float:
    """The signed mean load torque over the record (``T0`` without a gravity arm): its sign says which half of
    the pins carries the load."""
    return float(np.mean(_load_over_record(profile, load, T0, Omega, duration_s)))


def _pack_profile_modification(P: np.ndarray, params: ReducerParams, mean_load_Nm: float) -> np.ndarray:
    """The cycloid discs' equidistant and offset profile modifications and the stage's wear (docs/model.md
    section 3): each pin's initial clearance ``geo[g, 3, k]`` (:func:`rvdiag.dynamics.kernels.pin_geometry_cs`),
    with the disc's rotation that takes it up on the half of the pins the mean load presses (``sense``: the arm
    ``l_k`` of those pins is negative under a positive output torque).  The wear's clearance table
    (:func:`rvdiag.gears.pin_wear.pin_wear_table`) is appended to ``P`` (``P[I_PINWEAR]`` its start); returns
    ``P``."""
    from rvdiag.gears.cycloid import closing_offset
    from rvdiag.gears.pin_wear import pin_wear_table, stage_wear_depth, table_function

    s2 = params.stage2
    drrp, drp, worn = s2.equidistant_modification, s2.offset_modification, stage_wear_depth(params) > 0.0
    if drrp == 0.0 and drp == 0.0 and not worn:
        return P
    k1 = s2.eccentricity * s2.pins / s2.pin_circle_radius
    sense = -1 if mean_load_Nm >= 0.0 else 1
    P[kn.I_PINMOD] = 1.0
    P[kn.I_DRRP], P[kn.I_DRP] = drrp, drp
    if not worn:
        P[kn.I_CLOSE] = closing_offset(k1, drrp, drp, sense)
        return P
    table = pin_wear_table(params)
    P[kn.I_CLOSE] = closing_offset(k1, drrp, drp, sense, extra=table_function(table))
    P[kn.I_PINWEAR], P[kn.I_NPINWEAR] = float(P.size), float(table.size)
    return np.concatenate([P, table])


def pack_model_arrays(params: ReducerParams, mesh: MeshTable, sun_speed_hz: float, load_Nm: float,
                      st: ModelSettings, profile: SpeedProfile | None = None, load: LoadProfile | None = None,
                      duration_s: float | None = None) -> dict:
    """The keyword arguments of :class:`rvdiag.dynamics.model.Model` (all but ``settings``) at one operating
    point; the arguments are those of :func:`rvdiag.dynamics.model.build_model`, validated here."""
    s1, s2, br, dmp = params.stage1, params.stage2, params.bearings, params.damping
    positive(sun_speed_hz, "input speed", unit=" Hz")
    number(load_Nm, "load torque")
    bp = body_properties(params)
    N, D = s1.n_planets, s2.n_discs
    Zp, Zc, Z1, Z2 = s2.pins, s2.cycloid_lobes, s1.sun_teeth, s1.planet_teeth
    alpha = math.radians(s1.pressure_angle_deg)
    rb1 = 0.5 * s1.module * Z1 * math.cos(alpha)
    rb2 = 0.5 * s1.module * Z2 * math.cos(alpha)
    omega_s = TWO_PI * sun_speed_hz
    Omega = omega_s / params.ratio
    a = s1.centre_distance

    drive = params.drive
    motor = drive.speed_loop_bandwidth_hz > 0.0
    J_L = load_inertia(params, load)
    has_load = J_L > 0.0
    lay = dof_layout(N, D, motor, has_load)
    n = lay["pin_wheel"] + 3 + (1 if motor else 0) + (1 if has_load else 0)
    mass = np.empty(n)

    def put(body: str, m: float, J: float) -> None:
        i = lay[body]
        mass[i], mass[i + 1], mass[i + 2] = m, m, J

    put("sun", bp.sun.mass, bp.sun.inertia)
    for i in range(N):
        put(f"planet{i}", bp.planet.mass, bp.planet.inertia)
        put(f"crank{i}", bp.crank.mass, bp.crank.inertia)
    for j in range(D):
        put(f"disc{j}", bp.cycloid.mass, bp.cycloid.inertia)
    put("carrier", bp.carrier.mass, bp.carrier.inertia)
    if motor:
        mass[lay["motor"]] = drive.motor_inertia
    if has_load:
        mass[lay["load"]] = J_L
    # the pin wheel carries the housing shell and the mounting flange ([mounting] housing_added_mass, a thin
    # ring at the outer radius)
    m_add = params.mounting.housing_added_mass
    put("pin_wheel", bp.pin_wheel.mass + m_add,
        bp.pin_wheel.inertia + m_add * params.bodies.pin_wheel_outer_radius**2)

    zb = dmp.bearing_damping_ratio if st.damping else 0.0
    zm = dmp.mesh_damping_ratio if st.damping else 0.0
    zp = dmp.pin_damping_ratio if st.damping else 0.0

    def c(zeta: float, k: float, m1: float, m2: float | None = None) -> float:
        meq = m1 if m2 is None else m1 * m2 / (m1 + m2)
        return 2.0 * zeta * math.sqrt(k * meq)

    profile = profile or SpeedProfile()
    load = load or LoadProfile()
    profile.validate(duration_s)
    load.validate()
    k_pin = pin_contact_stiffness(params, _linearisation_load(profile, load, load_Nm, Omega, duration_s))
    k_rt = br.pin_wheel_torsional
    tv = mesh.resample(st.tvms_points)
    k_mean = float(np.mean(tv))
    J_s, J_p = bp.sun.inertia, bp.planet.inertia
    m_mesh = J_s * J_p / (J_s * rb2**2 + J_p * rb1**2)  # Kahraman's equivalent mesh mass
    # effective inertia of the whole train reflected to the sun (rigid kinematics), for the input coupling
    g_pl = Z1 / Z2  # planet (and crank) speed relative to carrier per sun speed relative to carrier
    J_eff = (J_s + N * (J_p + bp.crank.inertia) * g_pl**2
             + (bp.carrier.inertia + D * bp.cycloid.inertia) / params.ratio**2)

    P = np.zeros(kn.N_P)
    P[kn.I_NPL], P[kn.I_NDISC], P[kn.I_ZP], P[kn.I_ZC], P[kn.I_Z1] = N, D, Zp, Zc, Z1
    P[kn.I_OMEGA], P[kn.I_WREL], P[kn.I_A] = Omega, omega_s - Omega, a
    P[kn.I_E], P[kn.I_RP] = s2.eccentricity, s2.pin_circle_radius
    P[kn.I_ALPHA], P[kn.I_RB1], P[kn.I_RB2], P[kn.I_HALF_BACKLASH] = alpha, rb1, rb2, 0.5 * s1.backlash
    P[kn.I_SINA], P[kn.I_COSA] = math.sin(alpha), math.cos(alpha)
    P[kn.I_KSS], P[kn.I_CSS] = br.sun_support, c(zb, br.sun_support, bp.sun.mass)
    P[kn.I_KIN], P[kn.I_CIN] = br.input_torsional, c(zb, br.input_torsional, J_eff)
    P[kn.I_KCC], P[kn.I_CCC] = br.crank_carrier, c(zb, br.crank_carrier, bp.crank.mass, bp.carrier.mass)
    P[kn.I_KCD], P[kn.I_CCD] = br.crank_cycloid, c(zb, br.crank_cycloid, bp.crank.mass, bp.cycloid.mass)
    kpr = br.planet_crank_radial
    P[kn.I_KPR], P[kn.I_CPR] = kpr, c(zb, kpr, bp.planet.mass, bp.crank.mass)
    P[kn.I_KPT], P[kn.I_CPT] = br.planet_crank_torsional, c(zb, br.planet_crank_torsional, J_p, bp.crank.inertia)
    P[kn.I_KHS], P[kn.I_CHS] = br.carrier_support, c(zb, br.carrier_support, bp.carrier.mass)
    P[kn.I_KRH], P[kn.I_CRH] = br.pin_wheel_housing, c(zb, br.pin_wheel_housing, mass[lay["pin_wheel"]])
    P[kn.I_KRT], P[kn.I_CRT] = k_rt, c(zb, k_rt, mass[lay["pin_wheel"] + 2])
    P[kn.I_KPIN], P[kn.I_CPIN] = k_pin, c(zp, k_pin, bp.cycloid.mass, mass[lay["pin_wheel"]])
    P[kn.I_CMESH] = c(zm, k_mean, m_mesh)
    P[kn.I_IRAMP] = 1.0 / MESH_DAMPING_RAMP_M
    if motor:
        # speed PI of the servo drive on the rotor (docs/model.md section 3): a damper c = J w_c and a spring
        # k = c w_c / 4 (PI corner at a quarter of the bandwidth), tuned on the rotor plus the train reflected to
        # it; the steady drive torque T_L / i holds the static rotor angle at zero
        w_c = TWO_PI * drive.speed_loop_bandwidth_hz
        # a load inertia counts as well, reflected to the rotor: the drive is tuned for the joint it drives
        c_sl = (drive.motor_inertia + J_eff + J_L / params.ratio**2) * w_c
        P[kn.I_MOTOR] = 1.0
        P[kn.I_CSL] = c_sl if st.damping else 0.0
        P[kn.I_KSL] = c_sl * w_c / 4.0
        P[kn.I_TDRIVE] = load_Nm / params.ratio
    P[kn.I_TLOAD] = load_Nm
    P[kn.I_RATIO] = params.ratio
    # the drive's acceleration feed-forward: i J_ref, J_ref the inertia of the rigid train reflected to the rotor
    # (kinetic energy J_ref (i Omega)^2 / 2; docs/model.md section 2)
    P[kn.I_JREF_I] = params.ratio * (
        (drive.motor_inertia if motor else 0.0) + J_s + (
            N * (Zc**2 * (J_p + bp.crank.inertia) + a**2 * (bp.planet.mass + bp.crank.mass))
            + D * (bp.cycloid.inertia + bp.cycloid.mass * (s2.eccentricity * Zc) ** 2)
            + bp.carrier.inertia + J_L) / params.ratio**2)
    if has_load:
        # the output coupling (docs/model.md sections 3, 4): spring k_out = [bearings] output_torsional between
        # carrier and load, its damper on the reduced inertia of the load and the rigid train reflected to the
        # output (rotor included), as the input coupling's is on the train reflected to the sun
        J_train = P[kn.I_JREF_I] * params.ratio - J_L  # i^2 J_ref without the load
        P[kn.I_LOAD] = 1.0
        P[kn.I_KOUT] = br.output_torsional
        P[kn.I_COUT] = c(zb, br.output_torsional, J_L, J_train)
    if not profile.is_constant or load.has_arm:
        P[kn.I_PROFILE] = 1.0
        if not profile.is_constant:
            ts, ta, tc, acc, w = profile.segments(duration_s)
            if abs(w - Omega) > 1e-9 * Omega:
                raise ParameterError(f"the {profile.kind}'s cruise speed ({profile.output_speed_deg_s} deg/s) differs from "
                                     "the operating point's output speed")
            P[kn.I_PROFILE] = 3.0 if profile.kind == "scurve" else 2.0
            P[kn.I_PR_TS], P[kn.I_PR_TA], P[kn.I_PR_TC], P[kn.I_PR_ACC] = ts, ta, tc, acc
            P[kn.I_PR_TJ], P[kn.I_PR_JERK] = profile.jerk_segment()
            P[kn.I_PR_F0] = float(profile._cumulative(np.zeros(1), duration_s)[0][0])
        M, L = float(load.arm_mass_kg), float(load.arm_length_m)
        # with a load DOF the arm's inertia is that DOF's (its rigid acceleration torque J_L dOmega/dt is the load
        # DOF's nominal angular acceleration, and the drive's feed-forward has it through J_ref): the load torque
        # keeps only the gravity term
        P[kn.I_ARM_MGL], P[kn.I_ARM_ML2] = M * G * L, (0.0 if has_load else M * L * L)
        P[kn.I_ARM_TH0] = math.radians(load.arm_angle_deg)
    if st.electrical:
        _pack_motor(P, params, motor, Omega, load_Nm, profile, load, duration_s)
    P[kn.I_TFROZEN] = -1.0 if st.excitation else 0.0
    P[kn.I_CORIOLIS] = 1.0 if st.coriolis else 0.0
    P[kn.I_BETA0] = 0.0
    P[kn.I_DISCPHASE] = math.radians(s2.disc_phase_deg)
    P[kn.I_CPH], P[kn.I_SPH] = math.cos(P[kn.I_DISCPHASE]), math.sin(P[kn.I_DISCPHASE])
    pitches = s2.disc_phase_deg / (360.0 / Zp)
    P[kn.I_GSHARED] = 1.0 if abs(pitches - round(pitches)) < 1e-12 else 0.0
    P[kn.I_NTVMS] = tv.size
    R_out = params.bodies.pin_wheel_outer_radius
    sp = st.sensor_point_m or (R_out, 0.0)
    P[kn.I_SENSX], P[kn.I_SENSY] = sp
    P[kn.I_NCH] = len(st.sensor_directions)
    P[kn.I_DISPLIM] = st.max_displacement_m
    P = _pack_profile_modification(P, params, _mean_load(profile, load, load_Nm, Omega, duration_s))
    P[kn.I_ROTLIM] = st.max_rotation_rad

    psi = TWO_PI * np.arange(N) / N
    errs = draw_manufacturing_errors(params)
    planet, P = _pack_manufacturing_errors(P, errs, psi, alpha, Zp, pitches)
    kk = TWO_PI * np.arange(Zp) / Zp
    sensor = np.array([np.asarray(d, float) / math.hypot(*d) for d in st.sensor_directions])
    extra = {"k_pin_N_per_m": k_pin, "k_mesh_mean_N_per_m": k_mean, "carrier_speed_rad_s": Omega,
             "ratio": params.ratio, "manufacturing": errs}
    pk, pe = mesh.resample_pairs(st.tvms_points)
    P[kn.I_NSLOT] = pk.shape[0]
    return dict(P=P, mass=mass, planet=planet, tvms=tv, cosk=np.cos(kk), sink=np.sin(kk), sensor=sensor,
                n_planets=N, n_discs=D, mesh_source=mesh.source, extra=extra,
                tvms_error=mesh.resample_error(st.tvms_points), pairs=np.stack([pk, pe], axis=1))


def load_inertia(params: ReducerParams, load: LoadProfile | None = None) -> float:
    """The load inertia J_L (kg m^2) of the load DOF (docs/model.md section 1): ``[operation] load_inertia`` when
    the parameter set states it, else the gravity arm's point-mass inertia ``M L^2`` when ``load`` has an arm,
    else 0 (no load DOF: the load is a pure torque on the carrier)."""
    stated = params.operation.load_inertia
    if stated is not None:
        J = float(stated)
        if not (math.isfinite(J) and J >= 0.0):
            raise ParameterError(f"[operation] load_inertia must be finite and >= 0, got {stated!r}")
        return J
    if load is not None and load.has_arm:
        return float(load.arm_mass_kg) * float(load.arm_length_m) ** 2
    return 0.0


def _pack_manufacturing_errors(P: np.ndarray, errs: ManufacturingErrors, psi: np.ndarray, alpha: float, Zp: int,
                               pitches: float) -> tuple[np.ndarray, np.ndarray]:
    """The planet table and ``P`` with the reducer's manufacturing errors (:mod:`rvdiag.dynamics.manufacturing`;
    docs/model.md section 3).

    ``planet[i] = (cos psi, sin psi, sin(alpha - psi), cos(alpha - psi), A_i, B_i, eps_r, eps_t, Delta_i)``: the
    runout's transmission error ``e_i sin(b_0 + phi_i + alpha) = A_i cos b_0 + B_i sin b_0``, the crank hole's
    position error and the crank's eccentric angle error.  The pins' radius errors and the fixed-frame groove
    errors ``v_x, v_y`` are appended to ``P`` (each twice over, so the kernel indexes ``k + shift`` without a wrap),
    ``P[I_PINERR]`` their start.  ``P[I_MFG]`` and ``P[I_PINERR]`` stay 0 without errors, and the kernels then run
    the code of the model without them."""
    N = psi.size
    e, ph = np.asarray(errs.runout), np.asarray(errs.runout_angle)
    planet = np.column_stack([np.cos(psi), np.sin(psi), np.sin(alpha - psi), np.cos(alpha - psi),
                              e * np.sin(ph + alpha), e * np.cos(ph + alpha), np.asarray(errs.hole_radial),
                              np.asarray(errs.hole_tangential), np.asarray(errs.crank_phase)])
    if len(errs.runout) != N or len(errs.pin_radius) != Zp:
        raise ParameterError("manufacturing errors: one per planet and one per pin")
    P[kn.I_MFG] = 0.0 if errs.planets_zero else 1.0
    P[kn.I_PINSHIFT] = float(round(pitches) % Zp) if abs(pitches - round(pitches)) < 1e-12 else 0.0
    if errs.pins_zero:
        return planet, P
    P[kn.I_PINERR] = float(P.size)
    rho, vx, vy = errs.pin_offsets_fixed_frame()
    return planet, np.concatenate([P, np.tile(rho, 2), np.tile(vx, 2), np.tile(vy, 2)])


def _pack_motor(P: np.ndarray, params: ReducerParams, has_rotor: bool, Omega: float, load_Nm: float,
                profile: SpeedProfile, load: LoadProfile, duration_s: float | None) -> None:
    """The motor's electrical side in ``P`` (``[motor]``; :mod:`rvdiag.dynamics.motor_kernel`), after the
    operating point is checked against the motor's current and voltage limits
    (:func:`rvdiag.motor.check_operating_point`)."""
    from rvdiag.motor import check_operating_point, controller_gains

    if not has_rotor:
        raise ParameterError("the motor's electrical model needs the motor rotor: set [drive] "
                             "speed_loop_bandwidth_hz > 0")
    m = params.motor
    pp = params.operation.motor_pole_pairs
    g = controller_gains(m, pp)
    acc = 0.0 if profile.is_constant else abs(profile.segments(duration_s)[3])
    arm = float(load.arm_mass_kg) * float(load.arm_length_m)
    torque = ((abs(load_Nm) + arm * G + P[kn.I_ARM_ML2] * acc) / params.ratio
              + P[kn.I_JREF_I] * acc + m.viscous_friction * params.ratio * Omega)
    check_operating_point(m, pp, params.ratio * Omega, torque)
    P[kn.I_PMSM] = 1.0
    P[kn.I_M_P], P[kn.I_M_R], P[kn.I_M_LD], P[kn.I_M_LQ] = pp, m.resistance, m.inductance_d, m.inductance_q
    P[kn.I_M_PSI], P[kn.I_M_B] = m.flux_linkage, m.viscous_friction
    P[kn.I_M_KPC], P[kn.I_M_KIC], P[kn.I_M_VMAX] = g.kp_current, g.ki_current, g.voltage_limit
    P[kn.I_M_UDT], P[kn.I_M_IDT] = g.dead_time_voltage, m.dead_time_current
    P[kn.I_M_QENC], P[kn.I_M_L1], P[kn.I_M_L2] = g.encoder_quantum, g.observer_l1, g.observer_l2
    P[kn.I_M_IMAX], P[kn.I_M_KT] = m.max_current, g.torque_constant
    P[kn.I_M_EENC] = math.radians(m.encoder_error_arcsec / 3600.0)
