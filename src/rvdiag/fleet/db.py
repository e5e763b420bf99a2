"""The fleet store's tables (SQLAlchemy 2 declarative models) and how a database is opened, created and checked.

Tables (one row each):

- ``sites`` / ``robots`` / ``joints``: the asset tree, from a joint's name ``site/robot/joint`` (e.g.
  ``plant/r1/j3``).  A joint holds its monitor model directory, its signal kind (``vibration`` or ``current``, from
  the monitor's card), its reducer parameter set (the TOML's content, or none: the built-in default) and its rules
  (:class:`rvdiag.fleet.rules.Rules` as a dict).
- ``epochs``: a baseline of a joint: when it was commissioned, the baseline store it was made into, its operating
  points.  A new baseline is a new epoch; the old ones are kept (history is appended, never rewritten).
- ``commissioning_records``: the records an epoch's baseline was made of (checksum, file name, operating point).
- ``records``: every record ingested: its time, file checksum (SHA-256, unique per joint: the same file twice is one
  record), operating point, the reading options, and its result (health index, p-value, record alarm, most probable
  state and probability, what changed, recognised and why) or why it was rejected.
- ``events``: ``raised``, ``acknowledged``, ``cleared``, ``maintenance``, ``commissioned`` (who, a note).
- ``tokens``: API tokens, stored as the SHA-256 of the token (:mod:`rvdiag.fleet.auth`).

The schema is made and migrated by Alembic (:mod:`rvdiag.fleet.migrations`, :func:`migrate`); :func:`check_schema`
refuses a database of a newer schema than this rvdiag knows.  SQLite is opened in WAL mode with a busy timeout
(:func:`make_engine`), so that a watcher, the CLI and a server can share one file.
"""

from __future__ import annotations

import os
from datetime import datetime, timezone
from pathlib import Path

from sqlalchemy import (JSON, Boolean, DateTime, Float, ForeignKey, Integer, String, Text, TypeDecorator,
                        UniqueConstraint, create_engine, event, inspect)
from sqlalchemy.engine import Engine, make_url
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship

from rvdiag.errors import FleetError

#: the database when neither ``--db`` nor ``RVDIAG_FLEET_DB`` names one
DEFAULT_URL = "sqlite:///fleet.db"
ENV_DB = "RVDIAG_FLEET_DB"
#: the event kinds
EVENT_KINDS = ("raised", "acknowledged", "cleared", "maintenance", "commissioned", "failure-index")


class UTCDateTime(TypeDecorator):
    """A time stored as naive UTC (SQLite keeps no zone) and returned aware (UTC).  A naive time given is taken
    as UTC."""

    impl = DateTime
    cache_ok = True

    def process_bind_param(self, value, dialect):
        if value is None:
            return None
        if value.tzinfo is not None:
            value = value.astimezone(timezone.utc).replace(tzinfo=None)
        return value

    def process_result_value(self, value, dialect):
        return None if value is None else value.replace(tzinfo=timezone.utc)


class Base(DeclarativeBase):
    pass


class Site(Base):
    __tablename__ = "sites"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(200), unique=True)


class Robot(Base):
    __tablename__ = "robots"
    __table_args__ = (UniqueConstraint("site_id", "name", name="uq_robots_site_name"),)
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    site_id: Mapped[int] = mapped_column(ForeignKey("sites.id"))
    name: Mapped[str] = mapped_column(String(200))
    site: Mapped[Site] = relationship()


class Joint(Base):
    __tablename__ = "joints"
    __table_args__ = (UniqueConstraint("robot_id", "name", name="uq_joints_robot_name"),)
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    robot_id: Mapped[int] = mapped_column(ForeignKey("robots.id"))
    name: Mapped[str] = mapped_column(String(200))
    path: Mapped[str] = mapped_column(String(620), unique=True)  # site/robot/joint
    monitor: Mapped[str] = mapped_column(Text)
    signal_kind: Mapped[str] = mapped_column(String(20))
    params: Mapped[dict | None] = mapped_column(JSON, nullable=True)
    rules: Mapped[dict] = mapped_column(JSON)
    created: Mapped[datetime] = mapped_column(UTCDateTime)
    robot: Mapped[Robot] = relationship()


class Epoch(Base):
    __tablename__ = "epochs"
    __table_args__ = (UniqueConstraint("joint_id", "number", name="uq_epochs_joint_number"),)
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    joint_id: Mapped[int] = mapped_column(ForeignKey("joints.id"), index=True)
    number: Mapped[int] = mapped_column(Integer)
    started: Mapped[datetime] = mapped_column(UTCDateTime)
    baseline: Mapped[str] = mapped_column(Text)  # the baseline store, relative to the blob folder
    n_records: Mapped[int] = mapped_column(Integer)
    operating_points: Mapped[list] = mapped_column(JSON)
    alpha: Mapped[float | None] = mapped_column(Float, nullable=True)  # the monitor's per-record rate


class CommissioningRecord(Base):
    __tablename__ = "commissioning_records"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    epoch_id: Mapped[int] = mapped_column(ForeignKey("epochs.id"), index=True)
    checksum: Mapped[str] = mapped_column(String(64))
    filename: Mapped[str] = mapped_column(Text)
    operating_point: Mapped[dict] = mapped_column(JSON)


class Record(Base):
    __tablename__ = "records"
    __table_args__ = (UniqueConstraint("joint_id", "checksum", name="uq_records_joint_checksum"),)
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    joint_id: Mapped[int] = mapped_column(ForeignKey("joints.id"), index=True)
    epoch_id: Mapped[int | None] = mapped_column(ForeignKey("epochs.id"), nullable=True)
    time: Mapped[datetime] = mapped_column(UTCDateTime, index=True)
    received: Mapped[datetime] = mapped_column(UTCDateTime)
    checksum: Mapped[str] = mapped_column(String(64))
    filename: Mapped[str] = mapped_column(Text)
    client_id: Mapped[str | None] = mapped_column(String(200), nullable=True)
    reading: Mapped[dict] = mapped_column(JSON)
    operating_point: Mapped[dict | None] = mapped_column(JSON, nullable=True)
    health_index: Mapped[float | None] = mapped_column(Float, nullable=True)
    p_value: Mapped[float | None] = mapped_column(Float, nullable=True)
    record_alarm: Mapped[bool | None] = mapped_column(Boolean, nullable=True)  # the monitor's, at its alpha
    fault_state: Mapped[str | None] = mapped_column(String(40), nullable=True)
    probability: Mapped[float | None] = mapped_column(Float, nullable=True)
    changes: Mapped[list | None] = mapped_column(JSON, nullable=True)
    recognised: Mapped[bool | None] = mapped_column(Boolean, nullable=True)
    reason: Mapped[str | None] = mapped_column(Text, nullable=True)
    rejected: Mapped[str | None] = mapped_column(Text, nullable=True)
    result: Mapped[dict | None] = mapped_column(JSON, nullable=True)  # MonitorResult.to_dict() without windows


class Event(Base):
    __tablename__ = "events"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    joint_id: Mapped[int] = mapped_column(ForeignKey("joints.id"), index=True)
    kind: Mapped[str] = mapped_column(String(20))
    time: Mapped[datetime] = mapped_column(UTCDateTime)
    by: Mapped[str | None] = mapped_column(String(200), nullable=True)
    note: Mapped[str | None] = mapped_column(Text, nullable=True)
    record_id: Mapped[int | None] = mapped_column(ForeignKey("records.id"), nullable=True)
    epoch_id: Mapped[int | None] = mapped_column(ForeignKey("epochs.id"), nullable=True)


class Token(Base):
    __tablename__ = "tokens"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(200), unique=True)
    hash: Mapped[str] = mapped_column(String(64), unique=True)
    read_only: Mapped[bool] = mapped_column(Boolean)
    created: Mapped[datetime] = mapped_column(UTCDateTime)


# ------------------------------------------------------------------------------------------------ the database
def resolve_url(url: str | None) -> str:
    """``url``, else ``$RVDIAG_FLEET_DB``, else :data:`DEFAULT_URL`; a bare path is taken as a SQLite file."""
    url = url or os.environ.get(ENV_DB) or DEFAULT_URL
    if "://" not in url:
        url = f"sqlite:///{Path(url)}"
    try:
        make_url(url)
    except Exception as exc:  # noqa: BLE001 - sqlalchemy raises ArgumentError; one line for the user
        raise FleetError(f"--db {url!r} is not a database URL ({exc})") from None
    return url


def sqlite_path(url: str) -> Path | None:
    """The file of a SQLite URL (None for another database or an in-memory one)."""
    u = make_url(url)
    if u.get_backend_name() != "sqlite" or not u.database or u.database == ":memory:":
        return None
    return Path(u.database)


def make_engine(url: str) -> Engine:
    """An engine for ``url``; SQLite in WAL mode with foreign keys on and a 30 s busy timeout (writers wait for
    each other instead of failing)."""
    path = sqlite_path(url)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(url, connect_args={"timeout": 30})

        @event.listens_for(engine, "connect")
        def _pragmas(conn, _record):  # noqa: ANN001
            cur = conn.cursor()
            cur.execute("PRAGMA journal_mode=WAL")
            cur.execute("PRAGMA foreign_keys=ON")
            cur.execute("PRAGMA busy_timeout=30000")
            cur.close()

        return engine
    try:
        return create_engine(url, pool_pre_ping=True)
    except Exception as exc:  # noqa: BLE001 - a missing driver, a malformed URL
        raise FleetError(f"cannot open the fleet database {url!r}: {exc}") from None


def _alembic_config(engine: Engine):
    from alembic.config import Config

    cfg = Config()
    cfg.set_main_option("script_location", str(Path(__file__).with_name("migrations")))
    cfg.attributes["engine"] = engine
    return cfg


def head_revision() -> str:
    """The newest schema revision this rvdiag knows."""
    from alembic.script import ScriptDirectory

    return ScriptDirectory.from_config(_alembic_config(None)).get_current_head()


def current_revision(engine: Engine) -> str | None:
    """The schema revision the database is at (None: no fleet schema in it)."""
    from alembic.runtime.migration import MigrationContext

    with engine.connect() as conn:
        return MigrationContext.configure(conn).get_current_revision()


def migrate(engine: Engine) -> str:
    """Create the schema, or upgrade it to :func:`head_revision`; returns the revision.  A database of a newer
    schema is refused (:func:`check_schema`) before anything is written."""
    from alembic import command

    rev = current_revision(engine)
    if rev is not None:
        check_schema(engine, allow_older=True)
    command.upgrade(_alembic_config(engine), "head")
    return head_revision()


def check_schema(engine: Engine, *, allow_older: bool = False) -> None:
    """Refuse a database that is not a fleet store, of a newer schema than this rvdiag knows, or (unless
    ``allow_older``) of an older one that ``rvdiag fleet init`` must migrate first."""
    from alembic.script import ScriptDirectory

    url = engine.url.render_as_string(hide_password=True)
    try:
        rev = current_revision(engine)
    except Exception as exc:  # noqa: BLE001 - the server is down, the file is not a database
        raise FleetError(f"cannot open the fleet database {url}: {' '.join(str(exc).split())[:300]}") from None
    if rev is None:
        raise FleetError(f"{url} holds no fleet store: create it with 'rvdiag fleet init --db {url}'")
    script = ScriptDirectory.from_config(_alembic_config(engine))
    head = script.get_current_head()
    known = {s.revision for s in script.walk_revisions()}
    if rev not in known:
        raise FleetError(f"{url} has fleet schema {rev!r}, newer than this rvdiag knows (newest {head!r}): "
                         "upgrade rvdiag to open it")
    if rev != head and not allow_older:
        raise FleetError(f"{url} has the older fleet schema {rev!r} (this rvdiag writes {head!r}): migrate it with "
                         f"'rvdiag fleet init --db {url}'")


def tables(engine: Engine) -> set[str]:
    """The table names in the database."""
    return set(inspect(engine).get_table_names())
