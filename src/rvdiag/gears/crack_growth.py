"""Growth of a tooth-root crack by Paris' law, and the sun tooth's root stress that drives it.

Paris' law (Paris & Erdogan 1963, J. Basic Eng. 85, 528-534):

    da/dN = C (Delta K)^m,   Delta K = Y Delta sigma sqrt(pi a),

a the crack depth, N the load cycles (one per mesh pass of the cracked tooth, :func:`rvdiag.gears.wear.mesh_passes`),
Delta sigma the root stress range (the tooth is loaded from zero: R = 0), Y = 1.12 the edge-crack geometry factor
(Tada, Paris & Irwin, "The Stress Analysis of Cracks Handbook", a shallow edge crack in a half plane).  Constants:
BS 7910:2013's simplified law for steels in air (its Table 8.2 / clause 8.2.3.3: A = 5.21e-13 with da/dN in
mm/cycle and Delta K in N/mm^1.5, m = 3, the mean + 2 SD design curve), which in m/cycle and MPa sqrt(m) is
C = 5.21e-16 * 31.62^3 = 1.65e-11 and m = 3, with its conservative threshold Delta K_0 = 63 N/mm^1.5 = 2.0 MPa sqrt(m)
below which a crack does not grow.  Gear steels (case-hardened 18CrNiMo7-6, 42CrMo4) are reported inside this
design curve; it is a bound, not a fit to one steel.

With constant Y and m != 2 the law integrates in closed form (a^(1 - m/2) linear in N):

    a(N)^(1 - m/2) = a0^(1 - m/2) + (1 - m/2) C (Y Delta sigma sqrt(pi))^m N,

which for m > 2 reaches infinity after a finite number of cycles (the unstable growth that breaks the tooth).

Root stress: Lewis' cantilever with the whole mesh force at the tip, sigma = 6 F_t h / (b s^2), F_t the force's
component normal to the tooth's centre line (taken as the mesh force times the cosine of the pressure angle), h the
height from the root circle to the tip, s the chord at the root circle, b the face width, times a fillet stress
concentration K_f (Dolan & Broghamer 1942 give 1.4-1.8 for 20 deg teeth; 1.6 used).  On the RV-20E's sun at its
rated 167 N m this is about 27 MPa, so Delta K at a 0.1 mm crack is about 0.5 MPa sqrt(m), well under the 2 MPa
sqrt(m) threshold: by this law a sun root crack does not grow at the joint's own load until it is over about 1 mm
deep (:func:`threshold_crack_depth`).
"""

from __future__ import annotations

import math

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.gears.geometry import GearPair

#: BS 7910:2013 simplified Paris law for steels in air, in m/cycle and MPa sqrt(m) (module docstring)
PARIS_C = 1.65e-11
PARIS_M = 3.0
DELTA_K_THRESHOLD = 2.0
#: edge-crack geometry factor and fillet stress concentration (module docstring)
GEOMETRY_FACTOR = 1.12
FILLET_CONCENTRATION = 1.6


def sun_root_stress(params, load_Nm: float) -> float:
    """Lewis root stress (Pa, with the fillet concentration) of a sun tooth carrying the whole mesh force at its tip
    at output torque ``load_Nm``."""
    from rvdiag.gears.wear import mesh_force

    pair = GearPair.sun_planet(params)
    sun = pair.driver
    s = 2.0 * sun.root_radius * math.sin(sun.root_half_angle)
    h = sun.tip_radius - sun.root_radius
    f_t = mesh_force(params, load_Nm) * math.cos(sun.pressure_angle)
    return FILLET_CONCENTRATION * 6.0 * f_t * h / (sun.face_width * s * s)


def stress_intensity_range(a, delta_sigma_MPa: float, y: float = GEOMETRY_FACTOR):
    """Delta K (MPa sqrt(m)) of an edge crack of depth ``a`` (m) under the stress range ``delta_sigma_MPa``."""
    return y * float(delta_sigma_MPa) * np.sqrt(np.pi * np.asarray(a, dtype=float))


def threshold_crack_depth(delta_sigma_MPa: float, y: float = GEOMETRY_FACTOR,
                          delta_k_th: float = DELTA_K_THRESHOLD) -> float:
    """The crack depth (m) below which Delta K is under the threshold and the crack does not grow."""
    return (delta_k_th / (y * float(delta_sigma_MPa))) ** 2 / math.pi


def paris_crack_depth(a0: float, cycles, delta_sigma_MPa: float, *, c: float = PARIS_C, m: float = PARIS_M,
                      y: float = GEOMETRY_FACTOR, delta_k_th: float = DELTA_K_THRESHOLD):
    """Crack depth (m) after ``cycles`` load cycles from ``a0`` (m) by Paris' law (closed form, module docstring);
    ``inf`` once the growth has become unstable; ``a0`` throughout if Delta K at ``a0`` is below the threshold.

    >>> a = paris_crack_depth(1e-4, [0.0, 1e4], 300.0)
    >>> bool(abs(a[0] - 1e-4) < 1e-12 and a[1] > 1.1e-4)
    True
    """
    if not (a0 > 0 and delta_sigma_MPa >= 0 and m != 2):
        raise ParameterError("a0 must be > 0, the stress range >= 0 and m != 2")
    n = np.asarray(cycles, dtype=float)
    if stress_intensity_range(a0, delta_sigma_MPa, y) < delta_k_th:
        return np.full(n.shape, float(a0))
    e = 1.0 - m / 2.0
    base = a0 ** e + e * c * (y * delta_sigma_MPa * math.sqrt(math.pi)) ** m * n
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(base > 0, np.abs(base) ** (1.0 / e), np.inf)


def paris_cycles(a0: float, a1: float, delta_sigma_MPa: float, *, c: float = PARIS_C, m: float = PARIS_M,
                 y: float = GEOMETRY_FACTOR) -> float:
    """Load cycles for a crack to grow from ``a0`` to ``a1`` (m) by Paris' law (no threshold)."""
    e = 1.0 - m / 2.0
    return (a1 ** e - a0 ** e) / (e * c * (y * delta_sigma_MPa * math.sqrt(math.pi)) ** m)


def paris_stress_for_cycles(a0: float, a1: float, cycles: float, *, c: float = PARIS_C, m: float = PARIS_M,
                            y: float = GEOMETRY_FACTOR) -> float:
    """The stress range (MPa) under which a crack grows from ``a0`` to ``a1`` in ``cycles`` (inverse of
    :func:`paris_cycles`)."""
    e = 1.0 - m / 2.0
    return ((a1 ** e - a0 ** e) / (e * c * cycles)) ** (1.0 / m) / (y * math.sqrt(math.pi))
