"""Rolling resistance sub-models (MODELS.md §3-§6, §12).

Kernel signature (slot "rolling")::

    rolling_moment(hist, k, off, nx, ny, nz, onx, ony, onz, spin_angle,
                   dwx, dwy, dwz, normal_stiffness, tangential_stiffness,
                   force_elastic, force_total, r_eff, inertia_r, dt, p, poff)
        -> (mx, my, mz, dissipation)

(dwx, dwy, dwz) is the full relative rotation rate omega_i - omega_j (omega_i - omega_wall for a
wall); a model removes the twist part itself. The resistance moment M acts as -M on particle i
and +M on particle j (MODELS.md §0), so a pure couple. ``inertia_r`` is I_r of seed report eq. 12
(1.4 m R^2 for a wall). ``dissipation`` is the energy (J) dissipated by the couple in the step.
"""

from __future__ import annotations

import math

from numba import njit

from ..errors import check_non_negative
from .base import P_ROLLING_FRICTION, SubModel


@njit(cache=True)
def no_rolling(hist, k, off, nx, ny, nz, onx, ony, onz, spin_angle, dwx, dwy, dwz, kn, kt,
               force_elastic, force_total, r_eff, inertia_r, dt, p, poff):
    """No rolling resistance: M = 0."""
    return 0.0, 0.0, 0.0, 0.0


@njit(cache=True)
def constant_directional_torque(hist, k, off, nx, ny, nz, onx, ony, onz, spin_angle, dwx, dwy, dwz, kn, kt,
                                force_elastic, force_total, r_eff, inertia_r, dt, p, poff):
    """CDT, Ai et al. (2011) type A; seed report eq. 2; STAR-CCM+ Constant Torque.

    M = mu_r R* max(F_n,el, 0) dw_r / |dw_r|, dw_r = dw - (dw . n) n (twist removed), and with the
    optional moment limiter |M| <= f I_r |dw_r| / dt (STAR-CCM+ f = 0.08), so that the torque
    cannot reverse the relative rotation within one step (MODELS.md §11.6).
    """
    wn = dwx * nx + dwy * ny + dwz * nz
    rx = dwx - wn * nx
    ry = dwy - wn * ny
    rz = dwz - wn * nz
    rate = math.sqrt(rx * rx + ry * ry + rz * rz)
    if rate == 0.0:
        return 0.0, 0.0, 0.0, 0.0
    moment = p[P_ROLLING_FRICTION] * r_eff * max(force_elastic, 0.0)
    limiter = p[poff]
    if limiter > 0.0:
        moment = min(moment, limiter * inertia_r * rate / dt)
    s = moment / rate
    return s * rx, s * ry, s * rz, moment * rate * dt


class NoRolling(SubModel):
    """No rolling resistance."""

    slot = "rolling"
    name = "none"
    kernel = ("rollingdem.contact.rolling", "no_rolling")


class CDT(SubModel):
    """Constant directional torque (Ai type A, LIGGGHTS ``cdt``, STAR-CCM+ Constant Torque).

    Parameters
    ----------
    limiter: moment limiter factor f (-), >= 0; 0 switches it off (LIGGGHTS). With f > 0 the
        moment is capped at f I_r |dw_r| / dt; STAR-CCM+ uses 0.08.

    CDT chatters at rest (MODELS.md §11.6); it is offered for parity, not as the default.
    """

    slot = "rolling"
    name = "cdt"
    kernel = ("rollingdem.contact.rolling", "constant_directional_torque")

    def __init__(self, limiter: float = 0.0):
        self.limiter = check_non_negative("cdt limiter", limiter)

    def pair_parameters(self, pair):
        return (self.limiter,)

    def parameters(self):
        return {"limiter": self.limiter}
