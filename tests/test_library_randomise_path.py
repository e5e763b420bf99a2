"""Domain randomisation of the sensor path and the noise colour in library builds ([randomise] path keys)."""

from __future__ import annotations

import numpy as np
import pytest

from rvdiag.dynamics.noise import add_awgn, add_coloured_noise
from rvdiag.errors import ConfigError, ParameterError
from rvdiag.library import LibraryConfig, make_plan, run_unit
from rvdiag.library.build import Job
from rvdiag.params import ReducerParams

BASE = {
    "mode": "split-by-simulation", "seed": 3, "model": {"substeps": 4},
    "signal": {"fs": 48000.0, "duration_s": 0.06, "transient_s": 0.02, "segment_length": 1024, "hop": 1024},
    "operation": {"output_speed_deg_s": 45.0, "load_Nm": 100.0, "noise_snr_db": 30.0},
    "split": {"simulations_per_state": 2, "test_simulations_per_state": 1},
    "states": {"T1": {}, "T2": {}},
}
PATH = {"path_resonance_hz": {"min": 2000.0, "max": 8000.0}, "path_damping_ratio": {"min": 0.02, "max": 0.1},
        "housing_added_mass": {"min": 0.0, "max": 20.0}, "noise_colour_exponent": {"min": 0.0, "max": 1.5}}


def _cfg(randomise=None):
    data = dict(BASE)
    if randomise is not None:
        data["randomise"] = randomise
    return LibraryConfig.from_dict(data)


def test_path_draws_are_seeded_recorded_and_leave_other_draws_alone():
    plain, rnd = make_plan(_cfg()), make_plan(_cfg(PATH))
    for a, b in zip(plain, rnd):
        # the draws that existed before are the same bits: old configs keep their libraries
        assert (a.speed, a.load_Nm, a.noise_snr_db, a.seed) == (b.speed, b.load_Nm, b.noise_snr_db, b.seed)
        assert a.mounting == {} and a.noise_exponent is None
        assert 2000.0 <= b.mounting["path_resonance_hz"] <= 8000.0
        assert 0.0 <= b.mounting["housing_added_mass"] <= 20.0 and 0.0 <= b.noise_exponent <= 1.5
    assert make_plan(_cfg(PATH)) == rnd  # deterministic for the seed
    assert rnd[0].mounting != rnd[1].mounting
    cfg = _cfg(PATH)
    assert LibraryConfig.from_dict(cfg.to_dict()) == cfg  # round trip, stored with the library


def test_bad_path_ranges_are_refused():
    with pytest.raises(ConfigError, match="path_resonance_hz"):
        _cfg({"path_resonance_hz": {"min": -5.0, "max": 100.0}})
    with pytest.raises(ConfigError, match="noise_colour_exponent"):
        _cfg({"noise_colour_exponent": 4.0})
    data = dict(BASE, operation={"output_speed_deg_s": 45.0, "load_Nm": 100.0}, randomise={"noise_colour_exponent": 1.0})
    with pytest.raises(ConfigError, match="needs \\[operation\\] noise_snr_db"):
        LibraryConfig.from_dict(data)


def test_a_unit_is_simulated_through_its_drawn_path_and_records_it():
    cfg = _cfg(PATH)
    job = Job.from_config(cfg, ReducerParams.default())
    unit = make_plan(cfg)[0]
    res = run_unit(unit, job)
    assert res.meta["mounting.path_resonance_hz"][0] == unit.mounting["path_resonance_hz"]
    assert res.meta["noise_colour_exponent"][0] == unit.noise_exponent
    # the same unit without its path: a different signal
    bare = run_unit(type(unit)(**{**unit.__dict__, "mounting": {}, "noise_exponent": None}), job)
    assert np.linalg.norm(res.X - bare.X) > 0.05 * np.linalg.norm(bare.X)


def test_coloured_noise_has_its_snr_and_slope():
    rng = np.random.default_rng(0)
    x = np.sin(np.linspace(0, 400 * np.pi, 2**16))
    for beta in (0.0, 1.0, 2.0):
        n = add_coloured_noise(x, 10.0, beta, np.random.default_rng(1)) - x
        # coloured noise is scaled to the SNR exactly; white noise (add_awgn) has it in expectation
        assert 10 * np.log10(np.mean(x**2) / np.mean(n**2)) == pytest.approx(10.0, abs=1e-9 if beta else 0.05)
        p = np.abs(np.fft.rfft(n)) ** 2
        f = np.arange(p.size)
        band = (f > 100) & (f < p.size - 1)
        slope = np.polyfit(np.log10(f[band]), np.log10(p[band] + 1e-300), 1)[0]
        assert slope == pytest.approx(-beta, abs=0.1), (beta, slope)
    # exponent 0 is the white noise of add_awgn, draw for draw
    assert np.array_equal(add_coloured_noise(x, 10.0, 0.0, np.random.default_rng(5)),
                          add_awgn(x, 10.0, np.random.default_rng(5)))
    with pytest.raises(ParameterError, match="exponent"):
        add_coloured_noise(x, 10.0, -1.0, rng)
