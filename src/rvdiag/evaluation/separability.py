"""The separability bound: the best accuracy ANY classifier can reach in telling two states apart at an SNR.

Method (binary detection of a known signal in white Gaussian noise; Van Trees, *Detection, Estimation and
Modulation Theory*, Part I, sec. 2.6; Kay, *Fundamentals of Statistical Signal Processing* vol. 2, sec. 4.3).
Two states ``a`` and ``b`` are simulated noise-free with identical parameters, operating point, settings and
seeds, so that they differ by the fault alone, and both records are cut into the same aligned windows of
``window`` points (non-overlapping, from the first sample).  In window ``k`` the two hypotheses are

    H_a: y = s_a + n,    H_b: y = s_b + n,    n ~ N(0, sigma_k^2 I),

with equal priors.  The detector with the smallest error probability (the likelihood-ratio test; with equal
priors and equal noise the minimum-distance, or matched-filter, detector: decide ``a`` when
``||y - s_a|| < ||y - s_b||``) errs with probability ``Q(d_k / (2 sigma_k))``, ``d_k = ||s_a - s_b||_2``, so its
accuracy is ``Phi(d_k / (2 sigma_k))``.  No classifier does better on that window; the bound reported is the
mean over windows, ``mean_k Phi(d_k / (2 sigma_k))``.

The noise follows the SNR convention of :func:`rvdiag.dynamics.noise.add_awgn` (what the library, ``rvdiag
train --snr-db`` and ``rvdiag evaluate --snr-db`` add): SNR = mean power of the sample over the noise variance,
per sample (window) and per channel.  Here ``sigma_k^2 = P_k / 10^(snr/10)`` with ``P_k`` the mean power of the
pair, ``(mean(s_a^2) + mean(s_b^2)) / 2`` over the window: one noise level for both hypotheses, as the test
needs.  ``add_awgn`` scales each sample to its own power, so the two hypotheses' noise differs by the power
ratio of the pair (1.0x for a crack, docs/model.md section 9); the bound takes their mean.

Across specimens (``params_b``: the second state simulated on another reducer, e.g. another ``[modification]
error_seed``), the same bound says how far two reducers are apart: the bound of specimen A healthy against
specimen B healthy, beside that of A healthy against A cracked, tells whether the difference between two reducers
is larger than the fault's effect (then a classifier that does not know the reducer's healthy signal meets the
crack inside the spread of healthy reducers).

It is an upper bound: the ideal detector knows both signals, their phase in the window and the noise level,
whereas a classifier trained on a library meets the state at any phase, any severity of its range and any
draw of the other parameters.  A classifier near the bound has nothing left to learn; one far below it has.

**With run-to-run variation** (:func:`simulate_varied_pairs`, :func:`varied_bound_from_windows`; docs/monitoring.md).  Two
records of one reducer differ even in one state: load, speed, temperature (every stiffness together), mesh damping
and sensor gain change from run to run (:data:`RUN_TO_RUN_DEFAULT`).  The healthy hypothesis is then not one
known signal but a distribution, ``H_a: y = s_a(theta) + n``, ``H_b: y = s_b(theta) + n``, ``theta`` the record's
draw.  ``K`` draws ``theta_k`` are simulated in both states (paired: the same draw for both), and each pair is put
on the nominal record's angle axis: time stretched by ``v_k / v_0`` and shifted by the fractional lag that best
aligns the healthy draw with the nominal healthy record (the reduction; the detector is granted each record's shaft
angle, as an encoder gives it, and the phase, as the known-signal bound grants it).  Two figures per window:

- ``accuracy_bound_known_draw``: ``mean_k Phi(||s_b(theta_k) - s_a(theta_k)|| / (2 sigma))``, the detector that
  knows each record's draw (the clairvoyant detector; Van Trees Part I sec. 2.5, composite hypotheses: knowing the
  nuisance parameter can only help).  An upper bound on any detector that does not know it.
- ``accuracy_bound_gaussian``: the draws treated as Gaussian, ``s(theta) ~ N(mu_state, Sigma_rr)`` with one
  covariance for both states (the pooled sample covariance of the ``2K`` aligned windows about their state means),
  so the two hypotheses are ``N(mu_a, Sigma_rr + sigma^2 I)`` and ``N(mu_b, Sigma_rr + sigma^2 I)``.  The
  likelihood-ratio test is then linear (the generalised matched filter, Kay vol. 2 sec. 4.5, eq. 4.16; Van Trees
  Part I sec. 2.6, equal covariances) and errs with ``Q(d / 2)``, ``d^2 = delta^T (Sigma_rr + sigma^2 I)^-1 delta``,
  ``delta = mu_b - mu_a``: the accuracy ``Phi(d / 2)`` of the best detector that does not know the draw, under
  this second-order (Gaussian) approximation.  It assumes the crack's change ``delta`` does not depend on the draw
  (its spread is pooled into ``Sigma_rr``).  ``Sigma_rr`` of ``K`` draws has rank ``<= 2K - 2``: a small ``K``
  misses directions of the true spread, so the figure errs high (the detector is granted the directions never
  drawn); it falls towards the true value as ``K`` grows.  Computed with the Woodbury identity in the span of the
  draws, without forming the window-by-window matrix.

With zero variation every draw equals the nominal record, ``Sigma_rr = 0`` and both figures equal the bound above.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from rvdiag.errors import ParameterError
from rvdiag.progress import report


def _snr_levels(snr_db: Sequence[float]) -> list[float]:
    """The SNRs (dB) as floats: at least one, all finite, else one ParameterError."""
    levels = [float(s) for s in snr_db]
    if not levels or not all(math.isfinite(s) for s in levels):
        raise ParameterError(f"SNR levels must be finite numbers of dB, got {list(snr_db)!r}")
    return levels


def aligned_windows(a: np.ndarray, b: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Cut two records of the same length into aligned, non-overlapping windows: two arrays (n_windows, window).

    The tail shorter than a window is dropped.  Raises :class:`ParameterError` when the records differ in
    length or are shorter than one window."""
    a = np.asarray(a, dtype=float).ravel()
    b = np.asarray(b, dtype=float).ravel()
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 1:
        raise ParameterError(f"the window must be a whole number of points >= 1, got {window!r}")
    if a.shape != b.shape:
        raise ParameterError(f"the two records differ in length ({a.size} and {b.size} points)")
    n = a.size // int(window)
    if n < 1:
        raise ParameterError(f"the window of {window} points is longer than the record ({a.size} points); "
                             f"lengthen the duration or shorten the window")
    return a[:n * window].reshape(n, window), b[:n * window].reshape(n, window)


def bound_from_windows(A: np.ndarray, B: np.ndarray, snr_db: Sequence[float]) -> dict:
    """The separability bound of aligned window pairs ``A[k]``, ``B[k]`` (arrays (n_windows, window)).

    Returns ``{"window", "n_windows", "snr_db", "accuracy_bound", "distance_over_rms"}``: for each level,
    ``mean_k Phi(d_k / (2 sigma_k))`` with ``d_k = ||A_k - B_k||`` and ``sigma_k^2`` the pair's mean power over
    ``10^(snr/10)`` (module docstring); ``distance_over_rms`` is the median over windows of ``d_k / ||A_k||``
    (the relative L2 difference of the two states, independent of the noise)."""
    from scipy.special import ndtr

    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    if A.ndim != 2 or A.shape != B.shape or A.shape[0] < 1:
        raise ParameterError(f"need two arrays (n_windows, window) of one shape, got {A.shape} and {B.shape}")
    levels = _snr_levels(snr_db)
    d = np.linalg.norm(A - B, axis=1)
    power = 0.5 * (np.mean(A**2, axis=1) + np.mean(B**2, axis=1))
    norm_a = np.linalg.norm(A, axis=1)
    bound = []
    for s in levels:
        sigma = np.sqrt(power * 10.0 ** (-s / 10.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            arg = np.where(sigma > 0, d / (2.0 * np.where(sigma > 0, sigma, 1.0)), np.where(d > 0, np.inf, 0.0))
        bound.append(float(np.mean(ndtr(arg))))
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(norm_a > 0, d / np.where(norm_a > 0, norm_a, 1.0), np.where(d > 0, np.inf, 0.0))
    return {"window": int(A.shape[1]), "n_windows": int(A.shape[0]), "snr_db": levels, "accuracy_bound": bound,
            "distance_over_rms": float(np.median(rel))}


def separability_bound(a: np.ndarray, b: np.ndarray, window: int, snr_db: Sequence[float]) -> dict:
    """:func:`bound_from_windows` of two records cut by :func:`aligned_windows`."""
    return bound_from_windows(*aligned_windows(a, b, window), snr_db)


def simulate_pair(pair: Sequence[str], *, params=None, output_speed_deg_s: float, load_Nm: float,
                  duration_s: float, fs: float, transient_s: float, model: Mapping | None = None, channel: int = 0,
                  severities: Mapping[str, float] | None = None, seed: int = 0,
                  params_b=None) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free records of the two states of ``pair`` (``rvdiag.gears.ToothFaults.for_state`` names), one channel.

    Both come from :func:`rvdiag.dynamics.simulate` with the same parameters, operating point, settings
    (``model``: :class:`rvdiag.dynamics.ModelSettings` keywords, as a library config's ``[model]`` table) and
    seed; ``severities`` (SI, keyed as ``for_state`` takes them) go to both, each state using those of its
    faults.  ``params_b`` (default: ``params``) are the second state's parameters: two specimens, e.g. two
    ``[modification] error_seed``, so that the pair differs by the reducer (and the fault, if the states differ).
    Each simulation is reported to :mod:`rvdiag.progress` (stage ``simulating STATE``)."""
    from rvdiag.dynamics import ModelSettings, simulate
    from rvdiag.gears import ToothFaults

    settings = ModelSettings(**dict(model or {}), transient_s=float(transient_s))
    out = []
    for state, p in zip(pair, (params, params if params_b is None else params_b)):
        fault = ToothFaults.for_state(state, **dict(severities or {}))
        stage = f"simulating {fault.label or str(state).upper()}"

        def progress(done: int, total: int, stage: str = stage) -> None:
            report(stage, done, total)

        res = simulate(p, None if fault.is_healthy else fault, output_speed_deg_s=output_speed_deg_s,
                       load_Nm=load_Nm, duration_s=duration_s, fs=fs, noise_snr_db=None, seed=seed,
                       settings=settings, progress=progress)
        if not 0 <= channel < res.signal.shape[0]:
            raise ParameterError(f"channel {channel} out of range: the simulation has {res.signal.shape[0]}")
        out.append(np.asarray(res.signal[channel], dtype=float))
    return out[0], out[1]


#: run-to-run variation between two records of one reducer (docs/monitoring.md), half-ranges as fractions of the nominal
#: value, uniform: load, output speed, temperature (every stiffness by one factor), mesh damping, sensor gain
RUN_TO_RUN_DEFAULT = {"load": 0.03, "speed": 0.01, "temperature": 0.02, "damping": 0.10, "gain": 0.03}


def parse_run_to_run(text: str) -> dict[str, float]:
    """``"default"`` (:data:`RUN_TO_RUN_DEFAULT`) or ``"load=3,speed=1,temperature=2,damping=10,gain=3"`` (percent,
    half-ranges; keys not named vary by 0) -> half-ranges as fractions."""
    text = str(text).strip()
    if text.lower() == "default":
        return dict(RUN_TO_RUN_DEFAULT)
    out = {k: 0.0 for k in RUN_TO_RUN_DEFAULT}
    for part in (p.strip() for p in text.split(",")):
        key, sep, value = part.partition("=")
        key = key.strip().lower()
        if not sep or key not in out:
            raise ParameterError(f"--run-to-run: expected 'default' or KEY=PERCENT pairs with keys among "
                                 f"{', '.join(RUN_TO_RUN_DEFAULT)}, got {part!r}")
        try:
            pct = float(value)
        except ValueError:
            raise ParameterError(f"--run-to-run: {key}={value!r} is not a number of percent") from None
        if not 0 <= pct < 100 or not math.isfinite(pct):
            raise ParameterError(f"--run-to-run: {key} must be in [0, 100) percent, got {value}")
        out[key] = pct / 100.0
    return out


def draw_run_to_run(rng: np.random.Generator, ranges: Mapping[str, float]) -> dict[str, float]:
    """One record's factors, each uniform in ``1 +- ranges[key]`` (keys of :data:`RUN_TO_RUN_DEFAULT`)."""
    return {k: float(1.0 + float(ranges.get(k, 0.0)) * rng.uniform(-1.0, 1.0)) for k in RUN_TO_RUN_DEFAULT}


def apply_run_to_run(params, factors: Mapping[str, float]):
    """``params`` (:class:`rvdiag.params.ReducerParams`) with every stiffness of
    :data:`rvdiag.library.config.STIFFNESS_KEYS` times ``factors["temperature"]`` and the mesh damping ratio times
    ``factors["damping"]``; load, speed and gain act on the operating point and the signal, not here."""
    from rvdiag.library.config import STIFFNESS_KEYS

    changes: dict[str, dict] = {}
    for s, k in STIFFNESS_KEYS:
        changes.setdefault(s, {})[k] = getattr(getattr(params, s), k) * float(factors.get("temperature", 1.0))
    changes.setdefault("damping", {})["mesh_damping_ratio"] = (params.damping.mesh_damping_ratio
                                                               * float(factors.get("damping", 1.0)))
    return params.replace(**changes)


def on_nominal_axis(x: np.ndarray, ratio: float, ref: np.ndarray, lag: float | None = None) -> tuple[np.ndarray, float]:
    """``x``, recorded at ``ratio`` times the nominal speed, on the nominal record's angle axis: ``x(n / ratio + c)``
    for ``n = 0 .. len(ref) - 1`` (Keys cubic interpolation), NaN where its kernel reaches outside ``x``.  The lag ``c``
    (samples of ``x``) is ``lag`` when given, else the one that maximises the correlation with ``ref`` (integer
    cross-correlation, then a bounded scalar search within one sample).  Returns ``(y, c)``."""
    from scipy.optimize import minimize_scalar

    from rvdiag.features.orders import cubic_interpolate

    x = np.asarray(x, dtype=float)
    ref = np.asarray(ref, dtype=float)
    n = np.arange(ref.size, dtype=float)

    def at(c: float) -> np.ndarray:
        u = n / float(ratio) + c
        ok = (u >= 1) & (u <= x.size - 2)             # the cubic kernel's support lies inside x
        y = np.full(ref.size, np.nan)
        y[ok] = cubic_interpolate(x, u[ok])
        return y

    if lag is None:
        y0 = np.nan_to_num(at(0.0))
        m = 1 << int(math.ceil(math.log2(2 * ref.size)))
        c = np.fft.irfft(np.fft.rfft(ref, m) * np.conj(np.fft.rfft(y0, m)), m)
        k = int(np.argmax(c))
        k = k - m if k > m // 2 else k                        # y0(n - k) ~ ref(n): lag -k / ratio in x's samples
        c0 = -k / float(ratio)

        def cost(c: float) -> float:
            y = at(c)
            ok = np.isfinite(y)
            return -float(np.dot(y[ok], ref[ok]) / max(np.linalg.norm(y[ok]) * np.linalg.norm(ref[ok]), 1e-300))

        lag = float(minimize_scalar(cost, bounds=(c0 - 1.0, c0 + 1.0), method="bounded",
                                    options={"xatol": 1e-3}).x)
    return at(float(lag)), float(lag)


def simulate_varied_pairs(pair: Sequence[str], *, ranges: Mapping[str, float], draws: int, params=None,
                          output_speed_deg_s: float, load_Nm: float, duration_s: float, fs: float,
                          transient_s: float, model: Mapping | None = None, channel: int = 0,
                          severities: Mapping[str, float] | None = None, seed: int = 0) -> dict:
    """The nominal pair (:func:`simulate_pair`) and ``draws`` pairs with run-to-run variation on its angle axis.

    Draw ``k`` takes factors from :func:`draw_run_to_run` (``np.random.default_rng(seed)``), simulates both states
    at ``output_speed_deg_s * speed`` and ``load_Nm * load`` with :func:`apply_run_to_run` parameters, multiplies
    both by ``gain``, and puts both on the nominal axis with :func:`on_nominal_axis` (the lag found on the healthy
    one, i.e. the first state, used for both).  Returns ``{"a", "b"}`` (nominal records), ``{"A", "B"}`` (arrays
    (draws, n) with NaN outside each record), ``"factors"`` (list of dicts) and ``"lags"``."""
    from rvdiag.params import ReducerParams

    if isinstance(draws, bool) or not isinstance(draws, (int, np.integer)) or draws < 1:
        raise ParameterError(f"the number of run-to-run draws must be a whole number >= 1, got {draws!r}")
    p = params if params is not None else ReducerParams.default()
    kw = dict(duration_s=duration_s, fs=fs, transient_s=transient_s, model=model, channel=channel,
              severities=severities, seed=seed)
    a, b = simulate_pair(pair, params=p, output_speed_deg_s=output_speed_deg_s, load_Nm=load_Nm, **kw)
    rng = np.random.default_rng(seed)
    A, B, factors, lags = [], [], [], []
    for k in range(int(draws)):
        f = draw_run_to_run(rng, ranges)
        report("run-to-run draws", k, int(draws))
        ak, bk = simulate_pair(pair, params=apply_run_to_run(p, f), output_speed_deg_s=output_speed_deg_s * f["speed"],
                               load_Nm=load_Nm * f["load"], **kw)
        if f["speed"] == 1.0:
            ya, lag = ak * f["gain"], 0.0
            yb = bk * f["gain"]
        else:
            ya, lag = on_nominal_axis(f["gain"] * ak, f["speed"], a)
            yb, _ = on_nominal_axis(f["gain"] * bk, f["speed"], a, lag=lag)
        A.append(ya)
        B.append(yb)
        factors.append(f)
        lags.append(lag)
    report("run-to-run draws", int(draws), int(draws))
    return {"a": a, "b": b, "A": np.array(A), "B": np.array(B), "factors": factors, "lags": lags}


def gmf_reference(state: str = "T4", *, ranges: Mapping[str, float], draws: int, params=None,
                  output_speed_deg_s: float, load_Nm: float, duration_s: float, fs: float, transient_s: float,
                  model: Mapping | None = None, channel: int = 0, severities: Mapping[str, float] | None = None,
                  seed: int = 0) -> dict:
    """What the generalised matched filter (:class:`rvdiag.features.gmf.GeneralisedMatchedFilter`) needs at one
    operating point, simulated: the fault's change and ``draws`` healthy records with run-to-run variation.

    The nominal pair T1 / ``state`` (:func:`simulate_pair`) gives the template ``b - a``; draw ``k`` takes factors from
    :func:`draw_run_to_run` (``np.random.default_rng(seed)``), simulates the healthy state at ``output_speed_deg_s *
    speed`` and ``load_Nm * load`` with :func:`apply_run_to_run` parameters, times ``gain``, and is put on the nominal
    axis by :func:`rvdiag.features.gmf.on_angle_axis` (every record starts at the same angle, as a robot's repeated
    motion does: no lag is searched, unlike :func:`simulate_varied_pairs`).  Everything is cut to the ``n`` points
    that every speed within ``ranges["speed"]`` covers.  Returns ``{"healthy", "template"}`` (n,), ``"draws"`` (K, n)
    and ``"factors"`` (list of dicts).  ``draws + 2`` simulations."""
    from rvdiag.dynamics import ModelSettings, simulate
    from rvdiag.features.gmf import on_angle_axis
    from rvdiag.params import ReducerParams

    if isinstance(draws, bool) or not isinstance(draws, (int, np.integer)) or draws < 2:
        raise ParameterError(f"the generalised matched filter needs at least 2 run-to-run draws, got {draws!r}")
    p = params if params is not None else ReducerParams.default()
    a, b = simulate_pair(["T1", state], params=p, output_speed_deg_s=output_speed_deg_s, load_Nm=load_Nm,
                         duration_s=duration_s, fs=fs, transient_s=transient_s, model=model, channel=channel,
                         severities=severities, seed=seed)
    n = int((a.size - 3) * (1.0 - float(ranges.get("speed", 0.0))))
    settings = ModelSettings(**dict(model or {}), transient_s=float(transient_s))
    rng = np.random.default_rng(seed)
    H, factors = [], []
    for k in range(int(draws)):
        report("run-to-run draws", k, int(draws))
        f = draw_run_to_run(rng, ranges)
        res = simulate(apply_run_to_run(p, f), None, output_speed_deg_s=output_speed_deg_s * f["speed"],
                       load_Nm=load_Nm * f["load"], duration_s=duration_s, fs=fs, noise_snr_db=None, seed=seed,
                       settings=settings)
        H.append(on_angle_axis(f["gain"] * np.asarray(res.signal[channel], dtype=float), f["speed"], n))
        factors.append(f)
    report("run-to-run draws", int(draws), int(draws))
    return {"healthy": a[:n], "template": (b - a)[:n], "draws": np.array(H), "factors": factors}


def _woodbury_deflection(delta: np.ndarray, Z: np.ndarray, sigma2: float) -> float:
    """``delta^T (Z^T Z + sigma2 I)^-1 delta`` for ``Z`` (r, n) by the Woodbury identity:
    ``(||delta||^2 - (Z delta)^T (sigma2 I_r + Z Z^T)^-1 (Z delta)) / sigma2``."""
    zd = Z @ delta
    inner = np.linalg.solve(sigma2 * np.eye(Z.shape[0]) + Z @ Z.T, zd) if Z.shape[0] else zd
    return float(max(delta @ delta - zd @ inner, 0.0) / sigma2)


def varied_bound_from_windows(A0: np.ndarray, B0: np.ndarray, HA: np.ndarray, HB: np.ndarray,
                              snr_db: Sequence[float]) -> dict:
    """The bounds with run-to-run variation (module docstring) of aligned windows: the nominal pair ``A0``,
    ``B0`` (n_windows, window), which sets each window's noise level as in :func:`bound_from_windows`, and the
    draws ``HA``, ``HB`` (draws, n_windows, window) of the two states, paired (draw ``k`` of both states under the
    same variation).

    Returns ``{"window", "n_windows", "draws", "snr_db", "accuracy_bound_known_draw", "accuracy_bound_gaussian",
    "spread_over_distance"}``; the last is the median over windows of the healthy draws' RMS spread (the root of
    the trace of ``Sigma_rr`` over the window) over ``||delta||``."""
    from scipy.special import ndtr

    A0, B0 = np.asarray(A0, dtype=float), np.asarray(B0, dtype=float)
    HA, HB = np.asarray(HA, dtype=float), np.asarray(HB, dtype=float)
    if A0.ndim != 2 or A0.shape != B0.shape:
        raise ParameterError(f"need two nominal arrays (n_windows, window) of one shape, got {A0.shape}, {B0.shape}")
    if HA.ndim != 3 or HA.shape != HB.shape or HA.shape[1:] != A0.shape or HA.shape[0] < 1:
        raise ParameterError(f"need two draw arrays (draws, n_windows, window) matching the nominal {A0.shape}, "
                             f"got {HA.shape} and {HB.shape}")
    if not (np.all(np.isfinite(HA)) and np.all(np.isfinite(HB))):
        raise ParameterError("the draws hold non-finite values (cut the windows to where every draw is defined)")
    levels = _snr_levels(snr_db)
    K, nw, w = HA.shape
    power = 0.5 * (np.mean(A0**2, axis=1) + np.mean(B0**2, axis=1))
    d_known = np.linalg.norm(HB - HA, axis=2)                                  # (K, nw)
    mu_a, mu_b = HA.mean(axis=0), HB.mean(axis=0)
    delta = mu_b - mu_a
    dof = max(2 * K - 2, 1)
    Z = np.concatenate([HA - mu_a, HB - mu_b], axis=0) / math.sqrt(dof)        # (2K, nw, w): Sigma = Z^T Z
    known, gauss = [], []
    for s in levels:
        sigma2 = power * 10.0 ** (-s / 10.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            kd = np.where(sigma2 > 0, d_known / (2.0 * np.sqrt(np.where(sigma2 > 0, sigma2, 1.0))),
                          np.where(d_known > 0, np.inf, 0.0))
        known.append(float(np.mean(ndtr(kd))))
        g = []
        for j in range(nw):
            if sigma2[j] > 0:
                g.append(ndtr(0.5 * math.sqrt(_woodbury_deflection(delta[j], Z[:, j, :], float(sigma2[j])))))
            else:
                g.append(1.0 if np.any(delta[j] != 0) else 0.5)
        gauss.append(float(np.mean(g)))
    nd = np.linalg.norm(delta, axis=1)
    spread = np.sqrt(np.sum((HA - mu_a) ** 2, axis=(0, 2)) / max(K - 1, 1))
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(nd > 0, spread / np.where(nd > 0, nd, 1.0), np.where(spread > 0, np.inf, 0.0))
    return {"window": int(w), "n_windows": int(nw), "draws": int(K), "snr_db": levels,
            "accuracy_bound_known_draw": known, "accuracy_bound_gaussian": gauss,
            "spread_over_distance": float(np.median(rel))}


def varied_bound(sim: Mapping, window: int, snr_db: Sequence[float]) -> dict:
    """:func:`varied_bound_from_windows` of :func:`simulate_varied_pairs`' output, cut into aligned windows of
    ``window`` points over the stretch where every draw is defined (its first window start is ``"start"``)."""
    A, B = np.asarray(sim["A"], dtype=float), np.asarray(sim["B"], dtype=float)
    ok = np.all(np.isfinite(A), axis=0) & np.all(np.isfinite(B), axis=0)
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        raise ParameterError("no stretch of the record is covered by every run-to-run draw: lengthen --duration")
    start, stop = int(idx[0]), int(idx[-1]) + 1
    if not np.all(ok[start:stop]):
        raise ParameterError("the run-to-run draws do not cover one contiguous stretch of the record")
    A0, B0 = aligned_windows(sim["a"][start:stop], sim["b"][start:stop], window)
    nw = A0.shape[0]
    cut = lambda M: M[:, start:start + nw * window].reshape(M.shape[0], nw, window)  # noqa: E731
    return {**varied_bound_from_windows(A0, B0, cut(A), cut(B), snr_db), "start": start}


__all__ = ["RUN_TO_RUN_DEFAULT", "aligned_windows", "apply_run_to_run", "bound_from_windows", "draw_run_to_run",
           "gmf_reference", "on_nominal_axis", "parse_run_to_run", "separability_bound", "simulate_pair",
           "simulate_varied_pairs", "varied_bound", "varied_bound_from_windows"]
