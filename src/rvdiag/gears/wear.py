"""Flank wear of the sun-planet stage in absolute terms: Archard's law over a duty cycle and a number of hours.

:class:`rvdiag.gears.Wear` sets a wear *depth* and lets :func:`rvdiag.gears.faults.archard_wear_profile` shape the
flank; this module gives the depth itself, from the stage's load, kinematics and a wear coefficient, so that a
depth can be tied to a reducer's life and a life history can grow wear by a stated law.

Archard's law for a flank point (Flodin & Andersson 1997, Wear 207, eq. (2); Archard 1953):

    dh = k p ds,

k the specific (dimensional) wear coefficient (m^2/N = m^3/(N m)), p the contact pressure and ds the sliding
distance.  A flank point of gear i passes the Hertz contact of half width a in the time 2 a / v_i (v_i its rolling
speed, omega_i rho_i with rho_i its roll length) and slides meanwhile by 2 a |v_1 - v_2| / v_i; integrated over
the Hertz pressure, whose integral across the contact is the load per unit face width w = F / L, one pass wears

    h_pass = k w |1 - v_j / v_i| = k (F_share / L) * sliding_ratio,

so the Hertz half width cancels (Flodin & Andersson 1997, their eqs. (3)-(5) with a constant pressure over the
contact give the same product).  The sliding ratio (:func:`rvdiag.gears.faults.sliding_ratio`) is zero at the pitch
point and grows with the distance from it, steepest towards the sun's root, whose roll length is small.  F_share is
the pair's share of the mesh force F: all of it in single contact; in double contact the share of two pairs of
stiffness k_A, k_B whose flanks are worn by e_A, e_B (the sum of the sun's and the planet's depth at each contact)
follows from the unilateral balance k_A (delta - e_A)+ + k_B (delta - e_B)+ = F, recomputed as the wear grows
(Flodin & Andersson 1997; Bajpai, Kahraman & Anderson 2004, Wear 257, 1183-1190: the load distribution of the worn
geometry).  The pair stiffnesses are the healthy ones of :mod:`rvdiag.gears.tvms`.

Passes: in an RV reducer (carrier = output, ring = pin wheel fixed, sun = input), each sun tooth meshes with every
one of the n planets once per revolution of the sun relative to the carrier, and each planet tooth once per planet
revolution relative to the carrier, Z1 / Z2 of it; so a sun tooth passes n Z2 / Z1 times as often as a planet tooth
(6 on the RV-20E), which is why the sun wears more (Lubricants 13(8):362, 2025, measured and computed on an RV
reducer).  The mesh force at output torque T is F = T / (i n r_b1) along the line of action (no losses; equal planet
shares), 107 N per mesh on the RV-20E at its rated 167 N m.

Wear coefficient.  For lubricated, case-hardened steel gears in mild wear the literature's dimensional coefficients
span about 1e-18 to 1e-16 m^2/N: boundary-lubricated, slow FZG-type tests at the upper end (Flodin & Andersson 1997
and 2001, Wear 207 and 249, simulate FZG test gears with coefficients of this order from Andersson & Eriksson's
tests), mixed-EHL gears at the lower end (Wu & Cheng 1993, J. Tribol. 115, 493-500, derive the wear rate from the
asperity load share of a partial-EHL contact, which falls steeply with the film parameter; Bajpai, Kahraman &
Anderson 2004 calibrate k on their own long-running spur-gear tests).  [The exact figures of these papers were not
at hand when this module was written; :data:`WEAR_COEFFICIENTS` states the span used, not a value read from a
paper.]  The measured lost motion of an RV reducer in a 1,550 h endurance test (Lubricants 13(8):362, 2025) bounds
it for this stage: after the first 600 h the lost motion grew 0.0024 arcsec/h in all; this stage's Archard wear on
both flanks, at rated torque and 15 rpm output (the usual endurance-test duty; the paper's duty was not at hand),
would alone grow it by 0.0059 arcsec/h per 1e-17 m^2/N (``research/wear_archard.py``), so k <= ~4e-18 m^2/N, and less
where the cycloid stage and the bearings take their share: with the cycloid stage's Archard wear
(:mod:`rvdiag.gears.pin_wear`, which makes 95 % of that growth) the test gives k = 6.3e-19 m^2/N at that duty
(``research/pin_wear.py``).  The default is therefore the span's lower end,
1e-18 m^2/N (well-lubricated mild wear); the depth is proportional to k (outside the run-in's load sharing), so
any other k scales it.

Assumptions a user must know: the static load (no dynamic factor), no losses, equal planet load shares, a steady
duty cycle, and wear that does not change the lubrication regime (no scuffing, no pitting).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.gears.faults import Wear, sliding_ratio
from rvdiag.gears.geometry import GearPair
from rvdiag.gears.tvms import tooth_pair_components
from rvdiag.validation import finite_number

#: span of dimensional wear coefficients (m^2/N) for lubricated steel gears in mild wear (module docstring):
#: well lubricated (mixed EHL; the default, module docstring), the upper bound that an RV reducer's measured
#: lost-motion growth allows (about 4e-18) rounded up to a decade, and boundary lubrication
WEAR_COEFFICIENTS = {"low": 1.0e-18, "mid": 1.0e-17, "high": 1.0e-16}
DEFAULT_WEAR_COEFFICIENT = WEAR_COEFFICIENTS["low"]

#: grid of the path of contact, and the largest increment of the pair separation per integration step as a
#: fraction of the elastic deflection of one pair under the whole mesh force (as rvdiag.gears.faults' run-in)
_POINTS = 2001
_STEP = 0.05


@dataclass(frozen=True)
class DutyCycle:
    """A joint's steady duty: output speed (deg/s) and torque (N m) while it moves, and the share of the hours it
    moves (the rest it stands, and stands still wears nothing).

    >>> DutyCycle(30.0, 84.0, 0.5).moving_fraction
    0.5
    """

    output_speed_deg_s: float
    load_Nm: float
    moving_fraction: float = 1.0

    def __post_init__(self) -> None:
        for name, value in (("output speed", self.output_speed_deg_s), ("load", self.load_Nm),
                            ("moving fraction", self.moving_fraction)):
            finite_number(value, f"duty cycle {name}", 0)
        if self.moving_fraction > 1:
            raise ParameterError(f"duty cycle moving fraction must be <= 1, got {self.moving_fraction!r}")


def mesh_force(params, load_Nm: float) -> float:
    """Force (N) along the line of action of one sun-planet mesh at output torque ``load_Nm``: T / (i n r_b1)."""
    pair = GearPair.sun_planet(params)
    return float(load_Nm) / (params.ratio * params.stage1.n_planets * pair.driver.base_radius)


def mesh_passes(params, hours: float, duty: DutyCycle, gear: str = "sun") -> float:
    """How often one tooth flank of the ``gear`` ("sun" or "planet") passes through a mesh in ``hours``.

    Sun: n_planets (f_s - f_H) per second; planet: (f_s - f_H) Z1 / Z2, f_s = i f_H the sun's and f_H the output's
    speed (rev/s), times the moving share of the hours.
    """
    if gear not in ("sun", "planet"):
        raise ParameterError(f"gear must be 'sun' or 'planet', got {gear!r}")
    s1 = params.stage1
    f_h = duty.output_speed_deg_s / 360.0
    relative = (params.ratio - 1.0) * f_h             # sun relative to the carrier, rev/s
    per_s = s1.n_planets * relative if gear == "sun" else relative * s1.sun_teeth / s1.planet_teeth
    return float(per_s * 3600.0 * hours * duty.moving_fraction)


def pitch_roll(pair: GearPair) -> float:
    """Position of the pitch point along the path of contact (m from its start): where rho_1 / rho_2 = r_b1 / r_b2."""
    rb1, rb2 = pair.driver.base_radius, pair.driven.base_radius
    return pair.line_of_action_length * rb1 / (rb1 + rb2) - pair.start_roll_length_driver


@dataclass(frozen=True)
class WearDepthProfile:
    """Wear depth (m, normal to the flank) of the sun and the planet flanks along the path of contact.

    ``roll`` (m) runs along the path of contact from its start (the sun's root, the planet's tip) to its end (the
    sun's tip); ``sun`` and ``planet`` are the depths at the flank points that meet there; ``pitch_roll`` (m) is the
    pitch point's position; ``passes`` the passes of one sun and one planet tooth; ``force_N`` the mesh force and
    ``deflection_m`` the elastic deflection of one pair under it (F / min k, the scale of the run-in).
    """

    roll: np.ndarray
    sun: np.ndarray
    planet: np.ndarray
    pitch_roll: float
    passes: tuple[float, float]
    force_N: float
    deflection_m: float
    k_wear: float

    @property
    def max_depth(self) -> float:
        """Deepest point of the sun flank (m): the severity of :class:`rvdiag.gears.Wear`."""
        return float(self.sun.max())

    def to_wear(self, gear: str = "sun") -> Wear:
        """The ``gear``'s wear ("sun" or "planet") as a simulator fault (:class:`rvdiag.gears.Wear`): its maximum
        depth with this profile's shape, tabulated on this profile's grid (the kink at the pitch point and the
        steep root included).  Put it on the driver (sun) or the driven gear (planet) of
        :class:`rvdiag.gears.ToothFaults`."""
        if gear not in ("sun", "planet"):
            raise ParameterError(f"gear must be 'sun' or 'planet', got {gear!r}")
        h = self.sun if gear == "sun" else self.planet
        if not h.max() > 0:
            return Wear(0.0)
        x = self.roll / self.roll[-1]
        return Wear(float(h.max()), run_in_deflection=self.deflection_m, shape=(tuple(x), tuple(h)))


def wear_depth_profile(params, hours: float, duty: DutyCycle, k_wear: float = DEFAULT_WEAR_COEFFICIENT, *,
                       run_in: bool = True, points: int = _POINTS) -> WearDepthProfile:
    """Archard wear of the sun and planet flanks after ``hours`` of ``duty`` with wear coefficient ``k_wear`` (m^2/N).

    Parameters
    ----------
    params : rvdiag.params.ReducerParams
    hours : float
        Hours in service (the duty's moving share of them turns the gears).
    duty : DutyCycle
    k_wear : float
        Dimensional wear coefficient (m^2/N); :data:`WEAR_COEFFICIENTS` gives the literature's span.
    run_in : bool
        True (default): the load shares of double contact follow the worn separations as the wear grows
        (module docstring).  False: fixed equal shares (1/2 in double contact), so the depth is exactly linear in
        ``hours`` and ``k_wear``: h = k (F / L) share sliding_ratio passes.
    points : int
        Grid points along the path of contact.

    Returns
    -------
    WearDepthProfile
        Zero at the pitch point (no sliding there) for either setting; in single contact the depth is
        k (F / L) sliding_ratio passes whatever the run-in, because one pair carries the whole load there.

    Examples
    --------
    >>> from rvdiag.params import ReducerParams
    >>> p = ReducerParams.default()
    >>> w = wear_depth_profile(p, 1000.0, DutyCycle(30.0, 167.0), 1e-17, run_in=False)
    >>> float(np.interp(w.pitch_roll, w.roll, w.sun)) < 1e-3 * w.max_depth
    True
    """
    return wear_depth_history(params, [hours], duty, k_wear, run_in=run_in, points=points)[0]


def history_arguments(hours, duty: DutyCycle, k_wear: float) -> list:
    """``hours`` as a list, once checked with ``duty`` and ``k_wear`` as a wear history's arguments: finite numbers
    >= 0, the hours not decreasing, a :class:`DutyCycle` (one-line :class:`~rvdiag.errors.ParameterError` else)."""
    hours = list(hours)
    for value in hours + [k_wear]:
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
                or not math.isfinite(value) or value < 0:
            raise ParameterError(f"hours and the wear coefficient must be finite numbers >= 0, got {value!r}")
    if any(b < a for a, b in zip(hours, hours[1:])):
        raise ParameterError("hours must not decrease")
    if not isinstance(duty, DutyCycle):
        raise ParameterError(f"duty must be a DutyCycle, got {type(duty).__name__}")
    return hours


def wear_depth_history(params, hours, duty: DutyCycle, k_wear: float = DEFAULT_WEAR_COEFFICIENT, *,
                       run_in: bool = True, points: int = _POINTS) -> list[WearDepthProfile]:
    """:func:`wear_depth_profile` at each of the increasing ``hours`` (a sequence) of one steady duty, from one
    integration (the growth law of a life history: the profile at a record's time in service)."""
    hours = history_arguments(hours, duty, k_wear)
    pair = GearPair.sun_planet(params)
    path, pb = pair.path_of_contact, pair.base_pitch
    s = np.linspace(0.0, path, int(points))
    # the grid holds the pitch point exactly, so that its zero sliding is sampled
    s = np.unique(np.concatenate([s, [pitch_roll(pair)]]))
    slip_s, slip_p = sliding_ratio(pair, "driver", s), sliding_ratio(pair, "driven", s)
    force = mesh_force(params, duty.load_Nm)
    width = min(pair.driver.face_width, pair.driven.face_width)
    k_pair = tooth_pair_components(pair, s)["stiffness"]
    deflection = force / float(k_pair.min()) if force > 0 else 0.0
    rate = k_wear * force / width                          # depth per pass per unit sliding ratio and load share
    enter, leave = s <= path - pb, s >= pb                  # double contact: partner at s + pb / at s - pb
    double = enter | leave
    partner = np.where(enter, s + pb, np.where(leave, s - pb, np.nan))
    k_partner = np.interp(np.nan_to_num(partner), s, k_pair)
    ratio = params.stage1.sun_teeth / (params.stage1.planet_teeth * params.stage1.n_planets)  # planet / sun passes
    h_sun, h_planet = np.zeros_like(s), np.zeros_like(s)
    done, out = 0.0, []
    for t in hours:
        n_sun, n_planet = mesh_passes(params, t, duty, "sun"), mesh_passes(params, t, duty, "planet")
        if rate > 0.0 and not run_in:
            share = np.where(double, 0.5, 1.0)
            h_sun, h_planet = rate * share * slip_s * n_sun, rate * share * slip_p * n_planet
        while rate > 0.0 and run_in and done < n_sun:
            e = h_sun + h_planet
            e_partner = np.interp(np.nan_to_num(partner), s, e)
            delta = (force + k_pair * e + k_partner * e_partner) / (k_pair + k_partner)
            share = np.where(double, np.clip(k_pair * (delta - e) / force, 0.0, 1.0), 1.0)
            g = rate * share * (slip_s + ratio * slip_p)     # separation growth per sun pass
            step = min(n_sun - done, _STEP * deflection / float(g.max()))
            h_sun = h_sun + rate * share * slip_s * step
            h_planet = h_planet + rate * share * slip_p * ratio * step
            done += step
        out.append(WearDepthProfile(roll=s, sun=h_sun.copy(), planet=h_planet.copy(), pitch_roll=pitch_roll(pair),
                                    passes=(n_sun, n_planet), force_N=float(force), deflection_m=float(deflection),
                                    k_wear=float(k_wear)))
    return out
