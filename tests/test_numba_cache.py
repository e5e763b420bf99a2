"""numba's cache of a kernel module is dropped when any kernel file (whose kernels it inlines, or whose compile-time
constants it reads) changes, and every file of rvdiag.dynamics that defines kernels is watched."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np

from rvdiag.dynamics import kernels as kn
from rvdiag.dynamics import numba_cache
from rvdiag.dynamics.numba_cache import (KERNEL_FILES, dependency_digest, drop_stale_cache, guard_kernel_module,
                                         kernel_files)

DYNAMICS = Path(numba_cache.__file__).parent


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


def test_every_file_that_defines_kernels_is_watched_and_guards_itself():
    """A kernel file missing from KERNEL_FILES (a new motor or mounting-path file) would let the others keep
    stale machine code; each one calls the guard before its first kernel is defined."""
    with_kernels = {p.name for p in DYNAMICS.glob("*.py") if re.search(r"numba\.njit\(|@njit\b", p.read_text())}
    assert with_kernels == set(KERNEL_FILES)
    for path in kernel_files():
        text = path.read_text()
        guard = text.find("guard_kernel_module(__file__)")
        assert 0 < guard < text.find("numba.njit("), f"{path.name} must call guard_kernel_module(__file__) first"


def test_a_change_of_any_kernel_file_drops_the_cache_of_every_kernel_module(tmp_path):
    for name in KERNEL_FILES:
        shutil.copy(DYNAMICS / name, tmp_path / name)
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    modules = kernel_files(tmp_path)

    def write_cache_files() -> list[Path]:
        files = [cache / f"{m.stem}.some_kernel-10.py311.nbi" for m in modules]
        for f in files:
            f.write_bytes(b"x")
        return files

    for m in modules:
        guard_kernel_module(m)                              # stamp every module
    key = dependency_digest(modules)
    for changed in modules:
        files = write_cache_files()
        assert not any(guard_kernel_module(m) for m in modules)     # nothing changed: every cache kept
        assert all(f.exists() for f in files)
        original = changed.read_bytes()
        changed.write_bytes(original + b"\n# an edit\n")
        assert dependency_digest(modules) != key, changed.name
        assert all(guard_kernel_module(m) for m in modules), changed.name
        assert not any(f.exists() for f in files)
        changed.write_bytes(original)                       # back: every module is re-stamped on next guard
        for m in modules:
            guard_kernel_module(m)
        assert dependency_digest(modules) == key


def test_indices_are_generated_from_the_field_names_and_frozen_into_the_kernels(monkeypatch):
    """``I_<NAME>`` is the position of NAME in P_FIELDS, a plain int global that numba compiles in as a constant:
    a compiled kernel keeps the value it was compiled with."""
    assert len(set(kn.P_FIELDS)) == kn.N_P == len(kn.P_FIELDS)
    for i, name in enumerate(kn.P_FIELDS):
        assert type(getattr(kn, f"I_{name}")) is int and getattr(kn, f"I_{name}") == i
    P = np.zeros(kn.N_P)
    P[kn.I_TFROZEN] = 0.25
    P[kn.I_OMEGA] = 3.0
    assert kn.eval_time(1.0, P) == 0.25                    # compiled (or loaded) with I_TFROZEN
    monkeypatch.setattr(kn, "I_TFROZEN", kn.I_OMEGA)
    assert kn.eval_time(1.0, P) == 0.25                    # the machine code does not read the global again
