"""Prognostics: change detection with a stated lifetime false-alarm probability and remaining life with intervals,
on a joint's sequence of record scores / health indices (it consumes the monitor's outputs, never signals).

- :mod:`rvdiag.prognostics.change`: conformal test martingale (Ville's bound), CUSUM and Page-Hinkley.
- :mod:`rvdiag.prognostics.rul`: the exponential degradation model and linear extrapolation, Monte Carlo to the
  failure threshold.
- :mod:`rvdiag.prognostics.prognosis`: :func:`joint_prognosis`, the fleet's entry point.
- :mod:`rvdiag.prognostics.synthetic`: life histories with known truth (wear by Archard, a root crack by Paris' law)
  for validation.
- :mod:`rvdiag.prognostics.metrics`: :func:`~rvdiag.prognostics.metrics.life_metrics`, the figures over joints'
  lives (lifetime false alarms, detection delay, the remaining life's interval coverage and alpha-lambda accuracy)
  that ``rvdiag evaluate --life`` and ``bench/prognostics.py`` report.
"""

from rvdiag.prognostics.change import ConformalMartingale, Cusum, Detection, DetectorState, PageHinkley, Persistence
from rvdiag.prognostics.prognosis import Prognosis, joint_prognosis, model_for_state
from rvdiag.prognostics.rul import ASSUMPTION, RulEstimate, estimate_rul

__all__ = ["ASSUMPTION", "ConformalMartingale", "Cusum", "Detection", "DetectorState", "PageHinkley", "Persistence",
           "Prognosis", "RulEstimate", "estimate_rul", "joint_prognosis", "model_for_state"]
