"""Replacing a folder whole: write the new one beside it, then swap (used by model directories and sample stores).

A folder that a command replaces (``rvdiag train -o DIR``, a measured-data store) is first written in full to a
hidden temporary sibling; only then is the old folder renamed aside, the new one renamed into place and the old one
removed.  An interrupted write leaves the old folder as it was (and at most a hidden ``.NAME.*.tmp`` sibling), never a
mix of old and new files.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator


def replace_directory(tmp: Path, path: Path) -> None:
    """Move the finished folder ``tmp`` to ``path``, replacing what is there (two renames on the same filesystem)."""
    if path.exists():
        old = path.with_name(f".{path.name}.old-{os.getpid()}")
        os.replace(path, old)
        os.replace(tmp, path)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(tmp, path)


@contextmanager
def staged_directory(path: str | Path) -> Iterator[Path]:
    """Yield an empty temporary sibling of ``path`` to write into; on a normal exit it replaces ``path`` whole
    (:func:`replace_directory`), on an exception it is removed and ``path`` is untouched."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)  # mkdtemp's 0700 would become the folder's mode
        yield tmp
        replace_directory(tmp, path)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
