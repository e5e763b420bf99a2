"""Monitoring a joint against its own healthy baseline: the one home of monitoring (docs/monitoring.md).

Use::

    from rvdiag.workflows import load_model, read_record
    from rvdiag.monitoring import make_baseline, open_baseline, monitor_record

    model = load_model("monitor")                        # a monitor that ``rvdiag train`` wrote, loaded once
    base = open_baseline("joint3-baseline.zarr", model)  # the joint's commissioning records, opened once
    # or: base = make_baseline([read_record(f) for f in files], model=model, out="joint3-baseline.zarr",
    #                          operating_points=[{"output_speed_deg_s": 30.0, "load_Nm": 50.0}] * len(files))
    res = monitor_record(model, read_record("joint3/2026-11-28.npy"), base, load=50.0)
    res.alarm, res.health_index, res.state_name, res.to_dict(), res.plot()

Modules
-------
========================  ==================================================================================
``detector``              :class:`BaselineMonitor`: health index, alarm at a stated false-alarm rate (conformal,
                          CV+), most probable state and what changed; :func:`save_monitor` writes it
``pairing``               which store is paired, each monitored record's baseline records at the nearest
                          operating point (:func:`match_baseline`), the features of the pairs, one row per record
``baseline``              :class:`Baseline`, :func:`open_baseline`, :func:`make_baseline`: a joint's baseline,
                          checked against the model
``diagnosis``             :func:`monitor_record` -> :class:`MonitorResult`: one record against its baseline, with
                          the checks that it is recognised
``training``              :func:`train_monitor`, :func:`evaluate_monitor` on a paired store
``life``                  :func:`evaluate_life`: change detection and remaining life over a life store's
                          histories (``rvdiag evaluate --life``)
``crack``                 the crack detector with a joint's twin (:mod:`rvdiag.monitoring.crack`): its references
                          simulated at commissioning (:func:`~rvdiag.monitoring.crack.commission_crack_references`),
                          :func:`~rvdiag.monitoring.crack.load_twin`, ``diagnose`` / ``evaluate --twin``
                          (docs/twin.md)
========================  ==================================================================================

The baseline-referenced *features* (:class:`rvdiag.features.relative.BaselineReferencedFeatures`, the TSA change,
the motor-current lines) stay in :mod:`rvdiag.features`: they are signal features that take arrays and know
nothing of stores or models, :mod:`rvdiag.features` is a lower layer than this package (a feature set of the
classifiers could use them too), and saved monitors name them by their module (skops type names, the trusted list
of :mod:`rvdiag.registry`).  This package sits above :mod:`rvdiag.models`, :mod:`rvdiag.datasets` and
:mod:`rvdiag.workflows` (whose :func:`rvdiag.workflows.read_record` and record checks it uses), below the command
line.  A monitor saved when :class:`BaselineMonitor` lived in ``rvdiag.models.monitoring`` loads as before
(:data:`rvdiag.registry.MOVED_TYPES`).
"""

from __future__ import annotations

from rvdiag.monitoring.baseline import Baseline, make_baseline, needs_baseline, open_baseline, reducer_type
from rvdiag.monitoring.detector import BaselineMonitor, save_monitor
from rvdiag.monitoring.diagnosis import MonitorResult, monitor_record
from rvdiag.monitoring.life import evaluate_life
from rvdiag.monitoring.pairing import is_paired, match_baseline, paired_features, record_means
from rvdiag.monitoring.training import evaluate_monitor, train_monitor

__all__ = ["Baseline", "BaselineMonitor", "MonitorResult", "evaluate_life", "evaluate_monitor", "is_paired", "make_baseline",
           "match_baseline", "monitor_record", "needs_baseline", "open_baseline", "paired_features", "record_means",
           "reducer_type", "save_monitor", "train_monitor"]
