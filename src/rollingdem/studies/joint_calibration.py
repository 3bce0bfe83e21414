"""Joint calibration: several free parameters against several measured targets, from one or several experiments.

``calibrate_joint([Target("angle-of-repose", "angle", 32.5, 1.0), Target("rotating-drum", "angle",
38.0, 1.5)], free={"mu": (0.2, 0.9), "mur": (0.0, 0.5)})`` (and ``rollingdem calibrate --target
EXPERIMENT.OBSERVABLE=VALUE±U ... --free NAME=LOW:HIGH ...``). Each target's observable, averaged over
seeds, is modelled over the free parameters by a Gaussian process (scikit-learn); the posterior
of the free parameters (uniform prior on their box, Gaussian likelihood with the target's
uncertainty and the surrogate's) is evaluated on a grid; new points are run where the posterior is
high and the surrogate unsure, round after round. Every run goes through
:func:`rollingdem.studies.sweep.run_sweep` (resumable, on the same Dask cluster). The method and its
outputs: docs/studies.md, "Joint calibration".
"""

from __future__ import annotations

import json
import math
import re
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from rollingdem.errors import ParameterError, check_finite, check_non_negative, check_output_path
from rollingdem.experiments import get_experiment
from rollingdem.experiments.case_file import is_case_file
from rollingdem.experiments.results import pyplot
from rollingdem.studies.calibration import settle_saved
from rollingdem.studies.multifidelity import JointFidelity
from rollingdem.studies.parallel import Execution
from rollingdem.studies.surrogates import fit_surrogate, with_discrepancy
from rollingdem.studies.sweep import TABLE, failure_report, load_sweep, read_table, rows_matching, run_sweep

__all__ = ["Target", "JointSearch", "JointCalibration", "calibrate_joint", "parse_target", "posterior_grid",
           "fit_surrogate"]

LEVEL = 0.95
GRID = {1: 400, 2: 80, 3: 30}  # grid points per free parameter, by their number


@dataclass(frozen=True)
class Target:
    """A measured value (one sigma ``uncertainty``) of ``observable`` of ``experiment``."""

    experiment: str
    observable: str
    value: float
    uncertainty: float = 0.0

    @property
    def label(self) -> str:
        return f"{self.experiment}.{self.observable}"


@dataclass(frozen=True)
class JointSearch:
    """How the box of the free parameters is searched: ``initial`` Latin-hypercube points (None:
    4 per free parameter plus 2), then ``rounds`` rounds of ``per_round`` points each.
    ``share_settling``: an experiment that can (repose-rough-base, rotating-drum) settles each seed's bed once,
    with the free parameters at the middle of their ranges, and starts every run from it."""

    initial: int | None = None
    rounds: int = 3
    per_round: int = 4
    share_settling: bool = False


def _shared_references(search: JointSearch, experiments, box: dict) -> dict:
    """{experiment: the free parameters' reference values of its shared settling, or None}; refused
    when ``search.share_settling`` asks it of targets none of whose experiments can share."""
    if not search.share_settling:
        return {c: None for c in experiments}
    refs = {}
    for c in experiments:
        sc = get_experiment(c, observable=True, what="experiment")
        refs[c] = ({n: 0.5 * (lo + hi) for n, (lo, hi) in box.items() if n in sc.by_name}
                   if hasattr(sc, "share_settling") else None)
    if not any(refs.values()):
        raise ParameterError(f"share_settling is not allowed for experiments {', '.join(map(repr, experiments))}: none "
                             "has a settling stage to share (repose-rough-base and rotating-drum have)")
    return refs


@dataclass
class JointCalibration:
    """The result: best estimate (posterior mean and maximum), the 95 % credible region (the
    highest-posterior cells holding 95 % of it; per parameter its marginal 2.5-97.5 % interval),
    posterior samples, and, where the targets do not pin every parameter, the curve of equally
    good solutions."""

    targets: list
    free: dict
    fixed: dict
    best: dict
    maximum: dict
    interval: dict
    region_fraction: float  # of the box the 95 % region covers
    identified: bool
    message: str
    curve: list
    samples: list
    points: int
    runs: int
    seeds: list
    wall_time: float
    figures: list = field(default_factory=list)
    cells: np.ndarray | None = field(default=None, repr=False)  # grid points (parameter units)
    weights: np.ndarray | None = field(default=None, repr=False)  # posterior weight of each
    region: np.ndarray | None = field(default=None, repr=False)  # True in the 95 % region
    fidelity: dict | None = None  # a multi-fidelity search's runs of each kind and their cost
    settle_seconds_saved: float = 0.0  # wall time the runs saved by starting from shared settled beds

    def in_region(self, point: dict) -> bool:
        """Whether the grid cell nearest ``point`` ({name: value}) lies in the 95 % region."""
        names = list(self.free)
        span = np.array([self.free[n][1] - self.free[n][0] for n in names])
        p = np.array([point[n] for n in names], float)
        return bool(self.region[int(np.argmin(np.sum(((self.cells - p) / span) ** 2, axis=1)))])

    def as_dict(self) -> dict:
        d = {k: v for k, v in asdict(self).items() if k not in ("cells", "weights", "region")}
        d["figures"] = [str(f) for f in self.figures]
        d["targets"] = [asdict(t) for t in self.targets]
        return d


_TARGET = re.compile(r"^\s*([A-Za-z0-9_-]+)\.([A-Za-z0-9_]+)\s*=\s*([^±+]+?)\s*(?:(?:±|\+-|\+/-)\s*(.+))?\s*$")
_VALUE = re.compile(r"^\s*([^±+]+?)\s*(?:(?:±|\+-|\+/-)\s*(.+?))?\s*$")


def parse_value(text: str, target: str) -> tuple[float, float]:
    """``"32.5±1.0"`` (or ``+-``, ``+/-``; without it the uncertainty is 0) as (value, uncertainty);
    refused naming the whole ``target``."""
    m = _VALUE.match(text)
    try:
        return float(m.group(1)), float(m.group(2)) if m.group(2) else 0.0
    except (AttributeError, ValueError):
        raise ParameterError(f"target = {target!r} is not allowed: VALUE and UNCERTAINTY must be numbers") from None


def parse_target(text: str) -> Target:
    """``"angle-of-repose.angle=32.5±1.0"`` (or ``+-``, ``+/-``; without it the uncertainty is 0)."""
    m = _TARGET.match(text)
    if not m:
        raise ParameterError(f"target = {text!r} is not allowed: write EXPERIMENT.OBSERVABLE=VALUE±UNCERTAINTY, e.g. "
                             "angle-of-repose.angle=32.5±1.0")
    experiment, observable = m.group(1), m.group(2)
    return Target(experiment, observable, *parse_value(text.split("=", 1)[1], text))


def _check(targets, free, fix):
    """Everything refused before a run: unknown experiments, observables and parameters, a target no
    run can reach, an empty range. Returns (targets, free {name: (lo, hi)}, per-experiment fixed)."""
    if isinstance(targets, Target):
        targets = [targets]
    targets = list(targets or [])
    if not targets or not all(isinstance(t, Target) for t in targets):
        raise ParameterError(f"targets = {targets!r} is not allowed: give one or more rollingdem Target (or "
                             "--target EXPERIMENT.OBSERVABLE=VALUE±U)")
    experiments = {}
    for t in targets:
        sc = get_experiment(t.experiment, observable=True, what="experiment")
        experiments[t.experiment] = sc
        if t.observable not in sc.observables:
            raise ParameterError(f"target observable = {t.observable!r} is not known for experiment {t.experiment!r}: allowed "
                                 f"are {', '.join(sc.targets)}")
        if t.observable not in sc.targets:
            raise ParameterError(f"target observable = {t.observable!r} of experiment {t.experiment!r} is not something to "
                                 f"calibrate against: allowed are {', '.join(sc.targets)}")
        value = check_finite(f"target {t.label}", t.value)
        check_non_negative(f"uncertainty of target {t.label}", t.uncertainty)
        lo, hi = sc.targets[t.observable]
        if not lo <= value <= hi:
            raise ParameterError(f"target {t.label} = {value:g} is not allowed: no run can give it; "
                                 f"{t.observable} lies in [{lo:g}, {hi:g}] ({sc.observables[t.observable]})")
    if len({t.label for t in targets}) != len(targets):
        raise ParameterError("targets name the same EXPERIMENT.OBSERVABLE twice: give each once")
    if isinstance(free, str):
        free = [free]
    free = dict(free) if isinstance(free, dict) else {n: None for n in (free or [])}
    if not free:
        raise ParameterError("free = {} is not allowed: give at least one free parameter, e.g. mur=0.0:0.5")
    box = {}
    for name, rng in free.items():
        for sc in experiments.values():
            par = sc.by_name.get(name)
            if par is None or par.calibration_range is None:
                allowed = ", ".join(p.name for p in sc.parameters if p.calibration_range)
                raise ParameterError(f"free = {name!r} is not allowed for experiment {sc.name!r}: it is not one of its "
                                     f"real-valued parameters that calibration can vary ({allowed})")
            rng_here = rng or par.calibration_range
            if not math.isfinite(rng_here[1]):
                raise ParameterError(f"free = {name!r} is not allowed without its range for experiment {sc.name!r}: "
                                     f"give --free {name}=LOW:HIGH")
            for v in rng_here:
                par.check(v)
        lo, hi = (float(v) for v in (rng or next(iter(experiments.values())).by_name[name].calibration_range))
        if not lo < hi:
            raise ParameterError(f"free = {name}={lo:g}:{hi:g} is not allowed: the range is empty; write "
                                 "LOW:HIGH with LOW < HIGH")
        box[name] = (lo, hi)
    fix = dict(fix or {})
    both = [k for k in fix if k in box]
    if both:
        raise ParameterError(f"parameter {both[0]!r} is both fixed and free: give it in one place")
    unused = [k for k in fix if not any(k in sc.by_name for sc in experiments.values())]
    if unused:
        raise ParameterError(f"fix = {unused[0]!r} is not a parameter of any experiment calibrated ({', '.join(experiments)})")
    per_experiment = {}
    for name, sc in experiments.items():
        per_experiment[name] = {k: v for k, v in fix.items() if k in sc.by_name}
        sc.resolve({**per_experiment[name], **{k: lo for k, (lo, _) in box.items()}})  # refuse bad fixed values now
    return targets, box, per_experiment


def _grid(d: int) -> np.ndarray:
    """Cell centres of the unit box: a regular grid for up to 3 parameters, a Sobol sample above."""
    if d in GRID:
        n = GRID[d]
        axes = [(np.arange(n) + 0.5) / n] * d
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, d)
    from scipy.stats import qmc  # deferred: slow to load, used here only

    return qmc.Sobol(d, seed=0).random(2 ** 15)


def posterior_grid(surrogates, targets, d: int):
    """The posterior on the grid: (cells (n, d) in the unit box, normalised weights, each target's
    surrogate mean and std on the cells). Log-likelihood of a cell: the sum over targets of
    -((m(x) - y)^2 / (u^2 + s(x)^2) + log(u^2 + s(x)^2)) / 2, m and s the surrogate's mean and std."""
    cells = _grid(d)
    logp = np.zeros(len(cells))
    means, stds = [], []
    for f, t in zip(surrogates, targets):
        m, s = f(cells)
        var = t.uncertainty ** 2 + s ** 2 + 1e-300
        logp += -0.5 * ((m - t.value) ** 2 / var + np.log(var))
        means.append(m)
        stds.append(s)
    w = np.exp(logp - logp.max())
    return cells, w / w.sum(), np.array(means), np.array(stds)


@dataclass
class _Posterior:
    """The posterior on the grid: cells of the unit box, their weights, each target's surrogate mean
    and std on them."""

    cells: np.ndarray
    weights: np.ndarray
    means: np.ndarray
    stds: np.ndarray


def _hpd(weights: np.ndarray, level=LEVEL) -> np.ndarray:
    """Mask of the highest-weight cells holding ``level`` of the total."""
    order = np.argsort(weights)[::-1]
    keep = np.cumsum(weights[order]) <= level
    keep[np.argmax(~keep) if (~keep).any() else len(keep) - 1] = True  # the cell that crosses the level
    mask = np.zeros(len(weights), bool)
    mask[order[keep]] = True
    return mask


def _next_points(cells, weights, stds, targets, existing, k) -> np.ndarray:
    """``k`` new points: where the posterior weight times the surrogate's share of the variance
    is largest, each pushing its neighbours down so that the points spread."""
    u2 = np.array([t.uncertainty ** 2 for t in targets])[:, None]
    unsure = np.sum(stds ** 2 / (u2 + stds ** 2 + 1e-300), axis=0)
    score = weights * (unsure + 1e-3)
    chosen = []
    for p in existing:  # not again where a point ran
        score = score * (1.0 - np.exp(-np.sum((cells - p) ** 2, axis=1) / (2 * 0.03 ** 2)))
    for _ in range(k):
        j = int(np.argmax(score))
        chosen.append(cells[j])
        score = score * (1.0 - np.exp(-np.sum((cells - cells[j]) ** 2, axis=1) / (2 * 0.1 ** 2)))
    return np.array(chosen)


def calibrate_joint(targets, free, fix=None, seeds=None, search: JointSearch = JointSearch(), out=None,
                    execution: Execution = Execution(), progress: bool = True, echo=None,
                    fidelity=None) -> JointCalibration:
    """Find the ``free`` parameters ({name: (low, high)} or names, for their default ranges) whose
    simulated observables match every one of ``targets`` (a list of :class:`Target`), with the
    parameters ``fix`` held (each in the experiments that have it); ``seeds`` runs per point (default 3
    for a random experiment, 1 for a deterministic one), searched as ``search`` says, the runs going
    where ``execution`` says. Writes ``out/EXPERIMENT/runs.csv`` per experiment, ``calibration.json``,
    ``corner.png`` and ``observables.png``; ``echo`` tells each round and the result. With a
    ``fidelity`` (``rollingdem.studies.multifidelity.JointFidelity``) cheap runs make a surrogate per
    target and the full-size runs a discrepancy added to it (docs/studies.md, "Multi-fidelity
    calibration"); the rounds place full-size points."""
    from scipy.stats import qmc  # deferred: slow to load, used here only

    tic = time.perf_counter()
    targets, box, fixed = _check(targets, free, fix)
    if not isinstance(search, JointSearch):
        raise ParameterError(f"search = {search!r} is not allowed: must be a rollingdem.studies.joint_calibration.JointSearch")
    if not isinstance(execution, Execution):
        raise ParameterError(f"execution = {execution!r} is not allowed: must be a rollingdem.studies.calibration.Execution")
    names = list(box)
    d = len(names)
    initial = search.initial if search.initial is not None else 4 * d + 2
    for k, v, n_min in (("initial", initial, d + 1), ("rounds", search.rounds, 0), ("per_round", search.per_round, 1)):
        if isinstance(v, bool) or not isinstance(v, int) or v < n_min:
            raise ParameterError(f"{k} = {v!r} is not allowed: must be an integer >= {n_min}")
    experiments = list(dict.fromkeys(t.experiment for t in targets))
    seed_count = {c: seeds if seeds is not None else (3 if get_experiment(c, observable=True, what="experiment").stochastic else 1)
                  for c in experiments}
    out = check_output_path("out", out) if out is not None else Path(tempfile.mkdtemp(prefix="rollingdem-joint-"))
    for c in experiments:  # refuse a bad seeds value before any run
        load_sweep({"experiment": c, "fixed": fixed[c], "points": [{n: box[n][0] for n in names}], "seeds": seed_count[c]})
    shared = _shared_references(search, experiments, box)
    say = echo or (lambda *_: None)
    lows = np.array([box[n][0] for n in names])
    highs = np.array([box[n][1] for n in names])
    unit = qmc.LatinHypercube(d=d, seed=0).random(initial)
    design = list(unit)

    def run(m):
        points = [dict(zip(names, map(float, lows + u * (highs - lows)))) for u in design]
        tables = {}
        for c in experiments:
            spec = load_sweep({"experiment": c, "fixed": fixed[c], "points": points, "seeds": seed_count[c]})
            tables[c] = run_sweep(spec, out / folder_of(c), mapper=m, progress=progress, summary=False,
                                  share_settling=shared[c]).table
            report = failure_report(tables[c], out / folder_of(c) / TABLE)
            if report:
                say(f"{c}: {report}")
        return tables

    info = None
    with execution.runner() as m:
        if fidelity is not None:
            tables, surrogates, stats, info = _multifidelity(fidelity, targets, experiments, fixed, (names, lows, highs),
                                                             seed_count, search, out, m, progress, say)
            cells, weights, means, stds = posterior_grid(surrogates, targets, d)
            _check_reach(targets, means, stds, box, out)
        for r in range(search.rounds + 1 if fidelity is None else 0):
            tables = run(m)
            surrogates, stats = _surrogates(tables, targets, names, lows, highs)
            cells, weights, means, stds = posterior_grid(surrogates, targets, d)
            _check_reach(targets, means, stds, box, out)
            if r == search.rounds:
                break
            new = _next_points(cells, weights, stds, targets, design, search.per_round)
            say(f"round {r + 1}: {len(new)} new points where the posterior is high and the surrogate unsure")
            design += list(new)
    post = _Posterior(cells, weights, means, stds)
    result = _summarise(targets, box, fixed, post, names, lows, highs, stats, tables, seed_count, tic)
    if info is not None:
        result.fidelity, result.runs = info, info["cheap_runs"] + info["full_runs"]
    result.settle_seconds_saved = _settle_saved(out, experiments)
    _figures(result, post, names, lows, highs, stats, out)
    (out / "calibration.json").write_text(json.dumps(result.as_dict(), indent=2, default=float))
    np.savez(out / "posterior.npz", names=np.array(names), cells=result.cells, weights=result.weights,
             region=result.region)
    saved = (f"; the shared settled beds saved {result.settle_seconds_saved:.0f} s of runs"
             if search.share_settling else "")
    say(result.message + f" ({result.runs} runs, {result.wall_time:.0f} s{saved}; {out})")
    return result


def _settle_saved(out: Path, experiments) -> float:
    """The wall-clock seconds the runs of every experiment (cheap and full size) saved by starting
    from shared settled beds."""
    return sum(settle_saved(read_table(out / folder_of(c) / TABLE, get_experiment(c, observable=True)))
               for c in experiments)


def _multifidelity(fidelity, targets, experiments, fixed, box, seed_count, search, out, m, progress, say):
    """The multi-fidelity search: a Latin hypercube of cheap runs and a surrogate per target from
    them, then full-size points where the posterior is high and the model unsure (first from the
    cheap surrogates alone), each target's model the cheap surrogate plus a Gaussian process of
    the full-size residuals (``multifidelity.with_discrepancy``). Returns (the full-size runs per
    experiment, the surrogates, their point statistics, what ran of each kind). ``box``: the free
    parameters' (names, lows, highs)."""
    from scipy.stats import qmc  # deferred: slow to load, used here only

    if not isinstance(fidelity, JointFidelity):
        raise ParameterError(f"fidelity = {fidelity!r} is not allowed: must be a "
                             "rollingdem.studies.multifidelity.JointFidelity")
    names, lows, highs = box
    d = len(names)
    fidelity.check(d, experiments)
    cheap_fix = {c: {**fixed[c], **fidelity.cheap.get(c, {})} for c in experiments}
    full_of = {}  # the full-size value of each cheap parameter
    for c in experiments:
        sc = get_experiment(c, observable=True, what="experiment")
        for k in fidelity.cheap.get(c, {}):
            if k in names:
                raise ParameterError(f"cheap = {k}=... is not allowed: {k} is a free parameter")
            if k not in sc.by_name:
                raise ParameterError(f"cheap = {k!r} is not a parameter of experiment {c!r}")
        full_of[c] = {k: fixed[c].get(k, sc.by_name[k].default) for k in fidelity.cheap.get(c, {})}
        try:
            load_sweep({"experiment": c, "fixed": cheap_fix[c], "points": [dict(zip(names, map(float, lows)))],
                        "seeds": seed_count[c]})
            if c in fidelity.cheap:  # its scene built once: a parcel wider than an opening refused before any run
                sc.check({**cheap_fix[c], **{n: float(v) for n, v in zip(names, lows) if n in sc.by_name}})
        except ParameterError as err:
            raise ParameterError(f"cheap = {fidelity.cheap.get(c)} is not allowed for {c!r}: {err}") from None
    shared = _shared_references(search, experiments, dict(zip(names, zip(lows, highs))))
    cheap_n = fidelity.cheap_initial if fidelity.cheap_initial is not None else 6 * d + 2
    full_n = fidelity.full_initial if fidelity.full_initial is not None else d + 1

    def sweep(design, which):
        points = [dict(zip(names, map(float, lows + u * (highs - lows)))) for u in design]
        tables = {}
        for c in experiments:
            spec = load_sweep({"experiment": c, "fixed": which[c], "points": points, "seeds": seed_count[c]})
            table = run_sweep(spec, out / folder_of(c), mapper=m, progress=progress, summary=False,
                              share_settling=shared[c]).table
            report = failure_report(table, out / folder_of(c) / TABLE)
            if report:
                say(f"{c}: {report}")
            tables[c] = table
        return tables

    say(f"cheap runs: {cheap_n} points of a Latin hypercube ("
        + "; ".join(f"{c}: {', '.join(f'{k} = {v}' for k, v in v_.items())}" for c, v_ in fidelity.cheap.items()) + ")")
    cheap_design = list(qmc.LatinHypercube(d=d, seed=0).random(cheap_n))
    tables = sweep(cheap_design, cheap_fix)
    cheap_tables = {c: rows_matching(t, fidelity.cheap.get(c, {})) for c, t in tables.items()}
    cheap_surrogates, _ = _surrogates(cheap_tables, targets, names, lows, highs)
    surrogates = cheap_surrogates
    full_design: list = []
    for r in range(search.rounds + 1):
        cells, weights, means, stds = posterior_grid(surrogates, targets, d)
        new = _next_points(cells, weights, stds, targets, full_design, full_n if r == 0 else search.per_round)
        say(f"full-size round {r + 1}: {len(new)} points where the posterior is high and the model unsure"
            + (" (the cheap runs' posterior)" if r == 0 else ""))
        full_design += list(new)
        tables = sweep(full_design, fixed)
        # an experiment without cheap settings ran its cheap points at full size: they join its full-size runs
        full_tables = {c: rows_matching(t, full_of[c]) if c in fidelity.cheap else
                       pd.concat([cheap_tables[c], t], ignore_index=True).drop_duplicates("run_id")
                       for c, t in tables.items()}
        full_surrogates, stats = _surrogates(full_tables, targets, names, lows, highs, fit=False)
        surrogates = []
        for t, g, st in zip(targets, cheap_surrogates, stats):
            x = (st[names].to_numpy(float) - lows) / (highs - lows)
            pooled = float(st["seed_sd"].iloc[0]) ** 2
            surrogates.append(with_discrepancy(g, x, st["mean"].to_numpy(float),
                                               pooled / st["count"].to_numpy(float) + 1e-12)[0])
    cost = {}
    for kind, tabs in (("cheap", [cheap_tables[c] for c in fidelity.cheap]), ("full", list(full_tables.values()))):
        runs = pd.concat(tabs, ignore_index=True)
        cost[kind] = (int(len(runs)), float(pd.to_numeric(runs["wall_time_s"], errors="coerce").sum()))
    info = {"model": "each target: GP of the cheap runs + GP of the full-size residuals (Kennedy-O'Hagan, scale 1)",
            "cheap": {c: dict(v) for c, v in fidelity.cheap.items()}, "cheap_points": cheap_n,
            "full_points": len(full_design), "cheap_runs": cost["cheap"][0], "full_runs": cost["full"][0],
            "cheap_run_seconds": cost["cheap"][1] / max(cost["cheap"][0], 1),
            "full_run_seconds": cost["full"][1] / max(cost["full"][0], 1)}
    say(f"{info['cheap_runs']} cheap runs ({info['cheap_run_seconds']:.1f} s each) and {info['full_runs']} full-size "
        f"({info['full_run_seconds']:.1f} s each)")
    return full_tables, surrogates, stats, info


def folder_of(experiment: str) -> str:
    """The folder of an experiment's runs in the calibration's folder: its name, a case file's stem."""
    return Path(experiment).stem if is_case_file(experiment) else experiment


def _check_reach(targets, means, stds, box, out) -> None:
    """Refuse a target the surrogate puts outside everything the box gives (beyond twice its
    uncertainty): the answer would be an edge of the box, not a calibration."""
    for t, m, s in zip(targets, means, stds):
        lo, hi = float(np.min(m - 2 * s)), float(np.max(m + 2 * s))
        if not lo - 2 * t.uncertainty <= t.value <= hi + 2 * t.uncertainty:
            ranges = ", ".join(f"{n} in [{a:g}, {b:g}]" for n, (a, b) in box.items())
            raise ParameterError(f"target {t.label} = {t.value:g} is outside what {ranges} gives: {t.observable} from "
                                 f"{float(m.min()):.4g} to {float(m.max()):.4g}; widen the ranges with --free "
                                 f"NAME=LOW:HIGH (runs kept in {out})")


def _surrogates(tables, targets, names, lows, highs, fit: bool = True):
    """One surrogate per target from its experiment's runs: the mean over seeds per point, its variance
    from the seed scatter pooled over the points (a deterministic experiment: a tiny nugget).
    Without ``fit``, the point statistics alone (the surrogates None)."""
    surrogates, stats = [], []
    for t in targets:
        table = tables[t.experiment]
        ok = table[table["status"] == "ok"].copy()
        ok["_y"] = pd.to_numeric(ok[t.observable], errors="coerce")
        ok = ok[np.isfinite(ok["_y"])]
        grp = ok.groupby(names)["_y"].agg(["mean", "var", "count"]).reset_index()
        if len(grp) < 2:
            report = failure_report(table, Path(folder_of(t.experiment)) / TABLE)
            raise ParameterError(f"target {t.label}: fewer than two points gave a finite {t.observable}"
                                 + (f"; {report}" if report else ""))
        multi = grp["count"] >= 2
        dof = float((grp.loc[multi, "count"] - 1).sum())
        pooled = float(((grp.loc[multi, "count"] - 1) * grp.loc[multi, "var"]).sum() / dof) if dof > 0 else 0.0
        x = (grp[names].to_numpy(float) - lows) / (highs - lows)
        var = pooled / grp["count"].to_numpy(float) + 1e-10 * (grp["mean"].std() ** 2 + 1e-12)
        surrogates.append(fit_surrogate(x, grp["mean"].to_numpy(float), var) if fit else None)
        stats.append(grp.assign(seed_sd=math.sqrt(pooled)))
    return surrogates, stats


def _summarise(targets, box, fixed, post: _Posterior, names, lows, highs, stats, tables, seed_count, tic):
    cells, weights = post.cells, post.weights
    d = len(names)
    x = lows + cells * (highs - lows)
    best = dict(zip(names, map(float, weights @ x)))
    top = int(np.argmax(weights))
    maximum = dict(zip(names, map(float, x[top])))
    interval = {}
    for k, n in enumerate(names):
        order = np.argsort(x[:, k])
        cdf = np.cumsum(weights[order])
        interval[n] = (float(x[order][np.searchsorted(cdf, 0.025)][k]),
                       float(x[order][min(np.searchsorted(cdf, 0.975), len(cdf) - 1)][k]))
    region = _hpd(weights)
    fraction = float(region.mean())
    # pinned: as many targets as free parameters, and each parameter's interval a small part of its range
    widths = [(interval[n][1] - interval[n][0]) / (box[n][1] - box[n][0]) for n in names]
    identified = len(targets) >= d and max(widths) < 0.5
    curve = []
    if not identified and d == 2:
        # the ridge: for each value of the first parameter, the second where the posterior peaks,
        # kept where that peak lies in the 95 % region
        n0 = GRID[2]
        w2, r2 = weights.reshape(n0, n0), region.reshape(n0, n0)
        x2 = x.reshape(n0, n0, 2)
        for i in range(n0):
            j = int(np.argmax(w2[i]))
            if r2[i, j]:
                curve.append([float(x2[i, j, 0]), float(x2[i, j, 1])])
    if identified:
        message = ("calibrated: " + ", ".join(f"{n} = {best[n]:.4g} [{interval[n][0]:.4g}, {interval[n][1]:.4g}]"
                                              for n in names) + " (posterior mean, 95 % interval)")
    elif len(targets) < d:
        message = (f"{len(targets)} target{'s' * (len(targets) > 1)} cannot pin {d} free parameters: the equally good "
                   f"solutions form a {'curve' if d == 2 else 'set'} ({len(curve)} points in calibration.json, drawn in "
                   "corner.png); fix a parameter or add a target")
    else:
        message = ("the targets do not pin the parameters within their ranges: the 95 % region spans "
                   + ", ".join(f"{n} [{interval[n][0]:.4g}, {interval[n][1]:.4g}]" for n in names)
                   + "; more seeds, smaller uncertainties or another target narrow it")
    rng = np.random.default_rng(1)
    pick = rng.choice(len(cells), size=2000, p=weights)
    cell = (highs - lows) / GRID[d] if d in GRID else 0.0  # a Sobol sample has no cells to spread over
    samples = x[pick] + (rng.random((2000, d)) - 0.5) * cell
    runs = sum(int(len(t)) for t in tables.values())
    return JointCalibration(targets, {n: list(box[n]) for n in names}, fixed, best, maximum,
                            {n: list(v) for n, v in interval.items()}, fraction, identified, message, curve,
                            samples.round(6).tolist(), points=int(len(stats[0])), runs=runs,
                            seeds=sorted({s for v in seed_count.values() for s in (range(1, v + 1) if isinstance(v, int) else v)}), wall_time=time.perf_counter() - tic,
                            cells=x, weights=weights, region=region)


def _figures(result, post: _Posterior, names, lows, highs, stats, out: Path) -> None:
    cells, weights, means, stds = post.cells, post.weights, post.means, post.stds
    plt = pyplot()
    d = len(names)
    x = lows + cells * (highs - lows)
    region = _hpd(weights)
    fig, axes = plt.subplots(d, d, figsize=(3.2 * d + 1, 3.2 * d + 0.5), squeeze=False)
    for i in range(d):
        for j in range(d):
            ax = axes[i, j]
            if j > i:
                ax.axis("off")
                continue
            if i == j:
                edges = np.linspace(lows[i], highs[i], 41)
                ax.hist(x[:, i], bins=edges, weights=weights, color="tab:blue", alpha=0.7)
                ax.axvspan(*result.interval[names[i]], color="tab:red", alpha=0.1)
                ax.axvline(result.best[names[i]], color="tab:red")
                ax.set_yticks([])
            else:
                h, xe, ye = np.histogram2d(x[:, j], x[:, i], bins=40, weights=weights,
                                           range=[[lows[j], highs[j]], [lows[i], highs[i]]])
                ax.imshow(h.T, origin="lower", extent=[xe[0], xe[-1], ye[0], ye[-1]], aspect="auto", cmap="Blues")
                inside = x[region]
                ax.plot(inside[:, j], inside[:, i], ",", color="tab:orange", alpha=0.3)
                pts = stats[0][names].to_numpy(float)
                ax.plot(pts[:, j], pts[:, i], "k.", ms=4, label="points run")
                if result.curve and d == 2:
                    c = np.array(result.curve)
                    ax.plot(c[:, 0], c[:, 1], "-", color="tab:red", lw=1.5, label="equally good solutions")
                else:
                    ax.plot(result.best[names[j]], result.best[names[i]], "r+", ms=12, mew=2, label="best estimate")
                ax.legend(fontsize=6)
            if i == d - 1:
                ax.set_xlabel(names[j])
            if j == 0 and i > 0:
                ax.set_ylabel(names[i])
    fig.suptitle("posterior of the free parameters; orange: 95 % region", fontsize=9)
    fig.tight_layout()
    path = out / "corner.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    result.figures.append(path)

    fig, axes = plt.subplots(1, len(result.targets), figsize=(5 * len(result.targets), 4), squeeze=False)
    for k, (t, ax) in enumerate(zip(result.targets, axes[0])):
        pts = stats[k]
        if d == 1:
            order = np.argsort(x[:, 0])
            ax.plot(x[order, 0], means[k][order], "-", color="tab:green", label="surrogate")
            ax.fill_between(x[order, 0], (means[k] - 1.96 * stds[k])[order], (means[k] + 1.96 * stds[k])[order],
                            color="tab:green", alpha=0.2)
            ax.plot(pts[names[0]], pts["mean"], "o", color="tab:blue", label="mean over seeds")
            ax.axhspan(t.value - 1.96 * t.uncertainty, t.value + 1.96 * t.uncertainty, color="tab:orange", alpha=0.2)
            ax.axhline(t.value, color="tab:orange", label=f"target {t.value:g} ± 1.96 × {t.uncertainty:g}")
            ax.set_xlabel(names[0])
        else:
            n0 = GRID.get(d)
            if d == 2:
                grid = means[k].reshape(n0, n0)
                xs, ys = x.reshape(n0, n0, 2)[:, 0, 0], x.reshape(n0, n0, 2)[0, :, 1]
                cs = ax.contourf(xs, ys, grid.T, levels=14, cmap="viridis")
                fig.colorbar(cs, ax=ax)
                ax.contour(xs, ys, grid.T, levels=[t.value - 1.96 * t.uncertainty, t.value,
                                                   t.value + 1.96 * t.uncertainty] if t.uncertainty else [t.value],
                           colors=["w", "r", "w"] if t.uncertainty else ["r"], linewidths=1.2)
                ax.plot(pts[names[0]], pts[names[1]], "k.", ms=4)
                ax.set_xlabel(names[0])
                ax.set_ylabel(names[1])
            else:
                ax.scatter(pts[names[0]], pts["mean"], c="tab:blue", s=10)
                ax.axhline(t.value, color="tab:orange")
                ax.set_xlabel(names[0])
        ax.set_title(f"{t.label}: surrogate, target (red)", fontsize=9)
        if d == 1:
            ax.legend(fontsize=7)
    fig.tight_layout()
    path = out / "observables.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    result.figures.append(path)
