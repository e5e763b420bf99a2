"""A fast analytic stand-in for the dynamic model, for testing and timing the library machinery.

This is NOT a physical model of the reducer.  It produces a deterministic vibration-like signal from the
reducer kinematics (rvdiag.kinematics) so that build machinery (plans, seeds, Dask, resume, the store) can
be tested in milliseconds per simulation.  Use it with ``simulator = "rvdiag.library.synthetic:simulate"``
in a library config; real libraries use ``rvdiag.dynamics:simulate`` (the default).

Signal model (all amplitudes in m/s^2, arbitrary scale):

- stage-1 and stage-2 mesh tones at f_sp and f_cs (and two harmonics of f_sp), amplitude growing with load;
- wear (``wear_depth``): the 2nd and 3rd f_sp harmonics grow and are amplitude-modulated at the sun-fault
  frequency N (f_s - f_H), the classic distributed-fault signature (Randall 1982, sidebands);
- broken tooth (``broken_fraction``), root crack (``crack_depth``, ``crack_angle_deg``), pitting
  (``pit_area_fraction``) and spalling (``spall_width_fraction`` x ``spall_length_fraction``): an impulse at each
  passage of the faulty sun tooth through a mesh, N (f_s - f_H), exciting a 2nd-order structural resonance
  whose frequency scales with sqrt(stiffness scale) and whose damping with the damping-ratio scale;
- a small broadband component drawn from ``seed``, so different seeds give different signals;
- with a speed ``profile`` (:class:`rvdiag.dynamics.profile.SpeedProfile`) every tone and impact follows the
  carrier angle instead of time (the frequencies above are those of the cruise speed), and with a
  ``load_profile`` the amplitudes follow its torque.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.signal import lfilter

from rvdiag.errors import ConfigError, ParameterError
from rvdiag.kinematics import characteristic_frequencies

#: The library passes its FaultSpec (state + severities) instead of a gears.ToothFaults object.
accepts_fault_spec = True

_RESONANCE_HZ = 3200.0  # nominal housing resonance excited by tooth impacts


@dataclass
class SyntheticResult:
    """Result of :func:`simulate`: ``signal`` (channels x samples), ``fs`` (Hz), ``settings`` (dict)."""

    signal: np.ndarray
    fs: float
    settings: dict[str, Any] = field(default_factory=dict)
    channel_names: list[str] = field(default_factory=lambda: ["vibration"])


def simulate(
    params: Any,
    fault: Any = None,
    *,
    input_speed_rpm: float | None = None,
    output_speed_deg_s: float | None = None,
    load_Nm: float = 0.0,
    duration_s: float = 1.0,
    transient_s: float = 0.0,
    fs: float = 48000.0,
    seed: int = 0,
    model: Any = None,
    profile: Any = None,
    load_profile: Any = None,
) -> SyntheticResult:
    """Synthetic vibration signal of one operating point (see module docstring).

    Follows the simulator contract of :mod:`rvdiag.library.simulators`: ``fault`` is ``None`` (healthy)
    or an :class:`rvdiag.library.states.FaultSpec`; the first ``transient_s`` are generated and dropped;
    ``model`` must be empty (the stand-in has no model settings).
    """
    if model:
        raise ParameterError(f"the synthetic simulator takes no [model] options, got {sorted(model)}")
    n_tr = int(round(transient_s * fs))
    n = int(round(duration_s * fs)) + n_tr
    if n <= 0:
        raise ParameterError(f"duration_s x fs must give at least one sample, got {duration_s} x {fs}")
    f = characteristic_frequencies(params, input_speed_rpm, output_speed_deg_s)
    severity = dict(getattr(fault, "severity", {}) or {})
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    load = 1.0 + float(load_Nm) / float(params.operation.rated_torque)
    if profile is not None or load_profile is not None:
        t, load = _warp(params, f.f1, t - n_tr / fs, duration_s, load_Nm, profile, load_profile)
    phases = rng.uniform(0.0, 2.0 * np.pi, size=4)

    wear = severity.get("wear_depth", 0.0) / 1.0e-4
    mod = 1.0 + 0.5 * wear * np.cos(2.0 * np.pi * f.f_sun_fault * t)
    x = load * (
        np.cos(2.0 * np.pi * f.fsp * t + phases[0])
        + (0.3 + 0.8 * wear) * mod * np.cos(2.0 * np.pi * 2.0 * f.fsp * t + phases[1])
        + (0.1 + 0.5 * wear) * mod * np.cos(2.0 * np.pi * 3.0 * f.fsp * t + phases[2])
        + 0.5 * np.cos(2.0 * np.pi * f.fcs * t + phases[3])
    )

    impact = 4.0 * severity.get("broken_fraction", 0.0)
    impact += 2.0 * severity.get("crack_depth", 0.0) / 1.0e-3 * np.sin(np.radians(severity.get("crack_angle_deg", 0.0)))
    impact += 1.0 * severity.get("pit_area_fraction", 0.0)
    impact += 3.0 * severity.get("spall_width_fraction", 0.0) * severity.get("spall_length_fraction", 0.0)
    if impact > 0.0 and duration_s + transient_s > 0:
        k_scale = params.material.youngs_modulus / 2.06e11
        zeta = 0.05 * params.damping.mesh_damping_ratio / 0.07
        w0 = 2.0 * np.pi * _RESONANCE_HZ * np.sqrt(k_scale) / fs
        r = np.exp(-zeta * w0)
        pulses = np.zeros(n)
        if np.ndim(load) == 0:
            t_hit = np.arange(rng.uniform(0.0, 1.0 / f.f_sun_fault), n / fs, 1.0 / f.f_sun_fault)
            pulses[np.minimum((t_hit * fs).astype(np.int64), n - 1)] = impact * load
        else:  # warped time: the impacts fall at equal carrier angles
            t_hit = np.arange(rng.uniform(0.0, 1.0 / f.f_sun_fault), t[-1], 1.0 / f.f_sun_fault)
            idx = np.minimum(np.searchsorted(t, t_hit), n - 1)
            pulses[idx] = impact * load[idx]
        x += lfilter([1.0 - r], [1.0, -2.0 * r * np.cos(w0), r * r], pulses) * 20.0
    x += 0.05 * rng.standard_normal(n)
    x = x[n_tr:]
    settings = {
        "input_speed_rpm": input_speed_rpm, "output_speed_deg_s": output_speed_deg_s, "load_Nm": load_Nm,
        "duration_s": duration_s, "transient_s": transient_s, "fs": fs, "seed": seed, "fault": getattr(fault, "state", "T1"),
    }
    return SyntheticResult(signal=x[None, :], fs=float(fs), settings=settings)


def _warp(params: Any, f_sun: float, t_rec: np.ndarray, duration_s: float, load_Nm: float, profile: Any,
          load_profile: Any) -> tuple[np.ndarray, np.ndarray]:
    """Warped time (carrier angle / cruise speed, from 0) and the load factor per sample under the profiles."""
    from rvdiag.dynamics.profile import LoadProfile, SpeedProfile

    omega = 2.0 * np.pi * f_sun / params.ratio
    theta, _, domega = (profile or SpeedProfile()).state(t_rec, omega, duration_s)
    torque = (load_profile or LoadProfile()).torque(float(load_Nm), theta, domega)
    return (theta - theta[0]) / omega, 1.0 + np.abs(torque) / float(params.operation.rated_torque)


def check_options(model: Any) -> None:
    """The stand-in has no model settings: an empty ``[model]`` table only."""
    if model:
        raise ConfigError(f"[model]: the synthetic simulator takes no options, got {sorted(model)}")
