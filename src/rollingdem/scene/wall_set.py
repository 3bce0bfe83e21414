"""The walls of a scene: adding, removing, moving and naming them, and handing them to the engine.

The engine owns wall motion: it moves planes, cylinders and meshes with their prescribed velocities
and programs (``engine.wall_motion``) at every step (``rollingdem.engine.integrator.move_walls``,
the mesh passes). The ``Wall`` objects a user holds follow it at two sync points, each one call of
``WallSet.refresh``: after every call of the step loop (``Schedule.run``, the only code that moves
walls, and once more as a run ends), and when a checkpoint's state is restored
(``WallSet.restore``); so between runs, and between the calls of the step loop where operations and
observers act, every object is where the engine has its wall. A changed wall goes back to the engine
(``WallSet.hand_over``), a program that did not change with its row."""

from __future__ import annotations

import numpy as np

from rollingdem.engine.layout import MESH_MOTION as MO
from rollingdem.engine.layout import MOTION_TABLE_ROW
from rollingdem.errors import ParameterError, check_vector, short_repr
from rollingdem.physics.records import WALL_MESH
from rollingdem.scene.boundaries import Inflow
from rollingdem.scene.mesh import MeshWall, TriangleMesh
from rollingdem.scene.motion import check_program, motion_row
from rollingdem.scene.walls import INACTIVE, Wall, wall_from_dict


class Removed(Wall):
    """The place of a removed wall in ``WallSet.slots``; ``wall`` is the wall that was there."""

    kind = INACTIVE

    def __init__(self, wall=None):
        super().__init__(None)
        self.wall = wall

    def __repr__(self):
        return f"<removed wall {self.wall!r}>"


#: a mesh more than this many mean particle diameters across is refused (``check_mesh_size``): a
#: DEM scene that large would hold some 10^12 spheres; a file in mm read as m is 1000 times too large
MAX_MESH_DIAMETERS = 1e4


def check_mesh_size(wall, radius) -> None:
    """Refuse a mesh smaller than one particle, or larger than ``MAX_MESH_DIAMETERS`` mean
    diameters (unless its ``check_size`` is off): a file in mm read as m, or the reverse."""
    if not len(radius) or not getattr(wall, "check_size", True):
        return
    extent = float(np.ptp(wall.mesh.vertices, axis=0).max())
    diameter = 2.0 * float(radius.min())
    if extent < diameter:
        raise ParameterError(f"{wall.mesh.label}: the mesh is {extent:.3g} m across, smaller than one particle "
                             f"(diameter {diameter:.3g} m): a unit mistake? give its scale (0.001 for a file "
                             "in mm)")
    mean = 2.0 * float(np.mean(radius))
    if extent > MAX_MESH_DIAMETERS * mean:
        raise ParameterError(f"{wall.mesh.label}: the mesh is {extent:.3g} m across, {extent / mean:.3g} mean particle "
                             f"diameters ({mean:.3g} m), more than {MAX_MESH_DIAMETERS:.0f}: a unit mistake? give its "
                             "scale (0.001 for a file in mm), or check_size: false to accept it")


def check_openings(wall, state, materials, inflows) -> None:
    """Refuse a mesh with an opening (``TriangleMesh.openings``) that the real particles pass and
    the parcels standing for them do not: narrower than the largest parcel and wider than the
    smallest real particle, of those in the scene and its inflows. The material would flow
    through it; its parcels would jam. ``state``: the engine state, ``materials``: the material
    table, ``inflows``: the scene's."""
    st = state
    alpha = materials.coarse_graining_factors()
    inflows = [i.radius for i in inflows if getattr(i.radius, "alpha", 1.0) != 1.0]
    coarse = alpha[st.mat[:st.n]] != 1.0
    if not coarse.any() and not inflows:
        return
    parcel = 2.0 * max([float(st.radius[:st.n][coarse].max(initial=0.0))] + [d.max_radius for d in inflows])
    real = 2.0 * min([float((st.radius[:st.n][coarse] / alpha[st.mat[:st.n]][coarse]).min(initial=np.inf))]
                     + [d.real.min_radius for d in inflows])
    for centre, width in wall.mesh.openings():
        if real < width < parcel:
            at = ", ".join(f"{v if abs(v) > 1e-9 * width else 0.0:.4g}" for v in centre)  # no -4e-19
            raise ParameterError(f"{wall.mesh.label}: coarse_graining = {alpha.max():g} is not allowed with its opening at "
                                 f"({at}) m, {width:.3g} m wide: the real particles (from {real:.3g} m) pass it, the "
                                 f"parcels (to {parcel:.3g} m) do not; lower the material's coarse_graining or widen "
                                 "the opening")


class WallSet:
    """The walls of ``sim`` in the order they were added. A removed wall keeps its slot (labels and
    checkpoints number walls as the user added them) but leaves the engine, whose per-sphere wall
    history would otherwise keep a row per sphere for it and whose gather would test it at every
    step. ``in_engine``: the planes and cylinders in place, in the engine's order (meshes are in
    ``state.meshes.names``)."""

    def __init__(self, state, materials, schedule, on_change):
        self.state = state  # the engine state, the same object for the simulation's life
        self.materials, self.schedule, self.on_change = materials, schedule, on_change
        self.slots: list[Wall] = []
        self.in_engine: list[Wall] = []

    def in_place(self) -> list[Wall]:
        return [w for w in self.slots if w.kind != INACTIVE]

    def add(self, wall: Wall) -> Wall:
        """``Simulation.add_wall``."""
        materials = self.materials
        if not isinstance(wall, Wall) or isinstance(wall, Removed):
            raise ParameterError(f"wall = {wall!r} is not allowed: must be a rollingdem.Plane, Cylinder or MeshWall")
        if any(w is wall for w in self.slots):
            raise ParameterError(f"wall = {self.label(wall)} is not allowed: it is part of this simulation already")
        if wall.material is None:
            if not len(materials):
                raise ParameterError("wall material = None is not allowed: add a material first or name one")
            wall.material = materials.materials[0].name
        materials.index(wall.material)
        if wall.kind == WALL_MESH:
            check_mesh_size(wall, self.state.radius)
            check_openings(wall, self.state, self.materials, self.schedule.of(Inflow))
        self.slots.append(wall)
        self.hand_over()
        return wall

    def check_scene(self) -> None:
        """``check_mesh_size`` and ``check_openings`` of each mesh wall in place against the particles
        now in the scene."""
        for wall in self.in_place():
            if wall.kind == WALL_MESH:
                check_mesh_size(wall, self.state.radius)
                check_openings(wall, self.state, self.materials, self.schedule.of(Inflow))

    def remove(self, wall: Wall | str) -> None:
        """``Simulation.remove_wall``."""
        wall = self.own(wall)
        slot = next(k for k, w in enumerate(self.slots) if w is wall)
        self.slots[slot] = Removed(wall)
        self.hand_over()

    def own(self, wall: Wall | str) -> Wall:
        """A wall in place, given as the object or by name; else a ParameterError that names it and
        says why (removed already, never added, no such name)."""
        removed = [w.wall for w in self.slots if isinstance(w, Removed) and w.wall is not None]
        if isinstance(wall, str):
            named = [w for w in self.in_place() if w.name == wall]
            if named:
                return named[0]
            if any(w.name == wall for w in removed):
                raise ParameterError(f"wall = {wall!r} is not allowed: it was removed already")
            names = ", ".join(repr(w.name) for w in self.in_place() if w.name) or "none"
            raise ParameterError(f"wall = {wall!r} is not allowed: no wall has that name; wall names are {names}")
        if not isinstance(wall, Wall) or isinstance(wall, Removed):
            raise ParameterError(f"wall = {short_repr(wall)} is not allowed: must be a wall of this simulation (the "
                                 "rollingdem.Plane or Cylinder, or its name)")
        if any(w is wall for w in self.slots):
            return wall
        raise ParameterError(f"wall = {self.label(wall)} is not allowed: "
                             + ("it was removed already" if any(w is wall for w in removed) else
                                "it is not part of this simulation (add it with add_wall)"))

    def set_velocity(self, wall: Wall | str, velocity=None, angular_velocity=None, point=None) -> None:
        """``Simulation.set_wall_velocity``."""
        wall = self.own(wall)
        if velocity is not None:
            wall.velocity = check_vector("wall velocity", velocity)
        if angular_velocity is not None:
            wall.set_angular_velocity(angular_velocity)
        if point is not None:
            if wall.kind != WALL_MESH:
                raise ParameterError(f"point = {point!r} is not allowed for wall {self.label(wall)}: a plane or "
                                     "cylinder turns about its own point; only a mesh wall takes a rotation point")
            wall.point = check_vector("mesh point", point)
        wall.restart_motion = True
        if wall.motion is not None:
            check_program(wall, wall.motion, self.label(wall))
        self.hand_over()

    def set_motion(self, wall: Wall | str, motion) -> None:
        """``Simulation.set_wall_motion``."""
        wall = self.own(wall)
        wall.set_motion(motion)
        self.hand_over()

    def label(self, wall) -> str:
        """How a refusal names a wall: its name, else its slot and type."""
        if wall.name:
            return repr(wall.name)
        slot = next((k for k, w in enumerate(self.slots) if w is wall or getattr(w, "wall", None) is wall), None)
        kind = type(wall).__name__.lower()
        return f"#{slot} ({kind})" if slot is not None else f"({kind}, unnamed)"

    def key(self, wall) -> str:
        """A wall's key in ``loads``: its name, else '#slot'."""
        if wall.name:
            return wall.name
        return f"#{next(k for k, w in enumerate(self.slots) if w is wall)}"

    def hand_over(self) -> None:
        """Give the engine the walls in place, each keeping its contact history (and its motion, unless
        that changed: a changed motion starts again from where the wall is now)."""
        st, materials = self.state, self.materials
        active = [wl for wl in self.in_place() if wl.kind != WALL_MESH]
        meshes = [wl for wl in self.in_place() if wl.kind == WALL_MESH]
        rows, table = self._motion_rows(active + meshes)
        carry = [next((k for k, old in enumerate(self.in_engine) if old is wl), -1) for wl in active]
        st.set_walls(carry, wall_kind=[wl.kind for wl in active], wall_geom=[wl.geometry() for wl in active],
                     wall_vel=[r[[MO.tvx, MO.tvy, MO.tvz]] for r in rows[:len(active)]],
                     wall_omega=[wl.angular_velocity for wl in active],
                     wall_mat=[materials.index(wl.material) for wl in active], wall_program=rows[:len(active)])
        self.in_engine = active
        carry = [next((k for k, old in enumerate(st.meshes.names) if old is wl), -1) for wl in meshes]
        described = []
        for wl, row in zip(meshes, rows[len(active):]):
            described.append({**wl.engine_mesh(materials.index(wl.material)), "motion": row})
            if wl.motion is not None and not wl.restart_motion and wl.engine_motion_reference is not None:
                described[-1]["reference"] = wl.engine_motion_reference
        st.meshes.motion_table = table
        st.set_meshes(described, carry, meshes)
        for wl in active + meshes:
            wl.restart_motion = False
        self.on_change()

    @staticmethod
    def _motion_rows(walls) -> tuple:
        """Each wall's motion row (its carried one, unless its motion changed or it has none to
        carry) and the walls' motion tables in one array, each row pointing at its own."""
        rows, tables, start = [], [], 0
        for wl in walls:
            if wl.motion is not None and not wl.restart_motion and wl.engine_motion_row is not None:
                row = wl.engine_motion_row.copy()
            else:
                row = motion_row(wl, wl.point)
            part = wl.motion.table_rows() if wl.motion is not None else None
            if part is not None:
                row[MO.first], row[MO.last] = start, start + len(part)
                start += len(part)
                tables.append(part)
            rows.append(row)
        table = np.concatenate(tables) if tables else np.zeros((0, len(MOTION_TABLE_ROW)))
        return rows, np.ascontiguousarray(table)

    def refresh(self) -> None:
        """Copy where the engine has moved each wall (and its motion row) to its ``Wall`` object."""
        st = self.state
        for k, (wl, g) in enumerate(zip(self.in_engine, st.wall_geom)):
            wl.update_from_geometry(g)
            wl.engine_motion_row = st.wall_program[k].copy()
        ms = st.meshes
        for m, wl in enumerate(ms.names):
            v0, v1 = ms.vertex_start[m], ms.vertex_start[m + 1]
            mo = ms.motion[m]
            wl.update_from_engine(ms.vertices[v0:v1], mo[[MO.ox, MO.oy, MO.oz]])
            wl.engine_motion_row, wl.engine_motion_reference = mo.copy(), ms.reference[v0:v1].copy()

    def loads(self, point=None) -> dict:
        """``Simulation.wall_loads``."""
        st = self.state
        out = {}
        planes = (st.wall_load.reshape(st.n, st.n_walls, -1).sum(axis=0) if st.n and st.n_walls
                  else np.zeros((st.n_walls, 6)))
        meshes = st.meshes.loads()
        rows = [(wl, planes[k]) for k, wl in enumerate(self.in_engine)]
        rows += [(wl, meshes[k]) for k, wl in enumerate(st.meshes.names)]
        for wl, load in rows:
            about = np.array(wl.torque_point() if point is None else check_vector("torque point", point))
            force = load[0:3]
            torque = load[3:6] - np.cross(about, force)
            out[self.key(wl)] = {"force": tuple(float(c) for c in force),
                                 "torque": tuple(float(c) for c in torque),
                                 "point": tuple(float(c) for c in about)}
        return out

    def meshes(self) -> dict:
        """``Simulation.mesh_walls``."""
        out = {}
        for k, wl in enumerate(self.slots):
            if wl.kind == WALL_MESH:
                label = "".join(c if c.isalnum() or c in "-_" else "_" for c in wl.name) if wl.name else f"mesh{k}"
                out[label] = wl.mesh
        return out

    def describe(self) -> list:
        """Each slot for a checkpoint: None for a removed wall (a mesh's triangles go in the arrays)."""
        materials = self.materials
        return [None if wl.kind == INACTIVE else {**wl.describe(), "name": wl.name,
                                                    "material": materials[wl.material].name}
                for wl in self.slots]

    def restore(self, described: list) -> None:
        """The walls of a checkpoint (``describe``), on a state restored from its arrays."""
        st = self.state
        in_place = np.flatnonzero(st.wall_kind != INACTIVE)
        if len(in_place) < len(st.wall_kind):  # an older checkpoint keeps removed walls in the engine
            st.set_walls(in_place.tolist(), wall_kind=st.wall_kind[in_place], wall_geom=st.wall_geom[in_place],
                         wall_vel=st.wall_vel[in_place], wall_omega=st.wall_omega[in_place],
                         wall_mat=st.wall_mat[in_place])
        ms, m = st.meshes, 0
        self.slots = []
        for wd in described:
            if wd is None:
                self.slots.append(Removed(None))
            elif wd["type"] == "mesh":  # the meshes in the engine's order, their triangles from the arrays
                v0, v1 = ms.vertex_start[m], ms.vertex_start[m + 1]
                t0, t1 = ms.triangle_start[m], ms.triangle_start[m + 1]
                mesh = TriangleMesh(ms.vertices[v0:v1], ms.triangles[t0:t1] - v0, label=f"mesh {wd.get('name')!r}")
                self.slots.append(MeshWall.from_description(wd, wd["material"], mesh))
                m += 1
            else:
                wd = dict(wd)
                material = wd.pop("material")
                self.slots.append(wall_from_dict(wd, material))
        self.in_engine = [wl for wl in self.in_place() if wl.kind != WALL_MESH]
        for wl, g in zip(self.in_engine, st.wall_geom):
            wl.update_from_geometry(g)
        ms.names = [wl for wl in self.in_place() if wl.kind == WALL_MESH]
        self.refresh()
        for wl in self.in_place():  # the programs go on from the checkpoint's rows
            wl.restart_motion = False
