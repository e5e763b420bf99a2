"""Compound faults as several labels: three binary classifiers (broken, worn, cracked) decoded to T1..T6.

The six states of the reducer's sun gear are combinations of three faults:

=====  ======  ====  =======
state  broken  worn  cracked
=====  ======  ====  =======
T1     0       0     0
T2     1       0     0
T3     0       1     0
T4     0       0     1
T5     1       1     0
T6     1       1     1
=====  ======  ====  =======

:class:`CompoundFaultClassifier` fits one copy of a binary classifier per fault (each with
``predict_proba``) and decodes a sample to the state whose combination has the largest joint probability,
the product over the three faults of p_k (fault present in the state) or 1 - p_k (absent).  Only the
combinations of the states seen in training are candidates (a library without T6 never predicts it), so the
model's ``classes_`` are state names, ``predict`` returns one of them and ``predict_proba`` gives the joint
probabilities normalised over those states: every evaluation of a six-class model (confusion, accuracy,
``rvdiag evaluate``, ``rvdiag diagnose``) reads it unchanged.

``rvdiag train --model svm --multilabel`` puts it in place of the pipeline's classifier
(:func:`rvdiag.models.pipelines.make_classical_model` with ``multilabel=True``).  States with other names
(T7, T8 of other libraries, or measured classes) have no fault combination and are refused.
"""

from __future__ import annotations

import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin, clone
from sklearn.utils.validation import check_is_fitted

from rvdiag.errors import ParameterError
from rvdiag.gears.faults import FAULT_KINDS

#: The binary labels, in the order of the columns of :data:`STATE_FAULTS`.
FAULT_LABELS: tuple[str, ...] = ("broken", "worn", "cracked")

#: The fault kind of :data:`rvdiag.gears.faults.FAULT_KINDS` behind each label of :data:`FAULT_LABELS`.
_KINDS: tuple[str, ...] = ("broken", "wear", "crack")

#: Each state's fault combination (broken, worn, cracked), read from the library's own state table
#: (``"broken+wear+crack"``): the states made of those faults only, T1..T6.
STATE_FAULTS: dict[str, tuple[int, ...]] = {
    state: tuple(int(k in kinds.split("+")) for k in _KINDS) for state, kinds in FAULT_KINDS.items()
    if kinds == "healthy" or set(kinds.split("+")) <= set(_KINDS)
}

_EPS = 1e-12


def check_states(states, where: str = "the training labels") -> None:
    """:class:`ParameterError` (one line) unless every name in ``states`` is one of T1..T6."""
    unknown = sorted({str(s) for s in states} - set(STATE_FAULTS))
    if unknown:
        raise ParameterError(f"--multilabel needs the states T1..T6 (broken / worn / cracked combinations); "
                             f"{where} hold {', '.join(unknown)}, which have no fault combination: "
                             "train without --multilabel")


def fault_codes(states) -> np.ndarray:
    """The (n, 3) 0/1 matrix of (broken, worn, cracked) of each state name."""
    states = [str(s) for s in np.asarray(states, dtype=object).ravel()]
    check_states(states)
    return np.array([STATE_FAULTS[s] for s in states], dtype=np.int64).reshape(len(states), len(FAULT_LABELS))


def joint_probabilities(P: np.ndarray, classes) -> np.ndarray:
    """Joint probability of each state in ``classes`` from per-fault probabilities ``P`` (n, 3), normalised
    over those states: prod_k P[:, k] if the state has fault k else 1 - P[:, k] (computed in logs)."""
    P = np.clip(np.asarray(P, dtype=float), _EPS, 1.0 - _EPS)
    B = fault_codes(classes).astype(float)  # (m, 3)
    logp = np.log(P) @ B.T + np.log1p(-P) @ (1.0 - B).T  # (n, m)
    logp -= logp.max(axis=1, keepdims=True)
    J = np.exp(logp)
    return J / J.sum(axis=1, keepdims=True)


class CompoundFaultClassifier(ClassifierMixin, BaseEstimator):
    """One binary classifier per fault (broken, worn, cracked), decoded to the most probable state T1..T6.

    Parameters
    ----------
    estimator : classifier with ``predict_proba``
        Cloned once per fault and fitted on that fault's 0/1 labels.

    Attributes
    ----------
    classes_ : ndarray of str
        The states seen in training (a subset of T1..T6), sorted.
    estimators_ : list
        The fitted binary classifier of each fault in :data:`FAULT_LABELS` order, or None for a fault that is
        present in all or none of the training states (its probability is then ``constant_[k]``).
    constant_ : ndarray (3,)
        The probability used for a fault without a classifier (0 or 1; unused otherwise).
    """

    def __init__(self, estimator=None):
        self.estimator = estimator

    def fit(self, X, y):
        if self.estimator is None:
            raise ParameterError("CompoundFaultClassifier needs a binary classifier (estimator=...)")
        y = np.asarray(y, dtype=object).astype(str)
        codes = fault_codes(y)
        self.classes_ = np.unique(y)
        if self.classes_.size < 2:
            raise ParameterError("the training labels hold fewer than 2 states")
        self.estimators_, constant = [], np.zeros(len(FAULT_LABELS))
        for k in range(len(FAULT_LABELS)):
            yk = codes[:, k]
            if np.all(yk == yk[0]):
                self.estimators_.append(None)
                constant[k] = float(yk[0])
            else:
                self.estimators_.append(clone(self.estimator).fit(X, yk))
        self.constant_ = constant
        self.n_features_in_ = int(np.asarray(X).shape[1])
        return self

    def fault_probabilities(self, X) -> np.ndarray:
        """(n, 3) probability of each fault (broken, worn, cracked) being present."""
        check_is_fitted(self, "estimators_")
        n = np.asarray(X).shape[0]
        P = np.empty((n, len(FAULT_LABELS)))
        for k, est in enumerate(self.estimators_):
            if est is None:
                P[:, k] = self.constant_[k]
            else:
                col = list(np.asarray(est.classes_).tolist()).index(1)
                P[:, k] = np.asarray(est.predict_proba(X), dtype=float)[:, col]
        return P

    def predict_proba(self, X) -> np.ndarray:
        """Joint probability of each state of ``classes_``, normalised over them."""
        return joint_probabilities(self.fault_probabilities(X), self.classes_)

    def predict(self, X) -> np.ndarray:
        return self.classes_[np.argmax(self.predict_proba(X), axis=1)]


__all__ = ["CompoundFaultClassifier", "FAULT_LABELS", "STATE_FAULTS", "check_states", "fault_codes",
           "joint_probabilities"]
