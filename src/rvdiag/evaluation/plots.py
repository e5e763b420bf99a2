"""Figures of an evaluation: confusion matrix, t-SNE map of learned features, waveforms and spectra.

Every function returns a :class:`matplotlib.figure.Figure` built without pyplot: it needs no display, does not
change the user's matplotlib backend (a notebook keeps its inline one) and is not held by pyplot's figure list, so
nothing has to close it; ``fig.savefig`` writes it, and :func:`figure_to_base64` turns one into the PNG text the
HTML report embeds.
"""

from __future__ import annotations

import base64
import io
from typing import Mapping, Sequence

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from rvdiag.spectral import amplitude_spectrum

#: Characteristic frequencies marked on spectra (keys of ``rvdiag freqs --json``) and their labels.
MARKED_FREQUENCIES = {
    "f1": "f1 sun", "f2": "f2 crank", "fsp": "fsp mesh 1", "fcs": "fcs mesh 2",
    "f_sun_fault": "sun fault", "f_planet_fault": "planet fault",
}


def figure_to_base64(fig: Figure, dpi: int = 90) -> str:
    """PNG of ``fig`` as base64 text."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def plot_confusion(confusion: Sequence[Sequence[int]], labels: Sequence[str], title: str = "") -> Figure:
    """Confusion matrix: counts, shaded by the row share (true class = row, predicted = column)."""
    cm = np.asarray(confusion, dtype=float)
    share = cm / np.maximum(cm.sum(axis=1, keepdims=True), 1)
    n = len(labels)
    fig = Figure(figsize=(1.0 + 0.75 * n, 0.8 + 0.7 * n))
    ax = fig.subplots()
    ax.imshow(share, cmap="Blues", vmin=0, vmax=1)
    for i in range(n):
        for j in range(n):
            ax.text(j, i, f"{int(cm[i, j])}", ha="center", va="center",
                    color="white" if share[i, j] > 0.6 else "black", fontsize=9)
    ax.set_xticks(range(n), labels)
    ax.set_yticks(range(n), labels)
    ax.set_xlabel("predicted")
    ax.set_ylabel("true")
    ax.set_title(title or "confusion matrix")
    fig.tight_layout()
    return fig


def tsne_embedding(features: np.ndarray, random_state: int = 0) -> np.ndarray:
    """2-D t-SNE (van der Maaten & Hinton 2008; scikit-learn) of feature vectors, PCA-initialised."""
    from sklearn.manifold import TSNE

    F = np.asarray(features, dtype=np.float64)
    F = (F - F.mean(0)) / np.where(F.std(0) > 0, F.std(0), 1.0)
    perplexity = float(min(30.0, max(2.0, (len(F) - 1) / 3.0)))
    return TSNE(n_components=2, perplexity=perplexity, init="pca", random_state=random_state).fit_transform(F)


def plot_tsne(embedding: np.ndarray, labels: Sequence[str], title: str = "") -> Figure:
    """Scatter of a 2-D embedding coloured by class."""
    labels = np.asarray(labels).astype(str)
    fig = Figure(figsize=(6.0, 5.0))
    ax = fig.subplots()
    for i, c in enumerate(sorted(set(labels.tolist()))):
        m = labels == c
        ax.scatter(embedding[m, 0], embedding[m, 1], s=10, label=c, color=colormaps["tab10"](i % 10), alpha=0.8)
    ax.legend(markerscale=2, fontsize=8, loc="best")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title or "t-SNE of learned features")
    fig.tight_layout()
    return fig


def plot_tsne_panels(panels: Sequence[tuple[str, np.ndarray | None, Sequence[str]]], title: str = "") -> Figure:
    """One t-SNE scatter per panel ``(panel title, 2-D embedding or None, labels)``, side by side, one colour per
    class across all panels (``None``: too few points to embed, the panel says so)."""
    classes = sorted({str(c) for _, _, labels in panels for c in labels})
    colour = {c: colormaps["tab10"](i % 10) for i, c in enumerate(classes)}
    n = max(1, len(panels))
    fig = Figure(figsize=(4.2 * n, 4.2))
    axes = fig.subplots(1, n, squeeze=False)
    for ax, (name, emb, labels) in zip(axes[0], panels):
        labels = np.asarray(labels).astype(str)
        if emb is None:
            ax.text(0.5, 0.5, f"{len(labels)} samples: too few to embed", ha="center", va="center",
                    transform=ax.transAxes)
        else:
            for c in classes:
                m = labels == c
                if m.any():
                    ax.scatter(emb[m, 0], emb[m, 1], s=10, color=colour[c], alpha=0.8, label=c)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(name)
    handles = [Line2D([], [], ls="", marker="o", color=colour[c], label=c) for c in classes]
    if handles:
        fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 8), fontsize=8, frameon=False)
    fig.suptitle(title or "t-SNE")
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    return fig


def plot_examples(examples: Mapping[str, np.ndarray], fs: float | None = None,
                  frequencies: Mapping[str, float] | None = None, max_points: int = 2048,
                  fmax: float | None = None) -> Figure:
    """Waveform and amplitude spectrum of one example sample per state.

    Parameters
    ----------
    examples : {state: 1-D signal}
    fs : float or None
        Sampling rate (Hz); None: time in samples and frequency in cycles per sample.
    frequencies : {key: Hz}, optional
        Characteristic frequencies (``characteristic_frequencies(...).as_dict()``); those in
        :data:`MARKED_FREQUENCIES` below ``fmax`` are drawn as dashed lines on every spectrum.
    max_points : int
        Points of each waveform shown.
    fmax : float, optional
        Upper frequency of the spectra (default: Nyquist).  The frequency axis is logarithmic, so the
        low characteristic frequencies and the high-frequency resonances show on one plot.
    """
    states = list(examples)
    fig = Figure(figsize=(11, 1.9 * len(states) + 0.9))
    axes = fig.subplots(len(states), 2, squeeze=False)
    colors = [colormaps["tab10"](i) for i in (3, 0, 2, 4, 1, 6, 5, 7, 8)]
    handles = []
    for row, state in enumerate(states):
        x = np.asarray(examples[state], dtype=np.float64)
        n = min(len(x), max_points)
        t = np.arange(n) / fs * 1e3 if fs else np.arange(n)
        ax = axes[row, 0]
        ax.plot(t, x[:n], lw=0.6, color="tab:blue")
        ax.set_ylabel(state, rotation=0, ha="right", fontsize=11, fontweight="bold")
        ax.set_xlabel("time (ms)" if fs else "sample")
        f, a = amplitude_spectrum(x, fs)
        ax = axes[row, 1]
        keep = f > 0
        if fmax:
            keep &= f <= fmax
        ax.loglog(f[keep], a[keep], lw=0.6, color="black")
        ax.set_xlabel("frequency (Hz)" if fs else "frequency (cycles/sample)")
        if frequencies and fs:
            for i, (key, name) in enumerate(MARKED_FREQUENCIES.items()):
                v = frequencies.get(key)
                if v and (fmax is None or v <= fmax):
                    h = ax.axvline(v, ls="--", lw=0.9, color=colors[i % 9], label=f"{name} {v:.1f} Hz")
                    if row == 0:
                        handles.append(h)
    if handles:
        fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, frameon=False)
        fig.tight_layout(rect=(0, 0.06 / max(1, len(states) / 3), 1, 1))
    else:
        fig.tight_layout()
    axes[0, 0].set_title("waveform")
    axes[0, 1].set_title("amplitude spectrum (Hann, log-log), characteristic frequencies dashed")
    return fig


def plot_history(history: Sequence[Mapping]) -> Figure:
    """Training loss and validation accuracy per epoch of a CNN."""
    ep = [h["epoch"] for h in history]
    fig = Figure(figsize=(6, 3))
    ax = fig.subplots()
    ax.plot(ep, [h["loss"] for h in history], "o-", ms=3, label="training loss")
    if any(h.get("val_loss") is not None for h in history):
        ax.plot(ep, [h["val_loss"] for h in history], "s-", ms=3, label="validation loss")
        ax2 = ax.twinx()
        ax2.plot(ep, [h["val_accuracy"] for h in history], "^-", ms=3, color="tab:green",
                 label="validation accuracy")
        ax2.set_ylim(0, 1.02)
        ax2.set_ylabel("validation accuracy")
    ax.set_xlabel("epoch")
    ax.set_ylabel("cross-entropy")
    ax.legend(fontsize=8, loc="center right")
    fig.tight_layout()
    return fig


def bound_label(bound: Mapping) -> str:
    """Legend label of a separability bound: ``bound T1/T4 (crack 1.8 mm, 32.5 deg)`` (the severities given)."""
    pair = "/".join(map(str, bound.get("pair", ("?", "?"))))
    parts = []
    for key, v in dict(bound.get("severities_SI") or {}).items():
        if key == "crack_depth":
            parts.append(f"crack {1e3 * v:g} mm")
        elif key == "crack_angle_deg":
            parts.append(f"{v:g} deg")
        elif key == "wear_depth":
            parts.append(f"wear {1e6 * v:g} um")
        elif key == "broken_fraction":
            parts.append(f"broken {v:g}")
        else:
            parts.append(f"{key} {v:g}")
    return f"bound {pair}" + (f" ({', '.join(parts)})" if parts else "")


def plot_snr_curve(curve: Sequence[Mapping], bounds: Sequence[Mapping] = (), title: str = "") -> Figure:
    """Accuracy against added-noise SNR: the overall accuracy (black, solid), one recall curve per class, and each
    separability bound of ``bounds`` (dashed, :mod:`rvdiag.evaluation.separability`).

    ``curve`` is :func:`rvdiag.evaluation.evaluate.accuracy_against_snr`'s list (``snr_db``, ``accuracy``,
    ``per_class_recall``); each bound a dict with ``pair``, ``snr_db`` and ``accuracy_bound`` (the JSON of
    ``rvdiag separability``): the best accuracy any classifier can reach on that pair of states.  Lines in that
    order: ``1 + n_classes + len(bounds)``."""
    rows = sorted(curve, key=lambda r: r["snr_db"])
    x = [r["snr_db"] for r in rows]
    fig = Figure(figsize=(8.6, 4.2))
    ax = fig.subplots()
    ax.plot(x, [100 * r["accuracy"] for r in rows], "k-o", lw=2, label="overall accuracy")
    classes = list(rows[0].get("per_class_recall", {})) if rows else []
    for i, c in enumerate(classes):
        ax.plot(x, [100 * r["per_class_recall"][c] for r in rows], "-", marker=".", lw=1,
                color=colormaps["tab10"](i % 10), label=f"recall {c}")
    for j, b in enumerate(bounds):
        ax.plot(b["snr_db"], [100 * v for v in b["accuracy_bound"]], "--", lw=1.8, color=colormaps["Dark2"](j % 8),
                label=bound_label(b))
    ax.set_xlabel("added white-noise SNR (dB)")
    ax.set_ylabel("accuracy / recall (%)")
    ax.set_ylim(0, 102)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    ax.set_title(title or "accuracy against SNR")
    fig.tight_layout()
    return fig
