"""Saved models: a model is a DIRECTORY.

CNN models (``kind = "cnn"``)::

    MODEL_DIR/model.safetensors   the network weights (safetensors: plain tensors, no code is executed)
    MODEL_DIR/card.json           format "rvdiag-model", version 1, and the card fields below

Classical models (``kind = "classical"``, SVM / KELM pipelines) are written by
:func:`rvdiag.models.pipelines.save_classical` (``model.skops`` loaded with a trusted-type list, never
unpickled, plus its ``card.json``); the card fields below go into that card's ``metadata``.

Card fields (both kinds, returned by :func:`load_model` as ``card``):

``kind`` ("cnn" | "classical"), ``model`` (the ``--model`` name), ``features`` (classical), ``classes``,
``input_length`` (points per sample the model's ``predict`` takes = the training samples' length),
``fs`` (Hz or None), ``preprocessing`` (normalisation, network input length, window starts, policy for
long samples), ``training_store`` (``path``, ``config_hash``, ``kind``, ``n_train``), ``metrics`` (on the
held-out test split), ``seed``, ``rvdiag_version``, ``created`` (UTC ISO time); CNN cards also hold
``params`` (the estimator's ``get_params``), the learned scalars and ``history``.

Loading a directory that is no model, a card of another format/version, or weights that do not fit the
card (missing or extra tensors, wrong shapes) raises :class:`rvdiag.errors.ModelFileError`.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from rvdiag import __version__
from rvdiag.errors import ModelFileError, ParameterError
from rvdiag.models.cnn import build_network
from rvdiag.models.torch_estimator import CNNClassifier, network_length

CARD_FORMAT = "rvdiag-model"
CARD_VERSION = 1
WEIGHTS = "model.safetensors"
CARD = "card.json"

_CNN_PARAM_KEYS = ("architecture", "input_length", "long_input", "normalize", "max_epochs", "batch_size",
                   "learning_rate", "weight_decay", "validation_fraction", "n_iter_no_change", "device",
                   "random_state", "net_kwargs", "representation")


@dataclass
class LoadedModel:
    """A model read back from its directory.

    Attributes
    ----------
    estimator : fitted scikit-learn-compatible classifier (``predict``, ``predict_proba``, ``classes_``)
    card : dict, the card fields listed in the module docstring
    path : Path
    """

    estimator: Any
    card: dict
    path: Path

    @property
    def classes(self) -> list[str]:
        return [str(c) for c in self.card["classes"]]

    @property
    def input_length(self) -> int:
        return int(self.card["input_length"])

    @property
    def fs(self) -> float | None:
        fs = self.card.get("fs")
        return None if fs is None else float(fs)


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    return obj


def _atomic_write(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def base_card(estimator, *, model: str, features: str | None = None, fs: float | None = None,
              training_store: dict | None = None, metrics: dict | None = None, seed: int | None = None,
              extra: dict | None = None) -> dict:
    """The card fields common to both kinds (see module docstring)."""
    classes = [str(c) for c in getattr(estimator, "classes_", [])]
    card = {
        "model": model,
        "features": features,
        "classes": classes,
        "input_length": int(estimator.n_features_in_),
        "fs": None if fs is None else float(fs),
        "training_store": training_store or {},
        "metrics": metrics or {},
        "seed": seed,
        "rvdiag_version": __version__,
        "created": _now(),
    }
    if isinstance(estimator, CNNClassifier):
        card["kind"] = "cnn"
        card["preprocessing"] = {
            "normalize": estimator.normalize,
            "representation": estimator.representation,
            "norm_mean": float(estimator.norm_mean_),
            "norm_std": float(estimator.norm_std_),
            "net_input_length": int(estimator.net_input_length_),
            "long_input": estimator.long_input,
            "window_starts": [int(s) for s in estimator.window_starts_],
        }
    else:
        card["kind"] = "classical"
        card["preprocessing"] = {"features": features, "scaling": "StandardScaler on the features"}
    card.update(extra or {})
    return _jsonable(card)


def save_model(estimator, directory: str | Path, **card_fields) -> Path:
    """Save a fitted classifier as a model directory; returns the directory.

    Parameters
    ----------
    estimator : CNNClassifier or a classical pipeline from :func:`rvdiag.models.pipelines.make_classical_model`
    directory : path, created if needed (existing model files in it are replaced)
    **card_fields : keyword arguments of :func:`base_card` (``model`` is required)
    """
    d = Path(directory)
    if d.exists() and not d.is_dir():
        raise ModelFileError(f"{d} exists and is not a directory")
    card = base_card(estimator, **card_fields)
    if card["kind"] == "classical":
        from rvdiag.models.pipelines import save_classical

        save_classical(estimator, d, metadata=card)
        return d
    from safetensors.torch import save as st_save

    d.mkdir(parents=True, exist_ok=True)
    state = {k: v.detach().cpu().contiguous() for k, v in estimator.net_.state_dict().items()}
    card.update({
        "format": CARD_FORMAT,
        "version": CARD_VERSION,
        "params": _jsonable({k: estimator.get_params()[k] for k in _CNN_PARAM_KEYS}),
        "n_epochs": int(estimator.n_epochs_),
        "best_epoch": int(estimator.best_epoch_),
        "history": _jsonable(estimator.history_),
        "torch_version": torch.__version__,
    })
    _atomic_write(d / WEIGHTS, st_save(state, metadata={"format": CARD_FORMAT}))
    _atomic_write(d / CARD, json.dumps(card, indent=2).encode())
    return d


def read_card(directory: str | Path) -> dict:
    """The card of a model directory (either kind), normalised to the common fields."""
    d = Path(directory)
    if not d.exists():
        raise ModelFileError(f"no model at {d}")
    if not d.is_dir():
        raise ModelFileError(f"{d} is not a model directory (a model is a folder with card.json)")
    p = d / CARD
    if not p.is_file():
        raise ModelFileError(f"{d} is not an rvdiag model directory (no card.json)")
    try:
        raw = json.loads(p.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelFileError(f"{p}: unreadable model card ({exc})") from None
    if not isinstance(raw, dict):
        raise ModelFileError(f"{p}: not an rvdiag model card")
    if raw.get("format") == CARD_FORMAT:
        if raw.get("version") != CARD_VERSION:
            raise ModelFileError(f"{p}: model card version {raw.get('version')!r} is not supported")
        card = raw
    elif raw.get("format") == "rvdiag-classical-model":
        card = dict(raw.get("metadata") or {})
        card.setdefault("kind", "classical")
    else:
        raise ModelFileError(f"{p}: not an rvdiag model card (format {raw.get('format')!r})")
    for key in ("kind", "classes", "input_length"):
        if key not in card:
            raise ModelFileError(f"{p}: model card lacks {key!r}")
    if not isinstance(card["classes"], list) or len(card["classes"]) < 2:
        raise ModelFileError(f"{p}: model card has no valid class list")
    try:
        card["input_length"] = int(card["input_length"])
    except (TypeError, ValueError):
        raise ModelFileError(f"{p}: bad input_length {card['input_length']!r}") from None
    return card


def load_model(directory: str | Path) -> LoadedModel:
    """Load a model directory written by :func:`save_model`; :class:`ModelFileError` if it is not one."""
    d = Path(directory)
    card = read_card(d)
    if card["kind"] == "classical":
        from rvdiag.models.pipelines import load_classical

        est = load_classical(d)
        got = [str(c) for c in getattr(est, "classes_", [])]
        if got != [str(c) for c in card["classes"]]:
            raise ModelFileError(f"{d}: classes in model.skops {got} do not match the card {card['classes']}")
        return LoadedModel(est, card, d)
    if card["kind"] != "cnn":
        raise ModelFileError(f"{d}/card.json: unknown model kind {card['kind']!r}")
    return LoadedModel(_load_cnn(d, card), card, d)


def _load_cnn(d: Path, card: dict) -> CNNClassifier:
    from safetensors import SafetensorError
    from safetensors.torch import load_file

    w = d / WEIGHTS
    if not w.is_file():
        raise ModelFileError(f"{d}: no {WEIGHTS}")
    try:
        state = load_file(str(w))
    except (SafetensorError, OSError, ValueError, RuntimeError) as exc:
        raise ModelFileError(f"{w}: not a readable safetensors file ({exc})") from None
    try:
        params = dict(card["params"])
        pre = card["preprocessing"]
        if params.get("net_kwargs") and "fc_hidden" in params["net_kwargs"]:
            params["net_kwargs"] = dict(params["net_kwargs"], fc_hidden=tuple(params["net_kwargs"]["fc_hidden"]))
        est = CNNClassifier(**params)
        W = int(pre["net_input_length"])
        net = build_network(params["architecture"], len(card["classes"]),
                            network_length(W, params.get("representation", "waveform")),
                            **(params.get("net_kwargs") or {}))
    except (KeyError, TypeError, ValueError, ParameterError) as exc:
        raise ModelFileError(f"{d}/card.json: does not describe a CNN ({type(exc).__name__}: {exc})") from None
    expected = net.state_dict()
    missing = sorted(set(expected) - set(state))
    extra = sorted(set(state) - set(expected))
    if missing or extra:
        raise ModelFileError(f"{w}: weights do not match the card's {params['architecture']} "
                             f"(missing {missing[:3]}, unexpected {extra[:3]})")
    for k, v in expected.items():
        if tuple(v.shape) != tuple(state[k].shape):
            raise ModelFileError(f"{w}: tensor {k} has shape {tuple(state[k].shape)}, the card's "
                                 f"{params['architecture']} needs {tuple(v.shape)}")
    net.load_state_dict(state)
    net.eval()
    est.net_ = net
    est.classes_ = np.array(card["classes"], dtype=object)
    est.n_features_in_ = int(card["input_length"])
    est.net_input_length_ = W
    est.window_starts_ = np.asarray(pre["window_starts"], dtype=np.int64)
    if est.window_starts_.size == 0 or est.window_starts_.max() + W > est.n_features_in_:
        raise ModelFileError(f"{d}/card.json: window starts do not fit the input length")
    est.norm_mean_ = float(pre.get("norm_mean", 0.0))
    est.norm_std_ = float(pre.get("norm_std", 1.0))
    est.history_ = card.get("history", [])
    est.n_epochs_ = int(card.get("n_epochs", len(est.history_)))
    est.best_epoch_ = int(card.get("best_epoch", 0))
    est.device_ = "cpu"
    return est


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
