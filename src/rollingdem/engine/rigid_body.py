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
"""

from __future__ import annotations

import math

from numba import njit


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
