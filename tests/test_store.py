"""The sample store: atomic whole writes, unit-by-unit resumable builds, one reader for both."""

import json

import numpy as np
import pytest

from rvdiag.datasets import SampleStore, StoreBuilder, config_hash, write_store
from rvdiag.errors import StoreError


def _meta(n, split="train"):
    return {"split": [split] * n, "unit": list(range(n)), "load": np.arange(n, dtype=float)}


def test_write_and_read_round_trip(tmp_path):
    X = np.random.default_rng(0).normal(size=(6, 16))
    labels = ["b", "h", "b", "h", "b", "h"]
    meta = _meta(6)
    meta["split"] = ["train"] * 4 + ["test"] * 2
    path = write_store(tmp_path / "d.zarr", X, labels, meta, kind="measured", fs=1000.0, config={"a": 1})
    s = SampleStore.open(path)
    assert s.classes == ["b", "h"]
    assert s.n_samples == 6 and s.length == 16 and s.fs == 1000.0
    np.testing.assert_array_equal(s.label_names, labels)
    test = s.load("test")
    np.testing.assert_allclose(test.X, X[4:].astype(np.float32))
    np.testing.assert_array_equal(test.y, ["b", "h"])
    np.testing.assert_allclose(test.meta["load"], [4.0, 5.0])
    assert s.summary()["counts"] == {"b": {"test": 1, "train": 2}, "h": {"test": 1, "train": 2}}
    assert len(s.load("all").y) == 6


def test_write_refuses_existing_and_bad_input(tmp_path):
    X = np.ones((2, 4))
    write_store(tmp_path / "d.zarr", X, ["a", "b"], _meta(2), kind="measured", fs=None, config={})
    with pytest.raises(StoreError, match="already exists"):
        write_store(tmp_path / "d.zarr", X, ["a", "b"], _meta(2), kind="measured", fs=None, config={})
    with pytest.raises(StoreError, match="NaN"):
        write_store(tmp_path / "e.zarr", X * np.nan, ["a", "b"], _meta(2), kind="measured", fs=None, config={})
    assert not (tmp_path / "e.zarr").exists()
    assert [p.name for p in tmp_path.iterdir()] == ["d.zarr"]  # no temporary folders left behind


def test_open_rejects_foreign_or_missing(tmp_path):
    with pytest.raises(StoreError, match="no sample store"):
        SampleStore.open(tmp_path / "nope.zarr")
    (tmp_path / "x.zarr").mkdir()
    with pytest.raises(StoreError):
        SampleStore.open(tmp_path / "x.zarr")


def test_builder_resumes_and_matches_uninterrupted(tmp_path):
    cfg = {"seed": 1}
    rng = np.random.default_rng(1)
    units = [rng.normal(size=(3, 8)) for _ in range(4)]

    def build(path, stop_after=None):
        b = StoreBuilder(path, unit_rows=[3] * 4, length=8, classes=["T1", "T2"], config=cfg, fs=48000.0)
        for u in range(4):
            if u in b.committed_units():
                continue
            if stop_after is not None and u == stop_after:
                return b
            b.write_unit(u, units[u], ["T1" if u % 2 == 0 else "T2"] * 3, {"split": ["train"] * 3, "sev": [u * 0.1] * 3})
        b.finalize()
        return b

    build(tmp_path / "a.zarr")
    partial = build(tmp_path / "b.zarr", stop_after=2)
    assert partial.committed_units() == {0, 1}
    with pytest.raises(StoreError, match="unfinished"):
        SampleStore.open(tmp_path / "b.zarr")
    build(tmp_path / "b.zarr")
    a, b = SampleStore.open(tmp_path / "a.zarr"), SampleStore.open(tmp_path / "b.zarr")
    np.testing.assert_array_equal(a.load().X, b.load().X)
    np.testing.assert_array_equal(a.labels, b.labels)
    np.testing.assert_array_equal(a.meta["unit"], [0, 0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 3])
    np.testing.assert_allclose(b.meta["sev"], np.repeat([0.0, 0.1, 0.2, 0.3], 3))


def test_builder_refuses_other_config(tmp_path):
    StoreBuilder(tmp_path / "a.zarr", unit_rows=[1], length=4, classes=["T1"], config={"seed": 1}, fs=1.0)
    with pytest.raises(StoreError, match="different config"):
        StoreBuilder(tmp_path / "a.zarr", unit_rows=[1], length=4, classes=["T1"], config={"seed": 2}, fs=1.0)


def test_config_hash_is_order_independent():
    assert config_hash({"a": 1, "b": [1, 2]}) == config_hash({"b": [1, 2], "a": 1})
    assert config_hash({"a": 1}) != config_hash({"a": 2})
    json.dumps({"h": config_hash({})})
