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
``[model]`` table on the client before anything runs (raising :class:`rvdiag.errors.ConfigError`).

:func:`dynamics` (the default) adapts :func:`rvdiag.dynamics.simulate` (the 27-DOF model);
``rvdiag.library.synthetic:simulate`` is a fast analytic stand-in for tests.
"""

from __future__ import annotations

from typing import Any, Mapping

from rvdiag.errors import ConfigError, ParameterError


def _settings(model: Mapping[str, Any] | None, transient_s: float) -> Any:
    from rvdiag.dynamics import ModelSettings

    opts = {k: (tuple(tuple(x) if isinstance(x, list) else x for x in v) if isinstance(v, list) else v)
            for k, v in dict(model or {}).items()}
    if "transient_s" in opts:
        raise ConfigError("[model] transient_s: set the transient in [signal] transient_s")
    try:
        return ModelSettings(**opts, transient_s=float(transient_s))
    except TypeError as exc:
        raise ConfigError(f"[model]: {exc} (see rvdiag.dynamics.ModelSettings for the keys)") from None
    except ParameterError as exc:
        raise ConfigError(f"[model]: {exc}") from None


def check_options(model: Mapping[str, Any] | None) -> None:
    """Validate a ``[model]`` table as :class:`rvdiag.dynamics.ModelSettings` keyword arguments."""
    _settings(model, 0.0)


def dynamics(
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
    """The 27-DOF dynamic model (:func:`rvdiag.dynamics.simulate`) with the library's contract.

    ``operating`` holds the speed (``input_speed_rpm`` or ``output_speed_deg_s``) and ``load_Nm``, and with a
    ``[profile]`` table the ``profile`` and ``load_profile`` of the simulation.
    Returns a :class:`rvdiag.dynamics.SimulationResult` (two housing-acceleration channels, x and y).
    """
    from rvdiag.dynamics import simulate

    return simulate(params, fault, duration_s=duration_s, fs=fs, seed=seed,
                    settings=_settings(model, transient_s), **operating)
