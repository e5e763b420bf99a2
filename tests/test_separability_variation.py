"""The separability bound with run-to-run variation (docs/monitoring.md; rvdiag.evaluation.separability, "With run-to-run
variation"): the Gaussian (generalised matched filter) and known-draw figures against their closed forms, the
reduction onto the nominal angle axis, and ``rvdiag separability --run-to-run``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import run_cli as run
from rvdiag.evaluation.separability import (RUN_TO_RUN_DEFAULT, apply_run_to_run, on_nominal_axis,
                                            parse_run_to_run, varied_bound_from_windows)
from rvdiag.errors import ParameterError

FAST = ["--output-speed", "60", "--duration", "0.3", "-q"]


def _phi(x: float) -> float:
    return 0.5 * (1.0 + math.erf(x / math.sqrt(2.0)))


def _designed(u, delta, n=64):
    """Two draws per state, +-u about the state means mu and mu + delta: the pooled sample covariance is 2 u u^T."""
    mu = np.sin(2 * np.pi * 3 * np.arange(n) / n)
    HA = np.stack([mu + u, mu - u])[:, None, :]
    HB = np.stack([mu + delta + u, mu + delta - u])[:, None, :]
    return mu[None], (mu + delta)[None], HA, HB


@pytest.mark.parametrize("direction", ["parallel", "oblique", "orthogonal"])
def test_gaussian_bound_is_the_closed_form_deflection_of_a_known_covariance(direction):
    """Sigma_rr = 2 u u^T: d^2 = (||delta||^2 - 2 (u.delta)^2 / (sigma^2 + 2 ||u||^2)) / sigma^2 (Sherman-Morrison),
    the accuracy Phi(d / 2); the known-draw figure is Phi(||delta|| / 2 sigma) (delta is the same in each draw)."""
    n = 64
    rng = np.random.default_rng(3)
    delta = 0.05 * rng.standard_normal(n)
    other = rng.standard_normal(n)
    other -= other @ delta / (delta @ delta) * delta                  # orthogonal to delta
    u = {"parallel": 20.0 * delta, "oblique": 3.0 * delta + 0.2 * other, "orthogonal": 0.5 * other}[direction]
    A0, B0, HA, HB = _designed(u, delta, n)
    levels = [-5.0, 0.0, 10.0]
    got = varied_bound_from_windows(A0, B0, HA, HB, levels)
    power = 0.5 * (np.mean(A0**2) + np.mean(B0**2))
    for i, s in enumerate(levels):
        s2 = power * 10 ** (-s / 10)
        d2 = (delta @ delta - 2 * (u @ delta) ** 2 / (s2 + 2 * u @ u)) / s2
        d2_direct = delta @ np.linalg.solve(2 * np.outer(u, u) + s2 * np.eye(n), delta)
        assert d2 == pytest.approx(d2_direct, rel=1e-9)
        assert got["accuracy_bound_gaussian"][i] == pytest.approx(_phi(math.sqrt(d2) / 2), abs=1e-9)
        assert got["accuracy_bound_known_draw"][i] == pytest.approx(_phi(np.linalg.norm(delta) / 2 / math.sqrt(s2)),
                                                                    abs=1e-9)
    g, k = got["accuracy_bound_gaussian"], got["accuracy_bound_known_draw"]
    if direction == "orthogonal":   # a spread the crack does not share costs nothing
        assert g == pytest.approx(k, abs=1e-9)
    else:                           # a spread along the crack's change hides it
        assert all(x < y for x, y in zip(g, k))
    if direction == "parallel":
        assert g[-1] < 0.52 < k[-1]


def test_without_variation_both_figures_are_the_known_signal_bound():
    from rvdiag.evaluation.separability import bound_from_windows

    rng = np.random.default_rng(0)
    A0, B0 = rng.standard_normal((3, 50)), rng.standard_normal((3, 50))
    got = varied_bound_from_windows(A0, B0, np.stack([A0] * 4), np.stack([B0] * 4), [-10.0, 0.0])
    want = bound_from_windows(A0, B0, [-10.0, 0.0])["accuracy_bound"]
    assert got["accuracy_bound_gaussian"] == pytest.approx(want, abs=1e-12)
    assert got["accuracy_bound_known_draw"] == pytest.approx(want, abs=1e-12)
    assert got["spread_over_distance"] == 0.0 and got["draws"] == 4


def test_varied_bound_refuses_mismatched_or_undefined_draws():
    A0 = np.zeros((2, 8))
    with pytest.raises(ParameterError):
        varied_bound_from_windows(A0, A0, np.zeros((3, 2, 7)), np.zeros((3, 2, 7)), [0.0])
    bad = np.zeros((3, 2, 8))
    bad[0, 0, 0] = np.nan
    with pytest.raises(ParameterError, match="non-finite"):
        varied_bound_from_windows(A0, A0, bad, bad, [0.0])


def test_on_nominal_axis_undoes_a_speed_stretch_and_a_fractional_lag():
    """x(m) = g(ratio (m - c)) recorded at ratio times the speed: x(n / ratio + c) = g(n) on the nominal axis."""
    freqs, phases = np.array([0.013, 0.031, 0.07]), np.array([0.3, 1.1, 2.0])

    def g(t):
        return np.sum(np.sin(2 * np.pi * freqs[:, None] * t[None] + phases[:, None]), axis=0)

    ratio, c = 1.01, -3.3
    ref = g(np.arange(2000.0))
    x = g(ratio * (np.arange(2100.0) - c))
    y, lag = on_nominal_axis(x, ratio, ref)
    assert lag == pytest.approx(c, abs=0.01)
    ok = np.isfinite(y)
    assert ok.sum() > 1900 and np.max(np.abs(y[ok] - ref[ok])) < 1e-3 * np.max(np.abs(ref))
    assert not ok[0]                                               # before the record began: undefined, not zero


def test_run_to_run_parsing_and_application():
    assert parse_run_to_run("default") == RUN_TO_RUN_DEFAULT
    assert parse_run_to_run("load=3, gain=1.5") == {"load": 0.03, "speed": 0.0, "temperature": 0.0, "damping": 0.0,
                                                     "gain": 0.015}
    for bad in ("pressure=3", "load", "load=x", "load=-1", "load=100"):
        with pytest.raises(ParameterError):
            parse_run_to_run(bad)
    from rvdiag.params import ReducerParams

    p = ReducerParams.default()
    q = apply_run_to_run(p, {"temperature": 0.98, "damping": 1.1})
    assert q.material.youngs_modulus == pytest.approx(0.98 * p.material.youngs_modulus)
    assert q.bearings.sun_support == pytest.approx(0.98 * p.bearings.sun_support)
    assert q.damping.mesh_damping_ratio == pytest.approx(1.1 * p.damping.mesh_damping_ratio)
    assert q.damping.bearing_damping_ratio == p.damping.bearing_damping_ratio


# ----------------------------------------------------------------------------- rvdiag separability --run-to-run
def test_separability_without_variation_equals_todays_bound_in_the_same_run(capsys):
    code, out, err = run(["separability", "--pair", "T1,T4", "--snr-db=-10,0,20", "--crack-depth", "1.8",
                          "--run-to-run", "load=0", "--draws", "2", "--json", *FAST], capsys)
    assert code == 0, err
    res = json.loads(out)
    var = res["run_to_run"]
    assert var["ranges_pct"] == {k: 0.0 for k in RUN_TO_RUN_DEFAULT} and var["draws"] == 2
    assert var["n_windows"] == res["n_windows"] and var["start"] == 0
    assert var["accuracy_bound_gaussian"] == pytest.approx(res["accuracy_bound"], abs=1e-12)
    assert var["accuracy_bound_known_draw"] == pytest.approx(res["accuracy_bound"], abs=1e-12)
    assert 0.5 < res["accuracy_bound"][0] < 0.99                     # not saturated: the comparison can tell


def test_separability_with_the_issues_variation_is_lower(capsys):
    code, out, err = run(["separability", "--pair", "T1,T4", "--snr-db=-10,0", "--crack-depth", "1.8",
                          "--run-to-run", "default", "--draws", "3", "--seed", "5", "--json", *FAST], capsys)
    assert code == 0, err
    res = json.loads(out)
    var = res["run_to_run"]
    assert var["ranges_pct"] == pytest.approx({k: 100 * v for k, v in RUN_TO_RUN_DEFAULT.items()})
    assert var["seed"] == 5 and len(var["factors"]) == 3 and len(var["lags"]) == 3
    for f in var["factors"]:
        assert all(abs(f[k] - 1) <= RUN_TO_RUN_DEFAULT[k] for k in RUN_TO_RUN_DEFAULT)
    assert var["spread_over_distance"] > 1.0                         # the healthy spread exceeds the crack
    for g, k, b in zip(var["accuracy_bound_gaussian"], var["accuracy_bound_known_draw"], res["accuracy_bound"]):
        assert g < b and g < k and k == pytest.approx(b, abs=0.03)
    code, out, err = run(["separability", "--pair", "T1,T4", "--snr-db=0", "--run-to-run", "default", "--draws",
                          "2", *FAST], capsys)
    assert code == 0 and "knowing the draw" in out and "not knowing it" in out, err


@pytest.mark.parametrize("args, message", [(["--run-to-run", "humidity=3"], "--run-to-run"),
                                           (["--run-to-run", "default", "--draws", "1"], "--draws")])
def test_separability_run_to_run_refuses_bad_input_in_one_line(args, message, capsys):
    code, out, err = run(["separability", *args, *FAST], capsys)
    assert code == 2 and message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
