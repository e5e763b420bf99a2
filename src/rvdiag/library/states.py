"""The eight health states of the library (T1..T8) and their severity parameters.

T1..T6 are the states of the dynamics-model-driven study (docs/references.md, its section 2); T7 pitting and
T8 spalling add the sun-gear surface faults of the motor-current study (Li, Zhao et al. 2024, docs/references.md):

====  ==============================  ===============================================
name  description                     severity parameters (SI units, angles in degrees)
====  ==============================  ===============================================
T1    healthy                         none
T2    broken tooth                    ``broken_fraction``
T3    wear                            ``wear_depth``
T4    root crack                      ``crack_depth``, ``crack_angle_deg``
T5    broken tooth + wear             ``broken_fraction``, ``wear_depth``
T6    broken tooth + wear + crack     ``broken_fraction``, ``wear_depth``, ``crack_depth``, ``crack_angle_deg``
T7    pitting                         ``pit_area_fraction``, ``pit_radius``, ``pit_depth``
T8    spalling                        ``spall_width_fraction``, ``spall_length_fraction``, ``spall_depth``
====  ==============================  ===============================================

Each severity parameter has a physical validity interval (``lo``, ``hi``) that a library config must stay
inside, and a default value used when a config names a state without giving its severities.  The mapping
to the gear model is :func:`tooth_faults`, which calls ``rvdiag.gears.ToothFaults.for_state`` (the
mesh-stiffness model of the faults lives there: Archard wear thins the section, Chen & Shao 2011 /
Mohammed et al. 2013 crack model, broken tooth carries no load, pits (Liang et al. 2016) and a spall (Ma et al.
2016; Chaari et al. 2008) take part of the face width from the flank's sections and contact).

Examples
--------
>>> [s.name for s in STATES.values()]
['T1', 'T2', 'T3', 'T4', 'T5', 'T6', 'T7', 'T8']
>>> STATES["T7"].parameters
('pit_area_fraction', 'pit_radius', 'pit_depth')
>>> STATES["T6"].parameters
('broken_fraction', 'wear_depth', 'crack_depth', 'crack_angle_deg')
>>> FaultSpec("T4", {"crack_depth": 5e-4, "crack_angle_deg": 45.0}).is_healthy
False
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

from rvdiag.errors import ParameterError
from rvdiag.gears.faults import DEFAULT_SEVERITIES, FAULT_KINDS


@dataclass(frozen=True)
class SeverityParameter:
    """One severity parameter of a fault.

    Attributes
    ----------
    name : key in configs, metadata columns and ``ToothFaults.for_state`` keyword
    unit : unit of the value ("m", "deg" or "1")
    lo, hi : closed interval of physically valid values
    description : one line for docs and ``rvdiag library info``
    """

    name: str
    unit: str
    lo: float
    hi: float
    description: str

    @property
    def default(self) -> float:
        """The value used when a config does not give one: the gear model's
        (:data:`rvdiag.gears.faults.DEFAULT_SEVERITIES`, the one table of default severities)."""
        return DEFAULT_SEVERITIES[self.name]

    def check(self, value: float, where: str = "") -> float:
        """Return ``value`` as float or raise :class:`ParameterError` if outside ``[lo, hi]``."""
        value = float(value)
        if not self.lo <= value <= self.hi:
            prefix = f"{where}: " if where else ""
            raise ParameterError(
                f"{prefix}{self.name} = {value:g} {self.unit} is outside its valid range "
                f"[{self.lo:g}, {self.hi:g}] {self.unit}"
            )
        return value


#: Severity parameters.  Ranges for the RV-20E sun gear (module 1.25 mm, tooth whole depth 2.81 mm,
#: root half-thickness about 1.1 mm with the +0.4 profile shift of ``rv20e.toml``):
#: a root crack may cross the centreline (cases 3-4 of Mohammed, Rantatalo & Aidanpaa 2013) but must end
#: inside the tooth; at 45-60 deg the sun tooth admits about 2.2 mm, and the gear model
#: (:class:`rvdiag.gears.RootCrack`) refuses a deeper one with a GeometryError, so 2.2 mm caps the range; wear depths of
#: 5..100 um span the mild to severe wear of Flodin & Andersson 1997 / Chen & Shao; crack angles of
#: 30..75 deg cover the propagation paths of Chen & Shao 2011 (45 deg is their reference case).
#: Pitting (rvdiag.gears.Pitting, Liang, Zhang, Liu & Zuo 2016) and spalling (rvdiag.gears.Spalling, Ma et al. 2016;
#: Chaari et al. 2008): 2..35 % of the pitting band (the 40 % of the working flank around the pitch line)
#: pitted by pits of 0.05..0.4 mm radius and 0.02..0.3 mm depth; a spall 10..100 % of the face wide (only a spall
#: through the face, 100 %, lifts the contact: gears.faults.Spalling; configs/mcsa.toml draws that one), 10..80 % of
#: the working flank long and 0.05..0.5 mm deep.  Every combination of these fits the RV-20E sun tooth (pits in a
#: row stay narrower than the face, cavities shallower than the tooth; tests/test_pitting_spalling.py); a gear
#: where one does not gets a GeometryError from the gear model.
SEVERITY_PARAMETERS: dict[str, SeverityParameter] = {
    p.name: p
    for p in (
        SeverityParameter(
            "broken_fraction", "1", 0.05, 1.0,
            "fraction of the tooth that has broken off (1 = the whole tooth is missing)",
        ),
        SeverityParameter(
            "wear_depth", "m", 1.0e-6, 2.0e-4,
            "maximum uniform-Archard wear depth of the tooth flank (m)",
        ),
        SeverityParameter(
            "crack_depth", "m", 5.0e-5, 2.2e-3,
            "root crack depth q measured along the crack (m)",
        ),
        SeverityParameter(
            "crack_angle_deg", "deg", 15.0, 80.0,
            "root crack angle to the tooth centreline (deg)",
        ),
        SeverityParameter(
            "pit_area_fraction", "1", 0.02, 0.35,
            "fraction of the pitting band (40 % of the working flank, around the pitch line) covered by pits",
        ),
        SeverityParameter(
            "pit_radius", "m", 5.0e-5, 4.0e-4,
            "radius of the cylindrical pits on the flank (m)",
        ),
        SeverityParameter(
            "pit_depth", "m", 2.0e-5, 3.0e-4,
            "depth of the pits normal to the flank (m)",
        ),
        SeverityParameter(
            "spall_width_fraction", "1", 0.1, 1.0,
            "spall width across the face as a fraction of the face width",
        ),
        SeverityParameter(
            "spall_length_fraction", "1", 0.1, 0.8,
            "spall length along the profile as a fraction of the working flank (centred on the pitch point)",
        ),
        SeverityParameter(
            "spall_depth", "m", 5.0e-5, 5.0e-4,
            "depth of the spall normal to the flank (m)",
        ),
    )
}


@dataclass(frozen=True)
class HealthState:
    """A health state: name (class label), description and its severity parameters."""

    name: str
    description: str
    parameters: tuple[str, ...] = field(default_factory=tuple)

    def defaults(self) -> dict[str, float]:
        """Default severity values of this state."""
        return {p: SEVERITY_PARAMETERS[p].default for p in self.parameters}


#: what each fault kind adds to a state: its words in the description and its severity parameters
_KIND_WORDS = {"broken": "broken tooth", "wear": "wear", "crack": "crack", "pitting": "pitting",
               "spalling": "spalling"}
_KIND_PARAMETERS = {
    "broken": ("broken_fraction",),
    "wear": ("wear_depth",),
    "crack": ("crack_depth", "crack_angle_deg"),
    "pitting": ("pit_area_fraction", "pit_radius", "pit_depth"),
    "spalling": ("spall_width_fraction", "spall_length_fraction", "spall_depth"),
}


def _health_state(name: str, kinds: str) -> HealthState:
    parts = [] if kinds == "healthy" else kinds.split("+")
    if not parts:
        return HealthState(name, "healthy")
    description = "root crack" if parts == ["crack"] else " + ".join(_KIND_WORDS[k] for k in parts)
    return HealthState(name, description, tuple(p for k in parts for p in _KIND_PARAMETERS[k]))


#: the eight states, derived from the one state table :data:`rvdiag.gears.faults.FAULT_KINDS` (state -> fault
#: kinds, re-exported here as ``FAULT_KINDS``)
STATES: dict[str, HealthState] = {name: _health_state(name, kinds) for name, kinds in FAULT_KINDS.items()}


def get_state(name: str) -> HealthState:
    """The state called ``name`` ("T1".."T8"); :class:`ParameterError` otherwise."""
    try:
        return STATES[name]
    except KeyError:
        raise ParameterError(f"unknown health state {name!r}; known: {', '.join(STATES)}") from None


@dataclass(frozen=True)
class FaultSpec:
    """The fault of one simulation: a state and its severity values (validated on construction).

    This is what the library draws per simulation.  :meth:`to_tooth_faults` turns it into the gear
    model's fault object; a simulator with attribute ``accepts_fault_spec = True`` receives the
    :class:`FaultSpec` itself instead (the synthetic test simulator does).
    """

    state: str
    severity: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        st = get_state(self.state)
        extra = set(self.severity) - set(st.parameters)
        if extra:
            raise ParameterError(
                f"state {self.state} ({st.description}) has no severity parameter {sorted(extra)[0]!r}; "
                f"it has: {', '.join(st.parameters) or 'none'}"
            )
        values = st.defaults()
        for key, value in self.severity.items():
            values[key] = SEVERITY_PARAMETERS[key].check(value, where=f"state {self.state}")
        object.__setattr__(self, "severity", values)

    @property
    def is_healthy(self) -> bool:
        return not STATES[self.state].parameters

    def to_tooth_faults(self) -> Any:
        """The ``rvdiag.gears.ToothFaults`` of this spec (``None`` for the healthy state)."""
        return tooth_faults(self.state, **self.severity)


def tooth_faults(state: str, **severity: float) -> Any:
    """Map a state and its severities to ``rvdiag.gears.ToothFaults`` (``None`` for T1, healthy).

    The faults sit on the sun gear (the driver of the sun-planet mesh): the broken tooth on tooth 0,
    wear on every tooth, the crack on tooth 0 (T4) or, with a broken tooth (T6), five teeth on so
    that the broken tooth does not hide it, the pits (T7) and the spall (T8) on tooth 0 around its pitch line
    (``ToothFaults.for_state``).  The gear model is imported
    lazily so that configs can be validated without loading it.
    """
    spec = FaultSpec(state, severity)
    if spec.is_healthy:
        return None
    from rvdiag.gears import ToothFaults  # noqa: PLC0415 (lazy import)

    return ToothFaults.from_name(FAULT_KINDS[state], **spec.severity)
