"""Which planes and cylinders each sphere may touch before the neighbor list is built again, found
with the list: the gather tests only those (and the walls that moved since, and the contacts that
were on), as LIGGGHTS lists a sphere's wall neighbours with its own. A sphere moves less than
skin/2 between two builds, so a wall farther than R_i + skin/2 from it at the build cannot touch it
until the next, unless the wall moves. The arrays: the walls' record (``engine.schema``): ``near``
(particle x wall), ``geometry_built`` (each wall's geometry at the build), ``moved``."""

from numba import njit, uint64

from rollingdem.physics.walls import wall_within

#: the reach's relative slack: a sphere on the edge of R_i + skin/2 counts as near
NEAR_SLACK = 1.0 + 1e-9


@njit(cache=True)
def build_wall_candidates(x, radius, half_skin, walls):
    """``near[i, w]`` = 1 where wall w lies within R_i + skin/2 of sphere i; ``geometry_built`` the
    walls' geometry now."""
    nwall = walls.kind.shape[0]
    for i in range(x.shape[0]):
        reach = (radius[i] + half_skin) * NEAR_SLACK
        for wl in range(nwall):
            walls.near[uint64(i) * uint64(nwall) + uint64(wl)] = \
                1 if wall_within(i, wl, x, reach, walls.kind, walls.geometry) else 0
    for wl in range(nwall):
        for c in range(walls.geometry.shape[1]):
            walls.geometry_built[wl, c] = walls.geometry[wl, c]


@njit(cache=True)
def mark_moved_walls(walls):
    """``moved[w]`` = 1 where wall w's geometry is not what ``near`` was built with (it moved, or it
    came after the build: its built row is NaN), else 0."""
    for wl in range(walls.kind.shape[0]):
        moved = 0
        for c in range(walls.geometry.shape[1]):
            moved |= walls.geometry[wl, c] != walls.geometry_built[wl, c]
        walls.moved[wl] = moved
