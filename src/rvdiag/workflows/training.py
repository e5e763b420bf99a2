"""Training a classifier on a sample store: :func:`train` -> :class:`TrainResult` (``rvdiag train``; a baseline
monitor on a paired store is :func:`rvdiag.monitoring.train_monitor`).

Trains on the store's ``train`` split (optionally only where ``conditions`` hold), scores the ``test`` split (when
present) into the model card, fits the out-of-distribution check and records the training operating range, and
saves the model directory (:func:`rvdiag.models.persistence.save_model`).  With ``repeat`` N it trains N seeds
(seed, seed+1, ...) and keeps the first one's model with the summary of all.  The model names are those of
:mod:`rvdiag.registry`; the defaults are the setup docs/results.md recommends
(:data:`rvdiag.registry.RECOMMENDED_TRAINING`).
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from rvdiag.errors import ParameterError, StoreError
from rvdiag.models.conformal import FAULT_COVERAGE, HEALTHY_COVERAGE
from rvdiag.registry import CLASSICAL_MODELS, CNN_MODELS, RECOMMENDED_TRAINING
from rvdiag.workflows.training_store import signal_info, training_store_info

#: share of each state's training reducers held out of the fit to calibrate the prediction sets (``--calibration
#: split``)
DEFAULT_CALIBRATION_FRACTION = 0.2


@dataclass
class TrainResult:
    """A trained and saved classifier (:func:`train`); :meth:`to_dict` is what ``rvdiag train --json`` prints.

    ``metrics``: the first seed's scores on the test split (None without one); ``repeat``: the summary over the seeds
    (``repeat`` > 1); ``estimator``: the fitted model (the first seed's) as saved in ``model_dir``."""

    model_dir: str
    metrics: dict | None = None
    repeat: dict | None = None
    model: str | None = None
    n_train: int = 0
    streamed: bool = False
    estimator: Any = field(default=None, repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready values (``rvdiag train --json``)."""
        return {"model_dir": self.model_dir, "metrics": self.metrics, "repeat": self.repeat}


def check_counts(repeat: int, epochs: int) -> None:
    """Refuse a ``repeat`` or ``epochs`` below 1."""
    if repeat < 1:
        raise ParameterError(f"--repeat must be >= 1, got {repeat}")
    if epochs < 1:
        raise ParameterError(f"--epochs must be >= 1, got {epochs}")


def fit_plain(est, X, y, label: str, groups=None, source=None) -> None:
    """Fit ``est`` without progress output (the default ``fit`` of :func:`train`): a CNN with its validation
    ``groups``, from ``source`` (a :class:`rvdiag.models.streaming.StoreSamples`) when it streams."""
    if hasattr(est, "embed"):
        if source is not None:
            est.fit_store(source, groups=groups)
        else:
            est.fit(X, y, groups=groups)
    else:
        check_class_counts(est, y)
        est.fit(X, y)


def train(data, out, *, model: str | None = None, features: str | None = None,
          epochs: int = RECOMMENDED_TRAINING["epochs"], device: str = "auto", seed: int = 0, repeat: int = 1,
          batch_size: int = 32, lr: float = RECOMMENDED_TRAINING["lr"], input_length: int | None = None,
          patience: int = RECOMMENDED_TRAINING["patience"], validation_fraction: float = 0.2,
          normalize: str = "window", representation: str = RECOMMENDED_TRAINING["representation"],
          snr_db: float | None = None, bearing_geometry: str | None = None, rpm_column: str = "rpm",
          speed_column: str = "output_speed_deg_s", conditions: Sequence[str] = (), streaming: bool | None = None,
          multilabel: bool = False, echo: Callable[[str], None] | None = None,
          fit: Callable[..., None] | None = None, calibration: str | None = None, calibration_folds: int = 3,
          calibration_fraction: float = DEFAULT_CALIBRATION_FRACTION, healthy_coverage: float = HEALTHY_COVERAGE,
          fault_coverage: float = FAULT_COVERAGE, set_rule: str | None = None) -> TrainResult:
    """Train a classifier on the ``train`` split of the store ``data`` and save it to the directory ``out`` (module
    docstring).  The keywords are those of ``rvdiag train`` (``conditions``: its ``--where``); ``echo`` gets the
    progress lines (default: none), ``fit(est, X, y, label, groups=, source=)`` fits one estimator (default
    :func:`fit_plain`; the command line's draws progress bars).  ``out`` is written whole (replaced if it exists:
    refuse an existing one before calling).

    Prediction sets (:mod:`rvdiag.models.conformal`; card ``prediction_sets``): the default (None) is ``"cross"``,
    measured better on the demo's held-out reducers (bench/HISTORY.md), and ``"split"`` when streaming, which holds
    the folds' data out of memory.  ``calibration="split"`` holds
    ``calibration_fraction`` of each state's training reducers (metadata column ``unit``) out of the fit and
    calibrates on them; ``"cross"`` scores every training reducer by a model fitted on the other
    ``calibration_folds`` folds of reducers and applies the thresholds to the model fitted on all (K more fits, no
    reducer lost; measured better on the demo: bench/HISTORY.md).  Stated coverage ``healthy_coverage`` for the
    healthy state, ``fault_coverage`` for each fault.  ``set_rule`` (:data:`rvdiag.models.conformal.RULES`): how
    the thresholds count the calibration samples, ``"windows"`` (the default) or ``"reducers"`` (coverage for a new
    reducer, Lee, Barber & Willett 2023; a state with fewer calibration reducers than its coverage needs, 19 for
    95 % and 9 for 90 %, is in every set).  No sets (card ``prediction_sets_note`` says why) with
    ``calibration_fraction`` 0, without a ``unit`` column, or where a state would get fewer calibration samples than
    its coverage needs (then nothing is held out).

    Raises
    ------
    ParameterError, StoreError
        Unknown model or features, options that do not combine, a store without a train split or classes.
    """
    from rvdiag.datasets import SampleStore
    from rvdiag.evaluation.metrics import classification_metrics, headline, repeat_summary
    from rvdiag.io.windows import covering_starts
    from rvdiag.models.persistence import save_model

    from rvdiag.evaluation.metrics import healthy_class
    from rvdiag.models.conformal import stated_coverages

    echo = echo or (lambda msg: None)
    fit = fit or fit_plain
    out = Path(out)
    check_counts(repeat, epochs)
    if calibration not in (None, "split", "cross"):
        raise ParameterError(f"--calibration must be split or cross, got {calibration!r}")
    from rvdiag.models.conformal import RULES

    if set_rule is not None and set_rule not in RULES:
        raise ParameterError(f"--set-rule must be one of {', '.join(RULES)}, got {set_rule!r}")
    if calibration == "cross" and calibration_folds < 2:
        raise ParameterError(f"--calibration-folds must be >= 2, got {calibration_folds}")
    if not 0.0 <= calibration_fraction < 1.0:
        raise ParameterError(f"--calibration-fraction must lie in [0, 1), got {calibration_fraction}")

    def coverage_of(classes) -> dict[str, float]:
        classes = [str(c) for c in classes]
        return stated_coverages(classes, healthy=healthy_class(classes), healthy_coverage=healthy_coverage,
                                fault_coverage=fault_coverage)

    coverage_of([])  # the coverages are checked before any work
    model = model or RECOMMENDED_TRAINING["model"]
    new_estimator = functools.partial(build_estimator, model, features, epochs=epochs, device=device,
                                      batch_size=batch_size, lr=lr, input_length=input_length,
                                      patience=patience, validation_fraction=validation_fraction,
                                      normalize=normalize, representation=representation,
                                      bearing_geometry=bearing_geometry, rpm_column=rpm_column,
                                      speed_column=speed_column, multilabel=multilabel)
    probe = new_estimator(seed=seed)  # checks the model and features before any work
    if model in CNN_MODELS or "cnn" in (features or "").split("+"):
        from rvdiag.models.torch_estimator import resolve_device

        resolve_device(device)  # 'cuda' without a GPU fails now, not after loading the data
    store = data if isinstance(data, SampleStore) else SampleStore.open(data)
    new_estimator = functools.partial(new_estimator, signal=signal_info(store)["signal"])  # cnn features
    if "train" not in store.splits():
        raise StoreError(f"{data} has no 'train' split (splits: {', '.join(store.splits())})")
    if multilabel:
        from rvdiag.models.multilabel import check_states

        check_states(store.classes, where=f"the store {data}'s classes")
    conditions = list(conditions or ())
    train_idx = store.indices("train", conditions)
    if conditions and not train_idx.size:
        raise StoreError(f"{data}: no training sample where {' and '.join(conditions)}")
    from rvdiag.features.combine import input_metadata, with_metadata

    meta_cols = input_metadata(probe)
    if meta_cols and not store.fs:
        raise StoreError(f"{data} states no sampling rate, which {', '.join(meta_cols)} needs beside it (to place "
                         "the defect lines, or to resample to the shaft angle): rebuild it with "
                         "'rvdiag dataset from-files --fs HZ'")
    if model in CNN_MODELS:
        new_estimator(seed=seed, fs=store.fs).network_input_length(store.length)  # at least one network input long
    stream = _streaming_choice(streaming, model, snr_db, store)
    if calibration is None:
        calibration = "split" if stream else "cross"
    where = f"the store {data}"
    if stream:
        from rvdiag.models.streaming import DEFAULT_BUFFER_SAMPLES, StoreSamples, predict_proba_store, predict_store

        if calibration == "cross":
            raise ParameterError("--calibration cross fits the folds in memory and does not combine with "
                                 "--streaming (use --calibration split)")
        tr = StoreSamples(store, train_idx, meta_cols, where=where)
        te = StoreSamples(store, store.indices("test"), meta_cols, where=where) if "test" in store.splits() else None
        held, cal_note = calibration_split(tr, calibration_fraction, seed, coverage_of(store.classes))
        cal, folds = None, None
        if held is not None:
            cal = StoreSamples(store, tr.index[held], meta_cols, where=where)
            tr = StoreSamples(store, tr.index[~held], meta_cols, where=where)
        Xtr = Xte = Xcal = None
    else:
        tr = store.load(index=train_idx) if conditions else store.load("train")
        te = store.load("test") if "test" in store.splits() else None
        cal, folds = None, None
        if calibration == "cross" and calibration_fraction == 0:
            folds, cal_note = None, "--calibration-fraction 0"
        elif calibration == "cross":
            folds, cal_note = calibration_folds_of(tr, calibration_folds, seed, coverage_of(store.classes))
        else:
            held, cal_note = calibration_split(tr, calibration_fraction, seed, coverage_of(store.classes))
            if held is not None:
                tr, cal = subset(tr, ~held), subset(tr, held)
        if snr_db is not None:
            tr, te = _with_noise(tr, snr_db, [seed, 0]), (None if te is None else _with_noise(te, snr_db, [seed, 1]))
            cal = None if cal is None else _with_noise(cal, snr_db, [seed, 3])
        Xtr = with_metadata(tr.X, tr.meta, meta_cols, where=where)
        Xte = None if te is None else with_metadata(te.X, te.meta, meta_cols, where=where)
        Xcal = None if cal is None else with_metadata(cal.X, cal.meta, meta_cols, where=where)
    labels = [c for c in store.classes if c in set(tr.y.tolist())]
    if len(labels) < 2:
        raise StoreError(f"{data}: the train split holds fewer than 2 classes")
    echo(f"{data}: {len(tr.y)} training samples of {store.length} points, {len(labels)} classes"
         + (f", {len(te.y)} test samples" if te is not None else ", no test split")
         + (f"; streamed from the store, {DEFAULT_BUFFER_SAMPLES} samples at a time" if stream else "")
         + (f"; {len(cal.y)} samples of {_n_groups(cal)} held-out training reducers calibrate the prediction sets"
            if cal is not None else f"; every training reducer calibrates the prediction sets, scored by "
                                    f"{calibration_folds} fold models" if folds is not None
            else f"; no prediction sets ({cal_note})"))

    runs, first = [], None
    for r in range(repeat):
        s = seed + r
        est = new_estimator(seed=s, fs=store.fs)
        if r == 0 and model in CNN_MODELS and meta_cols:
            echo(f"note: each sample is resampled to the {est.shaft} shaft's angle at its {est.speed_column} and "
                 f"fitted to the {model} input of {est.network_input_length(store.length)} angle samples "
                 "(docs/models.md)")
        elif r == 0 and model in CNN_MODELS:
            W = est.network_input_length(store.length)
            starts = covering_starts(store.length, W, est.long_input)
            if W != store.length:
                echo(f"note: samples have {store.length} points and the {model} input is {W}: each sample is cut "
                     f"into {len(starts)} window(s) starting at {starts.tolist()}; training uses every window, "
                     "predictions average them (docs/models.md)")
        fit(est, Xtr, tr.y, f"seed {s}", groups=validation_groups(store, tr), source=tr if stream else None)
        metrics = None
        if te is not None and len(te.y):
            predicted = predict_store(est, te) if stream else est.predict(Xte)
            metrics = classification_metrics(te.y, predicted, labels=[str(c) for c in est.classes_])
            runs.append(metrics)
            echo(f"seed {s}: test {headline(metrics)}, kappa {metrics['kappa']:.4f}")
        if r == 0:
            first = (est, metrics)
    est, metrics = first
    extra: dict = {}
    classes = [str(c) for c in est.classes_]
    if cal is not None:
        from rvdiag.evaluation.evaluate import predict_in_chunks
        from rvdiag.models.conformal import PredictionSets

        P = predict_proba_store(est, cal) if stream else predict_in_chunks(est, Xcal, method="predict_proba")
        sets = PredictionSets.calibrate(P, cal.y, classes, coverage_of(classes), groups=cal.meta["unit"],
                                        source=calibration_source(cal, calibration_fraction, seed), rule=set_rule)
        extra["prediction_sets"] = sets.to_card()
    elif folds is not None:
        from rvdiag.models.conformal import PredictionSets

        P = np.zeros((len(tr.y), len(classes)))
        for k in range(calibration_folds):
            part = folds != k
            fold_est = new_estimator(seed=seed, fs=store.fs)
            fit(fold_est, Xtr[part], np.asarray(tr.y)[part], f"calibration fold {k + 1}/{calibration_folds}",
                groups=validation_groups(store, subset(tr, part)))
            if [str(c) for c in fold_est.classes_] != classes:
                raise StoreError(f"calibration fold {k + 1} lacks a class: use --calibration split")
            P[~part] = fold_est.predict_proba(Xtr[~part])
        sets = PredictionSets.calibrate(
            P, tr.y, classes, coverage_of(classes), groups=tr.meta["unit"],
            source={"method": "cross", "refit": True, "folds": int(calibration_folds), "seed": [int(seed), 5],
                    "what": "every training reducer (metadata column unit), scored by the model fitted on the "
                            "other folds of reducers; the thresholds apply to the model fitted on all",
                    "n_calibration": int(len(tr.y))}, rule=set_rule)
        extra["prediction_sets"] = sets.to_card()
    else:
        extra["prediction_sets"] = None
        extra["prediction_sets_note"] = cal_note
    novelty, op_range = _novelty_and_range(est, store, train_idx, tr, te, Xtr, Xte, meta_cols, seed, stream,
                                           where)
    store_info = training_store_info(store, data, len(tr.y) + (0 if cal is None else len(cal.y)))
    extra.update({} if snr_db is None else {"added_noise": {"snr_db": float(snr_db), "seed": [seed, 0],
                                                            "applies_to": "train and test splits"}})
    extra["operating_range"] = op_range
    if conditions:
        extra["train_where"] = conditions
    if stream:
        extra["streaming"] = {"buffer_samples": int(est.stream_buffer_samples_)}
    scalars = (store.attrs.get("config") or {}).get("scalars") or {}
    if meta_cols:  # where diagnose finds each column in a measured file (the store's --scalar regex)
        extra["metadata_sources"] = {c: scalars[c] for c in meta_cols if c in scalars}
    summary = None
    if repeat > 1 and runs:
        summary = repeat_summary(runs)
        extra["repeat"] = {"seeds": list(range(seed, seed + repeat)), **summary}
    repeat_file = {} if summary is None else {"repeat.json": json.dumps(summary, indent=2).encode()}
    save_model(est, out, model=model, features=(features or "wpd") if model in CLASSICAL_MODELS else None,
               fs=store.fs, training_store=store_info, metrics=metrics or {}, seed=seed, extra=extra,
               novelty=novelty, files=repeat_file)
    return TrainResult(model_dir=str(out), metrics=metrics, repeat=summary, model=model, estimator=est,
                       n_train=int(len(tr.y) + (0 if cal is None else len(cal.y))), streamed=bool(stream))


def calibration_split(tr, fraction: float, seed: int, coverage: dict[str, float]):
    """The training samples held out to calibrate the prediction sets (:func:`rvdiag.models.conformal.split_by_group`:
    whole reducers, the metadata column ``unit``, ``fraction`` of each state's, drawn with ``[seed, 4]``), as a
    boolean mask, and None; or None and the reason there are none (``fraction`` 0, no ``unit`` column, a state
    with too few held-out samples for its stated ``coverage``: then nothing is held out and the fit keeps every
    sample)."""
    from rvdiag.models.conformal import min_calibration_samples, split_by_group

    if fraction <= 0:
        return None, "--calibration-fraction 0"
    units = tr.meta.get("unit")
    if units is None:
        return None, "the store has no reducer column (unit) to hold whole reducers out of the fit"
    held = split_by_group(tr.y, units, fraction, [seed, 4])
    y = np.asarray(tr.y).astype(str)
    for c in np.unique(y):
        n, need = int(np.sum(held & (y == c))), min_calibration_samples(coverage[str(c)])
        if n < need:
            return None, (f"{n} held-out sample(s) of {c}, fewer than the {need} a {100 * coverage[str(c)]:g} % set "
                          "needs: build more reducers (simulations) or raise --calibration-fraction")
    return held, None


def calibration_folds_of(tr, folds: int, seed: int, coverage: dict[str, float]):
    """The fold of each training sample for ``--calibration cross`` (:func:`rvdiag.models.conformal.group_folds`
    over the reducers, metadata column ``unit``, drawn with ``[seed, 5]``), and None; or None and the reason there
    are no sets (no ``unit`` column, a state with fewer reducers than folds or fewer samples than its coverage
    needs)."""
    from rvdiag.models.conformal import group_folds, min_calibration_samples

    units = tr.meta.get("unit")
    if units is None:
        return None, "the store has no reducer column (unit) to fold the reducers"
    y = np.asarray(tr.y).astype(str)
    for c in np.unique(y):
        n, need = int(np.sum(y == c)), min_calibration_samples(coverage[str(c)])
        if n < need:
            return None, f"{n} training sample(s) of {c}, fewer than the {need} a {100 * coverage[str(c)]:g} % set needs"
    try:
        return group_folds(y, units, folds, [seed, 5]), None
    except ParameterError as exc:
        return None, str(exc)


def calibration_source(cal, fraction: float, seed: int) -> dict:
    """Where the held-out calibration samples came from, for the card."""
    held = {str(c): sorted({str(u) for u in np.asarray(cal.meta["unit"])[np.asarray(cal.y) == c]})
            for c in np.unique(np.asarray(cal.y))}
    return {"method": "split", "refit": False, "fraction": float(fraction), "seed": [int(seed), 4],
            "n_calibration": int(len(cal.y)),
            "what": "whole training reducers (metadata column unit) held out of the fit, per state",
            "held_out_reducers": held}


def subset(samples, mask):
    """The loaded samples (:class:`rvdiag.datasets.store.Samples`) where ``mask`` holds."""
    import dataclasses

    return dataclasses.replace(samples, X=samples.X[mask], y=np.asarray(samples.y)[mask],
                               meta={k: np.asarray(v)[mask] for k, v in samples.meta.items()},
                               index=np.asarray(samples.index)[mask])


def _n_groups(cal) -> int:
    return int(len({(str(c), str(u)) for c, u in zip(cal.y, cal.meta["unit"])}))


def _with_noise(samples, snr_db: float, seed: list[int]):
    """``samples`` with white Gaussian noise at ``snr_db`` below each sample's power (seeded)."""
    import dataclasses

    from rvdiag.dynamics.noise import add_awgn

    noisy = add_awgn(samples.X, float(snr_db), np.random.default_rng(seed)).astype(np.float32)
    return dataclasses.replace(samples, X=noisy)


def validation_groups(store, samples):
    """Groups for the early-stopping validation split: the simulation (``unit``) of each sample when a state has
    several simulations (each is a reducer of its own: the validation set then holds reducers the network did not
    train on, as the test split does; split by segment, it would hold windows of the training reducers and stop on
    their fingerprints), or when the store's segments overlap (a split by segment would then leak: neighbours share
    points); else None (split by segment).  A paper-mode library (one simulation per state, ``hop =
    segment_length``) so gets a real validation set instead of none at all."""
    units = samples.meta.get("unit")
    if units is None:
        return None
    y = getattr(samples, "y", None)
    if y is not None and len(y) == len(units):
        units_arr, y_arr = np.asarray(units), np.asarray(y)
        if any(np.unique(units_arr[y_arr == c]).size > 1 for c in np.unique(y_arr)):
            return units
    signal = (store.attrs.get("config") or {}).get("signal") or {}
    hop, seg = signal.get("hop"), signal.get("segment_length")
    if hop is not None and seg is not None and int(hop) >= int(seg):
        return None
    return units


def features_kw(features: str, *, epochs: int, device: str, seed: int, lr: float, batch_size: int,
                bearing_geometry: str | None, rpm_column: str, fs: float | None,
                speed_column: str = "output_speed_deg_s", signal: str = "vibration") -> dict:
    """Arguments of each part of a ``--features`` value (a dict per part name for names joined by '+');
    ``signal`` (the store's: vibration or current) picks the CNN features' input representation."""
    from rvdiag.features.bearing import geometry_from_mm
    from rvdiag.models.pipelines import feature_names

    parts = features.split("+")
    for name in parts:
        if name not in feature_names():
            raise ParameterError(f"unknown feature set {name!r}; use one of {'|'.join(feature_names())} "
                                 "(or several joined by '+')")
    if bearing_geometry is not None and "bearing-envelope" not in parts:
        raise ParameterError("--bearing-geometry applies to --features bearing-envelope only")
    kw: dict[str, dict] = {}
    for name in parts:
        if name == "cnn":
            from rvdiag.models.cnn_features import default_representation

            kw[name] = {"max_epochs": epochs, "device": device, "random_state": seed, "learning_rate": lr,
                        "batch_size": batch_size, "representation": default_representation(signal)}
        elif name == "bearing-envelope":
            if bearing_geometry is None:
                raise ParameterError("--features bearing-envelope needs --bearing-geometry "
                                     "N_BALLS,D_BALL_MM,D_PITCH_MM,CONTACT_DEG (e.g. 9,7.94,39.04,0 for a 6205)")
            kw[name] = {**geometry_from_mm(bearing_geometry), "fs": fs, "speed_column": rpm_column}
        elif name in ("tsa-ci", "tsa-mod", "tsa-ci-z", "tsa-mod-z", "orders"):  # angle-domain features: the store's rate and each window's speed
            kw[name] = {"fs": fs, "speed_column": speed_column}
    return kw if len(parts) > 1 else kw.get(features, {})


def build_estimator(model: str, features: str | None, *, epochs: int, device: str, seed: int,
                    batch_size: int, lr: float, input_length: int | None, patience: int,
                    validation_fraction: float, normalize: str = "window", representation: str = "waveform",
                    bearing_geometry: str | None = None, rpm_column: str = "rpm", fs: float | None = None,
                    speed_column: str = "output_speed_deg_s", multilabel: bool = False, signal: str = "vibration"):
    """A fresh, unfitted estimator for a ``--model`` name (``fs``: the store's, for bearing-envelope;
    ``signal``: the store's, vibration or current, for the cnn features' representation)."""
    if multilabel and model not in CLASSICAL_MODELS:
        raise ParameterError(f"--multilabel applies to the classical models ({'|'.join(CLASSICAL_MODELS)}), "
                             f"not {model!r}")
    if model in CNN_MODELS:
        if features is not None:
            raise ParameterError(f"--features does not apply to the CNN model {model!r} (it learns its features); "
                                 "for CNN features + SVM use --model svm --features cnn")
        from rvdiag.models.torch_estimator import CNNClassifier

        return CNNClassifier(architecture=model, input_length=input_length, max_epochs=epochs, device=device,
                             random_state=seed, batch_size=batch_size, learning_rate=lr,
                             n_iter_no_change=patience, validation_fraction=validation_fraction,
                             normalize=normalize, representation=representation, fs=fs,
                             speed_column=speed_column)
    if model in CLASSICAL_MODELS:
        from rvdiag.models.pipelines import make_classical_model

        feats = features or "wpd"
        kw = features_kw(feats, epochs=epochs, device=device, seed=seed, lr=lr, batch_size=batch_size,
                         bearing_geometry=bearing_geometry, rpm_column=rpm_column, fs=fs,
                         speed_column=speed_column, signal=signal)
        return make_classical_model(model, feats, seed=seed, features_kw=kw, multilabel=multilabel)
    raise ParameterError(f"unknown model {model!r}; use one of {'|'.join(CNN_MODELS + CLASSICAL_MODELS)}")


def check_class_counts(est, y) -> None:
    """Refuse, in one line, a training split too small for the classifier's internal cross-validation (the
    SVM's probability calibration splits each class 3 ways: ``CalibratedClassifierCV(cv=3)``)."""
    cv = getattr(est[-1] if hasattr(est, "steps") else est, "cv", None)
    if not isinstance(cv, int):
        return
    classes, counts = np.unique(np.asarray(y), return_counts=True)
    if counts.min() < cv:
        c = classes[int(np.argmin(counts))]
        raise ParameterError(f"class {c!r} has {int(counts.min())} training sample(s); the classifier's "
                             f"{cv}-fold probability calibration needs at least {cv} per class: build more "
                             "simulations or shorter samples")


#: at most this many training (and test) samples fit and calibrate the out-of-distribution check
MAX_NOVELTY_SAMPLES = 2000


def _novelty_and_range(est, store, train_idx, tr, te, Xtr, Xte, meta_cols, seed: int, stream: bool, where: str):
    """The out-of-distribution check of the model (:func:`rvdiag.models.novelty.fit_novelty`: fitted on at most
    :data:`MAX_NOVELTY_SAMPLES` training samples drawn with ``[seed, 2]``, its threshold from as many test samples)
    and the card's ``operating_range`` (:func:`rvdiag.models.conditions.operating_range`) of the training
    samples (of those drawn, when the samples are streamed)."""
    from rvdiag.features.combine import with_metadata
    from rvdiag.models.conditions import operating_range
    from rvdiag.models.novelty import fit_novelty

    rng = np.random.default_rng([seed, 2])

    def draw(n: int) -> np.ndarray:
        return np.sort(rng.choice(n, size=min(n, MAX_NOVELTY_SAMPLES), replace=False))

    if stream:
        rows = np.asarray(train_idx)[draw(len(train_idx))]
        sub = store.load(index=rows)
        X_fit, raw, meta = with_metadata(sub.X, sub.meta, meta_cols, where=where), sub.X, sub.meta
        test_idx = store.indices("test") if te is not None else np.zeros(0, np.int64)
        X_cal = None
        if len(test_idx):
            t = store.load(index=np.asarray(test_idx)[draw(len(test_idx))])
            X_cal = with_metadata(t.X, t.meta, meta_cols, where=where)
    else:
        pick = draw(len(Xtr))
        X_fit, raw, meta = Xtr[pick], tr.X, tr.meta
        X_cal = None if Xte is None or not len(Xte) else Xte[draw(len(Xte))]
    signal = signal_info(store)["signal"]
    unit = ("A" if signal == "current" else "m/s^2") if store.attrs.get("kind") == "simulated" else None
    op = operating_range(meta, raw, store.fs, unit=unit, normalize=getattr(est, "normalize", None))
    return fit_novelty(est, X_fit, X_cal), op


def _streaming_choice(streaming: bool | None, model: str, snr_db: float | None, store) -> bool:
    """Whether to stream the training samples (``--streaming/--no-streaming``; by default a CNN streams when its
    training split's float32 signals exceed :data:`rvdiag.models.streaming.STREAMING_THRESHOLD_BYTES`)."""
    from rvdiag.models.streaming import STREAMING_THRESHOLD_BYTES

    if streaming is None:
        big = len(store.indices("train")) * store.length * 4 > STREAMING_THRESHOLD_BYTES
        return bool(big and model in CNN_MODELS and snr_db is None)
    if streaming and model not in CNN_MODELS:
        raise ParameterError(f"--streaming applies to the CNN models ({'|'.join(CNN_MODELS)}); {model!r} has no "
                             "partial_fit and trains in memory (use --no-streaming or leave it out)")
    if streaming and snr_db is not None:
        raise ParameterError("--snr-db adds noise to the samples in memory and does not combine with --streaming; "
                             "build the library with [operation] noise_snr_db instead")
    return bool(streaming)


__all__ = ["TrainResult", "build_estimator", "check_class_counts", "check_counts", "features_kw", "fit_plain", "train",
           "validation_groups"]
