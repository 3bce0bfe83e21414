"""The neighbor-list rebuild on a CUDA GPU (``Simulation(backend="cuda")``, docs/gpu.md).

The same list as the CPU's ``rebuild_neighbor_list`` (``rollingdem.engine.neighbors``), entry for entry,
built where the particles are: the per-particle work is the CPU's own compiled functions
(``wrap_one``, ``centre_bounds``, ``grid_of_bounds``, ``cell_index``, ``scan_row``), called from
one thread per particle; what the CPU does in serial loops (bounds, counting sorts, prefix sums)
is done here with prefix sums and atomics whose order the result does not depend on:

- the bounding box: each thread's share (``centre_bounds``), then float min and max atomics
  (exact, in any order);
- the counting sorts of particles into cells and of entries into the transposed index: integer
  counts and slots taken with atomics; a cell's particles stay in the order the threads took
  their slots (each list row is sorted by partner id afterwards), each particle's entries of the
  transposed index are sorted (the gather sums in list order, as the CPU's);
- the prefix sums: a chunk of values per thread, the chunks' totals prefix-summed in turn.

Contact history goes from the old list to the new through a buffer of the contacts alone
(``RebuildArrays.carry``): each contact's history and partner, in list order, then each new row
merged with its old contacts by partner id. On the GPU each list entry keeps its contact in pool
row k (``rollingdem.engine.cuda.step_loop``). The triangle-mesh candidates are found the same way: the grid of
triangles on one thread (``prepare_mesh_grid``), each sphere's row on a thread of its own
(``mesh_candidate_row``). One synchronisation per rebuild: the host reads the list's length and
the meshes' (to grow their arrays when they are short) and the number of contacts (to grow the
carry buffer).
"""

from __future__ import annotations

import collections
import math

import numpy as np

from rollingdem.engine.cuda import target as cuda_target
from rollingdem.engine.layout import I_NEEDED, I_REBUILDS, I_STATUS, STATUS_CAPACITY, STATUS_MESH_CAPACITY, STATUS_MESH_GRID_CAPACITY
from rollingdem.engine.mesh_passes import mesh_candidate_row, prepare_mesh_grid
from rollingdem.engine.neighbors import cell_index, centre_bounds, grid_of_bounds, scan_row, wrap_one

#: the device's rebuild arrays: the centres' bounds (min x, y, z, max x, y, z, R_max), the grid
#: (lo x, y, z, cells along x, y, z, cell edges), the host's report (entries, contacts, the mesh
#: candidates' status and entries needed) and the contacts' history on their way to the new list
RebuildArrays = collections.namedtuple("RebuildArrays", ("bounds", "grid", "report", "carry"))
#: a counting sort of ``keys`` into groups: ``start`` (one longer than the CSR starts), ``items``
CountingSort = collections.namedtuple("CountingSort", ("keys", "start", "items"))
#: an inclusive prefix sum of ``values`` in chunks, the chunks' totals into ``sums``
Scan = collections.namedtuple("Scan", ("values", "sums"))
R_ENTRIES, R_CONTACTS, R_MESH_SHORT, R_MESH_NEEDED = range(4)
BOUNDS_THREADS = 1 << 16  # threads of the bounding-box reduction (each a stride of the particles)
CARRY_SLACK = 1.25  # the carry buffer's rows per contact when it grows

cuda = None  # ``numba.cuda``, set by ``kernel_bodies`` (see ``rollingdem.engine.cuda.step_loop``)


def scan_chunk() -> int:
    """Values per thread of a prefix sum (fewer in the simulator, so that its small scenes take more
    than one level)."""
    return 4 if cuda_target.simulated() else 64


def kernel_bodies(module) -> dict:
    """The rebuild's CUDA kernel bodies for an engine module, by name (``step_loop.kernel_bodies``
    adds them to the step's)."""
    global cuda
    cuda = cuda_target.cuda_module()
    history_size = module.HISTORY_SIZE
    chunk = scan_chunk()

    def prepare(particles, lists, rebuild):
        """Centres back into a periodic box; the bounds reset."""
        i = cuda.grid(1)
        if i == 0:
            for d in range(3):
                rebuild.bounds[d] = math.inf
                rebuild.bounds[3 + d] = -math.inf
            rebuild.bounds[6] = 0.0
        if i < particles.x.shape[0] and lists.box.shape[0] != 0:
            wrap_one(i, particles.x, particles.v, particles.image, lists.box)

    def bounds(particles, rebuild):
        """The centres' bounding box and R_max: a stride of particles per thread, then atomics."""
        lox, loy, loz, hix, hiy, hiz, rmax = centre_bounds(particles.x, particles.radius, cuda.grid(1),
                                                           cuda.gridsize(1))
        b = rebuild.bounds
        cuda.atomic.min(b, 0, lox)
        cuda.atomic.min(b, 1, loy)
        cuda.atomic.min(b, 2, loz)
        cuda.atomic.max(b, 3, hix)
        cuda.atomic.max(b, 4, hiy)
        cuda.atomic.max(b, 5, hiz)
        cuda.atomic.max(b, 6, rmax)

    def grid(skin, max_cells, lists, rebuild):
        """The cell grid (one thread): ``grid_of_bounds``, as the CPU's ``_grid``."""
        if cuda.grid(1) == 0:
            b, g = rebuild.bounds, rebuild.grid
            lo, dims, cells = grid_of_bounds(b[0], b[1], b[2], b[3], b[4], b[5], b[6], skin, max_cells, lists.box)
            for d in range(3):
                g[d] = lo[d]
                g[3 + d] = dims[d]
                g[6 + d] = cells[d]

    def bin_particles(particles, lists, rebuild):
        """Each particle's cell (``cell_index``)."""
        i = cuda.grid(1)
        if i < particles.x.shape[0]:
            g = rebuild.grid
            lists.cell_of[i] = cell_index(particles.x, i, (g[0], g[1], g[2]), (g[6], g[7], g[8]),
                                          (int(g[3]), int(g[4]), int(g[5])))

    def count_rows(skin, particles, lists, rebuild, fill):
        """Each particle's row of the new list (``scan_row``): its length into ``counts``, or (fill)
        written from ``start[i]`` and sorted by partner id."""
        i = cuda.grid(1)
        if i < particles.x.shape[0]:
            g = rebuild.grid
            dims = (int(g[3]), int(g[4]), int(g[5]))
            k = scan_row(i, particles.x, particles.radius, skin, particles.ids, particles.fixed, particles.clump, lists.box, dims,
                         lists.cell_start, lists.cell_items, lists.cell_of, lists.start, lists.j, fill != 0)
            if fill == 0:
                lists.counts[i] = k

    def count_contacts(particles, lists):
        """The contacts of each old row into ``tr_start[i + 1]`` (prefix-summed, they become where
        each row's contacts go in the carry buffer)."""
        i = cuda.grid(1)
        n = particles.x.shape[0]
        if i == 0:
            lists.tr_start[0] = 0
        if i < n:
            c = 0
            for k in range(lists.start[i], lists.start[i + 1]):
                if lists.contact_row[k] >= 0:
                    c += 1
            lists.tr_start[i + 1] = c

    def mesh_grid(skin, walls, rebuild):
        """The triangle grid (one thread, ``prepare_mesh_grid``), R_max from the bounds."""
        if cuda.grid(1) == 0:
            needed = prepare_mesh_grid(rebuild.bounds[6] + skin, walls)
            rebuild.report[R_MESH_SHORT] = 2 if needed else 0
            rebuild.report[R_MESH_NEEDED] = needed

    def mesh_rows(skin, particles, walls, rebuild, fill):
        """Each sphere's candidate triangles (``mesh_candidate_row``): their count into
        ``candidate_start[i + 1]``, or (fill) written from ``candidate_start[i]``."""
        i = cuda.grid(1)
        if i < particles.x.shape[0] and rebuild.report[R_MESH_SHORT] == 0:
            count = mesh_candidate_row(i, particles.x, particles.radius, skin, walls, fill != 0)
            if fill == 0:
                walls.candidate_start[i + 1] = count
                if i == 0:
                    walls.candidate_start[0] = 0

    def report(particles, walls, lists, rebuild):
        """The new list's length (its rows' lengths prefix-summed), the contacts to carry, and
        whether the mesh candidates fit."""
        if cuda.grid(1) == 0:
            n = particles.x.shape[0]
            rebuild.report[R_ENTRIES] = lists.counts[n - 1]
            rebuild.report[R_CONTACTS] = lists.tr_start[n]
            if walls.triangles.shape[0] != 0 and rebuild.report[R_MESH_SHORT] == 0:
                total = walls.candidate_start[n]
                if total > walls.candidates.shape[0]:
                    rebuild.report[R_MESH_SHORT] = 1
                    rebuild.report[R_MESH_NEEDED] = total

    def carry_out(particles, lists, rebuild):
        """Each old row's contacts, in list order, into the carry buffer: history and partner
        (in ``tr_k``, which the transposed index makes anew afterwards)."""
        i = cuda.grid(1)
        if i < particles.x.shape[0]:
            c = lists.tr_start[i]
            for k in range(lists.start[i], lists.start[i + 1]):
                row = lists.contact_row[k]
                if row >= 0:
                    lists.tr_k[c] = lists.j[k]
                    for q in range(history_size):
                        rebuild.carry[c, q] = lists.pool[row, q]
                    c += 1

    def new_starts(particles, lists):
        """The new rows' starts from their lengths, prefix-summed in ``counts``."""
        i = cuda.grid(1)
        if i == 0:
            lists.start[0] = 0
        if i < particles.x.shape[0]:
            lists.start[i + 1] = lists.counts[i]

    def carry_in(particles, lists, rebuild):
        """Each new row merged with its old contacts by partner id (both sorted by it): a contact
        still listed keeps its history in its entry's pool row; the rest of the row is out of
        contact. Also each entry's row (``lists.i``) and the positions the list was built at."""
        i = cuda.grid(1)
        if i < particles.x.shape[0]:
            ids = particles.ids
            c = lists.tr_start[i]
            last = lists.tr_start[i + 1]
            for q in range(lists.start[i], lists.start[i + 1]):
                j = lists.j[q]
                lists.i[q] = i
                while c < last and ids[lists.tr_k[c]] < ids[j]:
                    c += 1
                if c < last and lists.tr_k[c] == j:
                    for s in range(history_size):
                        lists.pool[q, s] = rebuild.carry[c, s]
                    lists.contact_row[q] = q
                    c += 1
                else:
                    lists.contact_row[q] = -1
            for d in range(3):
                particles.x_ref[i, d] = particles.x[i, d]

    def zero(scan, count):
        i = cuda.grid(1)
        if i < count:
            scan.values[i] = 0

    def count_keys(sort, count):
        """Items 0..count-1 counted into ``start[key + 2]``."""
        i = cuda.grid(1)
        if i < count:
            cuda.atomic.add(sort.start, sort.keys[i] + 2, 1)

    def place_keys(sort, count):
        """Each item into a slot of its group (``start[key + 1]`` its cursor: afterwards ``start``
        holds the groups' starts)."""
        i = cuda.grid(1)
        if i < count:
            slot = cuda.atomic.add(sort.start, sort.keys[i] + 1, 1)
            sort.items[slot] = i

    def sort_groups(sort, count):
        """Each group's items in ascending order (insertion sort: groups are small)."""
        g = cuda.grid(1)
        if g < count:
            items = sort.items
            first = sort.start[g]
            for p in range(first + 1, sort.start[g + 1]):
                v = items[p]
                q = p - 1
                while q >= first and items[q] > v:
                    items[q + 1] = items[q]
                    q -= 1
                items[q + 1] = v

    def chunk_sums(scan, count):
        """Each chunk's total into ``sums``."""
        first = cuda.grid(1) * chunk
        if first < count:
            total = 0
            for i in range(first, min(first + chunk, count)):
                total += scan.values[i]
            scan.sums[cuda.grid(1)] = total

    def chunk_scan(scan, count):
        """Each chunk's inclusive prefix sum, from the total of the chunks before it (``sums``,
        prefix-summed)."""
        t = cuda.grid(1)
        first = t * chunk
        if first < count:
            total = scan.sums[t - 1] if t > 0 else 0
            for i in range(first, min(first + chunk, count)):
                total += scan.values[i]
                scan.values[i] = total

    return dict(prepare=prepare, bounds=bounds, grid=grid, bin_particles=bin_particles, count_rows=count_rows,
                count_contacts=count_contacts, mesh_grid=mesh_grid, mesh_rows=mesh_rows, report=report, carry_out=carry_out,
                new_starts=new_starts, carry_in=carry_in, zero=zero, count_keys=count_keys, place_keys=place_keys,
                sort_groups=sort_groups, chunk_sums=chunk_sums, chunk_scan=chunk_scan)


class DeviceRebuild:
    """The neighbor-list rebuild of one upload of the records: its device arrays (the records'
    ``cell_start`` and ``tr_start`` are one longer on the device, as the counting sorts take it)
    and the launches."""

    def __init__(self, kernels, particles, walls, lists, history_size: int, contacts: int):
        self.k = kernels
        max_cells = self.max_cells = lists.cell_start.shape[0] - 2  # the host's length less one
        self.history_size = history_size
        n = particles.x.shape[0]
        self.n = n
        self.arrays = RebuildArrays(cuda_target.device_zeros(7, np.float64), cuda_target.device_zeros(9, np.float64),
                                    cuda_target.device_zeros(4, np.int64),
                                    cuda_target.device_zeros((self._carry_rows(contacts), history_size), np.float64))
        # the chunk totals of each level of a prefix sum as long as the longest (the cells'); the
        # mesh candidates' starts are int64
        self.sums = self._levels(max(max_cells + 2, n + 2), np.int32)
        self.sums64 = self._levels(n + 1 if walls.triangles.shape[0] else 0, np.int64)

    @staticmethod
    def _levels(length: int, dtype) -> list:
        levels = []
        while length > 1:
            length = -(-length // scan_chunk())
            levels.append(cuda_target.device_zeros(length, dtype))
        return levels

    @staticmethod
    def _carry_rows(contacts: int) -> int:
        return int(CARRY_SLACK * contacts) + 16

    def scan(self, values, count: int, sums=None, level: int = 0) -> None:
        """``values[:count]`` replaced by its inclusive prefix sum: each chunk's total, those totals
        prefix-summed (the next level), then each chunk's prefix sum from them. ``sums``: the
        levels' arrays of chunk totals, of the values' type (``self.sums``, int32, by default)."""
        sums = self.sums if sums is None else sums
        chunks = -(-count // scan_chunk())
        scan = Scan(values, sums[level] if level < len(sums) else values)
        if chunks > 1:
            cuda_target.launch(self.k["chunk_sums"], chunks, scan, count)
            self.scan(sums[level], chunks, sums, level + 1)
        cuda_target.launch(self.k["chunk_scan"], chunks, scan, count)

    def counting_sort(self, keys, start, items, count: int, groups: int, ordered: bool) -> None:
        """Items 0..count-1 grouped by ``keys`` in CSR form (``start[:groups + 1]``, ``items``), as
        the CPU's ``_counting_sort``; each group in ascending order if ``ordered`` (else in the
        order the threads took their slots)."""
        k, launch = self.k, cuda_target.launch
        launch(k["zero"], groups + 2, Scan(start, start), groups + 2)
        sort = CountingSort(keys, start, items)
        launch(k["count_keys"], count, sort, count)
        self.scan(start, groups + 2)
        launch(k["place_keys"], count, sort, count)
        if ordered:
            launch(k["sort_groups"], groups, sort, groups)

    def __call__(self, skin, particles, walls, lists, info) -> bool:
        """Rebuild the list on the device; False (with ``info``'s status and need, nothing but the
        wrapped centres changed) when the list's or the meshes' arrays are too short."""
        k, launch, n, rb = self.k, cuda_target.launch, self.n, self.arrays
        if n == 0:  # the list is empty already, and so are the mesh candidates
            info[I_REBUILDS] += 1
            return True
        launch(k["prepare"], n, particles, lists, rb)
        launch(k["bounds"], min(n, BOUNDS_THREADS), particles, rb)
        launch(k["grid"], 1, skin, self.max_cells, lists, rb)
        launch(k["bin_particles"], n, particles, lists, rb)
        # a cell's particles in any order: ``scan_row`` sorts each row by partner id
        self.counting_sort(lists.cell_of, lists.cell_start, lists.cell_items, n, self.max_cells, False)
        launch(k["count_rows"], n, skin, particles, lists, rb, 0)
        self.scan(lists.counts, n)
        launch(k["count_contacts"], n, particles, lists)
        self.scan(lists.tr_start, n + 1)
        meshes = walls.triangles.shape[0] != 0
        if meshes:
            launch(k["mesh_grid"], 1, skin, walls, rb)
            launch(k["mesh_rows"], n, skin, particles, walls, rb, 0)
            self.scan(walls.candidate_start, n + 1, self.sums64)
        launch(k["report"], 1, particles, walls, lists, rb)
        entries, contacts, mesh_short, mesh_needed = (int(v) for v in cuda_target.array_to_host(rb.report))
        if entries > lists.j.shape[0]:
            info[I_STATUS] = STATUS_CAPACITY
            info[I_NEEDED] = entries
            return False
        if mesh_short:
            info[I_STATUS] = STATUS_MESH_CAPACITY if mesh_short == 1 else STATUS_MESH_GRID_CAPACITY
            info[I_NEEDED] = mesh_needed
            return False
        if contacts > rb.carry.shape[0]:
            rb = self.arrays = rb._replace(carry=cuda_target.device_zeros((self._carry_rows(contacts),
                                                                           self.history_size), np.float64))
        if meshes:
            launch(k["mesh_rows"], n, skin, particles, walls, rb, 1)
        launch(k["carry_out"], n, particles, lists, rb)
        launch(k["new_starts"], n, particles, lists)
        launch(k["count_rows"], n, skin, particles, lists, rb, 1)
        launch(k["carry_in"], n, particles, lists, rb)
        # the gather sums a particle's entries in list order, as on the CPU
        self.counting_sort(lists.j, lists.tr_start, lists.tr_k, entries, n, True)
        info[I_REBUILDS] += 1
        return True
