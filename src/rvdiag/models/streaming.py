"""Training on a sample store larger than memory: the samples stream from the Zarr store in shuffled blocks.

A library of 100,000 samples of 4096 points is 1.6 GB of float32; training in memory holds it, its network
inputs (windows, log spectra) and their normalised copies at once.  Streaming holds one block instead.

:class:`StoreSamples` is a selection of a store's samples (a split): its labels and the metadata columns it needs
(those appended to the samples, and ``unit`` for the validation groups), one value per sample, are in memory (a few
MB for 100,000 samples); its signals stay in the store and are read a block at a time
(``zarr.Array.get_orthogonal_selection``, which reads only the chunks that hold the rows asked for).

:class:`StoreStream` (a ``torch.utils.data.IterableDataset``) gives the mini-batches of one epoch: the store's chunks
along the sample axis are visited in a random order (one chunk per sample in every store rvdiag writes, so this is a
random order of the samples), ``buffer_samples`` samples at a time are read, turned into network inputs, shuffled
among themselves together with the inputs left over from the previous buffer, and cut into batches; the inputs that
do not fill a batch go on to the next buffer.  The order comes from the NumPy generator it is given, so an epoch is
reproducible from the training seed.  This is the shuffle-buffer scheme of ``tf.data.Dataset.shuffle`` and of
WebDataset (a random permutation of shards, then a bounded buffer shuffled within; Aizman, Maltby & Breuel 2019, "High
performance I/O for large scale deep learning", IEEE BigData) applied to chunk-per-sample Zarr, where the "shards"
are single samples and the shuffle is a full one.  Peak memory does not grow with the store: one buffer of samples
and its network inputs, whatever the number of samples (``bench/large_library.py`` measures it).

The classical models (``svm``, ``kelm*``) have no ``partial_fit`` (scikit-learn's ``SVC`` and the KELM solve one
kernel system over all training samples) and train in memory: streaming is for the CNN models only.
"""

from __future__ import annotations

from typing import Any, Callable, Iterator, Sequence

import numpy as np
import torch

from rvdiag.errors import ParameterError

#: samples read at a time (one block: 2048 samples of 4096 points are 32 MB of float32)
DEFAULT_BUFFER_SAMPLES = 2048
#: samples turned into network inputs at a time within a buffer (bounds the float64 temporaries of a log spectrum)
TRANSFORM_PIECE = 256
#: ``rvdiag train`` streams a CNN's training split without being asked when its signals exceed this (float32 bytes)
STREAMING_THRESHOLD_BYTES = 2 * 1024 ** 3


class StoreSamples:
    """A selection of the samples of a :class:`rvdiag.datasets.SampleStore`, read block by block.

    Parameters
    ----------
    store : an open SampleStore
    index : sample indices in the store (sorted here)
    meta_columns : metadata columns appended after each sample's points (the model's
        :func:`rvdiag.features.combine.input_metadata`, e.g. the speed column of the angle-domain CNN inputs)
    where : how errors name the data (``"the store PATH"``)
    keep_meta : further metadata columns to keep in :attr:`meta` (``unit`` and ``meta_columns`` always are)

    Attributes
    ----------
    index : ndarray of int, the samples in the store, increasing
    y : ndarray of str, the class name of each
    meta : dict column -> ndarray, one value per selected sample (the columns kept)
    length : points per sample
    """

    def __init__(self, store: Any, index: Sequence[int] | np.ndarray, meta_columns: Sequence[str] = (),
                 where: str | None = None, keep_meta: Sequence[str] = ()):
        self.store = store
        self.index = np.sort(np.asarray(index, dtype=np.int64))
        self.y = np.asarray(store.label_names[self.index])
        keep = {"unit", *meta_columns, *keep_meta}
        self.meta = {k: np.asarray(v)[self.index] for k, v in store.meta.items() if k in keep}
        self.meta_columns = tuple(meta_columns)
        self.length = int(store.length)
        self.where = where or f"the store {store.path}"
        self.chunk_rows = max(1, int(store.signals.chunks[0]))
        if self.meta_columns and len(self.index):  # a missing or non-numeric column fails now, not mid-epoch
            from rvdiag.features.combine import with_metadata

            with_metadata(np.zeros((len(self.index), 0)), self.meta, self.meta_columns, where=self.where)

    def __len__(self) -> int:
        return int(self.index.size)

    @property
    def n_features(self) -> int:
        """Columns of a block: the points plus the appended metadata columns."""
        return self.length + len(self.meta_columns)

    @property
    def signal_bytes(self) -> int:
        """Size of the selection's signals in memory (float32)."""
        return len(self) * self.length * 4

    def subset(self, positions: np.ndarray) -> "StoreSamples":
        """The samples at ``positions`` of this selection (positions 0..len-1)."""
        out = object.__new__(StoreSamples)
        pos = np.sort(np.asarray(positions, dtype=np.int64))
        out.store, out.index, out.y = self.store, self.index[pos], self.y[pos]
        out.meta = {k: v[pos] for k, v in self.meta.items()}
        out.meta_columns, out.length, out.where, out.chunk_rows = (self.meta_columns, self.length, self.where,
                                                                   self.chunk_rows)
        return out

    def read(self, positions: np.ndarray) -> np.ndarray:
        """Samples at ``positions`` (increasing) of this selection: float32 ``(m, length)``, or float64 with the
        metadata columns appended."""
        pos = np.asarray(positions, dtype=np.int64)
        rows = self.index[pos]
        if rows.size == 0:
            X = np.zeros((0, self.length), dtype=np.float32)
        else:
            X = np.asarray(self.store.signals.get_orthogonal_selection((rows, slice(None))), dtype=np.float32)
        if not self.meta_columns:
            return X
        from rvdiag.features.combine import with_metadata

        return with_metadata(X, {c: self.meta[c][pos] for c in self.meta_columns}, self.meta_columns,
                             where=self.where)

    def blocks(self, block_samples: int = DEFAULT_BUFFER_SAMPLES) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """``(positions, X)`` of consecutive blocks of at most ``block_samples`` samples, in store order."""
        step = _check_block(block_samples)
        for start in range(0, len(self), step):
            pos = np.arange(start, min(start + step, len(self)))
            yield pos, self.read(pos)

    def shuffled_blocks(self, rng: np.random.Generator,
                        block_samples: int = DEFAULT_BUFFER_SAMPLES) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """``(positions, X)`` of blocks of whole store chunks taken in a random order (``rng``), each of about
        ``block_samples`` samples (positions increasing within a block)."""
        step = _check_block(block_samples)
        if not len(self):
            return
        chunk = self.index // self.chunk_rows
        starts = np.flatnonzero(np.r_[True, chunk[1:] != chunk[:-1]])  # first position of each chunk present
        ends = np.r_[starts[1:], len(self)]
        order = rng.permutation(starts.size)
        taken: list[np.ndarray] = []
        count = 0
        for c in order:
            taken.append(np.arange(starts[c], ends[c]))
            count += ends[c] - starts[c]
            if count >= step:
                pos = np.sort(np.concatenate(taken))
                yield pos, self.read(pos)
                taken, count = [], 0
        if taken:
            pos = np.sort(np.concatenate(taken))
            yield pos, self.read(pos)


def _check_block(block_samples: int) -> int:
    if not (isinstance(block_samples, (int, np.integer)) and block_samples >= 1):
        raise ParameterError(f"the streaming buffer must be an integer >= 1 sample, got {block_samples!r}")
    return int(block_samples)


class StoreStream(torch.utils.data.IterableDataset):
    """The mini-batches of one training epoch over a :class:`StoreSamples` (module docstring).

    Parameters
    ----------
    source : the training samples
    labels : class index of each sample of ``source`` (int)
    transform : ``X block -> network inputs`` (``(m * k, input length)`` float32, ``k`` per sample, sample-major),
        applied :data:`TRANSFORM_PIECE` samples at a time
    windows_per_sample : ``k``
    batch_size : inputs per batch
    rng : the generator of the order; each iteration (epoch) draws from it
    buffer_samples : samples read and shuffled at a time

    Each iteration yields ``(x, y)``: float32 ``(b, 1, input length)`` and int64 ``(b,)`` tensors, every input of
    every sample exactly once.  ``torch.utils.data.DataLoader(stream, batch_size=None)`` passes them through.
    """

    def __init__(self, source: StoreSamples, labels: np.ndarray, transform: Callable[[np.ndarray], np.ndarray], *,
                 windows_per_sample: int, batch_size: int, rng: np.random.Generator,
                 buffer_samples: int = DEFAULT_BUFFER_SAMPLES):
        super().__init__()
        self.source = source
        self.labels = np.asarray(labels, dtype=np.int64)
        if self.labels.shape != (len(source),):
            raise ParameterError(f"{self.labels.size} labels for {len(source)} samples")
        self.transform = transform
        self.k = int(windows_per_sample)
        self.batch_size = int(batch_size)
        self.rng = rng
        self.buffer_samples = _check_block(buffer_samples)

    def __len__(self) -> int:
        """Inputs per epoch."""
        return len(self.source) * self.k

    def __iter__(self) -> Iterator[tuple[torch.Tensor, torch.Tensor]]:
        bs = self.batch_size
        carry_x = carry_y = None
        for pos, X in self.source.shuffled_blocks(self.rng, self.buffer_samples):
            xw = transform_in_pieces(self.transform, X)
            yw = np.repeat(self.labels[pos], self.k)
            del X
            if carry_x is not None and len(carry_y):
                xw, yw = np.concatenate([carry_x, xw]), np.concatenate([carry_y, yw])
            perm = self.rng.permutation(len(yw))
            xw, yw = xw[perm], yw[perm]
            full = len(yw) // bs * bs
            for s in range(0, full, bs):
                yield torch.from_numpy(xw[s:s + bs]).unsqueeze(1), torch.from_numpy(yw[s:s + bs])
            carry_x, carry_y = xw[full:].copy(), yw[full:].copy()
            del xw, yw
        if carry_y is not None and len(carry_y):
            yield torch.from_numpy(carry_x).unsqueeze(1), torch.from_numpy(carry_y)


def transform_in_pieces(transform: Callable[[np.ndarray], np.ndarray], X: np.ndarray,
                        piece: int = TRANSFORM_PIECE) -> np.ndarray:
    """``transform(X)`` computed ``piece`` samples at a time and stacked (float32): the same rows, with the
    transform's temporaries bounded by the piece instead of the buffer."""
    parts = [np.asarray(transform(X[s:s + piece]), dtype=np.float32) for s in range(0, len(X), piece)]
    return np.concatenate(parts) if parts else np.asarray(transform(X), dtype=np.float32)


def predict_proba_store(estimator: Any, source: StoreSamples,
                        block_samples: int = DEFAULT_BUFFER_SAMPLES) -> np.ndarray:
    """``estimator.predict_proba`` of every sample of ``source``, block by block (store order)."""
    out = [estimator.predict_proba(X[s:s + TRANSFORM_PIECE]) for _, X in source.blocks(block_samples)
           for s in range(0, len(X), TRANSFORM_PIECE)]
    n_classes = len(getattr(estimator, "classes_", ()))
    return np.concatenate(out) if out else np.zeros((0, n_classes))


def predict_store(estimator: Any, source: StoreSamples, block_samples: int = DEFAULT_BUFFER_SAMPLES) -> np.ndarray:
    """The most probable class of every sample of ``source``, block by block (store order)."""
    proba = predict_proba_store(estimator, source, block_samples)
    return np.asarray(estimator.classes_)[proba.argmax(axis=1)]
