"""Saved models: a model is a DIRECTORY.

CNN models (``kind = "cnn"``)::

    MODEL_DIR/model.safetensors   the network weights (safetensors: plain tensors, no code is executed)
    MODEL_DIR/card.json           the model card

Classical models (``kind = "classical"``, SVM / KELM pipelines)::

    MODEL_DIR/model.skops         the pipeline (skops, loaded with a trusted-type list, never unpickled;
                                  written by :func:`rvdiag.models.pipelines.save_classical`)
    MODEL_DIR/card.json           the model card

Both kinds share ONE card format (:mod:`rvdiag.models.card`: format "rvdiag-model", version 1, the fields
below at the top level) and ONE reader, :func:`rvdiag.models.card.read_card`.

Card fields (both kinds, returned by :func:`load_model` as ``card``):

``kind`` ("cnn" | "classical"), ``model`` (the ``--model`` name), ``features`` (classical), ``classes``,
``input_length`` (points per sample = the training samples' length), ``metadata_columns`` (the
metadata a model reads after each sample's points, e.g. ``["rpm"]`` for bearing-envelope features:
its ``predict`` takes ``input_length + len(metadata_columns)`` columns, built by :meth:`LoadedModel.inputs`),
``fs`` (Hz or None), ``preprocessing`` (normalisation, representation, network input length, window starts,
policy for long samples; for ``--representation orders``/``orders-residual`` also ``samples_per_rev``,
``speed_column`` and ``shaft``, the speed column being the model's one ``metadata_columns`` entry),
``training_store`` (``path``, ``config_hash``, ``kind``, ``n_train``), ``metrics`` (on the
held-out test split), ``seed``, ``rvdiag_version``, ``created`` (UTC ISO time); CNN cards also hold
``params`` (the estimator's ``get_params``), the learned scalars and ``history``; classical cards hold
``estimator``, ``sklearn_version`` and ``skops_version``, and those trained with ``--multilabel``
``multilabel`` (``labels``: broken, worn, cracked; ``decoding``).  Models written by ``rvdiag train`` also
hold ``operating_range`` (speed, load, sampling rate and signal level of the training samples:
:func:`rvdiag.models.conditions.operating_range`) and ``novelty`` (the out-of-distribution check, its arrays in
``MODEL_DIR/novelty.safetensors``: :mod:`rvdiag.models.novelty`); both are optional, so earlier models load.

Loading a directory that is no model, a card of another format/version, or weights that do not fit the
card (missing or extra tensors, wrong shapes) raises :class:`rvdiag.errors.ModelFileError`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from rvdiag import __version__
from rvdiag.atomic import atomic_write, staged_directory
from rvdiag.errors import ModelFileError, ParameterError
from rvdiag.models.card import CARD, CARD_FORMAT, CARD_VERSION, jsonable, now, read_card, write_card
from rvdiag.models.cnn import build_network
from rvdiag.models.torch_estimator import ANGLE_REPRESENTATIONS, CNNClassifier, network_length

WEIGHTS = "model.safetensors"
__all__ = ["CARD", "CARD_FORMAT", "CARD_VERSION", "LoadedModel", "WEIGHTS", "base_card", "load_model", "read_card",
           "save_model"]

_CNN_PARAM_KEYS = ("architecture", "input_length", "long_input", "normalize", "max_epochs", "batch_size",
                   "learning_rate", "weight_decay", "validation_fraction", "n_iter_no_change", "device",
                   "random_state", "net_kwargs", "representation", "fs", "speed_column", "shaft", "samples_per_rev")


@dataclass
class LoadedModel:
    """A model read back from its directory.

    Attributes
    ----------
    estimator : fitted scikit-learn-compatible classifier (``predict``, ``predict_proba``, ``classes_``)
    card : dict, the card fields listed in the module docstring
    path : Path
    novelty : :class:`rvdiag.models.novelty.NoveltyDetector` or None (a model written without one)
    """

    estimator: Any
    card: dict
    path: Path
    novelty: Any = None

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

    @property
    def metadata_columns(self) -> list[str]:
        """Metadata the model reads after each sample's points (card ``metadata_columns``; usually none)."""
        return [str(c) for c in self.card.get("metadata_columns") or []]

    def inputs(self, X, meta: dict | None = None, where: str = "the data") -> np.ndarray:
        """The estimator's input for samples ``X``: ``X`` itself, or ``X`` with the model's metadata columns
        from ``meta`` appended (:func:`rvdiag.features.combine.with_metadata`; StoreError names ``where`` when
        a column is missing)."""
        from rvdiag.features.combine import with_metadata

        return with_metadata(X, meta, self.metadata_columns, where)


def base_card(estimator, *, model: str, features: str | None = None, fs: float | None = None,
              training_store: dict | None = None, metrics: dict | None = None, seed: int | None = None,
              extra: dict | None = None) -> dict:
    """The card fields common to both kinds (see module docstring)."""
    from rvdiag.features.combine import input_metadata

    classes = [str(c) for c in getattr(estimator, "classes_", [])]
    meta_cols = list(input_metadata(estimator))
    card = {
        "model": model,
        "features": features,
        "classes": classes,
        "input_length": int(estimator.n_features_in_) - len(meta_cols),
        "metadata_columns": meta_cols,
        "fs": None if fs is None else float(fs),
        "training_store": training_store or {},
        "metrics": metrics or {},
        "seed": seed,
        "rvdiag_version": __version__,
        "created": now(),
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
        if hasattr(estimator, "samples_per_rev_"):  # angle-domain input: what evaluate / diagnose rebuild
            card["preprocessing"].update({"samples_per_rev": int(estimator.samples_per_rev_),
                                          "speed_column": str(estimator.speed_column),
                                          "shaft": str(estimator.shaft)})
    else:
        card["kind"] = "classical"
        card["preprocessing"] = {"features": features, "scaling": "StandardScaler on the features"}
        from rvdiag.models.multilabel import FAULT_LABELS, CompoundFaultClassifier

        steps = getattr(estimator, "steps", None)
        if steps and isinstance(steps[-1][1], CompoundFaultClassifier):
            card["multilabel"] = {"labels": list(FAULT_LABELS),
                                  "decoding": "largest joint probability over the training states' combinations"}
    card.update(extra or {})
    return jsonable(card)


def save_model(estimator, directory: str | Path, novelty=None, *, files: dict[str, bytes] | None = None,
               **card_fields) -> Path:
    """Save a fitted classifier as a model directory; returns the directory.

    The directory is written whole to a temporary sibling and then swapped in (:func:`rvdiag.atomic.staged_directory`):
    an existing directory is replaced entirely (no ``model.safetensors`` of an earlier CNN is left beside a new
    ``model.skops``), and an interrupted save leaves the old directory as it was.

    Parameters
    ----------
    estimator : CNNClassifier or a classical pipeline from :func:`rvdiag.models.pipelines.make_classical_model`
    directory : path, created if needed; an existing directory is replaced whole
    novelty : :class:`rvdiag.models.novelty.NoveltyDetector` or None: written to ``novelty.safetensors``, its
        threshold to the card's ``novelty``
    files : more files to write into the directory (name -> bytes), e.g. ``repeat.json``
    **card_fields : keyword arguments of :func:`base_card` (``model`` is required)
    """
    d = Path(directory)
    if d.exists() and not d.is_dir():
        raise ModelFileError(f"{d} exists and is not a directory")
    card = base_card(estimator, **card_fields)
    if novelty is not None:
        card["novelty"] = novelty.card()
    with staged_directory(d) as tmp:
        if novelty is not None:
            novelty.save(tmp)
        _write_model(estimator, tmp, card)
        for name, data in (files or {}).items():
            atomic_write(tmp / name, data)
    return d


def _write_model(estimator, d: Path, card: dict) -> None:
    """The model files and card of ``estimator`` into the (new, empty) folder ``d``."""
    if card["kind"] == "classical":
        from rvdiag.models.pipelines import save_classical

        save_classical(estimator, d, metadata=card)
        return
    from safetensors.torch import save as st_save

    state = {k: v.detach().cpu().contiguous() for k, v in estimator.net_.state_dict().items()}
    card.update({
        "params": jsonable({k: estimator.get_params()[k] for k in _CNN_PARAM_KEYS}),
        "n_epochs": int(estimator.n_epochs_),
        "best_epoch": int(estimator.best_epoch_),
        "history": jsonable(estimator.history_),
        "torch_version": torch.__version__,
    })
    atomic_write(d / WEIGHTS, st_save(state, metadata={"format": CARD_FORMAT}))
    write_card(d, card)


def load_model(directory: str | Path) -> LoadedModel:
    """Load a model directory written by :func:`save_model`; :class:`ModelFileError` if it is not one."""
    from rvdiag.models.novelty import load_novelty

    d = Path(directory)
    card = read_card(d)
    if card["kind"] == "classical":
        from rvdiag.models.pipelines import load_classical

        est = load_classical(d)
        got = [str(c) for c in getattr(est, "classes_", [])]
        if got != [str(c) for c in card["classes"]]:
            raise ModelFileError(f"{d}: classes in model.skops {got} do not match the card {card['classes']}")
        return LoadedModel(est, card, d, load_novelty(d, card))
    return LoadedModel(_load_cnn(d, card), card, d, load_novelty(d, card))


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
    est.n_features_in_ = int(card["input_length"]) + len(card.get("metadata_columns") or [])
    est.net_input_length_ = W
    est.window_starts_ = np.asarray(pre["window_starts"], dtype=np.int64)
    if est.representation in ANGLE_REPRESENTATIONS:
        if not isinstance(pre.get("samples_per_rev"), int) or est.input_metadata() != tuple(card["metadata_columns"]):
            raise ModelFileError(f"{d}/card.json: an angle-domain CNN needs preprocessing.samples_per_rev and its "
                                 f"speed column in metadata_columns")
        est.samples_per_rev_ = int(pre["samples_per_rev"])
    elif est.window_starts_.size == 0 or est.window_starts_.max() + W > est.n_features_in_:
        raise ModelFileError(f"{d}/card.json: window starts do not fit the input length")
    est.norm_mean_ = float(pre.get("norm_mean", 0.0))
    est.norm_std_ = float(pre.get("norm_std", 1.0))
    est.history_ = card.get("history", [])
    est.n_epochs_ = int(card.get("n_epochs", len(est.history_)))
    est.best_epoch_ = int(card.get("best_epoch", 0))
    est.device_ = "cpu"
    return est
