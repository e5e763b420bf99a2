"""Diagnosis models: the classical pipelines (features -> scaling -> SVM / KELM), the 1-D CNNs, and the model
directory (card + weights) that ``rvdiag train`` writes and ``evaluate`` / ``diagnose`` read.

The public names below are imported on first use (PEP 562), so ``import rvdiag.models`` and the classical
pipelines do not import torch; only the CNN names do.

========================  ===========================================================================
make_classical_model      ``features -> StandardScaler -> svm | kelm | kelm-mpa | kelm-ga | kelm-pso``
feature_names             every ``features`` name of the pipelines (signal feature sets and ``cnn``)
KELMClassifier            kernel extreme learning machine (Huang et al. 2012)
TunedKELM                 KELM with (C, sigma) tuned by MPA, GA or PSO
CompoundFaultClassifier   three binary classifiers (broken, worn, cracked) decoded to T1..T6 (--multilabel)
CNNClassifier             1-D CNN classifier with the scikit-learn API (cnn1d, cnn1d-lean, spectrum-cnn)
CNNFeatures               the ``cnn`` feature set: a CNN's last hidden layer as features
save_model, load_model    model directories (card.json + model.safetensors | model.skops)
read_card                 the one reader of the model card
========================  ===========================================================================

The baseline monitor (a model that compares a record with its machine's own baseline) is
:class:`rvdiag.monitoring.BaselineMonitor`, in the monitoring package above this one.
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "CNNClassifier": "rvdiag.models.torch_estimator",
    "CNNFeatures": "rvdiag.models.cnn_features",
    "CompoundFaultClassifier": "rvdiag.models.multilabel",
    "KELMClassifier": "rvdiag.models.kelm",
    "LoadedModel": "rvdiag.models.persistence",
    "MODEL_NAMES": "rvdiag.models.pipelines",
    "TunedKELM": "rvdiag.models.tuning",
    "feature_names": "rvdiag.models.pipelines",
    "load_classical": "rvdiag.models.pipelines",
    "load_model": "rvdiag.models.persistence",
    "make_classical_model": "rvdiag.models.pipelines",
    "make_feature_set": "rvdiag.models.pipelines",
    "read_card": "rvdiag.models.card",
    "save_classical": "rvdiag.models.pipelines",
    "save_model": "rvdiag.models.persistence",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'rvdiag.models' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
