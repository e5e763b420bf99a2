"""Library units on a CUDA GPU: ``rvdiag library build --device cuda``.

The units of a build are taken in ensembles of ``ensemble`` simulations.  Each unit is prepared as the CPU path
prepares it (:func:`rvdiag.library.work_units.simulator_call`, the simulator's ``prepare``: the same model, start state
and record), all their integrator calls run as one GPU ensemble, one thread per simulation
(:func:`rvdiag.dynamics.ensemble.integrate_ensemble`), and each unit is finished exactly as on the CPU
(``PreparedSimulation.finish``, then :func:`rvdiag.library.work_units.finish_unit`: transfer path, noise, segments).
A unit whose noise is a floor below its healthy twin's power has its twin integrated in the same ensemble.
One ensemble is one task: in this process, or one Dask task per ensemble on a cluster of GPU workers.
"""

from __future__ import annotations

import time
import warnings
from typing import Any

import numpy as np

from rvdiag.errors import ConfigError, DeviceWarning, RvdiagError
from rvdiag.library.work_units import (Job, Unit, UnitResult, check_worker, finish_unit, needs_twin, resolve_simulator,
                                  run_unit, simulator_call)

#: values of ``--device``
DEVICES = ("cpu", "cuda", "auto")
#: simulations per GPU ensemble by default (``--ensemble``)
DEFAULT_ENSEMBLE = 1024


def check_device(device: str, ensemble: int) -> None:
    """Validate ``--device`` and ``--ensemble`` (:class:`ConfigError`)."""
    if device not in DEVICES:
        raise ConfigError(f"--device must be one of {', '.join(DEVICES)}, got {device!r}")
    if isinstance(ensemble, bool) or not isinstance(ensemble, int) or ensemble < 1:
        raise ConfigError(f"--ensemble must be a whole number >= 1, got {ensemble!r}")


def resolve_device(device: str, simulator: str, check_here: bool = True) -> str:
    """``"cuda"`` or ``"cpu"``: where a build with ``--device device`` runs.

    ``cuda`` needs a simulator with a GPU path (a ``prepare`` attribute: the dynamic model's) and, when
    ``check_here`` (the simulations run on this machine), a usable GPU; without one it falls back to the CPU with
    one :class:`DeviceWarning` that says why.  ``auto`` is ``cuda`` when both are there, else ``cpu``, silently.
    """
    if device == "cpu":
        return "cpu"
    if not callable(getattr(resolve_simulator(simulator), "prepare", None)):
        if device == "auto":
            return "cpu"
        raise ConfigError(f"--device cuda: the simulator {simulator!r} has no GPU path (the dynamic model, "
                          "rvdiag.library.simulators:dynamics, has one); use --device cpu")
    if not check_here:
        return "cuda"
    from rvdiag.dynamics.gpu import unavailable_reason

    reason = unavailable_reason()
    if reason is None:
        return "cuda"
    if device == "cuda":
        warnings.warn(f"{reason}; building on the CPU", DeviceWarning, stacklevel=2)
    return "cpu"


def run_ensemble(units: list[Unit], job: Job, layout: str = "last") -> list[UnitResult | RvdiagError]:
    """Simulate ``units`` as one GPU ensemble and finish each as :func:`rvdiag.library.work_units.run_unit` does.

    Returns, in the order of ``units``, each unit's :class:`UnitResult` or its error (named as the CPU path names
    it: ``simulation INDEX (STATE #k): ...``), so that one unstable simulation does not lose the others.
    """
    from rvdiag.dynamics.ensemble import IntegrationRequest, integrate_ensemble

    t0 = time.perf_counter()
    outcomes: list[Any] = [None] * len(units)
    runs: dict[tuple[int, bool], tuple[Any, int]] = {}  # (unit, twin?) -> (prepared run, its integrator calls)
    requests, owners = [], []
    for j, unit in enumerate(units):
        try:
            for twin in (False, True) if needs_twin(unit, job) else (False,):
                sim, args, kwargs = simulator_call(unit, job, twin=twin)
                run = sim.prepare(*args, **kwargs)
                calls = run.segment_calls()
                for call in calls:
                    requests.append(IntegrationRequest(run.model, run.start_state(call.t_start), run.fs,
                                                       call.n_samples, call.n_transient, call.first_sample))
                    owners.append(((j, twin), call))
                runs[(j, twin)] = (run, len(calls))
        except RvdiagError as exc:
            outcomes[j] = _named(unit, exc)
    results = integrate_ensemble(requests, layout=layout)
    rows = {key: np.zeros((run.rows, run.columns)) for key, (run, _) in runs.items()}
    for k, ((key, call), res) in enumerate(zip(owners, results)):
        if isinstance(res, RvdiagError):
            outcomes[key[0]] = outcomes[key[0]] or _named(units[key[0]], res)
        else:
            rows[key][:, call.column:call.column + call.n_samples] = res[0]
        results[k] = None  # keep one copy of the records
    for (j, twin), (run, n_segments) in runs.items():
        if outcomes[j] is None and not twin:
            try:
                twin_result = None
                if (j, True) in runs:
                    twin_run, twin_segments = runs[(j, True)]
                    twin_result = twin_run.finish(rows.pop((j, True)), twin_segments)
                outcomes[j] = finish_unit(units[j], job, run.finish(rows.pop((j, False)), n_segments), t0,
                                          twin=twin_result)
            except RvdiagError as exc:
                outcomes[j] = _named(units[j], exc)
    return outcomes


def ensemble_task(units: list[Unit], job: Job,
                  layout: str = "last") -> tuple[list[UnitResult | RvdiagError], str | None]:
    """One ensemble as a (Dask) task: ``(outcomes of run_ensemble, None)``, or on a machine without a usable GPU
    the units run one by one on its CPU and the second item says why (the client warns once)."""
    from rvdiag.dynamics.gpu import unavailable_reason

    check_worker(job)
    reason = unavailable_reason()
    if reason is None:
        return run_ensemble(units, job, layout), None
    outcomes: list[UnitResult | RvdiagError] = []
    for unit in units:
        try:
            outcomes.append(run_unit(unit, job))
        except RvdiagError as exc:
            outcomes.append(_named(unit, exc))
    return outcomes, reason


def _named(unit: Unit, exc: RvdiagError) -> RvdiagError:
    return type(exc)(f"simulation {unit.index} ({unit.state} #{unit.sim_index}): {exc}")
