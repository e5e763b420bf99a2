"""Tuning KELM's (C, sigma) by cross-validated accuracy with MPA, GA or PSO (mealpy 3.0.3).

The EEMD-MPA-KELM study (Tu et al. 2023) tunes the regularisation C and the kernel width sigma of a KELM with the
Marine Predators Algorithm (Faramarzi, Heidarinejad, Mirjalili & Gandomi, "Marine Predators Algorithm: a
nature-inspired metaheuristic", Expert Syst. Appl. 152 (2020) 113377) and compares a genetic algorithm
(Holland 1975; mealpy ``BaseGA``) and particle swarm optimisation (Kennedy & Eberhart 1995; mealpy
``OriginalPSO``).  The optimisers come from mealpy, pinned to 3.0.3 in ``constraints.txt``:
``mealpy.swarm_based.MPA.OriginalMPA``, ``mealpy.evolutionary_based.GA.BaseGA``,
``mealpy.swarm_based.PSO.OriginalPSO``.

Search space: x = (log10 C, log10 (sigma / sqrt(d))), d the number of features.  The sqrt(d) scaling makes
the sigma bounds independent of the feature count: for standardised features ||x - y||^2 is of order 2d.
Objective: mean accuracy over ``cv`` stratified folds (shuffled with ``random_state``), maximised.  The squared
distance matrices of every fold are computed once, so one evaluation costs one exp and one Cholesky solve
per fold.  Runs are reproducible: the folds and the optimiser both take ``random_state`` (``seed`` in the
functions :func:`minimize` / :func:`maximize`).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.model_selection import StratifiedKFold
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from rvdiag.errors import ParameterError
from rvdiag.models.kelm import KELMClassifier, one_hot_pm1, solve_output_weights, sq_distances
from rvdiag.progress import report
from rvdiag.validation import integer

#: optimiser name -> (mealpy module, class); the names of ``rvdiag train --model kelm-<name>``
OPTIMIZERS = {
    "mpa": ("mealpy.swarm_based.MPA", "OriginalMPA"),
    "ga": ("mealpy.evolutionary_based.GA", "BaseGA"),
    "pso": ("mealpy.swarm_based.PSO", "OriginalPSO"),
}


@dataclass
class OptimizeResult:
    """Result of :func:`maximize` / :func:`minimize`: best point, its value, best value per epoch."""

    x: np.ndarray
    fun: float
    history: list[float] = field(default_factory=list)
    n_evaluations: int = 0


def _optimizer(name: str, epoch: int, pop_size: int):
    if name not in OPTIMIZERS:
        raise ParameterError(f"unknown optimizer {name!r}; use one of {sorted(OPTIMIZERS)}")
    if not (isinstance(epoch, (int, np.integer)) and epoch >= 1):
        raise ParameterError(f"epoch must be a positive integer, got {epoch!r}")
    integer(pop_size, "pop_size", 10)  # mealpy's GA tournament takes k = 0.2 pop_size parents and needs k >= 2
    mod, cls = OPTIMIZERS[name]
    return getattr(importlib.import_module(mod), cls)(epoch=int(epoch), pop_size=int(pop_size))


def _run(func, lb, ub, optimizer, epoch, pop_size, seed, minmax) -> OptimizeResult:
    from mealpy import FloatVar

    lb = [float(v) for v in lb]
    ub = [float(v) for v in ub]
    if len(lb) != len(ub) or not all(a < b for a, b in zip(lb, ub)):
        raise ParameterError(f"bounds must satisfy lb < ub elementwise, got {lb}, {ub}")
    count = [0]
    # mealpy evaluates the initial population, then pop_size points per epoch (checked for mpa, ga, pso)
    total = int(pop_size) * (int(epoch) + 1)

    def f(x):
        count[0] += 1
        value = float(func(np.asarray(x, dtype=float)))
        report(f"{optimizer.upper()} tuning", count[0], max(total, count[0]))  # rvdiag.progress
        return value

    model = _optimizer(optimizer, epoch, pop_size)
    problem = {"obj_func": f, "bounds": FloatVar(lb=lb, ub=ub), "minmax": minmax, "log_to": None}
    best = model.solve(problem, seed=int(seed))
    hist = [float(v) for v in model.history.list_global_best_fit]
    return OptimizeResult(np.array(best.solution, dtype=float), float(best.target.fitness), hist, count[0])


def minimize(func: Callable[[np.ndarray], float], lb: Sequence[float], ub: Sequence[float],
             optimizer: str = "mpa", epoch: int = 50, pop_size: int = 20, seed: int = 0) -> OptimizeResult:
    """Minimise ``func`` over the box [lb, ub] with a mealpy optimiser (``'mpa'``, ``'ga'``, ``'pso'``)."""
    return _run(func, lb, ub, optimizer, epoch, pop_size, seed, "min")


def maximize(func: Callable[[np.ndarray], float], lb: Sequence[float], ub: Sequence[float],
             optimizer: str = "mpa", epoch: int = 50, pop_size: int = 20, seed: int = 0) -> OptimizeResult:
    """Maximise ``func`` over the box [lb, ub]; see :func:`minimize`."""
    return _run(func, lb, ub, optimizer, epoch, pop_size, seed, "max")


class KELMCVObjective:
    """Mean cross-validated accuracy of a KELM as a function of x = (log10 C, log10(sigma/sqrt(d)))."""

    def __init__(self, X: np.ndarray, y_idx: np.ndarray, n_classes: int, cv: int, seed: int):
        self.d = X.shape[1]
        folds = StratifiedKFold(n_splits=cv, shuffle=True, random_state=seed).split(X, y_idx)
        self.folds = []
        for tr, va in folds:
            self.folds.append((
                sq_distances(X[tr], X[tr]), sq_distances(X[va], X[tr]),
                one_hot_pm1(y_idx[tr], n_classes), y_idx[va],
            ))

    def params(self, x) -> tuple[float, float]:
        """(C, sigma) of a search point."""
        return 10.0 ** float(x[0]), 10.0 ** float(x[1]) * np.sqrt(self.d)

    def __call__(self, x) -> float:
        C, sigma = self.params(x)
        s2 = sigma * sigma
        acc = 0.0
        for Dtr, Dva, Ttr, yva in self.folds:
            beta = solve_output_weights(np.exp(-Dtr / s2), Ttr, C)
            acc += np.mean(np.argmax(np.exp(-Dva / s2) @ beta, axis=1) == yva)
        return acc / len(self.folds)


class TunedKELM(ClassifierMixin, BaseEstimator):
    """KELM whose (C, sigma) are chosen by MPA, GA or PSO on cross-validated accuracy.

    Parameters
    ----------
    optimizer : {'mpa', 'ga', 'pso'}
        mealpy optimiser (see :data:`OPTIMIZERS`).
    epoch, pop_size : int
        Iterations and population of the optimiser; epoch x pop_size evaluations of the objective.
    cv : int
        Stratified folds (reduced to the smallest class count when that is lower).
    random_state : int
        Seed of the folds and of the optimiser.
    log10_C_bounds : (float, float)
        Search range of log10 C.
    log10_sigma_bounds : (float, float)
        Search range of log10(sigma / sqrt(n_features)).

    Attributes
    ----------
    best_params_ : dict
        ``{"C": ..., "sigma": ...}`` found.
    best_score_ : float
        Their cross-validated accuracy.
    history_ : list of float
        Best accuracy after each epoch (non-decreasing).
    n_evaluations_ : int
    estimator_ : KELMClassifier
        Refitted on all the data with ``best_params_``.
    classes_ : ndarray
    """

    def __init__(self, optimizer: str = "mpa", epoch: int = 20, pop_size: int = 20, cv: int = 5,
                 random_state: int = 0, log10_C_bounds: tuple[float, float] = (-2.0, 4.0),
                 log10_sigma_bounds: tuple[float, float] = (-1.5, 1.5)):
        self.optimizer = optimizer
        self.epoch = epoch
        self.pop_size = pop_size
        self.cv = cv
        self.random_state = random_state
        self.log10_C_bounds = log10_C_bounds
        self.log10_sigma_bounds = log10_sigma_bounds

    def fit(self, X, y):
        """Search (C, sigma), then refit a KELM on all of (X, y).  Returns ``self``."""
        X, y = validate_data(self, X, y, dtype=np.float64)
        check_classification_targets(y)
        self.classes_, y_idx = np.unique(y, return_inverse=True)
        if self.classes_.size < 2:
            raise ParameterError(f"tuning needs at least 2 classes in y; got {self.classes_.size} class")
        min_count = int(np.bincount(y_idx).min())
        integer(self.cv, "cv", 2)
        n_splits = min(int(self.cv), min_count)
        if n_splits < 2:
            raise ParameterError("every class needs at least 2 samples for cross-validated tuning")
        obj = KELMCVObjective(X, y_idx, self.classes_.size, n_splits, int(self.random_state))
        lb = (self.log10_C_bounds[0], self.log10_sigma_bounds[0])
        ub = (self.log10_C_bounds[1], self.log10_sigma_bounds[1])
        res = maximize(obj, lb, ub, self.optimizer, self.epoch, self.pop_size, int(self.random_state))
        C, sigma = obj.params(res.x)
        self.best_params_ = {"C": float(C), "sigma": float(sigma)}
        self.best_score_ = res.fun
        self.history_ = res.history
        self.n_evaluations_ = res.n_evaluations
        self.estimator_ = KELMClassifier(C=C, sigma=sigma).fit(X, y)
        return self

    def _est(self):
        check_is_fitted(self, "estimator_")
        return self.estimator_

    def predict(self, X):
        """Predicted classes of the refitted KELM."""
        return self._est().predict(X)

    def predict_proba(self, X):
        """Softmax outputs of the refitted KELM."""
        return self._est().predict_proba(X)

    def decision_function(self, X):
        """Outputs of the refitted KELM."""
        return self._est().decision_function(X)
