"""The API reference (docs/api, ``make docs``) covers every package of rvdiag but the command line."""

from __future__ import annotations

import ast

from conftest import REPO

#: packages the reference leaves out: the command line is documented by ``rvdiag --help`` and docs/
NOT_IN_REFERENCE = {"cli", "configs"}


def _listed() -> list[str]:
    tree = ast.parse((REPO / "docs" / "api" / "conf.py").read_text())
    node = next(n for n in tree.body if isinstance(n, ast.AnnAssign | ast.Assign)
                and "PACKAGES" in ast.unparse(n).split("=")[0])
    return [name for name, _ in ast.literal_eval(node.value)]


def test_every_package_is_in_the_reference():
    packages = {p.parent.name for p in (REPO / "src" / "rvdiag").glob("*/__init__.py")}
    listed = _listed()
    assert len(listed) == len(set(listed))
    assert packages - NOT_IN_REFERENCE <= set(listed), sorted(packages - NOT_IN_REFERENCE - set(listed))
    assert "errors" in listed  # the exceptions a caller catches


def test_doctests_are_collected_from_the_package():
    """``make test`` runs the docstring examples: pytest's testpaths hold src/rvdiag, and the root conftest.py
    collects the modules with an example."""
    import tomllib

    options = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]
    assert "src/rvdiag" in options["testpaths"]
    assert {"ELLIPSIS", "NUMBER"} <= set(options["doctest_optionflags"].split())
    assert "DoctestModule" in (REPO / "conftest.py").read_text()


def test_the_old_paths_of_moved_modules_have_no_page():
    """The deprecated old paths (rvdiag.deprecation.moved_module) are not modules of the reference; their new
    homes are.  The page texts come from docs/api/conf.py's own functions, run without writing the pages."""
    from pathlib import Path

    from test_deprecation import MOVED

    tree = ast.parse((REPO / "docs" / "api" / "conf.py").read_text())
    functions = [n for n in tree.body
                 if isinstance(n, ast.FunctionDef) and n.name in {"_has_all", "_is_moved", "_page"}]
    namespace = {"ast": ast, "Path": Path, "SRC": REPO / "src"}
    exec(compile(ast.Module(functions, type_ignores=[]), "docs/api/conf.py", "exec"), namespace)  # noqa: S102
    pages = "\n".join(namespace["_page"](name, "") or "" for name in _listed())
    assert "rvdiag.evaluation.motor_current_study" in pages  # a package without __all__: each module listed
    for old, _, _, _ in MOVED:
        assert f"rvdiag.{old.split('.')[1]}" in pages and f"{old}`" not in pages and f"{old}\n" not in pages
