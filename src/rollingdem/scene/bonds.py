"""Bonded particles, the user's side: ``ParallelBond`` holds the parameters of Potyondy & Cundall's
(2004) parallel bond in PFC's ``linearpbond`` form (docs/models.md §1.7) and makes a bond's
parameter row (``records.BOND_PARAMETERS``); ``BondSet`` makes a simulation's bonds
(``Simulation.add_bonds``) and reads them. The bond's law, its compiled update, is
``rollingdem.physics.bonds``.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from rollingdem.errors import (
    Declared,
    ParameterError,
    check_choice,
    check_finite,
    check_non_negative,
    check_positive,
    check_range,
)
from rollingdem.physics.bonds import bond_energy
from rollingdem.physics.records import BOND_PARAMETERS, BOND_STATE
from rollingdem.physics.timestep import SPRING_FRACTION


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

    declared = {
        "youngs_modulus": Declared("the cement's Young's modulus E: k_n = E / (R_i + R_j)", "Pa", low=0.0, low_open=True),
        "stiffness_ratio": Declared("k_n / k_s", "-", low=0.0, low_open=True),
        "radius_multiplier": Declared("the bond's radius over the smaller sphere's", "-", low=0.0, low_open=True),
        "tensile_strength": Declared("tensile strength", "Pa", low=0.0, low_open=True),
        "cohesion": Declared("shear strength without normal stress", "Pa", low=0.0, low_open=True),
        "friction_angle": Declared("friction angle of the shear strength c - (F_n/A) tan phi", "deg", low=0.0,
                                   high=90.0, high_open=True),
        "moment_factor": Declared("the share of the moments in the peak stresses", "-", low=0.0, high=1.0),
        "damping_ratio": Declared("damping ratio of the dashpots beside the bond's springs", "-", low=0.0),
        "contact_while_bonded": Declared("parallel: the contact acts beside the bond (PFC); exclusive: no contact "
                                         "while the bond holds (STAR-CCM+, LAMMPS)", kind="text")}

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


class BondSet:
    """The bonds of a simulation: pairs of engine slots with a parameter row and a state row each;
    ``particles`` (its ``Particles``) numbers the spheres as the user does."""

    def __init__(self, state, particles):
        self.state = state  # the engine state, the same object for the simulation's life
        self.particles = particles

    def add(self, bond, pairs=None, gap=None) -> int:
        """``Simulation.add_bonds``."""
        st = self.state
        if not isinstance(bond, ParallelBond):
            raise ParameterError(f"bond = {bond!r} is not allowed: must be a rollingdem.ParallelBond")
        if (pairs is None) == (gap is None):
            raise ParameterError(f"pairs = {pairs!r}, gap = {gap!r} is not allowed: give exactly one of pairs "
                                 "(particle index pairs) and gap (m)")
        ids = self._pairs_within(check_finite("gap", gap)) if pairs is None else self._pairs_given(pairs)
        if pairs is None and not len(ids) and st.n > 1:
            warnings.warn(f"bonds: gap = {gap:g} m made no bond: no two particles' surfaces are that close (a "
                          "negative gap asks for spheres overlapping by at least -gap); the run goes on unbonded",
                          RuntimeWarning, stacklevel=3)
        slots = st.slots(ids.ravel()).reshape(-1, 2)
        key = np.sort(np.concatenate([st.bond_pairs, slots]), axis=1)
        if len(np.unique(key, axis=0)) < len(key):
            raise ParameterError("pairs: a pair is bonded twice (in the pairs given, or already): each pair takes one "
                                 "bond")
        fixed = st.is_fixed  # a fixed sphere is a partner of infinite mass and inertia
        mass = np.where(fixed, np.inf, st.mass)
        inertia = np.where(fixed, np.inf, st.inertia)
        rows = [bond.parameter_row(st.radius[i], st.radius[j], (mass[i], mass[j]), (inertia[i], inertia[j]))
                for i, j in slots]
        st.add_bonds(slots, np.array(rows).reshape(-1, len(BOND_PARAMETERS)))
        return len(slots)

    def _pairs_within(self, gap: float) -> np.ndarray:
        """Every pair (as the user numbers particles) whose surface gap is at most ``gap``."""
        from scipy.spatial import cKDTree  # deferred: slow to load, used here only

        x, r = self.particles.by_id("x"), self.particles.by_id("radius")
        reach = 2.0 * float(r.max(initial=0.0)) + gap
        found = np.array(sorted(cKDTree(x).query_pairs(reach)) if len(x) > 1 and reach > 0 else [],
                         dtype=np.int64).reshape(-1, 2)
        if len(found):
            surface = np.linalg.norm(x[found[:, 0]] - x[found[:, 1]], axis=1) - r[found[:, 0]] - r[found[:, 1]]
            found = found[surface <= gap]
        return found

    def _pairs_given(self, pairs) -> np.ndarray:
        n = self.state.n
        try:
            ids = np.asarray(pairs)
            ok = ids.ndim == 2 and ids.shape[1] == 2 and (ids.size == 0 or np.issubdtype(ids.dtype, np.integer))
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ParameterError(f"pairs = {pairs!r} is not allowed: must be a list of [i, j] particle index pairs")
        ids = ids.astype(np.int64)
        bad = (ids < 0) | (ids >= n)
        if bad.any():
            raise ParameterError(f"pairs: particle {int(ids[bad][0])} is not allowed: the indices run from 0 to "
                                 f"{n - 1}")
        same = ids[:, 0] == ids[:, 1]
        if same.any():
            raise ParameterError(f"pairs: [{ids[same][0, 0]}, {ids[same][0, 1]}] is not allowed: a bond between "
                                 "a particle and itself")
        return ids

    def table(self):
        """``Simulation.bonds``."""
        import pandas as pd  # deferred: slow to load, tables only

        st = self.state
        ids = st.ids  # slot -> id
        s = st.bond_state
        names = np.array(["intact", "tension", "shear"])
        return pd.DataFrame({
            "i": ids[st.bond_pairs[:, 0]], "j": ids[st.bond_pairs[:, 1]], "status": names[st.bond_status],
            "normal_force": s[:, BOND_STATE.normal_force],
            "shear_force": np.linalg.norm(s[:, [BOND_STATE.shear_x, BOND_STATE.shear_y, BOND_STATE.shear_z]], axis=1),
            "twisting_moment": s[:, BOND_STATE.twisting_moment],
            "bending_moment": np.linalg.norm(s[:, [BOND_STATE.bending_x, BOND_STATE.bending_y, BOND_STATE.bending_z]],
                                             axis=1)})

    def counts(self) -> dict[str, int]:
        """``Simulation.bond_counts``."""
        st = self.state
        if not len(st.bond_pairs):
            return {}
        counts = np.bincount(st.bond_status, minlength=3)
        return {"bonds_intact": int(counts[0]), "bonds_broken_tension": int(counts[1]),
                "bonds_broken_shear": int(counts[2])}

    def energy(self) -> float:
        """``Simulation.bond_energy``."""
        st = self.state
        return float(sum(bond_energy(st.bond_state, b, st.bond_parameters[b]) for b in range(len(st.bond_pairs))
                         if st.bond_status[b] == 0))

    def time_step_limits(self) -> list[tuple[str, float]]:
        """The intact bonds' stiffest mode (docs/models.md §1.7): with K_n, K_s, K_b, K_t its springs,
        omega^2 = K_n (1/m_i + 1/m_j) (axial), K_s (1/m_i + 1/m_j + R_i^2/I_i + R_j^2/I_j) (shear with
        rotation), K_b (1/I_i + 1/I_j) (bending), K_t (1/I_i + 1/I_j) (twisting); a tenth of its period."""
        st = self.state
        live = st.bond_status == 0
        if not live.any():
            return []
        i, j = st.bond_pairs[live, 0], st.bond_pairs[live, 1]
        p = st.bond_parameters[live]
        free = (~st.is_fixed).astype(float)  # a fixed sphere: infinite mass and inertia
        inv_m = free[i] / st.mass[i] + free[j] / st.mass[j]
        inv_i = free[i] / st.inertia[i] + free[j] / st.inertia[j]
        lever = free[i] * st.radius[i] ** 2 / st.inertia[i] + free[j] * st.radius[j] ** 2 / st.inertia[j]
        omega2 = np.max([p[:, BOND_PARAMETERS.normal_stiffness] * inv_m,
                         p[:, BOND_PARAMETERS.shear_stiffness] * (inv_m + lever),
                         p[:, BOND_PARAMETERS.bending_stiffness] * inv_i,
                         p[:, BOND_PARAMETERS.twisting_stiffness] * inv_i])
        per = 2.0 * math.pi / math.sqrt(omega2)
        return [(f"bond period {per:.4g} s / 10", SPRING_FRACTION * per)]
