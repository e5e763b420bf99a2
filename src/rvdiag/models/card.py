"""The model card: ``card.json`` of a model directory, ONE format for every kind of model, and its one reader.

A card is a flat JSON object::

    {"format": "rvdiag-model", "version": 1, "kind": "cnn" | "classical", "model": ..., "classes": [...],
     "input_length": ..., ...}

with the fields listed in :mod:`rvdiag.models.persistence`.  CNN cards add the network's parameters and
training history; classical cards add ``estimator``, ``sklearn_version`` and ``skops_version`` (the
versions that wrote ``model.skops``).  :func:`write_card` writes it atomically, :func:`read_card` is the
only function that parses one: every loader (:func:`rvdiag.models.persistence.load_model`,
:func:`rvdiag.models.pipelines.load_classical`) goes through it.

rvdiag 0.1.0 wrote classical models with a second format (``"rvdiag-classical-model"``, the fields nested
under ``metadata``); no such file ships with rvdiag, and :func:`read_card` refuses one with a message that
says to retrain (``rvdiag train``) rather than guess.
"""

from __future__ import annotations

import datetime as _dt
import json
from pathlib import Path
from typing import Any

import numpy as np

from rvdiag.atomic import atomic_write
from rvdiag.errors import ModelFileError, ParameterError

CARD_FORMAT = "rvdiag-model"
CARD_VERSION = 1
CARD = "card.json"
KINDS = ("cnn", "classical")
_OLD_CLASSICAL_FORMAT = "rvdiag-classical-model"


def now() -> str:
    """The current UTC time, ISO 8601 to the second (the card's ``created``)."""
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()


def jsonable(obj: Any) -> Any:
    """``obj`` with NumPy arrays and scalars, tuples and paths turned into JSON types."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    return obj


def card_text(card: dict) -> bytes:
    """The card as JSON text, with ``format`` and ``version`` first; ParameterError if not serialisable."""
    if card.get("kind") not in KINDS:
        raise ParameterError(f"model card kind must be one of {KINDS}, got {card.get('kind')!r}")
    full = {"format": CARD_FORMAT, "version": CARD_VERSION, **jsonable(card)}
    full["format"], full["version"] = CARD_FORMAT, CARD_VERSION
    try:
        return json.dumps(full, indent=2).encode()
    except TypeError as exc:
        raise ParameterError(f"model card is not JSON-serialisable: {exc}") from None


def write_card(directory: str | Path, card: dict) -> Path:
    """Write ``card`` (a dict with ``kind``; ``format`` and ``version`` are set here) as ``directory/card.json``."""
    p = Path(directory) / CARD
    atomic_write(p, card_text(card))
    return p


def read_card(directory: str | Path) -> dict:
    """The card of a model directory (either kind), checked: :class:`ModelFileError` if it is not one."""
    d = Path(directory)
    if not d.exists():
        raise ModelFileError(f"no model at {d}")
    if not d.is_dir():
        raise ModelFileError(f"{d} is not a model directory (a model is a folder with card.json)")
    p = d / CARD
    if not p.is_file():
        raise ModelFileError(f"{d} is not an rvdiag model directory (no card.json)")
    try:
        card = json.loads(p.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelFileError(f"{p}: unreadable model card ({exc})") from None
    if not isinstance(card, dict):
        raise ModelFileError(f"{p}: not an rvdiag model card")
    if card.get("format") == _OLD_CLASSICAL_FORMAT:
        raise ModelFileError(f"{p}: a model card of rvdiag 0.1.0's former classical format; retrain the model "
                             "with this version (rvdiag train)")
    if card.get("format") != CARD_FORMAT:
        raise ModelFileError(f"{p}: not an rvdiag model card (format {card.get('format')!r})")
    if card.get("version") != CARD_VERSION:
        raise ModelFileError(f"{p}: model card version {card.get('version')!r} is not supported")
    for key in ("kind", "classes", "input_length"):
        if key not in card:
            raise ModelFileError(f"{p}: model card lacks {key!r}")
    if card["kind"] not in KINDS:
        raise ModelFileError(f"{p}: unknown model kind {card['kind']!r}")
    if not isinstance(card["classes"], list) or len(card["classes"]) < 2:
        raise ModelFileError(f"{p}: model card has no valid class list")
    try:
        card["input_length"] = int(card["input_length"])
    except (TypeError, ValueError):
        raise ModelFileError(f"{p}: bad input_length {card['input_length']!r}") from None
    return card
