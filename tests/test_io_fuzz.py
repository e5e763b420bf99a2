"""Fuzzing the readers: random bytes and mangled files give DataFileError (or a signal), nothing else."""

from __future__ import annotations

import gzip
import io
import shutil
import tempfile
from pathlib import Path

import numpy as np
import scipy.io
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rvdiag.errors import DataFileError
from rvdiag.io import read_signal

SUFFIXES = [".csv", ".csv.gz", ".mat", ".npy", ".npz", ".wav", ".tdms"]
REGEX = {".csv": "a1", ".csv.gz": "a1", ".mat": "DE", ".npy": None, ".npz": r"\[1\]", ".wav": None}
FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _read(data: bytes, suffix: str, regex: str | None = None):
    d = Path(tempfile.mkdtemp())
    try:
        p = d / f"f{suffix}"
        p.write_bytes(data)
        try:
            sig = read_signal(p, regex)
        except DataFileError as exc:
            assert "\n" not in str(exc) and str(p) in str(exc)
            return None
        assert sig.data.ndim == 1 and sig.data.dtype == np.float64 and np.all(np.isfinite(sig.data))
        return sig
    finally:
        shutil.rmtree(d, ignore_errors=True)


@FUZZ
@given(data=st.binary(min_size=0, max_size=2000), suffix=st.sampled_from(SUFFIXES))
def test_random_bytes(data, suffix):
    _read(data, suffix)


def _valid_bytes(suffix: str) -> bytes:
    x = np.linspace(-1, 1, 64)
    buf = io.BytesIO()
    if suffix == ".mat":
        scipy.io.savemat(buf, {"X1_DE_time": x[:, None], "X1RPM": np.array([[1797]])})
    elif suffix == ".npy":
        np.save(buf, x)
    elif suffix == ".npz":
        np.savez(buf, signal=np.vstack([x, x]), fs=1000.0, settings="{}")
    elif suffix == ".wav":
        scipy.io.wavfile.write(buf, 8000, (x * 1000).astype(np.int16))
    else:
        text = "a1,a2\n" + "\n".join(f"{v},{-v}" for v in x) + "\n"
        return gzip.compress(text.encode()) if suffix.endswith(".gz") else text.encode()
    return buf.getvalue()


@FUZZ
@given(suffix=st.sampled_from([".csv", ".csv.gz", ".mat", ".npy", ".npz", ".wav"]),
       cut=st.floats(0, 1), flips=st.lists(st.tuples(st.floats(0, 1), st.integers(0, 255)), max_size=8))
def test_mangled_valid_files(suffix, cut, flips):
    """Valid files truncated at a random point and with random bytes overwritten."""
    raw = bytearray(_valid_bytes(suffix))
    for where, value in flips:
        raw[min(int(where * len(raw)), len(raw) - 1)] = value
    raw = bytes(raw[: int(cut * len(raw))])
    _read(raw, suffix, regex=REGEX[suffix])


_cell = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-10**6, 10**6).map(str),
    st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=6),
    st.just(""),
)


@FUZZ
@given(rows=st.lists(st.lists(_cell, min_size=1, max_size=4), min_size=0, max_size=12),
       delim=st.sampled_from([",", ";", "\t", " "]))
def test_mangled_csv_text(rows, delim):
    """Random tables (ragged rows, text cells, NaN, empty cells) never raise anything but DataFileError."""
    text = "\n".join(delim.join(r) for r in rows)
    sig = _read(text.encode("utf-8", "surrogatepass"), ".csv", regex=None)
    if sig is not None:
        assert sig.n_samples >= 2


def test_valid_bytes_helper_reads_back():
    """The seed files of the mangling test are valid, so the mangling test starts from readable files."""
    for suffix in [".csv", ".csv.gz", ".mat", ".npy", ".npz", ".wav"]:
        assert _read(_valid_bytes(suffix), suffix, regex=REGEX[suffix]) is not None
