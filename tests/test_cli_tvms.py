"""``rvdiag tvms``: JSON output, plot, custom pair, faults, and one-line errors with exit code 2."""

import json

import numpy as np
import pytest

from conftest import run_cli as run


def test_json_healthy_default_pair(capsys):
    code, out, err = run(["tvms", "--json", "--cycles", "2", "--points", "90"], capsys)
    assert code == 0, err
    data = json.loads(out)
    assert len(data["angle_rad"]) == len(data["stiffness_N_per_m"]) == 180
    assert data["mean_N_per_m"] == pytest.approx(np.mean(data["stiffness_N_per_m"]))
    assert data["contact_ratio"] == pytest.approx(1.4426, abs=1e-4)
    assert 1e8 < data["mean_N_per_m"] < 4e8


def test_broken_fault_has_zeros_and_lower_mean(capsys):
    _, out_h, _ = run(["tvms", "--json", "--cycles", "11", "--points", "36"], capsys)
    code, out_b, err = run(["tvms", "--json", "--cycles", "11", "--points", "36", "--fault", "broken",
                            "--broken-fraction", "1.0"], capsys)
    assert code == 0, err
    h, b = json.loads(out_h), json.loads(out_b)
    assert min(b["stiffness_N_per_m"]) == 0.0 and min(h["stiffness_N_per_m"]) > 0
    assert b["mean_N_per_m"] < h["mean_N_per_m"]


def test_custom_pair_and_plot(tmp_path, capsys):
    png = tmp_path / "k.png"
    code, out, err = run(["tvms", "--z1", "20", "--z2", "40", "--module", "2", "--face-width", "20",
                          "--fault", "broken+wear+crack", "--crack-depth", "0.5", "--crack-angle", "45",
                          "--wear-depth", "0.01", "--cycles", "3", "--points", "60", "--plot", str(png)],
                         capsys)
    assert code == 0, err
    assert "mean stiffness" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_custom_pair_profile_shift_cures_undercut(capsys):
    code, _, err = run(["tvms", "--z1", "12", "--z2", "30", "--module", "2", "--cycles", "1"], capsys)
    assert code == 2 and "undercut" in err and "profile_shift >= 0.298" in err
    code, out, err = run(["tvms", "--z1", "12", "--z2", "30", "--module", "2", "--x1", "0.4", "--x2", "-0.4",
                          "--json", "--cycles", "1", "--points", "20"], capsys)
    assert code == 0, err
    assert json.loads(out)["contact_ratio"] > 1


def test_params_file(tmp_path, capsys):
    from rvdiag.params import ReducerParams

    p = ReducerParams.default().replace(stage1={"face_width": 0.02})
    f = tmp_path / "p.toml"
    p.save(f)
    _, out10, _ = run(["tvms", "--json", "--cycles", "1", "--points", "40"], capsys)
    code, out20, err = run(["tvms", "--json", "--cycles", "1", "--points", "40", "--params", str(f)], capsys)
    assert code == 0, err
    # every term scales with the face width
    assert json.loads(out20)["mean_N_per_m"] == pytest.approx(2 * json.loads(out10)["mean_N_per_m"], rel=1e-9)


@pytest.mark.parametrize("args, match", [
    (["--z1", "0", "--z2", "30", "--module", "2"], "teeth"),
    (["--z1", "20", "--z2", "30"], "needs all of"),
    (["--z1", "8", "--z2", "30", "--module", "2"], "undercut"),
    (["--fault", "crack", "--crack-depth", "5"], "crack"),
    (["--fault", "wear", "--wear-depth", "-0.01"], "wear depth must be >= 0"),
    (["--fault", "broken", "--broken-fraction", "2"], "broken fraction"),
    (["--fault", "rust"], "unknown fault"),
    (["--cycles", "-1"], "--cycles"),
    (["--points", "2"], "--points"),
    (["--pair", "cycloid"], "unknown --pair"),
    (["--params", "/nonexistent/p.toml"], "not found"),
    (["--module", "nan", "--z1", "20", "--z2", "40"], "finite"),
])
def test_bad_input_one_line_exit_2(args, match, capsys):
    code, out, err = run(["tvms", *args], capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert match in lines[0]
