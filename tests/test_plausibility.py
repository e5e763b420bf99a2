"""Plausibility of the simulated housing vibration against measured machines (docs/model.md section 9).

Bounds from measured data: real healthy RV reducers on an industrial robot show window kurtosis 8-21 (range
3.5-50) and crest factor 5.7-9.1; wear of 20 um and a 2 mm root crack change a real gearbox's RMS little.  The
checks that the model does not yet meet (a broken tooth within 2x of healthy, a healthy dynamic mesh-force factor
<= 1.15) are in the docs table with their figures, not here; the wear bound, met before the extended tooth contact
and not since, and the healthy crest factor at 30 deg/s rated, met before the discs' profile modification and not
since, are strict expected failures below.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import kurtosis

from rvdiag.dynamics import ModelSettings, simulate
from rvdiag.dynamics import model as mdl
from rvdiag.dynamics import prepare
from rvdiag.dynamics.linear import static_equilibrium
from rvdiag.gears import ToothFaults
from rvdiag.params import ReducerParams

P0 = ReducerParams.default()
RATED = P0.operation.rated_torque


def _x(state, speed, load, **sev):
    fault = None if state == "T1" else ToothFaults.for_state(state, **sev)
    x = simulate(P0, fault, output_speed_deg_s=speed, load_Nm=load, duration_s=0.5).signal[0]
    return x - x.mean()


def _rms(x):
    return float(np.sqrt(np.mean(x * x)))


@pytest.fixture(scope="module", params=[(30.0, RATED), (60.0, RATED), (45.0, 0.4 * RATED)],
                ids=["30dps-rated", "60dps-rated", "45dps-40pct"])
def point(request):
    speed, load = request.param
    return speed, load, _x("T1", speed, load)


def test_healthy_is_impulsive_like_a_real_rv_reducer(point, request):
    """Kurtosis 3-25 and crest factor <= 10 (measured over 1 s at 30-60 deg/s, 40-150 %: kurtosis 6.2-24.1, crest
    5.6-12.4).  Not met at 30 deg/s rated since the discs' profile modification (crest 11.2 over these 0.5 s, 12.4
    over 1 s; 8.8 / 11.0 with conjugate discs): a strict expected failure there, so that meeting it shows."""
    if point[:2] == (30.0, RATED):
        request.applymarker(pytest.mark.xfail(strict=True, reason="healthy crest factor 11.2 > 10 at 30 deg/s rated "
                                              "(docs/model.md section 9)"))
    _, _, x = point
    k = float(kurtosis(x, fisher=False))
    crest = float(np.abs(x).max() / _rms(x))
    assert 3.0 <= k <= 25.0 and crest <= 10.0, (k, crest)


def test_little_energy_above_the_sensor_band(point):
    """Less than 10 % of the healthy acceleration energy above 10 kHz (measured 4-8 %)."""
    _, _, x = point
    p = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(x.size, 1 / 48000.0)
    assert p[f > 10e3].sum() / p.sum() < 0.10


def test_a_root_crack_changes_the_rms_like_a_real_gearbox(point):
    """A 2 mm root crack: RMS <= 1.2x healthy (measured 0.98-1.05x over 30-60 deg/s, 40-150 %)."""
    speed, load, x = point
    crack = _rms(_x("T4", speed, load, crack_depth=2e-3)) / _rms(x)
    assert 0.95 < crack <= 1.2, crack


@pytest.mark.xfail(strict=True, reason="20 um of run-in Archard wear gives 4.9-6.9x the healthy RMS: on this 1.4 N m "
                   "stage 20 um is ~30x the 0.6-1.1 um elastic deflection, and Archard's single-contact wear (no load "
                   "sharing there) leaves a 15-19 um transmission-error swing per mesh cycle. 20 um is a late-life depth "
                   "(20,000 h at k = 1e-17 m^2/N: 29 um); no measured RMS bound exists for wear that deep against "
                   "the deflection (research/README.md, 'Archard wear over a robot's life'), so the bound, not the "
                   "model, is in doubt; life-consistent depths are tested below")
def test_wear_changes_the_rms_like_a_real_gearbox(point):
    """20 um of wear: RMS <= 2x healthy (measured 3.16-6.93x over 30-60 deg/s, 40-150 % with the run-in wear
    profile, 2.46-6.28x with fixed load shares; 1.63-1.93x before the extended tooth contact).  Strict: once met,
    this test must lose its xfail mark."""
    speed, load, x = point
    wear = _rms(_x("T3", speed, load, wear_depth=20e-6)) / _rms(x)
    assert 1.0 < wear <= 2.0, wear


@pytest.fixture(scope="module")
def life_wear():
    """The sun's Archard wear after 20,000 h moving half the time at 30 deg/s and half the rated torque, with the
    well-lubricated wear coefficient 1e-18 m^2/N (rvdiag.gears.wear; 3.1 um deep, run in, zero at the pitch point)."""
    from rvdiag.gears.wear import DutyCycle, wear_depth_profile

    return wear_depth_profile(P0, 20000.0, DutyCycle(30.0, 0.5 * RATED, 0.5), 1e-18).to_wear()


def test_life_consistent_wear_changes_the_rms_little(point, life_wear):
    """Wear of a life-consistent depth and shape (fixture ``life_wear``): RMS within 0.8-2x healthy (measured
    0.99 / 1.11 / 1.36x at 30 deg/s rated, 60 deg/s rated, 45 deg/s 40 %, over these 0.5 s).  At k = 1e-17 (above what a measured RV lost-motion
    growth allows) the same life wears 29 um and gives 5-6x (research/README.md), so this test can fail."""
    speed, load, x = point
    fault = ToothFaults({}, wear=life_wear)
    y = simulate(P0, fault, output_speed_deg_s=speed, load_Nm=load, duration_s=0.5).signal[0]
    ratio = _rms(y - y.mean()) / _rms(x)
    assert 0.8 <= ratio <= 2.0, ratio


def _library_wear_draws() -> tuple[float, float]:
    """The wear depths (m) the monitoring libraries draw: configs/monitoring.toml's T3 range (demo-monitoring.toml
    draws the same; docs/library.md says which shipped configs keep other draws, and why)."""
    from rvdiag.library import LibraryConfig

    return LibraryConfig.load("monitoring").states["T3"]["wear_depth"].values


def test_the_libraries_draw_wear_of_a_robots_life(life_wear):
    """The monitoring libraries' wear draws span the sun's Archard depth over a robot's life (docs/model.md: 3.1 um after
    20,000 h at 30 deg/s, 8.9 um after 30,000 h at 60 deg/s, k = 1e-18 m^2/N), not the 10-80 um of before."""
    from rvdiag.gears.wear import DutyCycle, wear_depth_profile

    lo, hi = _library_wear_draws()
    heavy = wear_depth_profile(P0, 30000.0, DutyCycle(60.0, 0.5 * RATED, 0.5), 1e-18).max_depth
    assert lo <= life_wear.depth < heavy <= hi
    assert hi <= 1.1 * heavy and lo >= 0.9 * life_wear.depth


@pytest.mark.parametrize("end", ["shallowest", "deepest"])
def test_the_libraries_wear_draws_change_the_rms(point, end, request):
    """The libraries' wear (the run-in shape, ``Wear(depth)``) at the ends of their draws: RMS within 0.8-2x
    healthy.  Met at the shallowest draw (3 um: measured 1.10 / 1.04 / 1.17x at 30 deg/s rated, 60 deg/s rated,
    45 deg/s 40 %, over these 0.5 s).  Not met at the deepest (9 um: 3.00 / 2.35 / 2.20x): a strict expected
    failure, for the reason of ``test_wear_changes_the_rms_like_a_real_gearbox`` (the bound comes from gears whose
    deflection is 10-20 um; here 9 um is about 10 deflections)."""
    if end == "deepest":
        request.applymarker(pytest.mark.xfail(strict=True, reason="9 um of run-in wear gives 2.2-3.0x the healthy "
                                              "RMS (docs/model.md section 9)"))
    speed, load, x = point
    depth = _library_wear_draws()[0 if end == "shallowest" else 1]
    ratio = _rms(_x("T3", speed, load, wear_depth=depth)) / _rms(x)
    assert 0.8 <= ratio <= 2.0, ratio


def test_no_contact_ever_pulls():
    """A tooth pair or a pin whose flanks separate fast pushes nothing and pulls nothing (Modelica ElastoBacklash:
    the contact force is zero when spring + damper <= 0).  At the static solution, with the sun turning back at
    100 rad/s (every sun-planet pair separating at 0.65 m/s: a viscous damper alone would pull with ~5 kN), the
    sun's torque is the input coupling's alone; with the discs rocking back, the pin wheel's torque is its
    support's alone."""
    m = prepare(P0, output_speed_deg_s=45.0, load_Nm=100.0)
    q = static_equilibrium(m, 0.0)
    lay = mdl.dof_layout(2, 2)
    v = np.zeros_like(q)
    v[2] = -100.0
    Q = mdl.forces(m, 0.0, q, v)
    qm = q[-1] if m.has_motor else 0.0
    assert Q[2] == pytest.approx(-m.P[mdl.I_KIN] * (q[2] - qm) - m.P[mdl.I_CIN] * v[2], rel=1e-12, abs=1e-12)
    iR = lay["pin_wheel"] + 2
    support_only = -m.P[mdl.I_KRT] * q[iR]
    rocked = []
    for sense in (-100.0, 100.0):  # one sense separates the loaded pins, the other presses them
        v = np.zeros_like(q)
        for j in range(2):
            v[lay[f"disc{j}"] + 2] = sense
        rocked.append(mdl.forces(m, 0.0, q, v)[iR])
    assert min(abs(r - support_only) for r in rocked) <= 1e-9 * abs(support_only)
    assert max(abs(r - support_only) for r in rocked) > 1.0
    # and at rest the same contacts do carry load (the test can fail)
    Q0 = mdl.forces(m, 0.0, q, np.zeros_like(q))
    assert abs(Q0[iR] + m.P[mdl.I_KRT] * q[iR]) > 1.0
