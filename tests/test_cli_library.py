"""``rvdiag library build`` / ``rvdiag library info``: output, JSON, and one-line errors with exit code 2."""

import json

import pytest
import tomli_w

from rvdiag.cli import build_app, main
from rvdiag.datasets import StoreBuilder

CONFIG = {
    "name": "clitest",
    "mode": "paper",
    "seed": 3,
    "simulator": "rvdiag.library.synthetic:simulate",
    "signal": {"fs": 2000.0, "duration_s": 1.0, "segment_length": 200},
    "operation": {"output_speed_deg_s": 45.0, "load_Nm": 70.0, "noise_snr_db": 20.0},
    "split": {"train_per_state": 6, "test_per_state": 4},
    "states": {"T1": {}, "T2": {}, "T4": {"crack_depth": 6e-4}},
}


def run(args):
    """Run the CLI; return the exit code (0 when main returns normally)."""
    try:
        main(args)
    except SystemExit as exc:
        return 0 if exc.code is None else exc.code
    return 0


@pytest.fixture
def config_file(tmp_path):
    path = tmp_path / "lib.toml"
    path.write_text(tomli_w.dumps(CONFIG), encoding="utf-8")
    return path


def test_build_then_info(tmp_path, config_file, capsys):
    out = tmp_path / "lib.zarr"
    assert run(["library", "build", str(config_file), "--out", str(out), "--workers", "0", "--quiet"]) == 0
    assert "30 samples from 3 simulations (3 built" in capsys.readouterr().out
    assert run(["library", "build", str(config_file), "--out", str(out), "--workers", "0", "--quiet"]) == 0
    assert "already complete" in capsys.readouterr().out
    assert run(["library", "info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "30 samples of 200 points at 2000 Hz" in text and "root crack" in text and "mode paper" in text
    assert run(["library", "info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["counts"] == {s: {"train": 6, "test": 4} for s in ("T1", "T2", "T4")}
    assert info["length"] == 200 and info["fs"] == 2000.0 and info["kind"] == "simulated"
    assert info["config"]["states"]["T4"]["crack_depth"] == 6e-4 and info["library"]["seed"] == 3
    assert "crack_depth" in info["meta_columns"] and "seed" in info["meta_columns"]


def one_error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


@pytest.mark.parametrize(
    "args, message",
    [
        (["library", "build", "{dir}/missing.toml", "--out", "{dir}/x.zarr"], "library config not found"),
        (["library", "build", "{cfg}", "--out", "{dir}/x.zarr", "--workers", "-1"], "--workers must be >= 0"),
        (["library", "build", "{cfg}", "--out", "{dir}/x.zarr", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"],
         "not both"),
        (["library", "build", "{cfg}", "--out", "{dir}/x.zarr", "--workers", "two"], "--workers"),
        (["library", "build", "{cfg}"], "--out"),
        (["library", "info", "{dir}/nothing.zarr"], "no sample store"),
        (["library", "info", "{cfg}"], "not a Zarr sample store"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, config_file, capsys, args, message):
    args = [a.format(dir=tmp_path, cfg=config_file) for a in args]
    assert run(args) == 2
    assert message in one_error_line(capsys)


def test_bad_config_key_is_named(tmp_path, capsys):
    bad = dict(CONFIG, signal={**CONFIG["signal"], "segment_length": 5000})
    path = tmp_path / "bad.toml"
    path.write_text(tomli_w.dumps(bad), encoding="utf-8")
    assert run(["library", "build", str(path), "--out", str(tmp_path / "x.zarr"), "--workers", "0"]) == 2
    line = one_error_line(capsys)
    assert "bad.toml: [signal] segment_length: 5000 points exceed" in line
    assert not (tmp_path / "x.zarr").exists()


def test_out_that_is_not_a_store_or_another_config_is_refused(tmp_path, config_file, capsys):
    (tmp_path / "junk.zarr").mkdir()
    (tmp_path / "junk.zarr" / "file.txt").write_text("x")
    assert run(["library", "build", str(config_file), "--out", str(tmp_path / "junk.zarr"), "--workers", "0", "-q"]) == 2
    assert "not a" in one_error_line(capsys)
    out = tmp_path / "a.zarr"
    assert run(["library", "build", str(config_file), "--out", str(out), "--workers", "0", "-q"]) == 0
    capsys.readouterr()
    other = tmp_path / "other.toml"
    other.write_text(tomli_w.dumps(dict(CONFIG, seed=4)), encoding="utf-8")
    assert run(["library", "build", str(other), "--out", str(out), "--workers", "0", "-q"]) == 2
    assert "different config" in one_error_line(capsys)


def test_unreachable_scheduler_is_an_error(tmp_path, config_file, capsys):
    import dask
    import distributed  # noqa: F401  loads its config defaults first: leaving dask.config.set restores the
    # config as it found it, and would drop a 'distributed' section that an import inside the block added

    with dask.config.set({"distributed.comm.timeouts.connect": "2s"}):
        code = run(["library", "build", str(config_file), "--out", str(tmp_path / "x.zarr"), "-q",
                    "--scheduler", "tcp://127.0.0.1:9"])
    assert code == 2
    assert "cannot reach the Dask scheduler at 'tcp://127.0.0.1:9'" in one_error_line(capsys)


def test_ctrl_c_reports_progress_and_info_says_how_to_finish(tmp_path, config_file, capsys, monkeypatch):
    original = StoreBuilder.write_unit

    def interrupt_at_unit_2(self, unit, *args, **kwargs):
        if unit == 2:
            raise KeyboardInterrupt
        return original(self, unit, *args, **kwargs)

    monkeypatch.setattr(StoreBuilder, "write_unit", interrupt_at_unit_2)
    out = tmp_path / "c.zarr"
    # the command's own exit code (typer.Exit(130)), as the Typer app returns it
    rv = build_app()(args=["library", "build", str(config_file), "--out", str(out), "--workers", "0", "-q"],
                     prog_name="rvdiag", standalone_mode=False)
    assert rv == 130
    err = capsys.readouterr().err
    assert "interrupted: " in err and "2 of 3 simulations committed" in err and "Traceback" not in err
    assert run(["library", "info", str(out)]) == 2
    assert "unfinished build (2 of 3 simulations committed): re-run" in one_error_line(capsys)
    monkeypatch.setattr(StoreBuilder, "write_unit", original)
    assert run(["library", "build", str(config_file), "--out", str(out), "--workers", "0", "-q"]) == 0
    assert "2 were already committed" in capsys.readouterr().out


def test_build_from_a_given_parameter_file_records_it(tmp_path, config_file, capsys):
    """``--params`` (what ``rvdiag update`` writes) replaces the config's parameter set and is recorded; a bad
    file is one error line before anything is written."""
    from rvdiag.params import ReducerParams

    mine = tmp_path / "updated.toml"
    ReducerParams.default().replace(bearings={"sun_support": 2.5e8}).save(mine)
    out = tmp_path / "p.zarr"
    assert run(["library", "build", str(config_file), "--out", str(out), "--workers", "0", "-q",
                "--params", str(mine)]) == 0
    capsys.readouterr()
    assert run(["library", "info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["config"]["params"] == str(mine.resolve())
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 'x'\n[stage1]\nsun_teeth = -3\n", encoding="utf-8")
    assert run(["library", "build", str(config_file), "--out", str(tmp_path / "q.zarr"), "--workers", "0", "-q",
                "--params", str(bad)]) == 2
    assert "bad.toml" in one_error_line(capsys)
    assert not (tmp_path / "q.zarr").exists()


def test_seed_option_draws_the_library_anew_and_is_recorded(tmp_path, config_file, capsys):
    """``--seed`` replaces the config's seed: other draws (another store, refused as the first's resume), the
    same draws as a config that states that seed; a bad seed is one error line."""
    import numpy as np

    from rvdiag.datasets import SampleStore

    a, b = tmp_path / "a.zarr", tmp_path / "b.zarr"
    assert run(["library", "build", str(config_file), "--out", str(a), "--workers", "0", "-q"]) == 0
    assert run(["library", "build", str(config_file), "--out", str(b), "--workers", "0", "-q", "--seed", "4"]) == 0
    same = tmp_path / "seed4.toml"
    same.write_text(tomli_w.dumps({**CONFIG, "seed": 4}), encoding="utf-8")
    c = tmp_path / "c.zarr"
    assert run(["library", "build", str(same), "--out", str(c), "--workers", "0", "-q"]) == 0
    xa, xb, xc = (SampleStore.open(p).load().X for p in (a, b, c))
    assert not np.array_equal(xa, xb) and np.array_equal(xb, xc)
    capsys.readouterr()
    assert run(["library", "info", str(b), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["config"]["seed"] == 4
    assert run(["library", "build", str(config_file), "--out", str(tmp_path / "d.zarr"), "--workers", "0", "-q",
                "--seed", "-1"]) == 2
    assert "seed" in one_error_line(capsys)
