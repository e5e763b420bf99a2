"""The rvdiag command: version, help, error handling (one line, exit 2), params sub-commands."""

import json
import subprocess
import sys

import pytest

from rvdiag import __version__
from rvdiag.cli import main
from conftest import run_cli as run


def test_version(capsys):
    code, out, _ = run(["--version"], capsys)
    assert code == 0 and out.strip() == f"rvdiag {__version__}"


def test_unknown_command_is_one_line_exit_2(capsys):
    code, _, err = run(["no-such-command"], capsys)
    assert code == 2
    assert err.strip().startswith("error:") and len(err.strip().splitlines()) == 1


def test_params_show_json(capsys):
    code, out, _ = run(["params", "show", "--json"], capsys)
    data = json.loads(out)
    assert code == 0 and data["derived"]["ratio"] == 121.0
    assert data["params"]["stage1"]["sun_teeth"] == 11


def test_params_export_then_check_round_trip(tmp_path, capsys):
    target = tmp_path / "mine.toml"
    assert run(["params", "export", str(target)], capsys)[0] == 0
    assert "# [Li2024]" in target.read_text()  # the sources of the values travel with the copy
    code, out, _ = run(["params", "check", str(target)], capsys)
    assert code == 0 and out.startswith("ok: RV-20E")
    code, _, err = run(["params", "export", str(target)], capsys)
    assert code == 2 and "exists" in err


@pytest.mark.parametrize(
    "edit, message",
    [
        (("pins = 40", "pins = 41"), "pins (41) must equal cycloid_lobes + 1"),
        (("sun_teeth = 11", "sun_teeth = 0"), "sun_teeth: must be > 0"),
        (("density = 7850.0", 'density = "heavy"'), "density: expected a number"),
        (("[bodies]", "[bodys]"), "unknown section or key 'bodys'"),
    ],
)
def test_params_check_bad_file(tmp_path, capsys, edit, message):
    from importlib import resources

    text = resources.files("rvdiag.params").joinpath("rv20e.toml").read_text()
    assert edit[0] in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace(edit[0], edit[1], 1))
    code, _, err = run(["params", "check", str(bad)], capsys)
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1


def test_missing_params_file(tmp_path, capsys):
    code, _, err = run(["params", "check", str(tmp_path / "nope.toml")], capsys)
    assert code == 2 and "not found" in err


def test_console_script_exit_code(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "rvdiag", "params", "check", str(tmp_path / "x.toml")],
        capture_output=True, text=True,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and proc.stderr.startswith("error:")


def test_cli_exits_with_the_errors_exit_code(monkeypatch, capsys):
    """``RvdiagError.exit_code`` is the exit status: a subclass with another code gets it."""
    import rvdiag.cli as cli
    from rvdiag.errors import ParameterError

    class Special(ParameterError):
        exit_code = 3

    def boom(*args, **kwargs):
        raise Special("broken on purpose")

    monkeypatch.setattr(cli, "build_app", lambda: boom)
    with pytest.raises(SystemExit) as e:
        cli.main(["params", "show"])
    assert e.value.code == 3 and capsys.readouterr().err == "error: broken on purpose\n"


def test_rvdiag_warnings_are_one_line(capsys, monkeypatch):
    """A warning of rvdiag's own: one line ``warning: ...`` on stderr, not Python's two-line format with the
    source line; others the same, with their category's name (tests/test_warning_lines.py has the rest)."""
    from rvdiag.cli import _show_warning
    from rvdiag.errors import ModelRangeWarning

    monkeypatch.setattr("rvdiag.cli._shown", set())
    _show_warning(ModelRangeWarning("fit  extrapolated" + chr(10) + " here"), ModelRangeWarning, "x.py", 3)
    assert capsys.readouterr().err.splitlines() == ["warning: fit extrapolated here"]
    _show_warning(UserWarning("other"), UserWarning, "x.py", 3)
    assert capsys.readouterr().err == "warning: UserWarning: other\n"
