"""``rvdiag diagnose MODEL_DIR FILE [--channel C] [--fs HZ] [--json]``: diagnose a measured or simulated signal.

The signal (one channel, read by :func:`rvdiag.io.read_signal`) is cut into adjacent, non-overlapping
windows of the model's input length (the training samples' length); the tail shorter than a window is
not used (a warning says how many points).  Each window gets class probabilities; the overall
probabilities are their mean, and the diagnosis is the most probable class overall.  A WARNING is
printed when the file's sampling rate differs from the training rate, or is unknown.

A model that reads per-sample metadata (card ``metadata_columns``, e.g. the shaft speed ``rpm`` of
bearing-envelope features) gets it from ``--meta NAME=VALUE``, else from the file's scalar that the training
store read into that column (card ``metadata_sources``, e.g. CWRU's ``X105RPM`` for ``--scalar rpm=RPM``).

It also gives the gear condition indicators of the whole signal on the sun shaft (relative to the carrier;
:func:`file_indicators`, docs/orders.md): the nine of :data:`rvdiag.features.orders.INDICATORS` of the TSA
over all its whole revolutions, in a table and in ``--json`` under ``indicators`` (with ``indicators_source``:
the shaft, where the speed came from, the shaft frequency and the revolutions averaged).  The speed is the
first of ``--meta output_speed_deg_s=...`` (or ``input_speed_rpm=...``), the speed a simulated record states,
and the stage-1 mesh peak of the spectrum, as ``rvdiag orders``; indicators that cannot be computed (no
sampling rate, less than one revolution) leave ``indicators`` null and a WARNING, never a failed diagnosis.

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
from rvdiag.errors import DataFileError, ParameterError

MAX_ROWS = 40
#: ``--meta`` names that give the speed for the indicators: output deg/s, input rev/min.
SPEED_META = ("output_speed_deg_s", "input_speed_rpm")


def file_indicators(sig, meta: dict[str, float] | None = None) -> dict:
    """Gear condition indicators of the signal ``sig`` (:class:`rvdiag.io.readers.MeasuredSignal`) on the sun shaft.

    Returns ``{"indicators": {name: value} or None, "indicators_source": {"shaft", "speed_source",
    "shaft_hz", "n_revolutions", "samples_per_rev"} or {"shaft", "error"}}``."""
    from rvdiag.cli.orders import _angle
    from rvdiag.errors import RvdiagError
    from rvdiag.features import orders as o
    from rvdiag.params import ReducerParams

    meta = meta or {}
    out_speed, in_speed = meta.get(SPEED_META[0]), meta.get(SPEED_META[1])
    if out_speed is not None and in_speed is not None:
        in_speed = None  # the output speed is the one a library records
    try:
        if not sig.fs:
            raise ParameterError("the file states no sampling rate: give --fs")
        p = ReducerParams.default()
        revs, _, what = _angle(sig, "sun", p, output_speed=out_speed, input_speed=in_speed, rpm=None,
                               tacho_channel=None, ppr=None, angle_channel=None, meta_regex=None, speed_range=None,
                               fs=sig.fs)
        if out_speed is not None or in_speed is not None:
            what = f"--meta {SPEED_META[0] if out_speed is not None else SPEED_META[1]}=" \
                   f"{out_speed if out_speed is not None else in_speed:g}"
        res = o.analyse(np.asarray(sig.data, dtype=np.float64), float(sig.fs), revs, "sun", p)
    except RvdiagError as exc:
        return {"indicators": None, "indicators_source": {"shaft": "sun", "error": str(exc)}}
    return {"indicators": {k: float(v) for k, v in res["indicators"].items()},
            "indicators_source": {"shaft": "sun", "speed_source": what, "shaft_hz": res["shaft_hz"],
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
    L = loaded.input_length
    n = int(x.size)
    warnings = []
    if n < L:
        raise DataFileError(f"the signal has {n} points, shorter than one window of {L} points (the model's "
                            f"input length); give a longer recording")
    train_fs = loaded.fs
    if train_fs and fs is None:
        warnings.append(f"WARNING: the file states no sampling rate; the model was trained at {train_fs:g} Hz "
                        "(give --fs to check)")
    elif train_fs and fs and abs(fs - train_fs) > 1e-6 * train_fs:
        warnings.append(f"WARNING: the signal is sampled at {fs:g} Hz but the model was trained at {train_fs:g} Hz; "
                        "frequencies are off by a factor {:.3g}: resample first for a trustworthy diagnosis".format(fs / train_fs))
    k = n // L
    rest = n - k * L
    if rest:
        warnings.append(f"WARNING: {n} points is not a multiple of the model's {L}-point window: "
                        f"the last {rest} points are not used")
    X = x[: k * L].reshape(k, L)
    columns = {c: np.full(k, v, dtype=np.float64) for c, v in (meta or {}).items()}
    X = loaded.inputs(X, columns, where="the signal (give the value with --meta NAME=VALUE)")
    P = np.asarray(loaded.estimator.predict_proba(X), dtype=float)
    classes = [str(c) for c in loaded.estimator.classes_]
    overall = P.mean(axis=0)
    return {
        "diagnosis": classes[int(overall.argmax())],
        "probabilities": {c: float(p) for c, p in zip(classes, overall)},
        "n_windows": k,
        "window_length": L,
        "fs": fs,
        "training_fs": train_fs,
        "metadata": {c: float(v) for c, v in (meta or {}).items() if c in loaded.metadata_columns},
        "windows": [{"start": i * L, "prediction": classes[int(P[i].argmax())],
                     "probabilities": {c: float(p) for c, p in zip(classes, P[i])}} for i in range(k)],
        "warnings": warnings,
    }


def register(app: typer.Typer) -> None:
    @app.command("diagnose")
    def diagnose(
        model_dir: Path = typer.Argument(..., help="Model directory written by 'rvdiag train'."),
        file: Path = typer.Argument(..., help="Signal file: CSV/CSV.gz, MAT, NPY, NPZ, WAV, TDMS."),
        channel: str = opt.channel(),
        fs: float = opt.fs("Sampling rate in Hz (overrides the file's)."),
        json_out: bool = opt.json_flag("Print the result as JSON."),
        meta: List[str] = typer.Option([], "--meta",
                                       help="NAME=VALUE: a metadata value the model reads, e.g. rpm=1797 (default: "
                                            "the file's scalar the training store read, e.g. X105RPM)."),
    ) -> None:
        """Diagnose the state of a reducer from one signal file."""
        from rvdiag.io import read_signal
        from rvdiag.models.persistence import load_model

        loaded = load_model(model_dir)
        trained = loaded.card.get("training_store") or {}
        is_current = trained.get("signal") == "current"
        sig = _read_trained_channel(file, channel, fs, trained.get("channel")) if is_current \
            else read_signal(file, channel_regex=channel, fs=fs)
        values = _metadata_values(loaded, sig, meta)
        res = diagnose_signal(loaded, np.asarray(sig.data, dtype=np.float64), sig.fs, values)
        res.update({"file": str(file), "channel": sig.channel, "model": str(model_dir),
                    "signal": "current" if is_current else "vibration"})
        if is_current:
            res.update(file_current_lines(sig, values))
            if res["current_lines"] is None:
                res["warnings"].append(f"WARNING: no current line table: {res['current_lines_error']}")
        else:
            res.update(file_indicators(sig, values))
            if res["indicators"] is None:
                res["warnings"].append(f"WARNING: no gear condition indicators: {res['indicators_source']['error']}")
        for w in res["warnings"]:
            typer.echo(w, err=True)
        if json_out:
            typer.echo(json.dumps(res, indent=2))
            return
        _print(res)


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
    con.print(f"diagnosis: [bold]{res['diagnosis']}[/bold] (mean probability {p:.3f} over {res['n_windows']} windows)")
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
