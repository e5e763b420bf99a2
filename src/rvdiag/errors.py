"""The one exception hierarchy of rvdiag.

Every error a user can cause by bad input derives from :class:`RvdiagError`.  The ``rvdiag`` command
catches it, prints ``error: <message>`` as one line on stderr and exits with code 2 (see
:mod:`rvdiag.cli`).  Messages name the offending value and, where there is one, the remedy.
"""

from __future__ import annotations


class RvdiagError(Exception):
    """Base class of every rvdiag error that is the user's input, not a bug."""

    exit_code = 2


class ParameterError(RvdiagError, ValueError):
    """A reducer parameter, fault severity or setting is out of its valid range."""


class ConfigError(RvdiagError, ValueError):
    """A configuration file (parameter set, library config) cannot be read or is invalid."""


class GeometryError(ParameterError):
    """The gear or cycloid geometry is impossible (interference, crack deeper than the tooth...)."""


class SimulationError(RvdiagError, RuntimeError):
    """The numerical integration failed (instability, NaN)."""


class StoreError(RvdiagError, OSError):
    """A sample store is missing, corrupt, or was built from a different config."""


class DataFileError(RvdiagError, ValueError):
    """A measured-signal file cannot be read (format, channel, length, NaN...)."""


class ModelFileError(RvdiagError, ValueError):
    """A saved model directory is missing, corrupt, or does not match the data."""


class FleetError(RvdiagError):
    """The fleet store refuses an action: an unknown joint, a joint without a baseline, a database of a newer
    schema, a name that is not site/robot/joint (:mod:`rvdiag.fleet`)."""


class AuthError(FleetError):
    """A write to the fleet without a token, with an unknown one, or with a read-only one.  ``status`` is the HTTP
    status that fits: 401 (missing or unknown) or 403 (read-only)."""

    def __init__(self, message: str, status: int = 401):
        super().__init__(message)
        self.status = status


class RvdiagWarning(UserWarning):
    """Base class of rvdiag's warnings: the result is computed, but the user should know a caveat."""


class ModelRangeWarning(RvdiagWarning):
    """A formula is used outside the range its source fitted or validated (the result is an extrapolation)."""


class FallbackWarning(RvdiagWarning):
    """A value could not be read and a documented default was used instead (the report says so too)."""


class SplitLeakWarning(RvdiagWarning):
    """A train/test split lets one recording contribute to both sides: the test score is optimistic."""


class DeviceWarning(RvdiagWarning):
    """The compute device asked for cannot be used (no GPU, no CUDA support); the work runs on the CPU instead."""
