"""A motor-current model diagnoses a current file: the library's channel, the line table, the speed estimate."""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.io
from conftest import run_cli as run
from rvdiag.errors import ParameterError
from rvdiag.kinematics import characteristic_frequencies
from rvdiag.motor.lines import current_lines, output_speed_from_current, line_height, amplitude_spectrum
from rvdiag.params import ReducerParams

PARAMS = ReducerParams.default()


# ------------------------------------------------------------------------------ the line table, on known sinusoids
def _synthetic(speed=45.0, fs=1000.0, n=4096, sideband=0.01, noise=1e-4, seed=0):
    fr = characteristic_frequencies(PARAMS, output_speed_deg_s=speed)
    t = np.arange(n) / fs
    rng = np.random.default_rng(seed)
    x = (2.0 * np.cos(2 * np.pi * fr.fe * t) + sideband * np.cos(2 * np.pi * (fr.fe + fr.f1) * t + 0.3)
         + noise * rng.standard_normal(n))
    return x, fr


def test_line_amplitude_and_height_of_a_known_sideband():
    x, fr = _synthetic()
    table = current_lines(x, 1000.0, PARAMS, output_speed_deg_s=45.0)
    side = table["lines"]["fe+1f1"]
    # off-bin sinusoids read low by the Hann scalloping loss, at most 1.42 dB (Harris 1978, Table 1)
    assert 0.01 * 10 ** (-1.43 / 20) <= side["amplitude"] <= 0.01 * 1.001
    # 1e-4 white noise: the floor of a Hann amplitude spectrum of 4096 points sits near 2e-6, ~70 dB below 0.01
    assert side["height_db"] > 50.0
    assert table["lines"]["fe-1f1"]["height_db"] < 15.0  # no line there: the floor's own spread
    assert table["lines"]["fe"]["amplitude"] == pytest.approx(2.0, rel=0.16)
    assert table["frequencies"]["fe"] == pytest.approx(fr.fe)


def test_speed_is_estimated_from_the_supply_line():
    for speed in (30.0, 45.0, 60.0):
        x, _ = _synthetic(speed=speed)
        # one bin of 0.244 Hz at f_e = p f1 = 5 x 121 x speed / 360 Hz: speed to within 0.5 %
        assert output_speed_from_current(x, 1000.0, PARAMS) == pytest.approx(speed, rel=0.005)
    table = current_lines(_synthetic(speed=60.0)[0], 1000.0, PARAMS)
    assert table["speed_source"] == "strongest line taken as f_e"
    assert table["output_speed_deg_s"] == pytest.approx(60.0, rel=0.005)


def test_lines_beyond_the_spectrum_are_null_and_bad_input_is_refused():
    x, _ = _synthetic(speed=60.0)
    table = current_lines(x, 1000.0, PARAMS, output_speed_deg_s=60.0)
    assert table["lines"]["5fe"]["amplitude"] is None  # 504 Hz, over the 500 Hz Nyquist rate
    f, amp = amplitude_spectrum(x, 1000.0)
    assert np.isnan(line_height(amp, f[1], 1.0)[0])  # no floor below a line at 1 Hz
    with pytest.raises(ParameterError, match="at least"):
        current_lines(x[:100], 1000.0, PARAMS)
    with pytest.raises(ParameterError, match="speed"):
        output_speed_from_current(np.zeros(4096), 1000.0, PARAMS)


# ------------------------------------------------------------------------------ diagnose with a current model
@pytest.fixture(scope="module")
def current_model(tmp_path_factory):
    from rvdiag.library import LibraryConfig, build_library

    d = tmp_path_factory.mktemp("cur")
    cfg = LibraryConfig.from_dict({
        "mode": "split-by-simulation", "seed": 5, "channel": "i_a",
        "model": {"signal": "current", "substeps": 4},
        "signal": {"fs": 1000.0, "duration_s": 0.512, "transient_s": 0.05, "segment_length": 256, "hop": 128},
        "operation": {"output_speed_deg_s": [45.0], "load_Nm": 60.0, "noise_snr_db": 60.0},
        "split": {"simulations_per_state": 3, "test_simulations_per_state": 1},
        "states": {"T1": {}, "T2": {"broken_fraction": 1.0}},
    }, source="current.toml")
    build_library(cfg, d / "cur.zarr", workers=0, progress=False)
    from rvdiag.cli import main

    try:
        main(["train", str(d / "cur.zarr"), "--out", str(d / "model"), "--model", "svm", "--features", "time", "-q"])
    except SystemExit as exc:
        assert not exc.code, f"rvdiag train exited with {exc.code}"
    from rvdiag.dynamics import ModelSettings, simulate

    sim = simulate(output_speed_deg_s=45.0, duration_s=0.8, load_Nm=60.0, signal="current", seed=9,
                   settings=ModelSettings(substeps=4))
    names = list(sim.current_names)
    cur = {n: sim.current[names.index(n)] for n in ("i_a", "i_b", "i_c")}
    t = np.arange(cur["i_a"].size) / sim.current_fs
    csv = d / "current.csv"  # i_b first: the model must pick i_a by name, not by position
    np.savetxt(csv, np.column_stack([t, cur["i_b"], cur["i_a"], cur["i_c"]]), delimiter=",",
               header="time_s,i_b,i_a,i_c", comments="")
    sim.current_only().to_npz(d / "current.npz")  # what `rvdiag simulate --signal current` writes
    mat = d / "current.mat"
    scipy.io.savemat(mat, {"Ia": cur["i_a"], "Ib": cur["i_b"], "fs": sim.current_fs})
    return d / "model", csv, mat, cur


def test_the_card_records_a_current_library(current_model):
    card = json.loads((current_model[0] / "card.json").read_text())
    assert card["training_store"]["signal"] == "current"
    assert card["training_store"]["channel"] == "i_a"


def test_diagnose_reads_the_phase_current_by_name_and_gives_the_line_table(current_model, capsys):
    model, csv, _, cur = current_model
    code, out, err = run(["diagnose", model, csv, "--json"], capsys)
    assert code == 0, err
    out = json.loads(out)
    assert out["channel"] == "i_a" and out["signal"] == "current"
    assert out["n_windows"] == 3 and out["diagnosis"] in ("T1", "T2")
    assert sum(out["probabilities"].values()) == pytest.approx(1.0)
    lines = out["current_lines"]
    # 60 N m at 45 deg/s: i_q = T_L / (i K_t) = 60 / 121 / 0.332 = 1.49 A, the supply line's amplitude
    # (read low by at most the Hann window's 1.42 dB scalloping loss: 800 points give 1.25 Hz bins)
    i_q = 60.0 / 121.0 / (1.5 * 5 * 0.0443)
    assert i_q * 10 ** (-1.43 / 20) * 0.98 <= lines["lines"]["fe"]["amplitude"] <= i_q * 1.03
    assert lines["output_speed_deg_s"] == pytest.approx(45.0, rel=0.02)
    assert "indicators" not in out
    # the same window read as i_b by --channel gives another signal, so the channel choice is real
    code, out_b, err = run(["diagnose", model, csv, "--channel", "^i_b$", "--json"], capsys)
    out_b = json.loads(out_b)
    assert code == 0 and out_b["channel"] == "i_b"
    # i_b lags i_a by 120 deg: the model (trained on i_a) either scores it otherwise or does not recognise it
    assert out_b["recognised"] is False or out_b["windows"][0]["probabilities"] != out["windows"][0]["probabilities"]


def test_diagnose_reads_i_a_of_a_simulated_current_npz(current_model, capsys):
    model, csv, _, _ = current_model
    code, out, err = run(["diagnose", model, csv.with_suffix(".npz"), "--json"], capsys)
    assert code == 0, err
    out_npz = json.loads(out)
    code, out, err = run(["diagnose", model, csv, "--json"], capsys)
    out_csv = json.loads(out)
    assert out_npz["channel"] == "signal[0]"  # the row the file names i_a
    for a, b in zip(out_npz["windows"], out_csv["windows"]):  # the same current as the CSV's i_a column
        assert a["probabilities"] == pytest.approx(b["probabilities"], abs=1e-9)


def test_diagnose_a_mat_current_file_needs_its_channel_named(current_model, capsys):
    model, _, mat, _ = current_model
    code, out, err = run(["diagnose", model, mat], capsys)
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and "--channel" in err and "i_a" in err and "Traceback" not in err
    code, out, err = run(["diagnose", model, mat, "--channel", "Ia", "--meta", "output_speed_deg_s=45", "--json"],
                         capsys)
    assert code == 0, err
    out = json.loads(out)
    assert out["current_lines"]["speed_source"] == "--meta output_speed_deg_s"
    assert out["channel"] == "Ia"


def test_train_refuses_a_class_too_small_for_the_svm_calibration(tmp_path, capsys):
    from rvdiag.datasets import write_store

    rng = np.random.default_rng(0)
    X = rng.standard_normal((8, 256))
    y = np.array(["T1"] * 6 + ["T2"] * 2)
    write_store(tmp_path / "small.zarr", X.astype(np.float32), y,
                meta={"split": ["train"] * 8, "unit": list(range(8))}, kind="simulated", fs=1000.0,
                config={"name": "small"})
    code, _, err = run(["train", tmp_path / "small.zarr", "--out", tmp_path / "m", "--model", "svm", "--features",
                        "time", "-q"], capsys)
    assert code == 2 and "'T2' has 2 training sample(s)" in err and "Traceback" not in err
    assert not (tmp_path / "m").exists()
