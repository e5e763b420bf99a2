""""Not recognised" for a baseline monitor, judged against the machine's own baseline (rvdiag.monitoring.diagnosis):
the mesh-line check counts only where the baseline shows the lines; the level check refuses a disconnected sensor,
the baseline's spectrum at another gain or unit and another machine's spectrum, never a machine only louder."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.signal import lfilter

from rvdiag.features.mesh_lines import mesh_lines
from rvdiag.kinematics import characteristic_frequencies
from rvdiag.monitoring.diagnosis import (GAIN_FACTOR, LEVEL_FACTOR, MASK_DB, SHAPE_FACTOR, SPREAD_FACTOR, band_ratios,
                                        level_check_against_baseline, mesh_check_against_baseline)
from rvdiag.params import ReducerParams

FS, L, SPEED = 48000.0, 12000, 30.0
P = ReducerParams.default()
FCS = characteristic_frequencies(P, output_speed_deg_s=SPEED).fcs
t = np.arange(L) / FS


def _base(windows):
    return SimpleNamespace(X=np.asarray(windows), meta={"output_speed_deg_s": np.full(len(windows), SPEED)})


def _recognition_of(x):
    lines = mesh_lines(x, FS, P, SPEED)
    return {"recognised": bool(lines["present"]), "reason": None if lines["present"] else "no mesh line",
            "checks": {"mesh_lines": lines}}


def test_no_mesh_line_counts_only_where_the_baseline_shows_one():
    rng = np.random.default_rng(0)
    noise = rng.standard_normal(L)
    with_line = np.sin(2 * np.pi * FCS * t) + 0.05 * rng.standard_normal(L)
    speed = {"output_speed_deg_s": SPEED}
    rec = _recognition_of(noise)
    assert not rec["recognised"]
    # the baseline shows the cycloid-pin mesh line, the record does not: not this machine
    out = mesh_check_against_baseline(rec, noise, _base([with_line]), FS, speed, L)
    assert not out["recognised"] and "the machine's baseline shows" in out["reason"] and "stage2" in out["reason"]
    # the baseline shows no line either (a quiet mesh behind its path): the lines say nothing, the index decides
    out = mesh_check_against_baseline(rec, noise, _base([rng.standard_normal(L)]), FS, speed, L)
    assert out["recognised"] and out["checks"]["mesh_lines"]["baseline"] == []
    # a record with the line passes untouched
    ok = _recognition_of(with_line)
    assert mesh_check_against_baseline(ok, with_line, _base([noise]), FS, speed, L) is ok


def test_without_a_sampling_rate_a_record_far_outside_the_baselines_level_is_not_recognised():
    rng = np.random.default_rng(1)
    base = _base([rng.standard_normal(L) * g for g in (0.9, 1.0, 1.1)])
    rec = {"recognised": True, "reason": None, "checks": {}}
    same = level_check_against_baseline(rec, 1.05 * rng.standard_normal(L), base)
    assert same["recognised"] and same["checks"]["level"]["factor"] == LEVEL_FACTOR
    loud = level_check_against_baseline(rec, 20.0 * rng.standard_normal(L), base)
    assert not loud["recognised"] and "above the baseline's range" in loud["reason"]
    quiet = level_check_against_baseline(rec, 0.01 * rng.standard_normal(L), base)
    assert not quiet["recognised"] and "below" in quiet["reason"]


def test_a_line_masked_by_added_energy_is_a_changed_machine_a_lost_line_is_not():
    """A broken tooth's impacts raise the floor around the mesh lines (rvdiag.features.mesh_lines.confirm_speed):
    the line is still there, under more energy, and the record goes on to its index.  A disconnected sensor adds no
    energy at the reducer's orders: its line is lost, and it stays "not recognised".  Both read on the mean of the
    record's windows (a record of 4 windows here)."""
    rng = np.random.default_rng(2)
    k = 4
    tk = np.arange(k * L) / FS
    base = _base([np.sin(2 * np.pi * FCS * t) + 0.05 * rng.standard_normal(L) for _ in range(3)])
    speed = {"output_speed_deg_s": SPEED}
    masked = np.sin(2 * np.pi * FCS * tk) + 30.0 * rng.standard_normal(k * L)
    rec = _recognition_of(masked)
    assert not rec["recognised"]
    out = mesh_check_against_baseline(rec, masked, base, FS, speed, L)
    lines = out["checks"]["mesh_lines"]
    assert out["recognised"] and "stage2" in lines["baseline"] and "stage2" in lines["masked"]
    assert lines["record_lines"]["stage2"]["amplitude"] >= lines["baseline_lines"]["stage2"]["amplitude"] * 10 ** (
        -MASK_DB / 20)
    disconnected = 0.01 * rng.standard_normal(k * L)
    out = mesh_check_against_baseline(_recognition_of(disconnected), disconnected, base, FS, speed, L)
    assert not out["recognised"] and "the machine's baseline shows" in out["reason"] and "stage2" in out["reason"]
    assert out["checks"]["mesh_lines"]["masked"] == []


def test_a_line_read_just_under_its_threshold_is_weaker_not_lost():
    """A baseline whose line stands just above the reading's 10 dB (8 windows: 11.5 dB here): a record of 2 windows
    with the line at half its amplitude (-6 dB) and its floor 1 dB lower reads it under 10 dB, yet its amplitude at
    the line stays within LOST_DB of the baseline's: "weaker", recognised, on to its index (healthy records of
    simulated joints did this, -5.4 to +0.4 dB).  The same record with the sensor disconnected (everything 40 dB down) has lost the line."""
    from rvdiag.monitoring.diagnosis import LOST_DB

    rng = np.random.default_rng(0)
    k, speed = 2, {"output_speed_deg_s": SPEED}
    tk = np.arange(k * L) / FS
    base = _base([np.sin(2 * np.pi * FCS * t) + 10.0 * rng.standard_normal(L) for _ in range(8)])
    x = 0.5 * np.sin(2 * np.pi * FCS * tk) + 9.0 * rng.standard_normal(k * L)  # its floor a little lower
    rec = _recognition_of(x)
    assert not rec["recognised"]
    out = mesh_check_against_baseline(rec, x, base, FS, speed, L)
    lines = out["checks"]["mesh_lines"]
    assert 10.0 < lines["baseline_lines"]["stage2"]["height_db"] < 10.0 + LOST_DB
    assert lines["record_lines"]["stage2"]["height_db"] < 10.0 and "stage2" not in lines["record_windows"]
    assert out["recognised"] and lines["weaker"] == ["stage2"] and lines["masked"] == []
    drop = 20 * np.log10(lines["record_lines"]["stage2"]["amplitude"] / lines["baseline_lines"]["stage2"]["amplitude"])
    assert -LOST_DB < drop < 0
    off = 0.01 * x
    out = mesh_check_against_baseline(_recognition_of(off), off, base, FS, speed, L)
    assert not out["recognised"] and "the machine's baseline shows stage2" in out["reason"]
    assert out["checks"]["mesh_lines"]["weaker"] == [] == out["checks"]["mesh_lines"]["masked"]


def test_a_current_monitor_does_not_read_vibration_mesh_lines_on_its_records(monkeypatch):
    """monitor_record of a motor-current monitor skips the vibration mesh-line check (a phase current has no mesh
    line to show); the same record under a vibration monitor is refused by it."""
    from pathlib import Path

    import rvdiag.monitoring.diagnosis as diagnosis
    from rvdiag.datasets.store import Samples
    from rvdiag.monitoring.baseline import Baseline

    class Scored(Exception):
        pass

    def scored(*args, **kwargs):
        raise Scored

    monkeypatch.setattr(diagnosis, "paired_features", scored)
    rng = np.random.default_rng(3)
    X = np.array([np.sin(2 * np.pi * FCS * t) + 0.05 * rng.standard_normal(L) for _ in range(3)])
    meta = {"output_speed_deg_s": np.full(3, SPEED), "load_Nm": np.full(3, 20.0)}
    base = Baseline(path=Path("base.zarr"), n_records=3, operating_points=[{"output_speed_deg_s": SPEED,
                                                                             "load_Nm": 20.0}], fs=FS,
                    samples=Samples(X=X, y=np.array(["T1"] * 3), meta=meta, index=np.arange(3)))
    record = SimpleNamespace(data=rng.standard_normal(L), fs=FS, path=None, channel=None,
                             metadata={"output_speed_deg_s": SPEED, "load_Nm": 20.0})

    def model(signal):
        card = {"needs_baseline": True, "training_store": {"kind": "simulated", "signal": signal}}
        return SimpleNamespace(path=Path("mon"), card=card, fs=FS, input_length=L,
                               estimator=SimpleNamespace(alpha=0.05, threshold_=1.0, features=None))

    vib = diagnosis.monitor_record(model("acceleration"), record, base)
    assert not vib.recognised and "no mesh line" in vib.reason and "the machine's baseline shows" in vib.reason
    with pytest.raises(Scored):  # recognised: it goes on to its change against the baseline
        diagnosis.monitor_record(model("current"), record, base)


def _path(x, f0=2500.0, zeta=0.02):
    """The path from the mesh to the sensor: one lightly damped resonance (a two-pole resonator)."""
    w = 2 * np.pi * f0 / FS
    r = np.exp(-zeta * w)
    return lfilter([1.0], [1.0, -2 * r * np.cos(w), r * r], x)


def _impacts(n):
    """A broken tooth's impacts (0.33 ms each, 12 a second) rung through the same path."""
    imp = np.zeros(n)
    imp[:: int(FS / 12)] = 1.0
    return _path(np.convolve(imp, np.hanning(16), "same"))


FLOOR = 0.12  # the sensor's own floor (RMS), about 20 dB under the healthy machine's


def _machine(rng, n):
    """The healthy machine as its sensor records it: two mesh harmonics, the mesh's broadband excitation through
    the path, the sensor's floor."""
    tn = np.arange(n) / FS
    return (np.sin(2 * np.pi * 640 * tn) + 0.5 * np.sin(2 * np.pi * 1280 * tn) + _path(0.05 * rng.standard_normal(n))
            + FLOOR * rng.standard_normal(n))


def test_a_gain_or_another_machine_is_not_recognised_a_louder_machine_is():
    rng = np.random.default_rng(4)
    base = _base([_machine(rng, L) for _ in range(4)])
    hi = np.sqrt(np.mean(base.X ** 2, axis=1)).max()

    def check(x):
        return level_check_against_baseline({"recognised": True, "reason": None, "checks": {}}, x, base, FS, L,
                                            {"output_speed_deg_s": SPEED})

    def rms(x):
        return float(np.sqrt(np.mean(x ** 2)))

    healthy = _machine(rng, 2 * L)
    out = check(healthy)
    assert out["recognised"] and out["checks"]["level"]["louder"] is False
    assert 1 / GAIN_FACTOR < out["checks"]["level"]["bands"]["min"] <= 1 <= out["checks"]["level"]["bands"]["max"]
    # a broken tooth 20x and 50x the baseline's RMS: its impacts ring the path, the sensor's floor stays
    imp = _impacts(2 * L)
    for target in (20.0, 50.0):
        loud = healthy + np.sqrt((target * hi) ** 2 - rms(healthy) ** 2) / rms(imp) * imp
        assert rms(loud) / hi > LEVEL_FACTOR
        out = check(loud)
        assert out["recognised"], out["reason"]
        lv = out["checks"]["level"]
        assert lv["louder"] is True and lv["bands"]["min"] <= GAIN_FACTOR and lv["bands"]["shape"] <= SHAPE_FACTOR
    # the healthy record in another unit (m/s^2 read as mm/s^2, or as g, g as m/s^2): the same spectrum at a gain
    for gain in (1000.0, 9.81, 1 / 9.81):
        out = check(gain * healthy)
        assert not out["recognised"] and "another sensor, gain or unit" in out["reason"], gain
    out = check(9.81 * healthy)
    assert "alike" in out["reason"] and rms(9.81 * healthy) / hi < LEVEL_FACTOR  # the RMS range alone passed it
    # ... and a loud machine in another unit keeps no band at the machine's level
    out = check(1000.0 * loud)
    assert not out["recognised"] and "no band left at the machine's level" in out["reason"]
    # louder in every band but unevenly, within LEVEL_FACTOR: a changed machine, not a gain
    uneven = 3 * healthy + _path(0.6 * rng.standard_normal(2 * L))
    b = band_ratios(uneven.reshape(2, L), base.X, FS)
    assert b["min"] > GAIN_FACTOR and b["max"] / b["min"] > SPREAD_FACTOR and rms(uneven) / hi < LEVEL_FACTOR
    assert check(uneven)["recognised"]
    # another machine 20x as loud: a bearing's impacts ringing at 9 kHz, where this machine has only its floor
    w = 2 * np.pi * 9000.0 / FS
    ring = lfilter([1.0], [1.0, -2 * 0.99 * np.cos(w), 0.99 ** 2], (rng.random(2 * L) < 0.002).astype(float))
    out = check(20 * hi * ring / np.std(ring))
    assert not out["recognised"] and "another machine or sensor" in out["reason"]
    assert out["checks"]["level"]["bands"]["shape"] > SHAPE_FACTOR
    # a disconnected sensor that picks up the mains' hum: quieter in every band
    t2 = np.arange(2 * L) / FS
    out = check(0.01 * rng.standard_normal(2 * L) + 0.3 * hi * np.sin(2 * np.pi * 50 * t2))
    assert not out["recognised"] and "disconnected sensor" in out["reason"]


def test_band_ratios_are_third_octaves_of_enough_lines_and_a_gain_moves_them_alike():
    rng = np.random.default_rng(6)
    B = rng.standard_normal((3, L))
    b = band_ratios(7.0 * B[:2], B[:2], FS)
    # base-ten third octaves (IEC 61260-1): 10 a decade, the first wide enough for 8 lines of FS / L = 4 Hz (its
    # width is 0.23 of its midband), the last holding FS / 2
    assert np.allclose(np.diff(np.log10(b["hz"])), 0.1) and b["hz"][0] == pytest.approx(158.5, rel=1e-3)
    assert b["hz"][-1] * 10 ** -0.05 < FS / 2 <= b["hz"][-1] * 10 ** 0.05
    assert np.allclose(b["ratio"], 7.0, rtol=1e-12) and b["shape"] == pytest.approx(1.0, rel=1e-12)
    # noise against other noise: every band near 7 (a band of 8 Hann-windowed lines or more, 2 windows against 3,
    # scatters by less than a factor 2)
    b = band_ratios(7.0 * rng.standard_normal((2, L)), B, FS)
    assert 7.0 / 2 < b["min"] <= b["median"] <= b["max"] < 7.0 * 2
    assert b["overall"] == pytest.approx(7.0, rel=0.05) and b["shape"] < 2.0


def test_the_baselines_spectra_kept_between_records_give_the_same_checks(monkeypatch):
    """A baseline opened once keeps what the checks read on its own windows (Baseline.spectra): the level and
    mesh-line checks of many records with the cache equal those without it, and the baseline's spectrum is read once
    per operating point."""
    import rvdiag.monitoring.diagnosis as diagnosis

    rng = np.random.default_rng(5)
    base = _base([_machine(rng, L) for _ in range(4)])
    base.meta = {"output_speed_deg_s": np.array([SPEED, SPEED, 2 * SPEED, 2 * SPEED]),
                 "load_Nm": np.array([50.0, 50.0, 50.0, 50.0])}
    calls = []
    spectrum = diagnosis._mean_power_spectrum
    monkeypatch.setattr(diagnosis, "_mean_power_spectrum", lambda X, fs: calls.append(len(X)) or spectrum(X, fs))
    cache: dict = {}
    records = [_machine(rng, 2 * L), 20 * _machine(rng, 2 * L), 9.81 * _machine(rng, 2 * L),
               0.01 * rng.standard_normal(2 * L)] * 2
    for i, x in enumerate(records):
        v = {"output_speed_deg_s": SPEED if i < 4 else 2 * SPEED}
        rec = _recognition_of(x)
        args = (FS, v, L, 50.0)
        plain = diagnosis.mesh_check_against_baseline(rec, x, base, *args)
        kept = diagnosis.mesh_check_against_baseline(rec, x, base, *args, cache=cache)
        assert repr(kept) == repr(plain)
        rec = {"recognised": True, "reason": None, "checks": {}}
        plain = level_check_against_baseline(rec, x, base, FS, L, v, 50.0)
        kept = level_check_against_baseline(rec, x, base, FS, L, v, 50.0, cache=cache)
        assert repr(kept) == repr(plain)
    assert sorted(k[0] for k in cache) == ["power", "power", "rms"]  # two operating points
    calls.clear()
    level_check_against_baseline(rec, records[0], base, FS, L, {"output_speed_deg_s": SPEED}, 50.0, cache=cache)
    assert calls == [2]  # the record's two windows alone
