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
(this package reports its stages to :mod:`rvdiag.progress`).

The package, one module per concern:

- :mod:`~rvdiag.evaluation.motor_current_study.settings`: the feature sets, protocols and metrics, and
  :class:`McsaSettings`;
- :mod:`~rvdiag.evaluation.motor_current_study.data`: the store's channels and speeds, the samples grouped by speed;
- :mod:`~rvdiag.evaluation.motor_current_study.protocol`: the splits of each protocol;
- :mod:`~rvdiag.evaluation.motor_current_study.fitting`: the fits and scores, :func:`run_mcsa`;
- :mod:`~rvdiag.evaluation.motor_current_study.markdown`: ``mcsa.md``;
- :mod:`~rvdiag.evaluation.motor_current_study.outputs`: the files, with the t-SNE figures.

Everything a caller needs is imported here (``from rvdiag.evaluation.motor_current_study import run_mcsa``).
"""

from rvdiag.evaluation.motor_current_study.data import pick_channel, sample_channels, speed_labels, speed_unit
from rvdiag.evaluation.motor_current_study.fitting import (McsaResult, class_recalls, prepare,
                                                          recall_and_false_alarms, run_mcsa)
from rvdiag.evaluation.motor_current_study.markdown import markdown, protocol_markdown
from rvdiag.evaluation.motor_current_study.outputs import tsne_figure, write_outputs
from rvdiag.evaluation.motor_current_study.protocol import (held_out_split, protocol_splits, protocols_run,
                                                           study_split)
from rvdiag.evaluation.motor_current_study.settings import (CNN_REPRESENTATIONS, DEFAULT_CHANNEL,
                                                           DEFAULT_CNN_REPRESENTATION, FEATURE_SETS, FORMAT, METRICS,
                                                           PROTOCOL_KEYS, PROTOCOLS, STUDY_FIGURES, McsaSettings,
                                                           parse_feature_sets, split_seeds)

__all__ = ["CNN_REPRESENTATIONS", "DEFAULT_CHANNEL", "DEFAULT_CNN_REPRESENTATION", "FEATURE_SETS", "FORMAT", "METRICS",
           "PROTOCOL_KEYS", "PROTOCOLS", "McsaResult", "McsaSettings", "STUDY_FIGURES", "class_recalls",
           "held_out_split", "markdown", "parse_feature_sets", "pick_channel", "prepare", "protocol_markdown",
           "protocol_splits", "protocols_run", "recall_and_false_alarms", "run_mcsa", "sample_channels",
           "speed_labels", "speed_unit", "split_seeds", "study_split", "tsne_figure", "write_outputs"]
