"""``rvdiag mcsa STORE.zarr -o OUTDIR``: the motor-current study's evaluation protocol in one command.

    rvdiag mcsa STORE.zarr -o OUTDIR [--protocol windows|study|held-out|both] [--test OTHER.zarr]
                [-c/--channel NAME] [--speed-column COLUMN]
                [--feature-sets time,wpt,cnn] [--repeats 10] [--test-size 0.3] [--seed N] [--svm-c C]
                [--wavelet db4] [--wpt-level 4] [--cnn-epochs N] [--cnn-batch-size N] [--cnn-lr LR]
                [--cnn-patience N] [--cnn-input-length N]
                [--cnn-representation logspec|residual|waveform] [--device auto|cpu|cuda] [--tsne-samples N]
                [--overwrite] [--json] [-q]

At each speed of the store and for each feature set: ``--repeats`` splits (``--protocol``: random window
splits over the whole store; the study's one reducer per state with its windows split at random; unseen reducers
on the test side; or the last two side by side), StandardScaler + RBF SVM, accuracy / macro precision / recall / F1 / Cohen's kappa as mean and std over the splits; with
``--test`` also fitted on all of STORE and scored on OTHER.  Writes OUTDIR/mcsa.json, OUTDIR/mcsa.md and
OUTDIR/tsne_<set>.png.  The protocol lives in :mod:`rvdiag.evaluation.motor_current_study`; docs/models.md describes it.
"""

from __future__ import annotations

import json
from pathlib import Path

import typer

from rvdiag.cli import _options as opt
from rvdiag.errors import ParameterError

#: Fields of :class:`rvdiag.evaluation.motor_current_study.McsaSettings` -> the options that set them (for error messages).
OPTION_NAMES = {"feature_sets": "--feature-sets", "seed": "--seed", "repeats": "--repeats",
                "test_size": "--test-size", "svm_c": "--svm-c", "wpt_level": "--wpt-level",
                "cnn_epochs": "--cnn-epochs", "cnn_batch_size": "--cnn-batch-size", "cnn_lr": "--cnn-lr",
                "cnn_patience": "--cnn-patience", "cnn_input_length": "--cnn-input-length",
                "cnn_representation": "--cnn-representation",
                "tsne_samples": "--tsne-samples", "protocol": "--protocol"}


def register(app: typer.Typer) -> None:
    @app.command("mcsa")
    def mcsa(
        store: Path = typer.Argument(..., help="Sample store (.zarr) with samples at one or more speeds."),
        out: Path = opt.out("Folder to write mcsa.json, mcsa.md and tsne_<set>.png into."),
        test: Path = typer.Option(None, "--test",
                                  help="A second store (e.g. other simulations of the same states and speeds): "
                                       "also fit on all of STORE at each speed and score these unseen samples."),
        channel: str = opt.channel("Channel to classify: a name or regular expression (default: the phase "
                                   "current i_a when the store has it, else its first channel)."),
        speed_column: str = typer.Option("output_speed_deg_s", "--speed-column",
                                         help="Metadata column whose values group the samples by operating speed."),
        feature_sets: str = typer.Option("time,wpt,cnn", "--feature-sets",
                                         help="Comma-separated: time (10 time-domain statistics) | wpt (level-4 "
                                              "wavelet-packet energies) | cnn (features of the spectrum-cnn)."),
        protocol: str = typer.Option("windows", "--protocol",
                                     help="windows: random splits over every window of the store | study: one "
                                          "simulated reducer per state, its windows split at random (the study's "
                                          "protocol) | held-out: unseen reducers tested (needs >= 2 simulations "
                                          "per state and speed) | both: study and held-out side by side, their "
                                          "gap the protocol's leak."),
        repeats: int = typer.Option(10, "--repeats", help="Random splits per speed and feature set."),
        test_size: float = typer.Option(0.3, "--test-size", help="Share of each class on the test side of a split."),
        seed: int = opt.seed("Seed the split seeds (and CNN seeds) derive from; recorded in mcsa.json."),
        svm_c: float = typer.Option(10.0, "--svm-c", help="C of the RBF SVM (gamma 'scale'), for every feature set."),
        wavelet: str = typer.Option("db4", "--wavelet", help="wpt: the wavelet of the packet decomposition."),
        wpt_level: int = typer.Option(4, "--wpt-level", help="wpt: decomposition level (2^level bands)."),
        cnn_epochs: int = typer.Option(30, "--cnn-epochs", help="cnn: maximum training epochs per split "
                                                               "(early stopping may end sooner)."),
        cnn_batch_size: int = typer.Option(32, "--cnn-batch-size", help="cnn: mini-batch size."),
        cnn_lr: float = typer.Option(1e-3, "--cnn-lr", help="cnn: Adam learning rate."),
        cnn_patience: int = typer.Option(5, "--cnn-patience", help="cnn: early-stopping patience (epochs)."),
        cnn_input_length: int = typer.Option(None, "--cnn-input-length",
                                             help="cnn: network input in points (default 4096, or the sample "
                                                  "length when shorter)."),
        cnn_representation: str = typer.Option(None, "--cnn-representation",
                                               help="cnn: what the network sees of each window: logspec (its "
                                                    "log spectrum; the default) | residual (the window minus its "
                                                    "fitted supply line) | waveform (the z-scored window, the "
                                                    "study's input; at chance on unseen simulations, "
                                                    "docs/results.md)."),
        device: str = typer.Option("auto", "--device", help="cnn: auto | cpu | cuda"),
        tsne_samples: int = typer.Option(600, "--tsne-samples",
                                         help="At most this many test samples per speed in each t-SNE panel "
                                              "(0: no t-SNE figures)."),
        overwrite: bool = opt.overwrite("Replace the outputs of an earlier run in the --out folder."),
        json_out: bool = opt.json_flag("Print mcsa.json on stdout instead of the table."),
        quiet: bool = opt.quiet(),
    ) -> None:
        """The motor-current study's protocol (Li, Zhao et al. 2024) on a store: per speed and feature set,
        repeated stratified splits and an SVM; optionally a held-out store.  Progress on stderr (-q: none)."""
        from rvdiag.cli._progress import progress_bars
        from rvdiag.datasets import SampleStore
        from rvdiag.evaluation.motor_current_study import McsaSettings, markdown, parse_feature_sets, run_mcsa, write_outputs

        if out.exists() and not out.is_dir():
            raise ParameterError(f"--out {out} exists and is not a folder")
        if (out / "mcsa.json").exists() and not overwrite:
            raise ParameterError(f"{out} already holds the results of a run; use --overwrite to replace them")
        with opt.option_names(OPTION_NAMES):
            chosen = {} if cnn_representation is None else {"cnn_representation": cnn_representation}
            settings = McsaSettings(**chosen, feature_sets=parse_feature_sets(feature_sets), repeats=repeats,
                                    test_size=test_size, seed=seed, speed_column=speed_column, channel=channel,
                                    svm_c=svm_c, wavelet=wavelet, wpt_level=wpt_level, cnn_epochs=cnn_epochs,
                                    cnn_batch_size=cnn_batch_size, cnn_lr=cnn_lr, cnn_patience=cnn_patience,
                                    cnn_input_length=cnn_input_length, device=device, tsne_samples=tsne_samples,
                                    protocol=protocol)
            settings.check()
        if "cnn" in settings.feature_sets:
            from rvdiag.models.torch_estimator import resolve_device

            resolve_device(device)  # 'cuda' without a GPU fails now, not after the first feature sets
        data = SampleStore.open(store)
        other = SampleStore.open(test) if test is not None else None
        with progress_bars(quiet), opt.option_names(OPTION_NAMES):
            result = run_mcsa(data, settings, other)  # a store problem fails before the first fit
            written = write_outputs(result, out)
        if json_out:
            typer.echo(json.dumps(result.report, indent=2))
        else:
            typer.echo(markdown(result.report), nl=False)
        for path in written:
            typer.echo(f"wrote {path}", err=json_out)
