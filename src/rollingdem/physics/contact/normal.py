"""Normal contact sub-models (docs/models.md §1).

Compiled function of the slot "normal" (arguments: docs/architecture.md; results: docs/models.md §0)::

    normal_force(hist, k, history_at, overlap, normal_velocity, r_eff, m_eff, p, params_at)
        -> (force_elastic, force_damping, normal_stiffness, tangential_stiffness, tangential_damping,
            dissipation)

``hist[k, history_at:]`` is the contact's own declared history (none for the elastic laws, whose
force follows from the overlap and its rate alone). ``dissipation`` is the energy (J) the law lost
in the step besides its dashpot's (whose share the step loop counts, -force_damping v_n dt): the
hysteresis of a plastic law, 0 for an elastic one.
"""

from __future__ import annotations

import math

from numba import njit

from rollingdem.errors import ParameterError, check_choice, check_non_negative, check_positive
from rollingdem.physics.timestep import HERTZ_FRACTION, RAYLEIGH_FRACTION, SPRING_FRACTION, hertz_contact_time, rayleigh_time_step, spring_period
from rollingdem.physics.contact.base import P_SHEAR, P_YOUNG, SubModel, slots
from rollingdem.physics.contact.properties import RESTITUTION


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
    depends on c only. Integrating that equation (tests/physics/test_hertz_damping.py) returns e to 1e-9
    for e in [0.1, 0.99]: the closed form is the exact restitution of this model, not an
    approximation of it.
    """
    return -2.0 * math.sqrt(5.0 / 6.0) * restitution_beta(e)


HERTZ_PARAMETERS = slots("damping_factor", "tangential_damping_ratio")


@njit(cache=True, inline="always")
def hertz_normal(hist, k, history_at, overlap, normal_velocity, r_eff, m_eff, p, params_at):
    """Hertz-Mindlin (no-slip), LIGGGHTS ``normal_model_hertz.h`` / EDEM.

    a = sqrt(R* delta); S_n = 2 E* a; k_n = 4/3 E* a; F_el = k_n delta;
    S_t = 8 G* a; gamma_n = c sqrt(S_n m*); gamma_t = c sqrt(S_t m*) = gamma_n sqrt(4 G*/E*)
    (the last factor is a pair parameter: one square root per contact fewer).
    """
    a = math.sqrt(r_eff * overlap)
    sn = 2.0 * p[P_YOUNG] * a
    kn = (4.0 / 3.0) * p[P_YOUNG] * a
    st = 8.0 * p[P_SHEAR] * a
    gamma_n = p[params_at + HERTZ_PARAMETERS.damping_factor] * math.sqrt(sn * m_eff)
    return (kn * overlap, -gamma_n * normal_velocity, kn, st,
            gamma_n * p[params_at + HERTZ_PARAMETERS.tangential_damping_ratio], 0.0)


@njit(cache=True, inline="always")
def equivalent_stiffness(young, r_eff, m_eff, characteristic_velocity):
    """The linear spring that stores at the Hertz peak overlap of an impact at V_c the energy Hertz
    would: k = 16/15 sqrt(R*) E* [15 m* V_c^2 / (16 sqrt(R*) E*)]^(1/5) (LIGGGHTS
    ``normal_model_hooke.h``; = (16/15)^(4/5) (V_c R* E*^2 sqrt(m*))^(2/5))."""
    sr = math.sqrt(r_eff)
    return (16.0 / 15.0) * sr * young * (15.0 * m_eff * characteristic_velocity * characteristic_velocity
                                         / (16.0 * sr * young)) ** 0.2


HOOKE_PARAMETERS = slots("damping_factor", "characteristic_velocity", "tangential_stiffness_ratio")


@njit(cache=True, inline="always")
def hooke_normal(hist, k, history_at, overlap, normal_velocity, r_eff, m_eff, p, params_at):
    """Hooke with stiffness from a characteristic velocity V_c, LIGGGHTS ``normal_model_hooke.h``.

    k_n = 16/15 sqrt(R*) E* [15 m* V_c^2 / (16 sqrt(R*) E*)]^(1/5)  (= m* V_c^2 / delta_H^2);
    k_t = ratio k_n; gamma_n = 2 zeta sqrt(m* k_n); gamma_t = gamma_n.
    """
    kn = equivalent_stiffness(p[P_YOUNG], r_eff, m_eff, p[params_at + HOOKE_PARAMETERS.characteristic_velocity])
    gamma_n = p[params_at + HOOKE_PARAMETERS.damping_factor] * math.sqrt(m_eff * kn)
    return (kn * overlap, -gamma_n * normal_velocity, kn, p[params_at + HOOKE_PARAMETERS.tangential_stiffness_ratio] * kn,
            gamma_n, 0.0)


LINEAR_PARAMETERS = slots("normal_stiffness", "shear_stiffness", "normal_damping_factor", "shear_damping_factor")


@njit(cache=True, inline="always")
def linear_normal(hist, k, history_at, overlap, normal_velocity, r_eff, m_eff, p, params_at):
    """PFC-style linear contact with given k_n, k_s and dashpots gamma = 2 zeta sqrt(m* k)."""
    kn = p[params_at + LINEAR_PARAMETERS.normal_stiffness]
    ks = p[params_at + LINEAR_PARAMETERS.shear_stiffness]
    gamma_n = p[params_at + LINEAR_PARAMETERS.normal_damping_factor] * math.sqrt(m_eff * kn)
    gamma_t = p[params_at + LINEAR_PARAMETERS.shear_damping_factor] * math.sqrt(m_eff * ks)
    return kn * overlap, -gamma_n * normal_velocity, kn, ks, gamma_t, 0.0


WALTON_BRAUN_PARAMETERS = slots("loading_stiffness", "characteristic_velocity", "unloading_ratio",
                                "tangential_stiffness_ratio", "damping_factor", "reported_stiffness_ratio")
WALTON_BRAUN_HISTORY = slots("force_unclipped", "overlap_before")


@njit(cache=True, inline="always")
def walton_braun_normal(hist, k, history_at, overlap, normal_velocity, r_eff, m_eff, p, params_at):
    """Walton & Braun (1986) hysteretic spring, in incremental form (docs/models.md §1.4).

    F~ <- min(k1 delta, F~ + k2 (delta - delta_before)), F~ = 0 at first touch; F_el = max(0, F~).
    Loading follows k1; unloading and reloading follow k2 = k1 / e^2 from the residual overlap
    delta_0 = delta_max (1 - k1 / k2), back to the k1 line; F~ is kept unclipped, so a reload after
    the overlap fell below delta_0 starts from delta_0, not from where the force was last zero.
    A binary impact rebounds with e = sqrt(k1 / k2) at every speed. k1 is given, or (V_c > 0) the
    Hertz-equivalent spring of ``equivalent_stiffness``. Optional dashpot gamma_n = c sqrt(m* k2);
    k_n = k1 (or k2) for the rolling springs, k_t = ratio k1.
    Hysteresis: the work 1/2 (F_before + F_el) (delta - delta_before) minus the change of the energy
    the k2 line would give back, F^2 / (2 k2); 0 along the k2 line, (1 - k1/k2) k1 delta d(delta)
    along the k1 line.
    """
    vc = p[params_at + WALTON_BRAUN_PARAMETERS.characteristic_velocity]
    k1 = (p[params_at + WALTON_BRAUN_PARAMETERS.loading_stiffness] if vc == 0.0
          else equivalent_stiffness(p[P_YOUNG], r_eff, m_eff, vc))
    k2 = k1 * p[params_at + WALTON_BRAUN_PARAMETERS.unloading_ratio]
    f_before = hist[k, history_at + WALTON_BRAUN_HISTORY.force_unclipped]
    step = overlap - hist[k, history_at + WALTON_BRAUN_HISTORY.overlap_before]
    f = min(k1 * overlap, f_before + k2 * step)
    hist[k, history_at + WALTON_BRAUN_HISTORY.force_unclipped] = f
    hist[k, history_at + WALTON_BRAUN_HISTORY.overlap_before] = overlap
    f_el = max(f, 0.0)
    f_old = max(f_before, 0.0)
    hysteresis = 0.5 * (f_old + f_el) * step - (f_el * f_el - f_old * f_old) / (2.0 * k2)
    gamma_n = p[params_at + WALTON_BRAUN_PARAMETERS.damping_factor] * math.sqrt(m_eff * k2)
    return (f_el, -gamma_n * normal_velocity, k1 * p[params_at + WALTON_BRAUN_PARAMETERS.reported_stiffness_ratio],
            p[params_at + WALTON_BRAUN_PARAMETERS.tangential_stiffness_ratio] * k1, 0.0, hysteresis)


def rayleigh_limit(material, r_min):
    """(description, 0.2 dt_R) of the smallest sphere of a material (docs/models.md §2)."""
    t_r = rayleigh_time_step(r_min, material.density, material.youngs_modulus, material.poisson_ratio)
    return (f"{RAYLEIGH_FRACTION:g} x Rayleigh time {t_r:.4g} s of material {material.name!r} "
            f"(R_min = {r_min:.4g} m)", RAYLEIGH_FRACTION * t_r)


def spring_limits(normal_stiffness, tangential_stiffness, m_eff):
    """(description, period / 10) of the normal and the tangential linear spring."""
    limits = []
    for label, stiff in (("normal", normal_stiffness), ("tangential", tangential_stiffness)):
        per = spring_period(stiff, m_eff)
        limits.append((f"{label} spring period {per:.4g} s / 10", SPRING_FRACTION * per))
    return limits


class NormalModel(SubModel):
    """A normal contact law. Besides its compiled function it reports, for the time-step check of a
    material pair (docs/models.md §2), its stiffness and the limits it imposes; the contact of two
    of the smallest spheres (R* = R_min / 2, m* = m_min / 2) is the stiffest."""

    slot = "normal"
    material_properties = (RESTITUTION,)

    def reference_stiffness(self, pair, r_eff, m_eff, r_min) -> tuple[float, float, float]:
        """(k_n, k_t, overlap): the law's stiffnesses at a representative large overlap, at which
        the rotational springs are checked too."""
        raise NotImplementedError

    def time_step_limits(self, material, pair, r_min, m_min, impact_speed) -> list[tuple[str, float]]:
        """(description, largest allowed dt) of each criterion of the law, for the smallest spheres of
        ``material`` (radius r_min, mass m_min) at ``impact_speed``: by default those of linear springs."""
        m_eff = 0.5 * m_min
        kn, kt, _ = self.reference_stiffness(pair, 0.5 * r_min, m_eff, r_min)
        return spring_limits(kn, kt, m_eff)


class Hertz(NormalModel):
    """Hertz-Mindlin no-slip contact (docs/models.md §1.2), with the dashpot gamma_n = c sqrt(S_n m*)
    whose factor c (``hertz_damping_factor``) gives a binary impact exactly the pair's restitution
    e, as in LIGGGHTS and EDEM. No parameters of its own."""

    name = "hertz"
    parameters = HERTZ_PARAMETERS
    function = staticmethod(hertz_normal)

    def pair_values(self, pair):
        return (hertz_damping_factor(pair.restitution),
                math.sqrt(4.0 * pair.effective_shear_modulus / pair.effective_youngs_modulus))

    def coarse_graining_exponents(self):
        return (0, 0)  # with the same E and G, F ∝ E* sqrt(R*) delta^1.5 scales as alpha^2 by itself

    def reference_stiffness(self, pair, r_eff, m_eff, r_min):
        # 1 % of R_min: the Hertz stiffnesses grow as sqrt(overlap), and are larger there than in
        # any sane packing
        overlap = 0.01 * r_min
        a = math.sqrt(r_eff * overlap)
        return 4.0 / 3.0 * pair.effective_youngs_modulus * a, 8.0 * pair.effective_shear_modulus * a, overlap

    def time_step_limits(self, material, pair, r_min, m_min, impact_speed):
        limits = [rayleigh_limit(material, r_min)]
        if impact_speed > 0:
            t_h = hertz_contact_time(0.5 * m_min, 0.5 * r_min, pair.effective_youngs_modulus, impact_speed)
            limits.append((f"Hertz time {t_h:.4g} s / 20 at impact speed {impact_speed:.3g} m/s",
                           HERTZ_FRACTION * t_h))
        return limits


class Hooke(NormalModel):
    """Linear spring-dashpot with LIGGGHTS's stiffness from a characteristic velocity (docs/models.md §1.3).

    Parameters
    ----------
    characteristic_velocity: V_c (m/s), > 0; the spring stores at the Hertz peak overlap of an
        impact at V_c the energy Hertz would.
    tangential_stiffness_ratio: k_t / k_n (-); 1 is LIGGGHTS's default, 2/7 its ``ktToKnUser on``.
    """

    name = "hooke"
    parameters = HOOKE_PARAMETERS
    function = staticmethod(hooke_normal)

    def __init__(self, characteristic_velocity: float = 1.0, tangential_stiffness_ratio: float = 1.0):
        self.characteristic_velocity = check_positive("hooke characteristic_velocity",
                                                      characteristic_velocity, "m/s")
        self.tangential_stiffness_ratio = check_positive("hooke tangential_stiffness_ratio",
                                                         tangential_stiffness_ratio)

    def pair_values(self, pair):
        return (2.0 * linear_damping_ratio(pair.restitution), self.characteristic_velocity,
                self.tangential_stiffness_ratio)

    def coarse_graining_exponents(self):
        return (0, 0, 0)  # k from E*, R*, m* and V_c scales as alpha by itself

    def settings(self):
        return {"characteristic_velocity": self.characteristic_velocity,
                "tangential_stiffness_ratio": self.tangential_stiffness_ratio}

    def reference_stiffness(self, pair, r_eff, m_eff, r_min):
        kn = equivalent_stiffness(pair.effective_youngs_modulus, r_eff, m_eff, self.characteristic_velocity)
        return kn, self.tangential_stiffness_ratio * kn, math.sqrt(m_eff / kn)  # peak overlap at 1 m/s

    def time_step_limits(self, material, pair, r_min, m_min, impact_speed):
        return [rayleigh_limit(material, r_min)] + super().time_step_limits(material, pair, r_min, m_min,
                                                                             impact_speed)


class Linear(NormalModel):
    """PFC-style linear contact with given normal and shear stiffness (docs/models.md §5).

    Parameters
    ----------
    normal_stiffness: k_n (N/m), > 0.
    shear_stiffness: k_s (N/m), > 0.
    normal_damping_ratio: zeta_n (-), PFC ``dp_nratio``; default: from the pair's restitution e.
    shear_damping_ratio: zeta_s (-), PFC ``dp_sratio``; default 0 as in PFC.
    """

    name = "linear"
    parameters = LINEAR_PARAMETERS
    function = staticmethod(linear_normal)

    def __init__(self, normal_stiffness: float = 1e5, shear_stiffness: float | None = None,
                 normal_damping_ratio: float | None = None, shear_damping_ratio: float = 0.0):
        self.normal_stiffness = check_positive("linear normal_stiffness", normal_stiffness, "N/m")
        self.shear_stiffness = (self.normal_stiffness if shear_stiffness is None
                                else check_positive("linear shear_stiffness", shear_stiffness, "N/m"))
        self.normal_damping_ratio = (None if normal_damping_ratio is None
                                     else check_non_negative("linear normal_damping_ratio", normal_damping_ratio))
        self.shear_damping_ratio = check_non_negative("linear shear_damping_ratio", shear_damping_ratio)

    def pair_values(self, pair):
        zn = linear_damping_ratio(pair.restitution) if self.normal_damping_ratio is None else self.normal_damping_ratio
        return (self.normal_stiffness, self.shear_stiffness, 2.0 * zn, 2.0 * self.shear_damping_ratio)

    def coarse_graining_exponents(self):
        return (1, 1, 0, 0)

    def settings(self):
        return {"normal_stiffness": self.normal_stiffness, "shear_stiffness": self.shear_stiffness,
                "normal_damping_ratio": self.normal_damping_ratio, "shear_damping_ratio": self.shear_damping_ratio}

    def reference_stiffness(self, pair, r_eff, m_eff, r_min):
        kn, ks = self.pair_row(pair)[:2]  # as the parcels meet them
        return kn, ks, math.sqrt(m_eff / kn)


class WaltonBraun(NormalModel):
    """Walton & Braun's (1986) hysteretic ("partially latching") spring (docs/models.md §1.4):
    loading stiffness k1, unloading and reloading k2 = k1 / e^2 with the pair's restitution e, so
    that a binary impact rebounds with e whatever its speed; no dashpot by default.

    Parameters
    ----------
    loading_stiffness: k1 (N/m), > 0; 1e5 when neither it nor ``characteristic_velocity`` is given.
    characteristic_velocity: V_c (m/s), > 0, instead of ``loading_stiffness``: k1 per contact is
        the Hertz-equivalent spring at V_c (as ``hooke``), from E*, R* and m*.
    tangential_stiffness_ratio: k_t / k1 (-), > 0; the tangential spring's (initial) stiffness.
    damping_ratio: zeta (-), >= 0, of an optional dashpot 2 zeta sqrt(m* k2) that damps the
        oscillations of enduring contacts along the elastic k2 line; with zeta > 0 an impact's
        restitution falls below e.
    kn_source: "loading" (k1, default) or "unloading" (k2): the stiffness k_n the rolling springs
        take (EPSD's k_r = 2.25 k_n mu_r^2 R*^2).
    """

    name = "walton_braun"
    parameters = WALTON_BRAUN_PARAMETERS
    history = WALTON_BRAUN_HISTORY
    function = staticmethod(walton_braun_normal)
    DEFAULT_LOADING_STIFFNESS = 1e5

    def __init__(self, loading_stiffness: float | None = None, characteristic_velocity: float | None = None,
                 tangential_stiffness_ratio: float = 1.0, damping_ratio: float = 0.0, kn_source: str = "loading"):
        if loading_stiffness is not None and characteristic_velocity is not None:
            raise ParameterError(f"walton_braun characteristic_velocity = {characteristic_velocity!r} is not "
                                 f"allowed together with loading_stiffness = {loading_stiffness!r}: give one of them")
        self.loading_stiffness = (None if loading_stiffness is None
                                  else check_positive("walton_braun loading_stiffness", loading_stiffness, "N/m"))
        self.characteristic_velocity = (None if characteristic_velocity is None
                                        else check_positive("walton_braun characteristic_velocity",
                                                            characteristic_velocity, "m/s"))
        self.tangential_stiffness_ratio = check_positive("walton_braun tangential_stiffness_ratio",
                                                         tangential_stiffness_ratio)
        self.damping_ratio = check_non_negative("walton_braun damping_ratio", damping_ratio)
        self.kn_source = check_choice("walton_braun kn_source", kn_source, ("loading", "unloading"))

    @property
    def k1(self) -> float | None:
        """The given loading stiffness (N/m); None when it follows from ``characteristic_velocity``."""
        if self.characteristic_velocity is not None:
            return None
        return self.DEFAULT_LOADING_STIFFNESS if self.loading_stiffness is None else self.loading_stiffness

    def pair_values(self, pair):
        ratio = 1.0 / pair.restitution ** 2
        return (self.k1 or 0.0, self.characteristic_velocity or 0.0, ratio, self.tangential_stiffness_ratio,
                2.0 * self.damping_ratio, ratio if self.kn_source == "unloading" else 1.0)

    def coarse_graining_exponents(self):
        return (1, 0, 0, 0, 0, 0)

    def settings(self):
        return {"loading_stiffness": self.loading_stiffness, "characteristic_velocity": self.characteristic_velocity,
                "tangential_stiffness_ratio": self.tangential_stiffness_ratio, "damping_ratio": self.damping_ratio,
                "kn_source": self.kn_source}

    def loading_stiffness_of(self, pair, r_eff, m_eff) -> float:
        """k1 (N/m) of a contact of effective radius r_eff and mass m_eff."""
        if self.characteristic_velocity is None:
            return self.pair_row(pair)[WALTON_BRAUN_PARAMETERS.loading_stiffness]  # as the parcels meet it
        return equivalent_stiffness(pair.effective_youngs_modulus, r_eff, m_eff, self.characteristic_velocity)

    def reference_stiffness(self, pair, r_eff, m_eff, r_min):
        k1 = self.loading_stiffness_of(pair, r_eff, m_eff)
        kn = k1 / pair.restitution ** 2 if self.kn_source == "unloading" else k1
        return kn, self.tangential_stiffness_ratio * k1, math.sqrt(m_eff / k1)  # peak overlap at 1 m/s

    def time_step_limits(self, material, pair, r_min, m_min, impact_speed):
        # the unloading line is the stiffest: k2 = k1 / e^2
        m_eff = 0.5 * m_min
        k1 = self.loading_stiffness_of(pair, 0.5 * r_min, m_eff)
        return spring_limits(k1 / pair.restitution ** 2, self.tangential_stiffness_ratio * k1, m_eff)


__all__ = ["NormalModel", "Hertz", "Hooke", "Linear", "WaltonBraun", "walton_braun_normal", "equivalent_stiffness", "hertz_normal", "hooke_normal", "linear_normal", "hertz_damping_factor",
           "restitution_beta", "linear_damping_ratio"]
