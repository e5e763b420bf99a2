"""One rule for every output: an existing output is replaced only with ``--overwrite`` (else one
``error:`` line naming the file and the option, exit 2), and a model directory is replaced whole."""

from __future__ import annotations

import json

import numpy as np
import pytest
import tomli_w

from conftest import run_cli

SIM = ["simulate", "--state", "T2", "--output-speed", "30", "--load", "60", "--duration", "0.01", "--fs", "12000",
       "--substeps", "40", "--transient", "0.005", "--quiet"]


def test_simulate_refuses_an_existing_file_without_overwrite(tmp_path, capsys):
    out = tmp_path / "t2.npz"
    out.write_bytes(b"keep me")
    code, _, err = run_cli(SIM + ["-o", out], capsys)
    assert code == 2 and err == f"error: {out} exists; use --overwrite to replace it\n"
    assert out.read_bytes() == b"keep me"
    code, _, err = run_cli(SIM + ["-o", out, "--overwrite"], capsys)
    assert code == 0, err
    with np.load(out, allow_pickle=False) as z:
        assert z["signal"].shape == (2, 120)
    assert [p.name for p in tmp_path.iterdir()] == ["t2.npz"]  # no temporary file left beside it


def _fitted(kind: str):
    from rvdiag.models.pipelines import make_classical_model
    from rvdiag.models.torch_estimator import CNNClassifier

    rng = np.random.default_rng(0)
    X = rng.standard_normal((24, 256))
    X[12:, ::8] += 3.0
    y = np.array(["A"] * 12 + ["B"] * 12)
    if kind == "cnn":
        return CNNClassifier(max_epochs=1, device="cpu", random_state=0).fit(X, y)
    return make_classical_model("svm", "time").fit(X, y)


def test_a_model_directory_is_replaced_whole(tmp_path):
    """A classical model saved over a CNN's directory leaves no model.safetensors beside the new model.skops."""
    from rvdiag.models.persistence import load_model, save_model

    d = tmp_path / "m"
    save_model(_fitted("cnn"), d, model="cnn1d-lean", seed=0)
    (d / "notes.txt").write_text("old")
    assert (d / "model.safetensors").exists()
    save_model(_fitted("svm"), d, model="svm", features="time", seed=0, files={"repeat.json": b"{}"})
    assert sorted(p.name for p in d.iterdir()) == ["card.json", "model.skops", "repeat.json"]
    assert load_model(d).card["kind"] == "classical"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m"]  # no temporary or old sibling left


def test_an_interrupted_save_leaves_the_old_model_as_it_was(tmp_path, monkeypatch):
    from rvdiag.models import persistence

    d = tmp_path / "m"
    persistence.save_model(_fitted("svm"), d, model="svm", features="time", seed=0)
    before = {p.name: p.read_bytes() for p in d.iterdir()}

    def broken(est, folder, card):
        (folder / "model.safetensors").write_bytes(b"half")
        raise KeyboardInterrupt

    monkeypatch.setattr(persistence, "_write_model", broken)
    with pytest.raises(KeyboardInterrupt):
        persistence.save_model(_fitted("svm"), d, model="svm", features="time", seed=0)
    assert {p.name: p.read_bytes() for p in d.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m"]


def test_train_refuses_an_existing_model_directory_without_overwrite(tmp_path, capsys):
    out = tmp_path / "model"
    out.mkdir()
    (out / "model.safetensors").write_bytes(b"x")
    code, _, err = run_cli(["train", tmp_path / "none.zarr", "-o", out], capsys)
    assert code == 2 and err == f"error: {out} exists; use --overwrite to replace it\n"
    assert (out / "model.safetensors").read_bytes() == b"x"


LIB = {
    "name": "owtest", "mode": "paper", "seed": 3, "simulator": "rvdiag.library.synthetic:simulate",
    "signal": {"fs": 2000.0, "duration_s": 1.0, "segment_length": 200},
    "operation": {"output_speed_deg_s": 45.0, "load_Nm": 70.0, "noise_snr_db": 20.0},
    "split": {"train_per_state": 2, "test_per_state": 1},
    "states": {"T1": {}, "T2": {}},
}


def test_library_build_overwrite_starts_afresh_and_touches_only_a_store(tmp_path, capsys):
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text(tomli_w.dumps(LIB))
    b.write_text(tomli_w.dumps(dict(LIB, seed=4)))
    out = tmp_path / "lib.zarr"
    base = ["library", "build", "--workers", "0", "-q", "-o", out]
    assert run_cli(base[:2] + [a] + base[2:], capsys)[0] == 0
    code, _, err = run_cli(base[:2] + [b] + base[2:], capsys)  # another config: refused, and says how
    assert code == 2 and "different config" in err and "--overwrite" in err and err.count("\n") == 1
    code, stdout, err = run_cli(base[:2] + [b] + base[2:] + ["--overwrite"], capsys)
    assert code == 0 and "already" not in stdout, err
    from rvdiag.datasets import SampleStore

    assert SampleStore.open(out).attrs["config"]["seed"] == 4
    junk = tmp_path / "junk"
    junk.mkdir()
    (junk / "thesis.tex").write_text("keep")
    code, _, err = run_cli(base[:2] + [a, "-o", junk, "--workers", "0", "-q", "--overwrite"], capsys)
    assert code == 2 and "not a sample store" in err and (junk / "thesis.tex").read_text() == "keep"


def test_from_files_accepts_force_as_the_old_spelling_of_overwrite(tmp_path, capsys):
    d = tmp_path / "raw"
    d.mkdir()
    rng = np.random.default_rng(1)
    for c in "hb":
        (d / f"{c}_0.csv").write_text("a1\n" + "\n".join(map(repr, rng.standard_normal(400))) + "\n")
    out = tmp_path / "s.zarr"
    args = ["dataset", "from-files", d, "--label-regex", r"^(?P<label>[hb])_", "--window", "100", "--fs", "1000",
            "-q", "--json", "--out", out]
    assert run_cli(args, capsys)[0] == 0
    code, _, err = run_cli(args, capsys)
    assert code == 2 and "--overwrite" in err and str(out) in err
    code, stdout, err = run_cli(args + ["--force"], capsys)
    assert code == 0 and err == "warning: --force is deprecated; use --overwrite\n"
    assert json.loads(stdout)["n_samples"] > 0
