"""Engine state: the arrays the compiled step loop advances, and their capacity management.

``EngineState`` calls the step loop for K steps at a time and grows the arrays when it stops for
room; it re-sorts the particles' storage slots in space in large scenes (``ids[slot]`` is the
index the user knows). docs/architecture.md, "The engine state"."""

from __future__ import annotations

import numba
import numpy as np

from rollingdem.engine import layout  # SERIAL_BELOW read at the call: a test sets it
from rollingdem.engine.backends import BACKENDS
from rollingdem.engine.layout import (
    CONTACT_BLOCK,
    I_FORCES_VALID,
    I_NEED_REBUILD,
    I_NEEDED,
    I_REBUILDS,
    I_STATUS,
    I_STEPS_DONE,
    INFO_SIZE,
    LANE_HITS,
    LIST_MARGIN,
    MESH_SLOTS,
    MOTION_STEADY,
    PERIODIC_BOX,
    PERIODIC_BOX_SIZE,
    SHEARED_BOX_SIZE,
    STATUS_CAPACITY,
    STATUS_MESH_CAPACITY,
    STATUS_MESH_GRID_CAPACITY,
    STATUS_TOO_FAST,
    TILE_ROWS,
    Scratch,
    block_columns,
)
from rollingdem.engine.layout import MESH_MOTION as MO
from rollingdem.engine.mesh_state import MeshState
from rollingdem.engine.neighbors import ContactList, spatial_order
from rollingdem.engine.schema import (
    PARTICLE_RECORD,
    PER_BOND,
    PER_CLUMP,
    PER_PARTICLE,
    PER_PARTICLE_WALL,
    PER_WALL,
    SCHEMA,
)
from rollingdem.engine.threads import ThreadGovernor
from rollingdem.errors import SimulationError
from rollingdem.physics.bonds import BOND_INTACT
from rollingdem.physics.records import ENERGY_CHANNELS, WALL_LOAD_SIZE
from rollingdem.physics.walls import wall_contact_geometry

MAX_ENTRIES = 2**31 - 1  # neighbor-list entries: nl_start, tr_start, tr_k and contact_row are int32
# Re-sorting the slots in space pays once the state no longer fits in the cache; below that it
# costs (the threads' halves of the slots carry unequal work): the figures, docs/performance.md.
SORT_ABOVE = 50_000  # particles
SORT_EVERY = 1000  # steps (LIGGGHTS's and LAMMPS's default sort interval)


def periodic_box(periodic: dict, gradient: str | None = None, shear_velocity: float = 0.0) -> np.ndarray:
    """The step loop's periodic box (``layout.PERIODIC_BOX``) of ``{"x": (lo, hi), ...}``: empty
    without a periodic axis. With a ``gradient`` axis ("y" or "z"; x and it periodic) a sheared box
    (Lees-Edwards, flow along x): the image across the gradient end moves at ``shear_velocity``
    (m/s) along x, from a shift of 0."""
    box = np.zeros(0 if not periodic else SHEARED_BOX_SIZE if gradient else PERIODIC_BOX_SIZE)
    for axis, (lo, hi) in periodic.items():
        a = "xyz".index(axis)
        box[a], box[3 + a], box[6 + a] = lo, hi - lo, 1.0 / (hi - lo)
    if gradient:
        g = "xyz".index(gradient)
        box[PERIODIC_BOX.gradient_y], box[PERIODIC_BOX.gradient_z] = float(g == 1), float(g == 2)
        box[PERIODIC_BOX.lg], box[PERIODIC_BOX.inv_lg] = box[3 + g], box[6 + g]
        box[PERIODIC_BOX.shear_velocity] = shear_velocity
    return box


def minimum_image_branch(branch: np.ndarray, box: np.ndarray) -> np.ndarray:
    """``branch`` (x_i - x_j, one row per pair) taken to the nearest image of j, in place: across a
    sheared box's gradient end first (``neighbors.sheared_image``), then along each periodic axis."""
    if box.shape[0] > PERIODIC_BOX_SIZE:
        gradient = np.array([0.0, box[PERIODIC_BOX.gradient_y], box[PERIODIC_BOX.gradient_z]])
        k = np.round(branch @ gradient * box[PERIODIC_BOX.inv_lg])
        branch[:, 0] -= k * box[PERIODIC_BOX.shift]
        branch -= (k * box[PERIODIC_BOX.lg])[:, None] * gradient
    if box.shape[0]:
        for a in range(3):
            length = box[PERIODIC_BOX.lx + a]
            if length > 0.0:
                branch[:, a] -= length * np.round(branch[:, a] / length)
    return branch


class EngineState:
    """Structure of arrays, float64, SI units."""

    def __init__(self, history_size: int):
        self.history_size = history_size
        self.backend = BACKENDS["cpu"]  # where the step loop runs (rollingdem.engine.backends)
        self.backend_data = {}  # what a backend keeps with the state (the GPU's step loops), by its name
        self._blocks = self._lanes = None  # scratch of the pair pass, see contact_blocks
        self._one_material = None  # (mat, whether all particles are of one material), see contact_blocks
        for field in SCHEMA.all():  # the arrays, from the schema
            setattr(self, field.name, field.rows(0, history_size))
        self.bond_start = np.zeros(0, dtype=np.int64)
        self.bond_ends = np.zeros(0, dtype=np.int64)
        self.clump_start = np.zeros(0, dtype=np.int64)
        self.clump_members = np.zeros(0, dtype=np.int64)
        self.next_tag = 0
        self.energy_removed = np.zeros(len(ENERGY_CHANNELS))  # what the particles taken out had dissipated (J)
        self._slots = None  # slot of each id, once the slots were re-sorted
        self._governor = None  # made by governor() when first used
        self.steps_since_sort = 0
        self.meshes = MeshState(history_size)
        self.info = np.zeros(INFO_SIZE, dtype=np.int64)
        self.contact_list = ContactList(history_size)

    @property
    def n(self) -> int:
        return self.x.shape[0]

    @property
    def is_fixed(self) -> np.ndarray:
        """Whether each slot's particle is fixed, bool (n,)."""
        return self.fixed != 0 if len(self.fixed) else np.zeros(self.n, dtype=bool)

    @property
    def n_walls(self) -> int:
        return self.wall_kind.shape[0]

    # --- the contact list ----------------------------------------------------------------------
    def rebuild_list(self, skin: float) -> int:
        """Rebuild the neighbor list at the present positions, carrying the contacts over (the
        arrays grow as needed); returns its number of entries."""
        return self.contact_list.rebuild(self.x, self.v, self.radius, skin, self.ids, self.fixed, self.clump, self.image,
                                         self.x_ref, self.grow)

    def derive_wall_touch(self):
        """``wtouch[i * n_walls + w]``: whether particle i touched wall w at the last step (it keeps a
        contact normal). The step loop tests this byte, not the history row, for a sphere away from a
        wall: 1 byte instead of a cache line per sphere and wall and step."""
        self.wtouch = np.ascontiguousarray(np.any(self.whist[:, :3] != 0.0, axis=1), dtype=np.uint8)

    def grow(self, needed: int):
        """Room for ``needed`` list entries (and a margin); the entries and contacts are kept."""
        if needed > MAX_ENTRIES:
            raise SimulationError(f"the neighbor list needs {needed} entries ({needed / max(self.n, 1):.1f} per "
                                  f"particle), more than the {MAX_ENTRIES} one process holds (int32 indices): run "
                                  "fewer particles per process, or a smaller neighbor skin")
        keep = self.contact_list.size
        self.contact_list.allocate(min(int(needed * LIST_MARGIN) + 16, MAX_ENTRIES), keep=keep)
        self.info[I_NEED_REBUILD] = 1
        if keep:  # the list's entries were kept as they were; their indices are made anew
            self.contact_list.index()

    # --- particles and walls -----------------------------------------------------------------
    def append_particles(self, **values):
        """Append particles: each given per-particle field's rows (``x``, ``v``, ``radius``, ...,
        ``fixed``), the others' ``fill``; ``x_ref`` is ``x``, the ids and tags are the next ones.
        Existing indices, list entries and history keep their meaning."""
        n0, m, h = self.n, len(values["x"]), self.history_size
        fields = {f.name: f for f in SCHEMA.of(PER_PARTICLE)}
        unknown = set(values) - set(fields) - {"x_ref", "ids", "tags"}
        if unknown:
            raise TypeError(f"no per-particle field named {sorted(unknown)[0]!r} in the state's schema")
        values = {"x_ref": values["x"], **values, "ids": np.arange(n0, n0 + m, dtype=np.int64),
                  "tags": np.arange(self.next_tag, self.next_tag + m, dtype=np.int64)}
        for field in fields.values():
            old = getattr(self, field.name)
            new = field.rows(m, h, values.get(field.name))
            if field.lazy and (n0 == 0 or len(old) != n0):  # no rows yet: none until one differs from fill
                if field.name in values and np.any(new != field.fill):
                    setattr(self, field.name, np.concatenate([field.rows(n0, h), new]))
            else:
                setattr(self, field.name, np.concatenate([old, new]))
        self.next_tag += m
        if self._slots is not None:
            self._slots = np.concatenate([self._slots, np.arange(n0, n0 + m, dtype=np.int64)])
        self.contact_list.add_rows(m)
        walls = self.n_walls
        for field in SCHEMA.of(PER_PARTICLE_WALL):  # each new particle gets a row per wall
            shape = field.row_shape(h)
            old = getattr(self, field.name).reshape((n0, walls) + shape)
            setattr(self, field.name, np.concatenate([old, field.rows(m * walls, h).reshape((m, walls) + shape)])
                    .reshape((self.n * walls,) + shape))
        self.derive_wall_touch()
        self.meshes.resize_particles(self.n)
        if len(self.bond_pairs):
            self.index_bonds()
        self.index_clumps()
        self.info[I_NEED_REBUILD] = 1
        self.info[I_FORCES_VALID] = 0
        self.steps_since_sort = SORT_EVERY  # the new particles come in the user's order: sort at the next run
        if self.contact_list.capacity < 3 * self.n:  # a settled bed's half list holds ~4 entries per particle
            self.grow(3 * self.n)

    def set_walls(self, carry, **values):
        """Replace the walls: each per-wall field's rows (``wall_kind``, ``wall_geom``, ...).
        ``carry[w]``: the slot that new wall w had before (its contact history and load go with
        it), or -1 for a new wall."""
        n, h, old_w, new_w = self.n, self.history_size, self.n_walls, len(carry)
        for field in SCHEMA.of(PER_WALL):
            setattr(self, field.name, field.rows(new_w, h, values.get(field.name)))
        for field in SCHEMA.of(PER_PARTICLE_WALL):
            shape = field.row_shape(h)
            old = getattr(self, field.name).reshape((n, old_w) + shape)
            new = field.rows(n * new_w, h).reshape((n, new_w) + shape)
            if n and old_w:
                for new_slot, old_slot in enumerate(carry):
                    if old_slot >= 0:
                        new[:, new_slot] = old[:, old_slot]
            setattr(self, field.name, new.reshape((n * new_w,) + shape))
        self.derive_wall_touch()
        self.info[I_FORCES_VALID] = 0

    def set_meshes(self, meshes: list, carry: list, walls: list):
        """Replace the triangle meshes (``MeshState.set_meshes``); ``walls`` their Wall objects."""
        self.meshes.n = self.n
        self.meshes.set_meshes(meshes, carry)
        self.meshes.names = list(walls)
        self.info[I_FORCES_VALID] = 0

    # --- slots and ids -----------------------------------------------------------------------
    def slots(self, ids) -> np.ndarray:
        """Storage slots of the particles with these ids."""
        ids = np.asarray(ids, dtype=np.int64)
        return ids if self._slots is None else self._slots[ids]

    def by_id(self, arr: np.ndarray) -> np.ndarray:
        """A per-particle array in id order (the array itself while the slots are in id order)."""
        return arr if self._slots is None else arr[self._slots]

    # --- bonds --------------------------------------------------------------------------------
    def add_bonds(self, pairs: np.ndarray, parameters: np.ndarray) -> None:
        """Append intact, unloaded bonds between the slots ``pairs`` (m, 2), with their parameter rows."""
        values = {"bond_pairs": pairs, "bond_parameters": parameters}
        for field in SCHEMA.of(PER_BOND):
            setattr(self, field.name, np.concatenate([getattr(self, field.name),
                                                      field.rows(len(pairs), self.history_size, values.get(field.name))]))
        self.index_bonds()
        self.info[I_FORCES_VALID] = 0

    def index_bonds(self) -> None:
        """Each particle's bond ends in ascending order (``bond_start``, ``bond_ends``), the order the
        gather sums them in; empty arrays without bonds (the loops then skip them)."""
        nb = len(self.bond_pairs)
        if nb == 0:
            self.bond_start = np.zeros(0, dtype=np.int64)
            self.bond_ends = np.zeros(0, dtype=np.int64)
            return
        owner = np.concatenate([self.bond_pairs[:, 0], self.bond_pairs[:, 1]])
        code = np.concatenate([2 * np.arange(nb), 2 * np.arange(nb) + 1])
        order = np.lexsort((code, owner))
        self.bond_ends = np.ascontiguousarray(code[order], dtype=np.int64)
        self.bond_start = np.concatenate([[0], np.cumsum(np.bincount(owner, minlength=self.n))]).astype(np.int64)

    # --- clumps --------------------------------------------------------------------------------
    @property
    def n_clumps(self) -> int:
        return self.clump_mass.shape[0]

    def add_clumps(self, members: np.ndarray, offsets: np.ndarray, **values) -> None:
        """Append clumps: ``values`` their per-clump fields' rows (``clump_x``, ``clump_q``,
        ``clump_mass``, ...), ``members`` (m,) the clump (0..count-1 among the new ones) of each
        particle appended last, in its members' order, ``offsets`` (m, 3) their centres in the
        clump's principal frame (m). The members are placed by the step loop."""
        count = len(values["clump_mass"])
        first, n0 = self.n_clumps, self.n - len(members)
        for field in SCHEMA.of(PER_CLUMP):
            setattr(self, field.name, np.concatenate([getattr(self, field.name),
                                                      field.rows(count, self.history_size, values.get(field.name))]))
        for name, new in (("clump", first + np.asarray(members, dtype=np.int64)), ("body_offset", offsets)):
            field = next(f for f in SCHEMA.of(PER_PARTICLE) if f.name == name)
            old = getattr(self, name)
            if len(old) != self.n:
                old = field.rows(self.n, self.history_size)
            old[n0:] = new
            setattr(self, name, old)
        self.index_clumps()
        self.info[I_FORCES_VALID] = 0

    def whole_clumps(self, slots: np.ndarray) -> np.ndarray:
        """The mask of slots ``slots`` with every member of each clump one of them is in: a clump
        goes whole with any of its members."""
        slots = np.asarray(slots, dtype=bool)
        if not self.n_clumps or not slots.any():
            return slots
        member = self.clump >= 0
        hit = np.zeros(self.n_clumps, dtype=bool)
        hit[self.clump[slots & member]] = True
        return slots | (member & hit[np.maximum(self.clump, 0)])

    def index_clumps(self) -> None:
        """Each clump's members' slots in the order of their tags (``clump_start``,
        ``clump_members``), the order its forces are summed in whatever the slots; empty arrays
        without clumps (the step loop then skips them)."""
        if self.n_clumps == 0:
            self.clump_start = np.zeros(0, dtype=np.int64)
            self.clump_members = np.zeros(0, dtype=np.int64)
            self.clump, self.body_offset = self.clump[:0], self.body_offset[:0]
            return
        if len(self.body_offset) != self.n:  # every member at its clump's centre: no rows were kept
            self.body_offset = np.zeros((self.n, 3))
        members = np.nonzero(self.clump >= 0)[0]
        order = np.lexsort((self.tags[members], self.clump[members]))
        self.clump_members = np.ascontiguousarray(members[order], dtype=np.int64)
        self.clump_start = np.concatenate([[0], np.cumsum(np.bincount(self.clump[members],
                                                                      minlength=self.n_clumps))]).astype(np.int64)

    def sort(self, cell_size: float) -> None:
        """Re-sort the slots in Morton order of the positions; the neighbor list, its history and
        every per-particle array follow, so the next step computes exactly the same contacts."""
        n = self.n
        perm = spatial_order(self.x, cell_size)  # new slot s holds the particle of old slot perm[s]
        if np.array_equal(perm, np.arange(n)):
            return
        inv = np.empty(n, dtype=np.int64)
        inv[perm] = np.arange(n)
        self._take_particle_rows(perm)
        self.meshes.reorder(perm)
        self.contact_list.reorder(perm, inv)  # rows move with their particle
        if len(self.bond_pairs):
            self.bond_pairs = inv[self.bond_pairs]
            self.index_bonds()
        self.index_clumps()
        self._slots = np.argsort(self.ids)
        self.steps_since_sort = 0

    def _take_particle_rows(self, rows: np.ndarray) -> None:
        """Every per-particle field (a lazy one if it has rows) and every row per particle and wall
        taken at ``rows`` (a permutation, or the slots kept), in that order."""
        n, walls = self.n, self.n_walls
        for field in SCHEMA.of(PER_PARTICLE):
            if len(getattr(self, field.name)) == n:
                setattr(self, field.name, np.ascontiguousarray(getattr(self, field.name)[rows]))
        if walls:
            for field in SCHEMA.of(PER_PARTICLE_WALL):
                shape = field.row_shape(self.history_size)
                per_wall = getattr(self, field.name).reshape((n, walls) + shape)[rows]
                setattr(self, field.name, np.ascontiguousarray(per_wall.reshape((-1,) + shape)))

    def remove(self, gone: np.ndarray) -> None:
        """Take out the particles of the slots where ``gone`` is True. The others keep their state
        and every contact among them its history; their ids are renumbered in the same order (so
        each pair keeps its orientation in the half list), their tags stay. Forces are computed
        anew at the next step, without the particles that went."""
        gone = self.whole_clumps(gone)
        if not gone.any():
            return
        if self.n_clumps:
            clump_gone = np.zeros(self.n_clumps, dtype=bool)
            clump_gone[self.clump[gone & (self.clump >= 0)]] = True
        keep = ~gone
        n, h = self.n, self.history_size
        arrays = self.to_arrays()
        if len(self.energy) == n:  # the run's account keeps what the particles leaving had dissipated
            arrays["energy_removed"] = self.energy_removed + self.energy[gone].sum(axis=0)
        for field in SCHEMA.of(PER_PARTICLE):
            if field.saved and len(arrays[field.name]) == n:
                arrays[field.name] = arrays[field.name][keep]
        arrays["ids"] = np.argsort(np.argsort(arrays["ids"], kind="stable"), kind="stable").astype(np.int64)
        for field in SCHEMA.of(PER_PARTICLE_WALL):
            if field.saved:
                shape = field.row_shape(h)
                arrays[field.name] = arrays[field.name].reshape((n, self.n_walls) + shape)[keep].reshape((-1,) + shape)
        if self.meshes.n_meshes:
            arrays["mesh_slot_triangle"] = arrays["mesh_slot_triangle"][keep]
            for name, width in (("mesh_history", h), ("mesh_load", WALL_LOAD_SIZE)):
                arrays[name] = arrays[name].reshape(n, MESH_SLOTS, width)[keep].reshape(-1, width)
            arrays["mesh_candidate_start"] = np.zeros(keep.sum() + 1, dtype=np.int64)  # built again
            arrays["mesh_candidates"] = arrays["mesh_candidates"][:0]
        start = arrays["nl_start"].astype(np.int64)
        row = np.repeat(np.arange(n), np.diff(start))
        j = arrays["nl_j"].astype(np.int64)
        entry = keep[row] & keep[j]
        slot = np.cumsum(keep) - 1
        arrays["nl_j"] = slot[j[entry]].astype(np.int32)
        arrays["hist"] = arrays["hist"][entry]
        arrays["tr_k"] = arrays["tr_k"][entry]
        arrays["nl_start"] = np.concatenate([[0], np.cumsum(np.bincount(slot[row[entry]], minlength=int(keep.sum())))])
        arrays["tr_start"] = np.zeros_like(arrays["nl_start"])
        if len(self.bond_pairs):  # a bond goes with either of its particles
            held = keep[self.bond_pairs].all(axis=1)
            for field in SCHEMA.of(PER_BOND):
                arrays[field.name] = arrays[field.name][held]
            arrays["bond_pairs"] = slot[arrays["bond_pairs"]]
        if self.n_clumps:
            for field in SCHEMA.of(PER_CLUMP):
                arrays[field.name] = arrays[field.name][~clump_gone]
            renumber = np.cumsum(~clump_gone) - 1
            arrays["clump"] = np.where(arrays["clump"] >= 0, renumber[np.maximum(arrays["clump"], 0)], -1)
        fresh = EngineState.from_arrays(arrays, h)
        names = self.meshes.names
        for key, value in fresh.__dict__.items():
            if key not in ("_governor", "_blocks", "_lanes", "backend", "backend_data"):
                setattr(self, key, value)
        self.meshes.names = names
        self.info[I_FORCES_VALID] = 0
        self.info[I_NEED_REBUILD] = 1

    # --- running -------------------------------------------------------------------------------
    def contact_blocks(self):
        """The per-thread block buffers of the pair pass (``pair_rows``, ``engine/template/pairs.py``): (threads, columns
        x CONTACT_BLOCK) floats and (threads, LANE_HITS + TILE_ROWS, CONTACT_BLOCK) lane indices (the
        block's entries and a tile's candidate entries), about 38 KB per thread;
        made again when the number of Numba threads changes. Scratch space, never part of the state.
        Empty (0 columns) when the spheres are not all of one material: the pair pass then computes
        one contact at a time."""
        threads = numba.get_num_threads()
        if self._one_material is None or self._one_material[0] is not self.mat:  # the array is replaced when it changes
            self._one_material = (self.mat, self.n == 0 or bool((self.mat[:self.n] == self.mat[0]).all()))
        one_material = self._one_material[1]
        width = block_columns(self.history_size) * CONTACT_BLOCK if one_material else 0
        if self._blocks is None or self._blocks.shape != (threads, width):
            self._blocks = np.zeros((threads, width))
            self._lanes = np.zeros((threads, LANE_HITS + TILE_ROWS, CONTACT_BLOCK), dtype=np.int64)
        return self._blocks, self._lanes

    def records(self) -> tuple:
        """The step loop's four records of the arrays as they are now (the arrays are replaced when
        they grow: records are made for each call): the particles' and the walls' (their fields
        from the schema, ``rollingdem.engine.schema``), the list's and the scratch
        (``rollingdem.engine.layout``)."""
        particle_fields = [f for per in PARTICLE_RECORD for f in SCHEMA.of(per) if f.record_name is not None]
        wall_fields = [f for per in (PER_WALL, PER_PARTICLE_WALL) for f in SCHEMA.of(per) if f.record_name is not None]
        return (SCHEMA.particle_record()._make([getattr(self, f.name) for f in particle_fields]
                                               + [self.bond_start, self.bond_ends, self.clump_start,
                                                  self.clump_members]),
                SCHEMA.wall_record()._make([getattr(self, f.name) for f in wall_fields] + list(self.meshes.arrays())),
                self.contact_list.arrays(),
                Scratch(*self.contact_blocks()))

    def step_loop_args(self, dt, gravity, skin, pair_params):
        """The arguments of the step loop after ``nsteps``."""
        return (dt, gravity, skin, pair_params, *self.records(), self.info)

    def advance(self, module, nsteps: int, dt: float, gravity: np.ndarray, skin: float, pair_params: np.ndarray):
        """Advance up to ``nsteps`` steps (growing the list arrays as often as needed).

        Returns (steps done, None) or, when a particle outruns the skin, (steps done, message)."""
        if self.n == 0:
            return nsteps, None
        self.energy_for(module)
        if self.info[I_FORCES_VALID] == 0:
            self._evaluate_forces(module, dt, gravity, skin, pair_params)
        if self.n >= SORT_ABOVE and self.steps_since_sort >= SORT_EVERY:
            self.sort(2.0 * float(self.radius.max()) + skin)

        remaining = nsteps
        step_loop = self.step_loop(module)
        governor = self.governor()
        governor.begin(numba.get_num_threads(), parallel=step_loop is module.advance)
        try:
            while remaining > 0:
                step_loop(governor.segment(remaining), *self.step_loop_args(dt, gravity, skin, pair_params))
                done = int(self.info[I_STEPS_DONE])
                governor.done(done)
                remaining -= done
                self.steps_since_sort += done
                if self._make_room():
                    continue
                if self.info[I_STATUS] == STATUS_TOO_FAST:
                    if self.meshes.n_triangles and self.meshes.mesh_error.any():
                        return nsteps - remaining, self.meshes.error_message(self.ids)
                    return nsteps - remaining, self._too_fast_message(dt, skin)
        finally:
            governor.close()
        return nsteps, None

    def _make_room(self) -> bool:
        """Grow the arrays the last call of the step loop stopped for (the neighbor list, the mesh
        candidates, the triangle grid) to ``info[I_NEEDED]``; False if it stopped for none of them."""
        status, needed = self.info[I_STATUS], int(self.info[I_NEEDED])
        if status == STATUS_CAPACITY:
            self.grow(needed)
        elif status == STATUS_MESH_CAPACITY:
            self.meshes.grow(needed)
        elif status == STATUS_MESH_GRID_CAPACITY:
            self.meshes.grow_grid(needed)
        else:
            return False
        return True

    def energy_for(self, module):
        """Allocate the energy sums (zero) for an engine module that adds to them: without, it would write
        out of bounds (Numba does not check)."""
        if module.TRACK_ENERGY and self.energy.shape[0] != self.n:
            self.energy = np.zeros((self.n, len(ENERGY_CHANNELS)))

    def statistics(self) -> dict:
        """What the engine counts, for ``Simulation.engine_statistics``: neighbor-list rebuilds so
        far, steps made on each thread count (while the governor was active), the bytes of the
        state's arrays (with the contact list's and the meshes'), the pair contacts (spheres whose
        centres are nearer than the sum of their radii), the wall contacts and the pairs in the
        neighbor list."""
        n, cl = self.n, self.contact_list
        rows = np.repeat(np.arange(n), np.diff(cl.start[: n + 1])) if n else np.zeros(0, dtype=np.int64)
        j = cl.j[: cl.size] if n else np.zeros(0, dtype=np.int64)
        d = np.linalg.norm(self.x[rows] - self.x[j], axis=1)
        pairs = int(np.count_nonzero(d < self.radius[rows] + self.radius[j]))
        return {"neighbor_rebuilds": int(self.info[I_REBUILDS]),
                "steps_by_threads": dict(self.governor().steps_on),
                "state_bytes": sum(a.nbytes for owner in (self, cl, self.meshes) for a in vars(owner).values()
                                   if isinstance(a, np.ndarray)),
                "pair_contacts": pairs, "wall_contacts": int(self.contacts.sum()) - pairs,
                "neighbor_pairs": int(cl.size) if n else 0}

    def contact_forces(self) -> dict:
        """The last step's contacts, as arrays: ``i`` (the particle the force acts on, by its index in
        the order added, as ``by_id``), ``j`` (its partner's; -1 for a plane or cylinder), ``force`` (on i, N) and ``branch``
        (m: from the partner's centre, its periodic image nearest i, or from the wall's contact
        point, to i's centre), ``moment`` (N m: the pure moment on i, rolling and twisting
        resistance or a bond's bending and twisting), the pair contacts first, then intact bonds,
        then wall contacts. On j: -force and -moment. With n = b/|b|, levers R - overlap/2 and
        c = n x F, the torque on i is -lever_i c + moment and on j -lever_j c - moment (a wall's
        lever 0). Triangle-mesh contacts are not listed: a scene whose spheres touch a mesh is refused."""
        n, cl = self.n, self.contact_list
        if n and self.meshes.n_triangles and (self.meshes.slot_triangle[:n] >= 0).any():
            raise SimulationError("contact forces are not available while spheres touch a triangle-mesh wall: "
                                  "their contact points are not kept")
        total = int(cl.start[n]) if n else 0
        rows = cl.contact_row[:total]
        k = np.flatnonzero(rows >= 0)
        i = np.repeat(np.arange(n), np.diff(cl.start[: n + 1]))[k] if n else np.zeros(0, dtype=np.int64)
        j = cl.j[k].astype(np.int64)
        force = cl.pair_terms[rows[k], 0:3].copy()
        torque_j = -cl.pair_terms[rows[k], 3:6]  # the pair pass keeps -T_j
        intact = np.flatnonzero(self.bond_status == BOND_INTACT) if len(self.bond_status) else np.zeros(0, np.int64)
        i = np.concatenate([i, self.bond_pairs[intact, 0]]).astype(np.int64)
        j = np.concatenate([j, self.bond_pairs[intact, 1]]).astype(np.int64)
        force = np.concatenate([force, self.bond_load[intact, 0:3]])
        torque_j = np.concatenate([torque_j, self.bond_load[intact, 6:9]])
        branch = minimum_image_branch(self.x[i] - self.x[j], cl.box)
        distance = np.linalg.norm(branch, axis=1, keepdims=True)
        lever_j = self.radius[j][:, None] - 0.5 * (self.radius[i][:, None] + self.radius[j][:, None] - distance)
        moment = -torque_j - lever_j * np.cross(branch / np.where(distance > 0.0, distance, 1.0), force)
        walls = self.n_walls
        touching = np.flatnonzero(self.wtouch[: n * walls]) if walls else np.zeros(0, np.int64)
        wall_i, wall_of = touching // max(walls, 1), touching % max(walls, 1)
        wall_branch = np.zeros((len(touching), 3))
        for c, (q, wl) in enumerate(zip(wall_i, wall_of)):
            overlap, nx, ny, nz = wall_contact_geometry(q, wl, self.x, self.radius[q], self.wall_kind, self.wall_geom)
            wall_branch[c] = (self.radius[q] - overlap) * np.array([nx, ny, nz])
        # a wall's load row: -F and its moment about the origin, point x (-F) + the torque on the wall
        load = self.wall_load.reshape(-1, WALL_LOAD_SIZE)[touching]
        wall_moment = -(load[:, 3:6] - np.cross(self.x[wall_i] - wall_branch, load[:, 0:3]))
        i, j = np.concatenate([i, wall_i]), np.concatenate([j, np.full(len(touching), -1)])
        if self._slots is not None:  # slots to the order the particles were added (``by_id``)
            order = np.empty(n, dtype=np.int64)
            order[self._slots] = np.arange(n)
            i, j = order[i], np.where(j >= 0, order[np.maximum(j, 0)], -1)
        return {"i": i, "j": j, "force": np.concatenate([force, -load[:, 0:3]]),
                "branch": np.concatenate([branch, wall_branch]), "moment": np.concatenate([moment, wall_moment])}

    def governor(self):
        """The thread governor of this state's runs (``rollingdem.engine.threads``), made when first used."""
        if self._governor is None:
            self._governor = ThreadGovernor()
        return self._governor

    def serial(self) -> bool:
        """Whether the step loop runs on the calling thread (a small scene, or one Numba thread)."""
        return self.n < layout.SERIAL_BELOW or numba.get_num_threads() == 1

    def step_loop(self, module):
        """The engine module's step loop for this scene on its backend (``rollingdem.engine.backends``)."""
        have = self.features()
        if any(h and not getattr(module, flag) for h, flag in zip(have, ("BONDED_PAIRS", "MESHES", "CLUMPS", "PROGRAMS"))):
            raise RuntimeError(f"engine module {module.__name__} has no pass for this scene's bonds, meshes, clumps or "
                               f"wall programs {have}: take it from Simulation.engine_module()")
        return self.backend.step_loop(self, module)

    def features(self) -> tuple[bool, bool, bool, bool]:
        """(bonds, triangle meshes, clumps, a plane or cylinder with a motion program): whether the
        scene holds each, the passes its engine module must have (``codegen.EngineModules``)."""
        return (bool(len(self.bond_pairs)), bool(self.meshes.n_triangles or self.meshes.n_meshes), bool(self.n_clumps),
                bool((self.wall_program[:, MO.program] != MOTION_STEADY).any()))

    def _too_fast_message(self, dt, skin):
        bad = ~(np.isfinite(self.f).all(axis=1) & np.isfinite(self.t).all(axis=1))
        if bad.any():  # the flag also counts a NaN force: say what it is
            k = int(np.nonzero(bad)[0][0])
            same = np.nonzero((self.x == self.x[k]).all(axis=1))[0]
            why = (f"it shares its centre with particle {int(self.ids[same[same != k][0]])}: the contact normal is "
                   "undefined; remove one of them" if len(same) > 1 else "the run is unstable or the input holds a NaN")
            return f"the force on particle {int(self.ids[k])} is not finite at this step ({why})"
        speed = np.sqrt((self.v ** 2).sum(axis=1))
        k = int(np.nanargmax(speed)) if np.isfinite(speed).any() else 0
        return (f"particle {int(self.ids[k])} moves {speed[k] * dt:.3g} m in one step (speed {speed[k]:.3g} m/s, dt = {dt:.3g} s), "
                f"more than half the neighbor skin ({skin:.3g} m): contacts could be missed. Give a larger skin "
                f"(> {2 * speed[k] * dt:.3g} m) or a smaller dt; a speed like this often means the run is unstable")

    def _evaluate_forces(self, module, dt, gravity, skin, pair_params):
        """Forces and torques of the present state, leaving the contact history untouched.

        Rebuilding at unchanged positions is idempotent, so the contacts saved after one rebuild
        are exactly those the evaluation started from.
        """
        total = self.rebuild_list(skin)
        cl = self.contact_list
        saved = (cl.pool[:total].copy(), cl.contact_row[:total].copy(), cl.groups.copy(), self.whist.copy(),
                 self.energy.copy(), self.bond_state.copy(), self.bond_status.copy())
        mesh_saved = self.meshes.save_contacts()
        while True:
            self.info[I_FORCES_VALID] = 0
            self.step_loop(module)(0, *self.step_loop_args(dt, gravity, skin, pair_params))
            if not self._make_room():
                break
        cl = self.contact_list  # grown perhaps: the arrays are new
        (cl.pool[:total], cl.contact_row[:total], cl.groups[:], self.whist[:], self.energy[:], self.bond_state[:],
         self.bond_status[:]) = saved
        self.meshes.restore_contacts(mesh_saved)
        self.derive_wall_touch()

    # --- checkpoint ----------------------------------------------------------------------------
    def to_arrays(self) -> dict:
        """The state as named arrays, for a checkpoint: every saved field of the schema, the status
        record, the meshes' and the neighbor list's arrays."""
        out = {f.name: getattr(self, f.name) for f in SCHEMA.all() if f.saved}
        out["info"] = self.info
        out["next_tag"] = np.array(self.next_tag)
        out["energy_removed"] = self.energy_removed
        out["periodic_box"] = self.contact_list.box
        out.update(self.meshes.to_arrays())
        cl = self.contact_list
        total = cl.size
        out["nl_start"] = cl.start
        out["tr_start"] = cl.tr_start
        out["nl_j"] = cl.j[:total]
        out["hist"] = cl.entry_history()
        out["tr_k"] = cl.tr_k[:total]
        return out

    def take_over(self, other: "EngineState") -> None:
        """Hold ``other``'s arrays and counters from now on (a restored checkpoint), keeping this
        object and its backend: whoever was given this state at construction sees the new one."""
        backend = self.backend
        self.__dict__.clear()
        self.__dict__.update(other.__dict__)
        self.backend = backend

    @classmethod
    def from_arrays(cls, arrays: dict, history_size: int) -> "EngineState":
        st = cls(history_size)
        n = len(arrays["x"])
        walls = len(arrays["wall_kind"])
        count = {PER_PARTICLE: n, PER_BOND: 0, PER_WALL: walls, PER_PARTICLE_WALL: n * walls, PER_CLUMP: 0}
        for field in SCHEMA.all():
            if not field.saved:  # derived: a new row each (wtouch is made below)
                setattr(st, field.name, field.rows(0 if field.lazy else count[field.per], history_size))
                continue
            if field.name in arrays:  # an older checkpoint may lack a field: its rows are new ones
                value = np.array(arrays[field.name], dtype=field.dtype)
            else:
                value = field.rows(0 if field.lazy else count[field.per], history_size)
            if field.lazy and not np.any(value != field.fill):
                value = field.rows(0, history_size)
            setattr(st, field.name, value)
        st.info = np.array(arrays["info"])
        if "ids" not in arrays:  # a checkpoint from before the re-sorting
            st.ids = np.arange(n, dtype=np.int64)
        if "tags" not in arrays:
            st.tags = st.ids.copy()
        st.next_tag = int(arrays["next_tag"]) if "next_tag" in arrays else st.n
        if "energy_removed" in arrays:
            st.energy_removed = np.array(arrays["energy_removed"], dtype=np.float64)
        st.meshes.from_arrays(arrays, st.n)
        st.index_bonds()
        st.index_clumps()
        if not np.array_equal(st.ids, np.arange(st.n)):
            st._slots = np.argsort(st.ids)
        cl = st.contact_list = ContactList(history_size, rows=st.n)
        if "periodic_box" in arrays:
            cl.box = np.array(arrays["periodic_box"], dtype=np.float64)
        cl.start[:] = arrays["nl_start"]  # int64 in older checkpoints
        cl.tr_start[:] = arrays["tr_start"]
        total = int(arrays["nl_j"].shape[0])
        cl.allocate(max(int(total * LIST_MARGIN) + 16, 3 * st.n))
        cl.j[:total] = arrays["nl_j"]
        st.derive_wall_touch()
        cl.index()  # the checkpoint's tr_k too, made again (as it was written)
        cl.set_entry_history(arrays["hist"])
        return st
