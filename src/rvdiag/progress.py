"""Progress of long library calls, reported to whoever is listening (the ``rvdiag`` command's progress bars).

A long loop calls :func:`report` (``stage, done, total``); nothing happens unless a caller has installed a
listener with :func:`reporting`.  So estimators keep their scikit-learn parameters (no callback parameter
to save with a model), and the library never prints: the command line draws the bars, with an ETA, on
stderr (:mod:`rvdiag.cli._progress`).  The listener is a context variable: it follows the calling thread, and
a loop that fans out to threads reports from the thread that collects their results.

Reported today: EEMD features over windows (:class:`rvdiag.features.eemd.EEMDFeatures`), the objective
evaluations of the MPA / GA / PSO tuning of the kernel ELM (:mod:`rvdiag.models.tuning`), and the noise
levels of :func:`rvdiag.evaluation.evaluate.accuracy_against_snr`.
"""

from __future__ import annotations

import contextvars
from contextlib import contextmanager
from typing import Callable, Iterator

Listener = Callable[[str, int, int], None]

_listener: contextvars.ContextVar[Listener | None] = contextvars.ContextVar("rvdiag_progress", default=None)


@contextmanager
def reporting(listener: Listener) -> Iterator[None]:
    """Send every :func:`report` of the calls inside the ``with`` block to ``listener(stage, done, total)``."""
    token = _listener.set(listener)
    try:
        yield
    finally:
        _listener.reset(token)


def report(stage: str, done: int, total: int) -> None:
    """``done`` of ``total`` steps of ``stage`` are finished (a no-op when nobody listens)."""
    listener = _listener.get()
    if listener is not None:
        listener(stage, int(done), int(total))


__all__ = ["Listener", "report", "reporting"]
