"""The workflows of rvdiag as a Python API: read a record, load a model, train, evaluate and diagnose; the
command line only parses options, calls these and prints.  Each returns a result object (a dataclass) whose
``to_dict()`` is what the command prints with ``--json`` and whose ``plot()`` draws it.  Monitoring a joint against
its own baseline is :mod:`rvdiag.monitoring`.

Use::

    from rvdiag.workflows import diagnose, evaluate, load_model, read_record, train

    res = train("out/demo.zarr", "out/model", model="svm", features="wpd")   # -> TrainResult
    model = load_model("out/model")              # a directory that ``rvdiag train`` wrote; load once, reuse
    evaluate(model, "out/demo.zarr", split="test").to_dict()["accuracy"]      # -> Evaluation
    rec = read_record("rig/run3_30dps_50Nm.csv", channel="acc_x",
                      meta_regex=r"(?P<speed_dps>\\d+)dps_(?P<load>\\d+)Nm")
    d = diagnose(model, rec)                     # -> Diagnosis: d.state, d.probabilities, d.warnings, d.plot()

========================  ==================================================================================
``records``               :func:`read_record` (as ``dataset from-files`` reads a file), :func:`load_model`, the
                          record's speed, flatness, recognition and state names
``diagnosis``             :func:`diagnose` -> :class:`Diagnosis`
``evaluation``            :func:`evaluate` -> :class:`Evaluation`
``training``              :func:`train` -> :class:`TrainResult`, the estimators of the ``--model`` names
``training_store``        what a model card says of its training store
========================  ==================================================================================
"""

from __future__ import annotations

from rvdiag.workflows.diagnosis import Diagnosis, diagnose, read_model_record
from rvdiag.workflows.evaluation import Evaluation, evaluate
from rvdiag.workflows.records import Record, load_model, read_record
from rvdiag.workflows.training import TrainResult, train

__all__ = ["Diagnosis", "Evaluation", "Record", "TrainResult", "diagnose", "evaluate", "load_model",
           "read_model_record", "read_record", "train"]
