"""Case files (YAML or TOML): the same scene as the Python API, validated before anything runs.

A case file has the keys ``name``, ``materials``, ``pairs``, ``contact``, ``periodic``, ``walls``,
``particles``, ``outlets``, ``inflows``, ``measurements``, ``stages`` and ``output`` (see ``rollingdem/experiments/default.yaml`` for a complete example). Every
mapping is strict: an unknown or misspelled key is an error that names the key and lists the allowed
ones; a missing key names what is missing.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any, Literal, Optional, Union, get_type_hints

import re

import numpy as np
from pydantic import (BaseModel, BeforeValidator, ConfigDict, Discriminator, Field, PrivateAttr, Strict, Tag,
                      ValidationError, create_model)

from rollingdem.errors import ParameterError
from rollingdem.io.mapping_file import read_mapping
from rollingdem.scene.walls import surface_speed


def _whole(value):
    """An integer key: a bool (YAML ``yes``/``true``) is no count or index."""
    if isinstance(value, bool):
        raise ValueError("must be a whole number")
    return value


#: A number in a case file: an int or a float, never a bool or a string ("1e4" is read as a number
#: by the loader of :mod:`rollingdem.io.mapping_file`; ``true`` is not 1).
Number = Annotated[float, Strict()]
Whole = Annotated[int, BeforeValidator(_whole)]
Vector = tuple[Number, Number, Number]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


def _material_spec():
    """The schema of a material entry, taken from ``Material`` itself (one list of fields and defaults)."""
    from dataclasses import MISSING, fields

    from rollingdem.scene.materials import Material

    hints = get_type_hints(Material)
    strict = {float: Number, Optional[float]: Optional[Number]}
    spec = {f.name: (strict.get(hints[f.name], hints[f.name]), ... if f.default is MISSING else f.default)
            for f in fields(Material)}
    return create_model("MaterialSpec", __base__=_Strict, **spec)


MaterialSpec = _material_spec()


class PairSpec(_Strict):
    materials: tuple[str, str]
    friction: Optional[Number] = None
    rolling_friction: Optional[Number] = None
    restitution: Optional[Number] = None
    rolling_damping: Optional[Number] = None
    surface_energy: Optional[Number] = None
    cohesion_energy_density: Optional[Number] = None


class ContactSpec(_Strict):
    # a model name or {model: name, parameter: value, ...}; make_submodel checks both
    normal: Any = "hertz"
    tangential: Any = "history"
    rolling: Any = "none"
    twisting: Any = "none"
    cohesion: Any = "none"


class OscillateSpec(_Strict):
    """``rollingdem.Oscillation``: ``frequency`` (Hz), ``amplitude`` (m, a vector), ``angle`` (degrees)
    about ``axis`` (a mesh wall only), ``phase`` (degrees)."""
    frequency: Number
    amplitude: Vector = (0.0, 0.0, 0.0)
    angle: Number = 0.0
    axis: Optional[Vector] = None
    phase: Number = 0.0


class TableSpec(_Strict):
    """``rollingdem.MotionTable``: ``times`` (s) with ``displacements`` (m) and/or ``angles`` (degrees,
    about ``axis``; a mesh wall only), or a CSV ``file`` whose header names the columns t, dx, dy,
    dz and angle (each but t optional); ``repeat`` starts it again at its end."""
    file: Optional[str] = None
    times: Optional[list[Number]] = None
    displacements: Optional[list[Vector]] = None
    angles: Optional[list[Number]] = None
    axis: Optional[Vector] = None
    repeat: bool = False


class ServoSpec(_Strict):
    """``rollingdem.Servo``: moves along ``direction`` within ``max_speed`` (m/s) to hold ``force`` (N)
    or ``pressure`` (Pa) on ``area`` (m^2); ``gain`` (m/s per N)."""
    direction: Vector
    max_speed: Number
    force: Optional[Number] = None
    pressure: Optional[Number] = None
    area: Optional[Number] = None
    gain: Optional[Number] = None


class PlaneSpec(_Strict):
    type: Literal["plane"]
    name: Optional[str] = None
    material: str
    point: Vector = (0.0, 0.0, 0.0)
    normal: Vector = (0.0, 0.0, 1.0)
    velocity: Vector = (0.0, 0.0, 0.0)
    angular_velocity: Vector = (0.0, 0.0, 0.0)
    oscillate: Optional[OscillateSpec] = None  # a motion program: at most one of the three
    table: Optional[TableSpec] = None
    servo: Optional[ServoSpec] = None


class CylinderSpec(_Strict):
    type: Literal["cylinder"]
    name: Optional[str] = None
    material: str
    radius: Number
    point: Vector = (0.0, 0.0, 0.0)
    axis: Vector = (0.0, 0.0, 1.0)
    extent: Optional[tuple[Number, Number]] = None
    velocity: Vector = (0.0, 0.0, 0.0)
    angular_velocity: Vector = (0.0, 0.0, 0.0)
    oscillate: Optional[OscillateSpec] = None  # a motion program: at most one of the three
    table: Optional[TableSpec] = None
    servo: Optional[ServoSpec] = None


class RotateSpec(_Strict):
    """A turn about the axis through ``point``: at ``angular_velocity`` (rad/s) or ``rpm``
    (revolutions per minute) in a motion, by ``angle`` (degrees) in a placement. ``point``: a mesh
    wall's (default the origin); a plane or cylinder turns about its own point and takes none."""
    axis: Vector
    point: Optional[Vector] = None
    angular_velocity: Optional[Number] = None
    rpm: Optional[Number] = None
    angle: Optional[Number] = None


class MotionSpec(_Strict):
    velocity: Vector = (0.0, 0.0, 0.0)
    rotate: Optional[RotateSpec] = None
    oscillate: Optional[OscillateSpec] = None  # a motion program: at most one of the three
    table: Optional[TableSpec] = None
    servo: Optional[ServoSpec] = None


class PlaceSpec(_Strict):
    rotate: Optional[RotateSpec] = None
    translate: Vector = (0.0, 0.0, 0.0)


class MeshSpec(_Strict):
    """A triangle-mesh wall: ``file`` (STL or OBJ, relative to the case file; ``scale`` 0.001 for mm;
    vertices within ``weld`` m merged) or a ready-made ``shape`` with its ``size`` (its dimensions by
    name), placed by ``place`` (turned, then moved), moving by ``motion``; ``check_size: false``
    accepts a mesh implausibly large against the particles."""
    type: Literal["mesh"]
    name: Optional[str] = None
    material: str
    file: Optional[str] = None
    scale: Number = 1.0
    weld: Optional[Number] = None
    check_size: bool = True
    shape: Optional[str] = None
    size: dict[str, Any] = {}
    place: Optional[PlaceSpec] = None
    motion: Optional[MotionSpec] = None


WallSpec = Annotated[Union[PlaneSpec, CylinderSpec, MeshSpec], Field(discriminator="type")]


class BoxRegionSpec(_Strict):
    type: Literal["box"]
    lo: Vector
    hi: Vector


class CylinderRegionSpec(_Strict):
    type: Literal["cylinder"]
    radius: Number
    z_min: Number
    z_max: Number
    center: tuple[Number, Number] = (0.0, 0.0)


class _SensorMeshSpec(_Strict):
    """A sensor's mesh, given as a mesh wall is: ``file`` with ``scale``, or ``shape`` with ``size``; ``place``."""
    file: Optional[str] = None
    scale: Number = 1.0
    shape: Optional[str] = None
    size: dict[str, Any] = {}
    place: Optional[PlaceSpec] = None


class MeshRegionSpec(_SensorMeshSpec):
    """``rollingdem.MeshRegion``: the volume a closed mesh encloses, given as a mesh wall is, or the
    mesh of the ``wall`` named so (a region to fill)."""
    type: Literal["mesh"]
    wall: Optional[str] = None


RegionSpec = Annotated[Union[BoxRegionSpec, CylinderRegionSpec, MeshRegionSpec], Field(discriminator="type")]


class UniformSpec(_Strict):
    distribution: Literal["uniform"]
    low: Number
    high: Number


class NormalSpec(_Strict):
    distribution: Literal["normal"]
    mean: Number
    std: Number
    low: Optional[Number] = None
    high: Optional[Number] = None


class DiscreteSpec(_Strict):
    distribution: Literal["discrete"]
    values: list[Number]
    weights: Optional[list[Number]] = None


class MassFractionsSpec(_Strict):
    """``rollingdem.MassFractions``: the ``radii`` (m) and the fraction of the mass each makes up."""
    distribution: Literal["mass_fractions"]
    radii: list[Number]
    fractions: list[Number]


class SieveSpec(_Strict):
    """``rollingdem.SieveCurve``: the mass fraction ``passing`` each sieve of ``diameters`` (m)."""
    distribution: Literal["sieve"]
    diameters: list[Number]
    passing: list[Number]


def _radius_kind(value):
    """The tag of a radius: a number, or the distribution of a mapping (or of a parsed distribution)."""
    if isinstance(value, dict):
        return value.get("distribution")
    return getattr(value, "distribution", "number")


RadiusSpec = Annotated[Union[Annotated[Number, Tag("number")], Annotated[UniformSpec, Tag("uniform")],
                             Annotated[NormalSpec, Tag("normal")], Annotated[DiscreteSpec, Tag("discrete")],
                             Annotated[MassFractionsSpec, Tag("mass_fractions")], Annotated[SieveSpec, Tag("sieve")]],
                       Discriminator(_radius_kind, custom_error_type="radius_kind",
                                     custom_error_message="must be a number or a distribution {distribution: uniform "
                                                          "| normal | discrete | mass_fractions | sieve, ...}")]


class InsertSpec(_Strict):
    """Spheres inserted in a region: ``count`` of them, or ``mass`` (kg), or a ``fraction`` of the
    region's volume."""
    insert: RegionSpec
    count: Optional[Whole] = None
    mass: Optional[Number] = None
    fraction: Optional[Number] = None
    radius: RadiusSpec
    material: str
    seed: Whole = 0
    velocity: Optional[Vector] = None


class ListSpec(_Strict):
    positions: list[Vector]
    radius: Union[Number, list[Number]]
    material: str
    velocity: Optional[Union[Vector, list[Vector]]] = None
    angular_velocity: Optional[Union[Vector, list[Vector]]] = None
    allow_overlap: bool = False
    fixed: bool = False


class RoughBaseShape(_Strict):
    radius: Number
    extent: tuple[tuple[Number, Number], tuple[Number, Number]]
    spacing: Optional[Number] = None
    jitter: Optional[Number] = None
    seed: Whole = 0
    z: Number = 0.0


class RoughBaseSpec(_Strict):
    """Fixed spheres in a jittered hexagonal layer (``rd.rough_base``)."""
    rough_base: RoughBaseShape
    material: str


class ClumpShapeSpec(_Strict):
    """A clump template (``rd.Clump``): a named ``shape`` (dimer, trimer, tetrahedron, ring_prism,
    rod) with its members' ``radius``, their centres' ``distance`` (a rod's spacing; default 2 R,
    touching) and ``n`` (ring_prism, rod); or its ``spheres`` as rows x, y, z, r (m)."""
    shape: Optional[Literal["dimer", "trimer", "tetrahedron", "ring_prism", "rod"]] = None
    radius: Optional[Number] = None
    distance: Optional[Number] = None
    n: Optional[Whole] = None
    spheres: Optional[list[tuple[Number, Number, Number, Number]]] = None
    connected: bool = True


class ClumpSpec(_Strict):
    """Clumps of one template: inserted in a region (``insert`` with ``count``, ``mass`` or
    ``fraction``, at random orientations from ``seed``) or placed at ``positions`` (their centres of
    mass) turned by ``orientations`` (unit quaternions w, x, y, z; default the template's frame)."""
    clump: ClumpShapeSpec
    material: str
    insert: Optional[RegionSpec] = None
    count: Optional[Whole] = None
    mass: Optional[Number] = None
    fraction: Optional[Number] = None
    seed: Whole = 0
    positions: Optional[list[Vector]] = None
    orientations: Optional[list[tuple[Number, Number, Number, Number]]] = None
    velocity: Optional[Vector] = None
    angular_velocity: Optional[Vector] = None
    allow_overlap: bool = False
    fixed: bool = False


def _particle_kind(value):
    """A particle block with a ``clump`` key adds clumps, one with ``insert`` fills a region, one
    with ``rough_base`` lays a fixed base; any other lists its spheres."""
    if isinstance(value, dict):
        return ("clump" if "clump" in value else "insert" if "insert" in value else
                "rough_base" if "rough_base" in value else "list")
    return {InsertSpec: "insert", RoughBaseSpec: "rough_base", ListSpec: "list", ClumpSpec: "clump"}.get(type(value))


ParticleSpec = Annotated[Union[Annotated[InsertSpec, Tag("insert")], Annotated[RoughBaseSpec, Tag("rough_base")],
                               Annotated[ListSpec, Tag("list")], Annotated[ClumpSpec, Tag("clump")]],
                         Discriminator(_particle_kind)]


def _clump(spec: ClumpShapeSpec):
    """The ``rd.Clump`` of a case file's clump block."""
    from rollingdem.scene.clumps import Clump

    if (spec.shape is None) == (spec.spheres is None):
        raise ParameterError("clump: give exactly one of shape (dimer, trimer, tetrahedron, ring_prism, rod) and "
                             "spheres (rows x, y, z, r)")
    if spec.spheres is not None:
        rows = np.array(spec.spheres, dtype=float).reshape(-1, 4)
        try:
            return Clump(rows[:, :3], rows[:, 3], connected=spec.connected)
        except ParameterError as err:
            raise ParameterError(str(err).replace("pass connected=False", "set clump.connected: false")) from None
    if spec.radius is None:
        raise ParameterError(f"clump.radius = None is not allowed: shape {spec.shape!r} needs its members' radius (m)")
    if spec.shape in ("ring_prism", "rod"):
        if spec.n is None:
            raise ParameterError(f"clump.n = None is not allowed: shape {spec.shape!r} needs its number of spheres")
        return getattr(Clump, spec.shape)(spec.n, spec.radius, spec.distance)
    if spec.n is not None:
        raise ParameterError(f"clump.n = {spec.n} is not allowed: shape {spec.shape!r} has a fixed number of spheres")
    return getattr(Clump, spec.shape)(spec.radius, spec.distance)


def _add_clumps(sim, p: ClumpSpec, base: Path) -> None:
    """A case file's clump block into ``sim``."""
    clump = _clump(p.clump)
    if (p.insert is None) == (p.positions is None):
        raise ParameterError("give exactly one of insert (a region, with count, mass or fraction) and positions")
    if p.insert is not None:
        if p.orientations is not None or p.angular_velocity is not None or p.fixed or p.allow_overlap:
            raise ParameterError("orientations, angular_velocity, fixed and allow_overlap go with positions: inserted "
                                 "clumps are turned at random, at rest or at the block's velocity")
        sim.insert(_region(p.insert, base, sim), p.count, None, p.material, seed=p.seed, velocity=p.velocity,
                   mass=p.mass, fraction=p.fraction, clump=clump)
        return
    if p.count is not None or p.mass is not None or p.fraction is not None:
        raise ParameterError("count, mass and fraction go with insert: with positions each position is a clump")
    sim.add_clumps(clump, p.positions, p.material, orientations=p.orientations, velocity=p.velocity,
                   angular_velocity=p.angular_velocity, fixed=p.fixed, allow_overlap=p.allow_overlap)


class OutletSpec(_Strict):
    """``Simulation.add_outlet``; with ``refill`` each sphere taken out is put back there."""
    region: RegionSpec
    name: Optional[str] = None
    interval: Optional[Number] = None
    refill: Optional[RegionSpec] = None
    seed: Whole = 0


class DiskFaceSpec(_Strict):
    """``rollingdem.Disk``: a face of ``radius`` about ``center``, particles going along ``normal``."""
    type: Literal["disk"]
    center: Vector
    normal: Vector
    radius: Number


class RectangleFaceSpec(_Strict):
    """``rollingdem.Rectangle``: a face of ``size`` (width, height) about ``center``, its width along ``axis``."""
    type: Literal["rectangle"]
    center: Vector
    normal: Vector
    size: tuple[Number, Number]
    axis: Optional[Vector] = None


class MeshFaceSpec(_SensorMeshSpec):
    """``rollingdem.MeshFace``: a flat mesh (given as a mesh wall is, or the ``wall`` named so) as a face."""
    type: Literal["mesh_face"]
    wall: Optional[str] = None
    normal: Optional[Vector] = None


class InflowSpec(_Strict):
    """Particles inserted during the run into ``region``, or through a face (``disk``, ``rectangle``,
    ``mesh_face``) at ``velocity``."""
    region: Annotated[Union[BoxRegionSpec, CylinderRegionSpec, MeshRegionSpec, DiskFaceSpec, RectangleFaceSpec,
                            MeshFaceSpec], Field(discriminator="type")]
    radius: RadiusSpec
    material: str
    rate: Optional[Number] = None
    mass_rate: Optional[Number] = None
    velocity: Optional[Vector] = None
    seed: Whole = 0
    name: Optional[str] = None
    interval: Optional[Number] = None
    start: Optional[Number] = None


class StageWindowSpec(_Strict):
    """A measurement window that starts ``start`` seconds after the start of stage ``stage`` and
    lasts ``duration`` seconds (default: to that stage's end): it moves with a stage before it that
    ends on a condition."""
    stage: str
    start: Number = 0.0
    duration: Optional[Number] = None


class _MeasurementBase(_Strict):
    name: str
    interval: Optional[Number] = None  # the kind's own (INTERVAL)
    # [t0, t1] (s) from the run's start, or a window from a stage's start
    window: Optional[Union[tuple[Number, Number], StageWindowSpec]] = None


class MassFlowSpec(_MeasurementBase):
    """``rollingdem.MassFlow``: through the plane at ``point`` along ``normal`` (a disk with ``radius``)."""
    type: Literal["mass_flow"]
    point: Vector
    normal: Vector
    radius: Optional[Number] = None


class ProbeSpec(_MeasurementBase):
    """``rollingdem.Probe``: the particles in ``region`` (a box, a cylinder or a closed mesh)."""
    type: Literal["probe"]
    region: Annotated[Union[BoxRegionSpec, CylinderRegionSpec, MeshRegionSpec], Field(discriminator="type")]


class OutletMeasurementSpec(_MeasurementBase):
    """``rollingdem.OutletTotals``: what the outlet named ``outlet`` took out."""
    type: Literal["outlet"]
    outlet: str


class WallMeasurementSpec(_MeasurementBase):
    """``rollingdem.WallLoad``: force, torque and power of the wall named ``wall``."""
    type: Literal["wall"]
    wall: str


class ReposeMeasurementSpec(_MeasurementBase):
    """``rollingdem.PileAngle``: the pile's angle of repose (docs/analysis.md)."""
    type: Literal["repose_angle"]
    floor: Optional[Number] = None
    n_slices: Whole = 8
    exclude_apex: Number = 0.15
    exclude_toe: Number = 0.15


class DrumMeasurementSpec(_MeasurementBase):
    """``rollingdem.DrumAngle``: the bed's angle about the drum's axis, in the window ``extent``."""
    type: Literal["drum_angle"]
    center: Vector
    axis: Vector
    extent: Optional[tuple[Number, Number]] = None


class DrumFlowSpec(_MeasurementBase):
    """``rollingdem.DrumFlow``: the flowing layer's depth and the bed's turn with the drum, whose
    ``radius`` (m) and turning ``wall`` are given."""
    type: Literal["drum_flow"]
    center: Vector
    axis: Vector
    radius: Number
    wall: str
    extent: Optional[tuple[Number, Number]] = None


class MeshFlowSpec(_MeasurementBase, _SensorMeshSpec):
    """``rollingdem.MeshFlow``: through a triangle mesh surface, counted along its triangles' normals."""
    type: Literal["mesh_flow"]


class ProfileSpec(_MeasurementBase):
    """``rollingdem.SurfaceProfile``: the free surface against the measured profile in ``file`` (a CSV
    of two columns, m, named from the case file): a heap's (r, h) or a drum's (x, y)."""
    type: Literal["profile"]
    file: str
    shape: Literal["heap", "drum"] = "heap"
    center: Optional[list[Number]] = None
    axis: Vector = (0.0, 0.0, 1.0)
    floor: Optional[Number] = None


MeasurementSpec = Annotated[Union[MassFlowSpec, ProbeSpec, OutletMeasurementSpec, WallMeasurementSpec,
                                  ReposeMeasurementSpec, DrumMeasurementSpec, DrumFlowSpec, ProfileSpec,
                                  MeshFlowSpec],
                            Field(discriminator="type")]


class PeriodicSpec(_Strict):
    x: Optional[tuple[Number, Number]] = None
    y: Optional[tuple[Number, Number]] = None
    z: Optional[tuple[Number, Number]] = None


class SetVelocitySpec(_Strict):
    particles: Union[Literal["all"], list[Whole]] = "all"
    velocity: Optional[Vector] = None
    angular_velocity: Optional[Vector] = None


class WallMotionSpec(MotionSpec):
    """A wall's motion from this stage on (``velocity``, ``rotate``: for a plane or cylinder the
    rotation moves its surface, about its own point)."""
    wall: str


class _BondBase(_Strict):
    """Bonds made when the stage starts (``Simulation.add_bonds``, docs/models.md §1.7): between the
    ``pairs`` given or every pair at most ``gap`` (m) apart, with ``rollingdem.ParallelBond``'s
    parameters (the other keys)."""
    gap: Optional[Number] = None
    pairs: Optional[list[tuple[Whole, Whole]]] = None

    def parallel_bond(self):
        from rollingdem.scene.bonds import ParallelBond

        return ParallelBond(**self.model_dump(exclude={"gap", "pairs"}))


def _bond_spec():
    """The schema of a stage's bonds: gap or pairs, and ``ParallelBond``'s parameters as its
    constructor declares them (one list of names and defaults)."""
    import inspect

    from rollingdem.scene.bonds import ParallelBond

    kinds = {"float": Number, "str": str}
    spec = {name: (kinds[p.annotation], ... if p.default is p.empty else p.default)
            for name, p in inspect.signature(ParallelBond).parameters.items()}
    return create_model("BondSpec", __base__=_BondBase, **spec)


BondSpec = _bond_spec()


class SettledSpec(_Strict):
    """``rollingdem.Settled``: translational kinetic energy per free particle below ``kinetic_energy``
    (J; default 1e-6 m g d) for ``hold`` seconds (``rotation``: count the rotational energy too)."""
    kinetic_energy: Optional[Number] = None
    hold: Number = 0.05
    rotation: bool = False
    every: Number = 1e-3


class UntilSpec(_Strict):
    """What ends a stage early: ``settled``, ``empty``, or a ``measurement``'s quantity (``name.quantity``)
    ``above`` or ``below`` a value, for ``hold`` seconds (0: at one check), or its mean over the
    stage's samples ``known_within`` +- a value at 95 % (over ``min_samples`` samples at least)."""
    settled: Optional[SettledSpec] = None
    empty: Optional[bool] = None
    measurement: Optional[str] = None
    above: Optional[Number] = None
    below: Optional[Number] = None
    known_within: Optional[Number] = None
    min_samples: int = 20
    hold: Number = 0.0
    every: Number = 1e-3


def _until(value):
    """``until: settled`` / ``until: empty`` as the mappings they stand for."""
    if value == "settled":
        return {"settled": {}}
    if value == "empty":
        return {"empty": True}
    return value


class StageSpec(_Strict):
    name: str = "run"
    duration: Optional[Number] = None
    until: Optional[Annotated[UntilSpec, BeforeValidator(_until, json_schema_input_type=Union[
        Literal["settled", "empty"], UntilSpec])]] = None
    max_duration: Optional[Number] = None
    gravity: Optional[Vector] = None
    remove_walls: list[str] = []
    wall_motion: list[WallMotionSpec] = []
    set_velocity: Optional[SetVelocitySpec] = None
    bonds: Optional[BondSpec] = None


class SeriesSpec(_Strict):
    interval: Number = 1e-3
    particles: list[Whole] = []


class IntervalSpec(_Strict):
    interval: Number


class ReposeOutputSpec(_Strict):
    """Measure the pile at the end (``rollingdem.analysis.repose.repose_angle``) on a floor at ``floor``
    (m; default the top of the highest fixed sphere, else 0), with the estimator's options."""
    floor: Optional[Number] = None
    n_slices: Whole = 8
    exclude_apex: Number = 0.15
    exclude_toe: Number = 0.15


class ReportSpec(_Strict):
    """``report.html``: pictures of the scene at each stage's start and end and at ``pictures``
    (times, s)."""
    pictures: list[Number] = []


class OutputSpec(_Strict):
    directory: Optional[str] = None
    report: Optional[ReportSpec] = ReportSpec()
    repose_angle: Optional[ReposeOutputSpec] = None
    time_series: Optional[SeriesSpec] = SeriesSpec()
    snapshots: Optional[IntervalSpec] = None
    checkpoint: Optional[IntervalSpec] = None
    plot: bool = True


class CaseSpec(_Strict):
    name: str = "case"
    dt: Optional[Number] = None
    skin: Optional[Number] = None
    check_timestep: bool = True
    backend: Optional[str] = None
    gravity: Vector = (0.0, 0.0, -9.81)
    materials: list[MaterialSpec] = Field(min_length=1)
    pairs: list[PairSpec] = []
    contact: ContactSpec = ContactSpec()
    periodic: Optional[PeriodicSpec] = None
    walls: list[WallSpec] = []
    particles: list[ParticleSpec] = []  # none: an inflow fills the scene
    outlets: list[OutletSpec] = []
    inflows: list[InflowSpec] = []
    measurements: list[MeasurementSpec] = []
    stages: list[StageSpec] = Field(min_length=1)
    output: OutputSpec = OutputSpec()
    _base: Path = PrivateAttr(default=Path("."))  # the case file's folder (load_case): mesh files are named from it

    @property
    def base_directory(self) -> Path:
        return self._base


_KIND_OF_INPUT = {
    "float_type": "a number", "float_parsing": "a number", "finite_number": "a finite number",
    "int_type": "a whole number", "int_parsing": "a whole number", "int_from_float": "a whole number",
    "bool_type": "true or false", "bool_parsing": "true or false", "string_type": "a string",
    "list_type": "a list", "tuple_type": "a list", "dict_type": "a mapping of keys",
    "model_type": "a mapping of keys", "model_attributes_type": "a mapping of keys",
}
_NOT_A_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_TYPE_NAMES = {"float", "int", "str", "bool", "dict", "list", "tuple", "number"}


def _key_path(loc) -> tuple:
    """The case-file keys of a pydantic error location (union members and tags dropped)."""
    keep = []
    for p in loc:
        if isinstance(p, int):
            keep.append(p)
        elif (_NOT_A_KEY.match(p) and p not in _TYPE_NAMES and not p.endswith("Spec")
              and not (keep and p in ("insert", "list") and isinstance(keep[-1], int) and keep[:1] == ["particles"]
                       and len(keep) == 2)):
            keep.append(p)
    return tuple(keep)


def _spec_at(path, data=None) -> Optional[type]:
    """The model class of the mapping at ``path`` (None where it cannot be told), to list its keys."""
    from typing import get_args, get_origin

    def model_of(tp, key_hint=None):
        origin = get_origin(tp)
        if isinstance(tp, type) and issubclass(tp, BaseModel):
            return tp
        if origin is Annotated:
            return model_of(get_args(tp)[0], key_hint)
        if origin in (Union, list, tuple, Optional) or (origin is not None and str(origin).endswith("UnionType")):
            found = [m for m in (model_of(a, key_hint) for a in get_args(tp)) if m is not None]
            if key_hint is not None:
                found = [m for m in found if key_hint(m)] or found
            return found[0] if len(found) == 1 else None
        return None

    def tagged(value):
        """A hint that keeps the union members whose tag (``type``, ``distribution``) is the value's."""
        if not isinstance(value, dict):
            return None

        def hint(m):
            particle = {InsertSpec: "insert", RoughBaseSpec: "rough_base", ListSpec: "list", ClumpSpec: "clump"}.get(m)
            if particle is not None:
                return particle == _particle_kind(value)
            for key in ("type", "distribution"):
                field = m.model_fields.get(key)
                if key in value and field is not None and value[key] not in get_args(field.annotation):
                    return False
            return True
        return hint

    spec, node = CaseSpec, data
    for k, part in enumerate(path):
        if isinstance(part, int):
            continue
        field = spec.model_fields.get(part) if spec is not None else None
        if field is None:
            return None
        node = _value_at(node, (part,) + tuple(p for p in path[k + 1:k + 2] if isinstance(p, int)))
        spec = model_of(field.annotation, tagged(node))
    return spec


def _data_path(loc, data, missing: bool) -> tuple:
    """The keys of a pydantic error location as the file has them: each step kept where the file has
    that key (or index) there, union members and tags (``cylinder``, ``float``, ...) left out; a
    missing key is kept at the end."""
    keep, tag_seen = [], False
    for k, part in enumerate(loc):
        last = k == len(loc) - 1
        if (isinstance(data, dict) and not last and not tag_seen
                and part in (data.get("type"), data.get("distribution"), _particle_kind(data))):
            tag_seen = True  # the union's tag for this mapping (once), not one of its keys
            continue
        if isinstance(data, list) and isinstance(part, int) and 0 <= part < len(data):
            keep.append(part)
            data, tag_seen = data[part], False
        elif isinstance(data, dict) and part in data:
            keep.append(part)
            data, tag_seen = data[part], False
        elif last and missing and (isinstance(part, int) or _NOT_A_KEY.match(part)):
            keep.append(part)
    return tuple(keep)


def _describe_error(e: dict, data) -> tuple[tuple, str]:
    """(key path, what is wrong) of one pydantic error, in the words of the house style."""
    path = (_data_path(e["loc"], data, e["type"] == "missing") if isinstance(data, dict)
            else _key_path(e["loc"]))
    kind = e["type"]
    ctx = e.get("ctx") or {}
    if kind == "extra_forbidden":
        import difflib

        parent = _spec_at(path[:-1], data)
        if parent is None:
            return path, "not a known key (misspelled?)"
        near = difflib.get_close_matches(str(path[-1]), list(parent.model_fields), n=1, cutoff=0.75) if path else []
        allowed = f"allowed are {', '.join(parent.model_fields)}"
        return path, (f"not a known key: did you mean {near[0]!r}? ({allowed})" if near
                      else f"not a known key (misspelled?): {allowed}")
    if kind == "missing":
        return path, "missing (required)"
    if kind in _KIND_OF_INPUT:
        return path, f"must be {_KIND_OF_INPUT[kind]}"
    if kind == "literal_error":
        return path, f"must be {ctx.get('expected')}"
    if kind == "union_tag_invalid":
        key = str(ctx.get("discriminator", "")).strip("'")
        return path + ((key,) if key and key != "<function>" else ()), f"must be one of {ctx.get('expected_tags')}"
    if kind == "union_tag_not_found":
        key = str(ctx.get("discriminator", "")).strip("'")
        return path + (key,), "missing (required)"
    if kind in ("too_short", "too_long"):
        if ctx.get("field_type") == "Tuple":
            return path, f"must be {ctx.get('max_length', ctx.get('min_length'))} numbers"
        return path, (f"must have at least {ctx.get('min_length')} entries" if kind == "too_short"
                      else f"must have at most {ctx.get('max_length')} entries")
    if kind == "radius_kind":
        return path, e["msg"]
    return path, e["msg"].removeprefix("Value error, ")


def _value_at(data, path):
    for part in path:
        try:
            data = data[part]
        except (KeyError, IndexError, TypeError):
            return None
    return data


def _format_validation_error(err: ValidationError, source: str, data=None) -> str:
    """One line per key at fault (branches of a union that all failed are one line); a single
    fault is one line with the file's name."""
    problems: dict[tuple, list[str]] = {}
    kinds: dict[tuple, str] = {}
    for e in err.errors():
        path, what = _describe_error(e, data)
        kind = e["type"]
        if kind == "missing" and len(e["loc"]) > 1 and isinstance(e["loc"][-1], int):
            path, what, kind = path[:-1], "must be three numbers", "too_short"  # a vector with too few numbers
        kinds.setdefault(path, kind)
        if what not in problems.setdefault(path, []):
            problems[path].append(what)
    # a misspelled key is one problem, not two: the line of the unknown key names the one the file lacks
    for path in [p for p, k in kinds.items() if k == "extra_forbidden" and p]:
        meant = re.search(r"did you mean '([^']+)'", problems[path][0])
        if meant and path[:-1] + (meant.group(1),) in problems and kinds[path[:-1] + (meant.group(1),)] == "missing":
            del problems[path[:-1] + (meant.group(1),)]
    lines = []
    for path, whats in problems.items():
        key = ".".join(str(p) for p in path) or "(top level)"
        if kinds[path] in ("missing", "extra_forbidden", "union_tag_not_found"):
            lines.append(f"key {key!r}: {whats[0]}")
            continue
        shown = json.dumps(_value_at(data, path), default=str)
        if len(shown) > 80:
            shown = shown[:77] + "..."
        musts = [w.removeprefix("must be ") for w in whats if w.startswith("must be ")]
        what = ("must be " + " or ".join(musts)) if len(musts) == len(whats) else "; ".join(whats)
        lines.append(f"key {key!r} = {shown} is not allowed: {what}")
    if len(lines) == 1:
        return f"case file {source}: {lines[0]}"
    return "\n".join([f"case file {source} is not valid ({len(lines)} problems):"] + [f"  {x}" for x in lines])


def load_case(path_or_dict) -> CaseSpec:
    """Read and validate a case file (YAML, or TOML by extension) or a mapping."""
    data, source = read_mapping(path_or_dict)
    try:
        case = CaseSpec.model_validate(data)
    except ValidationError as err:
        raise ParameterError(_format_validation_error(err, source, data)) from None
    if isinstance(path_or_dict, (str, Path)):
        case._base = Path(path_or_dict).parent
    return case


def _radius(spec):
    from rollingdem.scene.insertion import Discrete, MassFractions, Normal, SieveCurve, Uniform

    if isinstance(spec, (int, float)):
        return float(spec)
    if isinstance(spec, UniformSpec):
        return Uniform(spec.low, spec.high)
    if isinstance(spec, NormalSpec):
        return Normal(spec.mean, spec.std, spec.low, spec.high)
    if isinstance(spec, MassFractionsSpec):
        return MassFractions(spec.radii, spec.fractions)
    if isinstance(spec, SieveSpec):
        return SieveCurve(spec.diameters, spec.passing)
    return Discrete(spec.values, spec.weights)


#: How a case-file user turns a check off (the refusals name these keys, not Python arguments).
CASE_HINTS = {"check_timestep": "set check_timestep: false in the case file",
              "allow_overlap": "set allow_overlap: true in the particle block"}


def take_materials(sim, case: CaseSpec) -> None:
    """The case's materials and pairs put in force on ``sim``, whose materials have their names
    (a run going on from another case's state: ``Simulation.set_material``)."""
    from rollingdem.scene.materials import Material

    for k, m in enumerate(case.materials):
        with _InCase(f"materials.{k}"):
            sim.set_material(Material(**m.model_dump()))
    for k, p in enumerate(case.pairs):
        with _InCase(f"pairs.{k}"):
            sim.set_pair(p.materials[0], p.materials[1],
                         **{c: v for c, v in p.model_dump(exclude={"materials"}).items() if v is not None})


def build_simulation(case: CaseSpec):
    """The Simulation a case describes (materials, walls, particles), before any stage runs."""
    from rollingdem.physics.contact.model import ContactModel
    from rollingdem.scene.materials import Material
    from rollingdem.scene.simulation import Simulation
    from rollingdem.scene.walls import Cylinder, Plane
    from rollingdem.scene.insertion import rough_base
    from rollingdem.errors import check_positive

    def where(key):
        return _InCase(key)

    if not case.particles and not case.inflows:
        raise ParameterError("particles = [] is not allowed without an inflow: give a particle block, or an inflow "
                             "that fills the scene")
    with where("contact"):
        contact = ContactModel(**case.contact.model_dump())
    periodic = {k: v for k, v in case.periodic.model_dump().items() if v is not None} if case.periodic else None
    for key in ("dt", "skin"):  # top-level keys: refused in their own name, before the periodic block's checks
        if getattr(case, key) is not None:
            check_positive(key, getattr(case, key), "s" if key == "dt" else "m")
    with where("periodic"):
        sim = Simulation(contact=contact, gravity=case.gravity, dt=case.dt, skin=case.skin,
                         check_timestep=case.check_timestep, periodic=periodic)
    if case.backend is not None:
        with where("backend"):
            sim.backend = case.backend
    sim.hints.update(CASE_HINTS)
    for k, m in enumerate(case.materials):
        with where(f"materials.{k}"):
            sim.add_material(Material(**m.model_dump()))
    for k, p in enumerate(case.pairs):
        with where(f"pairs.{k}"):
            coeffs = {c: v for c, v in p.model_dump(exclude={"materials"}).items() if v is not None}
            sim.set_pair(p.materials[0], p.materials[1], **coeffs)
    names = [w.name for w in case.walls if w.name]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ParameterError(f"walls: name = {twice[0]!r} is not allowed: it names two walls; wall names must differ")
    for k, w in enumerate(case.walls):
        with where(f"walls.{k}"):
            if w.type == "mesh":
                sim.add_wall(_mesh_wall(w, case.base_directory))
                continue
            d = w.model_dump(exclude={"type", "oscillate", "table", "servo"})
            d["motion"] = _program(w, case.base_directory)
            sim.add_wall(Plane(**d) if w.type == "plane" else Cylinder(**d))
    for k, p in enumerate(case.particles):
        with where(f"particles.{k}"):
            if isinstance(p, InsertSpec):
                sim.insert(_region(p.insert, case.base_directory, sim), p.count, _radius(p.radius), p.material,
                           seed=p.seed, velocity=p.velocity, mass=p.mass, fraction=p.fraction)
            elif isinstance(p, ClumpSpec):
                _add_clumps(sim, p, case.base_directory)
            elif isinstance(p, RoughBaseSpec):
                shape, alpha = p.rough_base.model_dump(), sim.materials[p.material].coarse_graining
                for key in ("radius", "spacing", "jitter"):  # a base of parcels: its lengths the parcels'
                    shape[key] = None if shape[key] is None else alpha * shape[key]
                sim.add_particles(rough_base(**shape), p.rough_base.radius, p.material, fixed=True)
            else:
                sim.add_particles(p.positions, p.radius, p.material, velocity=p.velocity,
                                  angular_velocity=p.angular_velocity, allow_overlap=p.allow_overlap, fixed=p.fixed)
    from rollingdem.physics.records import WALL_MESH
    from rollingdem.scene.wall_set import check_mesh_size, check_openings

    for k, wall in enumerate(sim.walls):  # against the particles now in place: a unit mistake
        if wall.kind == WALL_MESH:
            with where(f"walls.{k}"):
                check_mesh_size(wall, sim.radii)
    for k, o in enumerate(case.outlets):
        with where(f"outlets.{k}"):
            refill = None if o.refill is None else _region(o.refill, case.base_directory, sim)
            sim.add_outlet(_region(o.region, case.base_directory, sim), name=o.name, interval=o.interval,
                           refill=refill, seed=o.seed)
    for k, i in enumerate(case.inflows):
        with where(f"inflows.{k}"):
            sim.add_inflow(_region(i.region, case.base_directory, sim), _radius(i.radius), i.material, rate=i.rate, mass_rate=i.mass_rate,
                           velocity=i.velocity, seed=i.seed, name=i.name, interval=i.interval, start=i.start)
    for k, wall in enumerate(sim.walls):  # against the parcels in place and the inflows' parcels
        if wall.kind == WALL_MESH:
            with where(f"walls.{k}"):
                check_openings(wall, sim)
    return sim


def _region(r, base: Path | None = None, sim=None):
    """The region of a case block; a mesh region's mesh given as a mesh wall is, or a wall's of ``sim``."""
    from rollingdem.scene.insertion import BoxRegion, CylinderRegion

    if r.type == "disk":
        from rollingdem.scene.insertion import Disk

        return Disk(r.center, r.normal, r.radius)
    if r.type == "rectangle":
        from rollingdem.scene.insertion import Rectangle

        return Rectangle(r.center, r.normal, r.size, r.axis)
    if r.type in ("mesh", "mesh_face"):
        from rollingdem.scene.insertion import MeshFace
        from rollingdem.scene.mesh import MeshRegion

        made = MeshRegion if r.type == "mesh" else (lambda mesh: MeshFace(mesh, r.normal))
        if r.wall is not None:
            if r.file is not None or r.shape is not None:
                raise ParameterError(f"wall = {r.wall!r} is not allowed with a file or shape: the region is that "
                                     "wall's mesh")
            walls = [w for w in (sim.walls if sim is not None else []) if w.name == r.wall and hasattr(w, "mesh")]
            if not walls:
                names = [w.name for w in (sim.walls if sim is not None else []) if w.name and hasattr(w, "mesh")]
                raise ParameterError(f"wall = {r.wall!r} is not allowed: no mesh wall has that name; mesh walls are "
                                     f"{', '.join(map(repr, names)) or 'none'}")
            return made(walls[0])
        return made(_sensor_mesh(r, base))
    return BoxRegion(r.lo, r.hi) if r.type == "box" else CylinderRegion(r.radius, r.z_min, r.z_max, center=r.center)


def _sensor_mesh(spec, base: Path):
    """The TriangleMesh of a sensor's mesh block (a mesh-flow surface, a probe's mesh region)."""
    surface = MeshSpec(type="mesh", material="(sensor)", file=spec.file, scale=spec.scale, shape=spec.shape,
                       size=spec.size, place=spec.place)
    return _mesh_wall(surface, base).mesh


def _program(spec, base: Path):
    """The motion program (``rollingdem.scene.motion``) of a block's ``oscillate``, ``table`` or
    ``servo`` key, or None; angles in degrees."""
    from rollingdem.errors import check_finite
    from rollingdem.scene.motion import MotionTable, Oscillation, Servo

    given = [key for key in ("oscillate", "table", "servo") if getattr(spec, key) is not None]
    if len(given) > 1:
        raise ParameterError(f"{' and '.join(given)} are not allowed together: a wall follows one motion program")
    if not given:
        return None
    key = given[0]
    with _InCase(key):
        if key == "oscillate":
            o = spec.oscillate
            return Oscillation(o.frequency, o.amplitude, np.radians(check_finite("angle", o.angle)), o.axis,
                               np.radians(check_finite("phase", o.phase)))
        if key == "servo":
            return Servo(**spec.servo.model_dump())
        t = spec.table
        if t.file is not None:
            if t.times is not None or t.displacements is not None or t.angles is not None:
                raise ParameterError(f"file = {t.file!r} is not allowed with times, displacements or angles: the "
                                     "file holds them")
            times, displacements, angles = _table_file(Path(t.file) if Path(t.file).is_absolute() else base / t.file)
        else:
            times, displacements, angles = t.times, t.displacements, t.angles
            if times is None:
                raise ParameterError("times = None is not allowed: give times (s) with displacements and/or angles, "
                                     "or a CSV file")
        angles = None if angles is None else np.radians(np.asarray(angles, dtype=float))
        return MotionTable(times, displacements, angles, t.axis, t.repeat)


def _table_file(path: Path) -> tuple:
    """times, displacements (or None) and angles (degrees, or None) of a motion table's CSV file."""
    import pandas as pd

    try:
        frame = pd.read_csv(path, skipinitialspace=True)
    except FileNotFoundError:
        raise ParameterError(f"file = {str(path)!r} is not allowed: no such file") from None
    except Exception as err:  # noqa: BLE001 - pandas raises many kinds for a file it cannot parse
        raise ParameterError(f"file = {str(path)!r} is not allowed: not a CSV table ({err})") from None
    columns = [str(c).strip() for c in frame.columns]
    unknown = [c for c in columns if c not in ("t", "dx", "dy", "dz", "angle")]
    if unknown or "t" not in columns:
        raise ParameterError(f"file = {str(path)!r} is not allowed: its header names {columns}; allowed columns are "
                             "t (required), dx, dy, dz (m) and angle (degrees)")
    frame.columns = columns
    values = frame.apply(pd.to_numeric, errors="coerce")
    if values.isna().any().any():
        row = int(values.isna().any(axis=1).to_numpy().argmax())
        raise ParameterError(f"file = {str(path)!r} is not allowed: row {row + 2} holds a value that is no number")
    moves = any(c in columns for c in ("dx", "dy", "dz"))
    displacements = (np.column_stack([values[c].to_numpy() if c in columns else np.zeros(len(values))
                                      for c in ("dx", "dy", "dz")]) if moves else None)
    return values["t"].to_numpy(), displacements, values["angle"].to_numpy() if "angle" in columns else None


def _motion(spec, mesh: bool = False, base: Path = Path(".")) -> dict:
    """Keyword arguments of a wall's motion (velocity, angular_velocity, point, motion) from a
    MotionSpec; a ``mesh`` turns about the origin unless its point is given, a plane or cylinder
    about its own."""
    from rollingdem.errors import check_finite, check_vector

    if spec is None:
        return {}
    out = {"velocity": spec.velocity, "motion": _program(spec, base)}
    if spec.rotate is not None:
        r = spec.rotate
        if (r.angular_velocity is None) == (r.rpm is None):
            raise ParameterError("motion rotate: give exactly one of angular_velocity (rad/s) and rpm (revolutions "
                                 "per minute)" if r.rpm is not None else
                                 "motion rotate: angular_velocity missing: give the turning rate (rad/s) or rpm")
        rate = (check_finite("motion rotate angular_velocity", r.angular_velocity) if r.rpm is None
                else check_finite("motion rotate rpm", r.rpm) * 2.0 * np.pi / 60.0)
        axis = np.array(check_vector("motion rotate axis", r.axis, unit=True))
        out["angular_velocity"] = tuple(rate * axis)
        out["point"] = r.point if r.point is not None or not mesh else (0.0, 0.0, 0.0)
    return out


def _mesh_wall(w: MeshSpec, base: Path):
    """The MeshWall of a case's mesh block."""
    from rollingdem.errors import check_finite, check_vector
    from rollingdem.scene.mesh import MeshWall

    if (w.file is None) == (w.shape is None):
        raise ParameterError(f"file = {w.file!r}, shape = {w.shape!r} is not allowed: give exactly one of file "
                             "(an STL or OBJ file) and shape (drum, silo, hopper, disk, box, chute)")
    if w.file is not None:
        path = Path(w.file) if Path(w.file).is_absolute() else base / w.file
        wall = MeshWall.from_file(path, material=w.material, scale=w.scale, name=w.name, weld=w.weld)
    else:
        wall = MeshWall.shape(w.shape, material=w.material, name=w.name, **w.size)
    if w.place is not None:
        from scipy.spatial.transform import Rotation

        matrix, about = np.eye(3), np.zeros(3)
        if w.place.rotate is not None:
            axis = np.array(check_vector("place rotate axis", w.place.rotate.axis, unit=True))
            angle = check_finite("place rotate angle", w.place.rotate.angle if w.place.rotate.angle is not None
                                 else float("nan"))
            matrix = Rotation.from_rotvec(np.radians(angle) * axis).as_matrix()
            about = np.array(check_vector("place rotate point", w.place.rotate.point or (0.0, 0.0, 0.0)))
        shift = about - matrix @ about + np.array(check_vector("place translate", w.place.translate))
        wall = MeshWall(wall.mesh.moved(matrix, shift), material=w.material, name=w.name)
    motion = _motion(w.motion, mesh=True, base=base)
    if motion:
        wall = MeshWall(wall.mesh, material=w.material, name=w.name, **motion)
    wall.check_size = w.check_size
    return wall


class _InCase:
    """Prefix a ParameterError raised while a case block is built with the block's key."""

    def __init__(self, key: str):
        self.key = key

    def __enter__(self):
        return self

    def __exit__(self, kind, err, tb):
        if kind is not None and issubclass(kind, ParameterError):
            raise ParameterError(f"{self.key}: {err}") from None
        return False


def check_case(case: CaseSpec, sim=None):
    """Everything ``run_case`` would refuse before its first step, refused now, without running or
    writing anything: the scene (``build_simulation``), each stage (duration, gravity, walls it
    removes, velocities it sets), the outputs, and dt against the stable limit at the start of
    the first stage. ``rollingdem check`` and ``rollingdem run`` both call it; returns the
    simulation (``sim`` if given, else a new one)."""
    from rollingdem.errors import check_non_negative, check_positive, check_vector
    from rollingdem.scene.motion import check_program
    from rollingdem.scene.periodic import check_scene

    sim = build_simulation(case) if sim is None else sim
    with _InCase("periodic"):
        check_scene(sim)
    n = sim.n_particles
    in_place = {w.name for w in sim.walls if w.name}
    removed: set[str] = set()
    first_velocities = None
    measurements = build_measurements(case, sim)
    for k, stage in enumerate(case.stages):
        where = f"stage {stage.name!r}"
        stage_conditions(stage, measurements)
        check_non_negative(f"{where}: " + ("duration" if stage.until is None else "max_duration"),
                           stage_duration(stage), "s")
        if stage.gravity is not None:
            check_vector(f"{where}: gravity", stage.gravity)
        for name in stage.remove_walls:
            if name in removed:
                raise ParameterError(f"{where}: remove_walls = {name!r} is not allowed: an earlier stage removed "
                                     "that wall already")
            if name not in in_place:
                raise ParameterError(f"{where}: remove_walls = {name!r} is not allowed: no wall has that name; "
                                     f"wall names are {', '.join(map(repr, sorted(in_place))) or 'none'}")
            in_place.discard(name)
            removed.add(name)
        for m in stage.wall_motion:
            if m.wall not in in_place:
                raise ParameterError(f"{where}: wall_motion wall = {m.wall!r} is not allowed: no wall in place has "
                                     f"that name; wall names are {', '.join(map(repr, sorted(in_place))) or 'none'}")
            try:
                motion = _motion(m, base=case.base_directory)
                wall = next(w for w in sim.walls if w.name == m.wall)
                check_program(wall, motion["motion"], repr(m.wall), motion.get("angular_velocity", (0.0, 0.0, 0.0)))
            except ParameterError as err:
                raise ParameterError(f"{where}: wall_motion {m.wall!r}: {err}") from None
            mesh = next(w.type == "mesh" for w in case.walls if w.name == m.wall)
            if m.rotate is not None and m.rotate.point is not None and not mesh:
                raise ParameterError(f"{where}: wall_motion {m.wall!r}: rotate point = {list(m.rotate.point)} is not "
                                     "allowed: a plane or cylinder turns about its own point; only a mesh wall takes a "
                                     "rotation point")
        sv = stage.set_velocity
        if sv is not None:
            if sv.velocity is None and sv.angular_velocity is None:
                raise ParameterError(f"{where}: set_velocity = {sv.model_dump(exclude_none=True)} is not allowed: "
                                     "give velocity and/or angular_velocity")
            for key in ("velocity", "angular_velocity"):
                if getattr(sv, key) is not None:
                    check_vector(f"{where}: set_velocity {key}", getattr(sv, key))
            if sv.particles != "all":
                bad = [i for i in sv.particles if not 0 <= i < n]
                if bad:
                    raise ParameterError(f"{where}: set_velocity particles = {bad[0]} is not allowed: must be in "
                                         f"[0, {n - 1}] (the case has {n} particles)")
            if k == 0:
                first_velocities = sv
        if stage.bonds is not None:
            b = stage.bonds
            if (b.gap is None) == (b.pairs is None):
                raise ParameterError(f"{where}: bonds is not allowed without exactly one of gap (m) and pairs")
            try:
                b.parallel_bond()
            except ParameterError as err:
                raise ParameterError(f"{where}: bonds: {err}") from None
            for i, j in b.pairs or ():
                if not (0 <= i < n and 0 <= j < n) or i == j:
                    raise ParameterError(f"{where}: bonds pairs = [{i}, {j}] is not allowed: must be two different "
                                         f"particles in [0, {n - 1}]")
    check_windows(case)
    stage_time_steps(case, sim)  # a given dt against each stage's wall motion
    out = case.output
    for key in ("time_series", "snapshots", "checkpoint"):
        block = getattr(out, key)
        if block is not None:
            check_positive(f"output.{key}.interval", block.interval, "s")
    if out.time_series is not None:
        bad = [i for i in out.time_series.particles if not 0 <= i < n]
        if bad:
            raise ParameterError(f"output.time_series.particles = {bad[0]} is not allowed: must be in [0, {n - 1}] "
                                 f"(the case has {n} particles)")
    _check_first_time_step(sim, first_velocities)
    with _InCase("contact"):
        sim.time_step_policy.check_contact_reach()
    try:
        sim.boundary_set.check_room()
    except ParameterError as err:  # an inflow's region, or an outlet's refill region
        raise ParameterError(f"{'outlets' if str(err).startswith('outlet') else 'inflows'}: {err}") from None
    return sim


def build_measurements(case: CaseSpec, sim) -> dict:
    """The case's measurements by name (``rollingdem.io.measurements``), each checked against the
    scene (its wall or outlet named, its sensor inside the scene)."""
    from rollingdem.io import measurements as ms

    made = {}
    for k, m in enumerate(case.measurements):
        with _InCase(f"measurements.{k}"):
            if m.name in made:
                raise ParameterError(f"name = {m.name!r} is not allowed: it names two measurements; names must differ")
            # a window from a stage's start is set when that stage starts (stage_window)
            common = dict(name=m.name, interval=m.interval, window=None if isinstance(m.window, StageWindowSpec)
                          else m.window)
            if m.type == "mass_flow":
                made[m.name] = ms.MassFlow(point=m.point, normal=m.normal, radius=m.radius, **common)
            elif m.type == "probe":
                made[m.name] = ms.Probe(region=_region(m.region, case.base_directory, sim), **common)
            elif m.type == "outlet":
                made[m.name] = ms.OutletTotals(outlet=m.outlet, **common)
            elif m.type == "wall":
                made[m.name] = ms.WallLoad(wall=m.wall, **common)
            elif m.type == "repose_angle":
                made[m.name] = ms.PileAngle(floor=m.floor, n_slices=m.n_slices, exclude_apex=m.exclude_apex,
                                            exclude_toe=m.exclude_toe, **common)
            elif m.type == "mesh_flow":
                made[m.name] = ms.MeshFlow(mesh=_sensor_mesh(m, case.base_directory), **common)
            elif m.type == "drum_angle":
                made[m.name] = ms.DrumAngle(center=m.center, axis=m.axis, extent=m.extent, **common)
            elif m.type == "drum_flow":
                made[m.name] = ms.DrumFlow(center=m.center, axis=m.axis, radius=m.radius, wall=m.wall, extent=m.extent,
                                           **common)
            else:
                path = Path(m.file) if Path(m.file).is_absolute() else case.base_directory / m.file
                made[m.name] = ms.SurfaceProfile(points=ms.read_profile(path), shape=m.shape, center=m.center,
                                                 axis=m.axis, floor=m.floor, **common)
            made[m.name].check(sim)
    return made


def stage_duration(stage: StageSpec) -> float:
    """How long a stage runs at most: its ``duration``, or with ``until`` its ``max_duration``;
    refused when the pair does not fit."""
    where = f"stage {stage.name!r}"
    if stage.until is None:
        if stage.max_duration is not None:
            raise ParameterError(f"{where}: max_duration = {stage.max_duration:g} is not allowed without until: "
                                 "give duration (s), or until with max_duration")
        if stage.duration is None:
            raise ParameterError(f"{where}: key 'duration' is missing: a stage runs for duration (s), or until a "
                                 "condition with max_duration (s)")
        return stage.duration
    if stage.duration is not None:
        raise ParameterError(f"{where}: duration = {stage.duration:g} is not allowed with until: give max_duration "
                             "(s), the longest the stage may run")
    if stage.max_duration is None:
        raise ParameterError(f"{where}: until is not allowed without max_duration (s): a stage that waits for a "
                             "condition needs the longest it may run")
    return stage.max_duration


def stage_window(spec: StageWindowSpec, stage: StageSpec, start_time: float) -> tuple[float, float]:
    """The window (t0, t1) (s) of ``spec`` for ``stage`` starting at ``start_time``."""
    length = spec.duration if spec.duration is not None else stage_duration(stage) - spec.start
    return start_time + spec.start, start_time + spec.start + length


def check_windows(case: CaseSpec) -> None:
    """Refuse a measurement window that no run of the case reaches: an absolute one starting at or
    after the longest the stages can last, a stage's one naming no stage, starting before it or at
    or after its longest, or of no length."""
    ends = np.cumsum([stage_duration(s) for s in case.stages])
    lengths = {s.name: stage_duration(s) for s in case.stages}
    for k, m in enumerate(case.measurements):
        w, where = m.window, f"measurements.{k}: window"
        if w is None:
            continue
        if isinstance(w, StageWindowSpec):
            if w.stage not in lengths:
                raise ParameterError(f"{where} stage = {w.stage!r} is not allowed: no stage has that name; the stages "
                                     f"are {', '.join(repr(n) for n in lengths)}")
            if not 0 <= w.start < lengths[w.stage]:
                raise ParameterError(f"{where} start = {w.start:g} is not allowed: must be in [0, {lengths[w.stage]:g}) s, "
                                     f"within stage {w.stage!r}")
            if w.duration is not None and not w.duration > 0:
                raise ParameterError(f"{where} duration = {w.duration:g} is not allowed: must be > 0 (s)")
        elif len(ends) and w[0] >= ends[-1]:
            raise ParameterError(f"{where} = [{w[0]:g}, {w[1]:g}] is not allowed: it starts after the run, which lasts "
                                 f"at most {ends[-1]:g} s; give times within it, or a window from a stage's start "
                                 "({stage: NAME, start: S, duration: D})")


def stage_conditions(stage: StageSpec, measurements: dict) -> list:
    """The conditions (``rollingdem.scene.conditions``) that end ``stage`` early."""
    from rollingdem.scene.conditions import Empty, Settled

    u = stage.until
    if u is None:
        return []
    where = f"stage {stage.name!r}: until"
    given = [k for k in ("settled", "empty", "measurement") if getattr(u, k) is not None]
    if not given:
        raise ParameterError(f"{where} = {u.model_dump(exclude_none=True)} is not allowed: give settled, empty or "
                             "measurement (with above, below or known_within); with several the first met ends the "
                             "stage")
    conditions = []
    try:
        if u.settled is not None:
            conditions.append(Settled(**u.settled.model_dump()))
        if u.empty is not None:
            if not u.empty:
                raise ParameterError("empty = false is not allowed: write until: empty, or leave until out")
            conditions.append(Empty(every=u.every))
        if u.measurement is not None:
            conditions.append(_reaches(u, measurements))
    except ParameterError as err:
        raise ParameterError(f"{where}: {err}") from None
    return conditions


def _reaches(u: UntilSpec, measurements: dict):
    from rollingdem.scene.conditions import Known, Reaches

    name, _, quantity = u.measurement.partition(".")
    if name not in measurements:
        known = ", ".join(f"{n}.{q}" for n, m in measurements.items() for q in (m.QUANTITIES or ())) or "none"
        raise ParameterError(f"measurement = {u.measurement!r} is not allowed: no measurement is named {name!r}; "
                             f"the measurements give {known}")
    if not quantity:
        raise ParameterError(f"measurement = {u.measurement!r} is not allowed: name a quantity, "
                             f"{name}.QUANTITY, one of {', '.join(measurements[name].QUANTITIES)}")
    if u.known_within is not None:
        if u.above is not None or u.below is not None or u.hold:
            raise ParameterError(f"measurement = {u.measurement!r} with known_within is not allowed beside above, below "
                                 "or hold: known_within ends the stage when the mean is known, not when it reaches a "
                                 "value")
        return Known(measurements[name], quantity, u.known_within, every=u.every, min_samples=u.min_samples)
    return Reaches(measurements[name], quantity, above=u.above, below=u.below, every=u.every, hold=u.hold)


def _check_first_time_step(sim, sv) -> None:
    """dt against the stable limit as the first stage's run will see it (after its set_velocity);
    the velocities are put back afterwards."""
    from rollingdem.engine.layout import I_FORCES_VALID

    st = sim._state
    saved = (st.v.copy(), st.w.copy(), int(st.info[I_FORCES_VALID]))
    try:
        if sv is not None:
            idx = np.flatnonzero(~sim.fixed) if sv.particles == "all" else sv.particles
            sim.set_velocities(idx, sv.velocity, sv.angular_velocity)
        sim.check_time_step()
    finally:
        st.v[...] = saved[0]
        st.w[...] = saved[1]
        st.info[I_FORCES_VALID] = saved[2]


#: particle-steps per second on 2 cores that ``check``'s wall-time estimate takes: the default case's
#: dense bed (its lift and rest stages: 15.0 and 14.4 M on 2 cores, docs/performance.md)
DENSE_BED_RATE = 15e6
#: a wall surface faster than this (m/s) is warned about: beyond a mixer blade's tip speed
FAST_WALL = 100.0
#: an estimate above this many seconds is warned about (a duration in ms given as s, or 1e9)
LONG_RUN_S = 24 * 3600.0


def stage_wall_speed(sim, stage: StageSpec, base: Path) -> float:
    """The fastest a wall surface moves in ``stage`` (m/s) where a particle can meet it: each wall
    motion's velocity, its turn at the farthest particle or mesh vertex from its axis, and its
    program's peak; the walls that keep their motion count too."""
    names = {m.wall for m in stage.wall_motion}
    x = sim.positions
    speed = max((w.peak_speed(x) for w in sim.walls if w.name not in names and w.name not in stage.remove_walls),
                default=0.0)
    for m in stage.wall_motion:
        wall = next(w for w in sim.walls if w.name == m.wall)
        motion = _motion(m, mesh=hasattr(wall, "mesh"), base=base)
        omega = np.asarray(motion.get("angular_velocity", (0.0, 0.0, 0.0)), float)
        points = np.vstack([x, wall.mesh.vertices]) if hasattr(wall, "mesh") else x
        point = np.asarray(motion.get("point") if motion.get("point") is not None else wall.point, float)
        d = points - point
        if np.linalg.norm(omega) > 0:
            axis = omega / np.linalg.norm(omega)
            reach = float(np.linalg.norm(d - np.outer(d @ axis, axis), axis=1).max(initial=0.0))
        else:
            reach = float(np.linalg.norm(d, axis=1).max(initial=0.0))
        speed = max(speed, surface_speed(motion.get("velocity") or (0.0, 0.0, 0.0), omega, motion.get("motion"), reach))
    return speed


def stage_time_steps(case: CaseSpec, sim) -> list[tuple[float, float]]:
    """(the dt each stage starts with, its fastest wall surface (m/s), ``stage_wall_speed``, 0 without
    a wall motion): a dt the case gives, or the automatic one at the stable limit with the stage's
    wall motion. A given dt above that limit is refused (``check_case``)."""
    steps = []
    for stage in case.stages:
        dt, speed = sim.dt, 0.0
        if stage.wall_motion:
            speed = stage_wall_speed(sim, stage, case.base_directory)
            label, limit = min(sim.time_step_policy.limits(wall_speed=speed), key=lambda lv: lv[1])
            if sim.dt_automatic:
                dt = limit
            elif sim.check_timestep and sim.dt > limit * (1 + 1e-12):
                raise ParameterError(f"stage {stage.name!r}: dt = {sim.dt:.4g} s exceeds the stable limit {limit:.4g} s "
                                     f"with its wall motion ({label}): choose dt <= {limit:.4g} s, or check the wall's "
                                     f"speed (rad/s where rpm was meant is 60 times too fast), or "
                                     f"{sim.hints['check_timestep']}")
        steps.append((dt, speed))
    return steps


def run_length(case: CaseSpec, sim) -> tuple[list[str], list[str]]:
    """(lines, warnings) for ``check``: each stage's longest run in steps at the dt it starts with
    (``stage_time_steps``), the total and its wall time at ``DENSE_BED_RATE`` on 2 cores; a warning
    for a run estimated past ``LONG_RUN_S`` and for ``until: empty`` with no outlet to empty the
    scene."""
    lines, warnings, total = [], [], 0
    for stage, (dt, speed) in zip(case.stages, stage_time_steps(case, sim)):
        steps = int(round(stage_duration(stage) / dt))
        total += steps
        lines.append(f"stage {stage.name!r}: up to {steps:,} steps at dt = {dt:.3g} s")
        if speed > FAST_WALL:
            warnings.append(f"stage {stage.name!r}: a wall surface moves at {speed:.3g} m/s where particles can meet "
                            f"it, faster than {FAST_WALL:g} m/s: is an angular_velocity (rad/s) an rpm?")
        if stage.until is not None and stage.until.empty and not case.outlets:
            warnings.append(f"stage {stage.name!r}: until: empty is never met without an outlet; it runs its "
                            f"max_duration, {stage.max_duration:g} s")
    seconds = sim.n_particles * total / DENSE_BED_RATE
    lines.append(f"in all up to {total:,} steps of {sim.n_particles:,} particles: about {_duration(seconds)} on 2 cores "
                 f"(at {DENSE_BED_RATE / 1e6:.0f} M particle-steps/s, a dense bed's rate)")
    if seconds > LONG_RUN_S:
        warnings.append(f"the run is estimated at {_duration(seconds)}: check each stage's duration (s)")
    return lines, warnings


def _duration(seconds: float) -> str:
    """Seconds in words: "40 s", "12 min", "3.5 h", "2.1e+03 days"."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    if seconds < 172800:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.3g} days"


def mesh_lines(sim) -> list[str]:
    """Each mesh wall in one line (``TriangleMesh.report_line``): its size, triangles, free edges,
    what reading its file merged and dropped; then each insert's spheres and the size distribution
    they realise."""
    from rollingdem.physics.records import WALL_MESH

    return ([f"wall {w.name or '(unnamed)'!r}, {w.mesh.report_line()}" for w in sim.walls if w.kind == WALL_MESH]
            + [f"inserted {line}" for line in sim.particle_set.fills])


def default_case_path() -> Path:
    return Path(__file__).parents[1] / "experiments" / "default.yaml"


__all__ = ["CaseSpec", "load_case", "build_simulation", "build_measurements", "check_case", "stage_conditions",
           "stage_duration", "default_case_path"]
