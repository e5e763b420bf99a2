"""Keep numba's on-disk cache honest across modules.

numba's ``cache=True`` keys a compiled function on its own source file only.  The integrator kernels in
:mod:`rvdiag.dynamics.integrate` inline the force kernels of :mod:`rvdiag.dynamics.model`, so after an edit of
``model.py`` alone numba would keep loading the old machine code for the integrator (found the hard way,
bench/HISTORY.md 2026-11-23).  :func:`drop_stale_cache` stores a hash of the files a module depends on next
to numba's cache files and deletes that module's cache when the hash changes.  Only the default cache
location (``__pycache__`` beside the module) is handled; with ``NUMBA_CACHE_DIR`` set, clear that folder by
hand after editing.
"""

from __future__ import annotations

import hashlib
from pathlib import Path


def drop_stale_cache(module_file: str | Path, dependencies: list[str | Path]) -> bool:
    """Delete ``module_file``'s numba cache files when ``dependencies`` changed since they were written.

    Returns True when files were deleted.  Never raises: a read-only install just keeps its cache.
    """
    module = Path(module_file)
    cache = module.parent / "__pycache__"
    digest = hashlib.sha256()
    for dep in dependencies:
        digest.update(Path(dep).read_bytes())
    stamp = cache / f"{module.stem}.deps-sha256"
    try:
        if stamp.is_file() and stamp.read_text().strip() == digest.hexdigest():
            return False
        stale = list(cache.glob(f"{module.stem}.*.nbi")) + list(cache.glob(f"{module.stem}.*.nbc"))
        for f in stale:
            f.unlink()
        cache.mkdir(exist_ok=True)
        stamp.write_text(digest.hexdigest())
        return bool(stale)
    except OSError:
        return False
