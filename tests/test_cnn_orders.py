"""Order-domain CNN input (``--representation orders`` / ``orders-residual``), and the gear condition indicators in
``diagnose`` and in the report of ``evaluate``."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from rvdiag.cli import main
from rvdiag.datasets import write_store
from rvdiag.features.orders import INDICATORS, shaft_frequency
from rvdiag.models.persistence import load_model, read_card
from rvdiag.models.torch_estimator import CNNClassifier, angle_inputs
from conftest import run_cli as run

FS = 2000.0
L = 1024
COL = "output_speed_deg_s"


def _shaft_signal(v: float, n: int = L, fs: float = FS, orders=((1, 1.0, 0.3), (3, 0.5, 1.0), (11, 0.8, 2.0))):
    """A pure function of the sun shaft's angle: shaft-order harmonics (order, amplitude, phase)."""
    theta = shaft_frequency("sun", output_speed_deg_s=v) * np.arange(n) / fs
    return sum(a * np.cos(2 * np.pi * k * theta + p) for k, a, p in orders)


def _z(a):
    return (a - a.mean(axis=1, keepdims=True)) / a.std(axis=1, keepdims=True)


@pytest.mark.parametrize("residual", [False, True])
def test_orders_input_is_the_same_whatever_the_speed(residual):
    """x(t) = f(shaft angle) at 30 and 60 deg/s (5.1 and 10.2 revolutions of the sun shaft in 2048 points at
    4 kHz): the normalised network inputs agree within 1e-2 (measured: 7e-4, 1.5e-3); the time windows do not."""
    fs, n = 4000.0, 2048
    ins = [_z(angle_inputs(_shaft_signal(v, n, fs)[None], np.array([v]), fs=fs, speed_column=COL, shaft="sun",
                           samples_per_rev=128, length=512, residual=residual)) for v in (30.0, 60.0)]
    assert np.abs(ins[0] - ins[1]).max() < 1e-2
    waves = [_z(_shaft_signal(v, n, fs)[None, :512]) for v in (30.0, 60.0)]
    assert np.abs(waves[0] - waves[1]).max() > 0.5


def test_orders_input_repeats_whole_revolutions_and_needs_one():
    x = _shaft_signal(45.0)[None]  # 15 Hz: 7.7 revolutions at 2 kHz
    a = angle_inputs(x, np.array([45.0]), fs=FS, speed_column=COL, shaft="sun", samples_per_rev=64, length=1000)
    np.testing.assert_allclose(a[0, 448:896], a[0, :448])  # 7 whole revolutions, then again from angle 0
    from rvdiag.errors import ParameterError

    with pytest.raises(ParameterError, match="revolutions of the sun shaft"):
        angle_inputs(x[:, :100], np.array([45.0]), fs=FS, speed_column=COL, shaft="sun", samples_per_rev=64,
                     length=128)


def _sample(c: int, v: float, rng) -> np.ndarray:
    """Class T1: shaft order 1 and the stage-1 mesh (order 11); T2 adds order 4; white noise on both."""
    theta = shaft_frequency("sun", output_speed_deg_s=v) * np.arange(L) / FS
    x = np.cos(2 * np.pi * 11 * theta + rng.uniform(0, 6)) + 0.5 * np.cos(2 * np.pi * theta + rng.uniform(0, 6))
    if c == 1:
        x = x + 0.4 * np.cos(2 * np.pi * 4 * theta + rng.uniform(0, 6))
    return x + 0.3 * rng.standard_normal(L)


@pytest.fixture(scope="module")
def speeds_store(tmp_path_factory):
    """Training at 30 and 60 deg/s, test at 75 deg/s (a speed never trained on)."""
    rng = np.random.default_rng(0)
    X, y, sp, split = [], [], [], []
    for v, s, n in ((30.0, "train", 20), (60.0, "train", 20), (75.0, "test", 15)):
        for c in range(2):
            for _ in range(n):
                X.append(_sample(c, v, rng))
                y.append(f"T{c + 1}")
                sp.append(v)
                split.append(s)
    p = tmp_path_factory.mktemp("s") / "speeds.zarr"
    write_store(p, np.asarray(X, np.float32), y, meta={"split": split, "unit": list(range(len(y))), COL: sp},
                kind="simulated", fs=FS, config={"name": "speeds"})
    return p


@pytest.fixture(scope="module")
def orders_model(speeds_store, tmp_path_factory):
    out = tmp_path_factory.mktemp("m") / "orders"
    args = ["train", speeds_store, "--model", "cnn1d-lean", "--representation", "orders", "--input-length", "256",
            "--epochs", "15", "--lr", "0.01", "--batch-size", "8", "--patience", "15", "--device", "cpu",
            "--seed", "0", "--out", out, "--quiet"]
    try:
        main([str(a) for a in args])
    except SystemExit as exc:  # pragma: no cover - a failure shows here
        assert exc.code == 0
    return out


def test_orders_cnn_holds_at_an_unseen_speed(orders_model, speeds_store, capsys):
    """Trained at 30 and 60 deg/s, tested at 75 deg/s: measured 100 % (a waveform CNN with the same settings:
    60 %)."""
    code, out, err = run(["evaluate", orders_model, speeds_store, "--json", "-q"], capsys)
    assert code == 0, err
    assert json.loads(out)["accuracy"] >= 0.9


def test_card_records_representation_and_speed_column(orders_model):
    card = read_card(orders_model)
    assert card["params"]["representation"] == "orders" and card["preprocessing"]["representation"] == "orders"
    assert card["metadata_columns"] == [COL] and card["preprocessing"]["speed_column"] == COL
    # 60 points per revolution at 60 deg/s, but at least 4 mesh harmonics (order 44) and sidebands: 128
    assert card["preprocessing"]["samples_per_rev"] == 128
    assert card["input_length"] == L and card["fs"] == FS


def test_orders_model_loads_in_a_fresh_interpreter(orders_model, speeds_store):
    from rvdiag.datasets import SampleStore

    s = SampleStore.open(speeds_store).load("test")
    loaded = load_model(orders_model)
    here = loaded.estimator.predict_proba(loaded.inputs(s.X[:6], {COL: s.meta[COL][:6]}))
    code = ("import json, sys, numpy as np; from rvdiag.models.persistence import load_model; "
            "from rvdiag.datasets import SampleStore; m = load_model(sys.argv[1]); s = SampleStore.open(sys.argv[2])"
            ".load('test'); X = m.inputs(s.X[:6], {'output_speed_deg_s': s.meta['output_speed_deg_s'][:6]}); "
            "print(json.dumps(m.estimator.predict_proba(X).tolist()))")
    r = subprocess.run([sys.executable, "-c", code, str(orders_model), str(speeds_store)], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    np.testing.assert_allclose(np.array(json.loads(r.stdout)), here, atol=1e-6)


def test_diagnose_needs_the_speed_and_gives_the_nine_indicators(orders_model, tmp_path, capsys):
    f = tmp_path / "sig.npy"
    np.save(f, np.concatenate([_sample(1, 75.0, np.random.default_rng(3)) for _ in range(4)]))
    code, out, err = run(["diagnose", orders_model, f, "--fs", str(FS), "--json"], capsys)
    assert code == 2 and "--meta output_speed_deg_s=" in err
    code, out, err = run(["diagnose", orders_model, f, "--fs", str(FS), "--json", "--meta", f"{COL}=75"], capsys)
    assert code == 0, err
    res = json.loads(out)
    assert res["diagnosis"] == "T2" and res["metadata"] == {COL: 75.0}
    assert list(res["indicators"]) == list(INDICATORS)
    src = res["indicators_source"]
    assert src["speed_source"] == f"--meta {COL}=75" and src["shaft"] == "sun"
    assert src["shaft_hz"] == pytest.approx(shaft_frequency("sun", output_speed_deg_s=75.0))
    assert src["n_revolutions"] == int(4 * L * src["shaft_hz"] / FS)
    code, out, err = run(["diagnose", orders_model, f, "--fs", str(FS), "--meta", f"{COL}=75"], capsys)
    assert code == 0 and "gear condition indicators" in out and "sideband_index" in out


def test_diagnose_estimates_the_speed_without_one(tmp_path, capsys, orders_model):
    """A waveform model reads no metadata: the indicators' speed comes from the stage-1 mesh peak, when the
    cycloid-pin mesh (order 13 of the sun relative to the carrier) confirms it; without that line it is refused
    (speed unknown rather than indicators at a wrong speed)."""
    from rvdiag.workflows.diagnosis import file_indicators, record_speed
    from rvdiag.io import read_signal

    f = tmp_path / "mesh.npy"
    noise = 0.05 * np.random.default_rng(0).standard_normal(8192)
    x = _shaft_signal(45.0, 8192, orders=((1, 0.3, 0.3), (11, 1.0, 2.0), (13, 0.8, 1.0)))  # the stage-1 mesh dominates
    np.save(f, x + noise)
    sig = read_signal(f, fs=FS)
    res = file_indicators(sig, record_speed(sig))
    assert res["indicators_source"]["speed_source"].startswith("estimated from the stage-1 mesh peak")
    assert "confirmed by the cycloid-pin mesh" in res["indicators_source"]["speed_source"]
    assert res["indicators_source"]["shaft_hz"] == pytest.approx(15.0, rel=1e-3)
    sig = read_signal(f)
    res = file_indicators(sig, record_speed(sig))
    assert res["indicators"] is None and "sampling rate" in res["indicators_source"]["error"]
    np.save(f, _shaft_signal(45.0, 8192, orders=((1, 0.3, 0.3), (11, 1.0, 2.0))) + noise)
    sig = read_signal(f, fs=FS)
    speed = record_speed(sig)
    assert speed["output_speed_deg_s"] is None and "do not confirm" in speed["error"]
    assert file_indicators(sig, speed)["indicators"] is None


def test_report_has_the_indicator_section(orders_model, speeds_store, tmp_path, capsys):
    rep = tmp_path / "r.html"
    code, _, err = run(["evaluate", orders_model, speeds_store, "--report", rep, "-q"], capsys)
    assert code == 0, err
    text = rep.read_text()
    assert "<h2 id='indicators'>Gear condition indicators</h2>" in text
    assert all(f"<td>{k}</td>" for k in INDICATORS) and "T2 (n=15)" in text


def test_unfit_settings_of_the_orders_representation_are_refused():
    from rvdiag.errors import ParameterError

    X = np.column_stack([np.zeros((4, 64)), np.full(4, 45.0)])
    with pytest.raises(ParameterError, match="sampling rate"):
        CNNClassifier(representation="orders", max_epochs=1).fit(X, ["a", "b"] * 2)
    with pytest.raises(ParameterError, match="speed_column"):
        CNNClassifier(representation="orders", fs=1000.0, speed_column="v", max_epochs=1).fit(X, ["a", "b"] * 2)
