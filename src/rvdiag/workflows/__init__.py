"""The workflows of rvdiag as a Python API: read a record, load a model, and diagnose, train and evaluate; the
command line only parses options, calls these and prints.  Monitoring against a baseline is
:mod:`rvdiag.monitoring`.

Use::

    from rvdiag.workflows import load_model, read_record

    model = load_model("model")                  # a directory that ``rvdiag train`` wrote; load once, reuse
    rec = read_record("rig/run3_30dps_50Nm.csv", channel="acc_x",
                      meta_regex=r"(?P<speed_dps>\\d+)dps_(?P<load>\\d+)Nm")
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "Record": "rvdiag.workflows.records",
    "read_record": "rvdiag.workflows.records",
    "load_model": "rvdiag.workflows.records",
}


def __getattr__(name: str):
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'rvdiag.workflows' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + list(_EXPORTS))


__all__ = sorted(_EXPORTS)
