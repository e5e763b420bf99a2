"""Scoring a saved classifier on a split of a sample store: :func:`evaluate` -> :class:`Evaluation` (``rvdiag
evaluate``; a monitor is scored by :func:`rvdiag.monitoring.evaluate_monitor`).

The metrics are :func:`rvdiag.evaluation.evaluate.evaluate_on_store`'s (accuracy, macro precision / recall / F1,
kappa, per class, confusion); on request also the accuracy per value of a metadata column (``by``), against added
noise (``snr_db``), with classes merged (``merge``) and per whole record (``records``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

from rvdiag.errors import ParameterError


@dataclass
class Evaluation:
    """A classifier scored on a split (:func:`evaluate`); :meth:`to_dict` is what ``rvdiag evaluate --json`` prints:
    the ``metrics`` with ``by``, ``merged``, ``records``, ``snr`` and ``bound`` where they were asked for, and
    ``sets`` (the prediction sets: ``stated_coverage``, ``coverage``, ``mean_size``, ``per_state``; null with
    ``sets_note`` for a model without a calibration)."""

    metrics: dict
    split: str
    by: dict | None = None
    merged: dict | None = None
    records: dict | None = None
    snr: list[dict] | None = None
    bound: list[dict] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    #: the prediction sets' coverage and size (:func:`rvdiag.evaluation.evaluate.set_metrics_of`), or None with
    #: ``sets_note`` saying why (a model trained without a calibration)
    sets: dict | None = None
    sets_note: str | None = None
    #: the per-sample evaluation (:class:`rvdiag.evaluation.evaluate.Evaluation`), for a report
    details: Any = field(default=None, repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready values (``rvdiag evaluate --json``)."""
        out = dict(self.metrics)
        if self.by is not None:
            out["by"] = self.by
        if self.merged is not None:
            out["merged"] = self.merged
        if self.records is not None:
            out["records"] = self.records
        if self.snr is not None:
            out["snr"] = self.snr
        if self.bound:
            out["bound"] = self.bound
        out["sets"] = self.sets
        if self.sets is None:
            out["sets_note"] = self.sets_note
        return out

    def plot(self, ax=None, title: str = ""):
        """The accuracy against added noise when ``snr`` was asked for (:func:`rvdiag.evaluation.plots.plot_snr_curve`,
        a new figure), else the confusion matrix on ``ax``; returns the figure or the axes."""
        if self.snr is not None:
            from rvdiag.evaluation.plots import plot_snr_curve

            return plot_snr_curve(self.snr, self.bound, title=title)
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(4, 4))
        labels = self.metrics["labels"]
        ax.imshow(self.metrics["confusion"], cmap="Blues")
        ax.set_xticks(range(len(labels)), labels)
        ax.set_yticks(range(len(labels)), labels)
        ax.set_xlabel("predicted")
        ax.set_ylabel("true")
        ax.set_title(title or f"accuracy {100 * self.metrics['accuracy']:.1f} % [{self.split}]", fontsize="small")
        return ax


def parse_merge(text: str, classes) -> dict[str, str]:
    """``{"T4": "T1", "T6": "T5"}`` from ``T4=T1,T6=T5`` (``--merge``); both names must be classes of the model."""
    out: dict[str, str] = {}
    known = [str(c) for c in classes]
    for part in str(text).split(","):
        a, eq, b = (x.strip() for x in part.partition("="))
        if not (eq and a and b):
            raise ParameterError(f"--merge {text}: expected CLASS=CLASS pairs joined by ',' (e.g. T4=T1,T6=T5)")
        for c in (a, b):
            if c not in known:
                raise ParameterError(f"--merge {text}: {c!r} is not a class of the model ({', '.join(known)})")
        out[a] = b
    if any(b in out for b in out.values()):
        raise ParameterError(f"--merge {text}: a class merged into is itself merged away")
    return out


def read_bound(path: Path) -> dict:
    """A separability bound written by ``rvdiag separability --out`` (checked: pair, snr_db, accuracy_bound)."""
    try:
        b = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ParameterError(f"--bound {path}: not a readable JSON file ({exc})") from None
    ok = (isinstance(b, dict) and isinstance(b.get("pair"), list) and isinstance(b.get("snr_db"), list)
          and isinstance(b.get("accuracy_bound"), list) and len(b["snr_db"]) == len(b["accuracy_bound"]) > 0
          and all(isinstance(v, (int, float)) for v in b["snr_db"] + b["accuracy_bound"]))
    if not ok:
        raise ParameterError(f"--bound {path}: not the JSON of 'rvdiag separability' (pair, snr_db, accuracy_bound)")
    return b


def evaluate(model, data, *, split: str = "test", where: Sequence[str] = (), by: str | None = None,
             snr_db: Sequence[float] | None = None, seed: int = 0, merge: dict[str, str] | None = None,
             records: bool = False, bounds: Sequence[dict] = ()) -> Evaluation:
    """Score the loaded classifier ``model`` (:func:`rvdiag.workflows.load_model`) on ``split`` of the store
    ``data`` (a path or an open :class:`rvdiag.datasets.SampleStore`).

    Parameters
    ----------
    where : conditions ``COLUMN OP VALUE`` on the samples' metadata (all must hold)
    by : also the accuracy per value (or bin) of this metadata column
    snr_db : also the accuracy with white noise added at each of these SNRs (dB), drawn from ``seed``
    merge : also the metrics with classes merged (``{"T4": "T1"}``, :func:`parse_merge`)
    records : also the metrics per record (metadata ``unit``), windows decided together by mean probability
    bounds : separability bounds (:func:`read_bound`) to keep beside the SNR curve

    Returns
    -------
    Evaluation
    """
    from rvdiag.datasets import SampleStore
    from rvdiag.evaluation.evaluate import (accuracy_against_snr, accuracy_by, evaluate_on_store, merged_metrics,
                                            record_metrics, set_metrics_of)

    store = data if isinstance(data, SampleStore) else SampleStore.open(data)
    ev = evaluate_on_store(model, store, split, list(where or ()))
    groups = accuracy_by(ev, by) if by else None
    curve = accuracy_against_snr(model, ev, list(snr_db), seed) if snr_db else None
    merged = merged_metrics(ev, merge, model.card["classes"]) if merge else None
    by_record = record_metrics(model, ev, "unit", merge) if records else None
    sets, sets_note = set_metrics_of(model, ev)
    return Evaluation(metrics=dict(ev.metrics), split=ev.split,
                      by=None if groups is None else {"column": by, "groups": groups}, merged=merged,
                      records=by_record, snr=curve, bound=list(bounds), warnings=list(ev.warnings), sets=sets,
                      sets_note=sets_note, details=ev)


__all__ = ["Evaluation", "evaluate", "parse_merge", "read_bound"]
