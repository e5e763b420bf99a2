"""What a record is: reading it as ``rvdiag dataset from-files`` reads a file (:func:`read_record`), its speed and
where it came from (:func:`record_speed`), whether it is flat (:func:`flat_reason`), whether it looks like the
reducer the model knows (:func:`recognition`), and a state's name (:func:`state_name`).  One home below the
diagnosis of a classifier (:mod:`rvdiag.workflows.diagnosis`) and of a monitor (:mod:`rvdiag.monitoring`)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.io.readers import MeasuredSignal

#: groups of a file name's ``--meta-regex`` read as another name: the load in N m, ``load_Nm`` (the column a baseline
#: is matched by), may be spelled ``load`` as in a store's file names
LOAD_GROUPS = {"load": "load_Nm"}
#: ``--meta`` names that give the speed for the indicators: output deg/s, input rev/min.
SPEED_META = ("output_speed_deg_s", "input_speed_rpm")


@dataclass
class Record(MeasuredSignal):
    """One channel of a measured file (:class:`rvdiag.io.readers.MeasuredSignal`) with what the reading options
    say of it: ``metadata``, the groups of ``meta_regex`` in its name (numbers where they parse; a group ``load`` is
    the load ``load_Nm``, :data:`LOAD_GROUPS`), and ``angle``, the angle source
    (:class:`rvdiag.io.angles.AngleSpec`, or None) that gives its speed, as ``dataset from-files`` reads them."""

    metadata: dict[str, Any] = field(default_factory=dict)
    angle: Any = None


def read_record(path, *, channel: str | None = None, fs: float | None = None, angle_channel: str | None = None,
                tacho_channel: str | None = None, ppr: int | None = None, meta_regex: str | None = None) -> Record:
    """Read one record as ``rvdiag dataset from-files`` reads a file of a store.

    Parameters
    ----------
    path : path of the file (CSV/CSV.gz, MAT, NPY, NPZ, WAV, TDMS; :func:`rvdiag.io.read_signal`)
    channel : regex matching exactly one channel (None: the file's only one)
    fs : sampling rate in Hz (None: the file's)
    angle_channel, tacho_channel, ppr : the input shaft's angle or tachometer channel and its pulses (counts) per
        revolution (:class:`rvdiag.io.angles.AngleSpec`), from which :func:`record_speed` measures the speed
    meta_regex : regex whose named groups, searched in the file name, give metadata (``speed_dps``, ``rpm``,
        ``load`` or ``load_Nm``, ...); a group ``rpm`` or ``speed_dps`` states the speed

    Returns
    -------
    Record

    Raises
    ------
    DataFileError, ParameterError
        An unreadable file, no such channel, a name that does not match ``meta_regex``, two angle sources.
    """
    from rvdiag.io import read_signal
    from rvdiag.io.angles import SPEED_GROUPS, AngleSpec

    path = Path(path)
    sig = read_signal(path, channel_regex=channel, fs=fs)
    metadata = name_metadata(meta_regex, path.name, where=str(path))
    speed_groups = bool(set(SPEED_GROUPS) & set(metadata))
    angle = None
    if angle_channel is not None or tacho_channel is not None or ppr is not None or speed_groups:
        angle = AngleSpec(angle_channel=angle_channel, tacho_channel=tacho_channel, ppr=ppr,
                          meta_regex=meta_regex if speed_groups and angle_channel is None and tacho_channel is None
                          else None).validate()
    return Record(data=sig.data, fs=sig.fs, channel=sig.channel, path=sig.path, format=sig.format,
                  scalars=sig.scalars, attrs=sig.attrs, metadata=metadata, angle=angle)


def name_metadata(meta_regex: str | None, name: str, where: str | None = None) -> dict[str, Any]:
    """The values the named groups of ``meta_regex`` read from a file ``name``: numbers as floats, other text as
    it is, a group ``load`` as the column ``load_Nm`` (:data:`LOAD_GROUPS`), empty groups left out; ``{}`` without
    a regular expression.  The one reading of ``--meta-regex`` on a record's name (``read_record``, the fleet's
    operating points).  :class:`ParameterError` for an invalid expression or two groups giving one column,
    :class:`DataFileError` for a name it does not match (``where`` names the file in the message, default
    ``name``)."""
    from rvdiag.errors import DataFileError

    if meta_regex is None:
        return {}
    try:
        pat = re.compile(meta_regex)
    except re.error as exc:
        raise ParameterError(f"invalid --meta-regex {meta_regex!r}: {exc}") from None
    m = pat.search(name)
    if m is None:
        raise DataFileError(f"{where or name}: the name does not match --meta-regex {meta_regex!r}")
    metadata: dict[str, Any] = {}
    for k, v in m.groupdict().items():
        if v in (None, ""):
            continue
        col = LOAD_GROUPS.get(k, k)
        if col in metadata:
            raise ParameterError(f"--meta-regex: the groups {k} and {col} both give {col!r}: keep one")
        try:
            metadata[col] = float(v)
        except ValueError:
            metadata[col] = v
    return metadata


def load_model(model_dir):
    """The model of a directory that ``rvdiag train`` wrote (card + estimator;
    :func:`rvdiag.models.persistence.load_model`): load it once and pass it to every record's diagnosis."""
    from rvdiag.models.persistence import load_model as _load

    return _load(model_dir)


def record_speed(sig, meta: dict[str, float] | None = None, params=None) -> dict:
    """The record's output speed and where it came from: ``--output-speed`` / ``--meta output_speed_deg_s=...``
    (or ``input_speed_rpm=...``), else the speed a simulated record states, else the stage-1 mesh peak
    (:func:`rvdiag.io.angles.input_revolutions`), accepted only when the record's mesh lines confirm it
    (:func:`rvdiag.features.mesh_lines.confirm_speed`: the cycloid-pin mesh line with a second line of its family,
    and no line at half or a third of it, where a harmonic would be read as the mesh).

    Returns ``{"output_speed_deg_s", "source", "stated", "detail", "input_revs"}``, with ``output_speed_deg_s`` None
    and ``error`` the reason when the speed is unknown (no sampling rate, an unconfirmed estimate)."""
    from rvdiag.errors import RvdiagError
    from rvdiag.features.mesh_lines import confirm_speed
    from rvdiag.io.angles import AngleSpec, input_revolutions
    from rvdiag.params import ReducerParams

    meta = meta or {}
    p = params or ReducerParams.default()
    out_speed, in_speed = meta.get(SPEED_META[0]), meta.get(SPEED_META[1])
    if out_speed is not None and in_speed is not None:
        in_speed = None  # the output speed is the one a library records
    unknown = {"output_speed_deg_s": None, "source": None, "stated": False, "input_revs": None}
    try:
        if not sig.fs:
            raise ParameterError("the file states no sampling rate: give --fs")
        spec = getattr(sig, "angle", None)
        if spec is None or out_speed is not None or in_speed is not None:
            spec = AngleSpec(output_speed_deg_s=out_speed, input_speed_rpm=in_speed)
        got = input_revolutions(sig, spec, p)
    except RvdiagError as exc:
        return {**unknown, "error": str(exc)}
    speed = float(got.rev_per_s) * 360.0 / p.ratio
    detail = got.detail
    if out_speed is not None or in_speed is not None:
        detail = f"--meta {SPEED_META[0] if out_speed is not None else SPEED_META[1]}=" \
                 f"{out_speed if out_speed is not None else in_speed:g}"
    if got.source == "estimate":
        check = confirm_speed(sig.data, float(sig.fs), p, speed)
        if not check["confirmed"]:
            return {**unknown, "estimate": check,
                    "error": f"speed unknown: the stage-1 mesh peak gives {speed:.4g} deg/s, which the record's "
                             f"mesh lines do not confirm ({check['reason']}); give --output-speed"}
        detail += f", confirmed by the cycloid-pin mesh line at {check['stage2_peak_hz']:.5g} Hz"
    return {"output_speed_deg_s": speed, "source": got.source, "stated": got.source != "estimate", "detail": detail,
            "input_revs": got.revs}


#: a window is flat when its standard deviation is at most this fraction of the record's largest |value| (or 0)
FLAT_FRACTION = 1e-9


def fault_name(c: str) -> str | None:
    """``broken tooth`` for ``T2``: the words for a state of :data:`rvdiag.gears.faults.FAULT_KINDS`; None for other
    classes."""
    from rvdiag.gears.faults import FAULT_KINDS as STATES

    names = {"healthy": "healthy", "broken": "broken tooth", "wear": "wear", "crack": "root crack",
             "broken+wear": "broken tooth + wear", "broken+wear+crack": "broken tooth + wear + root crack"}
    kind = STATES.get(str(c))
    return None if kind is None else names.get(kind, kind)


def state_name(c: str) -> str:
    """``T2 (broken tooth)``: a state with its fault's name (:data:`rvdiag.gears.faults.STATES`); other classes as
    they are."""
    name = fault_name(c)
    return str(c) if name is None else f"{c} ({name})"


def flat_reason(x: np.ndarray, L: int) -> str | None:
    """Why the record is flat (a constant or dead signal), or None: every point equal, or most windows of ``L``
    points without variation (:data:`FLAT_FRACTION`)."""
    x = np.asarray(x, dtype=np.float64)
    if not np.all(np.isfinite(x)):
        return "the signal holds non-finite values"
    if np.ptp(x) == 0:
        return f"the signal is constant ({x[0]:g} at every point): a dead or disconnected sensor?"
    k = x.size // L
    if k:
        W = x[: k * L].reshape(k, L)
        flat = W.std(axis=1) <= FLAT_FRACTION * np.max(np.abs(x))
        if flat.mean() > 0.5:
            return f"{int(flat.sum())} of {k} windows are flat (no variation): a dead or saturated sensor?"
    return None


def recognition(loaded, x: np.ndarray, fs: float | None, res: dict, speed: dict, is_current: bool) -> dict:
    """Does the record look like the reducer the model knows?  ``{"recognised", "reason", "checks"}``, the reason
    the first failed check: a flat signal (:func:`flat_reason`); no mesh line at a stated speed
    (:func:`rvdiag.features.mesh_lines.mesh_lines`, vibration models trained on a simulated reducer library);
    windows far outside the training distribution (:mod:`rvdiag.models.novelty`)."""
    from rvdiag.features.mesh_lines import mesh_lines
    from rvdiag.models.novelty import RECORD_SHARE
    from rvdiag.params import ReducerParams

    checks: dict = {"flat": flat_reason(x, loaded.input_length)}
    if checks["flat"]:
        return {"recognised": False, "reason": checks["flat"], "checks": checks}
    reducer = (loaded.card.get("training_store") or {}).get("kind") == "simulated" and not is_current
    if reducer and fs and speed.get("stated"):
        lines = mesh_lines(x, fs, ReducerParams.default(), speed["output_speed_deg_s"])
        checks["mesh_lines"] = lines
        if not lines["present"]:
            return {"recognised": False, "checks": checks,
                    "reason": f"no mesh line at the stated speed {speed['output_speed_deg_s']:.4g} deg/s: neither "
                              f"the stage-1 mesh ({lines['stage1']['hz']:.5g} Hz) nor the cycloid-pin mesh "
                              f"({lines['stage2']['hz']:.5g} Hz) stands {lines['threshold_db']:g} dB above its floor"}
    ood = res.get("novelty")
    if ood is not None:
        checks["novelty"] = {k: v for k, v in ood.items() if k != "distances"}
        if ood["share_beyond"] > RECORD_SHARE:
            return {"recognised": False, "checks": checks,
                    "reason": f"{100 * ood['share_beyond']:.0f} % of the windows lie far outside the training data "
                              f"(Mahalanobis distance of the model's features above {ood['threshold']:.4g}, which "
                              f"{100 * ood['rate']:g} % of held-out training windows exceed)"}
    return {"recognised": True, "reason": None, "checks": checks}
