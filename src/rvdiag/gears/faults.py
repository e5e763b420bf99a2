"""Tooth faults that enter the mesh stiffness: flank wear, root crack, broken tooth, and combinations.

Each fault changes the loaded half of a tooth section (``x_loaded``) in the tooth frame of
:mod:`rvdiag.gears.geometry` (``y`` along the centreline, ``x`` half thickness), or, for a broken
tooth, removes the part of the flank above a cut radius.  The potential-energy integrals of
:mod:`rvdiag.gears.tvms` then run over the damaged section.

Models
------
Wear (Archard)
    Archard's law gives the depth worn per pass, dh = k p s, with p the contact pressure and s the
    sliding distance (Flodin & Andersson 1997, Wear 207, eq. (2)).  Over a Hertz half width a the
    sliding distance of a flank point of gear i is s_i = 2 a |v1 - v2| / v_i and the mean pressure is
    F / (2 a L), so the depth per pass is proportional to F |1 - v_j / v_i|, with the rolling speeds
    v_i = omega_i rho_i (rho_i the roll length, i.e. the radius of curvature of the involute).  This
    is zero at the pitch point, where rolling is pure.  F is the load share: the full load in single
    contact, half in double contact (equal sharing).  The profile is scaled so its maximum equals
    the severity ``depth``.  A normal depth h removes h / cos(tau) of half thickness, tau being the
    angle between the flank normal and the section (the load angle alpha_1 of Tian 2004); the dynamics
    paper writes h cos(alpha), which differs by less than 10 % on an RV-20E flank.
Root crack
    A straight crack from the loaded flank at the base circle (at the root circle when that lies
    above the base circle), of depth q and angle nu measured from the tooth centreline, running
    towards and possibly past the centreline (Chen & Shao 2011, Eng. Fail. Anal. 18, sec. 2.2;
    Mohammed, Rantatalo & Aidanpaa 2013, Eng. Fail. Anal. 34).  Its tip lies h_q = h_c - q sin(nu)
    from the centreline (negative: past the centreline) and q cos(nu) above the crack start.  Below
    the tip height the loaded side of the section reaches only to the tip, x_loaded = min(x, h_q);
    above it the section is whole.  The four cases of those papers (crack before / past the
    centreline, load point above / below the crack tip) follow from the sign of h_q and from where
    the integral over the section stops; :meth:`RootCrack.case` names them.
Broken tooth
    A fraction ``fraction`` of the tooth height (tip to root circle) is lost; contact points above
    the cut carry nothing (the dynamics paper, docs/references.md).  ``fraction = 1`` is a missing tooth: where it
    would be the only pair in contact the mesh stiffness is zero.
Pitting and spalling (partial tooth-face loss)
    Cavities in the loaded flank, on part of the face width (:class:`Pitting`, :class:`Spalling`).  A flank
    position is the involute arc length s = rho^2 / (2 r_b) from the base circle; across the face a cavity takes
    the width delta_L(s).  The section at the flank point s loses a delta_L(s) x d strip at its loaded edge (d the
    cavity depth, d / cos(tau) along the section, as for wear), which lowers its area and second moment
    (:func:`cut_section`), and a contact at s touches only L - delta_L(s) of the face, which enters the Hertz term
    (Liang, Zhang, Liu & Zuo 2016, Mech. Mach. Theory 106, for pits; Ma, Li, Feng, Feng & Wen 2016, Eng. Fail.
    Anal. 66, for spalls; Chaari, Baccar, Abbes & Haddar 2008, Eur. J. Mech. A/Solids 27, and Jia & Howard 2006,
    Mech. Syst. Signal Process. 20, model a spall as the loss of contact width over its profile length).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Iterable, Mapping

import numpy as np

from rvdiag.errors import GeometryError, ParameterError
from rvdiag.gears.geometry import Gear, GearPair
from rvdiag.validation import number, positive


#: The default severities of the T1..T8 states (SI; angles in degrees), keyed by :meth:`ToothFaults.for_state`'s
#: keywords: the one table of defaults, read by ``for_state`` (``rvdiag simulate --state T4``, ``rvdiag tvms``,
#: ``rvdiag separability``) and by the library (``rvdiag.library.states.SEVERITY_PARAMETERS``, a config that names
#: a state without its severities).
DEFAULT_SEVERITIES: dict[str, float] = {
    "broken_fraction": 1.0,         # whole tooth lost (as in the dynamics paper)
    "wear_depth": 20e-6,            # 20 um: moderate wear, about 1.5 % of the RV-20E module
    "crack_depth": 0.8e-3,          # 0.8 mm at 45 deg: about half way from the RV-20E sun flank to its centreline
    "crack_angle_deg": 45.0,        # the angle used by Chen & Shao (2011) and Tian (2004)
    "pit_area_fraction": 0.15,      # T7: 15 % of the band pitted (10-20 %: moderate pitting)
    "pit_radius": 0.15e-3,          # T7: 0.3 mm pits, about a quarter of the RV-20E module
    "pit_depth": 0.1e-3,            # T7
    "spall_width_fraction": 0.5,    # T8: half the face width
    "spall_length_fraction": 0.33,  # T8: a third of the working flank
    "spall_depth": 0.2e-3,          # T8
}


@dataclass(frozen=True)
class Wear:
    """Archard flank wear of maximum depth ``depth`` (m), zero at the pitch point.

    ``run_in_deflection`` (m) is the elastic deflection of the loaded tooth pair under which the wear ran in
    (default 1 um: the RV-20E's sun-planet pair at its rated torque, 107 N on a ~1.3e8 N/m pair); the load shares
    of the two pairs in double contact follow their worn separations within it (:func:`archard_wear_profile`).
    ``0`` keeps the fixed shares (1/2 in double contact) of the model before 2026-11-25.

    ``shape``, optional, replaces that profile by a tabulated one: ``(positions, depths)``, the positions as
    fractions 0..1 of the path of contact (0 its start) and the depths relative to their maximum, which ``depth``
    scales; :meth:`rvdiag.gears.wear.WearDepthProfile.to_wear` gives the shape Archard's law grows over a duty
    cycle.  ``run_in_deflection`` is then unused.
    """

    depth: float
    run_in_deflection: float = 1.0e-6
    shape: tuple[tuple[float, ...], tuple[float, ...]] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        d = number(self.depth, "wear depth")
        if d < 0:
            raise ParameterError(f"wear depth must be >= 0, got {d!r} m")
        r = number(self.run_in_deflection, "wear run-in deflection")
        if r < 0:
            raise ParameterError(f"wear run-in deflection must be >= 0, got {r!r} m")
        object.__setattr__(self, "depth", d)
        object.__setattr__(self, "run_in_deflection", r)
        if self.shape is not None:
            x, y = (np.asarray(v, dtype=float) for v in self.shape)
            if (x.ndim != 1 or x.shape != y.shape or x.size < 2 or not np.all(np.isfinite(x))
                    or not np.all(np.isfinite(y)) or np.any(np.diff(x) <= 0) or x[0] > 0 or x[-1] < 1
                    or np.any(y < 0) or y.max() <= 0):
                raise ParameterError("wear shape must be (positions, depths): increasing positions covering 0..1 "
                                     "of the path of contact and depths >= 0, not all zero")
            object.__setattr__(self, "shape", (tuple(x.tolist()), tuple((y / y.max()).tolist())))

    def profile(self, pair: GearPair, gear: str, roll: np.ndarray) -> np.ndarray:
        """Depth (m) at path-of-contact positions ``roll`` (m) of the ``gear`` flank: the tabulated ``shape``
        scaled to ``depth``, or :func:`archard_wear_profile` without one."""
        if self.shape is None:
            return archard_wear_profile(pair, gear, roll, self.depth, self.run_in_deflection)
        x, y = self.shape
        return self.depth * np.interp(np.asarray(roll, dtype=float) / pair.path_of_contact, x, y)


@dataclass(frozen=True)
class RootCrack:
    """Straight root crack of depth ``depth`` (m) at ``angle_deg`` from the tooth centreline."""

    depth: float
    angle_deg: float = DEFAULT_SEVERITIES["crack_angle_deg"]

    def __post_init__(self) -> None:
        d = number(self.depth, "crack depth")
        a = number(self.angle_deg, "crack angle")
        if d < 0:
            raise ParameterError(f"crack depth must be >= 0, got {d!r} m")
        if not 0.0 < a < 90.0:
            raise ParameterError(f"crack angle must lie in (0, 90) degrees, got {a!r}")
        object.__setattr__(self, "depth", d)
        object.__setattr__(self, "angle_deg", a)

    def start(self, gear: Gear) -> tuple[float, float]:
        """Crack start (y_c, h_c) on the loaded flank: at the base circle, or at the root
        circle when the base circle lies below it (Chen & Shao 2011)."""
        prof = gear.profile()
        radius = np.hypot(prof.x, prof.y)
        r_start = max(gear.base_radius, radius[0])
        y_c = float(np.interp(r_start, radius, prof.y))
        h_c = float(np.interp(y_c, prof.y, prof.x))
        return y_c, h_c

    def tip(self, gear: Gear) -> tuple[float, float]:
        """Crack tip (y_t, h_q): height along the centreline and signed distance from it (m)."""
        y_c, h_c = self.start(gear)
        nu = math.radians(self.angle_deg)
        return y_c + self.depth * math.cos(nu), h_c - self.depth * math.sin(nu)

    def case(self, gear: Gear, load_point_y: float) -> int:
        """Case 1..4 of Mohammed et al. (2013) / Chen & Shao (2011):
        1 before the centreline, load above the crack tip; 2 before, load below;
        3 past the centreline, load above; 4 past, load below."""
        y_t, h_q = self.tip(gear)
        past = h_q < 0
        below = load_point_y <= y_t
        return 1 + int(below) + 2 * int(past)


@dataclass(frozen=True)
class BrokenTooth:
    """Loss of ``fraction`` (0 < f <= 1) of the tooth height, measured from the tip."""

    fraction: float = DEFAULT_SEVERITIES["broken_fraction"]

    def __post_init__(self) -> None:
        f = number(self.fraction, "broken fraction")
        if not 0.0 < f <= 1.0:
            raise ParameterError(f"broken fraction must lie in (0, 1], got {f!r}")
        object.__setattr__(self, "fraction", f)

    def cut_radius(self, gear: Gear) -> float:
        """Radius above which the tooth is gone: r_a - f (r_a - r_f) (m)."""
        return gear.tip_radius - self.fraction * (gear.tip_radius - gear.root_radius)


def _fraction(name: str, value: float, lo: float, hi: float, *, open_hi: bool = False,
              open_lo: bool = False) -> float:
    """``value`` as a float in [lo, hi] (ends excluded where ``open_lo``/``open_hi``), else one ParameterError."""
    v = number(value, name)
    if (v < lo or (open_lo and v == lo)) or (v > hi or (open_hi and v == hi)):
        raise ParameterError(f"{name} must lie in {'(' if open_lo else '['}{lo:g}, {hi:g}{')' if open_hi else ']'}, "
                             f"got {v!r}")
    return v


def working_flank(pair: GearPair, gear: str) -> tuple[float, float, float]:
    """Flank positions (m) of the lowest and the highest contact point of the ``gear`` flank and of its pitch point.

    A flank position is the arc length of the involute from the base circle, s = rho^2 / (2 r_b), rho being the
    roll length (the involute's radius of curvature); it measures distances on the flank surface, where pits and
    spalls have their size.
    """
    g = pair.driver if gear == "driver" else pair.driven
    rho1, rho2 = pair.roll_lengths(np.array([0.0, pair.path_of_contact]))
    rho = np.sort(rho1 if gear == "driver" else rho2)
    rho_pitch = g.base_radius * math.tan(pair.operating_pressure_angle)
    s_lo, s_hi, s_pitch = (float(r) ** 2 / (2.0 * g.base_radius) for r in (rho[0], rho[1], rho_pitch))
    return s_lo, s_hi, s_pitch


def flank_zone(pair: GearPair, gear: str, length_fraction: float,
               centre_fraction: float | None) -> tuple[float, float]:
    """Flank positions (s_lo, s_hi) (m) of a zone covering ``length_fraction`` of the working flank, centred on its
    pitch point (``centre_fraction = None``) or at ``centre_fraction`` of the working flank (0 its lowest contact
    point, 1 its highest), moved as little as needed to lie on the working flank."""
    lo, hi, pitch = working_flank(pair, gear)
    span = length_fraction * (hi - lo)
    centre = pitch if centre_fraction is None else lo + centre_fraction * (hi - lo)
    start = min(max(centre - 0.5 * span, lo), hi - span)
    return start, start + span


@dataclass(frozen=True)
class FlankLoss:
    """Material missing from the loaded flank of one tooth, in flank positions s (m; :func:`working_flank`).

    ``spalls`` holds rectangular cavities ``(s_lo, s_hi, width, depth)``, ``pit_rows`` rows of ``count`` cylindrical
    pits ``(s_centre, radius, count, depth)`` (m).  Across the face a spall takes its ``width``, and a row of pits
    the sum of its chords, count * 2 sqrt(radius^2 - (s - s_centre)^2) (Liang, Zhang, Liu & Zuo 2016: circular
    pits cut the face width of a section by their chords).  Cavities are taken side by side, not overlapping.
    """

    spalls: tuple[tuple[float, float, float, float], ...] = ()
    pit_rows: tuple[tuple[float, float, int, float], ...] = ()

    def __bool__(self) -> bool:
        return bool(self.spalls or self.pit_rows)

    def __add__(self, other: "FlankLoss") -> "FlankLoss":
        return FlankLoss(self.spalls + other.spalls, self.pit_rows + other.pit_rows)

    def cavities(self, s: np.ndarray) -> list[tuple[np.ndarray, float]]:
        """(width lost across the face (m), depth normal to the flank (m)) of each cavity at flank positions ``s``."""
        s = np.asarray(s, dtype=float)
        out = [(np.where((s >= lo) & (s <= hi), width, 0.0), depth) for lo, hi, width, depth in self.spalls]
        out += [(count * 2.0 * np.sqrt(np.maximum(radius**2 - (s - centre) ** 2, 0.0)), depth)
                for centre, radius, count, depth in self.pit_rows]
        return out

    def width(self, s: np.ndarray) -> np.ndarray:
        """delta_L(s): the face width (m) that cavities take at flank positions ``s``."""
        total = np.zeros(np.shape(s))
        for width, _ in self.cavities(s):
            total = total + width
        return total

    def peaks(self) -> np.ndarray:
        """Flank positions where delta_L can be largest (the spall spans and the row centres)."""
        return np.array([p for lo, hi, _, _ in self.spalls for p in (lo, hi)]
                        + [row[0] for row in self.pit_rows], dtype=float)

    def through_face(self, contact_width: float) -> list[tuple[float, float, float]]:
        """Runs ``(s_lo, s_hi, depth)`` of the flank (m) over which spalls side by side take the whole
        ``contact_width`` (m) of the face, so that no intact face is left on the contact line; ``depth`` is the
        shallowest floor across the face there (where the mating tooth would first touch it).

        Pits never do: a row of pits that spans the face is refused (:meth:`Pitting.flank_loss`), and the intact
        face between and beside the pits carries the contact.
        """
        edges = np.unique([p for lo, hi, _, _ in self.spalls for p in (lo, hi)])
        runs: list[list[float]] = []
        for a, b in zip(edges[:-1], edges[1:]):
            mid = 0.5 * (a + b)
            over = [(w, d) for lo, hi, w, d in self.spalls if lo <= mid <= hi]
            if sum(w for w, _ in over) < contact_width * (1.0 - 1e-12):
                continue
            depth = min(d for _, d in over)
            if runs and runs[-1][1] == a:
                runs[-1][1], runs[-1][2] = b, min(runs[-1][2], depth)
            else:
                runs.append([float(a), float(b), depth])
        return [tuple(r) for r in runs]

    def contact_deviation(self, s: np.ndarray, curvature_radius: np.ndarray, contact_width: float) -> np.ndarray:
        """Profile deviation (m, along the flank normal, i.e. the line of action) that cavities through the face
        put between the flank at flank positions ``s`` and its mate, whose relative radius of curvature there is
        ``curvature_radius`` (m), 1 / R = 1 / rho_1 + 1 / rho_2.

        Where the contact line crosses a spall through the whole face (:meth:`through_face`, a run [a, b] of floor
        depth d) the mating flank cannot touch the cavity's floor at s until it has approached by d, nor the
        cavity's edges until it has approached by the gap that the two curved flanks leave there, (s - a)^2 / (2 R)
        and (b - s)^2 / (2 R) (Hertz's geometry of two cylinders in contact: the gap at a distance x along the
        surface is x^2 / (2 R)).  It touches first where the gap is least:

            e(s) = min(d, (s - a)^2 / (2 R), (b - s)^2 / (2 R))  on [a, b], 0 elsewhere,

        rising from the entry edge, at most min(d, (b - a)^2 / (8 R)) at the middle (the sag of the mate's arc
        under the chord of the spall), falling to the exit edge, where the flank re-enters.  This is the
        through-face tooth-face fault of the public BGU spur-gear model (PHM-BGU/public_dynamic_model_for_gear_
        vibrations, genToothFaceFaultProfile.m and calcFaultDispMeshForceT.m: the deviation is the sum of both
        flanks' arc sags under the chords of the fault edges, c^2 / (8 rho_1) + c^2 / (8 rho_2), and the mate
        pivots on the entry edge, then on the exit edge); a spall over part of the face leaves the intact part
        carrying the contact and gives no deviation (their PartialFaceFault: only the width and the section
        change).  Zero where no spall runs through the face.
        """
        s = np.asarray(s, dtype=float)
        out = np.zeros(np.shape(s))
        radius = np.asarray(curvature_radius, dtype=float)
        for a, b, depth in self.through_face(contact_width):
            inside = (s >= a) & (s <= b)
            gap = np.minimum(s - a, b - s) ** 2 / (2.0 * radius)
            out = np.where(inside, np.maximum(out, np.minimum(depth, gap)), out)
        return out


@dataclass(frozen=True)
class Pitting:
    """Pitting: rows of small cylindrical pits in a band around the pitch line of the loaded flank.

    Model (Liang, Zhang, Liu & Zuo 2016, Mech. Mach. Theory 106, 1-15): each pit is a cylinder of radius
    ``radius`` and depth ``depth`` (normal to the flank).  A tooth section through a pit loses the pit's chord
    across the face, delta_L(s), over the pit depth: its area and second moment drop accordingly
    (:func:`cut_section`), and a contact line at s touches L - delta_L(s) of the face, so that the Hertz stiffness
    is k_h = pi E (L - delta_L) / (4 (1 - nu^2)) there.

    Parameters
    ----------
    area_fraction : float
        Fraction of the band's flank area covered by pits, in [0, pi/4) (0: no pits, healthy).  Default 0.15
        (``DEFAULT_SEVERITIES``), within the 10-20 % of a moderately pitted flank; the number of pits,
        area_fraction x band area / (pi radius^2), is rounded to a whole number (at least one).
    radius : float
        Pit radius on the flank (m); default 0.15 mm, a 0.3 mm pit, about a quarter of the RV-20E module (1.25 mm).
    depth : float
        Pit depth normal to the flank (m); default 0.1 mm.
    band_fraction : float
        Height of the pitted band as a fraction of the working flank, in (0, 1]; default 0.4.
    centre_fraction : float or None
        Centre of the band on the working flank (0 its lowest contact point, 1 its highest); ``None`` (default)
        the pitch point, where pitting starts (:func:`flank_zone`).

    The default radius, depth and band are choices scaled to the RV-20E sun, not figures measured on one; Liang
    et al. (2016) model several pitting severity levels, and here the pitted area fraction is the severity.

    Layout: the pits sit in rows across the face, as many rows along the band as fit without overlapping
    (floor(band / (2 radius)), evenly spaced), the pits shared evenly between the rows and the remainder given
    to the rows nearest the band centre.  The layout is deterministic; more pits never take a pit away from a row,
    so the stiffness falls monotonically with ``area_fraction``.
    """

    area_fraction: float = DEFAULT_SEVERITIES["pit_area_fraction"]
    radius: float = DEFAULT_SEVERITIES["pit_radius"]
    depth: float = DEFAULT_SEVERITIES["pit_depth"]
    band_fraction: float = 0.4
    centre_fraction: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "area_fraction",
                           _fraction("pitting area fraction", self.area_fraction, 0.0, math.pi / 4, open_hi=True))
        object.__setattr__(self, "radius", positive(self.radius, "pit radius", unit=" m"))
        object.__setattr__(self, "depth", positive(self.depth, "pit depth", unit=" m"))
        object.__setattr__(self, "band_fraction",
                           _fraction("pitting band fraction", self.band_fraction, 0.0, 1.0, open_lo=True))
        if self.centre_fraction is not None:
            object.__setattr__(self, "centre_fraction",
                               _fraction("pitting band centre fraction", self.centre_fraction, 0.0, 1.0))

    def flank_loss(self, pair: GearPair, gear: str) -> FlankLoss:
        """The pit rows on the ``gear`` flank of ``pair`` (raises GeometryError when the pits do not fit)."""
        if self.area_fraction == 0.0:
            return FlankLoss()
        g = pair.driver if gear == "driver" else pair.driven
        lo, hi = flank_zone(pair, gear, self.band_fraction, self.centre_fraction)
        band, r = hi - lo, self.radius
        n_rows = int(band // (2.0 * r))
        if n_rows < 1:
            raise GeometryError(
                f"pits of radius {r * 1e3:.3f} mm do not fit in the {band * 1e3:.3f} mm high pitting band of the "
                f"{g.name} flank; use a smaller radius or a larger band fraction")
        n_pits = max(1, round(self.area_fraction * band * g.face_width / (math.pi * r * r)))
        counts = [n_pits // n_rows] * n_rows
        nearest_centre = sorted(range(n_rows), key=lambda i: (abs(i - 0.5 * (n_rows - 1)), i))
        for i in nearest_centre[: n_pits % n_rows]:
            counts[i] += 1
        if max(counts) * 2.0 * r >= g.face_width:
            raise GeometryError(
                f"pitting area fraction {self.area_fraction:g} is too large for pits of radius {r * 1e3:.3f} mm: "
                f"{max(counts)} pits in a row span the whole {g.face_width * 1e3:.1f} mm face of the {g.name}")
        pitch = band / n_rows
        return FlankLoss(pit_rows=tuple((lo + (i + 0.5) * pitch, r, c, self.depth)
                                        for i, c in enumerate(counts) if c > 0))


@dataclass(frozen=True)
class Spalling:
    """Spalling: one rectangular spall on the loaded flank, across part of the face width.

    Model: the spall is a rectangular cavity ``length_fraction`` of the working flank long (along the profile),
    ``width_fraction`` of the face wide and ``depth`` deep.  Contact points within its profile range touch only
    L - w of the face (w = width_fraction L), which enters the Hertz term, k_h = pi E (L - w) / (4 (1 - nu^2)),
    (a spall through the face, w = L, leaves no intact face on the contact line: the mate then touches the
    cavity's edges or floor across the whole face, k_h with L, after a profile deviation of up to
    min(depth, l^2 / (8 R)), l the spall length and R the relative radius of curvature,
    :meth:`FlankLoss.contact_deviation`, :func:`flank_deviation`),
    and the sections it crosses lose a w x depth strip at the loaded edge (:func:`cut_section`) (Ma, Li, Feng,
    Feng & Wen 2016, Eng. Fail. Anal. 66; the loss of contact width over the spall's profile length is the spall
    model of Chaari, Baccar, Abbes & Haddar 2008, Eur. J. Mech. A/Solids 27, and of Jia & Howard 2006, Mech.
    Syst. Signal Process. 20).

    Parameters
    ----------
    width_fraction : float
        Spall width across the face as a fraction of the face width, in [0, 1] (0: no spall, healthy; 1: a spall
        through the whole face).  Default 0.5 (``DEFAULT_SEVERITIES``): a spall over half the face, in
        the 40-60 % of a developed spall.  Only a spall through the face lifts the contact (a profile deviation,
        :meth:`FlankLoss.contact_deviation`); over part of the face the intact part carries the load, and the
        spall only softens the pair.
    length_fraction : float
        Spall length along the profile as a fraction of the working flank, in (0, 1]; default 0.33 (a third).
    depth : float
        Spall depth normal to the flank (m); default 0.2 mm, twice the default pit depth (spalls are pits grown
        together and deeper).
    centre_fraction : float or None
        Centre of the spall on the working flank (0 its lowest contact point, 1 its highest); ``None`` (default)
        the pitch point (:func:`flank_zone`).
    """

    width_fraction: float = DEFAULT_SEVERITIES["spall_width_fraction"]
    length_fraction: float = DEFAULT_SEVERITIES["spall_length_fraction"]
    depth: float = DEFAULT_SEVERITIES["spall_depth"]
    centre_fraction: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "width_fraction",
                           _fraction("spall width fraction", self.width_fraction, 0.0, 1.0))
        object.__setattr__(self, "length_fraction",
                           _fraction("spall length fraction", self.length_fraction, 0.0, 1.0, open_lo=True))
        object.__setattr__(self, "depth", positive(self.depth, "spall depth", unit=" m"))
        if self.centre_fraction is not None:
            object.__setattr__(self, "centre_fraction",
                               _fraction("spall centre fraction", self.centre_fraction, 0.0, 1.0))

    def flank_loss(self, pair: GearPair, gear: str) -> FlankLoss:
        """The spall on the ``gear`` flank of ``pair``."""
        if self.width_fraction == 0.0:
            return FlankLoss()
        g = pair.driver if gear == "driver" else pair.driven
        lo, hi = flank_zone(pair, gear, self.length_fraction, self.centre_fraction)
        return FlankLoss(spalls=((lo, hi, self.width_fraction * g.face_width, self.depth),))


Fault = Wear | RootCrack | BrokenTooth | Pitting | Spalling
_FAULT_TYPES = (Wear, RootCrack, BrokenTooth, Pitting, Spalling)

T6_CRACK_OFFSET = 5               # T6: the crack sits this many teeth after the broken tooth

#: The health states T1..T8 and the fault kinds each combines (``+``-joined, the names :meth:`ToothFaults.from_name`
#: reads): the one state table.  ``rvdiag.library.states.STATES`` derives its :class:`HealthState` objects from it.
FAULT_KINDS: dict[str, str] = {
    "T1": "healthy",
    "T2": "broken",
    "T3": "wear",
    "T4": "crack",
    "T5": "broken+wear",
    "T6": "broken+wear+crack",
    "T7": "pitting",
    "T8": "spalling",
}
_STATE_RANGE = f"{next(iter(FAULT_KINDS))}..{next(reversed(FAULT_KINDS))}"


@dataclass(frozen=True)
class ToothFaults:
    """Faults on chosen teeth of one gear of a pair.

    Parameters
    ----------
    teeth : mapping int -> sequence of faults
        Faults of individual teeth (tooth 0 is the driver tooth entering contact at angle 0;
        on the driven gear, tooth j is the one meeting driver engagement j).  At most one fault of
        each kind per tooth.
    wear : Wear, optional
        Wear of every tooth of the gear (wear is distributed, not local); a per-tooth ``Wear`` in
        ``teeth`` overrides it for that tooth.
    gear : {"driver", "driven"}
        Which gear carries the faults (default the driver, the sun in the RV studies of docs/references.md).

    Examples
    --------
    >>> f = ToothFaults.for_state("T5")
    >>> f.wear.depth, f.teeth[0]
    (2e-05, (BrokenTooth(fraction=1.0),))
    """

    teeth: Mapping[int, tuple[Fault, ...]] = field(default_factory=dict)
    wear: Wear | None = None
    gear: str = "driver"
    label: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        if self.gear not in ("driver", "driven"):
            raise ParameterError(f"fault gear must be 'driver' or 'driven', got {self.gear!r}")
        if self.wear is not None and not isinstance(self.wear, Wear):
            raise ParameterError(f"wear must be a Wear, got {self.wear!r}")
        clean: dict[int, tuple[Fault, ...]] = {}
        for tooth, faults in dict(self.teeth).items():
            if isinstance(tooth, bool) or not isinstance(tooth, (int, np.integer)) or tooth < 0:
                raise ParameterError(f"tooth index must be an integer >= 0, got {tooth!r}")
            if isinstance(faults, _FAULT_TYPES):
                faults = (faults,)
            faults = tuple(faults)
            kinds = [type(f) for f in faults]
            for f in faults:
                if not isinstance(f, _FAULT_TYPES):
                    raise ParameterError(f"tooth {tooth}: not a fault: {f!r}")
            if len(set(kinds)) != len(kinds):
                raise ParameterError(f"tooth {tooth}: at most one fault of each kind")
            clean[int(tooth)] = faults
        object.__setattr__(self, "teeth", clean)

    @property
    def is_healthy(self) -> bool:
        """True when no fault is present."""
        return (self.wear is None or self.wear.depth == 0.0) and not any(self.teeth.values())

    def faults_of(self, tooth: int) -> tuple[Fault, ...]:
        """All faults acting on ``tooth``, the gear-wide wear included."""
        own = self.teeth.get(tooth, ())
        if self.wear is not None and not any(isinstance(f, Wear) for f in own):
            own = own + (self.wear,)
        return own

    def validate(self, pair: GearPair) -> None:
        """Check tooth indices and severities against the gear geometry (raises GeometryError)."""
        gear = pair.driver if self.gear == "driver" else pair.driven
        for tooth in self.teeth:
            if tooth >= gear.teeth:
                raise ParameterError(
                    f"tooth index {tooth} out of range for the {gear.name} with {gear.teeth} teeth")
        for tooth in set(self.teeth) | {0}:
            damaged_profile(pair, self.gear, self.faults_of(tooth))

    @classmethod
    def for_state(cls, state: str, *, wear_depth: float = DEFAULT_SEVERITIES["wear_depth"],
                  crack_depth: float = DEFAULT_SEVERITIES["crack_depth"],
                  crack_angle_deg: float = DEFAULT_SEVERITIES["crack_angle_deg"],
                  broken_fraction: float = DEFAULT_SEVERITIES["broken_fraction"],
                  pit_area_fraction: float = DEFAULT_SEVERITIES["pit_area_fraction"],
                  pit_radius: float = DEFAULT_SEVERITIES["pit_radius"],
                  pit_depth: float = DEFAULT_SEVERITIES["pit_depth"],
                  spall_width_fraction: float = DEFAULT_SEVERITIES["spall_width_fraction"],
                  spall_length_fraction: float = DEFAULT_SEVERITIES["spall_length_fraction"],
                  spall_depth: float = DEFAULT_SEVERITIES["spall_depth"],
                  tooth: int = 0, crack_tooth: int | None = None,
                  gear: str = "driver") -> "ToothFaults":
        """The health states of the library: T1 healthy, T2 broken tooth, T3 wear, T4 root crack,
        T5 broken + wear, T6 broken + wear + crack, T7 pitting, T8 spalling (:data:`FAULT_KINDS`).  A severity
        not given takes its value from :data:`DEFAULT_SEVERITIES`.

        Pitting (:class:`Pitting`) and the spall (:class:`Spalling`) sit on ``tooth``, around its pitch line.

        Wear acts on every tooth; the broken tooth is ``tooth``; the crack is on ``tooth`` in T4
        and, in T6, on ``crack_tooth``, by default ``tooth + T6_CRACK_OFFSET`` (five teeth on: nearly
        opposite the broken tooth on the 11-tooth RV sun).  A crack on the tooth next to a missing
        one is half hidden, since that tooth already carries the whole load while its broken
        neighbour would have shared it: on the RV-20E its signature is half as large as five teeth
        on (log-spectrum change 0.06 against 0.11 for a 2 mm crack at 10 um wear, docs/model.md,
        "Fault sensitivity").
        """
        key = str(state).upper()
        if key not in FAULT_KINDS:
            raise ParameterError(f"unknown fault state {state!r}; choose one of {', '.join(FAULT_KINDS)}")
        kinds = FAULT_KINDS[key].split("+")
        wear = Wear(wear_depth) if "wear" in kinds else None
        teeth: dict[int, list[Fault]] = {}
        if "broken" in kinds:
            teeth.setdefault(tooth, []).append(BrokenTooth(broken_fraction))
        if "crack" in kinds:
            ct = tooth if key == "T4" else (tooth + T6_CRACK_OFFSET if crack_tooth is None else crack_tooth)
            teeth.setdefault(ct, []).append(RootCrack(crack_depth, crack_angle_deg))
        if "pitting" in kinds:
            teeth.setdefault(tooth, []).append(Pitting(pit_area_fraction, pit_radius, pit_depth))
        if "spalling" in kinds:
            teeth.setdefault(tooth, []).append(Spalling(spall_width_fraction, spall_length_fraction, spall_depth))
        return cls({k: tuple(v) for k, v in teeth.items()}, wear=wear, gear=gear, label=key)

    @classmethod
    def from_name(cls, name: str, **severities: float) -> "ToothFaults":
        """Build from a name ``healthy``, ``wear``, ``crack``, ``broken``, ``broken+wear``,
        ``broken+wear+crack``, ``pitting``, ``spalling`` (or T1..T8)."""
        lookup = {v: k for k, v in FAULT_KINDS.items()}
        key = str(name).strip().lower()
        if key.upper() in FAULT_KINDS:
            return cls.for_state(key.upper(), **severities)
        parts = sorted(key.split("+"))
        for label, kinds in lookup.items():
            if sorted(label.split("+")) == parts:
                return cls.for_state(kinds, **severities)
        raise ParameterError(
            f"unknown fault {name!r}; choose one of {', '.join(FAULT_KINDS.values())} or {_STATE_RANGE}")

    def describe(self) -> dict:
        """JSON-ready description of the faults (SI units)."""
        out: dict = {"gear": self.gear, "label": self.label,
                     "wear_depth_m": None if self.wear is None else self.wear.depth, "teeth": {}}
        for tooth, faults in self.teeth.items():
            out["teeth"][str(tooth)] = [
                {"kind": type(f).__name__, **{k: getattr(f, k) for k in f.__dataclass_fields__}}
                for f in faults]
        return out


# ---------------------------------------------------------------------- profile modifications
@dataclass(frozen=True)
class DamagedProfile:
    """A tooth section table after damage: loaded and unloaded half thickness over ``y``, and the
    radius above which the flank is missing (``inf`` when whole).

    With pitting or spalling, ``flank_loss`` holds the cavities, and ``area`` and ``inertia`` the area (m^2) and
    second moment (m^4) of the sections they cut (:func:`cut_section`), NaN where the section is the whole
    rectangle of thickness ``x_loaded + x_other`` and the face width; all three are ``None`` without such a fault.
    """

    y: np.ndarray
    x_loaded: np.ndarray
    x_other: np.ndarray
    cut_radius: float
    flank_loss: FlankLoss | None = None
    area: np.ndarray | None = None
    inertia: np.ndarray | None = None


def cut_section(thickness: np.ndarray, face_width: float,
                cavities: Iterable[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Area and second moment (about its own centroid) of a rectangular tooth section, ``thickness`` x
    ``face_width``, that lost a strip ``width`` x ``depth`` at its loaded edge for each ``(width, depth)`` cavity
    (depth along the section, widths across the face taken side by side).

    With xi measured across the section from the unloaded edge: A = t L - sum w d; first moment
    Q = t^2 L / 2 - sum w d (t - d / 2); I_0 = t^3 L / 3 - sum w (t^3 - (t - d)^3) / 3 about the unloaded edge;
    I = I_0 - Q^2 / A about the centroid xi_c = Q / A (parallel axes).  With no cavity, I = t^3 L / 12.  This is
    the section of Liang, Zhang, Liu & Zuo (2016) for a pitted tooth (the area and second moment of the section
    less the pits' part, with the shifted centroid); the moment arm of the load is still taken from the tooth
    centreline, as for wear and cracks.
    """
    t = np.asarray(thickness, dtype=float)
    area = t * face_width
    first = 0.5 * t * t * face_width
    second = t**3 * face_width / 3.0
    for width, depth in cavities:
        area = area - width * depth
        first = first - width * depth * (t - 0.5 * depth)
        second = second - width * (t**3 - (t - depth) ** 3) / 3.0
    return area, second - first * first / area


def sliding_ratio(pair: GearPair, gear: str, roll: np.ndarray) -> np.ndarray:
    """Sliding per unit rolling of the ``gear`` flank at path positions ``roll``: |1 - v_j / v_i| with
    v_i = omega_i rho_i (Flodin & Andersson 1997, eq. (2)); zero at the pitch point."""
    rho1, rho2 = pair.roll_lengths(np.asarray(roll, dtype=float))
    rb1, rb2 = pair.driver.base_radius, pair.driven.base_radius
    with np.errstate(divide="ignore", invalid="ignore"):  # omega2 / omega1 = rb1 / rb2
        if gear == "driver":
            slip = np.abs(1.0 - (rb1 * rho2) / (rb2 * rho1))
        else:
            slip = np.abs(1.0 - (rb2 * rho1) / (rb1 * rho2))
    return np.nan_to_num(slip)


#: grid of the run-in evolution along the path of contact, and the wear added per step as a fraction of the
#: run-in deflection (a step well below the deflection lets the load shares follow the worn separations)
_RUN_IN_POINTS = 2001
_RUN_IN_STEP = 0.05


def archard_wear_profile(pair: GearPair, gear: str, roll: np.ndarray, depth: float,
                         run_in_deflection: float = 0.0) -> np.ndarray:
    """Wear depth (m) at path-of-contact positions ``roll`` (m) on the ``gear`` flank.

    Archard's law per mesh cycle, h(rho) ~ F_share |1 - v_j / v_i| (Flodin & Andersson 1997, eq. (2), with the
    sliding distance 2 a |v1 - v2| / v_i), scaled so that the deepest point reaches ``depth``.

    With ``run_in_deflection = 0`` the load share is fixed: 1 in single contact, 1/2 in double contact, so the
    profile steps at the single/double contact boundaries by up to half its depth.  With ``d0 =
    run_in_deflection > 0`` the wear is grown in small steps, and in double contact each step's load share
    follows the separations that the wear so far has cut: two pairs of equal stiffness whose separations differ
    by ``e_B - e_A`` under a load that deflects one pair by ``d0`` share it as
    ``F_A / F = (1 + (e_B - e_A) / d0) / 2``, clipped to [0, 1] (one pair carries all once the other is more than
    ``d0`` deeper worn); the load distribution of the worn geometry, recomputed as the wear progresses (Flodin &
    Andersson 1997; Bajpai, Kahraman & Anderson 2004, Wear 257).  The deeper-worn pair of a double-contact zone
    then sheds its load and stops wearing, and the steps run in to about ``d0``.  Only this gear's wear enters
    the separations (the mate is taken unworn).
    """
    roll = np.asarray(roll, dtype=float)
    pb, path = pair.base_pitch, pair.path_of_contact
    s = np.linspace(0.0, path, _RUN_IN_POINTS)
    slip = sliding_ratio(pair, gear, s)
    enter = s <= path - pb          # double contact, the partner pair at s + pb
    leave = s >= pb                 # double contact, the partner pair at s - pb
    fixed_share = np.where(enter | leave, 0.5, 1.0)
    if depth <= 0.0:
        return np.zeros_like(roll)
    if run_in_deflection <= 0.0:
        h = fixed_share * slip
    else:
        d0 = float(run_in_deflection)
        step = _RUN_IN_STEP * d0
        h = np.zeros_like(s)
        for _ in range(int(math.ceil(depth / step)) + 1):
            e_partner = np.where(enter, np.interp(s + pb, s, h), np.where(leave, np.interp(s - pb, s, h), 0.0))
            share = np.where(enter | leave, np.clip(0.5 * (1.0 + (e_partner - h) / d0), 0.0, 1.0), 1.0)
            g = share * slip
            h = h + step * g / float(np.max(g))
            if h.max() >= depth:
                break
    hmax = float(np.max(h))
    return depth * np.interp(roll, s, h) / hmax if hmax > 0 else np.zeros_like(roll)


def flank_deviation(pair: GearPair, gear: str, faults: Iterable[Fault], roll: np.ndarray) -> np.ndarray:
    """Profile deviation (m) of a ``gear`` flank carrying ``faults`` at path-of-contact positions ``roll`` (m),
    along the line of action: how much further the mate must approach before it touches there.  The one home of
    a flank's deviation from the involute, which the TVMS reports per tooth pair
    (:attr:`rvdiag.gears.tvms.MeshStiffnessResult.pair_profile_error_m`) and the dynamic model adds to each
    pair's separation (:func:`rvdiag.dynamics.mesh.mesh_table_from_gears`).

    It is the sum of the Archard wear depth (:func:`archard_wear_profile`) and the deviation of spalls through
    the whole face (:meth:`FlankLoss.contact_deviation`, with the relative radius of curvature
    1 / R = 1 / rho_1 + 1 / rho_2 of the two involutes at the contact, rho_i their roll lengths).  Cracks and a
    broken tooth have none (a broken tooth's lost contact is a zero stiffness, :mod:`rvdiag.gears.tvms`);
    pits and spalls over part of the face neither.  Zero without such faults.
    """
    roll = np.asarray(roll, dtype=float)
    out = np.zeros_like(roll)
    faults = tuple(faults)
    for f in faults:
        if isinstance(f, Wear) and f.depth > 0:
            out = out + f.profile(pair, gear, roll)
    loss = FlankLoss()
    for f in faults:
        if isinstance(f, (Pitting, Spalling)):
            loss = loss + f.flank_loss(pair, gear)
    contact_width = min(pair.driver.face_width, pair.driven.face_width)
    if loss.through_face(contact_width):
        rho1, rho2 = pair.roll_lengths(roll)
        rho, rb = (rho1, pair.driver.base_radius) if gear == "driver" else (rho2, pair.driven.base_radius)
        out = out + loss.contact_deviation(rho * rho / (2.0 * rb), rho1 * rho2 / (rho1 + rho2), contact_width)
    return out


def has_flank_deviation(pair: GearPair, gear: str, faults: Iterable[Fault]) -> bool:
    """Whether :func:`flank_deviation` can be non-zero for ``faults``: wear, or spalls through the face."""
    faults = tuple(faults)
    if any(isinstance(f, Wear) and f.depth > 0 for f in faults):
        return True
    loss = FlankLoss()
    for f in faults:
        if isinstance(f, (Pitting, Spalling)):
            loss = loss + f.flank_loss(pair, gear)
    return bool(loss.through_face(min(pair.driver.face_width, pair.driven.face_width)))


def damaged_profile(pair: GearPair, gear: str, faults: Iterable[Fault]) -> DamagedProfile:
    """Section table of one tooth of ``gear`` ("driver"/"driven") carrying ``faults``."""
    g = pair.driver if gear == "driver" else pair.driven
    prof = g.profile()
    y, x = prof.y, prof.x
    xl = x.copy()
    cut = math.inf
    for f in faults:
        if isinstance(f, Wear) and f.depth > 0:
            r = np.hypot(x, y)
            rho = np.sqrt(np.maximum(r**2 - g.base_radius**2, 0.0))
            if gear == "driver":
                roll = rho - pair.start_roll_length_driver
            else:
                roll = (pair.line_of_action_length - rho) - pair.start_roll_length_driver
            active = (roll >= 0) & (roll <= pair.path_of_contact) & (np.arange(len(y)) >= prof.n_fillet)
            h = np.zeros_like(y)
            h[active] = f.profile(pair, gear, roll[active])
            tau = rho / g.base_radius - g.base_half_angle     # flank normal vs. section (load angle)
            xl = xl - h / np.cos(tau)
            if np.any(xl[active] <= 0.0):
                raise GeometryError(
                    f"wear deeper than the {g.name} tooth: a wear depth of {f.depth * 1e3:.3f} mm "
                    f"wears the flank through to the tooth centreline")
    for f in faults:
        if isinstance(f, RootCrack) and f.depth > 0:
            y_t, h_q = f.tip(g)
            if y_t >= y[-1]:
                raise GeometryError(
                    f"crack of depth {f.depth * 1e3:.3f} mm at {f.angle_deg} deg reaches above the "
                    f"{g.name} tooth tip")
            y_c, _ = f.start(g)
            zone = (y >= y_c) & (y <= y_t)
            xl = np.where(zone, np.minimum(xl, h_q), xl)
    for f in faults:
        if isinstance(f, BrokenTooth):
            cut = min(cut, f.cut_radius(g))
    thickness = xl + x
    if np.any(thickness <= 0.02 * g.module):
        worst = "crack" if any(isinstance(f, RootCrack) for f in faults) else "wear"
        raise GeometryError(
            f"{worst} deeper than the {g.name} tooth: the remaining section falls to "
            f"{max(float(thickness.min()), 0.0) * 1e3:.3f} mm")
    loss = FlankLoss()
    for f in faults:
        if isinstance(f, (Pitting, Spalling)):
            loss = loss + f.flank_loss(pair, gear)
    if not loss:
        return DamagedProfile(y=y, x_loaded=xl, x_other=x, cut_radius=cut)
    return _with_flank_loss(DamagedProfile(y=y, x_loaded=xl, x_other=x, cut_radius=cut), g, prof.n_fillet, loss)


def _with_flank_loss(prof: DamagedProfile, g: Gear, n_fillet: int, loss: FlankLoss) -> DamagedProfile:
    """``prof`` with the sections that the cavities of ``loss`` cut (:func:`cut_section`)."""
    y, x, thickness = prof.y, prof.x_other, prof.x_loaded + prof.x_other
    r2 = x * x + y * y
    rho = np.sqrt(np.maximum(r2 - g.base_radius**2, 0.0))
    involute = np.arange(len(y)) >= n_fillet
    s = np.where(involute, rho * rho / (2.0 * g.base_radius), -np.inf)   # flank position of each section
    tau = rho / g.base_radius - g.base_half_angle      # flank normal vs. section, as for wear
    at = np.concatenate([s, loss.peaks()])
    total, spalls = loss.width(at), FlankLoss(spalls=loss.spalls).width(at)
    full = g.face_width * (1.0 - 1e-12)
    # spalls may take the whole face (a spall through the face); pits may not complete it, nor anything exceed it
    if np.any(total > g.face_width * (1.0 + 1e-12)) or np.any((total >= full) & (spalls < full)):
        raise GeometryError(f"pitting and spalling together take more than the whole {g.face_width * 1e3:.1f} mm "
                            f"face of a {g.name} tooth")
    cavities = [(width, depth / np.cos(tau)) for width, depth in loss.cavities(s)]
    hit = np.zeros(len(y), dtype=bool)
    names = ["spalling"] * len(loss.spalls) + ["pitting"] * len(loss.pit_rows)   # the order of loss.cavities
    for name, (width, depth) in zip(names, cavities):
        hit |= width > 0
        left = np.where(width > 0, thickness - depth, np.inf)
        if np.any(left <= 0.02 * g.module):
            raise GeometryError(
                f"{name} deeper than the {g.name} tooth: the section under the cavity falls to "
                f"{max(float(left.min()), 0.0) * 1e3:.3f} mm")
    area, inertia = cut_section(thickness, g.face_width, cavities)
    return dataclasses.replace(prof, flank_loss=loss, area=np.where(hit, area, np.nan),
                               inertia=np.where(hit, inertia, np.nan))
