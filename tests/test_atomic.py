"""rvdiag.atomic, the one home of atomic writes: an interrupted write leaves the old file or folder as it was,
a finished one honours the umask, and every writer of a whole file or folder goes through it."""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import numpy as np
import pytest

from rvdiag import atomic
from rvdiag.atomic import atomic_file, atomic_write, staged_directory


class Interrupted(Exception):
    pass


@pytest.fixture
def umask_027():
    old = os.umask(0o027)
    try:
        yield 0o027
    finally:
        os.umask(old)


def _siblings(path: Path) -> list[str]:
    return sorted(p.name for p in path.parent.iterdir())


@pytest.mark.parametrize("mode, old, new", [("wb", b"old bytes", b"new"), ("w", "old text", "new")])
def test_an_interrupted_file_write_leaves_the_old_file(tmp_path, mode, old, new):
    p = tmp_path / "f.bin"
    atomic_write(p, old)
    with pytest.raises(Interrupted):
        with atomic_file(p, mode) as fh:
            fh.write(new)
            fh.flush()
            raise Interrupted  # mid-write: part of the new content is already in the temporary file
    assert (p.read_bytes() if mode == "wb" else p.read_text()) == old
    assert _siblings(p) == ["f.bin"]  # no temporary file left behind


def test_an_interrupted_first_write_leaves_nothing(tmp_path):
    p = tmp_path / "sub" / "f.json"
    with pytest.raises(Interrupted):
        with atomic_file(p, "w") as fh:
            fh.write("{")
            raise Interrupted
    assert not p.exists() and list(p.parent.iterdir()) == []


def test_a_finished_write_replaces_the_file_and_honours_the_umask(tmp_path, umask_027):
    p = tmp_path / "f.txt"
    p.write_text("old")
    assert atomic_write(p, "new ü") == p
    assert p.read_text(encoding="utf-8") == "new ü"
    assert stat.S_IMODE(p.stat().st_mode) == 0o666 & ~0o027  # not mkstemp's 0600
    assert _siblings(p) == ["f.txt"]


def test_a_staged_folder_honours_the_umask_and_an_interrupted_one_leaves_the_old(tmp_path, umask_027):
    d = tmp_path / "store"
    with staged_directory(d) as tmp:
        (tmp / "a").write_text("old")
    assert stat.S_IMODE(d.stat().st_mode) == 0o777 & ~0o027  # not mkdtemp's 0700
    with pytest.raises(Interrupted):
        with staged_directory(d) as tmp:
            (tmp / "a").write_text("new")
            (tmp / "b").write_text("new")
            raise Interrupted
    assert sorted(p.name for p in d.iterdir()) == ["a"] and (d / "a").read_text() == "old"
    assert _siblings(d) == ["store"]


def test_only_whole_file_modes_are_accepted(tmp_path):
    with pytest.raises(ValueError):
        with atomic_file(tmp_path / "f", "a"):
            pass


def _interrupt_rename(monkeypatch):
    """Make the final rename fail, as a crash between writing and swapping in would."""
    def boom(*_a, **_k):
        raise Interrupted
    monkeypatch.setattr(atomic.os, "replace", boom)


def test_every_file_writer_goes_through_the_one_home(tmp_path, monkeypatch):
    from rvdiag.dynamics.results import SimulationResult
    from rvdiag.evaluation.report import write_report
    from rvdiag.models.card import write_card

    report, card_dir = tmp_path / "r.html", tmp_path / "model"
    card_dir.mkdir()
    write_report(report, "<p>old</p>")
    write_card(card_dir, {"kind": "cnn", "classes": ["H", "T1"], "input_length": 8})
    old_card = (card_dir / "card.json").read_bytes()
    res = SimulationResult(np.zeros((1, 8)), 100.0, {"seed": 1}, ["acc"])
    res.to_npz(tmp_path / "sim.npz")
    old_npz = (tmp_path / "sim.npz").read_bytes()

    _interrupt_rename(monkeypatch)
    with pytest.raises(Interrupted):
        write_report(report, "<p>new</p>")
    with pytest.raises(Interrupted):
        write_card(card_dir, {"kind": "cnn", "classes": ["H", "T2"], "input_length": 8})
    with pytest.raises(Interrupted):
        SimulationResult(np.ones((1, 8)), 100.0, {"seed": 2}, ["acc"]).to_npz(tmp_path / "sim.npz")
    assert report.read_text() == "<p>old</p>"
    assert (card_dir / "card.json").read_bytes() == old_card
    assert (tmp_path / "sim.npz").read_bytes() == old_npz
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model", "r.html", "sim.npz"]
    assert sorted(p.name for p in card_dir.iterdir()) == ["card.json"]


def test_the_store_writes_through_the_one_home(tmp_path, monkeypatch, umask_027):
    from rvdiag.datasets.store import SampleStore, StoreBuilder, write_store

    path = tmp_path / "s.zarr"
    write_store(path, np.zeros((2, 4)), ["H", "T1"], {"split": ["train", "test"], "unit": [0, 1]},
                kind="measured", fs=10.0, config={})
    assert stat.S_IMODE(path.stat().st_mode) == 0o777 & ~0o027  # was mkdtemp's 0700 before rvdiag.atomic
    b = StoreBuilder(tmp_path / "b.zarr", unit_rows=[1, 1], length=4, classes=["H", "T1"], config={"a": 1},
                     fs=10.0)
    b.write_unit(0, np.zeros((1, 4)), ["H"], {"split": ["train"]})
    unit0 = (tmp_path / "b.zarr" / "_units" / "0.json").read_text()
    assert json.loads(unit0)["labels"] == ["H"]

    _interrupt_rename(monkeypatch)
    with pytest.raises(Interrupted):
        b.write_unit(0, np.ones((1, 4)), ["T1"], {"split": ["test"]})
    assert (tmp_path / "b.zarr" / "_units" / "0.json").read_text() == unit0
    assert sorted(p.name for p in (tmp_path / "b.zarr" / "_units").iterdir()) == ["0.json"]
    assert SampleStore.open(path).label_names.tolist() == ["H", "T1"]
