"""``rvdiag diagnose MODEL_DIR FILE [--channel C] [--fs HZ] [--json]``: diagnose a measured or simulated signal.

The signal (one channel, read by :func:`rvdiag.io.read_signal`) is cut into adjacent, non-overlapping
windows of the model's input length (the training samples' length); the tail shorter than a window is
not used (``--json``: ``unused_points``).  Each window gets class probabilities; the overall
probabilities are their mean, and the diagnosis is the most probable class overall.  A ``warning:`` line is
printed when the file's sampling rate differs from the training rate by more than 0.1 %
(:data:`rvdiag.models.conditions.FS_RTOL`), or is unknown.

A model that reads per-sample metadata (card ``metadata_columns``, e.g. the shaft speed ``rpm`` of
bearing-envelope features) gets it from ``--meta NAME=VALUE``, else from the file's scalar that the training
store read into that column (card ``metadata_sources``, e.g. CWRU's ``X105RPM`` for ``--scalar rpm=RPM``).

It also gives the gear condition indicators of the whole signal on the sun shaft (relative to the carrier;
:func:`file_indicators`, docs/orders.md): the nine of :data:`rvdiag.features.orders.INDICATORS` of the TSA
over all its whole revolutions, in a table and in ``--json`` under ``indicators`` (with ``indicators_source``:
the shaft, where the speed came from, the shaft frequency and the revolutions averaged).  The speed is the
first of ``--meta output_speed_deg_s=...`` (or ``input_speed_rpm=...``), the speed a simulated record states,
and the stage-1 mesh peak of the spectrum, as ``rvdiag orders``; indicators that cannot be computed (no
sampling rate, less than one revolution) leave ``indicators`` null and a ``warning:``, never a failed diagnosis.

A model trained on a motor-current library (card ``training_store.signal == "current"``) reads the library's
channel (e.g. ``i_a``) when the file has one of that name and ``--channel`` is not given, and shows the
motor-current line table instead of the indicators (:func:`rvdiag.motor.lines.current_lines`: ``f_e``, ``f_e +- k
f1``, ``|f_e +- f_sp|``, ``|f_e +- f_cs|``, ``5 f_e``; ``--json`` key ``current_lines``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import List

import numpy as np
import typer

from rvdiag.cli import _options as opt
from rvdiag.cli._record import (SPEED_META, fault_name, flat_reason, not_recognised_line,  # noqa: F401
                                 recognition, record_speed, state_name)
from rvdiag.errors import DataFileError, ParameterError

MAX_ROWS = 40
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


def _read_trained_channel(file: Path, channel: str | None, fs: float | None, trained_channel):
    """A motor-current model's channel of ``file``: ``--channel`` when given, else the channel the library was
    built from (e.g. ``i_a``) when the file has it by that exact name, else the file's only channel."""
    import re

    from rvdiag.io import read_signal
    from rvdiag.io.readers import stated_channel

    if channel is not None or not isinstance(trained_channel, str):
        return read_signal(file, channel_regex=channel, fs=fs)
    stated = stated_channel(file, trained_channel)  # an rvdiag simulate .npz names its rows
    try:
        return read_signal(file, channel_regex=f"^{re.escape(stated or trained_channel)}$", fs=fs)
    except DataFileError:
        try:
            return read_signal(file, channel_regex=None, fs=fs)
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
    as the diagnosis is) and of each window: ``set`` (the states, most probable first), ``set_coverage`` (the
    smallest stated coverage of the model's states: the set holds the true state at least this often, whatever it
    is), ``set_coverage_per_state``, ``set_state`` (the one state when the set has one, else None), ``set_text``
    (in words); or None and ``set_note`` (no calibration, or a record not recognised)."""
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
    name = (lambda c: fault_name(c) or c)
    return {"set": states, "set_coverage": cover, "set_coverage_per_state": dict(ps.coverage),
            "set_state": states[0] if len(states) == 1 else None,
            "set_text": conformal.describe_set(states, cover, name), "set_note": None}


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


def register(app: typer.Typer) -> None:
    @app.command("diagnose")
    def diagnose(
        model_dir: Path = typer.Argument(..., help="Model directory written by 'rvdiag train'."),
        file: Path = typer.Argument(..., help="Signal file: CSV/CSV.gz, MAT, NPY, NPZ, WAV, TDMS."),
        channel: str = opt.channel(),
        fs: float = opt.fs("Sampling rate in Hz (overrides the file's)."),
        json_out: bool = opt.json_flag("Print the result as JSON."),
        output_speed: float = opt.output_speed(),
        load: float = opt.load(),
        meta: List[str] = typer.Option([], "--meta",
                                       help="NAME=VALUE: a metadata value the model reads, e.g. rpm=1797 (default: "
                                            "the file's scalar the training store read, e.g. X105RPM)."),
        baseline: Path = typer.Option(None, "--baseline", metavar="BASE.zarr",
                                      help="A baseline-referenced model: a healthy store of the same machine "
                                           "(docs/monitoring.md)."),
    ) -> None:
        """Diagnose the state of a reducer from one signal file."""
        from rvdiag.io import read_signal
        from rvdiag.models.persistence import load_model

        loaded = load_model(model_dir)
        if _monitor(loaded, file, channel, fs, baseline, meta, output_speed, load, json_out):
            return
        trained = loaded.card.get("training_store") or {}
        is_current = trained.get("signal") == "current"
        sig = _read_trained_channel(file, channel, fs, trained.get("channel")) if is_current \
            else read_signal(file, channel_regex=channel, fs=fs)
        values = _metadata_values(loaded, sig, meta)
        res = build_diagnosis(loaded, sig, values, is_current=is_current, output_speed=output_speed, load=load)
        res.update({"file": str(file), "channel": sig.channel, "model": str(model_dir),
                    "signal": "current" if is_current else "vibration"})
        for w in res["warnings"]:
            typer.echo(w, err=True)
        if json_out:
            typer.echo(json.dumps(res, indent=2))
            return
        _print(res)


def _monitor(loaded, file, channel, fs, baseline, meta, output_speed, load, json_out) -> bool:
    """Diagnose with a baseline-referenced model (:mod:`rvdiag.cli._baseline`) and say True; False otherwise."""
    from rvdiag.cli import _baseline
    from rvdiag.io import read_signal

    if not _baseline.needs_baseline(loaded):
        if baseline is not None:
            raise ParameterError(f"--baseline applies to a baseline-referenced model; {loaded.path} is not one")
        return False
    sig = read_signal(file, channel_regex=channel, fs=fs)
    from types import SimpleNamespace

    given = _metadata_values(SimpleNamespace(card={}, metadata_columns=[]), sig, meta)  # --meta NAME=VALUE only
    res = _baseline.diagnose_monitor(loaded, sig, baseline, given,
                                     output_speed=output_speed, load=load)
    res.update({"file": str(file), "channel": sig.channel, "model": str(loaded.path)})
    for w in res["warnings"]:
        typer.echo(w, err=True)
    if json_out:
        typer.echo(json.dumps(res, indent=2))
    else:
        _baseline.print_diagnosis(res)
    return True


def _metadata_values(loaded, sig, items: list[str]) -> dict[str, float]:
    """The model's metadata for one file: ``--meta NAME=VALUE``, else the file's scalar named in the card."""
    import math

    given: dict[str, float] = {}
    for item in items:
        name, sep, text = item.partition("=")
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not sep or not name.strip() or not math.isfinite(value):
            raise ParameterError(f"--meta {item!r}: expected NAME=NUMBER, e.g. rpm=1797")
        given[name.strip()] = value
    sources = loaded.card.get("metadata_sources") or {}
    for column in loaded.metadata_columns:
        if column not in given and column in sources:
            try:
                given[column] = float(sig.scalar(sources[column]))
            except DataFileError as exc:
                raise DataFileError(f"the model reads {column!r} per window from the file's scalar "
                                    f"{sources[column]!r}: {exc}; pass --meta {column}=VALUE") from None
    missing = [c for c in loaded.metadata_columns if c not in given]
    if missing:
        raise ParameterError(f"the model reads metadata {missing} per window, which {sig.path} does not give: "
                             f"pass --meta {missing[0]}=VALUE (e.g. the shaft speed in rev/min)")
    return given


def _print(res: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    con = Console()
    if not res["recognised"]:
        con.print(not_recognised_line(res), soft_wrap=True)
        return
    classes = list(res["probabilities"])
    t = Table(title=f"{res['file']} [{res['channel']}]: {res['n_windows']} window(s) of {res['window_length']} points")
    t.add_column("window")
    t.add_column("start", justify="right")
    t.add_column("diagnosis")
    for c in classes:
        t.add_column(c, justify="right")
    rows = res["windows"]
    for i, w in enumerate(rows[:MAX_ROWS]):
        t.add_row(str(i), str(w["start"]), w["prediction"], *(f"{w['probabilities'][c]:.3f}" for c in classes))
    if len(rows) > MAX_ROWS:
        t.add_row("...", f"{len(rows) - MAX_ROWS} more (see --json)", "", *([""] * len(classes)))
    t.add_row("overall", "", res["diagnosis"], *(f"{res['probabilities'][c]:.3f}" for c in classes), style="bold")
    con.print(t)
    p = res["probabilities"][res["diagnosis"]]
    recall = res.get("model_recall")
    con.print(f"diagnosis: [bold]{res['state']}[/bold] (mean probability {p:.3f} over {res['n_windows']} windows"
              + ("" if recall is None else f"; the model recognises {100 * recall:.0f} % of its held-out "
                                           f"{res['diagnosis']} samples") + ")", soft_wrap=True)
    con.print(f"prediction set: [bold]{res['set_text']}[/bold]" if res.get("set_text") else res.get("set_note"),
              soft_wrap=True)
    if res.get("current_lines"):
        cl = res["current_lines"]
        lt = Table(title=f"motor-current lines (output speed {cl['output_speed_deg_s']:.4g} deg/s from "
                         f"{cl['speed_source']}; height over the median of the bins 6-40 away)")
        for col in ("line", "Hz", "amplitude", "height (dB)"):
            lt.add_column(col, justify="left" if col == "line" else "right")
        for name, ln in cl["lines"].items():
            if ln["amplitude"] is None:
                lt.add_row(name, f"{ln['hz']:.2f}", "beyond the spectrum", "")
            else:
                lt.add_row(name, f"{ln['hz']:.2f}", f"{ln['amplitude']:.4g}", f"{ln['height_db']:.1f}")
        con.print(lt)
    if res.get("indicators"):
        src = res["indicators_source"]
        it = Table(title=f"gear condition indicators, {src['shaft']} shaft ({src['shaft_hz']:.4g} Hz from "
                         f"{src['speed_source']}; TSA of {src['n_revolutions']} revolutions)")
        it.add_column("indicator")
        it.add_column("value", justify="right")
        for k, v in res["indicators"].items():
            it.add_row(k, f"{v:.4g}")
        con.print(it)
