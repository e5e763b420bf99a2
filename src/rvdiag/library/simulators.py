"""Simulators the library can call, behind one small contract.

A library simulator is a module-level function ``"package.module:function"`` (named in the config's
``simulator`` key, so it pickles by reference to Dask workers) called as::

    fn(params, fault, *, input_speed_rpm=... | output_speed_deg_s=..., load_Nm, duration_s, transient_s,
       fs, seed, model) -> result

- ``params``: :class:`rvdiag.params.ReducerParams` (already randomised for this simulation);
- ``fault``: ``None`` (healthy) or an ``rvdiag.gears.ToothFaults`` -- or, when the function has the
  attribute ``accepts_fault_spec = True``, the library's :class:`rvdiag.library.states.FaultSpec`;
- ``duration_s``: the signal to return, recorded after ``transient_s`` of discarded start-up (s);
- ``seed``: an integer from the unit's own seed stream; ``model``: the config's ``[model]`` table (dict);
- ``profile``, ``load_profile``: passed only by a config with a ``[profile]`` table, and only when the
  simulation drew a trapezoid or a gravity arm: a :class:`rvdiag.dynamics.profile.SpeedProfile` (cruising at
  the output speed given) and a :class:`rvdiag.dynamics.profile.LoadProfile`; a simulator that takes no
  profiles serves every config without ``[profile]``;
- ``result.signal``: array (channels, round(duration_s * fs)); ``result.fs``; optionally
  ``result.channel_names``.  The library adds the noise itself, so the simulator adds none.

An optional attribute ``check_options(model: dict) -> None`` of the function's module validates the
``[model]`` table on the client before anything runs (raising :class:`rvdiag.errors.ConfigError`).  An optional
attribute ``prepare`` of the function, called like it, returns a :class:`rvdiag.dynamics.PreparedSimulation`
instead of the result: a simulator with it can run on a GPU (``rvdiag library build --device cuda``, which
integrates many of them at once and finishes each as :func:`rvdiag.dynamics.simulate` does).

:func:`dynamics` (the default) adapts :func:`rvdiag.dynamics.simulate` (the 27-DOF model);
``rvdiag.library.synthetic:simulate`` is a fast analytic stand-in for tests.
"""

from __future__ import annotations

import inspect
from typing import Any, Mapping

from rvdiag.errors import ConfigError, ParameterError


#: keys of a ``[model]`` table that are not ModelSettings fields: what the dynamic model records
#: (``signal``: "vibration", the default, or "current", the servo motor's phase currents at ``[signal] fs``) and the
#: rate it integrates at when it records the current (``integration_fs``, Hz; default 48 kHz, or the next multiple
#: of ``[signal] fs`` above it)
RECORD_KEYS = ("signal", "integration_fs")


def _record_options(model: Mapping[str, Any] | None, fs: float) -> tuple[str, float]:
    """``(signal, integration_fs)`` of a ``[model]`` table (see :data:`RECORD_KEYS`)."""
    m = dict(model or {})
    signal = m.get("signal", "vibration")
    if signal not in ("vibration", "current"):
        raise ConfigError(f"[model] signal: must be \"vibration\" or \"current\", got {signal!r}")
    default = fs * max(1, -(-48000.0 // fs)) if fs > 0 else 48000.0
    f_int = m.get("integration_fs", default)
    if isinstance(f_int, bool) or not isinstance(f_int, (int, float)) or not f_int >= fs:
        raise ConfigError(f"[model] integration_fs: must be a number >= [signal] fs = {fs:g} Hz, got {f_int!r}")
    return signal, float(f_int)


def _settings(model: Mapping[str, Any] | None, transient_s: float) -> Any:
    from rvdiag.dynamics import ModelSettings

    opts = {k: (tuple(tuple(x) if isinstance(x, list) else x for x in v) if isinstance(v, list) else v)
            for k, v in dict(model or {}).items() if k not in RECORD_KEYS}
    if "transient_s" in opts:
        raise ConfigError("[model] transient_s: set the transient in [signal] transient_s")
    try:
        return ModelSettings(**opts, transient_s=float(transient_s))
    except TypeError as exc:
        raise ConfigError(f"[model]: {exc} (see rvdiag.dynamics.ModelSettings for the keys)") from None
    except ParameterError as exc:
        raise ConfigError(f"[model]: {exc}") from None


def check_options(model: Mapping[str, Any] | None) -> None:
    """Validate a ``[model]`` table: :class:`rvdiag.dynamics.ModelSettings` keyword arguments and
    :data:`RECORD_KEYS`."""
    _settings(model, 0.0)
    _record_options(model, 0.0)


def dynamics_request(
    params: Any,
    fault: Any = None,
    *,
    duration_s: float,
    transient_s: float,
    fs: float,
    seed: int = 0,
    model: Mapping[str, Any] | None = None,
    **operating: Any,
) -> Any:
    """The :class:`rvdiag.dynamics.SimulationRequest` of one library simulation (the contract's arguments, said once
    for :func:`dynamics` and :func:`prepare_dynamics`).

    ``operating`` holds the speed (``input_speed_rpm`` or ``output_speed_deg_s``) and ``load_Nm``, and with a
    ``[profile]`` table the ``profile`` and ``load_profile`` of the simulation.  With ``[model] signal =
    "current"`` the request records the servo motor's current at ``fs``, integrated at ``integration_fs``
    (:data:`RECORD_KEYS`).
    """
    from rvdiag.dynamics import SimulationRequest

    signal, f_int = _record_options(model, fs)
    settings = _settings(model, transient_s)
    if signal == "current":
        return SimulationRequest(params, fault, duration_s=duration_s, fs=f_int, seed=seed, settings=settings,
                                 signal="current", current_fs=fs, **operating)
    return SimulationRequest(params, fault, duration_s=duration_s, fs=fs, seed=seed, settings=settings, **operating)


def dynamics(*args: Any, **kwargs: Any) -> Any:
    """The 27-DOF dynamic model (:func:`rvdiag.dynamics.simulate`) with the library's contract: the request of
    :func:`dynamics_request` (the same arguments), run.

    Returns a :class:`rvdiag.dynamics.SimulationResult`: two housing-acceleration channels, x and y, or with
    ``[model] signal = "current"`` the servo motor's ``i_a, i_b, i_c, i_q, speed`` at ``fs``.
    """
    return dynamics_request(*args, **kwargs).run()


def prepare_dynamics(*args: Any, **kwargs: Any) -> Any:
    """:func:`dynamics` up to the integration: the :class:`rvdiag.dynamics.PreparedSimulation` whose ``finish``
    gives what :func:`dynamics` returns (the GPU ensemble integrates it, ``rvdiag.library.gpu``)."""
    return dynamics_request(*args, **kwargs).prepare()


dynamics.__signature__ = prepare_dynamics.__signature__ = inspect.signature(dynamics_request)  # type: ignore
dynamics.prepare = prepare_dynamics  # type: ignore[attr-defined]
