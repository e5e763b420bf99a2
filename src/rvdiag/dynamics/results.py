"""Result of a simulation: the sensor signal, its sampling rate and every setting that produced it."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rvdiag.atomic import atomic_file
from rvdiag.errors import DataFileError


@dataclass
class SimulationResult:
    """Simulated housing acceleration.

    Attributes
    ----------
    signal : ndarray, shape (channels, samples)
        Acceleration at the sensor point along each sensor direction, m/s^2.
    fs : float
        Sampling rate, Hz.
    settings : dict
        Every setting (operating point, model settings, fault, seed, parameter set): JSON-able, enough
        to repeat the run with :func:`rvdiag.dynamics.simulate`.
    channel_names : list of str
    theta_out, theta_in : ndarray, shape (samples,), or None
        The output (carrier) and input (sun) shafts' nominal angles at each sample, rad (0 at the first
        sample; the speed profile's closed form, without the micro-radian vibratory twist).
    current : ndarray, shape (channels, samples at current_fs), or None
        The servo motor's current record (``simulate(signal="current" | "both")``): ``current_names``
        ``i_a, i_b, i_c, i_q`` (A) and ``speed`` (rpm), sampled at ``current_fs`` (Hz).
    """

    signal: np.ndarray
    fs: float
    settings: dict[str, Any] = field(default_factory=dict)
    channel_names: list[str] = field(default_factory=list)
    theta_out: np.ndarray | None = None
    theta_in: np.ndarray | None = None
    current: np.ndarray | None = None
    current_fs: float | None = None
    current_names: list[str] = field(default_factory=list)

    def current_only(self) -> "SimulationResult":
        """The motor current as the result's signal (``signal="current"``): ``signal``, ``fs`` and
        ``channel_names`` are the current record's, the shaft angles are dropped (they are on the vibration's
        time base)."""
        if self.current is None:
            raise DataFileError("this result holds no motor current (simulate with signal='current' or 'both')")
        return SimulationResult(self.current, float(self.current_fs), dict(self.settings), list(self.current_names),
                                current=self.current, current_fs=self.current_fs,
                                current_names=list(self.current_names))

    @property
    def time_s(self) -> np.ndarray:
        """Sample times (s) from the end of the discarded transient."""
        return np.arange(self.signal.shape[-1]) / self.fs

    def spectrum(self, channel: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """One-sided amplitude spectrum (Hann window) of one channel: (frequency Hz, amplitude m/s^2)."""
        x = self.signal[channel] - np.mean(self.signal[channel])
        w = np.hanning(x.size)
        amp = 2.0 * np.abs(np.fft.rfft(x * w)) / np.sum(w)
        return np.fft.rfftfreq(x.size, 1.0 / self.fs), amp

    def plot(self, channel: int = 0, ax: Any = None, fmax_hz: float | None = None) -> Any:
        """Plot the waveform and its amplitude spectrum; returns the matplotlib Figure."""
        import matplotlib.pyplot as plt

        if ax is None:
            fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 6))
        else:
            a1, a2 = ax
            fig = a1.figure
        name = self.channel_names[channel] if channel < len(self.channel_names) else f"channel {channel}"
        a1.plot(self.time_s, self.signal[channel], lw=0.6)
        a1.set_xlabel("time (s)")
        a1.set_ylabel(f"{name} (m/s$^2$)")
        f, amp = self.spectrum(channel)
        a2.plot(f, amp, lw=0.6)
        a2.set_xlim(0, fmax_hz or self.fs / 2)
        a2.set_xlabel("frequency (Hz)")
        a2.set_ylabel("amplitude (m/s$^2$)")
        fig.tight_layout()
        return fig

    def to_npz(self, path: str | Path) -> None:
        """Write ``signal``, ``fs``, ``settings`` (JSON string), ``channel_names`` and, when known, the shaft
        angles ``theta_out`` and ``theta_in`` (rad) and the motor current (``current``, ``current_fs``,
        ``current_names``) to an ``.npz``."""
        angles = {k: np.asarray(v, dtype=np.float64) for k, v in
                  (("theta_out", self.theta_out), ("theta_in", self.theta_in)) if v is not None}
        if self.current is not None:
            angles.update(current=np.asarray(self.current, dtype=np.float64), current_fs=np.float64(self.current_fs),
                          current_names=np.array(self.current_names, dtype=str))
        path = Path(path)
        if path.suffix != ".npz":  # np.savez's own rule, kept now that it writes to a file object
            path = path.with_name(path.name + ".npz")
        with atomic_file(path) as fh:  # an interrupted write leaves an existing file as it was
            np.savez(
                fh,
                signal=np.asarray(self.signal, dtype=np.float64),
                fs=np.float64(self.fs),
                settings=np.array(json.dumps(self.settings, sort_keys=True)),
                channel_names=np.array(self.channel_names, dtype=str),
                **angles,
            )

    @classmethod
    def from_npz(cls, path: str | Path) -> "SimulationResult":
        """Read a file written by :meth:`to_npz` (no pickles are loaded)."""
        try:
            with np.load(Path(path), allow_pickle=False) as z:
                return cls(
                    np.array(z["signal"]),
                    float(z["fs"]),
                    json.loads(str(z["settings"])),
                    [str(s) for s in z["channel_names"]] if "channel_names" in z else [],
                    np.array(z["theta_out"]) if "theta_out" in z else None,
                    np.array(z["theta_in"]) if "theta_in" in z else None,
                    np.array(z["current"]) if "current" in z else None,
                    float(z["current_fs"]) if "current_fs" in z else None,
                    [str(s) for s in z["current_names"]] if "current_names" in z else [],
                )
        except (OSError, KeyError, ValueError) as exc:
            raise DataFileError(f"{path}: not a simulation result file ({exc})") from None
