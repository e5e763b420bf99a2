"""scikit-learn's estimator checks over every registered estimator and transformer of rvdiag.

Registered: every feature set of :func:`rvdiag.models.pipelines.feature_names` (the signal feature sets of
:mod:`rvdiag.features` and the ``cnn`` features), the other public transformers of :mod:`rvdiag.features`, and
every classifier behind ``rvdiag train --model`` that rvdiag implements (KELM, tuned KELM, the CNN).  The SVM
is scikit-learn's own.  Slow estimators get tiny settings (a 1-epoch network, a 2-member EEMD ensemble).
A check that cannot apply is listed in EXPECTED with the reason; no estimator is skipped as a whole.
"""

import numpy as np
import pytest
from sklearn.utils.estimator_checks import parametrize_with_checks

from rvdiag.features import (
    CharacteristicBandEnergy,
    CombinedFeatures,
    EnvelopeSpectrumFeatures,
    SpectrumFeatures,
    TimeDomainFeatures,
    feature_names as signal_feature_names,
    make_features,
)
from rvdiag.features.zscore import HealthyBaselineFeatures
from rvdiag.features.bearing import BearingEnvelopeFeatures
from rvdiag.features.current import FundamentalResidual
from rvdiag.features.tsa import TSAIndicatorFeatures
from rvdiag.models.cnn_features import CNNFeatures
from rvdiag.models.kelm import KELMClassifier
from rvdiag.models.pipelines import MODEL_NAMES, feature_names, make_feature_set
from rvdiag.models.torch_estimator import CNNClassifier
from rvdiag.models.tuning import TunedKELM

TINY = {
    "eemd": {"ensemble_size": 2, "n_sifts": 2},
    "cnn": {"max_epochs": 1, "batch_size": 64, "validation_fraction": 0.0, "device": "cpu",
            "architecture": "cnn1d-lean"},
}


def _estimators():
    ests = [make_feature_set(name, **TINY.get(name, {})) for name in feature_names()]
    ests += [CharacteristicBandEnergy(), EnvelopeSpectrumFeatures(centers=(0.1,)), BearingEnvelopeFeatures(),
             BearingEnvelopeFeatures(speed_column="rpm"),
             CombinedFeatures([("time", TimeDomainFeatures()), ("spectrum", SpectrumFeatures(n_bands=2))]),
             HealthyBaselineFeatures(TimeDomainFeatures(), columns=("c",), healthy="0", min_count=2),
             FundamentalResidual()]
    ests += [KELMClassifier(), TunedKELM(epoch=1, pop_size=10, cv=2),
             CNNClassifier(max_epochs=1, batch_size=64, validation_fraction=0.0, device="cpu")]
    return ests


#: The checks that feed windows of 1-10 points (sklearn's test data have 1-10 columns).  A transform that needs
#: longer windows refuses them with a ParameterError, as it should; these checks cannot apply to it.
SHORT_DATA_CHECKS = (
    "check_fit_score_takes_y", "check_estimators_overwrite_params", "check_dont_overwrite_parameters",
    "check_estimators_fit_returns_self", "check_readonly_memmap_input", "check_n_features_in_after_fitting",
    "check_positive_only_tag_during_fit", "check_estimators_dtypes", "check_dtype_object",
    "check_pipeline_consistency", "check_estimators_nan_inf", "check_estimators_pickle",
    "check_estimators_pickle(readonly_memmap=True)", "check_f_contiguous_array_estimator",
    "check_transformer_data_not_an_array", "check_transformer_general", "check_transformer_preserve_dtypes",
    "check_transformer_general(readonly_memmap=True)", "check_methods_sample_order_invariance",
    "check_methods_subset_invariance", "check_fit2d_1sample", "check_dict_unchanged", "check_fit_idempotent",
    "check_fit_check_is_fitted", "check_n_features_in", "check_fit2d_predict1d",
)
_MIN_POINTS = {"EEMDFeatures": "EEMD needs windows of >= 8 points",
               "WaveletPacketEnergy": "a level-4 wavelet packet needs windows of >= 16 points",
               "BearingEnvelopeFeatures": "the kurtogram bands need windows of >= 64 points",
               "TSAIndicatorFeatures": "a TSA needs windows of at least one shaft revolution",
               "OrderSpectrumFeatures": "an order spectrum needs windows of at least one shaft revolution",
               "FundamentalResidual": "the supply-line fit (3 lines of degree 3) needs windows of >= 84 points"}
#: short-data checks that pass all the same (they use >= 8 columns, or only test the error)
_PASS_ANYWAY = {("EEMDFeatures", "check_dtype_object"), ("EEMDFeatures", "check_fit2d_1sample"),
                ("FundamentalResidual", "check_fit2d_1sample")}
EXPECTED: dict[str, dict[str, str]] = {
    name: {check: f"{why}; sklearn's check data have 1-10 points per sample" for check in SHORT_DATA_CHECKS
           if (name, check) not in _PASS_ANYWAY}
    for name, why in _MIN_POINTS.items()
}
_CNN_TRAIN = "a 1-epoch CNN of raw signal windows does not fit 2-4-feature blob data to sklearn's 83 %"
EXPECTED["CNNClassifier"] = {c: _CNN_TRAIN for c in (
    "check_classifiers_train", "check_classifiers_train(readonly_memmap=True)",
    "check_classifiers_train(readonly_memmap=True,X_dtype=float32)")}


#: tsa-ci-z / tsa-mod-z: the TSA's windows, two metadata columns and a healthy class T1 in y
_HEALTHY_TSA = {check: "tsa-ci-z needs windows of a shaft revolution, speed and load columns and T1 in y; sklearn's "
                "check data have 1-10 points and integer labels"
                for check in SHORT_DATA_CHECKS + ("check_fit2d_1feature", "check_fit2d_1sample")}


#: the generic HealthyBaselineFeatures (time features, one metadata column, healthy label 0): these checks fit
#: 2-column data (one point left for the time features) or labels without two 0s
_HEALTHY_GENERIC = {check: "sklearn's check data: 2 columns leave 1 point beside the metadata column, or y holds "
                    "fewer than 2 of the healthy label 0" for check in (
                        "check_estimators_overwrite_params", "check_estimators_fit_returns_self",
                        "check_readonly_memmap_input", "check_estimators_dtypes", "check_estimators_nan_inf",
                        "check_fit_idempotent", "check_fit_check_is_fitted", "check_n_features_in")}


def _expected(est):
    if isinstance(est, HealthyBaselineFeatures):
        return _HEALTHY_TSA if isinstance(est.features, TSAIndicatorFeatures) else _HEALTHY_GENERIC
    return EXPECTED.get(type(est).__name__, {})


@parametrize_with_checks(_estimators(), expected_failed_checks=_expected)
def test_sklearn_estimator_checks(estimator, check):
    check(estimator)


def test_every_registered_name_is_checked():
    """The list above covers the feature registry and the rvdiag classifiers of the model names."""
    assert set(signal_feature_names()) | {"cnn"} == set(feature_names())
    kinds = {type(e).__name__ for e in _estimators()}
    assert {"KELMClassifier", "TunedKELM", "CNNClassifier", "CNNFeatures", "EEMDFeatures"} <= kinds
    assert {m.split("-")[0] for m in MODEL_NAMES} == {"svm", "kelm"}


@pytest.mark.parametrize("est", [TunedKELM(), make_features("eemd"), CNNClassifier(), CNNFeatures()])
def test_estimators_take_random_state_not_seed(est):
    params = est.get_params()
    assert "random_state" in params and "seed" not in params


def test_eemd_features_accept_n_jobs_minus_one():
    X = np.random.default_rng(0).standard_normal((6, 64))
    one = make_features("eemd", ensemble_size=2, n_jobs=1).fit_transform(X)
    np.testing.assert_array_equal(make_features("eemd", ensemble_size=2, n_jobs=-1).fit_transform(X), one)
    np.testing.assert_array_equal(make_features("eemd", ensemble_size=2, n_jobs=None).fit_transform(X), one)
    with pytest.raises(ValueError, match="n_jobs"):
        make_features("eemd", n_jobs=0).fit(X)


def test_models_package_exports():
    import rvdiag.models as models

    assert "make_classical_model" in models.__all__ and "CNNClassifier" in models.__all__
    for name in models.__all__:
        assert getattr(models, name) is not None
