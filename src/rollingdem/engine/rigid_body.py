"""A rigid body's rotation in the velocity Verlet step: the free rotor split into exact turns about
its principal axes (Dullweber, Leimkuhler & McLachlan, J. Chem. Phys. 107, 5840 (1997); LAMMPS's
``fix rigid/nve`` splits the same way, Miller et al., J. Chem. Phys. 116, 8649 (2002)).

The body's orientation is a unit quaternion q = (w, x, y, z), turning body-frame vectors into the
space frame; its angular momentum L is kept in the space frame. A step is a half kick of L by the
torque, the free rotation over dt, and the closing half kick, as the spheres' velocity Verlet step
kicks their velocities and drifts their positions. The free rotation with principal moments I_1,
I_2, I_3 is the symmetric sequence of turns about body axes 1, 2, 3, 2, 1 over dt/2, dt/2, dt,
dt/2, dt/2: each turn about axis k by pi_k h / I_k is exact for its part of the kinetic energy
pi_k^2 / (2 I_k), pi the body-frame angular momentum. The map is symplectic and time-reversible,
keeps |L| to rounding (every turn is a rotation), and keeps the energy to O(dt^2) without drift.
Nothing here allocates: the functions take and return scalars and write into the arrays given.

A clump in the step loop (``clump_rows``): its members are particles the gather gives forces as any
other (walls, pairs) but does not move. After the gather each clump sums its members' forces and
torques in its members' order, about its centre of mass, adds its weight there, kicks
its velocity and angular momentum, drifts and turns (the step's opening half), and puts its members
where it now is, with the velocity of the body at their centres.
"""

from __future__ import annotations

import math

from numba import njit, prange

from rollingdem.engine.layout import PERIODIC_BOX as PB

#: clumps a thread takes at a time in ``clump_pass``
CLUMP_RUN = 64
#: ``kick`` of ``clump_rows`` for the step's opening half kick and drift alone (``kick_drift``'s part)
KICK_OPEN = -1.0


@njit(cache=True, inline="always")
def quaternion_rotate(qw, qx, qy, qz, vx, vy, vz):
    """The vector v turned by the unit quaternion q: q v q*."""
    # t = 2 (q_vec x v); v' = v + w t + q_vec x t
    tx = 2.0 * (qy * vz - qz * vy)
    ty = 2.0 * (qz * vx - qx * vz)
    tz = 2.0 * (qx * vy - qy * vx)
    return (vx + qw * tx + (qy * tz - qz * ty),
            vy + qw * ty + (qz * tx - qx * tz),
            vz + qw * tz + (qx * ty - qy * tx))


@njit(cache=True, inline="always")
def _turn(axis, angle, qw, qx, qy, qz, px, py, pz):
    """Turn the body by ``angle`` about its own principal ``axis`` (0, 1, 2): q <- q (cos a/2, sin a/2
    e_axis); the body-frame angular momentum turns the other way, pi <- R_axis(-angle) pi."""
    c, s = math.cos(0.5 * angle), math.sin(0.5 * angle)
    ca, sa = math.cos(angle), math.sin(angle)
    if axis == 0:
        qw, qx, qy, qz = qw * c - qx * s, qx * c + qw * s, qy * c + qz * s, qz * c - qy * s
        py, pz = ca * py + sa * pz, -sa * py + ca * pz
    elif axis == 1:
        qw, qx, qy, qz = qw * c - qy * s, qx * c - qz * s, qy * c + qw * s, qz * c + qx * s
        px, pz = ca * px - sa * pz, sa * px + ca * pz
    else:
        qw, qx, qy, qz = qw * c - qz * s, qx * c + qy * s, qy * c - qx * s, qz * c + qw * s
        px, py = ca * px + sa * py, -sa * px + ca * py
    return qw, qx, qy, qz, px, py, pz


@njit(cache=True)
def free_rotation(q, angular_momentum, moments, dt):
    """Rotate a torque-free rigid body for dt: ``q`` (4,) its orientation (updated, renormalised),
    ``angular_momentum`` (3,) its L in the space frame (constant in a free rotation: not changed),
    ``moments`` (3,) its principal moments of inertia (kg m^2) along its body axes."""
    qw, qx, qy, qz = q[0], q[1], q[2], q[3]
    # pi = R^T L: L turned by q* into the body frame
    px, py, pz = quaternion_rotate(qw, -qx, -qy, -qz, angular_momentum[0], angular_momentum[1],
                                   angular_momentum[2])
    h = 0.5 * dt
    qw, qx, qy, qz, px, py, pz = _turn(0, px * h / moments[0], qw, qx, qy, qz, px, py, pz)
    qw, qx, qy, qz, px, py, pz = _turn(1, py * h / moments[1], qw, qx, qy, qz, px, py, pz)
    qw, qx, qy, qz, px, py, pz = _turn(2, pz * dt / moments[2], qw, qx, qy, qz, px, py, pz)
    qw, qx, qy, qz, px, py, pz = _turn(1, py * h / moments[1], qw, qx, qy, qz, px, py, pz)
    qw, qx, qy, qz, px, py, pz = _turn(0, px * h / moments[0], qw, qx, qy, qz, px, py, pz)
    norm = 1.0 / math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    q[0], q[1], q[2], q[3] = qw * norm, qx * norm, qy * norm, qz * norm


@njit(cache=True)
def rigid_rotation_step(q, angular_momentum, moments, torque, dt):
    """One velocity Verlet step of a rigid body's rotation under a constant ``torque`` (3,) in the
    space frame: L += dt/2 T, the free rotation over dt, L += dt/2 T."""
    for d in range(3):
        angular_momentum[d] += 0.5 * dt * torque[d]
    free_rotation(q, angular_momentum, moments, dt)
    for d in range(3):
        angular_momentum[d] += 0.5 * dt * torque[d]


@njit(cache=True)
def body_angular_velocity(q, angular_momentum, moments):
    """The angular velocity in the body frame, pi_k / I_k (rad/s)."""
    px, py, pz = quaternion_rotate(q[0], -q[1], -q[2], -q[3], angular_momentum[0], angular_momentum[1],
                                   angular_momentum[2])
    return px / moments[0], py / moments[1], pz / moments[2]


@njit(cache=True)
def rotate_free_body(q, angular_momentum, moments, dt, steps, out):
    """``steps`` free rotations of dt, writing the body-frame angular velocity after each into ``out``
    (steps, 3): what a test of the rotor needs from a compiled loop."""
    for k in range(steps):
        free_rotation(q, angular_momentum, moments, dt)
        w = body_angular_velocity(q, angular_momentum, moments)
        out[k, 0], out[k, 1], out[k, 2] = w[0], w[1], w[2]


@njit(cache=True, inline="always")
def _space_angular_velocity(q, L, moments):
    """omega = R diag(1/I) R^T L, space frame (rad/s)."""
    px, py, pz = quaternion_rotate(q[0], -q[1], -q[2], -q[3], L[0], L[1], L[2])
    return quaternion_rotate(q[0], q[1], q[2], q[3], px / moments[0], py / moments[1], pz / moments[2])


@njit(cache=True, inline="always")
def _place_members(c, particles, box, drifted, half_skin):
    """Clump c's members at its centre and orientation: x = X + R r_body (less the periodic lengths
    each member has crossed), v = V + omega x r, w = omega. Returns 1 if ``drifted`` and a member is
    now skin/2 or more from where the list was built."""
    x, v, w, image, offset, x_ref = particles.x, particles.v, particles.w, particles.image, particles.body_offset, \
        particles.x_ref
    members = particles.clump_members
    q, X, V = particles.clump_q[c], particles.clump_x[c], particles.clump_v[c]
    ox, oy, oz = _space_angular_velocity(q, particles.clump_L[c], particles.clump_moments[c])
    periodic = box.shape[0] != 0
    exceed = 0
    for e in range(particles.clump_start[c], particles.clump_start[c + 1]):
        m = members[e]
        rx, ry, rz = quaternion_rotate(q[0], q[1], q[2], q[3], offset[m, 0], offset[m, 1], offset[m, 2])
        x[m, 0] = X[0] + rx
        x[m, 1] = X[1] + ry
        x[m, 2] = X[2] + rz
        if periodic:
            for d in range(3):
                x[m, d] -= image[m, d] * box[PB.lx + d]
        v[m, 0] = V[0] + oy * rz - oz * ry
        v[m, 1] = V[1] + oz * rx - ox * rz
        v[m, 2] = V[2] + ox * ry - oy * rx
        w[m, 0] = ox
        w[m, 1] = oy
        w[m, 2] = oz
        if drifted:
            ex = x[m, 0] - x_ref[m, 0]
            ey = x[m, 1] - x_ref[m, 1]
            ez = x[m, 2] - x_ref[m, 2]
            if not ex * ex + ey * ey + ez * ez < half_skin * half_skin:  # NaN too
                exceed = 1
    return exceed


@njit(cache=True, inline="always")
def clump_reach(c, particles):
    """The farthest member centre of clump c from its centre of mass (m)."""
    off = particles.body_offset
    reach = 0.0
    for e in range(particles.clump_start[c], particles.clump_start[c + 1]):
        m = particles.clump_members[e]
        reach = max(reach, math.sqrt(off[m, 0] * off[m, 0] + off[m, 1] * off[m, 1] + off[m, 2] * off[m, 2]))
    return reach


@njit(cache=True, inline="always")
def clump_drift_bound(dt, c, particles, V, L, reach):
    """A bound on how far any member of clump c moves in the next drift (m), from its velocity
    ``V`` and angular momentum ``L`` before the opening half kick: the centre's
    dt (|V| + dt/2 |F|/M) and the turn's dt (|omega| + dt/2 |T|/I_min) times the reach."""
    F, T, moments = particles.clump_f[c], particles.clump_t[c], particles.clump_moments[c]
    ox, oy, oz = _space_angular_velocity(particles.clump_q[c], L, moments)
    i_min = min(moments[0], min(moments[1], moments[2]))
    move = dt * (math.sqrt(V[0] * V[0] + V[1] * V[1] + V[2] * V[2])
                 + 0.5 * dt * math.sqrt(F[0] * F[0] + F[1] * F[1] + F[2] * F[2]) / particles.clump_mass[c])
    turn = dt * (math.sqrt(ox * ox + oy * oy + oz * oz)
                 + 0.5 * dt * math.sqrt(T[0] * T[0] + T[1] * T[1] + T[2] * T[2]) / i_min)
    return move + turn * reach


@njit(cache=True, inline="always")
def _open_clump(dt, c, particles):
    """The opening half kick of clump c and its drift and free rotation over dt."""
    a = 0.5 * dt / particles.clump_mass[c]
    X, V, L, F, T = particles.clump_x[c], particles.clump_v[c], particles.clump_L[c], particles.clump_f[c], \
        particles.clump_t[c]
    for d in range(3):
        V[d] += a * F[d]
        L[d] += 0.5 * dt * T[d]
        X[d] += dt * V[d]
    free_rotation(particles.clump_q[c], L, particles.clump_moments[c], dt)


@njit(cache=True, _nrt=False, error_model="numpy", fastmath={"contract"})
def clump_rows(lo, hi, dt, kick, gravity, particles, box, half_skin):
    """Clumps lo..hi-1 after the gather (``kick`` as the gather's: 0 sum the forces, 1 and the
    closing half kick, 2 and the next step's opening half kick, drift and rotation) or for the
    step's opening half alone (``KICK_OPEN``). The members' forces and torques are summed in their
    order, and the weight added at the centre of mass: F = sum f_m + M g, T = sum (t_m + r_m x f_m)
    (a member's force is its contacts' alone: its share of the weight acting at its own centre
    would turn a clump whose members overlap). Returns the counts (members now skin/2 or more
    from where the list was built, clumps whose next drift would be skin/2 or more); a fixed
    clump (its members fixed) stays."""
    f, t, offset, members, fixed = particles.f, particles.t, particles.body_offset, particles.clump_members, \
        particles.fixed
    nexceed = 0
    nfast = 0
    for c in range(lo, hi):
        first, last = particles.clump_start[c], particles.clump_start[c + 1]
        if fixed.shape[0] != 0 and fixed[members[first]]:
            continue
        drift = kick < 0.0
        if not drift:
            q, F, T = particles.clump_q[c], particles.clump_f[c], particles.clump_t[c]
            fx = fy = fz = tx = ty = tz = 0.0
            reach2 = 0.0
            for e in range(first, last):
                m = members[e]
                rx, ry, rz = quaternion_rotate(q[0], q[1], q[2], q[3], offset[m, 0], offset[m, 1], offset[m, 2])
                reach2 = max(reach2, rx * rx + ry * ry + rz * rz)
                fx += f[m, 0]
                fy += f[m, 1]
                fz += f[m, 2]
                tx += t[m, 0] + ry * f[m, 2] - rz * f[m, 1]
                ty += t[m, 1] + rz * f[m, 0] - rx * f[m, 2]
                tz += t[m, 2] + rx * f[m, 1] - ry * f[m, 0]
            M = particles.clump_mass[c]
            F[0], F[1], F[2] = fx + M * gravity[0], fy + M * gravity[1], fz + M * gravity[2]
            T[0], T[1], T[2] = tx, ty, tz
            if kick >= 1.0:
                a = 0.5 * dt / particles.clump_mass[c]
                V, L = particles.clump_v[c], particles.clump_L[c]
                for d in range(3):
                    V[d] += a * F[d]
                    L[d] += 0.5 * dt * T[d]
            bound = clump_drift_bound(dt, c, particles, particles.clump_v[c], particles.clump_L[c],
                                      math.sqrt(reach2))
            if not bound < half_skin:  # NaN too
                nfast += 1
            # the next step's opening half, also when too fast (the chunk then stops and
            # clump_undo takes it back), but not when the state is not finite
            drift = kick == 2.0 and bound - bound == 0.0
        if drift:
            _open_clump(dt, c, particles)
        nexceed += _place_members(c, particles, box, drift, half_skin)
    return nexceed, nfast


@njit(cache=True, parallel=True, error_model="numpy", fastmath={"contract"})
def clump_pass(dt, kick, gravity, particles, box, half_skin):
    """``clump_rows`` on runs of ``CLUMP_RUN`` clumps, shared out among the threads (each clump
    writes its own rows and its members' only)."""
    nc = particles.clump_mass.shape[0]
    nexceed = 0
    nfast = 0
    for b in prange((nc + CLUMP_RUN - 1) // CLUMP_RUN):
        exceed, fast = clump_rows(b * CLUMP_RUN, min((b + 1) * CLUMP_RUN, nc), dt, kick, gravity, particles, box,
                                  half_skin)
        nexceed += exceed
        nfast += fast
    return nexceed, nfast


@njit(cache=True, parallel=True, error_model="numpy", fastmath={"contract"})
def clump_pass_serial(dt, kick, gravity, particles, box, half_skin):
    """``clump_pass`` on the calling thread."""
    nexceed = nfast = 0
    for b in range(1):
        nexceed, nfast = clump_rows(b, particles.clump_mass.shape[0], dt, kick, gravity, particles, box, half_skin)
    return nexceed, nfast


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def clump_undo(dt, particles, box):
    """Take back the opening half kick, drift and rotation ``clump_rows`` made (as ``undo_drift``
    does the spheres'), in the clumps it made them in: the free rotation over -dt is the inverse of
    that over dt (the splitting is symmetric)."""
    members, fixed = particles.clump_members, particles.fixed
    for c in range(particles.clump_mass.shape[0]):
        if fixed.shape[0] != 0 and fixed[members[particles.clump_start[c]]]:
            continue
        a = 0.5 * dt / particles.clump_mass[c]
        X, V, L, F, T = particles.clump_x[c], particles.clump_v[c], particles.clump_L[c], particles.clump_f[c], \
            particles.clump_t[c]
        # the velocity and angular momentum before the opening half kick, and clump_rows's test on them
        vx, vy, vz = V[0] - a * F[0], V[1] - a * F[1], V[2] - a * F[2]
        lx, ly, lz = L[0] - 0.5 * dt * T[0], L[1] - 0.5 * dt * T[1], L[2] - 0.5 * dt * T[2]
        bound = clump_drift_bound(dt, c, particles, (vx, vy, vz), (lx, ly, lz), clump_reach(c, particles))
        if bound - bound != 0.0:  # not drifted
            continue
        free_rotation(particles.clump_q[c], L, particles.clump_moments[c], -dt)
        for d in range(3):
            X[d] -= dt * V[d]
        V[0], V[1], V[2], L[0], L[1], L[2] = vx, vy, vz, lx, ly, lz
        _place_members(c, particles, box, False, 0.0)
