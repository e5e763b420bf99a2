"""Representations of a motor current for learned features: the fitted supply line removed
(:func:`rvdiag.features.current.fundamental_residual`), the log spectrum (:func:`rvdiag.features.spectrum.log_spectrum`),
the CNN features that take them, and the defaults of ``rvdiag mcsa`` and ``rvdiag train`` on a current store."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from rvdiag.errors import ParameterError
from rvdiag.features.current import FundamentalResidual, electrical_frequency, fundamental_residual
from rvdiag.features.spectrum import log_spectrum
from rvdiag.spectral import amplitude_spectrum

N = 4096
FE = 0.04137  # cycles/sample: 169.4 bins, between two bins
F1 = FE / 4  # a 4-pole-pair motor: the sun (input) shaft at f_e / p
A, SB = 5.0, 0.01  # supply line and sideband amplitudes (-54 dB)


def _current(am: float = 0.0) -> np.ndarray:
    """A supply line (with ``am`` slow amplitude modulation: 0.4 of a cycle per window, as the arm's load) and
    two sidebands f_e +- f1; also the sidebands alone."""
    n = np.arange(N)
    sidebands = SB * np.cos(2 * np.pi * (FE - F1) * n) + SB * np.cos(2 * np.pi * (FE + F1) * n + 1.0)
    line = A * (1.0 + am * np.sin(2 * np.pi * 0.4 * n / N + 0.3)) * np.sin(2 * np.pi * FE * n + 0.4)
    return line + sidebands, sidebands


def _line(x: np.ndarray, f0: float) -> float:
    f, amp = amplitude_spectrum(x)
    k = int(round(f0 * N))
    return float(amp[k - 2:k + 3].max())


@pytest.mark.parametrize("am, fundamental_left", [(0.0, 1e-4), (0.2, 2e-3)])
def test_the_fitted_supply_line_goes_and_the_sidebands_stay(am, fundamental_left):
    x, sidebands = _current(am)
    r, fe = fundamental_residual(x[None], return_frequency=True)
    assert abs(fe[0] - FE) * N < 0.02  # the window's own electrical frequency, to 1/50 of a bin
    # the supply line: 5 A -> below 1e-4 of it (constant amplitude; measured 1.4e-5), below 2e-3 of it with 20 %
    # load modulation (measured 8.7e-4)
    assert _line(r[0], FE) < fundamental_left * A
    for f0 in (FE - F1, FE + F1):  # the sidebands as they are without the line, to 1 %
        assert _line(r[0], f0) == pytest.approx(_line(sidebands, f0), rel=0.01)
    assert _line(x, FE) > 0.8 * A  # (the line was there; Hann scalloping between bins)


def test_a_plain_sine_fit_leaves_the_load_modulation_the_polynomial_one_removes():
    x, _ = _current(0.2)
    plain = fundamental_residual(x[None], degree=0)[0]  # IEEE 1057 three-parameter fit
    assert _line(plain, FE) > 0.02 * A > 10 * _line(fundamental_residual(x[None])[0], FE)


def test_the_residual_scales_with_the_gain_and_the_transformer_keeps_the_shape():
    x, _ = _current(0.1)
    X = np.stack([x, 3.0 * x, np.roll(x, 100)])
    r = FundamentalResidual().fit(X).transform(X)
    assert r.shape == X.shape
    np.testing.assert_allclose(r[1], 3.0 * r[0], atol=1e-9 * A)
    assert electrical_frequency(x) == pytest.approx(FE, abs=0.02 / N)


@pytest.mark.parametrize("kw, message", [({"harmonics": (0,)}, "harmonics must be"), ({"degree": -1}, "degree"),
                                         ({"degree": 9}, "degree")])
def test_bad_settings_are_refused(kw, message):
    with pytest.raises(ParameterError, match=message):
        fundamental_residual(_current()[0][None], **kw)
    with pytest.raises(ParameterError, match="too short"):
        fundamental_residual(np.ones((1, 20)), degree=3)


def test_log_spectrum_shape_gain_invariance_and_its_peak():
    x = _current()[0] + 1e-3 * np.random.default_rng(0).standard_normal(N)  # a sensor's noise floor
    X = np.stack([x, 1e3 * x, 1e-3 * x])
    S = log_spectrum(X)
    assert S.shape == (3, N // 2 + 1) and S.dtype == np.float32
    # a gain adds log g to every bin, which the row mean removes
    np.testing.assert_allclose(S[1], S[0], atol=1e-4)
    np.testing.assert_allclose(S[2], S[0], atol=1e-4)
    np.testing.assert_allclose(S.mean(axis=1), 0.0, atol=1e-4)
    assert abs(int(np.argmax(S[0])) - FE * N) < 1.0
    for f0 in (FE - F1, FE + F1):  # the -54 dB sidebands stand out of the floor in the log spectrum
        k = int(round(f0 * N))
        assert S[0, k - 2:k + 3].max() > np.median(S[0]) + 3.0


def _tiny_current_set(seed=0, n_per_class=12, length=512):
    """Two classes of 'current': the same supply line with random load, class 1 with f1 sidebands."""
    rng = np.random.default_rng(seed)
    n = np.arange(length)
    X, y = [], []
    for c in (0, 1):
        for _ in range(n_per_class):
            fe = rng.uniform(0.05, 0.06)
            x = rng.uniform(2, 6) * np.sin(2 * np.pi * fe * n + rng.uniform(0, 6))
            if c:
                x += 0.05 * np.cos(2 * np.pi * fe * 0.75 * n) + 0.05 * np.cos(2 * np.pi * fe * 1.25 * n)
            X.append(x + 0.002 * rng.standard_normal(length))
            y.append(f"T{c + 1}")
    return np.asarray(X, np.float32), np.asarray(y)


@pytest.mark.parametrize("representation", ["logspec", "residual"])
def test_cnn_features_take_the_representation_and_survive_a_round_trip(representation):
    from rvdiag.models.cnn_features import CNNFeatures

    X, y = _tiny_current_set()
    est = CNNFeatures(architecture="cnn1d-lean", representation=representation, max_epochs=2, batch_size=8,
                      device="cpu", random_state=0).fit(X, y)
    assert est._clf.representation == representation
    F = est.transform(X)
    restored = pickle.loads(pickle.dumps(est))  # rebuilt from weights_ with the representation's input length
    assert "_clf" not in restored.__dict__
    np.testing.assert_allclose(restored.transform(X), F, rtol=1e-5, atol=1e-6)
    with pytest.raises(ParameterError, match="representation must be one of"):
        CNNFeatures(representation="orders").fit(X, y)


def test_the_defaults_on_a_current_store_are_the_log_spectrum():
    from rvdiag.workflows.training import features_kw
    from rvdiag.evaluation.motor_current_study import McsaSettings
    from rvdiag.models.cnn_features import CNNFeatures, default_representation

    assert McsaSettings().cnn_representation == default_representation("current") == "logspec"
    kw = dict(epochs=1, device="cpu", seed=0, lr=1e-3, batch_size=8, bearing_geometry=None, rpm_column="rpm",
              fs=1000.0)
    assert features_kw("cnn", signal="current", **kw)["representation"] == "logspec"
    # vibration keeps the waveform the CNN features always took there
    assert features_kw("cnn", **kw)["representation"] == "waveform" == CNNFeatures().representation


@pytest.mark.parametrize("signal, representation", [("current", "logspec"), ("vibration", "waveform")])
def test_train_cnn_features_on_a_current_store_take_the_log_spectrum(tmp_path, capsys, signal, representation):
    from conftest import run_cli
    from rvdiag.datasets import write_store
    from rvdiag.models.cnn_features import CNNFeatures
    from rvdiag.models.persistence import load_model

    X, y = _tiny_current_set(n_per_class=8, length=256)
    split = ["train" if k % 4 else "test" for k in range(len(y))]
    store = write_store(tmp_path / "s.zarr", X, y.tolist(), meta={"split": split, "unit": list(range(len(y)))},
                        kind="simulated", fs=1000.0,
                        config={"name": "tiny", "channel": "i_a", "model": {"signal": signal}})
    code, _, err = run_cli(["train", store, "-o", tmp_path / "m", "--model", "svm", "--features", "cnn",
                            "--epochs", "1", "--device", "cpu", "-q"], capsys)
    assert code == 0, err
    est = load_model(tmp_path / "m").estimator
    found = [v for v in est.get_params(deep=True).values() if isinstance(v, CNNFeatures)]
    assert found and {f.representation for f in found} == {representation}
