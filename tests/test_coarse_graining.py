"""Coarse graining (docs/models.md §18): parcels alpha times the real particle's size.

The rule is stress similarity: lengths scale as alpha, times as alpha (at kept velocities),
masses as alpha^3, forces as alpha^2, moments and energies as alpha^3, spins as 1/alpha. Under it
the equations of motion of a contact are the same equations, so a parcel contact run at dt alpha is
the real contact to round-off, step by step. With alpha = 2 every scaling is a power of two, exact
in floating point; the only inexact steps are the fractional powers some laws take (Hooke's 1/5,
Walton's exponent), a few ulps each, so ``RT = 1e-9`` over some dozen steps is the round-off
allowance. A wrong exponent in a sub-model's rule is a factor 2 (or more) in its force or moment,
nine orders of magnitude above it.
"""

import math

import numpy as np
import pytest

import rollingdem as rd
from rollingdem.physics.contact.frame import contact_frame
from rollingdem.physics.contact.base import _REGISTRIES
from rollingdem.physics.records import contact_inputs

ALPHA = 2.0
RT = 1e-9

REAL = dict(youngs_modulus=5e7, poisson_ratio=0.3, density=2500.0, friction=0.4, rolling_friction=0.2,
            restitution=0.6, rolling_damping=0.3, surface_energy=0.05, cohesion_energy_density=2e4)

# Every built-in sub-model, and every parameter of one given (a given stiffness, damping or length
# is what needs a rule), in chains of the five slots.
CHAINS = {
    "hertz-epsd-marshall-jkr": dict(normal="hertz", rolling="epsd", twisting="marshall", cohesion="jkr"),
    "hooke-walton-sds-sds-sjkr": dict(
        normal=rd.Hooke(characteristic_velocity=1.3, tangential_stiffness_ratio=2 / 7), tangential="walton",
        rolling=rd.SDS(rolling_stiffness=3e3, rolling_damping=0.05),
        twisting=rd.TwistingSDS(2e-5, 1e-7, 1e-4), cohesion="sjkr"),
    "linear-viscous-zhou": dict(normal=rd.Linear(3e4, 1e4, normal_damping_ratio=0.3, shear_damping_ratio=0.2),
                                rolling=rd.Viscous(coefficient=2e-3)),
    "walton_braun-cdt": dict(normal=rd.WaltonBraun(loading_stiffness=4e4, damping_ratio=0.1),
                             rolling=rd.CDT(limiter=0.08)),
    "walton_braun-vc-viscous-kratos": dict(normal=rd.WaltonBraun(characteristic_velocity=1.0),
                                           tangential="walton", rolling=rd.Viscous(coefficient=0.5, form="kratos")),
    "hertz-epsd2": dict(normal="hertz", rolling="epsd2"),
    "hertz-epsd3": dict(normal="hertz", rolling=rd.EPSD3(stiffness_coefficient=1.7)),
    "linear-rrlinear": dict(normal=rd.Linear(3e4, 1e4), rolling="rrlinear"),
    "hertz-displacement_damping": dict(normal="hertz", rolling=rd.DisplacementDamping(theta_max=0.035,
                                                                                       damping=0.3)),
    "hertz-force_proportional": dict(normal="hertz", rolling="force_proportional"),
    "hooke-no-rolling": dict(normal="hooke"),
    "hertz-epsd-liggghts": dict(normal="hertz", rolling=rd.EPSD(parity="liggghts")),
    "hertz-sds-lammps": dict(normal="hertz", rolling=rd.SDS(rolling_stiffness=3e3, rolling_damping=0.05,
                                                             parity="lammps")),
}


def chain_run(model: rd.ContactModel, alpha: float, steps: int = 40) -> np.ndarray:
    """The five sub-models chained as the step loop chains them (``engine/template/contact.py``), on a
    contact of two spheres of radius alpha x 1 mm driven through loading and unloading with slip,
    rolling and twist, at dt = alpha x 1 us; each step's force components and moments (on i and
    j) and dissipated energies, by row."""
    table = rd.MaterialTable()
    table.add(rd.Material("m", **REAL, coarse_graining=alpha))
    p = model.pair_table(table.pairs())[0, 0]
    at = model.layout()
    hist = np.zeros((1, model.history_size))
    radius, mass = alpha * 1e-3, alpha ** 3 * 2500.0 * 4 / 3 * math.pi * 1e-9
    r_eff, m_eff, dt = radius / 2, mass / 2, alpha * 1e-6
    inertia_r = 0.4 * mass * radius ** 2 / 2
    n = (0.0, 0.0, 1.0)
    frame = contact_frame(*n, *n, 0.0)
    slip = (0.05, -0.02, 0.0)  # m/s, kept
    out = []
    for s in range(steps):
        vn = -0.3 if s < steps // 2 else 0.25  # approaching, then receding (m/s, kept)
        overlap = alpha * 1e-6 * (1.0 + 0.3 * min(s, steps // 2) - 0.25 * max(s - steps // 2, 0))
        wi = np.array([30.0, -10.0, 40.0]) / alpha  # spins scale as 1/alpha at kept velocities
        wj = np.array([-5.0, 20.0, -15.0]) / alpha
        lever = radius - overlap / 2
        g = contact_inputs(n, overlap=overlap, relative_velocity=(slip[0], slip[1], vn), omega_i=wi, omega_j=wj,
                           lever_i=lever, lever_j=lever, r_eff=r_eff, m_eff=m_eff, inertia_r=inertia_r)
        f_el, f_damp, kn, kt, gamma_t, e_n = type(model.normal).function(hist, 0, at["NORMAL_HISTORY"], overlap, vn,
                                                                         r_eff, m_eff, p, at["NORMAL_PARAMS"])
        normal = (f_el, f_el + f_damp, kn, kt, gamma_t)
        f_coh, e_coh = type(model.cohesion).function(hist, 0, at["COHESION_HISTORY"], g, normal, p,
                                                     at["COHESION_PARAMS"])
        ft = type(model.tangential).function(hist, 0, at["TANGENTIAL_HISTORY"], g, frame, slip, normal, dt, p,
                                             at["TANGENTIAL_PARAMS"])
        moment = type(model.rolling).function(hist, 0, at["ROLLING_HISTORY"], g, frame, normal, dt, p,
                                              at["ROLLING_PARAMS"], model.rolling.kernel_modes())
        twist = type(model.twisting).function(hist, 0, at["TWISTING_HISTORY"], g, normal, dt, p, at["TWISTING_PARAMS"])
        forces = [f_el, f_damp, f_coh, *ft[:3]]
        moments = [*moment[:6], twist[0]]
        energies = [e_n, e_coh, ft[3], moment[6], twist[1]]
        out.append(np.array([*(f / alpha ** 2 for f in forces), *(m / alpha ** 3 for m in moments),
                             *(e / alpha ** 3 for e in energies)]))
    return np.array(out)


@pytest.mark.parametrize("chain", list(CHAINS))
def test_a_parcel_contact_is_the_real_contact_scaled(chain):
    """Forces / alpha^2, moments and energies / alpha^3 of the parcel contact equal the real one's,
    step by step, for every built-in sub-model (module docstring: the tolerance). Catches any wrong
    exponent in a rule (e.g. SDS's k_roll scaled as alpha^3, JKR's w left unscaled, TwistingSDS's
    mu_tw unscaled), and a rule applied where the law scales by itself (Hertz or EPSD scaled again)."""
    model = rd.ContactModel(**CHAINS[chain])
    real, parcel = chain_run(model, 1.0), chain_run(model, ALPHA)
    scale = np.abs(real).max(axis=0) + 1e-300
    assert (np.abs(real[:, :3]).max(axis=0)[0] > 0) and np.abs(real[:, 3:6]).max() > 0  # a loaded, slipping contact
    np.testing.assert_allclose(parcel / scale, real / scale, rtol=0, atol=RT)


def test_every_built_in_sub_model_is_in_a_chain():
    """The chains above hold every registered built-in sub-model: a new one needs its rule tested."""
    used = {(slot, rd.ContactModel(**kw).submodels[i].name) for kw in CHAINS.values()
            for i, slot in enumerate(("normal", "tangential", "rolling", "twisting", "cohesion"))}
    built_in = {(slot, name) for slot, reg in _REGISTRIES.items() for name, cls in reg.items()
                if cls.__module__.startswith("rollingdem.")}
    assert built_in <= used, sorted(built_in - used)
