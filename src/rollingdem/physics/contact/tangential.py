"""Tangential contact sub-models (docs/models.md §1.2).

Compiled function of the slot "tangential" (arguments: docs/architecture.md; results: docs/models.md §0)::

    tangential_force(hist, k, history_at, g, frame, slip, normal, dt, p, params_at)
        -> (ftx, fty, ftz, dissipation)
"""

from __future__ import annotations

import math

from numba import njit

from rollingdem.errors import check_positive
from rollingdem.physics.records import NORMAL_RESULT as NR
from rollingdem.physics.contact.base import P_FRICTION, SubModel, nothing_to_scale, slots
from rollingdem.physics.contact.frame import carry_with_frame
from rollingdem.physics.contact.properties import FRICTION


@njit(cache=True, inline="always")
def history_spring(hist, k, history_at, g, frame, slip, normal, dt, p, params_at):
    """Tangential spring-dashpot with Coulomb limit.

    xi <- carry(xi) + v_t dt;  F_trial = -k_t xi - gamma_t v_t;
    if |F_trial| > mu max(F_n, 0): F_t = mu max(F_n, 0) F_trial/|F_trial| and the spring is backed
    out of it, xi = -(F_t + gamma_t v_t)/k_t (LAMMPS ``tangential mindlin``: the total force,
    spring and dashpot, never exceeds the Coulomb limit), or xi = 0 where the dashpot alone exceeds
    the limit: that spring would push along the slip (docs/models.md §1.2).
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
        if kt > 0.0 and gamma_t * gamma_t * (vtx * vtx + vty * vty + vtz * vtz) < limit * limit:
            xx = -(fx + gamma_t * vtx) / kt
            xy = -(fy + gamma_t * vty) / kt
            xz = -(fz + gamma_t * vtz) / kt
        else:  # the dashpot alone at or above the limit (an impact's first steps, a pulling contact):
            # backed out through it, the spring would push along the slip
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
    """Tangential history spring with Coulomb limit and dashpot (docs/models.md §1.2)."""

    slot = "tangential"
    material_properties = (FRICTION,)
    name = "history"
    history = slots("spring_x", "spring_y", "spring_z")  # xi (m), carried with the contact frame
    function = staticmethod(history_spring)
    coarse_graining_exponents = nothing_to_scale


@njit(cache=True, inline="always")
def capped(x, y, z, limit):
    """(x, y, z) scaled to the length ``limit`` if longer, and whether it was."""
    v2 = x * x + y * y + z * z
    if v2 > limit * limit:
        s = limit / math.sqrt(v2)
        return x * s, y * s, z * s, True
    return x, y, z, False


WALTON_TANGENTIAL_PARAMETERS = slots("exponent")
WALTON_TANGENTIAL_HISTORY = slots("force_x", "force_y", "force_z", "turning_force", "normal_force_before",
                                  "direction")


@njit(cache=True, inline="always")
def walton_tangential(hist, k, history_at, g, frame, slip, normal, dt, p, params_at):
    """Walton's micro-slip law (Walton & Braun 1986; Walton 1993), a Mindlin-Deresiewicz-like
    spring whose stiffness falls as the force nears the Coulomb limit (docs/models.md §1.5).

    T is the spring force, carried with the contact frame and scaled with N / N_before (T / mu N
    kept), and T* (signed along T) the force where the loading last turned. The slip
    ds = v_t dt splits into ds_par along T and ds_perp across it; with t = |T| and K_0 the initial
    stiffness (the normal law's k_t):
        |T| growing:   K = K_0 [1 - (t - T*) / (mu N - T*)]^gamma
        |T| shrinking: K = K_0 [1 - (T* - t) / (mu N + T*)]^gamma
    t <- t + K ds_par, T <- t T^ + K_0 ds_perp, |T| <= mu N; gamma = 1/3 gives Mindlin's loading
    curve T = mu N [1 - (1 - s/s*)^(3/2)], s* = 3 mu N / (2 K_0). A change of the sign of ds_par
    is a turning point (T* <- t); T passing through zero flips T^ and the sign of T*, which
    continues the same branch. F_t = -T - gamma_t v_t, capped at mu max(N, 0) as ``history_spring``;
    T itself stays at most mu N along its own direction (the dashpot does not move the spring).
    Dissipation: the work of F_t minus the change of |T|^2 / (2 K_0), exact over closed cycles.
    """
    vtx, vty, vtz = slip
    n_force = max(normal[NR.force_elastic], 0.0)
    k0 = normal[NR.tangential_stiffness]
    gamma_t = normal[NR.tangential_damping]
    mu_n = p[P_FRICTION] * n_force
    carry_with_frame(hist, k, history_at, frame)
    tx = hist[k, history_at + WALTON_TANGENTIAL_HISTORY.force_x]
    ty = hist[k, history_at + WALTON_TANGENTIAL_HISTORY.force_y]
    tz = hist[k, history_at + WALTON_TANGENTIAL_HISTORY.force_z]
    turning = hist[k, history_at + WALTON_TANGENTIAL_HISTORY.turning_force]
    direction = hist[k, history_at + WALTON_TANGENTIAL_HISTORY.direction]
    n_before = hist[k, history_at + WALTON_TANGENTIAL_HISTORY.normal_force_before]
    if n_before > 0.0:
        scale = n_force / n_before
        tx *= scale
        ty *= scale
        tz *= scale
        turning *= scale
    stored_before = (tx * tx + ty * ty + tz * tz) / (2.0 * k0) if k0 > 0.0 else 0.0
    dsx = vtx * dt
    dsy = vty * dt
    dsz = vtz * dt
    t = math.sqrt(tx * tx + ty * ty + tz * tz)
    if t > 0.0:
        ux = tx / t
        uy = ty / t
        uz = tz / t
    else:
        ds = math.sqrt(dsx * dsx + dsy * dsy + dsz * dsz)
        ux = dsx / ds if ds > 0.0 else 0.0
        uy = dsy / ds if ds > 0.0 else 0.0
        uz = dsz / ds if ds > 0.0 else 0.0
        turning = 0.0
    ds_par = dsx * ux + dsy * uy + dsz * uz
    step = 1.0 if ds_par >= 0.0 else -1.0
    if step != direction:
        turning = t  # a turning point (the first step counts as one from T = 0)
    gamma = p[params_at + WALTON_TANGENTIAL_PARAMETERS.exponent]
    if mu_n > 0.0:
        if step > 0.0:
            room = 1.0 - (t - turning) / (mu_n - turning) if mu_n > turning else 0.0
        else:
            room = 1.0 - (turning - t) / (mu_n + turning)
        stiffness = k0 * max(room, 0.0) ** gamma
    else:
        stiffness = 0.0
    t_new = t + stiffness * ds_par
    if t_new < 0.0:  # through zero: the same branch, seen from the other side
        t_new = -t_new
        ux = -ux
        uy = -uy
        uz = -uz
        turning = -turning
        step = 1.0
    tx = t_new * ux + k0 * (dsx - ds_par * ux)
    ty = t_new * uy + k0 * (dsy - ds_par * uy)
    tz = t_new * uz + k0 * (dsz - ds_par * uz)
    # the spring's force is capped on its own and never backed out through the dashpot: at the start
    # of an impact gamma_t |v_t| can exceed mu N, and T = -(F + gamma_t v_t) would then point against
    # the slip, a turning point that is not one
    tx, ty, tz, _ = capped(tx, ty, tz, mu_n)
    fx, fy, fz, _ = capped(-tx - gamma_t * vtx, -ty - gamma_t * vty, -tz - gamma_t * vtz, mu_n)
    hist[k, history_at + WALTON_TANGENTIAL_HISTORY.force_x] = tx
    hist[k, history_at + WALTON_TANGENTIAL_HISTORY.force_y] = ty
    hist[k, history_at + WALTON_TANGENTIAL_HISTORY.force_z] = tz
    hist[k, history_at + WALTON_TANGENTIAL_HISTORY.turning_force] = turning
    hist[k, history_at + WALTON_TANGENTIAL_HISTORY.normal_force_before] = n_force
    hist[k, history_at + WALTON_TANGENTIAL_HISTORY.direction] = step
    stored_after = (tx * tx + ty * ty + tz * tz) / (2.0 * k0) if k0 > 0.0 else 0.0
    work_on_contact = -(fx * vtx + fy * vty + fz * vtz) * dt
    return fx, fy, fz, work_on_contact - (stored_after - stored_before)


class WaltonTangential(SubModel):
    """Walton's micro-slip tangential law (docs/models.md §1.5): the stiffness falls from the
    normal law's k_t to 0 as the force nears mu N, with turning points (Masing-like unloading).

    Parameters
    ----------
    exponent: gamma (-), > 0; 1/3 (default) gives Mindlin's monotonic loading curve.
    """

    slot = "tangential"
    material_properties = (FRICTION,)
    name = "walton"
    parameters = WALTON_TANGENTIAL_PARAMETERS
    history = WALTON_TANGENTIAL_HISTORY  # T (N, carried with the frame), T*, N before, loading direction
    function = staticmethod(walton_tangential)

    def __init__(self, exponent: float = 1.0 / 3.0):
        self.exponent = check_positive("walton exponent", exponent)

    def pair_values(self, pair):
        return (self.exponent,)

    def coarse_graining_exponents(self):
        return (0,)

    def settings(self):
        return {"exponent": self.exponent}
