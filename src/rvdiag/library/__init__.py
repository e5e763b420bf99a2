"""The fault-sample library: eight health states, configs, and parallel resumable builds into a sample store.

- :mod:`rvdiag.library.states`: the states T1..T8 and their severity parameters;
- :mod:`rvdiag.library.config`: library configs (TOML) with validation;
- :mod:`rvdiag.library.build`: the plan of simulations and the Dask build into a
  :class:`rvdiag.datasets.SampleStore`;
- :mod:`rvdiag.library.paired`: paired libraries (``[baseline]``), each reducer recorded at commissioning and later;
- :mod:`rvdiag.library.life`: life histories (``[history]``), each reducer recorded at commissioning and then over
  its life along one drawn fate;
- :mod:`rvdiag.library.synthetic`: a fast analytic stand-in simulator for testing the machinery.

See ``docs/library.md``.
"""

from rvdiag.library.build import BuildReport, Unit, build_library, config_from_store, make_plan, run_unit
from rvdiag.library.config import LibraryConfig, Sweep
from rvdiag.library.states import SEVERITY_PARAMETERS, STATES, FaultSpec, HealthState, tooth_faults

__all__ = [
    "BuildReport", "FaultSpec", "HealthState", "LibraryConfig", "SEVERITY_PARAMETERS", "STATES", "Sweep",
    "Unit", "build_library", "config_from_store", "make_plan", "run_unit", "tooth_faults",
]
