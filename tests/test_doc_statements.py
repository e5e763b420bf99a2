"""Figures that README and docstrings state, checked against the code and against the figures they derive from."""

from __future__ import annotations

import re

from conftest import REPO

import rvdiag
from rvdiag.dynamics.model import dof_names


def test_dof_count_stated_everywhere_is_the_models():
    n = len(dof_names(2, 2))
    assert n == 27
    texts = {
        "README.md": (REPO / "README.md").read_text(),
        "pyproject.toml": (REPO / "pyproject.toml").read_text(),
        "rvdiag/__init__.py": rvdiag.__doc__,
        "library/simulators.py": (REPO / "src/rvdiag/library/simulators.py").read_text(),
    }
    for name, text in texts.items():
        counts = {int(m) for m in re.findall(r"(\d+)-DOF", text)}
        assert counts == {n}, (name, counts)


def test_speed_shortfall_is_the_ratio_of_the_readme_figures():
    text = (REPO / "README.md").read_text()
    speed = float(re.search(r"\| ([\d.]+) simulated s per s \(3/8 rule, 9 sub-steps", text).group(1))
    goal = float(re.search(r"goal: ([\d.]+) simulated s per s at 9 sub-steps", text).group(1))
    short = float(re.search(r"simulator is ([\d.]+)x short of its one-core speed goal", text).group(1))
    assert (speed, goal) == (1.09, 5.0)
    assert short == round(goal / speed, 1) == 4.6
    assert f"({speed} of {goal:g} simulated s per s" in text


def test_train_defaults_are_the_recommended_setup_of_results_md():
    """`rvdiag train STORE -o M` trains what docs/results.md recommends: the statement there, the registry's
    RECOMMENDED_TRAINING, the command's defaults and `make demo` (which no longer overrides them) agree."""
    import typer

    from rvdiag.cli import build_app
    from rvdiag.registry import RECOMMENDED_TRAINING

    text = (REPO / "docs" / "results.md").read_text()
    stated = re.search(r"\*\*Recommended setup\*\* \(the defaults of `rvdiag train`.*?: `(--model [^`]*)`", text,
                       re.S).group(1)
    options = dict(re.findall(r"--([\w-]+) (\S+)", stated))
    assert {k: type(RECOMMENDED_TRAINING[k])(v) for k, v in options.items()} == RECOMMENDED_TRAINING
    assert RECOMMENDED_TRAINING == {"model": "spectrum-cnn", "representation": "logspec", "epochs": 40, "lr": 3e-3,
                                   "patience": 6}
    train = typer.main.get_command(build_app()).commands["train"]
    defaults = {p.name: p.default for p in train.params}
    # --model has no fixed default: the recommended model (rvdiag.workflows.train), or the baseline monitor on a
    # paired store (cli/train.py dispatches to rvdiag.monitoring.train_monitor)
    assert defaults["model"] is None and 'model = model or RECOMMENDED_TRAINING["model"]' in (
        REPO / "src" / "rvdiag" / "workflows" / "training.py").read_text()
    assert {k: defaults[k] for k in RECOMMENDED_TRAINING if k != "model"} == {
        k: v for k, v in RECOMMENDED_TRAINING.items() if k != "model"}
    demo = (REPO / "examples" / "demo.py").read_text()
    assert "--representation" not in demo and "--lr" not in demo and "--epochs" not in demo
    readme = (REPO / "README.md").read_text()
    assert "rvdiag train out/demo.zarr -o out/model   # the recommended setup: spectrum-cnn on log spectra" in readme
