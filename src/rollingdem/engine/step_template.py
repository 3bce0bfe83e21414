"""The compiled step loop: neighbor list -> contact forces and torques -> velocity Verlet.

A template: ``rollingdem.engine.codegen`` writes a copy of it per contact law, the lines tagged ``# @@``
filled in; as it stands it is a valid module (Hertz, history, no rolling, no twisting). It takes
four records of arrays (``rollingdem.engine.layout``), allocates nothing and calls no Python. The step and the
contract: docs/architecture.md; what each choice is worth: docs/performance.md.
"""

import math

import numpy as np
from numba import njit, prange, uint32, uint64
from numba.np.arrayobj import reshape_unchecked

from rollingdem.physics.records import BOND_PARAMETERS, CONTACT_INPUTS as IN, N_INPUTS, N_RESULTS, WALL_LOAD_SIZE
from rollingdem.engine.layout import BLOCK_SHIFT, CONTACT_BLOCK, I_DRIFTED, I_FORCES_VALID, I_NEED_REBUILD, I_NEEDED, I_REBUILDS, I_STATUS, I_STEPS_DONE, I_TOO_FAST, LANE_HITS, MESH_GRID as GR, PERIODIC_BOX as PB, MESH_MOTION as MO, MESH_SLOTS, STATUS_CAPACITY, STATUS_MESH_CAPACITY, STATUS_MESH_GRID_CAPACITY, STATUS_TOO_FAST
from rollingdem.engine.integrator import (kick_drift, kick_drift_one, kick_drift_range, kick_drift_serial, move_walls,
                                   next_drift_bound, undo_drift)
from rollingdem.engine.neighbors import POOL_GROUP, free_row, list_rows, minimum_image, rebuild_neighbor_list, take_row
from rollingdem.engine.mesh_passes import build_mesh_candidates, match_mesh_contacts, move_meshes, surface_velocity
from rollingdem.physics.walls import wall_contact_geometry
from rollingdem.physics.bonds import BOND_INTACT, parallel_bond
from rollingdem.physics.contact.frame import SERIES_ANGLE, contact_frame, contact_frame_series, spin_angle, stored_normal
from rollingdem.physics.contact.normal import hertz_normal as normal_force  # @@NORMAL
from rollingdem.physics.contact.tangential import history_spring as tangential_force  # @@TANGENTIAL
from rollingdem.physics.contact.rolling import no_rolling as rolling_moment  # @@ROLLING
from rollingdem.physics.contact.twisting import no_twisting as twisting_moment  # @@TWISTING
from rollingdem.physics.contact.cohesion import no_cohesion as cohesion_force  # @@COHESION

NORMAL_PARAMS = 6  # @@NORMAL_PARAMS
TANGENTIAL_PARAMS = 8  # @@TANGENTIAL_PARAMS
ROLLING_PARAMS = 8  # @@ROLLING_PARAMS
TWISTING_PARAMS = 8  # @@TWISTING_PARAMS
COHESION_PARAMS = 8  # @@COHESION_PARAMS
NORMAL_HISTORY = 3  # @@NORMAL_HISTORY
TANGENTIAL_HISTORY = 3  # @@TANGENTIAL_HISTORY
ROLLING_HISTORY = 6  # @@ROLLING_HISTORY
TWISTING_HISTORY = 6  # @@TWISTING_HISTORY
COHESION_HISTORY = 6  # @@COHESION_HISTORY
DETACH_AT = -1  # @@DETACH_AT
TRACK_ENERGY = 1  # @@TRACK_ENERGY
# whether the scene holds bonds: a kernel of its own, as the per-entry bond check (an exclusive bond
# keeps its pair's contact off, a parallel one its rolling and twisting moments) costs the pair pass
# of every other scene a third
BONDED_PAIRS = 0  # @@BONDED_PAIRS
ROLLING_MODES = ()  # @@ROLLING_MODES
HISTORY_SIZE = 6  # @@HISTORY_SIZE
N_PARAMS = 8  # @@N_PARAMS

# Indices in the hot loops are unsigned (``uint64(k)``): Numba gives a signed index Python's
# wraparound for negative values, a compare and a select per index (40 % of the candidate loop).

# columns of a contact's pool row (``rollingdem.engine.neighbors``) after its history: F on i, T on j
P_FORCE = HISTORY_SIZE
P_TORQUE_J = HISTORY_SIZE + 3
B_IN = HISTORY_SIZE  # block buffer columns: history, inputs, results, the scalar contact's results
B_OUT = B_IN + N_INPUTS
B_SCALAR = B_OUT + N_RESULTS
BLOCK_COLUMNS = B_SCALAR + N_RESULTS
CANDIDATE_SLACK = 1.0 + 1e-12
GATHER_RUN = 256  # particles per call of gather_rows: the call is negligible, the threads stay balanced
INERTIA_R_FACTOR = 1.4  # I + m R^2 = 1.4 m R^2 for a solid sphere (seed report eq. 12)


@njit(cache=True, inline="always")
def contact_of(hist, k, g, p, dt, moments):
    """One contact, its inputs ``g`` (``CONTACT_INPUTS``): the ``CONTACT_RESULTS`` (force on i,
    torque on i, torque on j, dissipated energies). (rvx, rvy, rvz) is the velocity of i's centre
    relative to j's centre (for a wall: relative to the wall's surface velocity at the contact,
    with lever_j = 0). Without ``moments`` (a compile-time constant) no rolling or twisting moment."""
    nx, ny, nz = g[IN.nx], g[IN.ny], g[IN.nz]
    onx = hist[k, 0]
    ony = hist[k, 1]
    onz = hist[k, 2]
    # ``stored_normal`` with a branch: its selects give the same values, but move the compiler's
    # fused multiply-adds, and the scalar path would change at round-off
    if onx == 0.0 and ony == 0.0 and onz == 0.0:
        onx = nx
        ony = ny
        onz = nz
    frame = contact_frame(onx, ony, onz, nx, ny, nz, spin_angle(nx, ny, nz, g[IN.wix], g[IN.wiy], g[IN.wiz], g[IN.wjx],
                                                                g[IN.wjy], g[IN.wjz], dt))
    return contact_in_frame(hist, k, frame, g, p, dt, moments)


@njit(cache=True, _nrt=False, error_model="numpy", fastmath={"contract"})
def contact(hist, k, g, p, dt):
    """``contact_of`` with every moment."""
    return contact_of(hist, k, g, p, dt, True)


@njit(cache=True, _nrt=False, error_model="numpy", fastmath={"contract"})
def bonded_contact(hist, k, g, p, dt):
    """The contact of a pair held by an intact ``parallel`` bond: no rolling or twisting moment (the
    bond's bending and twisting springs resist that motion, docs/models.md §1.7), and their
    history stays zero, so that they start fresh at the break."""
    return contact_of(hist, k, g, p, dt, False)


@njit(cache=True, inline="always")
def contact_in_frame(hist, k, frame, g, p, dt, moments):
    """The body of ``contact`` once the frame change is known."""
    (nx, ny, nz, overlap, rvx, rvy, rvz, wix, wiy, wiz, wjx, wjy, wjz, lever_i, lever_j, r_eff, m_eff,
     inertia_r) = g
    vn = rvx * nx + rvy * ny + rvz * nz
    # slip velocity at the contact point: v_c = (v_i - v_j) - (R'_i w_i + R'_j w_j) x n
    sx = lever_i * wix + lever_j * wjx
    sy = lever_i * wiy + lever_j * wjy
    sz = lever_i * wiz + lever_j * wjz
    vcx = rvx - (sy * nz - sz * ny)
    vcy = rvy - (sz * nx - sx * nz)
    vcz = rvz - (sx * ny - sy * nx)
    vcn = vcx * nx + vcy * ny + vcz * nz
    vtx = vcx - vcn * nx
    vty = vcy - vcn * ny
    vtz = vcz - vcn * nz

    # a contact kept past touching (DETACH_AT >= 0) reaches the normal law at zero overlap
    f_el, f_damp, kn, kt, gamma_t, e_n = normal_force(hist, k, NORMAL_HISTORY, max(overlap, 0.0) if DETACH_AT >= 0
                                                      else overlap, vn, r_eff, m_eff, p, NORMAL_PARAMS)
    fn = f_el + f_damp
    normal = (f_el, fn, kn, kt, gamma_t)  # NORMAL_RESULT
    f_coh, e_coh = cohesion_force(hist, k, COHESION_HISTORY, g, normal, p, COHESION_PARAMS)
    fn += f_coh
    ftx, fty, ftz, e_t = tangential_force(hist, k, TANGENTIAL_HISTORY, g, frame, (vtx, vty, vtz), normal, dt, p,
                                          TANGENTIAL_PARAMS)
    mix = miy = miz = mjx = mjy = mjz = e_r = m_tw = e_tw = 0.0
    if moments:
        mix, miy, miz, mjx, mjy, mjz, e_r = rolling_moment(hist, k, ROLLING_HISTORY, g, frame, normal, dt, p,
                                                           ROLLING_PARAMS, ROLLING_MODES)
        m_tw, e_tw = twisting_moment(hist, k, TWISTING_HISTORY, g, normal, dt, p, TWISTING_PARAMS)
    hist[k, 0] = nx
    hist[k, 1] = ny
    hist[k, 2] = nz

    # torque of F_t at the contact point: -R'_i n x F_t on i, -R'_j n x F_t on j
    cx = ny * ftz - nz * fty
    cy = nz * ftx - nx * ftz
    cz = nx * fty - ny * ftx
    return (fn * nx + ftx, fn * ny + fty, fn * nz + ftz,
            -lever_i * cx - mix - m_tw * nx, -lever_i * cy - miy - m_tw * ny, -lever_i * cz - miz - m_tw * nz,
            -lever_j * cx + mjx + m_tw * nx, -lever_j * cy + mjy + m_tw * ny, -lever_j * cz + mjz + m_tw * nz,
            e_n + e_coh - f_damp * vn * dt if TRACK_ENERGY else 0.0, e_t if TRACK_ENERGY else 0.0,
            e_r if TRACK_ENERGY else 0.0, e_tw if TRACK_ENERGY else 0.0)


@njit(cache=True, inline="always")
def lane_columns(block):
    """The block buffer as ``col[lane, column]`` (column-major: a column's lanes are contiguous)."""
    return reshape_unchecked(block, (CONTACT_BLOCK, BLOCK_COLUMNS), (8, 8 * CONTACT_BLOCK))


@njit(cache=True, _nrt=False, error_model="numpy", fastmath={"contract"})
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


@njit(cache=True, _nrt=False, error_model="numpy", fastmath={"contract"})
def flush_block(count, block, lanes, dt, f, t, p, pool, energy, contacts):
    """Compute a block of ``count`` contacts (material pair parameters ``p``) and scatter the results:
    history back to each contact's pool row, F and T_j beside it, F and T added to row i in the
    order of its entries (the order the scalar loop summed them in)."""
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
            pool[row, P_FORCE + d] = force
            pool[row, P_TORQUE_J + d] = col[un, out + 6 + d]
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
                          v[i, 0] - v[j, 0], v[i, 1] - v[j, 1], v[i, 2] - v[j, 2],
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
def candidate_entries(k0, k1, x, radius, nl_j, nl_i, contact_row, lanes, box):
    """Entries k0..k1-1 whose spheres may touch now or touched at the last step, in ascending k, into
    the rows ``LANE_HITS..`` of ``lanes``; returns their count. One flat loop without branches over
    the entries of many rows (a loop per row mispredicts its exit once per row). The test is looser
    than ``entry_inputs``' by a relative 1e-12: an entry on the edge is left to it to decide. In a
    periodic box, a loop of its own with the minimum image."""
    nhit = uint64(0)
    if box.shape[0] != 0:
        lx, ly, lz = box[PB.lx], box[PB.ly], box[PB.lz]
        ilx, ily, ilz = box[PB.inv_lx], box[PB.inv_ly], box[PB.inv_lz]
        for kk in range(k0, k1):
            k = uint64(kk)
            i = uint32(nl_i[k])
            j = uint32(nl_j[k])
            dx = minimum_image(x[i, 0] - x[j, 0], lx, ilx)
            dy = minimum_image(x[i, 1] - x[j, 1], ly, ily)
            dz = minimum_image(x[i, 2] - x[j, 2], lz, ilz)
            reach = radius[i] + radius[j]
            lanes[uint64(LANE_HITS) + (nhit >> uint64(BLOCK_SHIFT)), nhit & uint64(CONTACT_BLOCK - 1)] = kk
            nhit += uint64((dx * dx + dy * dy + dz * dz < CANDIDATE_SLACK * reach * reach) | (contact_row[k] >= 0))
        return np.int64(nhit)
    for kk in range(k0, k1):
        k = uint64(kk)
        i = uint32(nl_i[k])
        j = uint32(nl_j[k])
        dx = x[i, 0] - x[j, 0]
        dy = x[i, 1] - x[j, 1]
        dz = x[i, 2] - x[j, 2]
        reach = radius[i] + radius[j]
        lanes[uint64(LANE_HITS) + (nhit >> uint64(BLOCK_SHIFT)), nhit & uint64(CONTACT_BLOCK - 1)] = kk
        nhit += uint64((dx * dx + dy * dy + dz * dz < CANDIDATE_SLACK * reach * reach) | (contact_row[k] >= 0))
    return np.int64(nhit)


@njit(cache=True, inline="always")
def pair_row(i, dt, particles, lists, pair_params):
    """Row i of the half list, one contact at a time through the scalar ``contact`` (spheres of more
    than one material, see ``pair_rows``)."""
    f, t, mat, pool = particles.f, particles.t, particles.mat, lists.pool
    fx = fy = fz = 0.0
    tx = ty = tz = 0.0
    en = et = er = etw = 0.0
    ncontact = 0
    for k in range(lists.start[i], lists.start[i + 1]):
        touching, j, row, g = entry_inputs(i, k, particles, lists)
        if not touching:
            continue
        if BONDED_PAIRS and bonded(uint64(i), uint64(j), particles, False):
            res = bonded_contact(pool, np.int64(row), g, pair_params[mat[i], mat[j]], dt)
        else:
            res = contact(pool, np.int64(row), g, pair_params[mat[i], mat[j]], dt)
        fx += res[0]
        fy += res[1]
        fz += res[2]
        tx += res[3]
        ty += res[4]
        tz += res[5]
        for d in range(3):
            pool[row, P_FORCE + d] = res[d]
            pool[row, P_TORQUE_J + d] = res[6 + d]
        en += res[9]
        et += res[10]
        er += res[11]
        etw += res[12]
        ncontact += 1
    f[i, 0] = fx
    f[i, 1] = fy
    f[i, 2] = fz
    t[i, 0] = tx
    t[i, 1] = ty
    t[i, 2] = tz
    if TRACK_ENERGY:
        particles.energy[i, 0] += en
        particles.energy[i, 1] += et
        particles.energy[i, 2] += er
        particles.energy[i, 3] += etw
    particles.contacts[i] = ncontact


@njit(cache=True, _nrt=False, error_model="numpy", fastmath={"contract"})
def pair_rows_scalar(lo, hi, dt, particles, lists, pair_params):
    """Rows lo..hi-1 through the scalar ``pair_row``, compiled as ``pair_rows`` is: the GPU's pair
    pass (``rollingdem.engine.cuda.step_loop``), equal bit for bit to the CPU's for spheres of several
    materials."""
    for i in range(lo, hi):
        pair_row(i, dt, particles, lists, pair_params)


@njit(cache=True, _nrt=False, error_model="numpy", fastmath={"contract"})
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
                flush_block(count, block, lanes, dt, f, t, p, pool, particles.energy, contacts)
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
        flush_block(count, block, lanes, dt, f, t, p, pool, particles.energy, contacts)


@njit(cache=True, parallel=True, error_model="numpy", fastmath={"contract"})
def pair_forces(dt, pair_params, particles, lists, scratch):
    """Pair contacts: each thread a contiguous range of whole pool groups, with its own block buffer."""
    n = particles.x.shape[0]
    blocks, lanes = scratch.blocks, scratch.lanes
    nblock = blocks.shape[0]
    ngroups = (n + POOL_GROUP - 1) // POOL_GROUP
    for b in prange(nblock):
        pair_rows(min(b * ngroups // nblock * POOL_GROUP, n), min((b + 1) * ngroups // nblock * POOL_GROUP, n), dt,
                  particles, lists, pair_params, blocks[b], lanes[b])


@njit(cache=True, parallel=True, error_model="numpy", fastmath={"contract"})
def pair_forces_serial(dt, pair_params, particles, lists, scratch):
    """``pair_forces`` on the calling thread (parallel=True, range: see ``integrator``)."""
    for b in range(1):  # lo = b, not 0: a literal 0 would compile pair_rows a second time
        pair_rows(b, particles.x.shape[0], dt, particles, lists, pair_params, scratch.blocks[b], scratch.lanes[b])


@njit(cache=True, inline="always")
def wall_contacts(i, dt, particles, walls, pair_params):
    """All wall contacts of particle i: total force and torque on i, energies, contact count.

    A wall is a partner of infinite radius and mass with a prescribed surface velocity
    v_wall + omega_wall x (c - point); R* = R_i, m* = m_i, I_r = 1.4 m_i R_i^2 (docs/models.md §0, §3.3).
    """
    x, v, w = particles.x, particles.v, particles.w
    wall_kind, wall_geom, whist, wtouch = walls.kind, walls.geometry, walls.history, walls.touching
    fx = fy = fz = 0.0
    tx = ty = tz = 0.0
    en = et = er = etw = 0.0
    ncontact = 0
    nwall = wall_kind.shape[0]
    ri = particles.radius[i]
    mi = particles.mass[i]
    # most spheres touch no wall and had no wall contact: a first loop of the bare tests lets them
    # skip the contact loop (whose call of ``contact`` keeps every sphere's loop heavy: 7 ns a
    # sphere on the collapse, where 1.7 % touch the plate)
    need = False
    for wl in range(nwall):
        overlap = wall_contact_geometry(i, wl, x, ri, wall_kind, wall_geom)[0]
        need |= (overlap > 0.0) | (wtouch[i * uint64(nwall) + uint64(wl)] != 0)
    if not need:
        return fx, fy, fz, tx, ty, tz, en, et, er, etw, ncontact
    for wl in range(nwall):
        k = i * uint64(nwall) + uint64(wl)
        overlap, nx, ny, nz = wall_contact_geometry(i, wl, x, ri, wall_kind, wall_geom)
        if overlap <= 0.0 and not (DETACH_AT >= 0 and wtouch[k] and overlap > -whist[k, DETACH_AT]):
            if wtouch[k]:  # the contact just ended: its springs go (a byte, not the history row)
                wtouch[k] = 0
                for s2 in range(whist.shape[1]):
                    whist[k, s2] = 0.0
                for s2 in range(WALL_LOAD_SIZE):
                    walls.load[k, s2] = 0.0
            continue
        wtouch[k] = 1
        # surface velocity of the wall at the contact point c = x_i - (R_i - overlap) n
        lever = ri - overlap
        cx = x[i, 0] - lever * nx - wall_geom[wl, 0]
        cy = x[i, 1] - lever * ny - wall_geom[wl, 1]
        cz = x[i, 2] - lever * nz - wall_geom[wl, 2]
        owx = walls.angular_velocity[wl, 0]
        owy = walls.angular_velocity[wl, 1]
        owz = walls.angular_velocity[wl, 2]
        swx = walls.velocity[wl, 0] + (owy * cz - owz * cy)
        swy = walls.velocity[wl, 1] + (owz * cx - owx * cz)
        swz = walls.velocity[wl, 2] + (owx * cy - owy * cx)
        res = contact(whist, np.int64(k), (nx, ny, nz, overlap, v[i, 0] - swx, v[i, 1] - swy, v[i, 2] - swz,
                                           w[i, 0], w[i, 1], w[i, 2], owx, owy, owz, ri - 0.5 * overlap, 0.0,
                                           ri, mi, INERTIA_R_FACTOR * mi * ri * ri),
                      pair_params[particles.mat[i], walls.material[wl]], dt)
        wall_load(walls.load, k, res, x[i, 0] - lever * nx, x[i, 1] - lever * ny, x[i, 2] - lever * nz)
        fx += res[0]
        fy += res[1]
        fz += res[2]
        tx += res[3]
        ty += res[4]
        tz += res[5]
        en += res[9]
        et += res[10]
        er += res[11]
        etw += res[12]
        ncontact += 1
    return fx, fy, fz, tx, ty, tz, en, et, er, etw, ncontact


@njit(cache=True, inline="always")
def wall_load(load, k, res, cx, cy, cz):
    """Row k of a wall contact's load (``records.WALL_LOAD``): the force on the wall, -F, and
    its moment about the origin, c x (-F) + the torque on the wall."""
    fx, fy, fz = -res[0], -res[1], -res[2]
    load[k, 0] = fx
    load[k, 1] = fy
    load[k, 2] = fz
    load[k, 3] = cy * fz - cz * fy + res[6]
    load[k, 4] = cz * fx - cx * fz + res[7]
    load[k, 5] = cx * fy - cy * fx + res[8]


@njit(cache=True, inline="always")
def mesh_contacts(i, dt, particles, walls, pair_params, half_skin):
    """All triangle-mesh contacts of particle i, one per touched surface feature, each in its
    contact slot (``mesh_kernel.match_mesh_contacts``): total force and torque on i, energies,
    contact count. A mesh is a wall: R* = R_i, m* = m_i, its surface velocity at the contact point
    v + omega x (c - o). A sphere with no contact at the last step skips its candidates when it
    cannot reach any: its gap to them at the build exceeds how far it has moved since (and a
    moving mesh's skin/2)."""
    x, v, w = particles.x, particles.v, particles.w
    fx = fy = fz = 0.0
    tx = ty = tz = 0.0
    en = et = er = etw = 0.0
    ncontact = 0
    lo = walls.candidate_start[i]
    gap = walls.candidate_gap[i]
    if lo == walls.candidate_start[i + 1] or gap > 0.0:
        used = False
        for s in range(MESH_SLOTS):
            used |= walls.slot_triangle[i, s] >= 0
        if not used:  # no contact to end
            if lo == walls.candidate_start[i + 1]:
                return fx, fy, fz, tx, ty, tz, en, et, er, etw, ncontact
            ex = x[i, 0] - particles.x_ref[i, 0]
            ey = x[i, 1] - particles.x_ref[i, 1]
            ez = x[i, 2] - particles.x_ref[i, 2]
            reach = math.sqrt(ex * ex + ey * ey + ez * ez) + (half_skin if walls.grid[GR.moving] != 0.0 else 0.0)
            if gap > reach:
                return fx, fy, fz, tx, ty, tz, en, et, er, etw, ncontact
    px, py, pz = x[i, 0], x[i, 1], x[i, 2]
    ri = particles.radius[i]
    mi = particles.mass[i]
    found = match_mesh_contacts(i, px, py, pz, ri, walls)
    for b in range(lo, lo + found):
        s = walls.touch_slot[b]
        if s < 0:
            continue
        m = walls.triangle_mesh[walls.touch_triangle[b]]
        qx, qy, qz = walls.touch_point[b, 0], walls.touch_point[b, 1], walls.touch_point[b, 2]
        dx, dy, dz = px - qx, py - qy, pz - qz
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        overlap = ri - dist
        inv = 1.0 / dist  # dist > 0: a centre on the surface has passed half through it (mesh_error)
        nx, ny, nz = dx * inv, dy * inv, dz * inv
        swx, swy, swz = surface_velocity(walls, m, qx, qy, qz)
        k = i * uint64(MESH_SLOTS) + uint64(s)
        res = contact(walls.mesh_history, np.int64(k),
                      (nx, ny, nz, overlap, v[i, 0] - swx, v[i, 1] - swy, v[i, 2] - swz, w[i, 0], w[i, 1], w[i, 2],
                       walls.motion[m, MO.wx], walls.motion[m, MO.wy], walls.motion[m, MO.wz], ri - 0.5 * overlap, 0.0, ri, mi,
                       INERTIA_R_FACTOR * mi * ri * ri),
                      pair_params[particles.mat[i], walls.mesh_material[m]], dt)
        wall_load(walls.mesh_load, k, res, qx, qy, qz)
        fx += res[0]
        fy += res[1]
        fz += res[2]
        tx += res[3]
        ty += res[4]
        tz += res[5]
        en += res[9]
        et += res[10]
        er += res[11]
        etw += res[12]
        ncontact += 1
    return fx, fy, fz, tx, ty, tz, en, et, er, etw, ncontact


@njit(cache=True, inline="always")
def gather_one(i, dt, kick, gravity, particles, walls, pair_params, half_skin):
    """Particle i, its pair terms gathered: walls, gravity; the closing half kick if ``kick`` >= 1.0,
    and if it is 2.0 the next step's opening kick and drift. Returns (1 if i drifted skin/2 or
    more from where the list was built, 1 if its next drift would: the skin is too small)."""
    x, v, w, f, t, mass, inertia = particles.x, particles.v, particles.w, particles.f, particles.t, particles.mass, \
        particles.inertia
    if particles.fixed.shape[0] != 0 and particles.fixed[i]:  # it keeps the sum of its pair forces, and stays
        return 0, 0
    fx = f[i, 0]
    fy = f[i, 1]
    fz = f[i, 2]
    tx = t[i, 0]
    ty = t[i, 1]
    tz = t[i, 2]
    wres = wall_contacts(i, dt, particles, walls, pair_params)
    mi = mass[i]
    fx += wres[0] + mi * gravity[0]
    fy += wres[1] + mi * gravity[1]
    fz += wres[2] + mi * gravity[2]
    tx += wres[3]
    ty += wres[4]
    tz += wres[5]
    if TRACK_ENERGY:
        particles.energy[i, 0] += wres[6]
        particles.energy[i, 1] += wres[7]
        particles.energy[i, 2] += wres[8]
        particles.energy[i, 3] += wres[9]
    particles.contacts[i] += wres[10]
    stop = False
    if walls.triangles.shape[0] > 0:
        mres = mesh_contacts(i, dt, particles, walls, pair_params, half_skin)
        fx += mres[0]
        fy += mres[1]
        fz += mres[2]
        tx += mres[3]
        ty += mres[4]
        tz += mres[5]
        if TRACK_ENERGY:
            particles.energy[i, 0] += mres[6]
            particles.energy[i, 1] += mres[7]
            particles.energy[i, 2] += mres[8]
            particles.energy[i, 3] += mres[9]
        particles.contacts[i] += mres[10]
        stop = walls.mesh_error[i] != 0  # the step stops as for a particle too fast, and says why
    f[i, 0] = fx
    f[i, 1] = fy
    f[i, 2] = fz
    t[i, 0] = tx
    t[i, 1] = ty
    t[i, 2] = tz
    if kick >= 1.0:
        a = 0.5 * dt / mi
        b = 0.5 * dt / inertia[i]
        v[i, 0] += a * fx
        v[i, 1] += a * fy
        v[i, 2] += a * fz
        w[i, 0] += b * tx
        w[i, 1] += b * ty
        w[i, 2] += b * tz
    step_move = next_drift_bound(dt, v[i, 0], v[i, 1], v[i, 2], fx, fy, fz, mi)
    exceed = 0
    fast = 0 if step_move < half_skin and not stop else 1  # NaN: 1
    # the next step's opening half kick and drift, also when i is too fast (the chunk then stops
    # and undo_drift takes them back), but not when i is not finite
    if kick == 2.0 and step_move - step_move == 0.0:
        exceed = kick_drift_one(i, dt, x, v, w, f, t, mass, inertia, particles.x_ref, particles.fixed, half_skin)
    return exceed, fast


@njit(cache=True, _nrt=False, error_model="numpy", fastmath={"contract"})
def bond_forces(lo, hi, dt, particles, box):
    """Bonds lo..hi-1, each intact one through ``bonds.parallel_bond`` (docs/models.md §1.7): its
    load row, which the gather adds to its two particles. A bond that breaks gets the mode it broke
    in (``bond_status``) and a zero load; a broken bond is skipped. Bond b writes row b alone."""
    x, v, w, radius = particles.x, particles.v, particles.w, particles.radius
    pairs, state, params, status, load = (particles.bond_pairs, particles.bond_state, particles.bond_parameters,
                                          particles.bond_status, particles.bond_load)
    for b in range(lo, hi):
        if status[b] != BOND_INTACT:
            continue
        i = pairs[b, 0]
        j = pairs[b, 1]
        dx = x[i, 0] - x[j, 0]
        dy = x[i, 1] - x[j, 1]
        dz = x[i, 2] - x[j, 2]
        if box.shape[0] != 0:
            dx = minimum_image(dx, box[PB.lx], box[PB.inv_lx])
            dy = minimum_image(dy, box[PB.ly], box[PB.inv_ly])
            dz = minimum_image(dz, box[PB.lz], box[PB.inv_lz])
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        overlap = radius[i] + radius[j] - dist
        g = (dx / dist, dy / dist, dz / dist, v[i, 0] - v[j, 0], v[i, 1] - v[j, 1], v[i, 2] - v[j, 2],
             w[i, 0], w[i, 1], w[i, 2], w[j, 0], w[j, 1], w[j, 2], radius[i] - 0.5 * overlap, radius[j] - 0.5 * overlap)
        fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz, mode = parallel_bond(state, b, params[b], g, dt)
        load[b, 0] = fx
        load[b, 1] = fy
        load[b, 2] = fz
        load[b, 3] = tix
        load[b, 4] = tiy
        load[b, 5] = tiz
        load[b, 6] = tjx
        load[b, 7] = tjy
        load[b, 8] = tjz
        status[b] = mode


@njit(cache=True, inline="always")
def gather_bonds(lo, hi, particles):
    """Particles lo..hi-1: the load of each of their bonds (the force on i, minus it on j, the torque
    on each), in the ascending order of ``bond_ends``."""
    f, t, load, start, ends = particles.f, particles.t, particles.bond_load, particles.bond_start, particles.bond_ends
    for q in range(lo, hi):
        for e in range(start[q], start[q + 1]):
            b = ends[e] >> 1
            if ends[e] & 1 == 0:
                f[q, 0] += load[b, 0]
                f[q, 1] += load[b, 1]
                f[q, 2] += load[b, 2]
                t[q, 0] += load[b, 3]
                t[q, 1] += load[b, 4]
                t[q, 2] += load[b, 5]
            else:
                f[q, 0] -= load[b, 0]
                f[q, 1] -= load[b, 1]
                f[q, 2] -= load[b, 2]
                t[q, 0] += load[b, 6]
                t[q, 1] += load[b, 7]
                t[q, 2] += load[b, 8]


@njit(cache=True, _nrt=False, error_model="numpy", fastmath={"contract"})
def gather_rows(lo, hi, dt, kick, gravity, particles, walls, lists, pair_params, half_skin):
    """Particles lo..hi-1: the pair terms where each is the second partner, subtracted from (F) and
    added to (T) its row sums in ascending entry order (one flat loop over their transposed
    entries), then ``gather_one``; returns the counts of its two flags. One function for both
    drivers: compiled once."""
    f, t, pool, contact_row, nl_j, tr_k = particles.f, particles.t, lists.pool, lists.contact_row, lists.j, lists.tr_k
    for m in range(lists.tr_start[lo], lists.tr_start[hi]):
        k = uint32(tr_k[uint64(m)])
        row = contact_row[k]
        if row < 0:
            continue
        r = uint64(row)
        j = uint32(nl_j[k])
        f[j, 0] -= pool[r, P_FORCE]
        f[j, 1] -= pool[r, P_FORCE + 1]
        f[j, 2] -= pool[r, P_FORCE + 2]
        t[j, 0] += pool[r, P_TORQUE_J]
        t[j, 1] += pool[r, P_TORQUE_J + 1]
        t[j, 2] += pool[r, P_TORQUE_J + 2]
    if particles.bond_start.shape[0] != 0:
        gather_bonds(lo, hi, particles)
    nexceed = 0
    nfast = 0
    for q in range(lo, hi):
        exceed, fast = gather_one(uint64(q), dt, kick, gravity, particles, walls, pair_params, half_skin)
        nexceed += exceed
        nfast += fast
    return nexceed, nfast


@njit(cache=True, parallel=True, error_model="numpy", fastmath={"contract"})
def gather(dt, kick, gravity, pair_params, particles, walls, lists, half_skin):
    """``gather_rows`` on runs of ``GATHER_RUN`` particles, shared out among the threads."""
    n = particles.x.shape[0]
    nexceed = 0
    nfast = 0
    for b in prange((n + GATHER_RUN - 1) // GATHER_RUN):
        exceed, fast = gather_rows(b * GATHER_RUN, min((b + 1) * GATHER_RUN, n), dt, kick, gravity, particles, walls,
                                   lists, pair_params, half_skin)
        nexceed += exceed
        nfast += fast
    return nexceed, nfast


@njit(cache=True, parallel=True, error_model="numpy", fastmath={"contract"})
def gather_serial(dt, kick, gravity, pair_params, particles, walls, lists, half_skin):
    """``gather`` on the calling thread."""
    nexceed = nfast = 0
    for b in range(1):  # lo = b, not a literal 0: see pair_forces_serial
        nexceed, nfast = gather_rows(b, particles.x.shape[0], dt, kick, gravity, particles, walls, lists, pair_params,
                                     half_skin)
    return nexceed, nfast


@njit(cache=True)
def _rebuild(particles, walls, lists, skin, info):
    total = rebuild_neighbor_list(particles.x, particles.radius, skin, particles.ids, particles.fixed, particles.image,
                                  particles.x_ref, lists)
    if total < 0:
        info[I_STATUS] = STATUS_CAPACITY
        info[I_NEEDED] = -total
        return False
    short, needed = build_mesh_candidates(particles.x, particles.radius, skin, walls)
    if short:
        info[I_STATUS] = STATUS_MESH_CAPACITY if short == 1 else STATUS_MESH_GRID_CAPACITY
        info[I_NEEDED] = needed
        return False
    list_rows(particles.x.shape[0], lists.start, lists.i)
    info[I_REBUILDS] += 1
    return True


@njit(cache=True)  # @@SERIAL_COPY
def advance(nsteps, dt, gravity, skin, pair_params, particles, walls, lists, scratch, info):
    """Advance ``nsteps`` steps (``advance_serial``: the same loop with the ``*_serial`` passes, on the
    calling thread); stop early at a step boundary with info[I_STATUS] = STATUS_CAPACITY (grow the
    list to info[I_NEEDED]) or STATUS_TOO_FAST (docs/architecture.md, the step)."""
    half_skin = 0.5 * skin
    info[I_STATUS] = 0
    info[I_STEPS_DONE] = 0
    if info[I_FORCES_VALID] == 0:
        info[I_DRIFTED] = 0
        if not _rebuild(particles, walls, lists, skin, info):
            return
        # the pair pass and the gather are called here and in the loop, not through one function
        # of their own, which would compile the whole kernel once more (1 s of a cold compile)
        pair_forces(dt, pair_params, particles, lists, scratch)
        if particles.bond_pairs.shape[0] != 0:
            # the bonds' load as it is: no motion in this evaluation to add (dt 0), so a fresh bond
            # starts unloaded and a run resumed after a change of the scene adds nothing twice
            bond_forces(0, particles.bond_pairs.shape[0], 0.0, particles, lists.box)
        exceed, fast = gather(dt, 0.0, gravity, pair_params, particles, walls, lists, half_skin)
        info[I_TOO_FAST] = fast
        info[I_NEED_REBUILD] = 0
        info[I_FORCES_VALID] = 1
    for step in range(nsteps):
        if info[I_DRIFTED] == 0:
            if info[I_TOO_FAST] > 0:
                # even a list built now would not hold for this step: refuse rather than miss contacts
                info[I_STATUS] = STATUS_TOO_FAST
                return
            exceed = kick_drift(dt, particles, half_skin)
            info[I_NEED_REBUILD] += exceed
            move_walls(dt, walls)
            info[I_NEED_REBUILD] += move_meshes(dt, walls, half_skin)
            info[I_DRIFTED] = 1
        if info[I_NEED_REBUILD] > 0:
            if not _rebuild(particles, walls, lists, skin, info):
                return  # drifted: the call after the arrays grow goes on from here
            info[I_NEED_REBUILD] = 0
        drift = step + 1 < nsteps
        kick = 2.0 if drift else 1.0
        pair_forces(dt, pair_params, particles, lists, scratch)
        if particles.bond_pairs.shape[0] != 0:
            bond_forces(0, particles.bond_pairs.shape[0], dt, particles, lists.box)
        exceed, fast = gather(dt, kick, gravity, pair_params, particles, walls, lists, half_skin)
        info[I_NEED_REBUILD] = exceed
        info[I_TOO_FAST] = fast
        info[I_STEPS_DONE] = step + 1
        info[I_DRIFTED] = 0
        if drift:
            if info[I_TOO_FAST] > 0:
                undo_drift(dt, particles)
                info[I_STATUS] = STATUS_TOO_FAST
                return
            move_walls(dt, walls)  # with the next step's drift, made in the gather
            info[I_NEED_REBUILD] += move_meshes(dt, walls, half_skin)
            info[I_DRIFTED] = 1
