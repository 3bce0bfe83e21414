"""The compiled passes of triangle-mesh walls that do not depend on the contact law: the candidate
triangles of each sphere (built with the neighbor list), the meshes' motion, and each sphere's
mesh contacts matched to its contact slots, so that the contact history goes with the sphere from
triangle to triangle (docs/architecture.md, "Mesh walls"). The arrays: the walls' record (``engine.schema``)."""

import math

from numba import njit

from rollingdem.physics.records import WALL_LOAD_SIZE
from rollingdem.engine.layout import MESH_GRID as GR, MESH_MOTION as MO, MESH_SLOTS, MOTION_SERVO, MOTION_STEADY
from rollingdem.engine.wall_motion import mesh_loads, step_program
from rollingdem.physics.mesh import closest_point_on_triangle, touching_features

#: a new mesh contact takes over the history of an ended contact of the same mesh whose normal was
#: within this angle: the sphere went on from one triangle, edge or vertex to the next (the normal
#: turns continuously over a convex edge; on a tessellated curved surface it turns by the angle
#: between faces, 3.75 deg on a 96-gon). Two contacts that both go on are two contacts: a sphere in a
#: concave corner keeps one per face.
CARRY_ANGLE_COS = math.cos(math.radians(20.0))

#: the triangle grid's cell size / (R_max + skin): a sphere tests the triangles within about
#: (1 + 1.7 GRID_CELL) (R + skin) of its centre; smaller cells test fewer, bin each triangle
#: into more cells
GRID_CELL = 0.75


@njit(cache=True)
def bin_triangles(reach, walls):
    """Bin the triangles on a grid over the meshes' box grown by ``reach`` (R_max + skin): each
    triangle goes into every cell its own box, grown by ``reach``, meets, so a cell lists every
    triangle within ``reach`` of any point in it. Cells are ``GRID_CELL`` ``reach`` wide, wider
    when the cells would outnumber ``walls.grid_start``. Returns 0, or the entries needed when
    ``walls.grid_items`` is too short."""
    vert, tri, grid = walls.vertices, walls.triangles, walls.grid
    lox, loy, loz = vert[0, 0], vert[0, 1], vert[0, 2]
    hix, hiy, hiz = lox, loy, loz
    for v in range(vert.shape[0]):
        lox, loy, loz = min(lox, vert[v, 0]), min(loy, vert[v, 1]), min(loz, vert[v, 2])
        hix, hiy, hiz = max(hix, vert[v, 0]), max(hiy, vert[v, 1]), max(hiz, vert[v, 2])
    lox, loy, loz = lox - reach, loy - reach, loz - reach
    h = GRID_CELL * reach
    ncell_max = walls.grid_start.shape[0] - 1
    while True:
        nx = int((hix + reach - lox) / h) + 1
        ny = int((hiy + reach - loy) / h) + 1
        nz = int((hiz + reach - loz) / h) + 1
        if nx * ny * nz <= ncell_max:
            break
        h *= 1.25
    cell_start, items = walls.grid_start, walls.grid_items
    for c in range(nx * ny * nz + 1):
        cell_start[c] = 0
    for fill in range(2):  # count per cell into cell_start[c + 1], then fill with cell_start[c] as the cursor
        for t in range(tri.shape[0]):
            a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
            ix0 = int((min(vert[a, 0], vert[b, 0], vert[c, 0]) - reach - lox) / h)
            iy0 = int((min(vert[a, 1], vert[b, 1], vert[c, 1]) - reach - loy) / h)
            iz0 = int((min(vert[a, 2], vert[b, 2], vert[c, 2]) - reach - loz) / h)
            ix1 = min(int((max(vert[a, 0], vert[b, 0], vert[c, 0]) + reach - lox) / h), nx - 1)
            iy1 = min(int((max(vert[a, 1], vert[b, 1], vert[c, 1]) + reach - loy) / h), ny - 1)
            iz1 = min(int((max(vert[a, 2], vert[b, 2], vert[c, 2]) + reach - loz) / h), nz - 1)
            for ix in range(max(ix0, 0), ix1 + 1):
                for iy in range(max(iy0, 0), iy1 + 1):
                    for iz in range(max(iz0, 0), iz1 + 1):
                        cell = (ix * ny + iy) * nz + iz
                        if fill:
                            items[cell_start[cell]] = t
                            cell_start[cell] += 1
                        else:
                            cell_start[cell + 1] += 1
        if not fill:
            for cell in range(nx * ny * nz):
                cell_start[cell + 1] += cell_start[cell]
            if cell_start[nx * ny * nz] > items.shape[0]:
                grid[GR.valid] = 0.0
                return cell_start[nx * ny * nz]
    for cell in range(nx * ny * nz, 0, -1):
        cell_start[cell] = cell_start[cell - 1]
    cell_start[0] = 0
    grid[GR.reach], grid[GR.h], grid[GR.x0], grid[GR.y0], grid[GR.z0] = reach, h, lox, loy, loz
    grid[GR.nx], grid[GR.ny], grid[GR.nz], grid[GR.valid] = nx, ny, nz, 1.0
    return 0


@njit(cache=True)
def build_mesh_candidates(x, radius, skin, walls):
    """The candidate rows: for each sphere i, the triangles within R_i + skin of its centre, in
    ascending order (``walls.candidate_start``, ``walls.candidates``). They stay complete while
    the sphere and the mesh each move less than skin/2 (the neighbor list's rule; ``move_meshes``
    tells when a mesh has moved that far). The triangles are binned (``bin_triangles``) anew only
    when a mesh moves or R_max + skin changed; a sphere tests the triangles of its own cell by
    their exact distance, so the cost grows with the triangles near spheres, not with all of them.
    ``walls.candidate_gap[i]``: the least distance from sphere i's centre to its candidates, less
    R_i (``mesh_contacts`` of the step loop skips a sphere that cannot have reached them since).
    Returns (0, entries), or (1, entries needed) when ``walls.candidates`` is too short, or (2,
    entries needed) when ``walls.grid_items`` is (nothing else is changed then)."""
    n = x.shape[0]
    if walls.triangles.shape[0] == 0 or n == 0:
        return 0, 0
    rmax = 0.0
    for i in range(n):
        rmax = max(rmax, radius[i])
    needed = prepare_mesh_grid(rmax + skin, walls)
    if needed:
        return 2, needed
    start, cand = walls.candidate_start, walls.candidates
    start[0] = 0
    for i in range(n):
        start[i + 1] = mesh_candidate_row(i, x, radius, skin, walls, False)
    for i in range(n):
        start[i + 1] += start[i]
    if start[n] > cand.shape[0]:
        return 1, start[n]
    for i in range(n):
        mesh_candidate_row(i, x, radius, skin, walls, True)
    return 0, start[n]


@njit(cache=True, inline="always")
def prepare_mesh_grid(reach, walls):
    """The triangle grid for ``reach`` (R_max + skin), binned anew when a mesh moves or ``reach``
    changed, and the vertices as the candidates are built (``walls.built``). Returns 0, or the
    grid entries needed (``bin_triangles``)."""
    grid, vert = walls.grid, walls.vertices
    moving = False
    for m in range(walls.motion.shape[0]):
        for c in range(6):
            moving |= walls.motion[m, c] != 0.0
        moving |= walls.motion[m, MO.program] != MOTION_STEADY
    if moving or grid[GR.valid] == 0.0 or grid[GR.reach] != reach:
        needed = bin_triangles(reach, walls)
        if needed:
            return needed
    grid[GR.moving] = 1.0 if moving else 0.0
    for v in range(vert.shape[0]):
        for d in range(3):
            walls.built[v, d] = vert[v, d]
    return 0


@njit(cache=True, inline="always")
def mesh_candidate_row(i, x, radius, skin, walls, fill):
    """Sphere i's candidate triangles, those of its grid cell within R_i + skin, in ascending
    order: counted, with ``walls.candidate_gap[i]`` (fill = False), or written from
    ``walls.candidate_start[i]`` (fill = True). Returns their count."""
    grid, vert, tri, gap = walls.grid, walls.vertices, walls.triangles, walls.candidate_gap
    h, lox, loy, loz = grid[GR.h], grid[GR.x0], grid[GR.y0], grid[GR.z0]
    nx, ny, nz = int(grid[GR.nx]), int(grid[GR.ny]), int(grid[GR.nz])
    if not fill:
        gap[i] = math.inf
    fx, fy, fz = (x[i, 0] - lox) / h, (x[i, 1] - loy) / h, (x[i, 2] - loz) / h
    if not (0.0 <= fx < nx and 0.0 <= fy < ny and 0.0 <= fz < nz):  # NaN too
        return 0
    cell = (int(fx) * ny + int(fy)) * nz + int(fz)
    within = radius[i] + skin
    first = walls.candidate_start[i] if fill else 0
    count = 0
    for m in range(walls.grid_start[cell], walls.grid_start[cell + 1]):
        t = walls.grid_items[m]
        a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
        q = closest_point_on_triangle(x[i, 0], x[i, 1], x[i, 2], vert[a, 0], vert[a, 1], vert[a, 2],
                                      vert[b, 0], vert[b, 1], vert[b, 2], vert[c, 0], vert[c, 1], vert[c, 2])
        dx, dy, dz = x[i, 0] - q[0], x[i, 1] - q[1], x[i, 2] - q[2]
        d2 = dx * dx + dy * dy + dz * dz
        if d2 < within * within:
            if fill:
                walls.candidates[first + count] = t
            else:
                gap[i] = min(gap[i], math.sqrt(d2) - radius[i])
            count += 1
    return count


@njit(cache=True)
def move_meshes(dt, walls, half_skin):
    """Advance each moving mesh by dt: vertex = origin + R (reference - p), origin = p + v tau (plus
    its program's displacement, ``engine.wall_motion``), R the turn by omega tau (or about the
    program's axis), tau the time since its motion began (exact rigid motion, no drift of repeated
    small rotations). Returns 1 if a vertex is now skin/2 or more from where the candidate lists
    were built."""
    motion, ref, vert, built = walls.motion, walls.reference, walls.vertices, walls.built
    exceed = 0
    for m in range(motion.shape[0]):
        mo = motion[m]
        vx, vy, vz = mo[MO.vx], mo[MO.vy], mo[MO.vz]
        wx, wy, wz = mo[MO.wx], mo[MO.wy], mo[MO.wz]
        if mo[MO.program] == MOTION_STEADY:
            if vx == 0.0 and vy == 0.0 and vz == 0.0 and wx == 0.0 and wy == 0.0 and wz == 0.0:
                continue
            tau = mo[MO.elapsed] + dt
            mo[MO.elapsed] = tau
            speed = math.sqrt(wx * wx + wy * wy + wz * wz)
            angle = speed * tau
            ux, uy, uz = (wx / speed, wy / speed, wz / speed) if speed > 0.0 else (0.0, 0.0, 1.0)
            ox, oy, oz = mo[MO.px] + vx * tau, mo[MO.py] + vy * tau, mo[MO.pz] + vz * tau
            mo[MO.ox], mo[MO.oy], mo[MO.oz] = ox, oy, oz
        else:
            fx, fy, fz = mesh_loads(walls, m) if mo[MO.program] == MOTION_SERVO else (0.0, 0.0, 0.0)
            turned = step_program(mo, walls.motion_table, dt, fx, fy, fz)
            tau = mo[MO.elapsed]
            ux, uy, uz = mo[MO.ux], mo[MO.uy], mo[MO.uz]
            if ux == 0.0 and uy == 0.0 and uz == 0.0:  # the program turns nothing: the steady turn
                speed = math.sqrt(wx * wx + wy * wy + wz * wz)
                angle = speed * tau
                ux, uy, uz = (wx / speed, wy / speed, wz / speed) if speed > 0.0 else (0.0, 0.0, 1.0)
            else:  # omega lies along u (``scene.motion`` checks it)
                angle = (wx * ux + wy * uy + wz * uz) * tau + turned
            ox, oy, oz = mo[MO.ox], mo[MO.oy], mo[MO.oz]
        # Rodrigues: R = I + sin(a) K + (1 - cos(a)) K^2, K the cross-product matrix of the unit axis
        s, c1 = math.sin(angle), 1.0 - math.cos(angle)
        r00, r01, r02 = 1.0 - c1 * (uy * uy + uz * uz), c1 * ux * uy - s * uz, c1 * ux * uz + s * uy
        r10, r11, r12 = c1 * ux * uy + s * uz, 1.0 - c1 * (ux * ux + uz * uz), c1 * uy * uz - s * ux
        r20, r21, r22 = c1 * ux * uz - s * uy, c1 * uy * uz + s * ux, 1.0 - c1 * (ux * ux + uy * uy)
        px, py, pz = mo[MO.px], mo[MO.py], mo[MO.pz]
        for k in range(walls.vertex_start[m], walls.vertex_start[m + 1]):
            ax, ay, az = ref[k, 0] - px, ref[k, 1] - py, ref[k, 2] - pz
            vert[k, 0] = ox + r00 * ax + r01 * ay + r02 * az
            vert[k, 1] = oy + r10 * ax + r11 * ay + r12 * az
            vert[k, 2] = oz + r20 * ax + r21 * ay + r22 * az
            ex, ey, ez = vert[k, 0] - built[k, 0], vert[k, 1] - built[k, 1], vert[k, 2] - built[k, 2]
            if ex * ex + ey * ey + ez * ez >= half_skin * half_skin:
                exceed = 1
    return exceed


@njit(cache=True, inline="always")
def surface_velocity(walls, m, cx, cy, cz):
    """Velocity (m/s) of mesh m's surface at the point c over the present step: v + omega x (c - o),
    o the rotation axis's point now."""
    mo = walls.motion
    rx = cx - mo[m, MO.ox]
    ry = cy - mo[m, MO.oy]
    rz = cz - mo[m, MO.oz]
    wx, wy, wz = mo[m, MO.twx], mo[m, MO.twy], mo[m, MO.twz]
    return mo[m, MO.tvx] + (wy * rz - wz * ry), mo[m, MO.tvy] + (wz * rx - wx * rz), mo[m, MO.tvz] + (wx * ry - wy * rx)


@njit(cache=True)
def match_mesh_contacts(i, px, py, pz, radius, walls):
    """Sphere i's mesh contacts now (``touching_features`` over its candidates), each matched to a
    contact slot (``walls.touch_slot``, -1 for one that found no slot); returns their count, in
    sphere i's candidate rows from ``walls.candidate_start[i]``.

    A contact keeps the slot of the same triangle; else it takes over the slot of an ended contact
    of the same mesh whose last normal is within ``CARRY_ANGLE_COS`` of its own (the sphere rolled
    on to a neighbouring triangle, edge or vertex: its springs go with it, and the contact law turns
    them into the new frame); else it starts in a free slot with no history. Slots no contact took
    end (history and load zeroed). Sets ``walls.mesh_error[i]`` to 1 when the contacts outnumber
    the slots, to 2 when a contact's normal turned over in one step (the centre passed through the
    surface); plus 4 x the mesh's index."""
    lo = walls.candidate_start[i]
    ncontact = touching_features(px, py, pz, radius, walls.vertices, walls.triangles, walls.neighbors,
                                 walls.candidates, lo, walls.candidate_start[i + 1], walls.touch_triangle,
                                 walls.touch_feature, walls.touch_point)
    slot_tri, hist, tslot = walls.slot_triangle, walls.mesh_history, walls.touch_slot
    claimed = 0
    for b in range(lo, lo + ncontact):
        tslot[b] = -1
        for s in range(MESH_SLOTS):
            if (claimed >> s) & 1 == 0 and slot_tri[i, s] == walls.touch_triangle[b]:
                tslot[b] = s
                claimed |= 1 << s
                break
    for b in range(lo, lo + ncontact):
        if tslot[b] >= 0:
            continue
        nx, ny, nz = px - walls.touch_point[b, 0], py - walls.touch_point[b, 1], pz - walls.touch_point[b, 2]
        norm = math.sqrt(nx * nx + ny * ny + nz * nz)
        mesh = walls.triangle_mesh[walls.touch_triangle[b]]
        best, best_cos = -1, CARRY_ANGLE_COS * norm
        for s in range(MESH_SLOTS):
            t = slot_tri[i, s]
            if (claimed >> s) & 1 or t < 0 or walls.triangle_mesh[t] != mesh:
                continue
            k = i * MESH_SLOTS + s
            cos = hist[k, 0] * nx + hist[k, 1] * ny + hist[k, 2] * nz
            if cos > best_cos:
                best, best_cos = s, cos
        if best >= 0:
            tslot[b] = best
            claimed |= 1 << best
    for s in range(MESH_SLOTS):
        if slot_tri[i, s] >= 0 and (claimed >> s) & 1 == 0:
            slot_tri[i, s] = -1
            k = i * MESH_SLOTS + s
            for c in range(hist.shape[1]):
                hist[k, c] = 0.0
            for c in range(WALL_LOAD_SIZE):
                walls.mesh_load[k, c] = 0.0
    for b in range(lo, lo + ncontact):
        if tslot[b] < 0:
            for s in range(MESH_SLOTS):
                if slot_tri[i, s] < 0 and (claimed >> s) & 1 == 0:
                    tslot[b] = s
                    claimed |= 1 << s
                    break
            if tslot[b] < 0:
                walls.mesh_error[i] = 1 + 4 * walls.triangle_mesh[walls.touch_triangle[b]]
                continue
        s = tslot[b]
        slot_tri[i, s] = walls.touch_triangle[b]
        k = i * MESH_SLOTS + s
        dot = (hist[k, 0] * (px - walls.touch_point[b, 0]) + hist[k, 1] * (py - walls.touch_point[b, 1])
               + hist[k, 2] * (pz - walls.touch_point[b, 2]))
        if dot < 0.0:
            walls.mesh_error[i] = 2 + 4 * walls.triangle_mesh[walls.touch_triangle[b]]
    return ncontact
