"""Keep numba's on-disk cache honest across the kernel files (docs/model.md section 7).

numba's ``cache=True`` keys a compiled function on its own source file only.  A kernel that calls or inlines a
kernel of another file, or reads another file's compile-time constants (the ``I_*`` indices of ``P``), would keep
loading its old machine code after an edit of that other file alone (found the hard way, bench/HISTORY.md
2026-11-23: the integrator ran old force code).  Every file that holds kernels is therefore listed in
:data:`KERNEL_FILES` and calls :func:`guard_kernel_module` before it defines its kernels: that module's cache is
dropped whenever ANY kernel file changed (a hash of them all is stored next to numba's cache files).  A new kernel
file (the motor, the mounting path) must join the list; ``tests/test_numba_cache.py`` fails until it does.
Only the default cache location (``__pycache__`` beside the module) is handled; with ``NUMBA_CACHE_DIR`` set,
clear that folder by hand after editing.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

#: the files of :mod:`rvdiag.dynamics` that define numba kernels, relative to this folder
KERNEL_FILES = ("kernels.py", "integrate.py", "motor_kernel.py")


def kernel_files(root: str | Path | None = None) -> list[Path]:
    """Paths of :data:`KERNEL_FILES` under ``root`` (default: this package's folder)."""
    base = Path(__file__).parent if root is None else Path(root)
    return [base / name for name in KERNEL_FILES]


def dependency_digest(dependencies: list[str | Path]) -> str:
    """SHA-256 of the contents of ``dependencies``, in order: the key a module's cache is stamped with."""
    digest = hashlib.sha256()
    for dep in dependencies:
        digest.update(Path(dep).read_bytes())
    return digest.hexdigest()


def drop_stale_cache(module_file: str | Path, dependencies: list[str | Path]) -> bool:
    """Delete ``module_file``'s numba cache files when ``dependencies`` changed since they were written.

    Returns True when files were deleted.  Never raises: a read-only install just keeps its cache.
    """
    module = Path(module_file)
    cache = module.parent / "__pycache__"
    key = dependency_digest(dependencies)
    stamp = cache / f"{module.stem}.deps-sha256"
    try:
        if stamp.is_file() and stamp.read_text().strip() == key:
            return False
        stale = list(cache.glob(f"{module.stem}.*.nbi")) + list(cache.glob(f"{module.stem}.*.nbc"))
        for f in stale:
            f.unlink()
        cache.mkdir(exist_ok=True)
        stamp.write_text(key)
        return bool(stale)
    except OSError:
        return False


def guard_kernel_module(module_file: str | Path) -> bool:
    """Drop ``module_file``'s numba cache when any kernel file changed; call it at the top of every kernel file,
    before its kernels are defined (numba reads the cache only when a kernel first runs)."""
    return drop_stale_cache(module_file, kernel_files(Path(module_file).parent))
