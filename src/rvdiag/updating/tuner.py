"""Tune the assumed parameters of a reducer model so that its healthy signal matches a measured one.

The score is the PCC of :mod:`rvdiag.updating.objectives` (log power spectrum by default), maximised over the
parameters of :mod:`rvdiag.updating.space` within their bounds.  The score is not smooth in the parameters (a
resonance crossing a mesh harmonic, Welch variance, contacts that open and close) and has no gradient at hand,
so the search is derivative-free, bounded and seeded:

1. global: :func:`scipy.optimize.differential_evolution` (Storn & Price 1997, J. Global Optim. 11, 341-359)
   on the unit cube, a small population, ``polish=False``, the base set as one member (``x0``), seeded;
2. local: bounded Nelder-Mead (:func:`scipy.optimize.minimize`) from the best point, with what is left of the
   budget.

Each evaluation simulates a short healthy record (default 0.5 s at the measured rate after a 0.1 s run-in that
``simulate`` discards).  The sensor-path parameters (path resonance and its damping) are a linear filter applied
after the integration (:mod:`rvdiag.dynamics.transfer`), so they do not need a new simulation: for each
simulated record they are fitted by a cheap inner search (a grid of resonance frequencies and "none", then a
bounded scalar search of frequency and damping) on the record filtered by the candidate path.  The outer search
therefore runs over the structural parameters only, and the budget counts simulations.  Identical parameter
vectors are looked up in a cache, never simulated twice.  The result depends on the seed only.

What counts as a change: the search works on the unit cube, and a base value mapped there and back comes out
moved in its last bits (1e8 -> 100000000.00000018).  A value within :data:`MOVED_RTOL` of its base is therefore
the base value, and the base set is kept whole unless the best set found raises the PCC by more than
:data:`MIN_PCC_GAIN` (a change that does not improve the match by more is not supported by the record).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, signal as sps

from rvdiag.dynamics import ModelSettings, simulate
from rvdiag.dynamics.transfer import path_sos
from rvdiag.errors import ParameterError, RvdiagError
from rvdiag.params import ReducerParams
from rvdiag.updating.objectives import Objective
from rvdiag.updating.space import Bound, apply_values, bounds_for
from rvdiag.validation import finite_number

#: RK4 steps per second of simulated time kept near the model's 9 sub-steps at 48 kHz
_STEP_RATE_HZ = 432000.0
#: points of the inner grid of path-resonance frequencies (log-spaced over the bounds, besides "none")
_PATH_GRID = 24
#: a tuned value within this relative distance of its base value has not moved (the unit-cube round trip
#: moves a base value by ~1e-15; the search's smallest steps, 1e-3 of the unit cube, by more than 1e-4)
MOVED_RTOL = 1e-6
#: the PCC gain the best set found must exceed to replace the base set
MIN_PCC_GAIN = 1e-3


@dataclass
class UpdateResult:
    """What :func:`update_parameters` found.

    Attributes
    ----------
    params_before, params_after : ReducerParams
    objective : str
    pcc_before, pcc_after : float
        Score of the base and of the updated set, each from a full :func:`rvdiag.dynamics.simulate` run
        (equal when the base set is kept).
    values : dict of name -> (before, after)
        ``after`` is exactly ``before`` for a value that did not move (see :data:`MOVED_RTOL`).
    updated : tuple of str
        Names of the values that moved; empty when the base set is kept.
    best_gain : float
        PCC of the best set found minus ``pcc_before`` (0 when no value moved).  The set replaces the base
        only when this exceeds ``min_gain``.
    min_gain : float
    evaluations : int
        Simulations run (search, base and the final check; cache hits not counted).
    seed : int
    fs : float
    measured, signal_before, signal_after : ndarray
        The measured record and the two simulated ones (for plots).
    history : list of float
        Best PCC after each simulation.
    """

    params_before: ReducerParams
    params_after: ReducerParams
    objective: str
    pcc_before: float
    pcc_after: float
    values: dict[str, tuple[float, float]]
    updated: tuple[str, ...]
    best_gain: float
    min_gain: float
    evaluations: int
    seed: int
    fs: float
    measured: np.ndarray = field(repr=False)
    signal_before: np.ndarray = field(repr=False)
    signal_after: np.ndarray = field(repr=False)
    history: list[float] = field(default_factory=list, repr=False)


class _BudgetSpent(Exception):
    """Raised inside the objective when the simulation budget is used up (ends the current search stage)."""


class _Evaluator:
    """Score of a point of the unit cube of the structural parameters, with its path fitted; cached."""

    def __init__(self, base: ReducerParams, bounds: list[Bound], objective: Objective, sim: dict,
                 channel: int, budget: int, progress: Callable[[int, int, float], None] | None) -> None:
        self.base = base
        self.struct = [b for b in bounds if not b.tunable.path]
        self.path = {b.name: b for b in bounds if b.tunable.path}
        self.objective = objective
        self.sim = sim
        self.channel = channel
        self.budget = budget
        self.limit = budget
        self.progress = progress
        self.cache: dict[tuple, tuple[float, dict[str, float]]] = {}
        self.raw: dict[tuple, np.ndarray] = {}
        self.n_sims = 0
        self.best = (-math.inf, None, None)  # (pcc, u, path values)
        self.history: list[float] = []

    # -------------------------------------------------------------- simulation
    def struct_values(self, u: np.ndarray) -> dict[str, float]:
        return {b.name: b.to_value(x) for b, x in zip(self.struct, u)}

    def simulate_raw(self, values: dict[str, float]) -> np.ndarray | None:
        """Simulated channel without the sensor path (None when the integration fails)."""
        p = apply_values(self.base, values).replace(mounting={"path_resonance_hz": 0.0, "sensor_cutoff_hz": 0.0})
        self.n_sims += 1
        try:
            res = simulate(p, None, **self.sim)
        except RvdiagError:  # unstable or invalid corner of the search space: worst score, search goes on
            return None
        x = np.asarray(res.signal[self.channel], dtype=np.float64)
        return x if np.all(np.isfinite(x)) else None

    def filtered(self, raw: np.ndarray, fn: float, zeta: float) -> np.ndarray:
        """``raw`` through the sensor path of the base set with resonance ``fn`` (0: none) and ``zeta``."""
        sos = path_sos(self.objective.fs, fn, zeta, self.base.mounting.sensor_cutoff_hz)
        return raw if sos is None else sps.sosfilt(sos, raw)

    # -------------------------------------------------------------- inner path fit
    def fit_path(self, raw: np.ndarray) -> tuple[float, dict[str, float]]:
        """Best path values for one simulated record: (PCC, {name: value}) of the tuned path parameters."""
        m = self.base.mounting
        fn, zeta = m.path_resonance_hz, m.path_damping_ratio
        score = lambda f, z: self.objective.score(self.filtered(raw, f, z))  # noqa: E731
        best = (score(fn, zeta), fn, zeta)  # the base path is always a candidate
        bf, bz = self.path.get("path_resonance_hz"), self.path.get("path_damping_ratio")
        if bz is not None:
            zeta_grid = min(max(zeta, bz.lower), bz.upper)
        else:
            zeta_grid = zeta
        if bf is not None:
            grid = np.geomspace(bf.lower, bf.upper, _PATH_GRID)
            for f in (0.0, *grid):
                s = score(f, zeta_grid)
                if s > best[0]:
                    best = (s, float(f), zeta_grid)
            if best[1] > 0:
                step = (bf.upper / bf.lower) ** (1.0 / (_PATH_GRID - 1))
                best = self._refine_fn(score, best, bf, step)
        if bz is not None and best[1] > 0:
            r = optimize.minimize_scalar(lambda z: -score(best[1], z), bounds=(bz.lower, bz.upper),
                                         method="bounded", options={"xatol": 1e-3, "maxiter": 14})
            if -r.fun > best[0]:
                best = (float(-r.fun), best[1], float(r.x))
            if bf is not None:
                best = self._refine_fn(score, best, bf, 1.05)
        out = {}
        if bf is not None:
            out["path_resonance_hz"] = best[1]
        if bz is not None:
            out["path_damping_ratio"] = best[2]
        return best[0], out

    @staticmethod
    def _refine_fn(score, best, bf: Bound, step: float):
        lo, hi = max(bf.lower, best[1] / step), min(bf.upper, best[1] * step)
        r = optimize.minimize_scalar(lambda lf: -score(math.exp(lf), best[2]), bounds=(math.log(lo), math.log(hi)),
                                     method="bounded", options={"xatol": 1e-3, "maxiter": 14})
        if -r.fun > best[0]:
            return (float(-r.fun), float(math.exp(r.x)), best[2])
        return best

    # -------------------------------------------------------------- the objective
    def key(self, u: np.ndarray) -> tuple:
        return tuple(float(f"{b.to_value(x):.10g}") for b, x in zip(self.struct, u))

    def pcc(self, u: np.ndarray) -> float:
        u = np.clip(np.asarray(u, dtype=np.float64), 0.0, 1.0)
        k = self.key(u)
        if k in self.cache:
            return self.cache[k][0]
        if self.n_sims >= self.limit:
            raise _BudgetSpent
        raw = self.simulate_raw(self.struct_values(u))
        if raw is None:
            s, pv = -1.0, {}
        else:
            s, pv = self.fit_path(raw)
            if not self.raw:  # keep the first (base) record for the "before" score
                self.raw[k] = raw
        self.cache[k] = (s, pv)
        if s > self.best[0]:
            self.best = (s, u.copy(), pv)
        self.history.append(self.best[0])
        if self.progress is not None:
            self.progress(self.n_sims, self.budget, self.best[0])
        return s

    def loss(self, u: np.ndarray) -> float:
        return 1.0 - self.pcc(u)


def update_parameters(
    base: ReducerParams,
    measured: np.ndarray,
    fs: float,
    *,
    output_speed_deg_s: float,
    load_Nm: float,
    objective: str = "logspec",
    names: list[str] | tuple[str, ...] | None = None,
    duration_s: float = 0.5,
    transient_s: float = 0.1,
    channel: int = 0,
    max_evals: int = 150,
    seed: int = 0,
    min_gain: float = MIN_PCC_GAIN,
    progress: Callable[[int, int, float], None] | None = None,
) -> UpdateResult:
    """Tune the parameters ``names`` (default all of :data:`rvdiag.updating.space.TUNABLES`) of ``base``.

    Parameters
    ----------
    base : ReducerParams
        Starting set; the values not tuned are kept.
    measured : ndarray, 1-D
        Measured healthy record (m/s^2 or any unit: every objective is gain-invariant), at least ``duration_s``
        long.
    fs : float
        Its sampling rate (Hz); the simulations run at the same rate.
    output_speed_deg_s, load_Nm : float
        Operating point of the measured record.
    objective : {"logspec", "envelope", "time"}
    names : list of str, optional
    duration_s, transient_s : float
        Simulated record length per evaluation and the run-in discarded before it (s).
    channel : int
        Simulated channel compared with the measured one (0 = x, 1 = y).
    max_evals : int
        Simulations allowed in all (the base, the search and the final check).
    seed : int
        Seed of the differential evolution; the result depends on nothing else.
    min_gain : float
        PCC gain over the base set that the best set found must exceed to replace it (default
        :data:`MIN_PCC_GAIN`); below it the base set is returned unchanged.
    progress : callable, optional
        ``progress(simulations_done, max_evals, best_pcc)``.

    Returns
    -------
    UpdateResult
    """
    measured = np.asarray(measured, dtype=np.float64).ravel()
    finite_number(fs, "fs", 0, strict=True, noun="a number")
    finite_number(duration_s, "duration_s", 0, strict=True, noun="a number")
    n_sim = int(round(duration_s * fs))
    if measured.size < n_sim:
        raise ParameterError(f"the measured record has {measured.size} samples ({measured.size / fs:.3g} s); "
                             f"model updating needs at least {duration_s:g} s ({n_sim} samples)")
    if max_evals < 3:
        raise ParameterError(f"max_evals must be >= 3 (base, one search point, final check), got {max_evals}")
    if not (math.isfinite(min_gain) and min_gain >= 0):
        raise ParameterError(f"min_gain must be >= 0, got {min_gain}")
    obj = Objective(objective, measured, fs, n_sim)
    bounds = bounds_for(base, names, fs)
    settings = ModelSettings(transient_s=transient_s, substeps=max(2, math.ceil(_STEP_RATE_HZ / fs)))
    sim = dict(output_speed_deg_s=output_speed_deg_s, load_Nm=load_Nm, duration_s=duration_s, fs=fs,
               settings=settings)
    ev = _Evaluator(base, bounds, obj, sim, channel, max_evals, progress)
    ev.limit = max_evals - 1  # keep one simulation for the final check
    struct = ev.struct
    u0 = np.array([b.to_unit(b.base) for b in struct])

    ev.pcc(u0)
    raw0 = next(iter(ev.raw.values()), None)
    if raw0 is None:
        raise ParameterError("the base parameter set does not simulate (integration failed)")
    m = base.mounting
    signal_before = ev.filtered(raw0, m.path_resonance_hz, m.path_damping_ratio)
    pcc_before = obj.score(signal_before)

    d = len(struct)
    if d > 0:
        rng = np.random.default_rng(seed)
        search = ev.limit - ev.n_sims
        n_de = max(1, int(round(0.7 * search)))
        pop = max(5, (2 if d >= 3 else 3) * d)
        ev.limit = ev.n_sims + n_de
        try:
            optimize.differential_evolution(ev.loss, [(0.0, 1.0)] * d, popsize=max(1, pop // d), rng=rng,
                                            maxiter=max(1, n_de // pop - 1), polish=False, x0=u0, tol=1e-3,
                                            init="latinhypercube", updating="immediate", workers=1)
        except _BudgetSpent:
            pass
        ev.limit = max_evals - 1
        if ev.n_sims < ev.limit and ev.best[1] is not None:
            x0 = ev.best[1]
            simplex = [x0] + [_step(x0, i, 0.1) for i in range(d)]
            try:
                optimize.minimize(ev.loss, x0, method="Nelder-Mead", bounds=[(0.0, 1.0)] * d,
                                  options={"initial_simplex": np.array(simplex), "maxfev": 10 * ev.limit,
                                           "xatol": 1e-3, "fatol": 1e-4})
            except _BudgetSpent:
                pass

    _, u_best, path_best = ev.best
    found = ev.struct_values(u_best)
    found.update(path_best)
    after = {b.name: _unless_unmoved(b.base, float(found.get(b.name, b.base))) for b in bounds}
    moved = tuple(b.name for b in bounds if after[b.name] != b.base)
    params_after, signal_after, pcc_after, gain = base, signal_before, pcc_before, 0.0
    if moved:
        candidate = apply_values(base, {name: after[name] for name in moved})
        ev.n_sims += 1
        res = simulate(candidate, None, **sim)
        signal = np.asarray(res.signal[channel], dtype=np.float64)
        score = obj.score(signal)
        gain = score - pcc_before
        if gain > min_gain:
            params_after, signal_after, pcc_after = candidate, signal, score
        else:
            moved = ()
    table = {b.name: (b.base, after[b.name] if b.name in moved else b.base) for b in bounds}
    return UpdateResult(
        params_before=base, params_after=params_after, objective=objective, pcc_before=pcc_before,
        pcc_after=pcc_after, values=table, updated=moved, best_gain=gain, min_gain=min_gain,
        evaluations=ev.n_sims, seed=seed, fs=fs, measured=measured, signal_before=signal_before,
        signal_after=signal_after, history=ev.history,
    )


def _unless_unmoved(base: float, value: float) -> float:
    """``value``, or exactly ``base`` when it lies within :data:`MOVED_RTOL` of it."""
    return base if math.isclose(value, base, rel_tol=MOVED_RTOL, abs_tol=0.0) else value


def _step(x0: np.ndarray, i: int, h: float) -> np.ndarray:
    """``x0`` moved by ``h`` along axis ``i``, backwards where forwards would leave the unit cube."""
    x = x0.copy()
    x[i] = x[i] + h if x[i] + h <= 1.0 else x[i] - h
    return x
