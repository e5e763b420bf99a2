"""Model and integrator settings that are not reducer parameters: :class:`ModelSettings` (one purpose).

Its fields are documented in docs/model.md section 7 (sub-steps, method, segments, cache) and section 6
(sensor); they are picklable and recorded with every simulation.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from rvdiag.errors import ParameterError


@dataclass(frozen=True)
class ModelSettings:
    """Model and integrator settings that are not reducer parameters (all picklable, all recorded).

    Parameters
    ----------
    substeps : int
        Runge-Kutta steps per output sample.  The stiffest mode of the RV-20E is near 34 kHz (crank
        shafts); RK4 is stable for ``omega h < 2.78``, so at 48 kHz at least 2 are needed.  Accuracy,
        not stability, sets the default 9: the output stays within 1e-3 (relative L2) of scipy's DOP853
        at rtol 1e-9 over 0.05 s at 48 kHz with the default method (figures under ``method``;
        docs/model.md section 7, tests/test_integrator.py); at other rates keep ``fs * substeps`` near
        430 kHz.
        A sample is further cut at the mesh table's kinks (:func:`rvdiag.dynamics.packing.table_events`), so a
        step may be shorter than ``1 / (fs substeps)``.
    method : str
        ``"rk38"`` (default): Kutta's 3/8 rule, the pin geometry exact at its three stage times per step;
        ``"rk4"``: classical RK4, stage times t, t + h/2, t + h (pin geometry exact three times per sample,
        interpolated in between; ~7 % faster).  Both on the same step grid.  With the tooth-pair contacts
        (pairs that touch and part as their separations are crossed, docs/model.md section 3) the 3/8 rule
        stays within 1e-3 of DOP853 at 9 sub-steps from 45 deg/s to 4500 rpm (6.2e-4 at 45 deg/s 100 N m,
        2.7e-4 at 1000 rpm 167 N m, 4.2e-4 at 3000 rpm and 7.3e-4 at 4500 rpm 50 N m) and RK4 does not
        above ~2500 rpm (9.0e-4, 1.3e-3, 2.2e-3 at 1000, 3000, 4500 rpm); before the tooth-pair contacts RK4 was
        the default (6.0e-4 to 7.3e-4).  Higher-order (Butcher 6, Verner 6(5), DOP853 fixed-step) and
        low-dispersion schemes (Berland et al. 2006 RK4-6) were measured and do not do better per right-hand
        side on this non-smooth model (docs/model.md section 7).
    transient_s : float
        Simulated time discarded before output starts (start-up transient), s.
    segment_s : float
        ``0`` (default): the record is one continuous integration.  ``> 0``: the record is cut into
        segments of this length (s), each integrated from its own static start ``transient_s`` ahead of
        it, so that the segments are independent and can run at once (``simulate(workers=...)``,
        :mod:`rvdiag.dynamics.segments`).  The damped model forgets its start: with the default 0.1 s
        run-in a segment differs from the continuous run by ~1e-7 (relative L2), far below the
        integrator's 1e-3.  The output depends on ``segment_s``, never on the number of workers.
        Needs damping on and ``transient_s > 0``.
    sensor_point_m : tuple of 2 floats or None
        Measurement point on the housing in the fixed frame (m); ``None`` puts it on the pin-wheel
        outer radius at angle 0.
    sensor_directions : tuple of (dx, dy)
        One output channel per direction (normalised); default x and y.
    excitation : bool
        ``False`` freezes every time-varying term (TVMS, contact geometry, disc unbalance) at t = 0:
        an autonomous, conservative-when-undamped system, used for energy and modal checks.
    damping : bool
        ``False`` sets every viscous damping coefficient to zero.
    coriolis : bool
        ``False`` drops the rotating-frame terms (Coriolis and centripetal of the vibratory motion).
    tvms_points : int
        Points of the uniform TVMS table over one relative sun revolution.
    chunk_samples : int
        Output samples computed per compiled call (memory stays flat; progress reported per chunk).
    max_displacement_m : float
        A vibratory displacement larger than this is taken as instability (growth without bound).
    max_rotation_rad : float
        A vibratory rotation larger than this is taken as instability (the small-rotation model is
        meaningless long before).
    electrical : bool
        ``True`` adds the servo motor's electrical side (``[motor]``: a PMSM under i_d = 0 vector control,
        its current loop, inverter dead time and encoder; docs/model.md section 10) and records its currents.
        ``simulate(signal="current" | "both")`` turns it on.  ``False`` (default): the speed loop acts on the
        rotor as an ideal torque source.
    """

    substeps: int = 9
    transient_s: float = 0.1
    segment_s: float = 0.0
    method: str = "rk38"
    sensor_point_m: tuple[float, float] | None = None
    sensor_directions: tuple[tuple[float, float], ...] = ((1.0, 0.0), (0.0, 1.0))
    excitation: bool = True
    damping: bool = True
    coriolis: bool = True
    tvms_points: int = 11 * 360
    chunk_samples: int = 48000
    max_displacement_m: float = 1.0e-2
    max_rotation_rad: float = 0.5
    electrical: bool = False

    def __post_init__(self) -> None:
        if int(self.substeps) != self.substeps or self.substeps < 1:
            raise ParameterError(f"substeps must be a whole number >= 1, got {self.substeps!r}")
        if self.method not in ("rk4", "rk38"):
            raise ParameterError(f"method must be 'rk4' or 'rk38', got {self.method!r}")
        if not (math.isfinite(self.transient_s) and self.transient_s >= 0):
            raise ParameterError(f"transient_s must be >= 0, got {self.transient_s!r}")
        if not (math.isfinite(self.segment_s) and self.segment_s >= 0):
            raise ParameterError(f"segment_s must be >= 0, got {self.segment_s!r}")
        if self.segment_s > 0 and not (self.damping and self.transient_s > 0):
            raise ParameterError("segment_s > 0 needs damping on and transient_s > 0: a segment starts "
                                 "from rest and must forget that start before it is recorded")
        if len(self.sensor_directions) < 1:
            raise ParameterError("give at least one sensor direction")
        for d in self.sensor_directions:
            if len(d) != 2 or not math.hypot(*d) > 0:
                raise ParameterError(f"sensor direction {d!r} must be a non-zero (dx, dy) pair")
        if self.sensor_point_m is not None and len(self.sensor_point_m) != 2:
            raise ParameterError("sensor_point_m must be an (x, y) pair in metres")
        if self.tvms_points < 16 or self.chunk_samples < 1:
            raise ParameterError("tvms_points must be >= 16 and chunk_samples >= 1")
        if not (self.max_displacement_m > 0 and self.max_rotation_rad > 0):
            raise ParameterError("max_displacement_m and max_rotation_rad must be > 0")

    def to_dict(self) -> dict:
        """Plain dict (JSON-able) of every setting."""
        d = asdict(self)
        d["sensor_directions"] = [list(x) for x in self.sensor_directions]
        if self.sensor_point_m is not None:
            d["sensor_point_m"] = list(self.sensor_point_m)
        return d
