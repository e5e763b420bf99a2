"""Gears: involute geometry, time-varying mesh stiffness (healthy and faulty), cycloid-pin contact.

>>> from rvdiag.params import ReducerParams
>>> pair = GearPair.sun_planet(ReducerParams.default())
>>> res = mesh_stiffness(pair, cycles=1, points_per_cycle=90)
>>> round(res.contact_ratio, 3)
1.443
"""

from rvdiag.gears.cycloid import pin_contact_state
from rvdiag.gears.faults import BrokenTooth, Pitting, RootCrack, Spalling, ToothFaults, Wear
from rvdiag.gears.geometry import Gear, GearPair
from rvdiag.gears.tvms import MeshStiffnessResult, mesh_stiffness, tooth_pair_components
from rvdiag.gears.wear import DutyCycle, wear_depth_history, wear_depth_profile

__all__ = [
    "BrokenTooth",
    "DutyCycle",
    "Gear",
    "GearPair",
    "MeshStiffnessResult",
    "Pitting",
    "RootCrack",
    "Spalling",
    "ToothFaults",
    "Wear",
    "mesh_stiffness",
    "pin_contact_state",
    "tooth_pair_components",
    "wear_depth_history",
    "wear_depth_profile",
]
