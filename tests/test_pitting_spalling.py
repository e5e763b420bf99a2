"""Pitting and spalling (partial tooth-face loss): exactness at zero severity, locality, the Hertz term with the
remaining width, the cut section, severity ordering and monotonicity, validation, and the T7/T8 states."""

import math

import numpy as np
import pytest

from rvdiag.errors import GeometryError, ParameterError
from rvdiag.gears import BrokenTooth, GearPair, Pitting, Spalling, ToothFaults, mesh_stiffness
from rvdiag.gears import tvms
from rvdiag.gears.faults import cut_section, flank_zone, working_flank
from rvdiag.params import ReducerParams

CYCLES, PPC = 11, 360  # one sun revolution


@pytest.fixture(scope="module")
def pair():
    return GearPair.sun_planet(ReducerParams.default())


@pytest.fixture(scope="module")
def healthy(pair):
    return mesh_stiffness(pair, cycles=CYCLES, points_per_cycle=PPC)


def _tooth0_contact(pair, angle):
    """Mask (candidates x angles) of driver tooth 0 in contact, and the flank position s of each contact (m)."""
    pidx, roll, inc = pair.contact_state(angle)
    rho1, _ = pair.roll_lengths(roll)
    return inc & (np.mod(pidx, pair.driver.teeth) == 0), rho1**2 / (2.0 * pair.driver.base_radius)


@pytest.mark.parametrize("fault", [Pitting(area_fraction=0.0), Spalling(width_fraction=0.0)])
def test_zero_severity_is_healthy_bit_for_bit(pair, healthy, fault):
    res = mesh_stiffness(pair, ToothFaults({0: (fault,)}), cycles=CYCLES, points_per_cycle=PPC)
    np.testing.assert_array_equal(res.stiffness_N_per_m, healthy.stiffness_N_per_m)


@pytest.mark.parametrize("fault", [Pitting(0.15, centre_fraction=0.6), Spalling(0.5, 0.33, centre_fraction=0.6)])
def test_stiffness_drops_only_where_the_damaged_flank_is_loaded(pair, healthy, fault):
    """Unchanged (bit for bit) while tooth 0 is out of contact or touches below the damaged zone; softer when it
    touches inside the zone (Hertz width and cut sections); above the zone only the beam terms see the cut
    sections below the load, so it is softer or equal, never stiffer."""
    res = mesh_stiffness(pair, ToothFaults({0: (fault,)}), cycles=CYCLES, points_per_cycle=PPC)
    on, s = _tooth0_contact(pair, res.angle_rad)
    lo, hi = flank_zone(pair, "driver", 0.4 if isinstance(fault, Pitting) else 0.33, 0.6)
    loss = fault.flank_loss(pair, "driver")
    width_lost = np.where(on, loss.width(s), 0.0)
    k, k0 = res.pair_stiffness_N_per_m, healthy.pair_stiffness_N_per_m

    untouched = ~on.any(axis=0)
    np.testing.assert_array_equal(res.stiffness_N_per_m[untouched], healthy.stiffness_N_per_m[untouched])
    below = on & (s < lo - 20e-6)   # 20 um: ten times the spacing of the section table along the flank
    assert below.sum() > 10
    np.testing.assert_array_equal(k[below], k0[below])
    inside = on & (width_lost > 0)
    assert inside.sum() > 10 and np.all(k[inside] < k0[inside])
    above = on & (s > hi)
    assert above.sum() > 10 and np.all(k[above] <= k0[above])
    # the drop in the zone is mostly the Hertz width: larger there than anywhere above it
    assert (1 - k[inside] / k0[inside]).max() > 2 * (1 - k[above] / k0[above]).max()


def test_hertz_term_uses_the_remaining_width(pair):
    """k_h = pi E L_eff / (4 (1 - nu^2)) with L_eff = L - delta_L at the contact (both gears of one steel)."""
    E, nu, L = pair.driver.youngs_modulus, pair.driver.poisson_ratio, pair.driver.face_width
    closed = lambda width: math.pi * E * width / (4.0 * (1.0 - nu**2))  # noqa: E731
    healthy = tvms.tooth_pair_components(pair, np.array([1e-3]))
    assert 1.0 / healthy["hertz"][0] == pytest.approx(closed(L), rel=1e-12, abs=0)

    spall = Spalling(0.4, 0.33)
    lo, hi = spall.flank_loss(pair, "driver").spalls[0][:2]
    pits = Pitting(0.15)
    rows = pits.flank_loss(pair, "driver").pit_rows
    for fault, s_contact, width in [(spall, 0.5 * (lo + hi), 0.6 * L),
                                    (pits, rows[0][0], L - rows[0][2] * 2 * rows[0][1])]:
        table = tvms._damaged_table(pair, "driver", (fault,))
        rho = math.sqrt(2.0 * pair.driver.base_radius * s_contact)
        roll = np.array([rho - pair.start_roll_length_driver])
        comp = tvms.tooth_pair_components(pair, roll, (table, tvms._healthy_table(pair, "driven")))
        assert comp["contact_width"][0] == pytest.approx(width, rel=1e-12, abs=0)
        assert 1.0 / comp["hertz"][0] == pytest.approx(closed(width), rel=1e-12, abs=0)


def test_cut_section_against_a_sliced_section():
    """Area and centroidal second moment of a t x L section less two strips at its loaded edge, against a
    midpoint sum over 220,000 slices across the thickness (the strip edges fall on slice edges)."""
    t, L = 2.2e-3, 10e-3
    cavities = [(np.array(3e-3), np.array(0.2e-3)), (np.array(1.5e-3), np.array(0.5e-3))]
    area, inertia = cut_section(np.array(t), L, cavities)
    n = 220_000
    xi = (np.arange(n) + 0.5) * t / n            # from the unloaded edge
    b = L - sum(w * (xi > t - d) for w, d in cavities)
    a_num = b.sum() * t / n
    c = (b * xi).sum() * t / n / a_num
    i_num = (b * (xi - c) ** 2).sum() * t / n
    assert float(area) == pytest.approx(a_num, rel=1e-9, abs=0)
    assert float(inertia) == pytest.approx(i_num, rel=1e-6, abs=0)
    # whole section: the rectangle
    a0, i0 = cut_section(np.array(t), L, [])
    assert float(a0) == pytest.approx(t * L, rel=1e-15, abs=0)
    assert float(i0) == pytest.approx(t**3 * L / 12, rel=1e-12, abs=0)


def test_loss_ordering_pitting_spalling_broken(pair, healthy):
    """Default severities (T7, T8, T2): mean and largest local loss ordered pitting < spalling < broken tooth."""
    k0 = healthy.stiffness_N_per_m
    mean_loss, local_loss = {}, {}
    for state in ("T7", "T8", "T2"):
        k = mesh_stiffness(pair, ToothFaults.for_state(state), cycles=CYCLES, points_per_cycle=PPC).stiffness_N_per_m
        mean_loss[state] = 1.0 - k.mean() / k0.mean()
        local_loss[state] = float(np.max(1.0 - k / k0))
    assert 0 < mean_loss["T7"] < mean_loss["T8"] < mean_loss["T2"]
    assert 0 < local_loss["T7"] < local_loss["T8"] < local_loss["T2"] == 1.0
    # the figures of docs/tvms.md, section 3
    assert mean_loss["T7"] == pytest.approx(0.00072, abs=0.00005)
    assert mean_loss["T8"] == pytest.approx(0.00344, abs=0.00005)
    assert local_loss["T7"] == pytest.approx(0.0212, abs=0.0005)
    assert local_loss["T8"] == pytest.approx(0.0767, abs=0.0005)


@pytest.mark.parametrize("make, values", [
    (lambda v: Pitting(area_fraction=v), [0.0, 0.05, 0.15, 0.3, 0.45]),
    (lambda v: Pitting(depth=v), [0.02e-3, 0.1e-3, 0.3e-3]),
    (lambda v: Spalling(width_fraction=v), [0.0, 0.25, 0.5, 0.75, 0.9]),
    (lambda v: Spalling(length_fraction=v), [0.1, 0.33, 0.6, 0.8]),
    (lambda v: Spalling(depth=v), [0.05e-3, 0.2e-3, 0.5e-3]),
])
def test_stiffness_falls_monotonically_with_severity(pair, make, values):
    curves = [mesh_stiffness(pair, ToothFaults({0: (make(v),)}), cycles=CYCLES, points_per_cycle=90).stiffness_N_per_m
              for v in values]
    for a, b in zip(curves, curves[1:]):
        assert np.all(b <= a)               # pointwise never stiffer
        assert b.mean() < a.mean()          # strictly softer on average


@pytest.mark.parametrize("make, match", [
    (lambda: Pitting(-0.1), r"^pitting area fraction must lie in \[0, 0\.785398\), got -0\.1$"),
    (lambda: Pitting(0.8), r"^pitting area fraction must lie in \[0, 0\.785398\), got 0\.8$"),
    (lambda: Pitting(radius=0.0), r"^pit radius must be > 0, got 0\.0 m$"),
    (lambda: Pitting(depth=float("nan")), r"^pit depth must be finite, got nan$"),
    (lambda: Pitting(band_fraction=0.0), r"^pitting band fraction must lie in \(0, 1\], got 0\.0$"),
    (lambda: Pitting(centre_fraction=1.5), r"^pitting band centre fraction must lie in \[0, 1\], got 1\.5$"),
    (lambda: Pitting("0.1"), r"^pitting area fraction must be a number, got '0\.1'$"),
    (lambda: Spalling(1.5), r"^spall width fraction must lie in \[0, 1\], got 1\.5$"),   # 1: through the face
    (lambda: Spalling(length_fraction=0.0), r"^spall length fraction must lie in \(0, 1\], got 0\.0$"),
    (lambda: Spalling(depth=-1e-4), r"^spall depth must be > 0, got -0\.0001 m$"),
    (lambda: ToothFaults.for_state("T7", pit_area_fraction=-1.0), r"^pitting area fraction must lie in"),
    (lambda: ToothFaults.for_state("T8", spall_width_fraction=2.0), r"^spall width fraction must lie in"),
])
def test_bad_severities_raise_one_clear_parameter_error(make, match):
    with pytest.raises(ParameterError, match=match) as exc:
        make()
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("fault, match", [
    (Pitting(0.1, radius=0.6e-3), "pits of radius 0.600 mm do not fit in the 1.006 mm high pitting band of the sun"),
    (Pitting(0.5, radius=0.26e-3), "pitting area fraction 0.5 is too large for pits of radius 0.260 mm"),
    (Spalling(depth=2e-3), "spalling deeper than the sun tooth"),
    (Pitting(depth=2e-3), "pitting deeper than the sun tooth"),
])
def test_faults_that_do_not_fit_the_tooth_raise_geometry_errors(pair, fault, match):
    with pytest.raises(GeometryError, match=match):
        mesh_stiffness(pair, ToothFaults({0: (fault,)}), cycles=1)


def test_zones_lie_on_the_working_flank_around_the_pitch_point(pair):
    lo, hi, pitch = working_flank(pair, "driver")
    assert lo < pitch < hi
    z_lo, z_hi = flank_zone(pair, "driver", 0.1, None)          # small: centred on the pitch point
    assert 0.5 * (z_lo + z_hi) == pytest.approx(pitch, rel=1e-12, abs=0)
    z_lo, z_hi = flank_zone(pair, "driver", 0.4, None)          # the sun's pitch point is low: moved up
    assert z_lo == pytest.approx(lo, rel=1e-12, abs=0)
    assert z_hi - z_lo == pytest.approx(0.4 * (hi - lo), rel=1e-12, abs=0)
    rows = Pitting(0.15).flank_loss(pair, "driver").pit_rows
    area = sum(c for _, _, c, _ in rows) * math.pi * (0.15e-3) ** 2
    assert area / ((z_hi - z_lo) * pair.driver.face_width) == pytest.approx(0.15, abs=0.01)
    # the driven gear's flank: its own working range
    d_lo, d_hi, d_pitch = working_flank(pair, "driven")
    assert d_lo < d_pitch < d_hi


def test_faults_on_the_driven_gear_recur_every_z2_cycles(pair):
    h = mesh_stiffness(pair, cycles=33, points_per_cycle=36)
    res = mesh_stiffness(pair, ToothFaults({0: (Spalling(),)}, gear="driven"), cycles=33, points_per_cycle=36)
    softer = np.flatnonzero(res.stiffness_N_per_m < h.stiffness_N_per_m)
    assert softer.size > 0 and set(softer // 36) <= {0, 1}


def test_states_t7_t8_round_trip_by_name():
    from rvdiag.gears.faults import FAULT_KINDS
    from rvdiag.library import STATES as LIBRARY_STATES
    from rvdiag.library import FaultSpec, tooth_faults

    assert FAULT_KINDS["T7"] == "pitting" and FAULT_KINDS["T8"] == "spalling"
    for name, label, kind in (("pitting", "T7", Pitting), ("spalling", "T8", Spalling)):
        by_name, by_state = ToothFaults.from_name(name), ToothFaults.for_state(label)
        assert by_name == by_state and by_name.label == label and ToothFaults.from_name(label).label == label
        assert by_name.wear is None and by_name.teeth == {0: (kind(),)}
        assert LIBRARY_STATES[label].description == name
        assert tooth_faults(label) == by_state
    t7 = tooth_faults("T7", pit_area_fraction=0.2, pit_radius=0.1e-3, pit_depth=0.05e-3)
    assert t7.teeth[0] == (Pitting(0.2, 0.1e-3, 0.05e-3),)
    t8 = tooth_faults("T8", spall_width_fraction=0.3, spall_length_fraction=0.5, spall_depth=0.1e-3)
    assert t8.teeth[0] == (Spalling(0.3, 0.5, 0.1e-3),)
    with pytest.raises(ParameterError, match="pit_area_fraction = 0.5 1 is outside its valid range"):
        FaultSpec("T7", {"pit_area_fraction": 0.5})
    with pytest.raises(ParameterError, match="no severity parameter 'wear_depth'"):
        FaultSpec("T8", {"wear_depth": 1e-5})
    with pytest.raises(ParameterError, match="unknown fault 'pits'.*pitting, spalling or T1..T8"):
        ToothFaults.from_name("pits")


def test_every_library_severity_fits_the_rv20e_sun(pair):
    """A library config may draw any value in [lo, hi]: every corner, over a fine grid of pit radii, builds."""
    import itertools

    from rvdiag.gears.faults import damaged_profile
    from rvdiag.library.states import SEVERITY_PARAMETERS as S

    for r in np.linspace(S["pit_radius"].lo, S["pit_radius"].hi, 120):
        for f, d in itertools.product(*[(S[k].lo, S[k].hi) for k in ("pit_area_fraction", "pit_depth")]):
            damaged_profile(pair, "driver", (Pitting(f, r, d),))
    for w, length, d in itertools.product(*[(S[k].lo, S[k].hi) for k in
                                            ("spall_width_fraction", "spall_length_fraction", "spall_depth")]):
        damaged_profile(pair, "driver", (Spalling(w, length, d),))


def test_library_config_names_t7_t8():
    from rvdiag.library import LibraryConfig, make_plan

    data = {
        "mode": "split-by-simulation", "seed": 1, "simulator": "rvdiag.library.synthetic:simulate",
        "signal": {"fs": 1000.0, "duration_s": 0.5, "transient_s": 0.1, "segment_length": 200, "hop": 100},
        "operation": {"input_speed_rpm": 1500.0, "load_Nm": 100.0},
        "split": {"simulations_per_state": 2, "test_simulations_per_state": 1},
        "states": {"T1": {}, "T7": {"pit_area_fraction": {"min": 0.1, "max": 0.2}}, "T8": {}, "T2": {}},
    }
    cfg = LibraryConfig.from_dict(data, source="t.toml")
    assert cfg.classes == ["T1", "T2", "T7", "T8"]
    plan = make_plan(cfg)
    t7 = [u for u in plan if u.state == "T7"]
    assert all(0.1 <= u.severity["pit_area_fraction"] <= 0.2 and u.severity["pit_depth"] == 1e-4 for u in t7)
    assert [u for u in plan if u.state == "T8"][0].severity == {
        "spall_width_fraction": 0.5, "spall_length_fraction": 0.33, "spall_depth": 2e-4}


def test_cli_tvms_pitting_and_spalling(capsys):
    import json

    from conftest import run_cli

    code, out, err = run_cli(["tvms", "--fault", "spalling", "--spall-width-fraction", "0.3", "--spall-depth", "0.1",
                              "--cycles", "11", "--points", "36", "--json"], capsys)
    assert code == 0, err
    fault = json.loads(out)["fault"]
    assert fault["label"] == "T8" and fault["teeth"]["0"] == [
        {"kind": "Spalling", "width_fraction": 0.3, "length_fraction": 0.33, "depth": 1e-4, "centre_fraction": None}]
    code, _, err = run_cli(["tvms", "--fault", "T7", "--pit-area-fraction", "0.9"], capsys)
    assert code == 2 and err.strip() == "error: pitting area fraction must lie in [0, 0.785398), got 0.9"
    code, _, err = run_cli(["simulate", "--state", "T8", "--input-speed", "1000", "--pit-depth", "0.1",
                            "-o", "x.npz", "-q"], capsys)
    assert code == 2 and "--pit-depth does not apply to state T8 (spalling)" in err
