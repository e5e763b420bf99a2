"""``python -m rvdiag`` runs the ``rvdiag`` command."""

from rvdiag.cli import main

main()
