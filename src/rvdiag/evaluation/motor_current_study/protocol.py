"""How the study splits the windows at each speed: random window splits (the study's protocol), one reducer per
state (``study``), or whole reducers held out (``held-out``); :data:`PROTOCOLS`."""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from rvdiag.errors import ParameterError, StoreError
from rvdiag.evaluation.motor_current_study.data import SpeedGroup
from rvdiag.evaluation.motor_current_study.settings import McsaSettings


def study_split(y: np.ndarray, units: np.ndarray, test_size: float, seed: int):
    """One split of the study's protocol: one reducer per state, its windows split at random.

    The study recorded each state on a different physical sun gear and split the windows of those recordings
    70/30 at random.  Here each state keeps the windows of one simulation (``units``: the simulation of every
    window; with ``[randomise] specimen = true`` each simulation is a reducer of its own), drawn with
    ``numpy.random.default_rng(seed)``, and those windows are split stratified at random
    (:func:`sklearn.model_selection.train_test_split`, ``random_state=seed``).

    Returns (train indices, test indices, the simulations used, one per state in sorted class order).

    >>> y = np.array(["a"] * 6 + ["b"] * 6); u = np.array([1, 1, 1, 2, 2, 2, 3, 3, 3, 4, 4, 4])
    >>> tr, te, used = study_split(y, u, 0.5, 0)
    >>> len(used), set(u[np.r_[tr, te]]) == set(used), len(te)
    (2, True, 3)
    """
    from sklearn.model_selection import train_test_split

    rng = np.random.default_rng(int(seed))
    used = []
    for c in sorted(set(y.tolist())):
        candidates = np.unique(units[y == c])
        used.append(candidates[rng.integers(len(candidates))])
    idx = np.flatnonzero(np.isin(units, used))
    tr, te = train_test_split(idx, test_size=float(test_size), stratify=y[idx], random_state=int(seed))
    return np.sort(tr), np.sort(te), [u.item() if hasattr(u, "item") else u for u in used]


def held_out_split(y: np.ndarray, units: np.ndarray, test_size: float, seed: int):
    """One split of the held-out protocol: whole reducers on the test side, none of them seen in the fit.

    For each state, ``round(test_size * n)`` of its ``n`` simulations (at least one, and at least one left to
    train on), drawn with ``numpy.random.default_rng(seed)``, give all their windows to the test side; the other
    simulations train.  A split by group (as :class:`sklearn.model_selection.GroupShuffleSplit`), stratified by
    state so that every state is on both sides.

    Returns (train indices, test indices, the test simulations).

    >>> y = np.array(["a"] * 4 + ["b"] * 4); u = np.array([1, 1, 2, 2, 3, 3, 4, 4])
    >>> tr, te, unseen = held_out_split(y, u, 0.5, 0)
    >>> len(unseen), set(u[tr]) & set(u[te])
    (2, set())
    """
    rng = np.random.default_rng(int(seed))
    unseen = []
    for c in sorted(set(y.tolist())):
        candidates = np.unique(units[y == c])
        k = min(max(1, round(float(test_size) * len(candidates))), len(candidates) - 1)
        unseen.extend(rng.choice(candidates, k, replace=False).tolist())
    test = np.isin(units, unseen)
    return np.flatnonzero(~test), np.flatnonzero(test), sorted(unseen)


def protocol_splits(protocol: str, y: np.ndarray, units: np.ndarray | None, test_size: float,
                    seeds: Sequence[int]) -> list[tuple[np.ndarray, np.ndarray, dict]]:
    """The (train, test, what the split used) of each repeat of one protocol (``windows``, ``study`` or
    ``held-out``; :data:`PROTOCOLS`), repeat ``r`` seeded with ``seeds[r]``."""
    from sklearn.model_selection import train_test_split

    out = []
    for s in seeds:
        if protocol == "windows":
            tr, te = train_test_split(np.arange(len(y)), test_size=float(test_size), stratify=y, random_state=s)
            out.append((np.sort(tr), np.sort(te), {}))
        elif protocol == "study":
            tr, te, used = study_split(y, units, test_size, s)
            out.append((tr, te, {"simulations": used}))
        elif protocol == "held-out":
            tr, te, unseen = held_out_split(y, units, test_size, s)
            out.append((tr, te, {"test_simulations": unseen}))
        else:
            raise ParameterError(f"protocol_splits runs windows | study | held-out, got {protocol!r}")
    return out


def protocols_run(protocol: str) -> list[str]:
    """The protocols a ``protocol`` setting runs (``both`` -> study and held-out)."""
    return ["study", "held-out"] if protocol == "both" else [protocol]


def check_protocol(groups: dict[str, SpeedGroup], settings: McsaSettings, where: Any, unit: str) -> None:
    """Refuse a store the study or held-out protocol cannot split (before any work)."""
    runs = protocols_run(settings.protocol)
    if runs == ["windows"]:
        return
    for speed, g in groups.items():
        at = f"{where} at {speed} {unit}".rstrip()
        if g.units is None:
            raise StoreError(f"{where} has no 'unit' column (the simulation of each window): the {settings.protocol} "
                             "protocol splits by simulated reducer")
        for c in sorted(set(g.y.tolist())):
            sims, windows = np.unique(g.units[g.y == c], return_counts=True)
            if "held-out" in runs and len(sims) < 2:
                raise StoreError(f"{at}: state {c} has {len(sims)} simulation; the held-out split needs at least "
                                 "2 per state and speed (one to train on, one unseen)")
            if "study" in runs and windows.min() < 2:
                raise StoreError(f"{at}: a simulation of state {c} has {windows.min()} window; the study's split "
                                 "takes the windows of one simulation to both sides and needs at least 2")
        if "study" in runs:
            n_classes = len(set(g.y.tolist()))
            n = n_classes * min(int(np.min(np.unique(g.units[g.y == c], return_counts=True)[1]))
                                for c in set(g.y.tolist()))
            n_test = math.ceil(float(settings.test_size) * n)
            if n_test < n_classes or n - n_test < n_classes:
                raise StoreError(f"{at}: one simulation per state gives as few as {n} windows, too few for a "
                                 f"stratified split with one per state on each side")
