""""Not recognised" for a baseline monitor, judged against the machine's own baseline (rvdiag.monitoring.diagnosis):
the mesh-line check counts only where the baseline shows the lines, and a record far outside the baseline's level
is refused."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from rvdiag.features.mesh_lines import mesh_lines
from rvdiag.kinematics import characteristic_frequencies
from rvdiag.monitoring.diagnosis import LEVEL_FACTOR, level_check_against_baseline, mesh_check_against_baseline
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
