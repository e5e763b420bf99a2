"""Progress bars of the ``rvdiag`` command (a ``_`` module: not a command itself).

:func:`progress_bars` shows, on stderr, what the library reports through :mod:`rvdiag.progress` (scoring,
noise levels, EEMD features, MPA / GA / PSO tuning): on a terminal one rich bar per stage with its ETA,
redrawn in place; in a log file one line per finished stage.  ``quiet`` (``-q/--quiet``) turns them off.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from typing import Iterator

from rvdiag.progress import reporting


def stderr_console():
    """The rich console of progress and notes: stderr, so stdout stays the result (``--json``)."""
    from rich.console import Console

    return Console(stderr=True)


def bar_columns() -> list:
    """Description, bar, done/total, elapsed and remaining time (the ETA)."""
    from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    return [TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
            TextColumn("ETA"), TimeRemainingColumn()]


@contextmanager
def progress_bars(quiet: bool) -> Iterator[None]:
    """Show what the calls inside the block report to :mod:`rvdiag.progress`, on stderr."""
    if quiet:
        yield
        return
    console = stderr_console()
    if not console.is_terminal:
        with reporting(_log_lines(console)):
            yield
        return
    from rich.progress import Progress

    with Progress(*bar_columns(), console=console, transient=True) as bars:
        tasks: dict[str, int] = {}
        last: dict[str, int] = {}

        def listener(stage: str, done: int, total: int) -> None:
            if stage not in tasks:
                tasks[stage] = bars.add_task(stage, total=total)
            elif done < last[stage]:  # the stage runs again (the next fit, or predict after fit)
                bars.reset(tasks[stage], total=total)
            last[stage] = done
            bars.update(tasks[stage], completed=done, total=total)

        with reporting(listener):
            yield


def _log_lines(console):
    """A listener that prints ``stage: done/total in T s`` when a stage finishes (for a log file)."""
    started: dict[str, float] = {}
    previous = [time.perf_counter()]  # a stage's first step began at the report before it (or here)

    def listener(stage: str, done: int, total: int) -> None:
        now = time.perf_counter()
        started.setdefault(stage, previous[0])
        previous[0] = now
        if done >= total:
            console.print(f"{stage}: {done}/{total} in {now - started.pop(stage):.1f} s", soft_wrap=True)

    return listener
