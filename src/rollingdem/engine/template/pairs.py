"""The pair pass: each thread a range of rows of the half list, contacts found by the distance
tests, queued and computed 64 at a time (one per SIMD lane) or one at a time (``pair_row``), their
force and torque on i summed per row, the pair terms stored with the contact.

A part of the step loop's template (``rollingdem.engine.template``).
"""

import math
import numpy as np
from numba import njit, prange, uint32, uint64
from numba.np.arrayobj import reshape_unchecked

from rollingdem.physics.records import BOND_PARAMETERS, CONTACT_INPUTS as IN, N_INPUTS, N_RESULTS
from rollingdem.engine.layout import BLOCK_SHIFT, CONTACT_BLOCK, LANE_HITS, PERIODIC_BOX as PB, PERIODIC_BOX_SIZE
from rollingdem.engine.neighbors import POOL_GROUP, free_row, minimum_image, sheared_image, take_row
from rollingdem.engine.step_records import PairRecords
from rollingdem.physics.bonds import BOND_INTACT
from rollingdem.physics.contact.frame import SERIES_ANGLE, contact_frame_series, spin_angle, stored_normal
from rollingdem.engine.template.contact import BLOCK_COLUMNS, BONDED_PAIRS, B_IN, B_OUT, B_SCALAR, CANDIDATE_SLACK, DETACH_AT, HISTORY_SIZE, INERTIA_R_FACTOR, NO_CONTACT, TRACK_ENERGY, add_contact, add_energies_and_count, bonded_contact, contact, contact_in_frame  # @@PART


@njit(cache=True, inline="always")
def lane_columns(block):
    """The block buffer as ``col[lane, column]`` (column-major: a column's lanes are contiguous)."""
    return reshape_unchecked(block, (CONTACT_BLOCK, BLOCK_COLUMNS), (8, 8 * CONTACT_BLOCK))


@njit(cache=True, no_cpython_wrapper=True, _nrt=False, error_model="numpy", fastmath={"contract"})
def block_contacts(block, p, dt):
    """All ``CONTACT_BLOCK`` lanes of a block buffer through the contact law, one contact per lane:
    ``contact`` for a spin angle below ``SERIES_ANGLE``, with selects instead of branches and the
    frame's cos and sin from their series, at offsets known when compiling, so that the loop
    vectorises. Lanes past the block's count hold stale inputs: computed and ignored (every
    contact goes through the same vector code, whatever block it falls in)."""
    col = lane_columns(block)
    for n in range(CONTACT_BLOCK):
        g = (col[n, B_IN + IN.nx], col[n, B_IN + IN.ny], col[n, B_IN + IN.nz], col[n, B_IN + IN.overlap],
             col[n, B_IN + IN.rvx], col[n, B_IN + IN.rvy], col[n, B_IN + IN.rvz], col[n, B_IN + IN.wix],
             col[n, B_IN + IN.wiy], col[n, B_IN + IN.wiz], col[n, B_IN + IN.wjx], col[n, B_IN + IN.wjy],
             col[n, B_IN + IN.wjz], col[n, B_IN + IN.lever_i], col[n, B_IN + IN.lever_j], col[n, B_IN + IN.r_eff],
             col[n, B_IN + IN.m_eff], col[n, B_IN + IN.inertia_r])
        onx, ony, onz = stored_normal(col, n, g[IN.nx], g[IN.ny], g[IN.nz])
        phi = spin_angle(g[IN.nx], g[IN.ny], g[IN.nz], g[IN.wix], g[IN.wiy], g[IN.wiz], g[IN.wjx], g[IN.wjy], g[IN.wjz],
                         dt)
        frame = contact_frame_series(onx, ony, onz, g[IN.nx], g[IN.ny], g[IN.nz], phi)
        res = contact_in_frame(col, n, frame, g, p, dt, True)
        for c in range(N_RESULTS):
            col[n, B_OUT + c] = res[c]


@njit(cache=True, no_cpython_wrapper=True, _nrt=False, error_model="numpy", fastmath={"contract"})
def flush_block(count, block, lanes, dt, f, t, p, pool, pair_terms, energy, contacts):
    """Compute a block of ``count`` contacts (material pair parameters ``p``) and scatter the results:
    history back to each contact's pool row, F and T_j to the same row of ``pair_terms``, F and T
    added to row i in the order of its entries (the order the scalar loop summed them in)."""
    block_contacts(block, p, dt)
    col = lane_columns(block)
    for n in range(count):
        un = uint64(n)
        row = uint64(lanes[0, n])  # the contact's pool row
        i = uint64(lanes[1, n])
        out = B_SCALAR if lanes[2, n] else B_OUT  # the scalar contact already wrote its history row
        if not lanes[2, n]:
            for s in range(HISTORY_SIZE):
                pool[row, s] = col[un, s]
        for d in range(3):
            force = col[un, out + d]
            f[i, d] += force
            t[i, d] += col[un, out + 3 + d]
            pair_terms[row, d] = force
            pair_terms[row, 3 + d] = -col[un, out + 6 + d]
        if TRACK_ENERGY:
            for c in range(4):
                energy[i, c] += col[un, out + 9 + c]
        contacts[i] += 1


NO_INPUTS = (0.0,) * N_INPUTS


@njit(cache=True, inline="always")
def bonded(i, j, particles, exclusive):
    """Whether particles i and j hold an intact bond whose ``exclusive`` flag is ``exclusive``."""
    pairs, status, ends = particles.bond_pairs, particles.bond_status, particles.bond_ends
    for e in range(particles.bond_start[i], particles.bond_start[i + 1]):
        b = ends[e] >> 1
        if (pairs[b, 1 - (ends[e] & 1)] == j and status[b] == BOND_INTACT
                and (particles.bond_parameters[b, BOND_PARAMETERS.exclusive] != 0.0) == exclusive):
            return True
    return False


@njit(cache=True, inline="always")
def entry_inputs(i, k, particles, lists):
    """Entry k (row i) of the half list: (whether the spheres touch, j, the contact's pool row, its
    ``CONTACT_INPUTS``). A contact that starts takes a pool row of its group (history zeroed); one
    that ends gives its row back (``rollingdem.engine.neighbors``)."""
    x, v, w, radius, mass = particles.x, particles.v, particles.w, particles.radius, particles.mass
    j = uint32(lists.j[k])
    dx = x[i, 0] - x[j, 0]
    dy = x[i, 1] - x[j, 1]
    dz = x[i, 2] - x[j, 2]
    box = lists.box
    jump = 0.0  # the partner's image's velocity along x, relative to the partner (a sheared box)
    if box.shape[0] > PERIODIC_BOX_SIZE:
        dx, dy, dz, lengths = sheared_image(dx, dy, dz, box)
        jump = lengths * box[PB.shear_velocity]
    if box.shape[0] != 0:
        dx = minimum_image(dx, box[PB.lx], box[PB.inv_lx])
        dy = minimum_image(dy, box[PB.ly], box[PB.inv_ly])
        dz = minimum_image(dz, box[PB.lz], box[PB.inv_lz])
    ri = radius[i]
    rj = radius[j]
    d2 = dx * dx + dy * dy + dz * dz
    reach = ri + rj
    row = lists.contact_row[k]
    apart = d2 >= reach * reach and not (DETACH_AT >= 0 and row >= 0
                                         and d2 < (reach + lists.pool[row, DETACH_AT]) * (reach + lists.pool[row, DETACH_AT]))
    if BONDED_PAIRS and not apart:
        apart = bonded(uint64(i), uint64(j), particles, True)
    # a list without pool groups keeps entry k's contact in pool row k (the GPU's, so that each
    # list row may start and end its contacts on a thread of its own, rollingdem.engine.cuda.step_loop); the
    # test is made only when a contact starts or ends
    if apart:
        if row >= 0:
            if lists.groups.shape[0] != 0:
                free_row(lists.pool, lists.groups, uint64(i) // uint64(POOL_GROUP), row)
            lists.contact_row[k] = -1
        return False, j, row, NO_INPUTS
    if row < 0:
        if lists.groups.shape[0] == 0:
            row = np.int32(k)
            for q in range(HISTORY_SIZE):
                lists.pool[k, q] = 0.0
        else:
            row = take_row(lists.pool, lists.groups, uint64(i) // uint64(POOL_GROUP), HISTORY_SIZE)
        lists.contact_row[k] = row
    dist = math.sqrt(d2)
    overlap = reach - dist
    inv_dist = 1.0 / dist
    mi = mass[i]
    mj = mass[j]
    ai = mi * ri * ri
    aj = mj * rj * rj
    m_eff = mi * mj / (mi + mj)
    inertia_r = INERTIA_R_FACTOR * ai * aj / (ai + aj)
    if particles.fixed.shape[0] != 0 and (particles.fixed[i] | particles.fixed[j]):
        # a fixed partner has infinite mass and inertia, as a wall (LAMMPS's frozen atoms in the
        # granular pair styles): the free partner's own
        free = j if particles.fixed[i] else uint32(i)
        m_eff = mass[free]
        inertia_r = INERTIA_R_FACTOR * mass[free] * radius[free] * radius[free]
    return True, j, row, (dx * inv_dist, dy * inv_dist, dz * inv_dist, overlap,
                          v[i, 0] - v[j, 0] - jump, v[i, 1] - v[j, 1], v[i, 2] - v[j, 2],
                          w[i, 0], w[i, 1], w[i, 2], w[j, 0], w[j, 1], w[j, 2],
                          ri - 0.5 * overlap, rj - 0.5 * overlap, ri * rj / reach, m_eff, inertia_r)


@njit(cache=True, inline="always")
def queue_inputs(col, n, g):
    """Lane n's ``CONTACT_INPUTS`` columns, written out (a loop over the tuple: pair pass 3-6 % slower)."""
    col[n, B_IN + IN.nx] = g[IN.nx]
    col[n, B_IN + IN.ny] = g[IN.ny]
    col[n, B_IN + IN.nz] = g[IN.nz]
    col[n, B_IN + IN.overlap] = g[IN.overlap]
    col[n, B_IN + IN.rvx] = g[IN.rvx]
    col[n, B_IN + IN.rvy] = g[IN.rvy]
    col[n, B_IN + IN.rvz] = g[IN.rvz]
    col[n, B_IN + IN.wix] = g[IN.wix]
    col[n, B_IN + IN.wiy] = g[IN.wiy]
    col[n, B_IN + IN.wiz] = g[IN.wiz]
    col[n, B_IN + IN.wjx] = g[IN.wjx]
    col[n, B_IN + IN.wjy] = g[IN.wjy]
    col[n, B_IN + IN.wjz] = g[IN.wjz]
    col[n, B_IN + IN.lever_i] = g[IN.lever_i]
    col[n, B_IN + IN.lever_j] = g[IN.lever_j]
    col[n, B_IN + IN.r_eff] = g[IN.r_eff]
    col[n, B_IN + IN.m_eff] = g[IN.m_eff]
    col[n, B_IN + IN.inertia_r] = g[IN.inertia_r]


@njit(cache=True, inline="always")
def queue_candidate(lanes, nhit, kk, dx, dy, dz, reach, row):
    """Entry kk written at place ``nhit`` of the hits; the count of hits after it: one more if its
    spheres, ``reach`` = R_i + R_j apart at separation (dx, dy, dz), may touch, or touched at the
    last step (its pool ``row`` >= 0). Written whatever the test: no branch."""
    lanes[uint64(LANE_HITS) + (nhit >> uint64(BLOCK_SHIFT)), nhit & uint64(CONTACT_BLOCK - 1)] = kk
    return nhit + uint64((dx * dx + dy * dy + dz * dz < CANDIDATE_SLACK * reach * reach) | (row >= 0))


@njit(cache=True, inline="always")
def candidate_entries(k0, k1, x, radius, nl_j, nl_i, contact_row, lanes, box):
    """Entries k0..k1-1 whose spheres may touch now or touched at the last step, in ascending k, into
    the rows ``LANE_HITS..`` of ``lanes``; returns their count. One flat loop without branches over
    the entries of many rows (a loop per row mispredicts its exit once per row). The test is looser
    than ``entry_inputs``' by a relative 1e-12: an entry on the edge is left to it to decide. In a
    periodic box, a loop of its own with the minimum image (in a sheared box, of the image across
    the gradient first)."""
    nhit = uint64(0)
    if box.shape[0] != 0:
        sheared = box.shape[0] > PERIODIC_BOX_SIZE
        lx, ly, lz = box[PB.lx], box[PB.ly], box[PB.lz]
        ilx, ily, ilz = box[PB.inv_lx], box[PB.inv_ly], box[PB.inv_lz]
        for kk in range(k0, k1):
            k = uint64(kk)
            i = uint32(nl_i[k])
            j = uint32(nl_j[k])
            dx, dy, dz = x[i, 0] - x[j, 0], x[i, 1] - x[j, 1], x[i, 2] - x[j, 2]
            if sheared:  # the same for every entry: predicted
                dx, dy, dz, _ = sheared_image(dx, dy, dz, box)
            dx = minimum_image(dx, lx, ilx)
            dy = minimum_image(dy, ly, ily)
            dz = minimum_image(dz, lz, ilz)
            nhit = queue_candidate(lanes, nhit, kk, dx, dy, dz, radius[i] + radius[j], contact_row[k])
        return np.int64(nhit)
    for kk in range(k0, k1):
        k = uint64(kk)
        i = uint32(nl_i[k])
        j = uint32(nl_j[k])
        dx = x[i, 0] - x[j, 0]
        dy = x[i, 1] - x[j, 1]
        dz = x[i, 2] - x[j, 2]
        nhit = queue_candidate(lanes, nhit, kk, dx, dy, dz, radius[i] + radius[j], contact_row[k])
    return np.int64(nhit)


@njit(cache=True, inline="always")
def pair_row(i, dt, particles, lists, pair_params):
    """Row i of the half list, one contact at a time through the scalar ``contact`` (spheres of more
    than one material, see ``pair_rows``)."""
    f, t, mat, pool = particles.f, particles.t, particles.mat, lists.pool
    sums = NO_CONTACT
    for k in range(lists.start[i], lists.start[i + 1]):
        touching, j, row, g = entry_inputs(i, k, particles, lists)
        if not touching:
            continue
        if BONDED_PAIRS and bonded(uint64(i), uint64(j), particles, False):
            res = bonded_contact(pool, np.int64(row), g, pair_params[mat[i], mat[j]], dt)
        else:
            res = contact(pool, np.int64(row), g, pair_params[mat[i], mat[j]], dt)
        sums = add_contact(sums, res)
        for d in range(3):
            lists.pair_terms[row, d] = res[d]
            lists.pair_terms[row, 3 + d] = -res[6 + d]
    f[i, 0] = sums[0]
    f[i, 1] = sums[1]
    f[i, 2] = sums[2]
    t[i, 0] = sums[3]
    t[i, 1] = sums[4]
    t[i, 2] = sums[5]
    particles.contacts[i] = 0
    add_energies_and_count(i, particles, sums)


@njit(cache=True, _nrt=False, error_model="numpy", fastmath={"contract"})
def pair_rows_scalar(lo, hi, dt, particles, lists, pair_params):
    """Rows lo..hi-1 through the scalar ``pair_row``, compiled as ``pair_rows`` is: the GPU's pair
    pass (``rollingdem.engine.cuda.step_loop``), equal bit for bit to the CPU's for spheres of several
    materials."""
    for i in range(lo, hi):
        pair_row(i, dt, particles, lists, pair_params)


@njit(cache=True, no_cpython_wrapper=True, _nrt=False, error_model="numpy", fastmath={"contract"})
def pair_rows(lo, hi, dt, particles, lists, pair_params, block, lanes):
    """Rows lo..hi-1 of the half list (whole groups of the pool): F and T on i summed over the row,
    F and T_j kept per contact. The contacts a tile's distance tests find are queued into
    ``block`` and computed ``CONTACT_BLOCK`` at a time (``block_contacts``); a block's lanes share
    one parameter row, so with spheres of several materials (an empty ``block``) the rows go
    through ``pair_row``. A contact that spins ``SERIES_ANGLE`` or more in the step is computed by
    the scalar ``contact`` (libm's cos and sin) and keeps its lane."""
    if block.shape[0] == 0:
        for i in range(lo, hi):
            pair_row(i, dt, particles, lists, pair_params)
        return
    f, t, pool, contacts = particles.f, particles.t, lists.pool, particles.contacts
    p = pair_params[particles.mat[lo], particles.mat[lo]] if hi > lo else pair_params[0, 0]
    count = np.int64(0)  # not a literal 0, which would compile flush_block a second time
    for i in range(lo, hi):
        for d in range(3):
            f[i, d] = 0.0
            t[i, d] = 0.0
        contacts[i] = 0
    col = lane_columns(block)
    tile = (lanes.shape[0] - LANE_HITS) * CONTACT_BLOCK
    kend = lists.start[hi]
    for k0 in range(lists.start[lo], kend, tile):
        nhit = candidate_entries(k0, min(k0 + tile, kend), particles.x, particles.radius, lists.j, lists.i,
                                 lists.contact_row, lanes, lists.box)
        for e in range(nhit):
            k = uint64(lanes[LANE_HITS + (e >> BLOCK_SHIFT), e & (CONTACT_BLOCK - 1)])
            i = uint32(lists.i[k])
            touching, j, row, g = entry_inputs(i, k, particles, lists)
            if not touching:
                continue
            if count == CONTACT_BLOCK:
                flush_block(count, block, lanes, dt, f, t, p, pool, lists.pair_terms, particles.energy, contacts)
                count = 0
            n = count
            un = uint64(n)
            count += 1
            queue_inputs(col, un, g)
            urow = uint64(row)
            for s in range(HISTORY_SIZE):
                col[un, s] = pool[urow, s]
            lanes[0, n] = row
            lanes[1, n] = i
            phi = spin_angle(g[IN.nx], g[IN.ny], g[IN.nz], g[IN.wix], g[IN.wiy], g[IN.wiz], g[IN.wjx], g[IN.wjy],
                             g[IN.wjz], dt)
            lanes[2, n] = 0 if abs(phi) < SERIES_ANGLE else 1
            if BONDED_PAIRS and bonded(uint64(i), uint64(j), particles, False):
                lanes[2, n] = 1  # computed here, as a fast spin is
                res = bonded_contact(pool, np.int64(row), g, p, dt)
                for c in range(N_RESULTS):
                    col[un, B_SCALAR + c] = res[c]
            elif lanes[2, n]:
                res = contact(pool, np.int64(row), g, p, dt)
                for c in range(N_RESULTS):
                    col[un, B_SCALAR + c] = res[c]
    if count > 0:
        flush_block(count, block, lanes, dt, f, t, p, pool, lists.pair_terms, particles.energy, contacts)


@njit(cache=True, inline="always")
def pair_chunk(b, nblock, dt, pair_params, held):
    """Thread b's share of ``pair_forces`` (of ``nblock``): a contiguous range of whole pool groups,
    with its own block buffer."""
    particles, scratch = held.particles, held.scratch
    n = particles.x.shape[0]
    ngroups = (n + POOL_GROUP - 1) // POOL_GROUP
    pair_rows(min(b * ngroups // nblock * POOL_GROUP, n), min((b + 1) * ngroups // nblock * POOL_GROUP, n), dt,
              particles, held.lists, pair_params, scratch.blocks[b], scratch.lanes[b])


@njit(cache=True, parallel=True, error_model="numpy", fastmath={"contract"})
def pair_forces(dt, pair_params, particles, lists, scratch):
    """Pair contacts: each thread a contiguous range of whole pool groups, with its own block buffer
    (``pair_chunk``; the records behind one reference, ``PairRecords``)."""
    nblock = scratch.blocks.shape[0]
    held = PairRecords(particles, lists, scratch)
    for b in prange(nblock):
        pair_chunk(np.int64(b), nblock, dt, pair_params, held)


@njit(cache=True, parallel=True, error_model="numpy", fastmath={"contract"})
def pair_forces_serial(dt, pair_params, particles, lists, scratch):
    """``pair_forces`` on the calling thread (parallel=True, range: see ``integrator``)."""
    for b in range(1):  # lo = b, not 0: a literal 0 would compile pair_rows a second time
        pair_rows(b, particles.x.shape[0], dt, particles, lists, pair_params, scratch.blocks[b], scratch.lanes[b])


