"""Feature extractors: scikit-learn transformers from signal windows (n_samples, n_points) to features.

================  ===========================================================  ===================================
name              transformer                                                  source
================  ===========================================================  ===================================
time              :class:`TimeDomainFeatures` (10 statistics)                  Li, Zhao et al. 2024
spectrum          :class:`SpectrumFeatures` (64 log relative
                  FFT band powers)
spectrum-abs      :class:`SpectrumFeatures` (64 log absolute
                  FFT band powers: keeps the level)
logspec           :class:`SpectrumFeatures` (every FFT bin, log                the input of the ``logspec`` CNNs
                  of the relative magnitude)
envelope          :class:`EnvelopeSpectrumFeatures` (squared-                  Randall & Antoni 2011
                  envelope spectrum, 40 bands)
bearing-envelope  :class:`~rvdiag.features.bearing.BearingEnvelopeFeatures`    Randall & Antoni 2011
                  (envelope lines at BPFO, BPFI, 2 BSF)
wpd               :class:`WaveletPacketEnergy` (16 bands)                      Li, Zhao et al. 2024
eemd              :class:`EEMDFeatures` (mean ``|IMF|`` x 6)                   Tu et al. 2023
tsa-ci            :class:`~rvdiag.features.tsa.TSAIndicatorFeatures`           Decker 2002; Lebold et al. 2000
                  (FM0, FM4, NA4, NB4, M6A, M8A... of the TSA)
tsa-mod           the same with ``modulation=True``: + sideband                Randall 1982; McFadden & Smith 1985;
                  asymmetry, phase modulation of the mesh                      McFadden 1986
tsa-ci-z          :class:`~rvdiag.features.zscore.HealthyBaselineFeatures`     Dempsey & Zakrajsek 2001
                  of ``tsa-ci``: z-scores against the healthy                  (load-normalised NA4*)
                  training samples of the same speed and load
                  bin (``tsa-mod-z``: of ``tsa-mod``)
orders            :class:`~rvdiag.features.tsa.OrderSpectrumFeatures`          Fyfe & Munck 1997 (computed order
                  (order-spectrum bands, envelope fault orders)                tracking); docs/orders.md
none              :class:`RawSignal` (the samples themselves)
================  ===========================================================  ===================================

Names joined by ``+`` (``spectrum-abs+bearing-envelope``) put feature sets side by side
(:class:`~rvdiag.features.combine.CombinedFeatures`, built by :func:`rvdiag.models.pipelines.make_feature_set`).
Also :class:`CharacteristicBandEnergy` (bands at the reducer's characteristic frequencies) and
:class:`~rvdiag.features.relative.BaselineReferencedFeatures` (what changed in a window since its reducer's own
baseline windows: docs/monitoring.md), and the input representations of a learned feature extractor:
:class:`~rvdiag.features.current.FundamentalResidual` (a motor current with its fitted supply line removed) and
:func:`~rvdiag.features.spectrum.log_spectrum` (the level-free log spectrum).  Extensions add
names with :func:`register_features`.  The learned ``cnn`` feature set trains a network, so it lives in the models layer
(:class:`rvdiag.models.cnn_features.CNNFeatures`, named by :func:`rvdiag.models.pipelines.feature_names`);
this package never imports torch.
"""

from __future__ import annotations

from typing import Callable

from rvdiag.errors import ParameterError
from rvdiag.features._base import SignalTransformer, as_signal_matrix
from rvdiag.features.zscore import HealthyBaselineFeatures, healthy_modulation_features, healthy_tsa_features
from rvdiag.features.bearing import BearingEnvelopeFeatures
from rvdiag.features.combine import CombinedFeatures, input_metadata, with_metadata
from rvdiag.features.current import FundamentalResidual, fundamental_residual
from rvdiag.features.eemd import EEMDFeatures, eemd, emd
from rvdiag.features.relative import BaselineReferencedFeatures, relative_features, tsa_change_features
from rvdiag.features.spectrum import (
    CharacteristicBandEnergy,
    EnvelopeSpectrumFeatures,
    SpectrumFeatures,
    bearing_defect_frequencies,
)
from rvdiag.features.tsa import OrderSpectrumFeatures, TSAIndicatorFeatures
from rvdiag.features.timedomain import TIME_FEATURE_NAMES, TimeDomainFeatures, time_features
from rvdiag.features.wavelet import WaveletPacketEnergy


class RawSignal(SignalTransformer):
    """Identity transformer: the window's samples are the features (feature set ``none``)."""

    def _features(self, X):
        return X.copy()

    def _feature_names(self):
        return [f"x{i}" for i in range(self.n_features_in_)]


def log_spectrum_features(**kw) -> SpectrumFeatures:
    """Every bin of the one-sided spectrum, log10 of the magnitude relative to the window's total: the
    sidebands a tooth fault adds to the mesh harmonics keep their weight (docs/results.md)."""
    return SpectrumFeatures(**{"n_bands": None, "log": True, "relative": True, **kw})


def absolute_spectrum_features(**kw) -> SpectrumFeatures:
    """64 log10 band powers of the spectrum, not divided by the window's total: the level is kept (on the CWRU
    bearings, the severity and the load change it; docs/real-data.md)."""
    return SpectrumFeatures(**{"relative": False, **kw})


def modulation_indicator_features(**kw) -> TSAIndicatorFeatures:
    """The nine TSA indicators and the four modulation indicators of :mod:`rvdiag.features.planetary` (feature
    set ``tsa-mod``)."""
    return TSAIndicatorFeatures(**{"modulation": True, **kw})


_REGISTRY: dict[str, Callable[..., object]] = {
    "time": TimeDomainFeatures,
    "spectrum": SpectrumFeatures,
    "spectrum-abs": absolute_spectrum_features,
    "logspec": log_spectrum_features,
    "envelope": EnvelopeSpectrumFeatures,
    "bearing-envelope": BearingEnvelopeFeatures,
    "wpd": WaveletPacketEnergy,
    "eemd": EEMDFeatures,
    "none": RawSignal,
    "tsa-ci": TSAIndicatorFeatures,
    "tsa-mod": modulation_indicator_features,
    "tsa-ci-z": healthy_tsa_features,
    "tsa-mod-z": healthy_modulation_features,
    "orders": OrderSpectrumFeatures,
}


def register_features(name: str, factory: Callable[..., object]) -> None:
    """Add a feature-set name for :func:`make_features` (``factory(**kw)`` returns a transformer)."""
    _REGISTRY[name] = factory


def feature_names() -> list[str]:
    """Names :func:`make_features` knows (the signal feature sets; the models layer adds ``cnn``)."""
    return sorted(_REGISTRY)


def make_features(name: str, **kw):
    """A new, unfitted feature transformer by name (:func:`feature_names`).

    Keyword arguments go to the transformer's constructor.
    """
    names = feature_names()
    if name not in _REGISTRY:
        raise ParameterError(f"unknown feature set {name!r}; use one of {'|'.join(names)}")
    try:
        return _REGISTRY[name](**kw)
    except TypeError as exc:
        raise ParameterError(f"bad options for feature set {name!r}: {exc}") from None


__all__ = [
    "BaselineReferencedFeatures", "relative_features", "tsa_change_features",
    "BearingEnvelopeFeatures", "CharacteristicBandEnergy", "HealthyBaselineFeatures", "CombinedFeatures", "EEMDFeatures",
    "EnvelopeSpectrumFeatures", "FundamentalResidual", "OrderSpectrumFeatures", "RawSignal", "SignalTransformer", "SpectrumFeatures", "TIME_FEATURE_NAMES",
    "TSAIndicatorFeatures", "TimeDomainFeatures", "WaveletPacketEnergy", "absolute_spectrum_features", "as_signal_matrix",
    "modulation_indicator_features",
    "healthy_modulation_features", "healthy_tsa_features",
    "bearing_defect_frequencies", "eemd", "emd", "feature_names", "fundamental_residual", "input_metadata", "log_spectrum_features",
    "make_features", "register_features", "time_features", "with_metadata",
]
