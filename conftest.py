"""The docstring examples of ``src/rvdiag`` run as doctests with the test suite (``make test``).

Only the modules whose docstrings hold an example (``>>>``) are collected, so that the collection imports no
module needlessly; the option flags (``ELLIPSIS``, ``NUMBER``, ``NORMALIZE_WHITESPACE``) are pyproject.toml's
``doctest_optionflags``.
"""

from __future__ import annotations

from pathlib import Path

from _pytest.doctest import DoctestModule

PACKAGE = Path(__file__).resolve().parent / "src" / "rvdiag"


def pytest_collect_file(file_path: Path, parent):
    if (file_path.suffix == ".py" and PACKAGE in file_path.parents and file_path.name != "__main__.py"
            and ">>>" in file_path.read_text(encoding="utf-8")):
        return DoctestModule.from_parent(parent, path=file_path)
    return None
