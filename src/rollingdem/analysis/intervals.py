"""Confidence intervals of a mean over seeds, as the sweeps, the PFC study and calibration report them."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["confidence_interval", "difference_interval"]


def confidence_interval(values: Any, level: float = 0.95) -> tuple[float, float]:
    """(mean, half-width) of the Student-t confidence interval of the mean of the finite values:
    half-width = t_{(1 + level)/2, n-1} s / sqrt(n) (scipy.stats.t); NaN half-width for n < 2."""
    v = np.asarray(values, dtype=float).ravel()
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return math.nan, math.nan
    if len(v) < 2:
        return float(v.mean()), math.nan
    from scipy import stats  # deferred: slow to load, used here only

    half = stats.t.ppf(0.5 + level / 2, len(v) - 1) * v.std(ddof=1) / math.sqrt(len(v))
    return float(v.mean()), float(half)


def difference_interval(a: Any, b: Any, level: float = 0.95) -> tuple[float, float]:
    """(mean(a) - mean(b), half-width) of Welch's confidence interval of the difference of two means
    from independent samples (the seeds of two scenes): half-width = t_{(1 + level)/2, nu}
    sqrt(s_a^2/n_a + s_b^2/n_b), nu by the Welch-Satterthwaite equation; NaN half-width when either
    has fewer than 2 finite values or both have no spread."""
    x, y = (np.asarray(v, dtype=float).ravel() for v in (a, b))
    x, y = x[np.isfinite(x)], y[np.isfinite(y)]
    if not len(x) or not len(y):
        return math.nan, math.nan
    diff = float(x.mean() - y.mean())
    if len(x) < 2 or len(y) < 2:
        return diff, math.nan
    va, vb = x.var(ddof=1) / len(x), y.var(ddof=1) / len(y)
    if va + vb == 0.0:
        return diff, math.nan
    nu = (va + vb) ** 2 / (va ** 2 / (len(x) - 1) + vb ** 2 / (len(y) - 1))
    from scipy import stats  # deferred: slow to load, used here only

    return diff, float(stats.t.ppf(0.5 + level / 2, nu) * math.sqrt(va + vb))
