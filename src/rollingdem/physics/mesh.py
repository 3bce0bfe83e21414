"""The geometry of a sphere's contacts with a triangle mesh: the closest point of a triangle to the
sphere's centre with the feature (face, edge, vertex) it lies on, and the sphere's contacts with a
mesh, one per touched surface feature (docs/models.md, "Mesh walls")."""

import math

from numba import njit


# the feature of a triangle a closest point lies on
FACE = 0
EDGE_AB, EDGE_BC, EDGE_CA = 1, 2, 3
VERTEX_A, VERTEX_B, VERTEX_C = 4, 5, 6


@njit(cache=True, inline="always")
def closest_point_on_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """(qx, qy, qz, feature): the point of triangle abc closest to p, and the feature it lies on
    (``FACE``, ``EDGE_*``, ``VERTEX_*``). The Voronoi-region test of Ericson, Real-Time Collision
    Detection (2005), sec. 5.1.5: the barycentric coordinates of the projection decide the region,
    with no square root."""
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return ax, ay, az, VERTEX_A
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bx, by, bz, VERTEX_B
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return ax + v * abx, ay + v * aby, az + v * abz, EDGE_AB
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cx, cy, cz, VERTEX_C
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return ax + w * acx, ay + w * acy, az + w * acz, EDGE_CA
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return bx + w * (cx - bx), by + w * (cy - by), bz + w * (cz - bz), EDGE_BC
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    return ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w, FACE


@njit(cache=True)
def closest_points(points, vertices, triangles, out_points, out_features):
    """``closest_point_on_triangle`` of points[k] and triangle triangles[k] (for tests and checks)."""
    for k in range(points.shape[0]):
        a, b, c = triangles[k, 0], triangles[k, 1], triangles[k, 2]
        q = closest_point_on_triangle(points[k, 0], points[k, 1], points[k, 2],
                                      vertices[a, 0], vertices[a, 1], vertices[a, 2],
                                      vertices[b, 0], vertices[b, 1], vertices[b, 2],
                                      vertices[c, 0], vertices[c, 1], vertices[c, 2])
        out_points[k, 0] = q[0]
        out_points[k, 1] = q[1]
        out_points[k, 2] = q[2]
        out_features[k] = q[3]


@njit(cache=True, inline="always")
def _into_triangle(vertices, triangles, u, va, vb, qx, qy, qz, px, py, pz):
    """(p - q) . m, m the direction in triangle u's plane, normal to its edge (va, vb), pointing into
    u; and |p - q| |m|, its scale."""
    w = triangles[u, 0] + triangles[u, 1] + triangles[u, 2] - va - vb  # u's third vertex
    ex, ey, ez = vertices[vb, 0] - vertices[va, 0], vertices[vb, 1] - vertices[va, 1], vertices[vb, 2] - vertices[va, 2]
    wx, wy, wz = vertices[w, 0] - vertices[va, 0], vertices[w, 1] - vertices[va, 1], vertices[w, 2] - vertices[va, 2]
    s = (wx * ex + wy * ey + wz * ez) / (ex * ex + ey * ey + ez * ez)
    mx, my, mz = wx - s * ex, wy - s * ey, wz - s * ez
    dx, dy, dz = px - qx, py - qy, pz - qz
    scale = math.sqrt((dx * dx + dy * dy + dz * dz) * (mx * mx + my * my + mz * mz))
    return dx * mx + dy * my + dz * mz, scale


#: relative tolerance of the feature tests: p counts as in a feature's region up to this much past it
FEATURE_TOLERANCE = 1e-12


#: two contacts whose points are closer than this x the radius are one (found from two triangles)
SAME_POINT = 1e-9


@njit(cache=True)
def touching_features(px, py, pz, radius, vertices, triangles, edge_neighbors, candidates, lo, hi, out_tri,
                      out_feature, out_point):
    """The contacts of a sphere (centre p, ``radius``) with the triangles ``candidates[lo:hi]``: one per
    touched surface feature, not one per triangle. Returns their count c; ``out_tri``, ``out_feature``,
    ``out_point`` hold at lo .. lo + c - 1 each one's triangle, feature and contact point (its normal
    is p - point): a sphere's own rows of the candidate list are its scratch.

    A triangle touches when its closest point q is nearer than ``radius``. A face contact is kept.
    An edge contact is kept when p also lies outside the triangle across that edge, (p - q) . m <= 0
    with m pointing into it in its plane (on a flat or concave edge the sphere is over the
    neighbour's face instead), and once per edge. A vertex contact is kept when p lies outside
    every touching triangle around the vertex, (p - v) . (x - v) <= 0 for each of their edges
    (v, x), and once per vertex. The triangles around a touched edge or vertex are within
    ``radius`` of p, so they are among the touching ones when the candidates hold every triangle
    that near. So a sphere crossing the shared edge of coplanar triangles has one contact with the
    face normal throughout, one on a convex edge or vertex with the normal from it to the centre,
    and one per face in a concave corner (Voronoi regions of the surface's features). Two contacts
    at the same point (within ``SAME_POINT`` R, as when round-off puts a point on a shared edge
    inside both faces) count once."""
    r2 = radius * radius
    nkeep = lo
    for a in range(lo, hi):
        t = candidates[a]
        i0, i1, i2 = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        q = closest_point_on_triangle(px, py, pz, vertices[i0, 0], vertices[i0, 1], vertices[i0, 2],
                                      vertices[i1, 0], vertices[i1, 1], vertices[i1, 2],
                                      vertices[i2, 0], vertices[i2, 1], vertices[i2, 2])
        dx, dy, dz = px - q[0], py - q[1], pz - q[2]
        if dx * dx + dy * dy + dz * dz >= r2:
            continue
        out_tri[nkeep] = t
        out_feature[nkeep] = q[3]
        out_point[nkeep, 0] = q[0]
        out_point[nkeep, 1] = q[1]
        out_point[nkeep, 2] = q[2]
        nkeep += 1
    n = lo
    for a in range(lo, nkeep):
        t, feature = out_tri[a], out_feature[a]
        qx, qy, qz = out_point[a, 0], out_point[a, 1], out_point[a, 2]
        keep = True
        if EDGE_AB <= feature <= EDGE_CA:
            e = feature - EDGE_AB
            va, vb = triangles[t, e], triangles[t, (e + 1) % 3]
            u = edge_neighbors[t, e]
            if u >= 0:
                into, scale = _into_triangle(vertices, triangles, u, va, vb, qx, qy, qz, px, py, pz)
                keep = into <= FEATURE_TOLERANCE * scale
                for b in range(lo, a):  # the same edge, seen from u
                    if out_tri[b] == u and EDGE_AB <= out_feature[b] <= EDGE_CA:
                        f = out_feature[b] - EDGE_AB
                        ua, ub = triangles[u, f], triangles[u, (f + 1) % 3]
                        if (ua == va and ub == vb) or (ua == vb and ub == va):
                            keep = False
        elif feature >= VERTEX_A:
            v = triangles[t, feature - VERTEX_A]
            dx, dy, dz = px - qx, py - qy, pz - qz
            for b in range(lo, nkeep):
                u = out_tri[b]
                for c in range(3):
                    if triangles[u, c] != v:
                        continue
                    if b < a and out_feature[b] == VERTEX_A + c:
                        keep = False  # counted already
                    for x in (triangles[u, (c + 1) % 3], triangles[u, (c + 2) % 3]):
                        ex = vertices[x, 0] - qx
                        ey = vertices[x, 1] - qy
                        ez = vertices[x, 2] - qz
                        scale = math.sqrt((dx * dx + dy * dy + dz * dz) * (ex * ex + ey * ey + ez * ez))
                        if dx * ex + dy * ey + dz * ez > FEATURE_TOLERANCE * scale:
                            keep = False
        for b in range(lo, n):  # the same point from two triangles (a centre over their shared edge,
            # classed as inside both faces by round-off): one contact
            ex, ey, ez = out_point[b, 0] - qx, out_point[b, 1] - qy, out_point[b, 2] - qz
            if ex * ex + ey * ey + ez * ez <= (SAME_POINT * radius) ** 2:
                keep = False
        if keep:
            out_tri[n] = t
            out_feature[n] = feature
            out_point[n, 0] = qx
            out_point[n, 1] = qy
            out_point[n, 2] = qz
            n += 1
    return n - lo


@njit(cache=True, inline="always")
def _edge_counts(ax, ay, bx, by, px, py):
    """Whether p is inside, to the left of, the directed edge a -> b, ties broken by the half-open
    rule (an edge pointing up, or left along x, owns the points on it): a point on an edge that two
    triangles share, the same way round, is inside exactly one of them."""
    # the same product for a shared edge whichever way round a triangle takes it (from its lower
    # end), so that it is exactly -e in the neighbour: a point beside the edge is in one of the two
    flip = ax > bx or (ax == bx and ay > by)
    if flip:
        e = -((ax - bx) * (py - by) - (ay - by) * (px - bx))
    else:
        e = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
    if e != 0.0:
        return e > 0.0
    dy = by - ay
    return dy > 0.0 or (dy == 0.0 and bx < ax)


@njit(cache=True)
def inside_closed_mesh(points, vertices, triangles, cell_start, cell_items, x0, y0, h, nx, ny, out):
    """Whether each point lies inside a closed triangle mesh: the parity of the triangles a ray from
    it along +z crosses. A triangle is taken in projection on the xy plane, turned counter-clockwise,
    with the half-open rule on its edges (``_edge_counts``), so a ray through a shared edge or vertex
    crosses once; where the surface folds over, the two triangles at the fold count twice or not at
    all, which keeps the parity. Triangles upright in projection (no area) are skipped: a ray along
    them meets their neighbours. ``cell_start``/``cell_items``: the triangles whose xy box meets each
    cell of an nx by ny grid of cells h wide from (x0, y0)."""
    for p in range(points.shape[0]):
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        i, j = int(math.floor((px - x0) / h)), int(math.floor((py - y0) / h))
        out[p] = False
        if i < 0 or j < 0 or i >= nx or j >= ny:
            continue
        cell = i * ny + j
        crossings = 0
        for k in range(cell_start[cell], cell_start[cell + 1]):
            t = cell_items[k]
            a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
            ax, ay, bx, by, cx, cy = vertices[a, 0], vertices[a, 1], vertices[b, 0], vertices[b, 1], \
                vertices[c, 0], vertices[c, 1]
            area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
            if area == 0.0:
                continue
            if area < 0.0:  # counter-clockwise in projection
                b, c = c, b
                bx, by, cx, cy = cx, cy, bx, by
                area = -area
            if not (_edge_counts(ax, ay, bx, by, px, py) and _edge_counts(bx, by, cx, cy, px, py)
                    and _edge_counts(cx, cy, ax, ay, px, py)):
                continue
            # the triangle's height over p, from the barycentric coordinates of p's projection
            wb = ((cx - ax) * (ay - py) - (cy - ay) * (ax - px)) / area
            wc = ((bx - ax) * (py - ay) - (by - ay) * (px - ax)) / area
            z = vertices[a, 2] + wb * (vertices[b, 2] - vertices[a, 2]) + wc * (vertices[c, 2] - vertices[a, 2])
            if z > pz:
                crossings += 1
        out[p] = crossings % 2 == 1
