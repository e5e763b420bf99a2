"""Healthy TVMS: cross-check with ROSS, ISO 6336-1 single-pair stiffness, RV-20E magnitude."""

import dataclasses
import math
import warnings

import numpy as np
import pytest

from rvdiag.errors import ParameterError
from rvdiag.gears import GearPair, mesh_stiffness, tooth_pair_components
from rvdiag.gears.tvms import (_healthy_table, hertz_compliance, load_point,
                               pair_stiffness_at, sainsot_coefficients)
from rvdiag.params import ReducerParams


def iso6336_single_pair_stiffness(z1, z2, x1=0.0, x2=0.0, hfp_over_m=1.25, alpha_deg=20.0):
    """ISO 6336-1:2006 method B, eqs. (B.1)-(B.4) spirit: c' = C_M C_R C_B / q' in N/(mm um),
    q' = C1 + C2/z1 + C3/z2 + C4 x1 + C5 x1/z1 + C6 x2 + C7 x2/z2 + C8 x1^2 + C9 x2^2,
    C_M = 0.8 (solid gears), C_R = 1 (solid blanks),
    C_B = [1 + 0.5 (1.2 - hfP/m)] [1 - 0.02 (20 - alpha)]."""
    c = (0.04723, 0.15551, 0.25791, -0.00635, -0.11654, -0.00193, -0.24188, 0.00529, 0.00182)
    q = (c[0] + c[1] / z1 + c[2] / z2 + c[3] * x1 + c[4] * x1 / z1 + c[5] * x2 + c[6] * x2 / z2
         + c[7] * x1**2 + c[8] * x2**2)
    cb = (1 + 0.5 * (1.2 - hfp_over_m)) * (1 - 0.02 * (20 - alpha_deg))
    return 0.8 * cb / q


def single_pair_max_per_width(pair):
    """Largest single-pair stiffness along the path, per face width, in N/(mm um)."""
    s = np.linspace(0.0, pair.path_of_contact, 2001)
    k = tooth_pair_components(pair, s)["stiffness"]
    return k.max() / (pair.driver.face_width * 1e3) / 1e6


@pytest.mark.parametrize("z1, z2, x1, x2, rel", [(19, 48, 0.0, 0.0, 0.15), (25, 50, 0.0, 0.0, 0.15),
                                                 (40, 80, 0.0, 0.0, 0.15), (11, 33, 0.4, -0.4, 0.25)])
def test_single_pair_stiffness_vs_iso6336(z1, z2, x1, x2, rel):
    """ISO 6336-1 c' is an empirical fit to measured steel gears (solid blanks); it stands for the
    largest single-pair stiffness.  The potential-energy model with Sainsot's body term gives it
    within 15 % for standard pairs (19/48 is the pair of Tian 2004 and Chen & Shao 2011).  For the
    11-tooth, x = +0.4 sun the ISO fit (made on ordinary tooth numbers) gives 11.6 against our
    14.0 N/(mm um): we allow 25 % there and report it in docs/tvms.md."""
    pair = GearPair.from_dimensions(z1, z2, 3.2e-3, 0.016, x1=x1, x2=x2, youngs_modulus=2.06e11,
                                    bore_radius1=None, bore_radius2=None)
    ours = single_pair_max_per_width(pair)
    iso = iso6336_single_pair_stiffness(z1, z2, x1, x2)
    assert ours == pytest.approx(iso, rel=rel)


def test_rv20e_mean_order_of_reference():
    """Mean ~1e8 N/m scaled by face width; ISO 6336-1 single-pair stiffness c' ~ 14-16 N/(mm um)."""
    pair = GearPair.sun_planet(ReducerParams.default())
    res = mesh_stiffness(pair, cycles=11, points_per_cycle=360)
    assert 1e8 < res.mean_N_per_m < 4e8
    c_prime = single_pair_max_per_width(pair)
    assert 12.0 < c_prime < 17.0
    assert res.contact_ratio == pytest.approx(pair.contact_ratio)
    # the healthy curve repeats every mesh cycle
    k = res.stiffness_N_per_m.reshape(11, 360)
    np.testing.assert_allclose(k, np.broadcast_to(k[0], k.shape), rtol=1e-12)


def test_double_contact_is_parallel_sum():
    pair = GearPair.from_dimensions(20, 40, 2e-3, 0.02)
    ang = np.array([0.1, 0.3]) * pair.mesh_period_rad  # both in the double zone (eps = 1.64)
    kp, inc = pair_stiffness_at(pair, ang)
    assert np.all(inc.sum(axis=0) == 2)
    s1 = pair.driver.base_radius * ang
    k_a = tooth_pair_components(pair, s1)["stiffness"]
    k_b = tooth_pair_components(pair, s1 + pair.base_pitch)["stiffness"]
    np.testing.assert_allclose(kp.sum(axis=0), k_a + k_b, rtol=1e-12)


def test_hertz_term_yang_sun():
    pair = GearPair.from_dimensions(20, 40, 2e-3, 0.02, youngs_modulus=2e11, poisson_ratio=0.3)
    assert 1 / hertz_compliance(pair) == pytest.approx(math.pi * 2e11 * 0.02 / (4 * (1 - 0.09)))


def test_bending_matches_independent_quadrature():
    """The cumulative-moment bending integral equals scipy quad of Tian's integrand over the
    same tooth profile (fillet + involute)."""
    from scipy.integrate import quad

    pair = GearPair.sun_planet(ReducerParams.default())
    gear = pair.driver
    prof = gear.profile()
    rho = 0.5 * (pair.start_roll_length_driver + pair.end_roll_length_driver)
    yk, xk, a1, _ = load_point(gear, np.array([rho]))
    yk, xk, a1 = float(yk[0]), float(xk[0]), float(a1[0])
    E, L = gear.youngs_modulus, gear.face_width

    def half(y):
        return np.interp(y, prof.y, prof.x)

    def f(y):
        h = half(y)
        return (math.cos(a1) * (yk - y) - xk * math.sin(a1)) ** 2 / (E * (2 * h) ** 3 * L / 12)

    ref, _ = quad(f, prof.y[0], yk, limit=400, points=list(prof.y[::100][1:-1]))
    ours = _healthy_table(pair, "driver").compliance(gear, np.array([yk]), np.array([xk]), np.array([a1]))
    assert ours["bending"][0] == pytest.approx(ref, rel=2e-3)


def test_sainsot_coefficients_in_published_range():
    """Inside the fitted range the four coefficients lie in the ranges ROSS checks against."""
    ls, ms, ps, qs = sainsot_coefficients(0.05, 3.0)
    assert 6.82 <= ls <= 6.94 and 1.08 <= ms <= 3.29 and 2.56 <= ps <= 13.47 and 0.141 <= qs <= 0.62


def test_bad_arguments():
    pair = GearPair.from_dimensions(20, 40, 2e-3, 0.02)
    for kw in (dict(cycles=0), dict(points_per_cycle=2), dict(cycles=1.5)):
        with pytest.raises(ParameterError):
            mesh_stiffness(pair, **kw)
    with pytest.raises(ParameterError):
        mesh_stiffness(pair, fault="broken")


def test_result_api_and_plot():
    import matplotlib

    matplotlib.use("Agg")
    pair = GearPair.from_dimensions(20, 40, 2e-3, 0.02)
    res = mesh_stiffness(pair, cycles=2, points_per_cycle=50)
    assert res.angle_rad.shape == res.stiffness_N_per_m.shape == (100,)
    assert res.period_rad == pytest.approx(2 * 2 * math.pi / 20)
    np.testing.assert_allclose(res.at(res.angle_rad + res.period_rad), res.stiffness_N_per_m, rtol=1e-9)
    d = res.to_dict()
    assert set(d) >= {"angle_rad", "stiffness_N_per_m", "mean_N_per_m", "contact_ratio"}
    ax = res.plot()
    assert len(ax.lines) == 1


# ------------------------------------------------------------------ ROSS cross-check
def _ross_mesh(z1, z2, m, b, bore, E=211e9, nu=0.3, n_points=41):
    ross = pytest.importorskip("ross")
    from ross.gear_element import GearElementTVMS, Mesh

    mat = ross.Material(name="tvms_steel", rho=7810, E=E, Poisson=nu)
    g1 = GearElementTVMS(n=0, material=mat, width=b, bore_diameter=bore, module=m, n_teeth=z1,
                         pr_angle=math.radians(20))
    g2 = GearElementTVMS(n=1, material=mat, width=b, bore_diameter=bore, module=m, n_teeth=z2,
                         pr_angle=math.radians(20))
    # Mesh() itself evaluates 1000 points with scipy quad (~20 s); build it on a stub, then ask
    # for a coarse curve
    orig = Mesh.get_stiffness_for_mesh_period
    Mesh.get_stiffness_for_mesh_period = lambda self, n_mesh_period=1, n_points=1000: (
        np.zeros(1), np.zeros(1))
    try:
        mesh = Mesh(g1, g2)
    finally:
        Mesh.get_stiffness_for_mesh_period = orig
    theta, k = mesh.get_stiffness_for_mesh_period(n_points=n_points)
    return g1, mesh, np.asarray(theta), np.asarray(k, dtype=float)


@pytest.mark.parametrize("z1, z2", [(55, 75), (20, 40)])
def test_healthy_tvms_matches_ross(z1, z2):
    """ROSS 2.3.0 (GearElementTVMS/Mesh): same potential-energy terms, unshifted gears.

    Differences by design: ROSS maps the contact linearly in pressure angle and takes
    u_f = y_k - r_f in Sainsot's term (we take the load line's crossing of the centreline,
    u_f = y_k - x_k tan(a1) - r_f, as Sainsot et al. define it).  The last ROSS sample (theta =
    one full mesh period) repeats the first with the opposite contact count convention and is
    left out.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g1, mesh, theta, k_ross = _ross_mesh(z1, z2, 2e-3, 0.02, 0.035 if z1 > 40 else 0.02)
    bore = 0.035 if z1 > 40 else 0.02
    pair = GearPair.from_dimensions(z1, z2, 2e-3, 0.02, youngs_modulus=211e9, poisson_ratio=0.3,
                                    bore_radius1=bore / 2, bore_radius2=bore / 2)
    assert pair.contact_ratio == pytest.approx(mesh.contact_ratio, rel=1e-9)
    kp, _ = pair_stiffness_at(pair, theta[:-1])
    ours = kp.sum(axis=0)
    ref = k_ross[:-1]
    assert ours.mean() == pytest.approx(ref.mean(), rel=0.05)
    # measured: pointwise within 4.9 % (55/75) and 3.5 % (20/40); README and docs/tvms.md state 5 %
    np.testing.assert_allclose(ours, ref, rtol=0.05)

    # the beam terms (bending, shear, axial) agree to 0.1 % at identical contact points
    gear = pair.driver
    rho = np.linspace(pair.start_roll_length_driver, pair.end_roll_length_driver, 5)
    yk, xk, a1, _ = load_point(gear, rho)
    ours_beam = _healthy_table(pair, "driver").compliance(gear, yk, xk, a1)
    for i, alpha in enumerate(np.arctan(rho / gear.base_radius)):
        tau = g1._to_tau(alpha)
        assert ours_beam["bending"][i] == pytest.approx(g1._inv_kb(tau), rel=1e-3)
        assert ours_beam["shear"][i] == pytest.approx(g1._inv_ks(tau), rel=1e-3)
        assert ours_beam["axial"][i] == pytest.approx(g1._inv_ka(tau), rel=2e-3)


def test_golden_rv20e():
    """Regression against tests/golden/tvms_rv20e.json (written by this model on 2026-11-23)."""
    import json
    from pathlib import Path

    from rvdiag.gears import ToothFaults, Wear

    gold = json.loads((Path(__file__).parent / "golden" / "tvms_rv20e.json").read_text())
    pair = GearPair.sun_planet(ReducerParams.default())
    h = mesh_stiffness(pair, cycles=1, points_per_cycle=36)
    # crack_tooth=1: the T6 layout the golden file was written with (the default moved to tooth 5 later)
    t6 = ToothFaults.for_state("T6", crack_tooth=1)
    f = mesh_stiffness(pair, t6, cycles=11, points_per_cycle=12)
    # the wear profile of 2026-11-23 (fixed load shares): Wear.run_in_deflection = 0
    fixed = mesh_stiffness(pair, dataclasses.replace(t6, wear=Wear(t6.wear.depth, 0.0)), cycles=11,
                           points_per_cycle=12)
    np.testing.assert_allclose(h.stiffness_N_per_m, gold["healthy_1x36"], rtol=1e-7)
    np.testing.assert_allclose(fixed.stiffness_N_per_m, gold["T6_11x12"], rtol=1e-7, atol=1e-3)
    np.testing.assert_allclose(f.stiffness_N_per_m, gold["T6_11x12_run_in"], rtol=1e-7, atol=1e-3)
    assert np.abs(f.stiffness_N_per_m - fixed.stiffness_N_per_m).max() > 1e3  # the two wear profiles differ
    assert pair.contact_ratio == pytest.approx(gold["contact_ratio"], rel=1e-12)


def test_demo_tvms_writes_figure_and_summary(tmp_path):
    import importlib.util
    import json
    from pathlib import Path

    path = Path(__file__).parents[1] / "examples" / "demo_tvms.py"
    spec = importlib.util.spec_from_file_location("demo_tvms_under_test", path)
    demo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(demo)
    summary = demo.run(tmp_path)
    assert (tmp_path / "tvms.png").read_bytes()[:4] == b"\x89PNG"
    assert json.loads((tmp_path / "tvms_summary.json").read_text()) == summary
    states = summary["states"]
    assert list(states) == ["T1", "T2", "T3", "T4", "T5", "T6", "T7", "T8"]
    assert states["T2"]["min_N_per_m"] == 0.0 and states["T1"]["min_N_per_m"] > 0
    assert states["T6"]["mean_N_per_m"] < states["T5"]["mean_N_per_m"] < states["T1"]["mean_N_per_m"]
    assert states["T2"]["mean_N_per_m"] < states["T8"]["mean_N_per_m"] < states["T7"]["mean_N_per_m"] \
        < states["T1"]["mean_N_per_m"]
    assert states["T3"]["max_profile_error_m"] > 0 and states["T1"]["max_profile_error_m"] == 0
