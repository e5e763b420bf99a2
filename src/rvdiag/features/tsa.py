"""Angle-domain feature sets: gear condition indicators of the TSA (``tsa-ci``) and order-spectrum bands
(``orders``), on :mod:`rvdiag.features.orders`.

Each window is resampled to angle at a constant speed (a window is short), either the ``output_speed_deg_s``
parameter or, with ``speed_column`` set, each window's own speed from a metadata column appended to ``X``
(:mod:`rvdiag.features.combine`): a column named ``*_deg_s`` holds the output speed in deg/s (a library store's
``output_speed_deg_s``), one named ``*_rpm`` the input (motor) speed in rev/min.  A window must hold at least one
whole revolution of the chosen shaft (``sun`` at 45 deg/s: 15 rev/s, so 3200 points at 48 kHz).
"""

from __future__ import annotations

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.features import orders as _o
from rvdiag.features._base import SignalTransformer
from rvdiag.validation import positive

_CI = tuple(_o.INDICATORS)
#: the median-tooth indicators of :func:`tooth_indicators` (``TSAIndicatorFeatures(median_tooth=True)``)
_TOOTH = ("median_tooth_rms_ratio", "tooth_deviation_trimmed")
#: indicators that may be negative: never log10
_SIGNED = ("sideband_asymmetry", "sideband_asymmetry_db")


def shaft_hz_from_column(shaft: str, column: str, value: float, params=None) -> float:
    """Rotation frequency (Hz) of ``shaft`` from a speed metadata column's value: a column named ``*_rpm`` holds
    the input (motor) speed in rev/min, any other (``*_deg_s``) the output speed in deg/s."""
    if str(column).endswith("_rpm"):
        return _o.shaft_frequency(shaft, params, input_speed_rpm=float(value))
    return _o.shaft_frequency(shaft, params, output_speed_deg_s=float(value))


def check_speed_column(column) -> str:
    """``column`` if it names a speed metadata column (ending in ``_deg_s`` or ``_rpm``), else ParameterError."""
    if not (isinstance(column, str) and column.endswith(("_rpm", "_deg_s"))):
        raise ParameterError(f"speed_column must name a metadata column ending in _deg_s (output speed) "
                             f"or _rpm (input speed), got {column!r}")
    return column


def tooth_indicators(t, mesh: int, trim: int) -> dict:
    """``median_tooth_rms_ratio`` rms(M) / rms(t) and ``tooth_deviation_trimmed`` (the mean square deviation of
    the ``mesh - trim`` closest periods from M) / mean(M^2), with M the median tooth of the TSA ``t``
    (:func:`rvdiag.features.orders.median_tooth`, ``mesh`` periods per revolution)."""
    mt = _o.median_tooth(t, mesh, trim)
    M = mt["median"]
    pm = float(np.mean(M**2))
    rt = float(np.std(t))
    return {"median_tooth_rms_ratio": float(np.std(M)) / rt if rt > 0 else 0.0,
            "tooth_deviation_trimmed": mt["trimmed_deviation"] / pm if pm > 0 else 0.0}


class _AngleFeatures(SignalTransformer):
    """Shared parameters and per-window resampling of the angle-domain feature sets."""

    _min_points = 16

    def input_metadata(self) -> tuple[str, ...]:
        """Metadata columns appended to each window of ``X``: ``(speed_column,)`` or none."""
        return () if self.speed_column is None else (str(self.speed_column),)

    def _shaft_hz(self, speed: float | None = None) -> float:
        if speed is None or self.speed_column is None:
            return _o.shaft_frequency(self.shaft, self.params, output_speed_deg_s=float(self.output_speed_deg_s))
        return shaft_hz_from_column(self.shaft, self.speed_column, speed, self.params)

    def _check_params(self, n_points: int, speed: float | None = None) -> None:
        _o._check_shaft(self.shaft)
        positive(self.fs, "fs", unit=" Hz")
        if self.speed_column is not None:
            check_speed_column(self.speed_column)
            n_points -= 1
            if speed is None:
                return
        f = self._shaft_hz(speed)
        revs = n_points * f / float(self.fs)
        if revs < 1:
            raise ParameterError(f"windows of {n_points} points hold {revs:.3g} revolutions of the {self.shaft} shaft "
                                 f"({f:.4g} Hz at fs {self.fs:g}): at least one is needed (use windows of "
                                 f">= {int(np.ceil(self.fs / f))} points, or a faster shaft)")

    def _features(self, X):
        if self.speed_column is None:
            self._check_params(X.shape[1])
            return self._rows(X, self._shaft_hz())
        W, v = X[:, :-1], X[:, -1]
        if not np.all(v > 0):
            raise ParameterError(f"the speed column {self.speed_column!r} holds values <= 0")
        out = np.empty((X.shape[0], len(self._feature_names())))
        for value in np.unique(v):
            rows = v == value
            self._check_params(X.shape[1], float(value))
            out[rows] = self._rows(np.ascontiguousarray(W[rows]), self._shaft_hz(float(value)))
        return out

    def _resampled(self, x, f_hz):
        m = _o.mesh_order(self.shaft, self.params)
        spr = self.samples_per_rev or _o.default_samples_per_rev(self.fs, f_hz, m)
        revs = _o.angle_from_speed(x.size, float(self.fs), f_hz)
        return _o.resample_to_angle(x, float(self.fs), revs, spr), spr, m


class TSAIndicatorFeatures(_AngleFeatures):
    """Gear condition indicators of each window's TSA on one shaft (feature set ``tsa-ci``).

    The nine indicators of :func:`rvdiag.features.orders.condition_indicators` (FM0, FM4, NA4, NB4, M6A, M8A,
    energy ratio, sideband level factor, sideband index; formulas, sources and the signal each uses there and in
    docs/orders.md), log10 with ``log`` (they are ratios spanning decades).  Each window is one record: NA4 and
    NB4 are normalised by the window's own variance (a classifier sees windows one at a time).

    Parameters
    ----------
    fs : float
        Sampling rate, Hz.
    shaft : {"sun", "crank", "output"}
        The shaft whose revolutions are averaged (:data:`rvdiag.features.orders.SHAFTS`).
    output_speed_deg_s : float
        Output speed when ``speed_column`` is None.
    speed_column : str or None
        Metadata column of each window's speed (``*_deg_s`` output deg/s, ``*_rpm`` input rpm).
    samples_per_rev : int or None
        Angular samples per revolution (default :func:`~rvdiag.features.orders.default_samples_per_rev`).
    shaft_orders : int
        Shaft orders 1..n counted as regular meshing components.
    params : str or None
        Reducer parameter TOML (default the built-in RV-20E).
    log : bool
        log10 of the indicators (not of the sideband asymmetries, which may be negative).
    modulation : bool
        Append the modulation indicators of :mod:`rvdiag.features.planetary` (sideband asymmetry about the mesh,
        also in dB clipped to +-60 dB, and the peak-to-peak and kurtosis of the mesh's phase modulation;
        Randall 1982, McFadden & Smith 1985, McFadden 1986): feature set ``tsa-mod``.
    median_tooth : bool
        Append the median-tooth indicators (:func:`rvdiag.features.orders.median_tooth` over the shaft's mesh
        periods): ``median_tooth_rms_ratio`` rms(median tooth) / rms(TSA), the share of the TSA every tooth
        shares, and ``tooth_deviation_trimmed``, the periods' mean-square deviation from the median tooth (the
        2 N largest left out on the sun, N planets; 2 on the other shafts) over its mean square; log10 with
        ``log``.  Wear of every tooth raises the first and lowers the second; a broken tooth barely moves either
        (docs/monitoring.md, "Why these features").  Off by default: the ``tsa-ci`` set keeps its nine.
    """

    def __init__(self, fs: float = 48000.0, shaft: str = "sun", output_speed_deg_s: float = 45.0,
                 speed_column: str | None = None, samples_per_rev: int | None = None, shaft_orders: int = 2,
                 params: str | None = None, log: bool = True, modulation: bool = False,
                 median_tooth: bool = False):
        self.fs = fs
        self.shaft = shaft
        self.output_speed_deg_s = output_speed_deg_s
        self.speed_column = speed_column
        self.samples_per_rev = samples_per_rev
        self.shaft_orders = shaft_orders
        self.params = params
        self.log = log
        self.modulation = modulation
        self.median_tooth = median_tooth

    def _names(self) -> tuple[str, ...]:
        from rvdiag.features.planetary import MODULATION_INDICATORS

        # models pickled before an option existed have no such attribute: the option was off
        return (_CI + (tuple(MODULATION_INDICATORS) if getattr(self, "modulation", False) else ())
                + (_TOOTH if getattr(self, "median_tooth", False) else ()))

    def _rows(self, X, f_hz):
        names = self._names()
        out = np.empty((X.shape[0], len(names)))
        mod = getattr(self, "modulation", False)
        tooth = getattr(self, "median_tooth", False)
        if tooth:
            trim = 2 * int(_o._params(self.params).stage1.n_planets) if self.shaft == "sun" else 2
        if mod:
            from rvdiag.features import planetary as pl

            spacing = pl.sideband_spacing(self.shaft, self.params)
        for i, x in enumerate(X):
            xa, spr, m = self._resampled(x, f_hz)
            t = _o.tsa(xa, spr)
            ci = _o.condition_indicators(t, m, self.shaft_orders)
            if mod:
                ci.update(pl.modulation_indicators(t, m, spacing))
                ci["sideband_asymmetry_db"] = float(np.clip(ci["sideband_asymmetry_db"], -60.0, 60.0))
            if tooth:
                ci.update(tooth_indicators(t, m, trim))
            out[i] = [ci[k] for k in names]
        if self.log:
            logged = [k not in _SIGNED for k in names]
            out[:, logged] = np.log10(np.maximum(out[:, logged], 1e-12))
        return out

    def _feature_names(self):
        return [("log10_" if self.log and k not in _SIGNED else "") + k for k in self._names()]


class OrderSpectrumFeatures(_AngleFeatures):
    """Order-spectrum and envelope-order-spectrum features of each window on one shaft (feature set ``orders``).

    ``n_bands`` log10 band powers of the order spectrum over orders (0, ``max_order``], each relative to their
    sum (level and transfer path cancel to first order), then the envelope order spectrum's amplitude at each
    fault order of the reducer on the shaft (:func:`rvdiag.features.orders.fault_orders`: sun, planet,
    cycloid-lobe and pin faults), log10, relative to the envelope's RMS.  Parameters as
    :class:`TSAIndicatorFeatures`, plus ``n_bands`` and ``max_order`` (default: 4.5 mesh orders).
    """

    _FAULTS = ("f_sun_fault", "f_planet_fault", "f_cycloid_fault", "f_pin_fault")

    def __init__(self, fs: float = 48000.0, shaft: str = "sun", output_speed_deg_s: float = 45.0,
                 speed_column: str | None = None, samples_per_rev: int | None = None, n_bands: int = 32,
                 max_order: float | None = None, params: str | None = None):
        self.fs = fs
        self.shaft = shaft
        self.output_speed_deg_s = output_speed_deg_s
        self.speed_column = speed_column
        self.samples_per_rev = samples_per_rev
        self.n_bands = n_bands
        self.max_order = max_order
        self.params = params

    def _rows(self, X, f_hz):
        if not (isinstance(self.n_bands, (int, np.integer)) and self.n_bands >= 1):
            raise ParameterError(f"n_bands must be a positive integer, got {self.n_bands!r}")
        fo = _o.fault_orders(self.shaft, self.params)
        out = np.empty((X.shape[0], self.n_bands + len(self._FAULTS)))
        for i, x in enumerate(X):
            xa, spr, m = self._resampled(x, f_hz)
            top = float(self.max_order or 4.5 * m)
            orders, amp = _o.order_spectrum(xa, spr)
            edges = np.linspace(0.0, top, self.n_bands + 1)
            idx = np.clip(np.searchsorted(edges, orders, side="left") - 1, -1, self.n_bands)
            p = np.bincount(idx[(idx >= 0) & (idx < self.n_bands)],
                            weights=(amp**2)[(idx >= 0) & (idx < self.n_bands)], minlength=self.n_bands)
            out[i, : self.n_bands] = np.log10(p / max(p.sum(), 1e-300) + 1e-12)
            eo, ea = _o.envelope_order_spectrum(xa, spr)
            rms = float(np.sqrt(np.mean(ea[1:] ** 2))) or 1e-300
            out[i, self.n_bands:] = [np.log10(np.interp(fo[k], eo, ea) / rms + 1e-12) for k in self._FAULTS]
        return out

    def _feature_names(self):
        return [f"order_band{k}" for k in range(self.n_bands)] + [f"env_{k}" for k in self._FAULTS]
