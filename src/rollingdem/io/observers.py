"""What a run writes while it goes: time series, snapshots, checkpoints (observers,
``rollingdem.scene.schedule.Observer``).

Each observer has an ``interval`` in simulated seconds (rounded to whole steps) and is called by
``Simulation.run`` between calls of the step loop, never inside the compiled loop. Files are flushed as they
are written, so a run that fails leaves what it had written readable.
"""

from __future__ import annotations

import base64
import csv
import hashlib
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from rollingdem.errors import ParameterError, check_integer
from rollingdem.scene.schedule import Observer
from rollingdem.scene.walls import INACTIVE


class TimeSeries(Observer):
    """CSV time series: time, kinetic energies, contacts, dissipated energies, chosen particles.

    Columns: ``time, step, kinetic_translational, kinetic_rotational, kinetic_total, contacts,
    dissipated_normal_damping, dissipated_sliding, dissipated_rolling, dissipated_twisting``; for
    each chosen particle p, ``p{p}_x .. p{p}_z, p{p}_vx .., p{p}_wx .., p{p}_tx ..`` (position m,
    velocity m/s, angular velocity rad/s, torque N m); and for each wall in place when the series
    starts (by name, or ``#k``), ``wall_{name}_fx .. fz, wall_{name}_tx .. tz``: the force on it (N)
    and its torque (N m) about its point (a mesh's turning point, default its centroid), empty once
    it is removed (``Simulation.wall_loads``); for each outlet and inflow (by name, or ``#k``),
    ``outlet_{name}_count``, ``outlet_{name}_mass`` (taken out, cumulative, kg) and
    ``inflow_{name}_count``, ``_mass``, ``_shortfall`` (inserted, cumulative; due but not placed at
    its last action). With bonds when the series starts: ``bonds_intact``, ``bonds_broken_tension``,
    ``bonds_broken_shear``. A chosen particle is the one with that ``particle_ids`` number; its columns
    are empty once an outlet has taken it out.
    """

    def __init__(self, path, interval: float, particles=()):
        super().__init__(interval)
        self.path = Path(path)
        if isinstance(particles, (str, bytes)) or not hasattr(particles, "__iter__"):
            raise ParameterError(f"time series particles = {particles!r} is not allowed: must be a list of particle "
                                 "indices")
        self.particles = [check_integer("time series particle", p, low=0) for p in particles]
        self._file = None
        self._writer = None
        self._walls = None  # the walls' keys, fixed when the series starts
        self._boundaries = None  # the outlets' and inflows' columns, as well
        self._bonds = None  # and the bond counts' (none without bonds)

    def columns(self):
        cols = ["time", "step", "kinetic_translational", "kinetic_rotational", "kinetic_total", "contacts",
                "dissipated_normal_damping", "dissipated_sliding", "dissipated_rolling", "dissipated_twisting"]
        for p in self.particles:
            for q in ("x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz", "tx", "ty", "tz"):
                cols.append(f"p{p}_{q}")
        for name in self._walls or ():
            cols += [f"wall_{name}_{q}" for q in ("fx", "fy", "fz", "tx", "ty", "tz")]
        return cols + list(self._boundaries or ()) + list(self._bonds or ())

    def check(self, sim):
        for p in self.particles:
            if not 0 <= p < sim.n_particles:
                raise ParameterError(f"time series particle = {p} is not allowed: must be in [0, {sim.n_particles - 1}]")

    def start(self, sim):
        self.check(sim)
        super().start(sim)
        sim.track_energy = True  # the dissipated-energy columns
        if self._walls is None:
            self._walls = list(sim.wall_loads())
            self._boundaries = list(sim.boundary_counts())
            self._bonds = list(sim.bond_counts())
        self.path.parent.mkdir(parents=True, exist_ok=True)
        exists = self.path.exists() and self.path.stat().st_size > 0
        self._file = open(self.path, "a", newline="")
        self._writer = csv.writer(self._file)
        if not exists:
            self._writer.writerow(self.columns())

    def observe(self, sim):
        tr, rot = sim.kinetic_energy()
        diss = sim.dissipated_energy()
        row = [repr(sim.time), sim.step, repr(tr), repr(rot), repr(tr + rot), sim.number_of_contacts()]
        row += [repr(v) for v in diss.values()]
        if self.particles:
            tags = sim.particle_ids
            rows = np.searchsorted(tags, self.particles)
            arrays = (sim.positions, sim.velocities, sim.angular_velocities, sim.torques)
        for p, k in zip(self.particles, rows if self.particles else ()):
            present = k < len(tags) and tags[k] == p
            for arr in arrays:
                row += [repr(float(c)) for c in arr[k]] if present else [""] * 3
        if self._walls:
            loads = sim.wall_loads()
            for name in self._walls:
                load = loads.get(name)
                row += [repr(c) for c in (*load["force"], *load["torque"])] if load else [""] * 6
        if self._boundaries:
            counts = sim.boundary_counts()
            row += [repr(counts[c]) if c in counts else "" for c in self._boundaries]
        if self._bonds:
            counts = sim.bond_counts()
            row += [repr(counts.get(c, 0)) for c in self._bonds]
        self._writer.writerow(row)
        self._file.flush()

    def finish(self, sim, failure=None):
        if self._file:
            self._file.close()
            self._file = None


class VTKSnapshots(Observer):
    """Particle snapshots as VTU files plus a PVD collection that ParaView opens; each wall as its
    own series beside them (``wall_{name}_{step}.vtu``, ``wall_{name}.pvd``: its triangles where they
    are at that time, ``wall_surfaces``), written again only when they have moved: a static wall is
    one file, a moving one goes with the particles.

    Point data: radius (m), velocity (m/s), angular_velocity (rad/s), material (index), fixed (1 for a
    fixed particle), id (``Simulation.particle_ids``: a particle keeps it when others are taken out).
    Field data: time (s), removed (particles the outlets took out so far), and with periodic
    boundaries periodic_box, (x_min, x_max, y_min, y_max, z_min, z_max), NaN along an axis that is
    not periodic. With bonds, ``bonds_{step}.vtu`` / ``bonds.pvd``: each bond a line between its
    particles' centres, with cell data status (0 intact, 1 broken in tension, 2 in shear),
    normal_force (N, tension positive), shear_force (N), twisting_moment and bending_moment (N m).
    With clumps, the particles' point data has clump (the clump a member belongs to, -1 for a
    sphere of its own), and ``clumps_{step}.vtu`` / ``clumps.pvd`` hold each clump's centre of mass
    as a point, with velocity, angular_velocity, mass (kg), orientation (the quaternion w, x, y, z
    of its principal frame) and its principal axes axis_1, axis_2, axis_3 (unit vectors, in the
    order of the principal moments, ascending): ParaView's Glyph filter draws them.
    """

    def __init__(self, directory, interval: float, prefix: str = "particles"):
        super().__init__(interval)
        self.directory = Path(directory)
        self.prefix = prefix
        self._entries: list[tuple[float, str]] = []
        self._mesh_entries: dict[str, list[tuple[float, str]]] = {}

    def start(self, sim):
        super().start(sim)
        self.directory.mkdir(parents=True, exist_ok=True)

    def observe(self, sim):
        name = f"{self.prefix}_{sim.step:09d}.vtu"
        write_vtu(self.directory / name, sim.positions, {
            "radius": sim.radii, "velocity": sim.velocities, "angular_velocity": sim.angular_velocities,
            "material": sim.material_indices.astype(np.int32), "fixed": sim.fixed.astype(np.uint8),
            "id": sim.particle_ids.astype(np.int64)} | self._clump_points(sim), field_data=_field_data(sim))
        self._entries.append((sim.time, name))
        self._write_pvd(self.prefix, self._entries)
        clumps = sim.clumps
        if len(clumps["mass"]):
            clump_name = f"clumps_{sim.step:09d}.vtu"
            write_vtu(self.directory / clump_name, clumps["centre"], {
                "velocity": clumps["velocity"], "angular_velocity": clumps["angular_velocity"],
                "mass": clumps["mass"], "orientation": clumps["orientation"],
                **{f"axis_{k + 1}": np.ascontiguousarray(clumps["axes"][:, :, k]) for k in range(3)}},
                field_data=_field_data(sim))
            entries = self._mesh_entries.setdefault("clumps", [])
            entries.append((sim.time, clump_name))
            self._write_pvd("clumps", entries)
        bonds = sim.bonds()
        if len(bonds):
            import meshio  # deferred: mesh files only

            bond_name = f"bonds_{sim.step:09d}.vtu"
            status = bonds["status"].map({"intact": 0, "tension": 1, "shear": 2}).to_numpy(np.int32)
            data = {"status": [status]} | {q: [bonds[q].to_numpy(float)] for q in
                                           ("normal_force", "shear_force", "twisting_moment", "bending_moment")}
            meshio.write(self.directory / bond_name,
                         meshio.Mesh(sim.positions, [("line", bonds[["i", "j"]].to_numpy(np.int64))], cell_data=data),
                         binary=True)
            entries = self._mesh_entries.setdefault("bonds", [])
            entries.append((sim.time, bond_name))
            self._write_pvd("bonds", entries)
        written = self.__dict__.setdefault("_written", {})
        for label, (vertices, triangles) in wall_surfaces(sim).items():
            key = hashlib.sha1(vertices.tobytes() + triangles.tobytes()).hexdigest()
            if written.get(label) == key:
                continue  # where it was at its last file: ParaView holds that one
            written[label] = key
            import meshio  # deferred: mesh files only

            stem = f"wall_{label}"
            mesh_name = f"{stem}_{sim.step:09d}.vtu"
            meshio.write(self.directory / mesh_name, meshio.Mesh(vertices, [("triangle", triangles)]), binary=True)
            entries = self._mesh_entries.setdefault(stem, [])
            entries.append((sim.time, mesh_name))
            self._write_pvd(stem, entries)

    @staticmethod
    def _clump_points(sim) -> dict:
        """The particles' clump point data, {} while there is no clump."""
        if not len(sim.clumps["mass"]):
            return {}
        return {"clump": sim.particle_field("clump").astype(np.int64)}

    def cut_after(self, step: int) -> None:
        """Remove the snapshot files written after ``step`` (a run resumed from there writes them
        again) and write the collections (``.pvd``) of those kept."""
        for f in self.directory.glob("*.vtu"):
            stem = f.stem.rsplit("_", 1)
            if len(stem) == 2 and stem[1].isdigit() and int(stem[1]) > step:
                f.unlink()
        self._write_pvd(self.prefix, self._entries)
        for name, entries in self._mesh_entries.items():
            self._write_pvd(name, entries)

    def _write_pvd(self, stem, entries):
        lines = ['<?xml version="1.0"?>', '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                 "  <Collection>"]
        for t, name in entries:
            lines.append(f'    <DataSet timestep="{t!r}" group="" part="0" file={quoteattr(name)}/>')
        lines += ["  </Collection>", "</VTKFile>", ""]
        tmp = self.directory / f"{stem}.pvd.tmp"
        tmp.write_text("\n".join(lines))
        tmp.replace(self.directory / f"{stem}.pvd")


#: sides of the polygon a cylinder wall is drawn with in the snapshots
CYLINDER_SEGMENTS = 64


def _nice(length: float) -> float:
    """``length`` rounded up to a power of two (m): a drawn extent that grows in a few steps."""
    return float(2.0 ** np.ceil(np.log2(max(length, 1e-6))))


def wall_surfaces(sim) -> dict:
    """Each wall in place as (vertices (n, 3), triangles (m, 3)), by a file-safe label (its name,
    else its kind and slot): a mesh as it is now; a plane as a square patch about its point,
    covering the particles seen along its normal with two of their largest diameters to spare;
    a cylinder as a ``CYLINDER_SEGMENTS``-sided tube through its radius over its extent (an
    infinite one over the particles' span along its axis, two largest diameters beyond). The
    patch's half side and an infinite tube's ends are rounded out to powers of two, so that they
    change only when the particles spread past them."""
    x = sim.positions
    margin = 4.0 * float(sim.radii.max()) if len(x) else 0.0
    meshes = sim.mesh_walls()
    out = {}
    for k, wall in enumerate(sim.wall_set.slots):
        kind = type(wall).__name__.lower()
        if wall.kind == INACTIVE or kind not in ("plane", "cylinder", "meshwall"):
            continue
        label = "".join(c if c.isalnum() or c in "-_" else "_" for c in wall.name) if wall.name else None
        if kind == "meshwall":
            mesh = meshes[label or f"mesh{k}"]
            out[label or f"mesh{k}"] = (mesh.vertices, mesh.triangles)
            continue
        point = np.asarray(wall.point, float)
        axis = np.asarray(wall.normal if kind == "plane" else wall.axis, float)
        u = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(axis, u)
        rel = x - point
        if kind == "plane":
            half = _nice(float(np.abs(np.column_stack([rel @ u, rel @ v])).max(initial=0.0)) + margin)
            corners = [point + half * (a * u + b * v) for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
            out[label or f"plane{k}"] = (np.array(corners), np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64))
            continue
        s0, s1 = wall.extent
        if not np.isfinite(s0) or not np.isfinite(s1):
            along = rel @ axis
            lo, hi = (float(along.min()) - margin, float(along.max()) + margin) if len(x) else (-wall.radius, wall.radius)
            s0 = s0 if np.isfinite(s0) else -_nice(-lo) if lo < 0 else 0.0
            s1 = s1 if np.isfinite(s1) else _nice(hi) if hi > 0 else 0.0
        n = CYLINDER_SEGMENTS
        phi = 2.0 * np.pi * np.arange(n) / n
        ring = wall.radius * (np.outer(np.cos(phi), u) + np.outer(np.sin(phi), v))
        vertices = np.vstack([point + ring + s0 * axis, point + ring + s1 * axis])
        j = np.arange(n)
        triangles = np.vstack([np.column_stack([j, (j + 1) % n, n + j]),
                               np.column_stack([(j + 1) % n, n + (j + 1) % n, n + j])]).astype(np.int64)
        out[label or f"cylinder{k}"] = (vertices, triangles)
    return out


def _field_data(sim) -> dict:
    out = {"time": np.array([sim.time]), "removed": np.array([sum(o.count for o in sim.outlets)], dtype=np.int64)}
    if sim.periodic:
        box = np.full(6, np.nan)
        for axis, (lo, hi) in sim.periodic.items():
            box[2 * "xyz".index(axis):2 * "xyz".index(axis) + 2] = (lo, hi)
        out["periodic_box"] = box
    return out


def write_vtu(path, points: np.ndarray, point_data: dict, field_data: dict | None = None) -> None:
    """Write points and their point data (and whole-grid field data) as a VTU unstructured grid of
    vertex cells (base64 binary)."""
    n = points.shape[0]

    def data_array(name, arr):
        arr = np.ascontiguousarray(arr)
        if arr.dtype == np.uint8:
            vtype = "UInt8"
        elif arr.dtype.kind == "f":
            arr = arr.astype("<f8")
            vtype = "Float64"
        elif arr.dtype == np.int64:
            arr = arr.astype("<i8")
            vtype = "Int64"
        else:
            arr = arr.astype("<i4")
            vtype = "Int32"
        comps = 1 if arr.ndim == 1 else arr.shape[1]
        raw = arr.tobytes()
        header = np.array([len(raw)], dtype="<u8").tobytes()
        payload = base64.b64encode(header + raw).decode()
        nc = f' NumberOfComponents="{comps}"' if comps > 1 else ""
        return f'        <DataArray type="{vtype}" Name="{name}"{nc} format="binary">{payload}</DataArray>'

    out = ['<?xml version="1.0"?>',
           '<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">',
           "  <UnstructuredGrid>"]
    if field_data:
        out.append("    <FieldData>")
        out += ["  " + data_array(name, arr).replace(" format=", f' NumberOfTuples="{len(arr)}" format=', 1)
                for name, arr in field_data.items()]
        out.append("    </FieldData>")
    out += [f'    <Piece NumberOfPoints="{n}" NumberOfCells="{n}">', "      <PointData>"]
    for name, arr in point_data.items():
        out.append(data_array(name, arr))
    out += ["      </PointData>", "      <Points>", data_array("Points", points.astype(np.float64)),
            "      </Points>", "      <Cells>",
        data_array("connectivity", np.arange(n, dtype=np.int64)),
        data_array("offsets", np.arange(1, n + 1, dtype=np.int64)),
        data_array("types", np.ones(n, dtype=np.uint8)),
        "      </Cells>", "    </Piece>", "  </UnstructuredGrid>", "</VTKFile>", ""]
    Path(path).write_text("\n".join(out))


class Checkpoints(Observer):
    """Periodic checkpoints ``{prefix}_{step}.npz`` (and ``{prefix}_last.npz``)."""

    def __init__(self, directory, interval: float, prefix: str = "checkpoint", keep_all: bool = False):
        super().__init__(interval)
        self.directory = Path(directory)
        self.prefix = prefix
        self.keep_all = keep_all

    def observe(self, sim):
        if self.keep_all:
            sim.checkpoint(self.directory / f"{self.prefix}_{sim.step:09d}.npz")
        sim.checkpoint(self.directory / f"{self.prefix}_last.npz")


__all__ = ["TimeSeries", "VTKSnapshots", "Checkpoints", "write_vtu"]
