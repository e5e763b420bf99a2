"""The assembled model of one operating point and its Python entry points.

One purpose: :class:`Model` (the flat arrays the compiled kernels take, plus what produced them),
:func:`build_model`, and the Python side of the kernels: :func:`load_kernels` (callees first, so that a fresh
compile and a cache load give the same bits; docs/model.md section 7), :func:`make_rhs` (for scipy),
:func:`forces` (static and linear analysis, section 5) and :func:`sensor_acceleration` (section 6).

The model is split by concern (the equations are derived in docs/model.md):

- :mod:`rvdiag.dynamics.settings`: :class:`ModelSettings`, the settings that are not reducer parameters;
- :mod:`rvdiag.dynamics.layout`: the DOF layout (:func:`dof_layout`, :func:`dof_names`; section 1);
- :mod:`rvdiag.dynamics.kernels`: the numba kernels (geometry, mesh terms, forces, right-hand side) and the
  ``I_*`` indices of ``P`` that they read, generated from :data:`P_FIELDS` (sections 2-4, 7);
- :mod:`rvdiag.dynamics.packing`: ``P``, the masses and the mesh tables from a ``ReducerParams``;
- :mod:`rvdiag.dynamics.numba_cache`: drops stale numba caches when any kernel file changes.

This module re-exports their public names (``mdl.I_*``, ``mdl.N_P``, ``mdl.mesh_terms``, ``mdl.rhs_with_terms``,
``mdl.dof_layout``, ``mdl.ModelSettings``, ``mdl.pin_contact_stiffness``, ...), so that
``from rvdiag.dynamics import model as mdl`` reaches the whole model.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import numpy as np

from rvdiag.dynamics import kernels as kn
from rvdiag.dynamics.kernels import (  # noqa: F401 (re-exported)
    FASTMATH, GEO_ROWS, N_P, P_FIELDS, P_INDEX, TWO_PI, accelerations, eval_time, frame_angles, frame_rotations,
    generalized_forces, interpolate_geometry, mesh_terms, pin_geometry, pin_geometry_cs, rhs, rhs_with_terms)
from rvdiag.dynamics.layout import dof_layout, dof_names
from rvdiag.dynamics.mesh import MeshTable
from rvdiag.dynamics.motor_kernel import N_MOTOR_STATES, motor_rates
from rvdiag.dynamics.profile import LoadProfile, SpeedProfile
from rvdiag.dynamics.packing import (  # noqa: F401 (re-exported)
    EVENT_DEVIATION_KINK, EVENT_STIFFNESS_KINK, MESH_DAMPING_RAMP_M, PIN_LOAD_FLOOR_FRACTION, PIN_STIFFNESS_ANGLES,
    pack_model_arrays, pin_contact_stiffness, separation_slopes, table_events)
from rvdiag.dynamics.settings import ModelSettings
from rvdiag.errors import ParameterError
from rvdiag.params import ReducerParams

# re-export the index constants I_NPL = 0, I_NDISC = 1, ... of kernels.py (mdl.I_TLOAD and so on)
globals().update(kn.INDEX_CONSTANTS)


@dataclass(frozen=True)
class Model:
    """Assembled model: flat arrays for the compiled kernels plus what produced them."""

    P: np.ndarray
    mass: np.ndarray
    #: (N, 9): cos psi, sin psi, sin(alpha - psi), cos(alpha - psi), then the planet's manufacturing errors: runout
    #: coefficients A, B, crank-hole error (radial, tangential), crank phase error (packing._pack_manufacturing_errors)
    planet: np.ndarray
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
        damp = self.P[kn.I_CMESH] * np.sqrt(np.clip(pairs[:, 0, :], 0.0, None) / kmean)
        object.__setattr__(self, "tables", np.ascontiguousarray(
            np.concatenate([pairs[:, 0, :], pairs[:, 1, :], damp, separation_slopes(pairs), k[None, :], e[None, :]])))
        if self.P[kn.I_NSLOT] != pairs.shape[0]:
            self.P[kn.I_NSLOT] = pairs.shape[0]
        object.__setattr__(self, "inv_mass", 1.0 / np.asarray(self.mass, dtype=float))
        object.__setattr__(self, "events", table_events(self.tables, self.n_planets))

    @property
    def n_dof(self) -> int:
        return self.mass.size

    @property
    def has_pmsm(self) -> bool:
        """True when the motor's electrical side (PMSM, current loop, encoder observer) is on: the state
        then ends with its :data:`N_MOTOR_STATES` states (:mod:`rvdiag.dynamics.motor_kernel`)."""
        return bool(self.P[kn.I_PMSM] != 0.0)

    @property
    def n_state(self) -> int:
        """Length of the first-order state ``y = [q, v]`` (plus the motor's electrical states)."""
        return 2 * self.n_dof + (N_MOTOR_STATES if self.has_pmsm else 0)

    def initial_state(self, q0: np.ndarray, t0: float = 0.0) -> np.ndarray:
        """The first-order state that starts a run from the displacements ``q0`` at rest at time ``t0``.

        With the motor's electrical side on, its states start in their steady state for that load: the
        observer on the rotor's angle, ``i_d = 0``, ``i_q`` carrying the speed loop's torque command and the
        current PIs' integrators holding the voltages that keep it (docs/model.md section 10)."""
        q0 = np.asarray(q0, dtype=float)
        y = np.concatenate([q0, np.zeros_like(q0)])
        if not self.has_pmsm:
            return y
        P = self.P
        mt = mesh_array(self)
        mesh_terms(float(t0), P, self.tables, mt)
        t_ff = kn.speed_loop_feed_forward(P, mt)
        qm = float(q0[self.rotor_index])
        i_q = float(np.clip((t_ff - P[kn.I_KSL] * qm) / P[kn.I_M_KT], -P[kn.I_M_IMAX], P[kn.I_M_IMAX]))
        x = np.array([0.0, i_q, 0.0, P[kn.I_M_R] * i_q / P[kn.I_M_KIC], qm, 0.0])
        return np.concatenate([y, x])

    @property
    def has_motor(self) -> bool:
        """True when a coordinate after the pin wheel's is the motor rotor's rotation (``[drive]`` speed loop on)."""
        return bool(self.P[kn.I_MOTOR] != 0.0)

    @property
    def has_load(self) -> bool:
        """True when the last coordinate is the load's rotation ``th_L`` (a load inertia on the output coupling,
        ``[operation] load_inertia``; docs/model.md section 1)."""
        return bool(self.P[kn.I_LOAD] != 0.0)

    @property
    def rotor_index(self) -> int:
        """Index of the motor rotor's coordinate (with :attr:`has_motor`): after the pin wheel's, before the
        load's."""
        return self.n_dof - 2 if self.has_load else self.n_dof - 1

    @property
    def names(self) -> list[str]:
        return dof_names(self.n_planets, self.n_discs, self.has_motor, self.has_load)

    def frozen(self, t: float = 0.0) -> "Model":
        """Copy with every time-varying term frozen at time ``t`` (for modal and static analysis)."""
        P = self.P.copy()
        P[kn.I_TFROZEN] = t
        return _replace_P(self, P)

    def with_P(self, **changes: float) -> "Model":
        """Copy with entries of ``P`` changed by name (``I_TLOAD`` -> ``TLOAD=...``)."""
        P = self.P.copy()
        for k, v in changes.items():
            P[P_INDEX[k]] = v
        return _replace_P(self, P)


def _replace_P(m: Model, P: np.ndarray) -> Model:
    return Model(P, m.mass, m.planet, m.tvms, m.cosk, m.sink, m.sensor, m.n_planets, m.n_discs,
                 m.mesh_source, m.settings, m.extra, m.tvms_error, m.pairs)


def build_model(
    params: ReducerParams,
    mesh: MeshTable,
    sun_speed_hz: float,
    load_Nm: float,
    settings: ModelSettings | None = None,
    profile: SpeedProfile | None = None,
    load: LoadProfile | None = None,
    duration_s: float | None = None,
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
    profile, load : SpeedProfile, LoadProfile, optional
        The output's speed profile (default constant at ``sun_speed_hz / i``; a trapezoid cruises at that speed)
        and the load model (default the constant ``load_Nm``); :mod:`rvdiag.dynamics.profile`.
    duration_s : float, optional
        The record's length, which a trapezoid without ``move_s`` fills.
    """
    st = settings or ModelSettings()
    return Model(**pack_model_arrays(params, mesh, sun_speed_hz, load_Nm, st, profile, load, duration_s), settings=st)


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
        y = np.zeros(model.n_state)
        eval_time(0.0, model.P)
        frame_angles(0.0, model.P)
        pin_geometry_cs(1.0, 0.0, 1.0, 0.0, model.P, model.cosk, model.sink, geo, rot)
        pin_geometry(0.0, model.P, model.cosk, model.sink, geo, rot)
        mesh_terms(0.0, model.P, model.tables, mt)
        ym = np.zeros(2 * model.n_dof + N_MOTOR_STATES)
        motor_rates(ym, model.P, kn.I_PMSM, model.n_dof, model.n_dof - 1, 0.0, 0.0, 0.0, 0.0, 0.0, np.zeros_like(ym))
        rhs_with_terms(y, model.P, model.inv_mass, model.planet, mt, geo, rot, Q, np.empty_like(y))
        _kernels_loaded = True


def work_arrays(model: Model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fresh (geo, rot, Q) work arrays for :func:`rhs`; ``Q`` holds the n generalized forces."""
    return (np.zeros((model.n_discs, GEO_ROWS, model.cosk.size)), np.zeros((model.n_discs, 4)),
            np.zeros(model.n_dof))


def mesh_array(model: Model) -> np.ndarray:
    """A fresh ``(n_planets + 1, 4 slots + 2)`` array for :func:`mesh_terms` (the last row: the speed and load
    profile's time terms)."""
    return np.zeros((model.n_planets + 1, max(6, 4 * int(model.P[kn.I_NSLOT]) + 2)))


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


def forces(model: Model, t: float, q: np.ndarray, v: np.ndarray | None = None) -> np.ndarray:
    """Generalized forces Q(t, q, v) (Python wrapper, for static and linear analysis)."""
    load_kernels(model)
    geo, rot, Q = work_arrays(model)
    q = np.asarray(q, float)
    v = np.zeros_like(q) if v is None else np.asarray(v, float)
    kn._forces_at(float(t), np.concatenate([q, v]), model.P, model.planet, model.tables, model.cosk,
               model.sink, geo, rot, mesh_array(model), Q)
    return Q.copy()


def sensor_acceleration(model: Model, acc: np.ndarray) -> np.ndarray:
    """Housing acceleration at the sensor point along each sensor direction, from the DOF accelerations.

    The pin wheel is the housing part of the model: a point r on it accelerates by
    ``a_r + alpha_r z x r`` (small rotations), projected on each direction.
    """
    iR = dof_layout(model.n_planets, model.n_discs)["pin_wheel"]
    acc = np.asarray(acc)
    ax = acc[..., iR] - acc[..., iR + 2] * model.P[kn.I_SENSY]
    ay = acc[..., iR + 1] + acc[..., iR + 2] * model.P[kn.I_SENSX]
    return np.stack([d[0] * ax + d[1] * ay for d in model.sensor], axis=0)
