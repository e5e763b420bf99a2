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
  we add it to the 26 DOF of the dynamics paper's model).

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
import threading
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
I_NSLOT = 52  # tooth-pair slots of each sun-planet mesh (rows of Model.tables: k, e, c per slot)
I_IRAMP = 53  # 1 / MESH_DAMPING_RAMP_M
I_MOTOR = 54  # 1.0: a motor rotor DOF (the last coordinate) on the input shaft, held by the speed loop
I_KSL, I_CSL, I_TDRIVE = 55, 56, 57  # speed-loop spring and damper on the rotor, its steady drive torque
N_P = 58

#: approach (m) over which a tooth pair's damper grows from nothing to its full value once the flanks touch
#: (a penetration-dependent damper, Hunt & Crossley 1975, J. Appl. Mech. 42, in its simplest, linear-ramp form):
#: the contact force then starts from zero as the flanks meet, instead of jumping by c * (approach rate), so a
#: pair touching or leaving within a step costs RK4 much less accuracy (docs/model.md section 7)
MESH_DAMPING_RAMP_M = 0.1e-6

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
        at rtol 1e-9 over 0.05 s at 48 kHz with the default method (figures under ``method``;
        docs/model.md section 7, tests/test_integrator.py); at other rates keep ``fs * substeps`` near
        430 kHz.
        A sample is further cut at the mesh table's kinks (:func:`table_events`), so a step may be
        shorter than ``1 / (fs substeps)``.
    method : str
        ``"rk38"`` (default): Kutta's 3/8 rule, the pin geometry exact at its three stage times per step;
        ``"rk4"``: classical RK4, stage times t, t + h/2, t + h (pin geometry exact three times per sample,
        interpolated in between; ~7 % faster).  Both on the same step grid.  With the tooth-pair contacts
        (pairs that touch and part as their separations are crossed, docs/model.md section 3) the 3/8 rule
        stays within 1e-3 of DOP853 at 9 sub-steps from 45 deg/s to 4500 rpm (6.2e-4 at 45 deg/s 100 N m,
        2.7e-4 at 1000 rpm 167 N m, 4.2e-4 at 3000 rpm and 7.3e-4 at 4500 rpm 50 N m) and RK4 does not
        above ~2500 rpm (9.0e-4, 1.3e-3, 2.2e-3 at 1000, 3000, 4500 rpm); before the tooth-pair contacts RK4 was
        the default (6.0e-4 to 7.3e-4).  Higher-order (Butcher 6, Verner 6(5), DOP853 fixed-step) and
        low-dispersion schemes (Berland et al. 2006 RK4-6) were measured and do not do better per right-hand
        side on this non-smooth model (docs/model.md section 7).
    transient_s : float
        Simulated time discarded before output starts (start-up transient), s.
    segment_s : float
        ``0`` (default): the record is one continuous integration.  ``> 0``: the record is cut into
        segments of this length (s), each integrated from its own static start ``transient_s`` ahead of
        it, so that the segments are independent and can run at once (``simulate(workers=...)``,
        :mod:`rvdiag.dynamics.segments`).  The damped model forgets its start: with the default 0.1 s
        run-in a segment differs from the continuous run by ~1e-7 (relative L2), far below the
        integrator's 1e-3.  The output depends on ``segment_s``, never on the number of workers.
        Needs damping on and ``transient_s > 0``.
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
    segment_s: float = 0.0
    method: str = "rk38"
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
        if not (math.isfinite(self.segment_s) and self.segment_s >= 0):
            raise ParameterError(f"segment_s must be >= 0, got {self.segment_s!r}")
        if self.segment_s > 0 and not (self.damping and self.transient_s > 0):
            raise ParameterError("segment_s > 0 needs damping on and transient_s > 0: a segment starts "
                                 "from rest and must forget that start before it is recorded")
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


def dof_layout(n_planets: int, n_discs: int, motor: bool = False) -> dict[str, int]:
    """Index of the first (x) coordinate of every body: ``{"sun": 0, "planet0": 3, ...}``; with ``motor``, the
    motor rotor's single coordinate (its rotation) comes last."""
    out = {"sun": 0}
    for i in range(n_planets):
        out[f"planet{i}"] = 3 + 3 * i
    for i in range(n_planets):
        out[f"crank{i}"] = 3 + 3 * n_planets + 3 * i
    for j in range(n_discs):
        out[f"disc{j}"] = 3 + 6 * n_planets + 3 * j
    out["carrier"] = 3 + 6 * n_planets + 3 * n_discs
    out["pin_wheel"] = out["carrier"] + 3
    if motor:
        out["motor"] = out["pin_wheel"] + 3
    return out


def dof_names(n_planets: int, n_discs: int, motor: bool = False) -> list[str]:
    """Names of the generalized coordinates, e.g. ``sun.x``, ``planet1.th``, ``pin_wheel.y``, ``motor.th``."""
    names: list[str] = []
    for body in dof_layout(n_planets, n_discs):
        names += [f"{body}.x", f"{body}.y", f"{body}.th"]
    if motor:
        names.append("motor.th")
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
    #: ``(S, 2, n)``: stiffness (N/m) and separation (m) of each of the S tooth-pair slots on the grid of
    #: ``tvms`` (:meth:`rvdiag.dynamics.mesh.MeshTable.resample_pairs`); ``None``: one slot, ``tvms`` with
    #: ``tvms_error`` as its separation
    pairs: np.ndarray | None = None
    #: ``(4 S + 2, n)`` C-contiguous ``[k_0..k_S-1, e_0..e_S-1, c_0..c_S-1, e'_0..e'_S-1, tvms, tvms_error]``: the
    #: per-slot stiffness, separation, damping ``c_s = c_mesh sqrt(k_s / mean(tvms))`` (a damping ratio held
    #: per pair, so a pair out of contact has no damper either) and separation slope per table interval
    #: (:func:`separation_slopes`), and the nominal TVMS and load-shared separation that the bilateral
    #: (linearised) model uses: the mesh table the compiled kernels take
    tables: np.ndarray = field(init=False, repr=False, compare=False)
    #: ``1 / mass``: the kernels multiply by it (a division per coordinate costs ~15 % of a right-hand side)
    inv_mass: np.ndarray = field(init=False, repr=False, compare=False)
    #: sorted phases in [0, 1) of a relative sun revolution at which some planet's mesh reaches a kink of
    #: the table (:func:`table_events`); the integrator puts step boundaries there
    events: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        k = np.asarray(self.tvms, dtype=float)
        e = np.zeros_like(k) if self.tvms_error is None else np.asarray(self.tvms_error, dtype=float)
        if e.shape != k.shape or not np.all(np.isfinite(e)):
            raise ParameterError("tvms_error must be finite and on the same grid as tvms")
        object.__setattr__(self, "tvms_error", e)
        if self.pairs is None:
            pairs = np.stack([k, e])[None, :, :]
        else:
            pairs = np.asarray(self.pairs, dtype=float)
            if pairs.ndim != 3 or pairs.shape[1] != 2 or pairs.shape[2] != k.size:
                raise ParameterError("pairs must have shape (slots, 2, len(tvms))")
        object.__setattr__(self, "pairs", pairs)
        kmean = float(np.mean(k)) if np.mean(k) > 0 else 1.0
        damp = self.P[I_CMESH] * np.sqrt(np.clip(pairs[:, 0, :], 0.0, None) / kmean)
        object.__setattr__(self, "tables", np.ascontiguousarray(
            np.concatenate([pairs[:, 0, :], pairs[:, 1, :], damp, separation_slopes(pairs), k[None, :], e[None, :]])))
        if self.P[I_NSLOT] != pairs.shape[0]:
            self.P[I_NSLOT] = pairs.shape[0]
        object.__setattr__(self, "inv_mass", 1.0 / np.asarray(self.mass, dtype=float))
        object.__setattr__(self, "events", table_events(self.tables, self.n_planets))

    @property
    def n_dof(self) -> int:
        return self.mass.size

    @property
    def has_motor(self) -> bool:
        """True when the last coordinate is the motor rotor's rotation (``[drive]`` speed loop on)."""
        return bool(self.P[I_MOTOR] != 0.0)

    @property
    def names(self) -> list[str]:
        return dof_names(self.n_planets, self.n_discs, self.has_motor)

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


def _replace_P(m: Model, P: np.ndarray) -> Model:
    return Model(P, m.mass, m.planet, m.tvms, m.cosk, m.sink, m.sensor, m.n_planets, m.n_discs,
                 m.mesh_source, m.settings, m.extra, m.tvms_error, m.pairs)


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

    drive = params.drive
    motor = drive.speed_loop_bandwidth_hz > 0.0
    lay = dof_layout(N, D, motor)
    n = lay["pin_wheel"] + 3 + (1 if motor else 0)
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
    P[I_KRH], P[I_CRH] = br.pin_wheel_housing, c(zb, br.pin_wheel_housing, mass[lay["pin_wheel"]])
    P[I_KRT], P[I_CRT] = k_rt, c(zb, k_rt, mass[lay["pin_wheel"] + 2])
    P[I_KPIN], P[I_CPIN] = k_pin, c(zp, k_pin, bp.cycloid.mass, mass[lay["pin_wheel"]])
    P[I_CMESH] = c(zm, k_mean, m_mesh)
    P[I_IRAMP] = 1.0 / MESH_DAMPING_RAMP_M
    if motor:
        # speed PI of the servo drive on the rotor (docs/model.md section 3): a damper c = J w_c and a spring
        # k = c w_c / 4 (PI corner at a quarter of the bandwidth), tuned on the rotor plus the train reflected to
        # it; the steady drive torque T_L / i holds the static rotor angle at zero
        w_c = TWO_PI * drive.speed_loop_bandwidth_hz
        c_sl = (drive.motor_inertia + J_eff) * w_c
        P[I_MOTOR] = 1.0
        P[I_CSL] = c_sl if st.damping else 0.0
        P[I_KSL] = c_sl * w_c / 4.0
        P[I_TDRIVE] = load_Nm / params.ratio
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
    pk, pe = mesh.resample_pairs(st.tvms_points)
    P[I_NSLOT] = pk.shape[0]
    return Model(P, mass, planet, tv, np.cos(kk), np.sin(kk), sensor, N, D, mesh.source, st, extra,
                 tvms_error=mesh.resample_error(st.tvms_points), pairs=np.stack([pk, pe], axis=1))


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
    for j in range(ng):
        for r in range(3):
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
    load-shared separation (bilateral model).  Computed once per
    distinct stage time by the integrator and shared by the stages that use it.
    """
    te = eval_time(t, P)
    N = int(P[I_NPL])
    S = int(P[I_NSLOT])
    nt = tvms.shape[1]
    inv_n = 1.0 / N
    x0 = P[I_WREL] * te * (1.0 / TWO_PI)
    erate = P[I_WREL] * nt * (1.0 / TWO_PI) if P[I_TFROZEN] < 0.0 else 0.0
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
def _pin_sums(geo, g, ux, uy, th, wx, wy, om, kp, cp, dlim, flo):
    """Sums of F n_x, F n_y and F l over the pins of one disc, F = max(k d + c d', flo) where d > dlim,
    else 0.

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
        f = max(kp * d + cp * (wx * nx + wy * ny + om * lk), flo)
        f = f if d > dlim else 0.0
        sx += f * nx
        sy += f * ny
        sm += f * lk
    return sx, sy, sm


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")
def _pin_sums_pair(geo, ux, uy, th, wx, wy, om, vx, vy, ph, zx, zy, ps, kp, cp, dlim, flo):
    """:func:`_pin_sums` for two discs that share pin geometry 0, in one fused pass (one load of the
    geometry for both discs)."""
    s0x = s0y = s0m = s1x = s1y = s1m = 0.0
    for k in range(geo.shape[2]):
        nx = geo[0, 0, k]
        ny = geo[0, 1, k]
        lk = geo[0, 2, k]
        d = ux * nx + uy * ny + th * lk
        f = max(kp * d + cp * (wx * nx + wy * ny + om * lk), flo)
        f = f if d > dlim else 0.0
        d2 = vx * nx + vy * ny + ph * lk
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
def generalized_forces(y, P, planet, mt, geo, rot, Q):
    """Generalized forces Q(t, q, v) of all springs, contacts, dampers and the external torques.

    ``y = [q, v]`` (the first-order state; ``Q`` has ``n = y.size / 2`` entries).  ``mt`` must hold
    :func:`mesh_terms` and ``geo, rot`` :func:`pin_geometry` at the same ``t``.  The equations are in
    docs/model.md.  Each sun-planet mesh force is ``k g(delta - e) + c (delta' - e')`` with the
    deviation ``e`` (transmission-error excitation, Kahraman & Singh 1990).

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
    iM = n - 1
    qm = y[iM] if mot else 0.0
    vm = y[n + iM] if mot else 0.0
    # input shaft between the motor rotor (or the ideal speed source) and the sun
    T_sh = P[I_KIN] * (y[2] - qm) + P[I_CIN] * (y[n + 2] - vm)
    S2 = -T_sh
    if mot:  # the rotor: drive torque, speed loop, and the shaft's reaction
        Q[iM] = P[I_TDRIVE] - P[I_KSL] * qm - P[I_CSL] * vm + T_sh
    # ---- carrier: support, load torque
    qH0 = y[iH]
    qH1 = y[iH + 1]
    qH2 = y[iH + 2]
    vH0 = y[n + iH]
    vH1 = y[n + iH + 1]
    vH2 = y[n + iH + 2]
    H0 = -(P[I_KHS] * qH0 + P[I_CHS] * vH0)
    H1 = -(P[I_KHS] * qH1 + P[I_CHS] * vH1)
    H2 = -P[I_TLOAD]
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
            dx = ucx + qc2 * tx - y[idd] + qd2 * asp
            dy = ucy + qc2 * ty - y[idd + 1] - qd2 * acp
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
    jd = 0
    while jd < D:
        a0, a1, a2, a3, a4, a5 = _disc_frame(jd, y, n, rot, iD0, qR0, qR1, qR2, vR0, vR1, vR2, rr)
        if gsh and jd + 1 < D:
            b0, b1, b2, b3, b4, b5 = _disc_frame(jd + 1, y, n, rot, iD0, qR0, qR1, qR2, vR0, vR1, vR2, rr)
            s0x, s0y, s0m, s1x, s1y, s1m = _pin_sums_pair(
                geo, a0, a1, a2, a3, a4, a5, b0, b1, b2, b3, b4, b5, kp, cp, dlim, dlim)
            r0, r1, r2 = _apply_pin_sums(jd, s0x, s0y, s0m, iD0, rr, rot, Q)
            R0 += r0
            R1 += r1
            R2 += r2
            r0, r1, r2 = _apply_pin_sums(jd + 1, s1x, s1y, s1m, iD0, rr, rot, Q)
            jd += 2
        else:
            sx, sy, sm = _pin_sums(geo, 0 if gsh else jd, a0, a1, a2, a3, a4, a5, kp, cp, dlim, dlim)
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
    Om = P[I_OMEGA]
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


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def rhs_with_terms(y, P, inv_mass, planet, mt, geo, rot, Q, dydt):
    """First-order right-hand side dy/dt, y = [q, v], from the time-varying terms precomputed at the
    stage time (:func:`mesh_terms`, :func:`pin_geometry`); ``inv_mass`` is ``Model.inv_mass``."""
    n = Q.size & 65535
    for i in range(n):
        dydt[i] = y[n + i]
    accelerations(y, P, inv_mass, planet, mt, geo, rot, Q, dydt)


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def rhs(t, y, P, inv_mass, planet, tvms, cosk, sink, geo, rot, mt, Q, dydt):
    """First-order right-hand side dy/dt computing the time-varying terms itself (for scipy and checks)."""
    pin_geometry(t, P, cosk, sink, geo, rot)
    mesh_terms(t, P, tvms, mt)
    rhs_with_terms(y, P, inv_mass, planet, mt, geo, rot, Q, dydt)


_kernels_loaded = False
_kernels_lock = threading.Lock()


def load_kernels(model: Model) -> None:
    """Compile (or load from numba's cache) the kernels that other kernels call, callees first; once per
    process, before any kernel runs.

    Why the order matters: numba links a callee's code into each caller's library as a weak symbol.  In a
    process that compiles, the callee is compiled on its own first and every caller's call binds to that
    standalone copy.  In a process that loads the caller from the cache, the standalone copy is absent and
    the call binds to the caller's private copy: the same source, compiled in another context, which with
    the kernels' fast-math flags (reassociation, FMA contraction) rounds differently in the last bits.
    Runs were thus bit-identical within a compile mode but not across one (9e-14 relative for T6 at
    45 deg/s, 2e-9 at 3000 rpm where the broken-tooth impacts amplify it; bench/HISTORY.md, fourth pass,
    "the same bits from a fresh compile and from the cache").  Loading the standalone callees first, with
    the argument types the callers use, makes a cache-loaded process bind as a compiling one does
    (``tests/test_integrator.py::test_output_is_identical_from_a_fresh_compile_and_from_the_cache``).
    """
    global _kernels_loaded
    if _kernels_loaded:
        return
    with _kernels_lock:
        if _kernels_loaded:
            return
        geo, rot, Q = work_arrays(model)
        mt = mesh_array(model)
        y = np.zeros(2 * model.n_dof)
        eval_time(0.0, model.P)
        frame_angles(0.0, model.P)
        pin_geometry_cs(1.0, 0.0, 1.0, 0.0, model.P, model.cosk, model.sink, geo, rot)
        pin_geometry(0.0, model.P, model.cosk, model.sink, geo, rot)
        mesh_terms(0.0, model.P, model.tables, mt)
        rhs_with_terms(y, model.P, model.inv_mass, model.planet, mt, geo, rot, Q, np.empty_like(y))
        _kernels_loaded = True


def work_arrays(model: Model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fresh (geo, rot, Q) work arrays for :func:`rhs`; ``Q`` holds the n generalized forces."""
    return (np.zeros((model.n_discs, 3, model.cosk.size)), np.zeros((model.n_discs, 4)),
            np.zeros(model.n_dof))


def mesh_array(model: Model) -> np.ndarray:
    """A fresh ``(n_planets, 4 slots + 2)`` array for :func:`mesh_terms`."""
    return np.zeros((model.n_planets, 4 * int(model.P[I_NSLOT]) + 2))


def make_rhs(model: Model):
    """A Python callable ``f(t, y) -> dy/dt`` on the compiled right-hand side (for scipy.solve_ivp)."""
    load_kernels(model)
    geo, rot, Q = work_arrays(model)
    mt = mesh_array(model)
    m = model

    def f(t: float, y: np.ndarray) -> np.ndarray:
        out = np.empty_like(y)
        rhs(float(t), np.ascontiguousarray(y, dtype=np.float64), m.P, m.inv_mass, m.planet, m.tables,
            m.cosk, m.sink, geo, rot, mt, Q, out)
        return out

    return f


@numba.njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def _forces_at(t, y, P, planet, tvms, cosk, sink, geo, rot, mt, Q):
    pin_geometry(t, P, cosk, sink, geo, rot)
    mesh_terms(t, P, tvms, mt)
    generalized_forces(y, P, planet, mt, geo, rot, Q)


def forces(model: Model, t: float, q: np.ndarray, v: np.ndarray | None = None) -> np.ndarray:
    """Generalized forces Q(t, q, v) (Python wrapper, for static and linear analysis)."""
    load_kernels(model)
    geo, rot, Q = work_arrays(model)
    q = np.asarray(q, float)
    v = np.zeros_like(q) if v is None else np.asarray(v, float)
    _forces_at(float(t), np.concatenate([q, v]), model.P, model.planet, model.tables, model.cosk,
               model.sink, geo, rot, mesh_array(model), Q)
    return Q.copy()


def sensor_acceleration(model: Model, acc: np.ndarray) -> np.ndarray:
    """Housing acceleration at the sensor point along each sensor direction, from the DOF accelerations.

    The pin wheel is the housing part of the model: a point r on it accelerates by
    ``a_r + alpha_r z x r`` (small rotations), projected on each direction.
    """
    iR = dof_layout(model.n_planets, model.n_discs)["pin_wheel"]
    acc = np.asarray(acc)
    ax = acc[..., iR] - acc[..., iR + 2] * model.P[I_SENSY]
    ay = acc[..., iR + 1] + acc[..., iR + 2] * model.P[I_SENSX]
    return np.stack([d[0] * ax + d[1] * ay for d in model.sensor], axis=0)
