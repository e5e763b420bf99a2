"""Paired libraries: each simulated reducer seen healthy at commissioning, then in its states (``[baseline]``).

A robot joint is monitored against its own commissioning records (docs/monitoring.md).  A library config with a
``[baseline]`` table simulates that: ``[split] reducers`` simulated reducers, each with its own specimen, stiffness,
damping, sensor path, sensor and noise floor (drawn once per reducer, from :func:`reducer_seed`), each recorded

- healthy at commissioning (role ``"baseline"``): ``records_per_point`` records at each of the ``operating_points``;
- later (role ``"monitored"``): ``monitored_healthy`` healthy (T1) records and ``monitored_per_state`` records of
  every other configured state, each at one of the operating points, drawn.

Between any two records of one reducer, commissioning ones included, the run-to-run variation of
:data:`rvdiag.library.config.VARIATION_KEYS` is drawn per record (:func:`draw_variation`) and recorded: load,
speed, temperature (every stiffness of :data:`rvdiag.library.config.STIFFNESS_KEYS` by one factor), mesh damping
and sensor gain, each a
factor uniform in ``1 +- pct / 100``.  Without it a record differs from its baseline only by its fault and noise,
and every figure measured on the library would be meaningless.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from rvdiag.library.config import STIFFNESS_KEYS, VARIATION_KEYS

#: the first element of a reducer's spawn key (:func:`reducer_seed`): two elements, so never a unit's key ``(u,)``
REDUCER_STREAM = 27


def reducer_seed(seed: int, reducer: int) -> int:
    """The 63-bit seed of simulated reducer ``reducer`` of a library of master seed ``seed``: the state of
    ``SeedSequence(seed, spawn_key=(REDUCER_STREAM, reducer))``, independent of every unit's stream (units are the
    children ``(u,)`` of ``SeedSequence(seed)``) and of how many records the reducer has."""
    child = np.random.SeedSequence(int(seed), spawn_key=(REDUCER_STREAM, int(reducer)))
    hi, lo = child.generate_state(2, np.uint32).tolist()
    return ((hi << 32) | lo) & 0x7FFF_FFFF_FFFF_FFFF


def draw_variation(rng: np.random.Generator, pct: Mapping[str, float] | None = None) -> dict[str, float]:
    """One record's run-to-run factors ``{key: 1 + pct[key] / 100 * U(-1, 1)}`` for every key of
    :data:`VARIATION_KEYS`, in its order (five draws of ``rng``, always, so that streams stay aligned; a key at
    0 % gives exactly 1).

    >>> f = draw_variation(np.random.default_rng(0))
    >>> list(f) == list(VARIATION_KEYS) and all(abs(v - 1) <= VARIATION_KEYS[k] / 100 for k, v in f.items())
    True
    """
    pct = VARIATION_KEYS if pct is None else {**VARIATION_KEYS, **pct}
    return {key: float(1.0 + float(pct[key]) / 100.0 * rng.uniform(-1.0, 1.0)) for key in VARIATION_KEYS}


def apply_variation(params: Any, variation: Mapping[str, float]) -> Any:
    """``params`` (:class:`rvdiag.params.ReducerParams`) with a record's ``temperature`` factor on every stiffness
    of :data:`rvdiag.library.config.STIFFNESS_KEYS` and its ``mesh_damping`` factor on the mesh damping ratio (the
    load, speed and gain factors act on the operating point and the signal, not on the parameters)."""
    changes: dict[str, dict[str, float]] = {}
    t = float(variation.get("temperature", 1.0))
    if t != 1.0:
        for section, key in STIFFNESS_KEYS:
            changes.setdefault(section, {})[key] = getattr(getattr(params, section), key) * t
    d = float(variation.get("mesh_damping", 1.0))
    if d != 1.0:
        changes.setdefault("damping", {})["mesh_damping_ratio"] = params.damping.mesh_damping_ratio * d
    return params.replace(**changes) if changes else params
