"""The layout the compiled step loop and the Python engine share: the status record, the mesh
motion and triangle-grid rows, the pair pass's block buffer, and the records of arrays the step
loop takes. The rows the physics reads (a contact's inputs and results, a bond's rows, the wall
kinds) are ``rollingdem.physics.records``."""

from __future__ import annotations

import collections

from rollingdem.physics.records import N_INPUTS, N_RESULTS, slots

# the kernel's status record ``info`` (int64): what a call did and why it stopped
INFO = slots("steps_done", "status", "needed", "rebuilds", "need_rebuild", "forces_valid", "too_fast", "drifted")
I_STEPS_DONE, I_STATUS, I_NEEDED, I_REBUILDS, I_NEED_REBUILD, I_FORCES_VALID, I_TOO_FAST, I_DRIFTED = INFO
INFO_SIZE = len(INFO)
STATUS_CAPACITY = 1  # the neighbor list outgrew its arrays: grow them to info[I_NEEDED] and call again
STATUS_TOO_FAST = 2  # a particle would move more than skin/2 in one step
STATUS_MESH_CAPACITY = 3  # the mesh candidate list outgrew its arrays: grow them to info[I_NEEDED]
STATUS_MESH_GRID_CAPACITY = 4  # the triangle grid's entries outgrew their array: grow it to info[I_NEEDED]

#: contacts one sphere can hold with triangle meshes at once (one per touched surface feature: 3 in
#: the corner of a box); a sphere that would need more stops the run with an error
MESH_SLOTS = 6
#: a mesh's motion row (``WallArrays.motion``): velocity (m/s), angular velocity (rad/s) about the axis
#: through (px, py, pz) where the motion began, and the time since it began (s)
MESH_MOTION = slots("vx", "vy", "vz", "wx", "wy", "wz", "px", "py", "pz", "elapsed")
MESH_MOTION_SIZE = len(MESH_MOTION)
#: the triangle grid's shape (``WallArrays.grid``): the reach it was binned for (m), cell size (m),
#: origin (m), cells along x, y, z, whether it holds the meshes as they are (1.0), and whether a
#: mesh moves (1.0)
MESH_GRID = slots("reach", "h", "x0", "y0", "z0", "nx", "ny", "nz", "valid", "moving")


# Scenes of fewer particles, and runs on one Numba thread, step on the calling thread
# (``advance_serial``): a parallel region's fork/join (~1 us with OpenMP, 3 per step) costs more
# than it saves there.
SERIAL_BELOW = 512

# The pair pass's block buffer (``pair_rows`` of the step loop): CONTACT_BLOCK lanes, one contact
# each; its columns are the contact's history, its inputs, its results, and the results of a
# contact computed by the scalar ``contact`` instead.
CONTACT_BLOCK = 64
BLOCK_SHIFT = 6  # log2(CONTACT_BLOCK)
# rows of a thread's ``lanes`` (int64, CONTACT_BLOCK wide): 0-2 the block's pool rows, list rows and
# series flags; from LANE_HITS on, the candidate entries of a tile of the list
LANE_HITS = 3
TILE_ROWS = 16  # a tile of 1024 entries


def block_columns(history_size: int) -> int:
    """Columns of the block buffer for a contact law with this history size."""
    return history_size + N_INPUTS + 2 * N_RESULTS


# The kernel's arrays, in four records built by ``engine.EngineState.records`` (Numba types a
# namedtuple of arrays as one argument). A parallel function takes its arrays out of a record
# before its ``prange`` loop and hands arrays to what it inlines there: with Numba 0.68.1, writes
# made through a record's array inside a prange body are lost (docs/architecture.md). A function
# called, not inlined, from a prange body may take records.
ParticleArrays = collections.namedtuple("ParticleArrays", (
    "x",          # (n, 3) position (m)
    "v",          # (n, 3) velocity (m/s)
    "w",          # (n, 3) angular velocity (rad/s)
    "f",          # (n, 3) force (N)
    "t",          # (n, 3) torque (N m)
    "radius",     # (n,) (m)
    "mass",       # (n,) (kg)
    "inertia",    # (n,) moment of inertia (kg m^2)
    "mat",        # (n,) int32 material index
    "ids",        # (n,) int64 the index the user knows (storage slots are re-sorted)
    "x_ref",      # (n, 3) position at the last neighbor-list build
    "energy",     # (n, 4) dissipated energy per ENERGY_CHANNELS, or (0, 4) when not summed
    "contacts",   # (n,) int32 contacts of the last step
    "image",      # (n, 3) int32 periodic images crossed: the unwrapped position is x + image L
    "fixed",      # (n,) uint8 1: a fixed particle (never moves; walls and gravity skip it; its
                  #   contacts take the free partner's mass and rolling inertia, as a wall's);
                  #   (0,) while no particle is fixed, so that the loops skip the test
    # the particles' bonds (rollingdem.scene.bonds); every array empty while there is none
    "bond_pairs",       # (bonds, 2) int64 the two particles' slots, i then j (the bond normal is j to i)
    "bond_state",       # (bonds, len(BOND_STATE)) the bond's load and frame
    "bond_parameters",  # (bonds, len(BOND_PARAMETERS))
    "bond_status",      # (bonds,) int64 BOND_INTACT, or the mode it broke in
    "bond_load",        # (bonds, BOND_LOAD_SIZE) the last step's force on i and torques on i and j
    "bond_start",       # (n + 1,) int64 CSR rows: each particle's bond ends
    "bond_ends",        # (2 bonds,) int64 2 b for the bond's i, 2 b + 1 for its j, each row in ascending order
))
WallArrays = collections.namedtuple("WallArrays", (
    "kind",              # (walls,) int32 WALL_PLANE, WALL_CYLINDER
    "geometry",          # (walls, WALL_GEOMETRY_SIZE) see rollingdem.scene.walls
    "velocity",          # (walls, 3) (m/s)
    "angular_velocity",  # (walls, 3) (rad/s)
    "material",          # (walls,) int32
    "history",           # (n * walls, history size) contact history of particle i and wall w at i * walls + w
    "touching",          # (n * walls,) uint8 whether that contact existed at the last step
    "load",              # (n * walls, WALL_LOAD_SIZE) that contact's load at the last step
    # triangle meshes (rollingdem.scene.mesh), the triangles of all of them in one array, each mesh's
    # vertices and triangles contiguous
    "reference",         # (vertices, 3) vertex positions where the mesh's present motion began (m)
    "vertices",          # (vertices, 3) vertex positions now (m)
    "built",             # (vertices, 3) vertex positions when the candidate lists were built (m)
    "vertex_start",      # (meshes + 1,) int64 each mesh's first vertex
    "triangles",         # (triangles, 3) int64 vertex indices
    "neighbors",         # (triangles, 3) int64 the triangle across edge ab, bc, ca; -1 on a free edge
    "triangle_mesh",     # (triangles,) int32 the mesh of each triangle
    "motion",            # (meshes, MESH_MOTION_SIZE)
    "mesh_material",     # (meshes,) int32
    "candidate_start",   # (n + 1,) int64 CSR rows: the triangles within R_i + skin of each sphere
    "candidates",        # (capacity,) int64 their triangles, built with the neighbor list
    "candidate_gap",     # (n,) the least distance to them minus R_i, at the build (m); 0: unknown
    "touch_triangle",    # (capacity,) int64 scratch of a sphere's contacts, in its own candidate rows:
    "touch_feature",     # (capacity,) int64   triangle, feature (rollingdem.physics.mesh.FACE ...), contact point,
    "touch_point",       # (capacity, 3)       and slot
    "touch_slot",        # (capacity,) int64
    "slot_triangle",     # (n, MESH_SLOTS) int64 the triangle of each mesh contact slot, -1 free
    "mesh_history",      # (n * MESH_SLOTS, history size) the slot's contact history
    "mesh_load",         # (n * MESH_SLOTS, WALL_LOAD_SIZE) the slot's load at the last step
    "mesh_error",        # (n,) int64 1: more mesh contacts than MESH_SLOTS, 2: passed through the
                         #   surface; plus 4 x the mesh (the step stops as for a particle too fast)
    "grid",              # (len(MESH_GRID),) the triangle grid's shape
    "grid_start",        # (cells + 1,) int64 CSR rows: the triangles binned in each cell of the grid
    "grid_items",        # (entries,) int64
))
ListArrays = collections.namedtuple("ListArrays", (  # rollingdem.engine.neighbors
    "start", "j", "i",          # CSR half list: row starts (n + 1), partner and row of each entry
    "pool", "contact_row", "groups",  # contact pool: rows (history, F_ij, T_j), each entry's row, group heads
    "tr_start", "tr_k",         # transposed index: entries where each particle is the second partner
    "cell_start", "cell_items", "cell_of", "counts",  # cell-list scratch of a rebuild
    "box",                      # (PERIODIC_BOX_SIZE,) the periodic box (PERIODIC_BOX); (0,) without one
))
#: the periodic box (``ListArrays.box``): per axis its low end (m), its length L (m) and 1/L, L and
#: 1/L 0.0 along an axis that is not periodic (the minimum image d - L rint(d / L) is then d, exactly).
#: A scene without a periodic axis has an empty box: the loops test its length, which the compiler
#: hoists out of them
PERIODIC_BOX = slots("lox", "loy", "loz", "lx", "ly", "lz", "inv_lx", "inv_ly", "inv_lz")
PERIODIC_BOX_SIZE = len(PERIODIC_BOX)
Scratch = collections.namedtuple("Scratch", (
    "blocks",  # (threads, BLOCK columns x CONTACT_BLOCK) float64 block buffers of the pair pass
    "lanes",   # (threads, LANE_HITS + TILE_ROWS, CONTACT_BLOCK) int64 their lane indices
))
