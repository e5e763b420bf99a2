"""The planetary (first) stage of the RV reducer in the angle domain: a time-synchronous average per planet by
windowed vibration separation, the sideband asymmetry about the mesh order, and the phase demodulation of a mesh
harmonic (``rvdiag orders``: keys ``planets`` and ``modulation``; docs/orders.md).

Planet TSA (McFadden, "Window functions for the calculation of the time domain averages of the vibration of the
individual planet gears and sun gear in an epicyclic gearbox", J. Vib. Acoust. 116 (1994) 179-187; the technique
of McFadden, J. Sound Vib. 144 (1991) 163-172): a sensor fixed on the housing hears planet k's mesh best while
planet k passes it.  Planet k sits at carrier angle theta_H + 2 pi k / N (N planets; the model's planet 0 is on
the x axis at t = 0), so its angle from a sensor at angle phi_s is

    alpha_k(t) = theta_H(t) + 2 pi k / N - phi_s  (wrapped to (-pi, pi]),

and its window is w_k = cos^2(pi alpha_k / W) for |alpha_k| < W / 2, else 0, a Hann window of width W in carrier
angle centred on the passage (McFadden 1994's window family; W = 4 pi / N by default, twice the planet spacing,
so that the N windows add up to 1 at every instant: nothing is counted twice or lost).  In the RV reducer the
planets ride on the cranks, which turn relative to the carrier at Zp Omega, and mesh with the sun only (no
ring): planet k's teeth come into mesh as its crank turns, so its average tooth-mesh signal is the weighted
TSA on the crank angle theta_c (a revolution of theta_c is a revolution of every planet; the cranks are in phase),

    TSA_k(theta) = sum_m w_k(theta_m) x(theta_m) / sum_m w_k(theta_m),   theta_m = theta + 2 pi m,

McFadden's vibration separation (the windowed segments of each passage, averaged per planet tooth) with the
windowed passages assembled on the planet's own angle; the weighted mean is the equation above.  Each planet's TSA is rated with the
indicators of :func:`rvdiag.features.orders.condition_indicators` for the stage-1 mesh Z2 (the stage-2 mesh
Zc, on the same crank, counted as regular).

Sideband asymmetry (:func:`sideband_asymmetry`): amplitude modulation alone gives sidebands of equal height about
a mesh order; amplitude and phase modulation together make them unequal (Randall, "A new method of modeling
gear faults", J. Mech. Des. 104 (1982) 259-267), as does the planets' passing in an epicyclic stage (McFadden &
Smith, "An explanation for the asymmetry of the modulation sidebands about the tooth meshing frequency in
epicyclic gear vibration", Proc. IMechE C 199 (1985) 65-70).  On the sun shaft the modulation of a sun tooth
is its order N (it meets the N planets once per relative revolution), so the sidebands are m +- N.

Phase demodulation (:func:`phase_demodulation`; McFadden, "Detecting fatigue cracks in gears by amplitude and
phase demodulation of the meshing vibration", J. Vib. Acoust. Stress Reliab. Des. 108 (1986) 165-170): the TSA
is band-passed to the h-th mesh harmonic +- m/2 orders, the analytic signal z = x_b + j H{x_b} formed (one-sided
spectrum), and the phase modulation is phi(theta) = unwrap(arg z(theta)) - 2 pi h m theta (theta in
revolutions), less its mean (periodic over the revolution, h m being a whole order; a crack shows as a local
jump of the phase, the paper's finding).
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.features import orders as _o

#: the modulation indicators of :func:`modulation_indicators`
MODULATION_INDICATORS = {
    "sideband_asymmetry": "(A(m+s) - A(m-s)) / (A(m+s) + A(m-s)), first-order sidebands s about the mesh m, TSA",
    "sideband_asymmetry_db": "20 log10(A(m+s) / A(m-s))",
    "phase_pp": "peak-to-peak phase modulation of the mesh harmonic, rad",
    "phase_kurtosis": "normalised 4th moment of the phase modulation",
}


# --------------------------------------------------------------------------- planet windows
def planet_windows(carrier_revs, n_planets: int, sensor_angle_deg: float = 0.0,
                   width_deg: float | None = None) -> np.ndarray:
    """``(n_planets, samples)`` window weights of each planet at carrier angles ``carrier_revs`` (revolutions,
    planet 0 at angle 0 at carrier angle 0): cos^2(pi alpha_k / W) within W / 2 of the sensor, else 0 (module
    docstring).  ``width_deg`` W defaults to twice the planet spacing, 720 / N deg, where the windows sum to 1."""
    N = int(n_planets)
    if N < 1:
        raise ParameterError(f"the stage needs at least one planet, got {n_planets}")
    W = math.radians(720.0 / N if width_deg is None else float(width_deg))
    if not (0.0 < W <= 2.0 * math.pi + 1e-12):
        raise ParameterError(f"the planet window must be wider than 0 and at most 360 deg, got {math.degrees(W):g}")
    r = np.asarray(carrier_revs, dtype=np.float64)
    out = np.empty((N, r.size))
    for k in range(N):
        a = 2.0 * math.pi * (r + k / N) - math.radians(float(sensor_angle_deg))
        a = (a + math.pi) % (2.0 * math.pi) - math.pi
        out[k] = np.where(np.abs(a) < 0.5 * W, np.cos(math.pi * a / W) ** 2, 0.0)
    return out


def _passes(carrier_revs: np.ndarray, k: int, N: int, sensor_angle_deg: float) -> int:
    """Times planet k passes the sensor (its angle from the sensor crosses 0) in the record."""
    a = np.asarray(carrier_revs) + k / N - float(sensor_angle_deg) / 360.0
    return int(np.floor(a[-1]) - np.floor(a[0]))


def planet_tsa(x, fs: float, input_revs, params=None, *, sensor_angle_deg: float = 0.0,
               width_deg: float | None = None, samples_per_rev: int | None = None, shaft_orders: int = 2) -> dict:
    """The averaged tooth-mesh signal of each stage-1 planet (module docstring): ``x`` at ``fs`` with the input
    (sun) shaft's revolutions ``input_revs`` per sample (:func:`rvdiag.io.angles.input_revolutions`).

    Returns ``{"n_planets", "mesh_order" (Z2), "extra_meshes" ((Zc,)), "samples_per_rev", "n_revolutions" (crank
    revolutions averaged), "planets": [{"planet", "passes", "weight_revs", "tsa", "indicators"}, ...]}``;
    ``weight_revs`` is the planet's summed window over the record in revolutions (its effective number of
    averages); a planet with less than one revolution's weight has ``tsa`` and ``indicators`` None."""
    p = _o._params(params)
    N, Z2, Zc, Zp = p.stage1.n_planets, p.stage1.planet_teeth, p.stage2.cycloid_lobes, p.stage2.pins
    r_in = np.asarray(input_revs, dtype=np.float64)
    r_crank = r_in * (Zp / p.ratio)  # the cranks (planets) relative to the carrier
    speed = (r_crank[-1] - r_crank[0]) * fs / max(r_crank.size - 1, 1)
    spr = int(samples_per_rev or _o.default_samples_per_rev(fs, speed, max(Z2, Zc)))
    xa = _o.resample_to_angle(x, fs, r_crank, spr)
    n_rev = xa.size // spr
    first = math.ceil(r_crank[0] - 1e-9)
    theta = first + np.arange(n_rev * spr) / spr  # crank revolutions on the grid
    w = planet_windows(theta / Zp, N, sensor_angle_deg, width_deg)
    X = xa.reshape(n_rev, spr)
    planets = []
    for k in range(N):
        Wk = w[k].reshape(n_rev, spr)
        weight = float(Wk.sum() / spr)
        entry = {"planet": k, "passes": _passes(theta / Zp, k, N, sensor_angle_deg), "weight_revs": weight,
                 "tsa": None, "indicators": None}
        if weight >= 1.0 and np.all(Wk.sum(axis=0) > 0):
            t = (Wk * X).sum(axis=0) / Wk.sum(axis=0)
            entry["tsa"] = t
            entry["indicators"] = _o.condition_indicators(t, Z2, shaft_orders, extra_meshes=(Zc,))
        planets.append(entry)
    return {"n_planets": N, "mesh_order": Z2, "extra_meshes": (Zc,), "samples_per_rev": spr,
            "n_revolutions": n_rev, "planets": planets}


# --------------------------------------------------------------------------- modulation
def sideband_asymmetry(t, mesh: int, spacing: int, harmonic: int = 1) -> tuple[float, float]:
    """``((A_u - A_l) / (A_u + A_l), 20 log10(A_u / A_l))`` of the sidebands ``harmonic`` x ``mesh`` +- ``spacing``
    in the amplitude spectrum of the TSA ``t`` of one revolution (bin k = order k): 0 (and 0 dB) for amplitude
    modulation alone (Randall 1982; McFadden & Smith 1985)."""
    t = np.asarray(t, dtype=np.float64).ravel()
    A = np.abs(np.fft.rfft(t - t.mean()))
    c = int(harmonic) * int(mesh)
    if not (int(spacing) >= 1 and c - spacing >= 1 and c + spacing < A.size):
        raise ParameterError(f"the sidebands {c} +- {spacing} lie outside the TSA's orders 1..{A.size - 1}")
    lo, hi = float(A[c - spacing]), float(A[c + spacing])
    if lo + hi <= 0:
        return 0.0, 0.0
    db = 20.0 * math.log10(hi / lo) if lo > 0 and hi > 0 else math.copysign(math.inf, hi - lo)
    return (hi - lo) / (hi + lo), db


def phase_demodulation(t, mesh: int, harmonic: int = 1, half_band: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(phase modulation (rad), amplitude envelope)`` over one revolution of the TSA ``t``, of its
    ``harmonic``-th mesh harmonic band-passed to +- ``half_band`` orders (default floor(mesh / 2)): McFadden
    (1986), module docstring.  The phase has its mean removed."""
    t = np.asarray(t, dtype=np.float64).ravel()
    n = t.size
    c = int(harmonic) * int(mesh)
    hw = max(1, int(mesh) // 2) if half_band is None else int(half_band)
    if not (c - hw >= 1 and c + hw < n // 2):
        raise ParameterError(f"the band {c} +- {hw} orders does not fit the TSA's {n // 2 - 1} orders")
    F = np.fft.fft(t)
    k = np.fft.fftfreq(n, 1.0 / n)
    z = np.fft.ifft(np.where((k >= c - hw) & (k <= c + hw), 2.0 * F, 0.0))
    ph = np.unwrap(np.angle(z)) - 2.0 * np.pi * c * np.arange(n) / n  # periodic: c is a whole order
    return ph - ph.mean(), np.abs(z)


def modulation_indicators(t, mesh: int, spacing: int, harmonic: int = 1) -> dict[str, float]:
    """:data:`MODULATION_INDICATORS` of the TSA ``t``: the sideband asymmetry about the ``harmonic``-th mesh harmonic
    at +- ``spacing`` orders and the peak-to-peak and normalised kurtosis of the phase modulation of that
    harmonic."""
    asym, db = sideband_asymmetry(t, mesh, spacing, harmonic)
    ph, _ = phase_demodulation(t, mesh, harmonic)
    return {"sideband_asymmetry": asym, "sideband_asymmetry_db": db, "phase_pp": float(ph.max() - ph.min()),
            "phase_kurtosis": _o.normalised_moment(ph, 4)}


def sideband_spacing(shaft: str, params=None) -> int:
    """The order of the modulation about the mesh of ``shaft``: N (planets) on the sun shaft, where a sun tooth
    meets each planet once per relative revolution; 1 (the shaft itself) on the others."""
    p = _o._params(params)
    return int(p.stage1.n_planets) if _o._check_shaft(shaft) == "sun" else 1


__all__: Sequence[str] = ("MODULATION_INDICATORS", "planet_windows", "planet_tsa", "sideband_asymmetry",
                          "phase_demodulation", "modulation_indicators", "sideband_spacing")
