"""Old names of public functions: they keep working, with a :class:`DeprecationWarning` that names the new one.

A module that renamed a public name serves the old one from its module ``__getattr__`` (PEP 562), so the old
name is in neither ``__all__`` nor ``dir()``, and using it (``from rvdiag.motor import estimate_output_speed``, or
``rvdiag.motor.estimate_output_speed``) warns once per place it is used (Python's default filter)::

    __getattr__ = renamed_names(__name__, {"estimate_output_speed": "output_speed_from_current"})
"""

from __future__ import annotations

import sys
import warnings
from typing import Any, Callable


def renamed_names(module: str, old_to_new: dict[str, str]) -> Callable[[str], Any]:
    """The ``__getattr__`` of ``module`` that gives each old name of ``old_to_new`` the object now under its new
    name (a name of the same module), with a :class:`DeprecationWarning` "``module.old`` is deprecated; use
    ``module.new``"; any other name is an :class:`AttributeError`, as without it."""

    def __getattr__(name: str) -> Any:
        if name not in old_to_new:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        new = old_to_new[name]
        warnings.warn(f"{module}.{name} is deprecated; use {module}.{new}", DeprecationWarning, stacklevel=2)
        return getattr(sys.modules[module], new)

    return __getattr__
