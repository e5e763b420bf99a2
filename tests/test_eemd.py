"""EEMD: spline kernel, EMD/EEMD behaviour on known components, agreement with PyEMD, the transformer."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.interpolate import CubicSpline

from rvdiag.errors import ParameterError
from rvdiag.features.eemd import EEMDFeatures, _spline_eval, eemd, emd

N = 1000
T = np.arange(N)
C1 = np.sin(2 * np.pi * 0.08 * T)          # fast tone
C2 = 0.8 * np.sin(2 * np.pi * 0.01 * T)    # slow tone
TREND = 0.002 * T
X = C1 + C2 + TREND


def best_corr(imfs, comp):
    return max(abs(np.corrcoef(i, comp)[0, 1]) for i in imfs if i.std() > 0)


def orthogonality_index(imfs, x):
    """Huang et al. 1998, Eq. (6.5): sum over j != k of <c_j, c_k> / <x, x>."""
    G = imfs @ imfs.T
    return float((G.sum() - np.trace(G)) / np.dot(x, x))


def test_spline_kernel_matches_scipy_natural_spline():
    rng = np.random.default_rng(0)
    t = np.sort(rng.choice(np.arange(-5, 205), 30, replace=False)).astype(float) + 0.25
    y = rng.standard_normal(30)
    out = np.empty(200)
    w = np.empty(40)
    _spline_eval(t, y, 30, 200, out, w.copy(), w.copy(), w.copy())
    assert_allclose(out, CubicSpline(t, y, bc_type="natural")(np.arange(200.0)), rtol=1e-10, atol=1e-10)


def test_emd_separates_two_tones_and_reconstructs_exactly():
    imfs, res = emd(X, n_imfs=6)
    assert_allclose(imfs.sum(0) + res, X, atol=1e-12)
    assert abs(np.corrcoef(imfs[0], C1)[0, 1]) > 0.99
    assert abs(np.corrcoef(imfs[1], C2)[0, 1]) > 0.95


@pytest.fixture(scope="module")
def decompositions():
    from PyEMD import EEMD

    ens = 20
    mine, res = eemd(X, n_imfs=6, ensemble_size=ens, noise_width=0.05, seed=1)
    ref = EEMD(trials=ens, noise_width=0.05 * X.std() / np.ptp(X), parallel=False)  # PyEMD: range-relative
    ref.noise_seed(1)
    theirs = ref.eemd(X, max_imf=6)
    return mine, res, theirs[:-1], theirs[-1]


def test_eemd_recovers_the_components_like_pyemd(decompositions):
    mine, res, theirs, their_res = decompositions
    for comp in (C1, C2):
        assert best_corr(mine, comp) > 0.95
        assert best_corr(theirs, comp) > 0.95
        assert best_corr(mine, comp) > best_corr(theirs, comp) - 0.03
    # the fast tone is the first IMF in both
    assert abs(np.corrcoef(mine[0], C1)[0, 1]) > 0.99 and abs(np.corrcoef(theirs[0], C1)[0, 1]) > 0.99
    assert_allclose(mine.sum(0) + res, X, atol=1e-10)
    # residue: the trend is what is left (up to the slow oscillation leaking into it)
    assert np.corrcoef(res, TREND)[0, 1] > 0.9


def test_eemd_orthogonality_index_is_small(decompositions):
    mine, _, theirs, _ = decompositions
    io_mine = orthogonality_index(mine, X)
    io_theirs = orthogonality_index(theirs, X)
    assert abs(io_mine) < 0.1
    assert abs(io_mine) <= abs(io_theirs) + 0.05


def test_eemd_is_seeded_and_noise_matters():
    a, _ = eemd(X, ensemble_size=5, seed=3)
    b, _ = eemd(X, ensemble_size=5, seed=3)
    c, _ = eemd(X, ensemble_size=5, seed=4)
    assert_allclose(a, b)
    assert not np.allclose(a, c)
    d, _ = eemd(X, ensemble_size=5, noise_width=0.0)
    assert_allclose(d, emd(X)[0], atol=1e-12)  # no noise: EEMD is EMD


def test_eemd_monotone_signal_has_no_imfs():
    imfs, res = eemd(np.linspace(0, 1, 200) ** 2, ensemble_size=3, noise_width=0.0)
    assert np.all(imfs == 0) and res[-1] == 1.0


def test_eemd_bad_parameters():
    with pytest.raises(ParameterError):
        eemd(X, ensemble_size=0)
    with pytest.raises(ParameterError):
        eemd(X, noise_width=-1)
    with pytest.raises(ParameterError):
        eemd(np.array([1.0, np.nan, 2.0, 3.0, 4.0]))
    with pytest.raises(ParameterError):
        EEMDFeatures(n_imfs=0).fit(np.zeros((1, 64)))


def test_eemd_features_transformer():
    rng = np.random.default_rng(0)
    Xs = np.vstack([X, 2 * X, X + 0.5 * rng.standard_normal(N)])
    tr = EEMDFeatures(ensemble_size=4, random_state=0)
    F = tr.fit_transform(Xs)
    assert F.shape == (3, 6)
    assert list(tr.get_feature_names_out())[0] == "eemd_imf1_mean_abs"
    # mean |IMF| scales with the signal (same noise realisations, scaled by each window's std)
    assert_allclose(F[1], 2 * F[0], rtol=1e-9)
    # the added broadband noise lands mainly in IMF 1
    assert F[2, 0] > 3 * F[0, 0]
    # batch independence and threads give the same numbers
    assert_allclose(tr.transform(Xs[2:]), F[2:])
    assert_allclose(EEMDFeatures(ensemble_size=4, random_state=0, n_jobs=2).fit_transform(Xs), F)
    # relative features are level-free
    R = EEMDFeatures(ensemble_size=4, relative=True).fit_transform(Xs[:2])
    assert_allclose(R[0], R[1], rtol=1e-9)
