"""Evaluate a saved model on a sample store, and build its HTML report."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rvdiag.errors import ModelFileError
from rvdiag.evaluation.metrics import classification_metrics
from rvdiag.models.novelty import learned_features
from rvdiag.models.conditions import fs_ratio
from rvdiag.progress import report


@dataclass
class Evaluation:
    """Result of :func:`evaluate_on_store`.

    Attributes
    ----------
    metrics : dict (:func:`classification_metrics`)
    y_true, y_pred : ndarray of str
    X : ndarray, the evaluated samples
    meta : dict of metadata columns of the evaluated samples
    warnings : list of str (fs mismatch...)
    sets, sets_note : the prediction sets' metrics, or why there are none (:func:`set_metrics_of` fills them)
    proba : ndarray (n, k) or None, the class probabilities (kept for a model with a prediction-set calibration)
    """

    metrics: dict
    y_true: np.ndarray
    y_pred: np.ndarray
    X: np.ndarray
    meta: dict
    split: str
    warnings: list[str] = field(default_factory=list)
    sets: dict | None = None
    sets_note: str | None = None
    proba: np.ndarray | None = None


def check_store_matches(card: dict, store) -> list[str]:
    """Refuse a store the model cannot score (sample length, unknown classes); return warnings (fs)."""
    if store.length != card["input_length"]:
        raise ModelFileError(
            f"the model takes samples of {card['input_length']} points, the store {store.path} has "
            f"{store.length}-point samples (use 'rvdiag diagnose' to window long signals)")
    unknown = sorted(set(store.classes) - set(map(str, card["classes"])))
    present = set(np.asarray(store.label_names).astype(str).tolist())
    unknown = [c for c in unknown if c in present]
    if unknown:
        raise ModelFileError(
            f"the store {store.path} has classes {unknown} the model was not trained on "
            f"(model classes: {', '.join(map(str, card['classes']))})")
    warnings = []
    if card.get("fs") and store.fs and fs_ratio(store.fs, card["fs"]) is not None:
        warnings.append(f"warning: the store's fs {store.fs:g} Hz differs from the training fs {card['fs']:g} Hz")
    return warnings


def predict_in_chunks(estimator, X: np.ndarray, chunk: int = 512, method: str = "predict") -> np.ndarray:
    """``estimator.predict(X)`` (or another ``method``, e.g. ``"predict_proba"``), ``chunk`` samples at a time, each
    chunk reported to :mod:`rvdiag.progress` (stage ``scoring``).  The same result: every model here predicts each
    sample on its own."""
    predict = getattr(estimator, method)
    n = len(X)
    parts = []
    for i in range(0, n, chunk):
        parts.append(np.asarray(predict(X[i:i + chunk])))
        report("scoring", min(i + chunk, n), n)
    return np.concatenate(parts) if parts else np.asarray(predict(X))


def evaluate_on_store(loaded, store, split: str = "test", where=()) -> Evaluation:
    """Predict every sample of ``split`` and score it.

    Parameters
    ----------
    loaded : :class:`rvdiag.models.persistence.LoadedModel`
    store : :class:`rvdiag.datasets.SampleStore`
    split : "test" | "train" | "all" | any split of the store
    where : conditions on the metadata (``"noise_snr_db>=20"``; :meth:`rvdiag.datasets.SampleStore.indices`):
        only the samples of ``split`` that satisfy all of them are scored
    """
    warnings = check_store_matches(loaded.card, store)
    where = list(where or ())
    s = store.load(index=store.indices(split, where)) if where else store.load(split)
    if len(s.y) == 0:
        raise ModelFileError(f"the split {split!r} of {store.path} is empty"
                             + (f" where {' and '.join(where)}" if where else ""))
    X = loaded.inputs(s.X, s.meta, where=f"the store {store.path}")
    proba = None
    if loaded.card.get("prediction_sets") and hasattr(loaded.estimator, "predict_proba"):
        # one pass gives the prediction sets too: every rvdiag classifier predicts the argmax of predict_proba
        proba = predict_in_chunks(loaded.estimator, X, method="predict_proba").astype(float)
        y_pred = np.asarray(loaded.estimator.classes_)[proba.argmax(axis=1)].astype(str)
    else:
        y_pred = predict_in_chunks(loaded.estimator, X).astype(str)
    y_true = np.asarray(s.y).astype(str)
    m = classification_metrics(y_true, y_pred, labels=[str(c) for c in loaded.card["classes"]])
    return Evaluation(m, y_true, y_pred, s.X, s.meta, split, warnings, proba=proba)


def _level_key(level: float) -> int:
    """A non-negative integer that names an SNR level exactly (the bits of the float64), for seeding its noise."""
    return int(np.float64(level).view(np.uint64))


def accuracy_against_snr(loaded, ev: Evaluation, snr_db: list[float], seed: int = 0) -> list[dict]:
    """Score the evaluated samples again with white Gaussian noise added at each SNR in ``snr_db``.

    The noise of a level comes from ``numpy.random.default_rng([seed, key])``, ``key`` the bits of the level as a
    float64 (:func:`_level_key`), so one level gets the same noise whatever other levels are asked for with it;
    it is scaled per sample to that level below that sample's mean power (:func:`rvdiag.dynamics.noise.add_awgn`).  Added to a
    sample that already holds noise at SNR ``s0``, the result has an SNR of
    ``-10 log10(10^(-s/10) + 10^(-s0/10) (1 + 10^(-s/10)))`` against the clean signal, within 0.05 dB of
    ``s`` for ``s <= 20`` dB and ``s0 >= 40`` dB; the store's own SNR column, when present, is reported as
    ``store_snr_db`` so the reader can check.  Every level scores the same samples, so the curve is
    one of noise alone (each level done is reported to :mod:`rvdiag.progress`): unlike ``--by noise_snr_db`` on a library whose simulations each drew an SNR, the
    states do not mix differently from one level to the next.

    Returns one dict per level: ``snr_db, accuracy, f1_macro, kappa, n, healthy_recall, false_alarm_rate,
    per_class_recall`` (:func:`rvdiag.evaluation.metrics.classification_metrics`).
    """
    from rvdiag.dynamics.noise import add_awgn

    labels = [str(c) for c in loaded.card["classes"]]
    out = []
    for i, level in enumerate(snr_db):
        rng = np.random.default_rng([int(seed), _level_key(level)])
        noisy = add_awgn(ev.X, float(level), rng).astype(np.float32)
        pred = predict_in_chunks(loaded.estimator, loaded.inputs(noisy, ev.meta)).astype(str)
        m = classification_metrics(ev.y_true, pred, labels=labels)
        out.append({"snr_db": float(level), "accuracy": m["accuracy"], "f1_macro": m["f1_macro"],
                    "kappa": m["kappa"], "n": int(len(pred)), "healthy_recall": m["healthy_recall"],
                    "false_alarm_rate": m["false_alarm_rate"], "per_class_recall":
                    {c: v["recall"] for c, v in m["per_class"].items()}})
        report("SNR levels", i + 1, len(snr_db))
    store_snr = ev.meta.get("noise_snr_db")
    if store_snr is not None and len(out):
        vals = np.asarray(store_snr, dtype=float)
        out[0]["store_snr_db"] = {"min": float(np.nanmin(vals)), "max": float(np.nanmax(vals))}
    return out


#: Speed columns the report's indicator section reads, in order of preference.
SPEED_COLUMNS = ("output_speed_deg_s", "input_speed_rpm")


def indicators_by_class(ev: Evaluation, fs: float | None, max_per_class: int = 50, seed: int = 0,
                        notes: list[str] | None = None) -> dict | None:
    """The gear condition indicators (sun shaft, :class:`rvdiag.features.tsa.TSAIndicatorFeatures`, linear) of
    at most ``max_per_class`` samples of each class of the evaluation (drawn with ``seed``), summarised per
    class by their quartiles.

    Returns ``{"speed_column", "names", "per_class": {class: {"n", "q25", "median", "q75"}}}`` (each quartile
    a dict name -> value), or None when the store gives no sampling rate or no speed column, or when the
    samples hold less than one revolution (the reason appended to ``notes``)."""
    from rvdiag.errors import RvdiagError
    from rvdiag.features.combine import with_metadata
    from rvdiag.features.tsa import TSAIndicatorFeatures

    notes = [] if notes is None else notes
    column = next((c for c in SPEED_COLUMNS if c in ev.meta), None)
    if not fs or column is None:
        notes.append("gear condition indicators not shown: the store gives no "
                     + ("sampling rate" if not fs else f"speed column ({' or '.join(SPEED_COLUMNS)})"))
        return None
    rng = np.random.default_rng(seed)
    tf = TSAIndicatorFeatures(fs=float(fs), speed_column=column, log=False)
    names = tf._feature_names()
    per_class = {}
    try:
        for c in np.unique(ev.y_true):
            rows = np.flatnonzero(ev.y_true == c)
            if rows.size > max_per_class:
                rows = np.sort(rng.choice(rows, max_per_class, replace=False))
            X = with_metadata(ev.X[rows], {column: np.asarray(ev.meta[column])[rows]}, [column])
            F = tf.fit_transform(X)
            q = np.percentile(F, [25, 50, 75], axis=0)
            per_class[str(c)] = {"n": int(rows.size), **{k: dict(zip(names, map(float, v)))
                                                         for k, v in zip(("q25", "median", "q75"), q)}}
    except RvdiagError as exc:
        notes.append(f"gear condition indicators not shown: {exc}")
        return None
    return {"speed_column": column, "names": names, "per_class": per_class}


def report_html(loaded, store, ev: Evaluation, max_tsne: int = 600, seed: int = 0) -> str:
    """The HTML report of an evaluation (see :mod:`rvdiag.evaluation.report`)."""
    from rvdiag.evaluation.plots import tsne_embedding
    from rvdiag.evaluation.report import characteristic_frequencies_for, render_report, store_reducer_params

    rng = np.random.default_rng(seed)
    n = len(ev.y_true)
    pick = np.sort(rng.choice(n, size=min(n, max_tsne), replace=False))
    emb = None
    if len(pick) >= 5:
        X = loaded.inputs(ev.X[pick], {k: np.asarray(v)[pick] for k, v in ev.meta.items()})
        emb = tsne_embedding(learned_features(loaded.estimator, X), random_state=seed)
    examples = {}
    first_idx = []
    for c in loaded.card["classes"]:
        hits = np.flatnonzero(ev.y_true == str(c))
        if hits.size:
            examples[str(c)] = ev.X[hits[0]]
            first_idx.append(hits[0])
    params, notes = store_reducer_params(store.attrs)
    freqs = characteristic_frequencies_for(store.attrs, ev.meta, np.array(first_idx, dtype=int), params=params,
                                           notes=notes)
    store_info = {
        "path": str(Path(store.path)), "split": ev.split, "kind": store.attrs.get("kind"),
        "config": store.attrs.get("config"), "config_hash": store.attrs.get("config_hash"),
    }
    title = f"rvdiag evaluation: {loaded.card.get('model')} on {Path(store.path).name} ({ev.split})"
    sets, sets_note = set_metrics_of(loaded, ev)
    return render_report(title=title, metrics=ev.metrics, card=loaded.card, store_info=store_info,
                         examples=examples, fs=store.fs, frequencies=freqs, embedding=emb,
                         embedding_labels=ev.y_true[pick], notes=notes,
                         indicators=indicators_by_class(ev, store.fs, seed=seed, notes=notes),
                         sets=sets, sets_note=sets_note)


def set_metrics_of(loaded, ev: Evaluation) -> tuple[dict | None, str | None]:
    """The prediction sets' coverage and size on the evaluated samples (``rvdiag evaluate --json`` key ``sets``:
    :func:`rvdiag.models.conformal.set_metrics` with ``calibration``, where the model's calibration came from), and
    None; or None and why there are none (a model trained before rvdiag stored a calibration, or trained with
    ``--calibration-fraction 0``).  Computed once per evaluation and kept on it."""
    from rvdiag.models import conformal

    if ev.sets is not None or ev.sets_note is not None:
        return ev.sets, ev.sets_note
    ps = conformal.from_card(loaded.card)
    if ps is None:
        ev.sets_note = (f"no prediction sets: {loaded.card['prediction_sets_note']}"
                        if loaded.card.get("prediction_sets_note") else conformal.NOT_CALIBRATED)
        return None, ev.sets_note
    P = ev.proba
    if P is None:
        X = loaded.inputs(ev.X, ev.meta, where="the evaluated samples")
        P = predict_in_chunks(loaded.estimator, X, method="predict_proba").astype(float)
    ev.sets = {**conformal.set_metrics(ps.contains(P), ev.y_true, ps.classes, ps.coverage),
               "calibration": {"n_calibration": ps.n_calibration, "n_reducers": ps.n_groups,
                               "method": ps.source.get("method"), "refit": ps.source.get("refit")}}
    return ev.sets, None


def merged_metrics(ev: Evaluation, merge: dict[str, str], labels) -> dict:
    """The metrics of ``ev`` with classes merged, true and predicted alike (``{"T4": "T1", "T6": "T5"}``: the
    crack-free decision, a crack counted as its state without the crack)."""
    from rvdiag.evaluation.metrics import merged_classification_metrics

    return merged_classification_metrics(ev.y_true, ev.y_pred, merge, labels)


def record_metrics(loaded, ev: Evaluation, column: str = "unit", merge: dict[str, str] | None = None) -> dict:
    """The metrics of whole records: the windows of each record (one value of the metadata ``column``: a
    simulation of a library, a file of ``rvdiag dataset from-files``) decided together by their mean class
    probability, as ``rvdiag diagnose`` decides a file (a model without ``predict_proba``: the majority of its
    windows' predictions).  A record's true class is that of its windows (a record whose windows disagree is an
    error).  Returns the metrics of :func:`rvdiag.evaluation.metrics.classification_metrics` plus ``column``,
    ``n_records``, ``windows_per_record`` (min, max) and ``decision``; with ``merge``, also ``merged``
    (:func:`merged_metrics` of the records' decisions)."""
    from rvdiag.errors import StoreError
    from rvdiag.evaluation.metrics import classification_metrics, merged_classification_metrics

    if column not in ev.meta:
        raise StoreError(f"no metadata column {column!r} to group windows into records "
                         f"(columns: {', '.join(sorted(ev.meta))})")
    labels = [str(c) for c in loaded.card["classes"]]
    records = np.asarray(ev.meta[column])
    keys, inverse = np.unique(records, return_inverse=True)
    estimator = loaded.estimator
    if hasattr(estimator, "predict_proba"):
        X = loaded.inputs(ev.X, ev.meta, where="the evaluated samples")
        P = predict_in_chunks(estimator, X, method="predict_proba").astype(float)
        classes = [str(c) for c in estimator.classes_]
        sums = np.zeros((keys.size, len(classes)))
        np.add.at(sums, inverse, P)
        decided = np.asarray(classes)[sums.argmax(axis=1)]
        decision = "mean probability"
    else:
        decided = np.asarray([max(labels, key=list(ev.y_pred[inverse == k]).count) for k in range(keys.size)])
        decision = "majority of the windows"
    truth = []
    for k in range(keys.size):
        states = np.unique(ev.y_true[inverse == k])
        if states.size != 1:
            raise StoreError(f"record {keys[k]!r} of column {column!r} holds windows of several classes "
                             f"({', '.join(states)}): not a record")
        truth.append(states[0])
    truth = np.asarray(truth)
    counts = np.bincount(inverse)
    out = {"column": column, "n_records": int(keys.size), "windows_per_record": [int(counts.min()), int(counts.max())],
           "decision": decision, **classification_metrics(truth, decided, labels=labels)}
    if merge:
        out["merged"] = merged_classification_metrics(truth, decided, merge, labels)
    return out


def accuracy_by(ev: Evaluation, column: str, n_bins: int = 6) -> list[dict]:
    """Accuracy per value (or per equal-width bin) of a metadata column, e.g. ``noise_snr_db``.

    A column with at most 12 distinct values is grouped by value, otherwise into ``n_bins`` equal-width
    bins between its minimum and maximum (the last bin closed).  Returns one dict per group:
    ``{"lo", "hi", "n", "accuracy", "healthy_recall", "false_alarm_rate"}`` (``lo == hi`` for a single value; the
    last two None in a group without a healthy sample, or for a model without a healthy class).
    """
    from rvdiag.evaluation.metrics import healthy_class

    from rvdiag.errors import StoreError

    if column not in ev.meta:
        raise StoreError(f"no metadata column {column!r} (columns: {', '.join(sorted(ev.meta))})")
    try:
        v = np.asarray(ev.meta[column], dtype=float)
    except (TypeError, ValueError):
        raise StoreError(f"metadata column {column!r} is not numeric") from None
    ok = np.isfinite(v)
    correct = ev.y_true == ev.y_pred
    healthy = healthy_class(ev.metrics.get("labels") or sorted(set(ev.y_true.tolist())))
    is_healthy = ev.y_true == healthy
    out = []
    values = np.unique(v[ok])
    if values.size <= 12:
        groups = [(x, x, ok & (v == x)) for x in values]
    else:
        edges = np.linspace(values[0], values[-1], n_bins + 1)
        groups = []
        for i in range(n_bins):
            hi_ok = v <= edges[i + 1] if i == n_bins - 1 else v < edges[i + 1]
            groups.append((edges[i], edges[i + 1], ok & (v >= edges[i]) & hi_ok))
    for lo, hi, m in groups:
        if m.any():
            h = m & is_healthy
            h_recall = float(correct[h].mean()) if h.any() else None
            out.append({"lo": float(lo), "hi": float(hi), "n": int(m.sum()), "accuracy": float(correct[m].mean()),
                        "healthy_recall": h_recall, "false_alarm_rate": None if h_recall is None else 1.0 - h_recall})
    return out
