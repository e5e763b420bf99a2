"""The synthetic stand-in simulator (:mod:`rvdiag.library.synthetic`), made to last a set time per simulation on
the processes that ask for it: ``RVDIAG_TEST_SIMULATION_DELAY_S`` seconds of sleep before each call (none when the
variable is unset).  The cluster test sets it on its Dask workers only, so that a worker it kills is certainly in
the middle of a simulation, while the in-process reference build runs at full speed; the signals do not depend on
the delay.  Library configs name it ``simulator = "slow_simulator:simulate"`` (the tests folder on the path)."""

from __future__ import annotations

import os
import time

from rvdiag.library import synthetic

#: the library passes its FaultSpec, as to the synthetic simulator
accepts_fault_spec = True

DELAY_VARIABLE = "RVDIAG_TEST_SIMULATION_DELAY_S"


def simulate(*args, **kwargs):
    """:func:`rvdiag.library.synthetic.simulate`, after ``$RVDIAG_TEST_SIMULATION_DELAY_S`` seconds."""
    time.sleep(float(os.environ.get(DELAY_VARIABLE) or 0.0))
    return synthetic.simulate(*args, **kwargs)
