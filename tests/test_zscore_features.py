"""Healthy-baseline z-scores (:mod:`rvdiag.features.zscore`, feature sets ``tsa-ci-z`` / ``tsa-mod-z``): an offset
that depends on the operating point hides a fault from the raw feature and not from the z-scores; thin bins
borrow from their neighbours; the model survives save and load; ``rvdiag train`` takes the name."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rvdiag.errors import ParameterError
from rvdiag.features import make_features
from rvdiag.features.zscore import HealthyBaselineFeatures
from rvdiag.features.timedomain import TimeDomainFeatures
from rvdiag.models.pipelines import load_classical, make_classical_model, save_classical

FS = 48000.0


def _offset_hides_fault(n_per=24, seed=0):
    """Windows whose RMS is speed x load (x 1.25 when faulty): the raw RMS of a faulty window at a low operating
    point is below the healthy RMS at a high one."""
    rng = np.random.default_rng(seed)
    rows, y, speed, load = [], [], [], []
    for s in (20.0, 40.0, 60.0):
        for ld in (1.0, 2.0, 3.0):
            for label, gain in (("T1", 1.0), ("T2", 1.25)):
                for _ in range(n_per):
                    rows.append(gain * s * ld * rng.standard_normal(512))
                    y.append(label)
                    speed.append(s)
                    load.append(ld)
    X = np.column_stack([np.asarray(rows), speed, load])
    return X, np.asarray(y), np.asarray(speed), np.asarray(load)


def _best_threshold_accuracy(f, y):
    """The best accuracy of one threshold on one feature (either direction)."""
    t = np.sort(f)
    acc = [max(np.mean((f > v) == (y == "T2")), np.mean((f <= v) == (y == "T2"))) for v in t]
    return max(acc)


def test_z_scores_reveal_a_fault_that_an_operating_point_offset_hides():
    X, y, _, _ = _offset_hides_fault()
    rms = TimeDomainFeatures().fit(X[:, :-2]).transform(X[:, :-2])[:, list(TimeDomainFeatures().fit(X[:, :8])
                                                                         .get_feature_names_out()).index("rms")]
    assert _best_threshold_accuracy(rms, y) < 0.75  # the offset hides it
    tr = HealthyBaselineFeatures(TimeDomainFeatures(), columns=("speed", "load"), n_bins=3, min_count=10)
    Z = tr.fit_transform(X, y)
    names = list(tr.get_feature_names_out())
    z = Z[:, names.index("rms_z")]
    assert _best_threshold_accuracy(z, y) > 0.98
    assert tr.count_.shape == (3, 3) and np.all(tr.count_ == 24)  # one healthy cell per operating point
    # the healthy samples are z-scores of themselves: mean 0, std 1 in every cell
    np.testing.assert_allclose(z[y == "T1"].mean(), 0.0, atol=1e-12)
    np.testing.assert_allclose(tr.transform(X), Z)
    assert tr.input_metadata() == ("speed", "load")


def test_thin_bins_borrow_from_their_neighbours_and_out_of_range_values_clip():
    X, y, speed, load = _offset_hides_fault(n_per=6)
    tr = HealthyBaselineFeatures(TimeDomainFeatures(), columns=("speed", "load"), n_bins=3, min_count=10).fit(X, y)
    # 6 healthy windows per cell < 10: each cell pools its 3x3 neighbourhood (4, 6 or 9 cells)
    assert sorted(set(tr.count_.ravel().tolist())) == [24, 36, 54]
    assert tr.count_[1, 1] == 54 and tr.count_[0, 0] == 24
    far = X[:2].copy()
    far[:, -2:] = [[1000.0, -5.0], [-3.0, 99.0]]  # outside the training range: the edge cells
    assert np.all(np.isfinite(tr.transform(far)))


def test_refusals():
    X, y, _, _ = _offset_hides_fault(n_per=4)
    tr = HealthyBaselineFeatures(TimeDomainFeatures(), columns=("speed", "load"), min_count=10)
    with pytest.raises(ParameterError, match="labels"):
        tr.fit(X)
    with pytest.raises(ParameterError, match="healthy"):
        HealthyBaselineFeatures(TimeDomainFeatures(), columns=("speed", "load"), healthy="H").fit(X, y)
    with pytest.raises(ParameterError, match="metadata"):
        HealthyBaselineFeatures(TimeDomainFeatures(), columns=("speed", "load"), min_count=10).fit(X[:, :1], y)
    with pytest.raises(ParameterError, match="n_bins"):
        HealthyBaselineFeatures(TimeDomainFeatures(), columns=("speed", "load"), n_bins=0).fit(X, y)
    with pytest.raises(ParameterError, match="columns"):
        HealthyBaselineFeatures(TimeDomainFeatures(), columns=()).fit(X, y)


def _tsa_windows(n=60, seed=1):
    """Mesh tones at 30-60 deg/s, impulses once per sun revolution in the faulty ones; speed and load columns."""
    from rvdiag.features import orders as o

    rng = np.random.default_rng(seed)
    t = np.arange(8192) / FS
    rows, y, sp, ld = [], [], [], []
    for i in range(n):
        s, L = rng.uniform(30.0, 60.0), rng.uniform(40.0, 140.0)
        f = o.shaft_frequency("sun", output_speed_deg_s=s)
        x = (1 + L / 100) * np.cos(2 * np.pi * 11 * f * t) + 0.05 * rng.standard_normal(t.size)
        if i % 2:
            x = x + 3.0 * (np.sin(np.pi * f * t) ** 200)
        rows.append(x)
        y.append("T2" if i % 2 else "T1")
        sp.append(s)
        ld.append(L)
    return np.column_stack([np.asarray(rows), sp, ld]), np.asarray(y)


def test_tsa_ci_z_is_registered_and_survives_save_and_load(tmp_path):
    X, y = _tsa_windows()
    f = make_features("tsa-ci-z", fs=FS, speed_column="output_speed_deg_s", min_count=8)
    assert f.input_metadata() == ("output_speed_deg_s", "load_Nm")
    p = make_classical_model("svm", "tsa-ci-z", features_kw={"fs": FS, "speed_column": "output_speed_deg_s",
                                                            "min_count": 8}).fit(X, y)
    assert p.score(X, y) > 0.9
    save_classical(p, tmp_path / "m")
    q = load_classical(tmp_path / "m")  # a fresh type must be on the trusted list
    np.testing.assert_array_equal(q.predict(X), p.predict(X))
    np.testing.assert_allclose(q.steps[0][1].mean_, p.steps[0][1].mean_)
    assert list(q.steps[0][1].get_feature_names_out())[1] == "log10_fm4_z"
    g = make_features("tsa-mod-z", fs=FS, speed_column="window_speed_deg_s")
    assert g.columns == ("window_speed_deg_s", "load_Nm") and g.features.modulation


def test_rvdiag_train_takes_tsa_ci_z(tmp_path, capsys):
    """``rvdiag train --features tsa-ci-z`` on a store with speed and load columns; ``evaluate`` supplies both."""
    from conftest import run_cli

    from rvdiag.datasets.store import write_store

    X, y = _tsa_windows(n=48)
    store = tmp_path / "s.zarr"
    split = np.where(np.arange(len(y)) < 36, "train", "test")
    write_store(store, X[:, :-2].astype(np.float32), y.tolist(), kind="library", fs=FS, config={},
                meta={"split": split.tolist(), "unit": list(range(len(y))), "output_speed_deg_s": X[:, -2].tolist(),
                      "load_Nm": X[:, -1].tolist()})
    code, _, err = run_cli(["train", store, "--model", "svm", "--features", "tsa-ci-z", "-o", tmp_path / "m", "-q"],
                           capsys)
    assert code == 0, err
    card = json.loads((tmp_path / "m" / "card.json").read_text())
    assert card["metadata_columns"] == ["output_speed_deg_s", "load_Nm"] and card["features"] == "tsa-ci-z"
    code, out, err = run_cli(["evaluate", tmp_path / "m", store, "--json", "-q"], capsys)
    assert code == 0, err
    assert json.loads(out)["n_samples"] == 12


def test_a_model_saved_before_the_move_to_zscore_still_loads(tmp_path):
    """features/baseline.py became features/zscore.py: a model.skops written before names the old module, and
    loads through rvdiag.registry.MOVED_TYPES (not through the deprecated alias left at the old path)."""
    import warnings

    import skops.io as sio
    from conftest import as_saved_before_a_move

    from rvdiag.registry import MOVED_TYPES, TRUSTED_TYPES

    X, y = _tsa_windows()
    p = make_classical_model("svm", "tsa-ci-z", features_kw={"fs": FS, "speed_column": "output_speed_deg_s",
                                                            "min_count": 8}).fit(X, y)
    save_classical(p, tmp_path / "m")
    as_saved_before_a_move(tmp_path / "m", "rvdiag.features.zscore", "rvdiag.features.baseline")
    old = "rvdiag.features.baseline.HealthyBaselineFeatures"
    assert old in sio.get_untrusted_types(data=(tmp_path / "m" / "model.skops").read_bytes())
    assert old not in TRUSTED_TYPES
    assert MOVED_TYPES[old] in TRUSTED_TYPES
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        q = load_classical(tmp_path / "m")
    assert not [w for w in rec if "rvdiag.features.baseline" in str(w.message)]
    assert type(q.steps[0][1]) is HealthyBaselineFeatures
    np.testing.assert_array_equal(q.predict(X), p.predict(X))
