"""Multi-fidelity calibration of one free parameter: cheap runs explore its range, a few full-size
runs correct them.

The model is Kennedy and O'Hagan's autoregressive one (Biometrika 87, 2000) with the scale fixed
at one: the full-size observable is y(x) = g(x) + delta(x), where g is a Gaussian process of the
cheap runs' means over seeds and delta a Gaussian process of the full-size runs' residuals from
g (each a constant times a squared-exponential kernel, each point's noise its mean's variance:
``rollingdem.studies.joint_calibration.fit_surrogate``). Away from the full-size runs delta
reverts to their mean residual, the offset between the fidelities. The free parameter's
posterior (uniform prior on its range, Gaussian likelihood with the target's uncertainty and the
model's) is evaluated on a grid; full-size runs go to its quartiles, round after round. The
answer is where g + delta crosses the target nearest the posterior's mode, its 95 % interval
the posterior's 2.5-97.5 percentiles. docs/studies.md, "Multi-fidelity calibration".
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from rollingdem.errors import ParameterError
from rollingdem.studies.calibration import Calibration, _direction, _point_stats, _pooled_sd

__all__ = ["Fidelity", "JointFidelity", "cheap_default", "corrected_model", "posterior_on_grid", "with_discrepancy"]


@dataclass(frozen=True)
class Fidelity:
    """The cheap runs and how many of each kind: ``cheap`` are the parameters that make a run cheap
    (e.g. ``{"count": 400}``: a smaller scene, or ``{"coarse_graining": 2}``: parcels); ``cheap_points``
    points of them (>= 3) span the range; then ``full_rounds`` rounds (>= 1) of ``full_points``
    full-size points (>= 1; >= 2 in the first round) where the corrected surrogate crosses the target."""

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
    from rollingdem.studies.joint_calibration import fit_surrogate

    def unit(x):
        return ((np.asarray(x, float) - lo) / (hi - lo))[:, None]

    def noise(stats):
        pooled, _ = _pooled_sd(stats["count"].to_numpy(float), stats["std"].fillna(0.0).to_numpy())
        return pooled ** 2 / stats["count"].to_numpy(float)

    g = fit_surrogate(unit(cheap["x"]), cheap["mean"].to_numpy(float), noise(cheap))
    if full is None:
        return (lambda x: g(unit(x))), None
    predict, delta = with_discrepancy(g, unit(full["x"]), full["mean"].to_numpy(float), noise(full))
    return (lambda x: predict(unit(x))), (lambda x: delta(unit(x)))


def with_discrepancy(g, x_full: np.ndarray, full_mean: np.ndarray, full_var: np.ndarray):
    """The full-size model g + delta over the unit box: delta a Gaussian process of the full-size
    means' residuals from the cheap surrogate g (a function ``x_unit -> (mean, std)``) at
    ``x_full``, each residual's noise its mean's variance plus g's there. The surrogate takes the
    residuals' mean as its known prior mean: the variance of that mean is added to delta's.
    Returns (``x_unit -> (mean, std)`` of g + delta, the same of delta)."""
    from rollingdem.studies.joint_calibration import fit_surrogate

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


def calibrate_multifidelity(experiment: str, target: float, uncertainty: float, fix: dict, name: str, lo: float,
                            hi: float, observable: str, seeds: int, fidelity: Fidelity, out: Path, execution,
                            progress: bool, say, share_settling: dict | None = None) -> Calibration:
    """The multi-fidelity search (module docstring) of ``name`` in [lo, hi]; arguments checked by
    ``rollingdem.studies.calibration.calibrate``, which calls it."""
    from rollingdem.experiments import get_experiment
    from rollingdem.studies.calibration import _all_runs, _figure_axes, _save_figure
    from rollingdem.studies.sweep import TABLE, failure_report, load_sweep, run_sweep

    tic = time.perf_counter()
    sc = get_experiment(experiment, observable=True, what="experiment")
    fidelity.check()
    if name in fidelity.cheap:
        raise ParameterError(f"cheap = {name}={fidelity.cheap[name]!r} is not allowed: {name} is the free parameter")
    cheap_fix = {**fix, **fidelity.cheap}
    try:  # a cheap run that cannot be built is refused before any run
        load_sweep({"experiment": experiment, "fixed": cheap_fix, "points": [{name: lo}], "seeds": seeds})
    except ParameterError as err:
        raise ParameterError(f"cheap = {fidelity.cheap} is not allowed: {err}") from None
    what = ", ".join(f"{k} = {v}" for k, v in fidelity.cheap.items())

    def sweep(xs, fixed, m):
        spec = load_sweep({"experiment": experiment, "fixed": fixed, "points": [{name: float(v)} for v in xs],
                           "seeds": seeds})
        run_sweep(spec, out, mapper=m, progress=progress, summary=False, share_settling=share_settling)

    def stats_of(fixed, kind, need):
        table = _all_runs(out, sc, experiment, fixed, name)
        report = failure_report(table, out / TABLE)
        if report:
            say(report)
        stats = _point_stats(table, name, observable)
        if len(stats) < need:
            raise ParameterError(f"multi-fidelity calibration needs at least {need} {kind} points with a finite "
                                 f"{observable}, and has {len(stats)}" + (f" (cheap runs: {what}): make them larger, "
                                                                          "or calibrate with --fidelity single"
                                                                          if kind == "cheap" else ""))
        return table, stats

    with execution.runner() as m:
        say(f"cheap runs ({what}): {name} at {fidelity.cheap_points} points in [{lo:g}, {hi:g}]")
        sweep(np.linspace(lo, hi, fidelity.cheap_points), cheap_fix, m)
        cheap_table, cheap = stats_of(cheap_fix, "cheap", 3)
        increasing = _direction(cheap)
        predict, _ = corrected_model(cheap, None, lo, hi)
        spacing = (hi - lo) / (fidelity.cheap_points - 1)
        full_xs: list[float] = []
        for r in range(fidelity.full_rounds):
            grid, w, _ = posterior_on_grid(predict, target, uncertainty, lo, hi)
            k = max(fidelity.full_points, 2) if r == 0 else fidelity.full_points
            qs = _quantiles(grid, w, np.linspace(0.25, 0.75, k) if k > 1 else [0.5])
            if k > 1 and qs[-1] - qs[0] < 0.25 * spacing:  # a narrow posterior: points a quarter spacing apart
                mid = 0.5 * (qs[0] + qs[-1])
                qs = list(np.clip(mid + 0.25 * spacing * np.linspace(-1, 1, k) * (0.5 ** r), lo, hi))
            new = [v for v in qs if not np.isclose(v, full_xs, atol=1e-3 * (hi - lo)).any()]
            say(f"full-size round {r + 1}: {name} at {', '.join(f'{v:.4g}' for v in new)}, the quartiles of its "
                f"posterior{' from the cheap runs alone' if r == 0 else ''}")
            full_xs += new
            sweep(full_xs, fix, m)
            full_table, full = stats_of(fix, "full-size", 1)
            predict, discrepancy = corrected_model(cheap, full, lo, hi)
    grid, w, mean = posterior_on_grid(predict, target, uncertainty, lo, hi)
    low, high = _quantiles(grid, w, (0.025, 0.975))
    value = _crossing(grid, mean, target, float(grid[np.argmax(w)]))
    if math.isnan(value):
        raise ParameterError(f"target = {target:g} is outside what {name} in [{lo:g}, {hi:g}] gives: the full-size model "
                             f"gives {observable} from {mean.min():.4g} to {mean.max():.4g}; widen the range with --free "
                             f"{name}=LOW:HIGH (runs kept in {out})")
    d, d_sd = (float(v[0]) for v in discrepancy(np.array([value])))
    cost = {kind: pd.to_numeric(t["wall_time_s"], errors="coerce") for kind, t in (("cheap", cheap_table),
                                                                                   ("full", full_table))}
    info = {"model": "full size = GP of the cheap runs + GP of the full-size residuals (Kennedy-O'Hagan, scale 1)",
            "cheap": dict(fidelity.cheap), "cheap_runs": int(len(cheap_table)), "full_runs": int(len(full_table)),
            "cheap_run_seconds": float(cost["cheap"].mean()), "full_run_seconds": float(cost["full"].mean()),
            "offset": d, "offset_low": d - 1.96 * d_sd, "offset_high": d + 1.96 * d_sd,
            "full_points": sorted(float(v) for v in full_xs)}
    table = pd.concat([cheap_table.assign(fidelity="cheap"), full_table.assign(fidelity="full")], ignore_index=True)
    from rollingdem.studies.calibration import settle_saved

    result = Calibration(experiment, name, observable, target, uncertainty, value, low, high, fix,
                         runs=int(len(table)), points=len(cheap) + len(full),
                         seeds=load_sweep({"experiment": experiment, "fixed": fix, "points": [{name: lo}],
                                           "seeds": seeds}).seed_list,
                         direction="increasing" if increasing else "decreasing",
                         outside_fraction=float(w[[0, -1]].sum()), wall_time=time.perf_counter() - tic, table=table,
                         fidelity=info, settle_seconds_saved=settle_saved(table))
    plt, fig, ax = _figure_axes(result)
    ax.plot(cheap_table[name], pd.to_numeric(cheap_table[observable], errors="coerce"), "x", color="0.6",
            label=f"cheap runs ({what})")
    ax.plot(full_table[name], pd.to_numeric(full_table[observable], errors="coerce"), "o", ms=4, color="tab:blue",
            label="full-size runs")
    m_full, s_full = predict(grid)
    ax.plot(grid, m_full, "-", color="tab:green", label="full-size model (cheap + discrepancy)")
    ax.fill_between(grid, m_full - 1.96 * s_full, m_full + 1.96 * s_full, color="tab:green", alpha=0.15)
    _save_figure(plt, fig, ax, result, out)
    (out / "calibration.json").write_text(json.dumps(result.as_dict(), indent=2, default=float))
    say(f"{name} = {value:.5g}, 95 % interval [{low:.5g}, {high:.5g}] for {observable} = {target:g} ± {uncertainty:g}: "
        f"{info['cheap_runs']} cheap runs ({info['cheap_run_seconds']:.1f} s each) and {info['full_runs']} full-size "
        f"({info['full_run_seconds']:.1f} s each); at {name} = {value:.4g} the full size reads {d:+.3g} against the "
        f"cheap runs (95 %: {info['offset_low']:+.3g} to {info['offset_high']:+.3g}); {result.wall_time:.0f} s; {out}")
    return result
