"""Kernel extreme learning machine (KELM) classifier, scikit-learn compatible.

Huang, Zhou, Ding & Zhang, "Extreme learning machine for regression and multiclass classification",
IEEE Trans. Syst. Man Cybern. B 42 (2012) 513-529, section IV-B, Eqs. (38)-(40): with the kernel matrix
Omega_ij = K(x_i, x_j) of the N training samples and the target matrix T (N x m, one column per class,
+1 for the sample's class and -1 elsewhere, their section IV-A), the output weights are

    beta = (I / C + Omega)^-1 T                                    (Huang et al. 2012, Eq. (38)/(40))

and the output for a new x is f(x) = [K(x, x_1), ..., K(x, x_N)] beta; the predicted class is the
argmax of f(x).

Kernel: the Gaussian (RBF) kernel K(x, y) = exp(-||x - y||^2 / sigma^2).  Conventions differ: Huang's
reference MATLAB code (``elm_kernel.m``, ``kernel_matrix``) writes exp(-||x - y||^2 / sigma) with the
parameter standing for sigma^2; papers on EEMD-MPA-KELM diagnosis usually print exp(-||x - y||^2 / sigma^2)
or exp(-||x - y||^2 / (2 sigma^2)).  Tu et al. 2023's exact text could not be checked here (it was not
available), so this module uses exp(-||x - y||^2 / sigma^2), i.e. scikit-learn's RBF ``gamma = 1/sigma^2``;
a tuner searching log(sigma) is unaffected by the choice up to a constant shift.

``predict_proba`` maps the outputs through a softmax (a monotone map, not a calibrated probability; for
two classes it is a logistic function of the ``decision_function``).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from rvdiag.errors import ParameterError
from rvdiag.validation import finite_number


def sq_distances(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Squared Euclidean distances ||a_i - b_j||^2, shape (len(A), len(B)), clipped at 0."""
    d = (A * A).sum(1)[:, None] + (B * B).sum(1)[None, :] - 2.0 * (A @ B.T)
    return np.maximum(d, 0.0)


def rbf_kernel(A: np.ndarray, B: np.ndarray, sigma: float) -> np.ndarray:
    """K(a, b) = exp(-||a - b||^2 / sigma^2)."""
    return np.exp(-sq_distances(A, B) / (sigma * sigma))


def solve_output_weights(Omega: np.ndarray, T: np.ndarray, C: float) -> np.ndarray:
    """beta = (I/C + Omega)^-1 T (Huang et al. 2012, Eq. (38)), by Cholesky; least squares if singular."""
    A = Omega + np.eye(Omega.shape[0]) / C
    try:
        return scipy.linalg.solve(A, T, assume_a="pos", check_finite=False)
    except (np.linalg.LinAlgError, scipy.linalg.LinAlgError):
        return np.linalg.lstsq(A, T, rcond=None)[0]


def one_hot_pm1(y_idx: np.ndarray, n_classes: int) -> np.ndarray:
    """Targets +1 for the class, -1 elsewhere (Huang et al. 2012, section IV-A)."""
    T = -np.ones((y_idx.size, n_classes))
    T[np.arange(y_idx.size), y_idx] = 1.0
    return T


class KELMClassifier(ClassifierMixin, BaseEstimator):
    """Kernel extreme learning machine with a Gaussian kernel (Huang et al. 2012).

    Parameters
    ----------
    C : float
        Regularisation coefficient (> 0); larger fits the training data more closely.
    sigma : float or "scale"
        Kernel width (> 0) in K(x, y) = exp(-||x - y||^2 / sigma^2), in the units of the features.
        ``"scale"`` uses sigma^2 = n_features * X.var(), the analogue of scikit-learn's SVC
        ``gamma="scale"`` (the same kernel as a default SVC).

    Attributes
    ----------
    classes_ : ndarray
        Class labels.
    X_fit_ : ndarray (N, d)
        Training inputs (the kernel expansion needs them).
    beta_ : ndarray (N, m)
        Output weights.
    sigma_ : float
        Kernel width used.
    n_features_in_ : int

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[0.0], [0.1], [1.0], [1.1]]); y = np.array([0, 0, 1, 1])
    >>> KELMClassifier(C=10, sigma=1).fit(X, y).predict([[0.05], [1.05]]).tolist()
    [0, 1]
    """

    def __init__(self, C: float = 1.0, sigma: float | str = "scale"):
        self.C = C
        self.sigma = sigma

    def _check_params(self):
        for name in ("C", "sigma"):
            v = getattr(self, name)
            if name == "sigma" and isinstance(v, str) and v == "scale":
                continue
            finite_number(v, f"KELM {name}", 0, strict=True)

    def fit(self, X, y):
        """Compute beta = (I/C + Omega)^-1 T from the training set.  Returns ``self``."""
        self._check_params()
        X, y = validate_data(self, X, y, dtype=np.float64)
        check_classification_targets(y)
        self.classes_, y_idx = np.unique(y, return_inverse=True)
        if self.classes_.size < 2:
            raise ParameterError(
                f"KELM needs at least 2 classes in y; got {self.classes_.size} class"
            )
        self.X_fit_ = X
        if isinstance(self.sigma, str):
            v = float(X.var())
            self.sigma_ = float(np.sqrt(X.shape[1] * v)) if v > 0 else 1.0
        else:
            self.sigma_ = float(self.sigma)
        Omega = rbf_kernel(X, X, self.sigma_)
        self.beta_ = solve_output_weights(Omega, one_hot_pm1(y_idx, self.classes_.size), float(self.C))
        return self

    def _outputs(self, X) -> np.ndarray:
        check_is_fitted(self, "beta_")
        X = validate_data(self, X, dtype=np.float64, reset=False)
        return rbf_kernel(X, self.X_fit_, self.sigma_) @ self.beta_

    def decision_function(self, X) -> np.ndarray:
        """Network outputs f(x) (n, n_classes); for two classes the 1-D score f_1(x) - f_0(x)."""
        F = self._outputs(X)
        if F.shape[1] == 2:
            return F[:, 1] - F[:, 0]
        return F

    def predict(self, X) -> np.ndarray:
        """Class of the largest output."""
        F = self._outputs(X)
        return self.classes_[np.argmax(F, axis=1)]

    def predict_proba(self, X) -> np.ndarray:
        """Softmax of the outputs (monotone in them; not calibrated)."""
        F = self._outputs(X)
        F = F - F.max(axis=1, keepdims=True)
        E = np.exp(F)
        return E / E.sum(axis=1, keepdims=True)
