"""Training and evaluating a baseline monitor on a paired store (docs/monitoring.md).  ``rvdiag train`` /
``evaluate`` call these when the store is paired (:func:`rvdiag.monitoring.pairing.is_paired`) or the model's card
says ``needs_baseline``.

- :func:`train_monitor`: :class:`rvdiag.monitoring.detector.BaselineMonitor` on
  :class:`rvdiag.features.relative.BaselineReferencedFeatures` of the monitored records of the ``train`` split, each
  against its reducer's baseline records at the nearest operating point
  (:func:`rvdiag.monitoring.pairing.match_baseline`).  The split must be by reducer: a reducer in both ``train`` and
  ``test`` is refused.  The alarm's threshold is calibrated by K-fold CV+ over the training reducers
  (:class:`BaselineMonitor`, ``calibration="cv+"``).
- :func:`evaluate_monitor`: the state's accuracy and recall beside the alarm's false-alarm and detection rates.

A baseline (a paired store's ``role == "baseline"`` records, or a healthy store of the same machine) must come from
the reducer type the model was trained on (:func:`rvdiag.monitoring.baseline.reducer_type`), at its sampling rate,
with a record within the card's tolerances of each monitored record's speed and load.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rvdiag.errors import ParameterError, StoreError
from rvdiag.evaluation.metrics import binomial_interval
from rvdiag.monitoring.baseline import open_baseline_store, teeth, reducer_type
from rvdiag.monitoring.life import check_life_store, evaluate_life, sensor_faulty
from rvdiag.datasets.store import Samples
from rvdiag.monitoring.pairing import (RECORD_COLUMN, baseline_records, is_paired, paired_features, per_record,
                                       record_ids, roles, subset, with_load_column)

MONITOR_MODEL = "baseline-monitor"
#: ``--features`` of a monitor -> (inner window features or "none", TSA change appended)
MONITOR_FEATURES = {"tsa-change": ("none", True), "orders": (None, False), "orders+tsa-change": (None, True),
                    "current-lines": ("current-lines", False)}
#: the TSA change alone: the best six-state accuracy of the routes measured in docs/monitoring.md (59.5 %, false
#: alarms 4.2 % at alpha 5 %, leave-3-reducers-out)
DEFAULT_MONITOR_FEATURES = "tsa-change"
#: the default of a motor-current store (its ``[model] signal = "current"``): the change of the order-spectrum
#: features, chosen by measurement (docs/monitoring.md, "Motor current against its baseline"): with the alarm
#: calibrated by CV+ it raised the alarm on 423 of 423 broken-tooth records and 54 of 54 spalls of 59 unseen joints
#: at 2 false alarms in 149 healthy records (stated 10 %), where the reducer's lines (``current-lines``) missed two
#: whole joints (95.5 %) and the TSA change, meant for a housing acceleration, half the broken teeth
DEFAULT_CURRENT_MONITOR_FEATURES = "orders"
#: the alarm's false-alarm rate per record
DEFAULT_ALPHA = 0.01
def monitor_features(name: str, fs: float):
    """The :class:`BaselineReferencedFeatures` of a ``--features`` value of :data:`MONITOR_FEATURES`."""
    from rvdiag.features.relative import BaselineReferencedFeatures

    if name not in MONITOR_FEATURES:
        raise ParameterError(f"--features {name!r} does not apply to a baseline-referenced model; use one of "
                             f"{'|'.join(MONITOR_FEATURES)} (default {DEFAULT_MONITOR_FEATURES})")
    inner, tsa = MONITOR_FEATURES[name]
    if inner == "current-lines":
        from rvdiag.features.current import CurrentLineFeatures

        inner = CurrentLineFeatures(fs=float(fs))
    return BaselineReferencedFeatures(features=inner, tsa_change=tsa, fs=float(fs))


def default_monitor_features(store) -> str:
    """The ``--features`` of a monitor trained on ``store`` when none is given: :data:`DEFAULT_CURRENT_MONITOR_FEATURES`
    on a motor-current store, else :data:`DEFAULT_MONITOR_FEATURES`."""
    from rvdiag.workflows.training_store import signal_info

    current = signal_info(store)["signal"] == "current"
    return DEFAULT_CURRENT_MONITOR_FEATURES if current else DEFAULT_MONITOR_FEATURES


# ------------------------------------------------------------------------------------------------------- train
def wants_monitor(data, model: str | None, alpha: float | None, **others) -> bool:
    """Whether ``rvdiag train`` trains a baseline monitor: ``--model baseline-monitor``, or no ``--model`` on a
    paired store.  ``others`` (``repeat``, ``snr_db``, ``multilabel``, ``streaming``) do not apply to a monitor; an
    ``--alpha`` applies to nothing else."""
    from rvdiag.datasets import SampleStore

    paired = False
    if model in (None, MONITOR_MODEL):
        try:
            paired = is_paired(SampleStore.open(data).meta)
        except StoreError:
            if model == MONITOR_MODEL:
                raise
    if model == MONITOR_MODEL and not paired:
        raise ParameterError(f"--model {MONITOR_MODEL} needs a paired store (metadata reducer and role, both roles "
                             f"present; docs/monitoring.md); {data} is not one")
    if not paired:
        if alpha is not None:
            raise ParameterError("--alpha applies to a baseline-referenced model (trained on a paired store)")
        return False
    bad = {"repeat": "--repeat", "snr_db": "--snr-db", "multilabel": "--multilabel", "streaming": "--streaming"}
    for key, flag in bad.items():
        v = others.get(key)
        if v not in (None, False) and not (key == "repeat" and v == 1):
            raise ParameterError(f"{flag} does not apply to a baseline-referenced model (a paired store)")
    return True


def check_reducer_split(tr, te, data) -> None:
    if te is None:
        return
    both = sorted(set(np.asarray(tr.meta["reducer"]).tolist()) & set(np.asarray(te.meta["reducer"]).tolist()))
    if both:
        raise StoreError(f"{data}: reducer(s) {both[:5]} are in both the train and the test split; a baseline-"
                         "referenced model is scored on held-out reducers: split the store by reducer")


def monitored_records(s: Samples) -> tuple[Samples, int]:
    """The monitored samples of ``s`` without those with a sensor fault (a life store's drawn dead, clipped or
    disconnected channel, :func:`rvdiag.monitoring.life.sensor_faulty`): neither trained on nor scored, as the fleet
    neither judges nor counts a record it does not recognise; and how many were left out."""
    mon = roles(s, "monitored")
    bad = mon & sensor_faulty(s.meta)
    return subset(s, mon & ~bad), int(bad.sum())


def train_monitor(store, data, out: Path, *, features: str | None, alpha: float | None, seed: int,
                  conditions=(), echo=print, warn=None) -> dict:
    """Fit and save a baseline monitor on a paired store (module docstring); returns its test evaluation (or
    None without a test split) and the alarm's achieved ``alpha``."""
    from rvdiag.monitoring.detector import BaselineMonitor, save_monitor
    from rvdiag.workflows.training_store import training_store_info
    from rvdiag.params import ReducerParams

    name = features or default_monitor_features(store)
    alpha = DEFAULT_ALPHA if alpha is None else float(alpha)
    if not 0 < alpha < 1:
        raise ParameterError(f"--alpha must lie in (0, 1), got {alpha}")
    if not store.fs:
        raise StoreError(f"{data} states no sampling rate, which the baseline-referenced features need")
    kind = reducer_type(store.attrs)
    default = reducer_type({"params": ReducerParams.default().to_dict()})
    if kind is not None and teeth(kind) != teeth(default):
        raise ParameterError(f"{data} holds a reducer of another type ({kind}); the TSA change is taken on the "
                             f"built-in {default['name']}'s sun shaft")
    fx = monitor_features(name, store.fs)
    base = baseline_records(store)
    idx = store.indices("train", list(conditions))
    tr = store.load(index=idx)
    tr, left_out = monitored_records(tr)
    te = None
    if "test" in store.splits():
        te, _ = monitored_records(store.load("test"))
    check_reducer_split(tr, te, data)
    if len(set(tr.y.tolist())) < 2:
        raise StoreError(f"{data}: the monitored records of the train split hold fewer than 2 states")
    n_rec = (lambda s: len(np.unique(s.meta[RECORD_COLUMN])) if RECORD_COLUMN in s.meta else len(s.y))
    echo(f"{data}: paired store: training a baseline-referenced monitor ({name} features, each record against its "
         f"reducer's baseline at the nearest operating point) on {n_rec(tr)} monitored records ({len(tr.y)} windows) "
         f"of {len(np.unique(tr.meta['reducer']))} reducers" + (f", scoring {n_rec(te)} of "
                                                               f"{len(np.unique(te.meta['reducer']))} held-out "
                                                               "reducers" if te is not None else ", no test split")
         + (f"; {left_out} window(s) with a sensor fault (life.sensor_fault) left out" if left_out else ""))
    fx.fit(first_row(tr, fx))
    D, _ = paired_features(fx, tr, base, fs=store.fs, baseline_fs=store.fs, where=f"the store {data}")
    D, y, reducers, counts = per_record(D, tr, f"the store {data}")  # one row per record: its windows' mean
    record_windows = int(np.median(counts))
    m = BaselineMonitor(alpha=alpha, features=fx, random_state=seed).fit(D, y, groups=reducers)
    n = int(m.n_calibration_)
    achieved = alpha
    if math.isinf(m.threshold_):
        achieved = math.ceil(1e4 / (n + 1)) / 1e4  # the lowest rate n calibration records guarantee (4 digits up)
        (warn or echo)(f"warning: {n} healthy calibration records are too few for a false-alarm rate of {100 * alpha:g} % "
             f"(it needs >= {math.ceil(1 / alpha) - 1}); the alarm is set at {100 * achieved:.2f} %, the lowest "
             "rate they can guarantee: simulate more healthy records or reducers for a lower one")
        m.set_params(alpha=achieved).fit(D, y, groups=reducers)
    metrics = None
    if te is not None and len(te.y):
        metrics = score(m, te, base, store.fs, store.fs, None, f"the test split of {data}")
        echo("test (held-out reducers): " + headline(metrics))
    store_info = training_store_info(store, data, len(tr.y))
    save_monitor(m, out, record_windows=record_windows, fs=store.fs, training_store=store_info,
                 metrics=metrics or {}, seed=seed, extra={"reducer": kind, "monitor_features": name})
    echo(f"saved model to {out}: it needs a baseline (card needs_baseline); the alarm's false-alarm rate is "
         f"{100 * m.alpha:g} % per record (of {record_windows} window(s), decided on their mean change), calibrated "
         f"on {n} healthy records of {m.n_calibration_groups_} training reducers, each scored by a detector that "
         f"never saw its reducer ({calibration_words(m)})")
    return {"model_dir": str(out), "metrics": metrics, "alpha": float(m.alpha), "n_calibration": n,
            "features": name, "needs_baseline": True}


def calibration_words(m) -> str:
    """How a monitor's threshold was calibrated, in words (card ``alarm.calibration``)."""
    if m.calibration == "cv+":
        return f"CV+ over {len(m.fold_detectors_)} folds of reducers"
    return "split: the detector fitted on the other reducers"


def first_row(s, fx):
    """A row of the monitored records with their metadata: ``fx.fit`` learns the window length from it."""
    from rvdiag.features.combine import with_metadata

    return with_metadata(s.X[:1], {k: v[:1] for k, v in s.meta.items()}, list(fx.input_metadata()))


# ---------------------------------------------------------------------------------------------------- evaluate
def record_rows(m, mon, base, fs, baseline_fs, tolerances, where):
    """Each monitored record of ``mon`` as one row, its windows' mean change against its baseline
    (:func:`paired_features`, :func:`per_record`): ``(D, labels, reducers, windows per record)``."""
    D, _ = paired_features(m.features, mon, base, fs=fs, baseline_fs=baseline_fs, card_tolerances=tolerances,
                           where=where)
    return per_record(D, mon, where)


def score(m, mon, base, fs, baseline_fs, tolerances, where, merge=None, rows=None) -> dict:
    """The state's classification metrics beside the alarm's rates on the monitored records ``mon``, each record
    decided on the mean change of its windows (:func:`record_means`); with ``merge`` (``{"T4": "T1"}``) also the
    state's metrics with classes merged (key ``merged``).  ``rows``: :func:`record_rows` of ``mon``, when already
    computed."""
    from rvdiag.evaluation.metrics import classification_metrics, healthy_class, merged_classification_metrics

    D, y, reducers, counts = rows if rows is not None else record_rows(m, mon, base, fs, baseline_fs, tolerances,
                                                                       where)
    pred = m.predict(D).astype(str)
    alarm = m.alarm(D)
    labels = [str(c) for c in m.classes_]
    out = classification_metrics(y, pred, labels=labels)
    out["n_records"] = int(y.size)
    out["windows_per_record"] = [int(counts.min()), int(counts.max())]
    h = healthy_class(labels) or str(m.healthy)
    faulty = y != h
    out["state_false_alarm_rate"] = out.pop("false_alarm_rate")
    out["false_alarm_rate"] = float(alarm[~faulty].mean()) if (~faulty).any() else None
    out["n_healthy_records"] = int((~faulty).sum())
    out["n_false_alarms"] = int(alarm[~faulty].sum())
    out["false_alarm_ci95"] = binomial_interval(out["n_false_alarms"], out["n_healthy_records"]) \
        if (~faulty).any() else None
    out["detection_rate"] = float(alarm[faulty].mean()) if faulty.any() else None
    out["detection_rate_per_state"] = {c: float(alarm[y == c].mean()) for c in sorted(set(y[faulty].tolist()))}
    out["alarm"] = {"alpha": float(m.alpha), "threshold": float(m.threshold_),
                    "n_calibration": int(m.n_calibration_), "calibration": m.calibration}
    out["n_reducers"] = int(len(np.unique(reducers))) if reducers is not None else None
    if merge:
        out["merged"] = merged_classification_metrics(y, pred, merge, labels)
    return out


def headline(m: dict) -> str:
    """Accuracy, the false-alarm and detection rates and the healthy recall together (never an accuracy alone)."""
    pct = (lambda v: "-" if v is None else f"{100 * v:.1f} %")
    per = ", ".join(f"{c} {pct(v)}" for c, v in m["detection_rate_per_state"].items())
    ci = m.get("false_alarm_ci95")
    ci = f", 95 % interval {100 * ci[0]:.1f}-{100 * ci[1]:.1f} %" if ci else ""
    return (f"accuracy {100 * m['accuracy']:.2f} %, false-alarm rate {pct(m['false_alarm_rate'])} "
            f"({m.get('n_false_alarms', '?')} of {m.get('n_healthy_records', '?')} healthy records{ci}; stated "
            f"{100 * m['alarm']['alpha']:g} %), detection rate {pct(m['detection_rate'])}"
            + (f" ({per})" if per else "") + f", healthy recall {pct(m['healthy_recall'])}")


def evaluate_monitor(loaded, store, data, split: str, where=(), baseline: Path | None = None,
                     merge: dict | None = None, *, life: bool = False, seed: int = 0) -> dict:
    """``rvdiag evaluate`` of a baseline-referenced model: the monitored records of ``split`` (all its records on a
    store without roles) against the store's own baseline records (a paired store) or ``baseline``'s; each record
    (metadata ``unit``) decided on its windows' mean change; ``merge`` as :func:`score`.  ``life``: also the
    figures over the split's lives of a life store (:func:`rvdiag.monitoring.life.evaluate_life`, key ``life``),
    from the same per-record changes."""
    if life and (baseline is not None or where):
        raise ParameterError("--life scores whole histories of a life store against its own commissioning records: "
                             "drop " + ("--baseline" if baseline is not None else "--where"))
    if life:
        check_life_store(store, data)  # before the per-record scoring

    m = loaded.estimator
    where = list(where or ())
    s = store.load(index=store.indices(split, where))
    if baseline is not None:
        base, bstore = open_baseline_store(baseline, loaded, loaded.fs)
        bfs = bstore.fs
    elif is_paired(store.meta):
        base, bfs = baseline_records(store), store.fs
        want, got = loaded.card.get("reducer"), reducer_type(store.attrs)
        if want and got and want != got:
            raise ParameterError(f"{data} holds a reducer of another type ({got}) than the model's ({want})")
    else:
        raise ParameterError(f"the model {loaded.path} is baseline-referenced and {data} is not a paired store: "
                             "give --baseline BASE.zarr, a healthy store of the same machine")
    s, bad = monitored_records(s)
    s = Samples(X=s.X, y=s.y, meta=with_load_column(s.meta), index=s.index)
    if not len(s.y):
        raise StoreError(f"the split {split!r} of {data} holds no monitored records"
                         + (f" where {' and '.join(where)}" if where else ""))
    if loaded.fs and store.fs and abs(store.fs - loaded.fs) > 1e-9 * loaded.fs:
        raise ParameterError(f"{data} is sampled at {store.fs:g} Hz, the model at {loaded.fs:g} Hz")
    rows = record_rows(m, s, base, store.fs, bfs, loaded.card.get("baseline"), f"the store {data}")
    out = score(m, s, base, store.fs, bfs, loaded.card.get("baseline"), f"the store {data}", merge, rows)
    out["split"] = split
    if bad:
        out["n_sensor_fault_samples_left_out"] = bad
    if life:
        out["life"] = evaluate_life(loaded, store, data, split, seed=seed, scored=(record_ids(s.meta), rows[0]))
    return out


__all__ = ["DEFAULT_ALPHA", "DEFAULT_CURRENT_MONITOR_FEATURES", "DEFAULT_MONITOR_FEATURES", "MONITOR_FEATURES",
           "MONITOR_MODEL", "calibration_words", "default_monitor_features", "evaluate_monitor", "record_rows",
           "headline", "monitor_features", "score", "train_monitor", "wants_monitor"]
