"""Manufacturing and assembly errors of one RV reducer, drawn from the tolerances of ``[manufacturing]``.

One purpose: turn the tolerances of :class:`rvdiag.params.schema.Manufacturing` and the specimen's seed
(``[modification] error_seed``) into the deviations of one reducer, which :mod:`rvdiag.dynamics.packing` puts in the
kernels' arrays (docs/model.md section 3, "Manufacturing errors").  The sun's pitch and profile deviations are
``[modification] iso1328_grade``'s (:mod:`rvdiag.gears.modification`, in the mesh table); these are the others:

- **planet runout** (ISO 1328-1:2013 class ``planet_runout_grade``, runout tolerance ``F_rT = 0.9 F_pT``): each
  planet's pitch circle is eccentric to its crank's axis by ``e_i = F_r,i / 2``, ``F_r,i`` uniform in
  ``[0, F_rT / 2]``, at an angle ``phi_i`` uniform in ``[0, 2 pi)``.  The offset turns with the planet, whose angle in
  the carrier frame is the cranks' eccentric angle ``beta_0(t)``; projected on the line of action it is the
  transmission error ``r_i(t) = e_i sin(beta_0(t) + phi_i + alpha)``, once per planet revolution relative to the
  carrier, which the mesh approach loses: ``delta_i - r_i`` (the eccentricity error of a planetary gear, Inalpolat
  & Kahraman 2009, J. Sound Vib. 323, 677-696, eq. (3)'s transmission-error term).
- **crank-hole position** (``crank_hole_position``, +- radial and tangential): the seat of crank bearing i in the
  carrier sits at ``a e_r(psi_i) + eps_i``, so the crank-carrier bearing's deflection is ``d - eps_i`` (in the
  orbiting frame); the crank and its planet settle where the carrier and the discs let them, and the planet's
  shift reaches its mesh through its coordinates (planet position errors: Bodas & Kahraman 2004, JSME Int. J. C
  47(3), 908-915; Gu & Velex 2012, J. Sound Vib. 331, 4554-4574).  The mean tangential error of the holes is a
  rotation of the pattern, not an error, and is taken out.
- **crank phase** (``crank_phase_arcmin``, +-): the eccentrics of crank i stand ``Delta_i`` ahead of where its
  planet's teeth put them (the planet's indexing on the crank's spline); the crank-cycloid bearings see the
  eccentric at ``e (th_ci + Delta_i) t_j``.  The mean over the cranks is a rotation of the sun, not an error, and is
  taken out.
- **pins** (``pin_radius``, ``pin_position``, +-; the pin radius and pin position tolerances of Blanche & Yang
  1989, J. Mech. Transm. Autom. Des. 111(3), 337-344): pin k has its radius off by ``rho_k`` and its groove's
  centre off by ``v_k = R_k e_r(gamma_k) + T_k e_t(gamma_k)`` (fixed frame, ``gamma_k = 2 pi k / Zp``); the contact
  of disc j with pin k is compressed by ``rho_k - v_k . n_jk`` more.  The means of ``rho`` and ``R`` (a pin-circle
  radius error, i.e. the stage's clearance, which the discs' profile modification sets) and of ``T`` (a
  rotation of the pin ring) are taken out.

Every deviation is drawn uniformly within +- half its tolerance (the convention of the sun's pitch deviations,
:func:`rvdiag.gears.modification.tooth_position_errors`) from ``numpy.random.default_rng([error_seed, stream])``,
one stream per kind, so turning one kind off leaves the others' draws unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rvdiag.gears.modification import iso1328_tolerances
from rvdiag.params import ReducerParams

#: the random stream of each kind of deviation (second entry of the seed sequence)
STREAMS = {"planet_runout": 1, "crank_hole": 2, "crank_phase": 3, "pin_radius": 4, "pin_position": 5}


@dataclass(frozen=True)
class ManufacturingErrors:
    """The deviations of one reducer (m and rad; tuples so that the object compares and hashes).

    ``runout[i]``, ``runout_angle[i]``: planet i's eccentricity and its angle ``phi_i``; ``hole_radial[i]``,
    ``hole_tangential[i]``: crank hole i's position error in planet i's orbiting frame; ``crank_phase[i]``: crank
    i's eccentric angle error; ``pin_radius[k]``, ``pin_radial[k]``, ``pin_tangential[k]``: pin k's radius error and
    its groove's radial and tangential position errors (module docstring).
    """

    runout: tuple[float, ...]
    runout_angle: tuple[float, ...]
    hole_radial: tuple[float, ...]
    hole_tangential: tuple[float, ...]
    crank_phase: tuple[float, ...]
    pin_radius: tuple[float, ...]
    pin_radial: tuple[float, ...]
    pin_tangential: tuple[float, ...]

    @property
    def planets_zero(self) -> bool:
        """True when no planet, crank-hole or crank-phase error is on."""
        return not any(any(v) for v in (self.runout, self.hole_radial, self.hole_tangential, self.crank_phase))

    @property
    def pins_zero(self) -> bool:
        """True when no pin error is on."""
        return not any(any(v) for v in (self.pin_radius, self.pin_radial, self.pin_tangential))

    @property
    def is_zero(self) -> bool:
        return self.planets_zero and self.pins_zero

    def pin_offsets_fixed_frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(rho, v_x, v_y)``: each pin's radius error and its groove's position error in the fixed frame (m)."""
        zp = len(self.pin_radius)
        g = 2.0 * math.pi * np.arange(zp) / zp
        R, T = np.asarray(self.pin_radial), np.asarray(self.pin_tangential)
        return (np.asarray(self.pin_radius, dtype=float), R * np.cos(g) - T * np.sin(g), R * np.sin(g) + T * np.cos(g))

    def to_dict(self) -> dict:
        """Plain lists, in um and arcmin, for records and reports."""
        um = 1e6
        arcmin = 60.0 * 180.0 / math.pi
        return {"runout_um": [v * um for v in self.runout],
                "runout_angle_deg": [math.degrees(v) for v in self.runout_angle],
                "hole_radial_um": [v * um for v in self.hole_radial],
                "hole_tangential_um": [v * um for v in self.hole_tangential],
                "crank_phase_arcmin": [v * arcmin for v in self.crank_phase],
                "pin_radius_um": [v * um for v in self.pin_radius],
                "pin_radial_um": [v * um for v in self.pin_radial],
                "pin_tangential_um": [v * um for v in self.pin_tangential]}


def _uniform(seed: int, kind: str, tolerance: float, size: int) -> np.ndarray:
    """``size`` deviations uniform in +- ``tolerance / 2`` from the stream of ``kind`` (zeros for no tolerance)."""
    if tolerance <= 0.0:
        return np.zeros(size)
    rng = np.random.default_rng([int(seed), STREAMS[kind]])
    return rng.uniform(-0.5, 0.5, size=size) * tolerance


def draw_manufacturing_errors(params: ReducerParams) -> ManufacturingErrors:
    """The deviations of the reducer ``params`` describes: its ``[manufacturing]`` tolerances drawn with the
    specimen's ``[modification] error_seed`` (module docstring).  All zero with every tolerance 0."""
    mf = params.manufacturing
    seed = params.modification.error_seed
    s1, s2 = params.stage1, params.stage2
    N, Zp = s1.n_planets, s2.pins
    if mf.planet_runout_grade > 0:
        tol = iso1328_tolerances(s1.module, s1.module * s1.planet_teeth, mf.planet_runout_grade)
        rng = np.random.default_rng([int(seed), STREAMS["planet_runout"]])
        runout = 0.5 * (0.5 * tol.runout) * rng.uniform(0.0, 1.0, size=N)  # e = F_r / 2, F_r in [0, F_rT / 2]
        angle = rng.uniform(0.0, 2.0 * math.pi, size=N)
    else:
        runout, angle = np.zeros(N), np.zeros(N)
    rng_hole = _uniform(seed, "crank_hole", mf.crank_hole_position, 2 * N)
    hole_r, hole_t = rng_hole[:N], rng_hole[N:]
    hole_t = hole_t - hole_t.mean()
    phase = _uniform(seed, "crank_phase", math.radians(mf.crank_phase_arcmin / 60.0), N)
    phase = phase - phase.mean()
    rho = _uniform(seed, "pin_radius", mf.pin_radius, Zp)
    rho = rho - rho.mean()
    pos = _uniform(seed, "pin_position", mf.pin_position, 2 * Zp)
    pin_r, pin_t = pos[:Zp] - pos[:Zp].mean(), pos[Zp:] - pos[Zp:].mean()

    def tup(a: np.ndarray) -> tuple[float, ...]:
        return tuple(float(v) for v in a)

    return ManufacturingErrors(tup(runout), tup(angle), tup(hole_r), tup(hole_t), tup(phase), tup(rho),
                               tup(pin_r), tup(pin_t))
