""""Not recognised" for a baseline monitor, judged against the machine's own baseline (rvdiag.monitoring.diagnosis):
the mesh-line check counts only where the baseline shows the lines, and a record far outside the baseline's level
is refused."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from rvdiag.features.mesh_lines import mesh_lines
from rvdiag.kinematics import characteristic_frequencies
from rvdiag.monitoring.diagnosis import LEVEL_FACTOR, MASK_DB, level_check_against_baseline, mesh_check_against_baseline
from rvdiag.params import ReducerParams

FS, L, SPEED = 48000.0, 12000, 30.0
P = ReducerParams.default()
FCS = characteristic_frequencies(P, output_speed_deg_s=SPEED).fcs
t = np.arange(L) / FS


def _base(windows):
    return SimpleNamespace(X=np.asarray(windows), meta={"output_speed_deg_s": np.full(len(windows), SPEED)})


def _recognition_of(x):
    lines = mesh_lines(x, FS, P, SPEED)
    return {"recognised": bool(lines["present"]), "reason": None if lines["present"] else "no mesh line",
            "checks": {"mesh_lines": lines}}


def test_no_mesh_line_counts_only_where_the_baseline_shows_one():
    rng = np.random.default_rng(0)
    noise = rng.standard_normal(L)
    with_line = np.sin(2 * np.pi * FCS * t) + 0.05 * rng.standard_normal(L)
    speed = {"output_speed_deg_s": SPEED}
    rec = _recognition_of(noise)
    assert not rec["recognised"]
    # the baseline shows the cycloid-pin mesh line, the record does not: not this machine
    out = mesh_check_against_baseline(rec, noise, _base([with_line]), FS, speed, L)
    assert not out["recognised"] and "the machine's baseline shows" in out["reason"] and "stage2" in out["reason"]
    # the baseline shows no line either (a quiet mesh behind its path): the lines say nothing, the index decides
    out = mesh_check_against_baseline(rec, noise, _base([rng.standard_normal(L)]), FS, speed, L)
    assert out["recognised"] and out["checks"]["mesh_lines"]["baseline"] == []
    # a record with the line passes untouched
    ok = _recognition_of(with_line)
    assert mesh_check_against_baseline(ok, with_line, _base([noise]), FS, speed, L) is ok


def test_a_record_far_outside_the_baselines_level_is_not_recognised():
    rng = np.random.default_rng(1)
    base = _base([rng.standard_normal(L) * g for g in (0.9, 1.0, 1.1)])
    rec = {"recognised": True, "reason": None, "checks": {}}
    same = level_check_against_baseline(rec, 1.05 * rng.standard_normal(L), base)
    assert same["recognised"] and same["checks"]["level"]["factor"] == LEVEL_FACTOR
    loud = level_check_against_baseline(rec, 20.0 * rng.standard_normal(L), base)
    assert not loud["recognised"] and "above the baseline's range" in loud["reason"]
    quiet = level_check_against_baseline(rec, 0.01 * rng.standard_normal(L), base)
    assert not quiet["recognised"] and "below" in quiet["reason"]


def test_a_line_masked_by_added_energy_is_a_changed_machine_a_lost_line_is_not():
    """A broken tooth's impacts raise the floor around the mesh lines (rvdiag.features.mesh_lines.confirm_speed):
    the line is still there, under more energy, and the record goes on to its index.  A disconnected sensor adds no
    energy at the reducer's orders: its line is lost, and it stays "not recognised".  Both read on the mean of the
    record's windows (a record of 4 windows here)."""
    rng = np.random.default_rng(2)
    k = 4
    tk = np.arange(k * L) / FS
    base = _base([np.sin(2 * np.pi * FCS * t) + 0.05 * rng.standard_normal(L) for _ in range(3)])
    speed = {"output_speed_deg_s": SPEED}
    masked = np.sin(2 * np.pi * FCS * tk) + 30.0 * rng.standard_normal(k * L)
    rec = _recognition_of(masked)
    assert not rec["recognised"]
    out = mesh_check_against_baseline(rec, masked, base, FS, speed, L)
    lines = out["checks"]["mesh_lines"]
    assert out["recognised"] and "stage2" in lines["baseline"] and "stage2" in lines["masked"]
    assert lines["record_lines"]["stage2"]["amplitude"] >= lines["baseline_lines"]["stage2"]["amplitude"] * 10 ** (
        -MASK_DB / 20)
    disconnected = 0.01 * rng.standard_normal(k * L)
    out = mesh_check_against_baseline(_recognition_of(disconnected), disconnected, base, FS, speed, L)
    assert not out["recognised"] and "the machine's baseline shows" in out["reason"] and "stage2" in out["reason"]
    assert out["checks"]["mesh_lines"]["masked"] == []


def test_a_current_monitor_does_not_read_vibration_mesh_lines_on_its_records(monkeypatch):
    """monitor_record of a motor-current monitor skips the vibration mesh-line check (a phase current has no mesh
    line to show); the same record under a vibration monitor is refused by it."""
    from pathlib import Path

    import rvdiag.monitoring.diagnosis as diagnosis
    from rvdiag.datasets.store import Samples
    from rvdiag.monitoring.baseline import Baseline

    class Scored(Exception):
        pass

    def scored(*args, **kwargs):
        raise Scored

    monkeypatch.setattr(diagnosis, "paired_features", scored)
    rng = np.random.default_rng(3)
    X = np.array([np.sin(2 * np.pi * FCS * t) + 0.05 * rng.standard_normal(L) for _ in range(3)])
    meta = {"output_speed_deg_s": np.full(3, SPEED), "load_Nm": np.full(3, 20.0)}
    base = Baseline(path=Path("base.zarr"), n_records=3, operating_points=[{"output_speed_deg_s": SPEED,
                                                                             "load_Nm": 20.0}], fs=FS,
                    samples=Samples(X=X, y=np.array(["T1"] * 3), meta=meta, index=np.arange(3)))
    record = SimpleNamespace(data=rng.standard_normal(L), fs=FS, path=None, channel=None,
                             metadata={"output_speed_deg_s": SPEED, "load_Nm": 20.0})

    def model(signal):
        card = {"needs_baseline": True, "training_store": {"kind": "simulated", "signal": signal}}
        return SimpleNamespace(path=Path("mon"), card=card, fs=FS, input_length=L,
                               estimator=SimpleNamespace(alpha=0.05, threshold_=1.0, features=None))

    vib = diagnosis.monitor_record(model("acceleration"), record, base)
    assert not vib.recognised and "no mesh line" in vib.reason and "the machine's baseline shows" in vib.reason
    with pytest.raises(Scored):  # recognised: it goes on to its change against the baseline
        diagnosis.monitor_record(model("current"), record, base)
