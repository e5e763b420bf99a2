"""The samples of a store the study reads: the channel of each sample, its operating speed, and the samples grouped
by speed (:class:`SpeedGroup`), checked for a stratified split before any work."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from rvdiag.errors import ParameterError, StoreError
from rvdiag.evaluation.motor_current_study.settings import DEFAULT_CHANNEL


def sample_channels(store) -> np.ndarray:
    """The channel name of every sample of a store.

    A store holds one signal per row.  A store written from measured files records the channel of each row in
    its ``channel`` metadata column; a simulated library keeps the channel its config names (``channel``, a
    simulator channel name such as ``i_a``, or an index, named by its number).
    """
    col = store.meta.get("channel")
    if col is not None and np.asarray(col).dtype.kind in "OUS":
        return np.asarray(col).astype(str)
    configured = (store.attrs.get("config") or {}).get("channel")
    name = "0" if configured is None or configured == "" else str(configured)
    return np.full(store.n_samples, name, dtype=object).astype(str)


def pick_channel(names: Sequence[str], wanted: str | None, where: Any) -> str:
    """The channel to use among ``names`` (in the store's order).

    ``wanted`` None: ``i_a`` (the phase current) when present, else the first channel.  Otherwise an exact name,
    or a regular expression (:func:`re.search`, as ``-c/--channel`` everywhere) matching exactly one name.
    """
    order = list(dict.fromkeys(str(n) for n in names))
    if wanted is None:
        return DEFAULT_CHANNEL if DEFAULT_CHANNEL in order else order[0]
    if wanted in order:
        return wanted
    try:
        pattern = re.compile(wanted)
    except re.error as exc:
        raise ParameterError(f"--channel {wanted!r} is no valid regular expression: {exc}") from None
    hits = [n for n in order if pattern.search(n)]
    if len(hits) == 1:
        return hits[0]
    what = "no channel" if not hits else f"{len(hits)} channels ({', '.join(hits)})"
    raise StoreError(f"{where}: {what} match --channel {wanted!r} (channels: {', '.join(order)})")


def speed_unit(column: str) -> str:
    """The unit of a speed column by its name's ending (``_deg_s`` -> deg/s, ``_rpm`` -> rev/min)."""
    if column.endswith("_deg_s"):
        return "deg/s"
    if column.endswith("_rpm"):
        return "rev/min"
    return ""


def speed_labels(store, column: str) -> np.ndarray:
    """The operating speed of every sample as a label (``"45"``, ``"37.5"``), from metadata ``column``."""
    if column not in store.meta:
        numeric = sorted(k for k, v in store.meta.items() if np.asarray(v).dtype.kind in "fiu"
                         and k not in ("unit", "seed", "segment", "simulation"))
        raise StoreError(f"{store.path} has no metadata column {column!r} to group the samples by speed; name one "
                         f"with --speed-column (numeric columns: {', '.join(numeric) or 'none'})")
    col = np.asarray(store.meta[column])
    if col.dtype.kind in "fiu":
        values = col.astype(np.float64)
        if not np.all(np.isfinite(values)):
            bad = int(np.sum(~np.isfinite(values)))
            raise StoreError(f"{store.path}: {bad} sample(s) have no speed in column {column!r} (NaN)")
        return np.asarray([f"{round(v, 6):g}" for v in values.tolist()], dtype=object).astype(str)
    return col.astype(str)


def _speed_order(labels) -> list[str]:
    def key(s: str):
        try:
            return (0, float(s), s)
        except ValueError:
            return (1, 0.0, s)

    return sorted(set(labels), key=key)


# ---------------------------------------------------------------------- data
@dataclass
class SpeedGroup:
    """The samples of one store at one speed, on one channel."""

    X: np.ndarray
    y: np.ndarray
    units: np.ndarray | None
    sims: np.ndarray | None  # (class, seed) identities of the simulations, when the store records seeds


def load_groups(store, channel: str, column: str) -> dict[str, SpeedGroup]:
    on_channel = sample_channels(store) == channel
    speeds = speed_labels(store, column)
    out: dict[str, SpeedGroup] = {}
    for speed in _speed_order(speeds[on_channel].tolist()):
        idx = np.flatnonzero(on_channel & (speeds == speed))
        s = store.load(index=idx)
        units = s.meta.get("unit")
        sims = None
        if "seed" in s.meta:
            sims = np.asarray([f"{c}/{v}" for c, v in zip(s.y.tolist(), s.meta["seed"].tolist())], dtype=object)
        out[speed] = SpeedGroup(X=np.asarray(s.X, dtype=np.float32), y=np.asarray(s.y).astype(str),
                            units=None if units is None else np.asarray(units), sims=sims)
    return out


def check_splittable(groups: dict[str, SpeedGroup], test_size: float, where: Any, unit: str) -> None:
    """Refuse a speed whose classes are too small for a stratified split (before any work)."""
    for speed, g in groups.items():
        classes, counts = np.unique(g.y, return_counts=True)
        at = f"{where} at {speed} {unit}".rstrip()
        if len(classes) < 2:
            raise StoreError(f"{at}: only one class ({classes[0]}); a classification needs at least two")
        n = len(g.y)
        n_test = math.ceil(test_size * n)
        n_train = n - n_test
        small = [f"{c} ({k})" for c, k in zip(classes.tolist(), counts.tolist()) if k < 2]
        if small or n_test < len(classes) or n_train < len(classes):
            detail = (f"class {', '.join(small)} has fewer than 2 samples" if small else
                      f"{n} samples give {n_train} training / {n_test} test samples for {len(classes)} classes")
            raise StoreError(f"{at}: too few samples for a stratified {round(100 * (1 - test_size))}/"
                             f"{round(100 * test_size)} split ({detail}); a split needs at least 2 samples per "
                             f"class and one per class on each side")
