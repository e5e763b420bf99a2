"""Involute geometry: radii, contact ratio, zones, undercut and interference checks."""

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from rvdiag.errors import GeometryError, ParameterError
from rvdiag.gears import Gear, GearPair
from rvdiag.gears.geometry import involute, inverse_involute
from rvdiag.params import ReducerParams


def test_standard_radii_iso21771():
    g = Gear(teeth=20, module=2e-3, face_width=0.02, profile_shift=0.3)
    assert g.pitch_radius == pytest.approx(0.020)
    assert g.base_radius == pytest.approx(0.020 * math.cos(math.radians(20)))
    assert g.tip_radius == pytest.approx(0.020 + 1.3 * 2e-3)
    assert g.root_radius == pytest.approx(0.020 - 0.95 * 2e-3)


def test_rv20e_sun_root_below_base_and_contact_ratio():
    pair = GearPair.sun_planet(ReducerParams.default())
    sun = pair.driver
    assert sun.root_radius < sun.base_radius  # the case Chen & Shao (2011) warn about
    # hand calculation (ISO 21771 eq. 74): eps = 1.4426 for m = 1.25, x = +-0.4
    ra1, rb1 = 8.625e-3, 6.875e-3 * math.cos(math.radians(20))
    ra2, rb2 = 21.375e-3, 20.625e-3 * math.cos(math.radians(20))
    eps = (math.sqrt(ra1**2 - rb1**2) + math.sqrt(ra2**2 - rb2**2)
           - 27.5e-3 * math.sin(math.radians(20))) / (math.pi * 1.25e-3 * math.cos(math.radians(20)))
    assert pair.contact_ratio == pytest.approx(eps, rel=1e-12)
    assert pair.centre_distance == pytest.approx(27.5e-3)


def test_zones_fractions_match_contact_ratio():
    pair = GearPair.from_dimensions(20, 40, 2e-3, 0.02)
    z = pair.zones(points=10000)
    frac_double = np.mean(z["pairs_in_contact"] == 2)
    assert frac_double == pytest.approx(pair.contact_ratio - 1.0, abs=2e-4)
    assert set(np.unique(z["pairs_in_contact"])) == {1, 2}


def test_fillet_meets_involute():
    for z, x in ((11, 0.4), (33, -0.4), (55, 0.0)):
        g = Gear(teeth=z, module=1e-3, face_width=0.01, profile_shift=x)
        yf, xf = g.fillet_point(g.pressure_angle)
        yi, xi = g.involute_point(g.form_radius)
        assert yf == pytest.approx(yi, rel=1e-9) and xf == pytest.approx(xi, rel=1e-9)
        prof = g.profile()
        assert np.all(np.diff(prof.y) > 0)


def test_undercut_rejected_with_remedy():
    with pytest.raises(GeometryError, match="undercut.*profile_shift >= 0.3"):
        Gear(teeth=11, module=1e-3, face_width=0.01)


def test_interference_rejected():
    # a 14-tooth pinion shifted just enough against undercut (x = 0.2 > 0.18) meets a large wheel
    # with a long addendum: the wheel tip reaches below the pinion's involute form circle
    pinion = Gear(teeth=14, module=1e-3, face_width=0.01, profile_shift=0.2, name="pinion")
    assert GearPair(pinion, Gear(teeth=200, module=1e-3, face_width=0.01))  # standard wheel: fine
    wheel = Gear(teeth=200, module=1e-3, face_width=0.01, addendum_coefficient=1.2,
                 dedendum_coefficient=1.45, name="wheel")
    with pytest.raises(GeometryError, match="interference.*wheel tip.*pinion below"):
        GearPair(pinion, wheel)


@pytest.mark.parametrize("kw, match", [
    (dict(teeth=0), "teeth"), (dict(teeth=2.5), "whole"), (dict(module=-1e-3), "module"),
    (dict(face_width=0.0), "face_width"), (dict(poisson_ratio=0.6), "poisson"),
    (dict(pressure_angle_deg=50), "pressure_angle"), (dict(teeth=12, profile_shift=1.2), "pointed"),
])
def test_bad_gear_parameters(kw, match):
    base = dict(teeth=30, module=1e-3, face_width=0.01)
    base.update(kw)
    with pytest.raises((GeometryError, ParameterError), match=match):
        Gear(**base)


def test_inverse_involute():
    for a in (0.1, 0.35, 0.7):
        assert inverse_involute(involute(a)) == pytest.approx(a, rel=1e-12)


@settings(max_examples=40, deadline=None)
@given(z1=st.integers(18, 60), z2=st.integers(18, 120), x=st.floats(-0.05, 0.5))
def test_property_contact_ratio_and_radii(z1, z2, x):
    pair = GearPair.from_dimensions(z1, z2, 2e-3, 0.02, x1=x, x2=0.0)
    d = pair.driver
    assert d.root_radius < d.pitch_radius < d.tip_radius
    assert 1.0 <= pair.contact_ratio < 2.2
    # operating pressure angle grows with the sum of the profile shifts
    if abs(x) > 1e-6:
        assert (pair.operating_pressure_angle > d.pressure_angle) == (x > 0)
    # the driver's tooth thickness at the pitch circle grows with x
    assert d.pitch_half_thickness == pytest.approx(2e-3 * (math.pi / 4 + x * math.tan(d.pressure_angle)))
