"""A wall's programmed motion in the step loop: oscillation, a table of times, a servo
(``rollingdem.scene.motion``, docs/models.md, "Wall motion").

A wall moves by its steady velocity v and angular velocity omega plus its program's displacement
d(tau) and angle a(tau) about the program's axis u, tau the time since the motion began:

    origin(tau) = p + v tau + d(tau),   vertex(tau) = origin(tau) + R(theta(tau)) (reference - p)

with theta about u (omega . u tau + a(tau)), or about omega (|omega| tau) when the program turns
nothing. Positions are computed from tau, not summed step by step, so they do not drift. Over a
step from tau to tau + dt a contact sees the wall's mean velocity v + (d(tau + dt) - d(tau)) / dt
(and the mean turning rate): the velocity at the half step, as the particles' in the velocity
Verlet step.

- oscillation (LIGGGHTS ``move/mesh`` ``wiggle``, ``riggle``): d = A (sin(w tau + phi) - sin phi),
  a = alpha (sin(w tau + phi) - sin phi): the wall starts where it is;
- table: d and a interpolated linearly between rows (t, d, a) of ``motion_table`` (CAD kinematics),
  less the first row's, so the wall starts where it is; after the last row it holds, or repeats;
- servo (PFC's servo, LIGGGHTS ``servo``): d = s e along the unit direction e, advanced each step at
  s' = clamp(G (F* - F), -v_max, v_max), F = -F_wall . e the load the particles put on the wall at
  the last step (pushing it back against e): a wall that moves while F < F* and stops where F = F*.
"""

from __future__ import annotations

import math

from numba import njit

from rollingdem.engine.layout import MESH_MOTION as MO, MOTION_OSCILLATION, MOTION_SERVO, MOTION_TABLE, \
    MOTION_TABLE_ROW as TR


@njit(cache=True, inline="always")
def table_offset(mo, table, tau):
    """The table's displacement and angle at tau, less its first row's."""
    first, last, period = int(mo[MO.first]), int(mo[MO.last]), mo[MO.period]
    t0 = table[first, TR.t]
    if period > 0.0:
        tau = tau - period * math.floor(tau / period)
    t = t0 + tau
    if t >= table[last - 1, TR.t]:
        k, frac = last - 2, 1.0
    else:
        lo, hi = first, last - 1  # table[lo].t <= t < table[hi].t
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if table[mid, TR.t] <= t:
                lo = mid
            else:
                hi = mid
        k, frac = lo, (t - table[lo, TR.t]) / (table[lo + 1, TR.t] - table[lo, TR.t])
    out0 = table[k, TR.dx] + frac * (table[k + 1, TR.dx] - table[k, TR.dx]) - table[first, TR.dx]
    out1 = table[k, TR.dy] + frac * (table[k + 1, TR.dy] - table[k, TR.dy]) - table[first, TR.dy]
    out2 = table[k, TR.dz] + frac * (table[k + 1, TR.dz] - table[k, TR.dz]) - table[first, TR.dz]
    out3 = table[k, TR.angle] + frac * (table[k + 1, TR.angle] - table[k, TR.angle]) - table[first, TR.angle]
    return out0, out1, out2, out3


@njit(cache=True, inline="always")
def program_offset(mo, table, tau):
    """(dx, dy, dz, angle): the program's displacement (m) and angle about its axis (rad) at tau."""
    kind = mo[MO.program]
    if kind == MOTION_OSCILLATION:
        s = math.sin(mo[MO.omega] * tau + mo[MO.phase]) - math.sin(mo[MO.phase])
        return mo[MO.ax] * s, mo[MO.ay] * s, mo[MO.az] * s, mo[MO.angle] * s
    if kind == MOTION_TABLE:
        return table_offset(mo, table, tau)
    if kind == MOTION_SERVO:
        s = mo[MO.shift]
        return mo[MO.ax] * s, mo[MO.ay] * s, mo[MO.az] * s, 0.0
    return 0.0, 0.0, 0.0, 0.0


@njit(cache=True)  # called, not inlined: compiled once, not into every engine module's step loop
def step_program(mo, table, dt, fx, fy, fz):
    """Advance a programmed motion row by dt (the servo from the force (fx, fy, fz) on its wall at
    the last step): the step's mean velocity and turning rate, the axis's point at the step's end,
    the time. Returns the program's angle at the step's end."""
    tau0 = mo[MO.elapsed]
    tau = tau0 + dt
    d0 = program_offset(mo, table, tau0)
    if mo[MO.program] == MOTION_SERVO:
        load = -(fx * mo[MO.ax] + fy * mo[MO.ay] + fz * mo[MO.az])
        speed = min(max(mo[MO.gain] * (mo[MO.target] - load), -mo[MO.max_speed]), mo[MO.max_speed])
        mo[MO.load] = load
        mo[MO.shift] += dt * speed
    d1 = program_offset(mo, table, tau)
    rate = (d1[3] - d0[3]) / dt
    mo[MO.tvx] = mo[MO.vx] + (d1[0] - d0[0]) / dt
    mo[MO.tvy] = mo[MO.vy] + (d1[1] - d0[1]) / dt
    mo[MO.tvz] = mo[MO.vz] + (d1[2] - d0[2]) / dt
    mo[MO.twx] = mo[MO.wx] + rate * mo[MO.ux]
    mo[MO.twy] = mo[MO.wy] + rate * mo[MO.uy]
    mo[MO.twz] = mo[MO.wz] + rate * mo[MO.uz]
    mo[MO.ox] = mo[MO.px] + mo[MO.vx] * tau + d1[0]
    mo[MO.oy] = mo[MO.py] + mo[MO.vy] * tau + d1[1]
    mo[MO.oz] = mo[MO.pz] + mo[MO.vz] * tau + d1[2]
    mo[MO.elapsed] = tau
    return d1[3]


@njit(cache=True)
def plane_loads(walls, wl):
    """The force (N) the particles put on plane or cylinder wl at the last step."""
    nwall = walls.kind.shape[0]
    fx = fy = fz = 0.0
    for k in range(wl, walls.load.shape[0], nwall):
        fx += walls.load[k, 0]
        fy += walls.load[k, 1]
        fz += walls.load[k, 2]
    return fx, fy, fz


@njit(cache=True)
def mesh_loads(walls, m):
    """The force (N) the particles put on mesh m at the last step."""
    fx = fy = fz = 0.0
    slots = walls.slot_triangle
    for i in range(slots.shape[0]):
        for s in range(slots.shape[1]):
            t = slots[i, s]
            if t >= 0 and walls.triangle_mesh[t] == m:
                k = i * slots.shape[1] + s
                fx += walls.mesh_load[k, 0]
                fy += walls.mesh_load[k, 1]
                fz += walls.mesh_load[k, 2]
    return fx, fy, fz
