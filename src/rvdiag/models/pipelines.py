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

With ``multilabel=True`` the classifier is wrapped in :class:`~rvdiag.models.multilabel.CompoundFaultClassifier`
(three binary copies, broken / worn / cracked, decoded to T1..T6 by the largest joint probability).

The feature-set names are those of :func:`feature_names`: those of :func:`rvdiag.features.make_features`
(``time|spectrum|spectrum-abs|logspec|envelope|bearing-envelope|wpd|eemd|none``) plus ``cnn``
(:class:`rvdiag.models.cnn_features.CNNFeatures`), or several joined by ``+``.

Persistence: :func:`save_classical` writes ``model.skops`` (``skops.io``) and ``card.json`` (the one model-card
format of :mod:`rvdiag.models.card`, ``kind = "classical"``);
:func:`load_classical` refuses any type that is not on an explicit trusted list (:data:`TRUSTED_TYPES`) and
never unpickles: skops reconstructs objects from a JSON schema without running ``pickle``.  The trusted
list lives in :mod:`rvdiag.registry`, below every layer, so it does not depend on what was imported before.
"""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

from sklearn.calibration import CalibratedClassifierCV
from sklearn.model_selection import GridSearchCV, StratifiedKFold
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC

from rvdiag import features as _features
from rvdiag.atomic import atomic_write
from rvdiag.errors import ModelFileError, ParameterError
from rvdiag.models.card import card_text, read_card, write_card
from rvdiag.models.cnn_features import CNNFeatures
from rvdiag.models.kelm import KELMClassifier
from rvdiag.models.multilabel import CompoundFaultClassifier
from rvdiag.models.tuning import OPTIMIZERS, TunedKELM
from rvdiag.registry import CLASSICAL_MODELS, MOVED_TYPES
from rvdiag.registry import TRUSTED_TYPES, register_trusted_type  # noqa: F401  (public names, re-exported)

MODEL_NAMES = CLASSICAL_MODELS  # the names are registered below every layer (rvdiag.registry)

#: Feature sets of the models layer, on top of :func:`rvdiag.features.feature_names`.
MODEL_FEATURE_SETS = {"cnn": CNNFeatures}


def feature_names() -> list[str]:
    """Every ``features`` name :func:`make_classical_model` takes (signal feature sets and ``cnn``)."""
    return sorted(set(_features.feature_names()) | set(MODEL_FEATURE_SETS))


def make_feature_set(name: str, **kw):
    """A new, unfitted feature transformer by name (:func:`feature_names`); ``kw`` go to its constructor.

    Names joined by ``+`` (``"spectrum-abs+bearing-envelope"``) give a
    :class:`~rvdiag.features.combine.CombinedFeatures` of those sets; ``kw`` then maps a part's name to the
    arguments of that part (``{"bearing-envelope": {"fs": 12000.0, "speed_column": "rpm"}}``).
    """
    if "+" in name:
        parts = [p.strip() for p in name.split("+")]
        if any(not p for p in parts) or len(set(parts)) != len(parts):
            raise ParameterError(f"feature set {name!r}: join distinct names with '+', "
                                 "e.g. spectrum-abs+bearing-envelope")
        unknown = sorted(set(kw) - set(parts))
        if unknown:
            raise ParameterError(f"options for {unknown}, which are not parts of the feature set {name!r}")
        return _features.CombinedFeatures([(p, make_feature_set(p, **dict(kw.get(p) or {}))) for p in parts])
    if name not in MODEL_FEATURE_SETS:
        if name not in _features.feature_names():
            raise ParameterError(f"unknown feature set {name!r}; use one of {'|'.join(feature_names())}")
        return _features.make_features(name, **kw)
    try:
        return MODEL_FEATURE_SETS[name](**kw)
    except TypeError as exc:
        raise ParameterError(f"bad options for feature set {name!r}: {exc}") from None


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
    kw = {"optimizer": name, "random_state": seed}
    kw.update(model_kw)
    return TunedKELM(**kw)


def make_classical_model(model: str, features: str, *, features_kw: dict | None = None,
                         model_kw: dict | None = None, seed: int = 0, grid: bool = False,
                         multilabel: bool = False) -> Pipeline:
    """Unfitted pipeline ``features -> StandardScaler -> classifier``.

    Parameters
    ----------
    model : {'svm', 'kelm', 'kelm-mpa', 'kelm-ga', 'kelm-pso'}
    features : a name of :func:`feature_names`, or names joined by '+' (:func:`make_feature_set`)
    features_kw : dict
        Arguments of the feature transformer (e.g. ``{"ensemble_size": 50}`` for eemd; for names joined by
        '+', a dict of arguments per part name).
    model_kw : dict
        Arguments of the classifier (SVC, KELMClassifier or TunedKELM, e.g. ``{"epoch": 30}``).
    seed : int
        The ``random_state`` of the SVM, its CV folds and the tuners (``rvdiag train --seed``).
    grid : bool
        SVM only: choose C by a small cross-validated grid.
    multilabel : bool
        The classifier becomes a :class:`~rvdiag.models.multilabel.CompoundFaultClassifier`: one binary copy
        per fault (broken, worn, cracked), decoded to the most probable of the states T1..T6
        (``rvdiag train --multilabel``).
    """
    if model not in MODEL_NAMES:
        raise ParameterError(f"unknown model {model!r}; use one of {'|'.join(MODEL_NAMES)}")
    assert all(m.split("-", 1)[1] in OPTIMIZERS for m in MODEL_NAMES if "-" in m)
    try:
        clf = _classifier(model, int(seed), bool(grid), dict(model_kw or {}))
    except TypeError as exc:
        raise ParameterError(f"bad options for model {model!r}: {exc}") from None
    if multilabel:
        clf = CompoundFaultClassifier(clf)
    return Pipeline([
        ("features", make_feature_set(features, **dict(features_kw or {}))),
        ("scale", StandardScaler()),
        ("clf", clf),
    ])


def save_classical(model, directory, metadata: dict | None = None) -> Path:
    """Write a fitted pipeline to ``directory`` as ``model.skops`` plus its ``card.json``.

    The card (:mod:`rvdiag.models.card`) holds ``kind = "classical"``, the model's ``classes`` and
    ``input_length`` (its ``n_features_in_``), the versions that wrote it, and the JSON-serialisable
    ``metadata`` fields (labels, feature set, fs...: :func:`rvdiag.models.persistence.save_model` passes the
    full card).  Both files are written to temporary names and renamed, so a failure leaves no half-written
    model.
    """
    import skops
    import skops.io as sio
    import sklearn

    import rvdiag

    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    card = {
        "classes": [str(c) for c in getattr(model, "classes_", [])],
        "input_length": getattr(model, "n_features_in_", None),
        **dict(metadata or {}),
        "kind": "classical",
        "estimator": f"{type(model).__module__}.{type(model).__qualname__}",
        "sklearn_version": sklearn.__version__,
        "skops_version": skops.__version__,
    }
    card.setdefault("rvdiag_version", rvdiag.__version__)
    card_text(card)  # not serialisable: ParameterError before anything is written
    atomic_write(d / "model.skops", sio.dumps(model))
    write_card(d, card)
    return d


def _with_moved_types_renamed(data: bytes) -> bytes:
    """A skops file ``data`` with every type of :data:`rvdiag.registry.MOVED_TYPES` named by its module now
    (the ``__module__`` / ``__class__`` of its ``schema.json`` entries); ``data`` itself when it names none.
    The arrays and every other entry are copied unchanged."""
    old = {tuple(k.rsplit(".", 1)): tuple(v.rsplit(".", 1)) for k, v in MOVED_TYPES.items()}
    renamed = []

    def rename(node):
        if isinstance(node, dict):
            key = (node.get("__module__"), node.get("__class__"))
            if key in old:
                renamed.append(key)
                node = {**node, "__module__": old[key][0], "__class__": old[key][1]}
            return {k: rename(v) for k, v in node.items()}
        if isinstance(node, list):
            return [rename(v) for v in node]
        return node

    src = zipfile.ZipFile(io.BytesIO(data))
    schema = rename(json.loads(src.read("schema.json")))
    if not renamed:
        return data
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as dst:
        for info in src.infolist():
            dst.writestr(info, json.dumps(schema).encode() if info.filename == "schema.json" else src.read(info))
    return out.getvalue()


def load_classical(directory):
    """Load a pipeline saved by :func:`save_classical`; only :data:`TRUSTED_TYPES` are accepted.

    Raises
    ------
    ModelFileError
        Missing or corrupt files, or a file that holds a type not on the trusted list.
    """
    import skops.io as sio

    if read_card(directory)["kind"] != "classical":
        raise ModelFileError(f"{directory}: not a classical model (use rvdiag.models.persistence.load_model)")
    p = Path(directory) / "model.skops"
    if not p.is_file():
        raise ModelFileError(f"{directory}: no model.skops")
    try:
        data = _with_moved_types_renamed(p.read_bytes())
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
