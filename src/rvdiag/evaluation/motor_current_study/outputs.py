"""The files of a run: ``mcsa.json``, ``mcsa.md`` and one t-SNE figure per feature set."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from rvdiag.atomic import atomic_file, atomic_write
from rvdiag.evaluation.motor_current_study.fitting import McsaResult
from rvdiag.evaluation.motor_current_study.markdown import markdown
from rvdiag.evaluation.motor_current_study.settings import FEATURE_SETS
from rvdiag.progress import report


def tsne_figure(name: str, panels: dict[str, tuple[np.ndarray, np.ndarray]], unit: str, seed: int,
                max_samples: int):
    """One figure per feature set: a t-SNE panel per speed of the first split's test features."""
    from rvdiag.evaluation.plots import plot_tsne_panels, tsne_embedding

    items = []
    rng = np.random.default_rng(seed)
    for speed, (F, y) in panels.items():
        if len(y) > max_samples:
            keep = np.sort(rng.choice(len(y), max_samples, replace=False))
            F, y = F[keep], y[keep]
        emb = tsne_embedding(F, random_state=seed) if len(y) >= 4 else None
        items.append((f"{speed} {unit}".strip(), emb, y))
    return plot_tsne_panels(items, title=f"t-SNE of {FEATURE_SETS[name]}, test side of the first split")


def write_outputs(result: McsaResult, out_dir: str | Path) -> list[Path]:
    """Write ``mcsa.json``, ``mcsa.md`` and ``tsne_<set>.png`` (one per feature set) into ``out_dir``, each file
    atomically (:mod:`rvdiag.atomic`)."""
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rep = result.report
    written = []
    written.append(atomic_write(out / "mcsa.json", json.dumps(rep, indent=2) + "\n"))
    written.append(atomic_write(out / "mcsa.md", markdown(rep)))
    st = rep["settings"]
    names = list(result.tsne)
    for i, name in enumerate(names):
        if st["tsne_samples"] > 0:
            fig = tsne_figure(name, result.tsne[name], rep["speed_unit"], int(st["seed"]) % 2**31,
                              int(st["tsne_samples"]))
            path = out / f"tsne_{name}.png"
            with atomic_file(path) as fh:
                fig.savefig(fh, format="png", dpi=110, bbox_inches="tight")
            plt.close(fig)
            written.append(path)
        report("t-SNE", i + 1, len(names))
    return written
