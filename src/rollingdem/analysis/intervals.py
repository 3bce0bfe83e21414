"""Confidence intervals of a mean over seeds, as the sweeps, the PFC study and calibration report them."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import stats

__all__ = ["confidence_interval"]


def confidence_interval(values: Any, level: float = 0.95) -> tuple[float, float]:
    """(mean, half-width) of the Student-t confidence interval of the mean of the finite values:
    half-width = t_{(1 + level)/2, n-1} s / sqrt(n) (scipy.stats.t); NaN half-width for n < 2."""
    v = np.asarray(values, dtype=float).ravel()
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return math.nan, math.nan
    if len(v) < 2:
        return float(v.mean()), math.nan
    half = stats.t.ppf(0.5 + level / 2, len(v) - 1) * v.std(ddof=1) / math.sqrt(len(v))
    return float(v.mean()), float(half)
