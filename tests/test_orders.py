"""Angle-domain core (rvdiag.features.orders): order tracking, TSA, gear condition indicators, the feature sets
tsa-ci and orders, and ``rvdiag orders``.  Every test asserts measured values."""

import json

import numpy as np
import pytest
from scipy.stats import kurtosis

from rvdiag.errors import ParameterError
from rvdiag.features import make_features
from rvdiag.features import orders as o

FS = 8192.0


def _chirp(seconds=4.0, f0=10.0, f1=20.0):
    """Shaft revolutions of a linear speed ramp f0 -> f1 rev/s, and a unit tone at order 11 of that shaft."""
    t = np.arange(int(seconds * FS)) / FS
    revs = f0 * t + 0.5 * (f1 - f0) / seconds * t**2
    return revs, np.sin(2 * np.pi * 11 * revs)


def _peak(orders, amp, lo=1.0):
    keep = orders >= lo
    return orders[keep][np.argmax(amp[keep])]


def test_chirp_resampled_by_encoder_angle_peaks_at_order_11():
    revs, x = _chirp()
    xa = o.resample_to_angle(x, FS, o.angle_from_encoder(2 * np.pi * revs, FS), 256)
    orders, amp = o.order_spectrum(xa, 256)
    assert abs(_peak(orders, amp) - 11) < 0.05
    assert amp.max() > 0.9  # the tone's amplitude 1 stays on one line
    # without tracking (a constant mean speed) the line smears over many orders
    mean = o.angle_from_speed(x.size, FS, revs[-1] / (x.size / FS))
    _, smeared = o.order_spectrum(o.resample_to_angle(x, FS, mean, 256), 256)
    assert smeared.max() < 0.3


def test_chirp_resampled_from_tachometer_pulses_peaks_at_order_11():
    revs, x = _chirp()
    ppr = 4
    t = np.arange(x.size) / FS
    pulses = np.interp(np.arange(1, int(revs[-1] * ppr)) / ppr, revs, t)
    xa = o.resample_to_angle(x, FS, o.angle_from_tacho(pulses, x.size, FS, ppr), 256)
    orders, amp = o.order_spectrum(xa, 256)
    assert abs(_peak(orders, amp) - 11) < 0.05
    # the pulse channel itself: square pulses at those times give the same times back
    chan = (np.interp(t, pulses, np.arange(pulses.size)) % 1 < 0.3).astype(float)
    found = o.tacho_pulse_times(chan, FS)
    assert found.size == pulses.size - 1  # the channel is high before the first pulse: no edge there
    assert np.abs(found - pulses[1:]).max() < 1.5 / FS


def test_constant_speed_resampling_is_exact():
    t = np.arange(int(2 * FS)) / FS
    x = np.sin(2 * np.pi * 11 * 16.0 * t)
    xa = o.resample_to_angle(x, FS, o.angle_from_speed(x.size, FS, 16.0), 512, antialias=False)
    assert xa.size == 32 * 512
    np.testing.assert_allclose(xa, x[: xa.size], atol=1e-12)
    orders, amp = o.order_spectrum(xa, 512)
    assert _peak(orders, amp) == pytest.approx(11.0, abs=1e-12)


def test_bad_angle_data_raise_one_clear_error():
    revs, x = _chirp(1.0)
    a = 2 * np.pi * revs
    a[3000] = a[2990]
    with pytest.raises(ParameterError, match="not monotonic.*sample 3000"):
        o.angle_from_encoder(a, FS)
    pulses = np.arange(1, 40) / 15.0
    with pytest.raises(ParameterError, match="missing tachometer pulse"):
        o.angle_from_tacho(np.delete(pulses, 20), x.size, FS, 1)
    with pytest.raises(ParameterError, match="do not increase"):
        o.angle_from_tacho(pulses[[0, 1, 2, 4, 3, 5]], x.size, FS, 1)
    with pytest.raises(ParameterError, match="spurious"):
        o.angle_from_tacho(np.sort(np.append(pulses, 20.5 / 15)), x.size, FS, 1)
    with pytest.raises(ParameterError, match="at least one whole revolution"):
        o.resample_to_angle(x[:100], FS, o.angle_from_speed(100, FS, 10.0), 64)


def test_speed_estimated_from_the_mesh_peak():
    t = np.arange(int(4 * FS)) / FS
    f = 15.37
    x = np.sin(2 * np.pi * 11 * f * t) + 0.3 * np.random.default_rng(0).standard_normal(t.size)
    assert o.estimate_shaft_speed(x, FS, 11, (5.0, 30.0)) == pytest.approx(f, rel=1e-3)


def test_tsa_noise_falls_as_one_over_sqrt_n():
    spr = 256
    rng = np.random.default_rng(1)
    clean = np.sin(2 * np.pi * 7 * np.arange(spr) / spr)
    err = {}
    for n in (16, 64):
        x = np.tile(clean, n) + rng.standard_normal(n * spr)
        err[n] = np.std(o.tsa(x, spr) - clean)
    assert err[16] / err[64] == pytest.approx(2.0, rel=0.2)


def _gear(spr=1024, mesh=20, pulse=0.0, noise=0.05, seed=2):
    k = np.arange(spr) / spr
    x = sum(a * np.cos(2 * np.pi * h * mesh * k + h) for h, a in ((1, 1.0), (2, 0.5), (3, 0.25)))
    x += noise * np.random.default_rng(seed).standard_normal(spr)
    if pulse:
        x += pulse * np.exp(-0.5 * ((np.arange(spr) - 300) / 2.0) ** 2)  # a local tooth fault, once per rev
    return x


def test_indicators_of_healthy_and_faulty_gears():
    healthy = o.condition_indicators(_gear(), 20)
    faulty = o.condition_indicators(_gear(pulse=1.0), 20)
    assert healthy["fm4"] == pytest.approx(3.0, abs=0.5)
    assert faulty["fm4"] > 3 * healthy["fm4"]
    assert faulty["m6a"] > 10 * healthy["m6a"] and faulty["m8a"] > 30 * healthy["m8a"]
    assert faulty["fm0"] > 1.2 * healthy["fm0"]
    # FM4 is the (Pearson) kurtosis of the difference signal: scipy's, independently
    d = o.gear_signals(_gear(pulse=1.0), 20)["difference"]
    assert faulty["fm4"] == pytest.approx(kurtosis(d, fisher=False), rel=1e-9)
    n = d.size
    dd = d - d.mean()
    assert faulty["m6a"] == pytest.approx(n**2 * np.sum(dd**6) / np.sum(dd**2) ** 3, rel=1e-9)


def test_energy_ratio_and_sidebands_by_hand():
    spr, mesh = 512, 16
    k = np.arange(spr) / spr
    t = 2.0 * np.cos(2 * np.pi * mesh * k) + 0.5 * np.cos(2 * np.pi * 5 * k) + 0.1 * np.cos(2 * np.pi * 17 * k)
    ci = o.condition_indicators(t, mesh, shaft_orders=2)
    regular_rms = np.sqrt((2.0**2 + 0.1**2) / 2)  # mesh and its upper sideband; order 5 is neither
    assert ci["energy_ratio"] == pytest.approx((0.5 / np.sqrt(2)) / regular_rms, rel=1e-9)
    assert ci["sideband_index"] == pytest.approx(0.05, rel=1e-9)
    assert ci["sideband_level_factor"] == pytest.approx(0.1 / t.std(), rel=1e-9)
    assert ci["fm0"] == pytest.approx((t.max() - t.min()) / 2.0, rel=1e-9)


def test_na4_running_average_over_a_run():
    rng = np.random.default_rng(3)
    recs = [rng.standard_normal(4096) * s for s in (1.0, 1.0, 2.0)]
    na4 = o.run_normalised_kurtosis(recs)
    assert na4[0] == pytest.approx(3.0, abs=0.3)
    # the growing third record over the mean variance of all three: 16 m4 / ((1 + 1 + 4) / 3)^2 = 4 x 3
    assert na4[2] == pytest.approx(12.0, rel=0.15)
    assert o.run_normalised_kurtosis(recs[2:], baseline_variance=1.0)[0] == pytest.approx(48.0, rel=0.15)


def test_feature_sets_tsa_ci_and_orders():
    t = np.arange(4096) / FS
    f_sun = o.shaft_frequency("sun", output_speed_deg_s=45.0)
    noise = 0.05 * np.random.default_rng(4).standard_normal(4096)
    mesh = np.cos(2 * np.pi * 11 * f_sun * t) + noise
    X = np.stack([mesh, mesh + (np.arange(4096) % 546 == 0)])
    tr = make_features("tsa-ci", fs=FS, shaft="sun", output_speed_deg_s=45.0).fit(X)
    F = tr.transform(X)
    names = list(tr.get_feature_names_out())
    assert F.shape == (2, 9) and names[1] == "log10_fm4"
    assert F[1, 1] > F[0, 1] + 0.3  # impulses raise FM4
    # the same through the speed column of the output speed
    Xs = np.column_stack([X, [45.0, 45.0]])
    tr2 = make_features("tsa-ci", fs=FS, speed_column="output_speed_deg_s").fit(Xs)
    np.testing.assert_allclose(tr2.transform(Xs), F)
    assert tr2.input_metadata() == ("output_speed_deg_s",)
    G = make_features("orders", fs=FS).fit_transform(X)
    assert G.shape == (2, 36) and np.all(np.isfinite(G))
    with pytest.raises(ParameterError, match="revolutions of the sun shaft"):
        make_features("tsa-ci", fs=FS).fit(X[:, :256])


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    from rvdiag.dynamics import simulate
    from rvdiag.gears import ToothFaults

    d = tmp_path_factory.mktemp("orders")
    out = {}
    for state in ("T1", "T2"):
        r = simulate(fault=ToothFaults.for_state(state), output_speed_deg_s=45.0, load_Nm=100.0, duration_s=0.5)
        r.to_npz(d / f"{state}.npz")
        out[state] = (r, d / f"{state}.npz")
    return out


def test_broken_tooth_raises_fm4_and_na4_on_the_sun_shaft(simulated):
    ci = {}
    for state, (r, _) in simulated.items():
        x = r.signal[0]
        f = o.shaft_frequency("sun", sun_speed_hz=r.settings["sun_speed_hz"])
        ci[state] = o.analyse(x, r.fs, o.angle_from_speed(x.size, r.fs, f), "sun")["indicators"]
    # measured: FM4 4.3 (T1) vs 12.3 (T2), NA4 3.9 vs 18.8
    assert ci["T2"]["fm4"] > 2 * ci["T1"]["fm4"]
    assert ci["T2"]["na4"] > 3 * ci["T1"]["na4"]


def _cli(args, capsys):
    from rvdiag.cli import main

    with pytest.raises(SystemExit) as exc:
        main(args)
        raise SystemExit(0)
    out = capsys.readouterr()
    return exc.value.code, out.out, out.err


def test_cli_orders_json_plot_and_errors(simulated, tmp_path, capsys):
    path = str(simulated["T2"][1])
    code, out, _ = _cli(["orders", path, "-c", r"1\]", "--json"], capsys)
    res = json.loads(out)
    assert code == 0 and {"shaft", "orders", "amplitude", "indicators"} <= set(res)
    assert res["shaft"] == "sun" and res["shaft_hz"] == pytest.approx(15.0)
    assert res["indicators"]["fm4"] > 6
    png = tmp_path / "orders.png"
    code, out, _ = _cli(["orders", path, "-c", r"1\]", "--output-speed", "45", "--plot", str(png)], capsys)
    assert code == 0 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and "fm4" in out
    # a non-monotonic angle channel: one error line, exit 2, nothing written
    bad = tmp_path / "bad.npz"
    sig = simulated["T2"][0].signal[0]
    angle = np.linspace(0, 100, sig.size)
    angle[500] = 0
    np.savez(bad, x=sig, angle=angle, fs=48000.0)
    png2 = tmp_path / "bad.png"
    code, out, err = _cli(["orders", str(bad), "-c", "^x$", "--angle-channel", "angle", "--plot", str(png2)], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1 and err.startswith("error: the shaft angle is not monotonic")
    assert not png2.exists()


# --------------------------------------------------------------------------- real data (docs/real-data.md)
from conftest import DATA, needs_real_data  # noqa: E402

SQ = ("spectraquest-gearbox/h30hz0.csv.gz", "spectraquest-gearbox/b30hz0.csv.gz",
      "spectraquest-gearbox/h30hz60.csv.gz", "spectraquest-gearbox/b30hz60.csv.gz")


@needs_real_data(*SQ)
def test_spectraquest_in_the_angle_domain(capsys):
    """docs/real-data.md, "SpectraQuest in the angle domain": the cepstrum's period agrees across the four
    accelerometers and grows with the load; on a1 the sideband index about order 160 is higher with the broken
    tooth, FM4 is not."""
    import pandas as pd

    from rvdiag.io.angles import estimate_period_cepstrum

    period = {}
    for f in SQ:
        d = pd.read_csv(DATA / f)
        T = [estimate_period_cepstrum(d[c].to_numpy())[0] for c in ("a1", "a2", "a3", "a4")]
        assert max(T) - min(T) < 0.5 and 2145 < np.mean(T) < 2165, (f, T)
        period[f.split("/")[1].split(".")[0]] = np.mean(T)
    assert period["h30hz60"] > period["h30hz0"] + 5 and period["b30hz60"] > period["b30hz0"] + 5
    ci = {}
    for f in SQ:
        code, out, err = _cli(["orders", str(DATA / f), "-c", "a1", "--fs", "1", "--cepstrum", "64:",
                               "--mesh-order", "160", "--json"], capsys)
        assert code == 0, err
        res = json.loads(out)
        assert res["angle_source"] == "cepstrum" and res["samples_per_rev"] == 2048
        ci[f.split("/")[1].split(".")[0]] = res["indicators"]
    for load in ("0", "60"):
        h, b = ci["h30hz" + load], ci["b30hz" + load]
        assert b["sideband_index"] > 1.3 * h["sideband_index"]
        assert b["fm4"] < h["fm4"]


def _toothed_tsa(n=2048, teeth=11, gain=1.0, impulse=0.0, seed=0):
    """One revolution: a tooth waveform of mesh harmonics 1..3 (x ``gain``, the same on every tooth), per-tooth
    noise, and with ``impulse`` a narrow pulse in tooth 3 (one tooth, once per revolution)."""
    th = np.arange(n) / n
    t = gain * (np.cos(2 * np.pi * teeth * th) + 0.5 * np.sin(2 * np.pi * 2 * teeth * th)
                + 0.2 * np.cos(2 * np.pi * 3 * teeth * th + 0.3))
    t = t + 0.05 * np.random.default_rng(seed).standard_normal(n)
    return t + impulse * np.exp(-0.5 * ((th - 3.4 / teeth) / 0.003) ** 2)


def test_tooth_segments_mean_is_the_mesh_harmonics_of_the_tsa():
    t = _toothed_tsa(impulse=2.0)
    S = o.tooth_segments(t, 11)
    # the other code path: keep only the orders k * 11 of the TSA's spectrum, sampled at the segments' points
    T = np.fft.rfft(t)
    keep = np.zeros(T.size, bool)
    keep[::11] = True
    L = S.size
    mesh = np.fft.irfft(np.where(keep, T, 0), L) * (L / t.size)
    np.testing.assert_allclose(S.mean(axis=0), mesh[: S.shape[1]], atol=1e-9 * np.abs(t).max())
    with pytest.raises(ParameterError, match="teeth must be"):
        o.tooth_segments(t, 1)


def test_median_tooth_follows_a_uniform_change_not_one_impulsive_tooth():
    ref = o.median_tooth(_toothed_tsa(), 11)["median"]
    imp = o.median_tooth(_toothed_tsa(impulse=3.0), 11, trim=1)
    worn = o.median_tooth(_toothed_tsa(gain=1.5), 11)["median"]
    rel = lambda a: np.linalg.norm(a - ref) / np.linalg.norm(ref)  # noqa: E731
    assert rel(imp["median"]) < 0.03  # the impulse moves the median tooth by less than 3 %
    assert abs(rel(worn) - 0.5) < 0.05  # a 1.5 x change of every tooth moves it by 50 %
    assert rel(imp["segments"].mean(axis=0)) > 0.05  # the mean tooth (mesh harmonics) does take the impulse
    e = imp["deviation"]
    assert int(np.argmax(e)) == 3 and e[3] > 20 * np.median(e)  # the impulsive part sits on tooth 3
    assert imp["trimmed_deviation"] < 2 * np.median(e) < e.mean() / 10  # leaving out the worst tooth removes it
    with pytest.raises(ParameterError, match="trim must be"):
        o.median_tooth(_toothed_tsa(), 11, trim=11)


def test_tsa_ci_median_tooth_option_appends_two_indicators():
    from rvdiag.features.tsa import TSAIndicatorFeatures

    rng = np.random.default_rng(1)
    X = rng.standard_normal((2, 9600))
    base = TSAIndicatorFeatures(fs=48000.0).fit(X)
    tooth = TSAIndicatorFeatures(fs=48000.0, median_tooth=True).fit(X)
    A, B = base.transform(X), tooth.transform(X)
    assert B.shape == (2, A.shape[1] + 2)
    np.testing.assert_allclose(B[:, : A.shape[1]], A)
    assert list(tooth.get_feature_names_out()[-2:]) == ["log10_median_tooth_rms_ratio",
                                                         "log10_tooth_deviation_trimmed"]
    del tooth.median_tooth  # as a model pickled before the option existed
    np.testing.assert_allclose(tooth.transform(X), A)
