"""numba's cache of the integrator is dropped when the model kernels it inlines change."""

from __future__ import annotations

from rvdiag.dynamics.numba_cache import drop_stale_cache


def test_cache_is_dropped_when_a_dependency_changes(tmp_path):
    module = tmp_path / "integrate.py"
    dep = tmp_path / "model.py"
    module.write_text("# kernels")
    dep.write_text("A = 1")
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    files = [cache / "integrate.rk4_run-36.py311.nbi", cache / "integrate.rk4_run-36.py311.1.nbc"]
    other = cache / "model.accelerations-529.py311.nbi"
    for f in files + [other]:
        f.write_bytes(b"x")
    assert drop_stale_cache(module, [dep])                 # no stamp yet: treated as stale
    assert not any(f.exists() for f in files) and other.exists()
    for f in files:
        f.write_bytes(b"x")                                # numba writes them again
    assert not drop_stale_cache(module, [dep])              # unchanged dependency: cache kept
    assert all(f.exists() for f in files)
    dep.write_text("A = 2")
    assert drop_stale_cache(module, [dep])                  # edited dependency: dropped
    assert not any(f.exists() for f in files)
