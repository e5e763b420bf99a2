"""One state table: the library's states and fault kinds are derived from ``rvdiag.gears.faults.STATES``."""

from __future__ import annotations

from rvdiag.gears import faults
from rvdiag.library.states import FAULT_KINDS, STATES


def test_library_states_are_derived_from_the_gear_table_with_the_same_values():
    assert FAULT_KINDS == faults.STATES and list(STATES) == list(faults.STATES)
    # the values the three hand-written tables held before they were derived from one (T1..T6), and T7/T8
    assert {s: (st.description, st.parameters) for s, st in STATES.items()} == {
        "T1": ("healthy", ()),
        "T2": ("broken tooth", ("broken_fraction",)),
        "T3": ("wear", ("wear_depth",)),
        "T4": ("root crack", ("crack_depth", "crack_angle_deg")),
        "T5": ("broken tooth + wear", ("broken_fraction", "wear_depth")),
        "T6": ("broken tooth + wear + crack", ("broken_fraction", "wear_depth", "crack_depth", "crack_angle_deg")),
        "T7": ("pitting", ("pit_area_fraction", "pit_radius", "pit_depth")),
        "T8": ("spalling", ("spall_width_fraction", "spall_length_fraction", "spall_depth")),
    }
