"""One option vocabulary across the ``rvdiag`` commands (rvdiag.cli._options): shared names, deprecated aliases
that still work and warn, errors that name the option the user typed, model names from the registry."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import typer

from conftest import REPO, run_cli

from rvdiag.cli import _options, build_app
from rvdiag.cli._options import DEPRECATED, VOCABULARY

#: Commands that write a file or folder (-o/--out) and commands that show progress (-q/--quiet).
WRITERS = {"simulate", "train", "library build", "dataset from-files", "update", "params export", "mcsa",
           "separability"}
PROGRESS = {"simulate", "train", "evaluate", "library build", "dataset from-files", "update", "mcsa",
            "separability"}
#: Python parameter names of the commands -> their concept in VOCABULARY.
PARAM_CONCEPT = {"out": "out", "quiet": "quiet", "overwrite": "overwrite", "snr_db": "snr_db", "seed": "seed",
                 "params": "params", "as_json": "json", "json_out": "json", "fs": "fs", "channel": "channel"}


def _commands() -> dict:
    """Every leaf command of the app by its path ('simulate', 'library build', ...) (typer's click commands)."""
    out: dict = {}

    def walk(cmd, path: str) -> None:
        if hasattr(cmd, "commands"):
            for name, sub in cmd.commands.items():
                walk(sub, f"{path} {name}".strip())
        else:
            out[path] = cmd

    walk(typer.main.get_command(build_app()), "")
    return out


def _opts_of(cmd) -> list:
    """The options (not arguments) of a click command."""
    return [p for p in cmd.params if p.param_type_name == "option"]


def test_every_command_uses_the_shared_names():
    commands = _commands()
    assert {"simulate", "train", "evaluate", "params export", "update", "dataset from-files"} <= set(commands)
    shared = {o: concept for concept, opts in VOCABULARY.items() for o in opts}
    bad = []
    for path, cmd in commands.items():
        for opt in _opts_of(cmd):
            names = set(opt.opts) | set(opt.secondary_opts)
            if opt.hidden:
                assert len(names) == 1 and names <= set(DEPRECATED), (path, names)  # hidden = an old spelling
                continue
            if names & set(DEPRECATED):
                bad.append(f"{path}: visible old spelling {sorted(names)}")
            concepts = {shared[n] for n in names if n in shared} | (
                {PARAM_CONCEPT[opt.name]} if opt.name in PARAM_CONCEPT else set())
            for concept in concepts:
                if sorted(names) != sorted(VOCABULARY[concept]):
                    bad.append(f"{path}: {opt.name} is {sorted(names)}, the shared name is {VOCABULARY[concept]}")
        opts = {o for p in _opts_of(cmd) if not p.hidden for o in p.opts}
        if path in WRITERS and not set(VOCABULARY["out"]) <= opts:
            bad.append(f"{path} writes but has no -o/--out")
        if path in PROGRESS and not set(VOCABULARY["quiet"]) <= opts:
            bad.append(f"{path} shows progress but has no -q/--quiet")
    assert not bad, "\n".join(bad)


def test_every_old_spelling_is_still_accepted_somewhere():
    hidden = {o for cmd in _commands().values() for p in _opts_of(cmd) if p.hidden for o in p.opts}
    assert hidden == set(DEPRECATED) == {"--noise-snr", "--force"}

_run = run_cli


def test_force_still_overwrites_and_warns(tmp_path, capsys):
    target = tmp_path / "p.toml"
    target.write_text("old")
    code, out, err = _run(["params", "export", str(target), "--force"], capsys)
    assert code == 0 and out.strip() == f"wrote {target}"
    assert err.splitlines() == ["warning: --force is deprecated; use --overwrite"]
    assert target.read_text().startswith("# ") and "old" != target.read_text()
    code, _, err = _run(["params", "export", str(target)], capsys)
    assert code == 2 and err == f"error: {target} exists; use --overwrite to replace it\n"
    code, _, err = _run(["params", "export", "-o", str(target), "--overwrite"], capsys)
    assert code == 0 and err == ""
    code, _, err = _run(["params", "export", str(target), "-o", str(target), "--overwrite"], capsys)
    assert code == 2 and err == "error: give the file to write once: rvdiag params export OUT, or -o/--out OUT\n"


def test_update_accepts_force_with_a_warning(tmp_path, capsys):
    (tmp_path / "u.toml").write_text("x")
    code, _, err = _run(["update", str(tmp_path / "none.csv"), "--output-speed", "45", "--load", "75",
                         "-o", str(tmp_path / "u.toml"), "--force", "-q"], capsys)
    lines = err.splitlines()
    assert code == 2 and lines[0] == "warning: --force is deprecated; use --overwrite", err
    assert lines[1].startswith("error:") and "exists" not in lines[1]  # --force let it past the overwrite check


def test_both_spellings_with_different_values_is_an_error(tmp_path, capsys):
    code, _, err = _run(["simulate", "--input-speed", "1500", "--snr-db", "10", "--noise-snr", "20",
                         "-o", str(tmp_path / "s.npz"), "-q"], capsys)
    assert code == 2 and err.splitlines()[-1] == "error: give --snr-db or its old spelling --noise-snr, not both"
    assert not (tmp_path / "s.npz").exists()


@pytest.mark.parametrize("args, message", [
    (["--duration", "-1"], "error: --duration must be a number > 0, got -1.0"),
    (["--fs", "0"], "error: --fs must be a number > 0, got 0.0"),
    (["--transient", "-0.5"], "error: --transient must be >= 0, got -0.5"),
    (["--substeps", "0"], "error: --substeps must be a whole number >= 1, got 0"),
])
def test_simulate_errors_name_the_option(tmp_path, capsys, args, message):
    code, _, err = _run(["simulate", "--input-speed", "1500", *args, "-o", str(tmp_path / "s.npz"), "-q"], capsys)
    assert code == 2 and err.splitlines()[-1] == message
    assert "_s " not in err and "duration_s" not in err


def test_option_names_rewrites_only_whole_parameter_names():
    from rvdiag.errors import ParameterError

    with pytest.raises(ParameterError) as exc:
        with _options.option_names({"input_length": "--input-length", "fs": "--fs"}):
            raise ParameterError("give a shorter input_length (--input-length); fs must be > 0, not ffs_x or fs_y")
    assert str(exc.value) == "give a shorter --input-length; --fs must be > 0, not ffs_x or fs_y"


def test_model_names_come_from_the_registry():
    import rvdiag.cli.train as train
    from rvdiag import registry
    from rvdiag.models import cnn, pipelines

    assert train.CNN_MODELS is registry.CNN_MODELS is cnn.ARCHITECTURES
    assert train.CLASSICAL_MODELS is registry.CLASSICAL_MODELS is pipelines.MODEL_NAMES
    cli_src = "".join(p.read_text() for d in ("cli", "workflows", "monitoring")
                      for p in (REPO / "src/rvdiag" / d).glob("*.py"))
    assert not re.search(r"\.(_check_params)\(", cli_src)  # the CLI and its workflows call no private method
    model = next(p for p in _opts_of(_commands()["train"]) if p.name == "model")
    assert model.help.startswith(" | ".join(registry.CNN_MODELS + registry.CLASSICAL_MODELS))


def test_readme_command_block_uses_existing_options():
    """Every option in the README's command blocks ("Start here", "Using it") is a visible option of its command (no
    stale spellings)."""
    text = (REPO / "README.md").read_text()
    blocks = [b for b in text.split("```")[1::2] if b.startswith("bash")]
    assert text[text.index("## Using it"):].split("```")[1] in blocks and len(blocks) >= 4
    commands = _commands()
    bad = []
    for line in re.sub(r"\\\n\s*", " ", "\n".join(blocks)).splitlines():
        words = line.split("#")[0].split()
        if not words or words[0] != "rvdiag":
            continue
        path = " ".join(words[1:3]) if " ".join(words[1:3]) in commands else words[1]
        visible = {o for p in _opts_of(commands[path]) if not p.hidden for o in p.opts + p.secondary_opts}
        for w in words:
            opt = w.split("=")[0]
            if opt.startswith("-") and not re.fullmatch(r"-[\d.,-]+", opt) and opt not in visible:
                bad.append(f"{path}: {opt}")
    assert not bad, bad


def test_the_fault_severity_options_are_declared_once_for_the_three_commands():
    """simulate, tvms and separability take the ten severities of one table (_options.FAULT_SEVERITY_OPTIONS), with its
    help, in the place the command's ``severities`` parameter holds, and receive the given ones in SI."""
    commands = _commands()
    from rvdiag.gears.faults import DEFAULT_SEVERITIES, FAULT_KINDS

    table = {spec.option: spec.help for spec in _options.FAULT_SEVERITY_OPTIONS.values()}
    assert len(table) == 10 and set(_options.FAULT_SEVERITY_OPTIONS) == set(DEFAULT_SEVERITIES)  # one per severity
    kinds = {k for name in FAULT_KINDS.values() for k in name.split("+")}
    assert {spec.kind for spec in _options.FAULT_SEVERITY_OPTIONS.values()} <= kinds
    for path in ("simulate", "tvms", "separability"):
        opts = [o for o in _opts_of(commands[path]) if o.opts[0] in table]
        assert [o.opts[0] for o in opts] == list(table), path
        assert all(o.help == table[o.opts[0]] and o.default is None for o in opts), path
    assert _options.fault_severities(crack_depth=1.5, crack_angle_deg=30.0, pit_radius=None, broken_fraction=0.5) == \
        {"crack_depth": 1.5e-3, "crack_angle_deg": 30.0, "broken_fraction": 0.5}
    with pytest.raises(TypeError, match="no parameter 'severities'"):
        _options.fault_severity_options(lambda quiet=False: None)


def test_the_severity_options_reach_the_command_as_one_dict(tmp_path, capsys):
    code, out, err = _run(["tvms", "--fault", "crack", "--crack-depth", "nan"], capsys)
    assert code == 2 and err.splitlines()[-1] == "error: --crack-depth must be finite, got nan"
    code, _, err = _run(["simulate", "--state", "T1", "--crack-depth", "1", "--input-speed", "1000",
                         "-o", str(tmp_path / "s.npz"), "-q"], capsys)
    assert code == 2 and err.splitlines()[-1] == "error: --crack-depth does not apply to state T1 (healthy)"
