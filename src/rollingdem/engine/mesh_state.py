"""The triangle meshes' arrays of the engine state (``MeshState``): every mesh's vertices and
triangles in one array, their motion, and per sphere its candidate triangles and contact slots;
``EngineState.meshes`` holds one. docs/architecture.md, "The engine state"."""

from __future__ import annotations

import numpy as np

from rollingdem.engine.layout import LIST_MARGIN, MESH_GRID, MESH_MOTION as MO, MESH_MOTION_SIZE, MESH_SLOTS, MOTION_TABLE_ROW
from rollingdem.physics.records import WALL_LOAD_SIZE


def pad_motion_rows(motion: np.ndarray) -> np.ndarray:
    """Mesh motion rows of an older checkpoint (velocity, angular velocity, point, time) as rows of
    ``layout.MESH_MOTION``: steady, the step's velocity the steady one, the axis's point where it is."""
    if motion.shape[1] == MESH_MOTION_SIZE:
        return motion
    out = np.zeros((motion.shape[0], MESH_MOTION_SIZE))
    out[:, :motion.shape[1]] = motion
    out[:, [MO.tvx, MO.tvy, MO.tvz, MO.twx, MO.twy, MO.twz]] = motion[:, 0:6]
    out[:, [MO.ox, MO.oy, MO.oz]] = motion[:, 6:9] + motion[:, 0:3] * motion[:, 9:10]
    return out


class MeshState:
    """The triangle meshes' arrays of the engine (the walls' record from ``reference``
    on, ``schema.MESH_RECORD``): every mesh's vertices and triangles in one array, their motion, and per sphere the
    candidate triangles and the contact slots. The per-sphere arrays have no rows while there is
    no mesh (a slot's history is 6 rows a sphere)."""

    def __init__(self, history_size: int):
        self.history_size = history_size
        self.n = 0
        self.names: list = []  # the Wall objects, in the engine's order
        self.reference = np.zeros((0, 3))
        self.vertices = np.zeros((0, 3))
        self.built = np.zeros((0, 3))
        self.vertex_start = np.zeros(1, dtype=np.int64)
        self.triangle_start = np.zeros(1, dtype=np.int64)
        self.triangles = np.zeros((0, 3), dtype=np.int64)
        self.neighbors = np.zeros((0, 3), dtype=np.int64)
        self.triangle_mesh = np.zeros(0, dtype=np.int32)
        self.motion = np.zeros((0, MESH_MOTION_SIZE))
        self.material = np.zeros(0, dtype=np.int32)
        self.motion_table = np.zeros((0, len(MOTION_TABLE_ROW)))
        self._grid_arrays()
        self._particle_arrays(0)
        self.allocate(0)

    @property
    def n_triangles(self) -> int:
        return self.triangles.shape[0]

    @property
    def n_meshes(self) -> int:
        return self.motion.shape[0]

    def _particle_arrays(self, rows: int):
        self.candidate_start = np.zeros(rows + 1 if rows else 0, dtype=np.int64)
        self.candidate_gap = np.zeros(rows)  # 0: unknown, never skips
        self.slot_triangle = np.full((rows, MESH_SLOTS), -1, dtype=np.int64)
        self.history = np.zeros((rows * MESH_SLOTS, self.history_size))
        self.load = np.zeros((rows * MESH_SLOTS, WALL_LOAD_SIZE))
        self.mesh_error = np.zeros(rows, dtype=np.int64)

    def _grid_arrays(self, items: int = 0):
        """The triangle grid, to be binned again: up to 64 cells a triangle (at least 32768), ``items``
        entries (at first 64 a triangle)."""
        ntri = self.triangles.shape[0]
        self.grid = np.zeros(len(MESH_GRID))
        self.grid_start = np.zeros(max(64 * ntri, 32768) + 1 if ntri else 0, dtype=np.int64)
        self.grid_items = np.zeros(max(items, 64 * ntri), dtype=np.int64)

    def allocate(self, capacity: int):
        """Room for ``capacity`` candidate entries (the contacts found are kept in them too)."""
        self.candidates = np.zeros(capacity, dtype=np.int64)
        self.touch_triangle = np.zeros(capacity, dtype=np.int64)
        self.touch_feature = np.zeros(capacity, dtype=np.int64)
        self.touch_point = np.zeros((capacity, 3))
        self.touch_slot = np.zeros(capacity, dtype=np.int64)

    def grow(self, needed: int):
        self.allocate(int(needed * LIST_MARGIN) + 16)

    def grow_grid(self, needed: int):
        self._grid_arrays(int(needed * LIST_MARGIN) + 16)

    def resize_particles(self, n: int):
        """Keep the slots of the first spheres, add empty ones up to n (none while there is no mesh)."""
        self.n = n
        if not self.n_meshes:
            return
        old = (self.slot_triangle, self.history, self.load)
        n0 = old[0].shape[0]
        self._particle_arrays(n)
        keep = min(n0, n)
        self.slot_triangle[:keep] = old[0][:keep]
        self.history[:keep * MESH_SLOTS] = old[1][:keep * MESH_SLOTS]
        self.load[:keep * MESH_SLOTS] = old[2][:keep * MESH_SLOTS]
        if self.candidates.shape[0] < 4 * n:
            self.allocate(4 * n)

    def reorder(self, perm):
        """The slots follow their spheres to new storage slots (``EngineState.sort``)."""
        if not self.n_meshes:
            return
        s, h = MESH_SLOTS, self.history_size
        self.slot_triangle = np.ascontiguousarray(self.slot_triangle[perm])
        self.history = np.ascontiguousarray(self.history.reshape(-1, s, h)[perm].reshape(-1, h))
        self.load = np.ascontiguousarray(self.load.reshape(-1, s, WALL_LOAD_SIZE)[perm].reshape(-1, WALL_LOAD_SIZE))
        self.mesh_error = np.ascontiguousarray(self.mesh_error[perm])
        self.candidate_gap = np.ascontiguousarray(self.candidate_gap[perm])
        if len(self.candidate_start) == len(perm) + 1:  # each sphere's candidate row goes with it
            start = self.candidate_start
            lengths = np.diff(start)[perm]
            new_start = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
            total = int(new_start[-1])
            source = np.repeat(start[:-1][perm] - new_start[:-1], lengths) + np.arange(total)
            self.candidates[:total] = self.candidates[source]
            self.candidate_start = new_start

    def set_meshes(self, meshes: list, carry: list):
        """Replace the meshes. Each is a dict of ``vertices``, ``triangles``, ``neighbors``,
        ``material`` and its ``motion`` row (``layout.MESH_MOTION``), with ``reference``, the
        vertices where that motion began (default: ``vertices``, the motion starts now).
        ``carry[m]``: the index new mesh m had before (the contacts with its triangles are kept),
        or -1."""
        old_start, old_slots = self.triangle_start, self.slot_triangle
        nv = [len(m["vertices"]) for m in meshes]
        nt = [len(m["triangles"]) for m in meshes]
        self.vertex_start = np.concatenate([[0], np.cumsum(nv)]).astype(np.int64)
        self.triangle_start = np.concatenate([[0], np.cumsum(nt)]).astype(np.int64)
        cat = (lambda parts, shape, dtype: np.ascontiguousarray(np.concatenate(parts), dtype=dtype) if parts
               else np.zeros(shape, dtype=dtype))
        self.vertices = cat([np.asarray(m["vertices"], dtype=float) for m in meshes], (0, 3), np.float64)
        self.reference = cat([np.asarray(m.get("reference", m["vertices"]), dtype=float) for m in meshes], (0, 3),
                             np.float64)
        self.built = self.vertices.copy()
        self.triangles = cat([np.asarray(m["triangles"]) + v0 for m, v0 in zip(meshes, self.vertex_start)], (0, 3),
                             np.int64)
        self.neighbors = cat([np.where(np.asarray(m["neighbors"]) >= 0, np.asarray(m["neighbors"]) + t0, -1)
                              for m, t0 in zip(meshes, self.triangle_start)], (0, 3), np.int64)
        self.triangle_mesh = np.repeat(np.arange(len(meshes), dtype=np.int32), nt)
        self.motion = cat([np.asarray(m["motion"], dtype=float)[None] for m in meshes], (0, MESH_MOTION_SIZE),
                          np.float64)
        self.material = np.array([m["material"] for m in meshes], dtype=np.int32)
        self._grid_arrays()
        if not meshes:
            self._particle_arrays(0)
            self.allocate(0)
            return
        if old_slots.shape[0] != self.n:  # the first mesh: the spheres get their slots
            self._particle_arrays(self.n)
            self.allocate(max(self.candidates.shape[0], 4 * self.n))
            return
        # a kept mesh's contacts keep their slots, renumbered; the others' end
        remap = np.full(int(old_start[-1]) + 1, -1, dtype=np.int64)
        for new, old in enumerate(carry):
            if old >= 0:
                remap[old_start[old]:old_start[old + 1]] = np.arange(self.triangle_start[new],
                                                                     self.triangle_start[new + 1])
        slots = np.where(old_slots >= 0, remap[np.maximum(old_slots, 0)], -1)
        ended = (slots < 0).reshape(-1)
        self.slot_triangle = slots
        self.history[ended] = 0.0
        self.load[ended] = 0.0

    def arrays(self) -> tuple:
        """The mesh fields of ``WallArrays``, in their order."""
        return (self.reference, self.vertices, self.built, self.vertex_start, self.triangles, self.neighbors,
                self.triangle_mesh, self.motion, self.material, self.candidate_start, self.candidates,
                self.candidate_gap, self.touch_triangle, self.touch_feature, self.touch_point, self.touch_slot,
                self.slot_triangle, self.history, self.load, self.mesh_error, self.grid, self.grid_start,
                self.grid_items, self.motion_table)

    CHECKPOINT = ("reference", "vertices", "built", "vertex_start", "triangle_start", "triangles", "neighbors",
                  "triangle_mesh", "motion", "material", "slot_triangle", "history", "load", "motion_table")

    def to_arrays(self) -> dict:
        """The meshes' arrays for a checkpoint (none without a mesh), the walls' motion tables."""
        if not self.n_meshes:
            return {"mesh_motion_table": self.motion_table} if len(self.motion_table) else {}
        out = {f"mesh_{name}": getattr(self, name) for name in self.CHECKPOINT}
        out["mesh_candidate_start"] = self.candidate_start  # the lists as built: a restored run goes on the same
        out["mesh_candidates"] = self.candidates[:int(self.candidate_start[-1])] if self.n else self.candidates[:0]
        return out

    def from_arrays(self, arrays: dict, n: int):
        self.n = n
        if "mesh_motion_table" in arrays:
            self.motion_table = np.array(arrays["mesh_motion_table"])
        if "mesh_triangles" not in arrays:
            return
        self._particle_arrays(n)
        for name in self.CHECKPOINT:
            if f"mesh_{name}" in arrays:  # an older checkpoint has no motion table
                setattr(self, name, np.array(arrays[f"mesh_{name}"]))
        self._grid_arrays()
        candidates = arrays["mesh_candidates"]
        self.allocate(max(4 * n, int(len(candidates) * LIST_MARGIN) + 16))
        self.candidates[:len(candidates)] = candidates
        self.candidate_start[:] = arrays["mesh_candidate_start"]
        self.motion = pad_motion_rows(self.motion)

    def save_contacts(self):
        return self.slot_triangle.copy(), self.history.copy()

    def restore_contacts(self, saved):
        self.slot_triangle[...], self.history[...] = saved
        self.mesh_error[:] = 0

    def loads(self, ids=None) -> np.ndarray:
        """(meshes, 6): each mesh's force (N) and moment about the origin (N m) at the last step."""
        out = np.zeros((self.n_meshes, WALL_LOAD_SIZE))
        if self.n_meshes and self.n:
            used = self.slot_triangle.reshape(-1) >= 0
            mesh = self.triangle_mesh[self.slot_triangle.reshape(-1)[used]]
            np.add.at(out, mesh, self.load[used])
        return out

    def error_message(self, ids) -> str:
        """The line that stops a run when a sphere's mesh contacts went wrong (``mesh_error``)."""
        k = int(np.nonzero(self.mesh_error)[0][0])
        code, mesh = int(self.mesh_error[k]) % 4, int(self.mesh_error[k]) // 4
        self.mesh_error[:] = 0
        where = repr(self.label(mesh))
        if code == 1:
            return (f"particle {int(ids[k])} touches mesh wall {where} at more than {MESH_SLOTS} surface features at "
                    "once: the mesh folds on itself there (a sliver or a self-intersection); repair it")
        return (f"particle {int(ids[k])} passed through mesh wall {where}: its centre crossed the surface in one "
                "step, faster than the contact can stop it; reduce dt or the speed, or thicken the wall")

    def label(self, m: int) -> str:
        wall = self.names[m] if m < len(self.names) else None
        return wall.name if wall is not None and wall.name else f"mesh {m}"
