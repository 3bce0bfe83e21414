"""``rollingdem validate``: run the experiments, compare with theory, write a report.

Writes into ``outdir``: ``report.md`` and ``report.html`` (tables, checks, figures), the PNG
figures, ``results.json`` (every check: case, model, quantity, measured, reference, tolerance,
pass) and one CSV table per experiment. An experiment that crashes is recorded as failed with its error, and
the others still run: nothing already measured is lost. Each experiment's outcome is also kept in
``cases/NAME.json``, so experiments run one at a time into the same folder (``--experiment``, maybe across
days) make one report: an experiment run again replaces its earlier result, the others stay.
"""

from __future__ import annotations

import dataclasses
import json
import time
import traceback
from pathlib import Path

import pandas as pd
from tqdm import tqdm

from rollingdem.errors import ParameterError
from rollingdem.experiments import EXPERIMENTS
from rollingdem.experiments.registry import rolling_models
from rollingdem.experiments.results import Check, ValidationResult
from rollingdem.studies.parallel import check_workers, runner
from rollingdem.studies.repose_study import repose_sweep


def available_experiments() -> dict:
    """What ``rollingdem validate`` runs, by name: every experiment of the registry
    (``rollingdem.experiments.EXPERIMENTS``, its ``validate``) and the PFC repose-angle study
    (``repose-sweep``); each a function(quick=False, outdir=None, progress=None, runner=map,
    [models= or model=]) -> ValidationResult."""
    found = {}
    for name, experiment in EXPERIMENTS.items():
        found[name] = experiment.validate
        if name == "angle-of-repose":  # before repose-rough-base, whose figure shows the sweep's angles
            found["repose-sweep"] = repose_sweep
    return found


def experiment_models() -> dict[str, tuple[str, list[str]]]:
    """Name -> (its keyword, the model names it takes) for what takes ``--model``: each
    experiment's ``model_keyword`` and ``models()`` ("models": a list, "model": one), and
    repose-sweep, which sweeps one rolling model."""
    table = {name: (e.model_keyword, e.models()) for name, e in EXPERIMENTS.items() if e.model_keyword}
    table["repose-sweep"] = ("model", rolling_models())
    return table


def _model_arguments(names, models, explicit, echo) -> tuple[list[str], dict[str, dict]]:
    """(the experiments to run, experiment -> its model keyword argument) for ``--model`` = ``models``.

    A model no chosen experiment knows is refused; an experiment that runs none of the models asked for (or,
    for repose-sweep, which sweeps one model, more than one) is refused when the user named it
    (``explicit``) and otherwise left out with a note through ``echo``."""
    if models is None:
        return names, {}
    if isinstance(models, str) or not all(isinstance(m, str) for m in models) or not models:
        raise ParameterError(f"models = {models!r} is not allowed: must be a list of model names")
    table = experiment_models()
    takes = {name: table[name] for name in names if name in table}
    known = [m for _, ms in takes.values() for m in ms]
    unknown = [m for m in models if m not in known]
    if unknown:
        allowed = "; ".join(f"{name}: {', '.join(map(repr, ms))}" for name, (_, ms) in takes.items()) or "none"
        raise ParameterError(f"model = {unknown[0]!r} is not known to the experiments chosen: allowed are {allowed}")
    run, kwargs = [], {}
    for name in names:
        keyword, allowed = takes.get(name, (None, []))
        chosen = [m for m in models if m in allowed]
        if keyword == "model" and len(chosen) > 1:
            why = f"it sweeps one rolling model and --model names {len(chosen)} ({', '.join(map(repr, chosen))})"
        elif not chosen:
            why = (f"it runs none of them (its models: {', '.join(map(repr, allowed))})" if allowed
                   else "it takes no model")
        else:
            run.append(name)
            kwargs[name] = {keyword: chosen[0] if keyword == "model" else chosen}
            continue
        if explicit:
            raise ParameterError(f"model = {', '.join(map(repr, models))} is not allowed with experiment {name}: {why}")
        if echo is not None:
            echo(f"{name}: left out, --model {' '.join(map(repr, models))} does not apply: {why}")
    if not run:
        raise ParameterError(f"model = {', '.join(map(repr, models))} is not allowed: no experiment chosen runs it")
    return run, kwargs


def run_validation(outdir, experiments=None, quick=False, progress=True, models=None, workers=None,
                   scheduler=None, echo=None) -> list[ValidationResult]:
    """Run the named experiments (all by default) and write the report; returns their results.

    The independent simulations of an experiment run side by side on ``workers`` processes (default: one
    per core; 1 runs them here, one after the other) or on the Dask cluster at ``scheduler``.
    ``models`` limits every experiment to those of its models (see ``_model_arguments``; one left
    out for it is announced through ``echo``). Bad arguments are refused before anything is written.
    """
    available = available_experiments()
    names = list(available) if not experiments else list(experiments)
    unknown = [c for c in names if c not in available]
    if unknown:
        raise ParameterError(f"experiment = {', '.join(unknown)} is not known: allowed are {', '.join(available)}")
    names, model_kwargs = _model_arguments(names, models, bool(experiments), echo)
    check_workers(workers, 1)
    out = Path(outdir)
    if out.exists() and not out.is_dir():
        raise ParameterError(f"out = {str(out)!r} is not allowed: it is a file; must be a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ParameterError(f"out = {str(out)!r} cannot be made: {err.strerror or err}") from None
    with runner(workers=workers, scheduler=scheduler) as mapper:
        return _run_cases(available, names, out, quick, progress, model_kwargs, mapper)


def _run_cases(available, names, out, quick, progress, model_kwargs, mapper) -> list[ValidationResult]:
    results = []
    bar = _bar(progress, len(names))
    for name in names:
        if bar is not None:
            bar.set_description(name)
        tic = time.perf_counter()
        try:
            kwargs = {"quick": quick, "outdir": out, "progress": _run_counter(bar), "runner": mapper,
                      **model_kwargs.get(name, {})}
            result = available[name](**kwargs)
        except Exception as err:  # a failed experiment is a result too: record it and go on
            result = ValidationResult(name, name, pd.DataFrame(), [Check(name, "-", "experiment ran", float("nan"), 0.0, 0.0,
                                                                   source=f"{type(err).__name__}: {err}")],
                                notes=["The experiment failed:\n\n```\n" + traceback.format_exc() + "```"])
            result.wall_time = time.perf_counter() - tic
        results.append(result)
        result.table.to_csv(out / f"{name}.csv", index=False)
        _save_case(out, result, quick)
        merged = _with_earlier_cases(out, results, list(available), quick)
        write_report(out, merged, quick and not any(r.title.endswith("(full)") for r in merged))  # after every experiment
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    return results


def _run_counter(bar):
    """A callback the experiment calls after each simulation: shows the runs done in the bar."""
    if bar is None:
        return None
    done = [0]

    def tick():
        done[0] += 1
        bar.set_postfix(runs=done[0])
    return tick


def _bar(progress, total):
    if not progress:
        return None
    return tqdm(total=total, unit="experiment")


def _save_case(out: Path, r: ValidationResult, quick: bool) -> None:
    folder = out / "cases"
    folder.mkdir(exist_ok=True)
    data = {"name": r.name, "title": r.title, "quick": quick, "wall_time": r.wall_time, "notes": r.notes,
            "figures": [Path(f).name for f in r.figures], "checks": [dataclasses.asdict(c) for c in r.checks]}
    tmp = folder / f"{r.name}.json.tmp"
    tmp.write_text(json.dumps(data, indent=1, default=_json_default))
    tmp.replace(folder / f"{r.name}.json")


def _load_case(out: Path, name: str, quick: bool) -> ValidationResult | None:
    """An experiment's result an earlier run saved into this folder (None if there is none or it is
    unreadable); its title says "(quick)" or "(full)" when its size differs from this run's."""
    try:
        data = json.loads((out / "cases" / f"{name}.json").read_text())
    except (OSError, ValueError):
        return None
    try:
        table = pd.read_csv(out / f"{name}.csv")
    except (OSError, pd.errors.EmptyDataError):  # an experiment that failed has no table
        table = pd.DataFrame()
    title = data["title"]
    if bool(data.get("quick")) != quick:
        title += " (quick)" if data.get("quick") else " (full)"
    return ValidationResult(data["name"], title, table, [Check(**c) for c in data["checks"]],
                      [out / f for f in data["figures"]], list(data["notes"]), float(data["wall_time"]))


def _with_earlier_cases(out: Path, results: list[ValidationResult], order: list[str], quick: bool) -> list[ValidationResult]:
    """This run's results and, for the experiments it did not run, those an earlier run saved here,
    in the order of ``order``."""
    done = {r.name: r for r in results}
    names = order + sorted(p.stem for p in (out / "cases").glob("*.json") if p.stem not in order)
    merged = (done.get(name) or _load_case(out, name, quick) for name in names)
    return [r for r in merged if r is not None]  # this run's experiments are saved under cases/: all in names


def write_report(out: Path, results: list[ValidationResult], quick: bool) -> None:
    """``results.json``, ``report.md`` and ``report.html`` for the results so far."""
    checks = [c.as_dict() for r in results for c in r.checks]
    summary = {"quick": quick, "passed": all(r.passed for r in results),
               "cases": {r.name: {"passed": r.passed, "wall_time_s": r.wall_time,
                                  "figures": [Path(f).name for f in r.figures]} for r in results},
               "checks": checks}
    (out / "results.json").write_text(json.dumps(summary, indent=2, default=_json_default))
    md = [f"# rollingdem validation{' (quick)' if quick else ''}", "",
          f"{sum(c['pass'] for c in checks)} of {len(checks)} checks pass.", ""]
    for r in results:
        md += [f"## {r.title}", "", f"Status: **{'pass' if r.passed else 'FAIL'}**, wall time {r.wall_time:.0f} s.", ""]
        md += [*r.notes, ""]
        if len(r.table):
            md += [r.table.to_markdown(index=False, floatfmt=".6g"), ""]
        for f in r.figures:
            md += [f"![{Path(f).stem}]({Path(f).name})", ""]
        if r.checks:
            md += ["| model | quantity | measured | reference | tolerance | source | pass |",
                   "|---|---|---|---|---|---|---|"]
            for c in r.checks:
                d = c.as_dict()
                md.append(f"| {c.model} | {c.quantity} | {c.measured:.6g} | {c.reference:.6g} | "
                          f"{c.tolerance:g} ({d['tolerance_kind']}) | {c.source} | {'yes' if c.passed else '**NO**'} |")
            md.append("")
    text = "\n".join(md)
    (out / "report.md").write_text(text)
    from markdown_it import MarkdownIt  # deferred: the report only

    body = MarkdownIt("commonmark").enable("table").render(text)
    style = ("body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;"
             "font-size:13px}td,th{border:1px solid #ccc;padding:2px 6px}img{max-width:100%}")
    (out / "report.html").write_text(f"<!doctype html><html><head><meta charset='utf-8'><title>rollingdem "
                                     f"validation</title><style>{style}</style></head><body>{body}</body></html>")


def _json_default(x):
    try:
        return float(x)
    except (TypeError, ValueError):
        return str(x)
