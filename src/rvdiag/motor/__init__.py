"""rvdiag.motor."""
