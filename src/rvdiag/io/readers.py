"""Readers for measured vibration / current files: one entry point for every supported format.

Supported formats (chosen by the file name's ending, never guessed from the bytes):

========================  =============================================================================
``.csv``, ``.txt``,       delimited text (``,`` ``;`` tab or blanks), with or without a header row; without
``.csv.gz``, ``.txt.gz``  one the columns are named ``col0``, ``col1`` ...  A column named ``time``, ``t``,
                          ``time_s`` or ``time [s]`` gives fs = 1 / (its median step).
``.mat``                  MATLAB v5 (:func:`scipy.io.loadmat`) or v7.3 (HDF5, :mod:`h5py`), told apart by
                          the HDF5 signature at byte 512.  Numeric vectors are channels, numeric scalars are
                          *scalars* (such as CWRU's ``X105RPM``); a scalar named ``fs``/``Fs``/``sf``/
                          ``sampling_rate``/``sample_rate`` gives fs.
``.npy``, ``.npz``        NumPy arrays, always with ``allow_pickle=False``.  An NPZ written by
                          ``rvdiag simulate`` holds ``signal`` (1-D, or channels x samples), ``fs`` and
                          ``settings`` (a JSON string, kept in :attr:`MeasuredSignal.attrs`); the motor
                          current of a ``--signal both`` file (``current``, at its own ``current_fs``) is
                          not read: ``--signal current`` writes it as the ``signal``.
``.wav``                  :func:`scipy.io.wavfile.read`; fs from the file; integer samples are scaled to
                          [-1, 1); channels ``ch0``, ``ch1`` ...
``.tdms``                 NI TDMS (:mod:`nptdms`); channels ``group/channel``; fs = 1 / ``wf_increment``
                          when the channel has that property.
========================  =============================================================================

Matrices: a 2-D array ``A`` is split into channels ``A[0]``, ``A[1]``, ... along its *shorter* axis (a row
or column vector is one channel named ``A``).  So an ``(channels, samples)`` signal and a
``(samples, channels)`` table both give one channel per sensor.

A channel is chosen by a regular expression (:func:`re.search`) that must match exactly one channel name
of the file (``DE_time`` picks ``X105_DE_time`` in a CWRU file).  Every problem with a file raises
:class:`rvdiag.errors.DataFileError` with one line naming the file and the problem.
"""

from __future__ import annotations

import gzip
import io
import json
import math
import re
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from rvdiag.errors import DataFileError, ParameterError

#: name endings understood by :func:`detect_format`, longest first
_FORMATS: tuple[tuple[str, str], ...] = (
    (".csv.gz", "csv"),
    (".txt.gz", "csv"),
    (".csv", "csv"),
    (".txt", "csv"),
    (".mat", "mat"),
    (".npy", "npy"),
    (".npz", "npz"),
    (".wav", "wav"),
    (".tdms", "tdms"),
)
SUPPORTED_SUFFIXES: tuple[str, ...] = tuple(s for s, _ in _FORMATS)

_FS_NAMES = {"fs", "sf", "sampling_rate", "sample_rate", "samplerate", "sampling_frequency", "srate"}
_TIME_COLUMN = re.compile(r"^\s*(time|t)\s*(_s|\[s\]|\(s\))?\s*$", re.IGNORECASE)


@dataclass
class MeasuredSignal:
    """One channel of a measured file.

    Attributes
    ----------
    data : ndarray, float64, 1-D, finite
    fs : float or None
        Sampling rate in Hz: the one given by the caller, else the one the file states, else None.
    channel : str
        Name of the channel within the file.
    path : Path
    format : str
        ``csv``, ``mat``, ``mat73``, ``npy``, ``npz``, ``wav`` or ``tdms``.
    scalars : dict of str -> float
        Numeric scalars stored beside the signals (e.g. ``X105RPM`` in a CWRU file).
    attrs : dict
        Other information from the file (e.g. the ``settings`` of an NPZ written by ``rvdiag simulate``).
    """

    data: np.ndarray
    fs: float | None
    channel: str
    path: Path
    format: str = ""
    scalars: dict[str, float] = field(default_factory=dict)
    attrs: dict[str, Any] = field(default_factory=dict)

    @property
    def n_samples(self) -> int:
        """Number of points."""
        return int(self.data.shape[0])

    def scalar(self, regex: str) -> float:
        """The one scalar whose name matches ``regex`` (re.search), e.g. ``sig.scalar("RPM")``."""
        try:
            pat = re.compile(regex)
        except re.error as exc:
            raise ParameterError(f"invalid regular expression {regex!r}: {exc}") from None
        hits = [k for k in self.scalars if pat.search(k)]
        if len(hits) != 1:
            have = ", ".join(sorted(self.scalars)) or "none"
            what = "no scalar" if not hits else f"{len(hits)} scalars ({', '.join(sorted(hits))})"
            raise DataFileError(f"{self.path}: {what} match {regex!r} (scalars: {have})")
        return self.scalars[hits[0]]


@dataclass
class _Contents:
    """What a format reader returns: channel name -> array (1-D), fs stated by the file, scalars, attrs."""

    channels: dict[str, np.ndarray]
    fs: float | None = None
    scalars: dict[str, float] = field(default_factory=dict)
    attrs: dict[str, Any] = field(default_factory=dict)
    format: str = ""


# --------------------------------------------------------------------------- public API
def detect_format(path: str | Path) -> str:
    """Format name of ``path`` from its ending (case-insensitive); DataFileError if unknown."""
    name = Path(path).name.lower()
    for suffix, fmt in _FORMATS:
        if name.endswith(suffix):
            return fmt
    raise DataFileError(
        f"{path}: unknown format (supported endings: {', '.join(SUPPORTED_SUFFIXES)})"
    )


def list_channels(path: str | Path) -> list[str]:
    """Names of the signal channels in a file, in file order."""
    return list(_read_contents(Path(path)).channels)


def stated_channel(path: str | Path, name: str) -> str | None:
    """The channel key of the row that an ``rvdiag simulate`` .npz states as ``name`` in its ``channel_names``
    (e.g. ``"i_a"`` -> ``"signal[0]"`` of a ``--signal current`` file), or None (another format, no such name)."""
    path = Path(path)
    if path.suffix.lower() != ".npz":
        return None
    with np.load(path, allow_pickle=False) as z:
        if "channel_names" not in z.files or "signal" not in z.files:
            return None
        names = [str(n) for n in np.atleast_1d(z["channel_names"])]
        rows = np.atleast_2d(z["signal"]).shape[0]
    if name not in names or len(names) != rows:
        return None
    return f"signal[{names.index(name)}]" if rows > 1 else "signal"


def read_signal(path: str | Path, channel_regex: str | None = None, fs: float | None = None) -> MeasuredSignal:
    """Read one channel of a measured file.

    Parameters
    ----------
    path : str or Path
    channel_regex : str, optional
        Regular expression (``re.search``) that must match exactly one channel name.  May be omitted
        when the file holds one channel only.
    fs : float, optional
        Sampling rate in Hz.  Given, it overrides what the file states; omitted, the file's rate is used
        (None when the file states none).

    Returns
    -------
    MeasuredSignal

    Raises
    ------
    DataFileError
        Unknown format, unreadable, empty or truncated file; no or several matching channels; NaN/Inf.
    ParameterError
        Invalid regular expression or fs.
    """
    path = Path(path)
    if fs is not None:
        fs = _check_fs(fs)
    pat = None
    if channel_regex is not None:
        try:
            pat = re.compile(channel_regex)
        except re.error as exc:
            raise ParameterError(f"invalid channel regular expression {channel_regex!r}: {exc}") from None
    contents = _read_contents(path)
    names = list(contents.channels)
    if pat is None:
        hits = names
        if len(hits) > 1:
            raise DataFileError(
                f"{path}: {len(hits)} channels ({_short_list(names)}); choose one with a channel regex"
            )
    else:
        hits = [n for n in names if pat.search(n)]
    if not hits:
        raise DataFileError(
            f"{path}: no channel matches {channel_regex!r} (channels: {_short_list(names)})"
        )
    if len(hits) > 1:
        raise DataFileError(
            f"{path}: {len(hits)} channels match {channel_regex!r} ({_short_list(hits)}); "
            "make the regex match exactly one"
        )
    name = hits[0]
    data = _as_float_vector(contents.channels[name], path, name)
    file_fs = contents.attrs.get("channel_fs", {}).get(name, contents.fs)
    if file_fs is not None:
        try:
            file_fs = _check_fs(file_fs)
        except ParameterError:
            raise DataFileError(f"{path}: the file states an invalid sampling rate {contents.fs!r}") from None
    return MeasuredSignal(
        data=data,
        fs=fs if fs is not None else file_fs,
        channel=name,
        path=path,
        format=contents.format,
        scalars=dict(contents.scalars),
        attrs=dict(contents.attrs),
    )


# --------------------------------------------------------------------------- helpers
def _short_list(names: list[str], limit: int = 8) -> str:
    if not names:
        return "none"
    shown = ", ".join(names[:limit])
    return shown + (f", ... ({len(names)} in all)" if len(names) > limit else "")


def _check_fs(fs: Any) -> float:
    try:
        value = float(fs)
    except (TypeError, ValueError):
        raise ParameterError(f"sampling rate must be a number, got {fs!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise ParameterError(f"sampling rate must be positive and finite, got {fs!r}")
    return value


def _as_float_vector(arr: np.ndarray, path: Path, name: str) -> np.ndarray:
    a = np.asarray(arr)
    if a.dtype.kind == "c":
        raise DataFileError(f"{path}: channel {name!r} is complex; give a real signal")
    try:
        v = np.ascontiguousarray(a, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise DataFileError(f"{path}: channel {name!r} is not numeric ({exc})") from None
    if v.size == 0:
        raise DataFileError(f"{path}: channel {name!r} is empty")
    if v.size < 2:
        raise DataFileError(f"{path}: channel {name!r} has a single point")
    bad = ~np.isfinite(v)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise DataFileError(
            f"{path}: channel {name!r} contains {int(bad.sum())} NaN or Inf value(s) (first at sample {first})"
        )
    return v


def _split_matrix(name: str, a: np.ndarray, out: dict[str, np.ndarray], scalars: dict[str, float]) -> None:
    """Add array ``a`` as channel(s) (vectors, matrices) or as a scalar; ignore other shapes."""
    if a.dtype.kind not in "biuf":
        return
    if a.size == 1:
        value = float(a.reshape(-1)[0])
        if math.isfinite(value):
            scalars[name] = value
        return
    if a.size == 0:
        out[name] = a.reshape(-1)
        return
    squeezed = np.squeeze(a)
    if squeezed.ndim == 1:
        out[name] = squeezed
    elif squeezed.ndim == 2:
        axis = 0 if squeezed.shape[0] <= squeezed.shape[1] else 1
        for k in range(squeezed.shape[axis]):
            out[f"{name}[{k}]"] = squeezed[k] if axis == 0 else squeezed[:, k]


def _fs_from_scalars(scalars: dict[str, float]) -> float | None:
    for k, v in scalars.items():
        if k.lower() in _FS_NAMES:
            return v
    return None


def _read_contents(path: Path) -> _Contents:
    fmt = detect_format(path)
    if not path.exists():
        raise DataFileError(f"{path}: no such file")
    if path.is_dir():
        raise DataFileError(f"{path}: is a folder, not a file")
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise DataFileError(f"{path}: cannot read ({exc.strerror})") from None
    if size == 0:
        raise DataFileError(f"{path}: empty file")
    reader: Callable[[Path], _Contents] = _READERS[fmt]
    try:
        contents = reader(path)
    except DataFileError:
        raise
    except MemoryError:
        raise DataFileError(f"{path}: corrupt {fmt} file (it asks for more memory than there is)") from None
    except PermissionError as exc:
        raise DataFileError(f"{path}: cannot read ({exc.strerror})") from None
    except Exception as exc:  # every library raises its own types for a corrupt file
        msg = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise DataFileError(f"{path}: not a readable {fmt} file (truncated or corrupt?): {msg}") from None
    if not contents.format:
        contents.format = fmt
    if not contents.channels:
        raise DataFileError(f"{path}: no signal channel in the file")
    return contents


# --------------------------------------------------------------------------- CSV
def _read_csv(path: Path) -> _Contents:
    raw = path.read_bytes()
    if path.name.lower().endswith(".gz"):
        try:
            raw = gzip.decompress(raw)
        except (OSError, EOFError, zlib.error) as exc:
            raise DataFileError(f"{path}: truncated or corrupt gzip data ({exc})") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise DataFileError(f"{path}: not a text file (not UTF-8)") from None
    if "\x00" in text:
        raise DataFileError(f"{path}: not a text file (contains NUL bytes)")
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise DataFileError(f"{path}: empty file (no data rows)")
    first = lines[0]
    delim = next((d for d in (",", ";", "\t") if d in first), None)
    fields = [f.strip().strip('"').strip("'") for f in (first.split(delim) if delim else first.split())]
    header = not all(_is_number(f) for f in fields)
    body = lines[1:] if header else lines
    if not body:
        raise DataFileError(f"{path}: empty file (a header but no data rows)")
    ncol = len(fields)
    names = fields if header else [f"col{k}" for k in range(ncol)]
    if header:
        names = [n if n else f"col{k}" for k, n in enumerate(names)]
        if len(set(names)) != len(names):
            raise DataFileError(f"{path}: duplicate column names in the header ({', '.join(names)})")
    try:
        table = np.loadtxt(io.StringIO("\n".join(body)), delimiter=delim, dtype=np.float64, ndmin=2,
                           comments=None)
    except ValueError as exc:
        msg = " ".join(str(exc).split())[:160]
        raise DataFileError(f"{path}: malformed or truncated CSV ({msg})") from None
    if table.shape[1] != ncol:
        raise DataFileError(f"{path}: {table.shape[1]} columns of data but {ncol} in the first row")
    channels = {n: table[:, k] for k, n in enumerate(names)}
    fs = None
    for n in names:
        if _TIME_COLUMN.match(n):
            fs = fs_from_time(channels[n])
            break
    return _Contents(channels=channels, fs=fs, format="csv")


def fs_from_time(t: np.ndarray) -> float | None:
    """Sampling rate (Hz) of a time column (s), or None when it does not rise.

    The step is the slope of a least-squares line through the whole column, not a median of differences: a column
    printed with few digits (``0.123456789``) rounds each difference by up to one unit of its last digit, which
    moves a median by that much (48000.768 Hz for 48 kHz at 9 digits) but a fit over n points by ~1/n^1.5 of it.
    A column with gaps or jitter (residuals over a quarter step) keeps the median step.  The rate is given to 8
    significant digits, what a fit of a printed column can claim.
    """
    t = np.asarray(t, dtype=np.float64)
    if t.size < 2 or not np.all(np.isfinite(t)):
        return None
    step = float(np.median(np.diff(t)))
    if not step > 0:
        return None
    k = np.arange(t.size, dtype=np.float64) - (t.size - 1) / 2.0
    slope = float(k @ (t - t.mean()) / (k @ k))
    if slope > 0 and np.max(np.abs(t - t.mean() - slope * k)) < 0.25 * step:
        step = slope
    return float(f"{1.0 / step:.8g}")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


# --------------------------------------------------------------------------- MATLAB
def _read_mat(path: Path) -> _Contents:
    with open(path, "rb") as fh:
        head = fh.read(520)
    if len(head) >= 520 and head[512:520] == b"\x89HDF\r\n\x1a\n":
        return _read_mat73(path)
    if len(head) < 128:
        raise DataFileError(f"{path}: truncated MATLAB file ({len(head)} bytes, header needs 128)")
    import scipy.io

    data = scipy.io.loadmat(str(path), squeeze_me=False, struct_as_record=True, mat_dtype=False)
    channels: dict[str, np.ndarray] = {}
    scalars: dict[str, float] = {}
    for name, value in data.items():
        if name.startswith("__") or not isinstance(value, np.ndarray):
            continue
        _split_matrix(name, value, channels, scalars)
    return _Contents(channels=channels, fs=_fs_from_scalars(scalars), scalars=scalars, format="mat")


def _read_mat73(path: Path) -> _Contents:
    import h5py

    channels: dict[str, np.ndarray] = {}
    scalars: dict[str, float] = {}
    with h5py.File(path, "r") as f:
        def visit(name: str, obj: Any) -> None:
            if name.startswith("#") or not isinstance(obj, h5py.Dataset):
                return
            if obj.dtype.kind not in "biuf" or obj.ndim > 2:
                return
            # MATLAB stores arrays column-major: an N x 1 vector appears as (1, N); transpose back.
            _split_matrix(name, np.asarray(obj[()]).T, channels, scalars)

        f.visititems(visit)
    return _Contents(channels=channels, fs=_fs_from_scalars(scalars), scalars=scalars, format="mat73")


# --------------------------------------------------------------------------- NumPy
def _read_npy(path: Path) -> _Contents:
    a = np.load(path, allow_pickle=False)
    channels: dict[str, np.ndarray] = {}
    scalars: dict[str, float] = {}
    if a.dtype.kind not in "biuf":
        raise DataFileError(f"{path}: array of dtype {a.dtype} is not a numeric signal")
    if a.ndim > 2:
        raise DataFileError(f"{path}: array of shape {a.shape}; expected 1-D or 2-D")
    _split_matrix("data", a, channels, scalars)
    if scalars and not channels:
        raise DataFileError(f"{path}: a single number, not a signal")
    return _Contents(channels=channels, format="npy")


def _read_npz(path: Path) -> _Contents:
    channels: dict[str, np.ndarray] = {}
    scalars: dict[str, float] = {}
    attrs: dict[str, Any] = {}
    with np.load(path, allow_pickle=False) as z:
        for name in z.files:
            a = z[name]
            if a.dtype.kind in "US" and a.ndim == 0:
                text = str(a[()])
                try:
                    attrs[name] = json.loads(text)
                except ValueError:
                    attrs[name] = text
                continue
            if a.ndim > 2 or name in ("current", "current_fs", "current_names"):
                continue  # a `--signal both` file's motor current runs at its own rate: not a channel at fs
            _split_matrix(name, a, channels, scalars)
    fs = scalars.get("fs", _fs_from_scalars(scalars))
    return _Contents(channels=channels, fs=fs, scalars=scalars, attrs=attrs, format="npz")


# --------------------------------------------------------------------------- WAV
def _read_wav(path: Path) -> _Contents:
    import warnings

    import scipy.io.wavfile

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # e.g. WavFileWarning for unknown chunks
        rate, data = scipy.io.wavfile.read(str(path), mmap=False)
    data = np.asarray(data)
    if data.dtype.kind in "iu":
        info = np.iinfo(data.dtype)
        if data.dtype.kind == "u":  # 8-bit WAV is unsigned, centred on 128
            data = (data.astype(np.float64) - (info.max + 1) / 2) / ((info.max + 1) / 2)
        else:
            data = data.astype(np.float64) / float(-info.min)
    if data.ndim == 1:
        channels = {"ch0": data}
    else:
        channels = {f"ch{k}": data[:, k] for k in range(data.shape[1])}
    return _Contents(channels=channels, fs=float(rate) if rate else None, format="wav")


# --------------------------------------------------------------------------- TDMS
def _read_tdms(path: Path) -> _Contents:
    from nptdms import TdmsFile

    tdms = TdmsFile.read(str(path))
    channels: dict[str, np.ndarray] = {}
    rates: dict[str, float] = {}
    for group in tdms.groups():
        for ch in group.channels():
            name = f"{group.name}/{ch.name}"
            a = np.asarray(ch[:])
            if a.dtype.kind not in "biuf":
                continue
            channels[name] = a
            inc = ch.properties.get("wf_increment")
            try:
                if inc is not None and float(inc) > 0:
                    rates[name] = 1.0 / float(inc)
            except (TypeError, ValueError):
                pass
    fs = None
    if rates:
        distinct = set(np.round(list(rates.values()), 9))
        if len(distinct) == 1:
            fs = next(iter(rates.values()))
    contents = _Contents(channels=channels, fs=fs, format="tdms")
    contents.attrs["channel_fs"] = rates
    return contents


_READERS: dict[str, Callable[[Path], _Contents]] = {
    "csv": _read_csv,
    "mat": _read_mat,
    "npy": _read_npy,
    "npz": _read_npz,
    "wav": _read_wav,
    "tdms": _read_tdms,
}
