"""Baseline-referenced features: what changed in a monitored window since the same reducer's healthy baseline at
the nearest operating point (docs/monitoring.md).

A reducer is compared with itself.  The classical gear indicators do this: NA4 divides the fourth moment of the
residual signal by the variance of the machine's own earlier records (Zakrajsek, Townsend & Decker 1993, NASA
TM-105950), NA4* by the variance of the healthy machine at the same load (Decker, Handschuh & Zakrajsek 1994,
NASA TM-106553; Dempsey & Zakrajsek 2001, NASA/TM-2001-210671), and ISO 13373-1/-2 and ISO 17359 monitor a
machine by the trend of its own indicators against its commissioning baseline.  Three families here:

- :func:`relative_features`: any feature vector (log band powers, log condition indicators) minus the mean of the
  baseline windows' vectors, so a log10 power becomes a change in decades (x 10 = dB).  What the reducer's
  manufacturing errors, build and sensor path put into the features, the baseline holds too, and the difference
  cancels it to first order.
- :func:`tsa_change_features`: the TSA of the window on the sun shaft (relative to the carrier) compared with the
  TSA of the baseline windows after a circular alignment (the start angle of a record is not known to a fraction
  of a tooth): the change of the whole TSA and of its residual (mesh harmonics and shaft orders removed, Lebold et
  al. 2000), NA4* of the change (its fourth moment over the squared variance of the baseline's own residual,
  Decker et al. 1994), and the per-tooth deviation (the largest energies of the change in half-pitch slots over
  their median: a tooth fault acts on one tooth once per planet pass, a load or temperature change on every
  tooth).  Each change is also given relative to the baseline's own spread (the leave-one-out change of each
  baseline window against the others), the reducer's run-to-run variation.
- :func:`median_tooth_change`: the change of the *median tooth* (:func:`rvdiag.features.orders.median_tooth`, the
  point-by-point median of the TSA's Z1 tooth-mesh periods) since the baseline's median tooth.  Wear of every
  sun tooth moves it; a broken tooth, which acts on the periods of one tooth, barely does.  So it sees wear under a
  broken tooth (T5 against T2), which the changes above, dominated by the broken tooth's impacts, do not.

This module knows nothing of stores or models: it takes arrays.  Matching a sample with its baseline windows is
:func:`rvdiag.monitoring.pairing.match_baseline`; the health index and the alarm are in :mod:`rvdiag.monitoring.detector`.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from sklearn.base import BaseEstimator, TransformerMixin, clone

from rvdiag.errors import ParameterError
from rvdiag.features import orders as _o
from rvdiag.features._base import as_signal_matrix
from rvdiag.features.combine import input_metadata, points_before_metadata

#: names of :func:`tsa_change_features`, in order
TSA_CHANGE_NAMES = ("log10_tsa_change", "log10_residual_change", "log10_na4_star", "log10_tooth_peak",
                    "log10_tsa_change_z", "log10_residual_change_z", "log10_tooth_peak_z")
#: names of :func:`median_tooth_change`, in order
MEDIAN_TOOTH_NAMES = ("log10_median_tooth_change", "log10_median_tooth_rms_ratio")


def relative_features(F, B) -> np.ndarray:
    """``F - mean(B)``: each window's features (rows of ``F``) minus the mean of its baseline windows' features
    ``B`` (rows; the same columns).  For log10 features this is the change in decades since the baseline (the
    ISO 13373-2 trend of an indicator against its reference value)."""
    F = np.atleast_2d(np.asarray(F, dtype=np.float64))
    B = np.atleast_2d(np.asarray(B, dtype=np.float64))
    if B.shape[0] < 1 or B.shape[1] != F.shape[1]:
        raise ParameterError(f"baseline features of shape {B.shape} do not match window features of shape "
                             f"{F.shape}")
    return F - B.mean(axis=0)


def align(t: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """``t`` circularly shifted (whole samples) to the lag of its largest cross-correlation with ``ref``."""
    c = np.fft.irfft(np.fft.rfft(ref) * np.conj(np.fft.rfft(t)), t.size)
    return np.roll(t, int(np.argmax(c)))


def sun_tsa(x, fs: float, output_speed_deg_s: float, samples_per_rev: int, params=None) -> np.ndarray:
    """TSA of ``x`` on the sun shaft relative to the carrier at a constant output speed, ``samples_per_rev``
    points per revolution (computed order tracking, :func:`rvdiag.features.orders.resample_to_angle`)."""
    f = _o.shaft_frequency("sun", params, output_speed_deg_s=float(output_speed_deg_s))
    revs = _o.angle_from_speed(np.asarray(x).size, float(fs), f)
    return _o.tsa(_o.resample_to_angle(np.asarray(x, dtype=np.float64), float(fs), revs, samples_per_rev),
                  samples_per_rev)


def _residual(t, mesh: int, shaft_orders: int = 2) -> np.ndarray:
    return _o.gear_signals(t, mesh, shaft_orders)["residual"]


def _tooth_peak(d, slots: int, peaks: int) -> float:
    """Mean of the ``peaks`` largest slot energies of ``d`` over their median (``slots`` equal slots)."""
    n = d.size - d.size % slots
    e = np.sort((d[:n].reshape(slots, -1) ** 2).sum(axis=1))
    med = float(np.median(e))
    return float(e[-peaks:].mean() / med) if med > 0 else 0.0


def _change(t, ref, mesh: int, slots: int, peaks: int):
    d = align(t, ref) - ref
    dr = _residual(d, mesh)
    rr = _residual(ref, mesh)
    return (float(np.linalg.norm(d) / max(np.linalg.norm(ref), 1e-300)),
            float(np.linalg.norm(dr) / max(np.linalg.norm(rr), 1e-300)),
            dr, float(np.var(rr)), _tooth_peak(dr, slots, peaks))


def median_tooth_change(t, ref, teeth: int) -> np.ndarray:
    """:data:`MEDIAN_TOOTH_NAMES` of the TSA ``t`` against the reference TSA ``ref`` (the same reducer's baseline,
    the same angular sampling): log10 of ||M - M_b|| / ||M_b|| and of rms(M) / rms(M_b), with M and M_b the median
    teeth (:func:`rvdiag.features.orders.median_tooth`, ``teeth`` periods per revolution) and M aligned to M_b
    within one pitch (:func:`align`; every tooth is alike, so no whole-revolution alignment is needed).

    The mean over the periods would be the TSA's mesh harmonics, the regular signal of Stewart 1977 / Lebold et
    al. 2000 less its sidebands; a broken tooth adds 1 / teeth of each of its impacts to that mean and nothing to
    the median while it acts on fewer than half the periods.  Measured on the paired simulations of
    research/tooth_median.py (docs/monitoring.md)."""
    M = _o.median_tooth(t, teeth)["median"]
    Mb = _o.median_tooth(ref, teeth)["median"]
    M = align(M, Mb)
    v = np.array([np.linalg.norm(M - Mb) / max(np.linalg.norm(Mb), 1e-300),
                  np.std(M) / max(float(np.std(Mb)), 1e-300)])
    return np.log10(np.maximum(v, 1e-12))


def tsa_change_features(x, output_speed_deg_s: float, baseline: Sequence[np.ndarray],
                        baseline_speeds: Sequence[float], fs: float, params=None,
                        samples_per_rev: int | None = None, median_tooth: bool = False) -> np.ndarray:
    """The TSA-change features (:data:`TSA_CHANGE_NAMES`) of the window ``x`` against its baseline windows.

    Parameters
    ----------
    x : array (n,)
        The monitored window, at output speed ``output_speed_deg_s``.
    baseline : sequence of arrays
        The same reducer's healthy windows at (about) the same operating point, each at its speed in
        ``baseline_speeds``; two or more give the baseline's own spread (the ``*_z`` features), one gives NaN there.
    fs : float
        Sampling rate, Hz.
    params : reducer parameters (default the built-in RV-20E): the sun's teeth Z1 and the planets N.
    samples_per_rev : int, optional
        Angular samples per sun revolution (default from the window's speed,
        :func:`rvdiag.features.orders.default_samples_per_rev`).
    median_tooth : bool
        Append :func:`median_tooth_change` of the window's TSA against the baseline's mean TSA
        (:data:`MEDIAN_TOOTH_NAMES`, 2 more values).

    Returns
    -------
    array (7,) or (9,)
        log10 of (ratios spanning decades, as the indicators of ``tsa-ci``): ``tsa_change`` ||T - T_b|| / ||T_b||, ``residual_change`` the same of their residuals, ``na4_star``
        mean(r^4) / var(r_b)^2 of the residual r of the change (Decker, Handschuh & Zakrajsek 1994, NA4* with the
        healthy baseline's variance), ``tooth_peak`` the mean of the N largest half-pitch energies of r over their
        median (N planets: a tooth meets N planets per revolution), and the first two and the last over the median
        of the same figure for each baseline window left out against the others.
    """
    p = _o._params(params)
    mesh, planets = int(p.stage1.sun_teeth), int(p.stage1.n_planets)
    if len(baseline) < 1 or len(baseline) != len(baseline_speeds):
        raise ParameterError(f"tsa_change_features needs >= 1 baseline window with its speed, got "
                             f"{len(baseline)} windows and {len(baseline_speeds)} speeds")
    f = _o.shaft_frequency("sun", p, output_speed_deg_s=float(output_speed_deg_s))
    spr = int(samples_per_rev or _o.default_samples_per_rev(float(fs), f, mesh))
    Tb = [sun_tsa(b, fs, v, spr, p) for b, v in zip(baseline, baseline_speeds)]
    t = sun_tsa(x, fs, output_speed_deg_s, spr, p)
    return tsa_change_from_tsa(t, Tb, mesh, planets, median_tooth=median_tooth)


def tsa_change_from_tsa(t, baseline_tsas: Sequence[np.ndarray], teeth: int, planets: int,
                        median_tooth: bool = False) -> np.ndarray:
    """:func:`tsa_change_features` of the sun TSA ``t`` against the baseline TSAs ``baseline_tsas`` (all at the
    same angular sampling, :func:`sun_tsa`), ``teeth`` = Z1 and ``planets`` = N: the same figures from TSAs
    already computed."""
    slots = 2 * teeth
    Tb = list(baseline_tsas)
    if len(Tb) < 1:
        raise ParameterError("tsa_change_from_tsa needs >= 1 baseline TSA")
    Tb = [Tb[0]] + [align(b, Tb[0]) for b in Tb[1:]]
    ref = np.mean(Tb, axis=0)
    c, cr, dr, var_b, peak = _change(t, ref, teeth, slots, planets)
    na4 = float(np.mean((dr - dr.mean()) ** 4) / var_b**2) if var_b > 0 else 0.0
    own = np.full(3, np.nan)
    if len(Tb) >= 2:
        loo = []
        for j in range(len(Tb)):
            cj, crj, _, _, pj = _change(Tb[j], np.mean(Tb[:j] + Tb[j + 1:], axis=0), teeth, slots, planets)
            loo.append((cj, crj, pj))
        own = np.median(loo, axis=0)
    v = np.array([c, cr, na4, peak, c / own[0], cr / own[1], peak / own[2]])
    out = np.log10(np.maximum(v, 1e-12), where=np.isfinite(v), out=np.full(v.size, np.nan))
    return np.r_[out, median_tooth_change(t, ref, teeth)] if median_tooth else out


class BaselineReferencedFeatures(TransformerMixin, BaseEstimator):
    """What changed in each window since its reducer's baseline windows: :func:`relative_features` of the
    ``features`` transformer's output and, with ``tsa_change``, :func:`tsa_change_features` (module docstring).

    Rows of ``X`` and of ``baseline`` follow :mod:`rvdiag.features.combine`: a window's points, then the metadata
    columns of :meth:`input_metadata` (the inner transformer's, then ``speed_column`` when ``tsa_change`` needs it).
    :meth:`transform` takes, besides ``X``, the baseline rows and ``groups``: for each row of ``X`` the indices of
    its baseline rows (:func:`rvdiag.monitoring.pairing.match_baseline`).  The baseline rows' features are computed once.

    Parameters
    ----------
    features : transformer, None or ``"none"``
        The window features compared (default :class:`rvdiag.features.tsa.OrderSpectrumFeatures` at ``fs`` with the
        speed column: the order-spectrum bands and the envelope lines at the fault orders); ``"none"``: no window
        features, the TSA change alone (the route of docs/monitoring.md with the best six-state accuracy; refused
        with ``tsa_change=False``).
    tsa_change : bool
        Append :func:`tsa_change_features` (needs the output speed in ``speed_column``).
    median_tooth : bool
        With ``tsa_change``, append :func:`median_tooth_change` too (:data:`MEDIAN_TOOTH_NAMES`; wear under a
        broken tooth, docs/monitoring.md).  A model saved before this option existed unpickles without it and
        keeps its 7 TSA-change features.
    fs : float
        Sampling rate, Hz.
    speed_column : str
        Metadata column of each window's output speed in deg/s.
    params : reducer parameters (str path or ReducerParams; default the built-in RV-20E).
    """

    def __init__(self, features=None, tsa_change: bool = True, fs: float = 48000.0,
                 speed_column: str = "output_speed_deg_s", params=None, median_tooth: bool = True):
        self.features = features
        self.tsa_change = tsa_change
        self.median_tooth = median_tooth
        self.fs = fs
        self.speed_column = speed_column
        self.params = params

    def _inner(self):
        if isinstance(self.features, str) and self.features == "none":
            if not self.tsa_change:
                raise ParameterError("BaselineReferencedFeatures(features='none') needs tsa_change=True: no "
                                     "features would be left")
            return None
        if self.features is not None:
            return self.features
        from rvdiag.features.tsa import OrderSpectrumFeatures

        return OrderSpectrumFeatures(fs=self.fs, speed_column=self.speed_column, params=self.params)

    def input_metadata(self) -> tuple[str, ...]:
        """The inner transformer's metadata columns, then the speed column when :func:`tsa_change_features` needs
        it and the inner one does not read it."""
        inner = tuple(input_metadata(self._inner())) if self._inner() is not None else ()
        extra = (str(self.speed_column),) if self.tsa_change and self.speed_column not in inner else ()
        return inner + extra

    def fit(self, X, y=None, **kw):
        """Fit the inner transformer on ``X`` (its own fit; it learns the window length); returns ``self``."""
        A = as_signal_matrix(X, 2)
        meta = self.input_metadata()
        n = points_before_metadata(A, meta, "BaselineReferencedFeatures reads")
        inner = self._inner()
        self.features_ = None if inner is None else clone(inner).fit(A[:, : n + len(input_metadata(inner))])
        self.n_features_in_ = A.shape[1]
        return self

    def _parts(self, A):
        meta = self.input_metadata()
        n = points_before_metadata(A, meta, "BaselineReferencedFeatures reads")
        inner = None if self.features_ is None else A[:, : n + len(input_metadata(self.features_))]
        speed = A[:, n + meta.index(self.speed_column)] if self.tsa_change else None
        return inner, A[:, :n], speed

    def transform(self, X, baseline=None, groups=None):
        """The change of every window of ``X`` against the mean of its baseline rows ``baseline[groups[i]]``."""
        from sklearn.utils.validation import check_is_fitted

        check_is_fitted(self, "features_")
        if baseline is None or groups is None:
            raise ParameterError("BaselineReferencedFeatures needs each window's baseline windows (baseline, groups)")
        A, B = as_signal_matrix(X, 2), as_signal_matrix(baseline, 2)
        for M, what in ((A, "X"), (B, "the baseline")):
            if M.shape[1] != self.n_features_in_:
                raise ParameterError(f"{what} has {M.shape[1]} columns; BaselineReferencedFeatures was fitted on "
                                     f"{self.n_features_in_}")
        if len(groups) != A.shape[0]:
            raise ParameterError(f"groups holds {len(groups)} baseline groups for {A.shape[0]} windows")
        ia, wa, va = self._parts(A)
        ib, wb, vb = self._parts(B)
        Fa, Fb = (np.zeros((M.shape[0], 0)) if self.features_ is None
                  else np.asarray(self.features_.transform(i), dtype=np.float64) for i, M in ((ia, A), (ib, B)))
        out = []
        for i, g in enumerate(groups):
            g = np.asarray(g, dtype=np.int64)
            if g.size == 0 or g.min() < 0 or g.max() >= B.shape[0]:
                raise ParameterError(f"window {i}: its baseline group must index 1..{B.shape[0]} baseline rows")
            row = relative_features(Fa[i:i + 1], Fb[g])[0]
            if self.tsa_change:
                row = np.r_[row, tsa_change_features(wa[i], va[i], list(wb[g]), vb[g], self.fs, self.params,
                                                     median_tooth=self._median_tooth())]
            out.append(row)
        return np.array(out)

    def _median_tooth(self) -> bool:
        # a model pickled before the option existed has no such attribute: its 7 TSA-change features
        return bool(self.tsa_change and getattr(self, "median_tooth", False))

    def get_feature_names_out(self, input_features=None):
        names = [] if self.features_ is None else [f"d_{f}" for f in self.features_.get_feature_names_out()]
        tsa = list(TSA_CHANGE_NAMES) if self.tsa_change else []
        return np.asarray(names + tsa + (list(MEDIAN_TOOTH_NAMES) if self._median_tooth() else []), dtype=object)


__all__ = ["MEDIAN_TOOTH_NAMES", "TSA_CHANGE_NAMES", "BaselineReferencedFeatures", "align", "median_tooth_change",
           "relative_features", "sun_tsa", "tsa_change_features", "tsa_change_from_tsa"]
