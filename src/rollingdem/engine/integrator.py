"""Velocity Verlet's half kicks and drift, compiled: the passes of the step that do not depend on
the contact law (the engine module imports them; docs/architecture.md, the step)."""

import math
import warnings

from numba import njit, prange
from numba.core.errors import NumbaPerformanceWarning

from rollingdem.engine.layout import MESH_MOTION as MO, MOTION_SERVO, MOTION_STEADY, PERIODIC_BOX as PB, PERIODIC_BOX_SIZE, \
    SHEARED_DRIFT_SHARE
from rollingdem.engine.wall_motion import plane_loads, step_program

# The ``*_serial`` passes are compiled with parallel=True but use range, not prange: no threads
# start, and Numba's parallel pipeline makes them 2-4x faster than a plain njit of the same code.
warnings.filterwarnings("ignore", message="(?s).*parallel=True.*no transformation for parallel execution",
                        category=NumbaPerformanceWarning)


@njit(cache=True, inline="always")
def next_drift_bound(dt, vx, vy, vz, fx, fy, fz, m):
    """dt (|v| + dt/2 |F|/m) >= dt |v + dt/2 F/m|, the length of the next drift."""
    return dt * (math.sqrt(vx * vx + vy * vy + vz * vz) + 0.5 * dt * math.sqrt(fx * fx + fy * fy + fz * fz) / m)


@njit(cache=True, inline="always")
def kick_drift_one(i, dt, x, v, w, f, t, mass, inertia, x_ref, fixed, clump, half_skin):
    """Opening half kick and drift of particle i; 1 if it is now skin/2 or more from where the list
    was built (NaN: 1). A fixed particle stays; a clump's member is moved by its clump
    (``rigid_body.clump_rows``). Arrays, not the record: it is inlined into a prange body."""
    if (fixed.shape[0] != 0 and fixed[i]) or (clump.shape[0] != 0 and clump[i] >= 0):
        return 0
    a = 0.5 * dt / mass[i]
    b = 0.5 * dt / inertia[i]
    for d in range(3):
        v[i, d] += a * f[i, d]
        w[i, d] += b * t[i, d]
        x[i, d] += dt * v[i, d]
    ex = x[i, 0] - x_ref[i, 0]
    ey = x[i, 1] - x_ref[i, 1]
    ez = x[i, 2] - x_ref[i, 2]
    return 0 if ex * ex + ey * ey + ez * ez < half_skin * half_skin else 1


@njit(cache=True, parallel=True, error_model="numpy", fastmath={"contract"})
def kick_drift(dt, particles, half_skin):
    """Opening half kick and drift of velocity Verlet; the count of particles now skin/2 or more
    from where the list was built."""
    x, v, w, f, t = particles.x, particles.v, particles.w, particles.f, particles.t
    mass, inertia, x_ref, fixed, clump = particles.mass, particles.inertia, particles.x_ref, particles.fixed, \
        particles.clump
    nexceed = 0
    for i in prange(x.shape[0]):
        nexceed += kick_drift_one(i, dt, x, v, w, f, t, mass, inertia, x_ref, fixed, clump, half_skin)
    return nexceed


@njit(cache=True, _nrt=False, error_model="numpy", fastmath={"contract"})
def kick_drift_range(lo, hi, dt, particles, half_skin):
    """``kick_drift`` on particles lo..hi-1, compiled as it is (the GPU's drift kernel,
    ``rollingdem.engine.cuda.step_loop``)."""
    x, v, w, f, t = particles.x, particles.v, particles.w, particles.f, particles.t
    mass, inertia, x_ref, fixed, clump = particles.mass, particles.inertia, particles.x_ref, particles.fixed, \
        particles.clump
    nexceed = 0
    for i in range(lo, hi):
        nexceed += kick_drift_one(i, dt, x, v, w, f, t, mass, inertia, x_ref, fixed, clump, half_skin)
    return nexceed


@njit(cache=True, parallel=True, error_model="numpy", fastmath={"contract"})
def kick_drift_serial(dt, particles, half_skin):
    x, v, w, f, t = particles.x, particles.v, particles.w, particles.f, particles.t
    mass, inertia, x_ref, fixed, clump = particles.mass, particles.inertia, particles.x_ref, particles.fixed, \
        particles.clump
    nexceed = 0
    for i in range(x.shape[0]):
        nexceed += kick_drift_one(i, dt, x, v, w, f, t, mass, inertia, x_ref, fixed, clump, half_skin)
    return nexceed


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def undo_drift(dt, particles):
    """Take back the opening half kick and drift that ``gather_one`` made, to round-off, in the
    particles it made them in: all whose state is finite (the test of ``next_drift_bound``, on the
    velocity before the kick). Only when a chunk stops because a particle is too fast, so that the
    state it leaves is at one time."""
    x, v, w, f, t, mass, inertia = particles.x, particles.v, particles.w, particles.f, particles.t, particles.mass, \
        particles.inertia
    for i in range(x.shape[0]):
        if particles.fixed.shape[0] != 0 and particles.fixed[i]:
            continue
        if particles.clump.shape[0] != 0 and particles.clump[i] >= 0:  # undone by its clump
            continue
        a = 0.5 * dt / mass[i]
        vx = v[i, 0] - a * f[i, 0]
        vy = v[i, 1] - a * f[i, 1]
        vz = v[i, 2] - a * f[i, 2]
        step_move = next_drift_bound(dt, vx, vy, vz, f[i, 0], f[i, 1], f[i, 2], mass[i])
        if step_move - step_move != 0.0:  # inf or NaN: not drifted
            continue
        b = 0.5 * dt / inertia[i]
        for d in range(3):
            x[i, d] -= dt * v[i, d]
            w[i, d] -= b * t[i, d]
        v[i, 0] = vx
        v[i, 1] = vy
        v[i, 2] = vz


@njit(cache=True, inline="always")
def move_images(dt, box, half_skin):
    """The images across a sheared box's gradient end moved by dt: the shift advances by the shear
    velocity times dt, put back into [0, lx). Returns 1 once it has moved the skin less twice the
    particles' drift limit ``half_skin`` since the list was built (``layout.SHEARED_DRIFT_SHARE``),
    else 0 (and 0 in any other box)."""
    if box.shape[0] <= PERIODIC_BOX_SIZE:
        return 0
    move = dt * box[PB.shear_velocity]
    shift = box[PB.shift] + move
    box[PB.shift] = shift - box[PB.lx] * math.floor(shift * box[PB.inv_lx])
    box[PB.shift_since_build] += abs(move)
    return 0 if box[PB.shift_since_build] < (1.0 / SHEARED_DRIFT_SHARE - 2.0) * half_skin else 1


@njit(cache=True, inline="always")
def move_steady(dt, walls, wl):
    """Move plane or cylinder ``wl`` by dt at its velocity."""
    for d in range(3):
        walls.geometry[wl, d] += dt * walls.velocity[wl, d]


@njit(cache=True, inline="always")
def move_walls(dt, walls):
    """Move the planes and cylinders by dt: at their velocity, or by their program
    (``engine.wall_motion``), whose step's mean velocity the contacts then see."""
    for wl in range(walls.geometry.shape[0]):
        mo = walls.program[wl]
        if mo[MO.program] == MOTION_STEADY:
            move_steady(dt, walls, wl)
            continue
        fx, fy, fz = plane_loads(walls, wl) if mo[MO.program] == MOTION_SERVO else (0.0, 0.0, 0.0)
        step_program(mo, walls.motion_table, dt, fx, fy, fz)
        walls.geometry[wl, 0], walls.geometry[wl, 1], walls.geometry[wl, 2] = mo[MO.ox], mo[MO.oy], mo[MO.oz]
        walls.velocity[wl, 0], walls.velocity[wl, 1], walls.velocity[wl, 2] = mo[MO.tvx], mo[MO.tvy], mo[MO.tvz]
