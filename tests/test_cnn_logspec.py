"""The log-spectrum input representation of the CNNs (``representation="logspec"``)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import periodogram

from rvdiag.errors import ParameterError
from rvdiag.models.persistence import load_model, read_card, save_model
from rvdiag.models.torch_estimator import CNNClassifier, log_spectrum, network_length


def test_log_spectrum_matches_scipy_periodogram():
    """Independent check: scipy's periodogram with the same (symmetric) Hann window is |FFT|^2 times constants (doubled inside the band), so
    its log square root equals ours up to one constant on the interior bins."""
    rng = np.random.default_rng(0)
    x = rng.standard_normal((3, 512)) + 5.0
    ours = log_spectrum(x)
    _, p = periodogram(x, window=np.hanning(512), detrend="constant", scaling="spectrum", axis=1)
    ref = 0.5 * np.log(p[:, 1:-1])
    diff = ours[:, 1:-1] - ref
    assert ours.shape == (3, 257) and ours.dtype == np.float32
    np.testing.assert_allclose(diff - diff.mean(axis=1, keepdims=True), 0.0, atol=1e-4)


def test_log_spectrum_is_level_and_offset_free():
    rng = np.random.default_rng(1)
    x = rng.standard_normal((2, 256))
    np.testing.assert_allclose(log_spectrum(1e-3 * x + 7.0), log_spectrum(x), atol=1e-4)
    np.testing.assert_allclose(log_spectrum(x).mean(axis=1), 0.0, atol=1e-5)


def _weak_tone_data(n=24, L=256, seed=0):
    """Both classes: a strong tone plus noise; class B adds a tone 40 dB weaker (0.01 of the amplitude),
    the kind of sideband a tooth crack adds to the mesh harmonics."""
    rng = np.random.default_rng(seed)
    t = np.arange(L)
    X = np.empty((2 * n, L), dtype=np.float32)
    for i in range(2 * n):
        phase = rng.uniform(0, 2 * np.pi, 2)
        x = np.sin(2 * np.pi * 0.11 * t + phase[0]) + 1e-4 * rng.standard_normal(L)
        if i >= n:
            x += 0.01 * np.sin(2 * np.pi * 0.31 * t + phase[1])
        X[i] = x
    return X, np.array(["A"] * n + ["B"] * n)


def test_logspec_cnn_finds_a_weak_sideband():
    X, y = _weak_tone_data()
    m = CNNClassifier(representation="logspec", max_epochs=15, learning_rate=1e-2, batch_size=16,
                      n_iter_no_change=15, validation_fraction=0.0, device="cpu", random_state=0).fit(X, y)
    Xt, yt = _weak_tone_data(10, seed=5)
    assert np.mean(m.predict(Xt) == yt) >= 0.95
    assert m.net_input_length_ == 256 and network_length(256, "logspec") == 129


def test_logspec_model_round_trip(tmp_path):
    X, y = _weak_tone_data(8)
    m = CNNClassifier(representation="logspec", normalize="global", max_epochs=2, device="cpu",
                      random_state=1).fit(X, y)
    save_model(m, tmp_path / "m", model="cnn1d-lean", fs=1000.0, seed=1)
    card = read_card(tmp_path / "m")
    assert card["params"]["representation"] == "logspec"
    assert card["preprocessing"]["representation"] == "logspec"
    loaded = load_model(tmp_path / "m").estimator
    assert loaded.representation == "logspec"
    np.testing.assert_allclose(loaded.predict_proba(X), m.predict_proba(X), rtol=1e-5, atol=1e-6)


def test_unknown_representation_is_refused():
    X, y = _weak_tone_data(4)
    with pytest.raises(ParameterError, match="representation"):
        CNNClassifier(representation="mel", max_epochs=1).fit(X, y)
