"""Many :func:`rvdiag.dynamics.integrate.integrate` calls at once on a CUDA GPU, one thread per call.

:func:`integrate_ensemble` takes a list of :class:`IntegrationRequest` (what ``integrate`` takes: a model, its
initial state, the rate, the samples to record and the run-in before them) and returns what ``integrate`` returns
for each.  Requests that share their shapes and their step settings (method, sub-steps, rate, record length,
run-in, first sample, chunk length, array shapes) form a group; the arrays of a group are stacked (ensemble index
first or last, :data:`rvdiag.dynamics.gpu.LAYOUTS`) and each chunk of samples is one launch of
:func:`rvdiag.dynamics.gpu.kernel`, the same chunks ``integrate`` runs, so every thread makes exactly the
integrator calls the CPU makes.  The models' mesh-table events differ in number with the fault: they are padded,
and each thread uses its own count.  The state between chunks stays on the GPU.

A simulation that becomes unstable stops (as on the CPU) without stopping the others; its entry of the result is
the :class:`rvdiag.errors.SimulationError` that ``integrate`` would have raised, with the same message.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from rvdiag.dynamics import gpu
from rvdiag.dynamics import kernels as kn
from rvdiag.dynamics import model as mdl
from rvdiag.dynamics.integrate import MOTOR_CHANNELS, OK, _load_step_kernels, _raise_unstable
from rvdiag.errors import SimulationError

#: threads per block of a launch (the probe's throughput figures used 32 and 64)
BLOCK = 64


@dataclass(frozen=True)
class IntegrationRequest:
    """The arguments of one :func:`rvdiag.dynamics.integrate.integrate` call."""

    model: mdl.Model
    y0: np.ndarray
    fs: float
    n_samples: int
    n_transient: int = 0
    first_sample: int = 0


def integrate_ensemble(requests: list[IntegrationRequest], layout: str = "last", block: int = BLOCK,
                       ) -> list[tuple[np.ndarray, np.ndarray] | SimulationError]:
    """``integrate(...)`` of every request, run as CUDA ensembles (:mod:`rvdiag.dynamics.gpu`).

    Returns, in the order of ``requests``, ``(signal, y_end)`` as ``integrate`` returns it, or the
    :class:`SimulationError` it would raise.  Raises :class:`rvdiag.dynamics.gpu.DeviceUnavailable` without a
    GPU (or numba's simulator).
    """
    cuda = gpu.load_cuda()
    results: list[Any] = [None] * len(requests)
    groups: dict[tuple, list[int]] = {}
    for j, req in enumerate(requests):
        if np.shape(req.y0) != (req.model.n_state,):
            raise SimulationError(f"initial state must have {req.model.n_state} entries, got {np.shape(req.y0)}")
        groups.setdefault(_group_key(req), []).append(j)
    for idx in groups.values():
        for j, res in zip(idx, _run_group(cuda, [requests[j] for j in idx], layout, block)):
            results[j] = res
    return results


def _group_key(req: IntegrationRequest) -> tuple:
    m = req.model
    st = m.settings
    shapes = tuple(np.shape(a) for a in (m.P, m.inv_mass, m.planet, m.tables, m.cosk, m.sink, m.sensor))
    return (st.method, int(st.substeps), float(req.fs), int(req.n_samples), int(req.n_transient),
            int(req.first_sample), max(1, int(st.chunk_samples)), m.n_state, m.n_dof, m.n_discs, m.has_pmsm,
            mdl.mesh_array(m).shape, shapes)


def _work_shapes(m: mdl.Model) -> list[tuple[int, ...]]:
    """Shapes of the integrator's slot and work arrays, in :func:`rvdiag.dynamics.integrate.integrate`'s order
    (18 for either method)."""
    geo, rot, mt = (m.n_discs, kn.GEO_ROWS, m.cosk.size), (m.n_discs, 4), mdl.mesh_array(m).shape
    if m.settings.method == "rk38":
        slots = [geo, rot, mt] * 4
        work = [(m.n_dof,)] + [(m.n_state,)] * 5  # Q, k1..k4, ytmp
    else:
        slots = [geo, rot, mt] * 3 + [geo, rot, geo, rot]
        work = [(m.n_dof,)] + [(m.n_state,)] * 4  # Q, k1..k3, ytmp
    return slots + work


def _breaks_size(m: mdl.Model, fs: float) -> int:
    """Work space for the events inside one sample, as :func:`rvdiag.dynamics.integrate.integrate` sizes it."""
    f_rel = abs(m.P[kn.I_WREL]) / (2.0 * math.pi)
    return m.events.size * (int(f_rel / fs) + 2) + 1


def _padded(rows: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Rows of different lengths as one zero-padded (n, max length) array, and the lengths."""
    n = np.array([r.size for r in rows], dtype=np.int64)
    out = np.zeros((len(rows), max(1, int(n.max()))))
    for i, r in enumerate(rows):
        out[i, :r.size] = r
    return out, n


def _run_group(cuda: Any, reqs: list[IntegrationRequest], layout: str, block: int) -> list[Any]:
    m0 = reqs[0].model
    _load_step_kernels(m0)  # the callees bound as in integrate() (the simulator runs the CPU build)
    st = m0.settings
    S = int(st.substeps)
    fs = float(reqs[0].fs)
    n_samples, n_transient, first = reqs[0].n_samples, reqs[0].n_transient, reqs[0].first_sample
    M = len(reqs)
    models = [r.model for r in reqs]

    def put(a: np.ndarray) -> Any:  # an (M, ...) host array in the layout
        return cuda.to_device(np.ascontiguousarray(np.moveaxis(a, 0, -1) if layout == "last" else a))

    def zeros(*shape: int) -> Any:
        return put(np.zeros((M,) + shape))

    Y = put(np.stack([np.asarray(r.y0, dtype=np.float64) for r in reqs]))
    fixed = [put(np.stack([getattr(m, name) for m in models]))
             for name in ("P", "inv_mass", "planet", "tables", "cosk", "sink", "sensor")]
    work = [zeros(*shape) for shape in _work_shapes(m0)]
    ev, ne = _padded([m.events for m in models])
    nbr = np.array([_breaks_size(m, fs) for m in models], dtype=np.int64)
    ngr = S + nbr + 2  # step boundaries of one sample
    EV = put(ev)
    BR, GR = zeros(int(nbr.max())), zeros(int(ngr.max()))
    NE, NBR, NGR = (cuda.to_device(a) for a in (ne, nbr, ngr))
    n_out = m0.sensor.shape[0] + (len(MOTOR_CHANNELS) if m0.has_pmsm else 0)
    chunk = max(1, int(st.chunk_samples))
    OUT = zeros(n_out, chunk)
    ST = cuda.to_device(np.zeros((M, 2), dtype=np.int64))
    launch = gpu.kernel(st.method, layout)[(M + block - 1) // block, block]

    out = np.zeros((M, n_out, n_samples))
    failed: dict[int, float] = {}  # request -> time of the instability (s)
    status = np.zeros((M, 2), dtype=np.int64)
    total = n_transient + n_samples
    done = 0
    k = first - n_transient
    while done < total and len(failed) < M:  # the chunks of integrate()
        m = min(chunk, total - done)
        rec = k >= first
        if not rec:
            m = min(m, first - k)
        launch(k, m, S, fs, rec, Y, *fixed, OUT, *work, EV, NE, BR, NBR, GR, NGR, ST)
        status = ST.copy_to_host()
        for i in np.flatnonzero(status[:, 0] != OK):
            failed.setdefault(int(i), (k + int(status[i, 1])) / fs)
        if rec:
            o = OUT.copy_to_host()
            o = np.moveaxis(o, -1, 0) if layout == "last" else o
            out[:, :, k - first:k - first + m] = o[:, :, :m]
        k += m
        done += m
    y_end = Y.copy_to_host()
    y_end = np.moveaxis(y_end, -1, 0) if layout == "last" else y_end
    results: list[Any] = []
    for i, m in enumerate(models):
        if i in failed:
            try:
                _raise_unstable(m, int(status[i, 0]), failed[i], fs)
            except SimulationError as exc:
                results.append(exc)
        else:
            results.append((out[i].copy(), np.array(y_end[i])))
    return results
