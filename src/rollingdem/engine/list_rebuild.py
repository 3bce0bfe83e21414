"""The lists a step needs, rebuilt at once: the neighbor list, the meshes' triangle candidates and
the walls' candidates (docs/architecture.md, "The step").

Compiled once for every contact law (none of it reads the law): the step loop of each engine
module calls ``rebuild_lists``, or ``rebuild_lists_without_meshes`` where its scene holds no
triangle mesh, instead of compiling a copy of its own.
"""

from numba import njit

from rollingdem.engine.layout import I_NEEDED, I_REBUILDS, I_STATUS, STATUS_CAPACITY, STATUS_MESH_CAPACITY, STATUS_MESH_GRID_CAPACITY
from rollingdem.engine.mesh_passes import build_mesh_candidates
from rollingdem.engine.neighbors import list_rows, rebuild_neighbor_list
from rollingdem.engine.wall_candidates import build_wall_candidates


@njit(cache=True, inline="always")
def _neighbors(particles, lists, skin, info):
    """The neighbor list; False (info says how much room it needs) where its arrays are too small."""
    total = rebuild_neighbor_list(particles.x, particles.v, particles.radius, skin, particles.ids, particles.fixed, particles.clump,
                                  particles.image, particles.x_ref, lists)
    if total < 0:
        info[I_STATUS] = STATUS_CAPACITY
        info[I_NEEDED] = -total
        return False
    return True


@njit(cache=True, inline="always")
def _rows_and_walls(particles, walls, lists, skin, info):
    list_rows(particles.x.shape[0], lists.start, lists.i)
    build_wall_candidates(particles.x, particles.radius, 0.5 * skin, walls)
    info[I_REBUILDS] += 1


@njit(cache=True)
def rebuild_lists(particles, walls, lists, skin, info):
    """Every list, the meshes' candidates with them; False where an array is too small (``info``:
    which, and the size it needs)."""
    if not _neighbors(particles, lists, skin, info):
        return False
    short, needed = build_mesh_candidates(particles.x, particles.radius, skin, walls)
    if short:
        info[I_STATUS] = STATUS_MESH_CAPACITY if short == 1 else STATUS_MESH_GRID_CAPACITY
        info[I_NEEDED] = needed
        return False
    _rows_and_walls(particles, walls, lists, skin, info)
    return True


@njit(cache=True)
def rebuild_lists_without_meshes(particles, walls, lists, skin, info):
    """``rebuild_lists`` for a scene without triangle meshes: their pass not compiled."""
    if not _neighbors(particles, lists, skin, info):
        return False
    _rows_and_walls(particles, walls, lists, skin, info)
    return True
