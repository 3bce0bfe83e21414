"""Running a case file: its stages, its outputs in one folder, checkpoints to resume it from.

``run_case`` runs every stage of a case (``rollingdem.io.casefile``) and writes into one folder:
``case.yaml``, ``series.csv``, ``measurements/NAME.csv``, snapshots, ``summary.json``,
``final.npz`` and ``checkpoints/``. A folder that holds an earlier run is refused unless asked to
overwrite it. While it runs, a checkpoint of the whole run (the simulation, the stage it is in,
what each output and measurement has seen) is written every ``output.checkpoint.interval``;
``resume_case`` continues a killed run from the last one and ends bit for bit where the run would
have ended (the outputs written after that checkpoint are cut off first).
"""

from __future__ import annotations

import json
import math
import pickle
import shutil
import time
from dataclasses import dataclass, field
from itertools import product
from pathlib import Path

import numpy as np
import yaml

from rollingdem.analysis.repose import plot_pile
from rollingdem.errors import ParameterError, check_output_path
from rollingdem.io.case_check import check_case
from rollingdem.io.case_schema import CaseSpec, ReposeOutputSpec, StageWindowSpec
from rollingdem.io.casefile import (
    CASE_HINTS,
    build_measurements,
    mesh_lines,
    motion_of,
    stage_conditions,
    stage_duration,
    stage_window,
    take_materials,
)
from rollingdem.io.observers import TimeSeries, VTKSnapshots
from rollingdem.io.report import ScenePictures, write_report
from rollingdem.io.rig_measurements import PileAngle
from rollingdem.scene.schedule import Observer
from rollingdem.scene.simulation import Simulation

#: What a run writes into its folder (files and folders): what ``--overwrite`` removes.
RUN_FILES = ("case.yaml", "summary.json", "final.npz", "series.csv", "kinetic_energy.png", "pile.png",
             "report.html", "snapshots", "checkpoints", "measurements")
#: Checkpoints a run writes when its case names no interval: this many over its longest duration.
CHECKPOINTS_PER_RUN = 20
RUN_STATE = "run_state.pkl"
RUN_CHECKPOINT = "checkpoint_last.npz"


def _fresh_directory(base: Path) -> Path:
    if not base.exists():
        return base
    stamp = time.strftime("%Y%m%d-%H%M%S")
    candidate = base.with_name(f"{base.name}-{stamp}")
    k = 1
    while candidate.exists():
        candidate = base.with_name(f"{base.name}-{stamp}-{k}")
        k += 1
    return candidate


def earlier_run(folder: Path) -> list[str]:
    """The files and folders of an earlier run in ``folder`` (``RUN_FILES``)."""
    return [name for name in RUN_FILES if (Path(folder) / name).exists()]


def check_output_folder(case: CaseSpec, out=None) -> Path:
    """The folder a run of ``case`` would write into (``out``, else the case's output.directory or
    rollingdem-output/NAME, with a time stamp when that exists), refused when it could not be
    written (``rollingdem check`` asks too)."""
    base = Path(out or case.output.directory or Path("rollingdem-output") / case.name)
    outdir = _fresh_directory(base) if out is None else base
    key = "output folder" if out is not None or not case.output.directory else "output.directory"
    check_output_path(key, outdir)
    return outdir


def _output_folder(case: CaseSpec, out, overwrite: bool = False) -> Path:
    """The folder a run writes into: ``out`` as given, else a fresh one (the case's directory or
    rollingdem-output/NAME, with a time stamp when that exists). Refused when it is a file, or
    when it holds an earlier run and ``overwrite`` is not given."""
    outdir = check_output_folder(case, out)
    found = earlier_run(outdir) if outdir.is_dir() else []
    if found and not overwrite:
        raise ParameterError(f"output folder = {str(outdir)!r} is not allowed: it holds an earlier run "
                             f"({', '.join(found[:4])}{', ...' if len(found) > 4 else ''}); pass --overwrite to "
                             "replace it, --resume to continue it, or choose another folder")
    return outdir


def _clear(outdir: Path) -> None:
    """Remove an earlier run's files (``RUN_FILES``) from ``outdir``, nothing else."""
    for name in earlier_run(outdir):
        path = outdir / name
        shutil.rmtree(path) if path.is_dir() else path.unlink()


@dataclass
class RunState:
    """What a run checkpoint holds beside the simulation: where in the case the run is, and every
    output's and measurement's state, to continue them as if never stopped."""
    case: CaseSpec
    base: str  # the case file's folder: mesh files are named from it
    stage: int = 0  # the stage in progress
    stage_start: int = 0  # the step it began at
    begun: bool = False  # its start actions (walls removed, velocities set, bonds) are done
    step: int = 0  # the step of the checkpoint
    observers: list = field(default_factory=list)
    measurements: dict = field(default_factory=dict)
    conditions: list = field(default_factory=list)  # the stage's, as they stand
    summary: dict = field(default_factory=dict)
    seconds: float = 0.0  # wall-clock seconds of the run before this checkpoint


class RunCheckpoint(Observer):
    """Writes the run's checkpoint (the simulation, then its ``RunState``) at its interval, last
    of the observers at a step; never at a run's first or last step (the stage's end is written
    by the run itself, with the next stage to start)."""

    def __init__(self, interval: float, run: "_Run"):
        super().__init__(interval)
        self.run = run

    def maybe_observe(self, sim, force: bool = False) -> None:
        if not force:
            super().maybe_observe(sim)

    def observe(self, sim):
        self.run.write_checkpoint(sim)

    def __getstate__(self):
        return {**super().__getstate__(), "run": None}  # the run holds the simulation: that is the .npz


class _Run:
    """One run of a case into ``outdir``: its stages, observers and measurements."""

    def __init__(self, case: CaseSpec, sim, outdir: Path, progress: bool, echo):
        self.case, self.sim, self.outdir, self.progress, self.echo = case, sim, outdir, progress, echo
        self.tic = time.perf_counter()
        out = case.output
        self.measurements = build_measurements(case, sim)
        observers = []
        if out.time_series is not None:
            observers.append(TimeSeries(outdir / "series.csv", out.time_series.interval, out.time_series.particles))
        if out.snapshots is not None:
            observers.append(VTKSnapshots(outdir / "snapshots", out.snapshots.interval))
        observers += [m.write_to(outdir / "measurements") for m in self.measurements.values()]
        if out.report is not None:
            observers.append(ScenePictures(out.report.pictures))
        longest = sum(stage_duration(s) for s in case.stages)
        interval = out.checkpoint.interval if out.checkpoint is not None else (
            max(longest / CHECKPOINTS_PER_RUN, sim.dt) if longest > 0 else 1.0)
        observers.append(RunCheckpoint(interval, self))
        self.state = RunState(case=case, base=str(Path(case.base_directory).resolve()), observers=observers,
                              measurements=self.measurements,
                              summary={"case": case.name, "output": str(outdir), "particles": sim.n_particles,
                                       "header": header_lines(case, sim), "stages": []})

    @classmethod
    def resumed(cls, outdir: Path, progress: bool, echo, case: CaseSpec | None = None) -> "_Run":
        """The run in ``outdir`` from its last checkpoint; with ``case``, a run of that case that
        takes over a prepared run's folder at a stage's end (``run_prepared``)."""
        folder = outdir / "checkpoints"
        if not (folder / RUN_STATE).exists() or not (folder / RUN_CHECKPOINT).exists():
            raise ParameterError(f"--resume = {str(outdir)!r} is not allowed: it holds no run checkpoint "
                                 f"(checkpoints/{RUN_STATE} and {RUN_CHECKPOINT}); it is not the folder of a "
                                 "rollingdem run, or the run was killed before its first checkpoint")
        summary = outdir / "summary.json"
        if summary.exists() and json.loads(summary.read_text()).get("status") == "ok":
            raise ParameterError(f"--resume = {str(outdir)!r} is not allowed: that run finished (summary.json says "
                                 "ok); nothing is left to run")
        try:
            with open(folder / RUN_STATE, "rb") as fh:
                state: RunState = pickle.load(fh)
            if not isinstance(state, RunState):
                raise TypeError(type(state).__name__)
        except Exception as err:  # noqa: BLE001 - a cut or foreign file: pickle raises many kinds
            raise ParameterError(f"--resume = {str(outdir)!r} is not allowed: its checkpoints/{RUN_STATE} cannot be "
                                 f"read ({type(err).__name__}: the file is cut short, written by another version of "
                                 "rollingdem, or not a run state); the run cannot be resumed, run the case "
                                 "again") from None
        if case is not None:
            state.case, state.base = case, str(Path(case.base_directory).resolve())
            _relocate(state, outdir)
        state.case.base_directory = Path(state.base)
        sim = Simulation.restore(folder / RUN_CHECKPOINT, backend=state.case.backend)
        if sim.step != state.step:
            raise ParameterError(f"--resume = {str(outdir)!r} is not allowed: its checkpoint is at step {sim.step} "
                                 f"and its run state at step {state.step}; they were not written together")
        sim.hints.update(CASE_HINTS)
        run = cls.__new__(cls)
        run.case, run.sim, run.outdir, run.progress, run.echo = state.case, sim, outdir, progress, echo
        run.tic = time.perf_counter() - state.seconds
        run.state, run.measurements = state, state.measurements
        for ob in state.observers:
            if isinstance(ob, RunCheckpoint):
                ob.run = run
        _cut_outputs(outdir, state)
        return run

    # --- checkpoints -------------------------------------------------------------------------------
    on_stage_end = None  # called as on_stage_end(run) after each stage's checkpoint (run_prepared's cache)

    def write_checkpoint(self, sim) -> None:
        """The simulation first, then the run state naming its step: a kill between the two leaves
        a pair that ``resumed`` refuses rather than one that continues wrongly."""
        folder = self.outdir / "checkpoints"
        sim.checkpoint(folder / RUN_CHECKPOINT)
        self.state.step = sim.step
        self.state.seconds = time.perf_counter() - self.tic
        tmp = folder / (RUN_STATE + ".tmp")
        with open(tmp, "wb") as fh:
            pickle.dump(self.state, fh)
        tmp.replace(folder / RUN_STATE)

    # --- the stages --------------------------------------------------------------------------------
    def go(self, continuing: bool = False) -> dict:
        sim, st, echo = self.sim, self.state, self.echo
        summary = st.summary
        failure, stage = None, None
        try:
            while st.stage < len(self.case.stages):
                stage = self.case.stages[st.stage]
                if not st.begun:
                    self._begin(stage)
                    st.begun, st.stage_start = True, sim.step
                    st.conditions = stage_conditions(stage, self.measurements)
                sim.check_before_run()  # (it may lower an automatic dt: the stage is counted in its steps)
                steps_left = int(round(stage_duration(stage) / sim.dt)) - (sim.step - st.stage_start)
                t0, steps0 = time.perf_counter(), sim.step
                ended = sim.schedule.run(sim, max(steps_left, 0), st.observers, self.progress, stage.name,
                                         st.conditions, continuing=continuing)
                continuing = False
                wall = time.perf_counter() - t0
                if stage.until is not None:
                    ended = ended or f"max_duration {stage.max_duration:g} s reached before the condition was met"
                    echo(f"  stage {stage.name!r} ended at t = {sim.time:.4g} s: {ended}")
                steps = sim.step - steps0
                summary["stages"].append({"name": stage.name, "steps": sim.step - st.stage_start, "wall_seconds": wall,
                                          "end_time": sim.time, "ended": ended or "duration",
                                          "particle_steps_per_second": sim.n_particles * steps / wall if wall else None})
                st.stage, st.begun = st.stage + 1, False
                self.write_checkpoint(sim)
                if self.on_stage_end is not None and st.stage < len(self.case.stages):
                    self.on_stage_end(self)
            for m in self.measurements.values():
                echo(f"  {m.summary_line()}")
            if self.measurements and sim.particle_set.coarse_graining_note():
                echo("  (counts are of parcels, each standing for alpha^3 real particles; masses, densities and rates "
                     "are the real material's)")
            for inflow in sim.inflows:
                echo(f"  {inflow.realised()}")
            if self.case.output.repose_angle is not None:
                summary["repose_angle"] = _measure_pile(sim, self.case.output.repose_angle, self.outdir, echo)
        except ParameterError as err:  # refused later on (a stage's dt after the state changed): say where
            failure = err
            raise ParameterError(f"stage {stage.name!r} at t = {sim.time:.6g} s: {err} (the outputs so far are in "
                                 f"{self.outdir})") from None
        except BaseException as err:  # noqa: BLE001 - recorded, then raised again (Ctrl-C included)
            failure = err
            raise
        finally:
            if self.measurements:  # a failed run's too, up to the failure
                summary["measurements"] = {name: m.summary() for name, m in self.measurements.items()}
            summary["inflows"] = [inflow.totals() for inflow in sim.inflows]
            summary.update({"time": sim.time, "steps": sim.step, "particles_left": sim.n_particles,
                            "particles_represented": sim.particle_set.represented(),
                            "wall_seconds": time.perf_counter() - self.tic,
                            "kinetic_energy": sum(sim.kinetic_energy()),
                            "dissipated": sim.dissipated_energy() if sim.track_energy else None,
                            "status": "ok" if failure is None else f"failed: {failure or type(failure).__name__}"})
            sim.checkpoint(self.outdir / "final.npz")
            (self.outdir / "summary.json").write_text(json.dumps(summary, indent=2))
            if self.case.output.report is not None:
                try:
                    pictures = next((o for o in st.observers if isinstance(o, ScenePictures)), None)
                    write_report(self.outdir, summary, run_header(summary, header_lines(self.case, sim)),
                                 self.measurements, pictures,
                                 self.case.name)
                except Exception as err:  # noqa: BLE001 - a failed report must not hide the run's own result
                    echo(f"  (report failed: {type(err).__name__}: {err})")
            if self.case.output.plot and (self.outdir / "series.csv").exists():
                try:
                    plot_kinetic_energy(self.outdir / "series.csv", self.outdir / "kinetic_energy.png",
                                        title=self.case.name)
                except Exception as err:  # noqa: BLE001 - a failed plot must not hide the run's own result
                    echo(f"  (kinetic-energy plot failed: {err})")
        echo(f"  done: {sim.step} steps in {summary['wall_seconds']:.1f} s; outputs in {self.outdir}")
        return summary

    def _begin(self, stage) -> None:
        """A stage's start actions: gravity, the shear rate, walls removed, wall motions, velocities set,
        bonds made."""
        sim = self.sim
        if stage.gravity is not None:
            sim.gravity = stage.gravity
        if stage.shear_rate is not None:
            sim.shear.shear_rate = stage.shear_rate
        walls = {w.name: w for w in sim.walls if w.name}
        for name in stage.remove_walls:  # check_case made sure each names a wall in place
            sim.remove_wall(walls.pop(name))
        meshes = {w.name for w in self.case.walls if w.type == "mesh"}
        for m in stage.wall_motion:
            motion = motion_of(m, mesh=m.wall in meshes, base=self.case.base_directory)
            sim.set_wall_motion(m.wall, None)  # the old program may not suit the new velocity
            sim.set_wall_velocity(m.wall, motion["velocity"], motion.get("angular_velocity", (0.0, 0.0, 0.0)),
                                  point=motion.get("point"))
            sim.set_wall_motion(m.wall, motion["motion"])
        if stage.set_velocity is not None:
            sv = stage.set_velocity
            idx = np.flatnonzero(~sim.fixed) if sv.particles == "all" else sv.particles
            sim.set_velocities(idx, sv.velocity, sv.angular_velocity)
        if stage.bonds is not None:
            made = sim.add_bonds(stage.bonds.parallel_bond(), pairs=stage.bonds.pairs, gap=stage.bonds.gap)
            self.echo(f"  stage {stage.name!r}: {made} bonds")
        sim.choose_time_step()  # after the stage's changes: each stage starts at its own stable step
        for spec in self.case.measurements:  # windows from this stage's start
            if isinstance(spec.window, StageWindowSpec) and spec.window.stage == stage.name:
                self.measurements[spec.name].window = stage_window(spec.window, stage, sim.time)


def _relocate(state: RunState, outdir: Path) -> None:
    """Point the outputs of a run state copied from another folder at ``outdir``."""
    old = Path(state.summary.get("output", outdir))
    for ob in state.observers:
        for attr in ("path", "directory"):
            value = getattr(ob, attr, None)
            if isinstance(value, Path):
                try:
                    setattr(ob, attr, outdir / value.relative_to(old))
                except ValueError:
                    pass
    state.summary["output"] = str(outdir)


def _cut_outputs(outdir: Path, state: RunState) -> None:
    """Cut what the killed run wrote after its checkpoint: CSV rows of later steps, later snapshot
    files; the snapshots' collections are written again from what the checkpoint holds."""
    step = state.step
    csvs = [outdir / "series.csv", *sorted((outdir / "measurements").glob("*.csv"))]
    for path in csvs:
        if not path.exists():
            continue
        lines = path.read_bytes().splitlines(keepends=True)  # bytes: the rows keep their line ends
        kept, header = [], False
        for line in lines:
            if line.startswith(b"#") or not header:
                kept.append(line)
                header = header or not line.startswith(b"#")
                continue
            try:
                if int(line.split(b",", 2)[1]) > step or not line.endswith(b"\n"):
                    continue
            except (IndexError, ValueError):
                continue  # a row cut short by the kill
            kept.append(line)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_bytes(b"".join(kept))
        tmp.replace(path)
    for ob in state.observers:
        if isinstance(ob, VTKSnapshots) and ob.directory.exists():
            ob.cut_after(step)


def run_case(case: CaseSpec, out: str | Path | None = None, progress: bool = True, echo=print,
             overwrite: bool = False) -> dict:
    """Run every stage of a case, writing its outputs; returns a summary (also in summary.json).

    Everything ``check_case`` refuses is refused before the output folder is made: a refused case
    leaves nothing behind, and a folder that holds an earlier run is refused unless ``overwrite``
    (then the earlier run's files, ``RUN_FILES``, are removed first). A run that fails later keeps
    what it wrote so far (summary.json says why it stopped); a killed one continues with
    ``resume_case``."""
    sim = check_case(case)
    outdir = _output_folder(case, out, overwrite)
    try:
        if overwrite and outdir.is_dir():
            _clear(outdir)
        outdir.mkdir(parents=True, exist_ok=True)
        (outdir / "case.yaml").write_text(yaml.safe_dump(json.loads(case.model_dump_json()), sort_keys=False))
    except OSError as err:
        raise ParameterError(f"output folder {outdir} cannot be written: {err.strerror or err}") from None
    echo(f"rollingdem: case {case.name!r}, writing to {outdir}")
    for line in header_lines(case, sim):
        echo(f"  {line}")
    return _Run(case, sim, outdir, progress, echo).go()


def run_prepared(case: CaseSpec, out: Path, cache: Path, keys: list[str], echo=print,
                 reference: CaseSpec | None = None) -> dict:
    """``run_case`` into ``out``, its preparation shared through ``cache``: ``keys[k]`` names the
    run's state at the end of its stage k (what decides it: the scene and the stages up to k). The
    latest stage end already in ``cache`` is copied into ``out`` and the run goes on from there
    (bit for bit as from scratch: ``resume_case``); each stage end not yet there is copied into it.
    ``summary["prepared"]`` names the stage it started after (None: from scratch) and the
    wall-clock seconds that saved.

    With a ``reference`` (the case with other materials and pairs: a calibration's reference
    values; ``keys`` then name its stage ends), the run starts from the end of the reference's
    first stage, made here when ``cache`` lacks it, and goes on with its own materials and pairs
    (``take_materials``): its bed is then the reference material's."""
    out, cache = Path(out), Path(cache)
    made_here = False
    if reference is not None:
        keys = keys[:1]
        if not (cache / keys[0] / "checkpoints" / RUN_STATE).exists():
            _first_stage(reference, cache, keys[0], echo)
            made_here = True
    start = next((k for k in range(len(keys) - 1, -1, -1) if (cache / keys[k] / "checkpoints" / RUN_STATE).exists()),
                 None)

    def keep(run: "_Run") -> None:
        k = run.state.stage - 1
        if k >= len(keys) or (cache / keys[k]).exists():
            return
        cache.mkdir(parents=True, exist_ok=True)
        tmp = cache / f".{keys[k]}.{time.time_ns()}"
        shutil.copytree(run.outdir, tmp, ignore=shutil.ignore_patterns("final.npz", "summary.json", "report*"))
        try:
            tmp.rename(cache / keys[k])
        except OSError:  # another worker kept it first
            shutil.rmtree(tmp, ignore_errors=True)

    if start is None:
        sim = check_case(case)
        out.mkdir(parents=True, exist_ok=False)
        run = _Run(case, sim, out, False, echo)
        run.on_stage_end = keep
        summary = run.go()
        summary["prepared"] = None
        return summary
    shutil.copytree(cache / keys[start], out)
    with open(out / "checkpoints" / RUN_STATE, "rb") as fh:
        saved = 0.0 if made_here else pickle.load(fh).seconds
    run = _Run.resumed(out, False, echo, case=case)
    if reference is not None:
        take_materials(run.sim, case)
    else:
        run.on_stage_end = keep
    summary = run.go()
    summary["prepared"] = {"after_stage": case.stages[start].name, "seconds_saved": saved}
    return summary


class _FirstStageKept(Exception):
    """Ends a run whose first stage's end is all that is wanted (``_first_stage``)."""


def _first_stage(case: CaseSpec, cache: Path, key: str, echo) -> None:
    """The end of ``case``'s first stage kept in ``cache / key`` (its stepping's wall time in the
    run state: the engine module is loaded first)."""
    sim = check_case(case)
    sim.engine_module()
    cache.mkdir(parents=True, exist_ok=True)
    work = cache / f".{key}.{time.time_ns()}"
    work.mkdir()
    run = _Run(case, sim, work, False, echo)

    def stop(_run) -> None:
        raise _FirstStageKept

    run.on_stage_end = stop  # called once the stage's end is written
    try:
        run.go()
    except _FirstStageKept:
        pass
    for name in ("final.npz", "summary.json"):  # the stopped run's: the kept state goes on
        (work / name).unlink(missing_ok=True)
    try:
        work.rename(cache / key)
    except OSError:  # another worker kept it first
        shutil.rmtree(work, ignore_errors=True)


def run_header(summary: dict, end: list[str]) -> list[str]:
    """The report's header: the scene as the run started (``header_lines`` then), and its first line
    at the end where that differs (particles taken out or added, walls removed)."""
    start = summary.get("header") or end
    return start + ([f"at the end: {end[0]}"] if end[0] != start[0] else [])


def header_lines(case: CaseSpec, sim) -> list[str]:
    """What a run is, in words: particles by kind, walls, dt, the contact law."""
    fixed = int(sim.fixed.sum())
    walls = ", ".join(w.name or type(w).__name__.lower() for w in sim.walls) or "none"

    clumps = len(sim.clumps["mass"])
    return [f"{sim.n_particles - fixed} free particles" + (f" and {fixed} fixed" if fixed else "")
            + (f" ({clumps} clumps among them)" if clumps else "") + sim.particle_set.coarse_graining_note()
            + f"; walls: {walls}; dt = {sim.dt:.3g} s", *mesh_lines(sim), f"contact: {sim.contact.describe()}"]


def resume_case(outdir, progress: bool = True, echo=print) -> dict:
    """Continue the run in ``outdir`` (``run_case``'s folder) from its last checkpoint: the stage it
    was in, the outputs cut back to the checkpoint's step and continued. It ends bit for bit where
    the run would have ended had it not been stopped."""
    outdir = Path(outdir)
    if not outdir.is_dir():
        raise ParameterError(f"--resume = {str(outdir)!r} is not allowed: it is not a folder; must be the output "
                             "folder of a run")
    run = _Run.resumed(outdir, progress, echo)
    st = run.state
    stage = run.case.stages[min(st.stage, len(run.case.stages) - 1)]
    echo(f"rollingdem: resuming case {run.case.name!r} in {outdir} at t = {run.sim.time:.6g} s (step {run.sim.step}), "
         f"stage {stage.name!r}")
    return run.go(continuing=st.begun)


#: The estimator's options a run's pile angle is also measured with, to show how much it depends on them.
OPTION_GRID = {"exclude_apex": (0.05, 0.15, 0.25, 0.35), "exclude_toe": (0.05, 0.15, 0.25)}


def _measure_pile(sim, spec: ReposeOutputSpec, outdir: Path, echo) -> dict:
    """The repose angle of the free spheres at the end of the run, printed, in ``pile.png`` and
    returned for summary.json, with its spread over the estimator's options (``OPTION_GRID``); a
    pile the cone fit refuses (too flat, too small) is said, not raised."""
    pile = PileAngle(floor=spec.floor, n_slices=spec.n_slices, exclude_apex=spec.exclude_apex,
                     exclude_toe=spec.exclude_toe)
    pile.values(sim)
    a, floor = pile.result, pile.floor_of(sim)
    if a is None:
        echo(f"  repose angle: not measured: {pile.note} (case file: output.repose_angle has the keys floor, "
             "n_slices, exclude_apex, exclude_toe)")
        return {"angle": None, "note": pile.note}
    free = ~sim.fixed
    plot_pile(sim.positions[free], sim.radii[free], a, path=outdir / "pile.png")
    options = {}
    for apex, toe in product(*OPTION_GRID.values()):
        other = PileAngle(floor=spec.floor, n_slices=spec.n_slices, exclude_apex=apex, exclude_toe=toe)
        options[f"exclude_apex={apex:g},exclude_toe={toe:g}"] = other.values(sim)[0]
    found = [v for v in options.values() if math.isfinite(v)]
    spread = (f"; with exclude_apex {min(OPTION_GRID['exclude_apex']):g}-{max(OPTION_GRID['exclude_apex']):g} and "
              f"exclude_toe {min(OPTION_GRID['exclude_toe']):g}-{max(OPTION_GRID['exclude_toe']):g} it reads "
              f"{min(found):.1f}-{max(found):.1f} deg" if found else "")
    echo(f"  repose angle: {a.angle:.1f} deg, the cone fit to the pile's surface (R² {a.r_squared:.2f}: the cone "
         f"explains {100 * a.r_squared:.0f} % of the surface heights' variance){spread}; {len(a.slice_angles)} "
         f"azimuthal slices {a.slice_mean:.1f} ± {a.slice_std:.1f} deg (the spread around the pile); pile and cone "
         f"in {outdir / 'pile.png'}")
    return {"angle": a.angle, "r_squared": a.r_squared, "slice_mean": a.slice_mean, "slice_std": a.slice_std,
            "floor": floor, "options": options,
            "option_range": [min(found), max(found)] if found else None}


def plot_kinetic_energy(series_csv, png, title=""):
    """Total, translational and rotational kinetic energy over time, log scale (the report's Figure 4)."""
    import matplotlib  # deferred: slow to load, figures only

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: slow to load, figures only
    import pandas as pd  # deferred: slow to load, tables only

    df = pd.read_csv(series_csv)
    fig, ax = plt.subplots(figsize=(7, 4.2))
    floor = 1e-300
    for col, label in (("kinetic_total", "total"), ("kinetic_translational", "translational"),
                       ("kinetic_rotational", "rotational")):
        ax.plot(df["time"], np.maximum(df[col], floor), label=label, lw=1.2 if col == "kinetic_total" else 0.8)
    ax.set_yscale("log")
    positive = df["kinetic_total"][df["kinetic_total"] > 0]
    if len(positive):
        ax.set_ylim(max(positive.min() * 0.5, positive.max() * 1e-14), positive.max() * 3)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("kinetic energy (J)")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    plt.close(fig)


__all__ = ["OPTION_GRID", "RUN_FILES", "RunState", "earlier_run", "plot_kinetic_energy", "resume_case", "run_case"]
