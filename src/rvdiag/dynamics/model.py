"""Equations of motion of the lumped-parameter RV-reducer model (sun-planet stage + cycloid-pin stage).

The derivation (Lagrange, frames, every relative displacement and the parameter each term uses) is
written out in ``docs/model.md``; the symbols below follow it.  Summary:

Degrees of freedom (``3 + 6 N + 3 D + 3 + 3`` = 27 for N = 2 planets, D = 2 discs), all *vibratory*
displacements about the rigid-body motion at constant speed:

- sun ``(x_s, y_s, th_s)``, carrier ``(x_H, y_H, th_H)`` and discs ``(x_dj, y_dj, th_dj)`` in the frame
  rotating with the carrier at ``Omega``;
- planets ``(x_pi, y_pi, th_pi)`` and crank shafts ``(x_ci, y_ci, th_ci)`` in frames orbiting with
  planet i (x radial, y tangential);
- pin wheel ``(x_r, y_r, th_r)`` in the fixed housing frame (its rotation, on the stiff housing support,
  carries the stage-2 reaction torque to the housing, where the sensor sits; see docs/model.md for why
  we add it to the 26 DOF of the issue).

Forces: sun-planet meshes along the line of action with the TVMS table and a backlash dead zone
(Kahraman & Singh 1990); planet-crank spline (radial + torsional); crank-carrier and crank-cycloid
bearings (isotropic linear springs); every cycloid-pin contact (Hertz line contact stiffness
linearised at the operating load, Johnson 1985, from :mod:`rvdiag.gears.cycloid`; compression only, normal through the pitch point: Litvin &
Feng 1996; lever arm e Zc sin(eta) / sqrt(1 + K1^2 - 2 K1 cos(eta)), Blanche & Yang 1989); pin wheel
and carrier supports; input coupling to the motor turning at constant speed; load torque on the
carrier.  Rotating-frame terms ``m (u'' + 2 Omega z x u' - Omega^2 u)`` and the nominal centripetal
accelerations of orbiting bodies are included.  Viscous damping ``c = 2 zeta sqrt(k m_eq)``.

Everything is passed to the compiled kernels as flat float64 arrays (``P``, ``mass``, ``planet``,
``tvms``, ``cosk``, ``sink``) so the kernels hold no global state and model objects pickle; the
kernels' ``tvms`` argument is ``Model.tables`` (stiffness and profile deviation, shape ``(2, n)``;
``(1, n)``, stiffness only, when the deviation is zero).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numba
import numpy as np

from rvdiag.dynamics.mesh import MeshTable
from rvdiag.errors import ParameterError
from rvdiag.params import ReducerParams, body_properties

# ---------------------------------------------------------------------------------------- P layout
I_NPL, I_NDISC, I_ZP, I_ZC, I_Z1 = 0, 1, 2, 3, 4
I_OMEGA, I_WREL, I_A, I_E, I_RP = 5, 6, 7, 8, 9
I_ALPHA, I_RB1, I_RB2, I_HALF_BACKLASH = 10, 11, 12, 13
I_KSS, I_CSS, I_KIN, I_CIN = 14, 15, 16, 17
I_KCC, I_CCC, I_KCD, I_CCD = 18, 19, 20, 21
I_KPR, I_CPR, I_KPT, I_CPT = 22, 23, 24, 25
I_KHS, I_CHS, I_KRH, I_CRH, I_KRT, I_CRT = 26, 27, 28, 29, 30, 31
I_KPIN, I_CPIN, I_CMESH, I_TLOAD = 32, 33, 34, 35
I_TFROZEN, I_CORIOLIS, I_BETA0, I_DISCPHASE = 36, 37, 38, 39
I_NTVMS, I_SENSX, I_SENSY, I_NCH = 40, 41, 42, 43
I_DISPLIM = 44
I_BILATERAL = 45
I_GSHARED = 46
I_SINA, I_COSA = 47, 48
I_ROTLIM = 49
I_CPH, I_SPH = 50, 51  # cos and sin of the disc phase
N_P = 52

TWO_PI = 2.0 * math.pi

#: LLVM fast-math flags of the compiled kernels: reassociation (vectorised reductions), fused
#: multiply-add contraction and signed-zero freedom only.  No ``nnan``/``ninf``: the integrator's
#: instability check must still see NaN and inf.  Results stay deterministic (same code, same order).
FASTMATH = {"reassoc", "contract", "nsz"}


@dataclass(frozen=True)
class ModelSettings:
    """Model and integrator settings that are not reducer parameters (all picklable, all recorded).

    Parameters
    ----------
    substeps : int
        Runge-Kutta steps per output sample.  The stiffest mode of the RV-20E is near 34 kHz (crank
        shafts); RK4 is stable for ``omega h < 2.78``, so at 48 kHz at least 2 are needed.  Accuracy,
        not stability, sets the default 9: the output stays within 1e-3 (relative L2) of scipy's DOP853
        at rtol 1e-9 over 0.05 s at 48 kHz (8.6e-4; 8 sub-steps: 1.18e-3, 10: 7.0e-4; 8.4e-4 at
        1000 rpm rated load; docs/model.md section 7, tests/test_integrator.py); at other rates keep
        ``fs * substeps`` near 430 kHz.
    method : str
        ``"rk4"`` (default): classical RK4, stage times t, t + h/2, t + h (two pin geometries per
        step).  ``"rk38"``: Kutta's 3/8 rule, same order and stability, 25-30 % smaller error at the
        same sub-steps (9: 6.0e-4) but three pin geometries per step (~5 % more CPU per step); at 8
        sub-steps it is 3 % cheaper than RK4 at 9 but not reliably within 1e-3 (9.3e-4 to 1.05e-3
        over three operating points), hence not the default.  Higher-order (Butcher 6, Verner 6(5),
        DOP853 fixed-step) and low-dispersion schemes (Berland et al. 2006 RK4-6) were measured and
        do not do better per right-hand side on this non-smooth model (docs/model.md section 7).
    transient_s : float
        Simulated time discarded before output starts (start-up transient), s.
    sensor_point_m : tuple of 2 floats or None
        Measurement point on the housing in the fixed frame (m); ``None`` puts it on the pin-wheel
        outer radius at angle 0.
    sensor_directions : tuple of (dx, dy)
        One output channel per direction (normalised); default x and y.
    excitation : bool
        ``False`` freezes every time-varying term (TVMS, contact geometry, disc unbalance) at t = 0:
        an autonomous, conservative-when-undamped system, used for energy and modal checks.
    damping : bool
        ``False`` sets every viscous damping coefficient to zero.
    coriolis : bool
        ``False`` drops the rotating-frame terms (Coriolis and centripetal of the vibratory motion).
    tvms_points : int
        Points of the uniform TVMS table over one relative sun revolution.
    chunk_samples : int
        Output samples computed per compiled call (memory stays flat; progress reported per chunk).
    max_displacement_m : float
        A vibratory displacement larger than this is taken as instability (growth without bound).
    max_rotation_rad : float
        A vibratory rotation larger than this is taken as instability (the small-rotation model is
        meaningless long before).
    """

    substeps: int = 9
    transient_s: float = 0.1
    method: str = "rk4"
    sensor_point_m: tuple[float, float] | None = None
    sensor_directions: tuple[tuple[float, float], ...] = ((1.0, 0.0), (0.0, 1.0))
    excitation: bool = True
    damping: bool = True
    coriolis: bool = True
    tvms_points: int = 11 * 360
    chunk_samples: int = 48000
    max_displacement_m: float = 1.0e-2
    max_rotation_rad: float = 0.5

    def __post_init__(self) -> None:
        if int(self.substeps) != self.substeps or self.substeps < 1:
            raise ParameterError(f"substeps must be a whole number >= 1, got {self.substeps!r}")
        if self.method not in ("rk4", "rk38"):
            raise ParameterError(f"method must be 'rk4' or 'rk38', got {self.method!r}")
        if not (math.isfinite(self.transient_s) and self.transient_s >= 0):
            raise ParameterError(f"transient_s must be >= 0, got {self.transient_s!r}")
        if len(self.sensor_directions) < 1:
            raise ParameterError("give at least one sensor direction")
        for d in self.sensor_directions:
            if len(d) != 2 or not math.hypot(*d) > 0:
                raise ParameterError(f"sensor direction {d!r} must be a non-zero (dx, dy) pair")
        if self.sensor_point_m is not None and len(self.sensor_point_m) != 2:
            raise ParameterError("sensor_point_m must be an (x, y) pair in metres")
        if self.tvms_points < 16 or self.chunk_samples < 1:
            raise ParameterError("tvms_points must be >= 16 and chunk_samples >= 1")
        if not (self.max_displacement_m > 0 and self.max_rotation_rad > 0):
            raise ParameterError("max_displacement_m and max_rotation_rad must be > 0")

    def to_dict(self) -> dict:
        """Plain dict (JSON-able) of every setting."""
        d = asdict(self)
        d["sensor_directions"] = [list(x) for x in self.sensor_directions]
        if self.sensor_point_m is not None:
            d["sensor_point_m"] = list(self.sensor_point_m)
        return d


#: Pin stiffness is linearised at ``max(|T_L|, PIN_LOAD_FLOOR_FRACTION * rated torque)``: the Hertz
#: tangent stiffness vanishes (logarithmically) at zero load, where a linearisation means nothing.
PIN_LOAD_FLOOR_FRACTION = 0.01
#: crank angles (over one pin pitch) averaged in :func:`pin_contact_stiffness`
PIN_STIFFNESS_ANGLES = 8


def pin_contact_stiffness(params: ReducerParams, load_Nm: float) -> float:
    """Cycloid-pin contact stiffness (N/m) linearised at the operating load, one value for every pin.

    The per-pin tangent stiffness is the Hertz line contact of the pin on the disc flank at its share
    of the load (Johnson 1985, *Contact Mechanics*, sec. 5.6; load shared in proportion to the lever
    arm, Blagojevic et al. 2011, J. Mech. Des. 133, eq. 11), as computed by
    :func:`rvdiag.gears.cycloid.pin_contact`.  The torque one disc carries about its own centre is the
    pin-wheel reaction ``T_L (1 - 1/i)`` (docs/model.md, sec. 5) times the arm ratio ``Zc / Zp``
    (arms ``e Zc n_y`` about the disc, ``e Zp n_y`` about the pin wheel), shared by the ``D`` discs:
    ``T_d = |T_L| (1 - 1/i) Zc / (Zp D)``.  The pins in contact act on the disc's rocking in parallel
    through their arms, so the equivalent uniform stiffness is the arm-weighted mean
    ``k = sum k_i l_i^2 / sum l_i^2`` (same disc torsional stiffness), averaged over
    ``PIN_STIFFNESS_ANGLES`` crank angles across one pin pitch (it varies by < 0.5 %).  For the RV-20E
    at rated torque (167 N m) this is 3.4e8 N/m, 2.3e8 at 1 N m: the Hertz stiffness of a loaded pin,
    against the load-independent 1.78e9 of Yang & Sun's ``pi E b / (4 (1 - nu^2))``.
    """
    from rvdiag.gears.cycloid import pin_contact

    s2 = params.stage2
    load = max(abs(float(load_Nm)), PIN_LOAD_FLOOR_FRACTION * params.operation.rated_torque)
    t_disc = load * (1.0 - 1.0 / params.ratio) * s2.cycloid_lobes / (s2.pins * s2.n_discs)
    vals = []
    for ang in np.arange(PIN_STIFFNESS_ANGLES) * (TWO_PI / s2.pins / PIN_STIFFNESS_ANGLES):
        c = pin_contact(s2, params.material, float(ang), t_disc)
        l2 = np.where(c.in_contact, c.arm_m, 0.0) ** 2
        vals.append(float(np.sum(c.stiffness_N_per_m * l2) / np.sum(l2)))
    return float(np.mean(vals))


def dof_layout(n_planets: int, n_discs: int) -> dict[str, int]:
    """Index of the first (x) coordinate of every body: ``{"sun": 0, "planet0": 3, ...}``."""
    out = {"sun": 0}
    for i in range(n_planets):
        out[f"planet{i}"] = 3 + 3 * i
    for i in range(n_planets):
        out[f"crank{i}"] = 3 + 3 * n_planets + 3 * i
    for j in range(n_discs):
        out[f"disc{j}"] = 3 + 6 * n_planets + 3 * j
    out["carrier"] = 3 + 6 * n_planets + 3 * n_discs
    out["pin_wheel"] = out["carrier"] + 3
    return out


def dof_names(n_planets: int, n_discs: int) -> list[str]:
    """Names of the generalized coordinates, e.g. ``sun.x``, ``planet1.th``, ``pin_wheel.y``."""
    names: list[str] = []
    for body in dof_layout(n_planets, n_discs):
        names += [f"{body}.x", f"{body}.y", f"{body}.th"]
    return names


@dataclass(frozen=True)
class Model:
    """Assembled model: flat arrays for the compiled kernels plus what produced them."""

    P: np.ndarray
    mass: np.ndarray
    planet: np.ndarray  # (N, 4): cos psi, sin psi, sin(alpha - psi), cos(alpha - psi)
    tvms: np.ndarray
    cosk: np.ndarray
    sink: np.ndarray
    sensor: np.ndarray  # (n_channels, 2) unit directions
    n_planets: int
    n_discs: int
    mesh_source: str
    settings: ModelSettings = field(default_factory=ModelSettings)
    extra: dict = field(default_factory=dict)
    #: mesh profile deviation (transmission-error excitation, m) on the same grid as ``tvms``;
    #: ``None`` means zeros (see :class:`rvdiag.dynamics.mesh.MeshTable`)
    tvms_error: np.ndarray | None = None
    #: ``(2, n)`` C-contiguous ``[tvms, tvms_error]`` (``(1, n)`` when the error is zero): the mesh
    #: table the compiled kernels take
    tables: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        k = np.asarray(self.tvms, dtype=float)
        e = np.zeros_like(k) if self.tvms_error is None else np.asarray(self.tvms_error, dtype=float)
        if e.shape != k.shape or not np.all(np.isfinite(e)):
            raise ParameterError("tvms_error must be finite and on the same grid as tvms")
        object.__setattr__(self, "tvms_error", e)
        # without a deviation the kernels get the stiffness row only and skip the error terms
        rows = [k, e] if np.any(e != 0.0) else [k]
        object.__setattr__(self, "tables", np.ascontiguousarray(np.stack(rows)))

    @property
    def n_dof(self) -> int:
        return self.mass.size

    @property
    def names(self) -> list[str]:
        return dof_names(self.n_planets, self.n_discs)

    def frozen(self, t: float = 0.0) -> "Model":
        """Copy with every time-varying term frozen at time ``t`` (for modal and static analysis)."""
        P = self.P.copy()
        P[I_TFROZEN] = t
        return _replace_P(self, P)

    def with_P(self, **changes: float) -> "Model":
        """Copy with entries of ``P`` changed by name (``I_TLOAD`` -> ``TLOAD=...``)."""
        P = self.P.copy()
        for k, v in changes.items():
            P[globals()[f"I_{k}"]] = v
        return _replace_P(self, P)


def _replace_P(m: Model, P: np.ndarray) -> Model:
    return Model(P, m.mass, m.planet, m.tvms, m.cosk, m.sink, m.sensor, m.n_planets, m.n_discs,
                 m.mesh_source, m.settings, m.extra, m.tvms_error)


def build_model(
    params: ReducerParams,
    mesh: MeshTable,
    sun_speed_hz: float,
    load_Nm: float,
    settings: ModelSettings | None = None,
) -> Model:
    """Assemble the flat parameter arrays of the model at one operating point.

    Parameters
    ----------
    params : ReducerParams
    mesh : MeshTable
        Sun-planet TVMS over one relative sun revolution.
    sun_speed_hz : float
        Input (sun) speed, Hz; the carrier turns at ``sun_speed_hz / i``.
    load_Nm : float
        Output load torque on the carrier (N m), resisting its rotation.
    settings : ModelSettings
    """
    st = settings or ModelSettings()
    s1, s2, br, dmp = params.stage1, params.stage2, params.bearings, params.damping
    if s2.equidistant_modification != 0.0 or s2.offset_modification != 0.0:
        raise ParameterError(
            "the dynamic model supports unmodified cycloid profiles only: set "
            "stage2.equidistant_modification and stage2.offset_modification to 0"
        )
    if not (math.isfinite(sun_speed_hz) and sun_speed_hz > 0):
        raise ParameterError(f"input speed must be > 0, got {sun_speed_hz} Hz")
    if not math.isfinite(load_Nm):
        raise ParameterError(f"load torque must be finite, got {load_Nm}")
    bp = body_properties(params)
    N, D = s1.n_planets, s2.n_discs
    Zp, Zc, Z1, Z2 = s2.pins, s2.cycloid_lobes, s1.sun_teeth, s1.planet_teeth
    alpha = math.radians(s1.pressure_angle_deg)
    rb1 = 0.5 * s1.module * Z1 * math.cos(alpha)
    rb2 = 0.5 * s1.module * Z2 * math.cos(alpha)
    omega_s = TWO_PI * sun_speed_hz
    Omega = omega_s / params.ratio
    a = s1.centre_distance

    lay = dof_layout(N, D)
    n = lay["pin_wheel"] + 3
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
    put("pin_wheel", bp.pin_wheel.mass, bp.pin_wheel.inertia)

    zb = dmp.bearing_damping_ratio if st.damping else 0.0
    zm = dmp.mesh_damping_ratio if st.damping else 0.0
    zp = dmp.pin_damping_ratio if st.damping else 0.0

    def c(zeta: float, k: float, m1: float, m2: float | None = None) -> float:
        meq = m1 if m2 is None else m1 * m2 / (m1 + m2)
        return 2.0 * zeta * math.sqrt(k * meq)

    k_pin = pin_contact_stiffness(params, load_Nm)
    k_rt = br.pin_wheel_torsional
    tv = mesh.resample(st.tvms_points)
    k_mean = float(np.mean(tv))
    J_s, J_p = bp.sun.inertia, bp.planet.inertia
    m_mesh = J_s * J_p / (J_s * rb2**2 + J_p * rb1**2)  # Kahraman's equivalent mesh mass
    # effective inertia of the whole train reflected to the sun (rigid kinematics), for the input coupling
    g_pl = Z1 / Z2  # planet (and crank) speed relative to carrier per sun speed relative to carrier
    J_eff = (J_s + N * (J_p + bp.crank.inertia) * g_pl**2
             + (bp.carrier.inertia + D * bp.cycloid.inertia) / params.ratio**2)

    P = np.zeros(N_P)
    P[I_NPL], P[I_NDISC], P[I_ZP], P[I_ZC], P[I_Z1] = N, D, Zp, Zc, Z1
    P[I_OMEGA], P[I_WREL], P[I_A], P[I_E], P[I_RP] = Omega, omega_s - Omega, a, s2.eccentricity, s2.pin_circle_radius
    P[I_ALPHA], P[I_RB1], P[I_RB2], P[I_HALF_BACKLASH] = alpha, rb1, rb2, 0.5 * s1.backlash
    P[I_SINA], P[I_COSA] = math.sin(alpha), math.cos(alpha)
    P[I_KSS], P[I_CSS] = br.sun_support, c(zb, br.sun_support, bp.sun.mass)
    P[I_KIN], P[I_CIN] = br.input_torsional, c(zb, br.input_torsional, J_eff)
    P[I_KCC], P[I_CCC] = br.crank_carrier, c(zb, br.crank_carrier, bp.crank.mass, bp.carrier.mass)
    P[I_KCD], P[I_CCD] = br.crank_cycloid, c(zb, br.crank_cycloid, bp.crank.mass, bp.cycloid.mass)
    kpr = br.planet_crank_radial
    P[I_KPR], P[I_CPR] = kpr, c(zb, kpr, bp.planet.mass, bp.crank.mass)
    P[I_KPT], P[I_CPT] = br.planet_crank_torsional, c(zb, br.planet_crank_torsional, J_p, bp.crank.inertia)
    P[I_KHS], P[I_CHS] = br.carrier_support, c(zb, br.carrier_support, bp.carrier.mass)
    P[I_KRH], P[I_CRH] = br.pin_wheel_housing, c(zb, br.pin_wheel_housing, bp.pin_wheel.mass)
    P[I_KRT], P[I_CRT] = k_rt, c(zb, k_rt, bp.pin_wheel.inertia)
    P[I_KPIN], P[I_CPIN] = k_pin, c(zp, k_pin, bp.cycloid.mass, bp.pin_wheel.mass)
    P[I_CMESH] = c(zm, k_mean, m_mesh)
    P[I_TLOAD] = load_Nm
    P[I_TFROZEN] = -1.0 if st.excitation else 0.0
    P[I_CORIOLIS] = 1.0 if st.coriolis else 0.0
    P[I_BETA0] = 0.0
    P[I_DISCPHASE] = math.radians(s2.disc_phase_deg)
    P[I_CPH], P[I_SPH] = math.cos(P[I_DISCPHASE]), math.sin(P[I_DISCPHASE])
    pitches = s2.disc_phase_deg / (360.0 / Zp)
    P[I_GSHARED] = 1.0 if abs(pitches - round(pitches)) < 1e-12 else 0.0
    P[I_NTVMS] = tv.size
    R_out = params.bodies.pin_wheel_outer_radius
    sp = st.sensor_point_m or (R_out, 0.0)
    P[I_SENSX], P[I_SENSY] = sp
    P[I_NCH] = len(st.sensor_directions)
    P[I_DISPLIM] = st.max_displacement_m
    P[I_ROTLIM] = st.max_rotation_rad

    psi = TWO_PI * np.arange(N) / N
    planet = np.column_stack([np.cos(psi), np.sin(psi), np.sin(alpha - psi), np.cos(alpha - psi)])
    kk = TWO_PI * np.arange(Zp) / Zp
    sensor = np.array([np.asarray(d, float) / math.hypot(*d) for d in st.sensor_directions])
    extra = {"k_pin_N_per_m": k_pin, "k_mesh_mean_N_per_m": k_mean, "carrier_speed_rad_s": Omega,
             "ratio": params.ratio}
    return Model(P, mass, planet, tv, np.cos(kk), np.sin(kk), sensor, N, D, mesh.source, st, extra,
                 tvms_error=mesh.resample_error(st.tvms_points))


# ================================================================================ compiled kernels


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def eval_time(t, P):
    """Time at which the time-varying terms are evaluated (``t``, or the frozen time)."""
    if P[I_TFROZEN] >= 0.0:
        return P[I_TFROZEN]
    return t


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def pin_geometry(t, P, cosk, sink, geo, rot):
    """Normal (in each disc's eccentric frame) and lever arm of every cycloid-pin contact at time t.

    ``geo[g, 0, k], geo[g, 1, k]`` is the unit normal from the pitch point C to pin k and
    ``geo[g, 2, k] = e Zc n_y`` the lever arm about the disc centre (struct-of-arrays so the contact
    loop vectorises); ``rot[j] = (cos b, sin b, cos B, sin B)``, ``b`` the eccentric angle of disc j in
    the carrier frame and ``B = b + Omega t`` in the fixed frame.  The pin angles relative to the
    eccentric are ``eta_k = eta_0 + 2 pi k / Zp``: one sin/cos per disc, the rest by angle addition
    with the precomputed ``cosk, sink`` (REFERENCE.md section 5).  When the discs' phase is a whole
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
    Om = P[I_OMEGA]
    b0 = P[I_BETA0] - P[I_ZP] * Om * te
    return math.cos(b0), math.sin(b0), math.cos(Om * te), math.sin(Om * te)


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
    D = int(P[I_NDISC])
    nz = cosk.size
    # b_j = b_0 + j phi and B_j = b_j + Omega t by angle addition
    cph = P[I_CPH]
    sph = P[I_SPH]
    cb = cb0
    sb = sb0
    for j in range(D):
        rot[j, 0] = cb
        rot[j, 1] = sb
        rot[j, 2] = cb * cw - sb * sw
        rot[j, 3] = sb * cw + cb * sw
        c = cb * cph - sb * sph
        sb = sb * cph + cb * sph
        cb = c
    ng = 1 if P[I_GSHARED] != 0.0 else D
    for j in range(ng):
        # eta_0 = Zc Omega t - beta0 - j phi = -B_j
        c0 = rot[j, 2]
        s0 = -rot[j, 3]
        gx = geo[j, 0]
        gy = geo[j, 1]
        gl = geo[j, 2]
        for k in range(nz):
            dx = Rp * (c0 * cosk[k] - s0 * sink[k]) - eZp
            dy = Rp * (s0 * cosk[k] + c0 * sink[k])
            inv = 1.0 / math.sqrt(dx * dx + dy * dy)
            gx[k] = dx * inv
            gy[k] = dy * inv
            gl[k] = eZc * dy * inv


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _pin_sums(gx, gy, gl, ux, uy, th, wx, wy, om, kp, cp, bil):
    """Sums of F n_x, F n_y and F l over the pins of one disc, F = k d + c d' where d > 0, else 0.

    Four interleaved partial sums (pins k, k+1, k+2, k+3) break the serial dependency of the
    reduction so the loop runs at throughput, without fast-math reassociation; the order of the
    additions is fixed, so results are deterministic.
    """
    sx0 = sx1 = sx2 = sx3 = 0.0
    sy0 = sy1 = sy2 = sy3 = 0.0
    sm0 = sm1 = sm2 = sm3 = 0.0
    nz = gx.size
    n4 = nz - nz % 4
    for k in range(0, n4, 4):
        d0 = ux * gx[k] + uy * gy[k] + th * gl[k]
        d1 = ux * gx[k + 1] + uy * gy[k + 1] + th * gl[k + 1]
        d2 = ux * gx[k + 2] + uy * gy[k + 2] + th * gl[k + 2]
        d3 = ux * gx[k + 3] + uy * gy[k + 3] + th * gl[k + 3]
        f0 = kp * d0 + cp * (wx * gx[k] + wy * gy[k] + om * gl[k])
        f1 = kp * d1 + cp * (wx * gx[k + 1] + wy * gy[k + 1] + om * gl[k + 1])
        f2 = kp * d2 + cp * (wx * gx[k + 2] + wy * gy[k + 2] + om * gl[k + 2])
        f3 = kp * d3 + cp * (wx * gx[k + 3] + wy * gy[k + 3] + om * gl[k + 3])
        f0 = f0 if (d0 > 0.0 or bil != 0.0) else 0.0
        f1 = f1 if (d1 > 0.0 or bil != 0.0) else 0.0
        f2 = f2 if (d2 > 0.0 or bil != 0.0) else 0.0
        f3 = f3 if (d3 > 0.0 or bil != 0.0) else 0.0
        sx0 += f0 * gx[k]
        sx1 += f1 * gx[k + 1]
        sx2 += f2 * gx[k + 2]
        sx3 += f3 * gx[k + 3]
        sy0 += f0 * gy[k]
        sy1 += f1 * gy[k + 1]
        sy2 += f2 * gy[k + 2]
        sy3 += f3 * gy[k + 3]
        sm0 += f0 * gl[k]
        sm1 += f1 * gl[k + 1]
        sm2 += f2 * gl[k + 2]
        sm3 += f3 * gl[k + 3]
    for k in range(n4, nz):
        d = ux * gx[k] + uy * gy[k] + th * gl[k]
        f = kp * d + cp * (wx * gx[k] + wy * gy[k] + om * gl[k])
        f = f if (d > 0.0 or bil != 0.0) else 0.0
        sx0 += f * gx[k]
        sy0 += f * gy[k]
        sm0 += f * gl[k]
    return (sx0 + sx1) + (sx2 + sx3), (sy0 + sy1) + (sy2 + sy3), (sm0 + sm1) + (sm2 + sm3)


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _pin_sums_pair(gx, gy, gl, ux, uy, th, wx, wy, om, vx, vy, ph, zx, zy, ps, kp, cp, bil):
    """:func:`_pin_sums` for two discs that share one pin geometry, in one fused pass.

    The six sums are plain reductions; the kernels' ``reassoc`` fast-math flag lets LLVM vectorise
    them (bench/HISTORY.md: pin part ~150 -> ~85 ns per right-hand side).  The summation order is
    fixed by the compiled code, so results are deterministic.
    """
    dlim = -np.inf if bil != 0.0 else 0.0
    s0x = s0y = s0m = s1x = s1y = s1m = 0.0
    for k in range(gx.size):
        nx = gx[k]
        ny = gy[k]
        lk = gl[k]
        d = ux * nx + uy * ny + th * lk
        f = kp * d + cp * (wx * nx + wy * ny + om * lk)
        f = f if d > dlim else 0.0
        d2 = vx * nx + vy * ny + ph * lk
        f2 = kp * d2 + cp * (zx * nx + zy * ny + ps * lk)
        f2 = f2 if d2 > dlim else 0.0
        s0x += f * nx
        s0y += f * ny
        s0m += f * lk
        s1x += f2 * nx
        s1y += f2 * ny
        s1m += f2 * lk
    return s0x, s0y, s0m, s1x, s1y, s1m


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def generalized_forces(t, q, v, P, planet, tvms, geo, rot, Q):
    """Generalized forces Q(t, q, v) of all springs, contacts, dampers and the external torques.

    ``geo, rot`` must hold :func:`pin_geometry` at the same ``t``.  The equations are in docs/model.md.
    ``tvms`` is ``Model.tables``, shape ``(2, n)`` or ``(1, n)``: row 0 the mesh stiffness, row 1
    (when present) the profile deviation ``e`` (m) subtracted from each sun-planet mesh deflection, force
    ``k g(delta - e) + c (delta' - e')`` (transmission-error excitation, Kahraman & Singh 1990).
    """
    te = eval_time(t, P)
    N = int(P[I_NPL])
    D = int(P[I_NDISC])
    iC0 = 3 + 3 * N
    iD0 = 3 + 6 * N
    iH = iD0 + 3 * D
    iR = iH + 3
    nq = iR + 3
    for i in range(nq):
        Q[i] = 0.0
    a = P[I_A]
    e = P[I_E]
    # ---- sun: support and input coupling (motor at constant speed), th_s relative to the motor angle
    kss = P[I_KSS]
    css = P[I_CSS]
    Q[0] -= kss * q[0] + css * v[0]
    Q[1] -= kss * q[1] + css * v[1]
    Q[2] -= P[I_KIN] * q[2] + P[I_CIN] * v[2]
    # ---- carrier: support, load torque
    Q[iH] -= P[I_KHS] * q[iH] + P[I_CHS] * v[iH]
    Q[iH + 1] -= P[I_KHS] * q[iH + 1] + P[I_CHS] * v[iH + 1]
    Q[iH + 2] -= P[I_TLOAD]
    # ---- pin wheel on the housing (fixed frame)
    Q[iR] -= P[I_KRH] * q[iR] + P[I_CRH] * v[iR]
    Q[iR + 1] -= P[I_KRH] * q[iR + 1] + P[I_CRH] * v[iR + 1]
    Q[iR + 2] -= P[I_KRT] * q[iR + 2] + P[I_CRT] * v[iR + 2]
    # ---- sun-planet meshes
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
    inv_n = 1.0 / N
    rb1 = P[I_RB1]
    rb2 = P[I_RB2]
    hb = P[I_HALF_BACKLASH]
    cm = P[I_CMESH]
    nt = tvms.shape[1]
    has_e = tvms.shape[0] > 1
    bil = P[I_BILATERAL]
    phi = P[I_WREL] * te
    # d(e)/dt = e'(phi) * w_rel of the profile deviation (table slope per grid step); 0 when frozen
    erate = P[I_WREL] * nt * (1.0 / TWO_PI) if P[I_TFROZEN] < 0.0 else 0.0
    for i in range(N):
        ip = 3 + 3 * i
        ic = iC0 + 3 * i
        cps = planet[i, 0]
        sps = planet[i, 1]
        sap = planet[i, 2]
        cap = planet[i, 3]
        # TVMS at the sun angle relative to planet i
        x = phi * (1.0 / TWO_PI) - i * inv_n
        x = (x - math.floor(x)) * nt
        j0 = int(x)
        fr = x - j0
        if j0 >= nt:
            j0 = 0
        j1 = j0 + 1
        if j1 >= nt:
            j1 = 0
        km = tvms[0, j0] + fr * (tvms[0, j1] - tvms[0, j0])
        d = q[0] * sap + q[1] * cap + rb1 * q[2] - q[ip] * sa - q[ip + 1] * ca + rb2 * q[ip + 2]
        dd = v[0] * sap + v[1] * cap + rb1 * v[2] - v[ip] * sa - v[ip + 1] * ca + rb2 * v[ip + 2]
        if has_e:
            # profile deviation e (transmission-error excitation) reduces the approach: delta - e
            e0 = tvms[1, j0]
            de = tvms[1, j1] - e0
            d -= e0 + fr * de
            dd -= erate * de
        F = 0.0
        if bil != 0.0:
            F = km * (d - bil * hb) + cm * dd
        elif d > hb:
            F = km * (d - hb) + cm * dd
        elif d < -hb:
            F = km * (d + hb) + cm * dd
        Q[0] -= F * sap
        Q[1] -= F * cap
        Q[2] -= F * rb1
        Q[ip] += F * sa
        Q[ip + 1] += F * ca
        Q[ip + 2] -= F * rb2
        # planet-crank spline (radial and torsional), both in the orbiting frame
        for m in range(2):
            f = kpr * (q[ip + m] - q[ic + m]) + cpr * (v[ip + m] - v[ic + m])
            Q[ip + m] -= f
            Q[ic + m] += f
        f = kpt * (q[ip + 2] - q[ic + 2]) + cpt * (v[ip + 2] - v[ic + 2])
        Q[ip + 2] -= f
        Q[ic + 2] += f
        # crank-carrier bearing: d = u_c - R^T u_H - a th_H e_t (orbiting frame)
        dx = q[ic] - (cps * q[iH] + sps * q[iH + 1])
        dy = q[ic + 1] - (-sps * q[iH] + cps * q[iH + 1]) - a * q[iH + 2]
        vx = v[ic] - (cps * v[iH] + sps * v[iH + 1])
        vy = v[ic + 1] - (-sps * v[iH] + cps * v[iH + 1]) - a * v[iH + 2]
        fx = kcc * dx + ccc * vx
        fy = kcc * dy + ccc * vy
        Q[ic] -= fx
        Q[ic + 1] -= fy
        Q[iH] += cps * fx - sps * fy
        Q[iH + 1] += sps * fx + cps * fy
        Q[iH + 2] += a * fy
        # crank-cycloid bearings (carrier frame): d = R u_c + th_c e t_j - u_d - th_d a e_t(psi)
        ucx = cps * q[ic] - sps * q[ic + 1]
        ucy = sps * q[ic] + cps * q[ic + 1]
        vcx = cps * v[ic] - sps * v[ic + 1]
        vcy = sps * v[ic] + cps * v[ic + 1]
        for jd in range(D):
            idd = iD0 + 3 * jd
            tx = -e * rot[jd, 1]
            ty = e * rot[jd, 0]
            dx = ucx + q[ic + 2] * tx - q[idd] + q[idd + 2] * a * sps
            dy = ucy + q[ic + 2] * ty - q[idd + 1] - q[idd + 2] * a * cps
            vx = vcx + v[ic + 2] * tx - v[idd] + v[idd + 2] * a * sps
            vy = vcy + v[ic + 2] * ty - v[idd + 1] - v[idd + 2] * a * cps
            fx = kcd * dx + ccd * vx
            fy = kcd * dy + ccd * vy
            Q[ic] -= cps * fx + sps * fy
            Q[ic + 1] -= -sps * fx + cps * fy
            Q[ic + 2] -= tx * fx + ty * fy
            Q[idd] += fx
            Q[idd + 1] += fy
            Q[idd + 2] += a * (-sps * fx + cps * fy)
    # ---- cycloid-pin contacts, in each disc's eccentric frame
    kp = P[I_KPIN]
    cp = P[I_CPIN]
    rr = P[I_ZP] / P[I_ZC]
    gsh = P[I_GSHARED] != 0.0
    jd = 0
    while jd < D:
        a0, a1, a2, a3, a4, a5 = _disc_frame(jd, q, v, rot, iD0, iR, rr)
        if gsh and jd + 1 < D:
            g = geo[0]
            b0, b1, b2, b3, b4, b5 = _disc_frame(jd + 1, q, v, rot, iD0, iR, rr)
            s0x, s0y, s0m, s1x, s1y, s1m = _pin_sums_pair(
                g[0], g[1], g[2], a0, a1, a2, a3, a4, a5, b0, b1, b2, b3, b4, b5, kp, cp, bil)
            _apply_pin_sums(jd, s0x, s0y, s0m, iD0, iR, rr, rot, Q)
            _apply_pin_sums(jd + 1, s1x, s1y, s1m, iD0, iR, rr, rot, Q)
            jd += 2
        else:
            g = geo[0] if gsh else geo[jd]
            sx, sy, sm = _pin_sums(g[0], g[1], g[2], a0, a1, a2, a3, a4, a5, kp, cp, bil)
            _apply_pin_sums(jd, sx, sy, sm, iD0, iR, rr, rot, Q)
            jd += 1


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _disc_frame(jd, q, v, rot, iD0, iR, rr):
    """Disc-minus-pin-wheel displacement, rotation and their rates in disc jd's eccentric frame."""
    idd = iD0 + 3 * jd
    cb = rot[jd, 0]
    sb = rot[jd, 1]
    cB = rot[jd, 2]
    sB = rot[jd, 3]
    ux = cb * q[idd] + sb * q[idd + 1] - (cB * q[iR] + sB * q[iR + 1])
    uy = -sb * q[idd] + cb * q[idd + 1] - (-sB * q[iR] + cB * q[iR + 1])
    th = q[idd + 2] - rr * q[iR + 2]
    wx = cb * v[idd] + sb * v[idd + 1] - (cB * v[iR] + sB * v[iR + 1])
    wy = -sb * v[idd] + cb * v[idd + 1] - (-sB * v[iR] + cB * v[iR + 1])
    om = v[idd + 2] - rr * v[iR + 2]
    return ux, uy, th, wx, wy, om


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _apply_pin_sums(jd, sx, sy, sm, iD0, iR, rr, rot, Q):
    """Disc jd gets -sum F n and -sum F l; the pin wheel +sum F n and +sum F l Zp/Zc (rotated back)."""
    idd = iD0 + 3 * jd
    cb = rot[jd, 0]
    sb = rot[jd, 1]
    cB = rot[jd, 2]
    sB = rot[jd, 3]
    Q[idd] -= cb * sx - sb * sy
    Q[idd + 1] -= sb * sx + cb * sy
    Q[idd + 2] -= sm
    Q[iR] += cB * sx - sB * sy
    Q[iR + 1] += sB * sx + cB * sy
    Q[iR + 2] += rr * sm


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def accelerations(t, q, v, P, mass, planet, tvms, geo, rot, Q, acc):
    """acc = M^-1 (Q + rotating-frame and nominal inertial terms), the second-order equations."""
    generalized_forces(t, q, v, P, planet, tvms, geo, rot, Q)
    te = eval_time(t, P)
    N = int(P[I_NPL])
    D = int(P[I_NDISC])
    n = q.size
    iR = n - 3
    Om = P[I_OMEGA]
    cor = P[I_CORIOLIS]
    for i in range(n):
        acc[i] = Q[i] / mass[i]
    # nominal centripetal accelerations of orbiting bodies (moved to the right-hand side)
    oa = Om * Om * P[I_A]
    for i in range(N):
        acc[3 + 3 * i] += oa
        acc[3 + 3 * N + 3 * i] += oa
    iD0 = 3 + 6 * N
    wz = P[I_ZC] * Om
    ue = P[I_E] * wz * wz
    for jd in range(D):
        idd = iD0 + 3 * jd
        acc[idd] += ue * rot[jd, 0]
        acc[idd + 1] += ue * rot[jd, 1]
    if cor != 0.0:
        O2 = Om * Om
        for b in range(iR // 3):
            i = 3 * b
            acc[i] += 2.0 * Om * v[i + 1] + O2 * q[i]
            acc[i + 1] += -2.0 * Om * v[i] + O2 * q[i + 1]
    return te


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def rhs_with_geometry(t, y, P, mass, planet, tvms, geo, rot, Q, dydt):
    """First-order right-hand side dy/dt, y = [q, v], using precomputed pin geometry at t."""
    n = mass.size
    q = y[:n]
    v = y[n:]
    for i in range(n):
        dydt[i] = y[n + i]
    accelerations(t, q, v, P, mass, planet, tvms, geo, rot, Q, dydt[n:])


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def rhs(t, y, P, mass, planet, tvms, cosk, sink, geo, rot, Q, dydt):
    """First-order right-hand side dy/dt computing the pin geometry itself (for scipy and checks)."""
    pin_geometry(t, P, cosk, sink, geo, rot)
    rhs_with_geometry(t, y, P, mass, planet, tvms, geo, rot, Q, dydt)


def work_arrays(model: Model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fresh (geo, rot, Q) work arrays for :func:`rhs`; ``Q`` holds the n generalized forces."""
    return (np.zeros((model.n_discs, 3, model.cosk.size)), np.zeros((model.n_discs, 4)),
            np.zeros(model.n_dof))


def make_rhs(model: Model):
    """A Python callable ``f(t, y) -> dy/dt`` on the compiled right-hand side (for scipy.solve_ivp)."""
    geo, rot, Q = work_arrays(model)
    m = model

    def f(t: float, y: np.ndarray) -> np.ndarray:
        out = np.empty_like(y)
        rhs(float(t), np.ascontiguousarray(y, dtype=np.float64), m.P, m.mass, m.planet, m.tables,
            m.cosk, m.sink, geo, rot, Q, out)
        return out

    return f


def forces(model: Model, t: float, q: np.ndarray, v: np.ndarray | None = None) -> np.ndarray:
    """Generalized forces Q(t, q, v) (Python wrapper, for static and linear analysis)."""
    geo, rot, Q = work_arrays(model)
    pin_geometry(float(t), model.P, model.cosk, model.sink, geo, rot)
    v = np.zeros_like(q) if v is None else np.asarray(v, float)
    generalized_forces(float(t), np.asarray(q, float), v, model.P, model.planet, model.tables, geo, rot, Q)
    return Q[: model.n_dof].copy()


def sensor_acceleration(model: Model, acc: np.ndarray) -> np.ndarray:
    """Housing acceleration at the sensor point along each sensor direction, from the DOF accelerations.

    The pin wheel is the housing part of the model: a point r on it accelerates by
    ``a_r + alpha_r z x r`` (small rotations), projected on each direction.
    """
    iR = model.n_dof - 3
    acc = np.asarray(acc)
    ax = acc[..., iR] - acc[..., iR + 2] * model.P[I_SENSY]
    ay = acc[..., iR + 1] + acc[..., iR + 2] * model.P[I_SENSX]
    return np.stack([d[0] * ax + d[1] * ay for d in model.sensor], axis=0)
