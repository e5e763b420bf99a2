"""The research/ folder: finished probes, apart from the benchmarks of bench/.

The probes were written against the one-spring mesh kernels of commit c726c7b; the tooth-pair contacts of
2026-11-24 changed the kernels' mesh arrays, so their figures are repeated at that commit (research/README.md),
and the checks of the pin-events probe against the model's right-hand side ran there (tests/test_bench_probes.py
of that commit).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

RESEARCH = Path(__file__).resolve().parents[1] / "research"


def test_research_holds_the_probes_and_bench_only_benchmarks():
    probes = {"pin_events_probe.py", "lane_simd_probe.py", "gpu_ensemble_probe.py"}
    assert probes <= {p.name for p in RESEARCH.glob("*.py")}
    assert not [p.name for p in (RESEARCH.parent / "bench").glob("*probe*.py")]
    readme = (RESEARCH / "README.md").read_text()
    assert all(p in readme for p in probes)


def test_gpu_probe_leaves_numpy_alone_on_import():
    import ast

    tree = ast.parse((RESEARCH / "gpu_ensemble_probe.py").read_text())
    module_level = [n for n in tree.body if not isinstance(n, (ast.FunctionDef, ast.Expr))]
    patched = [ast.unparse(n) for n in module_level if "np." in ast.unparse(n) and isinstance(n, ast.Assign)]
    assert patched == []
    before = dict(vars(np))
    spec = importlib.util.spec_from_file_location("gpu_ensemble_probe", RESEARCH / "gpu_ensemble_probe.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # imports without numba-cuda: nothing runs until main()
    assert module.cuda is None and dict(vars(np)) == before
