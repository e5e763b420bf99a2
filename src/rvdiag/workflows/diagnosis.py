"""Diagnosing one record with a classifier: :func:`diagnose` -> :class:`Diagnosis` (``rvdiag diagnose``; a model
that compares a record with a baseline is :func:`rvdiag.monitoring.monitor_record`).

The signal (one channel, :func:`rvdiag.workflows.read_record`) is cut into adjacent, non-overlapping windows of the
model's input length (the training samples' length); the tail shorter than a window is not used
(``unused_points``).  Each window gets class probabilities; the overall probabilities are their mean, and the
diagnosis is the most probable class overall.  A ``warning:`` is added when the file's sampling rate differs from
the training rate by more than 0.1 % (:data:`rvdiag.models.conditions.FS_RTOL`), or is unknown.

A model that reads per-sample metadata (card ``metadata_columns``, e.g. the shaft speed ``rpm`` of
bearing-envelope features) gets it from the values given, else from the file's scalar that the training store read
into that column (card ``metadata_sources``; :func:`model_metadata`).

It also gives the gear condition indicators of the whole signal on the sun shaft (:func:`file_indicators`), or for a
model trained on motor current the motor-current line table (:func:`file_current_lines`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from rvdiag.errors import DataFileError, ParameterError
from rvdiag.workflows.records import SPEED_META, fault_name, flat_reason, recognition, record_speed, state_name


@dataclass
class Diagnosis:
    """One record diagnosed by a classifier (:func:`diagnose`); :meth:`to_dict` is what ``rvdiag diagnose --json``
    prints.

    ``diagnosis`` is the most probable class over the windows (None when the record is not ``recognised``, with the
    ``reason``), ``state`` its name, ``probabilities`` the windows' mean probabilities, ``windows`` each window's
    start, prediction and probabilities, ``model_recall`` the model's held-out recall of the answer, ``warnings`` the
    lines that qualify it; ``indicators`` (vibration) or ``current_lines`` (motor current) describe the signal.
    ``set`` is the prediction set (the states the model cannot rule out, most probable first; :func:`record_set`),
    ``set_coverage`` its stated coverage, ``set_state`` the one state when the set has one, ``set_text`` the set in
    words; a model without a calibration leaves them None and says why in ``set_note``.
    """

    diagnosis: str | None = None
    novelty: dict | None = None
    probabilities: dict | None = None
    n_windows: int = 0
    window_length: int = 0
    unused_points: int | None = None
    fs: float | None = None
    training_fs: float | None = None
    metadata: dict = field(default_factory=dict)
    windows: list[dict] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    recognised: bool = False
    reason: str | None = None
    checks: dict = field(default_factory=dict)
    state: str | None = None
    model_recall: float | None = None
    operating_point: dict = field(default_factory=dict)
    indicators: dict | None = None
    indicators_source: dict | None = None
    current_lines: dict | None = None
    current_lines_error: str | None = None
    file: str | None = None
    channel: str | None = None
    model: str | None = None
    signal: str = "vibration"
    set: list[str] | None = None
    set_coverage: float | None = None
    set_coverage_per_state: dict | None = None
    set_state: str | None = None
    set_text: str | None = None
    set_note: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready values (``rvdiag diagnose --json``): the keys of the signal's kind only (indicators or current
        lines), ``model_recall`` only for a recognised record."""
        skip = {"current_lines", "current_lines_error"} if self.signal != "current" else \
            {"indicators", "indicators_source"}
        if not self.recognised:
            skip.add("model_recall")
        if self.unused_points is None:
            skip.add("unused_points")
        return {k: v for k, v in asdict(self).items() if k not in skip}

    def plot(self, ax=None):
        """Each window's probability of every class (matplotlib); returns the axes."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(6, 3))
        rows = [w for w in self.windows if "probabilities" in w]
        for c in (self.probabilities or {}):
            ax.plot([w["start"] / self.fs if self.fs else w["start"] for w in rows],
                    [w["probabilities"][c] for w in rows], "o-", label=c)
        ax.set_xlabel("window start (s)" if self.fs else "window start (points)")
        ax.set_ylabel("probability")
        ax.set_ylim(0, 1)
        ax.set_title(f"{self.file or 'record'}: " + (self.state or f"not recognised ({self.reason})"),
                     fontsize="small")
        if rows:
            ax.legend(fontsize="small")
        return ax


def is_current_model(model) -> bool:
    """Whether the model was trained on a motor-current store (card ``training_store.signal``)."""
    return (model.card.get("training_store") or {}).get("signal") == "current"


def file_indicators(sig, speed: dict) -> dict:
    """Gear condition indicators of the signal ``sig`` (:class:`rvdiag.io.readers.MeasuredSignal`) on the sun shaft,
    at the speed :func:`record_speed` found (none when it is unknown).

    Returns ``{"indicators": {name: value} or None, "indicators_source": {"shaft", "speed_source",
    "shaft_hz", "n_revolutions", "samples_per_rev"} or {"shaft", "error"}}``."""
    from rvdiag.errors import RvdiagError
    from rvdiag.features import orders as o
    from rvdiag.params import ReducerParams

    if speed.get("input_revs") is None:
        return {"indicators": None, "indicators_source": {"shaft": "sun", "error": speed.get("error")}}
    p = ReducerParams.default()
    try:
        revs = speed["input_revs"] * o.shaft_ratio("sun", p)
        res = o.analyse(np.asarray(sig.data, dtype=np.float64), float(sig.fs), revs, "sun", p)
    except RvdiagError as exc:
        return {"indicators": None, "indicators_source": {"shaft": "sun", "error": str(exc)}}
    return {"indicators": {k: float(v) for k, v in res["indicators"].items()},
            "indicators_source": {"shaft": "sun", "speed_source": speed["detail"], "shaft_hz": res["shaft_hz"],
                                  "n_revolutions": int(res["n_revolutions"]),
                                  "samples_per_rev": int(res["samples_per_rev"])}}


def read_model_record(model, path, *, channel: str | None = None, fs: float | None = None, **reading):
    """Read a record for ``model`` as its training store was read (:func:`rvdiag.workflows.read_record`;
    ``reading``: ``angle_channel``, ``tacho_channel``, ``ppr``, ``meta_regex``).  A motor-current model's channel is
    ``channel`` when given, else the channel the library was built from (e.g. ``i_a``) when the file has it by that
    exact name, else the file's only channel."""
    import re

    from rvdiag.io.readers import stated_channel
    from rvdiag.workflows.records import read_record

    trained_channel = (model.card.get("training_store") or {}).get("channel")
    if channel is not None or not is_current_model(model) or not isinstance(trained_channel, str):
        return read_record(path, channel=channel, fs=fs, **reading)
    stated = stated_channel(path, trained_channel)  # an rvdiag simulate .npz names its rows
    try:
        return read_record(path, channel=f"^{re.escape(stated or trained_channel)}$", fs=fs, **reading)
    except DataFileError:
        try:
            return read_record(path, channel=None, fs=fs, **reading)
        except DataFileError as exc:
            raise DataFileError(f"{exc}; the model was trained on the phase current {trained_channel!r}: "
                                f"pick the file's channel with --channel") from None


def file_current_lines(sig, meta: dict[str, float] | None = None) -> dict:
    """The motor-current line table of ``sig`` (:func:`rvdiag.motor.lines.current_lines`): ``{"current_lines":
    {...} or None, "current_lines_error": None or the reason}``.  The speed is ``--meta
    output_speed_deg_s=...`` (or ``input_speed_rpm=...``), else the strongest line taken as ``f_e``."""
    from rvdiag.errors import RvdiagError
    from rvdiag.motor.lines import current_lines
    from rvdiag.params import ReducerParams

    meta = meta or {}
    params = ReducerParams.default()
    speed = meta.get(SPEED_META[0])
    if speed is None and meta.get(SPEED_META[1]) is not None:
        speed = float(meta[SPEED_META[1]]) / 60.0 / params.ratio * 360.0
    try:
        table = current_lines(np.asarray(sig.data, dtype=np.float64), sig.fs, params, output_speed_deg_s=speed)
    except RvdiagError as exc:
        return {"current_lines": None, "current_lines_error": str(exc)}
    if speed is not None:
        table["speed_source"] = "--meta " + (SPEED_META[0] if meta.get(SPEED_META[0]) is not None else SPEED_META[1])
    return {"current_lines": table, "current_lines_error": None}


def diagnose_signal(loaded, x: np.ndarray, fs: float | None, meta: dict[str, float] | None = None) -> dict:
    """Window ``x`` to the model input, predict each window; returns the result dict of ``--json``.

    ``meta``: the value of each metadata column the model reads (:attr:`LoadedModel.metadata_columns`),
    the same for every window.
    """
    from rvdiag.models.conditions import fs_ratio

    L = loaded.input_length
    n = int(x.size)
    warnings = []
    if n < L:
        raise DataFileError(f"the signal has {n} points, shorter than one window of {L} points (the model's "
                            f"input length); give a longer recording")
    train_fs = loaded.fs
    ratio = fs_ratio(fs, train_fs) if train_fs and fs else None
    if train_fs and fs is None:
        warnings.append(f"warning: the file states no sampling rate; the model was trained at {train_fs:g} Hz "
                        "(give --fs to check)")
    elif ratio is not None:
        warnings.append(f"warning: the signal is sampled at {fs:g} Hz but the model was trained at {train_fs:g} Hz; "
                        f"frequencies are off by a factor {ratio:.4g}: resample first for a trustworthy diagnosis")
    k = n // L
    rest = n - k * L  # the tail shorter than a window: routine (a 1 s record at 48 kHz is 11.7 windows), no warning
    X = x[: k * L].reshape(k, L)
    columns = {c: np.full(k, v, dtype=np.float64) for c, v in (meta or {}).items()}
    X = loaded.inputs(X, columns, where="the signal (give the value with --meta NAME=VALUE)")
    P = np.asarray(loaded.estimator.predict_proba(X), dtype=float)
    classes = [str(c) for c in loaded.estimator.classes_]
    overall = P.mean(axis=0)
    ood = None
    if loaded.novelty is not None:
        from rvdiag.models.novelty import learned_features

        d = loaded.novelty.distances(learned_features(loaded.estimator, X))
        ood = {"distances": [float(v) for v in d], "threshold": loaded.novelty.threshold,
               "share_beyond": float(np.mean(d > loaded.novelty.threshold)), "rate": loaded.novelty.rate}
    return {
        "diagnosis": classes[int(overall.argmax())],
        "novelty": ood,
        "probabilities": {c: float(p) for c, p in zip(classes, overall)},
        "n_windows": k,
        "window_length": L,
        "unused_points": rest,
        "fs": fs,
        "training_fs": train_fs,
        "metadata": {c: float(v) for c, v in (meta or {}).items() if c in loaded.metadata_columns},
        "windows": [{"start": i * L, "prediction": classes[int(P[i].argmax())],
                     "probabilities": {c: float(p) for c, p in zip(classes, P[i])}} for i in range(k)],
        "warnings": warnings,
    }


def trust_warnings(loaded, res: dict, speed: dict, load: float | None, fs: float | None, x: np.ndarray) -> list[str]:
    """The warnings that qualify an answer: the OOD check unavailable (an older model), the operating point or the
    level outside the training range, the answer a class the model confuses, an unsure answer (its mean
    probability below one half; :mod:`rvdiag.models.conditions`)."""
    from rvdiag.models.conditions import (answer_warnings, class_limits, condition_warnings, record_warnings,
                                          signal_rms)

    out = []
    if loaded.novelty is None:
        out.append("warning: this model was trained before rvdiag stored an out-of-distribution check: it cannot "
                   "tell a record unlike its training data (retrain it to get one)")
    conditions = {"output_speed_deg_s": speed.get("output_speed_deg_s") if speed.get("stated") else None,
                  "load_Nm": load}
    out += condition_warnings(loaded.card.get("operating_range"), conditions=conditions, fs=fs,
                              level_rms=float(signal_rms(x[None, :])[0]))
    if res.get("diagnosis") is not None:
        out += answer_warnings(class_limits(loaded.card.get("metrics")), res["diagnosis"], state_name)
        out += record_warnings(res.get("probabilities"), [w["prediction"] for w in res["windows"]], state_name)
    return out


def record_set(loaded, res: dict) -> dict:
    """The prediction set of the record (:mod:`rvdiag.models.conformal`, applied to the windows' mean probability,
    as the diagnosis is) and of each window (``windows[i]["set"]``): ``set`` (the states, most probable first),
    ``set_coverage`` (the smallest stated coverage of the model's states: the set holds the true state at least this
    often, whatever it is), ``set_coverage_per_state``, ``set_state`` (the one state when the set has one, else
    None), ``set_text`` (in words); or those None and ``set_note`` (no calibration, or a record not recognised)."""
    from rvdiag.models import conformal

    ps = conformal.from_card(loaded.card)
    empty = {"set": None, "set_coverage": None, "set_coverage_per_state": None, "set_state": None,
             "set_text": None}
    if ps is None:
        note = (f"no prediction set: {loaded.card['prediction_sets_note']}" if loaded.card.get("prediction_sets_note")
                else conformal.NOT_CALIBRATED)
        return {**empty, "set_note": note}
    if res.get("probabilities") is None:
        return {**empty, "set_note": "no prediction set: the record is not recognised"}
    states = ps.prediction_set([res["probabilities"][c] for c in ps.classes])[0]
    cover = min(ps.coverage.values())
    for w in res["windows"]:
        w["set"] = ps.prediction_set([w["probabilities"][c] for c in ps.classes])[0]
    return {"set": states, "set_coverage": cover, "set_coverage_per_state": dict(ps.coverage),
            "set_state": states[0] if len(states) == 1 else None,
            "set_text": conformal.describe_set(states, cover, lambda c: fault_name(c) or c), "set_note": None}


def build_diagnosis(loaded, sig, values: dict, *, is_current: bool, output_speed: float | None = None,
                    load: float | None = None) -> dict:
    """The whole answer of ``rvdiag diagnose`` for one record (the dict of ``--json``), apart from its printing:
    the windows' probabilities (:func:`diagnose_signal`), the speed (:func:`record_speed`), whether the record is
    recognised (:func:`recognition`; when not, no state is named: ``diagnosis`` None and no probabilities), the
    model's held-out recall of the answer, the warnings that qualify it, and the indicators or current lines."""
    from rvdiag.models.conditions import class_limits

    x = np.asarray(sig.data, dtype=np.float64)
    if x.size < loaded.input_length:
        raise DataFileError(f"the signal has {x.size} points, shorter than one window of {loaded.input_length} "
                            "points (the model's input length); give a longer recording")
    if output_speed is not None:
        values = {**values, SPEED_META[0]: float(output_speed)}
    flat = flat_reason(x, loaded.input_length)
    if flat is None:
        res = diagnose_signal(loaded, x, sig.fs, values)
    else:  # a constant window has no z-score: nothing to classify
        res = {"diagnosis": None, "novelty": None, "n_windows": x.size // loaded.input_length,
               "window_length": loaded.input_length, "fs": sig.fs, "training_fs": loaded.fs, "metadata": {},
               "windows": [], "warnings": []}
    speed = record_speed(sig, values) if not is_current else {"output_speed_deg_s": values.get(SPEED_META[0]),
                                                              "stated": values.get(SPEED_META[0]) is not None}
    if output_speed is not None and speed.get("detail"):
        speed["detail"] = f"--output-speed {output_speed:g}"
    rec = recognition(loaded, x, sig.fs, res, speed, is_current)
    res.update({"recognised": rec["recognised"], "reason": rec["reason"], "checks": rec["checks"]})
    if not rec["recognised"]:
        res.update({"diagnosis": None, "state": None, "probabilities": None,
                    "windows": [{"start": w["start"]} for w in res["windows"]]})
    else:
        res["state"] = state_name(res["diagnosis"])
        res["model_recall"] = class_limits(loaded.card.get("metrics")).get("recall", {}).get(res["diagnosis"])
    res.update(record_set(loaded, res))
    res["operating_point"] = {"output_speed_deg_s": speed.get("output_speed_deg_s"),
                              "speed_source": speed.get("detail") or speed.get("error"), "load_Nm": load}
    res["warnings"] += trust_warnings(loaded, res, speed, load, sig.fs, x)
    if is_current:
        res.update(file_current_lines(sig, values))
        if res["current_lines"] is None:
            res["warnings"].append(f"warning: no current line table: {res['current_lines_error']}")
    else:
        res.update(file_indicators(sig, speed))
        if res["indicators"] is None:
            res["warnings"].append(f"warning: no gear condition indicators: {res['indicators_source']['error']}")
    return res


def model_metadata(model, sig, given: dict[str, float] | None = None) -> dict[str, float]:
    """The values of the metadata columns the model reads per window (card ``metadata_columns``) for one record:
    ``given`` (``--meta NAME=VALUE``), else the file's scalar that the training store read into the column (card
    ``metadata_sources``); ``given`` is returned with them."""
    given = dict(given or {})
    sources = model.card.get("metadata_sources") or {}
    for column in model.metadata_columns:
        if column not in given and column in sources:
            try:
                given[column] = float(sig.scalar(sources[column]))
            except DataFileError as exc:
                raise DataFileError(f"the model reads {column!r} per window from the file's scalar "
                                    f"{sources[column]!r}: {exc}; pass --meta {column}=VALUE") from None
    missing = [c for c in model.metadata_columns if c not in given]
    if missing:
        raise ParameterError(f"the model reads metadata {missing} per window, which {sig.path} does not give: "
                             f"pass --meta {missing[0]}=VALUE (e.g. the shaft speed in rev/min)")
    return given


def diagnose(model, record, *, output_speed: float | None = None, load: float | None = None,
             metadata: dict[str, float] | None = None) -> Diagnosis:
    """Diagnose one record with a classifier (module docstring).

    Parameters
    ----------
    model : the loaded model (:func:`rvdiag.workflows.load_model`), loaded once
    record : the record (:func:`read_model_record` or :func:`rvdiag.workflows.read_record`)
    output_speed : the output speed in deg/s (None: stated by ``metadata``, the record's angle source or name, the
        simulated record, or the confirmed mesh peak; :func:`rvdiag.workflows.records.record_speed`)
    load : the output torque in N m (None: the record's ``metadata["load_Nm"]``), for the operating-range check
    metadata : values of the model's metadata columns and ``output_speed_deg_s``/``input_speed_rpm``
        (``--meta NAME=VALUE``); the file's scalars fill the rest (:func:`model_metadata`)

    Returns
    -------
    Diagnosis
    """
    rec_meta = {k: v for k, v in (getattr(record, "metadata", None) or {}).items()
                if isinstance(v, (int, float)) and not isinstance(v, bool)}
    values = model_metadata(model, record, metadata)
    if load is None:
        load = rec_meta.get("load_Nm")
    current = is_current_model(model)
    res = build_diagnosis(model, record, values, is_current=current, output_speed=output_speed, load=load)
    res.update({"file": None if getattr(record, "path", None) is None else str(record.path),
                "channel": getattr(record, "channel", None), "model": str(model.path),
                "signal": "current" if current else "vibration"})
    return Diagnosis(**res)


__all__ = ["Diagnosis", "build_diagnosis", "diagnose", "diagnose_signal", "file_current_lines", "file_indicators",
           "is_current_model", "model_metadata", "read_model_record", "record_set", "trust_warnings"]
