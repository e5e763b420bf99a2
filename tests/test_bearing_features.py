"""Bearing envelope-line features (rvdiag.features.bearing) on synthetic defects and on CWRU files."""

from __future__ import annotations


import numpy as np
import pytest
from sklearn.base import clone

from rvdiag.errors import ParameterError
from rvdiag.features.bearing import (
    BEARING_6205,
    BearingEnvelopeFeatures,
    geometry_from_mm,
    kurtogram_bands,
    spectral_kurtosis,
)

from conftest import DATA, needs_real_data
FS = 12000.0
FR = 1797 / 60.0
N = 4096


def impacts(rate_hz: float, n: int = N, modulate_hz: float | None = None, seed: int = 0) -> np.ndarray:
    """Impulse train at ``rate_hz`` exciting a 3 kHz resonance, plus noise (a local bearing defect)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    x = np.zeros(n)
    for t0 in np.arange(0.003, t[-1], 1.0 / rate_hz):
        amp = 1.0 if modulate_hz is None else 1.0 + 0.8 * np.cos(2 * np.pi * modulate_hz * t0)
        k = int(round(t0 * FS * (1 + 0.005 * rng.standard_normal())))
        tt = t[k:] - t[k]
        x[k:] += amp * np.exp(-tt * 800.0) * np.sin(2 * np.pi * 3000.0 * tt)
    return x + 0.05 * rng.standard_normal(n)


def test_defect_frequencies_match_cwru_published_multiples():
    f = BearingEnvelopeFeatures(shaft_frequency=FR, fs=FS).defect_frequencies_cps()
    # CWRU bearing information page: BPFO 3.5848, BPFI 5.4152, BSF 2.357 x shaft speed
    np.testing.assert_allclose(f["bpfo"] / f["fr"], 3.5848, rtol=2e-3)
    np.testing.assert_allclose(f["bpfi"] / f["fr"], 5.4152, rtol=2e-3)
    np.testing.assert_allclose(f["bsf2"] / f["fr"], 2 * 2.357, rtol=3e-3)


@pytest.mark.parametrize("line, make", [
    ("bpfo", lambda f: impacts(f["bpfo"] * FS)),
    ("bpfi", lambda f: impacts(f["bpfi"] * FS, modulate_hz=FR)),
    ("bsf2", lambda f: impacts(f["bsf2"] * FS, modulate_hz=f["ftf"] * FS)),
])
def test_the_defect_line_dominates(line, make):
    t = BearingEnvelopeFeatures(shaft_frequency=FR, fs=FS)
    f = t.defect_frequencies_cps()
    X = np.vstack([make(f) for _ in range(2)])
    F = t.fit(X).transform(X)
    names = list(t.get_feature_names_out())
    contrast = F[:, [names.index(f"{k}_contrast") for k in ("bpfo", "bpfi", "bsf2")]]
    assert np.all(np.argmax(contrast, axis=1) == ("bpfo", "bpfi", "bsf2").index(line))
    np.testing.assert_allclose(contrast.sum(axis=1), 0.0, atol=1e-9)


def test_noise_has_weak_lines_and_scale_invariance():
    rng = np.random.default_rng(1)
    noise = rng.standard_normal((3, N))
    f = BearingEnvelopeFeatures(shaft_frequency=FR, fs=FS).defect_frequencies_cps()
    fault = impacts(f["bpfo"] * FS)[None, :]
    t = BearingEnvelopeFeatures(shaft_frequency=FR, fs=FS).fit(noise)
    assert t.transform(fault)[0, 0] > t.transform(noise)[:, 0].max() + 0.3  # BPFO line >2x stronger
    np.testing.assert_allclose(t.transform(7.5 * fault), t.transform(fault), atol=1e-9)


def test_per_window_speed_matches_single_speed_transformers():
    rng = np.random.default_rng(2)
    X = rng.standard_normal((4, 2048))
    speeds = np.array([29.95, 29.95, 28.8, 28.8])
    t = BearingEnvelopeFeatures(fs=FS, speed_column="rpm", **BEARING_6205)
    assert t.input_metadata() == ("rpm",)
    F = t.fit(np.column_stack([X, 60 * speeds])).transform(np.column_stack([X, 60 * speeds]))
    for s in (29.95, 28.8):
        rows = speeds == s
        G = BearingEnvelopeFeatures(shaft_frequency=s, fs=FS).fit(X[rows]).transform(X[rows])
        np.testing.assert_allclose(F[rows], G)
    # cycles per sample without fs gives the same features
    H = BearingEnvelopeFeatures(shaft_frequency=29.95 / FS, fs=None).fit(X[:2]).transform(X[:2])
    np.testing.assert_allclose(F[:2], H)


@pytest.mark.parametrize("line", ["bpfo", "bpfi", "bsf2"])
def test_am_signal_at_a_defect_frequency_gives_its_envelope_line(line):
    """A 3 kHz carrier amplitude-modulated at the defect frequency of ``line`` (at each window's own speed)
    has a squared envelope with a line there: that line's contrast is the largest, at both speeds."""
    t = np.arange(N) / FS
    rows, rpms = [], []
    for rpm in (1797.0, 1730.0):
        f = BearingEnvelopeFeatures(shaft_frequency=rpm / 60, fs=FS).defect_frequencies_cps()[line] * FS
        rows.append((1 + 0.5 * np.cos(2 * np.pi * f * t)) * np.sin(2 * np.pi * 3000.0 * t))
        rpms.append(rpm)
    X = np.column_stack([np.vstack(rows), rpms])
    feats = BearingEnvelopeFeatures(fs=FS, speed_column="rpm").fit(X)
    F = feats.transform(X)
    k = ("bpfo", "bpfi", "bsf2").index(line)
    assert np.all(np.argmax(F[:, 3:], axis=1) == k)
    # the line holds a large share of the envelope's energy: 10^feature > 0.3 (a pure tone's share is 1/2)
    assert np.all(F[:, k] > np.log10(0.3))
    # read at the wrong speed (10 % off), the line is lost
    wrong = X.copy()
    wrong[:, -1] *= 1.1
    assert np.all(feats.transform(wrong)[:, k] < F[:, k] - 0.5)


def test_speed_column_errors():
    X = np.random.default_rng(0).standard_normal((2, 2049))
    with pytest.raises(ParameterError, match="fs"):
        BearingEnvelopeFeatures(fs=None, speed_column="rpm").fit(X)
    X[:, -1] = [1797.0, -5.0]
    with pytest.raises(ParameterError, match="<= 0"):
        BearingEnvelopeFeatures(speed_column="rpm").fit(X).transform(X)


def test_geometry_in_mm():
    g = geometry_from_mm("9,7.94,39.04,0")
    assert g["n_balls"] == 9 and g["contact_angle_rad"] == 0.0
    np.testing.assert_allclose(g["ball_diameter"] / g["pitch_diameter"],
                               BEARING_6205["ball_diameter"] / BEARING_6205["pitch_diameter"], rtol=2e-5)
    assert geometry_from_mm("8,10,50,15")["contact_angle_rad"] == pytest.approx(np.deg2rad(15))
    for bad in ("9,7.94,39.04", "9,40,39.04,0", "x,1,2,0", "9,7.94,39.04,95"):
        with pytest.raises(ParameterError, match="bearing-geometry"):
            geometry_from_mm(bad)


def test_kurtogram_bands_and_spectral_kurtosis():
    assert kurtogram_bands(2) == [(0.0, 0.25), (0.25, 0.5), (0.0, 0.125), (0.125, 0.25), (0.25, 0.375),
                                  (0.375, 0.5)]
    rng = np.random.default_rng(3)
    gauss = spectral_kurtosis(rng.standard_normal((20, 8192)), (0.1, 0.2))
    assert abs(gauss.mean()) < 0.1  # complex Gaussian envelope: SK = 0 (Antoni 2007)
    f = BearingEnvelopeFeatures(shaft_frequency=FR, fs=FS).defect_frequencies_cps()
    assert spectral_kurtosis(impacts(f["bpfo"] * FS)[None], (0.2, 0.3))[0] > 2.0


def test_parameter_errors_and_clone():
    X = np.random.default_rng(0).standard_normal((2, 2048))
    with pytest.raises(ParameterError, match="Nyquist"):
        BearingEnvelopeFeatures(shaft_frequency=2000.0, fs=FS).fit(X)
    with pytest.raises(ParameterError, match="fewer than 2 periods"):
        BearingEnvelopeFeatures(shaft_frequency=FR, fs=FS).fit(X[:, :64])
    with pytest.raises(ParameterError, match="levels"):
        BearingEnvelopeFeatures(levels=9).fit(X)
    t = clone(BearingEnvelopeFeatures(harmonics=2))
    assert t.get_params()["harmonics"] == 2 and t.fit(X).transform(X).shape == (2, 6)


@needs_real_data("cwru-bearing/IR007_0.mat", "cwru-bearing/OR007@6_0.mat")
def test_cwru_inner_and_outer_race_files():
    from rvdiag.io import read_signal, window

    out = {}
    for name in ("IR007_0.mat", "OR007@6_0.mat"):
        sig = read_signal(DATA / "cwru-bearing" / name, "DE_time", fs=FS)
        X = window(sig, 2048)[:10]
        t = BearingEnvelopeFeatures(shaft_frequency=sig.scalar("RPM") / 60.0, fs=FS).fit(X)
        out[name] = t.transform(X)[:, 3:]
    assert np.all(np.argmax(out["IR007_0.mat"], axis=1) == 1)
    assert np.all(np.argmax(out["OR007@6_0.mat"], axis=1) == 0)
