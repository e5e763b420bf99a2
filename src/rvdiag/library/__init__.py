"""rvdiag.library."""
