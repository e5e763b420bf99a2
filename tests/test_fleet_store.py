"""The fleet store (:class:`rvdiag.fleet.Fleet`) on SQLite and on a real PostgreSQL server, with a stand-in judge
(tests/fleet_fakes.py): schema and migrations, the asset tree, commissioning epochs, ingest (duplicates, rejected
files, out-of-order records), the joint's states and events, maintenance, tokens, kept raw records."""

from __future__ import annotations

import random
import threading
from datetime import datetime, timedelta, timezone

import numpy as np
import pytest
from sqlalchemy import text

from fleet_fakes import ALARM_AT, FakeJudge, postgres_database, write_record
from rvdiag.errors import AuthError, FleetError
from rvdiag.fleet import Fleet, Reading
from rvdiag.fleet import db as fdb

T0 = datetime(2026, 1, 1, tzinfo=timezone.utc)
J = "plant/r1/j3"
R = Reading(output_speed=30.0, load=50.0)


@pytest.fixture(params=["sqlite", "postgresql"])
def url(request, tmp_path, monkeypatch):
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'fleet.db'}"
        return
    monkeypatch.setenv("RVDIAG_FLEET_BLOBS", str(tmp_path / "blobs"))
    with postgres_database() as u:
        yield u


@pytest.fixture
def fleet(url, tmp_path):
    f = Fleet.init(url, judge=FakeJudge())
    (tmp_path / "monitor").mkdir()
    f.add_joint(J, tmp_path / "monitor", rules={"learning": 19})
    yield f
    f.close()


def commission(fleet, tmp_path, joint=J, time=T0, n=3):
    files = [write_record(tmp_path / f"c{joint.replace('/', '_')}{i}.npy", 0.1, seed=100 + i) for i in range(n)]
    return fleet.commission(joint, files, R, time=time)


def feed(fleet, tmp_path, means, start=1, joint=J, flat=(), tag="r"):
    """Ingest one record per value of ``means``, 6 h apart from T0 + ``start`` steps; returns the answers."""
    out = []
    for i, m in enumerate(means):
        p = write_record(tmp_path / f"{tag}{start + i}.npy", m, seed=start + i, flat=(start + i) in flat)
        out.append(fleet.ingest(joint, p, reading=R, time=T0 + timedelta(hours=6 * (start + i))))
    return out


# ------------------------------------------------------------------------------------------------ the schema
def test_init_makes_the_schema_the_models_describe(fleet):
    """The Alembic migration and the SQLAlchemy models agree (autogenerate finds nothing to change)."""
    from alembic.autogenerate import compare_metadata
    from alembic.runtime.migration import MigrationContext

    with fleet.engine.connect() as c:
        diff = compare_metadata(MigrationContext.configure(c), fdb.Base.metadata)
    assert diff == []
    assert fdb.current_revision(fleet.engine) == fdb.head_revision()
    if fleet.engine.dialect.name == "sqlite":
        with fleet.engine.connect() as c:
            assert c.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"


def test_open_refuses_a_newer_schema_and_a_missing_store(fleet, tmp_path):
    with fleet.engine.begin() as c:
        c.execute(text("UPDATE alembic_version SET version_num = '9999'"))
    with pytest.raises(FleetError, match="newer than this rvdiag knows"):
        Fleet.open(fleet.url)
    with pytest.raises(FleetError, match="newer than this rvdiag knows"):
        Fleet.init(fleet.url)  # never migrates a newer database down
    with pytest.raises(FleetError, match="no fleet store at .*rvdiag fleet init"):
        Fleet.open(f"sqlite:///{tmp_path / 'none.db'}")


def test_init_twice_keeps_what_is_there(fleet, tmp_path):
    commission(fleet, tmp_path)
    again = Fleet.init(fleet.url, judge=FakeJudge())
    assert [r["joint"] for r in again.status()] == [J] and again.status()[0]["epoch"] == 1


# ------------------------------------------------------------------------------------------------ joints
@pytest.mark.parametrize("name", ["plant/r1", "plant/r1/j3/x", "plant/../j3", "plant/r 1/j3", "../r1/j3", ""])
def test_a_joint_is_named_site_robot_joint(fleet, tmp_path, name):
    with pytest.raises(FleetError, match="site/robot/joint"):
        fleet.add_joint(name, tmp_path / "monitor")


def test_add_joint_refuses_a_duplicate_and_a_missing_monitor(fleet, tmp_path):
    with pytest.raises(FleetError, match="exists already"):
        fleet.add_joint(J, tmp_path / "monitor")
    from rvdiag.errors import RvdiagError

    with pytest.raises(RvdiagError, match="no model"):
        fleet.add_joint("plant/r1/j4", tmp_path / "nowhere")
    fleet.add_joint("plant/r2/j1", tmp_path / "monitor")
    assert fleet.joints() == [J, "plant/r2/j1"]


def test_rules_that_cannot_alarm_are_refused(fleet, tmp_path):
    with pytest.raises(FleetError, match="cannot give a p-value <= 0.05"):
        fleet.add_joint("plant/r1/j5", tmp_path / "monitor", rules={"learning": 10})
    with pytest.raises(FleetError, match="k <= n"):
        fleet.add_joint("plant/r1/j5", tmp_path / "monitor", rules={"k": 4, "n": 3})


# ------------------------------------------------------------------------------------------------ ingest
def test_ingest_needs_a_known_joint_with_a_baseline(fleet, tmp_path):
    p = write_record(tmp_path / "x.npy", 0.1)
    with pytest.raises(FleetError, match="unknown joint 'plant/r9/j1'"):
        fleet.ingest("plant/r9/j1", p, reading=R, time=T0)
    with pytest.raises(FleetError, match="no baseline at"):
        fleet.ingest(J, p, reading=R, time=T0)
    commission(fleet, tmp_path, time=T0 + timedelta(days=1))
    with pytest.raises(FleetError, match="no baseline at 2026-01-01"):  # before the joint's commissioning
        fleet.ingest(J, p, reading=R, time=T0)
    assert fleet.history(J) == [] and fleet.status()[0]["state"] == "learning"


def test_the_same_file_twice_is_one_record(fleet, tmp_path):
    commission(fleet, tmp_path)
    p = write_record(tmp_path / "a.npy", 0.1)
    first = fleet.ingest(J, p, reading=R, time=T0 + timedelta(hours=1))
    again = fleet.ingest(J, p.read_bytes(), filename="renamed.npy", reading=R, time=T0 + timedelta(hours=2))
    assert not first["duplicate"] and again["duplicate"] and again["record_id"] == first["record_id"]
    assert again["time"] == first["time"] and len(fleet.history(J)) == 1
    assert fleet.judge.judged == 1


def test_a_bad_file_is_kept_as_rejected_and_changes_nothing_else(fleet, tmp_path):
    commission(fleet, tmp_path)
    feed(fleet, tmp_path, [0.1] * 5)
    before = {k: v for k, v in fleet.status()[0].items() if k != "n_records"}
    events = fleet.events()
    bad = tmp_path / "bad.npy"
    bad.write_bytes(b"not a record")
    res = fleet.ingest(J, bad, reading=R, time=T0 + timedelta(days=3))
    assert res["rejected"] and "not a record" in res["rejected"] and res["result"] is None
    empty = tmp_path / "empty.npy"
    np.save(empty, np.zeros(0))
    assert "no samples" in fleet.ingest(J, empty, reading=R, time=T0 + timedelta(days=4))["rejected"]
    after = fleet.status()[0]
    assert {k: v for k, v in after.items() if k != "n_records"} == before and after["n_records"] == 7
    assert fleet.events() == events
    h = fleet.history(J)
    assert [r["rejected"] is not None for r in h] == [False] * 5 + [True, True]
    assert h[-1]["joint_state"] is None and fleet.ingest(J, bad, reading=R)["duplicate"]


def test_the_time_comes_from_the_option_the_name_or_the_file(fleet, tmp_path):
    import os

    commission(fleet, tmp_path)
    p = write_record(tmp_path / "j3_2026-01-05T10-30-00.npy", 0.1, seed=1)
    res = fleet.ingest(J, p, reading=Reading(load=50.0, time_regex=r"(?P<time>\d{4}-\d\d-\d\d)T(\d\d)"))
    assert res["time"] == "2026-01-05T00:00:00+00:00"
    q = write_record(tmp_path / "q.npy", 0.1, seed=2)
    os.utime(q, (T0.timestamp() + 7200, T0.timestamp() + 7200))
    assert fleet.ingest(J, q, reading=R)["time"] == "2026-01-01T02:00:00+00:00"
    with pytest.raises(FleetError, match="does not match --time-regex"):
        fleet.ingest(J, write_record(tmp_path / "z.npy", 0.2), reading=Reading(time_regex=r"\d{8}"))


def test_states_through_learning_an_alarm_its_acknowledgement_and_clearing(fleet, tmp_path):
    commission(fleet, tmp_path)
    res = feed(fleet, tmp_path, [0.1] * 19)
    assert [r["joint_state"] for r in res] == ["learning"] * 18 + ["normal"]
    res = feed(fleet, tmp_path, [0.1, 10.0, 10.0, 10.0, 10.0], start=20)
    assert [r["joint_state"] for r in res] == ["normal", "alert", "alert", "alarm", "alarm"]
    s = fleet.status()[0]
    assert s["open_alarm"] and s["last_fault_state"] == "T2" and s["threshold"] == pytest.approx(
        max(r["health_index"] for r in fleet.history(J)[:19]))
    raised = fleet.events(kind="raised")
    assert len(raised) == 1 and raised[0]["time"] == (T0 + timedelta(hours=6 * 23)).isoformat()
    assert [r["joint_state"] for r in feed(fleet, tmp_path, [0.1] * 4, start=25)] == ["alarm"] * 4  # latched
    ack = fleet.acknowledge(J, "ann", "gearbox opened, tooth broken", time=T0 + timedelta(days=30))
    assert ack["joint_state"] == "normal"  # the last 3 records were normal: cleared on acknowledgement
    assert [e["kind"] for e in fleet.events(J)] == ["commissioned", "raised", "acknowledged", "cleared"]
    assert fleet.events(kind="acknowledged")[0]["by"] == "ann"
    with pytest.raises(FleetError, match="no open alarm"):
        fleet.acknowledge(J, "ann", "again")


def test_an_acknowledged_alarm_clears_after_m_normal_records(fleet, tmp_path):
    commission(fleet, tmp_path)
    feed(fleet, tmp_path, [0.1] * 19 + [10.0] * 3)
    fleet.acknowledge(J, "bo", "seen", time=T0 + timedelta(hours=6 * 22 + 1))
    res = feed(fleet, tmp_path, [0.1] * 3, start=23)
    assert [r["joint_state"] for r in res] == ["alarm", "alarm", "normal"]
    assert [e["kind"] for e in fleet.events(J)][-2:] == ["acknowledged", "cleared"]


def test_a_dead_sensor_is_a_sensor_fault_and_never_a_gear_fault(fleet, tmp_path):
    commission(fleet, tmp_path)
    feed(fleet, tmp_path, [0.1] * 19)
    res = feed(fleet, tmp_path, [5.0 + i for i in range(6)] + [0.1], start=20, flat=range(20, 26))
    assert [r["joint_state"] for r in res] == ["sensor-fault"] * 6 + ["normal"]
    assert fleet.events(kind="raised") == []
    h = fleet.history(J)[19:25]
    assert all(r["recognised"] is False and r["record_alarm"] is None and r["fault_state"] is None for r in h)
    assert "dead or disconnected sensor" in h[0]["reason"]


def test_records_out_of_time_order_give_the_history_of_records_in_order(url, tmp_path):
    means = [0.1] * 19 + [0.1, 10.0, 0.1, 10.0, 10.0, 10.0, 0.1, 0.1, 0.1, 0.1]
    answers = {}
    for order in ("sorted", "shuffled"):
        f = Fleet.init(url if order == "sorted" else f"sqlite:///{tmp_path / 'other.db'}", judge=FakeJudge())
        (tmp_path / "monitor").mkdir(exist_ok=True)
        f.add_joint(J, tmp_path / "monitor", rules={"learning": 19})
        commission(f, tmp_path)
        idx = list(range(len(means)))
        if order == "shuffled":
            random.Random(3).shuffle(idx)
        for i in idx:
            p = write_record(tmp_path / f"o{i}.npy", means[i], seed=i)
            f.ingest(J, p, reading=R, time=T0 + timedelta(hours=6 * (i + 1)))
        answers[order] = ([(r["time"], r["joint_state"], r["record_alarm"]) for r in f.history(J)],
                          f.status()[0]["state"])
        f.close()
    assert answers["sorted"] == answers["shuffled"]
    assert answers["sorted"][1] == "alarm"


def test_maintenance_then_recommissioning_starts_a_new_epoch_and_keeps_the_old(fleet, tmp_path):
    commission(fleet, tmp_path)
    feed(fleet, tmp_path, [0.1] * 19 + [10.0] * 3)
    fleet.maintenance(J, "cy", "reducer replaced", time=T0 + timedelta(days=10))
    assert fleet.status()[0]["state"] == "no-baseline" and not fleet.status()[0]["open_alarm"]
    p = write_record(tmp_path / "after.npy", 0.1, seed=99)
    with pytest.raises(FleetError, match="no baseline"):
        fleet.ingest(J, p, reading=R, time=T0 + timedelta(days=11))
    commission(fleet, tmp_path, time=T0 + timedelta(days=12), n=4)
    res = fleet.ingest(J, p, reading=R, time=T0 + timedelta(days=13))
    assert res["joint_state"] == "learning"
    h = fleet.history(J)
    assert [r["epoch"] for r in h] == [1] * 22 + [2] and h[21]["joint_state"] == "alarm"
    assert [e["kind"] for e in fleet.events(J)] == ["commissioned", "raised", "maintenance", "commissioned"]
    late = write_record(tmp_path / "late.npy", 0.1, seed=98)  # a late record of the first epoch keeps its epoch
    assert fleet.ingest(J, late, reading=R, time=T0 + timedelta(days=9))["joint_state"] == "learning"
    assert fleet.history(J)[22]["epoch"] == 1


def test_the_raw_record_is_kept_and_read_back(fleet, tmp_path):
    commission(fleet, tmp_path)
    p = write_record(tmp_path / "keep.npy", 0.3, seed=4)
    res = fleet.ingest(J, p, reading=R, time=T0 + timedelta(hours=1))
    np.testing.assert_array_equal(fleet.record_signal(J, res["checksum"]), np.load(p))
    with pytest.raises(FleetError, match="no record"):
        fleet.record_signal(J, "0" * 64)
    with pytest.raises(FleetError, match="not a record checksum"):
        fleet.blobs.find("../../etc/passwd")


def test_concurrent_ingests_lose_nothing_and_double_nothing(fleet, tmp_path):
    commission(fleet, tmp_path)
    files = [write_record(tmp_path / f"c{i}.npy", 0.1, seed=i) for i in range(24)]
    errors = []

    def client(k):
        try:
            for i in range(24):  # every client sends every file: each must end up once
                fleet.ingest(J, files[(i + 5 * k) % 24], reading=R, time=T0 + timedelta(hours=(i + 5 * k) % 24 + 1))
        except Exception as exc:  # noqa: BLE001
            errors.append(exc)

    threads = [threading.Thread(target=client, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    h = fleet.history(J)
    assert len(h) == 24 and len({r["checksum"] for r in h}) == 24


# ------------------------------------------------------------------------------------------------ tokens
def test_tokens_are_stored_hashed_and_checked(fleet):
    rw = fleet.create_token("line-1", read_only=False)
    ro = fleet.create_token("viewer", read_only=True)
    assert fleet.check_token(rw, write=True) == "line-1" and fleet.check_token(ro, write=False) == "viewer"
    with pytest.raises(AuthError, match="read-only") as e:
        fleet.check_token(ro, write=True)
    assert e.value.status == 403
    for bad in (None, "", "nope"):
        with pytest.raises(AuthError) as e:
            fleet.check_token(bad, write=False)
        assert e.value.status == 401
    with fleet.engine.connect() as c:
        stored = [r[0] for r in c.execute(text("SELECT hash FROM tokens"))]
    assert rw not in stored and ro not in stored and all(len(h) == 64 for h in stored)
    with pytest.raises(FleetError, match="exists already"):
        fleet.create_token("viewer", read_only=True)


def test_the_stated_rate_follows_the_rules(fleet, tmp_path):
    from rvdiag.fleet.rules import Rules, false_alarms_per_year

    assert fleet.stated_false_alarms_per_year(J) == pytest.approx(
        false_alarms_per_year(Rules(alpha=0.05, k=3, n=3, m=3, learning=19)))
    assert fleet.stated_false_alarms_per_year(J) <= 1.0
    assert fleet.stated_false_alarms_per_year(J, records_per_day=8) == pytest.approx(
        2 * fleet.stated_false_alarms_per_year(J))


def test_a_maintenance_ends_the_epoch_it_was_recorded_in(fleet, tmp_path):
    """Maintenance recorded now, the new baseline's time given earlier (a late entry): the new epoch holds."""
    commission(fleet, tmp_path)
    fleet.maintenance(J, "cy", "bearing replaced")  # now, 2026-11-28 or later
    commission(fleet, tmp_path, time=T0 + timedelta(days=2), n=4)
    assert fleet.status()[0]["state"] == "learning" and fleet.status()[0]["epoch"] == 2
    assert feed(fleet, tmp_path, [0.1], start=10)[0]["joint_state"] == "learning"  # 2.5 days in: epoch 2
    with pytest.raises(FleetError, match="a new baseline must start later"):
        commission(fleet, tmp_path, time=T0 + timedelta(days=1))


def test_status_gives_the_onset_of_a_rising_index_and_says_why_no_remaining_life(fleet, tmp_path):
    """The prognosis in the status rows (rvdiag.prognostics.joint_prognosis on the epoch's recognised records): no
    onset while the index stays healthy; an onset inside the rise once it has lasted; the remaining life not
    estimated without a failure threshold, with the reason."""
    commission(fleet, tmp_path)
    feed(fleet, tmp_path, [0.1] * 30)
    row = fleet.status()[0]
    assert row["onset_time"] is None and row["change_alarm_time"] is None and row["change_evidence"] < 100
    assert row["rul"]["estimated"] is False and "onset" in row["rul"]["reason"]
    rise = [0.1 + 0.04 * k for k in range(1, 16)]  # stays under the fake monitor's alarm, so no broken tooth
    assert max(rise) < ALARM_AT
    feed(fleet, tmp_path, rise, start=31)
    row = fleet.status()[0]
    start = T0 + timedelta(hours=6 * 31)  # the rise's first record; the onset estimate may lead it by a record or two
    assert row["onset_time"] is not None and datetime.fromisoformat(row["onset_time"]) >= start - timedelta(hours=12)
    assert datetime.fromisoformat(row["change_alarm_time"]) >= datetime.fromisoformat(row["onset_time"])
    assert row["change_evidence"] >= 100  # 1 / delta
    assert row["rul"]["estimated"] is False and "failure index" in row["rul"]["reason"]


def test_the_operating_point_is_read_from_the_name_as_read_record_reads_it(tmp_path):
    """One reading of --meta-regex (rvdiag.workflows.records.name_metadata): a group ``load`` is the load as
    ``load_Nm`` is; a value that is not a number, a name it does not match, two groups for one column: refused."""
    from rvdiag.errors import RvdiagError

    for regex in (r"_(?P<speed_dps>[\d.]+)dps_(?P<load>[\d.]+)Nm", r"_(?P<speed_dps>[\d.]+)dps_(?P<load_Nm>[\d.]+)Nm"):
        assert Reading(meta_regex=regex).operating_point("r_44.5dps_120Nm.npy") == {"output_speed_deg_s": 44.5,
                                                                                     "load_Nm": 120.0}
    assert Reading(load=50.0, meta_regex=r"_(?P<speed_dps>\d+)dps").operating_point("a_30dps.csv") == {
        "output_speed_deg_s": 30.0, "load_Nm": 50.0}
    for regex, name, match in ((r"_(?P<load>[a-z]+)Nm", "r_highNm.npy", "not a number"),
                               (r"_(?P<load>\d+)Nm", "r.npy", "does not match --meta-regex"),
                               (r"(?P<load>\d+)_(?P<load_Nm>\d+)", "1_2.npy", "both give 'load_Nm'")):
        with pytest.raises(RvdiagError, match=match):
            Reading(meta_regex=regex).operating_point(name)


def test_a_failure_index_gives_the_remaining_life_and_its_change_is_an_event(fleet, tmp_path):
    """With a failure index in the joint's rules (set later, with who and why), the status row counts the remaining
    life of a rising index to it: median between its 10 % and 90 % points, near the linear extrapolation of the
    rise (0.16 a day from 0.7 to 2.0: about 8 days); without one, the reason says how to set it.  A bad value is
    refused and changes nothing."""
    commission(fleet, tmp_path)
    feed(fleet, tmp_path, [0.1] * 30 + [0.1 + 0.04 * k for k in range(1, 16)])
    row = fleet.status()[0]
    assert row["failure_index"] is None and "rvdiag fleet set" in row["rul"]["reason"]
    with pytest.raises(FleetError, match="failure index must be a finite number > 0"):
        fleet.set_failure_index(J, -1.0, by="cy")
    assert fleet.status()[0]["failure_index"] is None
    res = fleet.set_failure_index(J, 2.0, by="cy", note="the wear limit")
    assert res["failure_index"] == 2.0 and "none -> 2" in res["note"] and "the wear limit" in res["note"]
    assert [e["kind"] for e in fleet.events(J)][-1] == "failure-index"
    row = fleet.status()[0]
    assert row["failure_index"] == 2.0 and row["state"] != "no-baseline"
    rul = row["rul"]
    assert rul["estimated"] is True, rul
    assert rul["p10_days"] <= rul["median_days"] <= rul["p90_days"]
    assert 2.0 < rul["median_days"] < 30.0
    from rvdiag.fleet import web

    page = web.joint_page(fleet, J)
    assert f"median {web.fmt_number(rul['median_days'], 3)} days" in page and "to failure index\n      2, if the duty stays" in page
    assert fleet.set_failure_index(J, None, by="cy")["failure_index"] is None
    assert fleet.status()[0]["rul"]["estimated"] is False
