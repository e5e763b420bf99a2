"""Old names of public functions and old paths of moved modules: they keep working, with a
:class:`DeprecationWarning` that names the new one.

A module that renamed a public name serves the old one from its module ``__getattr__`` (PEP 562), so the old
name is in neither ``__all__`` nor ``dir()``, and using it (``from rvdiag.motor import estimate_output_speed``, or
``rvdiag.motor.estimate_output_speed``) warns once per place it is used (Python's default filter)::

    __getattr__ = renamed_names(__name__, {"estimate_output_speed": "output_speed_from_current"})

A module that moved leaves a file at its old path that holds only::

    __getattr__, __dir__ = moved_module(__name__, "rvdiag.features.zscore")

which warns when the old path is imported and serves the new module's public names from then on.
"""

from __future__ import annotations

import importlib
import sys
import warnings
from types import ModuleType
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


def _public_names(module: ModuleType) -> list[str]:
    """What ``from module import *`` imports: its ``__all__``, or else every name not starting with ``_``."""
    names = getattr(module, "__all__", None)
    return list(names) if names is not None else [n for n in vars(module) if not n.startswith("_")]


def moved_module(old: str, new: str) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` (PEP 562) of the module left at ``old`` when its code moved to ``new``.

    Called in the old module's body, it warns once, when the old path is first imported, with a
    :class:`DeprecationWarning` "``old`` is deprecated; use ``new``" that points at the importing line.  Each
    public name of ``new`` (and its ``__all__``, so ``from old import *`` imports what it did) is then the very
    object of ``new``: a pickle that names a class by its old path unpickles to the class itself.  ``new`` is
    imported only when a name is first looked up, so importing the old path imports nothing of a higher layer
    (``rvdiag.models.monitoring`` serves the monitoring layer's detector without the models layer importing it);
    names starting with ``_`` are not served.
    """
    # stacklevel 3: past this function and the old module's body; the import machinery's frames are skipped
    warnings.warn(f"{old} is deprecated; use {new}", DeprecationWarning, stacklevel=3)

    def __getattr__(name: str) -> Any:
        if name == "__all__":
            return _public_names(importlib.import_module(new))
        if not name.startswith("_"):
            try:
                return getattr(importlib.import_module(new), name)
            except AttributeError:
                pass
        raise AttributeError(f"module {old!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(_public_names(importlib.import_module(new)))

    return __getattr__, __dir__
