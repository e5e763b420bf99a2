"""The package's layering: a lower layer never imports a higher one, and no subpackages import each other in a
circle.  Every ``import`` statement is read with ``ast`` (those inside functions too: a deferred import is still a
dependency), so the test needs no import of rvdiag and runs in well under a second."""

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "rvdiag"

#: Layer of each top-level module or subpackage of rvdiag, lowest first.  Equal numbers may import each other
#: (as long as they form no circle); a module may import any lower layer.
LAYERS = {
    "__init__": 0, "_version": 0, "atomic": 0, "spectral": 0, "errors": 0, "tomlfile": 0, "registry": 0, "progress": 0,
    "validation": 0, "deprecation": 0,
    "params": 1,
    "gears": 2, "kinematics": 2,
    "dynamics": 3, "motor": 3,
    "library": 4, "datasets": 4, "io": 4,
    "features": 5,
    "updating": 5,  # the model's updating and its observability, which takes the features' synchronous average
    "models": 6,
    "evaluation": 7,
    "workflows": 8,  # the application layer: read a record, train, evaluate, diagnose (rvdiag.workflows)
    "monitoring": 9,  # a joint against its own baseline; uses workflows' record reading and checks
    "prognostics": 9,  # change detection and remaining life on a joint's record scores (no signals)
    "fleet": 10,  # many joints over time, on monitoring and workflows
    "cli": 11, "__main__": 11,
}


def _unit(path: Path) -> str:
    rel = path.relative_to(SRC)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def _imported_units(path: Path) -> set[tuple[str, int]]:
    """rvdiag units (``LAYERS`` keys) that ``path`` imports, with the line of the import."""
    tree = ast.parse(path.read_text(), filename=str(path))
    out = set()
    for node in ast.walk(tree):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if node.module == "rvdiag":  # a submodule, or a name of rvdiag/__init__.py (``__version__``)
                names = [f"rvdiag.{a.name}" if a.name in LAYERS else "rvdiag" for a in node.names]
            else:
                names = [node.module]
        elif isinstance(node, ast.ImportFrom) and node.level > 0:
            raise AssertionError(f"{path}:{node.lineno}: relative import; rvdiag uses absolute imports")
        for name in names:
            parts = name.split(".")
            if parts[0] == "rvdiag":
                out.add((parts[1] if len(parts) > 1 else "__init__", node.lineno))
    return out


def _edges():
    files = sorted(SRC.rglob("*.py"))
    assert len(files) > 40
    edges = []
    for f in files:
        src = _unit(f)
        for dst, line in _imported_units(f):
            edges.append((src, dst, f"{f.relative_to(SRC.parent)}:{line}"))
    return edges


def test_every_unit_has_a_layer():
    units = {_unit(f) for f in SRC.rglob("*.py")}
    assert units <= set(LAYERS), f"give these a layer in LAYERS: {sorted(units - set(LAYERS))}"


def test_no_lower_layer_imports_a_higher_one():
    bad = [f"{where}: {src} (layer {LAYERS[src]}) imports rvdiag.{dst} (layer {LAYERS[dst]})"
           for src, dst, where in _edges() if src != dst and LAYERS[dst] > LAYERS[src]]
    assert not bad, "\n".join(bad)


def test_no_import_circle_between_subpackages():
    graph: dict[str, set[str]] = {}
    for src, dst, _ in _edges():
        if src != dst:
            graph.setdefault(src, set()).add(dst)

    def reaches(a, b, seen=()):
        return any(n == b or (n not in seen and reaches(n, b, seen + (n,))) for n in graph.get(a, ()))

    circles = sorted(f"{a} <-> {b}" for a in graph for b in graph[a] if reaches(b, a))
    assert not circles, circles


#: the tests of the command line's own machinery (its option vocabulary, its warning lines)
CLI_TESTS = ("test_cli_basics.py", "test_cli_options.py", "test_warning_lines.py")


def python_files(mentioning: str = ""):
    """The Python files of the package, the tests, benchmarks, research scripts and examples (those whose text
    matches the regular expression ``mentioning``: a quick filter before they are parsed)."""
    root = SRC.parents[1]
    for folder in (SRC, root / "tests", root / "bench", root / "research", root / "examples"):
        yield from (f for f in sorted(folder.rglob("*.py")) if folder.is_dir() and re.search(mentioning, f.read_text()))


def imported_names(path: Path):
    """``("FILE:LINE", name)`` of each module and name that ``path`` imports (``from a import b``: ``a`` and
    ``a.b``), FILE relative to the repository."""
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        yield from ((f"{path.relative_to(SRC.parents[1])}:{node.lineno}", n) for n in names)


def test_nothing_outside_the_cli_imports_its_private_modules():
    """``rvdiag.cli._*`` are the command line's own; the rest of the package, the tests, benchmarks, research scripts
    and examples use the public API (rvdiag.workflows, rvdiag.monitoring).  The command line's own unit tests
    (:data:`CLI_TESTS`) may test its private parts."""
    bad = [f"{where}: {name}" for f in python_files(r"rvdiag\.cli")
           if not (f.is_relative_to(SRC / "cli") or f == Path(__file__).resolve() or f.name in CLI_TESTS)
           for where, name in imported_names(f) if name.startswith("rvdiag.cli._")]
    assert not bad, "\n".join(bad)


def test_the_checker_sees_deferred_and_from_imports(tmp_path):
    """The parser finds an import inside a function and ``from rvdiag import x`` (the forms that hid the circle)."""
    f = tmp_path / "m.py"
    f.write_text("def f():\n    from rvdiag.models.pipelines import x\n\nfrom rvdiag import features\nimport numpy\n")
    assert _imported_units(f) == {("models", 2), ("features", 4)}


def _fresh(code: str) -> str:
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return r.stdout.strip()


@pytest.mark.parametrize("name", ["time", "spectrum", "wpd", "none"])
def test_signal_features_do_not_import_torch(name):
    out = _fresh("import sys; from rvdiag.features import make_features, feature_names; "
                 f"make_features({name!r}); feature_names(); print('torch' in sys.modules)")
    assert out == "False"
