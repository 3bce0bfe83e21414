"""Case files (YAML or TOML): the same scene as the Python API, validated before anything runs.

A case file has the keys ``name``, ``materials``, ``pairs``, ``contact``, ``walls``, ``particles``,
``stages`` and ``output`` (see ``rollingdem/cases/default.yaml`` for a complete example). Every
mapping is strict: an unknown or misspelled key is an error that names the key and lists the allowed
ones; a missing key names what is missing.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Annotated, Any, Literal, Optional, Union, get_type_hints

import re

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, create_model

from .errors import ParameterError

Vector = tuple[float, float, float]


class _YAMLLoader(yaml.SafeLoader):
    """PyYAML reads YAML 1.1, where 1.0e4 (no exponent sign) is a string; read it as the float
    every user means (YAML 1.2 rule)."""


_YAMLLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                |[-+]?\.(?:inf|Inf|INF)
                |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


def _material_spec():
    """The schema of a material entry, taken from ``Material`` itself (one list of fields and defaults)."""
    from dataclasses import MISSING, fields

    from .materials import Material

    hints = get_type_hints(Material)
    spec = {f.name: (hints[f.name], ... if f.default is MISSING else f.default) for f in fields(Material)}
    return create_model("MaterialSpec", __base__=_Strict, **spec)


MaterialSpec = _material_spec()


class PairSpec(_Strict):
    materials: tuple[str, str]
    friction: Optional[float] = None
    rolling_friction: Optional[float] = None
    restitution: Optional[float] = None
    rolling_damping: Optional[float] = None


class ContactSpec(_Strict):
    normal: Union[str, dict[str, Any]] = "hertz"
    tangential: Union[str, dict[str, Any]] = "history"
    rolling: Union[str, dict[str, Any]] = "none"
    twisting: Union[str, dict[str, Any]] = "none"


class PlaneSpec(_Strict):
    type: Literal["plane"]
    name: Optional[str] = None
    material: str
    point: Vector = (0.0, 0.0, 0.0)
    normal: Vector = (0.0, 0.0, 1.0)
    velocity: Vector = (0.0, 0.0, 0.0)
    angular_velocity: Vector = (0.0, 0.0, 0.0)


class CylinderSpec(_Strict):
    type: Literal["cylinder"]
    name: Optional[str] = None
    material: str
    radius: float
    point: Vector = (0.0, 0.0, 0.0)
    axis: Vector = (0.0, 0.0, 1.0)
    extent: Optional[tuple[float, float]] = None
    velocity: Vector = (0.0, 0.0, 0.0)
    angular_velocity: Vector = (0.0, 0.0, 0.0)


WallSpec = Annotated[Union[PlaneSpec, CylinderSpec], Field(discriminator="type")]


class BoxRegionSpec(_Strict):
    type: Literal["box"]
    lo: Vector
    hi: Vector


class CylinderRegionSpec(_Strict):
    type: Literal["cylinder"]
    radius: float
    z_min: float
    z_max: float
    center: tuple[float, float] = (0.0, 0.0)


RegionSpec = Annotated[Union[BoxRegionSpec, CylinderRegionSpec], Field(discriminator="type")]


class UniformSpec(_Strict):
    distribution: Literal["uniform"]
    low: float
    high: float


class NormalSpec(_Strict):
    distribution: Literal["normal"]
    mean: float
    std: float
    low: Optional[float] = None
    high: Optional[float] = None


class DiscreteSpec(_Strict):
    distribution: Literal["discrete"]
    values: list[float]
    weights: Optional[list[float]] = None


RadiusSpec = Union[float, Annotated[Union[UniformSpec, NormalSpec, DiscreteSpec], Field(discriminator="distribution")]]


class InsertSpec(_Strict):
    insert: RegionSpec
    count: int
    radius: RadiusSpec
    material: str
    seed: int = 0
    velocity: Optional[Vector] = None


class ListSpec(_Strict):
    positions: list[Vector]
    radius: Union[float, list[float]]
    material: str
    velocity: Optional[Union[Vector, list[Vector]]] = None
    angular_velocity: Optional[Union[Vector, list[Vector]]] = None


class SetVelocitySpec(_Strict):
    particles: Union[Literal["all"], list[int]] = "all"
    velocity: Optional[Vector] = None
    angular_velocity: Optional[Vector] = None


class StageSpec(_Strict):
    name: str = "run"
    duration: float
    gravity: Optional[Vector] = None
    remove_walls: list[str] = []
    set_velocity: Optional[SetVelocitySpec] = None


class SeriesSpec(_Strict):
    interval: float = 1e-3
    particles: list[int] = []


class IntervalSpec(_Strict):
    interval: float


class OutputSpec(_Strict):
    directory: Optional[str] = None
    time_series: Optional[SeriesSpec] = SeriesSpec()
    snapshots: Optional[IntervalSpec] = None
    checkpoint: Optional[IntervalSpec] = None
    plot: bool = True


class CaseSpec(_Strict):
    name: str = "case"
    dt: Optional[float] = None
    skin: Optional[float] = None
    check_timestep: bool = True
    gravity: Vector = (0.0, 0.0, -9.81)
    materials: list[MaterialSpec] = Field(min_length=1)
    pairs: list[PairSpec] = []
    contact: ContactSpec = ContactSpec()
    walls: list[WallSpec] = []
    particles: list[Union[InsertSpec, ListSpec]] = Field(min_length=1)
    stages: list[StageSpec] = Field(min_length=1)
    output: OutputSpec = OutputSpec()


def _format_validation_error(err: ValidationError, source: str) -> str:
    lines = [f"case file {source} is not valid:"]
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"] if not (isinstance(p, str) and p.endswith("Spec")
                                                       or p in ("function-after", "tagged-union")))
        value = e.get("input")
        if e["type"] == "extra_forbidden":
            lines.append(f"  key {loc!r}: not a known key (misspelled?)")
        elif e["type"] == "missing":
            lines.append(f"  key {loc!r}: missing (required)")
        else:
            shown = json.dumps(value, default=str)
            if len(shown) > 80:
                shown = shown[:77] + "..."
            lines.append(f"  key {loc!r} = {shown}: {e['msg']}")
    return "\n".join(lines)


def read_mapping(path_or_dict, what: str = "case file") -> tuple[dict, str]:
    """(data, source name) of a YAML file, a TOML file (by extension) or a mapping."""
    if isinstance(path_or_dict, dict):
        return path_or_dict, "<dict>"
    path = Path(path_or_dict)
    source = str(path)
    if not path.exists():
        raise ParameterError(f"{what} {source} does not exist")
    text = path.read_text()
    if path.suffix.lower() == ".toml":
        import tomllib

        data = tomllib.loads(text)
    else:
        data = yaml.load(text, Loader=_YAMLLoader)
    if not isinstance(data, dict):
        raise ParameterError(f"{what} {source} must hold a mapping of keys, got {type(data).__name__}")
    return data, source


def load_case(path_or_dict) -> CaseSpec:
    """Read and validate a case file (YAML, or TOML by extension) or a mapping."""
    data, source = read_mapping(path_or_dict)
    try:
        return CaseSpec.model_validate(data)
    except ValidationError as err:
        raise ParameterError(_format_validation_error(err, source)) from None


def _radius(spec):
    from .insertion import Discrete, Normal, Uniform

    if isinstance(spec, (int, float)):
        return float(spec)
    if isinstance(spec, UniformSpec):
        return Uniform(spec.low, spec.high)
    if isinstance(spec, NormalSpec):
        return Normal(spec.mean, spec.std, spec.low, spec.high)
    return Discrete(spec.values, spec.weights)


def build_simulation(case: CaseSpec):
    """The Simulation a case describes (materials, walls, particles), before any stage runs."""
    from . import ContactModel, Cylinder, Material, Plane, Simulation
    from .insertion import BoxRegion, CylinderRegion

    contact = ContactModel(**case.contact.model_dump())
    sim = Simulation(contact=contact, gravity=case.gravity, dt=case.dt, skin=case.skin,
                     check_timestep=case.check_timestep)
    for m in case.materials:
        sim.add_material(Material(**m.model_dump()))
    for p in case.pairs:
        coeffs = {k: v for k, v in p.model_dump(exclude={"materials"}).items() if v is not None}
        sim.set_pair(p.materials[0], p.materials[1], **coeffs)
    for w in case.walls:
        d = w.model_dump(exclude={"type"})
        sim.add_wall(Plane(**d) if w.type == "plane" else Cylinder(**d))
    for p in case.particles:
        if isinstance(p, InsertSpec):
            r = p.insert
            region = (BoxRegion(r.lo, r.hi) if r.type == "box"
                      else CylinderRegion(r.radius, r.z_min, r.z_max, center=r.center))
            sim.insert(region, p.count, _radius(p.radius), p.material, seed=p.seed, velocity=p.velocity)
        else:
            sim.add_particles(p.positions, p.radius, p.material, velocity=p.velocity,
                              angular_velocity=p.angular_velocity)
    return sim


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


def run_case(case: CaseSpec, out: str | Path | None = None, progress: bool = True, echo=print) -> dict:
    """Run every stage of a case, writing its outputs; returns a summary (also in summary.json)."""
    from . import Checkpoints, TimeSeries, VTKSnapshots

    base = Path(out or case.output.directory or Path("rollingdem-output") / case.name)
    outdir = _fresh_directory(base) if out is None else base
    outdir.mkdir(parents=True, exist_ok=True)
    (outdir / "case.yaml").write_text(yaml.safe_dump(json.loads(case.model_dump_json()), sort_keys=False))
    echo(f"rollingdem: case {case.name!r}, writing to {outdir}")
    tic = time.perf_counter()
    sim = build_simulation(case)
    echo(f"  {sim.n_particles} particles, {len(sim.walls)} walls, dt = {sim.dt:.3g} s, contact {sim.contact!r}")
    observers = []
    if case.output.time_series is not None:
        observers.append(TimeSeries(outdir / "series.csv", case.output.time_series.interval,
                                    case.output.time_series.particles))
    if case.output.snapshots is not None:
        observers.append(VTKSnapshots(outdir / "snapshots", case.output.snapshots.interval))
    if case.output.checkpoint is not None:
        observers.append(Checkpoints(outdir / "checkpoints", case.output.checkpoint.interval))
    walls_by_name = {w.name: w for w in sim.walls if w.name}
    summary = {"case": case.name, "output": str(outdir), "particles": sim.n_particles, "stages": []}
    failure = None
    try:
        for stage in case.stages:
            if stage.gravity is not None:
                sim.gravity = stage.gravity
            for name in stage.remove_walls:
                if name not in walls_by_name:
                    raise ParameterError(f"stage {stage.name!r}: remove_walls = {name!r} is not a wall name: "
                                         f"known are {', '.join(map(repr, walls_by_name)) or 'none'}")
                sim.remove_wall(walls_by_name.pop(name))
            if stage.set_velocity is not None:
                sv = stage.set_velocity
                idx = np.arange(sim.n_particles) if sv.particles == "all" else sv.particles
                sim.set_velocities(idx, sv.velocity, sv.angular_velocity)
            t0 = time.perf_counter()
            steps0 = sim.step
            sim.run(stage.duration, observers=observers, progress=progress, label=stage.name)
            wall = time.perf_counter() - t0
            steps = sim.step - steps0
            summary["stages"].append({"name": stage.name, "steps": steps, "wall_seconds": wall,
                                      "particle_steps_per_second": sim.n_particles * steps / wall if wall else None})
    except Exception as err:  # noqa: BLE001 - recorded, then raised again
        failure = err
        raise
    finally:
        summary.update({"time": sim.time, "steps": sim.step, "wall_seconds": time.perf_counter() - tic,
                        "kinetic_energy": sum(sim.kinetic_energy()), "dissipated": sim.dissipated_energy() if sim.track_energy else None,
                        "status": "ok" if failure is None else f"failed: {failure}"})
        sim.checkpoint(outdir / "final.npz")
        (outdir / "summary.json").write_text(json.dumps(summary, indent=2))
        if case.output.plot and (outdir / "series.csv").exists():
            try:
                plot_kinetic_energy(outdir / "series.csv", outdir / "kinetic_energy.png", title=case.name)
            except Exception as err:  # noqa: BLE001 - a failed plot must not hide the run's own result
                echo(f"  (kinetic-energy plot failed: {err})")
    echo(f"  done: {sim.step} steps in {summary['wall_seconds']:.1f} s; outputs in {outdir}")
    return summary


def plot_kinetic_energy(series_csv, png, title=""):
    """Total, translational and rotational kinetic energy over time, log scale (the report's Figure 4)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

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


def default_case_path() -> Path:
    return Path(__file__).parent / "cases" / "default.yaml"


__all__ = ["CaseSpec", "load_case", "build_simulation", "run_case", "plot_kinetic_energy", "default_case_path"]
