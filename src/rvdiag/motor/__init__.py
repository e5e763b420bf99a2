"""The servo motor: a PMSM under i_d = 0 vector control driving the reducer's sun (docs/model.md section 10).

The compiled rates of its electrical side live with the reducer's kernels (:mod:`rvdiag.dynamics.motor_kernel`);
this package holds the design side: controller gains, operating-point checks, the phase currents
(:mod:`rvdiag.motor.pmsm`), and the line table of a measured or simulated phase current (:mod:`rvdiag.motor.lines`).
"""

from rvdiag.deprecation import renamed_names
from rvdiag.motor.pmsm import (ControllerGains, check_operating_point, controller_gains, current_rate_ratio,
                               phase_currents, sample_current)
from rvdiag.motor.lines import current_lines, output_speed_from_current

__all__ = ["ControllerGains", "check_operating_point", "controller_gains", "current_lines", "current_rate_ratio",
           "output_speed_from_current", "phase_currents", "sample_current"]

#: old names, served with a DeprecationWarning naming the new one
__getattr__ = renamed_names(__name__, {"estimate_output_speed": "output_speed_from_current"})
