"""Parameter sweeps: one experiment over many parameter sets and seeds, on Dask, resumable.

A sweep file names an experiment of :mod:`rollingdem.experiments`, fixed parameters and a grid, a
list of points or a Latin-hypercube sample, repeated over seeds. Runs are appended to
``OUT/runs.csv`` as they finish (a rerun skips those done); ``OUT/summary.csv`` and ``summary.png``
give the means over seeds with 95 % intervals. docs/studies.md, "Sweeps"."""

from __future__ import annotations

import csv
import hashlib
import itertools
import json
import math
import os
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, Union

import numpy as np
import pandas as pd
from pydantic import AliasChoices, BaseModel, ConfigDict, Field, ValidationError, model_validator
from tqdm import tqdm

from rollingdem.analysis.intervals import confidence_interval
from rollingdem.errors import ParameterError, check_output_path
from rollingdem.experiments import Experiment, get_experiment
from rollingdem.experiments.case_file import is_case_file
from rollingdem.experiments.results import pyplot
from rollingdem.io.mapping_file import read_mapping
from rollingdem.scene.simulation import __version__
from rollingdem.studies.parallel import check_workers, completed, runner

__all__ = ["SweepSpec", "SweepResult", "failure_report", "load_sweep", "expand", "rows_matching", "run_sweep", "summarize"]

TABLE = "runs.csv"
BOOKKEEPING = ("run_id", "experiment", "status")
TRAILER = ("wall_time_s", "version", "error", "finished_at")


class SampleSpec(BaseModel):
    """A Latin-hypercube sample of ``n`` points over ``ranges`` (name: [low, high])."""

    model_config = ConfigDict(extra="forbid")
    n: int = Field(ge=1)
    ranges: dict[str, tuple[float, float]]
    seed: int = Field(0, ge=0)


class SweepSpec(BaseModel):
    """A sweep file: the experiment (key ``experiment``, or ``case`` as older files name it), fixed
    parameters, exactly one of grid / points / sample, and seeds."""

    model_config = ConfigDict(extra="forbid", populate_by_name=True)
    experiment: str = Field(validation_alias=AliasChoices("experiment", "case"))
    fixed: dict[str, Any] = {}
    grid: Optional[dict[str, list[Any]]] = None
    points: Optional[list[dict[str, Any]]] = None
    sample: Optional[SampleSpec] = None
    seeds: Union[int, list[int]] = 1

    @model_validator(mode="after")
    def _one_design(self):
        given = [k for k in ("grid", "points", "sample") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of grid, points, sample (got {', '.join(given) or 'none'})")
        if isinstance(self.seeds, int) and self.seeds < 1:
            raise ValueError(f"seeds = {self.seeds} is not allowed: a count must be >= 1 (or give a list of seeds)")
        if isinstance(self.seeds, list):
            if not self.seeds:
                raise ValueError("seeds = [] is not allowed: give at least one seed")
            if any(s < 0 for s in self.seeds):
                raise ValueError(f"seeds = {self.seeds} is not allowed: seeds must be >= 0")
        if self.grid is not None:
            empty = [k for k, v in self.grid.items() if not v]
            if not self.grid or empty:
                raise ValueError(f"grid is empty{' in ' + ', '.join(empty) if empty else ''}: give each swept "
                                 "parameter at least one value")
        if self.points is not None and not self.points:
            raise ValueError("points = [] is empty: give at least one point")
        if self.sample is not None:
            if not self.sample.ranges:
                raise ValueError("sample.ranges is empty: give at least one parameter range")
            bad = {k: v for k, v in self.sample.ranges.items() if not v[0] < v[1]}
            if bad:
                raise ValueError(f"sample.ranges {bad} is not allowed: each range must be [low, high] with low < high")
        return self

    @property
    def seed_list(self) -> list[int]:
        return list(range(1, self.seeds + 1)) if isinstance(self.seeds, int) else list(self.seeds)


def load_sweep(source) -> SweepSpec:
    """Read and check a sweep file (YAML, TOML by extension) or a mapping; ParameterError on bad input."""
    if isinstance(source, SweepSpec):
        return source

    data, name = read_mapping(source, "sweep file")
    try:
        spec = SweepSpec.model_validate(data)
    except ValidationError as err:
        lines = ["the sweep is not valid:" if name == "<dict>" else f"sweep file {name} is not valid:"]
        for e in err.errors():
            loc = ".".join(str(p) for p in e["loc"])
            if e["type"] == "extra_forbidden":
                lines.append(f"  key {loc!r}: not a known key (allowed: experiment, fixed, grid, points, sample, seeds)")
            elif e["type"] == "missing":
                lines.append(f"  key {loc!r}: missing (required)")
            else:
                lines.append(f"  {loc + ': ' if loc else ''}{e['msg'].removeprefix('Value error, ')}"
                             f"{'' if loc == '' else ' (got ' + json.dumps(e.get('input'), default=str)[:80] + ')'}")
        raise ParameterError("\n".join(lines)) from None

    if is_case_file(spec.experiment) and isinstance(source, (str, Path)) and not Path(spec.experiment).is_absolute():
        spec.experiment = str(Path(source).parent / spec.experiment)  # a case file named from the sweep file
    expand(spec)  # refuse unknown parameters and bad values before anything runs
    return spec


def swept_parameters(spec: SweepSpec) -> list[str]:
    """Names the design varies (seed excluded), in file order."""
    if spec.grid is not None:
        return list(spec.grid)
    if spec.sample is not None:
        return list(spec.sample.ranges)
    names: list[str] = []
    for p in spec.points:
        names += [k for k in p if k not in names]
    return names


def expand(spec: SweepSpec) -> list[dict]:
    """Every run of the sweep as a full, checked parameter set (the experiment's defaults filled in)."""
    experiment = get_experiment(spec.experiment, observable=True, what="experiment")
    if spec.grid is not None:
        keys = list(spec.grid)
        design = [dict(zip(keys, combo)) for combo in itertools.product(*spec.grid.values())]
    elif spec.points is not None:
        design = [dict(p) for p in spec.points]
    else:
        from scipy.stats import qmc  # deferred: slow to load, used here only

        for name in spec.sample.ranges:
            par = experiment.by_name.get(name)
            if par is not None and (par.choice or par.integer):
                raise ParameterError(f"sample.ranges: {name!r} is not allowed: Latin-hypercube sampling needs a "
                                     "real-valued parameter")
        unit = qmc.LatinHypercube(d=len(spec.sample.ranges), seed=spec.sample.seed).random(spec.sample.n)
        lows = np.array([r[0] for r in spec.sample.ranges.values()])
        highs = np.array([r[1] for r in spec.sample.ranges.values()])
        values = qmc.scale(unit, lows, highs)
        design = [dict(zip(spec.sample.ranges, map(float, row))) for row in values]
    if "seed" in spec.fixed or any("seed" in d for d in design):
        raise ParameterError("seed is not allowed in fixed, grid, points or sample: give the seeds under 'seeds'")
    clash = [k for k in spec.fixed if any(k in d for d in design)]
    if clash:
        raise ParameterError(f"parameter {clash[0]!r} is both fixed and swept: give it in one place")
    if "seed" not in experiment.by_name:  # a deterministic experiment: one run per point
        if len(spec.seed_list) > 1:
            raise ParameterError(f"seeds = {spec.seeds!r} is not allowed for experiment {experiment.name!r}: it takes no seed "
                                 "(its result does not depend on one); leave seeds out")
        return [experiment.resolve({**spec.fixed, **d}) for d in design]
    runs = []
    for d in design:
        for seed in spec.seed_list:
            runs.append(experiment.resolve({**spec.fixed, **d, "seed": seed}))
    return runs


def run_id(experiment: str, params: dict) -> str:
    """Stable id of a run: its experiment and full parameter set."""
    # the key keeps the ids of runs in tables written before experiments had their name
    text = json.dumps({"case": experiment, **params}, sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:16]


class _Execute:
    """One run in a worker: the experiment's observables, wall time, version; an exception becomes
    a failed row. Picklable, so Dask can ship it: the experiment goes by reference to its class,
    which a worker imports (and so registers) from the class's module."""

    def __init__(self, experiment: Experiment):
        self.experiment = experiment

    def __call__(self, params: dict) -> dict:
        tic = time.perf_counter()
        try:
            observables, status, error = self.experiment.observe(dict(params)), "ok", ""
        except Exception as err:  # recorded, and the sweep goes on
            observables, status = {}, "failed"
            error = f"{type(err).__name__}: {err}\n{traceback.format_exc(limit=4)}"[-2000:]
        return {"observables": observables, "status": status, "error": error, "version": __version__,
                "wall_time_s": time.perf_counter() - tic}


@dataclass
class SweepResult:
    """A sweep's outcome: every row of the table, and what this invocation did."""

    table: pd.DataFrame
    out: Path
    ran: int
    skipped: int
    failed: int
    wall_time: float
    figures: list[Path] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.failed == 0 and bool(len(self.table)) and bool((self.table["status"] == "ok").all())


def _columns(experiment: Experiment) -> list[str]:
    return [*BOOKKEEPING, *(p.name for p in experiment.parameters), *experiment.observables, *TRAILER]


def read_table(path: Path, experiment: Experiment | None = None) -> pd.DataFrame:
    """The runs table; a line cut short by a crash is dropped, the last row of a run id wins. An
    older table's ``case`` column is read as ``experiment``, and an observable it lacks (one an
    experiment gained since) as empty."""
    if not path.exists() or path.stat().st_size == 0:
        return pd.DataFrame(columns=_columns(experiment) if experiment else list(BOOKKEEPING))
    table = pd.read_csv(path, dtype={"run_id": str, "status": str, "error": str, "note": str},
                        keep_default_na=True, on_bad_lines="skip", engine="python").rename(columns={"case": "experiment"})
    if experiment is not None and set(table.columns) < set(_columns(experiment)) and \
            set(_columns(experiment)) - set(table.columns) <= set(experiment.observables):
        table = table.reindex(columns=_columns(experiment))
    if experiment is not None and list(table.columns) != _columns(experiment):
        other = table["experiment"].iloc[0] if "experiment" in table.columns and len(table) else "another experiment"
        raise ParameterError(f"{path} holds runs of {other!r} with other columns than experiment "
                             f"{experiment.name!r}: give another --out folder")
    table = table[table["status"].isin(["ok", "failed"])]
    return table.drop_duplicates("run_id", keep="last").reset_index(drop=True)


def _append(path: Path, columns: list[str], row: dict) -> None:
    new = not path.exists() or path.stat().st_size == 0
    if not new:
        with open(path, "rb") as fh:
            fh.seek(-1, os.SEEK_END)
            cut = fh.read(1) != b"\n"  # a row left half written by a crash: start a fresh line
    with open(path, "a", newline="") as fh:
        if not new and cut:
            fh.write("\n")
        writer = csv.DictWriter(fh, fieldnames=columns, extrasaction="ignore")
        if new:
            writer.writeheader()
        writer.writerow(row)
        fh.flush()
        os.fsync(fh.fileno())


def failure_report(table: pd.DataFrame, path: Path) -> str | None:
    """How many runs of ``table`` failed, the first one's reason in one line and where the rest
    are; None when none failed."""
    failed = table[table["status"] == "failed"] if len(table) else table
    if not len(failed):
        return None
    first = str(failed["error"].iloc[0]).strip().splitlines()[0] if len(failed) else ""
    kind, _, reason = first.partition(": ")
    reason = reason if kind.isidentifier() and reason else first
    return (f"{len(failed)} of {len(table)} runs failed; the first: {reason}; every failure's reason and traceback "
            f"are in {path} (column error)")


def rows_matching(table: pd.DataFrame, values: dict) -> pd.DataFrame:
    """The rows of a runs table whose parameters equal ``values`` (numbers to round-off)."""
    keep = np.ones(len(table), bool)
    for k, v in values.items():
        if isinstance(v, str):
            keep &= table[k].astype(str).to_numpy() == v
        else:
            keep &= np.isclose(pd.to_numeric(table[k], errors="coerce").to_numpy(float), float(v))
    return table[keep]


def run_sweep(spec, out, workers: int | None = None, scheduler: str | None = None, threads: int = 1,
              progress: bool = True, retry_failed: bool = False, mapper=None, summary: bool = True,
              echo=None, on_run=None, share_settling: dict | None = None) -> SweepResult:
    """Run every run of ``spec`` not yet in ``out/runs.csv``; returns the whole table.

    ``workers`` x ``threads`` fill the cores by default (``threads`` Numba threads per run, cores //
    threads worker processes of a Dask LocalCluster); ``scheduler`` uses an existing cluster;
    ``mapper`` (a :class:`rollingdem.studies.parallel.Mapper` or ``map``) reuses one already open.
    ``retry_failed`` runs again the runs the table records as failed; ``on_run()`` is called after
    each run is written. ``share_settling`` ({parameter: reference value}): an experiment that can
    (``share_settling``) settles its bed once with those parameters at those values and starts
    every run from it, kept in ``out/settled``.
    """
    check_workers(workers, threads)
    spec = load_sweep(spec)
    experiment = get_experiment(spec.experiment, observable=True, what="experiment")
    if share_settling and not hasattr(experiment, "share_settling"):
        raise ParameterError(f"share_settling is not allowed for experiment {spec.experiment!r}: it has no settling "
                             "stage to share (repose-rough-base and rotating-drum have)")
    out = check_output_path("out", out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / TABLE
    columns = _columns(experiment)
    table = read_table(path, experiment)
    if path.exists() and path.stat().st_size and list(pd.read_csv(path, nrows=0).columns) != columns:
        table.to_csv(path, index=False, columns=columns)  # an older table: rows of today's columns follow
    if retry_failed and len(table) and (table["status"] == "failed").any():
        table = table[table["status"] == "ok"]
        table.to_csv(path, index=False, columns=columns)
    (out / "sweep.json").write_text(json.dumps(spec.model_dump(), indent=2))
    runs = expand(spec)
    if hasattr(experiment, "prepare_in"):  # a case file: runs that share their first stages share them
        experiment.prepare_in(out / "prepared")
    if share_settling:
        experiment = experiment.share_settling(out / "settled", share_settling)
    ids = [run_id(spec.experiment, p) for p in runs]
    done = set(table["run_id"])
    todo = [(i, p) for i, p in zip(ids, runs) if i not in done]
    todo = list({i: (i, p) for i, p in todo}.values())  # identical runs listed twice run once
    tic = time.perf_counter()
    bar = None
    if progress:
        bar = tqdm(total=len(set(ids)), initial=len(set(ids)) - len(todo), unit="run", desc=spec.experiment)
    failed = 0
    if todo:
        def go(m):
            nonlocal failed
            for k, outcome in completed(m, _Execute(experiment), [p for _, p in todo]):
                rid, params = todo[k]
                if isinstance(outcome, BaseException):  # the run never finished: its workers died
                    outcome = {"observables": {}, "status": "failed", "version": "", "wall_time_s": math.nan,
                               "error": f"{type(outcome).__name__}: {outcome}"}
                failed += outcome["status"] != "ok"
                row = {"run_id": rid, "experiment": spec.experiment, "status": outcome["status"], **params,
                       **outcome["observables"], "wall_time_s": outcome["wall_time_s"],
                       "version": outcome["version"], "error": outcome["error"],
                       "finished_at": time.strftime("%Y-%m-%dT%H:%M:%S")}
                _append(path, columns, row)
                if on_run is not None:
                    on_run()
                if bar is not None:
                    bar.update(1)
                    bar.set_postfix(failed=failed)

        if mapper is not None:
            go(mapper)
        else:
            with runner(workers=workers, scheduler=scheduler, threads=threads) as m:
                go(m)
    if bar is not None:
        bar.close()
    table = read_table(path, experiment)
    table = table[table["run_id"].isin(set(ids))].reset_index(drop=True)
    result = SweepResult(table, out, ran=len(todo), skipped=len(set(ids)) - len(todo), failed=failed,
                         wall_time=time.perf_counter() - tic)
    if summary and len(table):
        summarize(table, experiment, swept_parameters(spec), out, result)
    if echo is not None:
        echo(f"{spec.experiment}: {len(table)} runs in {path} ({result.ran} ran now in {result.wall_time:.1f} s, "
             f"{result.skipped} already there, {int((table['status'] == 'failed').sum())} failed)")
        report = failure_report(table, path)
        if report:
            echo(report)
        saved = pd.to_numeric(table.get("prepared.seconds_saved", pd.Series(dtype=float)), errors="coerce")
        if (saved > 0).any():
            total = pd.to_numeric(table["wall_time_s"], errors="coerce").sum()
            echo(f"{int((saved > 0).sum())} of {len(table)} runs started from a bed an earlier run prepared "
                 f"({out / 'prepared'}): {saved.sum():.0f} s saved, the runs took {total:.0f} s")
    return result


def summarize(table: pd.DataFrame, experiment: Experiment, swept: list[str], out: Path | None = None,
              result: SweepResult | None = None) -> pd.DataFrame:
    """Mean and 95 % interval over seeds of every numeric observable per point; with ``out``,
    ``summary.csv`` and ``summary.png``: each observable against the first swept parameter, one
    line per value of the others, or for a sample (no two points on a line) the experiment's main
    observable against each swept parameter."""
    ok = table[table["status"] == "ok"]
    numeric = [o for o in experiment.observables if o in ok and pd.api.types.is_numeric_dtype(ok[o])]
    rows = []
    keys = [k for k in swept if k in ok]
    for point, grp in (ok.groupby(keys, sort=True, dropna=False) if keys else [((), ok)]):
        point = point if isinstance(point, tuple) else (point,)
        row = dict(zip(keys, point))
        row["runs"] = len(grp)
        for o in numeric:
            mean, half = confidence_interval(grp[o])
            row[f"{o} mean"], row[f"{o} 95% CI"] = mean, half
            row[f"{o} finite"] = int(np.isfinite(grp[o].to_numpy(dtype=float)).sum())
        rows.append(row)
    summary = pd.DataFrame(rows)
    if out is None or not len(summary):
        return summary
    summary.to_csv(Path(out) / "summary.csv", index=False)
    if keys and numeric:
        plt = pyplot()
        x, others = keys[0], keys[1:]
        scattered = bool(others) and summary.groupby(others).size().max() == 1  # a sample: no two points share a line
        if scattered:
            # one panel per swept parameter, the experiment's main observable against it
            o = experiment.default_observable if experiment.default_observable in numeric else numeric[0]
            fig, axes = plt.subplots(1, len(keys), figsize=(5.5 * len(keys), 4.2), squeeze=False)
            for ax, k in zip(axes[0], keys):
                ax.errorbar(summary[k], summary[f"{o} mean"], yerr=summary[f"{o} 95% CI"].fillna(0.0), fmt="o", ms=4,
                            capsize=3)
                ax.set_xlabel(k)
                ax.set_ylabel(f"{o} ({experiment.observables[o].split(',')[0]})")
        else:
            fig, axes = plt.subplots(1, len(numeric), figsize=(5.5 * len(numeric), 4.2), squeeze=False)
            groups = summary.groupby(others, sort=True) if others else [((), summary)]
            for ax, o in zip(axes[0], numeric):
                ax.set_prop_cycle(color=plt.get_cmap("tab10").colors)  # distinct neighbours, unlike tab20's pairs
                for label, grp in groups:
                    label = label if isinstance(label, tuple) else (label,)
                    grp = grp.sort_values(x)
                    name = ", ".join(f"{k} = {v:.4g}" if isinstance(v, float) else f"{k} = {v}"
                                     for k, v in zip(others, label)) or None
                    ax.errorbar(grp[x], grp[f"{o} mean"], yerr=grp[f"{o} 95% CI"].fillna(0.0), marker="o", ms=4,
                                capsize=3, label=name)
                ax.set_xlabel(x)
                ax.set_ylabel(f"{o} ({experiment.observables[o].split(',')[0]})")
                if others and len(summary.groupby(others)) <= 12:
                    ax.legend(fontsize=7)
        fig.suptitle(f"{experiment.name}: mean over seeds, 95 % Student-t interval")
        fig.tight_layout()
        path = Path(out) / "summary.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        if result is not None:
            result.figures.append(path)
    return summary
