"""Packaging: ranges in pyproject, exact pins in constraints.txt, one version, the shipped configs installed."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tomllib
import zipfile

from conftest import REPO

import rvdiag
from rvdiag.library.config import LibraryConfig, builtin_config_path, builtin_configs

PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())
SHIPPED = {"demo", "demo-fleet", "demo-monitoring", "demo-life", "life", "mcsa", "mcsa-study", "monitoring", "monitoring-current", "paper", "independent", "transfer", "experiments/snr", "experiments/independent20",
           "experiments/independent-speed"}


def _name(req: str) -> str:
    return re.split(r"[<>=!~\[; ]", req, maxsplit=1)[0].lower().replace("_", "-")


def _constraints() -> dict[str, str]:
    pins = {}
    for line in (REPO / "constraints.txt").read_text().splitlines():
        if line and not line.startswith("#"):
            name, version = line.split("==")
            pins[name.lower().replace("_", "-")] = version
    return pins


def test_runtime_dependencies_are_ranges_and_pyemd_is_for_tests_only():
    deps = PYPROJECT["project"]["dependencies"]
    assert not [d for d in deps if "==" in d]
    assert "emd-signal" not in {_name(d) for d in deps}
    assert "emd-signal" in {_name(d) for d in PYPROJECT["project"]["optional-dependencies"]["test"]}
    imports = [p for p in (REPO / "src").rglob("*.py")
               if re.search(r"^\s*(from|import) PyEMD", p.read_text(), re.M)]
    assert imports == []


def test_constraints_pin_every_dependency_and_the_cpu_torch():
    pins = _constraints()
    assert pins["torch"] == "2.13.0" and pins["mealpy"] == "3.0.3" and pins["emd-signal"] == "1.10.0"
    extras = PYPROJECT["project"]["optional-dependencies"]
    reqs = PYPROJECT["project"]["dependencies"] + extras["test"] + extras["docs"]
    assert [r for r in reqs if _name(r) not in pins] == []
    assert "-c constraints.txt" in (REPO / "Makefile").read_text()


def test_version_is_written_once():
    assert "version" not in PYPROJECT["project"] and PYPROJECT["project"]["dynamic"] == ["version"]
    assert PYPROJECT["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "rvdiag.__version__"}
    assert re.fullmatch(r"\d+\.\d+\.\d+", rvdiag.__version__)


def test_builtin_configs_are_the_repository_configs():
    assert set(builtin_configs()) == SHIPPED
    assert (REPO / "configs").resolve() == (REPO / "src/rvdiag/configs").resolve()
    for name in ("demo", "paper", "experiments/snr"):
        by_name, by_path = LibraryConfig.load(name), LibraryConfig.load(REPO / "configs" / f"{name}.toml")
        assert by_name.to_dict() == by_path.to_dict()
        assert builtin_config_path(name).read_bytes() == (REPO / "configs" / f"{name}.toml").read_bytes()


def test_wheel_ships_the_configs_and_the_version(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    for f in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / f, src / f)
    shutil.copytree(REPO / "src", src / "src", ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    subprocess.run([sys.executable, "-m", "pip", "wheel", str(src), "--no-deps", "--no-build-isolation", "-q",
                    "-w", str(tmp_path / "dist")], check=True, capture_output=True)
    (wheel,) = (tmp_path / "dist").glob("rvdiag-*.whl")
    assert wheel.name.startswith(f"rvdiag-{rvdiag.__version__}-")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert {f"rvdiag/configs/{n}.toml" for n in SHIPPED} <= names
    assert "rvdiag/params/rv20e.toml" in names
    assert {"rvdiag/fleet/migrations/env.py", "rvdiag/fleet/migrations/versions/0001_fleet_store.py"} <= names
    # the dashboard's templates and its own script and style (Plotly's comes from the plotly wheel)
    assert {f"rvdiag/fleet/web/templates/{n}.html" for n in ("base", "fleet", "joint", "alarms", "error")} <= names
    assert {f"rvdiag/fleet/web/static/{n}" for n in ("dashboard.css", "dashboard.js", "favicon.svg")} <= names


def test_every_declared_marker_is_used():
    declared = [m.split(":")[0] for m in PYPROJECT["tool"]["pytest"]["ini_options"].get("markers", [])]
    text = "".join(p.read_text() for p in (REPO / "tests").glob("test_*.py"))
    assert [m for m in declared if f"mark.{m}" not in text] == []
