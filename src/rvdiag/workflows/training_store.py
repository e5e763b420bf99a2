"""What a model card says of the store it was trained on (``training_store``): one home for ``rvdiag train`` and
the monitor's (:mod:`rvdiag.monitoring.training`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def content_hash(store) -> str:
    """Hash of the store's identity when it has no config hash: classes, length, n, labels."""
    import hashlib

    h = hashlib.sha256()
    h.update(json.dumps([store.classes, store.length, store.n_samples]).encode())
    h.update(np.asarray(store.labels, dtype=np.int64).tobytes())
    return h.hexdigest()[:16]


def signal_info(store) -> dict:
    """What the store's samples are: ``channel`` (the library's, e.g. ``x`` or ``i_a``) and ``signal``
    (``vibration`` or ``current``), so that ``rvdiag diagnose`` reads the same kind of channel of a file."""
    cfg = store.attrs.get("config") or {}
    model = cfg.get("model") if isinstance(cfg.get("model"), dict) else {}
    info = {"signal": str(model.get("signal") or "vibration")}
    if isinstance(cfg.get("channel"), (str, int)):
        info["channel"] = cfg["channel"]
    return info


def training_store_info(store, data, n_train: int) -> dict:
    """The card's ``training_store``: the store's path, its config hash (or :func:`content_hash`), its kind, the
    number of training samples and :func:`signal_info`."""
    return {"path": str(Path(data).resolve()), "config_hash": store.attrs.get("config_hash") or content_hash(store),
            "kind": store.attrs.get("kind"), "n_train": int(n_train), **signal_info(store)}
