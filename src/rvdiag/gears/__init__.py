"""rvdiag.gears."""
