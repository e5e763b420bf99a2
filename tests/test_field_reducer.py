"""bench/field_reducer.py: the field reducer a monitor never saw writes its commissioning and later records as CSV
files with time_s, acc and angle_in, which ``rvdiag dataset from-files --angle-channel`` reads (--small)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np

from conftest import run_cli

ROOT = Path(__file__).resolve().parents[1]


def _module():
    spec = importlib.util.spec_from_file_location("field_reducer", ROOT / "bench" / "field_reducer.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_field_reducer_writes_its_records_and_from_files_reads_them(tmp_path, capsys):
    mod = _module()
    out = tmp_path / "field"
    secret = mod.main(["--out", str(out), "--small", "--workers", "1"])
    assert sorted(p.name for p in (out / "commissioning").iterdir()) == ["T1_45dps_90Nm_000.csv"]
    assert sorted(p.name for p in (out / "later").iterdir()) == ["T1_45dps_90Nm_000.csv", "T2_45dps_90Nm_000.csv"]
    assert json.loads((out / "FIELD_SECRET.json").read_text())["floor_db"] == 18.0
    # the field reducer is none of the library's: another master seed
    assert secret["seed"] != 27 and {r["role"] for r in secret["records"]} == {"baseline", "monitored"}
    with open(out / "later" / "T2_45dps_90Nm_000.csv") as f:
        assert f.readline().strip() == "time_s,acc,angle_in"
    data = np.loadtxt(out / "later" / "T2_45dps_90Nm_000.csv", delimiter=",", skiprows=1)
    assert data.shape == (int(0.3 * 48000), 3) and np.all(np.isfinite(data))
    assert np.allclose(np.diff(data[:, 0]), 1 / 48000, rtol=1e-3)
    step = 2 * np.pi / mod.ENCODER_COUNTS
    assert np.allclose(data[:, 2] / step, np.round(data[:, 2] / step), atol=1e-3)  # encoder counts
    code, _, err = run_cli(["dataset", "from-files", out / "commissioning", "--label-regex", "^(?P<label>T1)_",
                            "--channel", "acc", "--angle-channel", "angle_in", "--meta-regex",
                            r"_(?P<nominal_dps>[\d.]+)dps_(?P<load_Nm>[\d.]+)Nm", "--window", "4800",
                            "-o", tmp_path / "base.zarr"], capsys)
    assert code == 0, err
    from rvdiag.datasets import SampleStore

    s = SampleStore.open(tmp_path / "base.zarr")
    assert s.fs == 48000.0 and s.n_samples == 3
    speed = np.asarray(s.meta["output_speed_deg_s"], dtype=float)
    rec = secret["records"][0]
    assert np.allclose(speed, rec["output_speed_deg_s"], rtol=2e-3)  # the encoder's speed: the record's own
    assert np.all(np.asarray(s.meta["load_Nm"]) == 90)  # the commanded load from the name
