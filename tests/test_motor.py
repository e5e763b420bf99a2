"""The servo motor (PMSM under i_d = 0 vector control) coupled to the reducer: its design side, its compiled rates
against an independent NumPy statement, the coupled run's steady state, the current spectrum and the errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from oracles.reference_pmsm import reference_motor_rates, reference_torque
from rvdiag.dynamics import ModelSettings, SimulationResult, prepare, simulate
from rvdiag.dynamics import kernels as kn
from rvdiag.dynamics.motor_kernel import MOTOR_P_FIELDS, air_gap_torque, motor_rates
from rvdiag.errors import ConfigError, ParameterError
from rvdiag.motor import check_operating_point, controller_gains, phase_currents, sample_current
from rvdiag.motor.lines import amplitude_spectrum, line_height
from rvdiag.params import ReducerParams

FAST = ModelSettings(transient_s=0.05)


def _line_db(x, fs, f0):
    """Amplitude of the line nearest ``f0`` (A) and its height over the median of the bins 6-40 away (dB):
    :func:`rvdiag.motor.lines.line_height`, the table ``rvdiag diagnose`` prints for a current."""
    f, amp = amplitude_spectrum(x, fs)
    return line_height(amp, f[1], f0)


# ------------------------------------------------------------------------------ design side
def test_gains_follow_pole_zero_cancellation_and_the_torque_constant():
    m = ReducerParams.default().motor
    pp = ReducerParams.default().operation.motor_pole_pairs
    g = controller_gains(m, pp)
    w_cc = 2 * math.pi * m.current_loop_bandwidth_hz
    assert g.torque_constant == pytest.approx(1.5 * pp * m.flux_linkage)
    assert g.kp_current == pytest.approx(m.inductance_q * w_cc)
    assert g.ki_current == pytest.approx(m.resistance * w_cc)
    assert g.ki_current / g.kp_current == pytest.approx(m.resistance / m.inductance_q)  # the zero cancels R/L
    assert g.voltage_limit == pytest.approx(m.dc_link_voltage / math.sqrt(3))
    assert g.dead_time_voltage == pytest.approx(m.dead_time_s * m.pwm_frequency_hz * m.dc_link_voltage)
    # the datasheet figures the defaults were derived from: K_t 0.47 N m / A rms, K_E ~28 V rms (l-l) per krpm
    assert g.torque_constant * math.sqrt(2) == pytest.approx(0.47, rel=0.01)
    w_e = pp * 1000 * 2 * math.pi / 60
    assert w_e * m.flux_linkage * math.sqrt(3) / math.sqrt(2) == pytest.approx(28.4, rel=0.01)


def test_phase_currents_are_balanced_and_have_the_q_current_as_amplitude():
    th = np.linspace(0, 4 * np.pi, 400)
    i = phase_currents(np.zeros_like(th), np.full_like(th, 3.0), th)
    assert np.max(np.abs(i.sum(axis=0))) < 1e-12
    assert np.max(np.abs(i), axis=1) == pytest.approx([3.0, 3.0, 3.0], rel=1e-3)
    # i_a = -i_q sin(theta): leads by 90 degrees against the d axis
    assert i[0] == pytest.approx(-3.0 * np.sin(th))
    # b lags a by 120 electrical degrees
    assert i[1] == pytest.approx(-3.0 * np.sin(th - 2 * np.pi / 3))


def test_sample_current_keeps_a_line_below_the_new_nyquist_and_refuses_odd_rates():
    fs = 48000.0
    t = np.arange(48000) / fs
    x = np.sin(2 * np.pi * 50 * t) + 0.5 * np.sin(2 * np.pi * 5000 * t)  # 5 kHz must be filtered out
    y = sample_current(x[None, :], fs, 1000.0)[0]
    assert y.size == 1000
    assert np.std(y[100:-100]) == pytest.approx(1 / math.sqrt(2), rel=0.01)
    with pytest.raises(ParameterError, match="above the simulation"):
        sample_current(x[None, :], fs, 96000.0)
    with pytest.raises(ParameterError, match="not a simple fraction"):
        sample_current(x[None, :], fs, 1000.0 * math.pi)


def test_operating_point_checks_name_the_limit():
    m = ReducerParams.default().motor
    check_operating_point(m, 5, 3000 * 2 * math.pi / 60, 2.39)  # the motor's rated point
    with pytest.raises(ParameterError, match=r"max_current = 21.6 A"):
        check_operating_point(m, 5, 100.0, 10.0)
    with pytest.raises(ParameterError, match=r"cannot reach 8000 rpm.*dc_link_voltage = 310 V"):
        check_operating_point(m, 5, 8000 * 2 * math.pi / 60, 1.0)


def test_bad_motor_parameters_give_one_clear_error():
    with pytest.raises(ConfigError, match=r"\[motor\] inductance_d"):
        ReducerParams.default().replace(motor={"inductance_d": -1e-3})
    with pytest.raises(ParameterError, match="saturates.*max_current"):
        prepare(output_speed_deg_s=30.0, load_Nm=5000.0, settings=ModelSettings(electrical=True))
    with pytest.raises(ParameterError, match="cannot reach"):
        prepare(output_speed_deg_s=400.0, load_Nm=50.0, settings=ModelSettings(electrical=True))
    with pytest.raises(ParameterError, match="needs the motor rotor"):
        prepare(params=ReducerParams.default().replace(drive={"speed_loop_bandwidth_hz": 0.0}),
                output_speed_deg_s=30.0, settings=ModelSettings(electrical=True))
    with pytest.raises(ParameterError, match="signal must be one of"):
        simulate(output_speed_deg_s=30.0, duration_s=0.01, signal="torque")


# ------------------------------------------------------------------------------ compiled rates
@pytest.mark.parametrize("dead_time_s,encoder_bits", [(1e-6, 23), (0.0, 0), (2e-6, 12)])
def test_compiled_motor_rates_match_an_independent_numpy_statement(dead_time_s, encoder_bits):
    params = ReducerParams.default().replace(motor={"dead_time_s": dead_time_s, "encoder_bits": encoder_bits})
    model = prepare(params, output_speed_deg_s=45.0, settings=ModelSettings(electrical=True))
    P = model.P
    b = kn.I_PMSM
    m = {name[2:].lower(): P[b + i] for i, name in enumerate(MOTOR_P_FIELDS) if name.startswith("M_")}
    n = model.n_dof
    rng = np.random.default_rng(3)
    for _ in range(20):
        y = np.zeros(model.n_state)
        y[n - 1], y[2 * n - 1] = rng.normal(0, 1e-4), rng.normal(0, 0.1)
        x = np.array([rng.normal(0, 0.5), rng.normal(4, 2), rng.normal(0, 1e-3), rng.normal(0, 1e-2),
                      y[n - 1] + rng.normal(0, 1e-6), rng.normal(0, 0.1)])
        y[2 * n:] = x
        theta, omega = rng.uniform(0, 2000), 45 * 121 * math.pi / 180
        t_ff, k_sl, c_sl = 1.4, P[kn.I_KSL], P[kn.I_CSL]
        dydt = np.zeros_like(y)
        motor_rates(y, P, b, n, n - 1, theta, omega, t_ff, k_sl, c_sl, dydt)
        ref = reference_motor_rates(x, y[n - 1], y[2 * n - 1], theta, omega, t_ff, k_sl, c_sl, m)
        # the observer's rates amplify the rounding of the ~1e3 rad absolute angle (ulp 2e-13) by l_2 ~ 1.6e8
        assert dydt[2 * n:] == pytest.approx(ref, rel=1e-8, abs=1e-8 * np.abs(ref).max())
        assert air_gap_torque(P, b, x[0], x[1]) == pytest.approx(reference_torque(x[0], x[1], m), rel=1e-12)


# ------------------------------------------------------------------------------ the coupled run
@pytest.fixture(scope="module")
def coupled_30():
    return simulate(output_speed_deg_s=30.0, load_Nm=120.0, duration_s=1.0, fs=48000.0, signal="both",
                    settings=FAST, seed=4)


def test_coupled_run_holds_the_speed_and_carries_the_load(coupled_30):
    r = coupled_30
    p = ReducerParams.default()
    i_a, i_b, i_c, i_q, speed = r.current
    assert r.current_fs == 1000.0 and r.current.shape == (5, 1000)
    assert r.current_names == ["i_a", "i_b", "i_c", "i_q", "speed"]
    rpm = 30.0 * p.ratio / 6.0
    assert np.mean(speed) == pytest.approx(rpm, rel=1e-4)
    kt = controller_gains(p.motor, p.operation.motor_pole_pairs).torque_constant
    load = 120.0 / p.ratio + p.motor.viscous_friction * rpm * 2 * math.pi / 60
    assert np.mean(i_q) == pytest.approx(load / kt, rel=2e-3)
    # balanced phases whose rms is i_q / sqrt(2); their fundamental at f_e = p n / 60
    assert np.max(np.abs(i_a + i_b + i_c)) < 0.05  # the sensors' noise only
    assert np.std(i_a) == pytest.approx(np.mean(i_q) / math.sqrt(2), rel=0.01)
    X = np.abs(np.fft.rfft(i_a * np.hanning(i_a.size)))
    assert np.fft.rfftfreq(i_a.size, 1e-3)[np.argmax(X)] == pytest.approx(p.operation.motor_pole_pairs * rpm / 60, abs=1.0)


def test_the_coupling_is_two_way(coupled_30):
    """The drive changes the vibration: the same run with the ideal torque source differs (a little)."""
    plain = simulate(output_speed_deg_s=30.0, load_Nm=120.0, duration_s=1.0, fs=48000.0, settings=FAST, seed=4)
    a, b = coupled_30.signal, plain.signal
    rel = np.linalg.norm(a - b) / np.linalg.norm(b)
    assert 1e-4 < rel < 0.5, rel
    # and a heavier rotor changes the current: the reducer's torque ripple reaches it less
    heavy = simulate(ReducerParams.default().replace(drive={"motor_inertia": 1.26e-3}), output_speed_deg_s=30.0,
                     load_Nm=120.0, duration_s=1.0, fs=48000.0, signal="current", settings=FAST, seed=4)
    assert heavy.signal[3].std() != pytest.approx(coupled_30.current[3].std(), rel=1e-3)


def test_current_result_round_trips_through_npz(coupled_30, tmp_path):
    f = tmp_path / "run.npz"
    coupled_30.to_npz(f)
    back = SimulationResult.from_npz(f)
    assert back.current_fs == 1000.0 and back.current_names == coupled_30.current_names
    assert np.array_equal(back.current, coupled_30.current)
    only = coupled_30.current_only()
    assert only.fs == 1000.0 and only.channel_names[0] == "i_a" and only.signal is coupled_30.current


def test_the_run_is_deterministic_for_a_seed_and_the_noise_follows_it(coupled_30):
    again = simulate(output_speed_deg_s=30.0, load_Nm=120.0, duration_s=1.0, fs=48000.0, signal="current",
                     settings=FAST, seed=4)
    assert np.array_equal(again.signal, coupled_30.current)
    other = simulate(output_speed_deg_s=30.0, load_Nm=120.0, duration_s=1.0, fs=48000.0, signal="current",
                     settings=FAST, seed=5)
    assert not np.array_equal(other.signal[0], again.signal[0])
    assert np.std(other.signal[0] - again.signal[0]) == pytest.approx(0.005 * math.sqrt(2), rel=0.1)


def _current(speed, **motor):
    params = ReducerParams.default().replace(motor=motor) if motor else None
    return simulate(params, output_speed_deg_s=speed, duration_s=4.2, fs=48000.0, signal="current", settings=FAST)


def test_dead_time_gives_the_5fe_line_and_the_encoder_error_the_f1_sidebands():
    speed = 45.0
    fe = 5 * speed * 121 / 360
    f1 = speed * 120 / 360  # the sun's speed relative to the carrier
    on = _current(speed).signal[0][-4096:]
    off = _current(speed, dead_time_s=0.0, encoder_error_arcsec=0.0).signal[0][-4096:]
    assert _line_db(on, 1000.0, 5 * fe)[1] > 20.0
    assert _line_db(off, 1000.0, 5 * fe)[1] < 10.0
    for f in (fe - f1, fe + f1):
        assert _line_db(on, 1000.0, f)[1] > 10.0
        assert _line_db(off, 1000.0, f)[1] < 10.0


# ------------------------------------------------------------------------------ a motor-current library
def test_a_current_library_stores_the_phase_current(tmp_path):
    from rvdiag.datasets import SampleStore
    from rvdiag.library import LibraryConfig, build_library
    from rvdiag.library.simulators import check_options

    cfg = LibraryConfig.from_dict({
        "mode": "split-by-simulation", "seed": 3, "channel": "i_a",
        "model": {"signal": "current", "substeps": 4},
        "signal": {"fs": 1000.0, "duration_s": 0.256, "transient_s": 0.05, "segment_length": 128, "hop": 128},
        "operation": {"output_speed_deg_s": [30.0, 60.0], "load_Nm": 100.0, "noise_snr_db": 60.0},
        "split": {"simulations_per_state": 2, "test_simulations_per_state": 1},
        "states": {"T1": {}, "T2": {"broken_fraction": 1.0}},
    }, source="current.toml")
    build_library(cfg, tmp_path / "cur.zarr", workers=0, progress=False)
    data = SampleStore.open(tmp_path / "cur.zarr").load()
    assert data.X.shape == (8, 128)
    # phase currents whose amplitude is the load's i_q = T_L / (i K_t) (100 N m: 2.49 A)
    amp = np.sqrt(2) * data.X.std(axis=1)
    assert amp == pytest.approx(np.full(8, 100.0 / 121.0 / (1.5 * 5 * 0.0443)), rel=0.03)
    with pytest.raises(ConfigError, match="signal"):
        check_options({"signal": "torque"})
