"""Streaming a store into CNN training (rvdiag.models.streaming, CNNClassifier.fit_store, rvdiag train --streaming):
every sample once per epoch in a seeded random order, reads bounded by the buffer, the store's samples written one
chunk each, and the in-memory path unchanged."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli as run
from rvdiag.datasets import SampleStore, StoreBuilder, write_store
from rvdiag.models import streaming
from rvdiag.models.streaming import StoreSamples, StoreStream, predict_store
from rvdiag.models.torch_estimator import CNNClassifier

FS = 1000.0
L = 128


def _signals(n_per_class: int, seed: int) -> tuple[np.ndarray, list[str]]:
    rng = np.random.default_rng(seed)
    t = np.arange(L) / FS
    X, y = [], []
    for c in range(3):
        for _ in range(n_per_class):
            X.append(np.sin(2 * np.pi * (60 + 120 * c) * t + rng.uniform(0, 6)) + 0.2 * rng.standard_normal(L))
            y.append(f"T{c + 1}")
    return np.asarray(X, np.float32), y


@pytest.fixture(scope="module")
def store_path(tmp_path_factory):
    X, y = _signals(20, 0)
    n = len(y)
    split = ["test" if i % 5 == 0 else "train" for i in range(n)]
    p = tmp_path_factory.mktemp("stream") / "s.zarr"
    write_store(p, X, y, meta={"split": split, "unit": np.arange(n) // 2,
                               "output_speed_deg_s": np.full(n, 45.0)},
                kind="simulated", fs=FS, config={"name": "stream-test"})
    return p


FAST = dict(architecture="cnn1d-lean", max_epochs=6, learning_rate=1e-2, batch_size=8, n_iter_no_change=6,
            device="cpu", random_state=2)


def test_stream_gives_every_window_once_per_epoch_in_a_seeded_order(store_path):
    store = SampleStore.open(store_path)
    src = StoreSamples(store, store.indices("train"))
    assert src.chunk_rows == 1 and len(src) == 48
    seen_blocks = []

    def transform(X):  # two "windows" per sample: the sample's first point, then minus it
        seen_blocks.append(len(X))
        return np.stack([X[:, :4], -X[:, :4]], axis=1).reshape(-1, 4)

    def epoch(stream):
        xs, ys = zip(*[(x.numpy(), y.numpy()) for x, y in stream])
        return np.concatenate(xs)[:, 0], np.concatenate(ys), [len(y) for y in ys]

    labels = np.arange(48) % 3
    stream = StoreStream(src, labels, transform, windows_per_sample=2, batch_size=7,
                         rng=np.random.default_rng(5), buffer_samples=10)
    x1, y1, sizes = epoch(stream)
    assert len(stream) == 96 and x1.shape == (96, 4)
    assert sizes[:-1] == [7] * 13 and sizes[-1] == 96 - 13 * 7  # full batches, one short one at the end
    assert max(seen_blocks) <= 10  # never more than one buffer of samples at a time
    X = src.read(np.arange(48))
    expected = np.concatenate([X[:, :4], -X[:, :4]])
    # every window exactly once, with its sample's label
    key = lambda a: np.lexsort(a.T[::-1])  # noqa: E731
    np.testing.assert_array_equal(x1[key(x1)], expected[key(expected)])
    first = {tuple(r): lab for r, lab in zip(X[:, :4].tolist(), labels)}
    assert all(first.get(tuple(r), first.get(tuple((-np.asarray(r)).tolist()))) == lab
               for r, lab in zip(x1.tolist(), y1))
    # shuffled across the whole split (not store order), differently in the next epoch, the same for the same seed
    x2, _, _ = epoch(stream)
    again, _, _ = epoch(StoreStream(src, labels, transform, windows_per_sample=2, batch_size=7,
                                    rng=np.random.default_rng(5), buffer_samples=10))
    assert not np.array_equal(x1, expected) and not np.array_equal(x1, x2)
    np.testing.assert_array_equal(x1, again)


def test_blocks_read_only_the_rows_asked_for(store_path, monkeypatch):
    store = SampleStore.open(store_path)
    src = StoreSamples(store, store.indices("test"), meta_columns=("output_speed_deg_s",))
    assert sorted(src.meta) == ["output_speed_deg_s", "unit"]  # only the columns it needs, not every column
    sizes = []
    original = type(store.signals).get_orthogonal_selection

    def spy(self, selection, *a, **k):
        sizes.append(len(selection[0]))
        return original(self, selection, *a, **k)

    monkeypatch.setattr(type(store.signals), "get_orthogonal_selection", spy)
    blocks = list(src.blocks(5))
    assert [len(p) for p, _ in blocks] == [5, 5, 2] and sizes == [5, 5, 2]
    X = np.concatenate([x for _, x in blocks])
    assert X.shape == (12, L + 1) and np.all(X[:, -1] == 45.0)  # the metadata column appended
    np.testing.assert_array_equal(X[:, :L], store.load("test").X)


def test_fit_store_learns_and_predicts_like_the_in_memory_model(store_path):
    store = SampleStore.open(store_path)
    tr, te = StoreSamples(store, store.indices("train")), StoreSamples(store, store.indices("test"))
    est = CNNClassifier(**FAST).fit_store(tr, buffer_samples=16)
    assert est.stream_buffer_samples_ == 16 and est.n_features_in_ == L and len(est.history_) >= 1
    Xte = store.load("test").X
    np.testing.assert_array_equal(predict_store(est, te, block_samples=5), est.predict(Xte))
    assert np.mean(predict_store(est, te) == te.y) >= 0.9  # three clearly different tones
    again = CNNClassifier(**FAST).fit_store(tr, buffer_samples=16)  # seeded
    np.testing.assert_array_equal(again.predict_proba(Xte), est.predict_proba(Xte))
    # the streamed global normalisation equals the in-memory one (same validation split, same seed)
    g = dict(FAST, normalize="global", max_epochs=1)
    a = CNNClassifier(**g).fit_store(tr, buffer_samples=7)
    b = CNNClassifier(**g).fit(store.load("train").X, tr.y)
    assert a.norm_mean_ == pytest.approx(b.norm_mean_, rel=1e-5, abs=1e-7)
    assert a.norm_std_ == pytest.approx(b.norm_std_, rel=1e-5)


def test_builder_writes_one_chunk_per_sample_and_never_touches_earlier_ones(tmp_path):
    """Writing unit k writes the chunk files of its own rows and nothing else: the build's memory and time per
    unit do not grow with the store."""
    b = StoreBuilder(tmp_path / "b.zarr", unit_rows=[3, 3, 3], length=L, classes=["T1", "T2"],
                     config={"name": "chunks"}, fs=FS)
    assert b._signals.chunks == (1, L)
    chunk_dir = tmp_path / "b.zarr" / "signals" / "c"

    def chunk_files():
        return {p.relative_to(chunk_dir).as_posix(): p.stat().st_mtime_ns
                for p in chunk_dir.rglob("*") if p.is_file()} if chunk_dir.exists() else {}

    rng = np.random.default_rng(0)
    before = {}
    for unit in range(3):
        b.write_unit(unit, rng.standard_normal((3, L)), ["T1"] * 3, {"split": ["train"] * 3})
        after = chunk_files()
        assert sorted(set(after) - set(before)) == [f"{r}/0" for r in range(3 * unit, 3 * unit + 3)]
        assert {k: after[k] for k in before} == before  # earlier chunks untouched
        before = after


def test_cli_streaming_trains_and_records_it(store_path, tmp_path, capsys):
    out = tmp_path / "m"
    args = ["train", store_path, "--model", "cnn1d-lean", "--representation", "waveform", "--epochs", "6",
            "--lr", "0.01", "--batch-size", "8", "--device", "cpu", "--seed", "2", "--patience", "6", "--out", out]
    code, _, err = run([*args, "--streaming"], capsys)
    assert code == 0, err
    assert "streamed from the store, 2048 samples at a time" in err
    card = json.loads((out / "card.json").read_text())
    assert card["streaming"] == {"buffer_samples": 2048} and card["training_store"]["n_train"] == 48
    assert card["metrics"]["accuracy"] >= 0.9
    # a small store trains in memory by default (no streaming entry), and streams once over the threshold
    code, _, err = run([*args[:-1], tmp_path / "d"], capsys)
    assert code == 0 and "streamed" not in err and "streaming" not in json.loads((tmp_path / "d" / "card.json").read_text())


def test_cli_streams_a_cnn_above_the_threshold(store_path, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(streaming, "STREAMING_THRESHOLD_BYTES", 1000)
    args = ["train", store_path, "--model", "cnn1d-lean", "--representation", "waveform", "--epochs", "1",
            "--device", "cpu", "--quiet"]
    code, _, err = run([*args, "--out", tmp_path / "auto"], capsys)
    assert code == 0, err
    assert "streaming" in json.loads((tmp_path / "auto" / "card.json").read_text())
    code, _, err = run([*args, "--no-streaming", "--out", tmp_path / "mem"], capsys)
    assert code == 0, err
    assert "streaming" not in json.loads((tmp_path / "mem" / "card.json").read_text())


@pytest.mark.parametrize("extra, message", [
    (["--model", "svm", "--features", "time"], "--streaming applies to the CNN models"),
    (["--model", "cnn1d-lean", "--snr-db", "10"], "does not combine with --streaming"),
])
def test_cli_streaming_refusals_are_one_line_exit_2(store_path, tmp_path, capsys, extra, message):
    code, out, err = run(["train", store_path, "--streaming", "--out", tmp_path / "x", *extra], capsys)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and message in lines[0], err
    assert "Traceback" not in err and not (tmp_path / "x").exists()
