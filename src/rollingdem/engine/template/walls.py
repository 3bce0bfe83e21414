"""The wall contacts of one particle: planes and cylinders, each contact's load, and the triangle
meshes' contacts, one per touched surface feature.

A part of the step loop's template (``rollingdem.engine.template``).
"""

import math
import numpy as np
from numba import njit, uint64

from rollingdem.physics.records import WALL_LOAD_SIZE
from rollingdem.engine.layout import MESH_GRID as GR, MESH_MOTION as MO, MESH_SLOTS
from rollingdem.engine.mesh_passes import match_mesh_contacts, surface_velocity
from rollingdem.physics.walls import wall_contact_geometry
from rollingdem.engine.template.contact import DETACH_AT, INERTIA_R_FACTOR, NO_CONTACT, add_contact, contact  # @@PART


@njit(cache=True, inline="always")
def wall_contacts(i, dt, particles, walls, pair_params):
    """All wall contacts of particle i: total force and torque on i, energies, contact count.

    A wall is a partner of infinite radius and mass with a prescribed surface velocity
    v_wall + omega_wall x (c - point); R* = R_i, m* = m_i, I_r = 1.4 m_i R_i^2 (docs/models.md §0, §3.3).
    """
    x, v, w = particles.x, particles.v, particles.w
    wall_kind, wall_geom, whist, wtouch = walls.kind, walls.geometry, walls.history, walls.touching
    sums = NO_CONTACT
    nwall = wall_kind.shape[0]
    ri = particles.radius[i]
    mi = particles.mass[i]
    # most spheres touch no wall and had no wall contact: a first loop of the bare tests lets them
    # skip the contact loop (whose call of ``contact`` keeps every sphere's loop heavy: 7 ns a
    # sphere on the collapse, where 1.7 % touch the plate)
    # and of those, most have no wall within R_i + skin/2 at the last build of the lists, and none
    # moved since (``engine.wall_candidates``): three bytes each
    need = False
    for wl in range(nwall):
        k = i * uint64(nwall) + uint64(wl)
        if wtouch[k] != 0:
            need = True
        elif walls.near[k] != 0 or walls.moved[wl] != 0:
            need |= wall_contact_geometry(i, wl, x, ri, wall_kind, wall_geom)[0] > 0.0
    if not need:
        return sums
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
        sums = add_contact(sums, res)
    return sums


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
    contact slot (``mesh_passes.match_mesh_contacts``): total force and torque on i, energies,
    contact count. A mesh is a wall: R* = R_i, m* = m_i, its surface velocity at the contact point
    v + omega x (c - o). A sphere with no contact at the last step skips its candidates when it
    cannot reach any: its gap to them at the build exceeds how far it has moved since (and a
    moving mesh's skin/2)."""
    x, v, w = particles.x, particles.v, particles.w
    sums = NO_CONTACT
    lo = walls.candidate_start[i]
    gap = walls.candidate_gap[i]
    if lo == walls.candidate_start[i + 1] or gap > 0.0:
        used = False
        for s in range(MESH_SLOTS):
            used |= walls.slot_triangle[i, s] >= 0
        if not used:  # no contact to end
            if lo == walls.candidate_start[i + 1]:
                return sums
            ex = x[i, 0] - particles.x_ref[i, 0]
            ey = x[i, 1] - particles.x_ref[i, 1]
            ez = x[i, 2] - particles.x_ref[i, 2]
            reach = math.sqrt(ex * ex + ey * ey + ez * ez) + (half_skin if walls.grid[GR.moving] != 0.0 else 0.0)
            if gap > reach:
                return sums
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
                       walls.motion[m, MO.twx], walls.motion[m, MO.twy], walls.motion[m, MO.twz], ri - 0.5 * overlap, 0.0, ri, mi,
                       INERTIA_R_FACTOR * mi * ri * ri),
                      pair_params[particles.mat[i], walls.mesh_material[m]], dt)
        wall_load(walls.mesh_load, k, res, qx, qy, qz)
        sums = add_contact(sums, res)
    return sums


