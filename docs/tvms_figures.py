"""Regenerate the validation figures of docs/tvms.md: ``python docs/tvms_figures.py``.

Writes docs/figures/tvms_vs_ross.png, tvms_rv20e_states.png, tvms_severity.png.
"""

from __future__ import annotations

import math
import pathlib
import warnings

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rvdiag.gears import GearPair, RootCrack, ToothFaults, Wear, mesh_stiffness  # noqa: E402
from rvdiag.gears.tvms import pair_stiffness_at  # noqa: E402
from rvdiag.params import ReducerParams  # noqa: E402

OUT = pathlib.Path(__file__).parent / "figures"


def vs_ross() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import ross
        from ross.gear_element import GearElementTVMS, Mesh
    mat = ross.Material(name="fig_steel", rho=7810, E=211e9, Poisson=0.3)
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.6))
    for ax, (z1, z2, bore) in zip(axes, ((55, 75, 0.035), (20, 40, 0.02))):
        g = [GearElementTVMS(n=i, material=mat, width=0.02, bore_diameter=bore, module=2e-3, n_teeth=z,
                             pr_angle=math.radians(20)) for i, z in enumerate((z1, z2))]
        orig = Mesh.get_stiffness_for_mesh_period
        Mesh.get_stiffness_for_mesh_period = lambda self, n_mesh_period=1, n_points=1000: (
            np.zeros(1), np.zeros(1))
        try:
            mesh = Mesh(*g)
        finally:
            Mesh.get_stiffness_for_mesh_period = orig
        th, kr = mesh.get_stiffness_for_mesh_period(n_points=61)
        pair = GearPair.from_dimensions(z1, z2, 2e-3, 0.02, youngs_modulus=211e9, poisson_ratio=0.3,
                                        bore_radius1=bore / 2, bore_radius2=bore / 2)
        fine = np.linspace(0, pair.mesh_period_rad, 600, endpoint=False)
        ours = pair_stiffness_at(pair, fine)[0].sum(axis=0)
        ax.plot(np.degrees(fine), ours / 1e8, label="rvdiag.gears")
        ax.plot(np.degrees(th), np.asarray(kr) / 1e8, "o", ms=3, label="ROSS 2.3.0")
        ax.set_title(f"{z1}/{z2} teeth, m = 2 mm, b = 20 mm")
        ax.set_xlabel("driver rotation (deg)")
        ax.set_ylabel("1e8 N/m")
        ax.grid(alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(OUT / "tvms_vs_ross.png", dpi=110)
    plt.close(fig)


def severity() -> None:
    pair = GearPair.sun_planet(ReducerParams.default())
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.6))
    for q in (0.0, 0.4e-3, 0.8e-3, 1.2e-3, 1.6e-3, 2.0e-3):
        r = mesh_stiffness(pair, ToothFaults({0: (RootCrack(q, 45.0),)}), cycles=2, points_per_cycle=360)
        axes[0].plot(np.degrees(r.angle_rad), r.stiffness_N_per_m / 1e8, label=f"q = {q * 1e3:.1f} mm")
    for w in (0.0, 50e-6, 100e-6, 200e-6, 400e-6):
        r = mesh_stiffness(pair, ToothFaults(wear=Wear(w)), cycles=2, points_per_cycle=360)
        axes[1].plot(np.degrees(r.angle_rad), r.stiffness_N_per_m / 1e8, label=f"{w * 1e6:.0f} um")
    axes[0].set_title("RV-20E: root crack on sun tooth 0 (45 deg)")
    axes[1].set_title("RV-20E: Archard wear on every sun tooth (max depth)")
    for ax in axes:
        ax.set_xlabel("sun rotation (deg)")
        ax.set_ylabel("1e8 N/m")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "tvms_severity.png", dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    import importlib.util
    import sys

    OUT.mkdir(exist_ok=True)
    sys.path.insert(0, str(pathlib.Path(__file__).parents[1] / "examples"))
    spec = importlib.util.spec_from_file_location("demo_tvms", pathlib.Path(__file__).parents[1] / "examples" / "demo_tvms.py")
    demo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(demo)
    demo.run(OUT)
    (OUT / "tvms.png").rename(OUT / "tvms_rv20e_states.png")
    (OUT / "tvms_summary.json").unlink()
    severity()
    vs_ross()
