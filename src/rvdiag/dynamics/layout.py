"""The layout of the generalized coordinates: which index belongs to which body (one purpose).

Bodies, frames and the DOF count are in docs/model.md section 1.  ``3 + 6 N + 3 D + 3 + 3`` = 27 for N = 2
planets, D = 2 discs (28 with the motor rotor), all *vibratory* displacements about the rigid-body motion at
constant speed:

- sun ``(x_s, y_s, th_s)``, carrier ``(x_H, y_H, th_H)`` and discs ``(x_dj, y_dj, th_dj)`` in the frame
  rotating with the carrier at ``Omega``;
- planets ``(x_pi, y_pi, th_pi)`` and crank shafts ``(x_ci, y_ci, th_ci)`` in frames orbiting with
  planet i (x radial, y tangential);
- pin wheel ``(x_r, y_r, th_r)`` in the fixed housing frame (its rotation, on the stiff housing support,
  carries the stage-2 reaction torque to the housing, where the sensor sits; see docs/model.md for why
  we add it to the 26 DOF of the dynamics paper's model);
- with ``[drive] speed_loop_bandwidth_hz > 0``, the motor rotor's rotation ``th_m``;
- with a load inertia (``[operation] load_inertia`` > 0), the load's rotation ``th_L`` (the robot arm on the
  output flange, vibratory about the carrier's rigid motion like ``th_H``), last.
"""

from __future__ import annotations


def dof_layout(n_planets: int, n_discs: int, motor: bool = False, load: bool = False) -> dict[str, int]:
    """Index of the first (x) coordinate of every body: ``{"sun": 0, "planet0": 3, ...}``; with ``motor``, the
    motor rotor's single coordinate (its rotation) follows the pin wheel, and with ``load`` the load's single
    coordinate comes last."""
    out = {"sun": 0}
    for i in range(n_planets):
        out[f"planet{i}"] = 3 + 3 * i
    for i in range(n_planets):
        out[f"crank{i}"] = 3 + 3 * n_planets + 3 * i
    for j in range(n_discs):
        out[f"disc{j}"] = 3 + 6 * n_planets + 3 * j
    out["carrier"] = 3 + 6 * n_planets + 3 * n_discs
    out["pin_wheel"] = out["carrier"] + 3
    if motor:
        out["motor"] = out["pin_wheel"] + 3
    if load:
        out["load"] = out["pin_wheel"] + 3 + (1 if motor else 0)
    return out


def dof_names(n_planets: int, n_discs: int, motor: bool = False, load: bool = False) -> list[str]:
    """Names of the generalized coordinates, e.g. ``sun.x``, ``planet1.th``, ``pin_wheel.y``, ``motor.th``,
    ``load.th``."""
    names: list[str] = []
    for body in dof_layout(n_planets, n_discs):
        names += [f"{body}.x", f"{body}.y", f"{body}.th"]
    if motor:
        names.append("motor.th")
    if load:
        names.append("load.th")
    return names
