"""One state table and one table of default severities: the library's states, fault kinds and severity defaults
are those of ``rvdiag.gears.faults`` (``FAULT_KINDS``, ``DEFAULT_SEVERITIES``)."""

from __future__ import annotations

import dataclasses
import inspect

from rvdiag.gears import BrokenTooth, Pitting, RootCrack, Spalling, ToothFaults, faults
from rvdiag.library.states import FAULT_KINDS, SEVERITY_PARAMETERS, STATES, FaultSpec


def test_library_states_are_derived_from_the_gear_table_with_the_same_values():
    assert FAULT_KINDS is faults.FAULT_KINDS and list(STATES) == list(faults.FAULT_KINDS)
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


def test_one_table_of_default_severities_for_the_gear_model_and_the_library():
    table = faults.DEFAULT_SEVERITIES
    assert set(SEVERITY_PARAMETERS) == set(table)
    for name, p in SEVERITY_PARAMETERS.items():
        assert p.default == table[name] and p.lo <= p.default <= p.hi, name
    keywords = inspect.signature(ToothFaults.for_state).parameters
    assert {k: keywords[k].default for k in table} == table
    # the fault classes' own field defaults are the same values
    fields = {cls: {f.name: f.default for f in dataclasses.fields(cls)} for cls in (RootCrack, BrokenTooth, Pitting,
                                                                                    Spalling)}
    assert fields[RootCrack]["angle_deg"] == table["crack_angle_deg"]
    assert fields[BrokenTooth]["fraction"] == table["broken_fraction"]
    assert (fields[Pitting]["area_fraction"], fields[Pitting]["radius"], fields[Pitting]["depth"]) == (
        table["pit_area_fraction"], table["pit_radius"], table["pit_depth"])
    assert (fields[Spalling]["width_fraction"], fields[Spalling]["length_fraction"], fields[Spalling]["depth"]) == (
        table["spall_width_fraction"], table["spall_length_fraction"], table["spall_depth"])


def test_a_state_without_severities_gives_the_same_faults_by_either_route():
    """A library config naming T4 / T6 bare and ``rvdiag simulate --state T4`` (``for_state``) build the same
    gear faults: a 0.8 mm crack at 45 deg (the library used 0.5 mm until the two tables became one)."""
    for state in STATES:
        assert FaultSpec(state).to_tooth_faults() == (None if state == "T1" else ToothFaults.for_state(state)), state
    crack = FaultSpec("T4").to_tooth_faults().teeth[0][0]
    assert crack == RootCrack(0.8e-3, 45.0)
