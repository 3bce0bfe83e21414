"""The step loop: velocity Verlet with forces at half-step velocities, the neighbor list rebuilt
when a particle has moved skin/2, stopping early at a step boundary for room or a particle too
fast (docs/architecture.md, "The step").

A part of the step loop's template (``rollingdem.engine.template``).
"""

from numba import njit

from rollingdem.engine.layout import I_DRIFTED, I_FORCES_VALID, I_NEED_REBUILD, I_STATUS, I_STEPS_DONE, I_TOO_FAST, STATUS_TOO_FAST
from rollingdem.engine.integrator import kick_drift, move_steady, move_walls, undo_drift
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
_rebuild = rebuild_lists if MESHES else rebuild_lists_without_meshes


@njit(cache=True)  # @@SERIAL_COPY
def advance(nsteps, dt, gravity, skin, pair_params, particles, walls, lists, scratch, info):
    """Advance ``nsteps`` steps (``advance_serial``: the same loop with the ``*_serial`` passes, on the
    calling thread); stop early at a step boundary with info[I_STATUS] = STATUS_CAPACITY (grow the
    list to info[I_NEEDED]) or STATUS_TOO_FAST (docs/architecture.md, the step)."""
    half_skin = 0.5 * skin
    info[I_STATUS] = 0
    info[I_STEPS_DONE] = 0
    if info[I_FORCES_VALID] == 0:
        info[I_DRIFTED] = 0
        if not _rebuild(particles, walls, lists, skin, info):
            return
        # the pair pass and the gather are called here and in the loop, not through one function
        # of their own, which would compile the whole engine module once more (1 s of a cold compile)
        pair_forces(dt, pair_params, particles, lists, scratch)
        if BONDED_PAIRS and particles.bond_pairs.shape[0] != 0:
            # the bonds' load as it is: no motion in this evaluation to add (dt 0), so a fresh bond
            # starts unloaded and a run resumed after a change of the scene adds nothing twice
            bond_forces(0, particles.bond_pairs.shape[0], 0.0, particles, lists.box)
        exceed, fast = gather(dt, 0.0, gravity, pair_params, particles, walls, lists, scratch, half_skin)
        if CLUMPS and particles.clump_mass.shape[0] != 0:
            fast += clump_pass(dt, 0.0, gravity, particles, lists.box, half_skin)[1]
        info[I_TOO_FAST] = fast
        info[I_NEED_REBUILD] = 0
        info[I_FORCES_VALID] = 1
    for step in range(nsteps):
        if info[I_DRIFTED] == 0:
            if info[I_TOO_FAST] > 0:
                # even a list built now would not hold for this step: refuse rather than miss contacts
                info[I_STATUS] = STATUS_TOO_FAST
                return
            exceed = kick_drift(dt, particles, half_skin)
            if CLUMPS and particles.clump_mass.shape[0] != 0:
                exceed += clump_pass(dt, KICK_OPEN, gravity, particles, lists.box, half_skin)[0]
            info[I_NEED_REBUILD] += exceed
            move_planes(dt, walls)
            if MESHES:
                info[I_NEED_REBUILD] += move_meshes(dt, walls, half_skin)
            info[I_DRIFTED] = 1
        if info[I_NEED_REBUILD] > 0:
            if not _rebuild(particles, walls, lists, skin, info):
                return  # drifted: the call after the arrays grow goes on from here
            info[I_NEED_REBUILD] = 0
        drift = step + 1 < nsteps
        kick = 2.0 if drift else 1.0
        pair_forces(dt, pair_params, particles, lists, scratch)
        if BONDED_PAIRS and particles.bond_pairs.shape[0] != 0:
            bond_forces(0, particles.bond_pairs.shape[0], dt, particles, lists.box)
        exceed, fast = gather(dt, kick, gravity, pair_params, particles, walls, lists, scratch, half_skin)
        if CLUMPS and particles.clump_mass.shape[0] != 0:
            clump_exceed, clump_fast = clump_pass(dt, kick, gravity, particles, lists.box, half_skin)
            exceed += clump_exceed
            fast += clump_fast
        info[I_NEED_REBUILD] = exceed
        info[I_TOO_FAST] = fast
        info[I_STEPS_DONE] = step + 1
        info[I_DRIFTED] = 0
        if drift:
            if info[I_TOO_FAST] > 0:
                undo_drift(dt, particles)
                if CLUMPS and particles.clump_mass.shape[0] != 0:
                    clump_undo(dt, particles, lists.box)
                info[I_STATUS] = STATUS_TOO_FAST
                return
            move_planes(dt, walls)  # with the next step's drift, made in the gather
            if MESHES:
                info[I_NEED_REBUILD] += move_meshes(dt, walls, half_skin)
            info[I_DRIFTED] = 1
