"""Command line: ``rollingdem run | validate | bench | sweep | calibrate | check | schema | experiments``."""

from __future__ import annotations

import re
import warnings
from pathlib import Path
from typing import Optional

import typer

from rollingdem.errors import ParameterError, SimulationError, check_output_path

app = typer.Typer(add_completion=False, no_args_is_help=False,
                  help="rollingdem: DEM simulation of spheres, built around rolling resistance.")

_option_type = typer.core.TyperOption.display_type_rich


def _flag_without_type(self, ctx):
    """A flag takes no value: its help line shows no ``<bool>``."""
    return "" if self.is_flag and self.metavar is None else _option_type(self, ctx)


typer.core.TyperOption.display_type_rich = _flag_without_type


def _one_line_warning(message, category, filename, lineno, line=None) -> str:
    """A run's warning (an inflow without room) on the command line: one line, ``warning: ...``."""
    return f"warning: {message}\n"


warnings.formatwarning = _one_line_warning


def _refuse(err) -> None:
    """A user's mistake: one message on stderr (``error: ...``), exit status 2, no traceback."""
    typer.echo(f"error: {err}", err=True)
    raise typer.Exit(2)


def _check_out(path, option: str = "--out", folder: bool = True) -> None:
    """Refuse, before anything runs, an output path the command could not write."""
    if path is not None:
        try:
            check_output_path(option, path, folder=folder)
        except ParameterError as err:
            _refuse(err)


def _check_in_file(path, option: str) -> None:
    """Refuse an input file that is a folder (a missing one is refused by the command itself)."""
    if path is not None and Path(path).is_dir():
        _refuse(f"{option} = {str(path)!r} is not allowed: it is a folder; must be a file")


def _version(value: bool):
    if value:
        from rollingdem import __version__  # deferred: commands load what they run

        typer.echo(f"rollingdem {__version__}")
        raise typer.Exit()


@app.callback()
def _main(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="Print the version and exit.")):
    pass


@app.command()
def run(case: Optional[Path] = typer.Argument(None, help="Case file (YAML or TOML). Without it: the built-in "
                                                         "angle-of-repose case."),
        out: Optional[Path] = typer.Option(None, "--out", "-o", help="Output folder (default: "
                                           "rollingdem-output/<case name>, made fresh)."),
        threads: Optional[int] = typer.Option(None, "--threads", "-t", help="Numba threads, fixed (default: all cores, "
                                              "fewer while other processes keep cores busy)."),
        progress: bool = typer.Option(True, "--progress/--no-progress", help="Show a progress bar."),
        backend: Optional[str] = typer.Option(None, "--backend", help="cpu or cuda (an NVIDIA GPU, docs/gpu.md); "
                                              "default: the case file's backend key, else cpu."),
        overwrite: bool = typer.Option(False, "--overwrite", help="Replace an earlier run in the --out folder "
                                       "(refused without)."),
        resume: Optional[Path] = typer.Option(None, "--resume", help="Continue the killed run in this folder from "
                                              "its last checkpoint.")):
    """Run a case file, or the built-in default case; or continue a killed run (--resume DIR)."""
    from rollingdem.io import casefile, runner  # deferred: commands load what they run

    _set_threads(threads)
    _check_out(out)
    try:
        if resume is not None:
            if case is not None or out is not None or overwrite or backend is not None:
                given = [n for n, v in (("CASE", case), ("--out", out), ("--overwrite", overwrite),
                                        ("--backend", backend)) if v]
                raise ParameterError(f"--resume = {str(resume)!r} is not allowed with {', '.join(given)}: a resumed "
                                     "run continues its own case in its own folder")
            runner.resume_case(resume, progress=progress, echo=typer.echo)
            return
        spec = casefile.load_case(case if case is not None else casefile.default_case_path())
        if backend is not None:
            from rollingdem.engine.backends import check_backend  # deferred: commands load what they run

            spec.backend = check_backend(backend, "--backend")
        runner.run_case(spec, out=out, progress=progress, echo=typer.echo, overwrite=overwrite)
    except ParameterError as err:
        _refuse(err)
    except SimulationError as err:
        typer.echo(f"error: the run failed: {err}\n(outputs written so far are kept)", err=True)
        raise typer.Exit(1)


def _set_backend(backend):
    """``--backend`` for every simulation of this command, its workers' included (they inherit the
    environment): refused at once if unknown or if it has no device."""
    if backend is None:
        return
    import os  # deferred: commands load what they run

    from rollingdem.engine.backends import check_backend  # deferred: commands load what they run

    try:
        os.environ["ROLLINGDEM_BACKEND"] = check_backend(backend, "--backend")
    except ParameterError as err:
        _refuse(err)


def _set_threads(threads):
    if threads is None:
        return
    import numba  # deferred: commands load what they run

    if not 1 <= threads <= numba.config.NUMBA_NUM_THREADS:
        _refuse(f"--threads = {threads} is not allowed: must be in [1, {numba.config.NUMBA_NUM_THREADS}]")
    from rollingdem.engine.threads import fix_threads  # deferred: commands load what they run

    fix_threads(threads)  # what the user asked for, whatever the machine's load


@app.command()
def validate(out: Path = typer.Option(Path("rollingdem-validation"), "--out", "-o", help="Output folder."),
             experiment: Optional[list[str]] = typer.Option(None, "--experiment", "-e", "--case", "-c", help="Run "
                                                            "only this experiment (repeatable); `rollingdem "
                                                            "experiments list` names them."),
             model: Optional[list[str]] = typer.Option(None, "--model", "-m", help="Only this model (repeatable), "
                                                       "e.g. epsd, 'cdt (liggghts)': each experiment runs those of its "
                                                       "models named; repose-sweep sweeps one. An experiment that runs "
                                                       "none of them is left out (refused if named with --experiment)."),
             quick: bool = typer.Option(False, "--quick", help="Reduced sizes (about 25 minutes on 2 cores, "
                                                                 "10 of them the three experiments)."),
             workers: Optional[int] = typer.Option(None, "--workers", "-w", help="Simulations side by side, one "
                                                   "thread each (default: one per core; 1: one after the other here)."),
             scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Dask scheduler address "
                                                     "(tcp://host:port) to run on an existing cluster."),
             progress: bool = typer.Option(True, "--progress/--no-progress", help="Show a progress bar."),
             backend: Optional[str] = typer.Option(None, "--backend", help="cpu or cuda (an NVIDIA GPU, "
                                                   "docs/gpu.md): where every experiment's simulations step.")):
    """Run the experiments (the seed report's test cases, the calibration experiments, the contact-law
    checks) and the repose-angle study; write report.md/.html and results.json.

    Exit status 1 when any check fails its tolerance."""
    from rollingdem.validate import run_validation  # deferred: commands load what they run

    _check_out(out)
    _set_backend(backend)
    try:
        results = run_validation(out, experiments=experiment, quick=quick, progress=progress, models=model, workers=workers,
                                 scheduler=scheduler, echo=typer.echo)
    except ParameterError as err:
        _refuse(err)
    for r in results:
        failed = [c for c in r.checks if not c.passed]
        typer.echo(f"{r.name:16s} {'pass' if r.passed else 'FAIL'}  {len(r.checks) - len(failed)}/{len(r.checks)} "
                   f"checks, {r.wall_time:.0f} s")
        for c in failed:
            typer.echo(f"    {c.model}: {c.quantity} = {c.measured:.6g}, reference {c.reference:.6g} "
                       f"(tolerance {c.tolerance:g}) {c.source}")
    typer.echo(f"report: {Path(out) / 'report.md'}")
    if not all(r.passed for r in results):
        raise typer.Exit(1)


@app.command()
def bench(scene: Optional[list[str]] = typer.Option(None, "--scene", "-s", help="column-collapse (default), "
                                                    "single-particle, dense-bed, slab, scaling (the slab at 20,000 and N "
                                                    "spheres in turn), collapse-scaling (the column-collapse likewise; "
                                                    "settling the column of 10^6 spheres once takes 2-3 h on 2 cores), "
                                                    "mesh-hopper (spheres discharging from a 10,000-triangle STL "
                                                    "hopper), rough-bed (free spheres at rest on half as many fixed "
                                                    "ones and on the bare plate, in turn), clumps (tetrahedral "
                                                    "clumps and as many spheres as their members, at rest in a box, "
                                                    "in turn), coarse-graining (the coarse-graining study's turning "
                                                    "drum of real particles and of parcels of alpha 3, in turn) "
                                                    "(repeatable)."),
          particles: Optional[int] = typer.Option(None, "--particles", "-n", help="Spheres in column-collapse, "
                                                  "dense-bed, slab, mesh-hopper and rough-bed, clump members in "
                                                  "clumps (default 20,000), and the large scene of "
                                                  "scaling and collapse-scaling (default 1,000,000; the small one has "
                                                  "20,000)."),
          steps: Optional[int] = typer.Option(None, "--steps", help="Timed steps (default: 10,000 column-collapse, "
                                              "150,000 single-particle, 2,000 dense-bed, rough-bed and clumps, 1,000 slab, "
                                              "300 scaling and collapse-scaling, 5,000 mesh-hopper, 12,000 of the real "
                                              "particles in coarse-graining)."),
          threads: Optional[int] = typer.Option(None, "--threads", "-t", help="Numba threads, fixed (default: all cores, "
                                              "fewer while other processes keep cores busy)."),
          model: Optional[list[str]] = typer.Option(None, "--model", "-m", help="Rolling models and contact laws "
                                                    "(walton_braun, walton, sjkr, jkr) of dense-bed (repeatable; "
                                                    "default: none and every one)."),
          from_dump: Optional[Path] = typer.Option(None, "--from-dump", help="Start column-collapse from the settled "
                                                   "state the LIGGGHTS reference input writes (write_dump custom)."),
          json_out: Optional[Path] = typer.Option(None, "--json", help="Write the results to this JSON file."),
          backend: str = typer.Option("cpu", "--backend", help="cpu, or cuda (an NVIDIA GPU, docs/gpu.md: "
                                      "column-collapse and slab).")):
    """Time standard scenes: particle-steps per second, where the time goes, memory, compile time."""
    from rollingdem import bench as bench_mod  # deferred: commands load what they run

    _set_threads(threads)
    _check_in_file(from_dump, "--from-dump")
    _check_out(json_out, "--json", folder=False)
    try:
        results = bench_mod.run_bench(scenes=scene or ["column-collapse"], particles=particles, steps=steps,
                                      threads=threads, from_dump=from_dump, models=model, echo=typer.echo,
                                      backend=backend)
    except ParameterError as err:
        _refuse(err)
    if json_out is not None:
        try:
            typer.echo(f"json: {bench_mod.write_json(results, json_out)}")
        except OSError as err:  # checked above; the file system may still say no
            _refuse(f"--json = {str(json_out)!r} cannot be written: {err.strerror or err} (the results are above)")


@app.command()
def sweep(sweep_file: Path = typer.Argument(..., help="Sweep file (YAML or TOML): experiment, fixed, grid | points | "
                                                      "sample, seeds."),
          out: Path = typer.Option(Path("rollingdem-sweep"), "--out", "-o", help="Output folder: runs.csv (one row "
                                   "per run, appended as runs finish; rerunning skips the rows there), summary.csv/png."),
          workers: Optional[int] = typer.Option(None, "--workers", "-w", help="Worker processes (default: cores // "
                                                "threads; 1: one after the other in this process)."),
          threads: int = typer.Option(1, "--threads", "-t", help="Numba threads per run."),
          scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Dask scheduler address "
                                                  "(tcp://host:port) of an existing cluster."),
          retry_failed: bool = typer.Option(False, "--retry-failed", help="Run again the runs recorded as failed."),
          progress: bool = typer.Option(True, "--progress/--no-progress", help="Show a progress bar.")):
    """Run an experiment over a grid, list or Latin-hypercube sample of parameters and seeds, on Dask.

    Exit status 1 when any run failed (its error is in runs.csv; the others still ran)."""
    from rollingdem.studies.sweep import run_sweep  # deferred: commands load what they run

    _check_in_file(sweep_file, "sweep file")
    _check_out(out)
    try:
        result = run_sweep(sweep_file, out, workers=workers, scheduler=scheduler, threads=threads, progress=progress,
                           retry_failed=retry_failed, echo=typer.echo)
    except ParameterError as err:
        _refuse(err)
    for f in result.figures:
        typer.echo(f"figure: {f}")
    failed = result.table[result.table["status"] == "failed"]
    for _, row in failed.head(5).iterrows():
        typer.echo(f"    failed {row['run_id']}: {str(row['error']).splitlines()[0]}", err=True)
    if len(failed):
        raise typer.Exit(1)


@app.command()
def calibrate(cases: Optional[list[Path]] = typer.Argument(None, help="Case files to calibrate against (instead "
                                                            "of built-in experiments): their measurements are the "
                                                            "observables, the numbers in them the parameters."),
              target: list[str] = typer.Option(..., "--target", help="What was measured (repeatable): "
                                               "EXPERIMENT.OBSERVABLE=VALUE±U (e.g. angle-of-repose.angle=32.5±1.0); "
                                               "with one case file MEASUREMENT.QUANTITY=VALUE±U, with several "
                                               "FILE:MEASUREMENT.QUANTITY=VALUE±U; or with --experiment a number (and "
                                               "--uncertainty)."),
              free: Optional[list[str]] = typer.Option(None, "--free", help="A parameter to find (repeatable): NAME or "
                                                       "NAME=LOW:HIGH (default: mur)."),
              fix: Optional[list[str]] = typer.Option(None, "--fix", help="NAME=VALUE held fixed (repeatable), e.g. "
                                                      "mu=0.5, model=epsd; in every experiment that has it."),
              experiment: Optional[str] = typer.Option(None, "--experiment", "-e", "--case", "-c", help="With a "
                                                       "numeric --target: its experiment (rolling-flat, inclined-wall, "
                                                       "angle-of-repose, repose-rough-base, rotating-drum, "
                                                       "silo-discharge)."),
              uncertainty: float = typer.Option(0.0, "--uncertainty", "-u", help="With a numeric --target: its "
                                                "standard uncertainty (one sigma)."),
              observable: Optional[str] = typer.Option(None, "--observable", help="With a numeric --target: the "
                                                       "observable (default: the experiment's: angle, distance, ...)."),
              seeds: Optional[int] = typer.Option(None, "--seeds", help="Runs per point (default 3 for a random "
                                                  "experiment, 1 for a deterministic one)."),
              coarse: int = typer.Option(5, "--coarse", help="One free parameter: points of the first sweep."),
              refine: int = typer.Option(4, "--refine", help="One free parameter: points added per round."),
              initial: Optional[int] = typer.Option(None, "--initial", help="Several free parameters or targets: "
                                                    "Latin-hypercube points first (default 4 per free parameter + 2)."),
              per_round: int = typer.Option(4, "--per-round", help="Several free parameters or targets: points "
                                            "added per round."),
              rounds: Optional[int] = typer.Option(None, "--rounds", help="Refinement rounds (default 2 for one free "
                                                   "parameter and target, else 3)."),
              fidelity: str = typer.Option("single", "--fidelity", help="One target and one free parameter: single "
                                           "(every run full size) or multi (cheap runs explore the range, a few "
                                           "full-size runs correct them: docs/studies.md)."),
              cheap: Optional[list[str]] = typer.Option(None, "--cheap", help="With --fidelity multi: NAME=VALUE that "
                                                        "makes a run cheap (repeatable; default: count at 40 % of "
                                                        "the full run's), e.g. count=400 or coarse_graining=2."),
              share_settling: bool = typer.Option(False, "--share-settling", help="Settle each seed's bed once, "
                                                  "with the free parameters at the middle of their ranges, and "
                                                  "start every run from it (repose-rough-base, rotating-drum; "
                                                  "other experiments settle their own)."),
              out: Path = typer.Option(Path("rollingdem-calibration"), "--out", "-o", help="Output folder."),
              workers: Optional[int] = typer.Option(None, "--workers", "-w", help="Worker processes."),
              scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Dask scheduler address."),
              progress: bool = typer.Option(True, "--progress/--no-progress", help="Show a progress bar.")):
    """Find the free parameters whose simulated observables match the measured targets, with their
    95 % region. One numeric target and one free parameter: a monotone search (with --fidelity
    multi, on cheap runs corrected by full-size ones); otherwise a Gaussian-process surrogate with
    sequential design (docs/studies.md, "Calibration")."""
    from rollingdem.studies.calibration import (  # deferred: commands load what they run
        Execution,
        Search,
        parse_assignments,
        parse_free,
    )
    from rollingdem.studies.calibration import calibrate as run_calibration  # deferred: commands load what they run
    from rollingdem.studies.joint_calibration import (  # deferred: commands load what they run
        JointSearch,
        Target,
        calibrate_joint,
        parse_target,
    )

    _check_out(out)
    try:
        frees = [parse_free(f) for f in (free or ["mur"])]
        execution = Execution(workers=workers, scheduler=scheduler)
        fixed = parse_assignments(fix, "fix")
        if cases and any(t.replace(" ", "").endswith("=min") for t in target):
            _minimum(cases, target, frees, fixed, seeds, coarse, refine, rounds, out, execution, progress)
            return
        if fidelity not in ("single", "multi"):
            raise ParameterError(f"--fidelity = {fidelity!r} is not allowed: single or multi")
        if cheap and fidelity == "single":
            raise ParameterError(f"--cheap = {cheap[0]!r} is not allowed with --fidelity single: the cheap runs are "
                                 "those of --fidelity multi")
        if cases:
            targets = _case_targets(cases, target, experiment, observable, uncertainty)
            if len(targets) == 1 and len(frees) == 1:
                t = targets[0]
                result = run_calibration(t.experiment, t.value, t.uncertainty, fix=fixed, free=frees[0],
                                         observable=t.observable, seeds=seeds,
                                         search=Search(coarse=coarse, refine=refine, rounds=2 if rounds is None else rounds,
                                                       fidelity=_fidelity(fidelity, cheap, t.experiment, fixed),
                                                       share_settling=share_settling),
                                         out=out, execution=execution, progress=progress, echo=typer.echo)
                typer.echo(f"figure: {result.figures[0]}")
                typer.echo(f"result: {Path(out) / 'calibration.json'}")
                return
            result = calibrate_joint(targets, {name: rng for name, rng in frees}, fix=fixed, seeds=seeds,
                                     search=JointSearch(initial=initial, rounds=3 if rounds is None else rounds,
                                                        per_round=per_round, share_settling=share_settling),
                                     out=out, execution=execution, progress=progress, echo=typer.echo,
                                     fidelity=_joint_fidelity(fidelity, cheap, targets, fixed))
            for f in result.figures:
                typer.echo(f"figure: {f}")
            typer.echo(f"result: {Path(out) / 'calibration.json'}")
            return
        numeric = [t for t in target if "=" not in t]
        if numeric and len(numeric) < len(target):
            raise ParameterError(f"target = {numeric[0]!r} is not allowed beside EXPERIMENT.OBSERVABLE=VALUE targets: give "
                                 "every target as EXPERIMENT.OBSERVABLE=VALUE±U")
        if numeric:
            if experiment is None:
                raise ParameterError(f"target = {numeric[0]!r} is not allowed without --experiment: give --experiment, or write "
                                     "the target as EXPERIMENT.OBSERVABLE=VALUE±U")
            if len(numeric) > 1:
                raise ParameterError("target: several numbers are not allowed with --experiment: give each as "
                                     "EXPERIMENT.OBSERVABLE=VALUE±U")
            try:
                value = float(numeric[0])
            except ValueError:
                raise ParameterError(f"target = {numeric[0]!r} is not allowed: must be a number, or "
                                     "EXPERIMENT.OBSERVABLE=VALUE±U") from None
            if len(frees) == 1:
                result = run_calibration(experiment, value, uncertainty, fix=fixed, free=frees[0], observable=observable,
                                         seeds=seeds, search=Search(coarse=coarse, refine=refine,
                                                                    rounds=2 if rounds is None else rounds,
                                                                    fidelity=_fidelity(fidelity, cheap, experiment, fixed),
                                                                    share_settling=share_settling),
                                         out=out, execution=execution, progress=progress, echo=typer.echo)
                typer.echo(f"figure: {result.figures[0]}")
                typer.echo(f"result: {Path(out) / 'calibration.json'}")
                return
            from rollingdem.experiments import get_experiment  # deferred: commands load what they run

            default = get_experiment(experiment, observable=True, what="experiment").default_observable
            targets = [Target(experiment, observable or default, value, uncertainty)]
        else:
            for what, given in (("--experiment", experiment), ("--observable", observable)):
                if given is not None:
                    raise ParameterError(f"{what} = {given!r} is not allowed with EXPERIMENT.OBSERVABLE=VALUE targets: "
                                         "each target names its experiment and observable")
            if uncertainty:
                raise ParameterError(f"--uncertainty = {uncertainty:g} is not allowed with EXPERIMENT.OBSERVABLE=VALUE "
                                     "targets: write each target's as VALUE±U")
            targets = [parse_target(t) for t in target]
        result = calibrate_joint(targets, {name: rng for name, rng in frees}, fix=fixed, seeds=seeds,
                                 search=JointSearch(initial=initial, rounds=3 if rounds is None else rounds,
                                                    per_round=per_round, share_settling=share_settling),
                                 out=out, execution=execution, progress=progress, echo=typer.echo,
                                 fidelity=_joint_fidelity(fidelity, cheap, targets, fixed))
    except ParameterError as err:
        _refuse(err)
    for f in result.figures:
        typer.echo(f"figure: {f}")
    typer.echo(f"result: {Path(out) / 'calibration.json'}")


def _fidelity(fidelity: str, cheap, experiment: str, fixed: dict):
    """The ``Fidelity`` of ``--fidelity multi`` (None for single): the ``--cheap`` parameters, or the
    experiment's smaller scene."""
    if fidelity == "single":
        return None
    from rollingdem.experiments import get_experiment  # deferred: commands load what they run
    from rollingdem.studies.calibration import parse_assignments  # deferred: commands load what they run
    from rollingdem.studies.multifidelity import Fidelity, cheap_default  # deferred: commands load what they run

    given = parse_assignments(cheap, "cheap")
    return Fidelity(cheap=given or cheap_default(get_experiment(experiment, observable=True), fixed))


def _joint_fidelity(fidelity: str, cheap, targets, fixed: dict):
    """The ``JointFidelity`` of ``--fidelity multi`` with several targets or free parameters (None for
    single): each ``--cheap NAME=VALUE`` in every experiment that has it; without ``--cheap`` each
    experiment's own cheap runs where it has them (the others run at full size throughout)."""
    if fidelity == "single":
        return None
    from rollingdem.experiments import get_experiment  # deferred: commands load what they run
    from rollingdem.studies.calibration import parse_assignments  # deferred: commands load what they run
    from rollingdem.studies.multifidelity import JointFidelity, cheap_default  # deferred: commands load what they run

    given = parse_assignments(cheap, "cheap")
    experiments = {t.experiment: get_experiment(t.experiment, observable=True) for t in targets}
    per = {}
    for c, sc in experiments.items():
        if given:
            mine = {k: v for k, v in given.items() if k in sc.by_name}
        else:
            try:
                mine = cheap_default(sc, {k: v for k, v in fixed.items() if k in sc.by_name})
            except ParameterError:
                mine = {}
        if mine:
            per[c] = mine
    unused = [k for k in given if not any(k in sc.by_name for sc in experiments.values())]
    if unused:
        raise ParameterError(f"--cheap = {unused[0]!r} is not a parameter of any experiment calibrated "
                             f"({', '.join(experiments)})")
    if not per:
        raise ParameterError("--fidelity multi is not allowed here: no experiment of the targets has cheap runs; give "
                             "--cheap NAME=VALUE")
    return JointFidelity(cheap=per)


def _minimum(cases, targets, frees, fixed, seeds, coarse, refine, rounds, out, execution, progress):
    """``--target MEASUREMENT.QUANTITY=min``: the free parameter where a misfit is lowest."""
    from rollingdem.studies.calibration import Search, calibrate_minimum  # deferred: commands load what they run

    if len(targets) > 1 or len(frees) > 1 or len(cases) > 1:
        raise ParameterError(f"target = {targets[0]!r} is not allowed with other targets, free parameters or case "
                             "files: a minimum is searched over one free parameter of one case file")
    name, rng = frees[0]
    if rng is None:
        raise ParameterError(f"free = {name!r} is not allowed without its range: give --free {name}=LOW:HIGH")
    left = targets[0].replace(" ", "").removesuffix("=min")
    file, obs = (left.rsplit(":", 1) if ":" in left else (str(cases[0]), left))
    result = calibrate_minimum(file, obs, (name, rng), fix=fixed, seeds=seeds,
                               search=Search(coarse=coarse, refine=refine, rounds=2 if rounds is None else rounds),
                               out=out, execution=execution, progress=progress, echo=typer.echo)
    typer.echo(f"figure: {result.figures[0]}")
    typer.echo(f"result: {Path(out) / 'calibration.json'}")


def _case_targets(cases, targets, experiment, observable, uncertainty):
    """The targets of a calibration against case files: MEASUREMENT.QUANTITY=VALUE±U (one file),
    FILE:MEASUREMENT.QUANTITY=VALUE±U (several), or a number with --observable (one file)."""
    from rollingdem.experiments import get_experiment  # deferred: commands load what they run
    from rollingdem.studies.joint_calibration import Target, parse_value  # deferred: commands load what they run

    if experiment is not None:
        raise ParameterError(f"--experiment = {experiment!r} is not allowed with case files: the case files are the "
                             "experiments")
    for c in cases:
        _check_in_file(c, "case file")
        get_experiment(str(c), observable=True)  # refuse a bad file now
    out = []
    for text in targets:
        if "=" not in text:
            if len(cases) > 1 or len(targets) > 1 or observable is None:
                raise ParameterError(f"target = {text!r} is not allowed: write MEASUREMENT.QUANTITY=VALUE±U"
                                     + (" (FILE:MEASUREMENT.QUANTITY=... with several case files)" if len(cases) > 1
                                        else ", or give --observable MEASUREMENT.QUANTITY"))
            file, obs, value, unc = str(cases[0]), observable, parse_value(text, text)[0], uncertainty
        else:
            left, right = text.split("=", 1)
            if ":" in left:
                file, obs = left.rsplit(":", 1)
            elif len(cases) == 1:
                file, obs = str(cases[0]), left
            else:
                raise ParameterError(f"target = {text!r} is not allowed with several case files: write "
                                     "FILE:MEASUREMENT.QUANTITY=VALUE±U")
            value, unc = parse_value(right, text)
        if file not in map(str, cases):
            raise ParameterError(f"target = {text!r} is not allowed: {file!r} is not one of the case files given "
                                 f"({', '.join(map(str, cases))})")
        exp = get_experiment(file, observable=True)
        if obs.strip() not in exp.observables:
            raise ParameterError(f"target = {text!r} is not allowed: {Path(file).name} measures "
                                 f"{', '.join(exp.observables) or 'nothing (add measurements: to it)'}")
        out.append(Target(file, obs.strip(), value, unc))
    return out


@app.command()
def schema():
    """Print the case file's JSON Schema (for an editor's completion and checks)."""
    import json  # deferred: commands load what they run

    from rollingdem.io.case_schema import CaseSpec, material_specs  # deferred: commands load what they run

    material_specs()
    typer.echo(json.dumps(CaseSpec.model_json_schema(), indent=1))


@app.command()
def check(case: Path = typer.Argument(..., help="Case file to validate.")):
    """Validate a case file without running it."""
    from rollingdem.io import case_check, casefile  # deferred: commands load what they run
    from rollingdem.io.runner import check_output_folder  # deferred: commands load what they run

    try:
        spec = casefile.load_case(case)
        sim = case_check.check_case(spec)  # what run refuses before its first step, refused here
        check_output_folder(spec)  # where a run without --out writes
        length, warned = casefile.run_length(spec, sim)
    except ParameterError as err:
        _refuse(err)
    clumps, fixed = len(sim.clumps["mass"]), int(sim.fixed.sum())
    split = f" ({sim.n_particles - fixed} free, {fixed} fixed)" if fixed else ""
    typer.echo(f"{case}: valid; {sim.n_particles} particles{split}{f' ({clumps} clumps)' if clumps else ''}"
               f"{sim.particle_set.coarse_graining_note()}, "
               f"{len(sim.walls)} walls, {len(spec.stages)} stages, "
               f"dt = {sim.dt:.3g} s")
    for line in casefile.mesh_lines(sim) + length:
        typer.echo(f"  {line}")
    for line in warned:
        typer.echo(f"warning: {line}")


experiments_app = typer.Typer(help="The experiments: case files shipped with rollingdem to start from, and the "
                                   "built-in experiments of validate, sweep and calibrate.")
app.add_typer(experiments_app, name="experiments")


@experiments_app.command("list")
def experiments_list():
    """List the shipped case files and the built-in experiments."""
    from rollingdem.experiments import EXPERIMENTS  # deferred: commands load what they run
    from rollingdem.experiments.case_file import is_case_file, shipped_cases  # deferred: commands load what they run

    typer.echo("case files (rollingdem experiments show NAME > my.yaml, then rollingdem run my.yaml):")
    for name, path in shipped_cases().items():
        lines = path.read_text().splitlines()
        head = [line.lstrip("#").strip() for line in lines[:next((k for k, x in enumerate(lines) if not x.startswith("#")),
                                                                  len(lines))]]
        typer.echo(f"  {name:<18} {_first_sentence(' '.join(head))}")
    typer.echo("built-in experiments (rollingdem validate / sweep / calibrate --experiment NAME):")
    for name, e in EXPERIMENTS.items():
        if not is_case_file(name):
            typer.echo(f"  {name:<18} {_first_sentence(e.description or '')}")


def _first_sentence(text: str) -> str:
    """The first sentence of ``text``, its lines joined: up to the first full stop followed by a space
    (not one inside a number or an abbreviation such as "e.g."), or all of it."""
    words = " ".join(text.split())
    end = re.search(r"(?<!e\.g)(?<!i\.e)(?<!\bcf)(?<!\bet al)\.(\s|$)", words)
    return words[:end.start() + 1] if end else words


@experiments_app.command("show")
def experiments_show(name: str = typer.Argument(..., help="A shipped case file's or a built-in experiment's name "
                                                          "(rollingdem experiments list).")):
    """Print a shipped case file, to save and edit (rollingdem experiments show drum > my_drum.yaml); or a
    built-in experiment's parameters (name, default, allowed range, unit) and observables."""
    from rollingdem.experiments import EXPERIMENTS  # deferred: commands load what they run
    from rollingdem.experiments.case_file import is_case_file, shipped_cases  # deferred: commands load what they run

    cases = shipped_cases()
    if name in cases:
        typer.echo(cases[name].read_text(), nl=False)
        return
    built_in = [n for n in EXPERIMENTS if not is_case_file(n)]
    if name not in built_in:
        _refuse(f"experiment = {name!r} is not known: the case files shipped are {', '.join(cases)}; the built-in "
                f"experiments are {', '.join(built_in)}")
    e = EXPERIMENTS[name]
    typer.echo(f"{name}: {' '.join((e.description or '').split())}")
    typer.echo("parameters (rollingdem sweep / calibrate --experiment NAME, as name=value):" if e.parameters
               else "parameters: none (validated only)")
    for p in e.parameters:
        if p.choice:
            allowed = f"a {p.choice} model name"
        else:
            lo = "-inf" if p.low is None else f"{p.low:g}"
            hi = "inf" if p.high is None else f"{p.high:g}"
            allowed = f"{'(' if p.low_open or p.low is None else '['}{lo}, {hi}{']' if p.high is not None else ')'}"
            allowed += f" {p.unit}" if p.unit else ""
        typer.echo(f"  {p.name:<24} default {p.default!r:<10} {allowed:<22} {p.description}")
    typer.echo("observables:")
    for key, meaning in e.observables.items():
        typer.echo(f"  {key:<24} {meaning}")


@app.command()
def shapes():
    """List the ready-made mesh shapes (a mesh wall's or a region's shape: and size:) with their dimensions
    and defaults, in m."""
    import inspect  # deferred: commands load what they run

    from rollingdem.scene.mesh import SHAPES  # deferred: commands load what they run

    for name, make in SHAPES.items():
        dims = [f"{k}" if p.default is inspect.Parameter.empty else f"{k}={p.default!r}"
                for k, p in inspect.signature(make).parameters.items()]
        doc = " ".join((make.__doc__ or "").replace("``", "").split(". ")[0].split())
        typer.echo(f"{name}: {', '.join(dims)}")
        if doc:
            typer.echo(f"  {doc.rstrip('.')}.")


def _reflow_help(typer_app) -> None:
    """Each command's help from its docstring with the lines of a paragraph joined: the terminal
    wraps them, and no line breaks mid-sentence where the source did."""
    import inspect  # deferred: commands load what they run

    for info in typer_app.registered_commands:
        if info.help is None and info.callback is not None and info.callback.__doc__:
            paragraphs = inspect.cleandoc(info.callback.__doc__).split("\n\n")
            info.help = "\n\n".join(" ".join(p.split()) for p in paragraphs)
    for group in typer_app.registered_groups:
        _reflow_help(group.typer_instance)


_reflow_help(app)


def main():
    app()


if __name__ == "__main__":
    main()
