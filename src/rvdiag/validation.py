"""Checks of one number a user gave, each failing with the one-line error that names it (:mod:`rvdiag.errors`).

The one home of "is this a finite number, above its bound, whole": every module that takes a number from a user
(a Python argument, a command-line option, a TOML key) checks it here and names it in the message, so the
``rvdiag`` command prints it as one ``error:`` line.

Two message forms, one per kind of check:

- step by step (:func:`number`, :func:`at_least`, :func:`positive`, :func:`whole_number`): one message per failed
  step, ``"pit radius must be a number, got '1'"``, ``"... must be finite, got nan"``, ``"... must be > 0, got 0.0
  m"``; with ``error=ConfigError`` (a key of a file) the key is followed by a colon and the type is "expected":
  ``"demo.toml: [signal] hop: expected a number, got 'x'"``, ``"...: must be > 0, got -1"``;
- in one phrase (:func:`finite_number`, :func:`integer`): ``"jerk (deg/s^3) must be a finite number > 0, got
  0.0"``, ``"cv must be an integer >= 2, got 1"``.

``error`` is the exception class to raise (:class:`~rvdiag.errors.ParameterError` by default), or any callable
that makes the exception from the message (``functools.partial(ApiError, 400)``).

Examples
--------
>>> positive(2, "pit radius")
2.0
>>> at_least(-1, "[signal] hop", 0, strict=True, error=ConfigError)
Traceback (most recent call last):
...
rvdiag.errors.ConfigError: [signal] hop: must be > 0, got -1
>>> integer(1, "cv", 2)
Traceback (most recent call last):
...
rvdiag.errors.ParameterError: cv must be an integer >= 2, got 1
"""

from __future__ import annotations

import math
import numbers
from typing import Any, Callable, Optional

import numpy as np

from rvdiag.errors import ConfigError, ParameterError

#: what :func:`number` accepts as a number: Python's and numpy's ints and floats, never a bool
_REAL = (int, float, np.integer, np.floating)


def _is_config(error: Any) -> bool:
    return isinstance(error, type) and issubclass(error, ConfigError)


def _says(name: str, error: Any, phrase: str) -> str:
    """``"name phrase"``, or ``"name: phrase"`` for a file's key (:class:`ConfigError`)."""
    return f"{name}: {phrase}" if _is_config(error) else f"{name} {phrase}"


def _bound(lo: Optional[float], strict: bool) -> str:
    return "" if lo is None else f" {'>' if strict else '>='} {lo:g}"


def is_number(value: Any) -> bool:
    """Whether ``value`` is an int or a float (Python's or numpy's), not a bool, not a string."""
    return not isinstance(value, bool) and isinstance(value, _REAL)


def number(value: Any, name: str, *, error: Callable[[str], Exception] = ParameterError) -> float:
    """``value`` as a finite float, else ``error``: "``name`` must be a number" (a file's key: "expected a number")
    or "must be finite"."""
    if not is_number(value):
        raise error(_says(name, error, f"{'expected' if _is_config(error) else 'must be'} a number, "
                                              f"got {value!r}"))
    x = float(value)
    if not math.isfinite(x):
        raise error(_says(name, error, f"must be finite, got {value!r}"))
    return x


def at_least(value: Any, name: str, lo: float, *, strict: bool = False, unit: str = "",
             error: Callable[[str], Exception] = ParameterError) -> float:
    """:func:`number`, then ``value >= lo`` (``> lo`` where ``strict``), else "``name`` must be >= lo, got value"
    (``unit`` after the value: ``" m"``)."""
    x = number(value, name, error=error)
    if x < lo or (strict and x == lo):
        raise error(_says(name, error, f"must be{_bound(lo, strict)}, got {value!r}{unit}"))
    return x


def positive(value: Any, name: str, *, unit: str = "", error: Callable[[str], Exception] = ParameterError) -> float:
    """:func:`at_least` 0, strictly: a finite number > 0."""
    return at_least(value, name, 0.0, strict=True, unit=unit, error=error)


def whole_number(value: Any, name: str, *, minimum: Optional[int] = None,
                 error: Callable[[str], Exception] = ParameterError) -> int:
    """:func:`number`, then a whole value (3 or 3.0) >= ``minimum``, as an int, else "must be a whole number" (a
    file's key: "expected a whole number") or "must be >= minimum"."""
    x = number(value, name, error=error)
    if x != int(x):
        raise error(_says(name, error, f"{'expected' if _is_config(error) else 'must be'} a whole number, "
                                              f"got {value!r}"))
    if minimum is not None and x < minimum:
        raise error(_says(name, error, f"must be >= {minimum}, got {int(x)}"))
    return int(x)


def finite_number(value: Any, name: str, lo: Optional[float] = None, *, strict: bool = False,
                  noun: str = "a finite number", type_first: bool = False,
                  error: Callable[[str], Exception] = ParameterError) -> float:
    """``value`` as a finite float >= ``lo`` (``> lo`` where ``strict``; any with ``lo`` None), else one phrase,
    "``name`` must be ``noun`` > lo, got value" (``noun``: "a finite number", or "a number" where the bound says
    enough); with ``type_first``, what is not a number gets "``name`` must be a number, got value" instead."""
    if type_first and not is_number(value):
        raise error(f"{name} must be a number, got {value!r}")
    if not is_number(value) or not math.isfinite(value) \
            or (lo is not None and (value < lo or (strict and value == lo))):
        raise error(f"{name} must be {noun}{_bound(lo, strict)}, got {value!r}")
    return float(value)


def integer(value: Any, name: str, minimum: int, *, error: Callable[[str], Exception] = ParameterError) -> int:
    """``value``, an int (Python's or numpy's, not a bool, not a float) >= ``minimum``, as an int, else one phrase:
    "``name`` must be an integer >= minimum, got value"."""
    if isinstance(value, bool) or not isinstance(value, (numbers.Integral, np.integer)) or value < minimum:
        raise error(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def finite_array(values: Any, name: str, *, error: Callable[[str], Exception] = ParameterError) -> np.ndarray:
    """``values`` as a flat float array, else "``name`` must be finite numbers" (a NaN, an infinity, a string)."""
    try:
        a = np.asarray(values, dtype=float).ravel()
    except (TypeError, ValueError):
        raise error(f"{name} must be finite numbers") from None
    if not np.all(np.isfinite(a)):
        raise error(f"{name} must be finite numbers")
    return a
