"""rvdiag.evaluation."""
