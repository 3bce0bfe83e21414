"""Twisting resistance sub-models (docs/models.md §4.8).

Compiled function of the slot "twisting"::

    twisting_moment(hist, k, history_at, g, normal, dt, p, params_at) -> (m_twist, dissipation)

``g`` is the contact's ``records.CONTACT_INPUTS``, ``normal`` the normal law's
``NORMAL_RESULT``. The twisting moment acts as -m_twist n on particle i and +m_twist n on particle j.
"""

from __future__ import annotations

import math

from numba import njit

from rollingdem.errors import ParameterError, check_finite, check_non_negative, check_positive
from rollingdem.physics.records import CONTACT_INPUTS as IN, NORMAL_RESULT as NR
from rollingdem.physics.contact.base import P_FRICTION, SubModel, nothing_to_scale, slots
from rollingdem.physics.contact.properties import FRICTION


@njit(cache=True, inline="always")
def no_twisting(hist, k, history_at, g, normal, dt, p, params_at):
    """No twisting resistance."""
    return 0.0, 0.0


class NoTwisting(SubModel):
    """No twisting resistance: a sphere spinning about the contact normal keeps spinning."""

    slot = "twisting"
    name = "none"
    function = staticmethod(no_twisting)
    coarse_graining_exponents = nothing_to_scale


TWISTING_PARAMETERS = slots("marshall", "twisting_stiffness", "twisting_damping", "twisting_friction")
TWISTING_HISTORY = slots("twist_angle")  # xi (rad)


@njit(cache=True, inline="always")
def spring_twisting(hist, k, history_at, g, normal, dt, p, params_at):
    """Twisting spring-dashpot-slider (LAMMPS ``twisting sds`` / ``marshall``, docs/models.md §4.8).

    Omega_tw = (omega_i - omega_j) . n;  xi += Omega_tw dt;  M = k_tw xi + gamma_tw Omega_tw;
    |M| <= mu_tw max(F_n,el, 0), and at the cap the spring is backed out: xi = (M - gamma_tw Omega_tw)/k_tw.
    Marshall (2009): k_tw = k_t a^2 / 2, gamma_tw = gamma_t a^2 / 2, mu_tw = 2/3 a mu, a = sqrt(R* delta).
    """
    nx, ny, nz = g[IN.nx], g[IN.ny], g[IN.nz]
    dwx = g[IN.wix] - g[IN.wjx]
    dwy = g[IN.wiy] - g[IN.wjy]
    dwz = g[IN.wiz] - g[IN.wjz]
    overlap, r_eff = g[IN.overlap], g[IN.r_eff]
    kt, gamma_t, force_elastic = normal[NR.tangential_stiffness], normal[NR.tangential_damping], normal[NR.force_elastic]
    spin = dwx * nx + dwy * ny + dwz * nz
    if p[params_at + TWISTING_PARAMETERS.marshall] > 0.0:
        a2 = r_eff * overlap
        k_tw = 0.5 * kt * a2
        g_tw = 0.5 * gamma_t * a2
        limit = (2.0 / 3.0) * math.sqrt(a2) * p[P_FRICTION] * max(force_elastic, 0.0)
    else:
        k_tw = p[params_at + TWISTING_PARAMETERS.twisting_stiffness]
        g_tw = p[params_at + TWISTING_PARAMETERS.twisting_damping]
        limit = p[params_at + TWISTING_PARAMETERS.twisting_friction] * max(force_elastic, 0.0)
    xi = hist[k, history_at + TWISTING_HISTORY.twist_angle]
    stored_before = 0.5 * k_tw * xi * xi
    xi += spin * dt
    moment = k_tw * xi + g_tw * spin
    if abs(moment) > limit:
        moment = limit if moment > 0.0 else -limit
        xi = (moment - g_tw * spin) / k_tw if k_tw > 0.0 else 0.0
    hist[k, history_at + TWISTING_HISTORY.twist_angle] = xi
    return moment, moment * spin * dt - (0.5 * k_tw * xi * xi - stored_before)


class Marshall(SubModel):
    """Twisting after Marshall (2009), as LAMMPS ``twisting marshall``: constants from the tangential
    model and the contact radius a = sqrt(R* delta); no parameters of its own."""

    slot = "twisting"
    name = "marshall"
    material_properties = (FRICTION,)
    parameters = TWISTING_PARAMETERS
    history = TWISTING_HISTORY
    function = staticmethod(spring_twisting)

    def pair_values(self, pair):
        return (1.0, 0.0, 0.0, 0.0)

    def coarse_graining_exponents(self):
        return (0, 0, 0, 0)  # from k_t, gamma_t and a = sqrt(R* delta): alpha^3 by themselves

    def rotational_stiffness(self, normal_stiffness, tangential_stiffness, r_eff, overlap, normal_force, pair):
        return 0.5 * tangential_stiffness * r_eff * overlap


class TwistingSDS(SubModel):
    """Twisting spring-dashpot-slider with given constants, as LAMMPS ``twisting sds``.

    twisting_stiffness: k_tw (N m/rad), > 0.  twisting_damping: gamma_tw (N m s/rad), >= 0.
    twisting_friction: mu_tw (m), > 0, required: the moment is capped at mu_tw max(F_n,el, 0).

    twisting_friction has no default and 0 is refused: the cap mu_tw F_n applies to spring and
    dashpot together, so with mu_tw = 0 the moment is always 0 and the model does nothing (a sphere
    spinning on a plate keeps its spin, as with ``twisting="none"``); LAMMPS also requires all three
    constants. It stays the third positional argument (``TwistingSDS(k, gamma, mu)`` keeps its
    meaning); leaving it out is a ParameterError, not a silent no-op.
    """

    slot = "twisting"
    name = "sds"
    material_properties = (FRICTION,)
    parameters = TWISTING_PARAMETERS
    history = TWISTING_HISTORY
    function = staticmethod(spring_twisting)

    def __init__(self, twisting_stiffness, twisting_damping=0.0, twisting_friction=None):
        self.twisting_stiffness = check_positive("twisting sds twisting_stiffness", twisting_stiffness, "N m/rad")
        self.twisting_damping = check_non_negative("twisting sds twisting_damping", twisting_damping, "N m s/rad")
        if twisting_friction is None:
            raise ParameterError("twisting sds twisting_friction is required: mu_tw (m), > 0, the moment is capped "
                                 "at mu_tw F_n (without a cap the model would do nothing)")
        friction = check_finite("twisting sds twisting_friction", twisting_friction)
        if friction <= 0.0:
            raise ParameterError(f"twisting sds twisting_friction = {friction:g} is not allowed: must be > 0 (m); the "
                                 "moment is capped at mu_tw F_n, so 0 would do nothing (use twisting=\"none\" for "
                                 "no twisting resistance)")
        self.twisting_friction = friction

    def pair_values(self, pair):
        return (0.0, self.twisting_stiffness, self.twisting_damping, self.twisting_friction)

    def coarse_graining_exponents(self):
        # M = k_tw xi + gamma_tw Omega must scale as alpha^3 with xi kept and Omega ~ 1/alpha, and
        # the cap mu_tw F_n with F_n ~ alpha^2
        return (0, 3, 4, 1)

    def rotational_stiffness(self, normal_stiffness, tangential_stiffness, r_eff, overlap, normal_force, pair):
        return self.pair_row(pair)[TWISTING_PARAMETERS.twisting_stiffness]  # as the parcels meet it

    def settings(self):
        return {"twisting_stiffness": self.twisting_stiffness, "twisting_damping": self.twisting_damping,
                "twisting_friction": self.twisting_friction}
