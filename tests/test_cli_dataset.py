"""``rvdiag dataset`` commands: the two real-data examples (on subsets), bad input -> one line + exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rvdiag.cli import main
from rvdiag.datasets import SampleStore

from conftest import DATA, needs_real_data
from conftest import run_cli as run

SQ_FILES = tuple(f"spectraquest-gearbox/{c}30hz{load}.csv.gz" for c in "hb" for load in (0, 60))
CWRU_FILES = ("cwru-bearing/normal_0.mat", "cwru-bearing/IR007_0.mat", "cwru-bearing/OR021@6_0.mat")


def run_ok(args, capsys):
    try:
        main(args)
    except SystemExit as e:  # typer may exit 0 explicitly
        assert e.code in (0, None), capsys.readouterr().err
    return capsys.readouterr()


@needs_real_data(*SQ_FILES)
def test_spectraquest_example_on_a_subset(tmp_path, capsys):
    out = tmp_path / "sq.zarr"
    cap = run_ok(["dataset", "from-files", str(DATA / "spectraquest-gearbox"),
                  "--label-regex", r"^(?P<label>[hb])30hz", "--meta-regex", r"hz(?P<load>\d+)",
                  "--channel", "a1", "--window", "2048", "--include", r"30hz(0|60)\.", "--unknown-fs", "--out", str(out)],
                 capsys)
    assert "wrote" in cap.out
    s = SampleStore.open(out)
    smp = s.load()
    assert s.classes == ["b", "h"] and s.fs is None and s.length == 2048 and s.attrs["kind"] == "measured"
    assert sorted(set(smp.meta["load"].tolist())) == [0, 60]
    assert set(smp.meta["source"]) == {"b30hz0.csv.gz", "b30hz60.csv.gz", "h30hz0.csv.gz", "h30hz60.csv.gz"}
    cap = run_ok(["dataset", "info", str(out), "--json"], capsys)
    info = json.loads(cap.out)
    assert info["n_samples"] == s.n_samples and set(info["counts"]) == {"b", "h"}


@needs_real_data(*CWRU_FILES)
def test_cwru_example_on_a_subset(tmp_path, capsys):
    out = tmp_path / "cwru.zarr"
    run_ok(["dataset", "from-files", str(DATA / "cwru-bearing"),
            "--label-regex", r"^(?P<label>normal|B\d{3}|IR\d{3}|OR\d{3})", "--meta-regex", r"_(?P<load>\d)\.mat$",
            "--channel", "DE_time", "--window", "2048", "--fs", "12000", "--include", r"^(normal|IR007|OR021@6)_0",
            "--scalar", "rpm=RPM", "--test-fraction", "0.25", "--split-by", "window", "--out", str(out)], capsys)
    s = SampleStore.open(out)
    smp = s.load()
    assert s.classes == ["IR007", "OR021", "normal"] and s.fs == 12000.0
    assert set(smp.meta["channel"]) == {"X097_DE_time", "X105_DE_time", "X234_DE_time"}
    assert set(smp.meta["split"]) == {"train", "test"} and set(smp.meta["load"]) == {0}
    assert 1790 < smp.meta["rpm"].min() <= smp.meta["rpm"].max() < 1800
    assert np.sum(smp.y == "normal") == 243938 // 2048


def test_channels_command(tmp_path, capsys):
    p = tmp_path / "x.csv"
    p.write_text("acc_x,acc_y\n1,2\n3,4\n")
    cap = run_ok(["dataset", "channels", str(p)], capsys)
    assert cap.out.split() == ["acc_x", "acc_y"]


def _folder(tmp_path: Path) -> Path:
    d = tmp_path / "raw"
    d.mkdir()
    rng = np.random.default_rng(0)
    for name in ["h_0.csv", "b_0.csv"]:
        (d / name).write_text("a1\n" + "\n".join(map(repr, rng.standard_normal(300))) + "\n")
    return d


@pytest.mark.parametrize("case, needle", [
    ("nan", "b_0.csv: channel 'a1' contains 1 NaN"),
    ("empty", "b_0.csv: empty file"),
    ("window", "shorter than the window of 5000"),
    ("nochannel", "no channel matches 'zz'"),
    ("unknown", "b_0.xlsx: unknown format"),
    ("label", "needs a named group (?P<label>...)"),
    ("exists", "already exists"),
])
def test_bad_input_one_line_exit_2_nothing_left(tmp_path, capsys, case, needle):
    d = _folder(tmp_path)
    out = tmp_path / "o" / "s.zarr"
    args = {"label": r"^(?P<label>[hb])_", "channel": "a1", "window": "100"}
    if case == "nan":
        (d / "b_0.csv").write_text("a1\n1\n2\nnan\n" + "1\n" * 300)
    elif case == "empty":
        (d / "b_0.csv").write_text("")
    elif case == "window":
        args["window"] = "5000"
    elif case == "nochannel":
        args["channel"] = "zz"
    elif case == "unknown":
        (d / "b_0.xlsx").write_bytes(b"PK\x03\x04")
    elif case == "label":
        args["label"] = r"^([hb])_"
    elif case == "exists":
        out.mkdir(parents=True)
    code, stdout, err = run(["dataset", "from-files", str(d), "--label-regex", args["label"], "--channel",
                             args["channel"], "--window", args["window"], "--unknown-fs", "--out", str(out)], capsys)
    assert code == 2, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0], err
    assert "Traceback" not in err
    if case != "exists":
        assert not out.exists()
        assert not out.parent.exists() or list(out.parent.iterdir()) == []


def test_bad_scalar_spec_and_missing_store(tmp_path, capsys):
    d = _folder(tmp_path)
    code, _, err = run(["dataset", "from-files", str(d), "--label-regex", r"^(?P<label>[hb])_", "--window", "100",
                        "--scalar", "rpm", "--out", str(tmp_path / "s.zarr")], capsys)
    assert code == 2 and "expected NAME=REGEX" in err
    code, _, err = run(["dataset", "info", str(tmp_path / "none.zarr")], capsys)
    assert code == 2 and err.startswith("error: no sample store")


def _two_loads(tmp_path: Path) -> Path:
    """Two classes x three recordings of 600 points (windows of 100 with hop 50 overlap)."""
    d = tmp_path / "raw3"
    d.mkdir()
    rng = np.random.default_rng(1)
    for c in "hb":
        for load in (0, 30, 60):
            (d / f"{c}_{load}.csv").write_text("a1\n" + "\n".join(map(repr, rng.standard_normal(600))) + "\n")
    return d


def test_from_files_test_fraction_holds_out_whole_files(tmp_path, capsys):
    """By default no recording contributes windows to both splits (the old random split of
    windows put overlapping neighbours on both sides)."""
    out = tmp_path / "s.zarr"
    cap = run_ok(["dataset", "from-files", str(_two_loads(tmp_path)), "--label-regex", r"^(?P<label>[hb])_",
                  "--window", "100", "--hop", "50", "--test-fraction", "0.3", "--unknown-fs", "-o", str(out), "-q"],
                 capsys)
    assert "warning" not in cap.err
    smp = SampleStore.open(out).load()
    per_file = {src: set(smp.meta["split"][smp.meta["source"] == src]) for src in set(smp.meta["source"])}
    assert len(per_file) == 6 and all(len(s) == 1 for s in per_file.values()), per_file
    assert sorted(src[0] for src, s in per_file.items() if s == {"test"}) == ["b", "h"]  # round(0.3 * 3) = 1 each
    assert np.sum(smp.meta["split"] == "test") == 2 * 11  # (600 - 100) // 50 + 1 windows per file


def test_from_files_window_split_is_explicit_and_warns_once(tmp_path, capsys):
    out = tmp_path / "s.zarr"
    cap = run_ok(["dataset", "from-files", str(_two_loads(tmp_path)), "--label-regex", r"^(?P<label>[hb])_",
                  "--window", "100", "--hop", "50", "--test-fraction", "0.3", "--split-by", "window", "--unknown-fs",
                  "-o", str(out), "-q"], capsys)
    warnings = [ln for ln in cap.err.splitlines() if ln.startswith("warning:")]
    assert warnings == ["warning: --split-by window puts neighbouring windows of one recording in both train and "
                        "test: the test accuracy is optimistic (the default --split-by unit holds out whole files)"]
    smp = SampleStore.open(out).load()
    both = [src for src in set(smp.meta["source"]) if len(set(smp.meta["split"][smp.meta["source"] == src])) == 2]
    assert both  # the leak the default avoids
    assert np.sum(smp.meta["split"] == "test") == 2 * round(0.3 * 33)
