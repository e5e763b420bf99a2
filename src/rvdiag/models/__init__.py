"""rvdiag.models."""
