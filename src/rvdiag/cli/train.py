"""``rvdiag train``: train a CNN or a classical model on a sample store and save it as a model directory.

    rvdiag train DATA.zarr -o MODEL_DIR [--model cnn1d|cnn1d-lean|spectrum-cnn|svm|kelm|kelm-mpa|kelm-ga|kelm-pso]
                 [--features time|spectrum|spectrum-abs|logspec|envelope|bearing-envelope|wpd|eemd|none|cnn]
                 [--epochs N] [--device auto|cpu|cuda] [--seed N] [--repeat N]
                 [--bearing-geometry N_BALLS,D_BALL_MM,D_PITCH_MM,CONTACT_DEG] [--rpm-column NAME]
                 [--where COND]... [--streaming | --no-streaming] [--multilabel]

Feature sets join with '+' (``--features spectrum-abs+bearing-envelope``).  ``bearing-envelope`` needs the
bearing's geometry and reads each sample's shaft speed (rev/min) from the store's metadata column
``--rpm-column``; the model card records the column, and ``evaluate`` / ``diagnose`` supply it.

With no options it trains the setup docs/results.md recommends (:data:`rvdiag.registry.RECOMMENDED_TRAINING`:
``spectrum-cnn`` on ``--representation logspec``, 40 epochs, lr 3e-3, patience 6).  The model names are those of
:mod:`rvdiag.registry`.  Trains on the store's ``train`` split, scores the ``test`` split (when present) into
the model card, and with ``--repeat N`` trains N seeds (seed, seed+1, ...) and prints best / mean accuracy per
class.

``--multilabel`` (classical models, stores of the states T1..T6) trains three binary classifiers (broken, worn,
cracked) instead of one six-class classifier and decodes each sample to the state of largest joint probability
(:mod:`rvdiag.models.multilabel`); the model still predicts T1..T6.

Prediction sets (:mod:`rvdiag.models.conformal`): ``--calibration-fraction`` (default 0.2) of each state's training
reducers (metadata column ``unit``) are held out of the fit, and the model's probabilities on their samples calibrate
class-conditional split-conformal sets, stated at ``--healthy-coverage`` (0.95) for the healthy state and
``--fault-coverage`` (0.90) for each fault; the card's ``prediction_sets`` holds the thresholds and the held-out
reducers, and ``evaluate`` / ``diagnose`` give the sets.  No reducer is held out (and there are no sets) where a state
would get fewer samples than its coverage needs (19 for 95 %, 9 for 90 %), or with ``--calibration-fraction 0``.

``--streaming`` (CNN models) reads the training samples from the store a block at a time instead of loading the
split (:mod:`rvdiag.models.streaming`): memory stays flat whatever the library's size.  A CNN streams without being
asked when its training split's signals exceed 2 GiB (``--no-streaming`` loads it anyway); smaller stores train in
memory as before, with the same results.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Optional

import numpy as np
import typer

from rvdiag.cli import _options as opt
from rvdiag.cli._progress import bar_columns, progress_bars, stderr_console
from rvdiag.workflows.training_store import signal_info, training_store_info
from rvdiag.errors import ParameterError, StoreError
from rvdiag.models.conformal import FAULT_COVERAGE, HEALTHY_COVERAGE
from rvdiag.registry import CLASSICAL_MODELS, CNN_MODELS, OLD_MODEL_NAMES, RECOMMENDED_TRAINING

#: Python parameters of :class:`rvdiag.models.torch_estimator.CNNClassifier` -> the options that set them.
CNN_OPTION_NAMES = {"max_epochs": "--epochs", "batch_size": "--batch-size", "n_iter_no_change": "--patience",
                    "validation_fraction": "--validation-fraction", "learning_rate": "--lr",
                    "input_length": "--input-length", "normalize": "--normalize",
                    "representation": "--representation", "architecture": "--model"}


def _with_noise(samples, snr_db: float, seed: list[int]):
    """``samples`` with white Gaussian noise at ``snr_db`` below each sample's power (seeded)."""
    import dataclasses

    from rvdiag.dynamics.noise import add_awgn

    noisy = add_awgn(samples.X, float(snr_db), np.random.default_rng(seed)).astype(np.float32)
    return dataclasses.replace(samples, X=noisy)


def validation_groups(store, samples):
    """Groups for the early-stopping validation split: the simulation (``unit``) of each sample when a state has
    several simulations (each is a reducer of its own: the validation set then holds reducers the network did not
    train on, as the test split does; split by segment, it would hold windows of the training reducers and stop on
    their fingerprints), or when the store's segments overlap (a split by segment would then leak: neighbours share
    points); else None (split by segment).  A paper-mode library (one simulation per state, ``hop =
    segment_length``) so gets a real validation set instead of none at all."""
    units = samples.meta.get("unit")
    if units is None:
        return None
    y = getattr(samples, "y", None)
    if y is not None and len(y) == len(units):
        units_arr, y_arr = np.asarray(units), np.asarray(y)
        if any(np.unique(units_arr[y_arr == c]).size > 1 for c in np.unique(y_arr)):
            return units
    signal = (store.attrs.get("config") or {}).get("signal") or {}
    hop, seg = signal.get("hop"), signal.get("segment_length")
    if hop is not None and seg is not None and int(hop) >= int(seg):
        return None
    return units


def features_kw(features: str, *, epochs: int, device: str, seed: int, lr: float, batch_size: int,
                bearing_geometry: str | None, rpm_column: str, fs: float | None,
                speed_column: str = "output_speed_deg_s", signal: str = "vibration") -> dict:
    """Arguments of each part of a ``--features`` value (a dict per part name for names joined by '+');
    ``signal`` (the store's: vibration or current) picks the CNN features' input representation."""
    from rvdiag.features.bearing import geometry_from_mm
    from rvdiag.models.pipelines import feature_names

    parts = features.split("+")
    for name in parts:
        if name not in feature_names():
            raise ParameterError(f"unknown feature set {name!r}; use one of {'|'.join(feature_names())} "
                                 "(or several joined by '+')")
    if bearing_geometry is not None and "bearing-envelope" not in parts:
        raise ParameterError("--bearing-geometry applies to --features bearing-envelope only")
    kw: dict[str, dict] = {}
    for name in parts:
        if name == "cnn":
            from rvdiag.models.cnn_features import default_representation

            kw[name] = {"max_epochs": epochs, "device": device, "random_state": seed, "learning_rate": lr,
                        "batch_size": batch_size, "representation": default_representation(signal)}
        elif name == "bearing-envelope":
            if bearing_geometry is None:
                raise ParameterError("--features bearing-envelope needs --bearing-geometry "
                                     "N_BALLS,D_BALL_MM,D_PITCH_MM,CONTACT_DEG (e.g. 9,7.94,39.04,0 for a 6205)")
            kw[name] = {**geometry_from_mm(bearing_geometry), "fs": fs, "speed_column": rpm_column}
        elif name in ("tsa-ci", "tsa-mod", "tsa-ci-z", "tsa-mod-z", "orders"):  # angle-domain features: the store's rate and each window's speed
            kw[name] = {"fs": fs, "speed_column": speed_column}
    return kw if len(parts) > 1 else kw.get(features, {})


def build_estimator(model: str, features: str | None, *, epochs: int, device: str, seed: int,
                    batch_size: int, lr: float, input_length: int | None, patience: int,
                    validation_fraction: float, normalize: str = "window", representation: str = "waveform",
                    bearing_geometry: str | None = None, rpm_column: str = "rpm", fs: float | None = None,
                    speed_column: str = "output_speed_deg_s", multilabel: bool = False, signal: str = "vibration"):
    """A fresh, unfitted estimator for a ``--model`` name (``fs``: the store's, for bearing-envelope;
    ``signal``: the store's, vibration or current, for the cnn features' representation)."""
    if multilabel and model not in CLASSICAL_MODELS:
        raise ParameterError(f"--multilabel applies to the classical models ({'|'.join(CLASSICAL_MODELS)}), "
                             f"not {model!r}")
    if model in CNN_MODELS:
        if features is not None:
            raise ParameterError(f"--features does not apply to the CNN model {model!r} (it learns its features); "
                                 "for CNN features + SVM use --model svm --features cnn")
        from rvdiag.models.torch_estimator import CNNClassifier

        return CNNClassifier(architecture=model, input_length=input_length, max_epochs=epochs, device=device,
                             random_state=seed, batch_size=batch_size, learning_rate=lr,
                             n_iter_no_change=patience, validation_fraction=validation_fraction,
                             normalize=normalize, representation=representation, fs=fs,
                             speed_column=speed_column)
    if model in CLASSICAL_MODELS:
        from rvdiag.models.pipelines import make_classical_model

        feats = features or "wpd"
        kw = features_kw(feats, epochs=epochs, device=device, seed=seed, lr=lr, batch_size=batch_size,
                         bearing_geometry=bearing_geometry, rpm_column=rpm_column, fs=fs,
                         speed_column=speed_column, signal=signal)
        return make_classical_model(model, feats, seed=seed, features_kw=kw, multilabel=multilabel)
    raise ParameterError(f"unknown model {model!r}; use one of {'|'.join(CNN_MODELS + CLASSICAL_MODELS)}")


def _fit(est, X, y, quiet: bool, label: str, groups=None, source=None):
    """Fit with a rich progress bar per epoch (CNN), or the bars of the stages a classical fit reports (EEMD
    features, MPA / GA / PSO tuning; :mod:`rvdiag.cli._progress`), each with an ETA, on stderr.  With ``source``
    (a :class:`rvdiag.models.streaming.StoreSamples`) the CNN streams its samples from the store instead of ``X``."""
    from rich.progress import Progress, TextColumn

    console = stderr_console()
    if hasattr(est, "embed"):
        cols = [*bar_columns(), TextColumn("{task.fields[info]}")]
        with Progress(*cols, console=console, disable=quiet, transient=False) as prog:
            task = prog.add_task(f"{label} epochs", total=est.max_epochs, info="")

            def cb(rec):
                info = f"loss {rec['loss']:.4f}"
                if rec["val_accuracy"] is not None:
                    info += f"  val loss {rec['val_loss']:.4f}  val acc {100 * rec['val_accuracy']:.1f} %"
                prog.update(task, completed=rec["epoch"], info=info)
                if not quiet and not console.is_terminal:  # a log file gets one line per epoch
                    console.print(f"{label} epoch {rec['epoch']}/{rec['max_epochs']}: {info} ({rec['seconds']:.1f} s)",
                                  soft_wrap=True)

            if source is not None:
                est.fit_store(source, callback=cb, groups=groups)
            else:
                est.fit(X, y, callback=cb, groups=groups)
            prog.update(task, total=est.n_epochs_, completed=est.n_epochs_,
                        info=f"stopped after {est.n_epochs_} epochs, kept epoch {est.best_epoch_}")
    else:
        _check_class_counts(est, y)
        if not quiet:
            console.print(f"{label}: fitting", soft_wrap=True)
        with progress_bars(quiet):
            est.fit(X, y)
    return est


def _check_class_counts(est, y) -> None:
    """Refuse, in one line, a training split too small for the classifier's internal cross-validation (the
    SVM's probability calibration splits each class 3 ways: ``CalibratedClassifierCV(cv=3)``)."""
    cv = getattr(est[-1] if hasattr(est, "steps") else est, "cv", None)
    if not isinstance(cv, int):
        return
    classes, counts = np.unique(np.asarray(y), return_counts=True)
    if counts.min() < cv:
        c = classes[int(np.argmin(counts))]
        raise ParameterError(f"class {c!r} has {int(counts.min())} training sample(s); the classifier's "
                             f"{cv}-fold probability calibration needs at least {cv} per class: build more "
                             "simulations or shorter samples")


def register(app: typer.Typer) -> None:
    @app.command("train")
    def train(
        data: Path = typer.Argument(..., help="Sample store (.zarr) from 'rvdiag library build' or 'rvdiag dataset'."),
        model: str = typer.Option(None, "--model", "-m",
                                  help=" | ".join(CNN_MODELS + CLASSICAL_MODELS) + " | baseline-monitor (default: "
                                       "the recommended setup of docs/results.md; on a paired store, "
                                       "baseline-monitor: docs/monitoring.md)"),
        features: str = typer.Option(None, "--features", "-f",
                                     help="Classical models: time | spectrum | spectrum-abs | logspec | envelope | "
                                          "bearing-envelope | wpd | eemd | tsa-ci | tsa-mod | tsa-ci-z | tsa-mod-z | "
                                          "orders | none | cnn, or several joined by '+' (default wpd).  A "
                                          "baseline monitor (paired store): tsa-change (default) | orders (default on a "
                                          "motor-current store) | orders+tsa-change | current-lines."),
        out: Path = opt.out("Model directory to write (replaced whole with --overwrite)."),
        overwrite: bool = opt.overwrite("Replace an existing --out model directory (whole: no file of the old "
                                        "model is left)."),
        epochs: int = typer.Option(RECOMMENDED_TRAINING["epochs"], "--epochs",
                                   help="CNN: maximum epochs (early stopping may end sooner)."),
        device: str = typer.Option("auto", "--device", help="auto | cpu | cuda"),
        seed: int = opt.seed("Random seed (weights, validation split, batch order)."),
        repeat: int = typer.Option(1, "--repeat", help="Train N seeds (seed .. seed+N-1); report best/mean per class."),
        batch_size: int = typer.Option(32, "--batch-size", help="CNN mini-batch size."),
        lr: float = typer.Option(RECOMMENDED_TRAINING["lr"], "--lr", help="CNN Adam learning rate."),
        input_length: int = typer.Option(None, "--input-length",
                                         help="CNN input in points (default: 6400 cnn1d, 4096 spectrum-cnn, sample length for cnn1d-lean)."),
        patience: int = typer.Option(RECOMMENDED_TRAINING["patience"], "--patience",
                                     help="CNN early-stopping patience (epochs)."),
        validation_fraction: float = typer.Option(0.2, "--validation-fraction",
                                                  help="Share of training samples held out for early stopping."),
        normalize: str = typer.Option("window", "--normalize",
                                      help="CNN input normalisation: window (z-score each window) | global "
                                           "(training mean/std, keeps amplitude) | none."),
        representation: str = typer.Option(RECOMMENDED_TRAINING["representation"], "--representation",
                                           help="CNN input: logspec (log-magnitude spectrum of each window; "
                                                "docs/models.md) | waveform (the time window, as in the paper) | "
                                                "orders (each sample resampled to the sun shaft's angle at its "
                                                "--speed-column) | orders-residual (its TSA residual)."),
        snr_db: float = opt.snr_db("Add white Gaussian noise at this SNR (dB, per sample) to the training and "
                                   "test samples before training, seeded by --seed: one point of an "
                                   "accuracy-against-SNR curve from a clean library (docs/results.md)."),
        json_out: bool = opt.json_flag("Print the test metrics (and repeat summary) as JSON."),
        quiet: bool = opt.quiet(),
        bearing_geometry: str = typer.Option(None, "--bearing-geometry",
                                             help="bearing-envelope features: N_BALLS,D_BALL_MM,D_PITCH_MM,"
                                                  "CONTACT_DEG of the bearing (e.g. 9,7.94,39.04,0: a 6205)."),
        rpm_column: str = typer.Option("rpm", "--rpm-column",
                                       help="bearing-envelope features: the store's metadata column holding each "
                                            "sample's shaft speed in rev/min (e.g. from dataset from-files "
                                            "--scalar rpm=RPM)."),
        speed_column: str = typer.Option("output_speed_deg_s", "--speed-column",
                                         help="tsa-ci / orders features and --representation orders: the store's "
                                              "metadata column holding each sample's speed, output deg/s (name ending in _deg_s, as a library "
                                              "writes) or input rev/min (ending in _rpm)."),
        conditions: list[str] = typer.Option(None, "--where", metavar="COND",
                                        help="Train only on the training samples whose metadata satisfy COND, COLUMN "
                                             "OP VALUE with OP < <= > >= == != (repeatable; all must hold), e.g. "
                                             "--where 'simulation<10' (a learning curve); the test split is scored "
                                             "whole."),
        streaming: Optional[bool] = typer.Option(None, "--streaming/--no-streaming",
                                                 help="CNN models: read the training samples from the store a block "
                                                      "at a time (memory flat in the store's size) instead of "
                                                      "loading the split. Default: stream when the training split's "
                                                      "signals exceed 2 GiB."),
        multilabel: bool = typer.Option(False, "--multilabel",
                                        help="Classical models: three binary labels (broken, worn, cracked) "
                                             "instead of six exclusive classes, decoded to the most probable of "
                                             "T1..T6 (stores whose states are T1..T6 only; docs/models.md)."),
        alpha: float = typer.Option(None, "--alpha",
                                    help="baseline-monitor: the alarm's false-alarm rate per healthy record "
                                         "(default 0.01; docs/monitoring.md)."),
        calibration: str = typer.Option(
            "split", "--calibration",
            help="How the prediction sets are calibrated: split (hold --calibration-fraction of the reducers out of "
                 "the fit) | cross (score every training reducer by a model fitted on the other "
                 "--calibration-folds folds, then fit on all: K more fits, no reducer lost; docs/models.md)."),
        calibration_folds: int = typer.Option(3, "--calibration-folds", help="--calibration cross: folds of reducers."),
        calibration_fraction: float = typer.Option(
            DEFAULT_CALIBRATION_FRACTION, "--calibration-fraction",
            help="Share of each state's training reducers (metadata column unit) held out of the fit to calibrate "
                 "the prediction sets (docs/models.md); 0: no sets."),
        healthy_coverage: float = typer.Option(HEALTHY_COVERAGE, "--healthy-coverage",
                                               help="Stated coverage of the healthy state (T1) in the sets."),
        fault_coverage: float = typer.Option(FAULT_COVERAGE, "--fault-coverage",
                                             help="Stated coverage of each fault state in the sets."),
    ) -> None:
        """Train a classifier on the train split of a store and save it as a model directory.

        With no options: the recommended setup of docs/results.md (spectrum-cnn on the log spectrum)."""
        from rvdiag.datasets import SampleStore
        from rvdiag.evaluation.metrics import classification_metrics, headline, repeat_summary
        from rvdiag.models.persistence import save_model
        from rvdiag.io.windows import covering_starts

        model = opt.renamed("--model", model, OLD_MODEL_NAMES)
        if repeat < 1:
            raise ParameterError(f"--repeat must be >= 1, got {repeat}")
        if calibration not in ("split", "cross"):
            raise ParameterError(f"--calibration must be split or cross, got {calibration!r}")
        if calibration == "cross" and calibration_folds < 2:
            raise ParameterError(f"--calibration-folds must be >= 2, got {calibration_folds}")
        if not 0.0 <= calibration_fraction < 1.0:
            raise ParameterError(f"--calibration-fraction must lie in [0, 1), got {calibration_fraction}")
        from rvdiag.models.conformal import stated_coverages

        from rvdiag.evaluation.metrics import healthy_class

        def coverage_of(classes) -> dict[str, float]:
            classes = [str(c) for c in classes]
            return stated_coverages(classes, healthy=healthy_class(classes), healthy_coverage=healthy_coverage,
                                    fault_coverage=fault_coverage)

        coverage_of([])  # the coverages are checked before any work
        if epochs < 1:
            raise ParameterError(f"--epochs must be >= 1, got {epochs}")
        if out.exists() and not out.is_dir():
            raise ParameterError(f"--out {out} exists and is not a directory")
        opt.refuse_existing(out, overwrite)
        from rvdiag.monitoring.training import train_monitor, wants_monitor

        if wants_monitor(data, model, alpha, repeat=repeat, snr_db=snr_db, multilabel=multilabel,
                                   streaming=streaming):
            echo = (lambda *a, **k: None) if json_out else (lambda msg: typer.echo(msg, err=True))
            res = train_monitor(SampleStore.open(data), data, out, features=features, alpha=alpha,
                                          seed=seed, conditions=conditions or (), echo=echo,
                                          warn=lambda msg: typer.echo(msg, err=True))
            if json_out:
                typer.echo(json.dumps(res, indent=2))
            return
        model = model or RECOMMENDED_TRAINING["model"]
        new_estimator = functools.partial(build_estimator, model, features, epochs=epochs, device=device,
                                          batch_size=batch_size, lr=lr, input_length=input_length,
                                          patience=patience, validation_fraction=validation_fraction,
                                          normalize=normalize, representation=representation,
                                          bearing_geometry=bearing_geometry, rpm_column=rpm_column,
                                          speed_column=speed_column, multilabel=multilabel)
        with opt.option_names(CNN_OPTION_NAMES):
            probe = new_estimator(seed=seed)  # checks --model/--features before any work
        if model in CNN_MODELS or "cnn" in (features or "").split("+"):
            from rvdiag.models.torch_estimator import resolve_device

            resolve_device(device)  # 'cuda' without a GPU fails now, not after loading the data
        store = SampleStore.open(data)
        new_estimator = functools.partial(new_estimator, signal=signal_info(store)["signal"])  # cnn features
        if "train" not in store.splits():
            raise StoreError(f"{data} has no 'train' split (splits: {', '.join(store.splits())})")
        if multilabel:
            from rvdiag.models.multilabel import check_states

            check_states(store.classes, where=f"the store {data}'s classes")
        conditions = list(conditions or ())
        train_idx = store.indices("train", conditions)
        if conditions and not train_idx.size:
            raise StoreError(f"{data}: no training sample where {' and '.join(conditions)}")
        from rvdiag.features.combine import input_metadata, with_metadata

        meta_cols = input_metadata(probe)
        if meta_cols and not store.fs:
            raise StoreError(f"{data} states no sampling rate, which {', '.join(meta_cols)} needs beside it (to place "
                             "the defect lines, or to resample to the shaft angle): rebuild it with "
                             "'rvdiag dataset from-files --fs HZ'")
        if model in CNN_MODELS:
            with opt.option_names(CNN_OPTION_NAMES):  # the samples must be at least one network input long
                new_estimator(seed=seed, fs=store.fs).network_input_length(store.length)
        stream = _streaming_choice(streaming, model, snr_db, store)
        where = f"the store {data}"
        if stream:
            from rvdiag.models.streaming import DEFAULT_BUFFER_SAMPLES, StoreSamples, predict_proba_store, predict_store

            tr = StoreSamples(store, train_idx, meta_cols, where=where)
            te = StoreSamples(store, store.indices("test"), meta_cols, where=where) if "test" in store.splits() else None
            if calibration == "cross":
                raise ParameterError("--calibration cross fits the folds in memory and does not combine with "
                                     "--streaming (use --calibration split)")
            held, cal_note = calibration_split(tr, calibration_fraction, seed, coverage_of(store.classes))
            cal, folds = None, None
            if held is not None:
                cal = StoreSamples(store, tr.index[held], meta_cols, where=where)
                tr = StoreSamples(store, tr.index[~held], meta_cols, where=where)
            Xtr = Xte = Xcal = None
        else:
            tr = store.load(index=train_idx) if conditions else store.load("train")
            te = store.load("test") if "test" in store.splits() else None
            cal, folds = None, None
            if calibration == "cross":
                folds, cal_note = calibration_folds_of(tr, calibration_folds, seed, coverage_of(store.classes))
            else:
                held, cal_note = calibration_split(tr, calibration_fraction, seed, coverage_of(store.classes))
                if held is not None:
                    tr, cal = subset(tr, ~held), subset(tr, held)
            if snr_db is not None:
                tr, te = _with_noise(tr, snr_db, [seed, 0]), (None if te is None else _with_noise(te, snr_db, [seed, 1]))
                cal = None if cal is None else _with_noise(cal, snr_db, [seed, 3])
            Xtr = with_metadata(tr.X, tr.meta, meta_cols, where=where)
            Xte = None if te is None else with_metadata(te.X, te.meta, meta_cols, where=where)
            Xcal = None if cal is None else with_metadata(cal.X, cal.meta, meta_cols, where=where)
        labels = [c for c in store.classes if c in set(tr.y.tolist())]
        if len(labels) < 2:
            raise StoreError(f"{data}: the train split holds fewer than 2 classes")
        echo = (lambda *a, **k: None) if json_out else (lambda msg: typer.echo(msg, err=True))
        echo(f"{data}: {len(tr.y)} training samples of {store.length} points, {len(labels)} classes"
             + (f", {len(te.y)} test samples" if te is not None else ", no test split")
             + (f"; {len(cal.y)} samples of {_n_groups(cal)} held-out training reducers calibrate the prediction sets"
                if cal is not None else f"; every training reducer calibrates the prediction sets, scored by "
                                        f"{calibration_folds} fold models" if folds is not None
                else f"; no prediction sets ({cal_note})")
             + (f"; streamed from the store, {DEFAULT_BUFFER_SAMPLES} samples at a time" if stream else ""))

        runs, first = [], None
        for r in range(repeat):
            s = seed + r
            est = new_estimator(seed=s, fs=store.fs)
            if r == 0 and model in CNN_MODELS and meta_cols:
                echo(f"note: each sample is resampled to the {est.shaft} shaft's angle at its {est.speed_column} and "
                     f"fitted to the {model} input of {est.network_input_length(store.length)} angle samples "
                     "(docs/models.md)")
            elif r == 0 and model in CNN_MODELS:
                W = est.network_input_length(store.length)
                starts = covering_starts(store.length, W, est.long_input)
                if W != store.length:
                    echo(f"note: samples have {store.length} points and the {model} input is {W}: each sample is cut "
                         f"into {len(starts)} window(s) starting at {starts.tolist()}; training uses every window, "
                         "predictions average them (docs/models.md)")
            _fit(est, Xtr, tr.y, quiet or json_out, f"seed {s}", groups=validation_groups(store, tr),
                 source=tr if stream else None)
            metrics = None
            if te is not None and len(te.y):
                predicted = predict_store(est, te) if stream else est.predict(Xte)
                metrics = classification_metrics(te.y, predicted, labels=[str(c) for c in est.classes_])
                runs.append(metrics)
                echo(f"seed {s}: test {headline(metrics)}, kappa {metrics['kappa']:.4f}")
            if r == 0:
                first = (est, metrics)
        est, metrics = first
        extra: dict = {}
        if cal is not None:
            from rvdiag.evaluation.evaluate import predict_in_chunks
            from rvdiag.models.conformal import PredictionSets

            P = predict_proba_store(est, cal) if stream else predict_in_chunks(est, Xcal, method="predict_proba")
            classes = [str(c) for c in est.classes_]
            sets = PredictionSets.calibrate(
                P, cal.y, classes, coverage_of(classes),
                groups=cal.meta["unit"], source=calibration_source(cal, calibration_fraction, seed))
            extra["prediction_sets"] = sets.to_card()
            if sets.too_few():
                echo(f"note: too few held-out samples of {', '.join(sets.too_few())} for the stated coverage: "
                     "in every prediction set")
        elif folds is not None:
            from rvdiag.models.conformal import PredictionSets

            P = np.zeros((len(tr.y), len(est.classes_)))
            for k in range(calibration_folds):
                part = folds != k
                fold_est = _fit(new_estimator(seed=seed, fs=store.fs), Xtr[part], np.asarray(tr.y)[part],
                                quiet or json_out, f"calibration fold {k + 1}/{calibration_folds}",
                                groups=validation_groups(store, subset(tr, part)))
                if [str(c) for c in fold_est.classes_] != [str(c) for c in est.classes_]:
                    raise StoreError(f"calibration fold {k + 1} lacks a class: use --calibration split")
                P[~part] = fold_est.predict_proba(Xtr[~part])
            classes = [str(c) for c in est.classes_]
            sets = PredictionSets.calibrate(
                P, tr.y, classes, coverage_of(classes), groups=tr.meta["unit"],
                source={"method": "cross", "refit": True, "folds": int(calibration_folds), "seed": [int(seed), 5],
                        "what": "every training reducer (metadata column unit), scored by the model fitted on the "
                                "other folds of reducers; the thresholds apply to the model fitted on all",
                        "n_calibration": int(len(tr.y))})
            extra["prediction_sets"] = sets.to_card()
        else:
            extra["prediction_sets"] = None
            extra["prediction_sets_note"] = cal_note
        novelty, op_range = _novelty_and_range(est, store, train_idx, tr, te, Xtr, Xte, meta_cols, seed, stream,
                                               where)
        store_info = training_store_info(store, data, len(tr.y) + (0 if cal is None else len(cal.y)))
        extra.update({} if snr_db is None else {"added_noise": {"snr_db": float(snr_db), "seed": [seed, 0],
                                                                "applies_to": "train and test splits"}})
        extra["operating_range"] = op_range
        if conditions:
            extra["train_where"] = conditions
        if stream:
            extra["streaming"] = {"buffer_samples": int(est.stream_buffer_samples_)}
        scalars = (store.attrs.get("config") or {}).get("scalars") or {}
        if meta_cols:  # where diagnose finds each column in a measured file (the store's --scalar regex)
            extra["metadata_sources"] = {c: scalars[c] for c in meta_cols if c in scalars}
        summary = None
        if repeat > 1 and runs:
            summary = repeat_summary(runs)
            extra["repeat"] = {"seeds": list(range(seed, seed + repeat)), **summary}
        repeat_file = {} if summary is None else {"repeat.json": json.dumps(summary, indent=2).encode()}
        save_model(est, out, model=model, features=(features or "wpd") if model in CLASSICAL_MODELS else None,
                   fs=store.fs, training_store=store_info, metrics=metrics or {}, seed=seed, extra=extra,
                   novelty=novelty, files=repeat_file)
        if json_out:
            typer.echo(json.dumps({"model_dir": str(out), "metrics": metrics, "repeat": summary}, indent=2))
            return
        if summary is not None:
            _print_repeat(summary, seed, repeat)
        echo(f"saved model to {out}" + (" (the first seed's model; repeat.json holds the summary)" if repeat > 1 else ""))


#: share of each state's training reducers held out of the fit to calibrate the prediction sets
DEFAULT_CALIBRATION_FRACTION = 0.2


def calibration_split(tr, fraction: float, seed: int, coverage: dict[str, float]):
    """The training samples held out to calibrate the prediction sets (:func:`rvdiag.models.conformal.split_by_group`:
    whole reducers, the metadata column ``unit``, ``fraction`` of each state's, drawn with ``[seed, 4]``), as a
    boolean mask, and None; or None and the reason there are none (``fraction`` 0, no ``unit`` column, a state
    with too few held-out samples for its stated ``coverage``: then nothing is held out and the fit keeps every
    sample)."""
    from rvdiag.models.conformal import min_calibration_samples, split_by_group

    if fraction <= 0:
        return None, "--calibration-fraction 0"
    units = tr.meta.get("unit")
    if units is None:
        return None, "the store has no reducer column (unit) to hold whole reducers out of the fit"
    held = split_by_group(tr.y, units, fraction, [seed, 4])
    y = np.asarray(tr.y).astype(str)
    for c in np.unique(y):
        n, need = int(np.sum(held & (y == c))), min_calibration_samples(coverage[str(c)])
        if n < need:
            return None, (f"{n} held-out sample(s) of {c}, fewer than the {need} a {100 * coverage[str(c)]:g} % set "
                          "needs: build more reducers (simulations) or raise --calibration-fraction")
    return held, None


def calibration_folds_of(tr, folds: int, seed: int, coverage: dict[str, float]):
    """The fold of each training sample for ``--calibration cross`` (:func:`rvdiag.models.conformal.group_folds`
    over the reducers, metadata column ``unit``, drawn with ``[seed, 5]``), and None; or None and the reason there
    are no sets (no ``unit`` column, a state with fewer reducers than folds or fewer samples than its coverage
    needs)."""
    from rvdiag.models.conformal import group_folds, min_calibration_samples

    units = tr.meta.get("unit")
    if units is None:
        return None, "the store has no reducer column (unit) to fold the reducers"
    y = np.asarray(tr.y).astype(str)
    for c in np.unique(y):
        n, need = int(np.sum(y == c)), min_calibration_samples(coverage[str(c)])
        if n < need:
            return None, f"{n} training sample(s) of {c}, fewer than the {need} a {100 * coverage[str(c)]:g} % set needs"
    try:
        return group_folds(y, units, folds, [seed, 5]), None
    except ParameterError as exc:
        return None, str(exc)


def calibration_source(cal, fraction: float, seed: int) -> dict:
    """Where the calibration samples came from, for the card."""
    held = {str(c): sorted({str(u) for u in np.asarray(cal.meta["unit"])[np.asarray(cal.y) == c]})
            for c in np.unique(np.asarray(cal.y))}
    return {"method": "split", "refit": False, "fraction": float(fraction), "seed": [int(seed), 4],
            "n_calibration": int(len(cal.y)),
            "what": "whole training reducers (metadata column unit) held out of the fit, per state",
            "held_out_reducers": held}


def subset(samples, mask):
    """The loaded samples (:class:`rvdiag.datasets.store.Samples`) where ``mask`` holds."""
    import dataclasses

    return dataclasses.replace(samples, X=samples.X[mask], y=np.asarray(samples.y)[mask],
                               meta={k: np.asarray(v)[mask] for k, v in samples.meta.items()},
                               index=np.asarray(samples.index)[mask])


def _n_groups(cal) -> int:
    return int(len({(str(c), str(u)) for c, u in zip(cal.y, cal.meta["unit"])}))


#: at most this many training (and test) samples fit and calibrate the out-of-distribution check
MAX_NOVELTY_SAMPLES = 2000


def _novelty_and_range(est, store, train_idx, tr, te, Xtr, Xte, meta_cols, seed: int, stream: bool, where: str):
    """The out-of-distribution check of the model (:func:`rvdiag.models.novelty.fit_novelty`: fitted on at most
    :data:`MAX_NOVELTY_SAMPLES` training samples drawn with ``[seed, 2]``, its threshold from as many test samples)
    and the card's ``operating_range`` (:func:`rvdiag.models.conditions.operating_range`) of the training
    samples (of those drawn, when the samples are streamed)."""
    from rvdiag.features.combine import with_metadata
    from rvdiag.models.conditions import operating_range
    from rvdiag.models.novelty import fit_novelty

    rng = np.random.default_rng([seed, 2])

    def draw(n: int) -> np.ndarray:
        return np.sort(rng.choice(n, size=min(n, MAX_NOVELTY_SAMPLES), replace=False))

    if stream:
        rows = np.asarray(train_idx)[draw(len(train_idx))]
        sub = store.load(index=rows)
        X_fit, raw, meta = with_metadata(sub.X, sub.meta, meta_cols, where=where), sub.X, sub.meta
        test_idx = store.indices("test") if te is not None else np.zeros(0, np.int64)
        X_cal = None
        if len(test_idx):
            t = store.load(index=np.asarray(test_idx)[draw(len(test_idx))])
            X_cal = with_metadata(t.X, t.meta, meta_cols, where=where)
    else:
        pick = draw(len(Xtr))
        X_fit, raw, meta = Xtr[pick], tr.X, tr.meta
        X_cal = None if Xte is None or not len(Xte) else Xte[draw(len(Xte))]
    signal = signal_info(store)["signal"]
    unit = ("A" if signal == "current" else "m/s^2") if store.attrs.get("kind") == "simulated" else None
    op = operating_range(meta, raw, store.fs, unit=unit, normalize=getattr(est, "normalize", None))
    return fit_novelty(est, X_fit, X_cal), op


def _streaming_choice(streaming: bool | None, model: str, snr_db: float | None, store) -> bool:
    """Whether to stream the training samples (``--streaming/--no-streaming``; by default a CNN streams when its
    training split's float32 signals exceed :data:`rvdiag.models.streaming.STREAMING_THRESHOLD_BYTES`)."""
    from rvdiag.models.streaming import STREAMING_THRESHOLD_BYTES

    if streaming is None:
        big = len(store.indices("train")) * store.length * 4 > STREAMING_THRESHOLD_BYTES
        return bool(big and model in CNN_MODELS and snr_db is None)
    if streaming and model not in CNN_MODELS:
        raise ParameterError(f"--streaming applies to the CNN models ({'|'.join(CNN_MODELS)}); {model!r} has no "
                             "partial_fit and trains in memory (use --no-streaming or leave it out)")
    if streaming and snr_db is not None:
        raise ParameterError("--snr-db adds noise to the samples in memory and does not combine with --streaming; "
                             "build the library with [operation] noise_snr_db instead")
    return bool(streaming)


def _print_repeat(summary: dict, seed: int, n: int) -> None:
    from rich.console import Console
    from rich.table import Table

    t = Table(title=f"accuracy per class over {n} seeds ({seed}..{seed + n - 1}), test split")
    for col in ("class", "best", "mean", "worst"):
        t.add_column(col, justify="right" if col != "class" else "left")
    for c, v in summary["per_class"].items():
        t.add_row(c, *(f"{100 * v[k]:.2f} %" for k in ("best", "mean", "worst")))
    a = summary["accuracy"]
    t.add_row("overall", *(f"{100 * a[k]:.2f} %" for k in ("best", "mean", "worst")))
    Console().print(t)
