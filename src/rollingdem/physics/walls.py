"""The geometry of a sphere's contact with a plane (a half-space) or a cylinder wall (a thin shell
with rounded rims): the overlap and the contact normal, from the wall's geometry row
(``rollingdem.scene.walls``)."""

import math

from numba import njit

from rollingdem.physics.records import WALL_CYLINDER as CYLINDER, WALL_PLANE as PLANE


# not inlined: the wall loops call it twice per wall (the bare test, then the contact), and its
# cylinder branches (faces, rims) inlined at each call made the gather 2 s slower to compile. The
# gather's floating-point flags, so that its arithmetic is the same as inlined
@njit(cache=True, _nrt=False, error_model="numpy", fastmath={"contract"})
def wall_contact_geometry(i, wl, x, ri, wall_kind, wall_geom):
    """(overlap, n) of sphere i (radius ri) and wall wl, n from the wall to the sphere; overlap -1
    where the wall cannot touch it (past a cylinder's rims, or on its axis). Geometry rows:
    ``rollingdem.scene.walls``."""
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
        # a thin shell: its inner face (the particles it holds), its outer face, and rounded rims at
        # its ends, so that a sphere that got out under a lifted tube's rim meets the rim or the
        # outer face, not the inner face's pull from behind (docs/models.md §0)
        ux = wall_geom[wl, 3]
        uy = wall_geom[wl, 4]
        uz = wall_geom[wl, 5]
        ddx = x[i, 0] - wall_geom[wl, 0]
        ddy = x[i, 1] - wall_geom[wl, 1]
        ddz = x[i, 2] - wall_geom[wl, 2]
        s = ddx * ux + ddy * uy + ddz * uz
        lo = wall_geom[wl, 7]
        hi = wall_geom[wl, 8]
        ds = s - lo if s < lo else (s - hi if s > hi else 0.0)  # past the nearer end; 0 within the extent
        if ds * ds < ri * ri:  # a sphere farther past an end than its radius touches nothing
            qx = ddx - s * ux
            qy = ddy - s * uy
            qz = ddz - s * uz
            r = math.sqrt(qx * qx + qy * qy + qz * qz)
            R = wall_geom[wl, 6]
            if r > 0.0:
                if ds == 0.0:
                    if r <= R:
                        overlap = r + ri - R
                        nx = -qx / r
                        ny = -qy / r
                        nz = -qz / r
                    else:
                        overlap = R + ri - r
                        nx = qx / r
                        ny = qy / r
                        nz = qz / r
                else:
                    # the rim: the circle at the nearer end; n from it to the centre
                    dr = r - R
                    d = math.sqrt(ds * ds + dr * dr)
                    if d < ri and d > 0.0:
                        overlap = ri - d
                        nx = (ds * ux + dr * qx / r) / d
                        ny = (ds * uy + dr * qy / r) / d
                        nz = (ds * uz + dr * qz / r) / d
    return overlap, nx, ny, nz


@njit(cache=True, inline="always")
def wall_within(i, wl, x, reach, wall_kind, wall_geom):
    """Whether a sphere of radius ``reach`` about x_i may overlap wall wl (a plane or a cylinder's
    shell with its rims): never False where ``wall_contact_geometry`` finds an overlap for a radius
    up to ``reach``. Conservative on a cylinder's ends and axis, which it does not resolve."""
    kind = wall_kind[wl]
    if kind == PLANE:
        return ((x[i, 0] - wall_geom[wl, 0]) * wall_geom[wl, 3] + (x[i, 1] - wall_geom[wl, 1]) * wall_geom[wl, 4]
                + (x[i, 2] - wall_geom[wl, 2]) * wall_geom[wl, 5]) < reach
    if kind == CYLINDER:
        ddx = x[i, 0] - wall_geom[wl, 0]
        ddy = x[i, 1] - wall_geom[wl, 1]
        ddz = x[i, 2] - wall_geom[wl, 2]
        s = ddx * wall_geom[wl, 3] + ddy * wall_geom[wl, 4] + ddz * wall_geom[wl, 5]
        lo = wall_geom[wl, 7]
        hi = wall_geom[wl, 8]
        ds = s - lo if s < lo else (s - hi if s > hi else 0.0)
        if ds * ds >= reach * reach:
            return False
        if ds != 0.0:
            return True  # near a rim
        qx = ddx - s * wall_geom[wl, 3]
        qy = ddy - s * wall_geom[wl, 4]
        qz = ddz - s * wall_geom[wl, 5]
        return abs(math.sqrt(qx * qx + qy * qy + qz * qz) - wall_geom[wl, 6]) < reach
    return False
