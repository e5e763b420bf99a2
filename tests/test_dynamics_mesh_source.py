"""The dynamics never fall back silently to the square-wave stand-in stiffness: rvdiag.gears is imported
unconditionally, and a broken gears package stops the import of rvdiag.dynamics with its own error."""

import subprocess
import sys

import rvdiag.dynamics.mesh as mesh
from rvdiag.dynamics import mesh_table
from rvdiag.params import ReducerParams


def test_the_default_mesh_table_is_the_potential_energy_tvms():
    P = ReducerParams.default()
    for source in ("auto", "gears"):
        t = mesh_table(P, source=source)
        assert t.source == "rvdiag.gears.mesh_stiffness"
    rect = mesh_table(P, source="rectangular")
    assert rect.source.startswith("rectangular")  # the stand-in only when asked for
    assert not hasattr(mesh, "gears_available")  # no switch that can turn the physics down


def test_a_broken_gears_package_fails_loudly():
    """With rvdiag.gears unimportable (simulated by a None entry in sys.modules), importing the dynamics raises
    instead of simulating a square-wave stiffness."""
    code = ("import sys; sys.modules['rvdiag.gears'] = None\n"
            "try:\n    import rvdiag.dynamics\nexcept ImportError as e:\n    print('ImportError', e.name)\n"
            "else:\n    print('imported')")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "ImportError rvdiag.gears"
