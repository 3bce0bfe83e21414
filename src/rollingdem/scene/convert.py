"""Parameter conversion from other DEM codes' rolling-resistance conventions (docs/models.md §12).

One function per code: it takes the parameters as the other code's input file names them and
returns a :class:`RollingParameters`, the rollingdem rolling sub-model and the material
coefficients (mu_r, eta_r) that give the same moment law. The conventions, the table of codes and
what ``parity`` selects: docs/models.md §12, "Parameters from other codes"."""

from __future__ import annotations

from dataclasses import dataclass

from rollingdem.physics.contact.base import SubModel
from rollingdem.physics.contact.rolling import CDT, EPSD, EPSD2, EPSD3, SDS, RRLinear
from rollingdem.errors import ParameterError, check_non_negative, check_positive


@dataclass(frozen=True)
class RollingParameters:
    """A rolling sub-model and the material coefficients that go with it."""

    model: SubModel
    rolling_friction: float
    rolling_damping: float = 0.0

    def material_kwargs(self) -> dict:
        """Keyword arguments for :class:`rollingdem.Material`."""
        return {"rolling_friction": self.rolling_friction, "rolling_damping": self.rolling_damping}


def from_liggghts(model: str, rolling_friction: float, rolling_viscous_damping: float = 0.0,
                  rolling_stiffness_coefficient: float = 2.25, parity: bool = True) -> RollingParameters:
    """LIGGGHTS 3.8 ``rolling_friction cdt|epsd|epsd2|epsd3`` (docs/models.md §3).

    rolling_friction: ``coefficientRollingFriction`` (mu_r, M_m = mu_r R* F_n, the same convention).
    rolling_viscous_damping: ``coefficientRollingViscousDamping`` (eta_r; epsd and epsd3 only).
    rolling_stiffness_coefficient: ``coeffRollingStiffness`` c of epsd3 (k_r = c k_n mu_r^2 R*^2).
    """
    mu_r = check_non_negative("liggghts coefficientRollingFriction", rolling_friction)
    eta_r = check_non_negative("liggghts coefficientRollingViscousDamping", rolling_viscous_damping)
    preset = "liggghts" if parity else None
    if model == "cdt":
        return RollingParameters(CDT(parity=preset), mu_r)
    if model == "epsd":
        return RollingParameters(EPSD(parity=preset), mu_r, eta_r)
    if model == "epsd2":
        return RollingParameters(EPSD2(parity=preset), mu_r)
    if model == "epsd3":
        return RollingParameters(EPSD3(rolling_stiffness_coefficient, parity=preset), mu_r, eta_r)
    raise ParameterError(f"liggghts rolling model = {model!r} is not known: allowed are "
                         "'cdt', 'epsd', 'epsd2', 'epsd3'")


def from_lammps_sds(k_roll: float, gamma_roll: float, mu_roll: float, parity: bool = True) -> RollingParameters:
    """LAMMPS ``pair_style granular ... rolling sds k_roll gamma_roll mu_roll`` (docs/models.md §4):
    torque stiffness k_roll R*^2, torque damping gamma_roll R*^2, limit mu_roll R* |F_n|."""
    mu_r = check_non_negative("lammps mu_roll", mu_roll)
    return RollingParameters(SDS(k_roll, gamma_roll, parity="lammps" if parity else None), mu_r)


def from_mercury(rolling_stiffness: float, rolling_dissipation: float, rolling_friction: float,
                 parity: bool = True) -> RollingParameters:
    """MercuryDPM ``FrictionSpecies`` rolling (Luding 2008; docs/models.md §7.2).

    Mercury applies a pseudo-force k xi + eta v_r at the lever d_eff = 2 R*, with v_r = d_eff (dw x n)
    and |f_r| <= mu |F_n|. In torque form: stiffness 4 k R*^2, damping 4 eta R*^2 and limit
    2 mu R* |F_n|, i.e. SDS(4 k, 4 eta) with mu_r = 2 mu. Its translation-corrected history is a
    first-order projection: LAMMPS's project-and-rescale is the parity preset.
    """
    k = check_positive("mercury rollingStiffness", rolling_stiffness, "N/m")
    eta = check_non_negative("mercury rollingDissipation", rolling_dissipation, "N s/m")
    mu = check_non_negative("mercury rollingFrictionCoefficient", rolling_friction)
    return RollingParameters(SDS(4.0 * k, 4.0 * eta, parity="lammps" if parity else None), 2.0 * mu)


def from_pfc_rrlinear(rr_fric: float, parity: bool = True) -> RollingParameters:
    """Itasca PFC ``rrlinear`` (docs/models.md §5): k_r = k_s R-bar^2, 1/R-bar = 1/R_1 + 1/R_2 (= R*),
    |M| <= rr_fric R-bar F_n,linear. Use it with :class:`rollingdem.Linear` (kn, ks as in PFC)."""
    mu_r = check_non_negative("pfc rr_fric", rr_fric)
    return RollingParameters(RRLinear(parity="pfc" if parity else None), mu_r)


def from_yade_cohfrict(alpha_kr: float, eta_roll: float, shear_stiffness: float, radius_1: float,
                       radius_2: float) -> RollingParameters:
    """Yade ``CohFrictMat`` with ``Law2_ScGeom6D_CohFrictPhys_CohesionMoment`` (incremental form;
    docs/models.md §8.1): k_r = alphaKr k_s R_1 R_2, |M| <= min(etaRoll R_1, etaRoll R_2) F_n,el.

    Yade's rolling stiffness uses R_1 R_2 where rollingdem uses R*^2, and its limit the smaller
    radius where rollingdem uses R*; both are exact for the given pair of radii (for a monodisperse
    packing, R_1 = R_2 = R: k_roll = 4 alphaKr k_s and mu_r = 2 etaRoll). k_s is Yade's constant
    shear stiffness (N/m), so the returned model is SDS (given torque stiffness), without damping.
    """
    alpha = check_positive("yade alphaKr", alpha_kr)
    eta = check_non_negative("yade etaRoll", eta_roll)
    ks = check_positive("yade shear stiffness k_s", shear_stiffness, "N/m")
    r1 = check_positive("yade radius_1", radius_1, "m")
    r2 = check_positive("yade radius_2", radius_2, "m")
    r_eff = r1 * r2 / (r1 + r2)
    return RollingParameters(SDS(alpha * ks * r1 * r2 / r_eff ** 2), eta * min(r1, r2) / r_eff)


def lammps_sds_equivalent_of_epsd2(tangential_stiffness: float) -> float:
    """k_roll (N/m) of LAMMPS ``rolling sds`` that equals EPSD2 / PFC rrlinear for a constant
    tangential stiffness k_t: k_r = k_roll R*^2 = k_t R*^2, so k_roll = k_t (docs/models.md §13 T6(f))."""
    return check_positive("tangential_stiffness", tangential_stiffness, "N/m")
