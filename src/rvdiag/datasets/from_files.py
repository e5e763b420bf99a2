"""Build a measured-data sample store from a folder of files (``rvdiag dataset from-files``).

Each file of the folder whose name matches ``label_regex`` (and ``include``, when given) is read with
:func:`rvdiag.io.read_signal`, cut into windows with :func:`rvdiag.io.window`, and its windows become
samples labelled by the regex's named group ``label``.  The result is a store of the same layout as a
simulated library (:mod:`rvdiag.datasets.store`, ``kind="measured"``), so ``train``, ``evaluate`` and
``diagnose`` read both.

Metadata columns of every sample:

``split``    ``train`` (all samples), unless ``test_fraction`` asks for a seeded split stratified by label: by
             file (``split_by="unit"``, the default: every window of a file lands on the same side) or, with
             a :class:`SplitLeakWarning`, by window (``split_by="window"``: neighbouring, possibly overlapping
             windows of one recording land on both sides, so the test score is optimistic);
             or ``test_include`` / ``test_block`` name the test windows (:func:`split_by_name`)
``unit``     index of the source file (sorted by name)
``source``   the source file name
``channel``  the channel read
``start``    the window's first sample index in the source signal
``<group>``  every named group of ``meta_regex`` (and of ``label_regex`` other than ``label``): numbers when
             every file's value parses as a number (int, else float), text otherwise; an optional group
             that did not take part in a file's match gives "" (so the column is text)
``<name>``   every ``scalars`` entry: the value of the file's one scalar matching the given regex
             (e.g. ``rpm`` from CWRU's ``X105RPM``)

With an angle source (``angle``, an :class:`rvdiag.io.angles.AngleSpec`: an angle or angle-counter channel, a
tachometer channel with its pulses per revolution, groups ``rpm`` / ``speed_dps`` of ``meta_regex``, the angles a
record of ``rvdiag simulate`` stores, or the stage-1 mesh-peak estimate; :func:`rvdiag.io.angles.input_revolutions`),
each window also gets

``input_speed_rpm``     the input (sun) shaft's mean speed over the window, rev/min
``output_speed_deg_s``  the same as the output (carrier) speed of the reducer ``params``, deg/s (the speed column
                        ``rvdiag train --features tsa-ci`` reads by default)
``input_rev_start``     the input shaft's revolutions at the window's first sample, from the file's first sample
``angle_source``        where the angle came from (:data:`rvdiag.io.angles.ANGLE_SOURCES`)

Bad angle data in any file (an angle that turns back, missing tachometer pulses, a speed out of the plausible
range) raise one ParameterError line naming the file, and nothing is written.

The store is written in one go into a temporary folder and renamed into place
(:func:`rvdiag.datasets.store.write_store`): a failure at any file leaves nothing behind.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from rvdiag.datasets.store import write_store
from rvdiag.errors import DataFileError, ParameterError, SplitLeakWarning, StoreError
from rvdiag.io import SUPPORTED_SUFFIXES, read_signal, window, window_starts

#: The ways ``build_from_files`` can split (``--split-by``): by file (the default) or by window.
SPLIT_BY = ("unit", "window")


@dataclass
class FileEntry:
    """One selected file: its path, class label and metadata parsed from its name."""

    path: Path
    label: str
    meta: dict[str, str]


def _compile(regex: str | None, what: str) -> re.Pattern | None:
    if regex is None:
        return None
    try:
        return re.compile(regex)
    except re.error as exc:
        raise ParameterError(f"invalid {what} {regex!r}: {exc}") from None


def select_files(
    folder: str | Path,
    label_regex: str,
    meta_regex: str | None = None,
    include: str | None = None,
) -> tuple[list[FileEntry], list[str]]:
    """The files of ``folder`` that make the dataset, and the names skipped.

    A file is used when its name matches ``include`` (if given; ``re.search``) and ``label_regex``
    (``re.search``, must have a named group ``label``).  Hidden files and sub-folders are ignored; other
    names that do not match are returned as skipped.  ``meta_regex`` must match every used file.

    Raises
    ------
    ParameterError
        A regex is invalid or ``label_regex`` lacks the group ``label``.
    DataFileError
        The folder is missing, no file is selected, or a selected file does not match ``meta_regex``.
    """
    folder = Path(folder)
    lab = _compile(label_regex, "--label-regex")
    if lab is None or "label" not in lab.groupindex:
        raise ParameterError(f"--label-regex {label_regex!r} needs a named group (?P<label>...)")
    meta = _compile(meta_regex, "--meta-regex")
    if meta is not None and not meta.groupindex:
        raise ParameterError(f"--meta-regex {meta_regex!r} has no named group (?P<name>...)")
    inc = _compile(include, "--include")
    if not folder.is_dir():
        raise DataFileError(f"{folder}: no such folder")
    entries: list[FileEntry] = []
    skipped: list[str] = []
    for p in sorted(folder.iterdir(), key=lambda q: q.name):
        name = p.name
        if name.startswith(".") or not p.is_file():
            continue
        if inc is not None and not inc.search(name):
            continue
        m = lab.search(name)
        if m is None or not m.group("label"):
            skipped.append(name)
            continue
        values = {k: ("" if v is None else v) for k, v in m.groupdict().items() if k != "label"}
        if meta is not None:
            mm = meta.search(name)
            if mm is None:
                raise DataFileError(f"{p}: the name does not match --meta-regex {meta_regex!r}")
            values.update({k: ("" if v is None else v) for k, v in mm.groupdict().items()})
        entries.append(FileEntry(path=p, label=m.group("label"), meta=values))
    if not entries:
        what = f"match --label-regex {label_regex!r}" + (f" and --include {include!r}" if include else "")
        raise DataFileError(f"{folder}: no file name {what} ({len(skipped)} other file(s))")
    return entries, skipped


def _typed_column(values: list[str]) -> np.ndarray:
    """Strings -> int64 if all parse as ints, float64 if all parse as floats, else str objects."""
    try:
        return np.asarray([int(v) for v in values], dtype=np.int64)
    except ValueError:
        pass
    try:
        col = np.asarray([float(v) for v in values], dtype=np.float64)
        if np.all(np.isfinite(col)):
            return col
    except ValueError:
        pass
    return np.asarray(values, dtype=object)


def build_from_files(
    folder: str | Path,
    out: str | Path,
    *,
    label_regex: str,
    channel: str | None,
    window_length: int,
    hop: int | None = None,
    fs: float | None = None,
    meta_regex: str | None = None,
    include: str | None = None,
    test_fraction: float | None = None,
    seed: int = 0,
    split_by: str = "unit",
    scalars: Mapping[str, str] | None = None,
    overwrite: bool = False,
    unknown_fs: bool = False,
    progress: Callable[[int, int, str], None] | None = None,
    test_include: str | None = None,
    test_block: str | None = None,
    angle: Any = None,
    params: Any = None,
) -> dict[str, Any]:
    """Read, window and label every selected file of ``folder``; write the store ``out``.

    Parameters
    ----------
    folder, label_regex, meta_regex, include
        See :func:`select_files`.
    channel : str or None
        Channel regex (:func:`rvdiag.io.read_signal`); None when each file holds one channel.
    window_length, hop : int
        Window length and step in samples (hop defaults to the window length: no overlap).
    fs : float, optional
        Sampling rate in Hz, for files that do not state it (and overriding those that do).  Every file
        must end up with the same fs; a file that states none needs ``fs`` (DataFileError otherwise) unless
        ``unknown_fs``.
    unknown_fs : bool
        The files' rate is not known (e.g. the SpectraQuest gearbox set): store the windows without one.
    test_fraction : float in (0, 1), optional
        Fraction of each class put in split ``test`` (seeded by ``seed``): of its files, or of its windows.
    split_by : ``"unit"`` (default) or ``"window"``
        ``"unit"``: whole files go to ``test`` (``round(test_fraction * files of the class)``, at least one, and
        at least one file stays in ``train``; a class needs two files).  ``"window"``: windows are drawn
        one by one, which leaks (neighbouring windows of one recording on both sides) and warns.
    scalars : mapping name -> regex, optional
        Scalars of each file to record as metadata columns (e.g. ``{"rpm": "RPM"}``).
    test_include, test_block : str, optional
        A split chosen by the user instead of ``test_fraction`` (:func:`split_by_name`).
    overwrite : bool
        Replace an existing store at ``out``.
    progress : callable(done, total, file name), optional
    angle : rvdiag.io.angles.AngleSpec, optional
        Where each file's input-shaft angle comes from (None: no speed columns); see the module docstring.
    params : ReducerParams or path, optional
        The reducer whose ratio and sun teeth the angle source uses (default the built-in RV-20E).

    Returns
    -------
    dict
        The summary: path, n_samples, classes, counts per class, files used and skipped.
    """
    out = Path(out)
    if out.exists() and not overwrite:
        raise StoreError(f"{out} already exists (remove it, choose another --out, or pass --overwrite)")
    if test_fraction is not None and (test_include is not None or test_block is not None):
        raise ParameterError("--test-fraction and --test-include/--test-block choose the test split in two ways: "
                             "give one")
    block = _parse_block(test_block)
    test_pat = _compile(test_include, "--test-include")
    if test_fraction is not None and not (0.0 < float(test_fraction) < 1.0):
        raise ParameterError(f"--test-fraction must be between 0 and 1 (exclusive), got {test_fraction}")
    if split_by not in SPLIT_BY:
        raise ParameterError(f"--split-by must be one of {'|'.join(SPLIT_BY)}, got {split_by!r}")
    if not isinstance(window_length, (int, np.integer)) or window_length < 2:
        raise ParameterError(f"--window must be an integer of at least 2, got {window_length!r}")
    if hop is not None and (not isinstance(hop, (int, np.integer)) or hop < 1):
        raise ParameterError(f"--hop must be a positive integer, got {hop!r}")
    scalar_pats = {k: v for k, v in (scalars or {}).items()}
    for k, v in scalar_pats.items():
        _compile(v, f"scalar regex for {k!r}")
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", k):
            raise ParameterError(f"scalar column name {k!r} must be an identifier")
    if angle is not None:
        from rvdiag.params import ReducerParams

        angle.validate()
        params = params if isinstance(params, ReducerParams) else ReducerParams.load(params)
    entries, skipped = select_files(folder, label_regex, meta_regex, include)
    if test_fraction is not None and split_by == "unit":
        _check_files_per_class(entries)

    blocks: list[np.ndarray] = []
    labels: list[str] = []
    cols: dict[str, list[Any]] = {"unit": [], "source": [], "channel": [], "start": []}
    file_meta: dict[str, list[str]] = {k: [] for k in entries[0].meta}
    scalar_vals: dict[str, list[float]] = {k: [] for k in scalar_pats}
    angle_cols: dict[str, list[Any]] = {k: [] for k in ANGLE_COLUMNS} if angle is not None else {}
    sources: dict[str, str] = {}
    rows_per_file: list[int] = []
    fs_seen: float | None | str = "unset"
    first_fs_file = None
    for i, entry in enumerate(entries):
        if progress is not None:
            progress(i, len(entries), entry.path.name)
        sig = read_signal(entry.path, channel, fs=fs)
        if fs_seen == "unset":
            fs_seen, first_fs_file = sig.fs, entry.path.name
        elif not _same_fs(fs_seen, sig.fs):
            raise DataFileError(
                f"{entry.path}: sampling rate {sig.fs} differs from {fs_seen} of {first_fs_file}; "
                "give --fs to set one rate for all files"
            )
        W = window(sig, int(window_length), hop)
        starts = window_starts(sig.n_samples, int(window_length), hop)
        n = W.shape[0]
        blocks.append(W.astype(np.float32))
        labels.extend([entry.label] * n)
        cols["unit"].extend([i] * n)
        cols["source"].extend([entry.path.name] * n)
        cols["channel"].extend([sig.channel] * n)
        cols["start"].extend(starts.tolist())
        if set(entry.meta) != set(file_meta):
            raise DataFileError(f"{entry.path}: its name gives metadata {sorted(entry.meta)}, "
                                f"other files {sorted(file_meta)}")
        for k, v in entry.meta.items():
            file_meta[k].extend([v] * n)
        for k, pat in scalar_pats.items():
            scalar_vals[k].extend([sig.scalar(pat)] * n)
        if angle is not None:
            _angle_columns(sig, angle, params, fs, starts, int(window_length), angle_cols, sources)
        rows_per_file.append(n)
    if progress is not None:
        progress(len(entries), len(entries), "")

    X = np.concatenate(blocks, axis=0)
    y = np.asarray(labels, dtype=object)
    meta: dict[str, Any] = {
        "unit": np.asarray(cols["unit"], dtype=np.int64),
        "source": np.asarray(cols["source"], dtype=object),
        "channel": np.asarray(cols["channel"], dtype=object),
        "start": np.asarray(cols["start"], dtype=np.int64),
    }
    for k, v in file_meta.items():
        if k in meta or k == "split":
            raise ParameterError(f"metadata group name {k!r} is reserved; rename the regex group")
        meta[k] = _typed_column(v)
    for k, v in scalar_vals.items():
        if k in meta or k == "split":
            raise ParameterError(f"scalar column name {k!r} is reserved or used twice")
        meta[k] = np.asarray(v, dtype=np.float64)
    for k, v in angle_cols.items():
        if k in meta:
            raise ParameterError(f"metadata column {k!r} is written by the angle source; rename the regex group or "
                                 "scalar")
        meta[k] = np.asarray(v, dtype=object if k == "angle_source" else np.float64)
    if test_pat is not None or block is not None:
        meta["split"] = split_by_name(meta["source"], test_pat, block)
    elif split_by == "unit":
        meta["split"] = _split_by_unit(y, meta["unit"], test_fraction, seed)
    else:
        meta["split"] = _split(y, test_fraction, seed)
        if test_fraction is not None:
            warnings.warn("--split-by window puts neighbouring windows of one recording in both train and test: "
                          "the test accuracy is optimistic (the default --split-by unit holds out whole files)",
                          SplitLeakWarning, stacklevel=2)

    config = {
        "source": "files",
        "folder": str(Path(folder).resolve()),
        "files": [e.path.name for e in entries],
        "label_regex": label_regex,
        "meta_regex": meta_regex,
        "include": include,
        "channel": channel,
        "window": int(window_length),
        "hop": int(hop) if hop is not None else int(window_length),
        "fs": fs,
        "test_fraction": test_fraction,
        "seed": int(seed),
        "split_by": split_by,
        "scalars": dict(scalar_pats),
        "test_include": test_include,
        "test_block": test_block,
    }
    if angle is not None:
        config["angle"] = {**angle.to_dict(), "params": params.to_dict()}
    file_fs = None if fs_seen == "unset" else fs_seen
    if file_fs is None and not unknown_fs:  # a store without a rate is read in cycles per sample, never in Hz
        raise DataFileError(f"{first_fs_file} states no sampling rate (no time column or fs variable): give --fs, "
                            "or --unknown-fs when no rate is known (features then in cycles per sample)")
    write_store(out, X, y.tolist(), meta, kind="measured", fs=file_fs, config=config,
                overwrite=overwrite, extra_attrs={"params": None})
    classes = sorted(set(labels))
    counts = {c: int(np.sum(y == c)) for c in classes}
    return {
        "path": str(out),
        "n_samples": int(X.shape[0]),
        "length": int(window_length),
        "fs": file_fs,
        "classes": classes,
        "counts": counts,
        "files": len(entries),
        "skipped": skipped,
        "rows_per_file": rows_per_file,
        "angle_sources": sources,
    }


#: the metadata columns an angle source adds to every window
ANGLE_COLUMNS = ("input_speed_rpm", "output_speed_deg_s", "input_rev_start", "angle_source")


def _angle_columns(sig, angle, params, fs, starts: np.ndarray, length: int, cols: dict, sources: dict) -> None:
    """Append the :data:`ANGLE_COLUMNS` of one file's windows to ``cols`` (and its source to ``sources``)."""
    from rvdiag.io.angles import input_revolutions

    try:
        got = input_revolutions(sig, angle, params, fs)
    except (ParameterError, DataFileError) as exc:
        msg = str(exc)
        raise ParameterError(msg if msg.startswith((str(sig.path), sig.path.name)) else f"{sig.path.name}: {msg}") \
            from None
    r = got.revs
    rpm = (r[starts + length - 1] - r[starts]) * float(sig.fs) / (length - 1) * 60.0
    cols["input_speed_rpm"].extend(rpm.tolist())
    cols["output_speed_deg_s"].extend((rpm * 6.0 / params.ratio).tolist())
    cols["input_rev_start"].extend(r[starts].tolist())
    cols["angle_source"].extend([got.source] * starts.size)
    sources[sig.path.name] = f"{got.source}: {got.detail}, mean {got.rpm:.6g} rev/min"


def _same_fs(a: float | None, b: float | None) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return math.isclose(a, b, rel_tol=1e-9)


def _check_files_per_class(entries: list[FileEntry]) -> None:
    """A split by file needs two files of every class (one to test, one to train)."""
    for label in sorted({e.label for e in entries}):
        names = [e.path.name for e in entries if e.label == label]
        if len(names) < 2:
            raise ParameterError(
                f"--test-fraction: class {label!r} has one file ({names[0]}); a split by file needs at least two "
                "per class (add files, or --split-by window, which leaks neighbouring windows into the test)")


def _split_by_unit(y: np.ndarray, unit: np.ndarray, test_fraction: float | None, seed: int) -> np.ndarray:
    """``train`` everywhere, or a seeded split of whole files: ``round(f * k_c)`` of the ``k_c`` files of each
    class ``c`` go to ``test`` (at least one, at most ``k_c - 1``), so no file has windows on both sides."""
    split = np.full(y.shape[0], "train", dtype=object)
    if test_fraction is None:
        return split
    rng = np.random.default_rng(seed)
    for c in sorted(set(y.tolist())):
        files = np.unique(unit[y == c])  # >= 2: checked by _check_files_per_class before reading
        n_test = min(max(int(round(float(test_fraction) * files.size)), 1), files.size - 1)
        split[np.isin(unit, rng.permutation(files)[:n_test])] = "test"
    return split


def _split(y: np.ndarray, test_fraction: float | None, seed: int) -> np.ndarray:
    """``train`` everywhere, or a seeded split with ``round(f * n_c)`` test windows per class ``c``."""
    split = np.full(y.shape[0], "train", dtype=object)
    if test_fraction is None:
        return split
    rng = np.random.default_rng(seed)
    for c in sorted(set(y.tolist())):
        idx = np.flatnonzero(y == c)
        n_test = int(round(float(test_fraction) * idx.size))
        if idx.size >= 2:
            n_test = min(max(n_test, 1), idx.size - 1)
        else:
            n_test = 0
        split[rng.permutation(idx)[:n_test]] = "test"
    return split


def _parse_block(text: str | None) -> tuple[re.Pattern, int, int] | None:
    """``"REGEX=K/N"`` -> (pattern, K, N); None stays None."""
    if text is None:
        return None
    regex, sep, frac = text.rpartition("=")
    k, slash, n = frac.partition("/")
    try:
        k_i, n_i = int(k), int(n)
    except ValueError:
        k_i = n_i = 0
    if not sep or not regex or not slash or not 1 <= k_i <= n_i or n_i < 2:
        raise ParameterError(f"--test-block {text!r}: expected REGEX=K/N with 1 <= K <= N and N >= 2, "
                             "e.g. normal=1/3")
    return _compile(regex, "--test-block regex"), k_i, n_i


def split_by_name(source: np.ndarray, test_include: re.Pattern | None,
                  block: tuple[re.Pattern, int, int] | None) -> np.ndarray:
    """The ``split`` column of a split chosen by file name (``dataset from-files --test-include/--test-block``).

    A window is ``test`` when its file's name matches ``test_include`` (``re.search``), else ``train``.  A
    file whose name matches the ``block`` regex (``REGEX=K/N``) is cut in time instead: its windows, in
    order, form N contiguous blocks (window i of n in block floor(i N / n) + 1), block K is ``test`` and the
    others ``train``; so one recording can serve both sides without a test window overlapping a training
    window (with no overlap between windows, ``--hop`` = ``--window``).
    """
    source = np.asarray(source).astype(str)
    split = np.full(source.shape[0], "train", dtype=object)
    for name in dict.fromkeys(source.tolist()):
        rows = np.flatnonzero(source == name)
        if block is not None and block[0].search(name):
            _, k, n = block
            split[rows[np.arange(rows.size) * n // rows.size == k - 1]] = "test"
        elif test_include is not None and test_include.search(name):
            split[rows] = "test"
    return split


__all__ = ["SPLIT_BY", "split_by_name", "FileEntry", "build_from_files", "select_files", "SUPPORTED_SUFFIXES"]
