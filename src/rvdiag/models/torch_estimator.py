"""scikit-learn-compatible wrapper around the 1-D CNNs of :mod:`rvdiag.models.cnn`.

:class:`CNNClassifier` follows the scikit-learn estimator conventions (``sklearn/svm/_classes.py``):
``__init__`` only stores its keyword arguments, ``fit`` validates and returns ``self``, learned
attributes end in ``_``, ``get_params``/``set_params``/``clone`` work, so it fits into pipelines and
``GridSearchCV``.

Samples longer than the network input (explicit, never silent)
--------------------------------------------------------------
A sample of ``L`` points and a network input of ``W <= L`` points (e.g. 8000-point library samples and
the paper's 6400-point CNN): each sample is cut into ``k = ceil(L / W)`` windows of ``W`` points whose
starts are spread evenly from ``0`` to ``L - W`` (:func:`rvdiag.io.windows.covering_starts`), so together they cover every
point (for 8000/6400: windows at 0 and 1600).  In ``fit`` each window is a training example with the
sample's label; in ``predict_proba`` the class probabilities of a sample are the mean over its windows.
``long_input="crop"`` instead keeps only the centred window.  ``L < W`` is an error.
The chosen policy and the window starts are stored in the model (``window_starts_``) and its card.

Input normalisation (stored in the model)
-----------------------------------------
``normalize="window"`` (default): every window is standardised to zero mean, unit variance, so the
classifier sees waveform shape, not amplitude — simulated accelerations and measured signals in other
units or gains become comparable.  ``"global"``: subtract the training mean and divide by the training
standard deviation (``norm_mean_``, ``norm_std_``), keeping the amplitude information.  ``"none"``.

Input representation (stored in the model)
------------------------------------------
``representation="waveform"`` (default): the network sees the (normalised) time window, as in the dynamics
paper.  ``"logspec"``: it sees the log-magnitude spectrum of each Hann-windowed window,
``log(|FFT| + eps)`` over the ``W // 2 + 1`` one-sided bins, minus its own mean (so independent of the
signal level), then normalised as above.  Tooth-fault signatures of an RV reducer are sidebands of the
mesh harmonics at the fault frequency, tens of dB above a floor that holds little energy; a waveform
network weighs points by energy and misses them, the log spectrum puts them on an equal footing
(docs/results.md, "Input representation").  The spectrum is the classic input of 1-D CNNs in gear
diagnosis (e.g. Jing et al. 2017, Measurement 111, "A convolutional neural network based feature learning
and fault diagnosis method for the condition monitoring of gearbox").  :func:`log_spectrum` lives in
:mod:`rvdiag.features.spectrum`.

``"residual"`` (motor current): the time window minus its fitted supply line
(:func:`rvdiag.features.current.fundamental_residual`), so the network sees the reducer's sidebands
``f_e +- k f1`` instead of the sinusoid and the load that dominate the z-scored current (docs/results.md,
"Motor current").

``"orders"`` and ``"orders-residual"`` (angle domain, docs/models.md): the network sees each sample
resampled to ``samples_per_rev`` points per revolution of ``shaft`` (computed order tracking,
:func:`rvdiag.features.orders.resample_to_angle`), so a line at a shaft order stays at one input position
whatever the speed.  Each sample's speed is read from the metadata column ``speed_column`` appended after
its points (``*_deg_s``: output deg/s; ``*_rpm``: input rpm; :func:`input_metadata`), the sampling rate is
``fs``.  The whole sample is resampled from shaft angle 0 over its whole revolutions, then fitted to the
network input of ``input_length`` angle samples: cut to its first ``input_length`` points when longer,
repeated revolution after revolution (``numpy.resize``) when shorter.  ``"orders-residual"`` takes instead
the residual signal of the sample's TSA (the TSA minus the shaft orders and the mesh harmonics,
:func:`rvdiag.features.orders.gear_signals`), one revolution repeated to the input length.  One sample is
one network input (``window_starts_ = [0]``).  ``samples_per_rev`` (default: the largest power of two that
one revolution holds at the fastest training speed, but at least enough for 4 mesh harmonics and their
sidebands, :func:`rvdiag.features.orders.default_samples_per_rev`) is learned as ``samples_per_rev_`` and stored in the card with the speed column.

Training
--------
Adam (Kingma & Ba 2015) on the cross-entropy loss, mini-batches, a stratified validation split of
*samples* (never of windows of one sample, which would leak), early stopping on the validation loss with
the best weights restored.  Seeded: ``torch.manual_seed``, a NumPy generator for the split and the batch
order, and ``torch.use_deterministic_algorithms(True, warn_only=True)`` during ``fit``: two fits with one seed on
the CPU give identical weights (tested); on CUDA every op with a deterministic kernel uses it, and one
without warns rather than failing the fit.
"""

from __future__ import annotations

import copy
import os
import time
from typing import Callable

import numpy as np
import torch
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from rvdiag.errors import ParameterError
from rvdiag.features.spectrum import LOGSPEC_EPS, log_spectrum  # noqa: F401 (LOGSPEC_EPS: re-exported)
from rvdiag.io.windows import COVER_POLICIES, covering_starts
from rvdiag.models.cnn import ARCHITECTURES, DEFAULT_INPUT_LENGTH, architecture_name, build_network
from rvdiag.validation import integer, positive

NORMALIZATIONS = ("window", "global", "none")
LONG_INPUT = COVER_POLICIES
ANGLE_REPRESENTATIONS = ("orders", "orders-residual")
REPRESENTATIONS = ("waveform", "logspec", "residual") + ANGLE_REPRESENTATIONS


def network_length(window: int, representation: str) -> int:
    """Length of the network input for ``window`` points in the given representation."""
    return int(window) // 2 + 1 if representation == "logspec" else int(window)


def angle_inputs(X: np.ndarray, speeds: np.ndarray, *, fs: float, speed_column: str, shaft: str,
                 samples_per_rev: int, length: int, residual: bool = False, params=None) -> np.ndarray:
    """Samples ``X`` (n, L) at ``speeds`` (one per sample, unit given by ``speed_column``) in the angle domain:
    ``samples_per_rev`` points per revolution of ``shaft`` from angle 0, whole revolutions, fitted to ``length``
    points (cut, or repeated revolution by revolution); with ``residual``, the TSA's residual signal repeated.
    Shape ``(n, length)``, float64 (representations ``orders`` / ``orders-residual``; module docstring)."""
    from rvdiag.features import orders as _o
    from rvdiag.features.tsa import shaft_hz_from_column

    X = np.asarray(X, dtype=np.float64)
    v = np.asarray(speeds, dtype=np.float64)
    if not np.all(np.isfinite(v) & (v > 0)):
        raise ParameterError(f"the speed column {speed_column!r} must hold finite values > 0")
    spr = int(samples_per_rev)
    mesh = _o.mesh_order(shaft, params) if residual else 0
    out = np.empty((X.shape[0], int(length)))
    L = X.shape[1]
    for value in np.unique(v):
        f = shaft_hz_from_column(shaft, speed_column, float(value), params)
        if L * f / float(fs) < 1:
            raise ParameterError(f"samples of {L} points hold {L * f / float(fs):.3g} revolutions of the {shaft} shaft "
                                 f"at {speed_column} = {value:g} (fs {float(fs):g} Hz): the orders representation "
                                 f"needs at least one (longer samples, or a faster speed)")
        revs = _o.angle_from_speed(L, float(fs), f)
        for i in np.flatnonzero(v == value):
            xa = _o.resample_to_angle(X[i], float(fs), revs, spr)
            if residual:
                xa = _o.gear_signals(_o.tsa(xa, spr), mesh)["residual"]
            out[i] = np.resize(xa, int(length))
    return out


def resolve_device(device: str) -> torch.device:
    """``"auto"`` -> CUDA when available, else CPU; ``"cpu"``; ``"cuda"`` (error if unavailable)."""
    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if device == "cpu":
        return torch.device("cpu")
    if device.startswith("cuda"):
        if not torch.cuda.is_available():
            raise ParameterError("device 'cuda' requested but no CUDA GPU is available (use --device cpu or auto)")
        return torch.device(device)
    raise ParameterError(f"unknown device {device!r}; choose auto, cpu or cuda")


class CNNClassifier(ClassifierMixin, BaseEstimator):
    """A 1-D CNN classifier of raw signal windows with the scikit-learn API.

    Parameters
    ----------
    architecture : {"cnn1d", "cnn1d-lean", "spectrum-cnn"}
        Network, see :mod:`rvdiag.models.cnn`.
    input_length : int or None
        Network input in points.  None: the architecture's native length (6400 for ``cnn1d``, 4096 for
        ``spectrum-cnn``) or, for ``cnn1d-lean``, the sample length; it is capped at the sample length only
        for ``cnn1d-lean``, the others raise if samples are shorter.
    long_input : {"window", "crop"}
        What to do with samples longer than the input (module docstring).
    normalize : {"window", "global", "none"}
        Input normalisation (module docstring).
    representation : {"waveform", "logspec", "residual", "orders", "orders-residual"}
        What the network sees of each window (module docstring).
    max_epochs : int
        Upper bound on epochs.
    batch_size : int
    learning_rate : float
        Adam step size.
    weight_decay : float
        L2 penalty (Adam ``weight_decay``).
    validation_fraction : float
        Share of the training samples held out for early stopping (0: none; the training loss is
        monitored instead).
    n_iter_no_change : int
        Early-stopping patience in epochs.
    device : str
        ``"auto"``, ``"cpu"`` or ``"cuda"``.
    random_state : int
        Seed of the weights, the validation split and the batch order.
    net_kwargs : dict or None
        Extra arguments of the network constructor (e.g. ``{"fc_hidden": (64, 32)}`` for tests).
    fs : float or None
        Sampling rate (Hz) of the samples; needed by the angle-domain representations.
    speed_column : str
        ``orders`` / ``orders-residual``: the metadata column of each sample's speed, appended after its points
        (``*_deg_s`` output deg/s, ``*_rpm`` input rpm).
    shaft : {"sun", "crank", "output"}
        ``orders`` / ``orders-residual``: the shaft whose revolutions set the angle (default the sun relative
        to the carrier, :data:`rvdiag.features.orders.SHAFTS`).
    samples_per_rev : int or None
        ``orders`` / ``orders-residual``: angle samples per revolution (default: from the training speeds).

    Attributes
    ----------
    classes_ : ndarray of class labels
    n_features_in_ : int, the sample length
    net_ : torch.nn.Module, the trained network (on CPU after ``fit``)
    net_input_length_ : int
    window_starts_ : ndarray of int
    samples_per_rev_ : int, angle samples per revolution (angle-domain representations only)
    norm_mean_, norm_std_ : float, used when ``normalize="global"``
    history_ : list of dict per epoch (loss, val_loss, val_accuracy, seconds)
    best_epoch_ : int, the epoch whose weights were kept
    """

    def __init__(self, architecture: str = "cnn1d-lean", input_length: int | None = None,
                 long_input: str = "window", normalize: str = "window", max_epochs: int = 30,
                 batch_size: int = 32, learning_rate: float = 1e-3, weight_decay: float = 0.0,
                 validation_fraction: float = 0.2, n_iter_no_change: int = 5, device: str = "auto",
                 random_state: int = 0, net_kwargs: dict | None = None, representation: str = "waveform",
                 fs: float | None = None, speed_column: str = "output_speed_deg_s", shaft: str = "sun",
                 samples_per_rev: int | None = None):
        self.architecture = architecture
        self.input_length = input_length
        self.long_input = long_input
        self.normalize = normalize
        self.max_epochs = max_epochs
        self.batch_size = batch_size
        self.learning_rate = learning_rate
        self.weight_decay = weight_decay
        self.validation_fraction = validation_fraction
        self.n_iter_no_change = n_iter_no_change
        self.device = device
        self.random_state = random_state
        self.net_kwargs = net_kwargs
        self.representation = representation
        self.fs = fs
        self.speed_column = speed_column
        self.shaft = shaft
        self.samples_per_rev = samples_per_rev

    def input_metadata(self) -> tuple[str, ...]:
        """Metadata columns appended to each sample of ``X``: the speed column for the angle-domain
        representations (``orders``, ``orders-residual``), else none."""
        return (str(self.speed_column),) if self.representation in ANGLE_REPRESENTATIONS else ()

    # ------------------------------------------------------------------ validation
    def _check_params(self, length: int) -> int:
        if architecture_name(self.architecture) not in ARCHITECTURES:
            raise ParameterError(f"unknown architecture {self.architecture!r}; choose one of {', '.join(ARCHITECTURES)}")
        if self.normalize not in NORMALIZATIONS:
            raise ParameterError(f"normalize must be one of {NORMALIZATIONS}, got {self.normalize!r}")
        if self.representation not in REPRESENTATIONS:
            raise ParameterError(f"representation must be one of {REPRESENTATIONS}, got {self.representation!r}")
        if self.long_input not in LONG_INPUT:
            raise ParameterError(f"long_input must be one of {LONG_INPUT}, got {self.long_input!r}")
        for name in ("max_epochs", "batch_size", "n_iter_no_change"):
            integer(getattr(self, name), name, 1)
        if not (0.0 <= float(self.validation_fraction) < 1.0):
            raise ParameterError(f"validation_fraction must be in [0, 1), got {self.validation_fraction}")
        positive(self.learning_rate, "learning_rate")
        W = self.input_length if self.input_length is not None else DEFAULT_INPUT_LENGTH[architecture_name(self.architecture)]
        if W is None:
            W = length
        W = int(W)
        if W < 1:
            raise ParameterError(f"input_length must be >= 1, got {W}")
        if self.representation in ANGLE_REPRESENTATIONS:
            self._check_angle_params()
            return W  # angle samples: revolutions are repeated to fill the input (module docstring)
        if W > length:
            if self.architecture == "cnn1d-lean":
                W = length
            else:
                raise ParameterError(
                    f"{self.architecture} takes windows of {W} points but the samples have only {length}; "
                    f"give a shorter input_length (--input-length) or use cnn1d-lean"
                )
        return W

    def _check_angle_params(self) -> None:
        from rvdiag.features.orders import _check_shaft
        from rvdiag.features.tsa import check_speed_column

        _check_shaft(self.shaft)
        check_speed_column(self.speed_column)
        if not (self.fs is not None and float(self.fs) > 0):
            raise ParameterError(f"representation {self.representation!r} needs the sampling rate fs > 0 Hz, "
                                 f"got {self.fs}")
        if self.samples_per_rev is not None:
            integer(self.samples_per_rev, "samples_per_rev", 8)

    def network_input_length(self, n_points: int) -> int:
        """Check the settings and return the network input (points) for samples of ``n_points``: the
        ``input_length`` (or the architecture's default), cut to the sample for ``cnn1d-lean``.

        Raises :class:`rvdiag.errors.ParameterError` for a bad setting or a sample shorter than the input.
        """
        return self._check_params(int(n_points))

    # ------------------------------------------------------------------ preprocessing
    def _windows(self, X: np.ndarray) -> np.ndarray:
        """(n, L) -> (n * k, W) windows, sample-major."""
        W = self.net_input_length_
        idx = self.window_starts_[:, None] + np.arange(W)[None, :]
        return X[:, idx].reshape(-1, W)

    def _normalise(self, Xw: np.ndarray) -> np.ndarray:
        if self.normalize == "window":
            mu = Xw.mean(axis=1, keepdims=True)
            sd = Xw.std(axis=1, keepdims=True)
            return ((Xw - mu) / np.where(sd > 0, sd, 1.0)).astype(np.float32)
        if self.normalize == "global":
            return ((Xw - self.norm_mean_) / self.norm_std_).astype(np.float32)
        return Xw.astype(np.float32)

    def _represent(self, X: np.ndarray) -> np.ndarray:
        """Windows of ``X`` in the model's representation, before normalisation."""
        if self.representation in ANGLE_REPRESENTATIONS:
            X = np.asarray(X, dtype=np.float64)
            return angle_inputs(X[:, :-1], X[:, -1], fs=float(self.fs), speed_column=self.speed_column,
                                shaft=self.shaft, samples_per_rev=self.samples_per_rev_,
                                length=self.net_input_length_,
                                residual=self.representation == "orders-residual").astype(np.float32)
        Xw = self._windows(np.asarray(X, dtype=np.float32))
        if self.representation == "logspec":
            return log_spectrum(Xw)
        if self.representation == "residual":
            from rvdiag.features.current import fundamental_residual

            return fundamental_residual(Xw).astype(np.float32)
        return Xw

    def _prepare(self, X: np.ndarray) -> np.ndarray:
        return self._normalise(self._represent(X))

    # ------------------------------------------------------------------ training
    def fit(self, X, y, callback: Callable[[dict], None] | None = None, groups=None):
        """Train the network.

        Parameters
        ----------
        X : array-like (n_samples, n_points)
        y : array-like (n_samples,) of class labels
        callback : callable, optional
            Called after every epoch with a dict ``epoch, max_epochs, loss, val_loss, val_accuracy,
            seconds`` (``val_*`` are None without a validation split).
        groups : array-like (n_samples,), optional
            Group of each sample (e.g. the simulation ``unit`` of a library): the validation split then
            holds whole groups, so overlapping windows of one simulation never straddle it.

        Returns
        -------
        self
        """
        angle = self.representation in ANGLE_REPRESENTATIONS
        X, y = validate_data(self, X, y, dtype=np.float64 if angle else np.float32, ensure_min_samples=2)
        check_classification_targets(y)
        W = self._check_params(X.shape[1] - (1 if angle else 0))
        y_idx, rng, device = self._start_fit(y, W, X.shape[1], X[:, -1] if angle else None)
        tr, va = self._validation_split(y_idx, groups, rng)
        k = len(self.window_starts_)
        if self.normalize == "global":
            R = self._represent(X[tr])
            self.norm_mean_ = float(R.mean())
            sd = float(R.std())
            self.norm_std_ = sd if sd > 0 else 1.0
        else:
            self.norm_mean_, self.norm_std_ = 0.0, 1.0
        Xtr = torch.from_numpy(self._prepare(X[tr])).unsqueeze(1)
        ytr = torch.from_numpy(np.repeat(y_idx[tr], k)).long()
        Xva = torch.from_numpy(self._prepare(X[va])).unsqueeze(1) if len(va) else None
        Xtr_d, ytr_d = Xtr.to(device), ytr.to(device)
        n = len(ytr)
        bs = int(self.batch_size)

        def batches():
            order = torch.from_numpy(rng.permutation(n)).to(device)
            for start in range(0, n, bs):
                b = order[start:start + bs]
                yield Xtr_d[b], ytr_d[b]

        def validation_proba(net):
            return _predict_windows(net, Xva, device, k)

        return self._train(W, device, batches, n, validation_proba if Xva is not None else None, y_idx[va],
                           callback)

    def fit_store(self, source, callback: Callable[[dict], None] | None = None, groups=None,
                  buffer_samples: int | None = None):
        """Train the network on samples streamed from a store (:mod:`rvdiag.models.streaming`): as :meth:`fit`
        with the same seed, validation split, normalisation and early stopping, but the training samples are read
        ``buffer_samples`` at a time in a random order of the store's chunks and shuffled within that buffer, and
        the validation samples are scored block by block, so memory does not grow with the store.  The batch
        order differs from :meth:`fit`'s, so the weights do too.

        Parameters
        ----------
        source : :class:`rvdiag.models.streaming.StoreSamples` (the training split, with the model's metadata
            columns appended when it reads any)
        callback, groups : as :meth:`fit` (``groups``: one per sample of ``source``)
        buffer_samples : samples per read (default :data:`rvdiag.models.streaming.DEFAULT_BUFFER_SAMPLES`)

        Returns
        -------
        self
        """
        from rvdiag.models.streaming import DEFAULT_BUFFER_SAMPLES, TRANSFORM_PIECE, StoreStream

        buffer_samples = DEFAULT_BUFFER_SAMPLES if buffer_samples is None else buffer_samples
        angle = self.representation in ANGLE_REPRESENTATIONS
        if len(source) < 2:
            raise ParameterError(f"need at least 2 samples to train, got {len(source)}")
        if angle and tuple(source.meta_columns) != self.input_metadata():
            raise ParameterError(f"representation {self.representation!r} reads the metadata column(s) "
                                 f"{list(self.input_metadata())} after each sample; the source appends "
                                 f"{list(source.meta_columns)}")
        y = np.asarray(source.y)
        check_classification_targets(y)
        W = self._check_params(source.length)
        speeds = np.asarray(source.meta[self.speed_column], dtype=np.float64) if angle else None
        y_idx, rng, device = self._start_fit(y, W, source.n_features, speeds)
        self.n_features_in_ = int(source.n_features)
        tr, va = self._validation_split(y_idx, groups, rng)
        k = len(self.window_starts_)
        train, val = source.subset(tr), source.subset(va)
        if self.normalize == "global":
            self.norm_mean_, sd = _streamed_moments(self._represent, train, TRANSFORM_PIECE)
            self.norm_std_ = sd if sd > 0 else 1.0
        else:
            self.norm_mean_, self.norm_std_ = 0.0, 1.0
        stream = StoreStream(train, y_idx[tr], self._prepare, windows_per_sample=k, batch_size=int(self.batch_size),
                             rng=rng, buffer_samples=buffer_samples)

        def batches():
            for xb, yb in stream:
                yield xb.to(device), yb.to(device)

        def validation_proba(net):
            out = [_predict_windows(net, torch.from_numpy(self._prepare(X[s:s + TRANSFORM_PIECE])).unsqueeze(1),
                                    device, k)
                   for _, X in val.blocks(buffer_samples) for s in range(0, len(X), TRANSFORM_PIECE)]
            return np.concatenate(out)

        self.stream_buffer_samples_ = int(buffer_samples)
        return self._train(W, device, batches, len(stream), validation_proba if len(va) else None, y_idx[va],
                           callback)

    def _start_fit(self, y: np.ndarray, W: int, n_features: int, speeds: np.ndarray | None):
        """Classes, input windows or angle sampling, device and the seeded generator of a fit: ``(y_idx, rng,
        device)``."""
        self.classes_, y_idx = np.unique(y, return_inverse=True)
        if len(self.classes_) < 2:
            raise ParameterError(f"need at least 2 classes to train, got {len(self.classes_)}")
        self.net_input_length_ = W
        if speeds is not None:
            self.window_starts_ = np.array([0], dtype=np.int64)
            self.samples_per_rev_ = self._default_samples_per_rev(speeds)
        else:
            self.window_starts_ = covering_starts(n_features, W, self.long_input)
        device = resolve_device(self.device)
        self.device_ = str(device)
        return y_idx, np.random.default_rng(self.random_state), device

    def _validation_split(self, y_idx: np.ndarray, groups, rng: np.random.Generator):
        if groups is not None:
            groups = np.asarray(groups)
            if groups.shape != (len(y_idx),):
                raise ParameterError(f"groups must have one entry per sample ({len(y_idx)}), got shape {groups.shape}")
        return _split(y_idx, float(self.validation_fraction), rng, groups)

    def _train(self, W: int, device: torch.device, batches: Callable[[], object], n: int,
               validation_proba: Callable[[torch.nn.Module], np.ndarray] | None, yva: np.ndarray,
               callback: Callable[[dict], None] | None):
        """The training loop of :meth:`fit` and :meth:`fit_store`: ``batches()`` yields one epoch's ``(x, y)``
        batches on ``device`` (``n`` inputs in all), ``validation_proba(net)`` the validation samples' class
        probabilities (None: no validation split)."""
        deterministic_before = (torch.are_deterministic_algorithms_enabled(),
                                torch.is_deterministic_algorithms_warn_only_enabled())
        os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
        # warn_only: on CUDA an op without a deterministic kernel warns instead of failing the fit
        torch.use_deterministic_algorithms(True, warn_only=True)
        try:
            torch.manual_seed(int(self.random_state))
            net = build_network(self.architecture, len(self.classes_), network_length(W, self.representation),
                                **(self.net_kwargs or {}))
            net.to(device)
            opt = torch.optim.Adam(net.parameters(), lr=float(self.learning_rate),
                                   weight_decay=float(self.weight_decay))
            loss_fn = torch.nn.CrossEntropyLoss()
            best, best_state, best_epoch, stale = np.inf, None, 0, 0
            self.history_ = []
            for epoch in range(1, int(self.max_epochs) + 1):
                t0 = time.perf_counter()
                net.train()
                total = 0.0
                for xb, yb in batches():
                    opt.zero_grad()
                    loss = loss_fn(net(xb), yb)
                    loss.backward()
                    opt.step()
                    total += float(loss.detach()) * len(yb)
                train_loss = total / n
                val_loss = val_acc = None
                if validation_proba is not None:
                    proba = validation_proba(net)
                    val_loss = float(-np.mean(np.log(np.clip(proba[np.arange(len(yva)), yva], 1e-12, None))))
                    val_acc = float(np.mean(proba.argmax(1) == yva))
                monitor = val_loss if val_loss is not None else train_loss
                record = {"epoch": epoch, "max_epochs": int(self.max_epochs), "loss": train_loss,
                          "val_loss": val_loss, "val_accuracy": val_acc,
                          "seconds": time.perf_counter() - t0}
                self.history_.append(record)
                if callback is not None:
                    callback(dict(record))
                if monitor < best - 1e-6:
                    best, best_epoch, stale = monitor, epoch, 0
                    best_state = copy.deepcopy({k_: v.detach().cpu() for k_, v in net.state_dict().items()})
                else:
                    stale += 1
                    if stale >= int(self.n_iter_no_change):
                        break
        finally:
            torch.use_deterministic_algorithms(deterministic_before[0], warn_only=deterministic_before[1])
        net = net.cpu()
        if best_state is not None:
            net.load_state_dict(best_state)
        net.eval()
        self.net_ = net
        self.best_epoch_ = best_epoch
        self.n_epochs_ = len(self.history_)
        return self

    # ------------------------------------------------------------------ inference
    def _default_samples_per_rev(self, speeds: np.ndarray) -> int:
        """``samples_per_rev``, or :func:`~rvdiag.features.orders.default_samples_per_rev` at the fastest speed."""
        from rvdiag.features import orders as _o
        from rvdiag.features.tsa import shaft_hz_from_column

        if self.samples_per_rev is not None:
            return int(self.samples_per_rev)
        v = np.asarray(speeds, dtype=np.float64)
        if not np.all(np.isfinite(v) & (v > 0)):
            raise ParameterError(f"the speed column {self.speed_column!r} must hold finite values > 0")
        f = shaft_hz_from_column(self.shaft, self.speed_column, float(v.max()))
        return _o.default_samples_per_rev(float(self.fs), f, _o.mesh_order(self.shaft))

    def _check_X(self, X) -> np.ndarray:
        check_is_fitted(self, "net_")
        angle = self.representation in ANGLE_REPRESENTATIONS
        return validate_data(self, X, dtype=np.float64 if angle else np.float32, reset=False)

    def predict_proba(self, X) -> np.ndarray:
        """Class probabilities (softmax), averaged over the windows of each sample; shape (n, n_classes)."""
        X = self._check_X(X)
        Xw = torch.from_numpy(self._prepare(X)).unsqueeze(1)
        return _predict_windows(self.net_, Xw, self._inference_device(), len(self.window_starts_))

    def _inference_device(self) -> torch.device:
        """CUDA when asked for (or ``auto``) and present, else the CPU: a model trained on a GPU still
        predicts on a machine without one."""
        if str(self.device).startswith("cuda") or self.device == "auto":
            if torch.cuda.is_available():
                return torch.device(self.device if str(self.device).startswith("cuda") else "cuda")
        return torch.device("cpu")

    def predict(self, X) -> np.ndarray:
        """Most probable class of each sample."""
        proba = self.predict_proba(X)
        return self.classes_[proba.argmax(axis=1)]

    def embed(self, X) -> np.ndarray:
        """Learned features (last hidden layer), averaged over windows; shape (n, n_hidden)."""
        X = self._check_X(X)
        Xw = torch.from_numpy(self._prepare(X)).unsqueeze(1)
        k = len(self.window_starts_)
        net = self.net_.cpu().eval()
        out = []
        with torch.no_grad():
            for s in range(0, len(Xw), 256):
                out.append(net.features(Xw[s:s + 256]).numpy())
        F = np.concatenate(out) if out else np.zeros((0, 1), np.float32)
        return F.reshape(len(X), k, -1).mean(axis=1)

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.non_deterministic = False
        return tags


def _split(y_idx: np.ndarray, fraction: float, rng: np.random.Generator,
           groups: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Stratified split of sample indices: about ``fraction`` of every class (at least one sample, or
    one group, per class stays in training) goes to validation.  With ``groups``, whole groups move
    (a group is assigned to the class of its first sample).  Returns (train, validation)."""
    n = len(y_idx)
    if fraction <= 0:
        return np.arange(n), np.zeros(0, dtype=np.int64)
    va = []
    for c in np.unique(y_idx):
        members = np.flatnonzero(y_idx == c)
        if groups is not None:
            units = rng.permutation(np.unique(groups[members]))
            m = min(int(round(fraction * len(units))), len(units) - 1)
            va.extend(members[np.isin(groups[members], units[:m])].tolist())
            continue
        members = rng.permutation(members)
        m = int(round(fraction * len(members)))
        m = min(m, len(members) - 1)
        va.extend(members[:m].tolist())
    va = np.sort(np.array(va, dtype=np.int64))
    tr = np.setdiff1d(np.arange(n), va)
    return tr, va


def _predict_windows(net: torch.nn.Module, Xw: torch.Tensor, device: torch.device, k: int) -> np.ndarray:
    """Softmax probabilities of windows, averaged over each sample's ``k`` consecutive windows."""
    net = net.to(device)
    was_training = net.training
    net.eval()
    out = []
    with torch.no_grad():
        for s in range(0, len(Xw), 256):
            out.append(torch.softmax(net(Xw[s:s + 256].to(device)), dim=1).cpu().numpy())
    if was_training:
        net.train()
    P = np.concatenate(out) if out else np.zeros((0, 1), np.float32)
    return P.reshape(-1, k, P.shape[1]).mean(axis=1).astype(np.float64)


def _streamed_moments(represent: Callable[[np.ndarray], np.ndarray], source, block_samples: int) -> tuple[float, float]:
    """Mean and standard deviation of every value of ``represent(X)`` over the blocks of ``source``, combined block
    by block (Chan, Golub & LeVeque 1983, "Algorithms for computing the sample variance", The American Statistician
    37(3): the pairwise update of the mean and the sum of squared deviations)."""
    n, mean, m2 = 0, 0.0, 0.0
    for _, X in source.blocks(block_samples):
        R = np.asarray(represent(X), dtype=np.float64)
        nb = R.size
        if nb == 0:
            continue
        mb = float(R.mean())
        m2b = float(np.sum((R - mb) ** 2))
        delta = mb - mean
        total = n + nb
        mean += delta * nb / total
        m2 += m2b + delta * delta * n * nb / total
        n = total
    return (mean, float(np.sqrt(m2 / n))) if n else (0.0, 1.0)
