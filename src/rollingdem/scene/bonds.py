"""Bonded particles, the user's side: ``ParallelBond`` holds the parameters of Potyondy & Cundall's
(2004) parallel bond in PFC's ``linearpbond`` form (docs/models.md §1.7) and makes a bond's
parameter row (``records.BOND_PARAMETERS``); ``Simulation.add_bonds`` makes bonds. The bond's law,
its compiled update, is ``rollingdem.physics.bonds``.
"""

from __future__ import annotations

import math

from rollingdem.errors import ParameterError, check_choice, check_non_negative, check_positive, check_range


class ParallelBond:
    """Potyondy & Cundall's parallel bond, as PFC's ``linearpbond`` (docs/models.md §1.7).

    Parameters
    ----------
    youngs_modulus: E (Pa), > 0, the cement's modulus: k_n = E / L with L = R_i + R_j (PFC's
        ``pb_deformability emod``).
    stiffness_ratio: kappa = k_n / k_s (-), > 0; PFC's ``kratio``. 2.5 (default) is Potyondy &
        Cundall's granite; L^2 / (3 R^2) (4/3 for lambda = 1 and touching equal spheres) makes a
        chain of bonds an Euler-Bernoulli beam.
    radius_multiplier: lambda (-), > 0 (``pb_rmul``): R = lambda min(R_i, R_j).
    tensile_strength: sigma_c (Pa), > 0 (``pb_ten``).
    cohesion: c (Pa), > 0 (``pb_coh``): the shear strength without normal stress.
    friction_angle: phi (degrees), in [0, 90) (``pb_fa``): the shear strength is c - (F_n/A) tan phi.
    moment_factor: beta (-), in [0, 1] (``pb_mcf``): the share of the moments in the peak stresses.
    damping_ratio: zeta (-), >= 0 (default 0, as PFC's bond): dashpots beside the bond's four springs,
        c = 2 zeta sqrt(m* K_n), 2 zeta sqrt(m* K_s), 2 zeta sqrt(I* K_b), 2 zeta sqrt(I* K_t) with
        m* and I* = I_i I_j / (I_i + I_j) the pair's reduced mass and inertia (quasi-static loading).
    contact_while_bonded: "parallel" (default, PFC): the pair's contact acts beside the bond;
        "exclusive" (STAR-CCM+, LAMMPS): no contact while the bond holds, and a fresh one (no
        history: sliding and rolling springs from zero) once it broke.
    """

    def __init__(self, youngs_modulus: float, stiffness_ratio: float = 2.5, radius_multiplier: float = 1.0,
                 tensile_strength: float = 1e6, cohesion: float = 1e6, friction_angle: float = 0.0,
                 moment_factor: float = 1.0, damping_ratio: float = 0.0, contact_while_bonded: str = "parallel"):
        self.youngs_modulus = check_positive("bond youngs_modulus", youngs_modulus, "Pa")
        self.stiffness_ratio = check_positive("bond stiffness_ratio", stiffness_ratio)
        self.radius_multiplier = check_positive("bond radius_multiplier", radius_multiplier)
        self.tensile_strength = check_positive("bond tensile_strength", tensile_strength, "Pa")
        self.cohesion = check_positive("bond cohesion", cohesion, "Pa")
        self.friction_angle = check_non_negative("bond friction_angle", friction_angle, "degrees")
        if self.friction_angle >= 90.0:
            raise ParameterError(f"bond friction_angle = {friction_angle!r} is not allowed: must be in [0, 90) degrees")
        self.moment_factor = check_range("bond moment_factor", moment_factor, 0.0, 1.0)
        self.damping_ratio = check_non_negative("bond damping_ratio", damping_ratio)
        self.contact_while_bonded = check_choice("bond contact_while_bonded", contact_while_bonded,
                                                 ("parallel", "exclusive"))

    def parameter_row(self, radius_i: float, radius_j: float, masses=(math.inf, math.inf),
                      inertias=(math.inf, math.inf)) -> tuple[float, ...]:
        """The ``BOND_PARAMETERS`` of a bond between spheres of these radii (and masses and moments of
        inertia, which the dashpots need): R = lambda min(R_i, R_j), A = pi R^2, I = pi R^4 / 4,
        J = pi R^4 / 2, k_n = E / (R_i + R_j), k_s = k_n / kappa."""
        radius = self.radius_multiplier * min(radius_i, radius_j)
        area = math.pi * radius ** 2
        bending, polar = math.pi * radius ** 4 / 4.0, math.pi * radius ** 4 / 2.0
        kn = self.youngs_modulus / (radius_i + radius_j)
        ks = kn / self.stiffness_ratio
        stiffness = (kn * area, ks * area, kn * bending, ks * polar)
        damping = (0.0,) * 4
        inv_m = 1.0 / masses[0] + 1.0 / masses[1]
        inv_i = 1.0 / inertias[0] + 1.0 / inertias[1]
        if self.damping_ratio > 0.0 and inv_m > 0.0 and inv_i > 0.0:  # (two fixed spheres: nothing to damp)
            m_eff, i_eff = 1.0 / inv_m, 1.0 / inv_i
            damping = tuple(2.0 * self.damping_ratio * math.sqrt(m * k)
                            for m, k in zip((m_eff, m_eff, i_eff, i_eff), stiffness))
        return (*stiffness, area, bending, polar, radius, self.tensile_strength, self.cohesion,
                math.tan(math.radians(self.friction_angle)), self.moment_factor,
                1.0 if self.contact_while_bonded == "exclusive" else 0.0, *damping)

    def settings(self) -> dict:
        return {"youngs_modulus": self.youngs_modulus, "stiffness_ratio": self.stiffness_ratio,
                "radius_multiplier": self.radius_multiplier, "tensile_strength": self.tensile_strength,
                "cohesion": self.cohesion, "friction_angle": self.friction_angle, "moment_factor": self.moment_factor,
                "damping_ratio": self.damping_ratio, "contact_while_bonded": self.contact_while_bonded}

    def __repr__(self):
        return "ParallelBond(" + ", ".join(f"{k}={v!r}" for k, v in self.settings().items()) + ")"
