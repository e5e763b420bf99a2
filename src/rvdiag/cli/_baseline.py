"""The baseline flow of the CLI: train, evaluate and diagnose a monitor that compares a reducer with its own healthy
baseline (docs/monitoring.md).  ``rvdiag train`` / ``evaluate`` / ``diagnose`` branch into this module
when the store is paired (:func:`rvdiag.datasets.store.is_paired`) or the model's card says ``needs_baseline``.

- :func:`train_monitor`: :class:`rvdiag.models.monitoring.BaselineMonitor` on
  :class:`rvdiag.features.relative.BaselineReferencedFeatures` of the monitored records of the ``train`` split, each
  against its reducer's baseline records at the nearest operating point (:func:`rvdiag.datasets.store.match_baseline`).
  The split must be by reducer: a reducer in both ``train`` and ``test`` is refused.
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
MONITOR_FEATURES = {"tsa-change": ("none", True), "orders": (None, False), "orders+tsa-change": (None, True)}
#: the TSA change alone: the best six-state accuracy of the routes measured in docs/monitoring.md (59.5 %, false
#: alarms 4.2 % at alpha 5 %, leave-3-reducers-out)
DEFAULT_MONITOR_FEATURES = "tsa-change"
#: the alarm's false-alarm rate per record
DEFAULT_ALPHA = 0.01
OPERATING_COLUMNS = ("output_speed_deg_s", "load_Nm")
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
    return BaselineReferencedFeatures(features=inner, tsa_change=tsa, fs=float(fs))


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

    name = features or DEFAULT_MONITOR_FEATURES
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
    echo(f"{data}: paired store: training a baseline-referenced monitor ({name} features, each record against its "
         f"reducer's baseline at the nearest operating point) on {len(tr.y)} monitored records of "
         f"{len(np.unique(tr.meta['reducer']))} reducers" + (f", scoring {len(te.y)} of "
                                                            f"{len(np.unique(te.meta['reducer']))} held-out reducers"
                                                            if te is not None else ", no test split"))
    fx.fit(_first_row(tr, fx))
    D, _ = paired_features(fx, tr, base, fs=store.fs, baseline_fs=store.fs, where=f"the store {data}")
    y = np.asarray(tr.y).astype(str)
    m = BaselineMonitor(alpha=alpha, features=fx, random_state=seed).fit(D, y, groups=tr.meta["reducer"])
    n = int(m.n_calibration_)
    achieved = alpha
    if math.isinf(m.threshold_):
        achieved = math.ceil(1e4 / (n + 1)) / 1e4  # the lowest rate n calibration records guarantee (4 digits up)
        (warn or echo)(f"warning: {n} healthy calibration records are too few for a false-alarm rate of {100 * alpha:g} % "
             f"(it needs >= {math.ceil(1 / alpha) - 1}); the alarm is set at {100 * achieved:.2f} %, the lowest "
             "rate they can guarantee: simulate more healthy records or reducers for a lower one")
        m.set_params(alpha=achieved).fit(D, y, groups=tr.meta["reducer"])
    metrics = None
    if te is not None and len(te.y):
        metrics = _score(m, te, base, store.fs, store.fs, None, f"the test split of {data}")
        echo("test (held-out reducers): " + headline(metrics))
    store_info = training_store_info(store, data, len(tr.y))
    save_monitor(m, out, fs=store.fs, training_store=store_info, metrics=metrics or {}, seed=seed,
                 extra={"reducer": kind, "monitor_features": name})
    echo(f"saved model to {out}: it needs a baseline (card needs_baseline); the alarm's false-alarm rate is "
         f"{100 * m.alpha:g} % per record, calibrated on {n} healthy records")
    return {"model_dir": str(out), "metrics": metrics, "alpha": float(m.alpha), "n_calibration": n,
            "features": name, "needs_baseline": True}


def _first_row(s, fx):
    """A row of the monitored records with their metadata: ``fx.fit`` learns the window length from it."""
    from rvdiag.features.combine import with_metadata

    return with_metadata(s.X[:1], {k: v[:1] for k, v in s.meta.items()}, list(fx.input_metadata()))


# ---------------------------------------------------------------------------------------------------- evaluate
def _score(m, mon, base, fs, baseline_fs, tolerances, where) -> dict:
    """The state's classification metrics beside the alarm's rates on the monitored records ``mon``."""
    from rvdiag.evaluation.metrics import classification_metrics, healthy_class

    D, _ = paired_features(m.features, mon, base, fs=fs, baseline_fs=baseline_fs, card_tolerances=tolerances,
                           where=where)
    y = np.asarray(mon.y).astype(str)
    pred = m.predict(D).astype(str)
    alarm = m.alarm(D)
    out = classification_metrics(y, pred, labels=[str(c) for c in m.classes_])
    h = healthy_class([str(c) for c in m.classes_]) or str(m.healthy)
    faulty = y != h
    out["state_false_alarm_rate"] = out.pop("false_alarm_rate")
    out["false_alarm_rate"] = float(alarm[~faulty].mean()) if (~faulty).any() else None
    out["detection_rate"] = float(alarm[faulty].mean()) if faulty.any() else None
    out["detection_rate_per_state"] = {c: float(alarm[y == c].mean()) for c in sorted(set(y[faulty].tolist()))}
    out["alarm"] = {"alpha": float(m.alpha), "threshold": float(m.threshold_),
                    "n_calibration": int(m.n_calibration_)}
    out["n_reducers"] = int(len(np.unique(mon.meta["reducer"]))) if "reducer" in mon.meta else None
    return out


def headline(m: dict) -> str:
    """Accuracy, the false-alarm and detection rates and the healthy recall together (never an accuracy alone)."""
    pct = (lambda v: "-" if v is None else f"{100 * v:.1f} %")
    per = ", ".join(f"{c} {pct(v)}" for c, v in m["detection_rate_per_state"].items())
    return (f"accuracy {100 * m['accuracy']:.2f} %, false-alarm rate {pct(m['false_alarm_rate'])} (stated "
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


def evaluate_monitor(loaded, store, data, split: str, where=(), baseline: Path | None = None) -> dict:
    """``rvdiag evaluate`` of a baseline-referenced model: the monitored records of ``split`` (all its records on a
    store without roles) against the store's own baseline records (a paired store) or ``baseline``'s."""
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
    out = _score(m, s, base, store.fs, bfs, loaded.card.get("baseline"), f"the store {data}")
    out["split"] = split
    return out


def print_evaluation(res: dict, loaded, data) -> None:
    from rich.console import Console
    from rich.table import Table

    con = Console()
    reds = "" if res.get("n_reducers") is None else f" of {res['n_reducers']} reducers"
    con.print(f"{loaded.card.get('model')} on {data} [{res['split']}], {res['n_samples']} monitored records{reds}: "
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
    if load is None:
        raise ParameterError("the record's load is needed to find its baseline: give --load N_M (output torque)")
    speed = record_speed(sig, values)
    rec = recognition(loaded, x, sig.fs, {"novelty": None}, speed, False) if flat_reason(x, L) is None else \
        {"recognised": False, "reason": flat_reason(x, L), "checks": {}}
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


def print_diagnosis(res: dict) -> None:
    from rich.console import Console

    con = Console()
    if not res["recognised"]:
        con.print(f"{res['file']} [{res['channel']}]: [bold]not recognised[/bold]: this record does not look like "
                  f"the reducer the model knows: {res['reason']}", soft_wrap=True)
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
