"""Warnings of a library build's tasks, carried back to the process that runs the build.

A Dask worker is a process of its own: a warning raised there (a formula used outside its fitted range, say) is
printed by that process in Python's raw format, with a source path, once per worker.  Instead, each task runs
under :func:`caught`, which keeps the warnings its thread raises and returns them with the result; the build's
process re-issues them with :func:`reissue`, so they reach its own warning display (``rvdiag``'s one-line
``warning:``, each distinct message once per command) like any warning of that process.

Thread-safe, unlike :class:`warnings.catch_warnings` (which swaps process-wide state and can leave another
thread's recorder installed when two tasks of a multi-threaded worker overlap): a hook installed once per process
hands each warning to the list of the task running in the same thread, and to the display it replaced otherwise.
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Callable
from typing import Any, TypeVar

T = TypeVar("T")

#: one (category, message) pair per warning a task raised
Caught = tuple[tuple[type[Warning], str], ...]

_local = threading.local()
_install_lock = threading.Lock()


def _keep_or_show(message, category, filename, lineno, file=None, line=None):  # noqa: ANN001
    kept = getattr(_local, "kept", None)
    if kept is None:
        return _keep_or_show.shown_by(message, category, filename, lineno, file, line)
    kept.append((category, str(message)))
    return None


def _install() -> None:
    with _install_lock:
        if warnings.showwarning is not _keep_or_show:
            _keep_or_show.shown_by = warnings.showwarning
            warnings.showwarning = _keep_or_show


def caught(fn: Callable[..., T], *args: Any) -> tuple[T, Caught]:
    """``(fn(*args), the warnings it raised)``; an exception of ``fn`` propagates (its warnings are dropped)."""
    _install()
    outer = getattr(_local, "kept", None)
    _local.kept = []
    try:
        result = fn(*args)
        return result, tuple(_local.kept)
    finally:
        _local.kept = outer


def reissue(warned: Caught) -> None:
    """Warn again, in this process, each warning a task raised elsewhere."""
    for category, message in warned:
        warnings.warn(message, category, stacklevel=2)
