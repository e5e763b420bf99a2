"""Reducer parameter schema: load, validate (messages name the key), save, round trip, derived values."""

import math
import re
import tomllib
from importlib import resources

import pytest
from hypothesis import given, settings, strategies as st

from rvdiag.errors import ConfigError, RvdiagError
from rvdiag.params import ReducerParams, body_properties
from rvdiag.params.schema import _SECTIONS


def test_default_is_rv20e():
    p = ReducerParams.default()
    s1, s2 = p.stage1, p.stage2
    assert (s1.sun_teeth, s1.planet_teeth, s2.cycloid_lobes, s2.pins) == (11, 33, 39, 40)
    assert s1.n_planets == s2.n_cranks == 2 and s2.n_discs == 2 and s2.disc_phase_deg == 180.0
    assert p.ratio == pytest.approx(121.0)
    assert s1.centre_distance == pytest.approx(27.5e-3)          # V-zero pair
    assert s1.operating_pressure_angle_deg == pytest.approx(20.0)


def test_every_value_in_the_toml_has_a_source_comment():
    text = resources.files("rvdiag.params").joinpath("rv20e.toml").read_text("utf-8")
    for line in text.splitlines():
        if re.match(r"^\s*[a-z_0-9]+\s*=", line) and not line.startswith("name"):
            assert "#" in line and len(line.split("#", 1)[1].strip()) > 5, line


def test_round_trip_save_load(tmp_path):
    p = ReducerParams.default()
    f = tmp_path / "p.toml"
    p.save(f)
    q = ReducerParams.load(f)
    assert q == p
    assert q.to_dict() == p.to_dict()
    assert tomllib.loads(p.to_toml()) == p.to_dict()


@settings(max_examples=25, deadline=None)
@given(width=st.floats(2e-3, 40e-3), e=st.floats(0.2e-3, 1.1e-3), x1=st.floats(0.36, 0.8))
def test_property_round_trip_after_replace(tmp_path_factory, width, e, x1):
    p = ReducerParams.default().replace(stage1={"face_width": width, "sun_profile_shift": x1},
                                        stage2={"eccentricity": e})
    f = tmp_path_factory.mktemp("rt") / "p.toml"
    p.save(f)
    assert ReducerParams.load(f) == p


def _bad(tmp_path, section, key, value):
    data = ReducerParams.default().to_dict()
    data[section][key] = value
    with pytest.raises(ConfigError) as exc:
        ReducerParams.from_dict(data, source="test.toml")
    return str(exc.value)


@pytest.mark.parametrize("section, key, value, expect", [
    ("stage1", "sun_teeth", 0, "sun_teeth"),
    ("stage1", "sun_teeth", 11.5, "sun_teeth"),
    ("stage1", "module", -1e-3, "module"),
    ("stage1", "face_width", "wide", "face_width"),
    ("stage1", "pressure_angle_deg", 50.0, "pressure_angle_deg"),
    ("stage1", "sun_profile_shift", 0.0, "sun_profile_shift"),
    ("stage1", "dedendum_coefficient", 0.9, "dedendum_coefficient"),
    ("stage1", "root_fillet_coefficient", 0.6, "root_fillet_coefficient"),
    ("stage1", "module", 4e-3, "pin_circle_radius"),
    ("stage2", "pins", 41, "pins"),
    ("stage2", "n_cranks", 3, "n_cranks"),
    ("stage2", "eccentricity", 1.3e-3, "eccentricity"),
    ("stage2", "pin_radius", 5e-3, "pin_radius"),
    ("stage2", "disc_phase_deg", 400.0, "disc_phase_deg"),
    ("material", "poisson_ratio", 0.7, "poisson_ratio"),
    ("material", "youngs_modulus", float("nan"), "youngs_modulus"),
    ("bodies", "crank_shaft_radius", 30e-3, "crank_shaft_radius"),
    ("bodies", "carrier_outer_radius", 60e-3, "carrier_outer_radius"),
    ("bearings", "crank_cycloid", 0.0, "crank_cycloid"),
    ("damping", "mesh_damping_ratio", -0.1, "mesh_damping_ratio"),
])
def test_validation_message_names_the_key(tmp_path, section, key, value, expect):
    msg = _bad(tmp_path, section, key, value)
    assert expect in msg and "test.toml" in msg


def test_missing_and_unknown_keys_named():
    data = ReducerParams.default().to_dict()
    del data["stage1"]["module"]
    with pytest.raises(ConfigError, match="missing key 'module'"):
        ReducerParams.from_dict(data)
    data = ReducerParams.default().to_dict()
    data["stage2"]["pinz"] = 3
    with pytest.raises(ConfigError, match="unknown key 'pinz'"):
        ReducerParams.from_dict(data)
    data = ReducerParams.default().to_dict()
    del data["material"]
    with pytest.raises(ConfigError, match=r"missing section \[material\]"):
        ReducerParams.from_dict(data)


def test_load_errors(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        ReducerParams.load(tmp_path / "none.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[stage1\nx = ", encoding="utf-8")
    with pytest.raises(ConfigError, match="not valid TOML"):
        ReducerParams.load(bad)
    with pytest.raises(RvdiagError, match="unknown parameter section"):
        ReducerParams.default().replace(gears={"x": 1})


def test_operating_centre_distance_with_profile_shift():
    """x1 + x2 != 0: a_w from inv(alpha_w) (ISO 21771), equal to the gear module's value."""
    from rvdiag.gears import GearPair

    p = ReducerParams.default().replace(stage1={"sun_profile_shift": 0.5, "planet_profile_shift": 0.0})
    a0 = math.radians(20.0)
    aw = math.radians(p.stage1.operating_pressure_angle_deg)
    inv = lambda a: math.tan(a) - a  # noqa: E731
    assert inv(aw) == pytest.approx(inv(a0) + 2 * 0.5 * math.tan(a0) / 44, rel=1e-12)
    assert p.stage1.centre_distance == pytest.approx(GearPair.sun_planet(p).centre_distance, rel=1e-12)
    assert p.stage1.centre_distance > 27.5e-3


def test_derived_masses_positive_and_scale_with_density():
    p = ReducerParams.default()
    b = body_properties(p)
    for body in (b.sun, b.planet, b.crank, b.cycloid, b.carrier, b.pin_wheel):
        assert body.mass > 0 and body.inertia > 0
    b2 = body_properties(p.replace(material={"density": 2 * p.material.density}))
    assert b2.planet.mass == pytest.approx(2 * b.planet.mass)


def test_all_sections_round_trip_through_to_dict():
    d = ReducerParams.default().to_dict()
    assert set(d) == set(_SECTIONS) | {"name"}


def test_crank_bearing_values_are_the_palmgren_estimates():
    """rv20e.toml holds bearing_estimates() rounded to two digits (no unexplained number)."""
    from rvdiag.params.derived import bearing_estimates, palmgren_roller_bearing_stiffness

    p = ReducerParams.default()
    est = bearing_estimates(p)
    assert p.bearings.crank_cycloid == pytest.approx(est["crank_cycloid"], rel=0.01)
    assert p.bearings.crank_carrier == pytest.approx(est["crank_carrier"], rel=0.01)
    # Palmgren: delta ~ F^0.9, so doubling the load raises the tangent stiffness by 2^0.1
    k1 = palmgren_roller_bearing_stiffness(1000.0, 20, 8e-3)
    k2 = palmgren_roller_bearing_stiffness(2000.0, 20, 8e-3)
    assert k2 / k1 == pytest.approx(2**0.1, rel=1e-12)


def test_torsional_values_follow_their_comments():
    """G J / L figures quoted in rv20e.toml's comments (shaft torsion, J = pi r^4 / 2)."""
    p = ReducerParams.default()
    G = p.material.shear_modulus
    gj_l = lambda r, L: G * math.pi * r**4 / 2 / L  # noqa: E731
    assert gj_l(p.bodies.crank_shaft_radius, 10e-3) == pytest.approx(3.9e4, rel=0.02)
    assert p.bearings.planet_crank_torsional == pytest.approx(0.5 * 3.9e4, rel=0.03)
    assert gj_l(p.bodies.sun_shaft_radius, 15e-3) == pytest.approx(5.2e3, rel=0.02)
    assert p.bearings.output_torsional == pytest.approx(0.7 * 49 * 60 * 180 / math.pi, rel=0.03)


def test_sun_body_is_the_gear_ring_on_the_input_shaft():
    """The RV-20E sun is cut on the input shaft: its mass and inertia are the gear ring's plus a solid
    steel shaft of bodies.input_shaft_radius x input_shaft_length (m = rho pi r^2 L, J = m r^2 / 2)."""
    from rvdiag.params.derived import annulus, input_shaft

    p = ReducerParams.default()
    rho, b, s1 = p.material.density, p.bodies, p.stage1
    ring = annulus(rho, 0.5 * s1.module * s1.sun_teeth, b.sun_shaft_radius, s1.face_width)
    m_shaft = rho * math.pi * b.input_shaft_radius**2 * b.input_shaft_length
    assert input_shaft(p).mass == pytest.approx(m_shaft, rel=1e-12)
    sun = body_properties(p).sun
    assert sun.mass == pytest.approx(ring.mass + m_shaft, rel=1e-12)
    assert sun.inertia == pytest.approx(ring.inertia + 0.5 * m_shaft * b.input_shaft_radius**2, rel=1e-12)
    assert 0.03 < sun.mass < 0.06  # 42 g, against 5.5 g for the bare gear ring
    longer = body_properties(p.replace(bodies={"input_shaft_length": 2 * b.input_shaft_length})).sun
    assert longer.mass == pytest.approx(sun.mass + m_shaft, rel=1e-12)


def test_pin_wheel_torsional_follows_its_comment():
    """bearings.pin_wheel_torsional = pin_wheel_housing x (pin-wheel outer radius)^2, rounded to 2 digits."""
    p = ReducerParams.default()
    k = p.bearings.pin_wheel_housing * p.bodies.pin_wheel_outer_radius**2
    assert p.bearings.pin_wheel_torsional == pytest.approx(k, rel=0.02)
    assert p.damping.pin_damping_ratio == p.damping.mesh_damping_ratio
