"""simulate, prepare_simulation and the library's simulator pair take their arguments from one
:class:`rvdiag.dynamics.SimulationRequest`: the keyword API is unchanged, and each route gives the same result."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from rvdiag.dynamics import ModelSettings, SimulationRequest, prepare_simulation, simulate
from rvdiag.errors import ParameterError
from rvdiag.library.simulators import dynamics, dynamics_request, prepare_dynamics

#: the keywords simulate took before the request said them once (a user's call must keep working)
SIMULATE_KEYWORDS = ["params", "fault", "input_speed_rpm", "output_speed_deg_s", "load_Nm", "duration_s", "fs",
                     "noise_snr_db", "seed", "settings", "mesh_source", "progress", "workers", "profile",
                     "load_profile", "signal", "current_fs", "current_snr_db", "load_inertia_kg_m2"]
TINY = dict(output_speed_deg_s=30.0, load_Nm=50.0, duration_s=0.01, fs=12000.0, noise_snr_db=20.0, seed=3,
            settings=ModelSettings(transient_s=0.005, substeps=16))


def test_the_keyword_api_is_that_of_before():
    sim = inspect.signature(simulate).parameters
    assert sorted(sim) == sorted(SIMULATE_KEYWORDS)
    assert [n for n, p in sim.items() if p.kind is p.POSITIONAL_OR_KEYWORD] == ["params", "fault"]
    assert sim["fs"].default == 48000.0 and sim["signal"].default == "vibration" and sim["seed"].default == 0
    assert sorted(inspect.signature(prepare_simulation).parameters) == sorted(set(SIMULATE_KEYWORDS) - {"progress"})
    with pytest.raises(TypeError, match="speed_deg_s"):
        simulate(speed_deg_s=30.0)  # a misspelt keyword fails at once, as before
    with pytest.raises(ParameterError, match="signal must be one of"):
        simulate(output_speed_deg_s=30.0, signal="sound")


def test_every_route_gives_the_same_result():
    calls = []
    a = simulate(None, None, progress=lambda done, total: calls.append((done, total)), **TINY)
    b = SimulationRequest(**TINY).run()
    run = prepare_simulation(**TINY)
    c = run.finish(*run.integrate())
    assert calls and calls[-1][0] == calls[-1][1]
    for other in (b, c):
        np.testing.assert_array_equal(a.signal, other.signal)
        assert a.settings == other.settings
    assert a.settings["seed"] == 3 and a.settings["noise_snr_db"] == 20.0 and a.settings["output_speed_deg_s"] == 30.0


def test_the_library_pair_builds_one_request():
    kw = dict(duration_s=0.01, transient_s=0.005, fs=12000.0, seed=3, model={"substeps": 16},
              output_speed_deg_s=30.0, load_Nm=50.0)
    req = dynamics_request(None, None, **kw)
    assert req == SimulationRequest(None, None, duration_s=0.01, fs=12000.0, seed=3,
                                    settings=ModelSettings(transient_s=0.005, substeps=16),
                                    output_speed_deg_s=30.0, load_Nm=50.0)
    assert inspect.signature(dynamics) == inspect.signature(prepare_dynamics) == inspect.signature(dynamics_request)
    res = dynamics(None, None, **kw)
    np.testing.assert_array_equal(res.signal, simulate(**{**TINY, "noise_snr_db": None}).signal)
    run = prepare_dynamics(None, None, **kw)
    np.testing.assert_array_equal(run.finish(*run.integrate()).signal, res.signal)
    cur = dynamics_request(None, None, **{**kw, "fs": 1000.0, "model": {"signal": "current"}})
    assert (cur.signal, cur.fs, cur.current_fs) == ("current", 48000.0, 1000.0)
