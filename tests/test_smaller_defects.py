"""Smaller defects found by a review as a new user: each test fails on the code before the fix."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import run_cli


def test_a_load_far_beyond_the_rated_torque_is_refused(tmp_path, capsys):
    code, _, err = run_cli(["simulate", "--output-speed", "30", "--load", "99999", "-o", tmp_path / "x.npz"], capsys)
    assert code == 2 and err.count("\n") == 1
    assert err.startswith("error: --load 99999 N m is 599x the rated torque 167 N m") and "835 N m" in err
    assert not (tmp_path / "x.npz").exists()


def test_fs_is_the_currents_rate_with_signal_current():
    from rvdiag.cli.simulate import _rates

    assert _rates("current", 1000.0, None) == (48000.0, 1000.0)  # was: integrated at 1 kHz, "unstable"
    assert _rates("current", None, 2000.0) == (48000.0, 2000.0)
    assert _rates("vibration", None, None) == (48000.0, 1000.0)
    assert _rates("both", 24000.0, 1000.0) == (24000.0, 1000.0)
    from rvdiag.errors import ParameterError

    with pytest.raises(ParameterError, match="not both"):
        _rates("current", 1000.0, 2000.0)


def test_a_time_column_printed_with_9_digits_gives_the_rate_it_was_written_at(tmp_path):
    from rvdiag.io import read_signal
    from rvdiag.io.readers import fs_from_time

    t = np.arange(48000) / 48000.0
    rounded = np.array([float(f"{x:.9g}") for x in t])
    assert 1.0 / np.median(np.diff(rounded)) == pytest.approx(48000.768, abs=1e-3)  # the old estimate
    assert fs_from_time(rounded) == 48000.0
    f = tmp_path / "r.csv"
    f.write_text("time,acc\n" + "\n".join(f"{x:.9g},{v!r}" for x, v in zip(t[:4800], np.sin(t[:4800]))) + "\n")
    assert read_signal(f, "acc").fs == 48000.0
    # a column with a gap keeps the median step
    gap = np.r_[t[:100], t[150:300]]
    assert fs_from_time(gap) == 48000.0
    assert fs_from_time(np.zeros(5)) is None


def test_from_files_refuses_files_with_no_rate_unless_fs_or_unknown_fs(tmp_path, capsys):
    d = tmp_path / "raw"
    d.mkdir()
    rng = np.random.default_rng(0)
    for c in "hb":
        (d / f"{c}_0.csv").write_text("a1\n" + "\n".join(map(repr, rng.standard_normal(400))) + "\n")
    base = ["dataset", "from-files", d, "--label-regex", r"^(?P<label>[hb])_", "--window", "100", "-q"]
    code, _, err = run_cli(base + ["--out", tmp_path / "a.zarr"], capsys)
    assert code == 2 and "states no sampling rate" in err and "--fs" in err and err.count("\n") == 1
    assert not (tmp_path / "a.zarr").exists()
    assert run_cli(base + ["--fs", "1000", "--out", tmp_path / "b.zarr"], capsys)[0] == 0
    assert run_cli(base + ["--unknown-fs", "--out", tmp_path / "c.zarr"], capsys)[0] == 0


def test_the_readme_measured_data_example_gives_windows_the_default_model_takes():
    import re

    from conftest import REPO
    from rvdiag.models.cnn import DEFAULT_INPUT_LENGTH
    from rvdiag.registry import RECOMMENDED_TRAINING

    readme = (REPO / "README.md").read_text()
    line = next(x for x in readme.splitlines() if "dataset from-files DIR" in x)
    assert int(re.search(r"--window (\d+)", line).group(1)) == DEFAULT_INPUT_LENGTH[RECOMMENDED_TRAINING["model"]]
