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

from rollingdem.physics.contact.base import REGISTRIES
from rollingdem.physics.contact.model import ContactModel
from rollingdem.physics.contact.properties import MATERIAL_PROPERTIES
from rollingdem.scene.bonds import ParallelBond
from rollingdem.scene.boundaries import Inflow, Outlet
from rollingdem.scene.conditions import Settled
from rollingdem.scene.insertion import ROUGH_BASE_DECLARED, rough_base
from rollingdem.scene.materials import OWN_PROPERTIES
from rollingdem.scene.particles import PARTICLE_DECLARED
from rollingdem.io.measurements import MassFlow, OutletTotals, Probe, WallLoad
from rollingdem.io.rig_measurements import DrumAngle, DrumFlow, PileAngle
from rollingdem.io.box_measurements import BoxStress
from rollingdem.io.field_measurements import ContinuumFields
from rollingdem.scene.motion import MotionTable, Oscillation, Servo
from rollingdem.scene.regions import BoxRegion, CylinderRegion, Disk, Rectangle
from rollingdem.scene.simulation import Simulation
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
    return create_model("PairSpec", __base__=_Strict,
                        materials=(tuple[str, str], Field(description="the names of the two materials")),
                        **{key: (Optional[Number], _documented(prop, None)) for key, prop in MATERIAL_PROPERTIES.items()})


MaterialSpec = _material_spec()
PairSpec = _pair_spec()


#: a declared kind of value (``errors.Declared.kind``) as a case file writes it
_KINDS = {"number": Number, "whole": Whole, "vector": Vector, "text": str, "flag": bool, "numbers": list[Number],
          "vectors": list[Vector], "pair": tuple[Number, Number]}


def spec_from(maker, name: str, doc: str, *, first=None, exclude=(), required=(), optional=(), units=None, last=None,
              kinds=None, base=None):
    """The schema (``name``, described by ``doc``) of the case-file block that makes a ``maker``: a
    field per parameter of its constructor, with the constructor's default and what ``maker.declared``
    says of it (kind, description, unit, bounds), so that a parameter is written once, beside the
    constructor. ``first``, ``last``: the block's own fields ({key: (type, default)}) before and
    after; ``exclude``: parameters the block gives otherwise; ``required``, ``optional``: parameters
    the block requires or may leave out where the constructor does not; ``units``: where the case
    file takes another unit than the constructor (degrees for radians), converted where it is
    built; ``kinds``: the case-file type of a kind of value of the block's own. A block that calls
    a function or method rather than a constructor gives ``maker`` as (that function, its
    declarations); ``base``: the model the block's class derives from."""
    fields = dict(first or {})
    call, declared = maker if isinstance(maker, tuple) else (maker.__init__, maker.declared)
    for key, parameter in inspect.signature(call).parameters.items():
        if key == "self" or key in exclude:
            continue
        kind = {**_KINDS, **(kinds or {})}[declared[key].kind]
        default = ... if key in required or (parameter.default is parameter.empty and key not in optional) else (
            None if parameter.default is parameter.empty else parameter.default)
        fields[key] = (Optional[kind] if default is None else kind,
                       _documented(declared[key], default, (units or {}).get(key)))
    fields.update(last or {})
    return create_model(name, __base__=base or _Strict, __doc__=doc, **fields)


def about(default, description: str, unit: str | None = None):
    """A field of a block that only the case file has (its layout: stages, outputs, the ``type``
    of a block), with its description and unit, as ``spec_from`` gives a declared one."""
    return Field(default, description=description, json_schema_extra={"unit": unit} if unit else None)


def described(kind, default, description: str, unit: str | None = None):
    """``about`` with its type, for ``create_model`` and ``spec_from``'s ``first`` and ``last``."""
    return kind, about(default, description, unit)


def kind_tag(tag: str, what: str):
    """The ``type`` (or ``distribution``) key that says which kind of block this is."""
    return described(Literal[tag], ..., f"{tag}: {what}")


ContactSpec = create_model(
    "ContactSpec", __base__=_Strict, __doc__="The contact law: one sub-model per slot (rollingdem.ContactModel, "
                                            "docs/models.md)",
    **{slot: described(Any, parameter.default, f"the {slot} sub-model: a name ({', '.join(sorted(REGISTRIES[slot]))}"
                       f") or {{model: NAME, parameter: value, ...}}")
       for slot, parameter in inspect.signature(ContactModel).parameters.items()})


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
                      first={"type": kind_tag("plane", "an infinite plane")}, exclude=("motion",),
                      required=("material",),
                      last=_PROGRAMS)
CylinderSpec = spec_from(Cylinder, "CylinderSpec", "rollingdem.Cylinder, its material by name, and a motion program",
                         first={"type": kind_tag("cylinder", "a cylinder about its axis")}, exclude=("motion",),
                         required=("material",),
                         last=_PROGRAMS)


class RotateSpec(_Strict):
    """A turn about the axis through ``point``: at ``angular_velocity`` (rad/s) or ``rpm``
    (revolutions per minute) in a motion, by ``angle`` (degrees) in a placement. ``point``: a mesh
    wall's (default the origin); a plane or cylinder turns about its own point and takes none."""
    axis: Vector = about(..., "the axis of the turn (made unit length)", "-")
    point: Optional[Vector] = about(None, "a point of the axis (a mesh wall's; default the origin)", "m")
    angular_velocity: Optional[Number] = about(None, "turning speed about the axis (or rpm)", "rad/s")
    rpm: Optional[Number] = about(None, "turning speed about the axis (or angular_velocity)", "1/min")
    angle: Optional[Number] = about(None, "the angle turned by (a placement)", "deg")


_MOTION = {"velocity": described(Vector, (0.0, 0.0, 0.0), "velocity of the wall", "m/s"),
           "rotate": described(Optional[RotateSpec], None, "a turn at a steady speed"), **_PROGRAMS}
MotionSpec = create_model("MotionSpec", __base__=_Strict, __doc__="A wall's motion: a velocity, a turn and one motion "
                          "program at most", **_MOTION)


class PlaceSpec(_Strict):
    """Where a mesh is put: turned by ``rotate``, then moved by ``translate``."""
    rotate: Optional[RotateSpec] = about(None, "a turn by an angle about an axis")
    translate: Vector = about((0.0, 0.0, 0.0), "a shift after the turn", "m")


class _MeshSource(_Strict):
    """A mesh given by a file or a ready-made shape, and placed."""
    file: Optional[str] = about(None, "an STL or OBJ file, named from the case file's folder")
    scale: Number = about(1.0, "factor on the file's coordinates (0.001 for mm)", "-")
    shape: Optional[str] = about(None, "a ready-made shape (instead of a file)")
    size: dict[str, Any] = about({}, "the shape's dimensions by name", "m")
    place: Optional[PlaceSpec] = about(None, "turned, then moved")


class MeshSpec(_MeshSource):
    """A triangle-mesh wall: ``file`` (STL or OBJ, relative to the case file; ``scale`` 0.001 for mm;
    vertices within ``weld`` m merged) or a ready-made ``shape`` with its ``size`` (its dimensions by
    name), placed by ``place`` (turned, then moved), moving by ``motion``; ``check_size: false``
    accepts a mesh implausibly large against the particles."""
    type: Literal["mesh"] = about(..., "mesh: a wall of triangles (rollingdem.MeshWall)")
    name: Optional[str] = about(None, "label of the wall in outputs and measurements")
    material: str = about(..., "name of the wall's material")
    weld: Optional[Number] = about(None, "vertices nearer than this merged", "m")
    check_size: bool = about(True, "refuse a mesh implausibly large against the particles (false: accept it)")
    motion: Optional[MotionSpec] = about(None, "how the wall moves")


WallSpec = Annotated[Union[PlaneSpec, CylinderSpec, MeshSpec], Field(discriminator="type")]


BoxRegionSpec = spec_from(BoxRegion, "BoxRegionSpec", "rollingdem.BoxRegion",
                          first={"type": kind_tag("box", "an axis-aligned box")})
CylinderRegionSpec = spec_from(CylinderRegion, "CylinderRegionSpec", "rollingdem.CylinderRegion (its axis along z)",
                               first={"type": kind_tag("cylinder", "a cylinder along z")})


class MeshRegionSpec(_MeshSource):
    """``rollingdem.MeshRegion``: the volume a closed mesh encloses, given as a mesh wall is, or the
    mesh of the ``wall`` named so (a region to fill)."""
    type: Literal["mesh"] = about(..., "mesh: the volume a closed mesh encloses")
    wall: Optional[str] = about(None, "the mesh wall of this name (instead of a file or shape)")


RegionSpec = Annotated[Union[BoxRegionSpec, CylinderRegionSpec, MeshRegionSpec], Field(discriminator="type")]


UniformSpec = spec_from(Uniform, "UniformSpec", "rollingdem.Uniform: radii uniform in [low, high]",
                        first={"distribution": kind_tag("uniform", "radii uniform between low and high")})


NormalSpec = spec_from(Normal, "NormalSpec", "rollingdem.Normal: a normal radius distribution, truncated",
                       first={"distribution": kind_tag("normal", "a truncated normal distribution of radii")})


DiscreteSpec = spec_from(Discrete, "DiscreteSpec", "rollingdem.Discrete: radii drawn from values",
                         first={"distribution": kind_tag("discrete", "radii drawn from values")})


MassFractionsSpec = spec_from(MassFractions, "MassFractionsSpec", "rollingdem.MassFractions: size classes by mass",
                              first={"distribution": kind_tag("mass_fractions", "size classes by mass")})


SieveSpec = spec_from(SieveCurve, "SieveSpec", "rollingdem.SieveCurve: a grading curve",
                      first={"distribution": kind_tag("sieve", "a grading curve")})


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


def _particle(key, kind, default):
    """A particle block's field of a particle-adding call's parameter ``key``, as declared."""
    return kind, _documented(PARTICLE_DECLARED[key], default)


InsertSpec = spec_from((Simulation.insert, PARTICLE_DECLARED), "InsertSpec",
                       "Spheres inserted in a region (Simulation.insert): count of them, or mass, or a fraction of "
                       "the region's volume", exclude=("region", "max_attempts", "clump"),
                       required=("radius", "material"), kinds={"radius": RadiusSpec, "velocities": Vector},
                       first={"insert": _particle("region", RegionSpec, ...)})


ListSpec = spec_from((Simulation.add_particles, PARTICLE_DECLARED), "ListSpec",
                     "Spheres at the positions given (Simulation.add_particles)",
                     kinds={"radius": Union[Number, list[Number]], "velocities": Union[Vector, list[Vector]]})


RoughBaseShape = spec_from((rough_base, ROUGH_BASE_DECLARED), "RoughBaseShape",
                           "A jittered hexagonal layer of spheres (rollingdem.rough_base)",
                           kinds={"extent": tuple[tuple[Number, Number], tuple[Number, Number]]})


class RoughBaseSpec(_Strict):
    """Fixed spheres in a jittered hexagonal layer (``rd.rough_base``)."""
    rough_base: RoughBaseShape = Field(description="the layer's shape")
    material: str = Field(description=PARTICLE_DECLARED["material"].description)


ClumpShapeSpec = create_model(
    "ClumpShapeSpec", __base__=_Strict,
    __doc__="A clump template (rd.Clump): a named shape with its members' radius, their centres' distance and n; or "
            "its spheres",
    shape=described(Optional[Literal["dimer", "trimer", "tetrahedron", "ring_prism", "rod"]], None,
                    "a named template (rd.Clump.dimer, trimer, tetrahedron, ring_prism, rod)"),
    radius=described(Optional[Number], None, "the members' radius (a named shape)", "m"),
    distance=described(Optional[Number], None, "distance between the members' centres (a rod's spacing; default "
                       "2 radius, touching)", "m"),
    n=described(Optional[Whole], None, "number of members (ring_prism, rod)"),
    spheres=described(Optional[list[tuple[Number, Number, Number, Number]]], None,
                      "the members as rows x, y, z, r (instead of a shape)", "m"),
    connected=described(bool, True, "refuse a template whose members do not touch in one piece"))


ClumpSpec = create_model(
    "ClumpSpec", __base__=_Strict,
    __doc__="Clumps of one template: inserted in a region (insert with count, mass or fraction, at random "
            "orientations from seed; Simulation.insert) or placed at positions (their centres of mass) turned by "
            "orientations (Simulation.add_clumps)",
    clump=_particle("clump", ClumpShapeSpec, ...), material=_particle("material", str, ...),
    insert=_particle("region", Optional[RegionSpec], None), count=_particle("count", Optional[Whole], None),
    mass=_particle("mass", Optional[Number], None), fraction=_particle("fraction", Optional[Number], None),
    seed=_particle("seed", Whole, 0), positions=_particle("positions", Optional[list[Vector]], None),
    orientations=_particle("orientations", Optional[list[tuple[Number, Number, Number, Number]]], None),
    velocity=_particle("velocity", Optional[Vector], None),
    angular_velocity=_particle("angular_velocity", Optional[Vector], None),
    allow_overlap=_particle("allow_overlap", bool, False), fixed=_particle("fixed", bool, False))


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
                         first={"type": kind_tag("disk", "a disk")})
RectangleFaceSpec = spec_from(Rectangle, "RectangleFaceSpec", "rollingdem.Rectangle: a face particles enter through",
                              first={"type": kind_tag("rectangle", "a rectangle")})


class MeshFaceSpec(_MeshSource):
    """``rollingdem.MeshFace``: a flat mesh (given as a mesh wall is, or the ``wall`` named so) as a face."""
    type: Literal["mesh_face"] = about(..., "mesh_face: a flat mesh particles enter through")
    wall: Optional[str] = about(None, "the mesh wall of this name (instead of a file or shape)")
    normal: Optional[Vector] = about(None, "the side particles enter towards (default the triangles' normal)", "-")


InflowSpec = spec_from((Simulation.add_inflow, Inflow.declared), "InflowSpec",
                       "Particles inserted during the run into region, or through a face (disk, rectangle, "
                       "mesh_face) at velocity (Simulation.add_inflow)",
                       kinds={"region": Annotated[Union[BoxRegionSpec, CylinderRegionSpec, MeshRegionSpec, DiskFaceSpec,
                                                        RectangleFaceSpec, MeshFaceSpec], Field(discriminator="type")],
                              "radius": RadiusSpec})


class StageWindowSpec(_Strict):
    """A measurement window that starts ``start`` seconds after the start of stage ``stage`` and
    lasts ``duration`` seconds (default: to that stage's end): it moves with a stage before it that
    ends on a condition."""
    stage: str = about(..., "name of the stage the window starts in")
    start: Number = about(0.0, "its start after the stage's start", "s")
    duration: Optional[Number] = about(None, "its length (default: to the stage's end)", "s")


class _MeasurementBase(_Strict):
    name: str = about(..., "label of the measurement: its columns are name.quantity")
    interval: Optional[Number] = about(None, "time between its samples (default the kind's own)", "s")
    window: Optional[Union[tuple[Number, Number], StageWindowSpec]] = about(
        None, "[t0, t1] from the run's start, or a window from a stage's start", "s")


#: a measurement's window: [t0, t1] from the run's start, or a window from a stage's start
_WINDOW = {"window": Union[tuple[Number, Number], StageWindowSpec]}


def _measurement(cls, name, kind, doc, kinds=None):
    """A measurement's block, its ``type`` the measurement's kind, from its declarations."""
    return spec_from(cls, name, doc, first={"type": kind_tag(kind, doc)}, required=("name",),
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


FieldsSpec = _measurement(ContinuumFields, "FieldsSpec", "fields",
                         "rollingdem.ContinuumFields: coarse-grained continuum fields on a grid (docs/analysis.md)")


BoxStressSpec = _measurement(BoxStress, "BoxStressSpec", "box_stress",
                             "rollingdem.BoxStress: a periodic box's stress and shear, with an optional pressure "
                             "control (docs/measurements.md)")


class MeshFlowSpec(_MeasurementBase, _MeshSource):
    """``rollingdem.MeshFlow``: through a triangle mesh surface, counted along its triangles' normals."""
    type: Literal["mesh_flow"] = about(..., "mesh_flow: the flow through a triangle mesh surface")


class ProfileSpec(_MeasurementBase):
    """``rollingdem.SurfaceProfile``: the free surface against the measured profile in ``file`` (a CSV
    of two columns, m, named from the case file): a heap's (r, h) or a drum's (x, y)."""
    type: Literal["profile"] = about(..., "profile: the free surface against a measured profile")
    file: str = about(..., "CSV of the measured profile, two columns (m), named from the case file's folder")
    shape: Literal["heap", "drum"] = about("heap", "a heap's (r, h) or a drum's (x, y) profile")
    center: Optional[list[Number]] = about(None, "the heap's axis (x, y) or the drum's centre", "m")
    axis: Vector = about((0.0, 0.0, 1.0), "the heap's axis or the drum's", "-")
    floor: Optional[Number] = about(None, "height of the heap's floor (default: the lowest sphere's bottom)", "m")


MeasurementSpec = Annotated[Union[MassFlowSpec, ProbeSpec, OutletMeasurementSpec, WallMeasurementSpec,
                                  ReposeMeasurementSpec, DrumMeasurementSpec, DrumFlowSpec, ProfileSpec,
                                  MeshFlowSpec, FieldsSpec, BoxStressSpec],
                            Field(discriminator="type")]


class PeriodicSpec(_Strict):
    """Periodic boundaries: each axis given wraps between its two bounds."""
    x: Optional[tuple[Number, Number]] = about(None, "(low, high) of the periodic box along x", "m")
    y: Optional[tuple[Number, Number]] = about(None, "(low, high) of the periodic box along y", "m")
    z: Optional[tuple[Number, Number]] = about(None, "(low, high) of the periodic box along z", "m")
    shear_rate: Optional[Number] = about(None, "Lees-Edwards shear: the box sheared at this rate, flow along x, "
                                               "its gradient along `gradient` (x and it periodic)", "1/s")
    shear_velocity: Optional[Number] = about(None, "Lees-Edwards shear given as the velocity jump across the "
                                                   "gradient's ends instead of the rate", "m/s")
    gradient: Optional[str] = about(None, "the sheared box's gradient axis, y or z (default z)")


class SetVelocitySpec(_Strict):
    """Velocities set when the stage starts."""
    particles: Union[Literal["all"], list[Whole]] = about("all", "all, or the indices of the particles set")
    velocity: Optional[Vector] = about(None, "their velocity", "m/s")
    angular_velocity: Optional[Vector] = about(None, "their angular velocity", "rad/s")


class WallMotionSpec(MotionSpec):
    """A wall's motion from this stage on (``velocity``, ``rotate``: for a plane or cylinder the
    rotation moves its surface, about its own point)."""
    wall: str = about(..., "name of the wall")


class _BondBase(_Strict):
    def parallel_bond(self):
        return ParallelBond(**self.model_dump(exclude={"gap", "pairs"}))


BondSpec = spec_from(ParallelBond, "BondSpec", "Bonds made when the stage starts (Simulation.add_bonds, "
                     "docs/models.md §1.7): between the pairs given or every pair at most gap apart, with "
                     "rollingdem.ParallelBond's parameters (the other keys)", base=_BondBase, first={
                         "gap": described(Optional[Number], None, "bond every pair whose surface gap is at most "
                                          "this (negative: overlapping by at least -gap)", "m"),
                         "pairs": described(Optional[list[tuple[Whole, Whole]]], None,
                                            "the pairs of particle indices to bond (instead of gap)")})


SettledSpec = spec_from(Settled, "SettledSpec", "rollingdem.Settled: the bed at rest")


class UntilSpec(_Strict):
    """What ends a stage early: ``settled``, ``empty``, or a ``measurement``'s quantity (``name.quantity``)
    ``above`` or ``below`` a value, for ``hold`` seconds (0: at one check), or its mean over the
    stage's samples ``known_within`` +- a value at 95 % (over ``min_samples`` samples at least)."""
    settled: Optional[SettledSpec] = about(None, "the bed at rest")
    empty: Optional[bool] = about(None, "no particle left in the scene")
    measurement: Optional[str] = about(None, "a measurement's quantity, name.quantity")
    above: Optional[Number] = about(None, "the quantity above this (in its own unit)", "the quantity's")
    below: Optional[Number] = about(None, "the quantity below this (in its own unit)", "the quantity's")
    known_within: Optional[Number] = about(None, "the quantity's mean over the stage known to +- this at 95 %",
                                           "the quantity's")
    min_samples: int = about(20, "samples the mean needs at least (known_within)")
    hold: Number = about(0.0, "how long the condition must hold (0: at one check)", "s")
    every: Number = about(1e-3, "time between checks", "s")


def _until(value):
    """``until: settled`` / ``until: empty`` as the mappings they stand for."""
    if value == "settled":
        return {"settled": {}}
    if value == "empty":
        return {"empty": True}
    return value


class StageSpec(_Strict):
    """One stage of the run: what changes at its start, and what ends it."""
    name: str = about("run", "label of the stage in outputs")
    duration: Optional[Number] = about(None, "its length (or until, or both: the first ends it)", "s")
    until: Optional[Annotated[UntilSpec, BeforeValidator(_until, json_schema_input_type=Union[
        Literal["settled", "empty"], UntilSpec])]] = about(None, "a condition that ends it: settled, empty, or a "
                                                                 "measurement's quantity")
    max_duration: Optional[Number] = about(None, "the longest it may wait for its condition", "s")
    gravity: Optional[Vector] = about(None, "gravity from this stage on", "m/s^2")
    shear_rate: Optional[Number] = about(None, "the sheared box's shear rate from this stage on (its periodic block "
                                               "gives a shear_rate or shear_velocity)", "1/s")
    remove_walls: list[str] = about([], "names of the walls removed at its start")
    wall_motion: list[WallMotionSpec] = about([], "walls' motions from its start")
    set_velocity: Optional[SetVelocitySpec] = about(None, "velocities set at its start")
    bonds: Optional[BondSpec] = about(None, "bonds made at its start")


class SeriesSpec(_Strict):
    """``series.csv``: the run's quantities at every interval."""
    interval: Number = about(1e-3, "time between rows", "s")
    particles: list[Whole] = about([], "particles whose position and velocity are written too (indices)")


class IntervalSpec(_Strict):
    """An output written at every interval."""
    interval: Number = about(..., "time between them", "s")


ReposeOutputSpec = spec_from(PileAngle, "ReposeOutputSpec", "Measure the pile at the end "
                             "(rollingdem.analysis.repose.repose_angle), with the estimator's options",
                             exclude=("name", "interval", "window"))


class ReportSpec(_Strict):
    """``report.html``: pictures of the scene at each stage's start and end and at ``pictures``
    (times, s)."""
    pictures: list[Number] = about([], "times of pictures besides each stage's start and end", "s")


class OutputSpec(_Strict):
    """What the run writes."""
    directory: Optional[str] = about(None, "the output folder (default rollingdem-output/<name>)")
    report: Optional[ReportSpec] = about(ReportSpec(), "report.html (null: none)")
    repose_angle: Optional[ReposeOutputSpec] = about(None, "the pile's angle of repose at the end")
    time_series: Optional[SeriesSpec] = about(SeriesSpec(), "series.csv (null: none)")
    snapshots: Optional[IntervalSpec] = about(None, "particles and walls as VTU files with a PVD index")
    checkpoint: Optional[IntervalSpec] = about(None, "checkpoints to resume from (--resume)")
    plot: bool = about(True, "series.png and, for a pile, pile.png")


class CaseSpec(_Strict):
    """A case file: the scene, its stages, its outputs."""
    name: str = about("case", "name of the case (the default output folder's)")
    dt: Optional[Number] = about(None, "time step (default: the largest stable step at each stage's start)", "s")
    skin: Optional[Number] = about(None, "neighbor-list skin (default 0.4 x the largest radius)", "m")
    check_timestep: bool = about(True, "refuse a time step above the stable limit")
    backend: Optional[str] = about(None, "where it steps: cpu or cuda (default cpu)")
    gravity: Vector = about((0.0, 0.0, -9.81), "gravity", "m/s^2")
    materials: list[MaterialSpec] = Field(min_length=1, description="the materials, by name")
    pairs: list[PairSpec] = about([], "properties of a pair of materials other than their mix")
    contact: ContactSpec = about(ContactSpec(), "the contact law")
    periodic: Optional[PeriodicSpec] = about(None, "periodic boundaries")
    walls: list[WallSpec] = about([], "planes, cylinders and mesh walls")
    particles: list[ParticleSpec] = about([], "particles: inserted, listed, a rough base, clumps (none: an inflow "
                                              "fills the scene)")
    outlets: list[OutletSpec] = about([], "regions particles are taken out of")
    inflows: list[InflowSpec] = about([], "particles inserted during the run")
    measurements: list[MeasurementSpec] = about([], "quantities sampled during the run")
    stages: list[StageSpec] = Field(min_length=1, description="the stages, in order")
    output: OutputSpec = about(OutputSpec(), "what the run writes")
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
