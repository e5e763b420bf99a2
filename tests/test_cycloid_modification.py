"""The cycloid discs' equidistant and offset profile modifications (docs/model.md section 3).

Checked here: the clearance formula against the disc profile generated numerically (the envelope of the pins at
the modified radii, with no formula for the clearance); the closing rotation; the kernels' clearance row against
the NumPy formula at every pin; Q = -grad V of the independent NumPy potential with the modification on; how many
pins carry the load (5-8 per disc instead of the unmodified half); both load senses; bad parameters as one-line
errors; and that the modification changes what the model returns.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from rvdiag.dynamics import kernels as kn
from rvdiag.dynamics import model as mdl
from rvdiag.dynamics import prepare, simulate
from rvdiag.dynamics.linear import static_equilibrium
from rvdiag.errors import ConfigError, ParameterError
from rvdiag.gears.cycloid import closing_offset, modification_clearance
from rvdiag.params import ReducerParams

from conftest import assert_forces_are_minus_gradient

P0 = ReducerParams.default()
S2 = P0.stage2
ZP, ZC, RP, E = S2.pins, S2.cycloid_lobes, S2.pin_circle_radius, S2.eccentricity
K1 = E * ZP / RP
UNMODIFIED = P0.replace(stage2={"equidistant_modification": 0.0, "offset_modification": 0.0})


@pytest.fixture(autouse=True, scope="module")
def _kernels_loaded_callees_first():
    """The tests below call kernels directly; load them the way a simulation does first (callees first,
    :func:`rvdiag.dynamics.model.load_kernels`), so that the simulations of later test files in the same process
    keep their bits (the golden-file tests)."""
    mdl.load_kernels(prepare(P0, output_speed_deg_s=45.0))


def _pin_centre_locus(pin_circle_radius: float, points: int = 400_000) -> np.ndarray:
    """The path of a pin's centre relative to the disc (disc frame), over Zc turns of the eccentric: the disc
    rolls inside the pin ring, turning by -b / Zc when the eccentric turns by b."""
    b = np.linspace(0.0, 2.0 * math.pi * ZC, points, endpoint=False)
    px, py = pin_circle_radius - E * np.cos(b), -E * np.sin(b)
    c, s = np.cos(b / ZC), np.sin(b / ZC)
    return np.stack([c * px - s * py, s * px + c * py], axis=1)


def _signed_distance(points: np.ndarray, curve: np.ndarray) -> np.ndarray:
    """Distance from each point to the closed polyline ``curve``, positive outside it (farther from the disc
    centre)."""
    _, nearest = cKDTree(curve).query(points)
    out = np.empty(len(points))
    for n, (p, j) in enumerate(zip(points, nearest)):
        best = (np.inf, p)
        for a, b in ((curve[j - 1], curve[j]), (curve[j], curve[(j + 1) % len(curve)])):
            t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
            q = a + t * (b - a)
            best = min(best, (float(np.linalg.norm(p - q)), q), key=lambda x: x[0])
        out[n] = best[0] if np.linalg.norm(p) > np.linalg.norm(best[1]) else -best[0]
    return out


def _pins_in_disc_frame(eccentric_angles) -> tuple[np.ndarray, np.ndarray]:
    """Every pin's centre in the disc frame and its phase eta (angle from the eccentricity) at a few eccentric
    angles of the nominal mesh."""
    pts, etas = [], []
    gam = 2.0 * math.pi * np.arange(ZP) / ZP
    for b in eccentric_angles:
        px, py = RP * np.cos(gam) - E * math.cos(b), RP * np.sin(gam) - E * math.sin(b)
        c, s = math.cos(b / ZC), math.sin(b / ZC)
        pts.append(np.stack([c * px - s * py, s * px + c * py], axis=1))
        etas.append(gam - b)
    return np.concatenate(pts), np.concatenate(etas)


@pytest.mark.parametrize("equidistant, offset", [(4e-6, -3e-6), (10e-6, -8e-6), (10e-6, 0.0), (0.0, -10e-6),
                                                 (-5e-6, -10e-6)])
def test_clearance_is_the_gap_to_the_generated_profile(equidistant, offset):
    """The modified disc's flank is the pin-centre path at pin circle r_p + Delta r_p offset inwards by the pin radius
    plus Delta r_rp; the gap between it and a pin of the nominal geometry, measured on that generated profile,
    equals modification_clearance (no closing rotation) to 2 % of the modification (first order in it)."""
    pins, eta = _pins_in_disc_frame((0.0, 0.05, 0.11))
    nominal = _signed_distance(pins, _pin_centre_locus(RP))
    assert np.max(np.abs(nominal)) < 1e-9  # the unmodified profile touches every pin (the check can see a gap)
    gap = _signed_distance(pins, _pin_centre_locus(RP + offset)) + equidistant
    formula = modification_clearance(np.cos(eta), np.sin(eta), K1, equidistant, offset, 0.0)
    scale = max(abs(equidistant), abs(offset))
    np.testing.assert_allclose(formula, gap, rtol=0, atol=0.02 * scale)
    assert np.ptp(formula) > 0.3 * scale or offset == 0.0  # the offset term varies with the phase


def test_closing_rotation_touches_the_tightest_loaded_pin():
    """For the usual positive equidistant and negative offset pair the closing rotation is Delta r_rp - Delta r_p
    sqrt(1 - K1^2) at unit arm, the pin at cos eta = K1 just touching; the loaded half keeps a non-negative clearance
    and the pin of the largest arm on the other half stands off by twice the closing (the disc's rotation from flank
    to flank); the sense flips it."""
    drrp, drp = S2.equidistant_modification, S2.offset_modification
    assert (drrp, drp) == (4e-6, -3e-6)  # the defaults
    c = closing_offset(K1, drrp, drp, 1)
    assert c == pytest.approx(drrp - drp * math.sqrt(1.0 - K1 * K1), rel=1e-9)
    assert closing_offset(K1, drrp, drp, -1) == pytest.approx(-c, rel=1e-12)
    eta = np.linspace(0.0, 2.0 * math.pi, 3601)
    gap = modification_clearance(np.cos(eta), np.sin(eta), K1, drrp, drp, c)
    loaded = np.sin(eta) > 0
    assert gap[loaded].min() == pytest.approx(0.0, abs=1e-12) and gap.min() > -1e-12
    assert math.cos(eta[loaded][np.argmin(gap[loaded])]) == pytest.approx(K1, abs=2e-3)
    assert gap.max() == pytest.approx(2.0 * c, rel=1e-4)
    # lost motion: the disc turns c / (e Zc) to close one flank, 0.50 arcmin (1.0 for both, the catalogue's limit)
    assert 2 * math.degrees(c / (E * ZC)) * 60 == pytest.approx(1.0, abs=0.02)
    assert closing_offset(K1, 0.0, 0.0) == 0.0


def test_bad_modifications_are_one_line_errors():
    with pytest.raises(ConfigError, match="radial clearance and must be >= 0"):
        P0.replace(stage2={"equidistant_modification": 1e-6, "offset_modification": 3e-6})
    with pytest.raises(ConfigError, match="equidistant_modification must be at most"):
        P0.replace(stage2={"equidistant_modification": 1e-3})
    with pytest.raises(ParameterError, match="sense"):
        closing_offset(K1, 1e-6, 0.0, 0)


def test_kernel_clearance_row_equals_the_formula():
    """geo[g, 3, k] of the compiled pin geometry is modification_clearance at each pin's phase eta_k = 2 pi k / Zp
    - B_j (B_j the disc's eccentric angle in the fixed frame), with the closing packed for the load's sense."""
    m = prepare(P0, output_speed_deg_s=45.0, load_Nm=100.0)
    assert m.P[kn.I_PINMOD] == 1.0 and m.P[kn.I_CLOSE] == pytest.approx(-closing_offset(K1, 4e-6, -3e-6, 1))
    geo, rot, _ = mdl.work_arrays(m)
    for t in (0.0, 0.0123, 0.31):
        kn.pin_geometry(t, m.P, m.cosk, m.sink, geo, rot)
        for j in range(1 if m.P[kn.I_GSHARED] else m.n_discs):
            eta = 2.0 * math.pi * np.arange(ZP) / ZP - math.atan2(rot[j, 3], rot[j, 2])
            want = modification_clearance(np.cos(eta), np.sin(eta), K1, 4e-6, -3e-6, m.P[kn.I_CLOSE])
            np.testing.assert_allclose(geo[j, 3], want, rtol=0, atol=1e-15)
    geo0, rot0, _ = mdl.work_arrays(prepare(UNMODIFIED, output_speed_deg_s=45.0, load_Nm=100.0))
    kn.pin_geometry(0.0123, prepare(UNMODIFIED, output_speed_deg_s=45.0, load_Nm=100.0).P, m.cosk, m.sink, geo0, rot0)
    assert not geo0[:, 3].any()


@pytest.mark.parametrize("load", [100.0, -100.0])
def test_forces_are_minus_gradient_of_the_potential_with_the_modification(load):
    """M a(v = 0) of the compiled kernels equals -dV/dq of the NumPy potential (linear.potential_energy writes the
    clearance from the pins' positions with numpy trigonometry) with a modification 5x the default, for both load
    senses, and the modification changes the forces (so the comparison can fail)."""
    rng = np.random.default_rng(5)
    st = mdl.ModelSettings(damping=False)
    big = P0.replace(stage2={"equidistant_modification": 20e-6, "offset_modification": -15e-6})
    m = prepare(big, output_speed_deg_s=45.0, load_Nm=load, settings=st)
    assert_forces_are_minus_gradient(m, prepare(UNMODIFIED, output_speed_deg_s=45.0, load_Nm=load, settings=st), 0.21,
                                     rng)


def _pins_in_contact(p: ReducerParams, load: float, t: float = 0.004) -> int:
    m = prepare(p, output_speed_deg_s=45.0, load_Nm=load)
    q = static_equilibrium(m, t)
    geo, rot, _ = mdl.work_arrays(m)
    kn.pin_geometry(t, m.P, m.cosk, m.sink, geo, rot)
    n = m.n_dof
    lay = mdl.dof_layout(m.n_planets, m.n_discs)
    iD0, iR = lay["disc0"], lay["pin_wheel"]
    y = np.concatenate([q, np.zeros(n)])
    ux, uy, th, *_ = kn._disc_frame(0, y, n, rot, iD0, q[iR], q[iR + 1], q[iR + 2], 0.0, 0.0, 0.0, ZP / ZC)
    d = ux * geo[0, 0] + uy * geo[0, 1] + th * geo[0, 2] - geo[0, 3]
    return int(np.sum(d > 0))


def test_a_modified_disc_carries_the_load_on_a_few_pins():
    """Unmodified, half the pins (17-19 of 40) carry the load; with the default modification 5-8, more as the load
    grows (a modified disc meshes with a part of the loaded half only), for either sense of the load."""
    assert 16 <= _pins_in_contact(UNMODIFIED, 167.0) <= 20
    counts = [_pins_in_contact(P0, f * 167.0) for f in (0.4, 1.0, 1.5)]
    assert 4 <= counts[0] <= counts[1] <= counts[2] <= 9 and counts[2] > counts[0]
    assert abs(_pins_in_contact(P0, -167.0) - counts[1]) <= 1


def test_the_modification_changes_the_vibration():
    """The pins' load hand-over becomes an excitation of the second stage: the healthy vibration at 60 deg/s and
    40 % load grows (2.6 against 1.2 m/s^2 over 1 s; docs/model.md section 9) and it records the modification."""
    kw = dict(output_speed_deg_s=60.0, load_Nm=0.4 * 167.0, duration_s=0.2)
    mod = simulate(P0, **kw).signal[0]
    bare = simulate(UNMODIFIED, **kw).signal[0]
    assert np.std(mod) > 1.4 * np.std(bare)
