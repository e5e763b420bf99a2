"""rvdiag.dynamics."""
