"""Cohesion sub-models (docs/models.md §1.6): an attractive normal force on top of the normal law.

Compiled function of the slot "cohesion" (arguments: docs/architecture.md; results: docs/models.md §0)::

    cohesion_force(hist, k, history_at, g, normal, p, params_at) -> (force, dissipation)

``force`` is added to the normal force on i along n (negative: attractive). The Coulomb, rolling and
twisting limits do not see it: they take the normal law's force (docs/models.md §11.4). A law that
acts past touching (``jkr``) names the history slot holding how far beyond touching its contact
lasts (``detach_slot``); the engine keeps such a contact until the spheres are that far apart.
"""

from __future__ import annotations

import math

from numba import njit

from rollingdem.errors import ParameterError
from rollingdem.physics.records import CONTACT_INPUTS as IN, NORMAL_RESULT as NR
from rollingdem.physics.contact.base import P_YOUNG, SubModel, nothing_to_scale, slots
from rollingdem.physics.contact.properties import COHESION_ENERGY_DENSITY, SURFACE_ENERGY


@njit(cache=True, inline="always")
def no_cohesion(hist, k, history_at, g, normal, p, params_at):
    """No cohesion."""
    return 0.0, 0.0


class Cohesion(SubModel):
    """Base of the cohesion laws; their parameters are the material pair's
    ``cohesion_energy_density`` and ``surface_energy`` (``rollingdem.Material``)."""

    slot = "cohesion"
    #: the history slot holding how far beyond touching (m) the contact lasts; None: it ends at touching
    detach_slot = None

    def separation_limit(self, pair, r_eff) -> float:
        """How far apart (m) two spheres of effective radius ``r_eff`` still hold a contact."""
        return 0.0

    def check_normal(self, normal) -> None:
        """Refuse a normal law this cohesion law cannot sit on (default: none refused)."""

    def time_step_limits(self, material, pair, r_min, m_min) -> list[tuple[str, float]]:
        """(description, largest allowed dt) of the law's own criteria, for two of the smallest
        spheres of ``material`` (docs/models.md §2); none by default."""
        return []


class NoCohesion(Cohesion):
    """No cohesion (the default)."""

    name = "none"
    function = staticmethod(no_cohesion)
    coarse_graining_exponents = nothing_to_scale


SJKR_PARAMETERS = slots("energy_density")


@njit(cache=True, inline="always")
def contact_area(g):
    """pi a^2 of the circle where the two spheres' surfaces cross (a wall: the sphere's circle at
    the plane), from the overlap and the levers R'_i = R_i - delta/2, R'_j = R_j - delta/2 (0 for a
    wall): a^2 = (d^2 - (R_i - R_j)^2)((R_i + R_j)^2 - d^2) / (4 d^2), d = R_i + R_j - delta; a wall
    a^2 = delta (2 R_i - delta)."""
    overlap = g[IN.overlap]
    ri = g[IN.lever_i] + 0.5 * overlap
    if g[IN.lever_j] == 0.0:
        return math.pi * overlap * (2.0 * ri - overlap)
    rj = g[IN.lever_j] + 0.5 * overlap
    d = ri + rj - overlap
    diff = ri - rj
    total = ri + rj
    return math.pi * (d * d - diff * diff) * (total * total - d * d) / (4.0 * d * d)


@njit(cache=True, inline="always")
def sjkr_cohesion(hist, k, history_at, g, normal, p, params_at):
    """Simplified JKR, LIGGGHTS ``cohesion sjkr``: F = -k_c A, A the area of the circle where the
    surfaces cross (``contact_area``), k_c the cohesion energy density (J/m^3). A function of the
    overlap alone, zero at touching: conservative, no dissipation."""
    return -p[params_at + SJKR_PARAMETERS.energy_density] * contact_area(g), 0.0


class SJKR(Cohesion):
    """LIGGGHTS's simplified JKR cohesion, F = -k_c A (docs/models.md §1.6), with k_c the pair's
    ``cohesion_energy_density`` (J/m^3, the mean of the two materials' unless set for the pair).
    No parameters of its own."""

    name = "sjkr"
    material_properties = (COHESION_ENERGY_DENSITY,)
    parameters = SJKR_PARAMETERS
    function = staticmethod(sjkr_cohesion)

    def pair_values(self, pair):
        return (pair.cohesion_energy_density,)

    def coarse_graining_exponents(self):
        return (0,)  # F = k_c A with the area A ~ alpha^2


JKR_PARAMETERS = slots("surface_energy")
JKR_HISTORY = slots("separation_limit", "overlap_before", "force_before", "energy_before", "root_before",
                    "energy_at_separation")


@njit(cache=True, inline="always")
def jkr_root(overlap, r_eff, c, x):
    """x = sqrt(a), a the JKR contact radius of the stable branch at ``overlap``: the root
    x >= x_f of g(x) = x^4 / R* - c x - delta (delta = a^2/R* - sqrt(2 pi w a / E*), c = sqrt(2 pi
    w / E*)), by Newton's method from ``x`` (the last step's root). g is convex right of x_f, where
    g' = 0: from a start between x_f and the root the first step lands right of the root, and from
    there Newton falls onto it without overshoot. A start at or left of x_f (a fresh contact: 0) is
    replaced by (R* max(delta, 0))^(1/4) + (c R*)^(1/3), which is right of the root."""
    if 4.0 * x * x * x / r_eff - c <= 0.0:
        x = (r_eff * max(overlap, 0.0)) ** 0.25 + (c * r_eff) ** (1.0 / 3.0)
    for _ in range(60):
        x3 = x * x * x
        slope = 4.0 * x3 / r_eff - c
        if slope <= 0.0:
            break
        step = (x3 * x / r_eff - c * x - overlap) / slope
        x -= step
        if abs(step) <= 1e-15 * x:
            break
    return x


@njit(cache=True, inline="always")
def jkr_energy(x, r_eff, young, c, surface_energy):
    """V(a) = 8 E* a^5 / (15 R*^2) - 4/(3 R*) sqrt(2 pi w E*) a^(7/2) + pi w a^2 at a = x^2 (with
    sqrt(2 pi w E*) = E* c), whose change along the JKR curve is the work int F d(delta): dV/da is
    F(a) d(delta)/da."""
    a = x * x
    a2 = a * a
    return (8.0 * young * a2 * a2 * a / (15.0 * r_eff * r_eff) - 4.0 * young * c * a2 * a * x / (3.0 * r_eff)
            + math.pi * surface_energy * a2)


@njit(cache=True, inline="always")
def jkr_cohesion(hist, k, history_at, g, normal, p, params_at):
    """JKR (Johnson, Kendall & Roberts 1971) on Hertz: with the contact radius a = x^2 of the stable
    branch (``jkr_root``), F_JKR = 4 E* a^3 / (3 R*) - sqrt(8 pi w E* a^3); returns F_JKR minus
    the normal law's elastic force (Hertz's), so that the pair feels F_JKR plus the dashpot. The
    contact forms at touching and lasts until the separation
    delta_c = -(3/4) (pi^2 w^2 R* / E*^2)^(1/3) (kept in ``separation_limit``); pull-off at
    -3/2 pi w R*. Dissipation: the step's work of the force minus the change of its energy
    U = V(a) - V(a_f) - 8/15 E* sqrt(R*) delta^(5/2) (zero at detachment, so the loss of a whole
    approach and separation, int_delta_c^0 |F_JKR| d(delta), is counted when the contact forms).
    What depends on R* alone (delta_c, V(a_f)) is computed at the contact's first step and kept."""
    overlap = g[IN.overlap]
    r_eff = g[IN.r_eff]
    young = p[P_YOUNG]
    w = p[params_at + JKR_PARAMETERS.surface_energy]
    c = math.sqrt(2.0 * math.pi * w / young)
    fresh = hist[k, history_at + JKR_HISTORY.separation_limit] == 0.0
    if fresh:
        x_f = (0.25 * c * r_eff) ** (1.0 / 3.0)
        hist[k, history_at + JKR_HISTORY.separation_limit] = 3.0 * x_f ** 4 / r_eff
        hist[k, history_at + JKR_HISTORY.energy_at_separation] = jkr_energy(x_f, r_eff, young, c, w)
        hist[k, history_at + JKR_HISTORY.overlap_before] = 0.0
    x = jkr_root(overlap, r_eff, c, hist[k, history_at + JKR_HISTORY.root_before])
    a = x * x
    force = 4.0 * young * a * a * a / (3.0 * r_eff) - 2.0 * young * c * a * x - normal[NR.force_elastic]
    positive = max(overlap, 0.0)
    hertz_energy = 8.0 / 15.0 * young * math.sqrt(r_eff) * positive * positive * math.sqrt(positive)
    energy = (jkr_energy(x, r_eff, young, c, w) - hist[k, history_at + JKR_HISTORY.energy_at_separation]
              - hertz_energy)
    work = 0.5 * (hist[k, history_at + JKR_HISTORY.force_before] + force) * (
        overlap - hist[k, history_at + JKR_HISTORY.overlap_before])
    dissipation = work - (energy - hist[k, history_at + JKR_HISTORY.energy_before])
    hist[k, history_at + JKR_HISTORY.overlap_before] = overlap
    hist[k, history_at + JKR_HISTORY.force_before] = force
    hist[k, history_at + JKR_HISTORY.energy_before] = energy
    hist[k, history_at + JKR_HISTORY.root_before] = x
    return force, dissipation


def jkr_separation_limit(surface_energy, r_eff, young) -> float:
    """|delta_c| = 3/4 (pi^2 w^2 R* / E*^2)^(1/3) (m): how far apart a JKR contact lasts."""
    return 0.75 * (math.pi ** 2 * surface_energy ** 2 * r_eff / young ** 2) ** (1.0 / 3.0)


class JKR(Cohesion):
    """Johnson-Kendall-Roberts adhesion on the Hertz normal law (docs/models.md §1.6): the full
    force-overlap relation, contacts kept past touching until JKR's separation, pull-off at
    -3/2 pi w R* with w the pair's ``surface_energy`` (J/m^2; the mean of the two materials'
    unless set for the pair). Needs ``normal: hertz``. No parameters of its own."""

    name = "jkr"
    material_properties = (SURFACE_ENERGY,)
    parameters = JKR_PARAMETERS
    history = JKR_HISTORY
    function = staticmethod(jkr_cohesion)
    detach_slot = "separation_limit"

    def pair_values(self, pair):
        return (pair.surface_energy,)

    def coarse_graining_exponents(self):
        return (1,)  # pull-off 3/2 pi w R* ~ alpha^2 with w ~ alpha; a_0 ~ (w R*^2 / E*)^(1/3) ~ alpha

    def surface_energy(self, pair) -> float:
        """w (J/m^2) as the parcels meet it."""
        return self.pair_row(pair)[JKR_PARAMETERS.surface_energy]

    def separation_limit(self, pair, r_eff) -> float:
        return jkr_separation_limit(self.surface_energy(pair), r_eff, pair.effective_youngs_modulus)

    def time_step_limits(self, material, pair, r_min, m_min):
        """The period of small oscillations about the zero-load overlap, T = 2 pi sqrt(m* / k),
        k = dF/d(delta) at a_0 = (9 pi w R*^2 / (2 E*))^(1/3), over 50: the snap-in and the tail
        out to delta_c are then crossed in many steps (a coarser step misjudges the sticking
        velocity by the work of the tail's last step)."""
        w, young, r_eff, m_eff = self.surface_energy(pair), pair.effective_youngs_modulus, 0.5 * r_min, 0.5 * m_min
        if w <= 0.0:
            return []
        a0 = (9.0 * math.pi * w * r_eff ** 2 / (2.0 * young)) ** (1.0 / 3.0)
        force_slope = 4.0 * young * a0 ** 2 / r_eff - 1.5 * math.sqrt(8.0 * math.pi * w * young * a0)
        overlap_slope = 2.0 * a0 / r_eff - 0.5 * math.sqrt(2.0 * math.pi * w / (young * a0))
        period = 2.0 * math.pi * math.sqrt(m_eff * overlap_slope / force_slope)
        return [(f"JKR oscillation period {period:.4g} s at zero load / 50", period / 50.0)]

    def check_normal(self, normal) -> None:
        if normal.name != "hertz":
            raise ParameterError(f"cohesion model 'jkr' with normal model {normal.name!r} is not allowed: "
                                 "JKR's force-overlap relation is built on Hertz; use normal: hertz")


__all__ = ["Cohesion", "NoCohesion", "SJKR", "JKR", "no_cohesion", "sjkr_cohesion", "jkr_cohesion", "contact_area",
           "jkr_root", "jkr_separation_limit"]
