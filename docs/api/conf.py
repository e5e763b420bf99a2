"""Sphinx configuration of rvdiag's API reference (``make docs``; output in build/docs, warnings are errors).

The reference is built from the numpydoc docstrings.  ``PACKAGES`` lists the public packages in the order of the
layers, top to bottom; each gets one page, written here at build time into ``generated/`` (not kept in git): the
package's docstring, then the names of its ``__all__``, or, for a package without ``__all__``, each public
module's members (not the deprecated old paths of moved modules).  A package listed but not in this checkout is
left out with a line on the console, so a new one is added by naming it here.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
SRC = HERE.parents[1] / "src"
sys.path.insert(0, str(SRC))

import rvdiag  # noqa: E402

project = "rvdiag"
release = version = rvdiag.__version__
extensions = ["sphinx.ext.autodoc", "numpydoc"]
exclude_patterns = ["_build"]
html_theme = "alabaster"
html_static_path: list[str] = []
autodoc_member_order = "bysource"
autodoc_typehints = "none"           # numpydoc's Parameters sections state the types
numpydoc_show_class_members = False  # autodoc lists the members; numpydoc's tables of them would repeat it
numpydoc_class_members_toctree = False


def _skip_sklearn_request_methods(app, what, name, obj, skip, options):
    """scikit-learn's generated ``set_*_request`` methods (metadata routing) are not rvdiag's API."""
    return True if name.startswith("set_") and name.endswith("_request") else None


def setup(app):
    app.connect("autodoc-skip-member", _skip_sklearn_request_methods)

#: (package, what it is for the reader), application layer first
PACKAGES = [
    ("workflows", "train, evaluate, diagnose a record: the Python API"),
    ("monitoring", "the baseline monitor: one home"),
    ("prognostics", "change detection and remaining life of a joint"),
    ("fleet", "history store, joint state, HTTP API, dashboard"),
    ("params", "reducer parameter sets"),
    ("gears", "gear geometry, mesh stiffness, tooth faults"),
    ("dynamics", "the 27-DOF model and its integrator"),
    ("motor", "the servo motor and its phase currents"),
    ("updating", "fitting a reducer model to a measured healthy record; what a record can identify"),
    ("library", "health states and simulated fault-sample libraries"),
    ("datasets", "the Zarr sample store"),
    ("io", "measured signal files"),
    ("features", "feature extractors"),
    ("models", "classifiers, CNN features, persistence"),
    ("evaluation", "metrics, figures, the report"),
    ("kinematics", "characteristic and fault frequencies"),
    ("errors", "the exceptions rvdiag raises"),
]


def _has_all(path: Path) -> bool:
    """Whether a module file assigns ``__all__`` (read without importing it)."""
    return any(isinstance(node, (ast.Assign, ast.AnnAssign)) and "__all__" in ast.unparse(node).split("=")[0]
               for node in ast.parse(path.read_text(encoding="utf-8")).body)


def _is_moved(path: Path) -> bool:
    """Whether a module file is the deprecated old path of a moved module (it calls
    :func:`rvdiag.deprecation.moved_module`): not a module of the reference, whose page is the new one's."""
    return any(isinstance(node, ast.Call) and getattr(node.func, "id", None) == "moved_module"
               for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))))


def _page(name: str, summary: str) -> str | None:
    pkg = SRC / "rvdiag" / name
    init = pkg / "__init__.py" if pkg.is_dir() else pkg.with_suffix(".py")
    if not init.is_file():
        return None
    title = f"``rvdiag.{name}``: {summary}"
    lines = [title, "=" * len(title), "", f".. automodule:: rvdiag.{name}", ""]
    if not pkg.is_dir():  # a module: what it defines
        lines[-1:] = ["   :members:", ""]
        return "\n".join(lines)
    if _has_all(init):  # a package: the names of its __all__, wherever they are defined
        lines[-1:] = ["   :members:", "   :imported-members:", ""]
        return "\n".join(lines)
    subs = [p.stem for p in pkg.glob("*.py") if not _is_moved(p)] + [p.parent.name for p in pkg.glob("*/__init__.py")]
    for mod in sorted(m for m in subs if not m.startswith("_")):
        sub = f"rvdiag.{name}.{mod}"
        lines += [f"``{sub}``", "-" * (len(sub) + 4), "", f".. automodule:: {sub}", "   :members:", ""]
    return "\n".join(lines)


def _write_pages() -> None:
    out = HERE / "generated"
    out.mkdir(exist_ok=True)
    toc = [".. toctree::", "   :maxdepth: 1", ""]
    for name, summary in PACKAGES:
        text = _page(name, summary)
        if text is None:
            print(f"rvdiag.{name}: not in this checkout, left out of the reference")
            continue
        page = out / f"{name}.rst"
        if not page.is_file() or page.read_text() != text:  # unchanged pages keep their time: no rebuild
            page.write_text(text)
        toc.append(f"   generated/{name}")
    (out / "toc.rst.inc").write_text("\n".join(toc) + "\n")


_write_pages()
