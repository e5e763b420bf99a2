"""The names rvdiag's models answer to, and the types a saved classical model may contain.

:data:`CNN_MODELS` and :data:`CLASSICAL_MODELS` are the ``rvdiag train --model`` names: the architectures that
:mod:`rvdiag.models.cnn` builds and the pipelines of :mod:`rvdiag.models.pipelines` (both check against these
tuples), listed here so that the command line reads them without importing torch or scikit-learn.
:data:`RECOMMENDED_TRAINING` is the setup docs/results.md recommends, and the defaults of ``rvdiag train``.

The trusted-type list of :mod:`rvdiag.models.pipelines` follows.

This module sits below every other rvdiag layer (it imports nothing from rvdiag), so the list is complete
whatever has been imported before a model is loaded: a fresh interpreter loads every model that
``save_classical`` writes.  The names are skops type names (``module.qualname``); loading refuses anything
else and never unpickles.
"""

from __future__ import annotations

#: The 1-D CNN architectures (``rvdiag train --model``; :data:`rvdiag.models.cnn.ARCHITECTURES`).
CNN_MODELS: tuple[str, ...] = ("cnn1d", "cnn1d-lean", "spectrum-cnn")

#: Old spellings of model names -> their names now (accepted by ``--model`` with a warning, and in saved cards).
#: ``mcsa-cnn`` read as motor-current analysis; the network is the default for log spectra of vibration.
OLD_MODEL_NAMES: dict[str, str] = {"mcsa-cnn": "spectrum-cnn"}

#: The classical pipelines (``rvdiag train --model``; :data:`rvdiag.models.pipelines.MODEL_NAMES`).
CLASSICAL_MODELS: tuple[str, ...] = ("svm", "kelm", "kelm-mpa", "kelm-ga", "kelm-pso")

#: The training setup docs/results.md recommends (the motor-current paper's CNN on the log spectrum: 100 % on
#: 5 paper-mode seeds, the best CNN on the demo): the defaults of ``rvdiag train``, so that the command with
#: no options trains it.  Keys are the ``rvdiag train`` option names without the leading ``--``.
RECOMMENDED_TRAINING: dict[str, object] = {
    "model": "spectrum-cnn", "representation": "logspec", "epochs": 40, "lr": 3e-3, "patience": 6,
}

#: The skops type names of everything rvdiag itself puts into a saved classical pipeline.
_BUILTIN: frozenset[str] = frozenset({
    "rvdiag.features.RawSignal",
    "rvdiag.features.timedomain.TimeDomainFeatures",
    "rvdiag.features.spectrum.SpectrumFeatures",
    "rvdiag.features.spectrum.CharacteristicBandEnergy",
    "rvdiag.features.spectrum.EnvelopeSpectrumFeatures",
    "rvdiag.features.wavelet.WaveletPacketEnergy",
    "rvdiag.features.bearing.BearingEnvelopeFeatures",
    "rvdiag.features.combine.CombinedFeatures",
    "rvdiag.features.eemd.EEMDFeatures",
    "rvdiag.features.tsa.TSAIndicatorFeatures",
    "rvdiag.features.tsa.OrderSpectrumFeatures",
    "rvdiag.features.zscore.HealthyBaselineFeatures",
    "rvdiag.features.relative.BaselineReferencedFeatures",
    "rvdiag.features.current.CurrentLineFeatures",
    "rvdiag.monitoring.detector.BaselineMonitor",
    "sklearn.covariance._shrunk_covariance.LedoitWolf",
    "sklearn.covariance._elliptic_envelope.EllipticEnvelope",
    "rvdiag.models.cnn_features.CNNFeatures",
    "rvdiag.models.kelm.KELMClassifier",
    "rvdiag.models.multilabel.CompoundFaultClassifier",
    "rvdiag.models.tuning.TunedKELM",
    "sklearn.pipeline.Pipeline",
    "sklearn.preprocessing._data.StandardScaler",
    "sklearn.svm._classes.SVC",
    "sklearn.model_selection._search.GridSearchCV",
    "sklearn.model_selection._split.StratifiedKFold",
    "sklearn.metrics._scorer._PassthroughScorer",
    "sklearn.calibration.CalibratedClassifierCV",
    "sklearn.calibration._CalibratedClassifier",
    "sklearn.calibration._SigmoidCalibration",
    "sklearn.preprocessing._label.LabelEncoder",
    "sklearn.preprocessing._label.LabelBinarizer",
    "sklearn.utils._bunch.Bunch",
    "numpy.ma.core.MaskedArray",
    "numpy.ma.core.MaskedConstant",
    "numpy.float64",
    "numpy.int64",
    "numpy.int32",
    "numpy.bool_",
    "numpy.str_",
    "numpy.ndarray",
    "numpy.dtype",
    "builtins.slice",
    "builtins.tuple",
    "builtins.dict",
    "builtins.list",
    "builtins.int",
    "builtins.float",
    "builtins.str",
    "builtins.bool",
    "builtins.NoneType",
})

#: Types a saved classical model may contain (skops type names); nothing else is loaded.
TRUSTED_TYPES: set[str] = set(_BUILTIN)

#: Types whose module has moved since a saved model could name them: the skops name in an older ``model.skops``
#: -> the name now (one of :data:`TRUSTED_TYPES`).  :func:`rvdiag.models.pipelines.load_classical` reads the new
#: name in place of the old before it checks the file against the trusted list, so a model saved before the move
#: loads as it did.
MOVED_TYPES: dict[str, str] = {
    # features/baseline.py held the healthy-sample z-scores until 2026-11-28 (now features/zscore.py)
    "rvdiag.features.baseline.HealthyBaselineFeatures": "rvdiag.features.zscore.HealthyBaselineFeatures",
    # the baseline monitor lived in models/monitoring.py until 2026-11-28 (now rvdiag.monitoring, its own package)
    "rvdiag.models.monitoring.BaselineMonitor": "rvdiag.monitoring.detector.BaselineMonitor",
    # the CNN features (feature set ``cnn``) lived in features/cnn.py until 2026-11-24 (now models/cnn_features.py)
    "rvdiag.features.cnn.CNNFeatures": "rvdiag.models.cnn_features.CNNFeatures",
}


def register_trusted_type(name: str) -> None:
    """Allow another type in saved models, by its skops name (``'package.module.ClassName'``).

    For user extensions only: every type rvdiag writes is listed here already, so loading never depends
    on which modules happen to have been imported.
    """
    if not (isinstance(name, str) and "." in name):
        raise ValueError(f"a trusted type is a dotted 'module.ClassName' string, got {name!r}")
    TRUSTED_TYPES.add(name)


__all__ = ["CLASSICAL_MODELS", "CNN_MODELS", "MOVED_TYPES", "OLD_MODEL_NAMES", "RECOMMENDED_TRAINING", "TRUSTED_TYPES", "register_trusted_type"]
