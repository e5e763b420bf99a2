"""The hidden test rig of bench/hidden_rig.py: measured-like files of a perturbed reducer whose values the
transfer workflow never sees."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np

from rvdiag.params import ReducerParams

ROOT = Path(__file__).resolve().parents[1]


def _rig_module():
    spec = importlib.util.spec_from_file_location("hidden_rig", ROOT / "bench" / "hidden_rig.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_rig_differs_from_the_default_and_is_seeded():
    rig = _rig_module()
    a, b, c = rig.rig_parameters(1), rig.rig_parameters(1), rig.rig_parameters(2)
    base = ReducerParams.default()
    assert a == b and a != c
    assert a.bearings != base.bearings and a.mounting.path_resonance_hz > 0.0
    assert 4.0 <= a.mounting.housing_added_mass <= 12.0


def test_rig_files_are_measured_like_csv_and_the_secret_is_kept_apart(tmp_path):
    rig = _rig_module()
    out = rig.make_rig(tmp_path / "rig", seed=3, record_s=0.02, calib_s=0.05)
    files = sorted(p.name for p in out.glob("*.csv"))
    assert len(files) == 1 + 6 * 3 * 2 and files[0] == "calib_T1_45dps_75Nm.csv"
    head = (out / "rig_T2_45dps_60Nm.csv").read_text(encoding="utf-8").splitlines()
    assert head[0] == "time_s,acc,angle_in"
    data = np.loadtxt(out / "rig_T2_45dps_60Nm.csv", delimiter=",", skiprows=1)
    assert data.shape == (int(0.02 * 48000), 3) and np.all(np.isfinite(data)) and data[:, 1].std() > 0
    assert np.allclose(np.diff(data[:, 0]), 1 / 48000.0)
    # angle_in: the input shaft's encoder angle (rad), 0 at the first sample, turning at the input speed
    # (45 deg/s at the output times the reducer's ratio; constant speed, so its slope is constant)
    omega_in = np.deg2rad(45.0) * ReducerParams.default().ratio
    assert data[0, 2] == 0.0
    np.testing.assert_allclose(np.diff(data[:, 2]) * 48000.0, omega_in, rtol=1e-6)
    calib = np.loadtxt(out / "calib_T1_45dps_75Nm.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(calib[-1, 2], omega_in * (calib.shape[0] - 1) / 48000.0, rtol=1e-6)
    secret = json.loads((out / "RIG_SECRET.json").read_text(encoding="utf-8"))
    assert ReducerParams.from_dict(secret["params"]) == rig.rig_parameters(3)
    # the shipped transfer library knows nothing of the rig
    text = (ROOT / "configs" / "transfer.toml").read_text(encoding="utf-8")
    assert "RIG" not in text and str(round(secret["params"]["mounting"]["path_resonance_hz"], 1)) not in text


def test_each_faulty_state_is_its_own_specimen_behind_one_sensor_floor():
    rig = _rig_module()
    seeds = rig.specimen_seeds(1)
    assert seeds == rig.specimen_seeds(1) and len(set(seeds.values())) == len(rig.STATES)
    quiet, loud = np.zeros(48000), 10.0 * np.sin(np.arange(48000) * 0.2)
    a = rig._disturb(quiet, np.random.default_rng(0), healthy_power=4.0)
    b = rig._disturb(loud, np.random.default_rng(0), healthy_power=4.0) - loud
    np.testing.assert_allclose(a, b, atol=1e-12)  # a louder record gets the same noise and hum
    floor = 4.0 * 10 ** (-rig.FLOOR_DB / 10)
    assert 0.9 * floor < np.var(a) < 1.1 * floor + 0.02**2 * 4.0 * 1.1
