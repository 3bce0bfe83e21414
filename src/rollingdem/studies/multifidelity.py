"""Multi-fidelity calibration of one free parameter: cheap runs explore its range, a few full-size
runs correct them.

The model is Kennedy and O'Hagan's autoregressive one (Biometrika 87, 2000) with the scale fixed
at one: the full-size observable is y(x) = g(x) + delta(x), where g is a Gaussian process of the
cheap runs' means over seeds and delta a Gaussian process of the full-size runs' residuals from
g (each a constant times a squared-exponential kernel, each point's noise its mean's variance:
``rollingdem.studies.surrogates.fit_surrogate``). Away from the full-size runs delta
reverts to their mean residual, the offset between the fidelities. The free parameter's
posterior (uniform prior on its range, Gaussian likelihood with the target's uncertainty and the
model's) is evaluated on a grid; full-size runs go to its quartiles, round after round. The
answer is where g + delta crosses the target nearest the posterior's mode, its 95 % interval
the posterior's 2.5-97.5 percentiles. docs/studies.md, "Multi-fidelity calibration".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from rollingdem.errors import ParameterError
from rollingdem.studies.surrogates import fit_surrogate, pooled_sd, with_discrepancy

__all__ = ["Fidelity", "JointFidelity", "cheap_default", "corrected_model", "posterior_on_grid"]


@dataclass(frozen=True)
class Fidelity:
    """The cheap runs and how many of each kind: ``cheap`` are the parameters that make a run cheap
    (e.g. ``{"count": 400}``: a smaller scene, or ``{"coarse_graining": 2}``: parcels); ``cheap_points``
    points of them (>= 3) span the range; then ``full_rounds`` rounds (>= 1) of ``full_points``
    full-size points (>= 1; >= 2 in the first round) at the quartiles of the parameter's posterior."""

    cheap: dict = field(default_factory=dict)
    cheap_points: int = 7
    full_points: int = 2
    full_rounds: int = 2

    def check(self) -> None:
        if not isinstance(self.cheap, dict) or not self.cheap:
            raise ParameterError(f"cheap = {self.cheap!r} is not allowed: give the parameters that make a run cheap, "
                                 "e.g. count=400 (a smaller scene) or coarse_graining=2 (parcels)")
        for k, n_min in (("cheap_points", 3), ("full_points", 1), ("full_rounds", 1)):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, int) or v < n_min:
                raise ParameterError(f"{k} = {v!r} is not allowed: must be an integer >= {n_min}")


@dataclass(frozen=True)
class JointFidelity:
    """The cheap runs of a joint calibration: ``cheap`` = {experiment: {NAME: VALUE}} (an experiment
    left out runs at full size for its cheap points too); ``cheap_initial`` Latin-hypercube points
    of cheap runs (None: 6 per free parameter + 2); ``full_initial`` full-size points first (None: one
    per free parameter + 1), where the cheap runs' posterior is high; then the search's rounds of
    full-size points."""

    cheap: dict = field(default_factory=dict)
    cheap_initial: int | None = None
    full_initial: int | None = None

    def check(self, d: int, experiments) -> None:
        if not isinstance(self.cheap, dict) or not self.cheap or not all(isinstance(v, dict) for v in self.cheap.values()):
            raise ParameterError(f"cheap = {self.cheap!r} is not allowed: give {{experiment: {{NAME: VALUE}}}} for at "
                                 "least one experiment")
        unknown = [c for c in self.cheap if c not in experiments]
        if unknown:
            raise ParameterError(f"cheap = {unknown[0]!r} is not allowed: not an experiment of the targets "
                                 f"({', '.join(experiments)})")
        for k, v, n_min in (("cheap_initial", self.cheap_initial, d + 1), ("full_initial", self.full_initial, 1)):
            if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < n_min):
                raise ParameterError(f"{k} = {v!r} is not allowed: must be an integer >= {n_min}")


#: the cheap scene's share of the full one's particles, when the cheap runs are not given
CHEAP_SHARE = 0.4


def cheap_default(sc, fix: dict) -> dict:
    """The cheap runs of an experiment when none are given: its own (``Experiment.cheap``, e.g. the
    drum's smaller drum), else ``CHEAP_SHARE`` of its particles (``count``), not fewer than the
    parameter allows; refused for an experiment with neither."""
    if getattr(sc, "cheap", None):
        return dict(sc.cheap)
    par = sc.by_name.get("count")
    if par is None:
        raise ParameterError(f"fidelity = multi is not allowed for {sc.name!r} without cheap runs: it has no count to "
                             "make smaller; give --cheap NAME=VALUE (e.g. --cheap coarse_graining=2)")
    full = int(fix.get("count", par.default))
    return {"count": max(int(round(CHEAP_SHARE * full)), int(math.ceil(par.low or 1)))}


GRID = 400  # points of the free parameter's posterior grid


def corrected_model(cheap: pd.DataFrame, full: pd.DataFrame | None, lo: float, hi: float):
    """The full-size model g + delta from the point statistics (columns x, mean, std, count) of the
    cheap and the full-size runs: a function ``x -> (mean, std)``, and one ``x -> (delta, std)``
    (without full-size runs: g alone, and None).
    A point's noise is its mean's variance, the seeds' scatter pooled over the points of its
    fidelity divided by its runs; the residuals' adds the cheap model's variance there."""
    def unit(x):
        return ((np.asarray(x, float) - lo) / (hi - lo))[:, None]

    def noise(stats):
        pooled, _ = pooled_sd(stats["count"].to_numpy(float), stats["std"].fillna(0.0).to_numpy())
        return pooled ** 2 / stats["count"].to_numpy(float)

    g = fit_surrogate(unit(cheap["x"]), cheap["mean"].to_numpy(float), noise(cheap))
    if full is None:
        return (lambda x: g(unit(x))), None
    predict, delta = with_discrepancy(g, unit(full["x"]), full["mean"].to_numpy(float), noise(full))
    return (lambda x: predict(unit(x))), (lambda x: delta(unit(x)))


def posterior_on_grid(predict, target: float, uncertainty: float, lo: float, hi: float, n: int = GRID):
    """(grid of the free parameter, posterior weights, the model's mean there): uniform prior on
    [lo, hi], likelihood N(target; m(x), u^2 + s(x)^2) for the model's mean m and std s."""
    x = lo + (np.arange(n) + 0.5) / n * (hi - lo)
    m, s = predict(x)
    var = uncertainty ** 2 + s ** 2 + 1e-300
    logp = -0.5 * ((m - target) ** 2 / var + np.log(var))
    w = np.exp(logp - logp.max())
    return x, w / w.sum(), m


def _quantiles(x, w, qs):
    c = np.cumsum(w)
    return [float(np.interp(q, c, x)) for q in qs]


def _crossing(x, m, target: float, near: float) -> float:
    """Where the mean m(x) crosses ``target``, the crossing nearest ``near`` (linear between grid
    points); NaN where it does not cross."""
    d = m - target
    k = np.nonzero(np.sign(d[:-1]) * np.sign(d[1:]) <= 0)[0]
    if not len(k):
        return math.nan
    roots = x[k] + (x[k + 1] - x[k]) * d[k] / np.where(d[k] == d[k + 1], 1.0, d[k] - d[k + 1])
    return float(roots[np.argmin(abs(roots - near))])
