"""The house: one home per concern, modules named for what they do, history out of the code."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "rvdiag"


def test_simulate_has_a_module_of_its_own_and_the_package_still_exports_it():
    import rvdiag.dynamics as dynamics
    from rvdiag.dynamics import ModelSettings, simulate

    assert simulate.__module__ == "rvdiag.dynamics.simulation"
    tree = ast.parse((SRC / "dynamics" / "__init__.py").read_text())
    assert not [n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))]
    # the docstrings name the default integrator, Kutta's 3/8 rule, not RK4
    assert ModelSettings().method == "rk38"
    for doc in (dynamics.__doc__, dynamics.simulation.__doc__):
        assert "3/8 rule" in doc and "compiled RK4 integrator" not in doc


def test_physics_revision_history_is_in_bench_history_not_in_the_code():
    from rvdiag.dynamics import PHYSICS_REVISION

    text = (SRC / "dynamics" / "__init__.py").read_text()
    comment = text[:text.index("PHYSICS_REVISION =")].rsplit("\n\n", 1)[-1]
    assert not re.findall(r"\d{4}-\d{2}-\d{2}", comment), comment
    history = (ROOT / "bench" / "HISTORY.md").read_text()
    table = history[history.index("## Physics revisions"):]
    assert f"| {PHYSICS_REVISION} |" in table


def test_the_motor_current_study_has_a_module_named_for_it():
    from rvdiag.evaluation import motor_current_study

    assert callable(motor_current_study.run_mcsa)
    assert motor_current_study.run_mcsa.__module__.startswith("rvdiag.evaluation.motor_current_study.")
    # its old path is only a deprecated alias of it (tests/test_deprecation.py)


def test_one_home_for_window_starts_and_the_spectral_peak():
    """``window_starts`` is defined once (io/windows.py, beside ``covering_starts``); the Hann amplitude spectrum
    and its peak once (rvdiag/spectral.py), used by the motor layer and the io layer below and above it."""
    defs: dict[str, list[str]] = {}
    for f in SRC.rglob("*.py"):
        for node in ast.parse(f.read_text()).body:
            if isinstance(node, ast.FunctionDef):
                defs.setdefault(node.name, []).append(str(f.relative_to(SRC)))
    assert defs["window_starts"] == ["io/windows.py"]
    assert defs["amplitude_spectrum"] == ["spectral.py"]
    import numpy as np

    from rvdiag.io.angles import estimate_shaft_speed
    from rvdiag.motor.lines import output_speed_from_current
    from rvdiag.params import ReducerParams

    fs, n = 1000.0, 4096
    t = np.arange(n) / fs
    p = ReducerParams.default()
    speed = 30.0  # deg/s at the output: the supply line f_e = p f1
    fe = speed / 360.0 * p.ratio * p.operation.motor_pole_pairs
    assert output_speed_from_current(np.sin(2 * np.pi * fe * t), fs, p) == \
        pytest.approx(speed, rel=fs / n / fe)
    assert estimate_shaft_speed(np.sin(2 * np.pi * 123.4 * t), fs, 10.0, (5.0, 30.0)) == \
        pytest.approx(12.34, rel=1e-3)


def test_no_two_modules_import_each_other():
    """Module level, not only between subpackages (library/build.py and library/gpu.py imported each other)."""
    mods = {}
    for f in SRC.rglob("*.py"):
        name = ".".join(f.relative_to(SRC.parent).with_suffix("").parts)
        mods[name.removesuffix(".__init__")] = f
    graph: dict[str, set[str]] = {}
    for m, f in mods.items():
        for node in ast.walk(ast.parse(f.read_text())):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            graph.setdefault(m, set()).update(n for n in names if n in mods and n != m and not m.startswith(n + "."))
    pairs = sorted(f"{a} <-> {b}" for a in graph for b in graph[a] if a < b and a in graph.get(b, ()))
    assert not pairs, pairs
