"""The study's fits and scores: features per set, ``StandardScaler -> SVC`` per split, the metrics, and
:func:`run_mcsa`, which runs the protocol on a store and returns the report of ``mcsa.json``
(:class:`McsaResult`)."""

from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass, field
from typing import Any, Sequence

import numpy as np

from rvdiag import __version__
from rvdiag.errors import ParameterError, SplitLeakWarning, StoreError
from rvdiag.evaluation.metrics import classification_metrics
from rvdiag.evaluation.motor_current_study.data import (check_splittable, load_groups, pick_channel, sample_channels,
                                                       speed_unit)
from rvdiag.evaluation.motor_current_study.protocol import check_protocol, protocol_splits, protocols_run
from rvdiag.evaluation.motor_current_study.settings import (FEATURE_SETS, FORMAT, METRICS, PROTOCOL_KEYS,
                                                           PROTOCOL_SPLITS, PROTOCOLS, STUDY_FIGURES, McsaSettings,
                                                           split_seeds)
from rvdiag.features.timedomain import TIME_FEATURE_NAMES
from rvdiag.progress import report


def recall_and_false_alarms(confusion: Sequence[Sequence[int]], labels: Sequence[str]) -> dict:
    """Per-class recall (:func:`class_recalls`) and the false-alarm rate (healthy windows called faulty, the
    healthy class of :func:`rvdiag.evaluation.metrics.healthy_class`) of a confusion matrix (rows true).

    >>> recall_and_false_alarms([[3, 1], [0, 4]], ["T1", "T2"])
    {'recall_per_class': {'T1': 0.75, 'T2': 1.0}, 'false_alarm_rate': 0.25}
    """
    from rvdiag.evaluation.metrics import healthy_class

    recall = class_recalls(confusion, labels)
    healthy = healthy_class(labels)
    fa = None if healthy is None or recall[healthy] is None else 1.0 - recall[healthy]
    return {"recall_per_class": recall, "false_alarm_rate": fa}



def _svm(settings: McsaSettings, seed: int):
    from sklearn.pipeline import Pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVC

    return Pipeline([("scale", StandardScaler()),
                     ("svm", SVC(kernel="rbf", C=float(settings.svm_c), gamma=settings.svm_gamma,
                                 random_state=int(seed)))])


def _fixed_features(name: str, settings: McsaSettings, X: np.ndarray) -> np.ndarray:
    """Features of a set that learns nothing (``time``, ``wpt``)."""
    if name == "time":
        from rvdiag.features.timedomain import time_features

        return time_features(X)
    from rvdiag.features.wavelet import WaveletPacketEnergy

    return WaveletPacketEnergy(wavelet=settings.wavelet, level=int(settings.wpt_level)).fit_transform(X)


def _cnn(settings: McsaSettings, seed: int):
    from rvdiag.models.cnn_features import CNNFeatures

    return CNNFeatures(architecture="spectrum-cnn", input_length=settings.cnn_input_length,
                       max_epochs=int(settings.cnn_epochs), batch_size=int(settings.cnn_batch_size),
                       learning_rate=float(settings.cnn_lr), n_iter_no_change=int(settings.cnn_patience),
                       validation_fraction=float(settings.cnn_validation_fraction), device=settings.device,
                       random_state=int(seed), representation=settings.cnn_representation)


def _fit_score(name: str, settings: McsaSettings, seed: int, Xtr, ytr, Xte, yte, Ftr=None, Fte=None):
    """Fit features (cnn) and the SVM on the training side; (metrics, standardised test features)."""
    if name == "cnn":
        cnn = _cnn(settings, seed).fit(Xtr, ytr)
        Ftr, Fte = cnn.transform(Xtr), cnn.transform(Xte)
    svm = _svm(settings, seed).fit(Ftr, ytr)
    pred = svm.predict(Fte)
    labels = sorted(set(ytr.tolist()) | set(yte.tolist()))
    m = classification_metrics(yte, pred, labels=labels)
    keep = {k: m[k] for k in METRICS}
    keep.update(confusion=m["confusion"], labels=m["labels"], n_train=int(len(ytr)), n_test=int(len(yte)),
                recall_per_class=class_recalls(m["confusion"], m["labels"]))
    return keep, svm.named_steps["scale"].transform(Fte)


def class_recalls(confusion, labels) -> dict[str, float | None]:
    """Recall of each class (its diagonal over its row of the confusion matrix; None for a class without
    test samples)."""
    C = np.asarray(confusion, dtype=np.float64)
    rows = C.sum(axis=1)
    return {str(c): (float(C[i, i] / rows[i]) if rows[i] > 0 else None) for i, c in enumerate(labels)}


def _summary(runs: list[dict]) -> dict:
    return {k: {"mean": float(np.mean([r[k] for r in runs])), "std": float(np.std([r[k] for r in runs]))}
            for k in METRICS}



@dataclass
class McsaResult:
    """What :func:`run_mcsa` found: ``report`` (the JSON of ``mcsa.json``) and the t-SNE inputs.

    ``tsne[set][speed]`` = (standardised test features of the first repeat, their classes).
    """

    report: dict
    tsne: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = field(default_factory=dict)


def _store_info(store, channel: str, n_used: int) -> dict:
    return {"path": str(store.path), "config_hash": store.attrs.get("config_hash"), "kind": store.attrs.get("kind"),
            "n_samples": int(store.n_samples), "n_used": int(n_used), "length": int(store.length), "fs": store.fs,
            "classes": list(store.classes), "channel": channel}


def prepare(store, settings: McsaSettings, test_store=None):
    """Check the settings and the stores before any work: (channel, groups, (other channel, other groups) or
    None, notes, leaks), ``leaks`` the notes that say a score is optimistic (also in ``notes``).

    Raises :class:`ParameterError` / :class:`StoreError` (one line each) for a bad setting, a missing channel or
    speed column, a speed with too few samples for the split, or a second store that does not fit the first.
    """
    settings.check()
    unit = speed_unit(settings.speed_column)
    channel = pick_channel(sample_channels(store).tolist(), settings.channel, store.path)
    if "cnn" in settings.feature_sets and settings.cnn_input_length and settings.cnn_input_length > store.length:
        raise ParameterError(f"cnn_input_length {settings.cnn_input_length} is longer than the samples of "
                             f"{store.path} ({store.length} points)")
    groups = load_groups(store, channel, settings.speed_column)
    check_splittable(groups, float(settings.test_size), store.path, unit)
    check_protocol(groups, settings, store.path, unit)
    notes: list[str] = []
    leaks: list[str] = []
    other = None
    if test_store is not None:
        if test_store.length != store.length:
            raise StoreError(f"{test_store.path} has {test_store.length}-point samples, {store.path} "
                             f"{store.length}-point ones: the features need samples of one length")
        if store.fs and test_store.fs and abs(store.fs - test_store.fs) > 1e-6 * store.fs:
            raise StoreError(f"{test_store.path} is sampled at {test_store.fs:g} Hz, {store.path} at {store.fs:g} Hz")
        other_channel = pick_channel(sample_channels(test_store).tolist(), settings.channel, test_store.path)
        other_groups = load_groups(test_store, other_channel, settings.speed_column)
        common = [s for s in groups if s in other_groups]
        if not common:
            raise StoreError(f"{test_store.path} has no sample at the speeds of {store.path} "
                             f"({', '.join(groups)} {unit}; it has {', '.join(other_groups) or 'none'})".rstrip())
        for s in common:
            unseen = sorted(set(other_groups[s].y.tolist()) - set(groups[s].y.tolist()))
            if unseen:
                raise StoreError(f"{test_store.path} has class(es) {', '.join(unseen)} at {s} {unit}, which "
                                 f"{store.path} lacks there: nothing could learn them")
        missing = [s for s in groups if s not in other_groups]
        if missing:
            notes.append(f"{test_store.path} has no sample at {', '.join(missing)} {unit}: no held-out figure there")
        shared = 0
        for s in common:
            a, b = groups[s].sims, other_groups[s].sims
            if a is not None and b is not None:
                shared += len(set(a.tolist()) & set(b.tolist()))
        same_hash = store.attrs.get("config_hash")
        if same_hash and test_store.attrs.get("config_hash") == same_hash:
            leaks.append(f"{test_store.path} was built from the same config as {store.path} (hash {same_hash}): the "
                         "same simulations, so the held-out figures are optimistic")
        elif shared:
            leaks.append(f"{shared} simulation(s) (class and seed) of {test_store.path} are also in {store.path}: "
                         "the held-out figure is optimistic")
        other = (other_channel, other_groups)
    if settings.protocol != "held-out" and any(g.units is not None and len(np.unique(g.units)) < len(g.units)
                                                for g in groups.values()):
        honest = ("the held-out protocol's figures are not" if settings.protocol == "both" else
                  "the held-out figures are not" if other is not None else
                  "--protocol held-out (unseen reducers) or a held-out store (--test) gives the honest figure")
        leaks.append("random window splits put windows of one simulation on both sides (the study's protocol): "
                     f"the split scores are optimistic; {honest}")
    return channel, groups, other, notes + leaks, leaks


def run_mcsa(store, settings: McsaSettings, test_store=None) -> McsaResult:
    """Run the study's protocol on ``store`` (a :class:`rvdiag.datasets.SampleStore`); see the module docstring.

    Progress goes to :mod:`rvdiag.progress`, one stage per feature set (``<set>: fits``).  Notes about the
    protocol (shared simulations) are also raised as :class:`SplitLeakWarning`.
    """
    channel, groups, other, notes, leaks = prepare(store, settings, test_store)
    for note in leaks:
        warnings.warn(note, SplitLeakWarning, stacklevel=2)
    seeds = split_seeds(settings.seed, settings.repeats)
    unit = speed_unit(settings.speed_column)
    results: dict[str, dict[str, Any]] = {}
    tsne: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = {name: {} for name in settings.feature_sets}
    n_held = 0 if other is None else sum(1 for s in groups if s in other[1])
    runs_of = protocols_run(settings.protocol)
    for name in settings.feature_sets:
        stage = f"{name}: fits"
        total = len(groups) * settings.repeats * len(runs_of) + n_held
        done = 0
        report(stage, done, total)
        for speed, g in groups.items():
            F = None if name == "cnn" else _fixed_features(name, settings, g.X)
            entry: dict[str, Any] = {
                "n_samples": int(len(g.y)),
                "counts": {c: int(k) for c, k in zip(*np.unique(g.y, return_counts=True))},
            }
            for proto in runs_of:
                runs = []
                for r, (s, (tr, te, used)) in enumerate(zip(seeds, protocol_splits(
                        proto, g.y, g.units, float(settings.test_size), seeds))):
                    kw = {} if F is None else {"Ftr": F[tr], "Fte": F[te]}
                    m, Fz = _fit_score(name, settings, s, g.X[tr], g.y[tr], g.X[te], g.y[te], **kw)
                    m["seed"] = int(s)
                    m.update(used)
                    runs.append(m)
                    if r == 0 and proto == runs_of[0]:
                        tsne[name][speed] = (Fz, g.y[te])
                    done += 1
                    report(stage, done, total)
                confusion = np.sum([r["confusion"] for r in runs], axis=0).astype(int).tolist()
                entry[PROTOCOL_KEYS[proto]] = {"repeats": runs, **_summary(runs), "confusion_sum": confusion,
                                               "labels": runs[0]["labels"],
                                               **recall_and_false_alarms(confusion, runs[0]["labels"])}
            entry["held_out"] = None
            if other is not None and speed in other[1]:
                h = other[1][speed]
                kw = {} if F is None else {"Ftr": F, "Fte": _fixed_features(name, settings, h.X)}
                m, _ = _fit_score(name, settings, seeds[0], g.X, g.y, h.X, h.y, **kw)
                m["seed"] = int(seeds[0])
                entry["held_out"] = m
                done += 1
                report(stage, done, total)
            results.setdefault(speed, {})[name] = entry
    out = {
        "format": FORMAT,
        "rvdiag_version": __version__,
        "protocol": (f"{settings.protocol}: {PROTOCOLS[settings.protocol]}; at each speed and for each feature "
                     "set: repeated splits (test_size of each class to the test side; " +
                     "; ".join(f"{PROTOCOL_KEYS[p]}: {PROTOCOL_SPLITS[p]}" for p in runs_of) +
                     "), StandardScaler + RBF SVC fitted on the training side; metrics on the test "
                     "side, mean and population std over the repeats" +
                     ("; held_out: fit on every sample of the store at that speed, score the test store's samples "
                      "at that speed" if other is not None else "")),
        "store": _store_info(store, channel, sum(len(g.y) for g in groups.values())),
        "test_store": None if other is None else _store_info(test_store, other[0],
                                                             sum(len(g.y) for g in other[1].values())),
        "speed_column": settings.speed_column,
        "speed_unit": unit,
        "speeds": list(groups),
        "feature_sets": {name: FEATURE_SETS[name] for name in settings.feature_sets},
        "time_features": list(TIME_FEATURE_NAMES),
        "settings": asdict(settings) | {"feature_sets": list(settings.feature_sets)},
        "svm": {"kernel": "rbf", "C": float(settings.svm_c), "gamma": settings.svm_gamma,
                "scaler": "StandardScaler (fitted on the training side)"},
        "split_seeds": seeds,
        "results": results,
        "study": {name: STUDY_FIGURES[name] for name in settings.feature_sets},
        "notes": notes,
    }
    return McsaResult(report=out, tsne=tsne)
