"""Readers of measured files (rvdiag.io): every format, channel selection, fs, bad files, windowing."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io
import scipy.io.wavfile

from rvdiag.errors import DataFileError, ParameterError
from rvdiag.io import detect_format, list_channels, read_signal, window, window_starts

from conftest import DATA, needs_real_data
RNG = np.random.default_rng(0)
X = RNG.standard_normal(500)
Y = RNG.standard_normal(500)


def _csv(path: Path, header: bool = True, delim: str = ",", gz: bool = False) -> Path:
    lines = ([delim.join(["a1", "a2"])] if header else []) + [f"{a!r}{delim}{b!r}" for a, b in zip(X, Y)]
    text = "\n".join(lines) + "\n"
    if gz:
        path.write_bytes(gzip.compress(text.encode()))
    else:
        path.write_text(text)
    return path


# --------------------------------------------------------------------------- formats
@pytest.mark.parametrize("delim", [",", ";", "\t", " "])
def test_csv_with_header_each_delimiter(tmp_path, delim):
    p = _csv(tmp_path / "x.csv", delim=delim)
    sig = read_signal(p, "a2")
    assert sig.channel == "a2" and sig.fs is None and sig.format == "csv"
    np.testing.assert_array_equal(sig.data, Y)


def test_csv_gz_without_header_names_columns_col0(tmp_path):
    p = _csv(tmp_path / "x.csv.gz", header=False, gz=True)
    assert list_channels(p) == ["col0", "col1"]
    np.testing.assert_array_equal(read_signal(p, "^col0$").data, X)


def test_csv_time_column_gives_fs(tmp_path):
    t = np.arange(300) / 2500.0
    p = tmp_path / "t.csv"
    p.write_text("time,acc\n" + "\n".join(f"{a!r},{b!r}" for a, b in zip(t, X)))
    sig = read_signal(p, "acc")
    assert sig.fs == pytest.approx(2500.0, rel=1e-9)
    assert read_signal(p, "acc", fs=1000).fs == 1000.0  # a given fs wins


def test_mat_v5_picks_channel_and_scalars(tmp_path):
    p = tmp_path / "IR007_0.mat"
    scipy.io.savemat(p, {"X105_DE_time": X[:, None], "X105_FE_time": Y[:, None], "X105RPM": np.array([[1797]])})
    sig = read_signal(p, "DE_time", fs=12000)
    assert sig.channel == "X105_DE_time" and sig.fs == 12000.0
    np.testing.assert_array_equal(sig.data, X)
    assert sig.scalars == {"X105RPM": 1797.0} and sig.scalar("RPM") == 1797.0
    assert list_channels(p) == ["X105_DE_time", "X105_FE_time"]


def test_mat_v5_fs_variable_and_matrix_columns(tmp_path):
    p = tmp_path / "m.mat"
    scipy.io.savemat(p, {"acc": np.column_stack([X, Y]), "fs": 5120.0})
    assert list_channels(p) == ["acc[0]", "acc[1]"]
    sig = read_signal(p, r"acc\[1\]")
    np.testing.assert_array_equal(sig.data, Y)
    assert sig.fs == 5120.0


def test_mat_v73_via_h5py(tmp_path):
    p = tmp_path / "v73.mat"
    # a MATLAB v7.3 file is HDF5 with a 512-byte user block; MATLAB writes an N x 1 vector as (1, N)
    with h5py.File(p, "w", userblock_size=512) as f:
        f["vib"] = X[None, :]
        f["Fs"] = np.array([[2000.0]])
    with open(p, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file".ljust(128, b" "))
    assert detect_format(p) == "mat"
    sig = read_signal(p, "vib")
    assert sig.format == "mat73" and sig.fs == 2000.0
    np.testing.assert_array_equal(sig.data, X)


def test_npy_one_and_two_d(tmp_path):
    p1 = tmp_path / "a.npy"
    np.save(p1, X)
    np.testing.assert_array_equal(read_signal(p1).data, X)  # one channel: no regex needed
    p2 = tmp_path / "b.npy"
    np.save(p2, np.column_stack([X, Y]))  # samples x channels: split along the shorter axis
    assert list_channels(p2) == ["data[0]", "data[1]"]
    np.testing.assert_array_equal(read_signal(p2, r"\[1\]").data, Y)


def test_npz_as_written_by_simulate(tmp_path):
    p = tmp_path / "sim.npz"
    np.savez(p, signal=np.vstack([X, Y]), fs=10000.0, settings=json.dumps({"state": "T1"}))
    assert list_channels(p) == ["signal[0]", "signal[1]"]
    sig = read_signal(p, r"signal\[1\]")
    np.testing.assert_array_equal(sig.data, Y)
    assert sig.fs == 10000.0 and sig.attrs["settings"] == {"state": "T1"}
    p1 = tmp_path / "sim1.npz"
    np.savez(p1, signal=X, fs=10000.0, settings="{}")
    assert read_signal(p1, "signal").fs == 10000.0


def test_npz_with_object_array_is_refused(tmp_path):
    p = tmp_path / "obj.npz"
    np.savez(p, signal=np.array([{"a": 1}, None], dtype=object))
    with pytest.raises(DataFileError, match="obj.npz"):
        read_signal(p)


def test_wav_int16_scaled_and_fs(tmp_path):
    p = tmp_path / "s.wav"
    pcm = (np.clip(np.column_stack([X, Y]) / 5, -1, 1) * 32767).astype(np.int16)
    scipy.io.wavfile.write(p, 8000, pcm)
    assert list_channels(p) == ["ch0", "ch1"]
    sig = read_signal(p, "ch1")
    assert sig.fs == 8000.0
    np.testing.assert_allclose(sig.data, pcm[:, 1] / 32768.0)


def test_tdms_fs_from_wf_increment(tmp_path):
    from nptdms import ChannelObject, TdmsWriter

    p = tmp_path / "r.tdms"
    with TdmsWriter(str(p)) as w:
        w.write_segment([
            ChannelObject("rig", "acc_x", X, properties={"wf_increment": 1 / 25600.0}),
            ChannelObject("rig", "acc_y", Y, properties={"wf_increment": 1 / 25600.0}),
        ])
    assert list_channels(p) == ["rig/acc_x", "rig/acc_y"]
    sig = read_signal(p, "acc_y")
    assert sig.fs == pytest.approx(25600.0)
    np.testing.assert_array_equal(sig.data, Y)


# --------------------------------------------------------------------------- bad files
def _msg(exc_info) -> str:
    text = str(exc_info.value)
    assert "\n" not in text
    return text


def test_unknown_format(tmp_path):
    p = tmp_path / "x.xlsx"
    p.write_bytes(b"abc")
    with pytest.raises(DataFileError, match="unknown format") as e:
        read_signal(p)
    assert "x.xlsx" in _msg(e)


def test_empty_file(tmp_path):
    p = tmp_path / "e.csv"
    p.write_text("")
    with pytest.raises(DataFileError, match="empty") as e:
        read_signal(p)
    assert "e.csv" in _msg(e)


def test_header_only_csv(tmp_path):
    p = tmp_path / "h.csv"
    p.write_text("a1,a2\n")
    with pytest.raises(DataFileError, match="no data rows"):
        read_signal(p, "a1")


def test_truncated_gzip(tmp_path):
    good = _csv(tmp_path / "g.csv.gz", gz=True)
    p = tmp_path / "t.csv.gz"
    p.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(DataFileError, match="t.csv.gz") as e:
        read_signal(p, "a1")
    assert "truncated" in _msg(e)


def test_truncated_csv_row(tmp_path):
    p = tmp_path / "r.csv"
    p.write_text("a1,a2\n1,2\n3,4\n5\n")
    with pytest.raises(DataFileError, match="malformed or truncated") as e:
        read_signal(p, "a1")
    assert "r.csv" in _msg(e)


def test_truncated_mat(tmp_path):
    good = tmp_path / "g.mat"
    scipy.io.savemat(good, {"X1_DE_time": X[:, None]})
    p = tmp_path / "t.mat"
    p.write_bytes(good.read_bytes()[:700])
    with pytest.raises(DataFileError, match="t.mat") as e:
        read_signal(p, "DE")
    _msg(e)


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf"])
def test_nan_or_inf(tmp_path, bad):
    p = tmp_path / "n.csv"
    p.write_text(f"a1,a2\n1,2\n{bad},4\n5,6\n")
    with pytest.raises(DataFileError, match="NaN or Inf.*sample 1") as e:
        read_signal(p, "a1")
    assert "n.csv" in _msg(e)
    assert read_signal(p, "a2").data.tolist() == [2, 4, 6]  # other columns stay readable


def test_no_and_two_matching_channels(tmp_path):
    p = _csv(tmp_path / "c.csv")
    with pytest.raises(DataFileError, match="no channel matches 'zz'.*a1, a2"):
        read_signal(p, "zz")
    with pytest.raises(DataFileError, match="2 channels match 'a'"):
        read_signal(p, "a")
    with pytest.raises(DataFileError, match="2 channels"):
        read_signal(p)  # several channels and no regex


def test_bad_regex_and_fs(tmp_path):
    p = _csv(tmp_path / "c.csv")
    with pytest.raises(ParameterError, match="regular expression"):
        read_signal(p, "(")
    with pytest.raises(ParameterError, match="positive"):
        read_signal(p, "a1", fs=-3)


def test_missing_file_and_folder(tmp_path):
    with pytest.raises(DataFileError, match="no such file"):
        read_signal(tmp_path / "none.csv")
    d = tmp_path / "d.csv"
    d.mkdir()
    with pytest.raises(DataFileError, match="folder"):
        read_signal(d)


# --------------------------------------------------------------------------- windowing
def test_window_contents_and_starts():
    x = np.arange(10.0)
    W = window(x, 4, hop=3)
    np.testing.assert_array_equal(W, [[0, 1, 2, 3], [3, 4, 5, 6], [6, 7, 8, 9]])
    np.testing.assert_array_equal(window_starts(10, 4, 3), [0, 3, 6])
    np.testing.assert_array_equal(window(x, 5), [[0, 1, 2, 3, 4], [5, 6, 7, 8, 9]])
    assert window(x, 3).shape == (3, 3)  # tail dropped
    W[0, 0] = 99  # a copy, not a view
    assert x[0] == 0


def test_window_too_long_names_the_file(tmp_path):
    p = _csv(tmp_path / "short.csv")
    sig = read_signal(p, "a1")
    with pytest.raises(DataFileError, match=r"short.csv.*500 points, shorter than the window of 2048"):
        window(sig, 2048)
    with pytest.raises(ParameterError):
        window(sig, 0)
    with pytest.raises(ParameterError):
        window(sig, 10, hop=0)


# --------------------------------------------------------------------------- real files
@needs_real_data("cwru-bearing/IR007_0.mat", "spectraquest-gearbox/h30hz0.csv.gz")
def test_real_cwru_and_spectraquest():
    sig = read_signal(DATA / "cwru-bearing" / "IR007_0.mat", "DE_time", fs=12000)
    assert sig.channel == "X105_DE_time" and sig.n_samples == 121265 and sig.scalar("RPM") == 1797.0
    sq = read_signal(DATA / "spectraquest-gearbox" / "h30hz0.csv.gz", "a1")
    assert sq.fs is None and list_channels(DATA / "spectraquest-gearbox" / "h30hz0.csv.gz") == ["a1", "a2", "a3", "a4"]
    assert sq.data[0] == pytest.approx(4.63671)
