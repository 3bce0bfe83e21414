"""The gather: per particle its pair terms where it is the second partner, its wall contacts, its
bonds, gravity, then the kicks (and the next step's drift); and the bonds' own pass.

A part of the step loop's template (``rollingdem.engine.template``).
"""

import math
import numpy as np
from numba import njit, prange, uint32, uint64

from rollingdem.engine.layout import PERIODIC_BOX as PB
from rollingdem.engine.integrator import kick_drift_one, next_drift_bound
from rollingdem.engine.neighbors import minimum_image
from rollingdem.engine.step_records import StepRecords
from rollingdem.engine.wall_candidates import mark_moved_walls
from rollingdem.physics.bonds import BOND_INTACT, parallel_bond
from rollingdem.engine.template.contact import BONDED_PAIRS, GATHER_RUN, MESHES, add_energies_and_count  # @@PART
from rollingdem.engine.template.walls import mesh_contacts, wall_contacts  # @@PART


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
    member = particles.clump.shape[0] != 0 and particles.clump[i] >= 0
    mg = 0.0 if member else mi  # a clump's weight acts at its centre of mass (rigid_body.clump_rows)
    fx += wres[0] + mg * gravity[0]
    fy += wres[1] + mg * gravity[1]
    fz += wres[2] + mg * gravity[2]
    tx += wres[3]
    ty += wres[4]
    tz += wres[5]
    add_energies_and_count(i, particles, wres)
    stop = False
    if MESHES and walls.triangles.shape[0] > 0:
        mres = mesh_contacts(i, dt, particles, walls, pair_params, half_skin)
        fx += mres[0]
        fy += mres[1]
        fz += mres[2]
        tx += mres[3]
        ty += mres[4]
        tz += mres[5]
        add_energies_and_count(i, particles, mres)
        stop = walls.mesh_error[i] != 0  # the step stops as for a particle too fast, and says why
    f[i, 0] = fx
    f[i, 1] = fy
    f[i, 2] = fz
    t[i, 0] = tx
    t[i, 1] = ty
    t[i, 2] = tz
    if member:  # its clump sums its force and torque and moves it (rigid_body.clump_rows)
        return 0, 1 if stop else 0
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
        exceed = kick_drift_one(i, dt, x, v, w, f, t, mass, inertia, particles.x_ref, particles.fixed, particles.clump,
                                half_skin)
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
    f, t, terms, contact_row, nl_j, tr_k = particles.f, particles.t, lists.pair_terms, lists.contact_row, lists.j, \
        lists.tr_k
    none = np.int32(terms.shape[0] - 1)  # the row of zeros: x - 0.0 is x, -0.0 too
    for m in range(lists.tr_start[lo], lists.tr_start[hi]):
        k = uint32(tr_k[uint64(m)])
        row = contact_row[k]
        r = uint64(row if row >= 0 else none)
        j = uint32(nl_j[k])
        f[j, 0] -= terms[r, 0]
        f[j, 1] -= terms[r, 1]
        f[j, 2] -= terms[r, 2]
        t[j, 0] -= terms[r, 3]  # -T_j kept: t - (-T_j) is t + T_j to the bit
        t[j, 1] -= terms[r, 4]
        t[j, 2] -= terms[r, 5]
    if BONDED_PAIRS and particles.bond_start.shape[0] != 0:
        gather_bonds(lo, hi, particles)
    nexceed = 0
    nfast = 0
    for q in range(lo, hi):
        exceed, fast = gather_one(uint64(q), dt, kick, gravity, particles, walls, pair_params, half_skin)
        nexceed += exceed
        nfast += fast
    return nexceed, nfast


@njit(cache=True, inline="always")
def free_run_bound(fixed, nruns, target):
    """The first run of ``GATHER_RUN`` particles after which at least ``target`` free particles lie
    behind: a fixed particle costs the gather next to nothing (a rough base's spheres come first, so
    equal counts of runs would leave one thread most of the free ones)."""
    n = fixed.shape[0]
    behind = 0
    for b in range(nruns):
        if behind >= target:
            return b
        for q in range(b * GATHER_RUN, min((b + 1) * GATHER_RUN, n)):
            behind += fixed[q] == 0
    return nruns


@njit(cache=True, inline="always")
def gather_chunk(c, nthreads, free, dt, kick, gravity, held, pair_params, half_skin):
    """Thread c's share of ``gather`` (of ``nthreads``; ``free`` free particles in all): a contiguous
    range of runs holding an equal share of the free particles, each run through ``gather_rows``;
    returns the counts of its two flags."""
    particles, walls, lists = held.particles, held.walls, held.lists  # once: each read counts references
    n = particles.x.shape[0]
    nruns = (n + GATHER_RUN - 1) // GATHER_RUN
    fixed = particles.fixed
    if fixed.shape[0] == 0:
        lo, hi = c * nruns // nthreads, (c + 1) * nruns // nthreads
    else:
        lo = free_run_bound(fixed, nruns, c * free / nthreads)
        hi = free_run_bound(fixed, nruns, (c + 1) * free / nthreads)
        if c == nthreads - 1:
            hi = nruns
    nexceed = 0
    nfast = 0
    for b in range(lo, hi):
        exceed, fast = gather_rows(b * GATHER_RUN, min((b + 1) * GATHER_RUN, n), dt, kick, gravity, particles,
                                   walls, lists, pair_params, half_skin)
        nexceed += exceed
        nfast += fast
    return nexceed, nfast


@njit(cache=True, parallel=True, error_model="numpy", fastmath={"contract"})
def gather(dt, kick, gravity, pair_params, particles, walls, lists, scratch, half_skin):
    """``gather_rows`` on runs of ``GATHER_RUN`` particles, each thread (``scratch`` has a block per
    thread) a contiguous range of runs holding an equal share of the free particles
    (``gather_chunk``). The threads get the records behind one reference (``StepRecords``)."""
    nexceed = 0
    nfast = 0
    mark_moved_walls(walls)
    nthreads = scratch.lanes.shape[0]
    fixed = particles.fixed
    free = 0
    for q in range(fixed.shape[0]):
        free += fixed[q] == 0
    held = StepRecords(particles, walls, lists)
    for c in prange(nthreads):
        exceed, fast = gather_chunk(np.int64(c), nthreads, free, dt, kick, gravity, held, pair_params, half_skin)
        nexceed += exceed
        nfast += fast
    return nexceed, nfast


@njit(cache=True, parallel=True, error_model="numpy", fastmath={"contract"})
def gather_serial(dt, kick, gravity, pair_params, particles, walls, lists, scratch, half_skin):
    """``gather`` on the calling thread."""
    n = particles.x.shape[0]
    nexceed = 0
    nfast = 0
    mark_moved_walls(walls)
    for b in range((n + GATHER_RUN - 1) // GATHER_RUN):
        exceed, fast = gather_rows(b * GATHER_RUN, min((b + 1) * GATHER_RUN, n), dt, kick, gravity, particles, walls,
                                   lists, pair_params, half_skin)
        nexceed += exceed
        nfast += fast
    return nexceed, nfast


