"""The integrator on a CUDA GPU: one thread per simulation runs the CPU's own ``rk38_run`` / ``rk4_run``.

One source for the CPU and the GPU.  numba compiles the Python functions of :mod:`rvdiag.dynamics.integrate`
and :mod:`rvdiag.dynamics.kernels` twice: with ``numba.njit`` for the CPU, and, called from the CUDA kernel
below, as device functions by numba's CUDA target (which compiles an njit function that a ``cuda.jit`` kernel
calls from its Python source).  This module adds only that kernel: thread ``i`` takes its own views of the
ensemble's arrays (``A[i]`` or ``A[..., i]``) and makes one call of the integrator, exactly the call
:func:`rvdiag.dynamics.integrate.integrate` makes per chunk.  The step loop, the step grid at the mesh-table
events, the right-hand side and the instability checks are the CPU's code.

Two memory layouts (``layout``): ``"first"``, the ensemble index first (each thread's arrays contiguous), and
``"last"``, the ensemble index last (neighbouring threads read neighbouring addresses, coalesced); the probe
behind this module (``research/gpu_ensemble_probe.py``, bench/HISTORY.md 2026-11-23) measured ``"last"`` about
twice as fast on an H100 at 16k-32k simulations.

Under numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``, no GPU needed) a kernel runs as Python on fake device
arrays, and a numba-compiled function cannot take those; :func:`_simulated` hands the integrator each thread's
views as NumPy arrays instead, so that it runs as the CPU build (compiled, from numba's cache).  The simulator
therefore checks this module's kernel and the ensemble code around it (:mod:`rvdiag.dynamics.ensemble`), not the
device compilation of the integrator, which only a CUDA toolchain does (``bench/gpu_ensemble.py --ptx``).
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np

from rvdiag.errors import RvdiagError

#: the memory layouts of the ensemble arrays
LAYOUTS = ("first", "last")

_kernels: dict[tuple[str, str], Any] = {}
_lock = threading.Lock()
#: ``numba.cuda``, set by :func:`_make_kernel`: the kernel names it as a global, as numba's simulator requires
cuda: Any = None


class DeviceUnavailable(RvdiagError):
    """numba's CUDA target cannot be imported, or it finds no GPU (the message says which)."""


def load_cuda() -> Any:
    """``numba.cuda``, with a usable GPU or numba's simulator; :class:`DeviceUnavailable` otherwise.

    numba-cuda still calls ``np.row_stack``, which numpy >= 2.5 removed: it is aliased to ``np.vstack`` here,
    when missing, and only by this function (nothing else in rvdiag imports numba's CUDA target).
    """
    if not hasattr(np, "row_stack"):
        np.row_stack = np.vstack
    try:
        from numba import cuda
    except Exception as exc:  # noqa: BLE001 - any import failure means "no CUDA"; its text says why
        raise DeviceUnavailable(f"numba has no CUDA support ({_first_line(exc)}; pip install numba-cuda)") from None
    if is_simulator():
        return cuda
    try:
        available = bool(cuda.is_available())
    except Exception as exc:  # noqa: BLE001 - a broken driver install raises here instead of returning False
        raise DeviceUnavailable(f"no CUDA GPU found (numba: {_first_line(exc)})") from None
    if not available:
        raise DeviceUnavailable(f"no CUDA GPU found (numba: {_driver_error(cuda)})")
    return cuda


def unavailable_reason() -> str | None:
    """Why :func:`load_cuda` fails, in one line, or ``None`` when a GPU (or the simulator) is usable."""
    try:
        load_cuda()
    except DeviceUnavailable as exc:
        return str(exc)
    return None


def is_simulator() -> bool:
    """True when numba's CUDA simulator stands in for a GPU (``NUMBA_ENABLE_CUDASIM=1``)."""
    from numba import config

    return bool(getattr(config, "ENABLE_CUDASIM", False))


def device_name(cuda: Any) -> str:
    """The current GPU's name, or ``"numba CUDA simulator"``."""
    if is_simulator():
        return "numba CUDA simulator"
    name = cuda.get_current_device().name
    return name.decode() if isinstance(name, bytes) else str(name)


def _first_line(exc: BaseException) -> str:
    lines = [s.strip() for s in str(exc).splitlines() if s.strip()]
    return lines[0] if lines else type(exc).__name__


def _driver_error(cuda: Any) -> str:
    """numba's reason for ``cuda.is_available()`` being false, in one line."""
    try:
        from numba.cuda.cudadrv.driver import driver

        err = getattr(driver, "initialization_error", None)
    except Exception:  # noqa: BLE001 - only for the message
        err = None
    if err:
        return _first_line(Exception(err))
    return "no CUDA device is visible"


def kernel(method: str, layout: str) -> Any:
    """The CUDA kernel that runs ``rk38_run`` (``method="rk38"``) or ``rk4_run`` (``"rk4"``) one thread per
    simulation, with the ensemble index ``layout`` (:data:`LAYOUTS`); compiled on its first launch, once per
    process.  Its arguments: ``(k_start, n_samples, substeps, fs, record, Y, P, inv_mass, planet, tables, cosk,
    sink, sensor, out, W0..W17, events, n_events, breaks, n_breaks, grid, n_grid, status)``, where ``W0..W17`` are
    the integrator's slot and work arrays in its own order, ``events``, ``breaks`` and ``grid`` are padded and each
    thread uses its first ``n_events[i]``, ``n_breaks[i]``, ``n_grid[i]`` entries, and ``status[i] = (code,
    sample)`` as the integrator returns it; a thread whose code is not 0 is skipped by later launches."""
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}, got {layout!r}")
    with _lock:
        key = (method, layout)
        if key not in _kernels:
            _kernels[key] = _make_kernel(method, layout)
        return _kernels[key]


def _make_kernel(method: str, layout: str) -> Any:
    from rvdiag.dynamics.integrate import rk4_run, rk38_run

    global cuda
    cuda = load_cuda()
    run = {"rk38": rk38_run, "rk4": rk4_run}[method]

    if is_simulator():
        run = _simulated(run)

    # the two layouts written out: a CUDA device function cannot return an array view
    def ensemble_first(k_start, n_samples, substeps, fs, record, Y, P, IM, PL, TB, CK, SK, SE, OUT,
                       W0, W1, W2, W3, W4, W5, W6, W7, W8, W9, W10, W11, W12, W13, W14, W15, W16, W17,
                       EV, NE, BR, NBR, GR, NGR, ST):
        i = cuda.grid(1)
        if i < ST.shape[0] and ST[i, 0] == 0:
            st, s = run(Y[i], k_start, n_samples, substeps, fs, record, P[i], IM[i], PL[i], TB[i], CK[i], SK[i],
                        SE[i], OUT[i], W0[i], W1[i], W2[i], W3[i], W4[i], W5[i], W6[i], W7[i], W8[i], W9[i], W10[i],
                        W11[i], W12[i], W13[i], W14[i], W15[i], W16[i], W17[i], EV[i, :NE[i]], BR[i, :NBR[i]],
                        GR[i, :NGR[i]])
            ST[i, 0] = st
            ST[i, 1] = s

    def ensemble_last(k_start, n_samples, substeps, fs, record, Y, P, IM, PL, TB, CK, SK, SE, OUT,
                      W0, W1, W2, W3, W4, W5, W6, W7, W8, W9, W10, W11, W12, W13, W14, W15, W16, W17,
                      EV, NE, BR, NBR, GR, NGR, ST):
        i = cuda.grid(1)
        if i < ST.shape[0] and ST[i, 0] == 0:
            st, s = run(Y[..., i], k_start, n_samples, substeps, fs, record, P[..., i], IM[..., i], PL[..., i],
                        TB[..., i], CK[..., i], SK[..., i], SE[..., i], OUT[..., i], W0[..., i], W1[..., i],
                        W2[..., i], W3[..., i], W4[..., i], W5[..., i], W6[..., i], W7[..., i], W8[..., i],
                        W9[..., i], W10[..., i], W11[..., i], W12[..., i], W13[..., i], W14[..., i], W15[..., i],
                        W16[..., i], W17[..., i], EV[:NE[i], i], BR[:NBR[i], i], GR[:NGR[i], i])
            ST[i, 0] = st
            ST[i, 1] = s

    return cuda.jit(ensemble_first if layout == "first" else ensemble_last)


def _simulated(run: Any) -> Any:
    """``run`` as simulated device code may call it: each fake device array (numba's simulator wraps a NumPy
    array) is handed over as that NumPy array, a non-contiguous view (layout ``"last"``) as a contiguous copy that
    is written back after the call.  ``run`` then executes its CPU build on exactly the thread's data (the
    integrator's arrays never alias one another, so copying in and out is the same as working in place)."""

    def call(*args: Any) -> Any:
        host = [_host_array(a) for a in args]
        staged = [np.ascontiguousarray(a) if isinstance(a, np.ndarray) else a for a in host]
        try:
            return run(*staged)
        finally:
            for a, s in zip(host, staged):
                if isinstance(a, np.ndarray) and s is not a:
                    a[...] = s

    return call


def _host_array(a: Any) -> Any:
    """The NumPy array behind a fake device array of numba's simulator (other values unchanged)."""
    item = getattr(a, "_item", None)  # FakeWithinKernelCUDAArray -> FakeCUDAArray -> numpy
    ary = getattr(item, "_ary", None) if item is not None else getattr(a, "_ary", None)
    return ary if isinstance(ary, np.ndarray) else a
