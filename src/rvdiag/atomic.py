"""Atomic writes, one home for files and folders: write the new one beside the old, then swap it in with a rename.

A file or folder that a command writes (a model card, a report, a simulation ``.npz``, a sample store, a model
directory) is first written in full to a hidden temporary sibling on the same filesystem; only then is it renamed into
place (``os.replace``, atomic on POSIX and Windows).  An interrupted write (an exception, Ctrl-C, a full disk) leaves
the old file or folder as it was, and removes the temporary sibling; it never leaves a half-written file or a mix of
old and new files.  The new file or folder gets the permissions an ordinary ``open`` / ``mkdir`` would give it under
the process's umask (``mkstemp`` and ``mkdtemp`` create theirs private, 0600 / 0700).

- :func:`atomic_file`: a context manager yielding an open temporary file; on a normal exit it replaces ``path``.
- :func:`atomic_write`: the same for bytes or text already in memory.
- :func:`staged_directory`: a context manager yielding an empty temporary folder; on a normal exit it replaces
  ``path`` whole (:func:`replace_directory`).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Iterator


def _umask() -> int:
    """The process's umask (read by setting it and restoring it: POSIX has no call that only reads it)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def atomic_file(path: str | Path, mode: str = "wb", *, encoding: str | None = None) -> Iterator[IO]:
    """Yield a temporary sibling of ``path`` opened with ``mode`` (``"wb"`` or ``"w"``); on a normal exit it is
    flushed to disk, given the mode ``0o666 & ~umask`` and renamed onto ``path``.  On an exception it is removed and
    ``path`` is untouched.  The parent folder is created if missing."""
    if mode not in ("wb", "w"):
        raise ValueError(f"atomic_file writes a whole file: mode must be 'wb' or 'w', got {mode!r}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, mode, encoding=encoding if mode == "w" else None) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write(path: str | Path, data: bytes | str) -> Path:
    """Write ``data`` (bytes, or text written as UTF-8) to ``path`` through :func:`atomic_file`; returns ``path``."""
    path = Path(path)
    with atomic_file(path, "w" if isinstance(data, str) else "wb",
                     encoding="utf-8" if isinstance(data, str) else None) as fh:
        fh.write(data)
    return path


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
    """Yield an empty temporary sibling of ``path`` (mode ``0o777 & ~umask``) to write into; on a normal exit it
    replaces ``path`` whole (:func:`replace_directory`), on an exception it is removed and ``path`` is untouched."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
    try:
        os.chmod(tmp, 0o777 & ~_umask())  # mkdtemp's 0700 would become the folder's mode
        yield tmp
        replace_directory(tmp, path)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
