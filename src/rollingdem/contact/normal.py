"""Normal contact sub-models (docs/models.md §1).

Kernel signature (slot "normal")::

    normal_force(overlap, normal_velocity, r_eff, m_eff, p, off)
        -> (force_elastic, force_damping, normal_stiffness, tangential_stiffness, tangential_damping)

``normal_velocity`` is v_n = (v_i - v_j) . n (negative while approaching); the scalar normal
force on i along n is force_elastic + force_damping, with force_damping = -gamma_n v_n.
``normal_stiffness`` is the secant stiffness k_n = F_el / delta that rolling models reuse.
"""

from __future__ import annotations

import math

from numba import njit

from ..errors import check_non_negative, check_positive
from .base import P_SHEAR, P_YOUNG, SubModel


def restitution_beta(e: float) -> float:
    """beta = ln e / sqrt(ln^2 e + pi^2) (docs/models.md §1.1); negative for e < 1, zero for e = 1."""
    if e >= 1.0:
        return 0.0
    le = math.log(e)
    return le / math.sqrt(le * le + math.pi * math.pi)


def linear_damping_ratio(e: float) -> float:
    """Critical damping ratio zeta of a linear spring-dashpot with restitution e: e = exp(-pi zeta / sqrt(1 - zeta^2))."""
    return -restitution_beta(e)


def hertz_damping_factor(e: float) -> float:
    """The factor c in gamma_n = c sqrt(S_n m*), S_n = 2 E* sqrt(R* delta), that gives a binary
    Hertz impact the restitution e: c = -2 sqrt(5/6) beta(e) (Tsuji et al. 1992; LIGGGHTS
    ``normal_model_hertz.h``, EDEM).

    With this dashpot the impact, in units delta0 = (m* v0^2 / k)^(2/5), t0 = delta0 / v0
    (k = 4/3 E* sqrt(R*)), obeys x'' = -x^(3/2) - sqrt(3/2) c x^(1/4) x' whatever v0 is, so e
    depends on c only. Integrating that equation (tests/test_hertz_damping.py) returns e to 1e-9
    for e in [0.1, 0.99]: the closed form is the exact restitution of this model, not an
    approximation of it.
    """
    return -2.0 * math.sqrt(5.0 / 6.0) * restitution_beta(e)


@njit(cache=True, inline="always")
def hertz_normal(overlap, normal_velocity, r_eff, m_eff, p, off):
    """Hertz-Mindlin (no-slip), LIGGGHTS ``normal_model_hertz.h`` / EDEM.

    a = sqrt(R* delta); S_n = 2 E* a; k_n = 4/3 E* a; F_el = k_n delta;
    S_t = 8 G* a; gamma_n = c sqrt(S_n m*); gamma_t = c sqrt(S_t m*) = gamma_n sqrt(4 G*/E*)
    (the last factor is a pair parameter: one square root per contact fewer).
    """
    a = math.sqrt(r_eff * overlap)
    sn = 2.0 * p[P_YOUNG] * a
    kn = (4.0 / 3.0) * p[P_YOUNG] * a
    st = 8.0 * p[P_SHEAR] * a
    gamma_n = p[off] * math.sqrt(sn * m_eff)
    return kn * overlap, -gamma_n * normal_velocity, kn, st, gamma_n * p[off + 1]


@njit(cache=True, inline="always")
def hooke_normal(overlap, normal_velocity, r_eff, m_eff, p, off):
    """Hooke with stiffness from a characteristic velocity V_c, LIGGGHTS ``normal_model_hooke.h``.

    k_n = 16/15 sqrt(R*) E* [15 m* V_c^2 / (16 sqrt(R*) E*)]^(1/5)  (= m* V_c^2 / delta_H^2);
    k_t = ratio k_n; gamma_n = 2 zeta sqrt(m* k_n); gamma_t = gamma_n.
    """
    young = p[P_YOUNG]
    sr = math.sqrt(r_eff)
    vc = p[off + 1]
    kn = (16.0 / 15.0) * sr * young * (15.0 * m_eff * vc * vc / (16.0 * sr * young)) ** 0.2
    gamma_n = p[off] * math.sqrt(m_eff * kn)
    return kn * overlap, -gamma_n * normal_velocity, kn, p[off + 2] * kn, gamma_n


@njit(cache=True, inline="always")
def linear_normal(overlap, normal_velocity, r_eff, m_eff, p, off):
    """PFC-style linear contact with given k_n, k_s and dashpots gamma = 2 zeta sqrt(m* k)."""
    kn = p[off]
    ks = p[off + 1]
    gamma_n = p[off + 2] * math.sqrt(m_eff * kn)
    gamma_t = p[off + 3] * math.sqrt(m_eff * ks)
    return kn * overlap, -gamma_n * normal_velocity, kn, ks, gamma_t


class Hertz(SubModel):
    """Hertz-Mindlin no-slip contact (docs/models.md §1.2), with the dashpot gamma_n = c sqrt(S_n m*)
    whose factor c (``hertz_damping_factor``) gives a binary impact exactly the pair's restitution
    e, as in LIGGGHTS and EDEM. No parameters of its own."""

    slot = "normal"
    name = "hertz"
    kernel = ("rollingdem.contact.normal", "hertz_normal")

    def pair_parameters(self, pair):
        return (hertz_damping_factor(pair.restitution),
                math.sqrt(4.0 * pair.effective_shear_modulus / pair.effective_youngs_modulus))


class Hooke(SubModel):
    """Linear spring-dashpot with LIGGGHTS's stiffness from a characteristic velocity (docs/models.md §1.3).

    Parameters
    ----------
    characteristic_velocity: V_c (m/s), > 0; the spring stores at the Hertz peak overlap of an
        impact at V_c the energy Hertz would.
    tangential_stiffness_ratio: k_t / k_n (-); 1 is LIGGGHTS's default, 2/7 its ``ktToKnUser on``.
    """

    slot = "normal"
    name = "hooke"
    kernel = ("rollingdem.contact.normal", "hooke_normal")

    def __init__(self, characteristic_velocity: float = 1.0, tangential_stiffness_ratio: float = 1.0):
        self.characteristic_velocity = check_positive("hooke characteristic_velocity",
                                                      characteristic_velocity, "m/s")
        self.tangential_stiffness_ratio = check_positive("hooke tangential_stiffness_ratio",
                                                         tangential_stiffness_ratio)

    def pair_parameters(self, pair):
        return (2.0 * linear_damping_ratio(pair.restitution), self.characteristic_velocity,
                self.tangential_stiffness_ratio)

    def parameters(self):
        return {"characteristic_velocity": self.characteristic_velocity,
                "tangential_stiffness_ratio": self.tangential_stiffness_ratio}


class Linear(SubModel):
    """PFC-style linear contact with given normal and shear stiffness (docs/models.md §5).

    Parameters
    ----------
    normal_stiffness: k_n (N/m), > 0.
    shear_stiffness: k_s (N/m), > 0.
    normal_damping_ratio: zeta_n (-), PFC ``dp_nratio``; default: from the pair's restitution e.
    shear_damping_ratio: zeta_s (-), PFC ``dp_sratio``; default 0 as in PFC.
    """

    slot = "normal"
    name = "linear"
    kernel = ("rollingdem.contact.normal", "linear_normal")

    def __init__(self, normal_stiffness: float = 1e5, shear_stiffness: float | None = None,
                 normal_damping_ratio: float | None = None, shear_damping_ratio: float = 0.0):
        self.normal_stiffness = check_positive("linear normal_stiffness", normal_stiffness, "N/m")
        self.shear_stiffness = (self.normal_stiffness if shear_stiffness is None
                                else check_positive("linear shear_stiffness", shear_stiffness, "N/m"))
        self.normal_damping_ratio = (None if normal_damping_ratio is None
                                     else check_non_negative("linear normal_damping_ratio", normal_damping_ratio))
        self.shear_damping_ratio = check_non_negative("linear shear_damping_ratio", shear_damping_ratio)

    def pair_parameters(self, pair):
        zn = linear_damping_ratio(pair.restitution) if self.normal_damping_ratio is None else self.normal_damping_ratio
        return (self.normal_stiffness, self.shear_stiffness, 2.0 * zn, 2.0 * self.shear_damping_ratio)

    def parameters(self):
        return {"normal_stiffness": self.normal_stiffness, "shear_stiffness": self.shear_stiffness,
                "normal_damping_ratio": self.normal_damping_ratio, "shear_damping_ratio": self.shear_damping_ratio}


__all__ = ["Hertz", "Hooke", "Linear", "hertz_normal", "hooke_normal", "linear_normal", "hertz_damping_factor",
           "restitution_beta", "linear_damping_ratio"]
