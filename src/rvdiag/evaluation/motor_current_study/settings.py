"""The motor-current study's settings and names: the feature sets, protocols and metrics a run may use, and
:class:`McsaSettings`, every setting of one run (recorded in ``mcsa.json``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.models.cnn_features import CNN_FEATURE_REPRESENTATIONS, default_representation
from rvdiag.validation import finite_number

FORMAT = "rvdiag-mcsa/1"

#: Feature-set name -> what the report calls it.
FEATURE_SETS = {
    "time": "time-domain statistics (10)",
    "wpt": "wavelet-packet energies (level 4)",
    "cnn": "CNN features (spectrum-cnn FC 32)",
}

#: The figures of the study on measured motor current (4 states), for comparison (docs/references.md).
STUDY_FIGURES = {"time": "<= 83.75 %", "wpt": "> 82.5 %", "cnn": "> 96 %"}

#: The metrics averaged over repeats (keys of :func:`classification_metrics`).
METRICS = ("accuracy", "precision_macro", "recall_macro", "f1_macro", "kappa")

#: Protocol name -> how it splits the windows at each speed (:func:`protocol_splits`).
PROTOCOLS = {
    "windows": "random stratified window splits over every window of the store",
    "study": "one simulated reducer per state (its own specimen), its windows split at random",
    "held-out": "several reducers per state; the test side holds only reducers the fit never saw",
    "both": "the study's protocol and the held-out one, side by side",
}

#: How each protocol that runs draws a split (recorded in mcsa.json).
PROTOCOL_SPLITS = {
    "windows": "stratified random window splits over all windows",
    "study": "per state one simulation drawn with default_rng(split seed), its windows split stratified at random",
    "held-out": "per state round(test_size x its simulations) drawn with default_rng(split seed) to the test side "
                "with all their windows",
}

#: The result key of each protocol that :func:`protocol_splits` runs.
PROTOCOL_KEYS = {"windows": "split", "study": "study", "held-out": "held_out_reducers"}

#: What the CNN of the ``cnn`` set may see of each window (:class:`rvdiag.models.cnn_features.CNNFeatures`):
#: ``waveform`` the z-scored window (the study's input), ``logspec`` its log spectrum, ``residual`` the window
#: minus its fitted supply line (:func:`rvdiag.features.current.fundamental_residual`).
CNN_REPRESENTATIONS = CNN_FEATURE_REPRESENTATIONS

#: The default: the feature CNN's on motor current (:data:`rvdiag.models.cnn_features.DEFAULT_REPRESENTATION`),
#: the one that finds what the spectrum finds on unseen simulations (docs/results.md, "Motor current"); the
#: study's raw waveform stays at chance there.
DEFAULT_CNN_REPRESENTATION = default_representation("current")

#: The channel the command picks when the store has it: the motor's phase current.
DEFAULT_CHANNEL = "i_a"


@dataclass
class McsaSettings:
    """Every setting of one run (recorded in ``mcsa.json``).

    Attributes
    ----------
    feature_sets : names of :data:`FEATURE_SETS`, in the order run
    repeats : random splits per speed and feature set
    test_size : share of each class on the test side of a split
    seed : the seed every split seed (and CNN seed) derives from (:func:`split_seeds`)
    speed_column : metadata column grouping the samples by operating speed
    channel : the channel asked for (a name or regular expression; None = ``i_a`` if present, else the first)
    svm_c, svm_gamma : the RBF SVC's ``C`` and ``gamma`` (the same for every feature set)
    wavelet, wpt_level : the wavelet-packet decomposition
    cnn_epochs, cnn_batch_size, cnn_lr, cnn_patience, cnn_validation_fraction, cnn_input_length, device :
        the CNN's training (:class:`rvdiag.models.cnn_features.CNNFeatures`)
    cnn_representation : what the CNN sees of each window (:data:`CNN_REPRESENTATIONS`; default
        :data:`DEFAULT_CNN_REPRESENTATION`)
    tsne_samples : at most this many test samples per speed in each t-SNE panel
    protocol : how the windows are split (:data:`PROTOCOLS`): ``windows`` (random splits over all windows),
        ``study`` (one reducer per state, its windows split at random), ``held-out`` (unseen reducers tested)
        or ``both`` (study and held-out side by side)
    """

    feature_sets: tuple[str, ...] = ("time", "wpt", "cnn")
    repeats: int = 10
    test_size: float = 0.3
    seed: int = 0
    speed_column: str = "output_speed_deg_s"
    channel: str | None = None
    svm_c: float = 10.0
    svm_gamma: str = "scale"
    wavelet: str = "db4"
    wpt_level: int = 4
    cnn_epochs: int = 30
    cnn_batch_size: int = 32
    cnn_lr: float = 1e-3
    cnn_patience: int = 5
    cnn_validation_fraction: float = 0.2
    cnn_input_length: int | None = None
    cnn_representation: str = DEFAULT_CNN_REPRESENTATION
    device: str = "auto"
    tsne_samples: int = 600
    protocol: str = "windows"

    def check(self) -> None:
        """Raise :class:`ParameterError` for a setting out of range (names as the Python fields)."""
        unknown = [s for s in self.feature_sets if s not in FEATURE_SETS]
        if unknown or not self.feature_sets:
            raise ParameterError(f"unknown feature set {', '.join(map(repr, unknown)) or '(none given)'}; "
                                 f"use one or more of {','.join(FEATURE_SETS)}")
        if len(set(self.feature_sets)) != len(self.feature_sets):
            raise ParameterError(f"feature_sets names a set twice: {','.join(self.feature_sets)}")
        if not (isinstance(self.seed, (int, np.integer)) and self.seed >= 0):
            raise ParameterError(f"seed must be a whole number >= 0, got {self.seed}")
        if not (isinstance(self.repeats, (int, np.integer)) and self.repeats >= 1):
            raise ParameterError(f"repeats must be a whole number >= 1, got {self.repeats}")
        if not (isinstance(self.test_size, (int, float)) and 0.0 < float(self.test_size) < 1.0):
            raise ParameterError(f"test_size must be a fraction in (0, 1), got {self.test_size}")
        finite_number(self.svm_c, "svm_c", 0, strict=True, noun="a number")
        if self.cnn_epochs < 1:
            raise ParameterError(f"cnn_epochs must be >= 1, got {self.cnn_epochs}")
        if self.cnn_batch_size < 1:
            raise ParameterError(f"cnn_batch_size must be >= 1, got {self.cnn_batch_size}")
        finite_number(self.cnn_lr, "cnn_lr", 0, strict=True, noun="a number")
        if self.cnn_patience < 1:
            raise ParameterError(f"cnn_patience must be >= 1, got {self.cnn_patience}")
        if not 0.0 <= self.cnn_validation_fraction < 1.0:
            raise ParameterError(f"cnn_validation_fraction must be in [0, 1), got {self.cnn_validation_fraction}")
        if self.cnn_representation not in CNN_REPRESENTATIONS:
            raise ParameterError(f"cnn_representation must be one of {', '.join(CNN_REPRESENTATIONS)}, "
                                 f"got {self.cnn_representation!r}")
        if self.cnn_input_length is not None and self.cnn_input_length < 4:
            raise ParameterError(f"cnn_input_length must be >= 4, got {self.cnn_input_length}")
        if self.protocol not in PROTOCOLS:
            raise ParameterError(f"protocol must be one of {' | '.join(PROTOCOLS)}, got {self.protocol!r}")
        if self.tsne_samples < 0:
            raise ParameterError(f"tsne_samples must be >= 0, got {self.tsne_samples}")
        import pywt

        if self.wavelet not in pywt.wavelist(kind="discrete"):
            raise ParameterError(f"unknown discrete wavelet {self.wavelet!r}")
        if not 1 <= self.wpt_level <= 10:
            raise ParameterError(f"wpt_level must be in 1..10, got {self.wpt_level}")


def parse_feature_sets(text: str) -> tuple[str, ...]:
    """``"time,wpt"`` -> ``("time", "wpt")``; unknown names raise :class:`ParameterError`."""
    names = tuple(s.strip() for s in str(text).split(",") if s.strip())
    unknown = [s for s in names if s not in FEATURE_SETS]
    if unknown or not names:
        raise ParameterError(f"unknown feature set {', '.join(map(repr, unknown)) or '(none given)'}; "
                             f"use one or more of {','.join(FEATURE_SETS)}, comma-separated")
    return names


def split_seeds(seed: int, repeats: int) -> list[int]:
    """One seed per repeat, derived from ``seed`` (``numpy.random.SeedSequence(seed).generate_state``, reduced to
    31 bits): repeat ``r`` splits with ``split_seeds(seed, n)[r]`` and trains its CNN and SVM with it; the held-out
    fit uses the first.

    >>> split_seeds(0, 3) == split_seeds(0, 3) != split_seeds(1, 3)
    True
    """
    return [int(s) % 2**31 for s in np.random.SeedSequence(int(seed)).generate_state(int(repeats))]
