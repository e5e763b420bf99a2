"""Specimens: each simulated reducer with manufacturing errors of its own (``[randomise] specimen = true``).

The dynamic model draws a reducer's manufacturing errors (the ISO 1328 pitch deviations of the sun, planet runout,
crank-hole positions, crank phases, pin radii: :mod:`rvdiag.dynamics.manufacturing`, docs/model.md section 9) from
``[modification] error_seed`` at the tolerance class ``[modification] iso1328_grade``.  A library whose units all
keep the parameter file's ``error_seed`` simulates one specimen; a classifier trained on it learns that specimen's
healthy signature, and calls another reducer's few micrometres of pitch error a fault.  With ``specimen = true``
every unit is its own specimen: :func:`draw_specimen` gives it a fresh ``error_seed`` (and a grade, when the config
sweeps ``iso1328_grade``) from the unit's own specimen stream (:func:`specimen_seed`), and :func:`apply_specimen`
puts it into the unit's parameters.

One function per step, so that a library that simulates one specimen several times (a paired library: the same
reducer healthy at commissioning and later in a fault state) draws the specimen from a seed of its own choosing.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

#: the index of the specimen stream among the children of a unit's ``SeedSequence`` (0-3: draws, simulator seed,
#: noise, split; :func:`rvdiag.library.build.unit_streams`); its own child, so adding it left the others unchanged
SPECIMEN_STREAM = 4
#: ``error_seed`` values drawn lie in ``[0, ERROR_SEED_RANGE)`` (short enough to type into a parameter file)
ERROR_SEED_RANGE = 2**31


def specimen_seed(unit_seed: int) -> int:
    """The seed of unit ``unit_seed``'s specimen: the 63-bit state of child :data:`SPECIMEN_STREAM` of
    ``SeedSequence(unit_seed)`` (a stream no other draw of the unit uses)."""
    child = np.random.SeedSequence(int(unit_seed), spawn_key=(SPECIMEN_STREAM,))
    hi, lo = child.generate_state(2, np.uint32).tolist()
    return ((hi << 32) | lo) & 0x7FFF_FFFF_FFFF_FFFF


def draw_specimen(seed: int, iso1328_grade: Any = None) -> dict[str, int]:
    """One specimen's manufacturing draw from ``seed``: ``{"error_seed": int}``, plus ``"iso1328_grade"`` when
    ``iso1328_grade`` is given (a whole number, or a :class:`rvdiag.library.config.Sweep` of whole numbers: a list
    draws one element, ``{min, max}`` one whole number in ``[min, max]``, each with equal probability).  The same
    seed always gives the same specimen; the grade's draw follows the error seed's, so a config that adds a grade
    sweep keeps every specimen's ``error_seed``.

    >>> draw_specimen(1) == draw_specimen(1) and draw_specimen(1) != draw_specimen(2)
    True
    """
    rng = np.random.default_rng(int(seed))
    out = {"error_seed": int(rng.integers(0, ERROR_SEED_RANGE))}
    if iso1328_grade is not None:
        u = rng.random()
        kind = getattr(iso1328_grade, "kind", "fixed")
        values = tuple(getattr(iso1328_grade, "values", (iso1328_grade,)))
        if kind == "uniform":
            lo, hi = int(values[0]), int(values[1])
            grade = lo + min(int(u * (hi - lo + 1)), hi - lo)
        elif kind == "choice":
            grade = int(values[min(int(u * len(values)), len(values) - 1)])
        else:
            grade = int(values[0])
        out["iso1328_grade"] = grade
    return out


def apply_specimen(params: Any, specimen: Mapping[str, int]) -> Any:
    """``params`` (:class:`rvdiag.params.ReducerParams`) with the specimen's ``error_seed`` (and ``iso1328_grade``,
    when drawn) in ``[modification]``, and without a stated ``sun_tooth_errors_um`` (the drawn specimen's own
    pattern replaces it); unchanged for an empty specimen."""
    changes = {k: int(v) for k, v in specimen.items() if k in ("error_seed", "iso1328_grade")}
    if not changes:
        return params
    data = params.to_dict()
    data["modification"].pop("sun_tooth_errors_um", None)      # a stated pattern is one specimen's: the draw's
    data["modification"].update(changes)
    return type(params).from_dict(data, source=params.source)


def override_message(params: Any, iso1328_grade: Any = None) -> str | None:
    """The one-line warning for a parameter file whose specimen the draw replaces (``None`` when nothing is lost):
    its ``[modification] error_seed`` is not the default, or it sets a grade that a drawn grade replaces."""
    from rvdiag.params.schema import Modification

    md, default = params.modification, Modification()
    lost = []
    if md.error_seed != default.error_seed:
        lost.append(f"error_seed = {md.error_seed}")
    if md.sun_tooth_errors_um is not None:
        lost.append("sun_tooth_errors_um")
    if iso1328_grade is not None and md.iso1328_grade != default.iso1328_grade:
        lost.append(f"iso1328_grade = {md.iso1328_grade}")
    if not lost:
        return None
    return (f"[randomise] specimen = true draws each simulated reducer's manufacturing errors: the parameter file's "
            f"[modification] {' and '.join(lost)} is not used (remove specimen to simulate that one specimen)")


def count_specimens(meta: Mapping[str, Any]) -> int:
    """Distinct specimens (``error_seed``, ``iso1328_grade`` pairs) among a library store's samples (its metadata
    columns); 1 for a library without specimen draws (every simulation the parameter file's specimen)."""
    if "error_seed" not in meta:
        return 1
    grades = meta.get("iso1328_grade", [None] * len(meta["error_seed"]))
    return len({(int(e), None if g is None else int(g)) for e, g in zip(meta["error_seed"], grades)})
