"""Feature extractors: analytic values, band placement, sklearn API, bad input."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.special import gamma
from sklearn.base import clone
from sklearn.pipeline import make_pipeline

from rvdiag.errors import ParameterError
from rvdiag.features import (
    CharacteristicBandEnergy,
    EnvelopeSpectrumFeatures,
    RawSignal,
    SpectrumFeatures,
    TIME_FEATURE_NAMES,
    TimeDomainFeatures,
    WaveletPacketEnergy,
    bearing_defect_frequencies,
    feature_names,
    make_features,
    time_features,
)

N = 4000
T = np.arange(N)


def sine(amp=1.0, f=0.01, phase=0.3):
    return amp * np.sin(2 * np.pi * f * T + phase)


# ----------------------------------------------------------------- time domain

def test_time_features_of_a_sine_match_the_analytic_values():
    A = 2.5
    F = TimeDomainFeatures().fit_transform(sine(A)[None, :])[0]
    got = dict(zip(TIME_FEATURE_NAMES, F))
    mean_sqrt_abs = gamma(0.75) / (np.sqrt(np.pi) * gamma(1.25))  # (1/pi) int_0^pi sqrt(sin)
    x_r = A * mean_sqrt_abs**2
    expected = {
        "peak_to_peak": 2 * A, "mean": 0.0, "variance": A**2 / 2, "rms": A / np.sqrt(2),
        "sqrt_amplitude": x_r, "kurtosis": 1.5, "pulse_factor": np.pi / 2,
        "margin_factor": A / x_r, "crest_factor": np.sqrt(2), "shape_factor": np.pi / (2 * np.sqrt(2)),
    }
    for k, v in expected.items():
        assert_allclose(got[k], v, rtol=1e-3, atol=1e-9, err_msg=k)


def test_time_features_of_a_square_wave_and_offsets():
    x = np.where(np.sin(2 * np.pi * 0.01 * T + 0.1) >= 0, 1.0, -1.0) + 3.0
    F = dict(zip(TIME_FEATURE_NAMES, TimeDomainFeatures().fit_transform(x[None, :])[0]))
    assert_allclose(F["mean"], 3.0, atol=0.01)
    assert_allclose(F["variance"], 1.0, atol=1e-3)
    assert_allclose(F["kurtosis"], 1.0, atol=1e-3)  # two-valued +-1 around the mean
    assert_allclose(F["peak_to_peak"], 2.0)


def test_time_features_dead_channel_gives_zeros_not_nan():
    F = TimeDomainFeatures().fit_transform(np.zeros((2, 100)))
    assert np.all(np.isfinite(F)) and np.all(F == 0)


def test_impulsive_signal_has_higher_kurtosis_and_crest():
    rng = np.random.default_rng(0)
    g = rng.standard_normal(N)
    imp = g.copy()
    imp[::400] += 15.0
    F = TimeDomainFeatures().fit_transform(np.vstack([g, imp]))
    k, c = TIME_FEATURE_NAMES.index("kurtosis"), TIME_FEATURE_NAMES.index("crest_factor")
    assert_allclose(F[0, k], 3.0, atol=0.3)
    assert F[1, k] > 2 * F[0, k] and F[1, c] > F[0, c]


# ----------------------------------------------------------------- spectrum

def test_spectrum_band_of_a_tone():
    f = 0.1234
    F = SpectrumFeatures(n_bands=50, log=False).fit_transform(np.sin(2 * np.pi * f * T)[None, :])[0]
    assert F.argmax() == int(f / 0.5 * 50)
    assert_allclose(F.sum(), 1.0, rtol=1e-9)  # relative powers sum to one


def test_spectrum_absolute_power_is_parseval():
    A = 3.0
    F = SpectrumFeatures(n_bands=8, log=False, relative=False, window=None).fit_transform(
        sine(A, f=0.05, phase=0)[None, :])[0]
    assert_allclose(F.sum(), A**2 / 2, rtol=1e-6)


def test_full_magnitude_spectrum_peaks_at_the_bin():
    F = SpectrumFeatures(n_bands=None, log=False, relative=False).fit_transform(sine(f=0.02)[None, :])
    assert F.shape == (1, N // 2 + 1) and F[0].argmax() == int(0.02 * N)


def test_characteristic_band_energy_peaks_at_the_right_frequency():
    from rvdiag.kinematics import characteristic_frequencies
    from rvdiag.params import ReducerParams

    p = ReducerParams.default()
    fs = 5000.0
    keys = ("f1", "fsp", "fcs")
    fr = characteristic_frequencies(p, input_speed_rpm=1500.0).as_dict()
    t = np.arange(8192) / fs
    x = np.sin(2 * np.pi * fr["fsp"] * t) + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    tr = CharacteristicBandEnergy.from_operating_point(p, fs, input_speed_rpm=1500.0, keys=keys, harmonics=2)
    F = tr.fit_transform(x[None, :])[0]
    names = list(tr.get_feature_names_out())
    assert names[int(F.argmax())] == "band_fsp_h1"
    assert F[names.index("band_fsp_h1")] > -0.05  # log10 of a relative power close to 1
    assert F[names.index("band_fcs_h1")] < -2


def test_characteristic_band_energy_in_orders_and_cycles_per_sample():
    x = np.sin(2 * np.pi * 0.06 * T)[None, :]
    a = CharacteristicBandEnergy(centers=[0.03, 0.05], harmonics=2).fit_transform(x)
    b = CharacteristicBandEnergy(centers=[3.0, 5.0], harmonics=2, shaft_frequency=0.01).fit_transform(x)
    assert_allclose(a, b)
    assert a[0].argmax() == 1  # second harmonic of 0.03


def test_characteristic_band_rejects_harmonics_above_nyquist():
    with pytest.raises(ParameterError, match="Nyquist"):
        CharacteristicBandEnergy(centers=[0.3], harmonics=2).fit(np.zeros((1, 64)))


def test_bearing_defect_frequencies_cwru_6205():
    fr = 1797 / 60
    f = bearing_defect_frequencies(fr, 9, 0.3126, 1.537)
    # CWRU bearing data centre: BPFI 5.4152, BPFO 3.5848, FTF 0.39828, BSF 4.7135 (x shaft speed)
    assert_allclose([f["bpfi"] / fr, f["bpfo"] / fr, f["ftf"] / fr], [5.4152, 3.5848, 0.39828], rtol=2e-4)
    assert_allclose(2 * f["bsf"] / fr, 4.7135, rtol=2e-3)
    with pytest.raises(ParameterError):
        bearing_defect_frequencies(fr, 9, 2.0, 1.0)


def _bearing_like(f_defect, f_res=0.2, n=N, amp=1.0, seed=0):
    """Decaying resonance bursts repeating at f_defect (cycles/sample) plus noise."""
    rng = np.random.default_rng(seed)
    x = 0.3 * rng.standard_normal(n)
    burst = np.exp(-np.arange(60) / 10.0) * np.sin(2 * np.pi * f_res * np.arange(60))
    for s in np.arange(0, n - 60, 1 / f_defect).astype(int):
        x[s:s + 60] += amp * burst
    return x


def test_envelope_spectrum_finds_the_defect_frequency():
    fd_a, fd_b = 0.0135, 0.0089
    X = np.vstack([_bearing_like(fd_a), _bearing_like(fd_b, seed=1)])
    tr = EnvelopeSpectrumFeatures(centers=[fd_a, fd_b], band=(0.15, 0.25), harmonics=1, names=["a", "b"])
    F = tr.fit_transform(X)
    assert F[0, 0] > F[0, 1] + 0.5 and F[1, 1] > F[1, 0] + 0.5
    # the plain spectrum sees only the resonance, not the repetition rate
    S = CharacteristicBandEnergy(centers=[fd_a, fd_b], harmonics=1).fit_transform(X)
    assert abs(S[0, 0] - S[0, 1]) < abs(F[0, 0] - F[0, 1])


def test_envelope_equal_bands_and_hz_units():
    fs = 12000.0
    x = _bearing_like(162.0 / fs)[None, :]
    F = EnvelopeSpectrumFeatures(n_bands=20, fmax=0.05, log=False).fit_transform(x)[0]
    assert F.argmax() == int(162.0 / fs / 0.05 * 20)
    G = EnvelopeSpectrumFeatures(centers=[162.0], fs=fs, band=(1800, 3000), harmonics=2).fit_transform(x)
    H = EnvelopeSpectrumFeatures(centers=[162.0 / fs], band=(0.15, 0.25), harmonics=2).fit_transform(x)
    assert_allclose(G, H)


# ----------------------------------------------------------------- wavelet packet

@pytest.mark.parametrize("band", [0, 1, 5, 8, 11, 15])
def test_wpd_tone_lands_in_its_band(band):
    f = (band + 0.5) / 32  # centre of band `band` of 16 over [0, 0.5]
    E = WaveletPacketEnergy(wavelet="db10").fit_transform(np.sin(2 * np.pi * f * T[:2048])[None, :])[0]
    assert E.shape == (16,)
    assert int(E.argmax()) == band
    assert E[band] > 0.5
    assert_allclose(E.sum(), 1.0, rtol=1e-9)


def test_wpd_natural_order_would_differ():
    """Frequency order is not the natural order: a tone in band 2 sits in natural node 3 ('aadd')."""
    import pywt

    x = np.sin(2 * np.pi * (2.5 / 32) * T[:2048])
    wp = pywt.WaveletPacket(x, "db10", maxlevel=4)
    nat = [np.sum(n.data**2) for n in wp.get_level(4, order="natural")]
    assert int(np.argmax(nat)) == 3
    assert int(WaveletPacketEnergy(wavelet="db10").fit_transform(x[None, :])[0].argmax()) == 2


# ----------------------------------------------------------------- API

ALL = [TimeDomainFeatures(), SpectrumFeatures(n_bands=16), WaveletPacketEnergy(), RawSignal(),
       CharacteristicBandEnergy(centers=[0.05]), EnvelopeSpectrumFeatures(n_bands=8)]


@pytest.mark.parametrize("tr", ALL, ids=lambda t: type(t).__name__)
def test_transformers_follow_the_sklearn_api(tr):
    X = np.random.default_rng(0).standard_normal((5, 256))
    t2 = clone(tr)
    F = t2.fit(X).transform(X)
    assert F.shape[0] == 5 and np.all(np.isfinite(F))
    assert len(t2.get_feature_names_out()) == F.shape[1]
    assert_allclose(t2.transform(X[2:3]), F[2:3])  # a row does not depend on its batch
    with pytest.raises(ParameterError, match="points"):
        t2.transform(X[:, :100])
    with pytest.raises(ParameterError, match="NaN"):
        t2.transform(np.full((1, 256), np.nan))
    with pytest.raises(ParameterError, match="2D"):
        t2.fit(X[0])
    assert make_pipeline(clone(tr)).fit_transform(X).shape == F.shape


def test_check_estimator_on_time_features():
    from sklearn.utils.estimator_checks import check_estimator

    check_estimator(TimeDomainFeatures())


def test_make_features_names_and_errors():
    assert {"time", "spectrum", "wpd", "eemd", "none"} <= set(feature_names())
    assert isinstance(make_features("wpd", level=3), WaveletPacketEnergy)
    assert make_features("spectrum", n_bands=7).fit_transform(np.ones((1, 64)) + T[:64]).shape == (1, 7)
    with pytest.raises(ParameterError, match="unknown feature set"):
        make_features("fancy")
    with pytest.raises(ParameterError, match="bad options"):
        make_features("time", nonsense=1)
    with pytest.raises(ParameterError):
        WaveletPacketEnergy(wavelet="nope").fit(np.ones((1, 64)))


from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays


@settings(max_examples=40, deadline=None)
@given(x=arrays(np.float64, 64, elements=st.floats(-1e3, 1e3, allow_subnormal=False)),
       a=st.floats(0.01, 100.0))
def test_time_features_scale_as_their_definitions_say(x, a):
    """Ratios and kurtosis are scale-free; mean, rms, p-p, x_r scale with a; variance with a^2."""
    F = time_features(x[None, :])[0]
    G = time_features(a * x[None, :])[0]
    idx = {k: i for i, k in enumerate(TIME_FEATURE_NAMES)}
    for k in ("peak_to_peak", "mean", "rms", "sqrt_amplitude"):
        assert_allclose(G[idx[k]], a * F[idx[k]], rtol=1e-9, atol=1e-9 * a * (1 + abs(F[idx[k]])))
    assert_allclose(G[idx["variance"]], a * a * F[idx["variance"]], rtol=1e-8, atol=1e-6)
    if F[idx["variance"]] > 1e-6 * (1 + F[idx["rms"]] ** 2):
        for k in ("kurtosis", "pulse_factor", "margin_factor", "crest_factor", "shape_factor"):
            assert_allclose(G[idx[k]], F[idx[k]], rtol=1e-6)
    assert F[idx["crest_factor"]] >= 1 - 1e-12 or F[idx["rms"]] == 0
    assert F[idx["shape_factor"]] >= 1 - 1e-12 or F[idx["rms"]] == 0


def test_logspec_features_are_every_bin_and_level_free():
    """``logspec``: one feature per FFT bin, independent of the signal level, and the same spectrum shape as
    the CNNs' logspec input (natural log there, log10 of the relative magnitude here)."""
    from rvdiag.features import make_features
    from rvdiag.models.torch_estimator import log_spectrum

    rng = np.random.default_rng(2)
    X = rng.standard_normal((5, 512))
    F = make_features("logspec").fit_transform(X)
    assert F.shape == (5, 257) and "logspec" in feature_names()
    np.testing.assert_allclose(make_features("logspec").fit_transform(30.0 * X), F, atol=1e-9)
    # interior bins (the one-sided power doubles all but DC and Nyquist): equal up to a constant per row
    diff = (F * np.log(10.0) - log_spectrum(X))[:, 1:-1]
    np.testing.assert_allclose(diff - diff.mean(axis=1, keepdims=True), 0.0, atol=1e-4)
