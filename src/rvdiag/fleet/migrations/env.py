"""Alembic's environment for the fleet store: runs the migrations on the engine that
:func:`rvdiag.fleet.db.migrate` passes in ``config.attributes["engine"]`` (online mode only; no alembic.ini)."""

from alembic import context

from rvdiag.fleet.db import Base

engine = context.config.attributes["engine"]
with engine.begin() as connection:
    context.configure(connection=connection, target_metadata=Base.metadata, render_as_batch=True)
    with context.begin_transaction():
        context.run_migrations()
