"""Case files (YAML or TOML): the same scene as the Python API, read, validated and built.

A case file has the keys ``name``, ``materials``, ``pairs``, ``contact``, ``periodic``, ``walls``,
``particles``, ``outlets``, ``inflows``, ``measurements``, ``stages`` and ``output`` (see
``rollingdem/experiments/default.yaml`` for a complete example). ``load_case`` reads and validates
one against the schema (``rollingdem.io.case_schema``; faults worded by
``rollingdem.io.case_errors``), ``build_simulation`` and ``build_measurements`` make its scene and
measurements, and the stage helpers its stages; ``rollingdem.io.case_check`` refuses before any
run what a run would refuse.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydantic import ValidationError

from rollingdem.errors import ParameterError, check_finite, check_positive, check_vector
from rollingdem.io import case_schema
from rollingdem.io import measurements as ms
from rollingdem.io import rig_measurements as rig
from rollingdem.io.box_measurements import BoxStress
from rollingdem.io.field_measurements import ContinuumFields
from rollingdem.io.case_errors import InCase, format_validation_error
from rollingdem.io.case_schema import (
    CaseSpec,
    ClumpShapeSpec,
    ClumpSpec,
    InsertSpec,
    MassFractionsSpec,
    MeshSpec,
    NormalSpec,
    RoughBaseSpec,
    SieveSpec,
    StageSpec,
    StageWindowSpec,
    UniformSpec,
    UntilSpec,
)
from rollingdem.io.mapping_file import read_mapping
from rollingdem.physics.contact.model import ContactModel
from rollingdem.physics.records import WALL_MESH
from rollingdem.scene.clumps import Clump
from rollingdem.scene.conditions import Empty, Known, Reaches, Settled
from rollingdem.scene.insertion import rough_base
from rollingdem.scene.materials import Material
from rollingdem.scene.mesh import MeshRegion, MeshWall
from rollingdem.scene.periodic import LeesEdwards
from rollingdem.scene.motion import MotionTable, Oscillation, Servo
from rollingdem.scene.regions import BoxRegion, CylinderRegion, Disk, MeshFace, Rectangle
from rollingdem.scene.simulation import Simulation
from rollingdem.scene.size_distributions import Discrete, MassFractions, Normal, SieveCurve, Uniform
from rollingdem.scene.wall_set import check_mesh_size, check_openings
from rollingdem.scene.walls import Cylinder, Plane, surface_speed


def load_case(path_or_dict) -> CaseSpec:
    """Read and validate a case file (YAML, or TOML by extension) or a mapping."""
    data, source = read_mapping(path_or_dict)
    case_schema.material_specs()  # a user's law may declare material properties of its own
    try:
        case = CaseSpec.model_validate(data)
    except ValidationError as err:
        raise ParameterError(format_validation_error(err, source, data)) from None
    if isinstance(path_or_dict, (str, Path)):
        case.base_directory = Path(path_or_dict).parent
    return case


def _clump(spec: ClumpShapeSpec):
    """The ``rd.Clump`` of a case file's clump block."""
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


def _radius(spec):
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
    for k, m in enumerate(case.materials):
        with InCase(f"materials.{k}"):
            sim.set_material(Material(**m.model_dump()))
    for k, p in enumerate(case.pairs):
        with InCase(f"pairs.{k}"):
            sim.set_pair(p.materials[0], p.materials[1],
                         **{c: v for c, v in p.model_dump(exclude={"materials"}).items() if v is not None})


def build_simulation(case: CaseSpec):
    """The Simulation a case describes (materials, walls, particles), before any stage runs."""
    def where(key):
        return InCase(key)

    if not case.particles and not case.inflows:
        raise ParameterError("particles = [] is not allowed without an inflow: give a particle block, or an inflow "
                             "that fills the scene")
    with where("contact"):
        contact = ContactModel(**case.contact.model_dump())
    periodic = {k: v for k, v in case.periodic.model_dump().items() if v is not None} if case.periodic else None
    shear = {k: (periodic or {}).pop(k) for k in ("shear_rate", "shear_velocity", "gradient") if k in (periodic or {})}
    lees_edwards = LeesEdwards(**shear) if shear else None
    for key in ("dt", "skin"):  # top-level keys: refused in their own name, before the periodic block's checks
        if getattr(case, key) is not None:
            check_positive(key, getattr(case, key), "s" if key == "dt" else "m")
    with where("periodic"):
        sim = Simulation(contact=contact, gravity=case.gravity, dt=case.dt, skin=case.skin,
                         check_timestep=case.check_timestep, periodic=periodic, lees_edwards=lees_edwards)
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
                check_openings(wall, sim.particle_set.state, sim.materials, sim.inflows)
    return sim


def _region(r, base: Path | None = None, sim=None):
    """The region of a case block; a mesh region's mesh given as a mesh wall is, or a wall's of ``sim``."""
    if r.type == "disk":
        return Disk(r.center, r.normal, r.radius)
    if r.type == "rectangle":
        return Rectangle(r.center, r.normal, r.size, r.axis)
    if r.type in ("mesh", "mesh_face"):

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
    given = [key for key in ("oscillate", "table", "servo") if getattr(spec, key) is not None]
    if len(given) > 1:
        raise ParameterError(f"{' and '.join(given)} are not allowed together: a wall follows one motion program")
    if not given:
        return None
    key = given[0]
    with InCase(key):
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
    import pandas as pd  # deferred: slow to load, tables only

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


def motion_of(spec, mesh: bool = False, base: Path = Path(".")) -> dict:
    """Keyword arguments of a wall's motion (velocity, angular_velocity, point, motion) from a
    MotionSpec; a ``mesh`` turns about the origin unless its point is given, a plane or cylinder
    about its own."""
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
    if (w.file is None) == (w.shape is None):
        raise ParameterError(f"file = {w.file!r}, shape = {w.shape!r} is not allowed: give exactly one of file "
                             "(an STL or OBJ file) and shape (drum, silo, hopper, disk, box, chute)")
    if w.file is not None:
        path = Path(w.file) if Path(w.file).is_absolute() else base / w.file
        wall = MeshWall.from_file(path, material=w.material, scale=w.scale, name=w.name, weld=w.weld)
    else:
        wall = MeshWall.shape(w.shape, material=w.material, name=w.name, **w.size)
    if w.place is not None:
        from scipy.spatial.transform import Rotation  # deferred: slow to load, used here only

        matrix, about = np.eye(3), np.zeros(3)
        if w.place.rotate is not None:
            axis = np.array(check_vector("place rotate axis", w.place.rotate.axis, unit=True))
            angle = check_finite("place rotate angle", w.place.rotate.angle if w.place.rotate.angle is not None
                                 else float("nan"))
            matrix = Rotation.from_rotvec(np.radians(angle) * axis).as_matrix()
            about = np.array(check_vector("place rotate point", w.place.rotate.point or (0.0, 0.0, 0.0)))
        shift = about - matrix @ about + np.array(check_vector("place translate", w.place.translate))
        wall = MeshWall(wall.mesh.moved(matrix, shift), material=w.material, name=w.name)
    motion = motion_of(w.motion, mesh=True, base=base)
    if motion:
        wall = MeshWall(wall.mesh, material=w.material, name=w.name, **motion)
    wall.check_size = w.check_size
    return wall


def build_measurements(case: CaseSpec, sim) -> dict:
    """The case's measurements by name (``rollingdem.io.measurements``), each checked against the
    scene (its wall or outlet named, its sensor inside the scene)."""
    made = {}
    for k, m in enumerate(case.measurements):
        with InCase(f"measurements.{k}"):
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
                made[m.name] = rig.PileAngle(floor=m.floor, n_slices=m.n_slices, exclude_apex=m.exclude_apex,
                                            exclude_toe=m.exclude_toe, **common)
            elif m.type == "mesh_flow":
                made[m.name] = ms.MeshFlow(mesh=_sensor_mesh(m, case.base_directory), **common)
            elif m.type == "drum_angle":
                made[m.name] = rig.DrumAngle(center=m.center, axis=m.axis, extent=m.extent, **common)
            elif m.type == "fields":
                made[m.name] = ContinuumFields(width=m.width, kernel=m.kernel, cells=m.cells, lower=m.lower,
                                               upper=m.upper, axis=m.axis, vtk=m.vtk, **common)
            elif m.type == "box_stress":
                made[m.name] = BoxStress(pressure_control=m.pressure_control, axes=m.axes, **common)
            elif m.type == "drum_flow":
                made[m.name] = rig.DrumFlow(center=m.center, axis=m.axis, radius=m.radius, wall=m.wall, extent=m.extent,
                                           **common)
            else:
                path = Path(m.file) if Path(m.file).is_absolute() else case.base_directory / m.file
                made[m.name] = rig.SurfaceProfile(points=rig.read_profile(path), shape=m.shape, center=m.center,
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


def stage_conditions(stage: StageSpec, measurements: dict) -> list:
    """The conditions (``rollingdem.scene.conditions``) that end ``stage`` early."""
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
        motion = motion_of(m, mesh=hasattr(wall, "mesh"), base=base)
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
    return ([f"wall {w.name or '(unnamed)'!r}, {w.mesh.report_line()}" for w in sim.walls if w.kind == WALL_MESH]
            + [f"inserted {line}" for line in sim.particle_set.fills])


def default_case_path() -> Path:
    return Path(__file__).parents[1] / "experiments" / "default.yaml"


__all__ = ["CaseSpec", "load_case", "build_simulation", "build_measurements", "stage_conditions",
           "stage_duration", "default_case_path"]
