"""Typed schema of a reducer parameter set, with TOML load, validation and save.

A parameter set is a TOML file with the sections of :class:`ReducerParams` (see ``rv20e.toml``, the
default).  Every field is SI unless its name says otherwise.  Loading validates every value and
raises :class:`rvdiag.errors.ConfigError` naming the file, the key and the problem; saving and
loading again returns an equal object (round trip).

Examples
--------
>>> p = ReducerParams.default()
>>> p.stage1.sun_teeth, p.stage2.pins
(11, 40)
>>> round(p.ratio, 6)
121.0
"""

from __future__ import annotations

import dataclasses
import functools
import math
import tomllib
from dataclasses import dataclass, field, fields
from importlib import resources
from pathlib import Path
from typing import Any

import tomli_w

from rvdiag.errors import ConfigError
from rvdiag.tomlfile import read_toml
from rvdiag.validation import at_least, number, positive, whole_number

DEFAULT_PARAMS_NAME = "rv20e.toml"


def _checked(check: str, **kw: Any) -> Any:
    """A field whose value :func:`_check_value` checks as ``check`` ("positive", "nonnegative" or "any"), with the
    other metadata (``unit``...) and the ``default`` of ``kw``."""
    if "default" in kw:
        return field(default=kw.pop("default"), metadata={"check": check, **kw})
    return field(metadata={"check": check, **kw})


_positive = functools.partial(_checked, "positive")
_nonnegative = functools.partial(_checked, "nonnegative")
_any = functools.partial(_checked, "any")


@dataclass(frozen=True)
class Stage1:
    """Involute sun-planet stage (first reduction stage)."""

    sun_teeth: int = _positive()
    planet_teeth: int = _positive()
    n_planets: int = _positive()
    module: float = _positive()
    pressure_angle_deg: float = _positive()
    addendum_coefficient: float = _positive()
    dedendum_coefficient: float = _positive()
    root_fillet_coefficient: float = _nonnegative()
    sun_profile_shift: float = _any()
    planet_profile_shift: float = _any()
    face_width: float = _positive()
    backlash: float = _nonnegative()

    @property
    def operating_pressure_angle_deg(self) -> float:
        """Operating pressure angle alpha_w (degrees) at zero backlash, from
        inv(alpha_w) = inv(alpha_0) + 2 (x1 + x2) tan(alpha_0) / (Z1 + Z2) (ISO 21771, eq. 50).
        Equals the rack's pressure angle for a V-zero pair (x1 + x2 = 0, the RV-20E default)."""
        a0 = math.radians(self.pressure_angle_deg)
        shift = self.sun_profile_shift + self.planet_profile_shift
        target = math.tan(a0) - a0 + 2.0 * shift * math.tan(a0) / (self.sun_teeth + self.planet_teeth)
        if shift == 0.0 or target <= 0.0:
            return self.pressure_angle_deg
        a = a0
        for _ in range(60):  # Newton on inv(a) = target, inv'(a) = tan(a)^2
            a_next = min(max(a - (math.tan(a) - a - target) / math.tan(a) ** 2, 1e-6), 1.5)
            if abs(a_next - a) < 1e-15:
                break
            a = a_next
        return math.degrees(a)

    @property
    def centre_distance(self) -> float:
        """Operating centre distance of the sun-planet pair (m):
        a_w = m (Z1 + Z2) / 2 cos(alpha_0) / cos(alpha_w) (ISO 21771); m (Z1 + Z2) / 2 for a V-zero pair."""
        a = 0.5 * self.module * (self.sun_teeth + self.planet_teeth)
        return a * math.cos(math.radians(self.pressure_angle_deg)) / math.cos(
            math.radians(self.operating_pressure_angle_deg))


@dataclass(frozen=True)
class Stage2:
    """Cycloid-pin stage (second reduction stage)."""

    cycloid_lobes: int = _positive()
    pins: int = _positive()
    n_discs: int = _positive()
    disc_phase_deg: float = _nonnegative()
    n_cranks: int = _positive()
    pin_circle_radius: float = _positive()
    pin_radius: float = _positive()
    eccentricity: float = _positive()
    cycloid_face_width: float = _positive()
    equidistant_modification: float = _any()
    offset_modification: float = _any()
    #: wear of the discs' flanks and the pins: the largest clearance growth along a contact normal on each flank
    #: (m), shaped by Archard's law at the rated torque (:mod:`rvdiag.gears.pin_wear`); unstated (None, the default)
    #: is a new stage, and is left out of the parameters' dict, so that the hash of every earlier store stays
    pin_wear_depth: float | None = _nonnegative(default=None)

    @property
    def short_amplitude_coefficient(self) -> float:
        """K1 = e Zp / rp, the cycloid's short-amplitude coefficient (must be < 1)."""
        return self.eccentricity * self.pins / self.pin_circle_radius


@dataclass(frozen=True)
class Material:
    """Elastic and inertial properties of the gear steel."""

    youngs_modulus: float = _positive()
    poisson_ratio: float = _nonnegative()
    density: float = _positive()

    @property
    def shear_modulus(self) -> float:
        """G = E / (2 (1 + nu))."""
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))


@dataclass(frozen=True)
class Bodies:
    """Dimensions from which masses and inertias are derived (see :mod:`rvdiag.params.derived`)."""

    sun_shaft_radius: float = _positive()
    crank_shaft_radius: float = _positive()
    crank_shaft_length: float = _positive()
    cycloid_bore_radius: float = _positive()
    carrier_outer_radius: float = _positive()
    carrier_width: float = _positive()
    pin_wheel_outer_radius: float = _positive()
    pin_wheel_width: float = _positive()
    input_shaft_radius: float = _positive()
    input_shaft_length: float = _positive()


@dataclass(frozen=True)
class Bearings:
    """Support stiffnesses: linear in N/m, torsional (``*_torsional``) in N m/rad."""

    sun_support: float = _positive()
    crank_carrier: float = _positive()
    crank_cycloid: float = _positive()
    carrier_support: float = _positive()
    pin_wheel_housing: float = _positive()
    planet_crank_torsional: float = _positive()
    input_torsional: float = _positive()
    output_torsional: float = _positive()
    planet_crank_radial: float = _positive()
    pin_wheel_torsional: float = _positive()


@dataclass(frozen=True)
class Damping:
    """Viscous damping ratios (dimensionless)."""

    mesh_damping_ratio: float = _nonnegative()
    bearing_damping_ratio: float = _nonnegative()
    pin_damping_ratio: float = _nonnegative()


@dataclass(frozen=True)
class Operation:
    """Rated operating figures used as defaults, and the driven load.

    ``load_inertia`` (kg m^2) is the polar inertia of the load on the output flange (a robot arm), joined to the
    carrier by the output coupling ``[bearings] output_torsional`` as a DOF of the dynamic model (an elastic
    joint: Spong 1987, "Modeling and control of elastic joint robots", J. Dyn. Syst. Meas. Control 109;
    docs/model.md sections 1 and 3).  0 is a pure load torque on the carrier (no load DOF).  Not stated (absent,
    ``None``): the gravity arm's point-mass inertia ``M L^2`` when a run has one
    (:class:`rvdiag.dynamics.profile.LoadProfile`), else 0.
    """

    rated_torque: float = _positive()
    motor_pole_pairs: int = _positive()
    load_inertia: float | None = _nonnegative(default=None)


@dataclass(frozen=True)
class Modification:
    """Flank design and accuracy of the sun-planet stage (:mod:`rvdiag.gears.modification`).

    Relief amounts and lengths in m along the line of action; ``relief_exponent`` 1 (linear) or 2
    (parabolic); ``iso1328_grade`` the ISO 1328-1:2013 flank tolerance class of both gears (0: perfect
    involutes, no pitch or profile error); ``error_seed`` seeds the drawn pitch deviations.
    ``extended_contact_separation`` (m) is the largest separation up to which a tooth pair's corner contact off
    the ends of the path of contact is carried (extended tooth contact, :func:`rvdiag.gears.modification.
    corner_contact_coefficient`; default 1 mm, which spans the whole gap between two pairs of a slot, so that a
    pair lagging by any realistic amount meets the next tooth's corner); 0 ends every pair's contact at the
    path's ends (the model before 2026-11-25).

    ``sun_tooth_errors_um`` (one value per sun tooth, um along the line of action; not stated: none), when stated,
    replaces the sun teeth's position errors drawn from ``error_seed``: a specimen's measured or identified
    pattern (``rvdiag update --specimen``, :mod:`rvdiag.updating.specimen`).  The profile slope deviation of
    ``iso1328_grade`` stays; the planet table's errors (``[manufacturing]``) are still drawn from ``error_seed``.
    """

    tip_relief_sun: float = _nonnegative(default=1.0e-6)
    tip_relief_planet: float = _nonnegative(default=1.0e-6)
    tip_relief_length: float = _nonnegative(default=1.6e-3)
    root_relief_sun: float = _nonnegative(default=0.0)
    root_relief_planet: float = _nonnegative(default=0.0)
    root_relief_length: float = _nonnegative(default=0.0)
    relief_exponent: int = _positive(default=2)
    iso1328_grade: int = _nonnegative(default=5)
    error_seed: int = _nonnegative(default=0)
    extended_contact_separation: float = _nonnegative(default=1.0e-3)
    sun_tooth_errors_um: tuple[float, ...] | None = _checked("numbers", default=None)


@dataclass(frozen=True)
class Manufacturing:
    """Manufacturing and assembly errors of the reducer outside the sun's flanks (those are ``[modification]``'s
    ``iso1328_grade``), entered in the dynamic model by :mod:`rvdiag.dynamics.manufacturing` (docs/model.md
    section 3, "Manufacturing errors").  Each is a tolerance: the deviations of one reducer are drawn uniformly
    within +- half of it from ``[modification] error_seed`` (the convention of the sun's pitch deviations: a part
    of the class meets its tolerance with margin), so one seed is one specimen.  0 turns an error off.

    - ``planet_runout_grade``: ISO 1328-1:2013 tolerance class of the planets' runout, F_rT = 0.9 F_pT with the
      total cumulative pitch tolerance F_pT = (0.002 d + 0.55 sqrt(d) + 0.7 m + 12) sqrt(2)^(A - 5) um (d, m in
      mm); 5, the class of the sun (RV-20E planet, d = 41.25 mm: F_rT = 14.8 um, so eccentricities up to 3.7 um).
      Each planet's pitch circle is eccentric to its crank by F_r / 2 at a drawn angle: a transmission error
      once per planet revolution in its mesh (Inalpolat & Kahraman 2009, J. Sound Vib. 323).
    - ``crank_hole_position`` (m): +- tolerance of each crank-bearing hole's position in the carrier, radially
      and tangentially; 3 um, an IT4 hole pattern (ISO 286-1: IT4 = 6 um at 18-30 mm) as jig-bored precision
      carriers are made (planet position errors: Bodas & Kahraman 2004, JSME Int. J. C 47(3); Gu & Velex 2012,
      J. Sound Vib. 331).
    - ``crank_phase_arcmin``: +- tolerance of each crank's eccentrics' angle relative to its planet's tooth
      phase, set by the planet's indexing on the crank's spline at assembly; 1 arcmin = 6 um of arc at the
      planet's pitch circle, the planet's grade-5 single pitch tolerance f_pT (5.6 um).
    - ``pin_radius`` (m): +- tolerance of each pin's radius; a needle-roller lot of ISO 3096 grade G2 (diameter
      variation within a lot <= 2 um) is 1 um.
    - ``pin_position`` (m): +- tolerance of each pin groove's position in the pin housing, radially and
      tangentially; an IT4 groove pattern is 3 um (the pin radius and position tolerances of Blanche & Yang 1989,
      J. Mech. Transm. Autom. Des. 111(3)).

    The pins' errors are 0 (off) by default.  They need the discs' profile modifications (``[stage2]
    equidistant_modification``, ``offset_modification``; on by default since 2026-11-28): on unmodified profiles the
    pins of the unloaded half stand off by less than 1 um under load, so pin errors of 1-3 um make 2-7 of them per
    disc touch and fight the loaded half (12-14 % of the pin torque at rated load, 30 % at 40 %, the largest pin
    force 3x).  With the default modification a G2 / IT4 pin ring changes the healthy vibration by at most 10 % in
    RMS at 30-60 deg/s and 40-150 % load, and costs 1.4x the simulation time (docs/model.md section 9), so it stays
    an option.
    """

    planet_runout_grade: int = _nonnegative(default=5)
    crank_hole_position: float = _nonnegative(default=3.0e-6)
    crank_phase_arcmin: float = _nonnegative(default=1.0)
    pin_radius: float = _nonnegative(default=0.0)
    pin_position: float = _nonnegative(default=0.0)

    @property
    def is_zero(self) -> bool:
        """True when every error is off (the model without manufacturing errors)."""
        return not (self.planet_runout_grade or self.crank_hole_position or self.crank_phase_arcmin
                    or self.pin_radius or self.pin_position)


@dataclass(frozen=True)
class Drive:
    """The servo drive on the input shaft: its rotor and the speed loop that holds its speed
    (:mod:`rvdiag.dynamics.model`, docs/model.md section 3).

    ``motor_inertia`` (kg m^2) is the rotor's; default 1.26e-4, a 0.75 kW, 3000 rpm low-inertia servo
    (Mitsubishi HG-KR73 class, the size of the motor-current rig's 0.75 kW motor).  The speed PI acts on the
    rotor as a damper ``c = J w_c`` and a spring ``k = c w_c / 4`` (``w_c = 2 pi speed_loop_bandwidth_hz``,
    the PI corner at a quarter of it; default 100 Hz, a typical industrial velocity-loop bandwidth under load).
    ``speed_loop_bandwidth_hz = 0`` removes the rotor: the input shaft is then driven by an ideal speed source.
    """

    motor_inertia: float = _positive(default=1.26e-4)
    speed_loop_bandwidth_hz: float = _nonnegative(default=100.0)


@dataclass(frozen=True)
class Motor:
    """The servo motor's electrical side: a surface-magnet PMSM under i_d = 0 vector control
    (:mod:`rvdiag.motor`, docs/model.md section 10).  Used when a simulation records the motor current
    (``simulate(signal="current" | "both")``); the rotor's inertia and the speed loop are ``[drive]``'s.

    The motor-current rig's motor is a 0.75 kW, 3000 rpm, 2.39 N m servo with p = 5 pole pairs and a 23-bit
    encoder (Li, Zhao et al. 2024, docs/references.md); its R, L and flux linkage are not public.  The pole pairs
    are ``[operation] motor_pole_pairs``.  The defaults
    are derived from the published figures of 0.75 kW, 3000 rpm, 2.39 N m, 200 V-class servos of that size
    (Delta ECMA-C20807, Mitsubishi HG-KR73, Panasonic MSMF082 catalogues: torque constant 0.45-0.50 N m per
    A rms, voltage constant 26-29 V rms line-to-line per 1000 rpm, electrical time constant 4-9 ms, rated
    current 4-5.8 A rms, peak torque 3x rated):

    - ``flux_linkage`` psi_f = K_t / (1.5 p) with K_t = 0.47 N m / A rms = 0.332 N m / A peak: 0.0443 Wb
      (back-EMF 28.4 V rms line-to-line per 1000 rpm, inside the catalogues' range);
    - ``resistance`` 0.62 ohm per phase (50 W of copper loss at the rated 5.1 A rms, 93 % efficiency at
      rated output with the iron and friction losses);
    - ``inductance_d`` = ``inductance_q`` = 3.2 mH (surface magnets, electrical time constant L/R = 5.2 ms);
    - ``max_current`` 21.6 A peak (3x the rated 5.1 A rms, the catalogues' peak-torque ratio);
    - ``viscous_friction`` 1e-4 N m s/rad (0.03 N m at 3000 rpm: bearing and seal drag of a motor this size);
    - ``dc_link_voltage`` 310 V (rectified 220 V mains), ``pwm_frequency_hz`` 10 kHz, ``dead_time_s``
      1 us (a 600 V IGBT bridge; 0 turns the inverter's dead time off), ``dead_time_current`` 0.1 A (the
      current below which the dead-time voltage reverses smoothly: the switches' output capacitance);
    - ``current_loop_bandwidth_hz`` 1000 (PI with pole-zero cancellation, K_p = L w_cc, K_i = R w_cc);
    - ``encoder_bits`` 23 (the rig's encoder; 0: an ideal angle sensor) and ``speed_observer_hz`` 2000 (the
      drive estimates speed from the quantised angle with a second-order tracking observer);
      ``encoder_error_arcsec`` 20: the amplitude of the encoder's once-per-revolution angle error (disc
      eccentricity and shaft mounting; servo encoders of this class are specified to +-20 to +-80 arcsec);
    - ``current_noise`` 5 mA rms: the current sensors' and ADC's noise (a 12-bit ADC over +-25 A has a 12 mA
      step, 3.5 mA rms of quantisation noise; Hall-effect sensors add a few mA), drawn from the run's seed.
    """

    resistance: float = _positive(default=0.62)
    inductance_d: float = _positive(default=3.2e-3)
    inductance_q: float = _positive(default=3.2e-3)
    flux_linkage: float = _positive(default=0.0443)
    max_current: float = _positive(default=21.6)
    viscous_friction: float = _nonnegative(default=1e-4)
    dc_link_voltage: float = _positive(default=310.0)
    pwm_frequency_hz: float = _positive(default=10000.0)
    dead_time_s: float = _nonnegative(default=1e-6)
    dead_time_current: float = _positive(default=0.1)
    current_loop_bandwidth_hz: float = _positive(default=1000.0)
    encoder_bits: int = _nonnegative(default=23)
    speed_observer_hz: float = _positive(default=2000.0)
    encoder_error_arcsec: float = _nonnegative(default=20.0)
    current_noise: float = _nonnegative(default=0.005)


@dataclass(frozen=True)
class Mounting:
    """What the pin wheel (housing) carries and how the sensor sees it.

    ``housing_added_mass`` (kg) is the mass moving with the pin wheel beyond the ring derived from
    [bodies]: the reducer's housing shell, flanges and the share of the robot link bolted to it; its
    inertia is taken at the pin-wheel outer radius (thin ring).  The sensor path is a linear filter
    between housing and accelerometer (:mod:`rvdiag.dynamics.transfer`): one structural resonance at
    ``path_resonance_hz`` with damping ratio ``path_damping_ratio`` (0 Hz: none) and the accelerometer's
    low-pass ``sensor_cutoff_hz`` (0: none).  Defaults: 6 kg added (the RV-20E weighs 4.7 kg [Nabtesco
    RV-E catalogue], of which the derived ring is 1.8 kg, plus an assumed 3 kg of robot-link flange), no
    path resonance, and the 10 kHz upper band limit of an industrial ICP accelerometer (+-3 dB).
    """

    housing_added_mass: float = _nonnegative(default=6.0)
    path_resonance_hz: float = _nonnegative(default=0.0)
    path_damping_ratio: float = _positive(default=0.05)
    sensor_cutoff_hz: float = _nonnegative(default=10000.0)


_SECTIONS: dict[str, type] = {
    "stage1": Stage1,
    "stage2": Stage2,
    "material": Material,
    "bodies": Bodies,
    "bearings": Bearings,
    "damping": Damping,
    "operation": Operation,
    "modification": Modification,
    "drive": Drive,
    "mounting": Mounting,
    "motor": Motor,
    "manufacturing": Manufacturing,
}
#: sections added after the first parameter files: a file without them takes every default of the section
OPTIONAL_SECTIONS = ("modification", "drive", "mounting", "motor", "manufacturing")
#: largest ``[manufacturing]`` length tolerance (m) and crank phase tolerance (arcmin) accepted: beyond them the
#: small-displacement model (errors of the order of the elastic deflections) no longer describes the reducer
MAX_MANUFACTURING_TOLERANCE_M = 1.0e-4
#: the deepest ``[stage2] pin_wear_depth`` (m) accepted: ten times the default modification's 7 um radial clearance,
#: 2.8 arcmin of added lost motion on the RV-20E (the catalogue's limit is 1 arcmin in all)
MAX_PIN_WEAR_DEPTH = 1.0e-4
MAX_CRANK_PHASE_ARCMIN = 30.0


@dataclass(frozen=True)
class ReducerParams:
    """A complete RV-reducer parameter set.

    The constructor arguments are the config: ``ReducerParams.from_dict(p.to_dict()) == p``.
    """

    name: str
    stage1: Stage1
    stage2: Stage2
    material: Material
    bodies: Bodies
    bearings: Bearings
    damping: Damping
    operation: Operation
    modification: Modification = field(default_factory=Modification)
    drive: Drive = field(default_factory=Drive)
    mounting: Mounting = field(default_factory=Mounting)
    motor: Motor = field(default_factory=Motor)
    manufacturing: Manufacturing = field(default_factory=Manufacturing)
    source: str = field(default="", compare=False)

    # ------------------------------------------------------------------ derived kinematics
    @property
    def ratio(self) -> float:
        """Overall ratio i = 1 + (Z2/Z1) Zp (sun input, carrier output, pin wheel fixed)."""
        s1, s2 = self.stage1, self.stage2
        return 1.0 + s1.planet_teeth / s1.sun_teeth * s2.pins

    # ------------------------------------------------------------------ construction
    @classmethod
    def default(cls) -> "ReducerParams":
        """The built-in RV-20E parameter set (``rvdiag/params/rv20e.toml``)."""
        text = resources.files("rvdiag.params").joinpath(DEFAULT_PARAMS_NAME).read_text("utf-8")
        return cls.from_dict(tomllib.loads(text), source=f"<builtin {DEFAULT_PARAMS_NAME}>")

    @classmethod
    def load(cls, path: str | Path | None = None) -> "ReducerParams":
        """Load and validate a TOML parameter file; ``None`` gives :meth:`default`."""
        if path is None:
            return cls.default()
        return cls.from_dict(read_toml(path, "parameter file"), source=str(path))

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "<dict>") -> "ReducerParams":
        """Build from a nested dict (as read from TOML), validating every value."""
        if not isinstance(data, dict):
            raise ConfigError(f"{source}: a parameter set must be a table")
        unknown = set(data) - set(_SECTIONS) - {"name"}
        if unknown:
            raise ConfigError(f"{source}: unknown section or key {sorted(unknown)[0]!r}")
        sections = {}
        for name, section_cls in _SECTIONS.items():
            if name not in data and name in OPTIONAL_SECTIONS:
                sections[name] = section_cls()
                continue
            if name not in data:
                raise ConfigError(f"{source}: missing section [{name}]")
            sections[name] = _build_section(section_cls, data[name], f"{source} [{name}]")
        params = cls(name=str(data.get("name", "unnamed")), source=source, **sections)
        _check_consistency(params, source)
        return params

    def to_dict(self) -> dict[str, Any]:
        """Nested plain dict of every value (the inverse of :meth:`from_dict`)."""
        out: dict[str, Any] = {"name": self.name}
        for name in _SECTIONS:  # an optional value not stated (None) is left out, as in the file it came from
            out[name] = {k: v for k, v in dataclasses.asdict(getattr(self, name)).items() if v is not None}
        return out

    def to_toml(self) -> str:
        """TOML text of the parameter set."""
        return tomli_w.dumps(self.to_dict())

    def save(self, path: str | Path) -> None:
        """Write the parameter set to a TOML file (comments of the source are not kept)."""
        Path(path).write_text(self.to_toml(), encoding="utf-8")

    def replace(self, **sections: Any) -> "ReducerParams":
        """Copy with some values changed: ``p.replace(stage1={"face_width": 0.02})``.

        The result is validated like a loaded file.
        """
        data = self.to_dict()
        for section, values in sections.items():
            if section == "name":
                data["name"] = values
                continue
            if section not in _SECTIONS:
                raise ConfigError(f"unknown parameter section {section!r}")
            data[section].update(values)
        return type(self).from_dict(data, source=self.source)


def _build_section(section_cls: type, values: Any, where: str) -> Any:
    if not isinstance(values, dict):
        raise ConfigError(f"{where}: must be a table")
    known = {f.name: f for f in fields(section_cls)}
    unknown = set(values) - set(known)
    if unknown:
        raise ConfigError(f"{where}: unknown key {sorted(unknown)[0]!r}")
    kwargs = {}
    for name, f in known.items():
        if name not in values and f.default is not dataclasses.MISSING:
            kwargs[name] = f.default
            continue
        if name not in values:
            raise ConfigError(f"{where}: missing key {name!r}")
        kwargs[name] = _check_value(values[name], f, f"{where} {name}")
    return section_cls(**kwargs)


def _check_value(value: Any, f: dataclasses.Field, where: str) -> Any:
    if f.metadata.get("check") == "numbers":
        if not isinstance(value, (list, tuple)) or not value:
            raise ConfigError(f"{where}: expected a list of numbers, got {value!r}")
        return tuple(number(v, f"{where}[{i}]", error=ConfigError) for i, v in enumerate(value))
    if f.type in (int, "int"):
        value = whole_number(value, where, error=ConfigError)
    else:
        value = number(value, where, error=ConfigError)
    check = f.metadata.get("check", "any")
    if check == "positive":
        positive(value, where, error=ConfigError)
    if check == "nonnegative":
        at_least(value, where, 0, error=ConfigError)
    return value


def _check_consistency(p: ReducerParams, source: str) -> None:
    s1, s2, m = p.stage1, p.stage2, p.material
    if s2.pins != s2.cycloid_lobes + 1:
        raise ConfigError(
            f"{source}: [stage2] pins ({s2.pins}) must equal cycloid_lobes + 1 ({s2.cycloid_lobes + 1})"
        )
    if s2.n_cranks != s1.n_planets:
        raise ConfigError(
            f"{source}: [stage2] n_cranks ({s2.n_cranks}) must equal [stage1] n_planets ({s1.n_planets}): "
            "each planet sits on one crank shaft"
        )
    if not 0.0 < s1.pressure_angle_deg < 45.0:
        raise ConfigError(f"{source}: [stage1] pressure_angle_deg must lie in (0, 45), got {s1.pressure_angle_deg}")
    if s1.dedendum_coefficient <= s1.addendum_coefficient:
        raise ConfigError(
            f"{source}: [stage1] dedendum_coefficient ({s1.dedendum_coefficient}) must exceed "
            f"addendum_coefficient ({s1.addendum_coefficient}) to leave tip clearance")
    a0 = math.radians(s1.pressure_angle_deg)
    rho_max = (s1.dedendum_coefficient - s1.addendum_coefficient) / (1.0 - math.sin(a0))
    if s1.root_fillet_coefficient > 1.01 * rho_max:  # ISO 53 rounds 0.25/(1 - sin 20°) = 0.37998 to 0.38
        raise ConfigError(
            f"{source}: [stage1] root_fillet_coefficient {s1.root_fillet_coefficient} exceeds the "
            f"largest rack tip radius that fits the clearance, {rho_max:.3f}")
    # undercut limit of the basic rack (Litvin & Fuentes 2004, sec. 10.7):
    # x >= (hf* - rho_f* (1 - sin a0)) - Z sin^2(a0) / 2
    h_rack = s1.dedendum_coefficient - s1.root_fillet_coefficient * (1.0 - math.sin(a0))
    for key, z, x in (("sun_profile_shift", s1.sun_teeth, s1.sun_profile_shift),
                      ("planet_profile_shift", s1.planet_teeth, s1.planet_profile_shift)):
        x_min = h_rack - 0.5 * z * math.sin(a0) ** 2
        if x < x_min - 1e-12:
            raise ConfigError(
                f"{source}: [stage1] {key} = {x} undercuts the {z}-tooth gear; it must be >= {x_min:.3f}")
    md = p.modification
    if md.relief_exponent not in (1, 2):
        raise ConfigError(f"{source}: [modification] relief_exponent must be 1 (linear) or 2 (parabolic), "
                          f"got {md.relief_exponent}")
    if md.iso1328_grade > 11:
        raise ConfigError(f"{source}: [modification] iso1328_grade must be 0 (perfect) or 1..11, got {md.iso1328_grade}")
    if md.sun_tooth_errors_um is not None:
        if len(md.sun_tooth_errors_um) != s1.sun_teeth:
            raise ConfigError(f"{source}: [modification] sun_tooth_errors_um must hold one value per sun tooth "
                              f"({s1.sun_teeth}), got {len(md.sun_tooth_errors_um)}")
        if max(abs(v) for v in md.sun_tooth_errors_um) * 1e-6 > MAX_MANUFACTURING_TOLERANCE_M:
            raise ConfigError(f"{source}: [modification] sun_tooth_errors_um must be at most "
                              f"{MAX_MANUFACTURING_TOLERANCE_M * 1e6:g} um in size (a precision gear's pitch errors "
                              "are microns)")
    mf = p.manufacturing
    if mf.planet_runout_grade > 11:
        raise ConfigError(f"{source}: [manufacturing] planet_runout_grade must be 0 (none) or 1..11, "
                          f"got {mf.planet_runout_grade}")
    for key in ("crank_hole_position", "pin_radius", "pin_position"):
        if getattr(mf, key) > MAX_MANUFACTURING_TOLERANCE_M:
            raise ConfigError(f"{source}: [manufacturing] {key} must be at most {MAX_MANUFACTURING_TOLERANCE_M:g} m "
                              f"(a precision reducer's tolerance is microns), got {getattr(mf, key)}")
    if mf.crank_phase_arcmin > MAX_CRANK_PHASE_ARCMIN:
        raise ConfigError(f"{source}: [manufacturing] crank_phase_arcmin must be at most {MAX_CRANK_PHASE_ARCMIN:g}, "
                          f"got {mf.crank_phase_arcmin}")
    if (md.tip_relief_sun or md.tip_relief_planet) and md.tip_relief_length <= 0:
        raise ConfigError(f"{source}: [modification] a tip relief needs tip_relief_length > 0")
    if (md.root_relief_sun or md.root_relief_planet) and md.root_relief_length <= 0:
        raise ConfigError(f"{source}: [modification] a root relief needs root_relief_length > 0")
    if not s2.pins >= 3:
        raise ConfigError(f"{source}: [stage2] pins must be >= 3, got {s2.pins}")
    if s2.equidistant_modification - s2.offset_modification < 0.0:
        raise ConfigError(
            f"{source}: [stage2] equidistant_modification - offset_modification is the discs' radial clearance and "
            f"must be >= 0 (the disc would interfere with the pins), got "
            f"{(s2.equidistant_modification - s2.offset_modification) * 1e6:.3g} um")
    for key in ("equidistant_modification", "offset_modification"):
        if abs(getattr(s2, key)) > MAX_MANUFACTURING_TOLERANCE_M:
            raise ConfigError(f"{source}: [stage2] {key} must be at most {MAX_MANUFACTURING_TOLERANCE_M:g} m in "
                              f"size (a precision reducer's modification is microns), got {getattr(s2, key)}")
    if s2.pin_wear_depth is not None and s2.pin_wear_depth > MAX_PIN_WEAR_DEPTH:
        raise ConfigError(f"{source}: [stage2] pin_wear_depth must be at most {MAX_PIN_WEAR_DEPTH:g} m (ten times the "
                          f"stage's radial clearance), got {s2.pin_wear_depth}")
    if not 0.0 <= s2.disc_phase_deg < 360.0:
        raise ConfigError(f"{source}: [stage2] disc_phase_deg must lie in [0, 360), got {s2.disc_phase_deg}")
    if p.bodies.crank_shaft_radius >= 0.5 * s1.module * s1.planet_teeth - (
            s1.dedendum_coefficient - s1.planet_profile_shift) * s1.module:
        raise ConfigError(f"{source}: [bodies] crank_shaft_radius must be smaller than the planet's root radius")
    if not m.poisson_ratio < 0.5:
        raise ConfigError(f"{source}: [material] poisson_ratio must be < 0.5, got {m.poisson_ratio}")
    if s2.short_amplitude_coefficient >= 1.0:
        raise ConfigError(
            f"{source}: [stage2] eccentricity too large: K1 = e*pins/pin_circle_radius = "
            f"{s2.short_amplitude_coefficient:.3f} must be < 1"
        )
    if s2.pin_radius >= s2.pin_circle_radius * math.sin(math.pi / s2.pins):
        raise ConfigError(f"{source}: [stage2] pin_radius {s2.pin_radius} m: neighbouring pins overlap")
    if s1.centre_distance >= s2.pin_circle_radius:
        raise ConfigError(
            f"{source}: [stage1] module and teeth give a centre distance {s1.centre_distance:.4g} m that must lie inside the "
            f"[stage2] pin_circle_radius {s2.pin_circle_radius:.4g} m"
        )
    if p.bodies.carrier_outer_radius >= s2.pin_circle_radius:
        raise ConfigError(f"{source}: [bodies] carrier_outer_radius must be smaller than pin_circle_radius")
    if p.bodies.pin_wheel_outer_radius <= s2.pin_circle_radius + s2.pin_radius:
        raise ConfigError(f"{source}: [bodies] pin_wheel_outer_radius must exceed pin_circle_radius + pin_radius")
