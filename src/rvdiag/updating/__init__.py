"""Model updating: tune the assumed parameters of a reducer model to a measured healthy signal.

- :mod:`rvdiag.updating.objectives`: the similarity scores (PCC of log spectra, envelope spectra or records);
- :mod:`rvdiag.updating.space`: the tuned parameters, their bounds and scales;
- :mod:`rvdiag.updating.tuner`: the seeded global + local search (:func:`update_parameters`);
- :mod:`rvdiag.updating.annotate`: the updated parameter file, every changed value commented.
- :mod:`rvdiag.updating.observability`: which of a reducer's own parameters (sun tooth errors, runouts, path,
  stiffnesses) a commissioning record can identify: the whitened Jacobian's singular values (docs/twin.md);
- :mod:`rvdiag.updating.specimen`: one joint's own sun tooth errors identified from its commissioning records'
  transmission error between two encoders (``rvdiag update --specimen``, docs/twin.md).
"""

from __future__ import annotations

from rvdiag.updating.objectives import OBJECTIVES, Objective, envelope_spectrum, log_spectrum, pcc
from rvdiag.updating.space import TUNABLE_NAMES, TUNABLES, Tunable, apply_values, bounds_for
from rvdiag.updating.tuner import MIN_PCC_GAIN, MOVED_RTOL, UpdateResult, update_parameters

__all__ = [
    "MIN_PCC_GAIN", "MOVED_RTOL", "OBJECTIVES", "Objective", "TUNABLES", "TUNABLE_NAMES", "Tunable", "UpdateResult", "apply_values",
    "bounds_for", "envelope_spectrum", "log_spectrum", "pcc", "update_parameters",
]
