"""rvdiag.updating.observability: the whitened Jacobian and its Fisher information on problems whose answer is known,
the planets' cancellation of sun orders, and the simulator's sensitivities (docs/twin.md)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rvdiag.errors import ParameterError
from rvdiag.updating import observability as ob


# --------------------------------------------------------------------------- the harmonics' algebra
def test_planet_phase_sum_keeps_only_multiples_of_the_planet_count():
    orders = np.arange(0, 25)
    for N in (1, 2, 3, 4):
        g = ob.planet_phase_sum(orders, N)
        assert np.allclose(g, (orders % N == 0).astype(float), atol=1e-12)
    with pytest.raises(ParameterError):
        ob.planet_phase_sum([1], 0)


@pytest.mark.parametrize("N,Z", [(2, 11), (3, 13), (3, 12)])
def test_the_summed_torque_of_equally_spaced_planets_cancels_the_other_orders(N, Z):
    """An independent statement: the per-tooth error pattern of a Z-tooth sun, seen by N planets at 2 pi i / N,
    summed over the planets (the net torque of equal meshes), has no sun order that N does not divide, and every
    tooth harmonic h survives at an order h + m Z or m Z - h of torsional_orders when Z and N are coprime (the
    RV-20E's 11 and 2), while with N dividing Z the harmonics that N does not divide vanish from the torque."""
    rng = np.random.default_rng(3)
    e = rng.standard_normal(Z)
    M = 64 * Z * N                                           # samples per sun revolution
    n = np.arange(M)

    def pattern(shift):                                     # the error of the tooth in mesh, planet at shift
        return e[np.mod(n - shift, M) * Z // M]

    torque = sum(pattern(i * M // N) for i in range(N))
    X = np.fft.rfft(torque) / M
    single = np.fft.rfft(pattern(0)) / M
    orders = np.arange(X.size)
    assert np.max(np.abs(X[orders % N != 0])) < 1e-12 * np.max(np.abs(X))
    assert np.allclose(np.abs(X[orders % N == 0]), N * np.abs(single[orders % N == 0]))
    for h in range(1, Z // 2 + 1):
        ords = ob.torsional_orders(h, Z, N, 4 * Z)
        assert all(o % N == 0 and (o % Z in (h, Z - h)) for o in ords)
        if math.gcd(Z, N) == 1:                             # sequenced meshing: every harmonic reaches the torque
            assert ords and max(abs(X[o]) for o in ords) > 1e-6
        elif h % N:                                         # in-phase meshing: the harmonic is lost to torsion
            assert not ords
            alias = [o for o in range(1, 4 * Z) if o % Z in (h, Z - h)]
            assert max(abs(X[o]) for o in alias) < 1e-12


def test_torsional_orders_of_the_rv20e():
    assert ob.torsional_orders(1, 11, 2, 40) == [10, 12, 32, 34]
    assert ob.torsional_orders(2, 11, 2, 40) == [2, 20, 24]


# --------------------------------------------------------------------------- Fisher information and SVD
def _jac(J: dict, names, kinds=None, sds=None):
    kinds = kinds or ["factor"] * len(names)
    sds = sds or [1.0] * len(names)
    pars = [ob.Parameter(n, k, (("material", "youngs_modulus"),) if k == "factor" else i, 0.01, sd)
            for i, (n, k, sd) in enumerate(zip(names, kinds, sds))]
    full = {s: np.asarray(J.get(s, np.zeros((next(iter(J.values())).shape[0], len(names)))), dtype=float)
            for s in ob.OBSERVATIONS}
    return ob.Jacobian(pars, full, {s: np.zeros(full[s].shape[0]) for s in full},
                       {s: np.zeros(len(names)) for s in full}, 100.0)


def test_woodbury_fisher_equals_the_explicit_inverse():
    rng = np.random.default_rng(0)
    J, G = rng.standard_normal((40, 6)), rng.standard_normal((40, 3))
    d, v = rng.uniform(0.5, 2.0, 40), rng.uniform(0.1, 3.0, 3)
    C = np.diag(d) + G @ np.diag(v) @ G.T
    assert np.allclose(ob.fisher_information(J, d, G, v), J.T @ np.linalg.solve(C, J), rtol=1e-10, atol=1e-10)
    with pytest.raises(ParameterError):
        ob.fisher_information(J, -d)


def test_a_parameter_that_does_not_enter_the_output_has_a_zero_singular_value():
    rng = np.random.default_rng(1)
    J = rng.standard_normal((30, 3))
    J[:, 2] = 0.0                                            # the third parameter reaches no observation
    jac = _jac({"vibration": J}, ["a", "b", "unseen"])
    r = ob.analyse(jac, None, ("vibration",))
    assert r.singular_values[-1] == 0.0 and r.singular_values[-2] > 0
    assert r.crb_sd[2] == np.inf and np.all(np.isfinite(r.crb_sd[:2]))
    assert r.posterior_sd[2] == pytest.approx(1.0)           # the prior, untouched
    assert r.identifiable(1.0) == [n for n, s in zip(r.names, r.crb_sd) if s < 1.0]


def test_pitch_deviations_take_the_difference_of_neighbouring_positions():
    r = ob.Observability(("te",), [], np.zeros(0), np.zeros((0, 0)), np.zeros(0), np.zeros(0), np.zeros(3),
                         np.zeros(3), np.zeros(3), np.diag([1.0, 4.0, 9.0]))
    assert np.allclose(r.pitch_posterior_m() ** 2, [1 + 9, 4 + 1, 9 + 4])


def test_known_singular_values_scale_with_records_and_length():
    """One parameter, one observation line: sensitivity s at prior spread 1 and line variance sigma^2/(2 f T)."""
    J = np.zeros((2, 1))
    J[0, 0] = 3.0
    jac = _jac({"vibration": J}, ["p"], sds=[0.5])
    noise = ob.NoiseModel(snr_db=20.0, vibration_fs=100.0)
    var = noise.line_variance("vibration", 1.0, jac.vibration_power)
    assert var == pytest.approx(100.0 * 0.01 / (2 * 100.0))
    r1 = ob.analyse(jac, None, ("vibration",), noise=noise)
    assert r1.singular_values[0] == pytest.approx(3.0 * 0.5 / math.sqrt(var))
    r = ob.analyse(jac, None, ("vibration",), noise=noise, records=4, record_s=9.0)
    assert r.singular_values[0] == pytest.approx(6.0 * r1.singular_values[0])
    assert r.crb_sd[0] == pytest.approx(1.0 / r.singular_values[0])


def test_a_parameter_confounded_with_the_run_to_run_variation_is_lost():
    """The run-to-run variation along the parameter's own column hides it in proportion to its spread; a column
    orthogonal to it is untouched."""
    rng = np.random.default_rng(2)
    J = rng.standard_normal((50, 2))
    J[:, 1] -= J[:, 0] * (J[:, 0] @ J[:, 1]) / (J[:, 0] @ J[:, 0])
    jac = _jac({"vibration": 1e-2 * J}, ["hidden", "free"])
    base = ob.analyse(jac, None, ("vibration",))
    crb = []
    for sd in (0.01, 1.0, 100.0):
        nu = ob.Jacobian([ob.Parameter("load", "load", None, 0.01, sd)], {
            "vibration": 1e-2 * J[:, :1], "te": np.zeros((50, 1)), "current": np.zeros((50, 1))},
            jac.nominal, {}, 100.0)
        r = ob.analyse(jac, nu, ("vibration",))
        assert r.crb_sd[1] == pytest.approx(base.crb_sd[1], rel=1e-9)
        crb.append(r.crb_sd[0])
    assert crb[0] < crb[1] < crb[2] and crb[2] > 50 * base.crb_sd[0]


def test_the_sun_tooth_prior_is_the_drawn_errors_covariance():
    from rvdiag.gears.modification import iso1328_tolerances, tooth_position_errors
    from rvdiag.params import ReducerParams

    p = ReducerParams.default()
    S = ob.sun_tooth_prior(p)
    tol = iso1328_tolerances(p.stage1.module, p.stage1.module * p.stage1.sun_teeth, p.modification.iso1328_grade)
    X = np.array([tooth_position_errors(p.stage1.sun_teeth, tol, s) for s in range(4000)])
    assert np.allclose(np.cov(X.T), S, atol=0.08 * S.max())
    assert np.linalg.matrix_rank(S, tol=1e-6 * S.max()) == p.stage1.sun_teeth - 1
    L, names = ob.prior_square_root(ob.reducer_parameters(p, planets=False, path=False, stiffness=False,
                                                          damping=False, encoder=False), S)
    assert L.shape == (11, 10) and np.allclose(L @ L.T, S)
    assert sorted(names) == sorted(f"sun tooth harmonic {h}" for h in (1, 1, 2, 2, 3, 3, 4, 4, 5, 5))


def test_the_averaging_period_must_divide_the_record():
    assert ob.OperatingPoint(revolutions=6, period_revs=3).max_order(_params(), "current") == 100   # 500 Hz in thirds of 15 Hz
    with pytest.raises(ParameterError):
        ob.OperatingPoint(revolutions=4, period_revs=3)
    with pytest.raises(ParameterError):
        ob.OperatingPoint(period_revs=0)


def _params():
    from rvdiag.params import ReducerParams

    return ReducerParams.default()


# --------------------------------------------------------------------------- the simulator's sensitivities
def test_explicit_tooth_errors_reproduce_the_drawn_mesh_table():
    from rvdiag.dynamics.mesh import mesh_table_from_gears
    from rvdiag.params import ReducerParams

    p = ReducerParams.default()
    a = mesh_table_from_gears(p)
    b = mesh_table_from_gears(p, tooth_errors_m=ob.nominal_tooth_errors(p))
    assert np.array_equal(a.pair_separation_m, b.pair_separation_m)
    c = mesh_table_from_gears(p, tooth_errors_m=ob.nominal_tooth_errors(p) + 1e-7 * (np.arange(11) == 4))
    assert not np.array_equal(a.pair_separation_m, c.pair_separation_m)
    with pytest.raises(ParameterError):
        mesh_table_from_gears(p, tooth_errors_m=np.zeros(3))


def test_simulated_sensitivities():
    """One sun revolution at 45 deg/s, 90 N m (8 simulations of 0.12 s: 5-16 s on the shared machine once the
    kernels are compiled): the gain's column is the signal itself, the motor encoder's error reaches the
    transmission error only, a sun tooth's position error reaches all three signals nearly linearly (+-h against
    +-2h), and moving every tooth alike (a rotation of the sun, no error) leaves the lines unchanged."""
    from rvdiag.params import ReducerParams

    base = ReducerParams.default()
    op = ob.OperatingPoint(revolutions=1, transient_s=0.05)
    by = {p.name: p for p in ob.reducer_parameters(base, planets=False, path=True, stiffness=False,
                                                   damping=False)}
    pars = [by["path gain"], by["motor encoder error cos"], by["sun tooth 4"]]
    J = ob.jacobian(base, op, pars)
    vib = J.columns["vibration"]
    assert np.allclose(vib[:, 0], J.nominal["vibration"], rtol=1e-9, atol=1e-12)
    assert not np.any(J.columns["te"][:, 0]) and not np.any(J.columns["current"][:, 0])
    assert not np.any(vib[:, 1]) and not np.any(J.columns["current"][:, 1])
    assert np.linalg.norm(J.columns["te"][:, 1]) > 0
    assert all(np.linalg.norm(J.columns[s][:, 2]) > 0 for s in ob.OBSERVATIONS)
    assert J.linearity["vibration"][0] < 1e-9 and J.linearity["te"][1] < 1e-9
    assert J.linearity["te"][2] < 0.05 and J.linearity["vibration"][2] < 0.15
    teeth0 = ob.nominal_tooth_errors(base)
    h = 1e-8
    y0 = ob.observe(base, op, None, teeth0)
    one = ob.observe(base, op, None, teeth0 + h * (np.arange(11) == 4))
    every = ob.observe(base, op, None, teeth0 + h)
    for s in ("vibration", "te"):
        assert np.linalg.norm(every[s] - y0[s]) < 0.05 * np.linalg.norm(one[s] - y0[s])
