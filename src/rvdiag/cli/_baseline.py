"""The baseline flow of the CLI: train, evaluate and diagnose a monitor that compares a reducer with its own healthy
baseline (docs/monitoring.md).  ``rvdiag train`` / ``evaluate`` / ``diagnose`` branch into this module
when the store is paired (:func:`rvdiag.datasets.store.is_paired`) or the model's card says ``needs_baseline``.

- :func:`train_monitor`: :class:`rvdiag.models.monitoring.BaselineMonitor` on
  :class:`rvdiag.features.relative.BaselineReferencedFeatures` of the monitored records of the ``train`` split, each
  against its reducer's baseline records at the nearest operating point (:func:`rvdiag.datasets.store.match_baseline`).
  The split must be by reducer: a reducer in both ``train`` and ``test`` is refused.  The alarm's threshold is
  calibrated by K-fold CV+ over the training reducers (:class:`BaselineMonitor`, ``calibration="cv+"``).
- :func:`evaluate_monitor`: the state's accuracy and recall beside the alarm's false-alarm and detection rates.
- :func:`diagnose_monitor`: one record's health index, alarm, most probable state and what changed, in words.

A baseline (a paired store's ``role == "baseline"`` records, or ``--baseline BASE.zarr``: a healthy store of the same
machine) must come from the reducer type the model was trained on (:func:`reducer_type`), at its sampling rate, with
a record within the card's tolerances of each monitored record's speed and load.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rvdiag.errors import ParameterError, StoreError

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
OPERATING_COLUMNS = ("output_speed_deg_s", "load_Nm")
#: the metadata column naming a window's record (every store has it): a library's simulation, a file of
#: ``rvdiag dataset from-files``.  A monitor decides a record on the mean change of its windows, as ``diagnose``
#: decides a file, and its alarm is calibrated and scored per record: the windows of one record share its run-to-run
#: variation and are not exchangeable with each other's records
RECORD_COLUMN = "unit"
#: the reducer-type fields of a parameter set that a baseline must share with the model
TYPE_FIELDS = {"stage1": ("sun_teeth", "planet_teeth", "n_planets"), "stage2": ("cycloid_lobes", "pins")}


def needs_baseline(loaded) -> bool:
    """Whether a loaded model compares a record with a baseline (card ``needs_baseline``)."""
    return bool(loaded.card.get("needs_baseline"))


def reducer_type(attrs) -> dict | None:
    """The reducer type a store holds: the name and tooth counts of its parameter set (a library's ``params``, or a
    measured store's angle-source parameters, ``config.angle.params``), or None when it states none."""
    params = attrs.get("params")
    if not isinstance(params, dict):
        params = ((attrs.get("config") or {}).get("angle") or {}).get("params")
    if not isinstance(params, dict):
        return None
    out = {"name": params.get("name")}
    for stage, fields in TYPE_FIELDS.items():
        for f in fields:
            out[f] = (params.get(stage) or {}).get(f)
    return out


def _teeth(kind: dict) -> dict:
    return {k: v for k, v in kind.items() if k != "name"}


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
    from rvdiag.cli._store_info import signal_info

    current = signal_info(store)["signal"] == "current"
    return DEFAULT_CURRENT_MONITOR_FEATURES if current else DEFAULT_MONITOR_FEATURES


def _roles(samples, role: str) -> np.ndarray:
    r = samples.meta.get("role")
    return np.ones(len(samples.y), bool) if r is None else np.asarray(r).astype(str) == role


def _baseline_records(store):
    """The ``role == "baseline"`` records of a store (all of a store without roles), loaded."""
    role = store.meta.get("role")
    idx = np.arange(store.n_samples) if role is None else np.flatnonzero(np.asarray(role).astype(str) == "baseline")
    return store.load(index=idx)


def _subset(s, keep):
    from rvdiag.datasets.store import Samples

    return Samples(X=s.X[keep], y=s.y[keep], meta={k: v[keep] for k, v in s.meta.items()}, index=s.index[keep])


def paired_features(fx, mon, base, *, fs, baseline_fs, card_tolerances=None, where="the data"):
    """``D``: each monitored record's change against its baseline records (match_baseline, then ``fx``).  Refuses a
    match of one baseline record when ``fx`` needs the baseline's own spread (the TSA change)."""
    from rvdiag.datasets.store import LOAD_TOLERANCE, SPEED_TOLERANCE, match_baseline
    from rvdiag.features.combine import with_metadata

    tol = card_tolerances or {}
    groups = match_baseline(mon.meta, base.meta, fs=fs, baseline_fs=baseline_fs,
                            speed_tolerance=float(tol.get("speed_tolerance", SPEED_TOLERANCE)),
                            load_tolerance=float(tol.get("load_tolerance", LOAD_TOLERANCE)),
                            columns=OPERATING_COLUMNS)
    if fx.tsa_change:
        few = [i for i, g in enumerate(groups) if len(g) < 2]
        if few:
            i = few[0]
            raise ParameterError(f"{where}: record {i} has one baseline record at its operating point "
                                 f"({mon.meta['output_speed_deg_s'][i]:g} deg/s, {mon.meta['load_Nm'][i]:g} N m); "
                                 "the TSA change needs >= 2 to know the reducer's run-to-run spread")
    cols = list(fx.input_metadata())
    X = with_metadata(mon.X, mon.meta, cols, where=where)
    B = with_metadata(base.X, base.meta, cols, where="the baseline")
    D = fx.transform(X, B, groups)
    if not np.all(np.isfinite(D)):
        raise ParameterError(f"{where}: the baseline-referenced features are not finite (records shorter than one "
                             "sun revolution, or a flat baseline?)")
    return D, groups


def record_means(D, meta, column: str = RECORD_COLUMN):
    """Each record's mean row of ``D`` (the windows' changes), in the order records first appear.

    Returns ``(means, first, counts)``: ``first`` indexes each record's first window (its label, reducer and
    operating point), ``counts`` its number of windows.  Without ``column`` every window is its own record.

    >>> m, first, n = record_means(np.array([[1.0], [3.0], [5.0]]), {"unit": np.array([7, 7, 2])})
    >>> m.ravel().tolist(), first.tolist(), n.tolist()
    ([2.0, 5.0], [0, 2], [2, 1])
    """
    D = np.asarray(D, dtype=np.float64)
    ids = np.asarray(meta[column]) if column in meta else np.arange(D.shape[0])
    _, first, inv = np.unique(ids, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")  # records in the order they first appear
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    inv = rank[inv.ravel()]
    counts = np.bincount(inv, minlength=order.size)
    means = np.zeros((order.size, D.shape[1]))
    np.add.at(means, inv, D)
    return means / counts[:, None], first[order], counts


def _per_record(D, s, where):
    """``(means, labels, reducers or None, counts)`` of the records of samples ``s`` (:func:`record_means`); a
    record whose windows carry different labels is refused."""
    means, first, counts = record_means(D, s.meta)
    y = np.asarray(s.y).astype(str)
    ids = np.asarray(s.meta[RECORD_COLUMN]) if RECORD_COLUMN in s.meta else np.arange(y.size)
    mixed = [i for i in np.unique(ids) if np.unique(y[ids == i]).size > 1] if counts.max() > 1 else []
    if mixed:
        raise StoreError(f"{where}: the windows of record {RECORD_COLUMN}={mixed[0]} carry different labels")
    red = np.asarray(s.meta["reducer"])[first] if "reducer" in s.meta else None
    return means, y[first], red, counts


# ------------------------------------------------------------------------------------------------------- train
def wants_monitor(data, model: str | None, alpha: float | None, **others) -> bool:
    """Whether ``rvdiag train`` trains a baseline monitor: ``--model baseline-monitor``, or no ``--model`` on a
    paired store.  ``others`` (``repeat``, ``snr_db``, ``multilabel``, ``streaming``) do not apply to a monitor; an
    ``--alpha`` applies to nothing else."""
    from rvdiag.datasets import SampleStore
    from rvdiag.datasets.store import is_paired

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


def _check_reducer_split(tr, te, data) -> None:
    if te is None:
        return
    both = sorted(set(np.asarray(tr.meta["reducer"]).tolist()) & set(np.asarray(te.meta["reducer"]).tolist()))
    if both:
        raise StoreError(f"{data}: reducer(s) {both[:5]} are in both the train and the test split; a baseline-"
                         "referenced model is scored on held-out reducers: split the store by reducer")


def train_monitor(store, data, out: Path, *, features: str | None, alpha: float | None, seed: int,
                  conditions=(), echo=print, warn=None) -> dict:
    """Fit and save a baseline monitor on a paired store (module docstring); returns its test evaluation (or
    None without a test split) and the alarm's achieved ``alpha``."""
    from rvdiag.cli._store_info import training_store_info
    from rvdiag.models.monitoring import BaselineMonitor, save_monitor
    from rvdiag.params import ReducerParams

    name = features or default_monitor_features(store)
    alpha = DEFAULT_ALPHA if alpha is None else float(alpha)
    if not 0 < alpha < 1:
        raise ParameterError(f"--alpha must lie in (0, 1), got {alpha}")
    if not store.fs:
        raise StoreError(f"{data} states no sampling rate, which the baseline-referenced features need")
    kind = reducer_type(store.attrs)
    default = reducer_type({"params": ReducerParams.default().to_dict()})
    if kind is not None and _teeth(kind) != _teeth(default):
        raise ParameterError(f"{data} holds a reducer of another type ({kind}); the TSA change is taken on the "
                             f"built-in {default['name']}'s sun shaft")
    fx = monitor_features(name, store.fs)
    base = _baseline_records(store)
    idx = store.indices("train", list(conditions))
    tr = store.load(index=idx)
    tr = _subset(tr, _roles(tr, "monitored"))
    te = None
    if "test" in store.splits():
        te = store.load("test")
        te = _subset(te, _roles(te, "monitored"))
    _check_reducer_split(tr, te, data)
    if len(set(tr.y.tolist())) < 2:
        raise StoreError(f"{data}: the monitored records of the train split hold fewer than 2 states")
    n_rec = (lambda s: len(np.unique(s.meta[RECORD_COLUMN])) if RECORD_COLUMN in s.meta else len(s.y))
    echo(f"{data}: paired store: training a baseline-referenced monitor ({name} features, each record against its "
         f"reducer's baseline at the nearest operating point) on {n_rec(tr)} monitored records ({len(tr.y)} windows) "
         f"of {len(np.unique(tr.meta['reducer']))} reducers" + (f", scoring {n_rec(te)} of "
                                                               f"{len(np.unique(te.meta['reducer']))} held-out "
                                                               "reducers" if te is not None else ", no test split"))
    fx.fit(_first_row(tr, fx))
    D, _ = paired_features(fx, tr, base, fs=store.fs, baseline_fs=store.fs, where=f"the store {data}")
    D, y, reducers, counts = _per_record(D, tr, f"the store {data}")  # one row per record: its windows' mean
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
        metrics = _score(m, te, base, store.fs, store.fs, None, f"the test split of {data}")
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


def _first_row(s, fx):
    """A row of the monitored records with their metadata: ``fx.fit`` learns the window length from it."""
    from rvdiag.features.combine import with_metadata

    return with_metadata(s.X[:1], {k: v[:1] for k, v in s.meta.items()}, list(fx.input_metadata()))


# ---------------------------------------------------------------------------------------------------- evaluate
def binomial_interval(k: int, n: int, level: float = 0.95) -> list[float]:
    """The Clopper-Pearson interval of a rate of ``k`` events in ``n`` trials (Clopper & Pearson, Biometrika 26
    (1934) 404-413; :meth:`scipy.stats.binomtest`'s ``proportion_ci(method="exact")``)."""
    from scipy.stats import binomtest

    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=level, method="exact")
    return [float(ci.low), float(ci.high)]


def _score(m, mon, base, fs, baseline_fs, tolerances, where, merge=None) -> dict:
    """The state's classification metrics beside the alarm's rates on the monitored records ``mon``, each record
    decided on the mean change of its windows (:func:`record_means`); with ``merge`` (``{"T4": "T1"}``) also the
    state's metrics with classes merged (key ``merged``)."""
    from rvdiag.evaluation.metrics import classification_metrics, healthy_class, merged_classification_metrics

    D, _ = paired_features(m.features, mon, base, fs=fs, baseline_fs=baseline_fs, card_tolerances=tolerances,
                           where=where)
    D, y, reducers, counts = _per_record(D, mon, where)
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


def open_baseline(path: Path, loaded, fs: float | None):
    """The baseline records of ``path`` (its ``role == "baseline"`` records, or all of a store without roles),
    checked against the model: the reducer type, the sampling rate ``fs`` (the model's), the record length and one
    machine; returns ``(samples, store)``."""
    from rvdiag.datasets import SampleStore

    store = SampleStore.open(path)
    want, got = loaded.card.get("reducer"), reducer_type(store.attrs)
    if want and got and want != got:
        raise ParameterError(f"--baseline {path} is of another reducer type ({got.get('name')}: {got}) than the "
                             f"model's ({want.get('name')}: {want})")
    if fs and store.fs and abs(store.fs - float(fs)) > 1e-9 * float(fs):
        raise ParameterError(f"--baseline {path} is sampled at {store.fs:g} Hz, the model at {float(fs):g} Hz: a "
                             "baseline must have the model's sampling rate")
    if not store.fs:
        raise ParameterError(f"--baseline {path} states no sampling rate: rebuild it with 'rvdiag dataset "
                             "from-files --fs HZ'")
    if store.length != loaded.input_length:
        raise ParameterError(f"--baseline {path} holds records of {store.length} points; the model reads "
                             f"{loaded.input_length}: build it with --window {loaded.input_length}")
    s = _baseline_records(store)
    if not len(s.y):
        raise ParameterError(f"--baseline {path} holds no baseline records")
    for c in OPERATING_COLUMNS:
        if c not in s.meta:
            raise ParameterError(f"--baseline {path} has no metadata column {c!r} to match operating points by "
                                 "(build it with 'rvdiag dataset from-files --meta-regex' naming groups speed_dps "
                                 "and load_Nm, or with --angle-channel)")
    return s, store


def evaluate_monitor(loaded, store, data, split: str, where=(), baseline: Path | None = None,
                     merge: dict | None = None) -> dict:
    """``rvdiag evaluate`` of a baseline-referenced model: the monitored records of ``split`` (all its records on a
    store without roles) against the store's own baseline records (a paired store) or ``baseline``'s; each record
    (metadata ``unit``) decided on its windows' mean change; ``merge`` as :func:`_score`."""
    from rvdiag.datasets.store import is_paired

    m = loaded.estimator
    where = list(where or ())
    s = store.load(index=store.indices(split, where))
    if baseline is not None:
        base, bstore = open_baseline(baseline, loaded, loaded.fs)
        bfs = bstore.fs
    elif is_paired(store.meta):
        base, bfs = _baseline_records(store), store.fs
        want, got = loaded.card.get("reducer"), reducer_type(store.attrs)
        if want and got and want != got:
            raise ParameterError(f"{data} holds a reducer of another type ({got}) than the model's ({want})")
    else:
        raise ParameterError(f"the model {loaded.path} is baseline-referenced and {data} is not a paired store: "
                             "give --baseline BASE.zarr, a healthy store of the same machine")
    s = _subset(s, _roles(s, "monitored"))
    if not len(s.y):
        raise StoreError(f"the split {split!r} of {data} holds no monitored records"
                         + (f" where {' and '.join(where)}" if where else ""))
    if loaded.fs and store.fs and abs(store.fs - loaded.fs) > 1e-9 * loaded.fs:
        raise ParameterError(f"{data} is sampled at {store.fs:g} Hz, the model at {loaded.fs:g} Hz")
    out = _score(m, s, base, store.fs, bfs, loaded.card.get("baseline"), f"the store {data}", merge)
    out["split"] = split
    return out


def print_evaluation(res: dict, loaded, data) -> None:
    from rich.console import Console
    from rich.table import Table

    con = Console()
    reds = "" if res.get("n_reducers") is None else f" of {res['n_reducers']} reducers"
    lo, hi = res["windows_per_record"]
    con.print(f"{loaded.card.get('model')} on {data} [{res['split']}], {res['n_records']} monitored records"
              f"{reds} ({lo if lo == hi else f'{lo}-{hi}'} window(s) each, decided on their mean change): "
              + headline(res), soft_wrap=True)
    t = Table()
    for col in ("state", "recall", "alarm raised", "support"):
        t.add_column(col, justify="left" if col == "state" else "right")
    for c, v in res["per_class"].items():
        det = res["detection_rate_per_state"].get(c)
        if det is None and c == res.get("healthy_class"):
            det = res["false_alarm_rate"]
        t.add_row(c, f"{100 * v['recall']:.1f} %", "-" if det is None else f"{100 * det:.1f} %", str(v["support"]))
    con.print(t)
    if "merged" in res:
        mg = res["merged"]
        con.print(f"merged {','.join(f'{a}={b}' for a, b in mg['merge'].items())}: accuracy "
                  f"{100 * mg['accuracy']:.2f} %; " + ", ".join(f"{c} recall {100 * v['recall']:.1f} %"
                                                              for c, v in mg["per_class"].items()), soft_wrap=True)


# ---------------------------------------------------------------------------------------------------- diagnose
def diagnose_monitor(loaded, sig, baseline: Path | None, values: dict, *, output_speed: float | None,
                     load: float | None) -> dict:
    """``rvdiag diagnose`` of a baseline-referenced model: the record's windows against the baseline windows at its
    operating point; the health index, alarm and state of the mean of the windows' changes."""
    from rvdiag.cli._record import SPEED_META, flat_reason, recognition, record_speed, state_name
    from rvdiag.datasets.store import Samples

    if baseline is None:
        raise ParameterError(f"the model {loaded.path} is baseline-referenced (its card says needs_baseline): give "
                             "--baseline BASE.zarr, a healthy store of the same machine (docs/monitoring.md)")
    base, bstore = open_baseline(baseline, loaded, loaded.fs)
    if not sig.fs:
        raise ParameterError("the file states no sampling rate: give --fs")
    if loaded.fs and abs(float(sig.fs) - loaded.fs) > 1e-9 * loaded.fs:
        raise ParameterError(f"the record is sampled at {float(sig.fs):g} Hz, the model and its baseline at "
                             f"{loaded.fs:g} Hz")
    L = loaded.input_length
    x = np.asarray(sig.data, dtype=np.float64)
    k = x.size // L
    if k < 1:
        raise ParameterError(f"the signal has {x.size} points, shorter than one window of {L} points (the model's "
                             "input length)")
    if output_speed is not None:
        values = {**values, SPEED_META[0]: float(output_speed)}
    load = values.get("load_Nm") if load is None else float(load)
    alpha = float((loaded.card.get("alarm") or {}).get("alpha", loaded.estimator.alpha))
    res = {"health_index": None, "alarm": None, "false_alarm_rate": alpha, "p_value": None, "state": None,
           "state_name": None, "probability": None, "changes": [], "n_windows": k, "window_length": L,
           "fs": float(sig.fs), "windows": [], "warnings": [], "unused_points": int(x.size - k * L)}
    n_cal = (loaded.card.get("alarm") or {}).get("record_windows")
    if n_cal and int(n_cal) != k:
        res["warnings"].append(f"warning: the alarm's rate is calibrated on records of {int(n_cal)} window(s) of "
                               f"{L} points, decided on their mean change; this record has {k}: the stated rate "
                               f"holds for records of {int(n_cal)}")
    if load is None:
        raise ParameterError("the record's load is needed to find its baseline: give --load N_M (output torque)")
    speed = record_speed(sig, values)
    rec = recognition(loaded, x, sig.fs, {"novelty": None}, speed, False) if flat_reason(x, L) is None else \
        {"recognised": False, "reason": flat_reason(x, L), "checks": {}}
    rec = mesh_check_against_baseline(rec, x, base, float(sig.fs), speed, L)
    rec = level_check_against_baseline(rec, x, base)
    res.update({"recognised": rec["recognised"], "reason": rec["reason"], "checks": rec["checks"]})
    res["operating_point"] = {"output_speed_deg_s": speed.get("output_speed_deg_s"),
                              "speed_source": speed.get("detail") or speed.get("error"), "load_Nm": load}
    if not rec["recognised"]:
        return res
    if speed.get("output_speed_deg_s") is None:
        raise ParameterError(f"the record's speed is needed to find its baseline: {speed.get('error')}")
    X = x[: k * L].reshape(k, L)
    meta = {OPERATING_COLUMNS[0]: np.full(k, float(speed["output_speed_deg_s"])), OPERATING_COLUMNS[1]: np.full(k, load)}
    mon = Samples(X=X, y=np.array(["?"] * k), meta=meta, index=np.arange(k))
    base_meta = {c: v for c, v in base.meta.items() if c != "reducer"} \
        if len(np.unique(base.meta.get("reducer", [0]))) == 1 else None
    if base_meta is None:
        raise ParameterError(f"--baseline {baseline} holds records of several reducers; give one machine's")
    base = Samples(X=base.X, y=base.y, meta=base_meta, index=base.index)
    D, groups = paired_features(loaded.estimator.features, mon, base, fs=float(sig.fs), baseline_fs=bstore.fs,
                                card_tolerances=loaded.card.get("baseline"), where="the record")
    m = loaded.estimator
    d = m.diagnose(D.mean(axis=0, keepdims=True))[0]
    res.update({"health_index": d["health_index"], "alarm": d["alarm"], "p_value": d["p_value"],
                "state": d["state"], "state_name": state_name(d["state"]), "probability": d["probability"],
                "probabilities": {str(c): float(p) for c, p in zip(m.classes_, m.predict_proba(D.mean(0, keepdims=True))[0])},
                "changes": d["changed"],
                "windows": [{"start": i * L, "health_index": float(h)} for i, h in enumerate(m.health_index(D))],
                "baseline": {"path": str(baseline), "n_records": int(len(groups[0])),
                             "output_speed_deg_s": float(np.mean(base.meta[OPERATING_COLUMNS[0]][groups[0]])),
                             "load_Nm": float(np.mean(base.meta[OPERATING_COLUMNS[1]][groups[0]]))}})
    return res


def mesh_check_against_baseline(rec: dict, x: np.ndarray, base, fs: float, speed: dict, L: int) -> dict:
    """The mesh-line check of :func:`rvdiag.cli._record.recognition`, judged against the machine's own baseline: a
    record without the reducer's mesh lines is "not recognised" only when the baseline shows them at the nearest
    operating point.  Both are read on windows of the model's ``L`` points (the same resolution): the record's
    first window against the baseline window nearest its speed.  Where the baseline shows no line either (a quiet
    mesh behind a noisy path or a sensor floor, as on a machine whose baseline is what it is), the lines say
    nothing about this machine and the record goes on to its health index (``checks["mesh_lines"]["baseline"]``
    says so)."""
    from rvdiag.features.mesh_lines import mesh_lines
    from rvdiag.params import ReducerParams

    lines = rec.get("checks", {}).get("mesh_lines")
    if rec["recognised"] or lines is None or lines["present"]:
        return rec
    v = float(speed["output_speed_deg_s"])
    near = int(np.argmin(np.abs(np.asarray(base.meta[OPERATING_COLUMNS[0]], dtype=float) - v)))
    p = ReducerParams.default()
    in_base = mesh_lines(np.asarray(base.X[near], dtype=np.float64), fs, p, v)["present"]
    in_record = mesh_lines(x[:L], fs, p, v)["present"]
    checks = {**rec["checks"], "mesh_lines": {**lines, "baseline": in_base, "record_window": in_record}}
    if in_base and not in_record:
        return {**rec, "checks": checks, "reason": rec["reason"] + f"; the machine's baseline shows {', '.join(in_base)}"}
    return {"recognised": True, "reason": None, "checks": checks}


#: a record whose RMS lies more than this factor above or below every baseline window's is "not recognised"
LEVEL_FACTOR = 10.0


def level_check_against_baseline(rec: dict, x: np.ndarray, base) -> dict:
    """A record whose level (RMS) lies more than :data:`LEVEL_FACTOR` outside the range of the baseline windows'
    is not this machine's signal as the baseline records it (another sensor, gain or unit, a loose mount): "not
    recognised", with the factor.  The alarm judges smaller changes."""
    if not rec["recognised"]:
        return rec
    rms = float(np.sqrt(np.mean(np.square(x))))
    b = np.sqrt(np.mean(np.square(np.asarray(base.X, dtype=np.float64)), axis=1))
    lo, hi = float(b.min()), float(b.max())
    checks = {**rec.get("checks", {}), "level": {"rms": rms, "baseline_rms": [lo, hi], "factor": LEVEL_FACTOR}}
    if lo > 0 and not (lo / LEVEL_FACTOR <= rms <= hi * LEVEL_FACTOR):
        ratio = rms / hi if rms > hi else lo / rms if rms > 0 else math.inf
        side = "above" if rms > hi else "below"
        return {"recognised": False, "checks": checks,
                "reason": f"its level (RMS {rms:.4g}) lies {ratio:.3g}x {side} the baseline's range ({lo:.4g}-"
                          f"{hi:.4g}): another sensor, gain or unit than the baseline's?"}
    return {**rec, "checks": checks}


def print_diagnosis(res: dict) -> None:
    from rich.console import Console

    from rvdiag.cli._record import not_recognised_line

    con = Console()
    if not res["recognised"]:
        con.print(not_recognised_line(res), soft_wrap=True)
        return
    b = res["baseline"]
    op = res["operating_point"]
    con.print(f"{res['file']} [{res['channel']}]: {res['n_windows']} window(s) of {res['window_length']} points at "
              f"{op['output_speed_deg_s']:.4g} deg/s, {op['load_Nm']:.4g} N m, against {b['n_records']} baseline "
              f"records at {b['output_speed_deg_s']:.4g} deg/s, {b['load_Nm']:.4g} N m", soft_wrap=True)
    con.print(f"health index {res['health_index']:.3g}: "
              + ("[bold]ALARM[/bold]" if res["alarm"] else "no alarm")
              + f" (the alarm's false-alarm rate is {100 * res['false_alarm_rate']:g} % of healthy records; p-value "
                f"{res['p_value']:.3g})", soft_wrap=True)
    con.print(f"most probable state: [bold]{res['state_name']}[/bold] (probability {res['probability']:.3f})",
              soft_wrap=True)
    if res["changes"]:
        con.print("what changed since the baseline: " + "; ".join(res["changes"]), soft_wrap=True)
