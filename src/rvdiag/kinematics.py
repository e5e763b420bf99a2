"""Characteristic frequencies of an RV reducer (pin wheel fixed, sun input, carrier output).

All follow from rigid-body kinematics of the two stages; see the Nabtesco RD-E description and the motor-current
study of Li, Zhao et al. 2024 (docs/references.md), Table 2 and the Table 3 test vector they reproduce.

With f_s the sun (input) speed and f_H = f_s / i the carrier (output) speed, i = 1 + (Z2/Z1) Zp:

- motor electrical frequency  f_e = p f_s                      (p pole pairs)
- crank shaft, absolute       f2 = Zc f_H  (= ``|crank relative to carrier|`` - f_H = Zp f_H - f_H)
- stage-1 mesh                f_sp = Z1 (f_s - f_H)
- stage-2 mesh                f_cs = Zc Zp f_H
- local sun-tooth fault       N (f_s - f_H)                   (N planets, each meets the tooth once)
- local planet-tooth fault    f_sp / Z2                        (a planet meshes only with the sun)
- local cycloid-lobe fault    Zp f_H  (eccentric sweeps the disc at Zp f_H in the carrier frame)
- local pin fault             Zc f_H  (eccentric sweeps the fixed pins at Zc f_H)
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from rvdiag.errors import ParameterError
from rvdiag.params.schema import ReducerParams
from rvdiag.validation import positive

FREQUENCY_KEYS = (
    "fe", "f1", "f2", "f3", "fsp", "fcs",
    "f_sun_fault", "f_planet_fault", "f_cycloid_fault", "f_pin_fault",
)


@dataclass(frozen=True)
class CharacteristicFrequencies:
    """Characteristic frequencies in Hz; field names are the ``rvdiag freqs --json`` keys."""

    fe: float
    f1: float
    f2: float
    f3: float
    fsp: float
    fcs: float
    f_sun_fault: float
    f_planet_fault: float
    f_cycloid_fault: float
    f_pin_fault: float

    def as_dict(self) -> dict[str, float]:
        """Plain dict in the order of :data:`FREQUENCY_KEYS`."""
        return asdict(self)


def sun_speed_hz(
    params: ReducerParams,
    input_speed_rpm: float | None = None,
    output_speed_deg_s: float | None = None,
) -> float:
    """Sun (input) rotation frequency in Hz from exactly one of the input or output speed."""
    if (input_speed_rpm is None) == (output_speed_deg_s is None):
        raise ParameterError("give exactly one of input speed (rpm) or output speed (deg/s)")
    if input_speed_rpm is not None:
        return positive(input_speed_rpm, "input speed", unit=" rpm") / 60.0
    return positive(output_speed_deg_s, "output speed", unit=" deg/s") / 360.0 * params.ratio


def output_speed_from_input_hz(params: ReducerParams, input_hz: float) -> float:
    """Output (carrier) speed in deg/s of a sun (input) rotation frequency ``input_hz``: f_H = f_s / i, the inverse
    of :func:`sun_speed_hz`.  Every speed estimate that reads an input-shaft frequency (a vibration mesh line,
    :func:`rvdiag.io.angles.input_revolutions`; a motor current's supply line,
    :func:`rvdiag.motor.lines.output_speed_from_fe`) turns it into the output speed here."""
    return float(input_hz) * 360.0 / params.ratio


def characteristic_frequencies(
    params: ReducerParams,
    input_speed_rpm: float | None = None,
    output_speed_deg_s: float | None = None,
    pole_pairs: int | None = None,
) -> CharacteristicFrequencies:
    """Characteristic and fault frequencies (Hz) of the reducer at one operating point.

    Examples
    --------
    Table 3 of Li, Zhao et al. 2024 (output 30 deg/s, p = 5):

    >>> from rvdiag.params import ReducerParams
    >>> f = characteristic_frequencies(ReducerParams.default(), output_speed_deg_s=30.0)
    >>> round(f.fe, 2), round(f.f1, 2), round(f.f2, 2), round(f.f3, 3), round(f.fsp, 1), round(f.fcs, 1)
    (50.42, 10.08, 3.25, 0.083, 110.0, 130.0)
    """
    s1, s2 = params.stage1, params.stage2
    p = params.operation.motor_pole_pairs if pole_pairs is None else int(pole_pairs)
    if p <= 0:
        raise ParameterError(f"pole pairs must be > 0, got {p}")
    fs = sun_speed_hz(params, input_speed_rpm, output_speed_deg_s)
    fh = fs / params.ratio
    f_rel = fs - fh
    fsp = s1.sun_teeth * f_rel
    return CharacteristicFrequencies(
        fe=p * fs,
        f1=fs,
        f2=s2.cycloid_lobes * fh,
        f3=fh,
        fsp=fsp,
        fcs=s2.cycloid_lobes * s2.pins * fh,
        f_sun_fault=s1.n_planets * f_rel,
        f_planet_fault=fsp / s1.planet_teeth,
        f_cycloid_fault=s2.pins * fh,
        f_pin_fault=s2.cycloid_lobes * fh,
    )
