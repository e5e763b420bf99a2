"""Angle sources of measured and simulated records (rvdiag.io.angles): encoder angles and counters, tachometers,
speeds in file names, the angles ``rvdiag simulate`` stores; in ``rvdiag orders`` and ``dataset from-files``.
Every angle is checked against the true angle it was made from."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli

from rvdiag.errors import ParameterError
from rvdiag.features import orders as o
from rvdiag.io import angles as an

FS = 8192.0


def _ramp(seconds=3.0, f0=10.0, f1=20.0):
    """Input revolutions of a linear speed ramp f0 -> f1 rev/s at FS."""
    t = np.arange(int(seconds * FS)) / FS
    return f0 * t + 0.5 * (f1 - f0) / seconds * t**2


@pytest.mark.parametrize("cpr", [64, 4096])  # under one count per sample, and several per sample
def test_counter_gives_the_true_angle_within_its_quantisation(cpr):
    revs = _ramp()
    counts = np.floor(revs * cpr + 0.37)  # an arbitrary counter phase
    got = an.angle_from_encoder(counts, FS, counts_per_rev=cpr)
    err = (got - got[100]) - (revs - revs[100])
    assert np.max(np.abs(err[100:-100])) < 1.0 / cpr  # each end within half a count
    # the order spectrum of a tone at order 11 through that angle: one sharp line
    x = np.sin(2 * np.pi * 11 * revs)
    orders, amp = o.order_spectrum(o.resample_to_angle(x, FS, got, 256), 256)
    assert orders[np.argmax(amp)] == pytest.approx(11.0, abs=0.05) and amp.max() > 0.9


def test_wrapped_angles_and_counters_are_unwrapped():
    revs = _ramp(1.0)
    wrapped = np.mod(2 * np.pi * revs + 1.0, 2 * np.pi)
    np.testing.assert_allclose(an.angle_from_encoder(wrapped, FS), revs - revs[0], atol=1e-9)
    # a shaft turning backwards: the sign is taken off
    np.testing.assert_allclose(an.angle_from_encoder(np.mod(-2 * np.pi * revs, 2 * np.pi), FS), revs, atol=1e-9)
    cpr = 1000
    got = an.angle_from_encoder(np.mod(np.floor(revs * cpr), cpr), FS, counts_per_rev=cpr)
    assert np.max(np.abs(got[100:-100] - got[100] - (revs[100:-100] - revs[100]))) < 1.0 / cpr


def test_counter_errors_name_the_sample():
    c = np.floor(_ramp(1.0) * 64)
    back = c.copy()
    back[2000:] -= 3
    with pytest.raises(ParameterError, match="counter goes back at sample 2000"):
        an.angle_from_encoder(back, FS, counts_per_rev=64)
    stall = c.copy()
    stall[3000:3400] = stall[3000]
    stall[3400:] -= stall[3400] - stall[3000]  # stands still for 400 samples (~50 ms, 30 counts missed)
    with pytest.raises(ParameterError, match="stands still from t = 0.36"):
        an.angle_from_encoder(stall, FS, counts_per_rev=64)


def test_missing_pulse_threshold_is_one_and_a_half_intervals():
    base = np.arange(1, 60) / 20.0
    for stretch, ok in ((1.4, True), (1.6, False)):
        t = base.copy()
        t[30:] += (stretch - 1.0) / 20.0  # interval 29 -> 30 is `stretch` times the others
        if ok:
            an.angle_from_tacho(t, int(3.5 * FS), FS)
        else:
            with pytest.raises(ParameterError, match=r"missing tachometer pulse\(s\) between t = 1.5 s"):
                an.angle_from_tacho(t, int(3.5 * FS), FS)


def test_tacho_angle_matches_the_truth_between_pulses():
    revs = _ramp()
    ppr = 8
    t = np.arange(revs.size) / FS
    pulses = np.interp(np.arange(1, int(revs[-1] * ppr)) / ppr, revs, t)
    chan = 2.5 + 2.5 * np.sin(2 * np.pi * ppr * revs)  # smooth edges: rising through 2.5 at revs = k / ppr
    found = an.tacho_pulse_times(chan, FS)
    assert np.max(np.abs(found[:pulses.size] - pulses)) < 1e-3 / FS
    got = an.angle_from_tacho(found, revs.size, FS, ppr)
    # 0 at the first sample (extrapolated back from the first pulse found): compare the angle turned since
    inside = np.flatnonzero((t > pulses[2]) & (t < pulses[-1]))
    err = (got[inside] - got[inside[0]]) - (revs[inside] - revs[inside[0]])
    assert np.max(np.abs(err)) < 2e-5  # of a revolution: PCHIP between pulses 1/8 rev apart


def test_speed_out_of_the_plausible_range():
    revs = _ramp(1.0, 30.0, 30.0)  # 1800 rev/min
    assert an.check_speed(revs, FS) == pytest.approx(30.0)
    # an angle in degrees read as radians: 57 times too fast
    with pytest.raises(ParameterError, match="above the plausible 10000 rev/min"):
        an.angle_from_encoder(np.degrees(2 * np.pi * revs), FS) is None or an.check_speed(
            an.angle_from_encoder(np.degrees(2 * np.pi * revs), FS), FS)
    with pytest.raises(ParameterError, match="below the plausible 2000 rev/min"):
        an.check_speed(revs, FS, (2000.0, 6000.0))
    # one glitch block too fast is enough
    glitch = revs.copy()
    glitch[4000:] += 50.0
    with pytest.raises(ParameterError, match=r"near t = 0.4\d* s"):
        an.check_speed(glitch, FS)
    with pytest.raises(ParameterError, match="MIN:MAX"):
        an.parse_speed_range("6000:10")


def test_speed_from_the_file_name_groups():
    assert an.speed_from_groups({"rpm": "1800"}, 121.0)[0] == pytest.approx(30.0)
    assert an.speed_from_groups({"speed_dps": "45"}, 121.0)[0] == pytest.approx(45 / 360 * 121)
    assert an.speed_from_groups({"load": "3"}, 121.0) is None
    with pytest.raises(ParameterError, match="both state a speed"):
        an.speed_from_groups({"rpm": "1", "speed_dps": "2"}, 121.0)
    with pytest.raises(ParameterError, match="not a positive number"):
        an.speed_from_groups({"rpm": "-3"}, 121.0)


# --------------------------------------------------------------------------- rvdiag orders
def _record(path, revs_in, extra=None, fs=FS, seed=0):
    """An NPZ with x = a tone at the stage-1 mesh of the sun (order 11 of the sun relative to the carrier) and
    the given channels."""
    sun = o.shaft_ratio("sun") * revs_in
    x = np.cos(2 * np.pi * 11 * sun) + 0.05 * np.random.default_rng(seed).standard_normal(revs_in.size)
    np.savez(path, x=x, fs=fs, **(extra or {}))
    return x


def test_orders_reads_a_counter_a_tacho_and_a_name(tmp_path, capsys):
    revs = _ramp(4.0, 8.0, 16.0)  # input rev/s
    cpr = 2048
    f = tmp_path / "run_speed.npz"
    t = np.arange(revs.size) / FS
    pulses = np.interp(np.arange(1, int(revs[-1])), revs, t)
    tach = np.where(np.interp(t, pulses, np.arange(pulses.size)) % 1 < 0.5, 1.0, 0.0)
    _record(f, revs, {"enc": np.floor(revs * cpr), "tach": tach})
    for args, source in ((["--angle-channel", "enc", "--ppr", str(cpr)], "counter"),
                         (["--tacho-channel", "tach"], "tacho")):
        code, out, err = run_cli(["orders", f, "-c", "^x$", "--json", *args], capsys)
        assert code == 0, err
        res = json.loads(out)
        assert res["angle_source"] == source
        orders, amp = np.array(res["orders"]), np.array(res["amplitude"])
        assert orders[np.argmax(amp)] == pytest.approx(11.0, abs=0.02) and amp.max() > 0.8
    # a constant speed in the file name
    g = tmp_path / "run_900rpm.npz"
    _record(g, np.arange(revs.size) * 15.0 / FS)
    code, out, err = run_cli(["orders", g, "-c", "^x$", "--json", "--meta-regex", r"_(?P<rpm>\d+)rpm"], capsys)
    res = json.loads(out)
    assert code == 0 and res["angle_source"] == "meta"
    assert res["shaft_hz"] == pytest.approx(15.0 * o.shaft_ratio("sun"), rel=1e-9)
    assert "900 rev/min of the input from the file name" in res["angle_detail"]


def test_orders_bad_angle_data_one_line_exit_2_nothing_written(tmp_path, capsys):
    revs = _ramp(2.0, 15.0, 15.0)
    f = tmp_path / "r.npz"
    t = np.arange(revs.size) / FS
    pulses = np.delete(np.arange(1, 29) / 15.0, 12)  # pulse 13 lost
    tach = np.where(np.interp(t, pulses, np.arange(pulses.size)) % 1 < 0.5, 1.0, 0.0)
    _record(f, revs, {"tach": tach, "deg": np.degrees(2 * np.pi * revs)})
    png = tmp_path / "o.png"
    for args, msg in ((["--tacho-channel", "tach"], "error: missing tachometer pulse"),
                      (["--angle-channel", "deg"], "error: the input shaft turns at"),
                      (["--meta-regex", r"(?P<rpm>\d+)"], "error: r.npz: the name does not match"),
                      (["--meta-regex", r"(?P<load>r)"], "error: --meta-regex '(?P<load>r)' has no group"),
                      (["--output-speed", "45", "--speed-range", "5000:6000"], "error: the input shaft turns at"),
                      (["--tacho-channel", "tach", "--input-speed", "900"], "error: give one angle source")):
        code, out, err = run_cli(["orders", f, "-c", "^x$", "--plot", png, *args], capsys)
        assert code == 2 and out == "" and err.count("\n") == 1 and err.startswith(msg), (args, err)
        assert not png.exists()


def test_orders_resamples_a_simulated_record_with_its_stored_angles(tmp_path, capsys):
    """A run-up and run-down record (the closed-form trapezoid of rvdiag.dynamics.profile, which
    ``simulate`` stores as theta_out / theta_in): the stored angles give one sharp mesh line at order 11; the
    record's stated (cruise) speed, taken as constant, smears it."""
    from rvdiag.dynamics import SimulationResult, SpeedProfile
    from rvdiag.params import ReducerParams

    fs, dur = 8192.0, 1.5
    i = ReducerParams.default().ratio
    prof = SpeedProfile.trapezoid(45.0, 60.0)  # a triangle: up for 0.75 s, down for 0.75 s
    th_out = prof.state(np.arange(int(fs * dur)) / fs, 0.0, dur)[0]
    x = np.cos(11 * (i - 1) * th_out)  # order 11 of the sun relative to the carrier: (i - 1) theta_out
    settings = {"sun_speed_hz": 45.0 / 360 * i, "speed_profile": prof.to_dict()}
    f = tmp_path / "sim.npz"
    SimulationResult(x[None, :], fs, settings, ["accel[1,0]"], th_out, i * th_out).to_npz(f)
    code, out, err = run_cli(["orders", f, "-c", r"signal", "--json"], capsys)
    assert code == 0, err
    res = json.loads(out)
    assert res["angle_source"] == "stored-angle"
    # only the part at half the peak speed or more is analysed: from 0.375 s to 1.125 s
    assert res["span_s"] == pytest.approx([0.375, 1.125], abs=0.05)
    amp = np.array(res["amplitude"])
    assert np.array(res["orders"])[np.argmax(amp)] == pytest.approx(11.0, abs=1e-9) and amp.max() > 0.95
    # the same record without its angles: the stated cruise speed smears the line
    np.savez(tmp_path / "noangle.npz", signal=x, fs=fs, settings=np.array(json.dumps(settings)))
    code, out, _ = run_cli(["orders", tmp_path / "noangle.npz", "--json"], capsys)
    res2 = json.loads(out)
    assert res2["angle_source"] == "record-speed" and max(res2["amplitude"]) < 0.5


# --------------------------------------------------------------------------- dataset from-files
def _folder(tmp_path, lose_pulse=False):
    d = tmp_path / "raw"
    d.mkdir()
    truth = {}
    for k, (f0, f1) in enumerate(((10.0, 14.0), (12.0, 12.0))):
        revs = _ramp(2.0, f0, f1)
        t = np.arange(revs.size) / FS
        pulses = np.interp(np.arange(1, int(revs[-1]) * 4) / 4, revs, t)
        if lose_pulse and k == 1:
            pulses = np.delete(pulses, 40)
        tach = np.where(np.interp(t, pulses, np.arange(pulses.size)) % 1 < 0.5, 1.0, 0.0)
        _record(d / f"{'ab'[k]}_{k}_{int(60 * f0)}rpm.npz", revs, {"tach": tach}, seed=k)
        truth[f"{'ab'[k]}_{k}_{int(60 * f0)}rpm.npz"] = revs
    return d, truth


def test_from_files_records_each_windows_speed_from_a_tachometer(tmp_path, capsys):
    from rvdiag.datasets import SampleStore

    d, truth = _folder(tmp_path)
    out = tmp_path / "s.zarr"
    code, stdout, err = run_cli(["dataset", "from-files", d, "--label-regex", r"^(?P<label>[ab])", "-c", "^x$",
                                 "--window", 2048, "--tacho-channel", "tach", "--ppr", 4, "-o", out, "-q"], capsys)
    assert code == 0, err
    assert "a_0_600rpm.npz: angle from tacho" in stdout
    smp = SampleStore.open(out).load("all")
    L = 2048
    for k in range(len(smp.y)):
        revs = truth[smp.meta["source"][k]]
        s = int(smp.meta["start"][k])
        want = (revs[s + L - 1] - revs[s]) * FS / (L - 1) * 60
        if s > 0:  # the first pulse is a quarter revolution in: before it the speed is extrapolated
            assert smp.meta["input_speed_rpm"][k] == pytest.approx(want, rel=2e-3)
        assert smp.meta["angle_source"][k] == "tacho"
    ratio = o._params(None).ratio
    np.testing.assert_allclose(smp.meta["output_speed_deg_s"], smp.meta["input_speed_rpm"] * 6 / ratio)
    # the windows of the ramp speed up, those of the steady file do not
    ramp = smp.meta["input_speed_rpm"][smp.meta["source"] == "a_0_600rpm.npz"]
    assert np.all(np.diff(ramp) > 0) and ramp[-1] > 1.3 * ramp[0]
    # the speed from the file name instead: constant per file
    out2 = tmp_path / "m.zarr"
    code, _, err = run_cli(["dataset", "from-files", d, "--label-regex", r"^(?P<label>[ab])", "-c", "^x$",
                            "--window", 2048, "--meta-regex", r"_(?P<rpm>\d+)rpm", "-o", out2, "-q"], capsys)
    assert code == 0, err
    m = SampleStore.open(out2).load("all").meta
    assert set(m["input_speed_rpm"].round(9)) == {600.0, 720.0} and set(m["angle_source"]) == {"meta"}
    assert set(m["rpm"]) == {600, 720}


def test_from_files_bad_pulses_one_line_exit_2_nothing_written(tmp_path, capsys):
    d, _ = _folder(tmp_path, lose_pulse=True)
    out = tmp_path / "s.zarr"
    code, stdout, err = run_cli(["dataset", "from-files", d, "--label-regex", r"^(?P<label>[ab])", "-c", "^x$",
                                 "--window", 2048, "--tacho-channel", "tach", "--ppr", 4, "-o", out, "-q"], capsys)
    assert code == 2 and stdout == "" and err.count("\n") == 1
    assert err.startswith("error: b_1_720rpm.npz: missing tachometer pulse(s)")
    assert not out.exists()
    code, _, err = run_cli(["dataset", "from-files", d, "--label-regex", r"^(?P<label>[ab])", "-c", "^x$",
                            "--window", 2048, "--speed-range", "1:2", "-o", out, "-q"], capsys)
    assert code == 2 and "--speed-range and --params apply to an angle source" in err and not out.exists()


# --------------------------------------------------------------------------- the cepstrum (unknown machine)
def _comb(period=437.3, n=2**16, seed=3):
    """Lines at harmonics of 1 / period samples: a mesh at order 25 with sidebands +-1, shaft orders 1, 2 and a
    narrow pulse once per period (a local fault: every harmonic), random phases, in noise."""
    rng = np.random.default_rng(seed)
    k = np.arange(n) / period
    x = 0.1 * rng.standard_normal(n)
    for order, a in ((1, 0.2), (2, 0.1), (24, 0.3), (25, 1.0), (26, 0.3)):
        x += a * np.cos(2 * np.pi * order * k + rng.uniform(0, 2 * np.pi))
    d = (k - 0.4 + 0.5) % 1.0 - 0.5
    return x + PULSE * np.exp(-0.5 * (d * period / 1.5) ** 2)


PULSE = 2.0


def test_cepstrum_finds_the_period_of_a_line_family():
    for period in (437.3, 1021.77):
        T, q0 = an.estimate_period_cepstrum(_comb(period))
        assert abs(q0 - period) <= 1.0 and T == pytest.approx(period, abs=0.01)
    with pytest.raises(ParameterError, match="period range"):
        an.estimate_period_cepstrum(_comb(), (500, 400))
    with pytest.raises(ParameterError, match="LO:HI"):
        an.parse_period_range("64")
    assert an.parse_period_range("64:") == (64, None) and an.parse_period_range("64:900") == (64, 900)


def test_orders_with_the_cepstrum_and_a_mesh_order_of_another_machine(tmp_path, capsys):
    f = tmp_path / "rig.npy"
    np.save(f, _comb())
    code, out, err = run_cli(["orders", f, "--fs", "1", "--cepstrum", "64:", "--mesh-order", "25", "--json"], capsys)
    assert code == 0, err
    res = json.loads(out)
    assert res["angle_source"] == "cepstrum" and res["shaft_hz"] == pytest.approx(1 / 437.3, rel=3e-5)
    assert res["mesh_order"] == 25 and res["fault_orders"] == {} and res["planets"] is None
    tsa = np.array(res["tsa"])
    amp = np.abs(np.fft.rfft(tsa)) * 2 / tsa.size
    pulse = PULSE * 1.5 * np.sqrt(2 * np.pi) / 437.3 * 2  # the pulse's line at a low order, one-sided
    assert amp[25] == pytest.approx(np.hypot(1.0, 0) + 0, abs=pulse + 0.02)
    assert abs(amp[24] - 0.3) < pulse + 0.02 and abs(amp[3] - pulse) < 0.01
    # the sidebands +-1 of the mesh: sideband index (A(24) + A(26)) / 2
    assert res["indicators"]["sideband_index"] == pytest.approx(0.3, abs=pulse + 0.02)
    for args, msg in ((["--cepstrum", "64:", "--input-speed", "900"], "--cepstrum is an angle source of its own"),
                      (["--cepstrum", "9:3"], "expected LO:HI"),
                      (["--cepstrum", "64:", "--mesh-order", "0"], "mesh order must be a positive integer")):
        code, out, err = run_cli(["orders", f, "--fs", "1", *args], capsys)
        assert code == 2 and out == "" and err.count("\n") == 1 and msg in err, (args, err)


def test_from_files_speed_out_of_range_one_line_exit_2_nothing_written(tmp_path, capsys):
    d, _ = _folder(tmp_path)
    out = tmp_path / "s.zarr"
    code, stdout, err = run_cli(["dataset", "from-files", d, "--label-regex", r"^(?P<label>[ab])", "-c", "^x$",
                                 "--window", 2048, "--tacho-channel", "tach", "--ppr", 4, "--speed-range", "5000:6000",
                                 "-o", out, "-q"], capsys)
    assert code == 2 and stdout == "" and err.count("\n") == 1 and not out.exists()
    assert err.startswith("error: a_0_600rpm.npz: the input shaft turns at") and "below the plausible 5000" in err
