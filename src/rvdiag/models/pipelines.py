"""Classical diagnosis pipelines (features -> standardisation -> SVM or KELM) and their safe persistence.

``make_classical_model(model, features)`` builds the scikit-learn :class:`~sklearn.pipeline.Pipeline`

    ("features", feature transformer) -> ("scale", StandardScaler) -> ("clf", classifier)

for the model names of ``rvdiag train --model``:

=========  =====================================================================================
svm        RBF SVC (C = 10, gamma = "scale") with Platt-scaled probabilities; ``grid=True`` picks C
           from {1, 10, 100, 1000} by 3-fold stratified CV (Li, Zhao et al. 2024: features + SVM).
           Probabilities come from ``CalibratedClassifierCV(method="sigmoid", ensemble=False)``,
           scikit-learn 1.9's replacement for the deprecated ``SVC(probability=True)`` (same Platt
           scaling; Platt 1999)
kelm       :class:`~rvdiag.models.kelm.KELMClassifier` (C = 1, sigma = "scale")
kelm-mpa   :class:`~rvdiag.models.tuning.TunedKELM` with the Marine Predators Algorithm
kelm-ga    ... with a genetic algorithm
kelm-pso   ... with particle swarm optimisation   (Tu et al. 2023, EEMD-MPA-KELM, and its comparisons)
=========  =====================================================================================

and feature names of :func:`rvdiag.features.make_features` (``time|spectrum|wpd|eemd|none``, ``cnn``).

Persistence: :func:`save_classical` writes ``model.skops`` (``skops.io``) and ``card.json``;
:func:`load_classical` refuses any type that is not on an explicit trusted list (:data:`TRUSTED_TYPES`) and
never unpickles: skops reconstructs objects from a JSON schema without running ``pickle``.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

from sklearn.calibration import CalibratedClassifierCV
from sklearn.model_selection import GridSearchCV, StratifiedKFold
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC

from rvdiag.errors import ModelFileError, ParameterError
from rvdiag.features import make_features
from rvdiag.models.kelm import KELMClassifier
from rvdiag.models.tuning import OPTIMIZERS, TunedKELM

MODEL_NAMES = ("svm", "kelm", "kelm-mpa", "kelm-ga", "kelm-pso")
CARD_FORMAT = "rvdiag-classical-model"
CARD_VERSION = 1

#: Types a saved classical model may contain (skops type names); nothing else is loaded.
TRUSTED_TYPES: set[str] = {
    "rvdiag.features.RawSignal",
    "rvdiag.features.timedomain.TimeDomainFeatures",
    "rvdiag.features.spectrum.SpectrumFeatures",
    "rvdiag.features.spectrum.CharacteristicBandEnergy",
    "rvdiag.features.spectrum.EnvelopeSpectrumFeatures",
    "rvdiag.features.wavelet.WaveletPacketEnergy",
    "rvdiag.features.bearing.BearingEnvelopeFeatures",
    "rvdiag.features.eemd.EEMDFeatures",
    "rvdiag.models.kelm.KELMClassifier",
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
}


def register_trusted_type(name: str) -> None:
    """Allow another type (its skops name, e.g. ``'rvdiag.models.cnn.CNNFeatures'``) in saved models."""
    TRUSTED_TYPES.add(name)


def _classifier(model: str, seed: int, grid: bool, model_kw: dict):
    if model == "svm":
        kw = {"C": 10.0, "gamma": "scale", "random_state": seed}
        kw.update(model_kw)
        svc = SVC(kernel="rbf", **kw)
        if grid:
            cv = StratifiedKFold(n_splits=3, shuffle=True, random_state=seed)
            svc = GridSearchCV(svc, {"C": [1.0, 10.0, 100.0, 1000.0]}, cv=cv)
        return CalibratedClassifierCV(svc, method="sigmoid", ensemble=False, cv=3)
    if model == "kelm":
        return KELMClassifier(**model_kw)
    name = model.split("-", 1)[1]
    kw = {"optimizer": name, "seed": seed}
    kw.update(model_kw)
    return TunedKELM(**kw)


def make_classical_model(model: str, features: str, *, features_kw: dict | None = None,
                         model_kw: dict | None = None, seed: int = 0, grid: bool = False) -> Pipeline:
    """Unfitted pipeline ``features -> StandardScaler -> classifier``.

    Parameters
    ----------
    model : {'svm', 'kelm', 'kelm-mpa', 'kelm-ga', 'kelm-pso'}
    features : {'time', 'spectrum', 'wpd', 'eemd', 'none', 'cnn'}
    features_kw : dict
        Arguments of the feature transformer (e.g. ``{"ensemble_size": 50}`` for eemd).
    model_kw : dict
        Arguments of the classifier (SVC, KELMClassifier or TunedKELM, e.g. ``{"epoch": 30}``).
    seed : int
        Seed of the SVM's probability calibration, the CV folds and the optimisers.
    grid : bool
        SVM only: choose C by a small cross-validated grid.
    """
    if model not in MODEL_NAMES:
        raise ParameterError(f"unknown model {model!r}; use one of {'|'.join(MODEL_NAMES)}")
    assert all(m.split("-", 1)[1] in OPTIMIZERS for m in MODEL_NAMES if "-" in m)
    try:
        clf = _classifier(model, int(seed), bool(grid), dict(model_kw or {}))
    except TypeError as exc:
        raise ParameterError(f"bad options for model {model!r}: {exc}") from None
    return Pipeline([
        ("features", make_features(features, **dict(features_kw or {}))),
        ("scale", StandardScaler()),
        ("clf", clf),
    ])


def save_classical(model, directory, metadata: dict | None = None) -> Path:
    """Write a fitted pipeline to ``directory`` as ``model.skops`` plus ``card.json``.

    ``metadata`` (JSON-serialisable: labels, feature set, window length, fs...) is stored in the card.
    Both files are written to temporary names and renamed, so a failure leaves no half-written model.
    """
    import skops
    import skops.io as sio
    import sklearn

    import rvdiag

    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    card = {
        "format": CARD_FORMAT,
        "version": CARD_VERSION,
        "estimator": f"{type(model).__module__}.{type(model).__qualname__}",
        "rvdiag_version": getattr(rvdiag, "__version__", "unknown"),
        "sklearn_version": sklearn.__version__,
        "skops_version": skops.__version__,
        "metadata": metadata or {},
    }
    try:
        card_text = json.dumps(card, indent=2)
    except TypeError as exc:
        raise ParameterError(f"model metadata is not JSON-serialisable: {exc}") from None
    blob = sio.dumps(model)
    for name, data in (("model.skops", blob), ("card.json", card_text.encode())):
        fd, tmp = tempfile.mkstemp(dir=d, prefix=f".{name}.")
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
            os.replace(tmp, d / name)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    return d


def read_card(directory) -> dict:
    """The ``card.json`` of a saved classical model, checked; ModelFileError if absent or not ours."""
    p = Path(directory) / "card.json"
    if not p.is_file():
        raise ModelFileError(f"{directory}: not a saved classical model (no card.json)")
    try:
        card = json.loads(p.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelFileError(f"{p}: unreadable model card ({exc})") from None
    if not isinstance(card, dict) or card.get("format") != CARD_FORMAT:
        raise ModelFileError(f"{p}: not an rvdiag classical model card")
    if card.get("version") != CARD_VERSION:
        raise ModelFileError(f"{p}: model card version {card.get('version')!r} is not supported")
    return card


def load_classical(directory):
    """Load a pipeline saved by :func:`save_classical`; only :data:`TRUSTED_TYPES` are accepted.

    Raises
    ------
    ModelFileError
        Missing or corrupt files, or a file that holds a type not on the trusted list.
    """
    import skops.io as sio

    read_card(directory)
    p = Path(directory) / "model.skops"
    if not p.is_file():
        raise ModelFileError(f"{directory}: no model.skops")
    try:
        data = p.read_bytes()
        untrusted = sio.get_untrusted_types(data=data)
    except Exception as exc:  # skops raises many kinds on a corrupt archive
        raise ModelFileError(f"{p}: not a readable skops model file ({type(exc).__name__}: {exc})") from None
    bad = sorted(set(untrusted) - TRUSTED_TYPES)
    if bad:
        raise ModelFileError(f"{p}: refusing to load untrusted types {bad}")
    try:
        return sio.loads(data, trusted=list(untrusted))
    except Exception as exc:
        raise ModelFileError(f"{p}: cannot load model ({type(exc).__name__}: {exc})") from None
