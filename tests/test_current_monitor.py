"""Monitoring a motor current against its own baseline: the reducer's lines relative to the supply line
(:class:`rvdiag.features.current.CurrentLineFeatures`), and ``rvdiag train`` / ``evaluate`` on a paired store of
currents (``[model] signal = "current"``), where they are an option (``--features current-lines``) beside the
default, the order-spectrum change.

The synthetic paired store: each reducer's current is a supply line at its f_e (speed +-1 %), its load moving the
line's level (+-3 %) and the sensor's gain (+-3 %), with the reducer's own lines at f_e +- f1, f_e +- f_sp and
f_e +- f_cs (its manufacturing errors: amplitudes drawn per reducer over a decade) and white noise; a broken tooth
(T2) triples the f_e +- f1 pair of that reducer.  Across reducers the tripled pair lies inside the spread of the
reducers' own lines: only the reducer's own baseline tells it.  (A doubled pair is told apart too, but the CV+
threshold of 8 training reducers is conservative: the healthy records' largest index is 0.22 at a stated 10 %, and
one doubled pair of 12 stays under it at 0.92.)"""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli
from rvdiag.datasets.store import write_store
from rvdiag.errors import ParameterError
from rvdiag.features.current import REDUCER_LINES, CurrentLineFeatures
from rvdiag.kinematics import characteristic_frequencies
from rvdiag.params import ReducerParams

FS, N = 1000.0, 2048
P = ReducerParams.default()


def current(speed: float, lines: dict, *, level: float = 1.0, noise: float = 0.0, rng=None, phase: float = 0.3):
    """A phase current at output speed ``speed`` (deg/s): the supply line of amplitude ``level`` and ``lines``
    (name of :data:`REDUCER_LINES` -> amplitude relative to the supply line)."""
    fr = characteristic_frequencies(P, output_speed_deg_s=speed)
    t = np.arange(N) / FS
    x = level * np.sin(2 * np.pi * fr.fe * t + phase)
    hz = {"fe-1f1": fr.fe - fr.f1, "fe+1f1": fr.fe + fr.f1, "fe-2f1": fr.fe - 2 * fr.f1, "fe+2f1": fr.fe + 2 * fr.f1,
          "fe-3f1": abs(fr.fe - 3 * fr.f1), "fe+3f1": fr.fe + 3 * fr.f1, "fe-fsp": abs(fr.fe - fr.fsp),
          "fe+fsp": fr.fe + fr.fsp, "fe-fcs": abs(fr.fe - fr.fcs), "fe+fcs": fr.fe + fr.fcs}
    for k, (name, a) in enumerate(lines.items()):
        x = x + level * a * np.cos(2 * np.pi * hz[name] * t + 0.7 * k)
    if noise:
        x = x + noise * rng.standard_normal(N)
    return x


def test_the_lines_read_their_amplitude_relative_to_the_supply_line_and_ignore_the_gain():
    # lines 40 and 60 dB below the supply line, at 45 deg/s and 31 deg/s (f_e from the window itself)
    for speed in (45.0, 31.0):
        x = current(speed, {"fe-1f1": 1e-2, "fe+1f1": 1e-2, "fe+fsp": 1e-3, "fe-fcs": 1e-3})
        fx = CurrentLineFeatures(fs=FS).fit(x[None])
        F = fx.transform(np.stack([x, 3.0 * x]))
        got = dict(zip(fx.get_feature_names_out(), F[0]))
        # a line between two bins reads up to 1.4 dB low under a Hann window, the supply line too: 0.1 decade
        for name, want in (("fe-1f1", -2), ("fe+1f1", -2), ("fe+fsp", -3), ("fe-fcs", -3)):
            assert got[f"log10_{name}_over_fe"] == pytest.approx(want, abs=0.1), (speed, name)
        assert got["log10_fe-2f1_over_fe"] < -5  # no line there: the other lines' leakage only
        np.testing.assert_allclose(F[1], F[0], atol=1e-9)  # the sensor's gain cancels


def test_bad_settings_are_refused():
    x = current(45.0, {"fe-1f1": 1e-2})[None]
    with pytest.raises(ParameterError, match="lines must name"):
        CurrentLineFeatures(fs=FS, lines=("fe-9f1",)).fit(x)
    with pytest.raises(ParameterError, match="fs must be"):
        CurrentLineFeatures(fs=0.0).fit(x)
    with pytest.raises(ParameterError, match="outside the spectrum"):  # 5 f_e at 60 deg/s: 504 Hz > 500 Hz
        CurrentLineFeatures(fs=FS, lines=("5fe",)).fit(x).transform(current(60.0, {})[None])


OPS = [(45.0, 20.0)]
N_REDUCERS, TRAIN_REDUCERS = 12, 8
STATES = {"T1": 6, "T2": 3}


def paired_currents(seed: int = 0):
    rng = np.random.default_rng(seed)
    X, y, meta = [], [], {k: [] for k in ("reducer", "role", "output_speed_deg_s", "load_Nm", "split", "unit")}
    for r in range(N_REDUCERS):
        own = {name: 10 ** rng.uniform(-3.0, -2.0) for name in REDUCER_LINES}  # the reducer's own lines
        split = "train" if r < TRAIN_REDUCERS else "test"
        rows = [("baseline", "T1")] * 3 + [("monitored", s) for s, n in STATES.items() for _ in range(n)]
        for role, state in rows:
            v, ld = 45.0 * (1 + 0.01 * rng.uniform(-1, 1)), 20.0 * (1 + 0.03 * rng.uniform(-1, 1))
            lines = {k: a * (1 + 0.05 * rng.uniform(-1, 1)) for k, a in own.items()}
            if state == "T2":
                lines["fe-1f1"] *= 3.0
                lines["fe+1f1"] *= 3.0
            X.append(current(v, lines, level=ld / 20.0 * (1 + 0.03 * rng.uniform(-1, 1)), noise=2e-5, rng=rng,
                             phase=rng.uniform(0, 2 * np.pi)))
            y.append(state)
            for k, val in zip(meta, (r, role, v, ld, split, len(X) - 1)):
                meta[k].append(val)
    return np.array(X), y, {k: np.array(v) for k, v in meta.items()}


@pytest.fixture(scope="module")
def current_store(tmp_path_factory):
    d = tmp_path_factory.mktemp("current")
    X, y, meta = paired_currents()
    write_store(d / "paired.zarr", X, y, meta, kind="simulated", fs=FS,
                config={"model": {"signal": "current"}, "channel": "i_a"}, extra_attrs={"params": P.to_dict()})
    return d


def test_train_on_a_current_store_with_the_current_lines_tells_the_broken_tooth(current_store, capsys):
    d = current_store
    code, out, err = run_cli(["train", str(d / "paired.zarr"), "-o", str(d / "mon"), "--alpha", "0.1",
                              "--features", "current-lines"], capsys)
    assert code == 0, out + err
    assert "current-lines features" in out + err
    card = json.loads((d / "mon" / "card.json").read_text())
    assert card["monitor_features"] == "current-lines"
    code, out, err = run_cli(["evaluate", str(d / "mon"), str(d / "paired.zarr"), "--split", "test", "--json"],
                             capsys)
    assert code == 0, out + err
    m = json.loads(out[out.index("{"):])
    assert m["n_records"] == 4 * 9 and m["detection_rate_per_state"]["T2"] == 1.0
    assert m["false_alarm_rate"] <= 0.25  # 24 healthy records against a stated 10 %; the tripled pair is far out


def test_a_current_store_defaults_to_the_order_spectrum_change(current_store, capsys):
    from rvdiag.monitoring.training import DEFAULT_MONITOR_FEATURES, default_monitor_features
    from rvdiag.datasets import SampleStore

    assert default_monitor_features(SampleStore.open(current_store / "paired.zarr")) == "orders"
    assert DEFAULT_MONITOR_FEATURES == "tsa-change"  # an acceleration store keeps the TSA change


def test_diagnose_a_current_file_against_the_joints_own_commissioning_files(current_store, tmp_path, capsys):
    """The user's flow on a current: commissioning CSV files -> ``dataset from-files`` -> ``diagnose --baseline``
    of a later CSV file, with the record's measured speed and load."""
    d = current_store
    code, out, err = run_cli(["train", str(d / "paired.zarr"), "-o", str(tmp_path / "mon"), "--alpha", "0.1",
                              "--features", "current-lines"], capsys)
    assert code == 0, out + err
    X, y, meta = paired_currents()
    r = N_REDUCERS - 1  # a held-out joint
    t = np.arange(X.shape[1]) / FS
    (tmp_path / "base").mkdir()
    picked = {}
    for i in np.flatnonzero(meta["reducer"] == r):
        name = f"{y[i]}_{i:03d}_{meta['output_speed_deg_s'][i]:.4f}dps_{meta['load_Nm'][i]:.4f}Nm.csv"
        where = tmp_path / ("base" if meta["role"][i] == "baseline" else "later")
        where.mkdir(exist_ok=True)
        np.savetxt(where / name, np.c_[t, X[i]], delimiter=",", header="time_s,i_a", comments="")
        if meta["role"][i] == "monitored":
            picked.setdefault(y[i], (where / name, meta["output_speed_deg_s"][i], meta["load_Nm"][i]))
    code, out, err = run_cli(["dataset", "from-files", str(tmp_path / "base"), "--label-regex", "^(?P<label>T1)_",
                              "--channel", "i_a", "--meta-regex",
                              r"_(?P<output_speed_deg_s>[\d.]+)dps_(?P<load_Nm>[\d.]+)Nm", "--window", str(X.shape[1]),
                              "-o", str(tmp_path / "base.zarr")], capsys)
    assert code == 0, out + err
    got = {}
    for state, (path, speed, load) in picked.items():
        code, out, err = run_cli(["diagnose", str(tmp_path / "mon"), str(path), "--channel", "i_a",
                                  "--output-speed", f"{speed:.4f}", "--load", f"{load:.4f}",
                                  "--baseline", str(tmp_path / "base.zarr"), "--json"], capsys)
        assert code == 0, out + err
        got[state] = json.loads(out[out.index("{"):])
    assert not got["T1"]["alarm"] and got["T1"]["health_index"] < 1
    assert got["T2"]["alarm"] and got["T2"]["health_index"] > 1 and got["T2"]["state"] == "T2"
