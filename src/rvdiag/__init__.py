"""rvdiag: physics-based fault diagnosis of RV (rotate-vector) reducers.

The package follows the data flow of ``docs/design.md``: reducer parameters -> gears (mesh stiffness,
faults) -> dynamics (27-DOF model) -> signals -> library (Zarr store) -> features -> models ->
evaluation.  A lower layer never imports a higher one.

The model has 27 degrees of freedom (``rvdiag.dynamics.model.dof_names(2, 2)``): the 26 of the dynamics paper's
RV model plus the rotation of the pin wheel (housing) on its torsional support, which docs/model.md explains.
"""

#: The one place the version is written: ``pyproject.toml`` reads it (``[tool.setuptools.dynamic]``).
__version__ = "0.1.0"

__all__ = ["__version__"]
