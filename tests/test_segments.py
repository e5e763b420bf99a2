"""Time-parallel segments (rvdiag.dynamics.segments): the damped model forgets its start, so a record cut
into independently started segments equals the continuous run; the output does not depend on the
number of workers.  The `rvdiag simulate --workers/--segment` options are tested in test_cli_simulate.py."""

from __future__ import annotations

import numpy as np
import pytest

from rvdiag.dynamics import ModelSettings, simulate
from rvdiag.dynamics.segments import segment_bounds
from rvdiag.errors import ParameterError, SimulationError

FS = 48000.0
KW = dict(input_speed_rpm=1000.0, fs=FS)


def rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


@pytest.mark.parametrize("n, seg, expected", [
    (100, 0, [(0, 100)]),
    (100, 100, [(0, 100)]),
    (100, 250, [(0, 100)]),
    (100, 25, [(0, 25), (25, 25), (50, 25), (75, 25)]),
    (110, 25, [(0, 25), (25, 25), (50, 25), (75, 35)]),    # a 10-sample tail joins the last segment
    (115, 25, [(0, 25), (25, 25), (50, 25), (75, 25), (100, 15)]),
])
def test_segment_bounds(n, seg, expected):
    b = segment_bounds(n, seg)
    assert b == expected
    assert sum(c for _, c in b) == n and all(b[i][0] + b[i][1] == b[i + 1][0] for i in range(len(b) - 1))


@pytest.fixture(scope="module")
def continuous():
    return simulate(duration_s=0.06, settings=ModelSettings(transient_s=0.05), **KW)


def test_segments_match_the_continuous_run(continuous):
    """Three 20-ms segments, each run in for 50 ms from its own static start, against one continuous run.
    At 50 ms run-in the seam error is ~3e-5 (1e-7 at the default 100 ms, docs/model.md section 7); a
    run-in of 1 ms does not forget the start and is far off, so the comparison can fail."""
    seg = simulate(duration_s=0.06, settings=ModelSettings(transient_s=0.05, segment_s=0.02), **KW)
    assert seg.settings["segments"] == 3
    assert rel(seg.signal, continuous.signal) < 1e-4
    short = simulate(duration_s=0.06, settings=ModelSettings(transient_s=0.001, segment_s=0.02), **KW)
    cont_short = simulate(duration_s=0.06, settings=ModelSettings(transient_s=0.001), **KW)
    n = int(0.02 * FS)   # compare the later segments, whose start differs from the continuous state
    assert rel(short.signal[:, n:], cont_short.signal[:, n:]) > 1e-2


def test_first_segment_is_the_continuous_run(continuous):
    seg = simulate(duration_s=0.06, settings=ModelSettings(transient_s=0.05, segment_s=0.02), **KW)
    n = int(0.02 * FS)
    assert np.array_equal(seg.signal[:, :n], continuous.signal[:, :n])


def test_output_does_not_depend_on_workers():
    st = ModelSettings(transient_s=0.02, segment_s=0.01)
    one = simulate(duration_s=0.04, settings=st, workers=1, **KW)
    three = simulate(duration_s=0.04, settings=st, workers=3, **KW)
    assert np.array_equal(one.signal, three.signal)
    assert three.settings["segments"] == 4 and three.settings["workers"] == 3


def test_progress_counts_every_segment():
    calls = []
    st = ModelSettings(transient_s=0.01, segment_s=0.01, chunk_samples=100)
    simulate(duration_s=0.03, settings=st, workers=2, progress=lambda d, t: calls.append((d, t)), **KW)
    total = 3 * (480 + 480)
    assert all(t == total for _, t in calls)
    assert calls[-1][0] == total and all(b[0] >= a[0] for a, b in zip(calls, calls[1:]))


@pytest.mark.parametrize("kw, match", [
    (dict(segment_s=-1.0), "segment_s must be >= 0"),
    (dict(segment_s=float("nan")), "segment_s must be >= 0"),
    (dict(segment_s=0.5, damping=False), "needs damping on"),
    (dict(segment_s=0.5, transient_s=0.0), "transient_s > 0"),
])
def test_settings_refuse_segments_that_cannot_forget_their_start(kw, match):
    with pytest.raises(ParameterError, match=match):
        ModelSettings(**kw)


def test_bad_workers_and_unstable_segments():
    with pytest.raises(ParameterError, match="workers"):
        simulate(duration_s=0.01, workers=0, **KW)
    with pytest.raises(SimulationError, match="unstable"):
        simulate(duration_s=0.02, settings=ModelSettings(substeps=1, transient_s=0.01, segment_s=0.005),
                 workers=2, **KW)


def test_segments_of_a_broken_tooth_keep_its_spectrum():
    """With a broken tooth the signal is sensitive to small perturbations at the tooth impacts (RK4 at 9
    sub-steps differs from DOP853 by 5e-2 pointwise, docs/model.md section 7), so a segment's start
    moves it by more than on healthy gears (T6: ~1e-3), but not its spectrum."""
    from scipy.signal import welch

    from rvdiag.gears import ToothFaults

    fault = ToothFaults.for_state("T6", broken_fraction=0.5, wear_depth=10e-6, crack_depth=1.8e-3)
    op = dict(output_speed_deg_s=45.0, load_Nm=75.0, duration_s=0.3)
    cont = simulate(None, fault, **op)
    seg = simulate(None, fault, settings=ModelSettings(segment_s=0.1), workers=2, **op)
    assert seg.settings["segments"] == 3
    assert rel(seg.signal, cont.signal) < 2e-2
    f, pc = welch(cont.signal[0], FS, nperseg=2048)
    _, ps = welch(seg.signal[0], FS, nperseg=2048)
    band = (f > 50) & (f < 20000)
    assert np.sqrt(np.mean((10 * np.log10(ps[band] / pc[band])) ** 2)) < 0.1
