"""Accuracy against SNR as rvdiag commands: `rvdiag evaluate --snr-db --plot [--bound]` (one recall curve per class)
and `rvdiag separability` (the best accuracy any classifier can reach on two states, rvdiag.evaluation.separability).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import run_cli as run
from rvdiag.datasets import write_store
from rvdiag.evaluation.separability import aligned_windows, bound_from_windows, separability_bound

FS = 1000.0
L = 256
#: a short, fast operating point for the simulator: 0.3 s at 60 deg/s holds three 4096-point windows
FAST = ["--output-speed", "60", "--duration", "0.3", "-q"]


def _phi(x: float) -> float:
    return 0.5 * (1.0 + math.erf(x / math.sqrt(2.0)))


# ----------------------------------------------------------------------------- the bound, on synthetic signals
def test_bound_is_the_analytic_phi_of_half_the_distance_over_sigma():
    """Sine against cosine over whole periods: ||a - b||^2 = N, pair power 1/2, so the bound is
    Phi(sqrt(N / 2) 10^(snr/20)); +A against -A: Phi(sqrt(N) 10^(snr/20)).  Windows are averaged."""
    n = 64
    t = np.arange(n)
    a = np.sin(2 * np.pi * 4 * t / n)
    b = np.cos(2 * np.pi * 4 * t / n)
    levels = [-20.0, -10.0, -3.0, 0.0, 5.0]
    got = separability_bound(a, b, n, levels)
    assert got["window"] == n and got["n_windows"] == 1 and got["snr_db"] == levels
    want = [_phi(math.sqrt(n / 2) * 10 ** (s / 20)) for s in levels]
    assert got["accuracy_bound"] == pytest.approx(want, abs=1e-9)
    assert got["distance_over_rms"] == pytest.approx(math.sqrt(n) / math.sqrt(n / 2))
    # two windows of different kinds: the bound is the mean of their own Phi
    ones = np.full(n, 0.3)
    two = bound_from_windows(np.stack([a, ones]), np.stack([b, -ones]), [-10.0])
    assert two["accuracy_bound"][0] == pytest.approx(
        0.5 * (_phi(math.sqrt(n / 2) * 10 ** -0.5) + _phi(math.sqrt(n) * 10 ** -0.5)), abs=1e-9)


def test_bound_is_one_half_for_identical_signals_and_windows_are_aligned():
    x = np.random.default_rng(0).standard_normal(1000)
    got = separability_bound(x, x.copy(), 300, [-10.0, 40.0])
    assert got["n_windows"] == 3 and got["accuracy_bound"] == [0.5, 0.5] and got["distance_over_rms"] == 0.0
    A, B = aligned_windows(x, 2 * x, 300)
    assert A.shape == B.shape == (3, 300) and np.array_equal(B, 2 * A)


def test_matched_filter_reaches_the_bound_in_monte_carlo():
    """The minimum-distance (matched-filter) detector on noisy copies of two equal-power signals, the noise drawn
    by rvdiag.dynamics.noise.add_awgn (the library's own convention), scores the bound within 1 %; a detector
    that ignores the phase (energy) stays near chance."""
    from rvdiag.dynamics.noise import add_awgn

    n, snr = 128, -8.0
    t = np.arange(n)
    pairs = [(np.sin(2 * np.pi * 5 * t / n), np.sin(2 * np.pi * 5 * t / n + 0.6)),
             (np.sin(2 * np.pi * 3 * t / n), np.sin(2 * np.pi * 3 * t / n + 1.1))]
    bound = bound_from_windows(np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs]), [snr])
    assert 0.6 < bound["accuracy_bound"][0] < 0.95          # neither trivial nor chance: the test can tell
    rng = np.random.default_rng(1)
    trials = 20000
    hits = energy_hits = 0
    for a, b in pairs:
        truth = rng.integers(0, 2, trials)
        clean = np.where(truth[:, None] == 0, a, b)
        y = add_awgn(clean, snr, rng)                       # per row: its own power, as the library adds it
        pick_b = np.sum((y - b) ** 2, axis=1) < np.sum((y - a) ** 2, axis=1)
        hits += int(np.sum(pick_b == (truth == 1)))
        energy_hits += int(np.sum((np.sum(y**2, axis=1) > np.sum(a**2)) == (truth == 1)))
    assert hits / (2 * trials) == pytest.approx(bound["accuracy_bound"][0], abs=0.01)
    assert energy_hits / (2 * trials) < 0.53


# ----------------------------------------------------------------------------- rvdiag separability
def test_separability_of_a_state_with_itself_is_chance(capsys):
    code, out, err = run(["separability", "--pair", "T1,T1", "--snr-db=-10,20,60", "--json", *FAST], capsys)
    assert code == 0, err
    res = json.loads(out)
    assert res["pair"] == ["T1", "T1"] and res["accuracy_bound"] == [0.5, 0.5, 0.5]
    assert res["distance_over_rms"] == 0.0 and res["n_windows"] == 3 and res["window"] == 4096


def test_separability_params_b_compares_two_specimens(tmp_path, capsys):
    """--params-b simulates the pair's second state on another reducer: the healthy state against itself on
    another specimen ([modification] error_seed) is no longer chance, while a file of the same specimen (the
    default error_seed, 0) gives the self-pair's zero distance."""
    from importlib import resources

    from rvdiag.params.schema import DEFAULT_PARAMS_NAME

    builtin = resources.files("rvdiag.params").joinpath(DEFAULT_PARAMS_NAME).read_text("utf-8")
    same = tmp_path / "same.toml"
    same.write_text(builtin + "\n[modification]\nerror_seed = 0\n")
    other = tmp_path / "other.toml"
    other.write_text(builtin + "\n[modification]\nerror_seed = 7\n")
    code, out, err = run(["separability", "--pair", "T1,T1", "--snr-db=60", "--json", "--params-b", str(same),
                          *FAST], capsys)
    assert code == 0, err
    res = json.loads(out)
    assert res["distance_over_rms"] == 0.0 and res["accuracy_bound"] == [0.5]
    assert res["params_file"] is None and res["params_file_b"] == str(same)
    code, out, err = run(["separability", "--pair", "T1,T1", "--snr-db=60", "--json", "--params-b", str(other),
                          *FAST], capsys)
    assert code == 0, err
    res = json.loads(out)
    assert res["distance_over_rms"] > 1e-3 and res["accuracy_bound"][0] > 0.99, res


def test_separability_of_a_broken_tooth_rises_with_snr_towards_one(capsys):
    code, out, err = run(["separability", "--pair", "T1,T2", "--snr-db=-50,-40,-30,-20,0", "--json", *FAST], capsys)
    assert code == 0, err
    res = json.loads(out)
    assert set(res) >= {"pair", "window", "n_windows", "snr_db", "accuracy_bound", "distance_over_rms"}
    b = res["accuracy_bound"]
    assert res["snr_db"] == [-50.0, -40.0, -30.0, -20.0, 0.0]
    assert all(0.5 < x <= 1.0 for x in b) and all(x < y or x == y == 1.0 for x, y in zip(b, b[1:])), b
    # the broken tooth changes the housing signal by several times its RMS: chance only far below 0 dB
    assert b[-1] > 0.999 and b[0] < 0.6 and res["distance_over_rms"] > 1.0


def test_separability_progress_goes_to_stderr(capsys):
    code, out, err = run(["separability", "--pair", "T1,T4", "--snr-db=0", "--output-speed", "60", "--duration",
                          "0.3"], capsys)
    assert code == 0 and "separability bound T1/T4" in out and "accuracy bound" in out
    stages = [ln.split(":")[0] for ln in err.splitlines() if not ln.startswith("warning:")]
    assert stages == ["simulating T1", "simulating T4"], err


# ----------------------------------------------------------------------------- rvdiag evaluate --plot / --bound
def _signal(c: int, n: int, rng) -> np.ndarray:
    t = np.arange(n) / FS
    return np.sin(2 * np.pi * (50 + 60 * c) * t + rng.uniform(0, 6)) + 0.2 * rng.standard_normal(n)


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    rng = np.random.default_rng(0)
    X, y, split, unit = [], [], [], []
    for c in range(3):
        for i in range(12):
            X.append(_signal(c, L, rng))
            y.append(f"T{c + 1}")
            split.append("test" if i < 4 else "train")
            unit.append(c * 100 + i)
    p = tmp_path_factory.mktemp("s") / "tiny.zarr"
    write_store(p, np.asarray(X, np.float32), y, meta={"split": split, "unit": unit}, kind="simulated", fs=FS,
                config={"name": "tiny"})
    return p


@pytest.fixture(scope="module")
def model(store, tmp_path_factory):
    from rvdiag.cli import main

    out = tmp_path_factory.mktemp("m") / "model"
    try:
        main([str(a) for a in ["train", store, "--model", "svm", "--features", "spectrum", "--out", out, "-q"]])
    except SystemExit as exc:  # pragma: no cover - a failure shows here
        assert exc.code == 0
    return out


@pytest.fixture(scope="module")
def bound_file(tmp_path_factory):
    from rvdiag.cli import main

    out = tmp_path_factory.mktemp("b") / "bound.json"
    try:
        main(["separability", "--pair", "T1,T4", "--snr-db=-30,0,30", "--crack-depth", "1.8", "--out", str(out),
              *FAST])
    except SystemExit as exc:  # pragma: no cover
        assert exc.code == 0
    return out


def test_evaluate_plot_draws_overall_one_recall_per_class_and_the_bound(model, store, bound_file, tmp_path, capsys,
                                                                        monkeypatch):
    import rvdiag.evaluation.plots as plots

    figures = []
    original = plots.plot_snr_curve
    monkeypatch.setattr(plots, "plot_snr_curve", lambda *a, **k: figures.append(original(*a, **k)) or figures[-1])
    png = tmp_path / "snr.png"
    code, out, err = run(["evaluate", model, store, "--snr-db=-30,0,30", "--plot", png, "--bound", bound_file,
                          "--json", "-q"], capsys)
    assert code == 0, err
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and err.strip() == f"plot: {png.resolve()}"
    res = json.loads(out)
    assert res["bound"] == [json.loads(bound_file.read_text())]
    assert len(figures) == 1
    lines = figures[0].axes[0].get_lines()
    assert [ln.get_label() for ln in lines] == ["overall accuracy", "recall T1", "recall T2", "recall T3",
                                                 "bound T1/T4 (crack 1.8 mm)"]
    assert [ln.get_linestyle() for ln in lines] == ["-", "-", "-", "-", "--"]
    assert list(lines[0].get_xdata()) == [-30.0, 0.0, 30.0]
    assert list(lines[2].get_ydata()) == [100 * r["per_class_recall"]["T2"] for r in res["snr"]]
    assert list(lines[4].get_ydata()) == [100 * v for v in res["bound"][0]["accuracy_bound"]]
    # without --bound: no dashed line
    assert len(original(res["snr"]).axes[0].get_lines()) == 4


def test_evaluate_table_has_one_recall_column_per_class(model, store, capsys):
    code, out, err = run(["evaluate", model, store, "--snr-db=-30,30", "-q"], capsys)
    assert code == 0, err
    table = out[out.index("accuracy against added-noise SNR"):]
    header = next(ln for ln in table.splitlines() if "SNR" in ln and "kappa" in ln)
    assert [c for c in ("T1", "T2", "T3") if c in header] == ["T1", "T2", "T3"]
    assert "recall of each class (class columns)" in " ".join(table.split())  # the caption may wrap


def test_a_level_gets_the_same_noise_whatever_levels_are_asked_with_it(model, store, capsys, monkeypatch):
    """The noise of a level is seeded by the level itself, not by its place in the list."""
    import rvdiag.dynamics.noise as noise

    drawn, original = [], noise.add_awgn

    def add_awgn(x, snr, rng):
        noisy = original(x, snr, rng)
        drawn.append((snr, noisy - x))  # the noise alone
        return noisy

    monkeypatch.setattr(noise, "add_awgn", add_awgn)
    runs = []
    for levels in ("--snr-db=0,30", "--snr-db=30,-3,0"):
        drawn.clear()
        code, out, err = run(["evaluate", model, store, levels, "--json", "-q"], capsys)
        assert code == 0, err
        runs.append(dict(drawn))
    assert set(runs[0]) == {0.0, 30.0} and set(runs[1]) == {30.0, -3.0, 0.0}
    np.testing.assert_array_equal(runs[0][0.0], runs[1][0.0])
    np.testing.assert_array_equal(runs[0][30.0], runs[1][30.0])
    # different levels draw independent noise, not one draw rescaled
    assert abs(np.corrcoef(runs[1][0.0].ravel(), runs[1][-3.0].ravel())[0, 1]) < 0.05


def test_figures_leave_the_users_matplotlib_backend_alone():
    """Importing the evaluation's figures (and the report, the CLI) must not switch a notebook's backend."""
    import subprocess
    import sys

    code = ("import matplotlib; matplotlib.use('svg'); import rvdiag.evaluation.plots as p, rvdiag.evaluation.report, "
            "rvdiag.updating.plot, rvdiag.cli; fig = p.plot_confusion([[2, 1], [0, 3]], ['T1', 'T2']); "
            "import io; b = io.BytesIO(); fig.savefig(b, format='png'); assert b.getvalue()[:4] == b'\\x89PNG'; "
            "print(matplotlib.get_backend())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "svg"


@pytest.mark.parametrize("args, needle", [
    (["evaluate", "{model}", "{store}", "--plot", "{tmp}/p.png"], "--snr-db"),
    (["evaluate", "{model}", "{store}", "--bound", "{tmp}/b.json"], "--snr-db"),
    (["evaluate", "{model}", "{store}", "--snr-db=0", "--bound", "{tmp}/bad.json"], "--bound"),
    (["evaluate", "{model}", "{store}", "--snr-db=0", "--plot", "{tmp}/no/p.png"], "--plot"),
    (["separability", "--pair", "T1,T9"], "unknown state"),
    (["separability", "--pair", "T1"], "two states"),
    (["separability", "--snr-db", "loud"], "--snr-db"),
    (["separability", "--duration", "0.05"], "longer than the record"),
    (["separability", "--window", "20000", "--duration", "0.3"], "longer than the record"),
    (["separability", "--pair", "T1,T2", "--crack-depth", "1"], "--crack-depth does not apply"),
    (["separability", "--out", "{tmp}/no/b.json"], "--out"),
    (["separability", "--params-b", "{tmp}/missing.toml"], "missing.toml"),
])
def test_bad_input_is_one_error_line_and_exit_2(args, needle, model, store, tmp_path, capsys):
    (tmp_path / "bad.json").write_text("{not json")
    argv = [a.format(model=model, store=store, tmp=tmp_path) for a in args]
    code, out, err = run(argv, capsys)
    assert code == 2, (out, err)
    assert len(err.splitlines()) == 1 and err.startswith("error: ") and needle in err, err
    assert not (tmp_path / "p.png").exists()
