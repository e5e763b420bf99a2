"""The fleet schema's revisions, oldest first (:mod:`rvdiag.fleet.migrations`)."""
