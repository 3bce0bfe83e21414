"""The case file's schema: one pydantic model per block (``CaseSpec`` at the top), strict (an
unknown or misspelled key is an error), a material's and a pair's fields taken from the
declarations ``Material`` checks against (``material_specs`` brings them up to date).
``rollingdem schema`` prints it as JSON Schema; reading and building: ``rollingdem.io.casefile``."""

from __future__ import annotations

import inspect
from pathlib import Path
from typing import Annotated, Any, Literal, Optional, Union

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    PrivateAttr,
    Strict,
    Tag,
    create_model,
)

from rollingdem.physics.contact.properties import MATERIAL_PROPERTIES
from rollingdem.scene.bonds import ParallelBond
from rollingdem.scene.boundaries import Outlet
from rollingdem.scene.conditions import Settled
from rollingdem.scene.materials import OWN_PROPERTIES
from rollingdem.io.measurements import MassFlow, OutletTotals, Probe, WallLoad
from rollingdem.io.rig_measurements import DrumAngle, DrumFlow, PileAngle
from rollingdem.scene.motion import MotionTable, Oscillation, Servo
from rollingdem.scene.regions import BoxRegion, CylinderRegion, Disk, Rectangle
from rollingdem.scene.size_distributions import Discrete, MassFractions, Normal, SieveCurve, Uniform
from rollingdem.scene.walls import Cylinder, Plane


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


def _documented(prop, default, unit=None):
    """A field from a declaration (a material property, a constructor's ``Declared`` parameter):
    its description, unit (``unit``: the case file's, where it differs) and bounds in the JSON
    Schema; the bounds are checked by the object the field makes, whose refusal names it."""
    extra = {"unit": prop.unit if unit is None else unit} if (prop.unit or unit) else {}
    for key, bound, is_open in (("minimum", prop.low, prop.low_open), ("maximum", prop.high, prop.high_open)):
        if bound is not None:
            extra[("exclusiveM" + key[1:]) if is_open else key] = bound
    return Field(default, description=prop.description, json_schema_extra=extra)


def _material_spec():
    """The schema of a material entry, from the declarations ``Material`` checks against: its own
    values and the properties the registered contact laws declare."""
    own = {key: (Number, _documented(prop, ... if prop.default is None else prop.default))
           for key, prop in OWN_PROPERTIES.items()}
    laws = {key: (Number, _documented(prop, prop.default)) for key, prop in MATERIAL_PROPERTIES.items()}
    return create_model("MaterialSpec", __base__=_Strict, name=(str, Field(description="label the other blocks "
                                                                           "use to refer to the material")),
                        **own, **laws)


def _pair_spec():
    """The schema of a pair entry: any declared property, in place of its mixed value."""
    return create_model("PairSpec", __base__=_Strict, materials=(tuple[str, str], ...),
                        **{key: (Optional[Number], _documented(prop, None)) for key, prop in MATERIAL_PROPERTIES.items()})


MaterialSpec = _material_spec()
PairSpec = _pair_spec()


#: a declared kind of value (``errors.Declared.kind``) as a case file writes it
_KINDS = {"number": Number, "whole": Whole, "vector": Vector, "text": str, "flag": bool, "numbers": list[Number],
          "vectors": list[Vector], "pair": tuple[Number, Number]}


def spec_from(cls, name: str, doc: str, *, first=None, exclude=(), required=(), optional=(), units=None, last=None,
              kinds=None):
    """The schema (``name``, described by ``doc``) of the case-file block that makes a ``cls``: a
    field per parameter of its constructor, with the constructor's default and what ``cls.declared``
    says of it (kind, description, unit, bounds), so that a parameter is written once, beside the
    constructor. ``first``, ``last``: the block's own fields ({key: (type, default)}) before and
    after; ``exclude``: parameters the block gives otherwise; ``required``, ``optional``: parameters
    the block requires or may leave out where the constructor does not; ``units``: where the case
    file takes another unit than the constructor (degrees for radians), converted where it is
    built; ``kinds``: the case-file type of a kind of value of the block's own."""
    fields = dict(first or {})
    for key, parameter in inspect.signature(cls.__init__).parameters.items():
        if key == "self" or key in exclude:
            continue
        declared = cls.declared[key]
        kind = {**_KINDS, **(kinds or {})}[declared.kind]
        default = ... if key in required or (parameter.default is parameter.empty and key not in optional) else (
            None if parameter.default is parameter.empty else parameter.default)
        fields[key] = (Optional[kind] if default is None else kind,
                       _documented(declared, default, (units or {}).get(key)))
    fields.update(last or {})
    return create_model(name, __base__=_Strict, __doc__=doc, **fields)


class ContactSpec(_Strict):
    # a model name or {model: name, parameter: value, ...}; make_submodel checks both
    normal: Any = "hertz"
    tangential: Any = "history"
    rolling: Any = "none"
    twisting: Any = "none"
    cohesion: Any = "none"


OscillateSpec = spec_from(Oscillation, "OscillateSpec", "rollingdem.Oscillation, its angles in degrees",
                          units={"angle": "deg", "phase": "deg"})
TableSpec = spec_from(MotionTable, "TableSpec", "rollingdem.MotionTable (rows given or from a CSV file), its angles in "
                      "degrees", optional=("times",), units={"angles": "deg"},
                      first={"file": (Optional[str], Field(None, description="a CSV file of the table, relative to "
                                                           "the case file: columns t, dx, dy, dz, angle (each but t "
                                                           "optional)"))})
ServoSpec = spec_from(Servo, "ServoSpec", "rollingdem.Servo")
#: a wall block's motion program: one of three keys
_PROGRAMS = {"oscillate": (Optional[OscillateSpec], Field(None, description="an oscillation (one program at most)")),
             "table": (Optional[TableSpec], Field(None, description="a table of times (one program at most)")),
             "servo": (Optional[ServoSpec], Field(None, description="a servo (one program at most)"))}
PlaneSpec = spec_from(Plane, "PlaneSpec", "rollingdem.Plane, its material by name, and a motion program",
                      first={"type": (Literal["plane"], ...)}, exclude=("motion",), required=("material",),
                      last=_PROGRAMS)
CylinderSpec = spec_from(Cylinder, "CylinderSpec", "rollingdem.Cylinder, its material by name, and a motion program",
                         first={"type": (Literal["cylinder"], ...)}, exclude=("motion",), required=("material",),
                         last=_PROGRAMS)


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


BoxRegionSpec = spec_from(BoxRegion, "BoxRegionSpec", "rollingdem.BoxRegion", first={"type": (Literal["box"], ...)})
CylinderRegionSpec = spec_from(CylinderRegion, "CylinderRegionSpec", "rollingdem.CylinderRegion (its axis along z)",
                               first={"type": (Literal["cylinder"], ...)})


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


UniformSpec = spec_from(Uniform, "UniformSpec", "rollingdem.Uniform: radii uniform in [low, high]",
                        first={"distribution": (Literal["uniform"], ...)})


NormalSpec = spec_from(Normal, "NormalSpec", "rollingdem.Normal: a normal radius distribution, truncated",
                       first={"distribution": (Literal["normal"], ...)})


DiscreteSpec = spec_from(Discrete, "DiscreteSpec", "rollingdem.Discrete: radii drawn from values",
                         first={"distribution": (Literal["discrete"], ...)})


MassFractionsSpec = spec_from(MassFractions, "MassFractionsSpec", "rollingdem.MassFractions: size classes by mass",
                              first={"distribution": (Literal["mass_fractions"], ...)})


SieveSpec = spec_from(SieveCurve, "SieveSpec", "rollingdem.SieveCurve: a grading curve",
                      first={"distribution": (Literal["sieve"], ...)})


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


def particle_kind(value):
    """A particle block with a ``clump`` key adds clumps, one with ``insert`` fills a region, one
    with ``rough_base`` lays a fixed base; any other lists its spheres."""
    if isinstance(value, dict):
        return ("clump" if "clump" in value else "insert" if "insert" in value else
                "rough_base" if "rough_base" in value else "list")
    return {InsertSpec: "insert", RoughBaseSpec: "rough_base", ListSpec: "list", ClumpSpec: "clump"}.get(type(value))


ParticleSpec = Annotated[Union[Annotated[InsertSpec, Tag("insert")], Annotated[RoughBaseSpec, Tag("rough_base")],
                               Annotated[ListSpec, Tag("list")], Annotated[ClumpSpec, Tag("clump")]],
                         Discriminator(particle_kind)]


OutletSpec = spec_from(Outlet, "OutletSpec", "Simulation.add_outlet (rollingdem.scene.boundaries.Outlet)",
                       kinds={"region": RegionSpec})


DiskFaceSpec = spec_from(Disk, "DiskFaceSpec", "rollingdem.Disk: a face particles enter through",
                         first={"type": (Literal["disk"], ...)})
RectangleFaceSpec = spec_from(Rectangle, "RectangleFaceSpec", "rollingdem.Rectangle: a face particles enter through",
                              first={"type": (Literal["rectangle"], ...)})


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


#: a measurement's window: [t0, t1] from the run's start, or a window from a stage's start
_WINDOW = {"window": Union[tuple[Number, Number], StageWindowSpec]}


def _measurement(cls, name, kind, doc, kinds=None):
    """A measurement's block, its ``type`` the measurement's kind, from its declarations."""
    return spec_from(cls, name, doc, first={"type": (Literal[kind], ...)}, required=("name",),
                     kinds={**_WINDOW, **(kinds or {})})


MassFlowSpec = _measurement(MassFlow, "MassFlowSpec", "mass_flow", "rollingdem.MassFlow: through a plane or a disk")


ProbeSpec = _measurement(Probe, "ProbeSpec", "probe", "rollingdem.Probe: the particles in a region",
                         kinds={"region": RegionSpec})


OutletMeasurementSpec = _measurement(OutletTotals, "OutletMeasurementSpec", "outlet",
                                     "rollingdem.OutletTotals: what an outlet took out")


WallMeasurementSpec = _measurement(WallLoad, "WallMeasurementSpec", "wall",
                                   "rollingdem.WallLoad: force, torque, power and place of a wall")


ReposeMeasurementSpec = _measurement(PileAngle, "ReposeMeasurementSpec", "repose_angle",
                                     "rollingdem.PileAngle: the pile's angle of repose (docs/analysis.md)")


DrumMeasurementSpec = _measurement(DrumAngle, "DrumMeasurementSpec", "drum_angle",
                                   "rollingdem.DrumAngle: the bed's angle about the drum's axis")


DrumFlowSpec = _measurement(DrumFlow, "DrumFlowSpec", "drum_flow",
                            "rollingdem.DrumFlow: the flowing layer's depth and the bed's turn with the drum")


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
        return ParallelBond(**self.model_dump(exclude={"gap", "pairs"}))


def _bond_spec():
    """The schema of a stage's bonds: gap or pairs, and ``ParallelBond``'s parameters as its
    constructor declares them (one list of names and defaults)."""
    kinds = {"float": Number, "str": str}
    spec = {name: (kinds[p.annotation], ... if p.default is p.empty else p.default)
            for name, p in inspect.signature(ParallelBond).parameters.items()}
    return create_model("BondSpec", __base__=_BondBase, **spec)


BondSpec = _bond_spec()


SettledSpec = spec_from(Settled, "SettledSpec", "rollingdem.Settled: the bed at rest")


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

    @base_directory.setter
    def base_directory(self, folder) -> None:  # where a case made from a mapping names its files from
        self._base = Path(folder)


_SPECS_OF = tuple(MATERIAL_PROPERTIES)


def material_specs() -> None:
    """Bring the material and pair entries up to date with the declared material properties (a
    user's contact law defined after this module was imported declares its own)."""
    global MaterialSpec, PairSpec, _SPECS_OF
    if tuple(MATERIAL_PROPERTIES) == _SPECS_OF:
        return
    MaterialSpec, PairSpec, _SPECS_OF = _material_spec(), _pair_spec(), tuple(MATERIAL_PROPERTIES)
    CaseSpec.model_fields["materials"].annotation = list[MaterialSpec]
    CaseSpec.model_fields["pairs"].annotation = list[PairSpec]
    CaseSpec.model_rebuild(force=True)
