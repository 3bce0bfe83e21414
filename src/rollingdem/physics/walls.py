"""The geometry of a sphere's contact with a plane or a cylinder wall (particles inside): the
overlap and the contact normal, from the wall's geometry row (``rollingdem.scene.walls``)."""

import math

from numba import njit

from rollingdem.physics.records import WALL_CYLINDER as CYLINDER, WALL_PLANE as PLANE


@njit(cache=True, inline="always")
def wall_contact_geometry(i, wl, x, ri, wall_kind, wall_geom):
    """(overlap, n) of sphere i (radius ri) and wall wl; overlap -1 where the wall cannot touch it
    (past a cylinder's ends, or on its axis). Geometry rows: ``rollingdem.scene.walls``."""
    kind = wall_kind[wl]
    overlap = -1.0
    nx = ny = nz = 0.0
    if kind == PLANE:
        dist = ((x[i, 0] - wall_geom[wl, 0]) * wall_geom[wl, 3] + (x[i, 1] - wall_geom[wl, 1]) * wall_geom[wl, 4]
                + (x[i, 2] - wall_geom[wl, 2]) * wall_geom[wl, 5])
        overlap = ri - dist
        nx = wall_geom[wl, 3]
        ny = wall_geom[wl, 4]
        nz = wall_geom[wl, 5]
    elif kind == CYLINDER:
        ux = wall_geom[wl, 3]
        uy = wall_geom[wl, 4]
        uz = wall_geom[wl, 5]
        ddx = x[i, 0] - wall_geom[wl, 0]
        ddy = x[i, 1] - wall_geom[wl, 1]
        ddz = x[i, 2] - wall_geom[wl, 2]
        s = ddx * ux + ddy * uy + ddz * uz
        if s >= wall_geom[wl, 7] and s <= wall_geom[wl, 8]:
            qx = ddx - s * ux
            qy = ddy - s * uy
            qz = ddz - s * uz
            r = math.sqrt(qx * qx + qy * qy + qz * qz)
            if r > 0.0:
                overlap = r + ri - wall_geom[wl, 6]
                nx = -qx / r
                ny = -qy / r
                nz = -qz / r
    return overlap, nx, ny, nz
