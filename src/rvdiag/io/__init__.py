"""rvdiag.io."""
