"""The speed and load profile of the simulator (rvdiag.dynamics.profile; docs/model.md section 2)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import welch

from rvdiag.dynamics import LoadProfile, ModelSettings, SimulationResult, SpeedProfile, simulate
from rvdiag.errors import ParameterError
from rvdiag.params import ReducerParams


def test_trapezoid_closed_form():
    p = SpeedProfile.trapezoid(45.0, 90.0, move_s=2.0, start_s=0.5)
    t = np.array([0.0, 0.75, 1.25, 1.5, 2.25, 2.75, 3.0])
    th, w, a = p.state(t, 0.0)
    assert np.degrees(w) == pytest.approx([0, 22.5, 45, 45, 22.5, 0, 0])
    assert np.degrees(a) == pytest.approx([0, 90, 0, 0, -90, 0, 0])
    # the angle is the integral of the speed: 45 deg/s x (2 s - 0.5 s) in all
    assert np.degrees(th[-1]) == pytest.approx(45.0 * 1.5)
    assert th[0] == 0.0


def test_trapezoid_that_cannot_reach_its_speed_is_refused():
    with pytest.raises(ParameterError, match="needs 1 s"):
        SpeedProfile.trapezoid(45.0, 90.0, move_s=0.5)
    with pytest.raises(ParameterError, match="longer than its move"):
        simulate(profile=SpeedProfile.trapezoid(45.0, 90.0), duration_s=0.05)


def test_segments_refuse_a_profile():
    with pytest.raises(ParameterError, match="segment"):
        simulate(profile=SpeedProfile.trapezoid(45.0, 1e4), load_Nm=50.0, duration_s=0.02,
                 settings=ModelSettings(segment_s=0.01, transient_s=0.01))


def test_a_trapezoid_in_cruise_reproduces_the_constant_speed_run():
    """The profile path (exact frame angles at every stage, Newton-located table events) at zero acceleration
    over the whole run: the constant-speed run to rounding."""
    c = simulate(output_speed_deg_s=45.0, load_Nm=100.0, duration_s=0.02)
    z = simulate(profile=SpeedProfile.trapezoid(45.0, 1e5, move_s=10.0, start_s=-1.0), load_Nm=100.0,
                 duration_s=0.02)
    assert np.max(np.abs(z.theta_out - c.theta_out)) < 1e-15
    assert np.linalg.norm(z.signal - c.signal) / np.linalg.norm(c.signal) < 1e-11


def _third_octaves_db(x: np.ndarray) -> np.ndarray:
    f, p = welch(x, fs=48000.0, nperseg=1024)
    edges = 50.0 * 2.0 ** (np.arange(0.0, 7.7, 1.0 / 3.0))  # 50 Hz - 10 kHz
    return np.array([10 * np.log10(p[(f >= a) & (f < b)].mean()) for a, b in zip(edges[:-1], edges[1:])
                     if np.any((f >= a) & (f < b))])


def test_quasi_static_trapezoid_gives_the_cruise_spectrum():
    """Accelerate at 300 deg/s^2 from rest to 45 deg/s (0.15 s), cruise: the last 0.1 s has the spectrum of the
    constant-speed run over the same carrier angles within 0.5 dB in every third-octave band from 50 Hz to
    10 kHz (at 45 deg/s the pin geometry changes slowly, so windows at other angles differ by several dB).  In
    cruise theta_H = Omega (t - t_a / 2): the constant run's window ends 0.075 s earlier."""
    q = simulate(profile=SpeedProfile.trapezoid(45.0, 300.0, move_s=10.0), load_Nm=100.0, duration_s=0.3)
    c = simulate(output_speed_deg_s=45.0, load_Nm=100.0, duration_s=0.225)
    assert np.degrees(q.theta_out[1]) * 48000.0 < 0.1  # starts from rest
    assert np.max(np.abs(q.theta_out[-4800:] - c.theta_out[-4800:])) < 1e-12
    for ch in range(2):
        d = _third_octaves_db(q.signal[ch, -4800:]) - _third_octaves_db(c.signal[ch, -4800:])
        assert np.max(np.abs(d)) < 0.5


def test_gravity_arm_and_angles_are_recorded(tmp_path):
    r = simulate(profile=SpeedProfile.trapezoid(45.0, 900.0), load_profile=LoadProfile(15.0, 0.5, 0.0),
                 load_Nm=0.0, duration_s=0.12)
    assert r.settings["speed_profile"]["kind"] == "trapezoid"
    assert r.settings["load_profile"]["arm_mass_kg"] == 15.0
    assert np.array_equal(r.theta_in, ReducerParams.default().ratio * r.theta_out)
    # 0.12 s: accelerate 0.05 s, cruise 0.02 s, decelerate 0.05 s: 45 x 0.07 deg in all
    assert np.degrees(r.theta_out[-1]) == pytest.approx(45.0 * 0.07, rel=2e-3)
    assert np.all(np.isfinite(r.signal))
    r.to_npz(tmp_path / "a.npz")
    back = SimulationResult.from_npz(tmp_path / "a.npz")
    assert np.array_equal(back.theta_out, r.theta_out) and np.array_equal(back.theta_in, r.theta_in)


# --------------------------------------------------------------------------- the jerk-limited S-curve
@pytest.mark.parametrize("v, a, j, reached", [(45.0, 90.0, 900.0, True),     # V J >= A^2: A reached, held
                                               (45.0, 300.0, 900.0, False)])  # V J < A^2: A not reached
def test_scurve_is_continuous_and_covers_its_distance(v, a, j, reached):
    """Against an independent integration (scipy's cumulative trapezoid of the acceleration, then of the speed):
    the speed and the acceleration are continuous, the jerk stays within J, the peak speed is V, the peak
    acceleration A (or sqrt(V J) when A is not reached), the move covers V (T_a + T_c)."""
    from scipy.integrate import cumulative_trapezoid

    move = 2.0
    p = SpeedProfile.scurve(v, a, j, move_s=move, start_s=0.1)
    dt = 1e-5
    t = np.arange(-0.05, 2.3, dt)
    th, w, acc = (np.degrees(x) for x in p.state(t, 0.0))
    tj, ta, alim = p.ramp_times()
    assert alim == pytest.approx(a if reached else np.sqrt(v * j), rel=1e-12)
    assert ta == pytest.approx(tj + v / alim, rel=1e-12) and (tj == pytest.approx(a / j)) == reached
    # continuity: no step larger than the largest rate allows over one dt
    assert np.max(np.abs(np.diff(w))) <= alim * dt * (1 + 1e-9)
    assert np.max(np.abs(np.diff(acc))) <= j * dt * (1 + 1e-6)
    # (the grid may miss the instant of a peak acceleration by dt / 2)
    assert w.max() == pytest.approx(v, rel=1e-12) and acc.max() == pytest.approx(alim, abs=j * dt)
    assert acc.min() == pytest.approx(-alim, abs=j * dt) and w.min() == 0.0
    # the closed form against scipy's integration of its own acceleration
    w_int = cumulative_trapezoid(acc, t, initial=0.0)
    th_int = cumulative_trapezoid(w_int, t, initial=0.0)
    assert np.max(np.abs(w_int - w)) < 1e-6 * v
    assert np.max(np.abs((th_int - th_int[t.searchsorted(0.0)]) - th)) < 1e-6 * v
    tc = move - 2 * ta
    assert th[-1] - th[t.searchsorted(0.1)] == pytest.approx(v * (ta + tc), rel=1e-12)
    assert th[t.searchsorted(0.0)] == 0.0 < th[-1]  # theta_H(0) = 0 at the first recorded sample


def test_scurve_compiled_profile_state_equals_the_closed_form():
    from rvdiag.dynamics import kernels as kn
    from rvdiag.dynamics import prepare

    p = SpeedProfile.scurve(45.0, 300.0, 3000.0, move_s=0.5, start_s=0.02)
    m = prepare(ReducerParams.default(), output_speed_deg_s=45.0, load_Nm=50.0, profile=p)
    t = np.linspace(-0.01, 0.6, 6101)
    want = p.state(t, 0.0)
    got = np.array([kn.profile_state(x, m.P) for x in t]).T
    for g, w_ in zip(got, want):
        np.testing.assert_allclose(g, w_, rtol=1e-12, atol=1e-12)
    assert m.P[kn.I_PROFILE] == 3.0


@pytest.mark.parametrize("kw, match", [
    (dict(jerk_deg_s3=0.0), "jerk .* must be a finite number > 0"),
    (dict(jerk_deg_s3=None), r"jerk \(deg/s\^3\) must be a number, got None"),
    (dict(jerk_deg_s3=100.0, move_s=1.0), r"an S-curve at 90 deg/s\^2 and 100 deg/s\^3 needs 2\.683 s"),
])
def test_scurve_bad_values_are_one_line_errors(kw, match):
    args = dict(kind="scurve", output_speed_deg_s=45.0, accel_deg_s2=90.0, move_s=2.0)
    args.update(kw)
    with pytest.raises(ParameterError, match=match) as exc:
        SpeedProfile(**args).validate()
    assert "\n" not in str(exc.value)
    with pytest.raises(ParameterError, match="jerk limit applies to the S-curve"):
        SpeedProfile("trapezoid", 45.0, 90.0, 2.0, 0.0, 100.0).validate()


def test_scurve_simulation_records_its_true_angles():
    """The dynamic model on an S-curve from rest: the recorded output angle is the profile's closed form, the
    input turns i times as far, the signal is finite; the settings name the profile and its jerk."""
    p = SpeedProfile.scurve(45.0, 600.0, 12000.0)
    r = simulate(profile=p, load_Nm=50.0, duration_s=0.3, fs=24000.0)
    t = np.arange(r.theta_out.size) / 24000.0
    np.testing.assert_array_equal(r.theta_out, p.state(t, 0.0, 0.3)[0])
    np.testing.assert_array_equal(r.theta_in, ReducerParams.default().ratio * r.theta_out)
    tj, ta, _ = p.ramp_times()  # T_j 0.05 s, T_a 0.125 s: up 0.125 s, cruise 0.05 s, down 0.125 s
    assert (tj, ta) == pytest.approx((0.05, 0.125))
    assert np.degrees(p.state(np.array([0.3]), 0.0, 0.3)[0][0]) == pytest.approx(45.0 * (0.3 - ta))
    assert np.degrees(r.theta_out[-1]) == pytest.approx(45.0 * (0.3 - ta), rel=1e-6)
    assert r.settings["speed_profile"]["kind"] == "scurve" and r.settings["speed_profile"]["jerk_deg_s3"] == 12000.0
    assert np.all(np.isfinite(r.signal)) and np.std(r.signal[0]) > 0
