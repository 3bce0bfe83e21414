"""Cell list and Verlet neighbor list with skin, and contact history carried across rebuilds.

The half list in CSR form, the pool of the contacts' rows (in groups of ``POOL_GROUP`` list rows)
and the transposed index of the gather: ``ContactList`` and the compiled rebuild. Their layout and
rules: docs/architecture.md, "The neighbor list and the contact pool"; what they are worth in
speed: docs/performance.md."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange, uint32, uint64

from rollingdem.engine.layout import PERIODIC_BOX as PB, PERIODIC_BOX_SIZE, ListArrays

POOL_GROUP = 256  # list rows per group of the contact pool (the pair pass's threads take whole groups)
PAIR_TERMS = 6  # columns of an entry's pair terms: F_ij (force on i) and T_j (torque on j) of the step


@njit(cache=True, inline="always")
def take_row(pool, groups, g, width):
    """A pool row for a contact that starts in group g, its ``width`` history columns zeroed (a new
    contact): the head of the group's free list, else the group's next unused row."""
    row = groups[g, 0]
    if row >= 0:
        groups[g, 0] = np.int32(pool[row, 0])  # a free row holds the next free row in its first column
    else:
        row = groups[g, 1]
        groups[g, 1] = row + 1
    for q in range(width):
        pool[row, q] = 0.0
    return row


@njit(cache=True, inline="always")
def free_row(pool, groups, g, row):
    """Row ``row`` of group g, whose contact ended, to the head of the group's free list."""
    pool[row, 0] = groups[g, 0]
    groups[g, 0] = row


@njit(cache=True)
def _counting_sort(keys, nitems, nkeys, start, items):
    """Group items 0..nitems-1 by ``keys[item]`` in CSR form (``start``, ``items``); stable, so the
    items of a group stay in ascending order."""
    for c in range(nkeys + 1):
        start[c] = 0
    for i in range(nitems):
        start[keys[i] + 1] += 1
    for c in range(nkeys):
        start[c + 1] += start[c]
    for i in range(nitems):  # the group starts serve as cursors ...
        c = keys[i]
        items[start[c]] = i
        start[c] += 1
    for c in range(nkeys, 0, -1):  # ... and are shifted back afterwards
        start[c] = start[c - 1]
    start[0] = 0


@njit(cache=True, inline="always")
def cell_index(x, i, lo, cells, dims):
    """The cell of particle i (edges ``cells`` from ``lo``, ``dims`` cells along x, y, z; a centre
    outside the grid goes to the cell at its edge)."""
    cx = min(max(int((x[i, 0] - lo[0]) / cells[0]), 0), dims[0] - 1)
    cy = min(max(int((x[i, 1] - lo[1]) / cells[1]), 0), dims[1] - 1)
    cz = min(max(int((x[i, 2] - lo[2]) / cells[2]), 0), dims[2] - 1)
    return (cz * dims[1] + cy) * dims[0] + cx


@njit(cache=True)
def _bin_particles(x, cells, lo, dims, cell_start, cell_items, cell_of):
    """Counting sort of particles into cells (edges ``cells`` along x, y, z); items of a cell in
    ascending particle index."""
    n = x.shape[0]
    for i in range(n):
        cell_of[i] = cell_index(x, i, lo, cells, dims)
    _counting_sort(cell_of, n, dims[0] * dims[1] * dims[2], cell_start, cell_items)


@njit(cache=True)
def _grid(x, radius, skin, max_cells, box):
    """Bounding box, cell edges >= 2 R_max + skin, and grid dimensions (``grid_of_bounds``)."""
    lox, loy, loz, hix, hiy, hiz, rmax = centre_bounds(x, radius, 0, 1)
    return grid_of_bounds(lox, loy, loz, hix, hiy, hiz, rmax, skin, max_cells, box)


@njit(cache=True, inline="always")
def centre_bounds(x, radius, first, stride):
    """(min x, y, z, max x, y, z, R_max) over the particles first, first + stride, ... (all of them
    from 0 with stride 1; a GPU thread's share with its own first and the grid's stride)."""
    lox = loy = loz = math.inf
    hix = hiy = hiz = -math.inf
    rmax = 0.0
    for i in range(first, x.shape[0], stride):
        lox = min(lox, x[i, 0])
        loy = min(loy, x[i, 1])
        loz = min(loz, x[i, 2])
        hix = max(hix, x[i, 0])
        hiy = max(hiy, x[i, 1])
        hiz = max(hiz, x[i, 2])
        rmax = max(rmax, radius[i])
    return lox, loy, loz, hix, hiy, hiz, rmax


@njit(cache=True, inline="always")
def grid_of_bounds(lox, loy, loz, hix, hiy, hiz, rmax, skin, max_cells, box):
    """(lo, dims, cells) of the cell grid over the centres' bounding box: cell edges >= 2 R_max +
    skin, at most max_cells cells. Along a periodic axis the cells tile the box's length exactly (so
    that the cells at its two ends are neighbors)."""
    cell = 2.0 * rmax + skin
    if box.shape[0] == 0:
        vol = (hix - lox + cell) * (hiy - loy + cell) * (hiz - loz + cell)
        cell = max(cell, (vol / max_cells) ** (1.0 / 3.0))
        while True:  # the volume estimate can round the count over the cap
            nx = max(1, int((hix - lox) / cell) + 1)
            ny = max(1, int((hiy - loy) / cell) + 1)
            nz = max(1, int((hiz - loz) / cell) + 1)
            if nx * ny * nz <= max_cells:
                break
            cell *= 1.05
        return (lox, loy, loz), (nx, ny, nz), (cell, cell, cell)
    # the three axes as scalars, not lists: the GPU's rebuild calls this too, and has no allocation
    lx, ly, lz = box[PB.lx], box[PB.ly], box[PB.lz]
    lo0, span0 = (box[PB.lox], lx) if lx > 0.0 else (lox, hix - lox + cell)
    lo1, span1 = (box[PB.loy], ly) if ly > 0.0 else (loy, hiy - loy + cell)
    lo2, span2 = (box[PB.loz], lz) if lz > 0.0 else (loz, hiz - loz + cell)
    cell = max(cell, (span0 * span1 * span2 / max_cells) ** (1.0 / 3.0))
    first = cell  # a closed axis keeps the first edge (its last cell takes what lies beyond)
    while True:
        n0, e0 = _axis_cells(span0, lx > 0.0, cell, first)
        n1, e1 = _axis_cells(span1, ly > 0.0, cell, first)
        n2, e2 = _axis_cells(span2, lz > 0.0, cell, first)
        if n0 * n1 * n2 <= max_cells:
            break
        cell *= 1.05
    return (lo0, lo1, lo2), (n0, n1, n2), (e0, e1, e2)


@njit(cache=True, inline="always")
def _axis_cells(span, periodic, cell, first):
    """(cells, edge) along one axis of a periodic box's grid: a periodic axis tiled exactly by cells
    of at least ``cell``; a closed one counted with ``cell`` and cut at ``first``."""
    if periodic:
        count = max(1, int(span / cell))
        return count, span / count
    return max(1, int((span - cell) / cell) + 1), first


@njit(cache=True)
def wrap_positions(x, v, image, box):
    """Put every centre back into the periodic box along its periodic axes, counting the lengths it
    moved in ``image`` (the unwrapped position is x + image L; in a sheared box, not along x)."""
    if box.shape[0] == 0:
        return
    for i in range(x.shape[0]):
        wrap_one(i, x, v, image, box)


@njit(cache=True, inline="always")
def wrap_one(i, x, v, image, box):
    """``wrap_positions`` for particle i (a periodic ``box``). In a sheared box a centre that crosses
    the gradient axis's end k times (k = +1: the upper end) becomes the image k lengths back: x
    less k times the shift and v_x less k times the shear velocity (Lees & Edwards 1972)."""
    if box.shape[0] > PERIODIC_BOX_SIZE:
        g = 1 if box[PB.gradient_y] != 0.0 else 2
        s = math.floor((x[i, g] - box[PB.lox + g]) * box[PB.inv_lg])
        if s != 0.0:
            x[i, g] -= s * box[PB.lg]
            x[i, 0] -= s * box[PB.shift]
            v[i, 0] -= s * box[PB.shear_velocity]
            image[i, g] += np.int32(s)
    for d in range(3):
        length = box[PB.lx + d]
        if length == 0.0:
            continue
        s = math.floor((x[i, d] - box[PB.lox + d]) * box[PB.inv_lx + d])
        if s != 0.0:
            x[i, d] -= s * length
            image[i, d] += np.int32(s)


@njit(cache=True, inline="always")
def minimum_image(d, length, inv_length):
    """The shortest of d + k L over whole k (d itself, exactly, where L = 1/L = 0)."""
    return d - length * round(d * inv_length)


@njit(cache=True, inline="always")
def sheared_image(dx, dy, dz, box):
    """(dx, dy, dz, k): x_i - x_j taken to the image of j k gradient lengths away that is nearest
    along the gradient axis (a sheared ``box``), before the minimum image of every axis: that image
    lies k lg along the gradient and k shift along x, and moves k shear velocities faster along x."""
    gy, gz = box[PB.gradient_y], box[PB.gradient_z]
    k = round((dy * gy + dz * gz) * box[PB.inv_lg])
    return dx - k * box[PB.shift], dy - k * box[PB.lg] * gy, dz - k * box[PB.lg] * gz, k


@njit(cache=True, parallel=True)
def _scan_pairs(x, radius, skin, ids, fixed, clump, box, dims, cell_start, cell_items, cell_of, counts, new_start, new_j,
                fill):
    """``scan_row`` for every particle: the rows' lengths into ``counts`` (fill = False) or the rows
    written (fill = True)."""
    for i in prange(x.shape[0]):
        k = scan_row(i, x, radius, skin, ids, fixed, clump, box, dims, cell_start, cell_items, cell_of, new_start, new_j,
                     fill)
        if not fill:
            counts[i] = k


@njit(cache=True, inline="always")
def scan_row(i, x, radius, skin, ids, fixed, clump, box, dims, cell_start, cell_items, cell_of, new_start, new_j, fill):
    """Row i of the half list: the j with ids[j] > ids[i] in the 27 cells around i's (across the
    ends of a periodic axis) with |x_i - x_j| < R_i + R_j + skin (the minimum image), not both
    fixed, not members of one clump. Returns their count (fill = False: nothing written) or writes them, sorted by id, from
    ``new_start[i]`` in ``new_j`` (fill = True). A periodic axis has at least 2 cells (its length is
    at least twice the cutoff); with 2, the cells on either side are the same one and are visited
    once."""
    periodic = box.shape[0] != 0
    sheared = box.shape[0] > PERIODIC_BOX_SIZE
    gradient = (1 if box[PB.gradient_y] != 0.0 else 2) if sheared else -1
    lx = box[PB.lx] if periodic else 0.0
    ly = box[PB.ly] if periodic else 0.0
    lz = box[PB.lz] if periodic else 0.0
    ilx = box[PB.inv_lx] if periodic else 0.0
    ily = box[PB.inv_ly] if periodic else 0.0
    ilz = box[PB.inv_lz] if periodic else 0.0
    wrap_x = lx > 0.0 and dims[0] >= 3
    has_fixed = fixed.shape[0] != 0
    c = cell_of[i]
    cx = c % dims[0]
    cy = (c // dims[0]) % dims[1]
    cz = c // (dims[0] * dims[1])
    k = new_start[i] if fill else 0
    xi = x[i, 0]
    yi = x[i, 1]
    zi = x[i, 2]
    ri = radius[i]
    idi = ids[i]
    fixed_i = has_fixed and fixed[i] != 0
    clump_i = clump[i] if clump.shape[0] != 0 else -1
    for dz in range(-1, 2):
        z = cz + dz
        across_z = z < 0 or z >= dims[2]
        if across_z:
            if lz == 0.0 or dims[2] < 3:
                continue
            z = (z + dims[2]) % dims[2]
        for dy in range(-1, 2):
            y = cy + dy
            across_y = y < 0 or y >= dims[1]
            if across_y:
                if ly == 0.0 or dims[1] < 3:
                    continue
                y = (y + dims[1]) % dims[1]
            # the three cells x-1, x, x+1 of this row are consecutive, so their items are too;
            # at the ends of a periodic x, the cell across the end is a second range
            row = (z * dims[1] + y) * dims[0]
            first = cell_start[row + max(cx - 1, 0)]
            last = cell_start[row + min(cx + 1, dims[0] - 1) + 1]
            parts = 2 if wrap_x and (cx == 0 or cx == dims[0] - 1) else 1
            # across a sheared end, the image row is displaced along x by the shift: the whole row
            # (and with fewer than 3 cells along the gradient, its one row serves both sides)
            if sheared and ((across_y or dims[1] < 3) if gradient == 1 else (across_z or dims[2] < 3)):
                first = cell_start[row]
                last = cell_start[row + dims[0]]
                parts = 1
            for part in range(parts):
                if part == 1:
                    across = row + dims[0] - 1 if cx == 0 else row
                    first = cell_start[across]
                    last = cell_start[across + 1]
                for m in range(first, last):
                    j = uint32(cell_items[uint64(m)])  # unsigned: no wraparound test per index
                    cut = ri + radius[j] + skin
                    ddx = xi - x[j, 0]
                    ddy = yi - x[j, 1]
                    ddz = zi - x[j, 2]
                    if sheared:
                        ddx, ddy, ddz, _ = sheared_image(ddx, ddy, ddz, box)
                    if periodic:
                        ddx = minimum_image(ddx, lx, ilx)
                        ddy = minimum_image(ddy, ly, ily)
                        ddz = minimum_image(ddz, lz, ilz)
                    # one test, mostly false, instead of the id test first (true for half the
                    # candidates, in no pattern: a mispredicted branch each other time)
                    if (ids[j] > idi) & (ddx * ddx + ddy * ddy + ddz * ddz < cut * cut):
                        if fixed_i and fixed[j] != 0:  # two fixed particles never touch
                            continue
                        if clump_i >= 0 and clump[j] == clump_i:  # nor two members of one rigid body
                            continue
                        if fill:
                            new_j[k] = j
                        k += 1
    if not fill:
        return k
    # insertion sort of the row: rows are short
    a = new_start[i]
    for p in range(a + 1, k):
        v = new_j[p]
        q = p - 1
        while q >= a and ids[new_j[q]] > ids[v]:
            new_j[q + 1] = new_j[q]
            q -= 1
        new_j[q + 1] = v
    return k


@njit(cache=True)
def _compact_contacts(n, nl_start, nl_j, contact_row, pool, act_start, act_j, target):
    """Move the contact rows of ``pool`` (entries k with ``contact_row[k] >= 0``) to its front, in
    list order, their partners into ``act_j`` and each row's range into ``act_start``. In place:
    the rows are permuted along the cycles of the permutation, one swap per row put in its place,
    with ``target`` (one int per row; the list's ``nl_i``, which the rebuild makes anew) saying
    where each row goes. Every row in use lies below the list's length, as each group's rows lie
    among its own entries."""
    width = pool.shape[1]
    used = nl_start[n]
    for s in range(used):
        target[s] = -1
    c = 0
    for i in range(n):
        act_start[i] = c
        for k in range(nl_start[i], nl_start[i + 1]):
            s = contact_row[k]
            if s >= 0:
                target[s] = c
                act_j[c] = nl_j[k]
                c += 1
    act_start[n] = c
    for s in range(used):
        t = target[s]
        while t >= 0 and t != s:  # the row at s goes to t; the row from t comes to s
            for q in range(width):
                held = pool[t, q]
                pool[t, q] = pool[s, q]
                pool[s, q] = held
            target[s] = target[t]
            target[t] = t
            t = target[s]


@njit(cache=True)
def _drop_lost_contacts(n, ids, nl_start, nl_j, pool, act_start, act_j):
    """Remove the compacted contacts whose pair is not in the new list (only after the positions
    were changed from outside: a contact of the last step is always within the cutoff plus skin).
    In place, moving rows down only."""
    width = pool.shape[1]
    out = 0
    for i in range(n):
        q = nl_start[i]
        qend = nl_start[i + 1]
        first = out
        for c in range(act_start[i], act_start[i + 1]):
            j = act_j[c]
            while q < qend and ids[nl_j[q]] < ids[j]:
                q += 1
            if q < qend and nl_j[q] == j:
                if out != c:
                    act_j[out] = j
                    for s in range(width):
                        pool[out, s] = pool[c, s]
                out += 1
        act_start[i] = first
    act_start[n] = out


@njit(cache=True)
def _place_contacts(n, nl_start, nl_j, contact_row, pool, act_start, act_j, groups):
    """Give each compacted contact its entry of the new list (``contact_row``, -1 for the entries out of
    contact) and its row at the front of its group's rows, in list order; each group's free list
    empty and its next unused row after its contacts.

    In place, from the last contact down: contact c goes to row p = (the group's first entry) +
    (its rank in the group) >= c, as a group's first entry is at least the number of contacts
    before it, so every row not yet read sits below p."""
    width = pool.shape[1]
    ngroups = (n + POOL_GROUP - 1) // POOL_GROUP
    for g in range(ngroups):
        groups[g, 0] = -1
        groups[g, 1] = nl_start[g * POOL_GROUP]
    for i in range(n):  # rows of both lists are sorted by partner id: a merge
        c = act_start[i]
        cend = act_start[i + 1]
        g = i // POOL_GROUP
        for q in range(nl_start[i], nl_start[i + 1]):
            if c < cend and act_j[c] == nl_j[q]:
                contact_row[q] = c
                c += 1
                groups[g, 1] += 1
            else:
                contact_row[q] = -1
    for g in range(ngroups - 1, -1, -1):
        p = groups[g, 1]
        for q in range(nl_start[min((g + 1) * POOL_GROUP, n)] - 1, nl_start[g * POOL_GROUP] - 1, -1):
            c = contact_row[q]
            if c >= 0:
                p -= 1
                if p != c:
                    for s in range(width):
                        pool[p, s] = pool[c, s]
                contact_row[q] = p


@njit(cache=True)
def _transpose(n, nl_start, nl_j, tr_start, tr_k):
    """For each particle j, the list entries k with nl_j[k] == j, in ascending k (so ascending i)."""
    _counting_sort(nl_j, np.int64(nl_start[n]), n, tr_start, tr_k)  # int64 as the binning's: one compile


@njit(cache=True)
def list_rows(n, nl_start, nl_i):
    """``nl_i[k]``: the row (first partner) of list entry k, so that a loop can run over the
    entries of many rows as one flat range (the pair pass's distance tests)."""
    for i in range(n):
        for k in range(nl_start[i], nl_start[i + 1]):
            nl_i[k] = i


@njit(cache=True)
def rebuild_neighbor_list(x, v, radius, skin, ids, fixed, clump, image, x_ref, lists):
    """Rebuild the half list (``lists``, a ``layout.ListArrays``) at the current positions,
    carrying contact history over (pairs of two fixed particles, and of two members of one clump, are
    left out); the centres are first
    put back into the periodic box (``wrap_positions``); ``x_ref`` gets the positions it was built at.

    Returns the number of list entries, or minus the capacity needed when ``nl_j`` is too short
    (nothing is changed then: the caller grows the arrays and calls again). The contact rows move
    in place, without a second buffer: they are compacted to the front of ``pool`` in list order
    (their partners and row ranges parked in ``tr_k`` and ``tr_start``, which the transpose
    rebuilds afterwards; ``nl_i`` is scratch, the caller makes it again with ``list_rows``), the
    new list is written over the old, and each contact goes to the front of its group's rows.
    """
    nl_start, nl_j, nl_i, pool, contact_row, groups = lists.start, lists.j, lists.i, lists.pool, lists.contact_row, \
        lists.groups
    tr_start, tr_k, cell_start, cell_items, cell_of, counts = lists.tr_start, lists.tr_k, lists.cell_start, \
        lists.cell_items, lists.cell_of, lists.counts
    n = x.shape[0]
    if n == 0:
        nl_start[0] = 0
        tr_start[0] = 0
        return 0
    box = lists.box
    wrap_positions(x, v, image, box)
    if box.shape[0] > PERIODIC_BOX_SIZE:
        box[PB.shift_since_build] = 0.0
    max_cells = cell_start.shape[0] - 1
    lo, dims, cells = _grid(x, radius, skin, max_cells, box)
    _bin_particles(x, cells, lo, dims, cell_start, cell_items, cell_of)
    # np.bool_, not a literal False/True: a literal compiles _scan_pairs once per value (1.5 s more
    # of a cold compile, and the rebuild no faster: 16.6 and 16.1 ms on the 20,000-sphere column)
    _scan_pairs(x, radius, skin, ids, fixed, clump, box, dims, cell_start, cell_items, cell_of, counts, nl_start, nl_j,
                np.bool_(False))
    total = 0
    for i in range(n):
        total += counts[i]
    if total > nl_j.shape[0]:
        return -total
    _compact_contacts(n, nl_start, nl_j, contact_row, pool, tr_start, tr_k, nl_i)
    nl_start[0] = 0
    for i in range(n):
        nl_start[i + 1] = nl_start[i] + counts[i]
    _scan_pairs(x, radius, skin, ids, fixed, clump, box, dims, cell_start, cell_items, cell_of, counts, nl_start, nl_j,
                np.bool_(True))
    _drop_lost_contacts(n, ids, nl_start, nl_j, pool, tr_start, tr_k)
    _place_contacts(n, nl_start, nl_j, contact_row, pool, tr_start, tr_k, groups)
    _transpose(n, nl_start, nl_j, tr_start, tr_k)
    for i in range(n):
        for d in range(3):
            x_ref[i, d] = x[i, d]
    return total


def spatial_order(x: np.ndarray, cell_size: float) -> np.ndarray:
    """A permutation that puts particles in Morton (Z-curve) order of cells of edge ``cell_size``.

    Neighbors in space become neighbors in memory, so the contact loop reads the partners' state
    from cache rather than from RAM (a randomly ordered 20,000-sphere bed runs ~40 % slower).
    Stable: particles in one cell keep their order.
    """
    x = np.asarray(x, dtype=np.float64)
    if len(x) == 0:
        return np.zeros(0, dtype=np.int64)
    cells = np.floor((x - x.min(axis=0)) / cell_size).astype(np.uint64)
    cells = np.minimum(cells, np.uint64((1 << 21) - 1))
    key = np.zeros(len(x), dtype=np.uint64)
    for bit in range(21):
        for axis in range(3):
            key |= ((cells[:, axis] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + 2 - axis)
    return np.argsort(key, kind="stable")


def brute_force_pairs(x: np.ndarray, radius: np.ndarray, skin: float) -> set[tuple[int, int]]:
    """All pairs (i < j) with |x_i - x_j| < R_i + R_j + skin, by brute force (for tests)."""
    d = np.linalg.norm(x[:, None, :] - x[None, :, :], axis=-1)
    cut = radius[:, None] + radius[None, :] + skin
    i, j = np.nonzero(np.triu(d < cut, k=1))
    return set(zip(i.tolist(), j.tolist()))


class ContactList:
    """The half list, its contact pool and its transposed index: the arrays (``ListArrays``), their
    capacity, and what Python does with them between calls of the step loop (the compiled half is above).

    ``rows`` list rows (one per particle); ``capacity`` entries, grown on demand. The pool's rows
    hold ``history_size`` history columns; the pair terms of a contact are the same row of
    ``pair_terms``.
    """

    def __init__(self, history_size: int, rows: int = 0, capacity: int = 16):
        self.history_size = history_size
        self.box = np.zeros(0)  # no periodic axis (``engine.periodic_box``)
        self.rows = 0
        self._allocate_rows(rows)
        self.allocate(capacity)

    # --- arrays ----------------------------------------------------------------------------
    def _allocate_rows(self, rows: int) -> None:
        """The arrays sized by the rows, empty (row starts int32, as the entry indices: < 2**31 entries)."""
        self.rows = rows
        self.start = np.zeros(rows + 1, dtype=np.int32)
        self.tr_start = np.zeros(rows + 1, dtype=np.int32)
        # rebuild scratch, int32 (16 B/p less than int64): at most max(2 n, 64) cells, n spheres
        self.cell_items = np.zeros(rows, dtype=np.int32)
        self.cell_of = np.zeros(rows, dtype=np.int32)
        self.counts = np.zeros(rows, dtype=np.int32)
        self.cell_start = np.zeros(max(2 * rows, 64) + 1, dtype=np.int32)
        # the pool's groups: head of the free list, next unused row; a rebuild sets them
        self.groups = np.zeros(((rows + POOL_GROUP - 1) // POOL_GROUP, 2), dtype=np.int32)
        self.groups[:, 0] = -1

    def add_rows(self, count: int) -> None:
        """``count`` empty rows after the last (new particles); the entries and contacts stay."""
        old_start, n0 = self.start, self.rows
        self._allocate_rows(n0 + count)
        self.start[: n0 + 1] = old_start[: n0 + 1]
        self.start[n0 + 1:] = old_start[n0] if n0 else 0

    def allocate(self, capacity: int, keep: int = 0) -> None:
        """Entry arrays of ``capacity``, the first ``keep`` entries (and their contacts) kept."""
        old = (getattr(self, "j", None), getattr(self, "pool", None), getattr(self, "contact_row", None))
        self.j = np.zeros(capacity, dtype=np.int32)
        self.i = np.zeros(capacity, dtype=np.int32)  # the row of each entry (list_rows)
        # the rows in use lie below the list's length, so the first ``keep`` rows are all there is
        # a free row keeps the next free row in its first column: one column at least
        self.pool = np.zeros((capacity, max(self.history_size, 1)))
        # apart from the history, which the pair pass reads and writes: the gather reads them alone,
        # in the order of the second partners; one row more, of zeros, that the gather reads for an
        # entry without a contact (no branch)
        self.pair_terms = np.zeros((capacity + 1, PAIR_TERMS))
        self.contact_row = np.full(capacity, -1, dtype=np.int32)
        if keep and old[0] is not None:
            self.j[:keep] = old[0][:keep]
            self.pool[:keep] = old[1][:keep]
            self.contact_row[:keep] = old[2][:keep]
        self.tr_k = np.zeros(capacity, dtype=np.int32)
        self.capacity = capacity

    def arrays(self) -> ListArrays:
        """The step loop's record of the list (made anew: the arrays are replaced when they grow)."""
        return ListArrays(self.start, self.j, self.i, self.pool, self.pair_terms, self.contact_row, self.groups,
                          self.tr_start, self.tr_k, self.cell_start, self.cell_items, self.cell_of, self.counts,
                          self.box)

    @property
    def size(self) -> int:
        """The number of entries."""
        return int(self.start[-1]) if self.start.size else 0

    # --- building --------------------------------------------------------------------------
    def rebuild(self, x, v, radius, skin, ids, fixed, clump, image, x_ref, grow) -> int:
        """Rebuild at the present positions, carrying the contacts over; ``grow(needed)`` is called
        while the arrays are too short. Returns the number of entries."""
        while True:
            total = rebuild_neighbor_list(x, v, radius, skin, ids, fixed, clump, image, x_ref, self.arrays())
            if total >= 0:
                list_rows(self.rows, self.start, self.i)
                return total
            grow(-total)

    def index(self) -> None:
        """The indices derived from the list (``start``, ``j``): the transposed index (``tr_start``,
        ``tr_k``) and each entry's row (``i``), as a rebuild makes them."""
        index_list(self.arrays())

    def reorder(self, perm: np.ndarray, inv: np.ndarray) -> None:
        """Rows follow a re-sort of the particles (new row s is old row ``perm[s]``, ``inv`` its
        inverse); entries keep their order (by partner id) and their contacts."""
        hist = self.entry_history()
        old_start = self.start.copy()
        lengths = np.diff(old_start)[perm]
        self.start[0] = 0
        np.cumsum(lengths, out=self.start[1:])
        total = int(self.start[-1])
        src = np.repeat(old_start[:-1][perm] - self.start[:-1], lengths) + np.arange(total)
        self.j[:total] = inv[self.j[src]]
        self.index()
        self.set_entry_history(hist[src])

    # --- contact history per entry (the layout of checkpoints) -----------------------------
    def entry_history(self) -> np.ndarray:
        """The contact history of each entry, (entries, history_size), zeros out of contact."""
        total = self.size
        hist = np.zeros((total, self.history_size))
        rows = self.contact_row[:total]
        touching = rows >= 0
        hist[touching] = self.pool[rows[touching], :self.history_size]
        return hist

    def set_entry_history(self, hist: np.ndarray) -> None:
        """Put a history per entry (``entry_history``'s layout) into the pool, as a rebuild leaves
        it (``put_entry_history``). Needs ``i`` (``index``)."""
        put_entry_history(self.arrays(), hist, self.history_size)


def index_list(lists) -> None:
    """A list record's indices derived from its rows (``start``, ``j``): the transposed index
    (``tr_start``, ``tr_k``) and each entry's row (``i``), as a rebuild makes them."""
    rows = lists.start.shape[0] - 1
    _transpose(rows, lists.start, lists.j, lists.tr_start, lists.tr_k)
    list_rows(rows, lists.start, lists.i)


def put_entry_history(lists, hist: np.ndarray, history_size: int) -> None:
    """Put a history per entry into a list record's pool, as a rebuild leaves it: an entry is in
    contact iff it keeps a contact normal, each group's contacts at the front of its rows in list
    order. Needs ``lists.i``."""
    total = int(lists.start[-1]) if lists.start.size else 0
    rows_n = lists.start.shape[0] - 1
    touching = np.nonzero(np.any(hist[:total, :3] != 0.0, axis=1))[0]
    group = lists.i[touching] // POOL_GROUP
    first_entry = lists.start[np.minimum(np.arange(len(lists.groups)) * POOL_GROUP, rows_n)]
    rank = np.arange(len(touching)) - np.searchsorted(group, group)  # in its group, in list order
    rows = first_entry[group] + rank
    lists.contact_row[:total] = -1
    lists.contact_row[touching] = rows
    lists.pool[rows, :history_size] = hist[touching]
    lists.groups[:, 0] = -1
    lists.groups[:, 1] = first_entry + np.bincount(group, minlength=len(lists.groups))


__all__ = ["ContactList", "index_list", "put_entry_history", "rebuild_neighbor_list", "list_rows", "brute_force_pairs", "spatial_order"]
