"""rvdiag: physics-based fault diagnosis of RV (rotate-vector) reducers.

The package follows the data flow of ``DESIGN.md``: reducer parameters -> gears (mesh stiffness,
faults) -> dynamics (26-DOF model) -> signals -> library (Zarr store) -> features -> models ->
evaluation.  A lower layer never imports a higher one.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
