"""The planetary stage in the angle domain (rvdiag.features.planetary): McFadden's windowed TSA per planet, the
sideband asymmetry and the phase demodulation, on synthetic signals whose answers are known analytically."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.special import jv

from conftest import run_cli

from rvdiag.errors import ParameterError
from rvdiag.features import orders as o
from rvdiag.features import planetary as pl
from rvdiag.params import ReducerParams

P = ReducerParams.default()
N, Z2, Zp, I = P.stage1.n_planets, P.stage1.planet_teeth, P.stage2.pins, P.ratio
FS = 16384.0


def test_windows_of_the_planets_add_up_to_one_and_centre_on_the_passage():
    r = np.linspace(0.0, 3.0, 3001)
    for n in (2, 3, 4):
        w = pl.planet_windows(r, n, sensor_angle_deg=30.0)
        np.testing.assert_allclose(w.sum(axis=0), 1.0, atol=1e-12)
        # planet k is at the sensor when the carrier is at 30 deg - 360 k / n: its window is 1 there
        for k in range(n):
            c = ((30.0 - 360.0 * k / n) % 360.0) / 360.0
            assert pl.planet_windows(np.array([c]), n, 30.0)[k, 0] == pytest.approx(1.0)
    narrow = pl.planet_windows(r, 2, width_deg=90.0)
    assert np.all(narrow[:, np.abs(((r + 0.5) % 1.0) - 0.5) > 0.125][0] == 0.0)  # planet 0 beyond 45 deg: 0
    with pytest.raises(ParameterError, match="at most 360 deg"):
        pl.planet_windows(r, 2, width_deg=400.0)


def _planetary_record(seconds=4.0, carrier_hz=0.5, fault_planet=1, pulse=2.0, seed=0):
    """Two planets on cranks turning Zp times per carrier revolution; planet k's mesh (order Z2 of the crank, its
    own phase) and, on ``fault_planet``, a local tooth fault (a narrow pulse at crank angle 0.3 rev), each heard
    through the transmission 0.5 (1 + cos alpha_k) of its distance alpha_k from the sensor at angle 0."""
    t = np.arange(int(seconds * FS)) / FS
    r_h = carrier_hz * t
    r_c = Zp * r_h
    x = np.zeros(t.size)
    parts = []
    for k in range(N):
        alpha = 2 * np.pi * (r_h + k / N)
        g = 0.5 * (1 + np.cos(alpha))
        s = np.cos(2 * np.pi * Z2 * r_c + 1.3 * k)
        if k == fault_planet:
            d = (r_c - 0.3 + 0.5) % 1.0 - 0.5
            s = s + pulse * np.exp(-0.5 * (d / 0.002) ** 2)
        x += g * s
        parts.append(s)
    x += 0.05 * np.random.default_rng(seed).standard_normal(t.size)
    return x, I * r_h


def test_planet_tsa_separates_a_local_fault_on_one_planet():
    """With the Hann windows matching the transmission (W = 360 deg for 2 planets), the planet-k TSA over whole
    carrier revolutions is 3/4 of planet k's own signal plus 1/4 of the other's (<w_k^2> / <w_k> = 3/8 / 1/2 and
    <w_0 w_1> / <w_k> = 1/8 / 1/2): the fault pulse is 3 times higher in the faulty planet's TSA, at its angle,
    and its FM4 the higher; the plain TSA of the crank splits it 1/2, 1/2."""
    x, r_in = _planetary_record()
    res = pl.planet_tsa(x, FS, r_in, P)
    assert res["n_planets"] == 2 and res["mesh_order"] == Z2 and res["extra_meshes"] == (P.stage2.cycloid_lobes,)
    spr = res["samples_per_rev"]
    t0, t1 = (p_["tsa"] for p_ in res["planets"])
    # 2 carrier revolutions from planet 0 at the sensor: planet 0 passes again at 2 s, planet 1 at 1 s and 3 s
    assert [p_["passes"] for p_ in res["planets"]] == [1, 2]
    for p_ in res["planets"]:
        assert p_["weight_revs"] == pytest.approx(res["n_revolutions"] / 2, rel=0.02)
    # the pulse: remove the mesh (order 33 and harmonics) and read the peak
    r0 = o.gear_signals(t0, Z2)["residual"]
    r1 = o.gear_signals(t1, Z2)["residual"]
    k1 = int(np.argmax(r1))
    assert abs(k1 / spr - 0.3) < 2.0 / spr
    assert r1[k1] / r0[k1] == pytest.approx(3.0, rel=0.05)
    i0, i1 = (p_["indicators"] for p_ in res["planets"])
    assert set(i1) == set(o.INDICATORS) and i1["fm4"] > 5  # the pulse dominates the difference signal
    # each planet's mesh: 3/4 of its own phase plus 1/4 of the other's
    m0, m1 = (np.fft.rfft(t)[Z2] * 2 / spr for t in (t0, t1))
    want0, want1 = 0.75 + 0.25 * np.exp(1.3j), 0.25 + 0.75 * np.exp(1.3j)
    assert abs(m0 - want0) < 0.02 and abs(m1 - want1) < 0.02
    # the whole-crank TSA (every revolution alike) splits the pulse evenly between the planets
    xa = o.resample_to_angle(x, FS, r_in * Zp / I, spr)
    plain = o.gear_signals(o.tsa(xa, spr), Z2)["residual"]
    assert plain[k1] / r1[k1] == pytest.approx(0.5 / 0.75, rel=0.05)


def test_a_planet_that_never_passes_the_sensor_has_no_tsa():
    # 0.4 s at 0.25 rev/s: the carrier turns 36 deg; with 60-deg windows planet 1 (180 deg away) stays silent
    x, r_in = _planetary_record(seconds=0.4, carrier_hz=0.25)
    res = pl.planet_tsa(x, FS, r_in, P, width_deg=60.0)
    assert res["planets"][0]["tsa"] is not None and res["planets"][1]["tsa"] is None
    assert res["planets"][1]["weight_revs"] == 0.0 and res["planets"][1]["passes"] == 0


@pytest.mark.parametrize("a, b", [(0.4, 0.0), (0.4, 0.3), (0.0, 0.5), (0.2, -0.4)])
def test_sideband_asymmetry_of_amplitude_and_phase_modulation(a, b):
    """(1 + a cos N theta) cos(m theta + b sin N theta): the sidebands m +- N are |+-J1(b) + (a/2)(J0(b) + J2(b))|
    (the Jacobi-Anger expansion); amplitude modulation alone (b = 0) is symmetric."""
    n, m, s = 1024, 40, 2
    th = np.arange(n) / n
    x = (1 + a * np.cos(2 * np.pi * s * th)) * np.cos(2 * np.pi * m * th + b * np.sin(2 * np.pi * s * th))
    c = a / 2 * (jv(0, b) + jv(2, b))
    up, lo = abs(jv(1, b) + c), abs(-jv(1, b) + c)
    asym, db = pl.sideband_asymmetry(x, m, s)
    assert asym == pytest.approx((up - lo) / (up + lo), abs=1e-12)
    if up > 0 and lo > 0:
        assert db == pytest.approx(20 * math.log10(up / lo), abs=1e-9)
    if b == 0:
        assert asym == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(ParameterError, match="outside the TSA's orders"):
        pl.sideband_asymmetry(x, m, 600)


def test_phase_demodulation_gives_the_known_phase():
    """cos(2 pi m theta + b sin(2 pi k theta)) with a fault-like phase step: the demodulated phase is the
    modulation itself (to the Bessel content left outside the +- m/2 band), and the envelope stays 1."""
    n, m = 1024, 30
    th = np.arange(n) / n
    for phi in (0.5 * np.sin(2 * np.pi * 3 * th), 0.8 * np.exp(-0.5 * ((th - 0.6) / 0.05) ** 2)):
        phi = phi - phi.mean()
        x = np.cos(2 * np.pi * m * th + phi)
        got, env = pl.phase_demodulation(x, m)
        assert np.max(np.abs(got - phi)) < 5e-3
        assert np.max(np.abs(env - 1.0)) < 5e-3
    # a second harmonic carrier: h = 2 reads the doubled phase of the tooth pattern
    x = np.cos(2 * np.pi * 2 * m * th + 2 * 0.3 * np.sin(2 * np.pi * 2 * th))
    got, _ = pl.phase_demodulation(x, m, harmonic=2)
    assert np.max(np.abs(got - 0.6 * np.sin(2 * np.pi * 2 * th))) < 5e-3
    ind = pl.modulation_indicators(np.cos(2 * np.pi * m * th + 0.5 * np.sin(2 * np.pi * 3 * th)), m, 3)
    assert ind["phase_pp"] == pytest.approx(1.0, abs=0.01) and ind["sideband_asymmetry"] == pytest.approx(0.0, abs=1e-9)
    assert ind["phase_kurtosis"] == pytest.approx(1.5, abs=0.02)  # a sine's normalised 4th moment


def test_orders_json_has_planets_and_modulation(tmp_path, capsys):
    x, r_in = _planetary_record(seconds=4.0)
    f = tmp_path / "planets.npz"
    np.savez(f, x=x, fs=FS)
    code, out, err = run_cli(["orders", f, "-c", "^x$", "--input-speed", I * 0.5 * 60, "--json"], capsys)
    assert code == 0, err
    res = json.loads(out)
    assert res["angle_source"] == "input-speed"
    planets = res["planets"]
    assert [p_["planet"] for p_ in planets["planets"]] == [0, 1] and planets["mesh_order"] == Z2
    t0, t1 = (np.array(p_["tsa"]) for p_ in planets["planets"])
    assert t1.size == planets["samples_per_rev"]
    k = int(round(0.3 * t1.size))  # the fault pulse: 3/4 in planet 1's TSA, 1/4 in planet 0's
    r0, r1 = (o.gear_signals(t, Z2)["residual"] for t in (t0, t1))
    assert r1[k] / r0[k] == pytest.approx(3.0, rel=0.1)
    mod = res["modulation"]
    assert set(mod) >= {"sideband_asymmetry", "sideband_asymmetry_db", "phase_pp", "phase_kurtosis",
                        "sideband_spacing", "phase"}
    assert mod["sideband_spacing"] == N and len(mod["phase"]) == res["samples_per_rev"]
    # the text output lists each planet
    code, out, _ = run_cli(["orders", f, "-c", "^x$", "--input-speed", I * 0.5 * 60], capsys)
    assert code == 0 and "planet 1" in out and "sideband_asymmetry" in out


def test_feature_set_tsa_mod_appends_the_modulation_indicators():
    from rvdiag.features import make_features

    fs = 8192.0
    t = np.arange(4096) / fs
    f_sun = o.shaft_frequency("sun", output_speed_deg_s=45.0)
    ph = 2 * np.pi * f_sun * t
    # mesh order 11 of the sun, amplitude- and phase-modulated at the sun-fault order 2 (asymmetric sidebands)
    x = (1 + 0.3 * np.cos(2 * ph)) * np.cos(11 * ph + 0.4 * np.sin(2 * ph))
    X = np.stack([x, np.cos(11 * ph)]) + 0.01 * np.random.default_rng(1).standard_normal((2, 4096))
    tr = make_features("tsa-mod", fs=fs).fit(X)
    F = tr.transform(X)
    names = list(tr.get_feature_names_out())
    assert F.shape == (2, 13) and names[:9] == list(make_features("tsa-ci", fs=fs).fit(X).get_feature_names_out())
    assert names[9:] == ["sideband_asymmetry", "sideband_asymmetry_db", "log10_phase_pp", "log10_phase_kurtosis"]
    np.testing.assert_allclose(F[:, :9], make_features("tsa-ci", fs=fs).fit_transform(X))
    # against the functions themselves on the same TSA
    spr = o.default_samples_per_rev(fs, f_sun, 11)
    tsa0 = o.tsa(o.resample_to_angle(X[0], fs, o.angle_from_speed(4096, fs, f_sun), spr), spr)
    want = pl.modulation_indicators(tsa0, 11, 2)
    assert F[0, 9] == pytest.approx(want["sideband_asymmetry"]) and F[0, 11] == pytest.approx(np.log10(want["phase_pp"]))
    c = 0.15 * (jv(0, 0.4) + jv(2, 0.4))
    assert F[0, 9] == pytest.approx((abs(jv(1, 0.4) + c) - abs(c - jv(1, 0.4))) / (abs(jv(1, 0.4) + c) + abs(c - jv(1, 0.4))),
                                    abs=0.02)
    assert abs(F[1, 9]) < abs(F[0, 9])
