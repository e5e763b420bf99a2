"""The first fleet schema: the asset tree, epochs and their commissioning records, records, events, tokens.

Revision ID: 0001
Revises:
"""

import sqlalchemy as sa
from alembic import op

from rvdiag.fleet.db import UTCDateTime

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table("sites", sa.Column("id", sa.Integer, primary_key=True),
                    sa.Column("name", sa.String(200), nullable=False, unique=True))
    op.create_table("robots", sa.Column("id", sa.Integer, primary_key=True),
                    sa.Column("site_id", sa.Integer, sa.ForeignKey("sites.id"), nullable=False),
                    sa.Column("name", sa.String(200), nullable=False),
                    sa.UniqueConstraint("site_id", "name", name="uq_robots_site_name"))
    op.create_table("joints", sa.Column("id", sa.Integer, primary_key=True),
                    sa.Column("robot_id", sa.Integer, sa.ForeignKey("robots.id"), nullable=False),
                    sa.Column("name", sa.String(200), nullable=False),
                    sa.Column("path", sa.String(620), nullable=False, unique=True),
                    sa.Column("monitor", sa.Text, nullable=False),
                    sa.Column("signal_kind", sa.String(20), nullable=False),
                    sa.Column("params", sa.JSON, nullable=True),
                    sa.Column("rules", sa.JSON, nullable=False),
                    sa.Column("created", UTCDateTime, nullable=False),
                    sa.UniqueConstraint("robot_id", "name", name="uq_joints_robot_name"))
    op.create_table("epochs", sa.Column("id", sa.Integer, primary_key=True),
                    sa.Column("joint_id", sa.Integer, sa.ForeignKey("joints.id"), nullable=False, index=True),
                    sa.Column("number", sa.Integer, nullable=False),
                    sa.Column("started", UTCDateTime, nullable=False),
                    sa.Column("baseline", sa.Text, nullable=False),
                    sa.Column("n_records", sa.Integer, nullable=False),
                    sa.Column("operating_points", sa.JSON, nullable=False),
                    sa.Column("alpha", sa.Float, nullable=True),
                    sa.UniqueConstraint("joint_id", "number", name="uq_epochs_joint_number"))
    op.create_table("commissioning_records", sa.Column("id", sa.Integer, primary_key=True),
                    sa.Column("epoch_id", sa.Integer, sa.ForeignKey("epochs.id"), nullable=False, index=True),
                    sa.Column("checksum", sa.String(64), nullable=False),
                    sa.Column("filename", sa.Text, nullable=False),
                    sa.Column("operating_point", sa.JSON, nullable=False))
    op.create_table("records", sa.Column("id", sa.Integer, primary_key=True),
                    sa.Column("joint_id", sa.Integer, sa.ForeignKey("joints.id"), nullable=False, index=True),
                    sa.Column("epoch_id", sa.Integer, sa.ForeignKey("epochs.id"), nullable=True),
                    sa.Column("time", UTCDateTime, nullable=False, index=True),
                    sa.Column("received", UTCDateTime, nullable=False),
                    sa.Column("checksum", sa.String(64), nullable=False),
                    sa.Column("filename", sa.Text, nullable=False),
                    sa.Column("client_id", sa.String(200), nullable=True),
                    sa.Column("reading", sa.JSON, nullable=False),
                    sa.Column("operating_point", sa.JSON, nullable=True),
                    sa.Column("health_index", sa.Float, nullable=True),
                    sa.Column("p_value", sa.Float, nullable=True),
                    sa.Column("record_alarm", sa.Boolean, nullable=True),
                    sa.Column("fault_state", sa.String(40), nullable=True),
                    sa.Column("probability", sa.Float, nullable=True),
                    sa.Column("changes", sa.JSON, nullable=True),
                    sa.Column("recognised", sa.Boolean, nullable=True),
                    sa.Column("reason", sa.Text, nullable=True),
                    sa.Column("rejected", sa.Text, nullable=True),
                    sa.Column("result", sa.JSON, nullable=True),
                    sa.UniqueConstraint("joint_id", "checksum", name="uq_records_joint_checksum"))
    op.create_table("events", sa.Column("id", sa.Integer, primary_key=True),
                    sa.Column("joint_id", sa.Integer, sa.ForeignKey("joints.id"), nullable=False, index=True),
                    sa.Column("kind", sa.String(20), nullable=False),
                    sa.Column("time", UTCDateTime, nullable=False),
                    sa.Column("by", sa.String(200), nullable=True),
                    sa.Column("note", sa.Text, nullable=True),
                    sa.Column("record_id", sa.Integer, sa.ForeignKey("records.id"), nullable=True),
                    sa.Column("epoch_id", sa.Integer, sa.ForeignKey("epochs.id"), nullable=True))
    op.create_table("tokens", sa.Column("id", sa.Integer, primary_key=True),
                    sa.Column("name", sa.String(200), nullable=False, unique=True),
                    sa.Column("hash", sa.String(64), nullable=False, unique=True),
                    sa.Column("read_only", sa.Boolean, nullable=False),
                    sa.Column("created", UTCDateTime, nullable=False))


def downgrade() -> None:
    for t in ("tokens", "events", "records", "commissioning_records", "epochs", "joints", "robots", "sites"):
        op.drop_table(t)
