"""The layout the compiled step loop and the Python engine share: the status record, the mesh
motion and triangle-grid rows, the pair pass's block buffer, and the neighbor list's and the
scratch's records (the particles' and walls' records are the schema's, ``engine.schema``). The rows the physics reads (a contact's inputs and results, a bond's rows, the wall
kinds) are ``rollingdem.physics.records``."""

from __future__ import annotations

import collections

from rollingdem.physics.records import N_INPUTS, N_RESULTS, slots

# the step loop's status record ``info`` (int64): what a call did and why it stopped
INFO = slots("steps_done", "status", "needed", "rebuilds", "need_rebuild", "forces_valid", "too_fast", "drifted")
I_STEPS_DONE, I_STATUS, I_NEEDED, I_REBUILDS, I_NEED_REBUILD, I_FORCES_VALID, I_TOO_FAST, I_DRIFTED = INFO
INFO_SIZE = len(INFO)
STATUS_CAPACITY = 1  # the neighbor list outgrew its arrays: grow them to info[I_NEEDED] and call again
STATUS_TOO_FAST = 2  # a particle would move more than skin/2 in one step
STATUS_MESH_CAPACITY = 3  # the mesh candidate list outgrew its arrays: grow them to info[I_NEEDED]
STATUS_MESH_GRID_CAPACITY = 4  # the triangle grid's entries outgrew their array: grow it to info[I_NEEDED]

# what the gather does after a particle's forces (its ``kick``, a float the compiler folds): nothing
# (forces evaluated alone), the step's closing half kick, or that and the next step's opening kick
# and drift (one pass for the two, docs/architecture.md, "The step")
KICK_NONE, KICK_CLOSE, KICK_CLOSE_AND_DRIFT = 0.0, 1.0, 2.0

#: contacts one sphere can hold with triangle meshes at once (one per touched surface feature: 3 in
#: the corner of a box); a sphere that would need more stops the run with an error
MESH_SLOTS = 6
#: a wall's motion row (a mesh's ``WallArrays.motion``, a plane's or cylinder's ``WallArrays.motion_program``;
#: ``rollingdem.engine.wall_motion``): its steady velocity (m/s) and angular velocity (rad/s) about the axis through
#: (px, py, pz) where the motion began, the time since it began (s); the program added to it (``program``:
#: MOTION_STEADY, MOTION_OSCILLATION, MOTION_TABLE, MOTION_SERVO) with its parameters; and over the present step the
#: velocity, the angular velocity and where the axis's point is now (what a contact sees)
MESH_MOTION = slots("vx", "vy", "vz", "wx", "wy", "wz", "px", "py", "pz", "elapsed",
                    "program",
                    "ax", "ay", "az",       # oscillation: translation amplitude (m); servo: its unit direction
                    "ux", "uy", "uz",       # the program's rotation axis (unit)
                    "angle",                # oscillation: angle amplitude (rad)
                    "omega", "phase",       # oscillation: angular frequency 2 pi f (rad/s), phase (rad)
                    "first", "last", "period",  # table: its rows of ``motion_table``, repeated every period (s; 0: holds)
                    "target", "gain", "max_speed",  # servo: the load to hold (N), gain (m/s per N), speed limit (m/s)
                    "shift", "load",        # servo: its displacement along the direction so far (m), the last load (N)
                    "tvx", "tvy", "tvz", "twx", "twy", "twz", "ox", "oy", "oz")
MESH_MOTION_SIZE = len(MESH_MOTION)
MOTION_STEADY, MOTION_OSCILLATION, MOTION_TABLE, MOTION_SERVO = 0.0, 1.0, 2.0, 3.0
#: a row of ``motion_table``: time (s), displacement (m), angle about the program's axis (rad)
MOTION_TABLE_ROW = slots("t", "dx", "dy", "dz", "angle")
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


# The step loop's arrays, in four records built by ``engine.EngineState.records`` (Numba types a
# namedtuple of arrays as one argument): the particles' and the walls' (their fields declared in
# ``rollingdem.engine.schema``), the neighbor list's and the scratch of the pair pass. A parallel
# function takes its arrays out of a record before its ``prange`` loop and hands arrays to what it inlines there: with Numba 0.68.1, writes
# made through a record's array inside a prange body are lost (docs/architecture.md). A function
# called, not inlined, from a prange body may take records.
ListArrays = collections.namedtuple("ListArrays", (  # rollingdem.engine.neighbors
    "start", "j", "i",          # CSR half list: row starts (n + 1), partner and row of each entry
    "pool", "pair_terms",       # contact pool: rows of history, and the same rows' F_ij and T_j of the step
    "contact_row", "groups",    # each entry's pool row, the groups' free-list heads
    "tr_start", "tr_k",         # transposed index: entries where each particle is the second partner
    "cell_start", "cell_items", "cell_of", "counts",  # cell-list scratch of a rebuild
    "box",                      # (PERIODIC_BOX_SIZE,) the periodic box (PERIODIC_BOX); (0,) without one
))
#: the periodic box (``ListArrays.box``): per axis its low end (m), its length L (m) and 1/L, L and
#: 1/L 0.0 along an axis that is not periodic (the minimum image d - L rint(d / L) is then d, exactly).
#: A scene without a periodic axis has an empty box: the loops test its length, which the compiler
#: hoists out of them. A sheared box (Lees-Edwards, flow along x) has SHEARED_BOX_SIZE slots: the
#: image across the gradient axis (unit vector (0, gradient_y, gradient_z), length lg) is displaced
#: by ``shift`` (m, in [0, lx)) along x and moves at ``shear_velocity`` (m/s) along x;
#: ``shift_since_build`` is how far the shift has moved since the neighbor list was built (m)
PERIODIC_BOX = slots("lox", "loy", "loz", "lx", "ly", "lz", "inv_lx", "inv_ly", "inv_lz",
                     "shift", "shear_velocity", "gradient_y", "gradient_z", "lg", "inv_lg", "shift_since_build")
PERIODIC_BOX_SIZE = 9
SHEARED_BOX_SIZE = len(PERIODIC_BOX)
#: how far a particle may drift from where the list was built, as a share of the skin: a half; in a
#: sheared box a quarter, as the images across its gradient end may move by half the skin before
#: the list is built again (``integrator.move_images``), and two spheres then come at most a quarter
#: + a quarter + a half of the skin closer
DRIFT_SHARE, SHEARED_DRIFT_SHARE = 0.5, 0.25
Scratch = collections.namedtuple("Scratch", (
    "blocks",  # (threads, BLOCK columns x CONTACT_BLOCK) float64 block buffers of the pair pass
    "lanes",   # (threads, LANE_HITS + TILE_ROWS, CONTACT_BLOCK) int64 their lane indices
))

# list capacity = entries needed x this (16 bytes per entry and a pool row of 8 (history + 6) bytes,
# 136 with EPSD): growing costs a reallocation and one more counting pass of the neighbor search,
# so a small margin is cheap
LIST_MARGIN = 1.15
