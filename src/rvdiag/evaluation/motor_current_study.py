"""The evaluation protocol of the motor-current study (Li, Zhao et al. 2024) on a sample store.

The study classifies sun-gear states from the motor phase current (1 kHz, 4096-point samples) at each of three
output speeds (30, 45, 60 deg/s) with three feature sets, each fed to an SVM, over 70/30 random splits repeated
10 times.  :func:`run_mcsa` runs that protocol on any store (``rvdiag mcsa``):

- the samples are grouped by operating speed (a metadata column, default ``output_speed_deg_s``: the speed a
  library draws per simulation; ``window_speed_deg_s`` varies window by window under a speed profile and is
  no grouping key);
- at each speed, for each feature set, ``repeats`` stratified splits (``test_size`` of each class to the test
  side; :func:`split_seeds` derives one seed per repeat from ``seed``) fit ``StandardScaler -> SVC`` (RBF,
  the same settings for every feature set) on the training side and score the test side: accuracy, macro
  precision / recall / F1 and Cohen's kappa (:func:`rvdiag.evaluation.metrics.classification_metrics`),
  their mean and (population) standard deviation over the repeats;
- with a second store (``test_store``), the honest protocol as well: fit on every sample of the first store at
  that speed, score the samples of the second store at the same speed (simulations the fit never saw).

Feature sets (:data:`FEATURE_SETS`):

``time``  the ten time-domain statistics of :mod:`rvdiag.features.timedomain` (peak-to-peak, mean, variance,
          RMS, square-root amplitude, kurtosis, pulse factor, margin factor, crest factor, shape factor): the
          study's set, so the existing ``time`` features are used as they are;
``wpt``   the relative energies of the 16 bands of a level-4 wavelet-packet decomposition
          (:class:`rvdiag.features.wavelet.WaveletPacketEnergy`, ``db4``, frequency order);
``cnn``   the 32 FC activations of the study's CNN (``spectrum-cnn``, Table 5, 1 x 4096 input;
          :class:`rvdiag.models.cnn_features.CNNFeatures`), trained on the training side of each split only.
          What the network sees of each window is ``cnn_representation``: by default its log spectrum
          (the study's z-scored waveform stays at chance on unseen simulations, where the log spectrum finds
          the broken tooth: docs/results.md, "Motor current"), or ``waveform`` / ``residual``.

``time`` and ``wpt`` learn nothing from the data, so their features are computed once per speed and split
afterwards (the same figures as a pipeline refitted per split, in a fraction of the time).

The random window splits are the study's protocol; when a simulation (``unit``) gives several windows, windows
of one simulation land on both sides and the split scores are optimistic (a
:class:`rvdiag.errors.SplitLeakWarning`).  ``test_store`` gives the honest figure.

The module has no command-line logic: :mod:`rvdiag.cli.mcsa` parses the options and draws the progress bars
(this module reports its stages to :mod:`rvdiag.progress`).
"""

from __future__ import annotations

import json
import math
import re
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from rvdiag import __version__
from rvdiag.errors import ParameterError, SplitLeakWarning, StoreError
from rvdiag.evaluation.metrics import classification_metrics
from rvdiag.features.timedomain import TIME_FEATURE_NAMES
from rvdiag.models.cnn_features import CNN_FEATURE_REPRESENTATIONS, default_representation
from rvdiag.progress import report

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
_PROTOCOL_SPLITS = {
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
        if not (math.isfinite(self.svm_c) and self.svm_c > 0):
            raise ParameterError(f"svm_c must be a number > 0, got {self.svm_c}")
        if self.cnn_epochs < 1:
            raise ParameterError(f"cnn_epochs must be >= 1, got {self.cnn_epochs}")
        if self.cnn_batch_size < 1:
            raise ParameterError(f"cnn_batch_size must be >= 1, got {self.cnn_batch_size}")
        if not (math.isfinite(self.cnn_lr) and self.cnn_lr > 0):
            raise ParameterError(f"cnn_lr must be a number > 0, got {self.cnn_lr}")
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


# ---------------------------------------------------------------------- channels and speeds
def sample_channels(store) -> np.ndarray:
    """The channel name of every sample of a store.

    A store holds one signal per row.  A store written from measured files records the channel of each row in
    its ``channel`` metadata column; a simulated library keeps the channel its config names (``channel``, a
    simulator channel name such as ``i_a``, or an index, named by its number).
    """
    col = store.meta.get("channel")
    if col is not None and np.asarray(col).dtype.kind in "OUS":
        return np.asarray(col).astype(str)
    configured = (store.attrs.get("config") or {}).get("channel")
    name = "0" if configured is None or configured == "" else str(configured)
    return np.full(store.n_samples, name, dtype=object).astype(str)


def pick_channel(names: Sequence[str], wanted: str | None, where: Any) -> str:
    """The channel to use among ``names`` (in the store's order).

    ``wanted`` None: ``i_a`` (the phase current) when present, else the first channel.  Otherwise an exact name,
    or a regular expression (:func:`re.search`, as ``-c/--channel`` everywhere) matching exactly one name.
    """
    order = list(dict.fromkeys(str(n) for n in names))
    if wanted is None:
        return DEFAULT_CHANNEL if DEFAULT_CHANNEL in order else order[0]
    if wanted in order:
        return wanted
    try:
        pattern = re.compile(wanted)
    except re.error as exc:
        raise ParameterError(f"--channel {wanted!r} is no valid regular expression: {exc}") from None
    hits = [n for n in order if pattern.search(n)]
    if len(hits) == 1:
        return hits[0]
    what = "no channel" if not hits else f"{len(hits)} channels ({', '.join(hits)})"
    raise StoreError(f"{where}: {what} match --channel {wanted!r} (channels: {', '.join(order)})")


def speed_unit(column: str) -> str:
    """The unit of a speed column by its name's ending (``_deg_s`` -> deg/s, ``_rpm`` -> rev/min)."""
    if column.endswith("_deg_s"):
        return "deg/s"
    if column.endswith("_rpm"):
        return "rev/min"
    return ""


def speed_labels(store, column: str) -> np.ndarray:
    """The operating speed of every sample as a label (``"45"``, ``"37.5"``), from metadata ``column``."""
    if column not in store.meta:
        numeric = sorted(k for k, v in store.meta.items() if np.asarray(v).dtype.kind in "fiu"
                         and k not in ("unit", "seed", "segment", "simulation"))
        raise StoreError(f"{store.path} has no metadata column {column!r} to group the samples by speed; name one "
                         f"with --speed-column (numeric columns: {', '.join(numeric) or 'none'})")
    col = np.asarray(store.meta[column])
    if col.dtype.kind in "fiu":
        values = col.astype(np.float64)
        if not np.all(np.isfinite(values)):
            bad = int(np.sum(~np.isfinite(values)))
            raise StoreError(f"{store.path}: {bad} sample(s) have no speed in column {column!r} (NaN)")
        return np.asarray([f"{round(v, 6):g}" for v in values.tolist()], dtype=object).astype(str)
    return col.astype(str)


def _speed_order(labels) -> list[str]:
    def key(s: str):
        try:
            return (0, float(s), s)
        except ValueError:
            return (1, 0.0, s)

    return sorted(set(labels), key=key)


# ---------------------------------------------------------------------- data
@dataclass
class _Group:
    """The samples of one store at one speed, on one channel."""

    X: np.ndarray
    y: np.ndarray
    units: np.ndarray | None
    sims: np.ndarray | None  # (class, seed) identities of the simulations, when the store records seeds


def _load_groups(store, channel: str, column: str) -> dict[str, _Group]:
    on_channel = sample_channels(store) == channel
    speeds = speed_labels(store, column)
    out: dict[str, _Group] = {}
    for speed in _speed_order(speeds[on_channel].tolist()):
        idx = np.flatnonzero(on_channel & (speeds == speed))
        s = store.load(index=idx)
        units = s.meta.get("unit")
        sims = None
        if "seed" in s.meta:
            sims = np.asarray([f"{c}/{v}" for c, v in zip(s.y.tolist(), s.meta["seed"].tolist())], dtype=object)
        out[speed] = _Group(X=np.asarray(s.X, dtype=np.float32), y=np.asarray(s.y).astype(str),
                            units=None if units is None else np.asarray(units), sims=sims)
    return out


def _check_splittable(groups: dict[str, _Group], test_size: float, where: Any, unit: str) -> None:
    """Refuse a speed whose classes are too small for a stratified split (before any work)."""
    for speed, g in groups.items():
        classes, counts = np.unique(g.y, return_counts=True)
        at = f"{where} at {speed} {unit}".rstrip()
        if len(classes) < 2:
            raise StoreError(f"{at}: only one class ({classes[0]}); a classification needs at least two")
        n = len(g.y)
        n_test = math.ceil(test_size * n)
        n_train = n - n_test
        small = [f"{c} ({k})" for c, k in zip(classes.tolist(), counts.tolist()) if k < 2]
        if small or n_test < len(classes) or n_train < len(classes):
            detail = (f"class {', '.join(small)} has fewer than 2 samples" if small else
                      f"{n} samples give {n_train} training / {n_test} test samples for {len(classes)} classes")
            raise StoreError(f"{at}: too few samples for a stratified {round(100 * (1 - test_size))}/"
                             f"{round(100 * test_size)} split ({detail}); a split needs at least 2 samples per "
                             f"class and one per class on each side")


# ---------------------------------------------------------------------- protocols
def study_split(y: np.ndarray, units: np.ndarray, test_size: float, seed: int):
    """One split of the study's protocol: one reducer per state, its windows split at random.

    The study recorded each state on a different physical sun gear and split the windows of those recordings
    70/30 at random.  Here each state keeps the windows of one simulation (``units``: the simulation of every
    window; with ``[randomise] specimen = true`` each simulation is a reducer of its own), drawn with
    ``numpy.random.default_rng(seed)``, and those windows are split stratified at random
    (:func:`sklearn.model_selection.train_test_split`, ``random_state=seed``).

    Returns (train indices, test indices, the simulations used, one per state in sorted class order).

    >>> y = np.array(["a"] * 6 + ["b"] * 6); u = np.array([1, 1, 1, 2, 2, 2, 3, 3, 3, 4, 4, 4])
    >>> tr, te, used = study_split(y, u, 0.5, 0)
    >>> len(used), set(u[np.r_[tr, te]]) == set(used), len(te)
    (2, True, 3)
    """
    from sklearn.model_selection import train_test_split

    rng = np.random.default_rng(int(seed))
    used = []
    for c in sorted(set(y.tolist())):
        candidates = np.unique(units[y == c])
        used.append(candidates[rng.integers(len(candidates))])
    idx = np.flatnonzero(np.isin(units, used))
    tr, te = train_test_split(idx, test_size=float(test_size), stratify=y[idx], random_state=int(seed))
    return np.sort(tr), np.sort(te), [u.item() if hasattr(u, "item") else u for u in used]


def held_out_split(y: np.ndarray, units: np.ndarray, test_size: float, seed: int):
    """One split of the held-out protocol: whole reducers on the test side, none of them seen in the fit.

    For each state, ``round(test_size * n)`` of its ``n`` simulations (at least one, and at least one left to
    train on), drawn with ``numpy.random.default_rng(seed)``, give all their windows to the test side; the other
    simulations train.  A split by group (as :class:`sklearn.model_selection.GroupShuffleSplit`), stratified by
    state so that every state is on both sides.

    Returns (train indices, test indices, the test simulations).

    >>> y = np.array(["a"] * 4 + ["b"] * 4); u = np.array([1, 1, 2, 2, 3, 3, 4, 4])
    >>> tr, te, unseen = held_out_split(y, u, 0.5, 0)
    >>> len(unseen), set(u[tr]) & set(u[te])
    (2, set())
    """
    rng = np.random.default_rng(int(seed))
    unseen = []
    for c in sorted(set(y.tolist())):
        candidates = np.unique(units[y == c])
        k = min(max(1, round(float(test_size) * len(candidates))), len(candidates) - 1)
        unseen.extend(rng.choice(candidates, k, replace=False).tolist())
    test = np.isin(units, unseen)
    return np.flatnonzero(~test), np.flatnonzero(test), sorted(unseen)


def protocol_splits(protocol: str, y: np.ndarray, units: np.ndarray | None, test_size: float,
                    seeds: Sequence[int]) -> list[tuple[np.ndarray, np.ndarray, dict]]:
    """The (train, test, what the split used) of each repeat of one protocol (``windows``, ``study`` or
    ``held-out``; :data:`PROTOCOLS`), repeat ``r`` seeded with ``seeds[r]``."""
    from sklearn.model_selection import train_test_split

    out = []
    for s in seeds:
        if protocol == "windows":
            tr, te = train_test_split(np.arange(len(y)), test_size=float(test_size), stratify=y, random_state=s)
            out.append((np.sort(tr), np.sort(te), {}))
        elif protocol == "study":
            tr, te, used = study_split(y, units, test_size, s)
            out.append((tr, te, {"simulations": used}))
        elif protocol == "held-out":
            tr, te, unseen = held_out_split(y, units, test_size, s)
            out.append((tr, te, {"test_simulations": unseen}))
        else:
            raise ParameterError(f"protocol_splits runs windows | study | held-out, got {protocol!r}")
    return out


def protocols_run(protocol: str) -> list[str]:
    """The protocols a ``protocol`` setting runs (``both`` -> study and held-out)."""
    return ["study", "held-out"] if protocol == "both" else [protocol]


def _check_protocol(groups: dict[str, _Group], settings: McsaSettings, where: Any, unit: str) -> None:
    """Refuse a store the study or held-out protocol cannot split (before any work)."""
    runs = protocols_run(settings.protocol)
    if runs == ["windows"]:
        return
    for speed, g in groups.items():
        at = f"{where} at {speed} {unit}".rstrip()
        if g.units is None:
            raise StoreError(f"{where} has no 'unit' column (the simulation of each window): the {settings.protocol} "
                             "protocol splits by simulated reducer")
        for c in sorted(set(g.y.tolist())):
            sims, windows = np.unique(g.units[g.y == c], return_counts=True)
            if "held-out" in runs and len(sims) < 2:
                raise StoreError(f"{at}: state {c} has {len(sims)} simulation; the held-out split needs at least "
                                 "2 per state and speed (one to train on, one unseen)")
            if "study" in runs and windows.min() < 2:
                raise StoreError(f"{at}: a simulation of state {c} has {windows.min()} window; the study's split "
                                 "takes the windows of one simulation to both sides and needs at least 2")
        if "study" in runs:
            n_classes = len(set(g.y.tolist()))
            n = n_classes * min(int(np.min(np.unique(g.units[g.y == c], return_counts=True)[1]))
                                for c in set(g.y.tolist()))
            n_test = math.ceil(float(settings.test_size) * n)
            if n_test < n_classes or n - n_test < n_classes:
                raise StoreError(f"{at}: one simulation per state gives as few as {n} windows, too few for a "
                                 f"stratified split with one per state on each side")


def recall_and_false_alarms(confusion: Sequence[Sequence[int]], labels: Sequence[str]) -> dict:
    """Per-class recall (:func:`class_recalls`) and the false-alarm rate (healthy windows called faulty, the
    healthy class of :func:`rvdiag.evaluation.metrics.healthy_class`) of a confusion matrix (rows true).

    >>> recall_and_false_alarms([[3, 1], [0, 4]], ["T1", "T2"])
    {'recall_per_class': {'T1': 0.75, 'T2': 1.0}, 'false_alarm_rate': 0.25}
    """
    from rvdiag.evaluation.metrics import healthy_class

    recall = class_recalls(confusion, labels)
    healthy = healthy_class(labels)
    fa = None if healthy is None or recall[healthy] is None else 1.0 - recall[healthy]
    return {"recall_per_class": recall, "false_alarm_rate": fa}


# ---------------------------------------------------------------------- models
def _svm(settings: McsaSettings, seed: int):
    from sklearn.pipeline import Pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVC

    return Pipeline([("scale", StandardScaler()),
                     ("svm", SVC(kernel="rbf", C=float(settings.svm_c), gamma=settings.svm_gamma,
                                 random_state=int(seed)))])


def _fixed_features(name: str, settings: McsaSettings, X: np.ndarray) -> np.ndarray:
    """Features of a set that learns nothing (``time``, ``wpt``)."""
    if name == "time":
        from rvdiag.features.timedomain import time_features

        return time_features(X)
    from rvdiag.features.wavelet import WaveletPacketEnergy

    return WaveletPacketEnergy(wavelet=settings.wavelet, level=int(settings.wpt_level)).fit_transform(X)


def _cnn(settings: McsaSettings, seed: int):
    from rvdiag.models.cnn_features import CNNFeatures

    return CNNFeatures(architecture="spectrum-cnn", input_length=settings.cnn_input_length,
                       max_epochs=int(settings.cnn_epochs), batch_size=int(settings.cnn_batch_size),
                       learning_rate=float(settings.cnn_lr), n_iter_no_change=int(settings.cnn_patience),
                       validation_fraction=float(settings.cnn_validation_fraction), device=settings.device,
                       random_state=int(seed), representation=settings.cnn_representation)


def _fit_score(name: str, settings: McsaSettings, seed: int, Xtr, ytr, Xte, yte, Ftr=None, Fte=None):
    """Fit features (cnn) and the SVM on the training side; (metrics, standardised test features)."""
    if name == "cnn":
        cnn = _cnn(settings, seed).fit(Xtr, ytr)
        Ftr, Fte = cnn.transform(Xtr), cnn.transform(Xte)
    svm = _svm(settings, seed).fit(Ftr, ytr)
    pred = svm.predict(Fte)
    labels = sorted(set(ytr.tolist()) | set(yte.tolist()))
    m = classification_metrics(yte, pred, labels=labels)
    keep = {k: m[k] for k in METRICS}
    keep.update(confusion=m["confusion"], labels=m["labels"], n_train=int(len(ytr)), n_test=int(len(yte)),
                recall_per_class=class_recalls(m["confusion"], m["labels"]))
    return keep, svm.named_steps["scale"].transform(Fte)


def class_recalls(confusion, labels) -> dict[str, float | None]:
    """Recall of each class (its diagonal over its row of the confusion matrix; None for a class without
    test samples)."""
    C = np.asarray(confusion, dtype=np.float64)
    rows = C.sum(axis=1)
    return {str(c): (float(C[i, i] / rows[i]) if rows[i] > 0 else None) for i, c in enumerate(labels)}


def _recall_text(recalls: dict) -> str:
    return " / ".join(f"{c} {'-' if r is None else f'{100 * r:.0f}'}" for c, r in recalls.items())


def _summary(runs: list[dict]) -> dict:
    return {k: {"mean": float(np.mean([r[k] for r in runs])), "std": float(np.std([r[k] for r in runs]))}
            for k in METRICS}


# ---------------------------------------------------------------------- the run
@dataclass
class McsaResult:
    """What :func:`run_mcsa` found: ``report`` (the JSON of ``mcsa.json``) and the t-SNE inputs.

    ``tsne[set][speed]`` = (standardised test features of the first repeat, their classes).
    """

    report: dict
    tsne: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = field(default_factory=dict)


def _store_info(store, channel: str, n_used: int) -> dict:
    return {"path": str(store.path), "config_hash": store.attrs.get("config_hash"), "kind": store.attrs.get("kind"),
            "n_samples": int(store.n_samples), "n_used": int(n_used), "length": int(store.length), "fs": store.fs,
            "classes": list(store.classes), "channel": channel}


def prepare(store, settings: McsaSettings, test_store=None):
    """Check the settings and the stores before any work: (channel, groups, (other channel, other groups) or
    None, notes, leaks), ``leaks`` the notes that say a score is optimistic (also in ``notes``).

    Raises :class:`ParameterError` / :class:`StoreError` (one line each) for a bad setting, a missing channel or
    speed column, a speed with too few samples for the split, or a second store that does not fit the first.
    """
    settings.check()
    unit = speed_unit(settings.speed_column)
    channel = pick_channel(sample_channels(store).tolist(), settings.channel, store.path)
    if "cnn" in settings.feature_sets and settings.cnn_input_length and settings.cnn_input_length > store.length:
        raise ParameterError(f"cnn_input_length {settings.cnn_input_length} is longer than the samples of "
                             f"{store.path} ({store.length} points)")
    groups = _load_groups(store, channel, settings.speed_column)
    _check_splittable(groups, float(settings.test_size), store.path, unit)
    _check_protocol(groups, settings, store.path, unit)
    notes: list[str] = []
    leaks: list[str] = []
    other = None
    if test_store is not None:
        if test_store.length != store.length:
            raise StoreError(f"{test_store.path} has {test_store.length}-point samples, {store.path} "
                             f"{store.length}-point ones: the features need samples of one length")
        if store.fs and test_store.fs and abs(store.fs - test_store.fs) > 1e-6 * store.fs:
            raise StoreError(f"{test_store.path} is sampled at {test_store.fs:g} Hz, {store.path} at {store.fs:g} Hz")
        other_channel = pick_channel(sample_channels(test_store).tolist(), settings.channel, test_store.path)
        other_groups = _load_groups(test_store, other_channel, settings.speed_column)
        common = [s for s in groups if s in other_groups]
        if not common:
            raise StoreError(f"{test_store.path} has no sample at the speeds of {store.path} "
                             f"({', '.join(groups)} {unit}; it has {', '.join(other_groups) or 'none'})".rstrip())
        for s in common:
            unseen = sorted(set(other_groups[s].y.tolist()) - set(groups[s].y.tolist()))
            if unseen:
                raise StoreError(f"{test_store.path} has class(es) {', '.join(unseen)} at {s} {unit}, which "
                                 f"{store.path} lacks there: nothing could learn them")
        missing = [s for s in groups if s not in other_groups]
        if missing:
            notes.append(f"{test_store.path} has no sample at {', '.join(missing)} {unit}: no held-out figure there")
        shared = 0
        for s in common:
            a, b = groups[s].sims, other_groups[s].sims
            if a is not None and b is not None:
                shared += len(set(a.tolist()) & set(b.tolist()))
        same_hash = store.attrs.get("config_hash")
        if same_hash and test_store.attrs.get("config_hash") == same_hash:
            leaks.append(f"{test_store.path} was built from the same config as {store.path} (hash {same_hash}): the "
                         "same simulations, so the held-out figures are optimistic")
        elif shared:
            leaks.append(f"{shared} simulation(s) (class and seed) of {test_store.path} are also in {store.path}: "
                         "the held-out figure is optimistic")
        other = (other_channel, other_groups)
    if settings.protocol != "held-out" and any(g.units is not None and len(np.unique(g.units)) < len(g.units)
                                                for g in groups.values()):
        honest = ("the held-out protocol's figures are not" if settings.protocol == "both" else
                  "the held-out figures are not" if other is not None else
                  "--protocol held-out (unseen reducers) or a held-out store (--test) gives the honest figure")
        leaks.append("random window splits put windows of one simulation on both sides (the study's protocol): "
                     f"the split scores are optimistic; {honest}")
    return channel, groups, other, notes + leaks, leaks


def run_mcsa(store, settings: McsaSettings, test_store=None) -> McsaResult:
    """Run the study's protocol on ``store`` (a :class:`rvdiag.datasets.SampleStore`); see the module docstring.

    Progress goes to :mod:`rvdiag.progress`, one stage per feature set (``<set>: fits``).  Notes about the
    protocol (shared simulations) are also raised as :class:`SplitLeakWarning`.
    """
    channel, groups, other, notes, leaks = prepare(store, settings, test_store)
    for note in leaks:
        warnings.warn(note, SplitLeakWarning, stacklevel=2)
    seeds = split_seeds(settings.seed, settings.repeats)
    unit = speed_unit(settings.speed_column)
    results: dict[str, dict[str, Any]] = {}
    tsne: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = {name: {} for name in settings.feature_sets}
    n_held = 0 if other is None else sum(1 for s in groups if s in other[1])
    runs_of = protocols_run(settings.protocol)
    for name in settings.feature_sets:
        stage = f"{name}: fits"
        total = len(groups) * settings.repeats * len(runs_of) + n_held
        done = 0
        report(stage, done, total)
        for speed, g in groups.items():
            F = None if name == "cnn" else _fixed_features(name, settings, g.X)
            entry: dict[str, Any] = {
                "n_samples": int(len(g.y)),
                "counts": {c: int(k) for c, k in zip(*np.unique(g.y, return_counts=True))},
            }
            for proto in runs_of:
                runs = []
                for r, (s, (tr, te, used)) in enumerate(zip(seeds, protocol_splits(
                        proto, g.y, g.units, float(settings.test_size), seeds))):
                    kw = {} if F is None else {"Ftr": F[tr], "Fte": F[te]}
                    m, Fz = _fit_score(name, settings, s, g.X[tr], g.y[tr], g.X[te], g.y[te], **kw)
                    m["seed"] = int(s)
                    m.update(used)
                    runs.append(m)
                    if r == 0 and proto == runs_of[0]:
                        tsne[name][speed] = (Fz, g.y[te])
                    done += 1
                    report(stage, done, total)
                confusion = np.sum([r["confusion"] for r in runs], axis=0).astype(int).tolist()
                entry[PROTOCOL_KEYS[proto]] = {"repeats": runs, **_summary(runs), "confusion_sum": confusion,
                                               "labels": runs[0]["labels"],
                                               **recall_and_false_alarms(confusion, runs[0]["labels"])}
            entry["held_out"] = None
            if other is not None and speed in other[1]:
                h = other[1][speed]
                kw = {} if F is None else {"Ftr": F, "Fte": _fixed_features(name, settings, h.X)}
                m, _ = _fit_score(name, settings, seeds[0], g.X, g.y, h.X, h.y, **kw)
                m["seed"] = int(seeds[0])
                entry["held_out"] = m
                done += 1
                report(stage, done, total)
            results.setdefault(speed, {})[name] = entry
    out = {
        "format": FORMAT,
        "rvdiag_version": __version__,
        "protocol": (f"{settings.protocol}: {PROTOCOLS[settings.protocol]}; at each speed and for each feature "
                     "set: repeated splits (test_size of each class to the test side; " +
                     "; ".join(f"{PROTOCOL_KEYS[p]}: {_PROTOCOL_SPLITS[p]}" for p in runs_of) +
                     "), StandardScaler + RBF SVC fitted on the training side; metrics on the test "
                     "side, mean and population std over the repeats" +
                     ("; held_out: fit on every sample of the store at that speed, score the test store's samples "
                      "at that speed" if other is not None else "")),
        "store": _store_info(store, channel, sum(len(g.y) for g in groups.values())),
        "test_store": None if other is None else _store_info(test_store, other[0],
                                                             sum(len(g.y) for g in other[1].values())),
        "speed_column": settings.speed_column,
        "speed_unit": unit,
        "speeds": list(groups),
        "feature_sets": {name: FEATURE_SETS[name] for name in settings.feature_sets},
        "time_features": list(TIME_FEATURE_NAMES),
        "settings": asdict(settings) | {"feature_sets": list(settings.feature_sets)},
        "svm": {"kernel": "rbf", "C": float(settings.svm_c), "gamma": settings.svm_gamma,
                "scaler": "StandardScaler (fitted on the training side)"},
        "split_seeds": seeds,
        "results": results,
        "study": {name: STUDY_FIGURES[name] for name in settings.feature_sets},
        "notes": notes,
    }
    return McsaResult(report=out, tsne=tsne)


# ---------------------------------------------------------------------- outputs
def _pct(v: float) -> str:
    return f"{100 * v:.2f}"


def markdown(report_: dict) -> str:
    """The Markdown of ``mcsa.md``: one table speed x feature set (split protocol), and one of the held-out
    figures when the run had a test store."""
    unit = report_["speed_unit"]
    st = report_["settings"]
    protocol = st.get("protocol", "windows")
    if protocol != "windows":
        lines = ["# Motor-current study protocol (rvdiag mcsa)", ""] + protocol_markdown(report_)
        return _markdown_tail(report_, lines + _test_store_lines(report_))
    lines = [
        "# Motor-current study protocol (rvdiag mcsa)",
        "",
        f"Store `{report_['store']['path']}`, channel `{report_['store']['channel']}`, "
        f"speeds from `{report_['speed_column']}`.  {st['repeats']} stratified "
        f"{round(100 * (1 - st['test_size']))}/{round(100 * st['test_size'])} splits per speed and feature set, "
        f"seed {st['seed']}; StandardScaler + RBF SVC (C = {st['svm_c']:g}, gamma = {st['svm_gamma']}) for every "
        "feature set.  Accuracy as mean ± std over the splits (%); precision, recall and F1 are macro averages "
        "(%), kappa is Cohen's; all means over the splits.",
        "",
        f"| speed ({unit or report_['speed_column']}) | features | accuracy | precision | recall | F1 | kappa | "
        "recall per class (all splits) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for speed, sets in report_["results"].items():
        for name, e in sets.items():
            s = e["split"]
            lines.append(f"| {speed} | {FEATURE_SETS[name]} | {_pct(s['accuracy']['mean'])} ± "
                         f"{_pct(s['accuracy']['std'])} | {_pct(s['precision_macro']['mean'])} | "
                         f"{_pct(s['recall_macro']['mean'])} | {_pct(s['f1_macro']['mean'])} | "
                         f"{s['kappa']['mean']:.3f} | {_recall_text(s['recall_per_class'])} |")
    return _markdown_tail(report_, lines + _test_store_lines(report_))


def _test_store_lines(report_: dict) -> list[str]:
    """The table of the figures on a held-out store (``--test``), or nothing without one."""
    unit = report_["speed_unit"]
    lines: list[str] = []
    if report_.get("test_store"):
        lines += ["", f"Held out: fitted on every sample of the store at each speed, scored on "
                      f"`{report_['test_store']['path']}` (channel `{report_['test_store']['channel']}`).", "",
                  f"| speed ({unit or report_['speed_column']}) | features | accuracy | precision | recall | F1 | "
                  "kappa | test samples | recall per class |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for speed, sets in report_["results"].items():
            for name, e in sets.items():
                h = e["held_out"]
                if h is None:
                    continue
                lines.append(f"| {speed} | {FEATURE_SETS[name]} | {_pct(h['accuracy'])} | "
                             f"{_pct(h['precision_macro'])} | {_pct(h['recall_macro'])} | {_pct(h['f1_macro'])} | "
                             f"{h['kappa']:.3f} | {h['n_test']} | {_recall_text(h['recall_per_class'])} |")
    return lines


def _markdown_tail(report_: dict, lines: list[str]) -> str:
    st = report_["settings"]
    if "cnn" in report_["feature_sets"]:
        lines += ["", f"The CNN sees each window as `{st.get('cnn_representation', 'waveform')}` "
                      "(waveform: the z-scored window, the study's input; logspec: its log spectrum; residual: the "
                      "window minus its fitted supply line)."]
    study = "; ".join(f"{FEATURE_SETS[k]} {v}" for k, v in report_["study"].items())
    lines += ["", f"The study (Li, Zhao et al. 2024, measured motor current, 4 states) reports: {study}."]
    if report_["notes"]:
        lines += [""] + [f"Note: {n}." for n in report_["notes"]]
    return "\n".join(lines) + "\n"


def _recalls(e: dict) -> str:
    return " / ".join("-" if v is None else f"{100 * v:.0f}" for v in e["recall_per_class"].values())


def _fa(e: dict) -> str:
    return "-" if e["false_alarm_rate"] is None else f"{100 * e['false_alarm_rate']:.1f}"


def protocol_markdown(report_: dict) -> list[str]:
    """The lines of the study / held-out tables (``--protocol study|held-out|both``): per speed and feature set
    the accuracy (mean ± std over the splits), the per-class recall and the false-alarm rate (of the summed
    confusion), and with ``both`` the two protocols side by side and their gap (the protocol's leak)."""
    unit = report_["speed_unit"] or report_["speed_column"]
    st = report_["settings"]
    runs = protocols_run(st["protocol"])
    split = f"{round(100 * (1 - st['test_size']))}/{round(100 * st['test_size'])}"
    first = next(iter(next(iter(report_["results"].values())).values()))
    labels = first[PROTOCOL_KEYS[runs[0]]]["labels"]
    lines = [f"Store `{report_['store']['path']}`, channel `{report_['store']['channel']}`, speeds from "
             f"`{report_['speed_column']}`; {st['repeats']} splits per speed, feature set and protocol, seed "
             f"{st['seed']}; StandardScaler + RBF SVC (C = {st['svm_c']:g}, gamma = {st['svm_gamma']}).", ""]
    if "study" in runs:
        lines.append(f"- study: per state one simulated reducer (drawn per split), its windows split {split} at "
                     "random (the study's protocol: each state a different physical gear);")
    if "held-out" in runs:
        lines.append(f"- held-out: per state about {round(100 * st['test_size'])} % of the simulated reducers, "
                     "with all their windows, on the test side: every test reducer is unseen by the fit;")
    lines += ["- accuracy: mean ± std over the splits (%); recall per class "
              f"({' / '.join(labels)}) and false alarms (healthy windows called faulty) from the confusion summed "
              "over the splits (%).", ""]
    if len(runs) == 2:
        lines += [f"| speed ({unit}) | features | study accuracy | held-out accuracy | leak (points) | "
                  "study recall | held-out recall | study false alarms | held-out false alarms |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for speed, sets in report_["results"].items():
            for name, e in sets.items():
                a, b = e[PROTOCOL_KEYS["study"]], e[PROTOCOL_KEYS["held-out"]]
                gap = 100 * (a["accuracy"]["mean"] - b["accuracy"]["mean"])
                lines.append(f"| {speed} | {FEATURE_SETS[name]} | {_pct(a['accuracy']['mean'])} ± "
                             f"{_pct(a['accuracy']['std'])} | {_pct(b['accuracy']['mean'])} ± "
                             f"{_pct(b['accuracy']['std'])} | {gap:+.1f} | {_recalls(a)} | {_recalls(b)} | "
                             f"{_fa(a)} | {_fa(b)} |")
    else:
        key = PROTOCOL_KEYS[runs[0]]
        lines += [f"| speed ({unit}) | features | {runs[0]} accuracy | kappa | recall | false alarms |",
                  "|---|---|---|---|---|---|"]
        for speed, sets in report_["results"].items():
            for name, e in sets.items():
                a = e[key]
                lines.append(f"| {speed} | {FEATURE_SETS[name]} | {_pct(a['accuracy']['mean'])} ± "
                             f"{_pct(a['accuracy']['std'])} | {a['kappa']['mean']:.3f} | {_recalls(a)} | {_fa(a)} |")
    return lines


def tsne_figure(name: str, panels: dict[str, tuple[np.ndarray, np.ndarray]], unit: str, seed: int,
                max_samples: int):
    """One figure per feature set: a t-SNE panel per speed of the first split's test features."""
    from rvdiag.evaluation.plots import plot_tsne_panels, tsne_embedding

    items = []
    rng = np.random.default_rng(seed)
    for speed, (F, y) in panels.items():
        if len(y) > max_samples:
            keep = np.sort(rng.choice(len(y), max_samples, replace=False))
            F, y = F[keep], y[keep]
        emb = tsne_embedding(F, random_state=seed) if len(y) >= 4 else None
        items.append((f"{speed} {unit}".strip(), emb, y))
    return plot_tsne_panels(items, title=f"t-SNE of {FEATURE_SETS[name]}, test side of the first split")


def write_outputs(result: McsaResult, out_dir: str | Path) -> list[Path]:
    """Write ``mcsa.json``, ``mcsa.md`` and ``tsne_<set>.png`` (one per feature set) into ``out_dir``."""
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rep = result.report
    written = []
    path = out / "mcsa.json"
    path.write_text(json.dumps(rep, indent=2) + "\n", encoding="utf-8")
    written.append(path)
    path = out / "mcsa.md"
    path.write_text(markdown(rep), encoding="utf-8")
    written.append(path)
    st = rep["settings"]
    names = list(result.tsne)
    for i, name in enumerate(names):
        if st["tsne_samples"] > 0:
            fig = tsne_figure(name, result.tsne[name], rep["speed_unit"], int(st["seed"]) % 2**31,
                              int(st["tsne_samples"]))
            path = out / f"tsne_{name}.png"
            fig.savefig(path, dpi=110, bbox_inches="tight")
            plt.close(fig)
            written.append(path)
        report("t-SNE", i + 1, len(names))
    return written


__all__ = ["CNN_REPRESENTATIONS", "DEFAULT_CHANNEL", "DEFAULT_CNN_REPRESENTATION", "FEATURE_SETS", "METRICS",
           "PROTOCOLS", "McsaResult", "McsaSettings", "STUDY_FIGURES", "class_recalls", "held_out_split", "markdown",
           "parse_feature_sets", "pick_channel", "prepare", "protocol_markdown", "protocol_splits", "protocols_run",
           "recall_and_false_alarms", "run_mcsa", "sample_channels", "speed_labels", "split_seeds", "study_split",
           "write_outputs"]
