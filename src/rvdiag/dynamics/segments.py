"""Time-parallel integration: a long record cut into segments that are integrated at once.

The model is damped, so a run forgets its initial state: started from rest (the static deflection)
``transient_s`` ahead of a time ``t``, it meets the continuous run at ``t`` to ~1e-7 (relative L2 of
the acceleration at 0.1 s run-in; 3e-5 at 0.05 s; ``tests/test_segments.py``).  This is the same argument
by which every run discards its start-up transient.  A record of ``N`` samples is therefore cut into
segments of ``ModelSettings.segment_s``; each segment starts from its own static deflection
``transient_s`` before its first sample and is integrated independently (the step grid of a sample
depends on the sample alone, :func:`rvdiag.dynamics.integrate.sample_breaks`, so only the start differs).

The compiled kernels release the GIL (``nogil=True``), so the segments run on threads.  The output
depends on the segment length only: 1 worker or 16 give the same bits.  The cost is one run-in per
segment (5 % at 2-s segments with the default 0.1 s run-in).  This is parallelism in time for one long
signal; a library of many short signals is parallel across signals instead (:mod:`rvdiag.library`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from rvdiag.dynamics import model as mdl
from rvdiag.dynamics.integrate import MOTOR_CHANNELS, integrate
from rvdiag.errors import ParameterError


def check_workers(workers: object) -> None:
    """Raise :class:`ParameterError` unless ``workers`` is a whole number >= 1."""
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ParameterError(f"workers must be a whole number >= 1, got {workers!r}")


def segment_bounds(n_samples: int, segment_samples: int) -> list[tuple[int, int]]:
    """``(first, count)`` of each segment of a record of ``n_samples`` cut every ``segment_samples``
    (``segment_samples <= 0``: one segment).  A last piece shorter than half a segment joins the one
    before, so no segment pays a whole run-in for a few samples."""
    if segment_samples <= 0 or segment_samples >= n_samples:
        return [(0, n_samples)]
    starts = list(range(0, n_samples, segment_samples))
    if len(starts) > 1 and n_samples - starts[-1] < segment_samples // 2:
        starts.pop()
    ends = starts[1:] + [n_samples]
    return [(a, b - a) for a, b in zip(starts, ends)]


@dataclass(frozen=True)
class SegmentCall:
    """One :func:`rvdiag.dynamics.integrate.integrate` call of a segmented record: from the start state at
    ``t_start`` (s), ``n_transient`` run-in samples, then ``n_samples`` recorded from sample ``first_sample`` on,
    whose rows go to columns ``column .. column + n_samples`` of the record."""

    t_start: float
    n_samples: int
    n_transient: int
    first_sample: int
    column: int


def segment_calls(model: mdl.Model, fs: float, n_samples: int, n_transient: int,
                  margin: tuple[int, int] = (0, 0)) -> list[SegmentCall]:
    """The integrator calls that record ``n_samples`` in segments of ``model.settings.segment_s`` with the record
    ``margin`` (:func:`integrate_segments`, which makes them)."""
    m_lead, m_tail = margin
    seg = int(round(model.settings.segment_s * fs))
    bounds = segment_bounds(n_samples, seg)
    if len(bounds) > 1 and model.P[mdl.I_PROFILE] != 0.0:
        raise ParameterError("time-parallel segments (segment_s > 0) support the constant speed and load only: "
                             "a speed or load profile runs as one segment (segment_s = 0)")
    if m_lead > n_transient:
        raise ParameterError(f"a record margin of {m_lead} samples needs at least as many run-in samples "
                             f"(transient_s), got {n_transient}")
    calls = []
    for i, (first, count) in enumerate(bounds):
        lead = m_lead if i == 0 else 0
        tail = m_tail if i == len(bounds) - 1 else 0
        calls.append(SegmentCall((first - n_transient) / fs, count + lead + tail, n_transient - lead, first - lead,
                                 m_lead + first - lead))
    return calls


def integrate_segments(
    model: mdl.Model,
    fs: float,
    n_samples: int,
    n_transient: int,
    start_state: Callable[[float], np.ndarray],
    workers: int = 1,
    progress: Callable[[int, int], None] | None = None,
    margin: tuple[int, int] = (0, 0),
) -> tuple[np.ndarray, int]:
    """Record ``n_samples`` sensor samples in segments of ``model.settings.segment_s``.

    ``start_state(t)`` gives the state (displacements and zero velocities) a run starts from at time
    ``t``; each segment starts at ``first / fs - n_transient / fs``.  ``workers`` segments run at once.
    Returns ``(signal, number of segments)``; ``progress(done, total)`` counts every segment's samples,
    run-ins included.  ``margin = (lead, tail)`` also records ``lead`` samples before the first (the end of
    the first segment's run-in, so ``lead <= n_transient``) and ``tail`` after the last: ``signal`` then has
    ``lead + n_samples + tail`` columns, sample ``k`` of the record at column ``k + lead`` (for filters that need
    their edges, such as the motor current's rate change); the integration itself, and so every sample, is the
    same as without.  The calls are those of :func:`segment_calls`.
    """
    check_workers(workers)
    m_lead, m_tail = margin
    calls = segment_calls(model, fs, n_samples, n_transient, margin)
    n_out = model.sensor.shape[0] + (len(MOTOR_CHANNELS) if model.has_pmsm else 0)
    out = np.zeros((n_out, m_lead + n_samples + m_tail))
    total = m_lead + sum(c.n_samples + c.n_transient for c in calls)
    done = [0] * len(calls)
    lock = threading.Lock()

    def run(i: int) -> None:
        call = calls[i]

        def seg_progress(d: int, _t: int) -> None:
            if progress is not None:
                with lock:
                    done[i] = d
                    progress(sum(done), total)

        y0 = start_state(call.t_start)
        sig, _ = integrate(model, y0, fs, call.n_samples, call.n_transient, seg_progress,
                           first_sample=call.first_sample)
        out[:, call.column:call.column + call.n_samples] = sig

    if workers == 1 or len(calls) == 1:
        for i in range(len(calls)):
            run(i)
    else:
        with ThreadPoolExecutor(max_workers=min(workers, len(calls))) as pool:
            futures = [pool.submit(run, i) for i in range(len(calls))]
            try:
                for f in futures:
                    f.result()
            except BaseException:
                for f in futures:
                    f.cancel()
                raise
    return out, len(calls)
