"""Dynamics of the RV reducer: the lumped-parameter model (:mod:`~rvdiag.dynamics.model`), its compiled integrators
(:mod:`~rvdiag.dynamics.integrate`: Kutta's 3/8 rule by default, classical RK4 on request) and ``simulate``
(:mod:`~rvdiag.dynamics.simulation`, re-exported here: ``from rvdiag.dynamics import simulate``).
"""

from __future__ import annotations

from rvdiag.dynamics.mesh import MeshTable
from rvdiag.dynamics.model import Model, ModelSettings, build_model
from rvdiag.dynamics.noise import add_awgn
from rvdiag.dynamics.profile import LoadProfile, SpeedProfile
from rvdiag.dynamics.results import SimulationResult
from rvdiag.dynamics.simulation import (CURRENT_CHANNELS, CURRENT_UNITS, SIGNALS, PreparedSimulation,
                                        current_record_margin, initial_deflection, mesh_table, motor_current_record,
                                        prepare, prepare_simulation, simulate, SimulationRequest,
                                        with_load_inertia)

#: The revision of the simulated physics: the date of the last deliberate change to what a simulation returns for
#: the same parameters (bumped with it; what each revision changed: bench/HISTORY.md, "Physics revisions").
#: Library stores record it in their hashed config, so a build never resumes a store simulated by other physics.
PHYSICS_REVISION = "2026-11-28"

__all__ = [
    "PHYSICS_REVISION",
    "LoadProfile", "MeshTable", "Model", "ModelSettings", "SimulationResult", "SpeedProfile", "add_awgn", "build_model",
    "mesh_table", "prepare", "prepare_simulation", "PreparedSimulation", "simulate", "SimulationRequest",
    "CURRENT_CHANNELS", "CURRENT_UNITS", "SIGNALS", "current_record_margin", "initial_deflection",
    "motor_current_record", "with_load_inertia",
]
