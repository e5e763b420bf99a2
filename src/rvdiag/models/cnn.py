"""One-dimensional convolutional networks for raw vibration / current windows.

Three architectures, all taking a batch of shape ``(n, 1, input_length)`` and returning class logits
(softmax is applied by the loss / by :meth:`predict_proba`, never inside the net):

``cnn1d`` — :class:`PaperCNN1D`, the dynamics-model-driven study's network (docs/references.md), exactly as its §3
    (network figure and table) gives it::

        Conv(k5, s2, p2) ReLU -> Conv(k3, s1, p1) ReLU -> MaxPool 2 -> Conv(k3, s1, p1) ReLU -> MaxPool 2
        -> Flatten -> Dropout 0.9 -> FC 6400 ReLU -> Dropout 0.5 -> FC 320 ReLU -> FC n_classes

    The paper prints an FC input of 12,800 but not the channel counts.  The length after the conv stack
    is ``L1 = floor((L + 4 - 5) / 2) + 1`` then two halvings, i.e. ``L / 8`` for L a multiple of 8; with
    **16 channels in every conv layer** and the paper's window of **6400 points** this gives
    ``16 x 800 = 12,800`` — the only consistent reading (8000 points would give 16,000).  We therefore
    use 16/16/16 channels and derive the flatten size from ``input_length`` (:func:`conv_output_length`).
    The first FC layer then holds 12,800 x 6,400 + 6,400 = 81.9 million parameters.

``cnn1d-lean`` — :class:`LeanCNN1D`, the same three conv layers (16/16/16 channels, same kernels,
    strides, pools) followed by a fourth conv (32 channels) and global average + max pooling, then
    Dropout 0.5 -> FC 32 ReLU -> FC n_classes.  It replaces the 82 M-parameter FC block with ~5 k
    parameters, trains an order of magnitude faster on a CPU, and accepts any input length (the global
    pooling makes the head independent of the length).  See ``docs/models.md`` for the comparison.

``spectrum-cnn`` — :class:`SpectrumCNN` (``mcsa-cnn`` before), the motor-current study's network (Li, Zhao
    et al. 2024, Table 5), named for what rvdiag uses it for by default: its flattened FC head keeps where a
    feature lies, so on a log spectrum it knows the frequency of a line.  Table 5: input 4096 points; conv kernel 7 / 8 channels; max-pool 3 stride 2; conv 5 / 8; pool;
    conv 3 / 16; pool; FC 32; output.  The table gives no padding: we use "same" padding (k // 2),
    stride 1 in the convs, and ReLU after each conv and the FC layer.  The 32-unit FC output is the
    feature vector used by the CNN + SVM pipeline (:mod:`rvdiag.models.cnn_features`).

Every network exposes ``features(x)``: the activations of the last hidden layer (input to the output
layer), used for the t-SNE map of the report and as learned features.
"""

from __future__ import annotations

import torch
from torch import nn

from rvdiag.errors import ParameterError
from rvdiag.registry import CNN_MODELS, OLD_MODEL_NAMES

ARCHITECTURES = CNN_MODELS  # the names are registered below every layer (rvdiag.registry)

#: Native input length of each architecture (points per window).  ``None``: any length.
DEFAULT_INPUT_LENGTH = {"cnn1d": 6400, "cnn1d-lean": None, "spectrum-cnn": 4096}


def architecture_name(name: str) -> str:
    """The architecture's name now: an old spelling (:data:`rvdiag.registry.OLD_MODEL_NAMES`, e.g. ``mcsa-cnn`` in
    the card of a model saved before the rename) maps to its new name; other names are returned as they are."""
    return OLD_MODEL_NAMES.get(name, name)


def conv_output_length(length: int, kernel: int, stride: int = 1, padding: int = 0) -> int:
    """Output length of a 1-D convolution or pooling (PyTorch's floor formula, dilation 1).

    >>> conv_output_length(6400, 5, 2, 2)
    3200
    """
    return (length + 2 * padding - kernel) // stride + 1


def paper_flatten_size(input_length: int, channels: int = 16) -> int:
    """Flatten size of :class:`PaperCNN1D` for a given input length.

    >>> paper_flatten_size(6400)   # the paper's FC input
    12800
    >>> paper_flatten_size(8000)
    16000
    """
    n = conv_output_length(input_length, 5, 2, 2)
    n = conv_output_length(n, 3, 1, 1)
    n = conv_output_length(n, 2, 2)
    n = conv_output_length(n, 3, 1, 1)
    n = conv_output_length(n, 2, 2)
    return channels * n


class PaperCNN1D(nn.Module):
    """The dynamics paper's 1-D CNN (dynamics-model-driven study, §3); see the module docstring.

    Parameters
    ----------
    n_classes : int
    input_length : int
        Points per window (6400 in the paper).  The flatten size is derived from it.
    channels : int
        Channels of every conv layer (16 reproduces the paper's FC input of 12,800 at 6400 points).
    fc_hidden : tuple of int
        Widths of the two hidden FC layers, (6400, 320) in the paper.  Smaller values are only for tests.
    """

    def __init__(self, n_classes: int, input_length: int = 6400, channels: int = 16,
                 fc_hidden: tuple[int, int] = (6400, 320)):
        super().__init__()
        if input_length < 8:
            raise ParameterError(f"cnn1d needs windows of at least 8 points, got {input_length}")
        self.input_length = int(input_length)
        self.flatten_size = paper_flatten_size(input_length, channels)
        self.conv = nn.Sequential(
            nn.Conv1d(1, channels, 5, stride=2, padding=2), nn.ReLU(),
            nn.Conv1d(channels, channels, 3, stride=1, padding=1), nn.ReLU(),
            nn.MaxPool1d(2),
            nn.Conv1d(channels, channels, 3, stride=1, padding=1), nn.ReLU(),
            nn.MaxPool1d(2),
        )
        self.hidden = nn.Sequential(
            nn.Flatten(), nn.Dropout(0.9),
            nn.Linear(self.flatten_size, fc_hidden[0]), nn.ReLU(), nn.Dropout(0.5),
            nn.Linear(fc_hidden[0], fc_hidden[1]), nn.ReLU(),
        )
        self.out = nn.Linear(fc_hidden[1], n_classes)

    def features(self, x: torch.Tensor) -> torch.Tensor:
        """Activations of the 320-unit layer, shape (n, 320)."""
        return self.hidden(self.conv(x))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.out(self.features(x))


class LeanCNN1D(nn.Module):
    """The paper's conv stack with a global-pooling head instead of the 82 M-parameter FC block.

    Parameters
    ----------
    n_classes : int
    input_length : int or None
        Recorded only; the network accepts any length >= 1.
    channels : int
        Channels of the three paper conv layers (16).
    """

    def __init__(self, n_classes: int, input_length: int | None = None, channels: int = 16):
        super().__init__()
        self.input_length = input_length
        c2 = 2 * channels
        self.conv = nn.Sequential(
            nn.Conv1d(1, channels, 5, stride=2, padding=2), nn.BatchNorm1d(channels), nn.ReLU(),
            nn.Conv1d(channels, channels, 3, stride=1, padding=1), nn.BatchNorm1d(channels), nn.ReLU(),
            nn.MaxPool1d(2, ceil_mode=True),
            nn.Conv1d(channels, channels, 3, stride=1, padding=1), nn.BatchNorm1d(channels), nn.ReLU(),
            nn.MaxPool1d(2, ceil_mode=True),
            nn.Conv1d(channels, c2, 3, stride=1, padding=1), nn.BatchNorm1d(c2), nn.ReLU(),
        )
        self.hidden = nn.Sequential(nn.Dropout(0.5), nn.Linear(2 * c2, 32), nn.ReLU())
        self.out = nn.Linear(32, n_classes)

    def features(self, x: torch.Tensor) -> torch.Tensor:
        """Activations of the 32-unit layer, shape (n, 32)."""
        h = self.conv(x)
        pooled = torch.cat([h.mean(dim=2), h.amax(dim=2)], dim=1)
        return self.hidden(pooled)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.out(self.features(x))


class SpectrumCNN(nn.Module):
    """The CNN of Li, Zhao et al. 2024 (motor current, Table 5); see the module docstring.

    Parameters
    ----------
    n_classes : int
    input_length : int
        4096 in the paper; the flatten size is derived from it.
    """

    def __init__(self, n_classes: int, input_length: int = 4096):
        super().__init__()
        if input_length < 4:
            raise ParameterError(f"spectrum-cnn needs windows of at least 4 points, got {input_length}")
        self.input_length = int(input_length)
        self.conv = nn.Sequential(
            nn.Conv1d(1, 8, 7, padding=3), nn.ReLU(), nn.MaxPool1d(3, 2, ceil_mode=True),
            nn.Conv1d(8, 8, 5, padding=2), nn.ReLU(), nn.MaxPool1d(3, 2, ceil_mode=True),
            nn.Conv1d(8, 16, 3, padding=1), nn.ReLU(), nn.MaxPool1d(3, 2, ceil_mode=True),
        )
        with torch.no_grad():
            self.flatten_size = int(self.conv(torch.zeros(1, 1, self.input_length)).numel())
        self.hidden = nn.Sequential(nn.Flatten(), nn.Linear(self.flatten_size, 32), nn.ReLU())
        self.out = nn.Linear(32, n_classes)

    def features(self, x: torch.Tensor) -> torch.Tensor:
        """Activations of the FC-32 layer, shape (n, 32)."""
        return self.hidden(self.conv(x))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.out(self.features(x))


#: the old name of :class:`SpectrumCNN`
McsaCNN = SpectrumCNN


def build_network(architecture: str, n_classes: int, input_length: int, **kw) -> nn.Module:
    """Instantiate one of :data:`ARCHITECTURES` for ``n_classes`` and windows of ``input_length`` points."""
    if architecture == "cnn1d":
        return PaperCNN1D(n_classes, input_length, **kw)
    if architecture == "cnn1d-lean":
        return LeanCNN1D(n_classes, input_length, **kw)
    architecture = architecture_name(architecture)
    if architecture == "spectrum-cnn":
        return SpectrumCNN(n_classes, input_length, **kw)
    raise ParameterError(f"unknown architecture {architecture!r}; choose one of {', '.join(ARCHITECTURES)}")


def count_parameters(net: nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in net.parameters() if p.requires_grad)
