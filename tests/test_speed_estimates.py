"""A record's speed, three estimates each from its own signal (a motor current's supply line, a vibration's
stage-1 mesh line, a tachometer / encoder), and one conversion from an input-shaft frequency to the output speed
(:func:`rvdiag.kinematics.output_speed_from_input_hz`): the conversions give what the inline formulas they replace
gave, and the two readings of the supply line agree within half a bin."""

from __future__ import annotations

import numpy as np
import pytest

from rvdiag.features.current import electrical_frequency
from rvdiag.io.angles import estimate_shaft_speed
from rvdiag.kinematics import characteristic_frequencies, output_speed_from_input_hz, sun_speed_hz
from rvdiag.motor.lines import current_lines, output_speed_from_current, output_speed_from_fe
from rvdiag.params import ReducerParams
from rvdiag.spectral import amplitude_spectrum

P = ReducerParams.default()
SPEEDS = (1.0, 17.3, 45.0, 200.0)


@pytest.mark.parametrize("speed", SPEEDS)
def test_one_conversion_both_ways_equals_the_formulas_it_replaces(speed):
    hz = sun_speed_hz(P, output_speed_deg_s=speed)
    assert hz == speed / 360.0 * P.ratio  # io.angles' band and --output-speed, bit for bit
    assert output_speed_from_input_hz(P, hz) == hz * 360.0 / P.ratio  # io.angles' estimate detail, bit for bit
    assert output_speed_from_input_hz(P, hz) == pytest.approx(speed, rel=1e-14)
    fe = characteristic_frequencies(P, output_speed_deg_s=speed).fe
    old = fe / P.operation.motor_pole_pairs / P.ratio * 360.0  # output_speed_from_fe before: another rounding order
    assert output_speed_from_fe(fe, P) == pytest.approx(old, rel=1e-14)
    assert output_speed_from_fe(fe, P) == pytest.approx(speed, rel=1e-14)


@pytest.mark.parametrize("speed", (20.0, 33.3, 45.0))
def test_the_supply_line_read_two_ways_agrees_within_half_a_bin(speed):
    fs, n = 2000.0, 8192
    t = np.arange(n) / fs
    fe = characteristic_frequencies(P, output_speed_deg_s=speed).fe
    rng = np.random.default_rng(0)
    x = 3.0 * np.sin(2 * np.pi * fe * t + 0.3) + 0.05 * np.sin(2 * np.pi * 5 * fe * t) + 0.01 * rng.normal(size=n)
    f, amp = amplitude_spectrum(x, fs)
    by_bin = output_speed_from_current(x, fs, P)
    # the record's speed reads the peak bin: the bin of the largest amplitude above 2 Hz, unrefined
    assert by_bin == output_speed_from_fe(f[f >= 2.0][np.argmax(amp[f >= 2.0])], P)
    assert current_lines(x, fs, P)["output_speed_deg_s"] == by_bin
    refined = output_speed_from_fe(electrical_frequency(x) * fs, P)  # the features' per-window reading
    half_bin = output_speed_from_fe(0.5 * fs / n, P)
    assert abs(by_bin - refined) <= half_bin
    assert refined == pytest.approx(speed, abs=0.05 * half_bin)  # refined: far inside the bin


def test_a_vibration_mesh_line_gives_the_shaft_speed_inside_its_band_only():
    """The vibration estimate looks for the mesh order only where a plausible speed puts it: a stronger line
    outside the band (a harmonic) is not taken, as the current's whole-spectrum supply peak would take it."""
    fs, n = 20000.0, 16384
    t = np.arange(n) / fs
    order, shaft = 11.0, 9.37
    x = np.sin(2 * np.pi * order * shaft * t) + 3.0 * np.sin(2 * np.pi * 2 * order * shaft * t)
    assert estimate_shaft_speed(x, fs, order, (5.0, 15.0)) == pytest.approx(shaft, rel=2e-4)
    f, amp = amplitude_spectrum(x, fs)
    assert f[np.argmax(amp)] == pytest.approx(2 * order * shaft, abs=fs / n)  # the whole spectrum's peak: 2x
