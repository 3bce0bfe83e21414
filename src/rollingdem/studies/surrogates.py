"""Gaussian-process surrogates of an observable's mean over the unit box of the free parameters,
and the multi-fidelity model built from two of them (docs/studies.md, "Joint calibration" and
"Multi-fidelity calibration")."""

from __future__ import annotations

import math
import warnings

import numpy as np

__all__ = ["fit_surrogate", "pooled_sd", "with_discrepancy"]


def pooled_sd(counts: np.ndarray, std: np.ndarray) -> tuple[float, float]:
    """(the seeds' standard deviation pooled over the points with two or more seeds, its degrees of
    freedom); (0, 0) without such a point (a deterministic experiment)."""
    multi = counts >= 2
    dof = float(np.sum(counts[multi] - 1))
    return (math.sqrt(np.sum((counts[multi] - 1) * std[multi] ** 2) / dof) if dof > 0 else 0.0), dof


def fit_surrogate(x_unit: np.ndarray, mean: np.ndarray, var_of_mean: np.ndarray):
    """A Gaussian process of the observable's mean over the unit box: constant x anisotropic RBF
    kernel (scikit-learn), each point's noise its mean's variance (seed scatter / runs). Returns a
    function ``x_unit -> (mean, std)`` of the latent mean."""
    from sklearn.exceptions import ConvergenceWarning  # deferred: slow to load, surrogates only
    from sklearn.gaussian_process import GaussianProcessRegressor  # deferred: slow to load, surrogates only
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel  # deferred: slow to load, surrogates only

    x_unit = np.atleast_2d(np.asarray(x_unit, float))
    y = np.asarray(mean, float)
    shift, scale = float(y.mean()), float(y.std()) or 1.0
    kernel = ConstantKernel(1.0, (1e-3, 1e3)) * RBF(np.full(x_unit.shape[1], 0.3), (0.03, 100.0))
    gp = GaussianProcessRegressor(kernel, alpha=np.maximum(np.asarray(var_of_mean, float) / scale ** 2, 1e-8),
                                  n_restarts_optimizer=3, random_state=0, normalize_y=False)
    with warnings.catch_warnings():  # a length scale at its bound: an observable nearly linear in a parameter
        warnings.simplefilter("ignore", ConvergenceWarning)
        gp.fit(x_unit, (y - shift) / scale)

    def predict(xq):
        m, s = gp.predict(np.atleast_2d(xq), return_std=True)
        return m * scale + shift, s * scale
    return predict


def with_discrepancy(g, x_full: np.ndarray, full_mean: np.ndarray, full_var: np.ndarray):
    """The full-size model g + delta over the unit box: delta a Gaussian process of the full-size
    means' residuals from the cheap surrogate g (a function ``x_unit -> (mean, std)``) at
    ``x_full``, each residual's noise its mean's variance plus g's there. The surrogate takes the
    residuals' mean as its known prior mean: the variance of that mean is added to delta's.
    Returns (``x_unit -> (mean, std)`` of g + delta, the same of delta)."""
    g_at, g_sd = g(x_full)
    residual_var = np.asarray(full_var, float) + g_sd ** 2
    fit = fit_surrogate(x_full, np.asarray(full_mean, float) - g_at, residual_var)
    mean_var = float(residual_var.sum()) / len(residual_var) ** 2

    def delta(x):
        m, s = fit(x)
        return m, np.sqrt(s ** 2 + mean_var)

    def predict(x):
        m1, s1 = g(x)
        m2, s2 = delta(x)
        return m1 + m2, np.sqrt(s1 ** 2 + s2 ** 2)

    return predict, delta
