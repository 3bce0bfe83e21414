"""Tangential contact sub-models (docs/models.md §1.2).

Compiled function of the slot "tangential" (arguments: docs/architecture.md; results: docs/models.md §0)::

    tangential_force(hist, k, history_at, g, frame, slip, normal, dt, p, params_at)
        -> (ftx, fty, ftz, dissipation)
"""

from __future__ import annotations

import math

from numba import njit

from ..kernel_layout import NORMAL_RESULT as NR
from .base import P_FRICTION, SubModel, slots
from .frame import carry_with_frame


@njit(cache=True, inline="always")
def history_spring(hist, k, history_at, g, frame, slip, normal, dt, p, params_at):
    """Tangential spring-dashpot with Coulomb limit.

    xi <- carry(xi) + v_t dt;  F_trial = -k_t xi - gamma_t v_t;
    if |F_trial| > mu max(F_n, 0): F_t = mu max(F_n, 0) F_trial/|F_trial| and the spring is backed
    out of it, xi = -(F_t + gamma_t v_t)/k_t (LAMMPS ``tangential mindlin``: the total force,
    spring and dashpot, never exceeds the Coulomb limit).
    The spring is carried with the contact frame (rotated, not just projected: docs/models.md §11.3).
    The limit uses max(F_n, 0), never |F_n|: a contact pulled by its dashpot cannot grip (§11.4).
    Dissipation: the work of F_t over the step, -F_t . v_t dt, minus the increase of the spring
    energy 1/2 k_t |xi|^2. The work is taken with the end-of-step force, so a purely elastic step
    leaves a residual 1/2 k_t |v_t|^2 dt^2 (>= 0, vanishing as dt^2); the dashpot adds gamma_t |v_t|^2 dt;
    steady sliding at the limit dissipates mu max(F_n, 0) |v_t| dt, the friction work.
    """
    vtx, vty, vtz = slip
    normal_force = normal[NR.force_total]
    kt = normal[NR.tangential_stiffness]
    gamma_t = normal[NR.tangential_damping]
    carry_with_frame(hist, k, history_at, frame)
    x0 = hist[k, history_at]
    y0 = hist[k, history_at + 1]
    z0 = hist[k, history_at + 2]
    stored_before = 0.5 * kt * (x0 * x0 + y0 * y0 + z0 * z0)
    xx = x0 + vtx * dt
    xy = y0 + vty * dt
    xz = z0 + vtz * dt
    fx = -kt * xx - gamma_t * vtx
    fy = -kt * xy - gamma_t * vty
    fz = -kt * xz - gamma_t * vtz
    limit = p[P_FRICTION] * max(normal_force, 0.0)
    f2 = fx * fx + fy * fy + fz * fz
    if f2 > limit * limit:
        if f2 > 0.0:
            s = limit / math.sqrt(f2)
            fx *= s
            fy *= s
            fz *= s
        if kt > 0.0:
            xx = -(fx + gamma_t * vtx) / kt
            xy = -(fy + gamma_t * vty) / kt
            xz = -(fz + gamma_t * vtz) / kt
        else:
            xx = 0.0
            xy = 0.0
            xz = 0.0
    hist[k, history_at] = xx
    hist[k, history_at + 1] = xy
    hist[k, history_at + 2] = xz
    stored_after = 0.5 * kt * (xx * xx + xy * xy + xz * xz)
    work_on_contact = -(fx * vtx + fy * vty + fz * vtz) * dt
    return fx, fy, fz, work_on_contact - (stored_after - stored_before)


class HistorySpring(SubModel):
    """Tangential history spring with Coulomb limit and dashpot (the only tangential model so far)."""

    slot = "tangential"
    name = "history"
    history = slots("spring_x", "spring_y", "spring_z")  # xi (m), carried with the contact frame
    function = staticmethod(history_spring)
