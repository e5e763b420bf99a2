"""Raw records kept content-addressed beside the fleet database.

A record's bytes are stored once under their SHA-256, ``BLOBS/ab/cdef...<suffix>`` (the first two hex digits a
folder, the suffix the file's own, lower case, so that the reader knows the format).  The blob folder is
``<database file>.blobs/`` beside a SQLite file, or the folder given by ``RVDIAG_FLEET_BLOBS`` (needed for
PostgreSQL, whose database has no file to stand beside).  A blob is written to a temporary sibling and renamed into
place, so a reader never sees half a file; writing the same bytes twice is a no-op.  Names from users never become
paths: a blob's path is made of its checksum and a suffix of letters and digits only.
"""

from __future__ import annotations

import hashlib
import os
import re
import tempfile
from pathlib import Path

from rvdiag.errors import FleetError

ENV_BLOBS = "RVDIAG_FLEET_BLOBS"
#: a suffix kept on a blob: a dot, then letters and digits (``.csv``, ``.gz``, ``.npy``), at most three of them
_SUFFIX = re.compile(r"^(\.[a-z0-9]{1,8}){1,3}$")
_HEX = re.compile(r"^[0-9a-f]{64}$")
_ONE = re.compile(r"^\.[a-z][a-z0-9]{0,7}$")
_COMPRESSED = (".gz", ".bz2", ".xz", ".zst")


def checksum(data: bytes) -> str:
    """The SHA-256 of ``data`` in hex."""
    return hashlib.sha256(data).hexdigest()


def safe_suffix(filename: str) -> str:
    """The file's format ending in lower case (``.csv``, ``.npy``; with a compression ending before it, ``.csv.gz``)
    when it is plain letters and digits, else ``""``: what the reader needs to know the format, and nothing of the
    user's name that could make a path.

    >>> safe_suffix("../../etc/x.CSV.gz"), safe_suffix("r_44.9dps_50.1Nm.npy"), safe_suffix("a.b c"), safe_suffix("x")
    ('.csv.gz', '.npy', '', '')
    """
    name = Path(str(filename).replace("\\", "/")).name.lower()
    parts = Path(name).suffixes
    if not parts or not _ONE.match(parts[-1]):
        return ""
    if parts[-1] in _COMPRESSED and len(parts) > 1 and _ONE.match(parts[-2]):
        return parts[-2] + parts[-1]
    return parts[-1]


class BlobStore:
    """The content-addressed folder of raw records (module docstring)."""

    def __init__(self, root: Path):
        self.root = Path(root)

    @classmethod
    def for_url(cls, url: str) -> "BlobStore":
        """The blob folder of a database URL: ``$RVDIAG_FLEET_BLOBS``, else ``<file>.blobs`` beside a SQLite file."""
        from rvdiag.fleet.db import sqlite_path

        env = os.environ.get(ENV_BLOBS)
        if env:
            return cls(Path(env))
        path = sqlite_path(url)
        if path is None:
            raise FleetError(f"the fleet database {url.split('@')[-1]} has no file to keep raw records beside: set "
                             f"{ENV_BLOBS} to a folder for them")
        return cls(path.with_name(path.name + ".blobs"))

    def path(self, digest: str, suffix: str = "") -> Path:
        if not _HEX.match(digest) or (suffix and not _SUFFIX.match(suffix)):
            raise FleetError(f"not a record checksum: {digest!r}")
        return self.root / digest[:2] / (digest[2:] + suffix)

    def put(self, data: bytes, filename: str) -> tuple[str, Path]:
        """Keep ``data`` (once); returns its checksum and path."""
        digest = checksum(data)
        path = self.path(digest, safe_suffix(filename))
        if not path.exists():
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=".", suffix=".tmp", dir=path.parent)
            try:
                with os.fdopen(fd, "wb") as f:
                    f.write(data)
                os.replace(tmp, path)
            except BaseException:
                Path(tmp).unlink(missing_ok=True)
                raise
        return digest, path

    def find(self, digest: str) -> Path:
        """The kept file of ``digest`` (whatever its suffix)."""
        self.path(digest)  # checks the digest
        folder = self.root / digest[:2]
        hits = sorted(folder.glob(digest[2:] + "*")) if folder.is_dir() else []
        hits = [h for h in hits if not h.name.endswith(".tmp")]
        if not hits:
            raise FleetError(f"no raw record {digest[:12]}... is kept in {self.root}")
        return hits[0]

    def baseline_dir(self, joint_id: int, epoch: int) -> Path:
        """Where a joint's baseline of an epoch is written (``baselines/<joint id>/epoch-<n>.zarr``)."""
        return self.root / "baselines" / str(int(joint_id)) / f"epoch-{int(epoch)}.zarr"
