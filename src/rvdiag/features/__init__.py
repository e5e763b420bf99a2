"""rvdiag.features."""
