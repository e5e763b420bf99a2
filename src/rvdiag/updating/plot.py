"""Before/after figure of model updating: the compared spectra of the measured, base and updated records."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rvdiag.updating.objectives import Objective
from rvdiag.updating.tuner import UpdateResult


def before_after_figure(result: UpdateResult, path: str | Path, title: str = "") -> None:
    """Write a PNG with the feature the objective compares (log spectrum, envelope spectrum or record) of the
    measured record, the base simulation and the updated simulation, PCCs in the legend.  The figure is built
    without pyplot, so the caller's matplotlib backend is left as it is."""
    from matplotlib.figure import Figure

    obj = Objective(result.objective, result.measured, result.fs, result.signal_after.size)
    fig = Figure(figsize=(9, 4.5), layout="constrained")
    ax = fig.subplots()
    curves = (("measured", result.measured, "k", None),
              ("base model", result.signal_before, "tab:blue", result.pcc_before),
              ("updated model", result.signal_after, "tab:red", result.pcc_after))
    for label, x, colour, score in curves:
        f, feat = obj.feature(x)
        if f is None:
            f = np.arange(feat.size) / result.fs
        if score is not None:
            label = f"{label} (PCC {score:.3f})"
        ax.plot(f, feat, color=colour, lw=0.8, label=label, alpha=0.9 if colour == "k" else 0.8)
    ax.set_xlabel("time (s)" if result.objective == "time" else "frequency (Hz)")
    ax.set_ylabel({"logspec": "power spectral density (dB)", "envelope": "envelope spectrum amplitude",
                   "time": "acceleration"}[result.objective])
    note = " (PCC with the fitted noise floor; spectra without it)" if obj.name == "logspec" and obj.fit_floor else ""
    ax.set_title((title or f"model updating, objective {result.objective}") + note, fontsize=10)
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    fig.savefig(path, dpi=120)
