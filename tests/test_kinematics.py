"""Characteristic frequencies against Table 3 of Li, Zhao et al. 2024 (motor current; docs/references.md)."""

from __future__ import annotations

import pytest
from numpy.testing import assert_allclose

from rvdiag.errors import ParameterError
from rvdiag.kinematics import FREQUENCY_KEYS, characteristic_frequencies, sun_speed_hz
from rvdiag.params import ReducerParams

P0 = ReducerParams.default()

# output speed deg/s -> (fe, f1, f2, f3, fsp, fcs), Li, Zhao et al. 2024, Table 3 (p = 5, i = 121)
TABLE3 = {
    30.0: (50.42, 10.08, 3.25, 0.083, 109.96, 129.96),
    45.0: (75.625, 15.125, 4.875, 0.125, 165.0, 195.0),
    60.0: (100.83, 20.17, 6.5, 0.167, 220.04, 260.04),
}


@pytest.mark.parametrize("speed", sorted(TABLE3))
def test_table3_within_half_percent(speed):
    f = characteristic_frequencies(P0, output_speed_deg_s=speed, pole_pairs=5)
    got = (f.fe, f.f1, f.f2, f.f3, f.fsp, f.fcs)
    assert_allclose(got, TABLE3[speed], rtol=5e-3)


def test_fault_frequencies_and_keys():
    f = characteristic_frequencies(P0, input_speed_rpm=1210.0)  # f_s = 20.1667 Hz, f_H = f_s / 121
    d = f.as_dict()
    assert tuple(d) == FREQUENCY_KEYS
    fs, fh = 1210.0 / 60.0, 1210.0 / 60.0 / 121.0
    assert_allclose(d["f_sun_fault"], 2 * (fs - fh))
    assert_allclose(d["f_planet_fault"], d["fsp"] / 33)
    assert_allclose(d["f_cycloid_fault"], 40 * fh)
    assert_allclose(d["f_pin_fault"], 39 * fh)
    # consistency of the two speed inputs
    g = characteristic_frequencies(P0, output_speed_deg_s=fh * 360.0)
    assert_allclose(list(g.as_dict().values()), list(d.values()), rtol=1e-12)


@pytest.mark.parametrize("kw", [dict(), dict(input_speed_rpm=100.0, output_speed_deg_s=3.0),
                                dict(input_speed_rpm=-1.0), dict(output_speed_deg_s=0.0)])
def test_bad_speed_inputs(kw):
    with pytest.raises(ParameterError):
        sun_speed_hz(P0, **kw)


def test_bad_pole_pairs():
    with pytest.raises(ParameterError):
        characteristic_frequencies(P0, input_speed_rpm=100.0, pole_pairs=0)
