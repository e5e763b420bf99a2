"""The fleet store's Alembic migrations, run programmatically by :func:`rvdiag.fleet.db.migrate` (``rvdiag fleet
init``).  ``versions/`` holds one file per schema revision; a new revision is added, never an old one edited."""
