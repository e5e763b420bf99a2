"""Building a measured store from a folder (rvdiag.datasets.from_files)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from rvdiag.datasets import SampleStore
import functools

from rvdiag.datasets.from_files import build_from_files as _build_from_files, select_files

#: these files state no sampling rate; the refusal without --fs / unknown_fs is tests/test_smaller_defects.py's
build_from_files = functools.partial(_build_from_files, unknown_fs=True)
from rvdiag.errors import DataFileError, ParameterError, SplitLeakWarning, StoreError

N = 1000


def _folder(tmp_path: Path) -> Path:
    """Six CWRU-like MAT files: 3 classes x 2 loads; the signal encodes (class, load) for checks."""
    d = tmp_path / "raw"
    d.mkdir()
    for ci, cls in enumerate(["normal", "IR007", "OR014"]):
        for load in (0, 1):
            x = np.arange(N, dtype=np.float64) + 10000 * ci + 100000 * load
            scipy.io.savemat(d / f"{cls}_{load}.mat", {"X1_DE_time": x[:, None], "X1_FE_time": -x[:, None],
                                                        "X1RPM": np.array([[1797 - 20 * load]])})
    (d / "README.txt").write_text("not data\n")
    return d


REGEX = r"^(?P<label>normal|IR\d{3}|OR\d{3})"


def test_store_contents_and_metadata(tmp_path):
    d = _folder(tmp_path)
    out = tmp_path / "s.zarr"
    summary = build_from_files(d, out, label_regex=REGEX, meta_regex=r"_(?P<load>\d)\.mat$", channel="DE_time",
                               window_length=300, hop=200, fs=12000, scalars={"rpm": "RPM"})
    assert summary["skipped"] == ["README.txt"]
    s = SampleStore.open(out)
    per_file = (N - 300) // 200 + 1  # 4 windows per file
    assert s.n_samples == 6 * per_file and s.length == 300 and s.fs == 12000.0
    assert s.attrs["kind"] == "measured" and s.classes == ["IR007", "OR014", "normal"]
    smp = s.load("all")
    assert set(smp.meta["split"]) == {"train"}
    assert smp.meta["load"].dtype.kind == "i" and sorted(set(smp.meta["load"])) == [0, 1]
    assert smp.meta["rpm"].dtype.kind == "f" and set(smp.meta["rpm"]) == {1797.0, 1777.0}
    np.testing.assert_array_equal(np.unique(smp.meta["start"]), [0, 200, 400, 600])
    # every window is the right slice of the right file
    for k in range(s.n_samples):
        src, start = smp.meta["source"][k], int(smp.meta["start"][k])
        ci = ["normal", "IR007", "OR014"].index(src.split("_")[0])
        load = int(src.split("_")[1][0])
        assert smp.y[k] == src.split("_")[0] and smp.meta["load"][k] == load
        np.testing.assert_array_equal(smp.X[k], np.arange(start, start + 300) + 10000 * ci + 100000 * load)
        assert smp.meta["channel"][k] == "X1_DE_time"
    assert s.attrs["config"]["label_regex"] == REGEX


def test_test_fraction_splits_by_file_by_default(tmp_path):
    """A random split of windows put neighbours of one recording on both sides.  By default no
    file contributes windows to both splits; each class holds out round(f * its files) whole files."""
    d = _folder(tmp_path)
    kw = dict(label_regex=REGEX, channel="DE", window_length=100, hop=50, test_fraction=0.5)
    build_from_files(d, tmp_path / "a.zarr", seed=1, **kw)
    build_from_files(d, tmp_path / "b.zarr", seed=1, **kw)
    a, b = (SampleStore.open(tmp_path / f"{n}.zarr") for n in "ab")
    smp = a.load()
    sides = {src: set(smp.meta["split"][smp.meta["source"] == src]) for src in set(smp.meta["source"])}
    assert len(sides) == 6 and all(len(v) == 1 for v in sides.values()), sides
    test_files = sorted(src for src, v in sides.items() if v == {"test"})
    assert len(test_files) == 3 and sorted(f.split("_")[0] for f in test_files) == ["IR007", "OR014", "normal"]
    assert a.attrs["config"]["split_by"] == "unit"
    np.testing.assert_array_equal(smp.meta["split"], b.load().meta["split"])
    held_out = set()
    for seed in range(2, 6):  # other seeds hold out other files
        build_from_files(d, tmp_path / f"s{seed}.zarr", seed=seed, **kw)
        other = SampleStore.open(tmp_path / f"s{seed}.zarr").load()
        held_out.add(tuple(sorted(set(other.meta["source"][other.meta["split"] == "test"]))))
    assert len(held_out) > 1


def test_split_by_file_needs_two_files_per_class_and_writes_nothing(tmp_path):
    d = _folder(tmp_path)
    with pytest.raises(ParameterError, match=r"class 'IR007' has one file \(IR007_0\.mat\).*--split-by window"):
        build_from_files(d, tmp_path / "a.zarr", label_regex=REGEX, channel="DE", window_length=100,
                         include=r"_0\.mat$", test_fraction=0.3)
    assert not (tmp_path / "a.zarr").exists()
    with pytest.raises(ParameterError, match=re.escape("--split-by must be one of unit|window, got 'file'")):
        build_from_files(d, tmp_path / "a.zarr", label_regex=REGEX, channel="DE", window_length=100,
                         test_fraction=0.3, split_by="file")


def test_window_split_warns_and_is_stratified_and_seeded(tmp_path):
    d = _folder(tmp_path)
    kw = dict(label_regex=REGEX, channel="DE", window_length=100, include=r"_0\.mat$", test_fraction=0.3,
              split_by="window")
    with pytest.warns(SplitLeakWarning, match="neighbouring windows of one recording in both train and test"):
        build_from_files(d, tmp_path / "a.zarr", seed=1, **kw)
    with pytest.warns(SplitLeakWarning):
        build_from_files(d, tmp_path / "b.zarr", seed=1, **kw)
        build_from_files(d, tmp_path / "c.zarr", seed=2, **kw)
    a, b, c = (SampleStore.open(tmp_path / f"{n}.zarr").load() for n in "abc")
    assert set(a.meta["source"]) == {"normal_0.mat", "IR007_0.mat", "OR014_0.mat"}
    for cls in ["normal", "IR007", "OR014"]:
        assert np.sum((a.y == cls) & (a.meta["split"] == "test")) == 3  # round(0.3 * 10)
    np.testing.assert_array_equal(a.meta["split"], b.meta["split"])
    assert not np.array_equal(a.meta["split"], c.meta["split"])


def test_non_numeric_meta_stays_text(tmp_path):
    d = tmp_path / "r"
    d.mkdir()
    for name in ["h_fast.npy", "b_slow.npy"]:
        np.save(d / name, np.random.default_rng(0).standard_normal(64))
    build_from_files(d, tmp_path / "s.zarr", label_regex=r"^(?P<label>[hb])_", meta_regex=r"_(?P<speed>\w+)\.npy",
                     channel=None, window_length=32)
    smp = SampleStore.open(tmp_path / "s.zarr").load()
    assert sorted(set(smp.meta["speed"].tolist())) == ["fast", "slow"] and smp.X.shape == (4, 32)


@pytest.mark.parametrize("bad, match", [
    ("nan", "NaN or Inf"),
    ("short", "shorter than the window"),
    ("garbage", "not a readable mat file"),
    ("twochannels", "2 channels match"),
])
def test_bad_file_leaves_nothing(tmp_path, bad, match):
    d = _folder(tmp_path)
    p = d / "OR014_1.mat"
    if bad == "nan":
        x = np.ones(N)
        x[5] = np.nan
        scipy.io.savemat(p, {"X1_DE_time": x[:, None]})
    elif bad == "short":
        scipy.io.savemat(p, {"X1_DE_time": np.ones((50, 1))})
    elif bad == "garbage":
        p.write_bytes(b"MATLAB 5.0" + bytes(range(256)) * 3)
    else:
        scipy.io.savemat(p, {"X1_DE_time": np.ones((N, 1)), "X2_DE_time": np.ones((N, 1))})
    out = tmp_path / "o" / "s.zarr"
    with pytest.raises(DataFileError, match=match) as e:
        build_from_files(d, out, label_regex=REGEX, channel="DE_time", window_length=100)
    assert "OR014_1.mat" in str(e.value) and "\n" not in str(e.value)
    assert not out.exists()
    assert not out.parent.exists() or list(out.parent.iterdir()) == []


def test_argument_errors(tmp_path):
    d = _folder(tmp_path)
    with pytest.raises(ParameterError, match="named group"):
        select_files(d, r"^(normal|IR)")
    with pytest.raises(ParameterError, match="invalid"):
        select_files(d, r"(?P<label>")
    with pytest.raises(DataFileError, match="no file name match"):
        select_files(d, r"^(?P<label>zz)")
    with pytest.raises(DataFileError, match="does not match --meta-regex"):
        select_files(d, REGEX, meta_regex=r"_(?P<load>\d)_x")
    with pytest.raises(DataFileError, match="no such folder"):
        select_files(tmp_path / "none", REGEX)
    with pytest.raises(ParameterError, match="test-fraction"):
        build_from_files(d, tmp_path / "x.zarr", label_regex=REGEX, channel="DE", window_length=100,
                         test_fraction=1.5)
    build_from_files(d, tmp_path / "x.zarr", label_regex=REGEX, channel="DE", window_length=100)
    with pytest.raises(StoreError, match="already exists"):
        build_from_files(d, tmp_path / "x.zarr", label_regex=REGEX, channel="DE", window_length=100)
    build_from_files(d, tmp_path / "x.zarr", label_regex=REGEX, channel="DE", window_length=200, overwrite=True)
    assert SampleStore.open(tmp_path / "x.zarr").length == 200


def test_differing_fs_is_refused(tmp_path):
    d = tmp_path / "w"
    d.mkdir()
    np.savez(d / "h_0.npz", signal=np.ones(64), fs=1000.0)
    np.savez(d / "b_0.npz", signal=np.ones(64), fs=2000.0)
    with pytest.raises(DataFileError, match="sampling rate .* differs"):
        build_from_files(d, tmp_path / "s.zarr", label_regex=r"^(?P<label>[hb])_", channel="signal",
                         window_length=32)
    build_from_files(d, tmp_path / "s.zarr", label_regex=r"^(?P<label>[hb])_", channel="signal",
                     window_length=32, fs=500)
    assert SampleStore.open(tmp_path / "s.zarr").fs == 500.0


def test_optional_meta_group_gives_text_column(tmp_path):
    """normal_0 has no fault size: an optional group that does not take part gives ''."""
    d = _folder(tmp_path)
    build_from_files(d, tmp_path / "s.zarr", label_regex=r"^(?P<label>normal|IR|OR)",
                     meta_regex=r"^[A-Za-z]+(?P<size>\d{3})?.*_(?P<load>\d)\.mat$", channel="DE", window_length=500)
    smp = SampleStore.open(tmp_path / "s.zarr").load()
    assert sorted(set(smp.meta["size"].tolist())) == ["", "007", "014"]
    assert set(smp.meta["size"][smp.y == "normal"]) == {""} and smp.meta["load"].dtype.kind == "i"
