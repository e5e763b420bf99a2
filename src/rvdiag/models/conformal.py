"""Class-conditional ("Mondrian") split-conformal prediction sets for any classifier with ``predict_proba``.

A classifier that must name one state names one even where it cannot tell two apart (across reducers a root crack
is barely separable from healthy: docs/results.md).  A prediction set names every state the model cannot rule out,
with a stated coverage: the probability that the true state is in the set.

Score and sets
--------------
The conformity score of a sample of state y is the LAC score ``s = 1 - p_y`` (Sadinle, Lei & Wasserman, "Least
ambiguous set-valued classifiers with bounded error levels", JASA 114 (2019) 223-234), ``p_y`` the classifier's
probability of the true state.  Calibration is per state, "Mondrian" (Vovk, "Conditional validity of inductive
conformal predictors", ACML 2012, PMLR 25: 475-490, label-conditional ICP; Angelopoulos & Bates, "A gentle
introduction to conformal prediction and distribution-free uncertainty quantification", 2021, Sec. 4.5
"class-conditional conformal prediction"): for each state c with ``n_c`` calibration samples of that state and a
stated coverage ``1 - alpha_c``, its threshold ``q_c`` is the ``ceil((n_c + 1)(1 - alpha_c))``-th smallest of their
scores (``inf`` when that rank exceeds ``n_c``: too few samples of c to exclude it at that level, so c is in every
set).  The prediction set of a sample with probabilities ``p`` is ``{c : 1 - p_c <= q_c}``, and where that is empty
(every state less probable than its calibration samples were: a sample unlike them all), the most probable state
``argmax p``: a set that only grows keeps the guarantee, and a user is never told "no state" by a set (the
out-of-distribution check says when a record is unlike the training data).

Guarantee (Vovk 2012, Prop. 4; Angelopoulos & Bates eq. 11): for a new sample of state c exchangeable with the
calibration samples of c, ``1 - alpha_c <= P(c in set) < 1 - alpha_c + 1/(n_c + 1)`` (the upper bound without ties),
for each state separately, whatever the other states' share.  By default T1 (healthy) is covered at 95 % and each
fault at 90 %: no more than 5 % of healthy samples get a set without T1.

Which samples are exchangeable
------------------------------
Windows of one reducer share its manufacturing errors, path and noise floor: they are not exchangeable with another
reducer's, and a model scores the windows of the reducers it trained on better than a new reducer's.  So the
calibration samples must come from reducers the model never trained on (``rvdiag train`` holds out whole reducers
of each state, :func:`split_by_group`, or with ``--calibration cross`` scores each training reducer by a model fitted
on the other folds of reducers, :func:`group_folds`, and applies the thresholds to the model refitted on all: the
cross-conformal / CV+ construction of Vovk, "Cross-conformal predictors", Ann. Math. Artif. Intell. 74 (2015) 9-28,
and Barber et al. 2021, whose guarantee is 1 - 2 alpha in the worst case, near 1 - alpha for a stable fit), and the guarantee holds for a new reducer only as well as the calibration
reducers represent it.

Which threshold for a new reducer (``rule``)
--------------------------------------------
A user asks how often the set of a window of *their* reducer holds its state: a new group, not a new window of the
calibration groups.  The windows of one reducer are exchangeable among themselves and the reducers among themselves
(two-layer hierarchical exchangeability: Dunn, Wasserman & Ramdas, "Distribution-free prediction sets for two-layer
hierarchical models", JASA 118 (2023) 2491-2502; Lee, Barber & Willett, "Distribution-free inference with
hierarchical data", 2023, arXiv:2306.06342), but the windows of K reducers are not K N exchangeable samples, so the
finite-sample correction of the window-pooled quantile counts the wrong samples:

- ``"reducers"``: the hierarchical conformal threshold of Lee, Barber &
  Willett, :func:`reducer_threshold`, the (1 - alpha) quantile of each state's calibration scores weighted
  ``1 / ((K + 1) N_k)`` per reducer, with ``1 / (K + 1)`` at +inf.  A window of a new reducer exchangeable with the
  K is in the set with probability at least 1 - alpha; it needs ``ceil(1/alpha) - 1`` reducers of the state (19
  for 95 %, 9 for 90 %), whatever their windows.  With equal N it is the ``ceil(N (K + 1)(1 - alpha))``-th smallest
  score, where the pooled rule takes the ``ceil((N K + 1)(1 - alpha))``-th.
- ``"windows"`` (the default): every window one exchangeable sample, :func:`conformal_threshold` (Dunn et al.'s CDF pooling with the
  window count's correction).  Where the reducers differ more than their windows it under-covers a new reducer: by
  up to about (1 - alpha) / (K + 1) (tests/test_conformal.py has the known answer: 84.6 % for 90 % with 12
  reducers, where the hierarchical threshold gives 92.3 %).

Neither makes the coverage of *one* new reducer 1 - alpha: it is the mean over new reducers; one reducer's own
share varies around it (on the demo's held-out reducers a rig of one reducer per state reads 81-98 % for 90.8 %
stated, 90 % of the time: bench/set_coverage.py), and a reducer unlike the calibration reducers (another rig,
another sensor) is not exchangeable with them at all.  Measured on the rig of bench/hidden_rig.py (seed 1 / 2),
overall 87.2 / 95.2 % with ``windows`` and 91.8 / 96.0 % with ``reducers``, of 90.8 % stated: the rig's one reducer
per state moves the figure more than the rule does, so ``windows`` stays the default (bench/HISTORY.md,
"prediction sets on a reducer nobody trained on").

Why not MAPIE
-------------
MAPIE 1.x (scikit-learn-contrib; 1.6.0 checked) has no label-conditional classification sets: its
``SplitConformalClassifier`` takes one confidence level and one quantile over all classes (marginal coverage), the
``MondrianCP`` of 0.9 was removed in 1.0, and its ``ConditionalSplitConformalClassifier`` (Gibbs, Cherian & Candes
2023) conditions on a feature map of ``x``, not on the label, and needs cvxpy.  Its estimators wrap a fitted
scikit-learn estimator, while the calibration here must be stored as JSON in the model card and applied to
probabilities a model already computed.  So the few lines are written here, and tests/test_conformal.py checks them
against MAPIE's ``SplitConformalClassifier`` (LAC, prefit) run once per state on that state's calibration samples,
which is the same Mondrian construction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rvdiag.errors import ModelFileError, ParameterError

#: the stated coverage of the healthy state's set membership by default (no healthy record gets a set
#: without T1 at more than 5 %)
HEALTHY_COVERAGE = 0.95
#: the stated coverage of each fault state by default
FAULT_COVERAGE = 0.90
#: the healthy state of rvdiag's libraries
HEALTHY = "T1"
#: the calibration rules (module docstring): ``windows`` (every window one exchangeable sample, the default) and
#: ``reducers`` (hierarchical conformal over the reducers)
RULES = ("reducers", "windows")
METHODS = {
    "reducers": ("class-conditional (Mondrian) hierarchical conformal, LAC score 1 - p_y, threshold the (1-alpha) "
                 "quantile of each state's calibration scores weighted 1/((K+1) N_k) per reducer of its K (Lee, "
                 "Barber & Willett 2023): a new reducer's window is covered; an empty set gets the most probable "
                 "state"),
    "windows": ("class-conditional (Mondrian) split-conformal, LAC score 1 - p_y, threshold the ceil((n+1)(1-alpha))-th "
                "smallest calibration score of each state; an empty set gets the most probable state"),
}


def conformal_threshold(scores, alpha: float) -> float:
    """The split-conformal threshold of calibration ``scores`` for a miscoverage (false-alarm) rate ``alpha``: their
    ceil((n + 1)(1 - alpha))-th smallest value (Lei et al., "Distribution-free predictive inference for
    regression", JASA 113 (2018), Eq. 2); ``inf`` when that exceeds n (too few calibration samples for this
    ``alpha``).  The one home of this quantile: the monitor's alarm (:mod:`rvdiag.monitoring.detector`) and the
    prediction sets here use it.

    >>> conformal_threshold(np.arange(1.0, 100.0), 0.01)  # n = 99: the 99th smallest
    99.0
    """
    s = np.sort(np.asarray(scores, dtype=np.float64).ravel())
    k = conformal_rank(s.size, alpha)
    return float(s[k - 1]) if 1 <= k <= s.size else math.inf


def reducer_threshold(scores, groups, alpha: float) -> float:
    """The hierarchical conformal threshold of calibration ``scores`` from K ``groups`` (reducers) for a new group's
    sample at miscoverage ``alpha`` (Lee, Barber & Willett, "Distribution-free inference with hierarchical data",
    2023, arXiv:2306.06342, hierarchical conformal prediction): the (1 - alpha) quantile of the scores weighted
    ``1 / ((K + 1) N_k)`` each for the ``N_k`` scores of group k, with the weight ``1 / (K + 1)`` left at ``+inf``
    (``inf`` when the quantile falls there: fewer than ``ceil(1/alpha) - 1`` groups).  With N windows in every
    group it is the ``ceil(N (K + 1)(1 - alpha))``-th smallest of the N K scores, where the window-pooled
    :func:`conformal_threshold` takes the ``ceil((N K + 1)(1 - alpha))``-th: the finite-sample correction counts
    reducers, not windows.

    >>> s, g = np.arange(1.0, 21.0), np.repeat(np.arange(10), 2)  # 10 reducers of 2 windows
    >>> reducer_threshold(s, g, 0.1), conformal_threshold(s, 0.1)  # ranks ceil(2 * 11 * 0.9) = 20 and 19
    (20.0, 19.0)
    """
    s = np.asarray(scores, dtype=np.float64).ravel()
    g = np.asarray(groups).ravel()
    if g.size != s.size:
        raise ParameterError(f"{g.size} groups for {s.size} calibration scores")
    if not s.size:
        return math.inf
    _, inv = np.unique(g, return_inverse=True)
    counts = np.bincount(inv)
    order = np.argsort(s, kind="stable")
    cum = np.cumsum(1.0 / ((counts.size + 1) * counts[inv[order]]))
    k = int(np.searchsorted(cum, 1.0 - float(alpha) - 1e-12))
    return float(s[order[k]]) if k < s.size else math.inf


def conformal_rank(n: int, alpha: float) -> int:
    """ceil((n + 1)(1 - alpha)): the rank of the conformal quantile among n calibration scores (> n: too few).

    >>> conformal_rank(99, 0.05), conformal_rank(18, 0.05), conformal_rank(19, 0.05)
    (95, 19, 19)
    """
    return math.ceil((int(n) + 1) * (1.0 - float(alpha)) - 1e-9)


def min_calibration_samples(coverage: float) -> int:
    """The fewest calibration samples of a state for a finite threshold at ``coverage``: ceil(1/alpha) - 1 (windows
    for :func:`conformal_threshold`, reducers for :func:`reducer_threshold`).

    >>> min_calibration_samples(0.95), min_calibration_samples(0.9)
    (19, 9)
    """
    return math.ceil(1.0 / (1.0 - float(coverage)) - 1e-9) - 1


def stated_coverages(classes, healthy: str | None = HEALTHY, healthy_coverage: float = HEALTHY_COVERAGE,
                     fault_coverage: float = FAULT_COVERAGE) -> dict[str, float]:
    """The stated coverage of each class: ``healthy_coverage`` for ``healthy`` (None: no class is the healthy
    one), ``fault_coverage`` for the others; :class:`ParameterError` unless both lie in (0, 1)."""
    for name, v in (("healthy coverage", healthy_coverage), ("fault coverage", fault_coverage)):
        if not 0.0 < float(v) < 1.0:
            raise ParameterError(f"the {name} must lie strictly between 0 and 1, got {v}")
    return {str(c): float(healthy_coverage if str(c) == healthy else fault_coverage) for c in classes}


def lac_scores(proba, y, classes) -> np.ndarray:
    """The LAC conformity score ``1 - p_y`` of each sample (Sadinle et al. 2019): ``proba`` (n, k) in the order of
    ``classes``, ``y`` the true class names."""
    P = _proba(proba, classes)
    index = {str(c): i for i, c in enumerate(classes)}
    try:
        col = np.asarray([index[str(v)] for v in np.asarray(y).ravel()], dtype=np.int64)
    except KeyError as exc:
        raise ParameterError(f"calibration label {exc.args[0]!r} is not a class of the model "
                             f"({', '.join(map(str, classes))})") from None
    if col.size != P.shape[0]:
        raise ParameterError(f"{col.size} labels for {P.shape[0]} rows of probabilities")
    return 1.0 - P[np.arange(col.size), col]


def _proba(proba, classes) -> np.ndarray:
    P = np.asarray(proba, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != len(classes):
        raise ParameterError(f"probabilities must be (n, {len(classes)}), got shape {P.shape}")
    return P


@dataclass
class PredictionSets:
    """A class-conditional conformal calibration: per-class thresholds on the LAC score (module docstring).

    Attributes
    ----------
    classes : list of str, the model's classes (the columns of its ``predict_proba``)
    coverage : dict class -> stated coverage (1 - alpha_c)
    thresholds : dict class -> q_c (``inf``: too few calibration samples of the class, always in the set)
    n_calibration : dict class -> calibration samples of the class
    n_groups : dict class -> the reducers (groups) they come from (None when no groups were given)
    source : dict, how the calibration samples were obtained (stored in the card as is)
    rule : {"reducers", "windows"}, how the thresholds were computed (:data:`RULES`; a card without it: windows)
    """

    classes: list[str]
    coverage: dict[str, float]
    thresholds: dict[str, float]
    n_calibration: dict[str, int]
    n_groups: dict[str, int | None] = field(default_factory=dict)
    source: dict = field(default_factory=dict)
    rule: str = "windows"

    @classmethod
    def calibrate(cls, proba, y, classes, coverage: dict[str, float] | None = None, groups=None,
                  source: dict | None = None, rule: str | None = None) -> "PredictionSets":
        """Calibrate on held-out samples: ``proba`` (n, k) their probabilities in the order of ``classes``, ``y``
        their true classes, ``coverage`` the stated coverage per class (default :func:`stated_coverages`),
        ``groups`` the reducer of each sample (the caller must make sure the model never trained on them:
        :func:`split_by_group`, :func:`group_folds`), ``rule`` how the thresholds count the samples
        (:data:`RULES`): ``"windows"`` (:func:`conformal_threshold`, the default) or ``"reducers"``
        (:func:`reducer_threshold`, which needs ``groups``)."""
        classes = [str(c) for c in classes]
        coverage = stated_coverages(classes) if coverage is None else {str(k): float(v) for k, v in coverage.items()}
        missing = [c for c in classes if c not in coverage]
        if missing:
            raise ParameterError(f"no stated coverage for class(es) {', '.join(missing)}")
        for c, v in coverage.items():
            if not 0.0 < v < 1.0:
                raise ParameterError(f"the stated coverage of {c} must lie strictly between 0 and 1, got {v}")
        s = lac_scores(proba, y, classes)
        y = np.asarray(y).astype(str).ravel()
        g = None if groups is None else np.asarray(groups).ravel()
        if g is not None and g.size != y.size:
            raise ParameterError(f"{g.size} groups for {y.size} calibration samples")
        rule = rule or "windows"
        if rule not in RULES:
            raise ParameterError(f"the calibration rule must be one of {', '.join(RULES)}, got {rule!r}")
        if rule == "reducers" and g is None:
            raise ParameterError("the 'reducers' calibration rule needs the reducer (group) of each sample")
        thresholds, counts, n_groups = {}, {}, {}
        for c in classes:
            m = y == c
            thresholds[c] = (reducer_threshold(s[m], g[m], 1.0 - coverage[c]) if rule == "reducers"
                             else conformal_threshold(s[m], 1.0 - coverage[c]))
            counts[c] = int(np.sum(m))
            n_groups[c] = None if g is None else int(np.unique(g[m]).size)
        return cls(classes, {c: coverage[c] for c in classes}, thresholds, counts, n_groups, dict(source or {}), rule)

    def contains(self, proba, nonempty: bool = True) -> np.ndarray:
        """Boolean (n, k): whether each class is in each sample's prediction set, ``1 - p_c <= q_c``, or with
        ``nonempty`` the most probable class where no class passes (module docstring)."""
        P = _proba(proba, self.classes)
        q = np.asarray([self.thresholds[c] for c in self.classes], dtype=np.float64)
        inside = (1.0 - P) <= q[None, :]
        if not nonempty:
            return inside
        empty = ~inside.any(axis=1)
        inside[np.flatnonzero(empty), P[empty].argmax(axis=1)] = True
        return inside

    def prediction_set(self, proba) -> list[list[str]]:
        """The prediction set of each row of ``proba`` (n, k) (or of one row, shape (k,)): its classes, most
        probable first."""
        P = np.atleast_2d(np.asarray(proba, dtype=np.float64))
        inside = self.contains(P)
        out = []
        for p, m in zip(P, inside):
            order = np.argsort(-p, kind="stable")
            out.append([self.classes[i] for i in order if m[i]])
        return out

    def too_few(self) -> list[str]:
        """The classes with too few calibration samples for a finite threshold (in every set)."""
        return [c for c in self.classes if math.isinf(self.thresholds[c])]

    def to_card(self) -> dict:
        """JSON-ready dict for the model card (an infinite threshold written as null)."""
        return {"method": METHODS[self.rule], "rule": self.rule, "classes": list(self.classes),
                "coverage": dict(self.coverage),
                "thresholds": {c: (None if math.isinf(v) else float(v)) for c, v in self.thresholds.items()},
                "n_calibration": dict(self.n_calibration), "n_groups": dict(self.n_groups),
                "source": self.source}

    @classmethod
    def from_card(cls, d: dict) -> "PredictionSets":
        """The calibration stored by :meth:`to_card`; :class:`ModelFileError` if it is malformed."""
        try:
            classes = [str(c) for c in d["classes"]]
            th = {c: (math.inf if d["thresholds"][c] is None else float(d["thresholds"][c])) for c in classes}
            cov = {c: float(d["coverage"][c]) for c in classes}
            n = {c: int(d["n_calibration"][c]) for c in classes}
            groups = {c: (None if (d.get("n_groups") or {}).get(c) is None else int(d["n_groups"][c]))
                      for c in classes}
            rule = str(d.get("rule", "windows"))
            if rule not in RULES:
                raise ValueError(f"unknown rule {rule!r}")
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelFileError(f"the model card's prediction_sets are malformed ({type(exc).__name__}: {exc})") \
                from None
        return cls(classes, cov, th, n, groups, dict(d.get("source") or {}), rule)


def from_card(card: dict) -> PredictionSets | None:
    """The calibration of a model card (key ``prediction_sets``), or None for a model trained without one."""
    d = card.get("prediction_sets")
    if not d:
        return None
    ps = PredictionSets.from_card(d)
    if ps.classes != [str(c) for c in card.get("classes", ps.classes)]:
        raise ModelFileError("the model card's prediction_sets name other classes than the model's")
    return ps


#: what a model without a calibration says instead of a set
NOT_CALIBRATED = ("this model was trained before rvdiag stored a conformal calibration: no prediction set "
                  "(retrain it with 'rvdiag train' to get one)")


def set_metrics(inside: np.ndarray, y, classes, coverage: dict[str, float]) -> dict:
    """Empirical coverage and mean size of prediction sets.

    Parameters
    ----------
    inside : bool (n, k), :meth:`PredictionSets.contains`
    y : the true class of each sample
    classes : the columns of ``inside``
    coverage : the stated coverage per class

    Returns
    -------
    dict: ``n``, ``stated_coverage`` (the stated coverages weighted by the evaluated samples' classes), ``coverage``
    (share of samples whose set holds their true class), ``mean_size``, ``singletons`` (share of sets of one state),
    ``empty`` (share of empty sets) and ``per_state`` (class -> ``n``, ``stated_coverage``, ``coverage``,
    ``mean_size`` of the samples of that true class; classes absent from ``y`` left out).
    """
    classes = [str(c) for c in classes]
    y = np.asarray(y).astype(str).ravel()
    inside = np.asarray(inside, dtype=bool)
    col = {c: i for i, c in enumerate(classes)}
    known = np.asarray([v in col for v in y])
    hit = np.zeros(y.size, dtype=bool)
    hit[known] = inside[np.flatnonzero(known), [col[v] for v in y[known]]]
    size = inside.sum(axis=1)
    per = {}
    for c in classes:
        m = y == c
        if m.any():
            per[c] = {"n": int(m.sum()), "stated_coverage": float(coverage[c]), "coverage": float(hit[m].mean()),
                      "mean_size": float(size[m].mean())}
    n = int(y.size)
    stated = float(sum(v["n"] * v["stated_coverage"] for v in per.values()) / n) if n else math.nan
    return {"n": n, "stated_coverage": stated, "coverage": float(hit.mean()) if n else math.nan,
            "mean_size": float(size.mean()) if n else math.nan,
            "singletons": float(np.mean(size == 1)) if n else math.nan,
            "empty": float(np.mean(size == 0)) if n else math.nan, "per_state": per}


def split_by_group(y, groups, fraction: float, seed) -> np.ndarray:
    """A calibration mask that holds out whole groups (reducers) of each class: ``round(fraction * G_c)`` of the
    ``G_c`` groups of class c, at least one when ``G_c >= 2`` and never all of them (a class of one group keeps it for
    training, and gets no calibration sample: it is then in every set).  Drawn with ``numpy.random.default_rng(seed)``,
    class by class in sorted order; groups are taken within a class (the same group name under two classes is two
    groups).  Returns a boolean mask of the calibration samples."""
    if not 0.0 < float(fraction) < 1.0:
        raise ParameterError(f"the calibration fraction must lie strictly between 0 and 1, got {fraction}")
    y = np.asarray(y).astype(str).ravel()
    g = np.asarray(groups).ravel()
    if g.size != y.size:
        raise ParameterError(f"{g.size} groups for {y.size} samples")
    rng = np.random.default_rng(seed)
    cal = np.zeros(y.size, dtype=bool)
    for c in np.unique(y):
        in_c = y == c
        names = np.unique(g[in_c])
        if names.size < 2:
            continue
        k = min(max(1, int(round(float(fraction) * names.size))), names.size - 1)
        held = rng.choice(names, size=k, replace=False)
        cal |= in_c & np.isin(g, held)
    return cal


def group_folds(y, groups, folds: int, seed) -> np.ndarray:
    """The fold (0 .. ``folds`` - 1) of each sample for cross-conformal calibration over whole groups (reducers):
    each class's groups, in an order drawn with ``numpy.random.default_rng(seed)``, cut into ``folds`` nearly equal
    parts (:func:`numpy.array_split`), so every fold holds groups of every class; :class:`ParameterError` when a
    class has fewer groups than folds."""
    y = np.asarray(y).astype(str).ravel()
    g = np.asarray(groups).ravel()
    if int(folds) < 2:
        raise ParameterError(f"cross-conformal calibration needs at least 2 folds, got {folds}")
    rng = np.random.default_rng(seed)
    fold = np.zeros(y.size, dtype=np.int64)
    for c in np.unique(y):
        names = rng.permutation(np.unique(g[y == c]))
        if names.size < int(folds):
            raise ParameterError(f"class {c} has {names.size} reducer(s), fewer than the {folds} calibration folds")
        for k, part in enumerate(np.array_split(names, int(folds))):
            fold[(y == c) & np.isin(g, part)] = k
    return fold


def describe_set(states: list[str], coverage: float, names=None) -> str:
    """The set in words: ``"healthy or root crack (95 % set): this model cannot tell them apart on a reducer it has
    not seen"``; one state: ``"broken tooth (90 % set)"``; none: no state fits."""
    name = names or (lambda s: s)
    pct = f"{100 * coverage:g} % set"
    if not states:
        return f"no state ({pct}): the record is unlike every state the model calibrated on"
    words = [str(name(s)) for s in states]
    if len(words) == 1:
        return f"{words[0]} ({pct})"
    joined = ", ".join(words[:-1]) + f" or {words[-1]}"
    pronoun = "them" if len(words) == 2 else "these"
    return f"{joined} ({pct}): this model cannot tell {pronoun} apart on a reducer it has not seen"
