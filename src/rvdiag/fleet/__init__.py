"""Watching a fleet of robot joints over their life (docs/fleet.md).

- :mod:`rvdiag.fleet.store`: :class:`Fleet`, the one code path of the CLI (``rvdiag fleet ...``), the folder
  watcher and the HTTP API: joints, commissioning (epochs), ingest, status, history, events, acknowledgement,
  maintenance, tokens;
- :mod:`rvdiag.fleet.db`: the tables (SQLAlchemy 2) and :mod:`rvdiag.fleet.migrations` (Alembic);
- :mod:`rvdiag.fleet.rules`: the joint's state from its records (pure functions) and the stated false-alarm rate;
- :mod:`rvdiag.fleet.judge`: reading a record and calling the monitor, models and baselines cached per process;
- :mod:`rvdiag.fleet.blobs`: raw records kept content-addressed beside the database;
- :mod:`rvdiag.fleet.auth`: API tokens, stored hashed;
- :mod:`rvdiag.fleet.watch`: new files in a folder tree named by joint;
- :mod:`rvdiag.fleet.export`: a joint's records as CSV (its service record).
"""

from rvdiag.errors import AuthError, FleetError
from rvdiag.fleet.export import history_csv
from rvdiag.fleet.judge import Reading
from rvdiag.fleet.rules import STATES, Rules
from rvdiag.fleet.store import Fleet

__all__ = ["AuthError", "Fleet", "FleetError", "Reading", "Rules", "STATES", "history_csv"]
