"""Deprecated: this module moved to :mod:`rvdiag.evaluation.motor_current_study`.

Importing this old path warns; it will be removed in a later release.
"""

from rvdiag.deprecation import moved_module

__getattr__, __dir__ = moved_module(__name__, "rvdiag.evaluation.motor_current_study")
