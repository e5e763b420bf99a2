"""Feature set ``cnn``: the CNN of Li, Zhao et al. 2024 as a feature extractor (CNN features + SVM).

Li, Zhao et al. (2024, motor-current study) train the CNN of their Table 5 (see
:class:`rvdiag.models.cnn.SpectrumCNN`) on the labelled windows and feed the 32 activations of its FC layer
to an SVM; they report > 96 % on measured motor current against <= 83.75 % for time-domain features.

:class:`CNNFeatures` is a supervised scikit-learn transformer: ``fit(X, y)`` trains the CNN (through
:class:`rvdiag.models.torch_estimator.CNNClassifier`), ``transform(X)`` returns the FC-layer activations,
shape (n, 32).  Use it as ``make_classical_model("svm", "cnn")`` / ``rvdiag train --model svm --features cnn``.

Persistence: the trained weights are kept as plain NumPy arrays (``weights_``) and the network is rebuilt
from them on first use, so the fitted transformer holds no torch object and a classical pipeline that
contains it is saved by skops like any other (its type is on :data:`rvdiag.registry.TRUSTED_TYPES`).  The
class lives in the models layer because it trains a model; torch is imported only when a network is built.
"""

from __future__ import annotations

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.utils.validation import check_is_fitted

from rvdiag.errors import ParameterError
from rvdiag.features import as_signal_matrix


#: the input representations a feature CNN takes (the time-domain ones and the log spectrum; the angle-domain
#: ones need each sample's speed, which a feature set does not get)
CNN_FEATURE_REPRESENTATIONS = ("waveform", "logspec", "residual")


#: The representation a feature CNN takes by default on each kind of signal (``rvdiag train --features cnn``;
#: ``rvdiag mcsa``): on motor current the log spectrum, which finds the broken sun tooth on unseen simulations
#: where the study's z-scored waveform stays at chance (docs/results.md, "Motor current"); on vibration the
#: waveform, as before.
DEFAULT_REPRESENTATION = {"vibration": "waveform", "current": "logspec"}


def default_representation(signal: str) -> str:
    """The default input representation of the CNN features for a store's ``signal`` (vibration or current)."""
    return DEFAULT_REPRESENTATION.get(str(signal), "waveform")


class CNNFeatures(TransformerMixin, BaseEstimator):
    """Learned features of a 1-D CNN (default: the motor-current paper's ``spectrum-cnn``).

    Parameters
    ----------
    architecture : {"spectrum-cnn", "cnn1d-lean", "cnn1d"}
    input_length : int or None
        Network input; None = the architecture's native length (4096 for spectrum-cnn), or the sample
        length when the samples are shorter (then the network is built for that length).
    representation : {"waveform", "logspec", "residual"}
        What the network sees of each window (:class:`rvdiag.models.torch_estimator.CNNClassifier`): the
        z-scored window (the study's input), its log spectrum, or the window minus its fitted supply line
        (motor current; :func:`rvdiag.features.current.fundamental_residual`).
    max_epochs, batch_size, learning_rate, validation_fraction, n_iter_no_change, device, random_state :
        as :class:`rvdiag.models.torch_estimator.CNNClassifier`.

    Attributes
    ----------
    weights_ : dict of str -> ndarray, the trained network weights
    classes_ : ndarray, the classes the network was trained on
    n_features_in_ : int, the sample length
    net_input_length_ : int
    window_starts_ : ndarray of int
    """

    def __init__(self, architecture: str = "spectrum-cnn", input_length: int | None = None, max_epochs: int = 30,
                 batch_size: int = 32, learning_rate: float = 1e-3, validation_fraction: float = 0.2,
                 n_iter_no_change: int = 5, device: str = "auto", random_state: int = 0,
                 representation: str = "waveform"):
        self.architecture = architecture
        self.representation = representation
        self.input_length = input_length
        self.max_epochs = max_epochs
        self.batch_size = batch_size
        self.learning_rate = learning_rate
        self.validation_fraction = validation_fraction
        self.n_iter_no_change = n_iter_no_change
        self.device = device
        self.random_state = random_state

    def _classifier(self, length: int):
        from rvdiag.models.cnn import DEFAULT_INPUT_LENGTH, architecture_name
        from rvdiag.models.torch_estimator import CNNClassifier

        if self.representation not in CNN_FEATURE_REPRESENTATIONS:
            raise ParameterError(f"representation must be one of {', '.join(CNN_FEATURE_REPRESENTATIONS)}, "
                                 f"got {self.representation!r}")
        W = self.input_length
        native = DEFAULT_INPUT_LENGTH.get(architecture_name(self.architecture))
        if W is None and native is not None:
            W = min(native, length)
        return CNNClassifier(architecture=self.architecture, input_length=W, max_epochs=self.max_epochs,
                             batch_size=self.batch_size, learning_rate=self.learning_rate,
                             validation_fraction=self.validation_fraction,
                             n_iter_no_change=self.n_iter_no_change, device=self.device,
                             random_state=self.random_state, representation=self.representation)

    def fit(self, X, y=None):
        """Train the CNN on labelled windows (``y`` is required).  Returns ``self``."""
        if y is None:
            raise ParameterError("the cnn feature set is supervised: fit needs the labels y")
        A = as_signal_matrix(X).astype(np.float32)
        clf = self._classifier(A.shape[1]).fit(A, y)
        self.weights_ = {k: v.detach().cpu().numpy().copy() for k, v in clf.net_.state_dict().items()}
        self.classes_ = np.asarray(clf.classes_)
        self.n_features_in_ = int(A.shape[1])
        self.net_input_length_ = int(clf.net_input_length_)
        self.window_starts_ = np.asarray(clf.window_starts_, dtype=np.int64)
        self._clf = clf
        return self

    def _restore(self):
        clf = getattr(self, "_clf", None)
        if clf is not None:
            return clf
        import torch

        from rvdiag.models.cnn import build_network
        from rvdiag.models.torch_estimator import CNNClassifier, network_length

        representation = getattr(self, "representation", "waveform")  # models saved before it existed: waveform
        clf = CNNClassifier(architecture=self.architecture, input_length=self.net_input_length_,
                            representation=representation)
        net = build_network(self.architecture, len(self.classes_),
                            network_length(self.net_input_length_, representation))
        net.load_state_dict({k: torch.from_numpy(np.asarray(v)) for k, v in self.weights_.items()})
        net.eval()
        clf.net_, clf.classes_, clf.n_features_in_ = net, self.classes_, self.n_features_in_
        clf.net_input_length_, clf.window_starts_ = self.net_input_length_, self.window_starts_
        clf.norm_mean_, clf.norm_std_ = 0.0, 1.0
        self._clf = clf
        return clf

    def transform(self, X):
        """FC-layer activations averaged over each sample's windows, shape (n, 32)."""
        check_is_fitted(self, "weights_")
        A = as_signal_matrix(X, 1)
        if A.shape[1] != self.n_features_in_:
            raise ParameterError(f"X has {A.shape[1]} features, but CNNFeatures is expecting {self.n_features_in_} "
                                 f"features as input (windows of {A.shape[1]} points, fitted on {self.n_features_in_})")
        return self._restore().embed(A.astype(np.float32)).astype(np.float64)

    def get_feature_names_out(self, input_features=None):
        n = len(self.transform(np.zeros((1, self.n_features_in_)) + np.arange(self.n_features_in_))[0])
        return np.array([f"cnn{i}" for i in range(n)], dtype=object)

    def __getstate__(self):
        state = dict(self.__dict__)
        state.pop("_clf", None)  # the torch net is rebuilt from weights_; nothing torch is serialised
        return state

