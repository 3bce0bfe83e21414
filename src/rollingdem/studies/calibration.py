"""Calibration: the value of one free parameter whose simulated observable matches a measured one.

``calibrate(experiment, target, uncertainty, fix={"mu": 0.5}, free="mur")`` (and ``rollingdem
calibrate``): a coarse sweep, a monotone surrogate, refinement rounds where it crosses the target,
and a 95 % interval from a parametric bootstrap, every run through :func:`rollingdem.studies.sweep.run_sweep`
(resumable). The method step by step: docs/studies.md, "Calibration"."""

from __future__ import annotations

import json
import math
import tempfile
import time
from dataclasses import asdict, astuple, dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from rollingdem.analysis.intervals import confidence_interval
from rollingdem.errors import ParameterError, check_finite, check_non_negative, check_output_path
from rollingdem.experiments import get_experiment
from rollingdem.experiments.results import pyplot
from rollingdem.studies.multifidelity import Fidelity, _crossing, _quantiles, corrected_model, posterior_on_grid
from rollingdem.studies.parallel import Execution
from rollingdem.studies.surrogates import pooled_sd as _pooled_sd
from rollingdem.studies.sweep import TABLE, failure_report, load_sweep, read_table, rows_matching, run_sweep

__all__ = ["Calibration", "Execution", "Search", "calibrate", "calibrate_minimum", "monotone_inverse", "parabola_minimum"]

BOOTSTRAP = 4000


@dataclass(frozen=True)
class Search:
    """How the free parameter's range is searched (docs/studies.md, "Calibration"): ``coarse`` points
    first (>= 3), then ``rounds`` refinements (>= 0) of ``refine`` points each (>= 1), and
    ``bootstrap`` replicates for the 95 % interval (>= 1); or, with a ``fidelity``, cheap runs
    corrected by full-size ones ("Multi-fidelity calibration"). ``share_settling``: each seed's bed
    settles once and every run starts from it (``run_sweep``)."""

    coarse: int = 5
    refine: int = 4
    rounds: int = 2
    bootstrap: int = BOOTSTRAP
    fidelity: object = None  # a rollingdem.studies.multifidelity.Fidelity: cheap runs corrected by full-size ones
    share_settling: bool = False  # each seed's bed settled once, the free parameter at the middle of its range


@dataclass
class Calibration:
    """The calibrated value of ``parameter`` with its 95 % interval, and the evidence."""

    experiment: str
    parameter: str
    observable: str
    target: float
    uncertainty: float
    value: float
    low: float
    high: float
    fixed: dict
    runs: int
    points: int
    seeds: list
    direction: str
    outside_fraction: float  # of bootstrap replicates whose target fell outside the swept range
    wall_time: float
    figures: list = field(default_factory=list)
    table: pd.DataFrame | None = field(default=None, repr=False)
    fidelity: dict | None = None  # a multi-fidelity search's runs of each kind, their cost and the offset
    settle_seconds_saved: float = 0.0  # wall time the runs saved by starting from a shared settled bed

    def as_dict(self) -> dict:
        d = {k: v for k, v in asdict(self).items() if k != "table"}
        d["figures"] = [str(f) for f in self.figures]
        return d


def parse_assignments(items, what: str) -> dict:
    """``["mu=0.5", "model=epsd"]`` -> {"mu": 0.5, "model": "epsd"} (numbers read as numbers)."""
    out = {}
    for item in items or ():
        if "=" not in item:
            raise ParameterError(f"{what} = {item!r} is not allowed: write NAME=VALUE, e.g. mu=0.5")
        key, value = (s.strip() for s in item.split("=", 1))
        try:
            out[key] = int(value) if value.lstrip("-").isdigit() else float(value)
        except ValueError:
            out[key] = value
    return out


def parse_free(item: str) -> tuple[str, tuple[float, float] | None]:
    """``"mur"`` or ``"mur=0.05:0.6"`` -> (name, range or None)."""
    if "=" not in item:
        return item.strip(), None
    name, rng = (s.strip() for s in item.split("=", 1))
    try:
        lo, hi = (float(s) for s in rng.split(":"))
    except ValueError:
        raise ParameterError(f"free = {item!r} is not allowed: write NAME or NAME=LOW:HIGH, e.g. mur=0.05:0.6") from None
    return name, (lo, hi)


def _point_stats(table: pd.DataFrame, parameter: str, observable: str) -> pd.DataFrame:
    ok = table[table["status"] == "ok"]
    y = pd.to_numeric(ok[observable], errors="coerce")
    ok = ok.assign(_y=y)[np.isfinite(y)]
    stats = ok.groupby(parameter)["_y"].agg(["mean", "std", "count"]).reset_index().sort_values(parameter)
    return stats.rename(columns={parameter: "x"})


def _monotone(means: np.ndarray, weights: np.ndarray, increasing: bool) -> np.ndarray:
    from scipy.optimize import isotonic_regression  # deferred: slow to load, used here only

    return isotonic_regression(means, weights=weights, increasing=increasing).x


def monotone_inverse(x: np.ndarray, g: np.ndarray, target: float) -> float:
    """x where the monotone piecewise-linear curve (x, g) meets ``target``; NaN outside its range.
    On a flat stretch at the target, the middle of the stretch."""
    x, g = np.asarray(x, float), np.asarray(g, float)
    if g[-1] < g[0]:
        g = -g
        target = -target
    if not g[0] <= target <= g[-1]:
        return math.nan
    at = np.nonzero(g == target)[0]
    if len(at):
        return float(0.5 * (x[at[0]] + x[at[-1]]))
    k = int(np.searchsorted(g, target))  # g[k-1] < target < g[k]
    return float(x[k - 1] + (target - g[k - 1]) * (x[k] - x[k - 1]) / (g[k] - g[k - 1]))


def _direction(stats: pd.DataFrame) -> bool:
    """True when the observable grows with the parameter (Spearman over the point means)."""
    from scipy.stats import spearmanr  # deferred: slow to load, used here only

    if len(stats) < 2:
        raise ParameterError("calibration needs at least two points with a finite observable")
    rho = spearmanr(stats["x"], stats["mean"]).statistic
    if not np.isfinite(rho) or rho == 0:
        raise ParameterError("the observable does not change with the free parameter over its range: "
                             "nothing to calibrate")
    return bool(rho > 0)


def calibrate(experiment: str, target: float, uncertainty: float = 0.0, fix: dict | None = None, free="mur",
              observable: str | None = None, seeds=None, search: Search = Search(), out=None,
              execution: Execution = Execution(), progress: bool = True, echo=None) -> Calibration:
    """Find the ``free`` parameter (a name, or (name, (low, high))) whose ``observable`` matches
    ``target`` +- ``uncertainty`` (one sigma) with the parameters ``fix`` held, ``seeds`` runs per
    point, searched as ``search`` says (the method: docs/studies.md, "Calibration"), the runs going
    where ``execution`` says; with ``search.fidelity`` (``rollingdem.studies.multifidelity.Fidelity``),
    cheap runs explore the range and a few full-size runs correct them instead; with
    ``search.share_settling`` each seed's bed settles once, with the free parameter at the middle of
    its range, and every run starts from it (``run_sweep``). Writes ``out/runs.csv``,
    ``calibration.json`` and ``calibration.png``; ``echo`` (a print-like function) tells each round
    and the result."""
    tic = time.perf_counter()
    sc = get_experiment(experiment, observable=True, what="experiment")
    if isinstance(free, str):
        name, rng = free, None
    elif isinstance(free, (list, tuple)) and len(free) == 2 and not isinstance(free[1], str):
        name, rng = free
    else:
        raise ParameterError(f"free = {free!r} is not allowed: calibrate takes one free parameter (one target "
                             "observable fixes one parameter; sweep the others with rollingdem sweep)")
    par = sc.by_name.get(name)
    if par is None:
        raise ParameterError(f"free = {name!r} is not known for experiment {experiment!r}: allowed are "
                             f"{', '.join(p.name for p in sc.parameters if p.calibration_range)}")
    if par.calibration_range is None:
        raise ParameterError(f"free = {name!r} is not allowed: it is not a real-valued parameter that calibration "
                             f"can vary (those are {', '.join(p.name for p in sc.parameters if p.calibration_range)})")
    lo, hi = rng or par.calibration_range
    if not math.isfinite(hi):
        raise ParameterError(f"free = {name!r} is not allowed without its range: give --free {name}=LOW:HIGH "
                             "(free=(name, (low, high)) in Python)")
    par.check(lo)
    par.check(hi)
    if not lo < hi:
        raise ParameterError(f"free = {name}={lo}:{hi} is not allowed: the range must be LOW:HIGH with LOW < HIGH")
    observable = observable or sc.default_observable
    if observable not in sc.observables:
        raise ParameterError(f"observable = {observable!r} is not known for experiment {experiment!r}: allowed are "
                             f"{', '.join(sc.observables)}")
    target = check_finite("target", target)
    uncertainty = check_non_negative("uncertainty", uncertainty)
    fix = dict(fix or {})
    if name in fix:
        raise ParameterError(f"parameter {name!r} is both fixed and free: give it in one place")
    for what, value, kind in (("search", search, Search), ("execution", execution, Execution)):
        if not isinstance(value, kind):
            raise ParameterError(f"{what} = {value!r} is not allowed: must be a rollingdem.studies.calibration.{kind.__name__}")
    for k, n_min in (("coarse", 3), ("refine", 1), ("rounds", 0), ("bootstrap", 1)):
        v = getattr(search, k)
        if isinstance(v, bool) or not isinstance(v, int) or v < n_min:
            raise ParameterError(f"{k} = {v!r} is not allowed: must be an integer >= {n_min}")
    coarse, refine, rounds = search.coarse, search.refine, search.rounds
    seeds = seeds if seeds is not None else (3 if sc.stochastic else 1)
    out = check_output_path("out", out) if out is not None else Path(tempfile.mkdtemp(prefix="rollingdem-calibrate-"))
    first = load_sweep({"experiment": experiment, "fixed": fix, "points": [{name: lo}], "seeds": seeds})  # refuse bad input now
    say = echo or (lambda *_: None)
    fidelity, share_settling = search.fidelity, search.share_settling
    shared = None
    if share_settling:
        if not hasattr(sc, "share_settling"):
            raise ParameterError(f"share_settling is not allowed for experiment {experiment!r}: it has no settling "
                                 "stage to share (repose-rough-base and rotating-drum have)")
        shared = {name: 0.5 * (lo + hi)}
    if fidelity is not None:
        if not isinstance(fidelity, Fidelity):
            raise ParameterError(f"fidelity = {fidelity!r} is not allowed: must be a "
                                 "rollingdem.studies.multifidelity.Fidelity")
        return _calibrate_multifidelity(_Problem(experiment, target, uncertainty, fix, name, lo, hi, observable, seeds,
                                                 out), fidelity, execution, progress, say, shared)

    def sweep(xs, m):
        spec = load_sweep({"experiment": experiment, "fixed": fix, "points": [{name: float(x)} for x in xs], "seeds": seeds})
        return run_sweep(spec, out, mapper=m, progress=progress, summary=False, share_settling=shared).table

    with execution.runner() as m:
        xs = list(np.linspace(lo, hi, coarse))
        sweep(xs, m)
        table = None
        for r in range(rounds + 1):
            table, stats = _usable(out, sc, experiment, fix, name, observable, 2, "calibration", say)
            increasing = _direction(stats)
            g = _monotone(stats["mean"].to_numpy(), stats["count"].to_numpy(float), increasing)
            if not min(g) <= target <= max(g):
                raise ParameterError(
                    f"target = {target:g} is outside what {name} in [{lo:g}, {hi:g}] gives: {observable} from "
                    f"{g[0]:.4g} ({name} = {stats['x'].iloc[0]:g}) to {g[-1]:.4g} ({name} = "
                    f"{stats['x'].iloc[-1]:g}); widen the range with --free {name}=LOW:HIGH (runs kept in {out})")
            if r == rounds:
                break
            x = stats["x"].to_numpy()
            s = np.sign(g - target) * (1 if increasing else -1)
            k = max(int(np.argmax(s >= 0)), 1)  # first point at or past the target
            a, b = x[max(k - 1, 0)], x[k]
            # where the seed scatter alone leaves the answer (a deterministic experiment: nowhere but the
            # bracket), so that a noisy experiment does not crowd its new points into a narrow bracket
            s_lo, s_hi, _ = _bootstrap(x, stats["mean"].to_numpy(), stats["count"].to_numpy(float),
                                       stats["std"].to_numpy(), increasing, target, 0.0, 500)
            a, b = max(min(a, s_lo), lo), min(max(b, s_hi), hi)
            new = np.linspace(a, b, refine + 2)[1:-1]
            say(f"round {r + 1}: refining {name} in [{a:.5g}, {b:.5g}], where {observable} crosses {target:g}")
            sweep(xs + list(new), m)
            xs += list(new)
    stats = _point_stats(table, name, observable)
    x, means, counts = stats["x"].to_numpy(), stats["mean"].to_numpy(), stats["count"].to_numpy(float)
    g = _monotone(means, counts, increasing)
    value = monotone_inverse(x, g, target)
    lo95, hi95, outside = _bootstrap(x, means, counts, stats["std"].to_numpy(), increasing, target, uncertainty,
                                     search.bootstrap)
    result = Calibration(experiment, name, observable, target, uncertainty, value, lo95, hi95, fix,
                         runs=int(len(table)), points=len(x), seeds=first.seed_list,
                         direction="increasing" if increasing else "decreasing", outside_fraction=outside,
                         wall_time=time.perf_counter() - tic, table=table, settle_seconds_saved=settle_saved(table))
    _figure(result, stats, g, out)
    (out / "calibration.json").write_text(json.dumps(result.as_dict(), indent=2, default=float))
    shared_note = (f"; the shared settled beds saved {result.settle_seconds_saved:.0f} s of runs"
                   if share_settling else "")
    say(f"{name} = {value:.5g}, 95 % interval [{lo95:.5g}, {hi95:.5g}] for {observable} = {target:g} ± "
        f"{uncertainty:g} ({result.runs} runs, {result.wall_time:.0f} s{shared_note}; {out})")
    return result


def settle_saved(table: pd.DataFrame) -> float:
    """The wall-clock seconds a calibration's runs saved by starting from shared settled beds."""
    if "settle_seconds_saved" not in table:
        return 0.0
    return float(pd.to_numeric(table["settle_seconds_saved"], errors="coerce").fillna(0.0).sum())


def _usable(out: Path, sc, experiment: str, fix: dict, name: str, observable: str, need: int, what: str, say):
    """(this calibration's runs, their means per point); the failures said, and refused in one line
    when fewer than ``need`` points are left."""
    table = _all_runs(out, sc, experiment, fix, name)
    stats = _point_stats(table, name, observable)
    report = failure_report(table, out / TABLE)
    if len(stats) < need:
        raise ParameterError(f"{what} needs at least {['', 'one', 'two', 'three'][need]} points with a finite "
                             f"{observable}, and has {len(stats)}: " + (report or f"the runs gave no finite {observable}"))
    if report:
        say(report)
    return table, stats


def _all_runs(out: Path, sc, experiment: str, fix: dict, name: str) -> pd.DataFrame:
    """The runs of this calibration in the table (same experiment and fixed parameters)."""
    resolved = sc.resolve({**fix, name: sc.by_name[name].default})
    return rows_matching(read_table(out / TABLE, sc),
                         {k: v for k, v in resolved.items() if k not in (name, "seed")}).reset_index(drop=True)


def _bootstrap(x, means, counts, std, increasing, target, uncertainty, n) -> tuple[float, float, float]:
    """2.5 and 97.5 percentiles of the inverted surrogate over parametric bootstrap replicates,
    and the fraction of replicates whose target fell outside the swept range (clipped to its ends)."""
    rng = np.random.default_rng(12345)
    pooled, dof = _pooled_sd(counts, std)
    draws = rng.standard_t(dof, size=(n, len(x))) if dof > 0 else np.zeros((n, len(x)))
    targets = target + uncertainty * rng.standard_normal(n)
    values = np.empty(n)
    outside = 0
    for b in range(n):
        g = _monotone(means + pooled / np.sqrt(counts) * draws[b], counts, increasing)
        v = monotone_inverse(x, g, targets[b])
        if math.isnan(v):
            outside += 1
            low_end = (targets[b] < g.min()) == increasing
            v = x[0] if low_end else x[-1]
        values[b] = v
    return float(np.percentile(values, 2.5)), float(np.percentile(values, 97.5)), outside / n


def _figure(result: Calibration, stats: pd.DataFrame, g: np.ndarray, out: Path) -> None:
    plt, fig, ax = _figure_axes(result)
    t = result.table
    ok = t[t["status"] == "ok"]
    ax.plot(ok[result.parameter], pd.to_numeric(ok[result.observable], errors="coerce"), ".", color="0.6",
            label="runs")
    ci = [confidence_interval(pd.to_numeric(ok[ok[result.parameter] == v][result.observable], errors="coerce"))[1]
          for v in stats["x"]]
    ax.errorbar(stats["x"], stats["mean"], yerr=np.nan_to_num(ci), fmt="o", ms=4, capsize=3, color="tab:blue",
                label="mean over seeds, 95 % CI")
    ax.plot(stats["x"], g, "-", color="tab:green", label="monotone surrogate")
    _save_figure(plt, fig, ax, result, out)


def _figure_axes(result: Calibration):
    """(pyplot, figure, axes) of a calibration's figure with its target band, labels and title."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.axhspan(result.target - 1.96 * result.uncertainty, result.target + 1.96 * result.uncertainty, color="tab:orange",
               alpha=0.15)
    ax.axhline(result.target, color="tab:orange", lw=1, label=f"target {result.target:g} ± 1.96 × {result.uncertainty:g}")
    unit = get_experiment(result.experiment, observable=True, what="experiment").observables[result.observable].split(",")[0]
    ax.set_ylabel(f"{result.observable} ({unit})")
    fixed = ", ".join(f"{k} = {v}" for k, v in result.fixed.items())
    ax.set_title(f"Calibration, {result.experiment}{': ' + fixed if fixed else ''}", fontsize=10)
    return plt, fig, ax


def _save_figure(plt, fig, ax, result: Calibration, out: Path) -> None:
    """The calibrated value and its 95 % interval drawn on ``ax``; the figure saved as
    ``out/calibration.png`` and listed in ``result.figures``."""
    ax.axvspan(result.low, result.high, color="tab:red", alpha=0.12)
    ax.axvline(result.value, color="tab:red", lw=1.2, label=f"{result.parameter} = {result.value:.4g} "
                                                       f"[{result.low:.4g}, {result.high:.4g}]")
    ax.set_xlabel(result.parameter)
    ax.legend(fontsize=7)
    fig.tight_layout()
    path = out / "calibration.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    result.figures.append(path)


def parabola_minimum(x, y) -> float:
    """Where the least-squares parabola through (x, y) is lowest: its vertex when it opens upwards
    and lies within [min x, max x], else the lowest point's x."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    best = float(x[np.argmin(y)])
    if len(x) < 3:
        return best
    a, b, _ = np.polyfit(x, y, 2)
    if a <= 0:
        return best
    vertex = -b / (2 * a)
    return float(vertex) if x.min() <= vertex <= x.max() else best


def _around_lowest(means, k: int = 5) -> slice:
    """The ``k`` points nearest the lowest of ``means`` (by rank along the sorted x)."""
    lo = max(0, min(int(np.argmin(means)) - k // 2, len(means) - k))
    return slice(lo, lo + k)


def local_minimum(x, means) -> float:
    """Where the least-squares parabola through the five points nearest the lowest of ``means``
    (``x`` sorted) is lowest (:func:`parabola_minimum`)."""
    x, means = np.asarray(x, float), np.asarray(means, float)
    near = _around_lowest(means)
    return parabola_minimum(x[near], means[near])


def minimum_interval(x, means, errors, replicates: int, rng) -> tuple[float, float]:
    """The 95 % interval of :func:`local_minimum` from a parametric bootstrap: ``means`` drawn
    about themselves with their standard ``errors``, each draw's minimum found around its own
    lowest point, so that where the curve is flat over more points than a parabola takes, the
    interval spans them."""
    x, means, errors = (np.asarray(a, float) for a in (x, means, errors))
    draws = [local_minimum(x, means + errors * rng.standard_normal(len(x))) for _ in range(replicates)]
    return float(np.percentile(draws, 2.5)), float(np.percentile(draws, 97.5))


def calibrate_minimum(experiment: str, observable: str, free, fix: dict | None = None, seeds=None,
                      search: Search = Search(), out=None, execution: Execution = Execution(), progress: bool = True,
                      echo=None) -> Calibration:
    """The value of the ``free`` parameter, (name, (low, high)), where ``observable`` is lowest: a
    misfit such as a surface profile's RMSE. A coarse sweep, then ``search.rounds`` rounds of
    ``search.refine`` points between the neighbours of the lowest mean, and the vertex of the
    least-squares parabola through the five points around it; its 95 % interval from a
    parametric bootstrap of the seed means (the spread of the seeds about each mean), each draw's
    minimum found around its own lowest point (:func:`minimum_interval`)."""
    tic = time.perf_counter()
    sc = get_experiment(experiment, observable=True, what="experiment")
    if not (isinstance(free, (list, tuple)) and len(free) == 2 and not isinstance(free[1], str) and free[1]):
        raise ParameterError(f"free = {free!r} is not allowed: a minimum is searched over one parameter's range, "
                             "NAME=LOW:HIGH")
    name, (lo, hi) = free
    if name not in sc.by_name:
        raise ParameterError(f"free = {name!r} is not known for experiment {experiment!r}")
    if not lo < hi:
        raise ParameterError(f"free = {name}={lo}:{hi} is not allowed: the range must be LOW:HIGH with LOW < HIGH")
    if observable not in sc.observables:
        raise ParameterError(f"observable = {observable!r} is not known for experiment {experiment!r}: allowed are "
                             f"{', '.join(sc.observables)}")
    fix = dict(fix or {})
    seeds = seeds if seeds is not None else (3 if sc.stochastic else 1)
    out = check_output_path("out", out) if out is not None else Path(tempfile.mkdtemp(prefix="rollingdem-min-"))
    first = load_sweep({"experiment": experiment, "fixed": fix, "points": [{name: lo}], "seeds": seeds})
    say = echo or (lambda *_: None)

    def sweep(xs, m):
        spec = load_sweep({"experiment": experiment, "fixed": fix, "points": [{name: float(v)} for v in xs],
                           "seeds": seeds})
        run_sweep(spec, out, mapper=m, progress=progress, summary=False)

    with execution.runner() as m:
        xs = list(np.linspace(lo, hi, search.coarse))
        sweep(xs, m)
        for r in range(search.rounds + 1):
            table, stats = _usable(out, sc, experiment, fix, name, observable, 3, "a minimum", say)
            if r == search.rounds:
                break
            x = stats["x"].to_numpy()
            i = int(np.argmin(stats["mean"].to_numpy()))
            a, b = x[max(i - 1, 0)], x[min(i + 1, len(x) - 1)]
            new = [v for v in np.linspace(a, b, search.refine + 2)[1:-1] if not np.isclose(v, x).any()]
            say(f"round {r + 1}: refining {name} in [{a:.5g}, {b:.5g}], around the lowest {observable}")
            sweep(xs + new, m)
            xs += new
    every_x, every_mean, counts = (stats["x"].to_numpy(), stats["mean"].to_numpy(), stats["count"].to_numpy(float))
    value = local_minimum(every_x, every_mean)
    pooled, _ = _pooled_sd(counts, stats["std"].fillna(0.0).to_numpy())
    low, high = minimum_interval(every_x, every_mean, pooled / np.sqrt(counts), search.bootstrap,
                                 np.random.default_rng(12345))
    result = Calibration(experiment, name, observable, math.nan, 0.0, value, low, high, fix, runs=int(len(table)),
                         points=len(stats), seeds=first.seed_list, direction="minimum", outside_fraction=0.0,
                         wall_time=time.perf_counter() - tic, table=table)
    (out / "calibration.json").write_text(json.dumps(result.as_dict(), indent=2, default=float))
    _minimum_figure(result, stats, out)
    say(f"{name} = {value:.5g}, 95 % interval [{low:.5g}, {high:.5g}] where {observable} is lowest "
        f"({result.runs} runs, {result.wall_time:.0f} s; {out})")
    return result


def _minimum_figure(result: Calibration, stats: pd.DataFrame, out: Path) -> None:
    """The misfit's mean over seeds at each point, the parabola through the five around the lowest,
    and the minimum with its 95 % interval."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.errorbar(stats["x"], stats["mean"], yerr=stats["std"].fillna(0.0), fmt="o", ms=4, capsize=3,
                label="mean over seeds ± sd")
    near = _around_lowest(stats["mean"].to_numpy())
    x, means = stats["x"].to_numpy()[near], stats["mean"].to_numpy()[near]
    if len(x) >= 3:
        grid = np.linspace(x.min(), x.max(), 100)
        ax.plot(grid, np.polyval(np.polyfit(x, means, 2), grid), "-", color="tab:green", label="parabola near the minimum")
    ax.set_ylabel(result.observable)
    _save_figure(plt, fig, ax, result, out)


@dataclass(frozen=True)
class _Problem:
    """What a calibration of one free parameter seeks, as ``calibrate`` checked it."""

    experiment: str
    target: float
    uncertainty: float
    fix: dict
    name: str
    lo: float
    hi: float
    observable: str
    seeds: object
    out: Path


def _calibrate_multifidelity(problem: _Problem, fidelity, execution, progress: bool, say,
                             share_settling: dict | None) -> Calibration:
    """The multi-fidelity search of ``problem`` (``rollingdem.studies.multifidelity``: cheap runs, a
    few full-size runs at the quartiles of the posterior, Kennedy and O'Hagan's model)."""
    experiment, target, uncertainty, fix, name, lo, hi, observable, seeds, out = astuple(problem)

    tic = time.perf_counter()
    sc = get_experiment(experiment, observable=True, what="experiment")
    fidelity.check()
    if name in fidelity.cheap:
        raise ParameterError(f"cheap = {name}={fidelity.cheap[name]!r} is not allowed: {name} is the free parameter")
    cheap_fix = {**fix, **fidelity.cheap}
    try:  # a cheap run that cannot be built is refused before any run
        load_sweep({"experiment": experiment, "fixed": cheap_fix, "points": [{name: lo}], "seeds": seeds})
        sc.check({**cheap_fix, name: lo})  # its scene built once: a parcel wider than an opening, say
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
            "full_points": sorted(float(v) for v in full_xs),
            "full_seed_sd": _pooled_sd(full["count"].to_numpy(float), full["std"].fillna(0.0).to_numpy())[0],
            "model_file": "model.csv"}
    m_full, s_full = predict(grid)
    pd.DataFrame({name: grid, f"{observable}_mean": m_full, f"{observable}_std": s_full}).to_csv(out / "model.csv",
                                                                                                 index=False)
    table = pd.concat([cheap_table.assign(fidelity="cheap"), full_table.assign(fidelity="full")], ignore_index=True)
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
    ax.plot(grid, m_full, "-", color="tab:green", label="full-size model (cheap + discrepancy)")
    ax.fill_between(grid, m_full - 1.96 * s_full, m_full + 1.96 * s_full, color="tab:green", alpha=0.15)
    _save_figure(plt, fig, ax, result, out)
    (out / "calibration.json").write_text(json.dumps(result.as_dict(), indent=2, default=float))
    say(f"{name} = {value:.5g}, 95 % interval [{low:.5g}, {high:.5g}] for {observable} = {target:g} ± {uncertainty:g}: "
        f"{info['cheap_runs']} cheap runs ({info['cheap_run_seconds']:.1f} s each) and {info['full_runs']} full-size "
        f"({info['full_run_seconds']:.1f} s each); at {name} = {value:.4g} the full size reads {d:+.3g} against the "
        f"cheap runs (95 %: {info['offset_low']:+.3g} to {info['offset_high']:+.3g}); {result.wall_time:.0f} s; {out}")
    return result
