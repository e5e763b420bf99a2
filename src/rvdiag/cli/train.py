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

Prediction sets (:mod:`rvdiag.models.conformal`): ``--calibration cross`` is the default (``split`` with
``--streaming``); ``--calibration split`` holds
``--calibration-fraction`` (0.2) of each state's training reducers (metadata column ``unit``) out of the fit and
calibrates class-conditional conformal sets on them; ``--calibration cross`` scores every training reducer by a
model fitted on the other ``--calibration-folds`` (3) folds of reducers and keeps the model fitted on all (K more
fits).  Stated coverage ``--healthy-coverage`` (0.95) for the healthy state, ``--fault-coverage`` (0.90) for each
fault; the card's ``prediction_sets`` holds the thresholds and where they came from, and ``evaluate`` /
``diagnose`` give the sets.  There are none (the card says why) where a state would get fewer calibration samples
than its coverage needs (19 for 95 %, 9 for 90 %), or with ``--calibration-fraction 0``.

``--streaming`` (CNN models) reads the training samples from the store a block at a time instead of loading the
split (:mod:`rvdiag.models.streaming`): memory stays flat whatever the library's size.  A CNN streams without being
asked when its training split's signals exceed 2 GiB (``--no-streaming`` loads it anyway); smaller stores train in
memory as before, with the same results.

The training itself is :func:`rvdiag.workflows.train` (a monitor's :func:`rvdiag.monitoring.train_monitor`); this
module parses the options, draws the progress bars and prints (``--json``: the result's ``to_dict()``).
"""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Optional

import typer

from rvdiag.cli import _options as opt
from rvdiag.cli._progress import bar_columns, progress_bars, stderr_console
from rvdiag.errors import ParameterError
from rvdiag.registry import CLASSICAL_MODELS, CNN_MODELS, OLD_MODEL_NAMES, RECOMMENDED_TRAINING
from rvdiag.models.conformal import FAULT_COVERAGE, HEALTHY_COVERAGE
from rvdiag.workflows.training import DEFAULT_CALIBRATION_FRACTION, check_class_counts

#: Python parameters of :class:`rvdiag.models.torch_estimator.CNNClassifier` -> the options that set them.
CNN_OPTION_NAMES = {"max_epochs": "--epochs", "batch_size": "--batch-size", "n_iter_no_change": "--patience",
                    "validation_fraction": "--validation-fraction", "learning_rate": "--lr",
                    "input_length": "--input-length", "normalize": "--normalize",
                    "representation": "--representation", "architecture": "--model"}


def _fit(est, X, y, label: str, groups=None, source=None, *, quiet: bool = False):
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
        check_class_counts(est, y)
        if not quiet:
            console.print(f"{label}: fitting", soft_wrap=True)
        with progress_bars(quiet):
            est.fit(X, y)
    return est


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
            None, "--calibration", show_default=False,
            help="How the prediction sets are calibrated: cross (the default: score every training reducer by a "
                 "model fitted on the other --calibration-folds folds, then fit on all: K more fits, no reducer "
                 "lost) | split (hold --calibration-fraction of the reducers out of the fit; the default with "
                 "--streaming; docs/models.md)."),
        calibration_folds: int = typer.Option(3, "--calibration-folds", help="--calibration cross: folds of reducers."),
        calibration_fraction: float = typer.Option(
            DEFAULT_CALIBRATION_FRACTION, "--calibration-fraction",
            help="Share of each state's training reducers (metadata column unit) held out of the fit to calibrate "
                 "the prediction sets (--calibration split; docs/models.md); 0: no sets."),
        healthy_coverage: float = typer.Option(HEALTHY_COVERAGE, "--healthy-coverage",
                                               help="Stated coverage of the healthy state (T1) in the sets."),
        fault_coverage: float = typer.Option(FAULT_COVERAGE, "--fault-coverage",
                                             help="Stated coverage of each fault state in the sets."),
        set_rule: str = typer.Option(
            None, "--set-rule", show_default=False,
            help="How the sets' thresholds count the calibration samples: windows (the default) | reducers "
                 "(coverage for a reducer never seen, Lee, Barber & Willett 2023: larger sets; a state needs 19 "
                 "calibration reducers for 95 %, 9 for 90 %, else it is in every set; docs/models.md)."),
    ) -> None:
        """Train a classifier on the train split of a store and save it as a model directory.

        With no options: the recommended setup of docs/results.md (spectrum-cnn on the log spectrum)."""
        from rvdiag.datasets import SampleStore
        from rvdiag.monitoring.training import train_monitor, wants_monitor
        from rvdiag.workflows.training import check_counts, train as train_model

        model = opt.renamed("--model", model, OLD_MODEL_NAMES)
        check_counts(repeat, epochs)
        if out.exists() and not out.is_dir():
            raise ParameterError(f"--out {out} exists and is not a directory")
        opt.refuse_existing(out, overwrite)
        echo = (lambda *a, **k: None) if json_out else (lambda msg: typer.echo(msg, err=True))
        if wants_monitor(data, model, alpha, repeat=repeat, snr_db=snr_db, multilabel=multilabel,
                         streaming=streaming):
            res = train_monitor(SampleStore.open(data), data, out, features=features, alpha=alpha, seed=seed,
                                conditions=conditions or (), echo=echo, warn=lambda msg: typer.echo(msg, err=True))
            if json_out:
                typer.echo(json.dumps(res, indent=2))
            return
        with opt.option_names(CNN_OPTION_NAMES):
            res = train_model(data, out, model=model, features=features, epochs=epochs, device=device, seed=seed,
                              repeat=repeat, batch_size=batch_size, lr=lr, input_length=input_length,
                              patience=patience, validation_fraction=validation_fraction, normalize=normalize,
                              representation=representation, snr_db=snr_db, bearing_geometry=bearing_geometry,
                              rpm_column=rpm_column, speed_column=speed_column, conditions=conditions or (),
                              streaming=streaming, multilabel=multilabel, echo=echo,
                              fit=functools.partial(_fit, quiet=quiet or json_out), calibration=calibration,
                              calibration_folds=calibration_folds, calibration_fraction=calibration_fraction,
                              healthy_coverage=healthy_coverage, fault_coverage=fault_coverage,
                              set_rule=set_rule)
        if json_out:
            typer.echo(json.dumps(res.to_dict(), indent=2))
            return
        if res.repeat is not None:
            _print_repeat(res.repeat, seed, repeat)
        echo(f"saved model to {out}" + (" (the first seed's model; repeat.json holds the summary)" if repeat > 1 else ""))


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
