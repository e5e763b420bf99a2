"""`rvdiag simulate` and `rvdiag freqs`: outputs, repeatability from the recorded settings, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rvdiag.dynamics import ModelSettings, SimulationResult, simulate
from rvdiag.kinematics import FREQUENCY_KEYS
from rvdiag.params import ReducerParams
from conftest import run_cli as run


def test_freqs_json_keys_and_values(capsys):
    code, out, err = run(["freqs", "--output-speed", "45", "--json"], capsys)
    assert code in (0, None), err
    d = json.loads(out)
    assert tuple(d) == FREQUENCY_KEYS
    assert abs(d["fsp"] - 165.0) < 1e-9 and abs(d["fcs"] - 195.0) < 1e-9


def test_freqs_table(capsys):
    code, out, _ = run(["freqs", "--input-speed", "1000"], capsys)
    assert code in (0, None)
    assert "fsp" in out and "stage-1 mesh" in out


def test_simulate_writes_repeatable_npz(tmp_path, capsys):
    path = tmp_path / "s.npz"
    argv = ["simulate", "--state", "T2", "--output-speed", "30", "--load", "60", "--duration", "0.01",
            "--fs", "12000", "--substeps", "40", "--transient", "0.005", "--snr-db", "20", "--seed", "3",
            "--quiet", "--out", str(path)]
    code, out, err = run(argv, capsys)
    assert code in (0, None), err
    with np.load(path, allow_pickle=False) as z:
        assert set(z.files) >= {"signal", "fs", "settings"}
        signal, fs, settings = z["signal"], float(z["fs"]), json.loads(str(z["settings"]))
    assert signal.shape == (2, 120) and fs == 12000.0 and np.all(np.isfinite(signal))
    assert settings["seed"] == 3 and settings["state"] == "T2" and settings["noise_snr_db"] == 20.0
    assert settings["params"] == ReducerParams.default().to_dict()
    assert settings["model_settings"]["substeps"] == 40
    # the recorded settings repeat the run exactly through the Python API
    from rvdiag.gears import ToothFaults

    again = simulate(ReducerParams.from_dict(settings["params"]), ToothFaults.for_state(settings["state"]),
                     output_speed_deg_s=settings["output_speed_deg_s"], load_Nm=settings["load_Nm"],
                     duration_s=settings["duration_s"], fs=settings["fs"],
                     noise_snr_db=settings["noise_snr_db"], seed=settings["seed"],
                     settings=ModelSettings(**{k: (tuple(map(tuple, v)) if k == "sensor_directions" else v)
                                               for k, v in settings["model_settings"].items()}))
    np.testing.assert_array_equal(again.signal, signal)
    res = SimulationResult.from_npz(path)
    assert res.fs == 12000.0 and res.signal.shape == (2, 120)


@pytest.mark.parametrize("argv, fragment", [
    (["simulate", "--input-speed", "-100"], "input speed must be > 0"),
    (["simulate", "--input-speed", "100", "--output-speed", "30"], "not both"),
    (["simulate"], "--input-speed"),
    (["simulate", "--state", "T9", "--input-speed", "100"], "unknown fault state"),
    (["simulate", "--input-speed", "1000", "--substeps", "1", "--transient", "0", "--duration", "0.01"],
     "increase the sub-steps"),
    (["simulate", "--input-speed", "1000", "--duration", "0"], "--duration must be"),
    (["simulate", "--state", "T2", "--input-speed", "1000", "--broken-fraction", "2"], "broken fraction"),
    (["simulate", "--state", "T1", "--input-speed", "1000", "--wear-depth", "0.01"], "does not apply"),
    (["simulate", "--input-speed", "1000", "--load-inertia", "-1"], "--load-inertia must be a finite number >= 0"),
    (["simulate", "--input-speed", "1000", "--load-inertia", "nan"], "--load-inertia must be a finite number >= 0"),
    (["freqs", "--output-speed", "-3"], "output speed must be > 0"),
    (["freqs"], "--input-speed"),
])
def test_bad_input_one_line_exit_2(argv, fragment, tmp_path, capsys):
    if argv[0] == "simulate":
        argv = argv + ["--quiet", "--out", str(tmp_path / "x.npz")]
    code, _, err = run(argv, capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and fragment in lines[0], err


def test_out_must_be_npz(tmp_path, capsys):
    code, _, err = run(["simulate", "--input-speed", "100", "--out", str(tmp_path / "x.txt")], capsys)
    assert code == 2 and ".npz" in err


def test_result_plot_and_npz_roundtrip(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.arange(4800) / 48000.0
    sig = np.vstack([np.sin(2 * np.pi * 1000 * t), 0.5 * np.cos(2 * np.pi * 2000 * t)])
    res = SimulationResult(sig, 48000.0, {"seed": 1}, ["x", "y"])
    f, amp = res.spectrum(1)
    assert abs(f[np.argmax(amp)] - 2000.0) < 1e-9 and abs(amp.max() - 0.5) < 0.01
    fig = res.plot(channel=1, fmax_hz=5000)
    assert len(fig.axes) == 2 and fig.axes[0].get_ylabel().startswith("y")
    plt.close(fig)
    res.to_npz(tmp_path / "r.npz")
    back = SimulationResult.from_npz(tmp_path / "r.npz")
    np.testing.assert_array_equal(back.signal, sig)
    assert back.settings == {"seed": 1} and back.channel_names == ["x", "y"]
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    from rvdiag.errors import DataFileError

    with pytest.raises(DataFileError):
        SimulationResult.from_npz(tmp_path / "bad.npz")


def test_add_awgn_snr_and_validation():
    from rvdiag.dynamics import add_awgn
    from rvdiag.errors import ParameterError

    x = np.sin(np.linspace(0, 400 * np.pi, 200000))[None, :]
    y = add_awgn(x, 3.0, np.random.default_rng(0))
    snr = 10 * np.log10(np.mean(x**2) / np.mean((y - x) ** 2))
    assert abs(snr - 3.0) < 0.05
    np.testing.assert_array_equal(add_awgn(x, 3.0, 7), add_awgn(x, 3.0, np.random.default_rng(7)))
    for bad in (float("nan"), "10", True):
        with pytest.raises(ParameterError):
            add_awgn(x, bad)


def test_cli_workers_and_segment(tmp_path, capsys):
    """`--workers 2 --segment 0.01`: recorded in the settings, and the same bits as the serial segmented run."""
    path = tmp_path / "s.npz"
    argv = ["simulate", "--input-speed", "1000", "--duration", "0.03", "--transient", "0.02", "--workers", "2",
            "--segment", "0.01", "--quiet", "--out", str(path)]
    code, _, err = run(argv, capsys)
    assert code in (0, None), err
    with np.load(path) as z:
        settings = json.loads(str(z["settings"]))
        signal = z["signal"]
    assert settings["model_settings"]["segment_s"] == 0.01 and settings["segments"] == 3
    serial = simulate(duration_s=0.03, settings=ModelSettings(transient_s=0.02, segment_s=0.01),
                      input_speed_rpm=1000.0, fs=48000.0)
    assert np.array_equal(signal, serial.signal)


@pytest.mark.parametrize("extra, match", [
    (["--workers", "0"], "--workers must be >= 1"),
    (["--segment", "-1"], "--segment must be >= 0"),
    (["--segment", "0.01", "--transient", "0"], "--transient > 0"),
])
def test_cli_bad_segment_options(tmp_path, capsys, extra, match):
    path = tmp_path / "s.npz"
    code, _, err = run(["simulate", "--input-speed", "1000", "--duration", "0.01", "--quiet",
                        "--out", str(path), *extra], capsys)
    assert code == 2 and match in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 and not path.exists()


def test_simulate_default_transient_and_the_old_noise_option(tmp_path, capsys):
    """Without --transient, simulate discards the model's run-in (0.1 s, as library configs do); the old
    spelling --noise-snr still sets the noise, with one warning line."""
    from rvdiag.library.config import DEFAULT_TRANSIENT_S

    path = tmp_path / "s.npz"
    code, out, err = run(["simulate", "--output-speed", "30", "--duration", "0.005", "--fs", "8000",
                          "--substeps", "40", "--noise-snr", "20", "-q", "-o", str(path)], capsys)
    assert code in (0, None), err
    assert [ln for ln in err.splitlines() if "deprecated" in ln] == ["warning: --noise-snr is deprecated; use --snr-db"]
    with np.load(path, allow_pickle=False) as z:
        settings = json.loads(str(z["settings"]))
    assert settings["model_settings"]["transient_s"] == DEFAULT_TRANSIENT_S == ModelSettings().transient_s
    assert settings["noise_snr_db"] == 20.0


def test_simulate_trapezoid_records_the_shaft_angles(tmp_path, capsys):
    """``--profile trapezoid``: from rest at --accel to the speed and back; the .npz keeps the true carrier and
    input angles (the input turns i = 121 times the carrier), and the profile is recorded with the settings."""
    out = tmp_path / "move.npz"
    code, _, err = run(["simulate", "--profile", "trapezoid", "--output-speed", "45", "--accel", "900",
                        "--arm-mass", "15", "--arm-length", "0.5", "--load", "0", "--duration", "0.2",
                        "--fs", "24000", "-o", out, "-q"], capsys)
    assert code == 0, err
    with np.load(out, allow_pickle=False) as z:
        th_out, th_in = z["theta_out"], z["theta_in"]
    assert th_out.shape == (4800,) and np.all(np.diff(th_out) >= 0)
    np.testing.assert_allclose(th_in, 121.0 * th_out, rtol=1e-12, atol=1e-12)
    # a trapezoid 45 deg/s at 900 deg/s^2 up and down over 0.2 s: 0.05 s each way, 0.1 s cruising; 6.75 deg in all
    assert np.degrees(th_out[-1]) == pytest.approx(6.75, abs=0.05)


def test_simulate_trapezoid_that_cannot_reach_its_speed_is_one_error_line(tmp_path, capsys):
    out = tmp_path / "slow.npz"
    code, _, err = run(["simulate", "--profile", "trapezoid", "--output-speed", "45", "--accel", "10",
                        "--duration", "0.2", "-o", out], capsys)
    assert code == 2 and err.startswith("error:") and err.count("\n") == 1, err
    assert not out.exists()
    code, _, err = run(["simulate", "--accel", "100", "--output-speed", "45", "-o", out], capsys)
    assert code == 2 and "--profile trapezoid" in err


def test_simulate_scurve_records_the_shaft_angles_and_refuses_bad_values(tmp_path, capsys):
    """``--profile scurve --jerk``: the .npz keeps the true angles of the jerk-limited move (45 deg/s, 900 deg/s^2,
    18000 deg/s^3 over 0.2 s: T_j = 0.05 s, T_a = 0.1 s, no cruise, 4.5 deg); bad values are one error line."""
    out = tmp_path / "s.npz"
    code, _, err = run(["simulate", "--profile", "scurve", "--output-speed", "45", "--accel", "900", "--jerk",
                        "18000", "--load", "50", "--duration", "0.2", "--fs", "24000", "-o", out, "-q"], capsys)
    assert code == 0, err
    with np.load(out, allow_pickle=False) as z:
        th_out = z["theta_out"]
        settings = json.loads(str(z["settings"]))
    assert settings["speed_profile"]["kind"] == "scurve" and settings["speed_profile"]["jerk_deg_s3"] == 18000.0
    w = np.diff(th_out) * 24000
    assert np.all(w > 0) and np.degrees(th_out[-1]) == pytest.approx(4.5, abs=1e-3)
    assert np.degrees(w.max()) == pytest.approx(45.0, rel=1e-3)
    for args, msg in ((["--jerk", "100", "--output-speed", "45"], "--jerk needs --profile scurve"),
                      (["--profile", "scurve", "--output-speed", "45", "--accel", "900"], "needs --output-speed "
                                                                                          "DEG_S, --accel DEG_S2 and --jerk"),
                      (["--profile", "scurve", "--output-speed", "45", "--accel", "900", "--jerk", "-5"],
                       "jerk (deg/s^3) must be a finite number > 0"),
                      (["--profile", "scurve", "--output-speed", "45", "--accel", "900", "--jerk", "100",
                        "--duration", "0.2"], "an S-curve at 900 deg/s^2 and 100 deg/s^3 needs")):
        bad = tmp_path / "bad.npz"
        code, _, err = run(["simulate", *args, "-o", bad], capsys)
        assert code == 2 and err.count("\n") == 1 and msg in err, (args, err)
        assert not bad.exists()
