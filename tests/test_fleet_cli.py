"""``rvdiag fleet ...`` end to end with a stand-in judge (tests/fleet_fakes.py): from ``init`` to an acknowledged
alarm, the folder watcher, and every bad input as one ``error:`` line with exit code 2."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli
from fleet_fakes import FakeJudge, write_record

J = "plant/r1/j3"


@pytest.fixture
def env(tmp_path, monkeypatch):
    """A fleet store with one joint, commissioned; the stand-in judge in place of the monitor."""
    monkeypatch.setattr("rvdiag.fleet.store.Judge", FakeJudge)
    db = f"sqlite:///{tmp_path / 'fleet.db'}"
    monkeypatch.setenv("RVDIAG_FLEET_DB", db)
    (tmp_path / "monitor").mkdir()
    return {"db": db, "dir": tmp_path}


def ok(argv, capsys):
    code, out, err = run_cli(argv, capsys)
    assert code == 0, err
    return out, err


def fail(argv, capsys, match):
    code, out, err = run_cli(argv, capsys)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, (code, err)
    assert match in err, err
    return err


def setup_joint(env, capsys):
    d = env["dir"]
    ok(["fleet", "init"], capsys)
    out, _ = ok(["fleet", "add", J, "--monitor", d / "monitor", "--learning", 19], capsys)
    assert "stated 0.766 false alarms per joint-year at 4 records/day" in out
    files = [write_record(d / f"c{i}.npy", 0.1, seed=50 + i) for i in range(3)]
    out, _ = ok(["fleet", "commission", J, *files, "--output-speed", 30, "--load", 50,
                 "--time", "2026-01-01T00:00:00Z"], capsys)
    assert "commissioned plant/r1/j3: epoch 1 from 3 records at 1 operating point(s)" in out


def test_from_commissioning_to_an_acknowledged_alarm(env, capsys):
    setup_joint(env, capsys)
    d = env["dir"]
    files = [write_record(d / f"rec_2026-01-{2 + i // 4:02d}T{6 * (i % 4):02d}.npy", 10.0 if i >= 20 else 0.1, seed=i)
             for i in range(23)]
    out, _ = ok(["fleet", "ingest", J, *files, "--time-regex", r"\d{4}-\d\d-\d\dT\d\d", "--load", 50], capsys)
    lines = out.strip().splitlines()
    assert len(lines) == 23 and lines[-1].endswith("joint alarm") and "joint learning" in lines[0]
    out, _ = ok(["fleet", "status", "--json"], capsys)
    row = json.loads(out)[0]
    assert row["state"] == "alarm" and row["open_alarm"] and row["n_records"] == 23
    assert row["last_record_time"] == "2026-01-07T12:00:00+00:00" and row["last_fault_state"] == "T2"
    out, _ = ok(["fleet", "status"], capsys)
    assert "alarm (unacknowledged)" in out
    out, _ = ok(["fleet", "history", J, "--json", "--limit", 4], capsys)
    h = json.loads(out)
    assert [r["joint_state"] for r in h] == ["normal", "alert", "alert", "alarm"]
    assert h[-1]["record_alarm"] and h[-1]["joint_p_value"] == 0.05 and len(h[-1]["checksum"]) == 64
    ok(["fleet", "history", J], capsys)
    out, _ = ok(["fleet", "ack", J, "--note", "tooth broken, reducer ordered", "--by", "ann"], capsys)
    assert "acknowledged the alarm of plant/r1/j3 by ann; joint alarm" in out
    out, _ = ok(["fleet", "events", J, "--json"], capsys)
    assert [e["kind"] for e in json.loads(out)] == ["commissioned", "raised", "acknowledged"]
    out, _ = ok(["fleet", "maintenance", J, "--note", "reducer replaced", "--by", "bo"], capsys)
    assert "no-baseline until it is commissioned again" in out
    fail(["fleet", "ingest", J, write_record(d / "x.npy", 0.2), "--time", "2099-01-01T00:00:00"], capsys,
         "has no baseline at 2099-01-01T00:00:00+00:00: commission it first")


def test_history_as_csv_and_a_static_snapshot_from_the_cli(env, capsys):
    """``fleet history --csv`` prints the JSON's records as CSV (one row each, values read back equal);
    ``fleet snapshot DIR`` writes the static dashboard, replaces an earlier snapshot, and refuses any other folder
    with one error line, leaving it as it was."""
    import csv
    import io

    setup_joint(env, capsys)
    d = env["dir"]
    files = [write_record(d / f"rec_2026-01-02T{6 * i:02d}.npy", 0.1, seed=i) for i in range(3)]
    ok(["fleet", "ingest", J, *files, "--time-regex", r"\d{4}-\d\d-\d\dT\d\d", "--load", 50], capsys)
    out, _ = ok(["fleet", "history", J, "--json"], capsys)
    hist = json.loads(out)
    out, _ = ok(["fleet", "history", J, "--csv"], capsys)
    rows = list(csv.DictReader(io.StringIO(out)))
    assert [r["checksum"] for r in rows] == [h["checksum"] for h in hist] and len(rows) == 3
    assert [float(r["health_index"]) for r in rows] == [h["health_index"] for h in hist]
    assert [r["learning"] for r in rows] == ["true"] * 3 and rows[0]["filename"] == files[0].name
    fail(["fleet", "history", J, "--csv", "--json"], capsys, "give --json or --csv, not both")
    out, _ = ok(["fleet", "snapshot", d / "dash"], capsys)
    assert "wrote the dashboard's snapshot" in out and (d / "dash" / "joints" / f"{J}.html").is_file()
    ok(["fleet", "snapshot", d / "dash"], capsys)
    (d / "mine").mkdir()
    (d / "mine" / "keep.txt").write_text("mine")
    fail(["fleet", "snapshot", d / "mine"], capsys, "is not an earlier dashboard snapshot")
    assert [p.name for p in (d / "mine").iterdir()] == ["keep.txt"]


def test_the_watcher_ingests_a_folder_tree_named_by_joint(env, capsys):
    setup_joint(env, capsys)
    root = env["dir"] / "incoming"
    folder = root / "plant" / "r1" / "j3"
    folder.mkdir(parents=True)
    for i in range(3):
        write_record(folder / f"r_2026-01-03T0{i}.npy", 0.1, seed=i)
    (folder / "partial.npy.part").write_bytes(b"half")
    (root / "plant" / "r9" / "j1").mkdir(parents=True)
    write_record(root / "plant" / "r9" / "j1" / "r.npy", 0.1)
    argv = ["fleet", "watch", root, "--once", "--time-regex", r"\d{4}-\d\d-\d\dT\d\d", "--load", 50]
    code, out, err = run_cli(argv, capsys)
    assert code == 0, err
    assert "3 ingested, 0 duplicates, 0 rejected, 1 refused" in out and "unknown joint 'plant/r9/j1'" in err
    code, out, err = run_cli(argv, capsys)
    assert "0 ingested, 3 duplicates" in out


def test_tokens_from_the_cli(env, capsys):
    ok(["fleet", "init"], capsys)
    out, err = ok(["fleet", "token", "create", "--read-only", "--name", "wall"], capsys)
    token = out.strip()
    assert len(token) >= 40 and "read-only token 'wall': shown once" in err
    from rvdiag.fleet import Fleet

    assert Fleet.open(env["db"]).check_token(token, write=False) == "wall"


def test_bad_input_is_one_error_line(env, capsys):
    d = env["dir"]
    fail(["fleet", "status"], capsys, "no fleet store at")
    setup_joint(env, capsys)
    rec = write_record(d / "r.npy", 0.1)
    fail(["fleet", "ingest", "plant/r9/j1", rec], capsys, "unknown joint 'plant/r9/j1'")
    fail(["fleet", "ingest", J, d / "missing.npy"], capsys, "no file")
    fail(["fleet", "ingest", J, rec, "--time", "yesterday"], capsys, "--time 'yesterday' is not an ISO 8601 time")
    fail(["fleet", "ingest", J, rec, "--time-regex", "("], capsys, "is not a regular expression")
    bad = d / "bad.npy"
    bad.write_bytes(b"garbage")
    fail(["fleet", "ingest", J, bad, "--time", "2026-01-02T00:00:00"], capsys,
         "1 of 1 file(s) rejected (kept with the reason, nothing else changed): bad.npy: bad.npy: not a record")
    fail(["fleet", "add", "plant/../x", "--monitor", d / "monitor"], capsys, "a joint is named site/robot/joint")
    fail(["fleet", "add", "plant/r1/j9", "--monitor", d / "monitor", "--persistence", "3"], capsys,
         "--persistence '3': expected K/N")
    fail(["fleet", "ack", J, "--note", "x"], capsys, "has no open alarm to acknowledge")
    fail(["fleet", "events", "--kind", "exploded"], capsys, "unknown event kind 'exploded'")
    fail(["fleet", "commission", J, d / "missing.npy", "--load", 50], capsys, "no file")
    from sqlalchemy import create_engine, text

    eng = create_engine(env["db"])
    with eng.begin() as c:
        c.execute(text("UPDATE alembic_version SET version_num = 'f00d'"))
    eng.dispose()
    fail(["fleet", "status"], capsys, "has fleet schema 'f00d', newer than this rvdiag knows")
    fail(["fleet", "status", "--db", "postgresql+nodriver://x@/y"], capsys, "cannot open the fleet database")


def test_the_watcher_picks_up_a_file_that_appears(env, capsys):
    """The running watcher (watchdog): a file written under a temporary name and renamed is ingested once."""
    import threading
    import time

    from rvdiag.fleet import Fleet, Reading
    from rvdiag.fleet.watch import watch

    setup_joint(env, capsys)
    root = env["dir"] / "live"
    folder = root / "plant" / "r1" / "j3"
    folder.mkdir(parents=True)
    fleet = Fleet.open(env["db"])
    done, lines = threading.Event(), []
    counts = {}

    def run():
        counts.update(watch(fleet, root, Reading(load=50.0), settle=0.2, report=lambda line, err: lines.append(line),
                            stop=done.is_set))

    t = threading.Thread(target=run)
    t.start()
    time.sleep(1.0)
    tmp = folder / "new.npy.part"
    with open(tmp, "wb") as fh:  # a writer copying under a temporary name, then renaming
        np.save(fh, np.load(write_record(env["dir"] / "staging.npy", 0.1, seed=7)))
    tmp.rename(folder / "new.npy")
    deadline = time.time() + 20
    while time.time() < deadline and not fleet.history(J):
        time.sleep(0.2)
    done.set()
    t.join(timeout=10)
    assert [r["filename"] for r in fleet.history(J)] == ["new.npy"]
    assert counts["ingested"] == 1 and counts["refused"] == 0


def test_serve_takes_the_upload_limit_and_the_read_token_rule(env, capsys, monkeypatch):
    """``fleet serve --max-upload-mb --read-token`` reach the app (uvicorn stubbed: the app is read back); a bad limit
    is one error line before anything starts."""
    from fastapi.testclient import TestClient

    setup_joint(env, capsys)
    fail(["fleet", "serve", "--max-upload-mb", "0"], capsys, "--max-upload-mb must be a positive number")
    served = {}
    monkeypatch.setattr("uvicorn.run", lambda app, host, port: served.update(app=app, host=host, port=port))
    ok(["fleet", "serve", "--max-upload-mb", "0.001", "--read-token"], capsys)
    assert served["host"] == "127.0.0.1" and served["port"] == 8000
    token = ok(["fleet", "token", "create", "--name", "plc"], capsys)[0].strip()
    with TestClient(served["app"]) as client:
        assert client.get("/api/joints").status_code == 401  # reads need a token
        auth = {"Authorization": f"Bearer {token}"}
        assert client.get("/api/joints", headers=auth).status_code == 200
        big = client.post(f"/api/joints/{J}/records", files={"file": ("r.npy", b"0" * 4096)}, headers=auth)
        assert big.status_code == 413  # over 0.001 MiB
    ok(["fleet", "serve", "--open-reads"], capsys)
    with TestClient(served["app"]) as client:
        assert client.get("/api/joints").status_code == 200


def test_fleet_set_changes_the_failure_index_with_who_and_why(env, capsys):
    """``fleet add --failure-index`` and ``fleet set --failure-index`` (a number or 'none'), shown in the status and
    the event log; a bad value is one error line."""
    d = env["dir"]
    ok(["fleet", "init"], capsys)
    ok(["fleet", "add", J, "--monitor", d / "monitor", "--learning", 19, "--failure-index", 5], capsys)
    out, _ = ok(["fleet", "status", "--json"], capsys)
    assert json.loads(out)[0]["failure_index"] == 5.0
    out, _ = ok(["fleet", "set", J, "--failure-index", "2.5", "--note", "wear limit 20 um", "--by", "ann"], capsys)
    assert "failure index 5 -> 2.5: wear limit 20 um (by ann)" in out
    ok(["fleet", "set", J, "--failure-index", "none"], capsys)
    out, _ = ok(["fleet", "events", J, "--json"], capsys)
    assert [e["kind"] for e in json.loads(out)] == ["failure-index", "failure-index"]
    fail(["fleet", "set", J, "--failure-index", "high"], capsys, "expected a number > 0 or 'none'")
    fail(["fleet", "set", J, "--failure-index", "0"], capsys, "failure index must be a finite number > 0")
    fail(["fleet", "add", "plant/r1/j4", "--monitor", d / "monitor", "--failure-index", -1], capsys,
         "failure index must be a finite number > 0")
