"""``rvdiag fleet watch DIR``: ingest new record files from a folder tree named by joint.

A file ``DIR/site/robot/joint/NAME`` is a record of the joint ``site/robot/joint`` (e.g.
``DIR/plant/r1/j3/2026-11-28T08-00.csv``).  Files already there are ingested first (a file already in the store is
a duplicate and changes nothing), then new ones as they appear (:mod:`watchdog`), each once its size has stayed the
same for ``settle`` seconds (a file still being copied is not read half-way).  Hidden files and names ending in
``.tmp`` / ``.part`` are left alone, so a writer can copy to such a name and rename.  A file of an unknown joint, or
one the store refuses, is reported and the watcher goes on; the one code path is :meth:`Fleet.ingest`.
"""

from __future__ import annotations

import queue
import time
from pathlib import Path
from typing import Callable

from rvdiag.errors import FleetError, RvdiagError

IGNORED_SUFFIXES = (".tmp", ".part", ".partial", ".crdownload")


def joint_of(root: Path, path: Path) -> str | None:
    """The joint a file belongs to (its three folders under ``root``), or None when it is not a record file."""
    try:
        rel = Path(path).resolve().relative_to(Path(root).resolve())
    except ValueError:
        return None
    if len(rel.parts) != 4 or any(p.startswith(".") for p in rel.parts):
        return None
    if rel.name.lower().endswith(IGNORED_SUFFIXES):
        return None
    return "/".join(rel.parts[:3])


def existing_files(root: Path) -> list[Path]:
    """The record files under ``root`` in name order (:func:`joint_of`)."""
    return sorted(p for p in Path(root).glob("*/*/*/*") if p.is_file() and joint_of(root, p))


def _settled(path: Path, settle: float) -> bool:
    try:
        a = path.stat()
        time.sleep(settle)
        b = path.stat()
    except FileNotFoundError:
        return False
    return (a.st_size, a.st_mtime_ns) == (b.st_size, b.st_mtime_ns)


def watch(fleet, root: Path, reading, *, once: bool = False, settle: float = 1.0, report: Callable = print,
          stop: Callable[[], bool] | None = None) -> dict:
    """Ingest the record files under ``root`` (module docstring); with ``once`` only those there now.  Returns
    ``{"ingested", "duplicates", "rejected", "refused"}`` counts.  ``report(line, error)`` is told of each file."""
    root = Path(root)
    if not root.is_dir():
        raise FleetError(f"no folder {root} to watch")
    counts = {"ingested": 0, "duplicates": 0, "rejected": 0, "refused": 0}

    def handle(path: Path) -> None:
        joint = joint_of(root, path)
        if joint is None or not path.is_file():
            return
        try:
            res = fleet.ingest(joint, path, filename=path.name, reading=reading, time=None)
        except RvdiagError as exc:
            counts["refused"] += 1
            report(f"{path}: refused: {' '.join(str(exc).split())}", True)
            return
        if res["duplicate"]:
            counts["duplicates"] += 1
            return
        if res["rejected"]:
            counts["rejected"] += 1
            report(f"{path}: rejected (stored with its reason): {res['rejected']}", True)
            return
        counts["ingested"] += 1
        r = res["result"] or {}
        hi = r.get("health_index")
        report(f"{joint} {path.name}: health index {'-' if hi is None else f'{hi:.3g}'}, joint {res['joint_state']}",
               False)

    for p in existing_files(root):
        handle(p)
    if once:
        return counts

    from watchdog.events import FileSystemEventHandler
    from watchdog.observers import Observer

    todo: queue.Queue = queue.Queue()

    class _Handler(FileSystemEventHandler):
        def on_created(self, event):  # noqa: ANN001
            if not event.is_directory:
                todo.put(Path(event.src_path))

        def on_moved(self, event):  # noqa: ANN001
            if not event.is_directory:
                todo.put(Path(event.dest_path))

        def on_closed(self, event):  # noqa: ANN001
            if not event.is_directory:
                todo.put(Path(event.src_path))

    obs = Observer()
    obs.schedule(_Handler(), str(root), recursive=True)
    obs.start()
    try:
        while not (stop and stop()):
            try:
                p = todo.get(timeout=0.5)
            except queue.Empty:
                continue
            if joint_of(root, p) and _settled(p, settle):
                handle(p)
    except KeyboardInterrupt:
        pass
    finally:
        obs.stop()
        obs.join(timeout=5)
    return counts
