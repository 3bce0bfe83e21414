"""A user's case file as an experiment: what ``rollingdem sweep`` and ``rollingdem calibrate`` vary
and measure when given a case file instead of a built-in experiment.

Its parameters are the numbers written in the file, each by its path: list entries by their
``name`` where they have one, else by their index (``materials.glass.rolling_friction``,
``stages.discharge.max_duration``, ``particles.0.count``); where the file has one material, also
the short names of the built-in experiments (``mu``, ``mur``, ``e``, ``eta_r``, ``E``, ``nu``,
``density``); and ``seed``, added to every seed in the file (its insertions and inflows). Its
observables are its measurements' quantities (``NAME.QUANTITY``: the summary's mean over the
window; a cumulative quantity's final value; a rate's least-squares slope) and, with
``output.repose_angle``, the pile's (``repose_angle.angle``, ``repose_angle.r_squared``, ...).
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import tempfile
from pathlib import Path
from typing import Any

from rollingdem.errors import ParameterError
from rollingdem.experiments.registry import (
    CASE_FILE_SUFFIXES,
    EXPERIMENTS,
    FILE_EXPERIMENT,
    UNBOUNDED,
    Experiment,
    Parameter,
)
from rollingdem.io.case_check import check_case
from rollingdem.io.casefile import build_measurements, build_simulation, load_case
from rollingdem.io.mapping_file import read_mapping
from rollingdem.io.runner import run_case, run_prepared
from rollingdem.scene.materials import Material
from rollingdem.scene.simulation import __version__

#: Short names of a one-material file's coefficients, as the built-in experiments name them.
ALIASES = {"mu": "friction", "mur": "rolling_friction", "e": "restitution", "eta_r": "rolling_damping",
           "E": "youngs_modulus", "nu": "poisson_ratio", "density": "density", "coarse_graining": "coarse_graining"}
#: the short names a file may leave out, with the value it then means (the case file's default)
UNWRITTEN = {"coarse_graining": 1.0}
SUFFIXES = CASE_FILE_SUFFIXES
PILE = ("angle", "r_squared", "slice_mean", "slice_std")


def is_case_file(name: str) -> bool:
    return isinstance(name, str) and name.lower().endswith(SUFFIXES)


def _key_of(entry, index: int) -> str:
    return str(entry["name"]) if isinstance(entry, dict) and isinstance(entry.get("name"), str) else str(index)


def numeric_leaves(data, prefix: str = "") -> dict[str, float]:
    """Every number written in the file that stands alone (not in a vector), by its path."""
    out = {}
    items = (data.items() if isinstance(data, dict)
             else ((_key_of(v, k), v) for k, v in enumerate(data)) if isinstance(data, list) else ())
    for key, value in items:
        path = f"{prefix}{key}"
        if isinstance(value, bool):
            continue
        if isinstance(value, (int, float)) and not isinstance(data, list):
            out[path] = value
        elif isinstance(value, (dict, list)) and not (isinstance(value, list) and value
                                                       and all(isinstance(v, (int, float)) for v in value)):
            out.update(numeric_leaves(value, path + "."))
    return out


def _locate(data, path: str):
    """(the list or mapping that holds the number at ``path``, its index or key); KeyError when the
    file has no such path."""
    node = holder = key = data
    for part in path.split("."):
        if isinstance(node, list):
            keys = [_key_of(v, k) for k, v in enumerate(node)]
            if part not in keys:
                raise KeyError(path)
            holder, key = node, keys.index(part)
        elif isinstance(node, dict) and part in node:
            holder, key = node, part
        else:
            raise KeyError(path)
        node = holder[key]
    return holder, key


def set_path(data, path: str, value) -> None:
    """Set the number at ``path`` (``numeric_leaves``'s names) in ``data``, in place; a key a
    mapping lacks is added."""
    try:
        holder, key = _locate(data, path)
    except KeyError:
        parent, _, key = path.rpartition(".")
        outer, at = _locate(data, parent)
        holder = outer[at]
        if not isinstance(holder, dict):
            raise
    holder[key] = value


class CaseExperiment(Experiment):
    """The experiment a case file describes (see the module's docstring)."""

    model_keyword = None

    def __init__(self, path):
        self.path = Path(path)
        self.data, _ = read_mapping(self.path)
        case = load_case(self.path)  # refuse a bad file now, with its own messages
        self.name = str(path)
        self.description = f"the case file {path}"
        self.base = self.path.resolve().parent
        leaves = numeric_leaves(self.data)
        materials = self.data.get("materials") or []
        self.aliases = {}
        if len(materials) == 1:
            m = _key_of(materials[0], 0)
            self.aliases = {short: f"materials.{m}.{long}" for short, long in ALIASES.items()
                            if f"materials.{m}.{long}" in leaves or short in UNWRITTEN}
            leaves = {**{self.aliases[k]: v for k, v in UNWRITTEN.items()}, **leaves}
        seeded = self._seed_paths()
        self.stochastic = bool(seeded)
        params = [Parameter(short, leaves[long], f"{long} (the file's one material)", calibration_range=UNBOUNDED)
                  for short, long in self.aliases.items()]
        params += [Parameter(p, v, f"{p} in {self.path.name}", integer=isinstance(v, int) and p not in seeded,
                             calibration_range=UNBOUNDED) for p, v in leaves.items() if p not in seeded]
        if seeded:
            params.append(Parameter("seed", 0, "added to every seed in the file (insertions, inflows)", low=0,
                                    integer=True))
        self.parameters = tuple(params)
        self.observables = self._observables(case)
        self.default_observable = next(iter(self.observables), "")
        if len(case.stages) > 1:
            self.observables["prepared.seconds_saved"] = "s, wall-clock time a prepared bed saved (sweeps)"
        self.targets = {o: (-math.inf, math.inf) for o in self.observables}

    def _seed_paths(self) -> list[str]:
        return [p for p in numeric_leaves(self.data) if p.split(".")[-1] == "seed"
                and p.split(".")[0] in ("particles", "inflows")]

    @staticmethod
    def _observables(case) -> dict[str, str]:
        out = {}
        for name, m in build_measurements(case, build_simulation(case)).items():
            for q, unit in (m.QUANTITIES or {}).items():
                out[f"{name}.{q}"] = f"{unit}, {m.describe()}"
        if case.output.repose_angle is not None and not any(o.startswith("repose_angle.") for o in out):
            out.update({f"repose_angle.{q}": "the pile at the end (output.repose_angle)" for q in PILE})
        return out

    def resolve(self, params: dict) -> dict:
        """The values to run with: every parameter (defaults from the file), checked; a path or name
        the file does not have is refused, naming the paths it has."""
        by_name = self.by_name
        unknown = [k for k in params if k not in by_name]
        if unknown:
            shown = ", ".join(list(by_name)[:12]) + (", ..." if len(by_name) > 12 else "")
            raise ParameterError(f"parameter = {unknown[0]!r} is not allowed: {self.path.name} has no number at that "
                                 f"path; its parameters are {shown}")
        resolved = {p.name: p.check(params[p.name]) if p.name in params else p.default for p in self.parameters}
        doubled = [s for s, long in self.aliases.items() if s in params and long in params]
        if doubled:
            raise ParameterError(f"parameter {doubled[0]!r} and {self.aliases[doubled[0]]!r} are one number: give one")
        self.case_data(resolved)  # refuse now what the case file's own checks would refuse
        return resolved

    def case_data(self, params: dict) -> dict:
        """The file's data with ``params`` written in, checked as a case file."""
        data = copy.deepcopy(self.data)
        for name, value in params.items():
            if name == "seed":
                for p in self._seed_paths():
                    set_path(data, p, int(_get(self.data, p)) + int(value))
            elif name not in self.aliases:
                set_path(data, name, value)
        for short, long in self.aliases.items():  # a short name given overrides its path's default
            if short in params and params[short] != _get(self.data, long):
                set_path(data, long, params[short])
        try:
            case = load_case(data)

            for k, m in enumerate(case.materials):  # cheap, and where most bad values show
                try:
                    Material(**m.model_dump())
                except ParameterError as err:
                    raise ParameterError(f"materials.{k}: {err}") from None
        except ParameterError as err:
            raise ParameterError(f"{self.path.name} with {_changed(self.data, params, self.aliases)}: "
                                 f"{str(err).replace('case file <dict>: ', '')}") from None
        return data

    def check(self, params: dict) -> None:
        """The file with ``params`` written in, built and checked as ``rollingdem check`` does."""
        case = load_case(self.case_data(self.resolve(params)))
        case.base_directory = self.base
        try:
            check_case(case)
        except ParameterError as err:
            raise ParameterError(f"{self.path.name} with {_changed(self.data, params, self.aliases)}: {err}") from None

    prepared = None  # the folder of the stage ends that runs share (prepare_in)

    def prepare_in(self, folder) -> None:
        """Share the runs' preparation through ``folder``: a run whose scene and first stages equal
        an earlier run's starts from that run's state at their end (``rollingdem.io.runner.run_prepared``)."""
        self.prepared = Path(folder)

    def stage_keys(self, data: dict) -> list[str]:
        return stage_keys(data)

    def observe(self, params: dict) -> dict:
        """Run the case with ``params`` in a folder of its own, removed afterwards; its measurements'
        summaries are the observables. With ``prepare_in``, from the latest stage end it shares
        with an earlier run (``prepared.seconds_saved``: the wall-clock seconds that saved)."""
        data = self.case_data(params)
        data.setdefault("output", {})["snapshots"] = None  # a sweep keeps numbers, not pictures
        data["output"]["report"] = None
        case = load_case(data)
        case.base_directory = self.base
        with tempfile.TemporaryDirectory(prefix="rollingdem-case-") as folder:
            if self.prepared is not None and len(case.stages) > 1:
                summary = run_prepared(case, Path(folder) / "run", self.prepared, self.stage_keys(data),
                                       echo=lambda *_: None)
            else:
                summary = run_case(case, out=Path(folder) / "run", progress=False, echo=lambda *_: None)
        out = {}
        for name, s in (summary.get("measurements") or {}).items():
            for q, entry in s.items():
                if isinstance(entry, dict) and "value" in entry:
                    out[f"{name}.{q}"] = entry["value"]
        pile = summary.get("repose_angle") or {}
        for q in PILE:
            out.setdefault(f"repose_angle.{q}", pile.get(q) if pile.get(q) is not None else math.nan)
        out["prepared.seconds_saved"] = (summary.get("prepared") or {}).get("seconds_saved", 0.0)
        return {o: out.get(o, math.nan) for o in self.observables}


def stage_keys(data: dict) -> list[str]:
    """What decides the state at the end of each stage but the last: a case file's data without
    its name and the later stages, hashed."""
    keys = []
    for k in range(1, len(data.get("stages") or [])):
        head = {key: v for key, v in data.items() if key not in ("stages", "name")}
        head["stages"] = data["stages"][:k]
        text = json.dumps({"version": __version__, "case": head}, sort_keys=True, default=str)
        keys.append(hashlib.sha1(text.encode()).hexdigest()[:16])
    return keys


def run_case_data(data: dict, series: tuple[str, ...] = (), what: str = "case",
                  shared: tuple | None = None) -> tuple[dict, dict]:
    """Run the case file's ``data`` as ``rollingdem run`` does, in a folder removed afterwards:
    (its summary, the series of the measurements named in ``series`` as pandas DataFrames). A run
    that fails raises a RuntimeError naming ``what`` and its reason. With ``shared`` = (a folder,
    the reference's data: the case with other materials), the run starts from the reference's
    first stage end, kept in the folder (``rollingdem.io.runner.run_prepared``)."""
    import pandas as pd  # deferred: slow to load, tables only

    with tempfile.TemporaryDirectory(prefix="rollingdem-case-") as folder:
        if shared is None:
            summary = run_case(load_case(data), out=Path(folder) / "run", progress=False, echo=lambda *_: None)
        else:
            cache, reference = shared
            summary = run_prepared(load_case(data), Path(folder) / "run", Path(cache), stage_keys(reference),
                                   echo=lambda *_: None, reference=load_case(reference))
        if summary.get("status") != "ok":
            raise RuntimeError(f"the {what}'s run failed: {summary.get('error', summary.get('status'))}")
        return summary, {name: pd.read_csv(Path(folder) / "run" / "measurements" / f"{name}.csv", comment="#")
                         for name in series}


def _get(data, path: str) -> Any:
    try:
        holder, key = _locate(data, path)
    except KeyError:
        short = path.rpartition(".")[2]
        if short in UNWRITTEN:
            return UNWRITTEN[short]
        raise
    return holder[key]


def _changed(data, params: dict, aliases: dict) -> str:
    diff = [f"{k} = {v!r}" for k, v in params.items()
            if k != "seed" and v != _get(data, aliases.get(k, k))]
    return ", ".join(diff) or "its own values"


def case_experiment(path) -> CaseExperiment:
    """The experiment of the case file at ``path``, registered under its path (as given) so that
    sweeps and calibrations find it by name; a file that does not exist is refused."""
    key = str(path)
    if key not in EXPERIMENTS:
        if not Path(path).is_file():
            raise ParameterError(f"experiment = {key!r} is not allowed: no such case file (a case file ends in "
                                 f"{', '.join(SUFFIXES)}; the built-in experiments are "
                                 f"{', '.join(n for n in EXPERIMENTS if not is_case_file(n))})")
        EXPERIMENTS[key] = CaseExperiment(path)
    return EXPERIMENTS[key]


def shipped_cases() -> dict[str, Path]:
    """The case files shipped with the package, by name: the default pile and those in ``cases/``."""
    here = Path(__file__).parent
    return {"pile": here / "default.yaml", **{p.stem: p for p in sorted((here / "cases").glob("*.yaml"))}}


FILE_EXPERIMENT[:] = [case_experiment]

__all__ = ["ALIASES", "CaseExperiment", "case_experiment", "is_case_file", "run_case_data", "shipped_cases", "numeric_leaves",
           "set_path"]
