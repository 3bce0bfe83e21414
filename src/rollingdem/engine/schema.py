"""The engine state's schema: each array of the state declared once, as LAMMPS's ``AtomVec`` field
lists are.

A ``Field`` names an array of ``EngineState``, its dtype, the shape of one row, the value of a new
row, what it has a row for (``per``), whether checkpoints hold it, and its name in the step loop's
record (the compiled passes, and on a GPU the device, get exactly the fields that have one). From
these declarations ``EngineState`` makes the arrays, grows them when particles, walls or bonds come,
takes rows out when particles go, re-sorts them with the storage slots, writes and reads
checkpoints, and builds the step loop's records; the GPU backend moves the records. Adding a
per-particle array is one ``Field`` in ``PARTICLE`` (or ``SCHEMA.declare`` at run time).

The triangle meshes' arrays (``MeshState``) and the neighbor list's (``ContactList``) are declared
by their owners' record types (``MESH_RECORD``, ``layout.ListArrays``): their rows are not one per
particle (candidate entries, list entries, vertices) and their owners grow and carry them.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses

import numpy as np

from rollingdem.engine.layout import MESH_MOTION_SIZE
from rollingdem.physics.records import (BOND_LOAD_SIZE, BOND_PARAMETERS, BOND_STATE, ENERGY_CHANNELS,
                                        WALL_GEOMETRY_SIZE, WALL_LOAD_SIZE)

#: what a field has a row for
PER_PARTICLE = "particle"
PER_BOND = "bond"
PER_WALL = "wall"
PER_PARTICLE_WALL = "particle_wall"  # a row per particle and wall, particle i's at i * walls + w
PER_CLUMP = "clump"  # a row per clump (a rigid body of member spheres)
HISTORY = "history"  # a width: the contact law's history size, known when the state is made


@dataclasses.dataclass(frozen=True)
class Field:
    """One array of the engine state.

    name: the ``EngineState`` attribute and the checkpoint's key.
    dtype: numpy dtype of its values.
    width: the shape of one row: () a scalar, (3,) a vector; ``HISTORY`` stands for the contact
        law's history size.
    fill: the value of a new row.
    per: what it has a row for (``PER_PARTICLE``, ``PER_BOND``, ``PER_WALL``, ``PER_PARTICLE_WALL``).
    record: its name in the step loop's record ("" for ``name``); None: not in the step loop.
    saved: whether checkpoints hold it (a field derived from others is made again on restore).
    lazy: no rows until one holds other than ``fill`` (``energy`` until a run sums it, ``fixed``
        until a particle is fixed): the compiled loops test the length and skip it.
    settable: whether a user may set it (``Simulation.set_particle_field``); not the engine's own
        bookkeeping (ids, images crossed, contact counts, ...).
    doc: what it holds, with its unit.
    """

    name: str
    dtype: type = np.float64
    width: tuple = ()
    fill: float = 0
    per: str = PER_PARTICLE
    record: str | None = ""
    saved: bool = True
    lazy: bool = False
    settable: bool = True
    doc: str = ""

    def row_shape(self, history_size: int) -> tuple:
        return tuple(history_size if w == HISTORY else w for w in self.width)

    def rows(self, count: int, history_size: int, values=None) -> np.ndarray:
        """``count`` rows: ``values`` (broadcast) or ``fill``."""
        shape = (count,) + self.row_shape(history_size)
        if values is None:
            return np.full(shape, self.fill, dtype=self.dtype)
        values = np.asarray(values, dtype=self.dtype)
        if values.size == int(np.prod(shape)):
            return np.ascontiguousarray(values.reshape(shape))
        return np.ascontiguousarray(np.broadcast_to(values, shape))

    @property
    def record_name(self) -> str | None:
        return self.name if self.record == "" else self.record


PARTICLE = (
    Field("x", width=(3,), doc="position (m)"),
    Field("v", width=(3,), doc="velocity (m/s)"),
    Field("w", width=(3,), doc="angular velocity (rad/s)"),
    Field("f", width=(3,), doc="force (N)"),
    Field("t", width=(3,), doc="torque (N m)"),
    Field("radius", doc="radius (m)"),
    Field("mass", doc="mass (kg)"),
    Field("inertia", doc="moment of inertia (kg m^2)"),
    Field("mat", np.int32, doc="material index"),
    Field("ids", np.int64, settable=False, doc="the index the user knows (storage slots are re-sorted)"),
    Field("x_ref", width=(3,), settable=False, doc="position at the last neighbor-list build (m)"),
    Field("energy", width=(len(ENERGY_CHANNELS),), lazy=True, settable=False,
          doc="dissipated energy per ENERGY_CHANNELS (J); no rows while a run does not sum it"),
    Field("contacts", np.int32, settable=False, doc="contacts of the last step"),
    Field("image", np.int32, width=(3,), settable=False, doc="periodic images crossed: the unwrapped position is x + image L"),
    Field("fixed", np.uint8, lazy=True,
          doc="1: a fixed particle (never moves; walls and gravity skip it; its contacts take the free "
              "partner's mass and rolling inertia, as a wall's); no rows while no particle is fixed"),
    Field("clump", np.int64, fill=-1, lazy=True, settable=False,
          doc="the clump (rigid body) the particle is a member of, -1 none: the clump moves it, the neighbor "
              "list leaves out its pairs with its clump's other members; no rows while there is no clump"),
    Field("body_offset", width=(3,), lazy=True, settable=False,
          doc="a clump member's centre in its clump's principal frame, from the clump's centre of mass (m); "
              "rows while there is a clump"),
    Field("tags", np.int64, record=None, settable=False, doc="each particle's number for good (VTK id); ids are renumbered "
                                              "when particles go"),
)

BOND = (
    Field("bond_pairs", np.int64, width=(2,), per=PER_BOND,
          doc="the two particles' slots, i then j (the bond normal is j to i)"),
    Field("bond_state", width=(len(BOND_STATE),), per=PER_BOND, doc="the bond's load and frame (BOND_STATE)"),
    Field("bond_parameters", width=(len(BOND_PARAMETERS),), per=PER_BOND, doc="BOND_PARAMETERS"),
    Field("bond_status", np.int64, per=PER_BOND, doc="BOND_INTACT, or the mode it broke in"),
    Field("bond_load", width=(BOND_LOAD_SIZE,), per=PER_BOND,
          doc="the last step's force on i and torques on i and j"),
)
CLUMP = (
    Field("clump_x", width=(3,), per=PER_CLUMP,
          doc="centre of mass (m); across a periodic boundary it is not wrapped, its members are"),
    Field("clump_v", width=(3,), per=PER_CLUMP, doc="velocity of the centre of mass (m/s)"),
    Field("clump_q", width=(4,), per=PER_CLUMP,
          doc="orientation: the unit quaternion (w, x, y, z) turning the principal frame into the space frame"),
    Field("clump_L", width=(3,), per=PER_CLUMP, doc="angular momentum about the centre of mass, space frame (kg m^2/s)"),
    Field("clump_mass", per=PER_CLUMP, doc="mass (kg)"),
    Field("clump_moments", width=(3,), per=PER_CLUMP, doc="principal moments of inertia (kg m^2)"),
    Field("clump_f", width=(3,), per=PER_CLUMP, doc="the members' forces summed at the last step (N)"),
    Field("clump_t", width=(3,), per=PER_CLUMP,
          doc="the members' torques and moments of their forces about the centre of mass, summed (N m)"),
)
#: each clump's members, made from ``clump`` (``EngineState.index_clumps``): CSR rows (clumps + 1)
#: and the members' slots, each row in the members' order (by tag: the order forces are summed in,
#: whatever the slots); empty without clumps
CLUMP_INDEX = ("clump_start", "clump_members")

#: each particle's bonds, made from ``bond_pairs`` (``EngineState.index_bonds``): CSR rows (n + 1)
#: of each particle's bond ends, and the ends (2 b for bond b's i, 2 b + 1 for its j), each row in
#: ascending order; empty without bonds
BOND_INDEX = ("bond_start", "bond_ends")

WALL = (
    Field("wall_kind", np.int32, per=PER_WALL, record="kind", doc="WALL_PLANE, WALL_CYLINDER, WALL_MESH"),
    Field("wall_geom", width=(WALL_GEOMETRY_SIZE,), per=PER_WALL, record="geometry",
          doc="the geometry row (rollingdem.scene.walls)"),
    Field("wall_vel", width=(3,), per=PER_WALL, record="velocity", doc="velocity (m/s)"),
    Field("wall_omega", width=(3,), per=PER_WALL, record="angular_velocity", doc="angular velocity (rad/s)"),
    Field("wall_mat", np.int32, per=PER_WALL, record="material", doc="material index"),
    Field("wall_program", width=(MESH_MOTION_SIZE,), per=PER_WALL, record="program",
          doc="the wall's motion row (engine.layout.MESH_MOTION; moved by it unless its program is steady)"),
    Field("wall_geom_built", width=(WALL_GEOMETRY_SIZE,), fill=np.nan, per=PER_WALL, record="geometry_built",
          saved=False, doc="the geometry row when ``wall_near`` was made (NaN: never)"),
    Field("wall_moved", np.uint8, fill=1, per=PER_WALL, record="moved", saved=False,
          doc="whether the geometry differs from ``wall_geom_built`` (engine.wall_candidates)"),
    Field("whist", width=(HISTORY,), per=PER_PARTICLE_WALL, record="history",
          doc="contact history of particle i and wall w"),
    Field("wtouch", np.uint8, per=PER_PARTICLE_WALL, record="touching", saved=False,
          doc="whether that contact existed at the last step (made from whist)"),
    Field("wall_near", np.uint8, fill=1, per=PER_PARTICLE_WALL, record="near", saved=False,
          doc="whether wall w lay within R_i + skin/2 of particle i at the last neighbor-list build"),
    Field("wall_load", width=(WALL_LOAD_SIZE,), per=PER_PARTICLE_WALL, record="load",
          doc="that contact's load at the last step (WALL_LOAD)"),
)

#: the triangle meshes' arrays in the walls' record, after the fields of ``WALL`` (``MeshState.arrays``),
#: the triangles of all meshes in one array, each mesh's vertices and triangles contiguous
MESH_RECORD = (
    "reference",         # (vertices, 3) vertex positions where the mesh's present motion began (m)
    "vertices",          # (vertices, 3) vertex positions now (m)
    "built",             # (vertices, 3) vertex positions when the candidate lists were built (m)
    "vertex_start",      # (meshes + 1,) int64 each mesh's first vertex
    "triangles",         # (triangles, 3) int64 vertex indices
    "neighbors",         # (triangles, 3) int64 the triangle across edge ab, bc, ca; -1 on a free edge
    "triangle_mesh",     # (triangles,) int32 the mesh of each triangle
    "motion",            # (meshes, MESH_MOTION_SIZE)
    "mesh_material",     # (meshes,) int32
    "candidate_start",   # (n + 1,) int64 CSR rows: the triangles within R_i + skin of each sphere
    "candidates",        # (capacity,) int64 their triangles, built with the neighbor list
    "candidate_gap",     # (n,) the least distance to them minus R_i, at the build (m); 0: unknown
    "touch_triangle",    # (capacity,) int64 scratch of a sphere's contacts, in its own candidate rows:
    "touch_feature",     # (capacity,) int64   triangle, feature (rollingdem.physics.mesh.FACE ...),
    "touch_point",       # (capacity, 3)       contact point and slot
    "touch_slot",        # (capacity,) int64
    "slot_triangle",     # (n, MESH_SLOTS) int64 the triangle of each mesh contact slot, -1 free
    "mesh_history",      # (n * MESH_SLOTS, history size) the slot's contact history
    "mesh_load",         # (n * MESH_SLOTS, WALL_LOAD_SIZE) the slot's load at the last step
    "mesh_error",        # (n,) int64 1: more mesh contacts than MESH_SLOTS, 2: passed through the
                         #   surface; plus 4 x the mesh (the step stops as for a particle too fast)
    "grid",              # (len(MESH_GRID),) the triangle grid's shape
    "grid_start",        # (cells + 1,) int64 CSR rows: the triangles binned in each cell of the grid
    "grid_items",        # (entries,) int64
    "motion_table",      # (rows, len(MOTION_TABLE_ROW)) the rows of every wall's motion table (planes' too)
)


class Schema:
    """The declared fields, and the step loop's record types made from them."""

    def __init__(self, particle, bond, wall, clump):
        self.fields = {PER_PARTICLE: list(particle), PER_BOND: list(bond), PER_WALL: [], PER_PARTICLE_WALL: [],
                       PER_CLUMP: list(clump)}
        for f in wall:
            self.fields[f.per].append(f)
        self._types = {}

    def of(self, per: str) -> list[Field]:
        return self.fields[per]

    def all(self) -> list[Field]:
        """Every declared field: the particles', the bonds', the walls', the particle-wall ones, the clumps'."""
        return [f for per in (PER_PARTICLE, PER_BOND, PER_WALL, PER_PARTICLE_WALL, PER_CLUMP) for f in self.fields[per]]

    def declare(self, field: Field) -> None:
        """Add a field (its name new): every state made afterwards has it."""
        if any(f.name == field.name for fields in self.fields.values() for f in fields):
            raise ValueError(f"a state field named {field.name!r} is declared already")
        self.fields[field.per].append(field)

    @contextlib.contextmanager
    def declared(self, field: Field):
        """``field`` declared inside the block only (tests)."""
        self.declare(field)
        try:
            yield field
        finally:
            self.fields[field.per].remove(field)

    def _record_type(self, name: str, names: tuple):
        key = (name, names)
        if key not in self._types:
            self._types[key] = collections.namedtuple(name, names)
        return self._types[key]

    def particle_record(self):
        """The step loop's ``ParticleArrays`` type: the particles' fields, the bonds', the bond index,
        the clumps' fields and the clump index."""
        names = tuple(f.record_name for per in PARTICLE_RECORD for f in self.fields[per]
                      if f.record_name is not None) + BOND_INDEX + CLUMP_INDEX
        return self._record_type("ParticleArrays", names)

    def wall_record(self):
        """The step loop's ``WallArrays`` type: the walls' fields, then the meshes' (``MESH_RECORD``)."""
        names = tuple(f.record_name for per in (PER_WALL, PER_PARTICLE_WALL) for f in self.fields[per]
                      if f.record_name is not None) + MESH_RECORD
        return self._record_type("WallArrays", names)


#: the kinds of field in the particles' record, in its order (the bond index and the clump index follow)
PARTICLE_RECORD = (PER_PARTICLE, PER_BOND, PER_CLUMP)
SCHEMA = Schema(PARTICLE, BOND, WALL, CLUMP)
# The declared schema's record types, bound to this module's names: Numba's disk cache keys a
# compiled function by its argument types and pickles a namedtuple's class by reference only when
# the class is the module attribute of its name; a class it cannot find so is pickled by value and
# never matches in the next process, which would compile the whole step loop again in each one. A
# field declared at run time makes new types, pickled by value: they compile anew in each process
# (and a cache written with them never breaks a process that does not declare the field).
ParticleArrays = SCHEMA.particle_record()
WallArrays = SCHEMA.wall_record()
