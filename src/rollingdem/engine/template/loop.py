"""The step loop: velocity Verlet with forces at half-step velocities, the neighbor list rebuilt
when a particle has moved skin/2, stopping early at a step boundary for room or a particle too
fast (docs/architecture.md, "The step").

A part of the step loop's template (``rollingdem.engine.template``).
"""

from numba import njit

from rollingdem.engine.layout import DRIFT_SHARE, PERIODIC_BOX_SIZE, SHEARED_DRIFT_SHARE, I_DRIFTED, I_FORCES_VALID, I_NEED_REBUILD, I_STATUS, I_STEPS_DONE, I_TOO_FAST, KICK_CLOSE, KICK_CLOSE_AND_DRIFT, KICK_NONE, STATUS_TOO_FAST
from rollingdem.engine.integrator import kick_drift, move_images, move_steady, move_walls, undo_drift
# the engine module's own names for its callers: the serial copy of the step loop calls
# kick_drift_serial, the GPU's drift kernel kick_drift_range
from rollingdem.engine.integrator import kick_drift_range, kick_drift_serial  # noqa: F401
from rollingdem.engine.list_rebuild import rebuild_lists, rebuild_lists_without_meshes
from rollingdem.engine.rigid_body import KICK_OPEN, clump_pass, clump_undo
from rollingdem.engine.rigid_body import clump_pass_serial, clump_rows  # noqa: F401
from rollingdem.engine.mesh_passes import move_meshes
from rollingdem.engine.template.pairs import pair_forces  # @@PART
from rollingdem.engine.template.gather import bond_forces, gather  # @@PART
from rollingdem.engine.template.contact import BONDED_PAIRS, CLUMPS, MESHES, PROGRAMS  # @@PART


@njit(cache=True, inline="always")
def move_planes(dt, walls):
    """``move_walls``; without a motion program (PROGRAMS = 0) its steady motion alone, the same
    arithmetic, and no program compiled."""
    if PROGRAMS:
        move_walls(dt, walls)
    else:
        for wl in range(walls.geometry.shape[0]):
            move_steady(dt, walls, wl)


# compiled once for every law, in a package module (a copy in each engine module cost its cold compile 2 s)
rebuild = rebuild_lists if MESHES else rebuild_lists_without_meshes


@njit(cache=True, inline="always")  # @@SERIAL_COPY
def open_step(dt, gravity, particles, walls, lists, half_skin):
    """The opening half of a step where the last step left none: the half kick and the drift of
    particles and clumps, the walls' and meshes' move, a sheared box's images' move. Returns the
    count past the drift limit."""
    exceed = kick_drift(dt, particles, half_skin)
    if CLUMPS and particles.clump_mass.shape[0] != 0:
        exceed += clump_pass(dt, KICK_OPEN, gravity, particles, lists.box, half_skin)[0]
    move_planes(dt, walls)
    exceed += move_images(dt, lists.box, half_skin)
    if MESHES:
        exceed += move_meshes(dt, walls, half_skin)
    return exceed


@njit(cache=True, inline="always")  # @@SERIAL_COPY
def close_step(dt, dt_bonds, kick, gravity, pair_params, particles, walls, lists, scratch, half_skin):
    """The forces at the drifted positions (pairs, bonds advanced by ``dt_bonds``, walls, gravity,
    clumps) and ``kick``: KICK_NONE, KICK_CLOSE (the closing half kick) or KICK_CLOSE_AND_DRIFT
    (and the next step's opening half kick and drift, and, unless a particle is too fast, the
    walls' move with it). Returns (the count past skin/2, the count too fast)."""
    pair_forces(dt, pair_params, particles, lists, scratch)
    if BONDED_PAIRS and particles.bond_pairs.shape[0] != 0:
        bond_forces(0, particles.bond_pairs.shape[0], dt_bonds, particles, lists.box)
    exceed, fast = gather(dt, kick, gravity, pair_params, particles, walls, lists, scratch, half_skin)
    if CLUMPS and particles.clump_mass.shape[0] != 0:
        clump_exceed, clump_fast = clump_pass(dt, kick, gravity, particles, lists.box, half_skin)
        exceed += clump_exceed
        fast += clump_fast
    if kick == KICK_CLOSE_AND_DRIFT and fast == 0:
        move_planes(dt, walls)
        exceed += move_images(dt, lists.box, half_skin)
        if MESHES:
            exceed += move_meshes(dt, walls, half_skin)
    return exceed, fast


@njit(cache=True, inline="always")
def take_back_drift(dt, particles, lists):
    """The drift of particles and clumps made with the last closing half, taken back (a particle
    was too fast: the walls did not move)."""
    undo_drift(dt, particles)
    if CLUMPS and particles.clump_mass.shape[0] != 0:
        clump_undo(dt, particles, lists.box)


@njit(cache=True)  # @@SERIAL_COPY
def advance(nsteps, dt, gravity, skin, pair_params, particles, walls, lists, scratch, info):
    """Advance ``nsteps`` steps (``advance_serial``: the same loop with the ``*_serial`` passes, on the
    calling thread); stop early at a step boundary with info[I_STATUS] = STATUS_CAPACITY (grow the
    list to info[I_NEEDED]) or STATUS_TOO_FAST (docs/architecture.md, the step).

    The step's control, for every backend: the GPU runs this function's Python body on the host
    with ``rebuild``, ``open_step``, ``close_step`` and ``take_back_drift`` bound to its kernel
    launches (``rollingdem.engine.cuda.step_loop``)."""
    half_skin = skin * (DRIFT_SHARE if lists.box.shape[0] <= PERIODIC_BOX_SIZE else SHEARED_DRIFT_SHARE)
    info[I_STATUS] = 0
    info[I_STEPS_DONE] = 0
    if info[I_FORCES_VALID] == 0:
        info[I_DRIFTED] = 0
        if not rebuild(particles, walls, lists, skin, info):
            return
        # the bonds' load as it is: no motion in this evaluation to add (dt_bonds 0), so a fresh bond
        # starts unloaded and a run resumed after a change of the scene adds nothing twice
        info[I_TOO_FAST] = close_step(dt, 0.0, KICK_NONE, gravity, pair_params, particles, walls, lists, scratch,
                                      half_skin)[1]
        info[I_NEED_REBUILD] = 0
        info[I_FORCES_VALID] = 1
    for step in range(nsteps):
        if info[I_DRIFTED] == 0:
            if info[I_TOO_FAST] > 0:
                # even a list built now would not hold for this step: refuse rather than miss contacts
                info[I_STATUS] = STATUS_TOO_FAST
                return
            info[I_NEED_REBUILD] += open_step(dt, gravity, particles, walls, lists, half_skin)
            info[I_DRIFTED] = 1
        if info[I_NEED_REBUILD] > 0:
            if not rebuild(particles, walls, lists, skin, info):
                return  # drifted: the call after the arrays grow goes on from here
            info[I_NEED_REBUILD] = 0
        drift = step + 1 < nsteps
        exceed, fast = close_step(dt, dt, KICK_CLOSE_AND_DRIFT if drift else KICK_CLOSE, gravity, pair_params,
                                  particles, walls, lists, scratch, half_skin)
        info[I_NEED_REBUILD] = exceed
        info[I_TOO_FAST] = fast
        info[I_STEPS_DONE] = step + 1
        info[I_DRIFTED] = 0
        if drift:
            if fast > 0:
                take_back_drift(dt, particles, lists)
                info[I_STATUS] = STATUS_TOO_FAST
                return
            info[I_DRIFTED] = 1  # with the walls' move, made in close_step
