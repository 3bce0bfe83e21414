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
import pandas as pd
import pytest

import rollingdem as rd
from rollingdem.physics.contact.frame import contact_frame
from rollingdem.physics.contact.base import REGISTRIES
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
    built_in = {(slot, name) for slot, reg in REGISTRIES.items() for name, cls in reg.items()
                if cls.__module__.startswith("rollingdem.")}
    assert built_in <= used, sorted(built_in - used)


def collision_scene(alpha: float) -> rd.Simulation:
    """Two spheres meeting obliquely with spin, and a third glancing off a plane wall (of a material
    without coarse graining), with no gravity: the real scene at alpha = 1, its parcels at alpha
    (positions alpha x, the same velocities, spins / alpha, dt alpha x)."""
    # a law with a given stiffness (N/m), which the parcels' pairs must scale
    sim = rd.Simulation(contact=rd.ContactModel(normal=rd.Linear(2e4, 2e4 * 2 / 7)), gravity=(0, 0, 0), dt=alpha * 2e-7)
    sim.add_material(rd.Material("m", **REAL, coarse_graining=alpha))
    sim.add_material(rd.Material("steel", 2e11, 0.3, 7800.0, friction=0.3, rolling_friction=0.1, restitution=0.8))
    sim.add_wall(rd.Plane(point=(0, 0, -alpha * 3e-3), normal=(0, 0, 1), material="steel"))
    x = alpha * np.array([[-1.05e-3, 0.0, 0.0], [1.05e-3, 0.4e-3, 0.0], [5e-3, 0.0, -1.9e-3]])
    sim.add_particles(x, 1e-3, "m", velocity=[[0.6, 0.0, 0.1], [-0.6, 0.0, 0.0], [0.2, 0.1, -0.5]],
                      angular_velocity=np.array([[0, 50.0, 20.0], [10.0, 0, -30.0], [0, 0, 40.0]]) / alpha)
    return sim


def test_parcels_collide_as_the_real_spheres_scaled():
    """Through the engine: parcels of alpha = 2 given the real radius end, after the collisions, at
    alpha times the real positions, with the real velocities and 1/alpha the real spins (module
    docstring: exact similarity, RT). Catches the radius not scaled at ``add_particles``, a mass
    or inertia not from the parcel's radius, the wall pair's alpha taken from the wall (1) instead
    of the parcel."""
    real, parcel = collision_scene(1.0), collision_scene(ALPHA)
    assert parcel.radii.tolist() == [ALPHA * 1e-3] * 3
    real.run(steps=3000)
    parcel.run(steps=3000)
    assert np.abs(real.velocities[2, 2]) > 0 and real.velocities[2, 2] > 0  # bounced off the wall
    assert real.velocities[0, 0] < 0.6  # the pair met
    np.testing.assert_allclose(parcel.positions / ALPHA, real.positions, rtol=0, atol=RT * 1e-2)
    np.testing.assert_allclose(parcel.velocities, real.velocities, rtol=0, atol=RT)
    np.testing.assert_allclose(parcel.angular_velocities * ALPHA, real.angular_velocities, rtol=0, atol=RT * 100)


def bonded_scene(alpha: float, tensile_strength: float) -> rd.Simulation:
    """Two touching spheres of the real radius 1 mm bonded (a parallel bond with dashpots), pulled
    apart, sheared and twisted from their start, with no gravity: the real scene at alpha = 1, its
    parcels at alpha (positions alpha x, the same velocities, spins / alpha, dt alpha x)."""
    sim = rd.Simulation(gravity=(0, 0, 0), dt=alpha * 2e-8)
    sim.add_material(rd.Material("m", **REAL, coarse_graining=alpha))
    sim.add_particles(alpha * np.array([[0.0, 0.0, 0.0], [2e-3, 0.0, 0.0]]), 1e-3, "m",
                      velocity=[[-0.02, 0.01, 0.0], [0.02, -0.01, 0.005]],
                      angular_velocity=np.array([[5.0, 0.0, 8.0], [-3.0, 4.0, 0.0]]) / alpha)
    assert sim.add_bonds(rd.ParallelBond(youngs_modulus=1e8, tensile_strength=tensile_strength, cohesion=1e9,
                                         damping_ratio=0.2), pairs=[(0, 1)]) == 1
    return sim


@pytest.mark.parametrize("tensile_strength", [1e9, 5e3])  # the pull peaks at 1.1e4 Pa
def test_bonded_parcels_move_and_break_as_the_real_pair_scaled(tensile_strength):
    """docs/models.md §18, parallel bond: k_n = E / (R_i + R_j) from the parcels' radii, K_n = k_n A ~
    alpha, K_b = k_n I ~ alpha^3, dashpots 2 zeta sqrt(m K) ~ alpha^2, strengths in Pa kept. The bonded
    parcels end at alpha times the real positions, with the real velocities, spins / alpha, the bond's
    forces alpha^2 and moments alpha^3 the real ones (module docstring: RT); with a tensile strength
    the pull exceeds, the bond breaks in both scenes, in tension. Catches a bond stiffness, dashpot or
    area taken from the real radius, or a strength scaled."""
    real, parcel = bonded_scene(1.0, tensile_strength), bonded_scene(ALPHA, tensile_strength)
    real.run(steps=4000)
    parcel.run(steps=4000)
    a, b = real.bonds(), parcel.bonds()
    assert list(a["status"]) == list(b["status"]) == (["intact"] if tensile_strength > 1e8 else ["tension"])
    if tensile_strength > 1e8:
        assert abs(a["normal_force"].iloc[0]) > 0 and a["shear_force"].iloc[0] > 0  # loaded
        for column, power in (("normal_force", 2), ("shear_force", 2), ("twisting_moment", 3), ("bending_moment", 3)):
            assert b[column].iloc[0] / ALPHA ** power == pytest.approx(a[column].iloc[0], rel=RT, abs=1e-300), column
    speed = np.abs(real.velocities).max()
    np.testing.assert_allclose(parcel.positions / ALPHA, real.positions, rtol=0, atol=RT * 2e-3)
    np.testing.assert_allclose(parcel.velocities, real.velocities, rtol=0, atol=RT * speed)
    np.testing.assert_allclose(parcel.angular_velocities * ALPHA, real.angular_velocities, rtol=0,
                               atol=RT * np.abs(real.angular_velocities).max())


@pytest.mark.parametrize("chain", list(CHAINS))
def test_the_time_step_limits_of_parcels_are_alpha_times_the_real(chain):
    """Every limit of docs/models.md §2 is a time of the contact (a Rayleigh time ~ r, a spring period
    ~ sqrt(m / k) ~ alpha, a Hertz time at kept speeds ~ alpha): parcels' limits are alpha times the
    real ones. Catches a time-step path that reads a sub-model's unscaled value (linear's k_n, SDS's
    k_roll, TwistingSDS's k_tw, JKR's w)."""
    limits = []
    for alpha in (1.0, ALPHA):
        sim = rd.Simulation(contact=rd.ContactModel(**CHAINS[chain]))
        sim.add_material(rd.Material("m", **REAL, coarse_graining=alpha))
        sim.add_particles([[0, 0, 0], [0, 0, 0.01 * alpha]], 1e-3, "m", velocity=[[0, 0, 0.5], [0, 0, -0.5]])
        limits.append(sim.time_step_limits())
    assert [label.split(" ")[0] for label, _ in limits[0]] == [label.split(" ")[0] for label, _ in limits[1]]
    for (label, real), (_, parcel) in zip(*limits):
        assert parcel == pytest.approx(ALPHA * real, rel=1e-12), label


def parcel_scene(alpha=ALPHA, contact=None) -> rd.Simulation:
    sim = rd.Simulation(contact=contact, gravity=(0, 0, -9.81))
    sim.add_material(rd.Material("m", **REAL, coarse_graining=alpha))
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    return sim


def test_insert_places_parcels_for_the_real_count_and_mass():
    """``count`` counts real particles: 800 of radius 1 mm are 800 / alpha^3 = 100 parcels of 2 mm with
    the same total mass (a parcel of the same density is alpha^3 particles, exactly); ``mass`` gives the
    parcels nearest it (within one parcel's mass); ``represented`` counts alpha^3 per parcel."""
    sim = parcel_scene()
    sim.insert(rd.BoxRegion((-0.03, -0.03, 0.01), (0.03, 0.03, 0.05)), 800, 1e-3, "m", seed=1)
    real_mass = 2500.0 * 4 / 3 * math.pi * 1e-9
    assert sim.n_particles == 100 and set(sim.radii.tolist()) == {ALPHA * 1e-3}
    assert float(sim.masses.sum()) == pytest.approx(800 * real_mass, rel=1e-12)
    assert sim.particles_represented == 800
    assert "800 particles" in sim.particle_set.fills[-1] and "100 parcels" in sim.particle_set.fills[-1]
    sim.insert(rd.BoxRegion((-0.03, -0.03, 0.06), (0.03, 0.03, 0.1)), radius=1e-3, material="m", mass=0.004)
    assert abs(float(sim.masses.sum()) - 800 * real_mass - 0.004) <= 0.5 * ALPHA ** 3 * real_mass


def test_an_inflow_of_parcels_keeps_the_real_rate_and_size_distribution(tmp_path):
    """An inflow's ``rate`` counts real particles: 40,000 /s of them come as 5,000 parcels /s; its
    radii (a distribution of the real particles) are alpha times theirs, and a checkpoint keeps that.
    It acts every 1 ms, so after 0.02 s it has placed what was due at its last action, 95 to 100
    parcels (800 had the rate counted parcels), all of radius 2 to 3 mm."""
    sim = parcel_scene()
    inflow = sim.add_inflow(rd.BoxRegion((-0.05, -0.05, 0.05), (0.05, 0.05, 0.09)), rd.Uniform(1e-3, 1.5e-3), "m",
                            rate=40000.0)
    sim.run(0.02)
    assert 95 <= inflow.count <= 100 and inflow.count == sim.n_particles
    assert ALPHA * 1e-3 <= sim.radii.min() and sim.radii.max() <= ALPHA * 1.5e-3
    sim.checkpoint(tmp_path / "c.npz")
    restored = rd.Simulation.restore(tmp_path / "c.npz")
    assert restored.inflows[0].radius.max_radius == ALPHA * 1.5e-3
    assert restored.inflows[0].rate == pytest.approx(40000.0 / ALPHA ** 3, rel=1e-15)


def test_an_outlet_refill_puts_a_parcel_back_as_it_was():
    """A parcel taken out and put back keeps its radius (alpha r, not alpha^2 r) and mass."""
    sim = parcel_scene()
    sim.add_particles([[0, 0, 0.0021]], 1e-3, "m")
    sim.add_outlet(rd.BoxRegion((-0.01, -0.01, 0.0), (0.01, 0.01, 0.01)), interval=1e-4,
                   refill=rd.BoxRegion((-0.01, -0.01, 0.05), (0.01, 0.01, 0.06)))
    mass = float(sim.masses[0])
    sim.run(steps=20)
    assert sim.positions[0, 2] > 0.05 and sim.radii.tolist() == [ALPHA * 1e-3] and sim.masses[0] == mass


def test_a_case_file_rough_base_of_parcels_scales_its_lengths():
    """A case file's rough base of a coarse-grained material is a layer of parcels: radius and
    spacing alpha times the real, so alpha^2 fewer spheres on the same plate (within the rows cut at
    the edges: about one spacing of 9 in each direction, 25 %), none overlapping, on the plate."""
    from scipy.spatial import cKDTree

    from rollingdem.io import casefile

    def base(alpha):
        case = casefile.load_case({
            "name": "cg", "materials": [dict(name="m", **REAL, coarse_graining=alpha)],
            "walls": [{"type": "plane", "material": "m"}],
            "particles": [{"rough_base": {"radius": 1e-3, "extent": [[-0.02, 0.02], [-0.02, 0.02]], "seed": 1},
                           "material": "m"}],
            "stages": [{"name": "s", "duration": 1e-4}]})
        return casefile.build_simulation(case)

    real, parcels = base(1.0), base(ALPHA)
    x = parcels.positions
    assert set(parcels.radii.tolist()) == {ALPHA * 1e-3} and np.allclose(x[:, 2], ALPHA * 1e-3)
    assert cKDTree(x).query(x, k=2)[0][:, 1].min() >= 2 * ALPHA * 1e-3
    assert parcels.n_particles == pytest.approx(real.n_particles / ALPHA ** 2, rel=0.25)


@pytest.mark.parametrize("make, message", [
    (lambda: rd.Material("m", 1e7, 0.3, 1000.0, coarse_graining=0.5),
     "material 'm': coarse_graining = 0.5 is not allowed: must be >= 1"),
    (lambda: parcel_scene(contact=rd.ContactModel(rolling="epsd")).add_material(
        rd.Material("other", 1e7, 0.3, 1000.0, coarse_graining=3.0)),
     "material 'other': coarse_graining = 3 is not allowed beside material 'm''s 2: one coarse-graining factor"),
    (lambda: parcel_scene().add_clumps(rd.Clump([[0, 0, 0], [1e-3, 0, 0]], [1e-3, 1e-3]), [[0, 0, 0.01]], "m"),
     "material 'm': coarse_graining = 2 is not allowed for clumps"),
])
def test_coarse_graining_bad_input_is_one_line(make, message):
    with pytest.raises(rd.ParameterError, match=message.replace("(", r"\(")):
        make()


def test_a_sub_model_without_a_rule_refuses_coarse_graining():
    """A user's sub-model that declares no ``coarse_graining_exponents`` runs at alpha = 1 and is
    refused, in one line naming it, with a coarse-grained material: its parameters' scaling is not
    known. The refusal lists the models that have a rule."""
    from numba import njit

    from rollingdem.physics.contact.base import ROLLING_MODELS, SubModel

    @njit
    def no_moment(hist, k, history_at, g, frame, normal, dt, p, params_at, modes):
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0

    class Unscaled(SubModel):
        slot, name, function = "rolling", "unscaled_test", staticmethod(no_moment)

    try:
        sim = rd.Simulation(contact=rd.ContactModel(rolling="unscaled_test"))
        sim.add_material(rd.Material("real", **REAL))
        with pytest.raises(rd.ParameterError, match="coarse_graining = 2 is not allowed with rolling model "
                                                    "'unscaled_test': .* rolling models with a rule are cdt, "):
            sim.add_material(rd.Material("m", **REAL, coarse_graining=2.0))
    finally:
        ROLLING_MODELS.pop("unscaled_test", None)


# --- the study's checks on known inputs (experiments/coarse_graining.py) ------------------------------

def test_welch_difference_interval_by_hand():
    """(1, 2, 3) against (2, 3, 4): difference -1, variances 1/3 each, Welch's nu = 4,
    half-width t(0.975, 4) sqrt(2/3) = 2.7764 x 0.8165 = 2.2670."""
    from rollingdem.analysis.intervals import difference_interval

    diff, half = difference_interval([1, 2, 3], [2, 3, 4])
    assert diff == -1.0 and half == pytest.approx(2.776445 * math.sqrt(2 / 3), rel=1e-6)
    assert math.isnan(difference_interval([1.0], [2.0, 3.0])[1])


def test_beverloo_ratio_by_hand():
    """Orifice 12 d, k = 1.5: parcels of alpha 2 leave (12 - 3)^2.5 / (12 - 1.5)^2.5 = 0.6802 of the flow."""
    from rollingdem.experiments.coarse_graining import beverloo_ratio

    assert beverloo_ratio(12.0, 2.0) == pytest.approx((9 / 10.5) ** 2.5, rel=1e-12)
    assert beverloo_ratio(12.0, 1.0) == 1.0


def study_runs(pile_shift, drum_shift, flow_over_beverloo, mur_crit):
    """A made-up table of the study's runs: real angles 30, 31, 32 deg, parcels shifted by the given
    amounts; silo flows 1.0, 1.02, 0.98 kg/s and the parcels' Beverloo's ratio (0.6802 through 12 d
    at alpha 2) times ``flow_over_beverloo``."""
    rows = []
    for k, s in enumerate((1, 2, 3)):
        for alpha in (1.0, 2.0):
            rows.append(dict(scene="pile", alpha=alpha, mur=0.4, length_convention=0, seed=s,
                             angle=30.0 + k + (pile_shift if alpha > 1 else 0.0)))
            rows.append(dict(scene="drum", alpha=alpha, seed=s, angle=25.0 + 0.1 * k + (drum_shift if alpha > 1 else 0),
                             particles=1000, wall_time=10.0 / alpha ** 2))
            rows.append(dict(scene="silo", alpha=alpha, seed=s, flow_rate=(1.0, 1.02, 0.98)[k]
                             * ((9 / 10.5) ** 2.5 * flow_over_beverloo if alpha > 1 else 1.0)))
    rows.append(dict(scene="slope", alpha=3.0, model="epsd", beta=20.0, mur_critical=mur_crit))
    return pd.DataFrame(rows)


TAN20 = math.tan(math.radians(20.0))


@pytest.mark.parametrize("pile_shift, drum_shift, flow_over_beverloo, mur_crit, failing", [
    (0.5, -0.5, 0.97, TAN20 * 1.003, []),
    (1.5, 0.0, 1.0, TAN20, ["pile angle, alpha 2 - alpha 1"]),
    (0.0, 1.2, 1.0, TAN20, ["drum angle, alpha 2 - alpha 1"]),
    (0.0, 0.0, 0.94, TAN20, ["silo flow rate, alpha 2 / alpha 1"]),
    (0.0, 0.0, 1.0 / (9 / 10.5) ** 2.5, TAN20, ["silo flow rate, alpha 2 / alpha 1"]),  # the real flow unchanged
    (0.0, 0.0, 1.0, TAN20 * 1.006, ["parcel (alpha 3): mu_r,crit / tan(beta) at 20 deg"]),
])
def test_the_study_s_checks_on_known_tables(pile_shift, drum_shift, flow_over_beverloo, mur_crit, failing):
    """Each full-size check passes inside its bound and fails just outside it: the pile's mean angle
    1 deg, the drum's 1 deg, the silo's flow 5 % of Beverloo's at the parcels' diameter (an
    unchanged flow fails), the slope's mu_r,crit 0.5 % of tan(beta); the notes state each
    difference with its interval, Beverloo's expectation and the drum's particles represented per
    second."""
    from rollingdem.experiments.coarse_graining import (drum_checks, pile_checks, silo_checks, slope_checks)
    from rollingdem.experiments.results import ValidationResult

    runs = study_runs(pile_shift, drum_shift, flow_over_beverloo, mur_crit)
    result = ValidationResult("coarse-graining", "test", runs, [])
    pile_checks(result, runs, "epsd", {"murs": (0.4,)}, quick=False)
    drum_checks(result, runs, "epsd", quick=False)
    silo_checks(result, runs, "epsd", quick=False)
    slope_checks(result, runs)
    failed = [c.quantity for c in result.checks if not c.passed]
    assert [f for f in failed if not any(f.startswith(x) for x in failing)] == []
    assert all(any(f.startswith(x) for f in failed) for x in failing)
    notes = " ".join(result.notes)
    assert f"difference {pile_shift:+.2f} +- " in notes and "alpha 2: 400 (4 x alpha 1)" in notes
    assert "expects -32.0 %" in notes and f"flow at {flow_over_beverloo:.3f} of that" in notes


@pytest.mark.parametrize("shift, spread, passes", [
    (0.9, 0.2, True),    # within 1 deg
    (1.2, 0.2, False),   # outside 1 deg, the seeds' interval (+-0.45 deg) narrower
    (1.2, 1.0, True),    # the interval (+-2.27 deg) wider than 1 deg: no difference resolved
    (3.0, 1.0, False),   # outside the interval too
])
def test_the_parcels_against_the_real_scene_alpha_times_smaller(shift, spread, passes):
    """The similarity check: the parcels' mean angle minus the smaller real scene's within 1 deg, or
    within Welch's 95 % interval where the seeds' scatter makes that wider. Three seeds each at
    30 +- spread (the same values in both: s = spread, half-width t(0.975, 4) s sqrt(2/3), 2.27 deg
    at spread 1) and the parcels shifted by ``shift``; the mu_r of the pile is matched, the other
    mu_r and the length convention ignored."""
    from rollingdem.experiments.coarse_graining import similarity_checks
    from rollingdem.experiments.results import ValidationResult

    rows = []
    for k, s in enumerate((1, 2, 3)):
        real = 30.0 + spread * (k - 1)
        for scene in ("pile", "drum"):
            rows.append(dict(scene=f"{scene}-scaled", alpha=2.0, seed=s, angle=real))
            rows.append(dict(scene=scene, alpha=2.0, seed=s, angle=real + shift))
        rows += [dict(scene="pile", alpha=2.0, mur=0.4, length_convention=1, seed=s, angle=real - 10.0),
                 dict(scene="pile", alpha=2.0, mur=0.1, length_convention=0, seed=s, angle=real - 10.0)]
    runs = pd.DataFrame(rows)
    piles = runs["scene"].str.startswith("pile")
    runs.loc[piles, "mur"] = runs.loc[piles, "mur"].fillna(0.4)
    runs.loc[piles, "length_convention"] = runs.loc[piles, "length_convention"].fillna(0)
    result = ValidationResult("coarse-graining", "test", runs, [])
    similarity_checks(result, runs, "epsd", quick=False)
    assert [c.passed for c in result.checks] == [passes, passes], result.notes
    assert all(f"parcels {shift:+.2f} +- " in n for n in result.notes) and len(result.notes) == 2
    assert math.isclose(result.checks[0].measured, shift, abs_tol=1e-9)
    similarity_checks(quick := ValidationResult("coarse-graining", "test", runs, []), runs, "epsd", quick=True)
    assert quick.checks == [] and len(quick.notes) == 2


def test_the_smaller_scene_is_the_parcels_scene_scaled_by_one_over_alpha(monkeypatch):
    """The real particles' scene beside parcels of alpha: lengths / alpha (the count / alpha^3, the
    drum's and slice's diameters / alpha), speeds set by gravity / sqrt(alpha) (the lift; the drum's
    Froude number unchanged), E / alpha (docs/models.md §18: the Hertz force E sqrt(alpha R)
    (alpha delta)^1.5 is alpha^3 times (E / alpha) sqrt(R) delta^1.5), the real time step."""
    import rollingdem.experiments.coarse_graining as cg
    from rollingdem.experiments.drum import RotatingDrum
    from rollingdem.experiments.repose import ReposeRoughBase

    seen = {}

    def capture(self, params, checkpoint=None):
        seen[type(self).__name__] = self.resolve(params)
        return {"angle": 30.0, "r_squared": 0.9, "note": "", "wall_time": 1.0, "angle_ci": 0.5, "particles": 7}

    monkeypatch.setattr(ReposeRoughBase, "observe", capture)
    monkeypatch.setattr(RotatingDrum, "observe", capture)
    cg.scaled_pile_point("epsd", 3.0, 0.4, 2, 40500)
    pile = seen["ReposeRoughBase"]
    assert pile["count"] == 1500 and pile["seed"] == 2 and pile["mur"] == 0.4 and pile["mu"] == 0.5
    assert pile["lift_speed"] == pytest.approx(0.1 / math.sqrt(3.0), rel=1e-12)
    assert pile["youngs_modulus"] == pytest.approx(5e6 / 3.0, rel=1e-12)
    assert pile["dt"] == 2.5e-5 and pile["coarse_graining"] == 1.0 and pile["radius"] == 0.005
    # the parcels' collapse lasts its lift and REST s; the smaller pile's lift is sqrt(alpha) shorter
    assert pile["max_collapse"] == pytest.approx(cg.lift_time(40500, 3.0) / math.sqrt(3.0) + cg.REST, rel=1e-12)
    size = cg.CoarseGraining.sizes["full"]["drum"]
    cg.scaled_drum_point("epsd", 2.0, 1, size)
    drum, parcels = seen["RotatingDrum"], RotatingDrum().resolve(cg.drum_parameters("epsd", 2.0, 1, size))
    assert (drum["drum_diameters"], drum["slice_diameters"]) == (15.0, 5.0)
    assert drum["youngs_modulus"] == 2.5e6 and drum["coarse_graining"] == 1.0 and drum["dt"] == 2.5e-5
    assert parcels["coarse_graining"] == 2.0 and parcels["drum_diameters"] == 30.0
    for same in ("froude", "gravity", "mu", "mur", "fill", "spin_up", "measure", "samples", "radius", "seed"):
        assert drum[same] == parcels[same], same


def test_a_silo_orifice_narrower_than_a_parcel_is_refused():
    """An orifice of 5 real diameters with parcels of alpha 6 (7.2 d with the 20 % spread): one line."""
    from rollingdem.experiments.pile import PileMaterial
    from rollingdem.experiments.silo import SiloSetup, silo_case

    with pytest.raises(rd.ParameterError, match=r"orifice_diameters = 5 is not allowed with coarse_graining = 6: "
                                                r"the orifice \(0.05 m\) is narrower than the largest parcel"):
        silo_case(material=PileMaterial(coarse_graining=6.0), setup=SiloSetup(orifice_diameters=5.0))


def test_a_region_narrower_than_a_parcel_is_refused_naming_the_coarse_graining():
    """Parcels of alpha 15 of 1 mm spheres (1.5 cm radius) into a tube region 1 cm in radius: one line."""
    sim = parcel_scene(alpha=15.0)
    with pytest.raises(rd.ParameterError, match=r"coarse_graining = 15 is not allowed for CylinderRegion\(radius=0.01.*"
                                                r"its parcels, up to 0.015 m in radius, do not fit in it"):
        sim.insert(rd.CylinderRegion(0.01, 0.0, 0.2), 100, 1e-3, "m")


def test_a_mesh_opening_is_measured_across():
    """``TriangleMesh.openings``: the silo's orifice of radius r drawn with n = 48 segments is a
    regular polygon whose edges lie r cos(pi/n) from its centre, so it is 2 r cos(pi/n) wide, on the
    axis at the floor (rounding: 1e-12); its open top likewise. A sheet's outer rim has its centre on
    the sheet (a disk) and a closed mesh has no free edge (a box, a capped drum): no opening."""
    from rollingdem.scene.mesh import box, disk, drum, silo

    holes = sorted(silo(0.1, 0.3, 0.01, segments=48).openings(), key=lambda h: h[1])
    assert len(holes) == 2
    for (centre, width), radius, z in zip(holes, (0.01, 0.1), (0.0, 0.3)):
        assert width == pytest.approx(2 * radius * math.cos(math.pi / 48), rel=1e-12)
        np.testing.assert_allclose(centre, [0.0, 0.0, z], rtol=0, atol=1e-12)
    assert disk(0.1).openings() == box((0.1, 0.2, 0.3)).openings() == drum(0.1, 0.05).openings() == []


@pytest.mark.parametrize("real_radius, alpha, refused", [(2e-3, 6.0, True), (2e-3, 4.0, False), (0.0105, 2.0, False)])
def test_a_mesh_opening_the_parcels_cannot_pass_is_refused(real_radius, alpha, refused):
    """A silo mesh's orifice 2 cm cos(pi/48) = 19.96 mm wide: real spheres of 4 mm pass it, their parcels
    of alpha 6 (24 mm) do not, refused in one line naming the mesh, the opening and both sizes, whether
    the mesh or the parcels come first (at add_wall; at run). Parcels of alpha 4 (16 mm) pass: no
    refusal. Real spheres of 21 mm do not pass either: the parcels jam where the material does, so
    alpha 2 is not refused."""
    message = (r"silo: coarse_graining = .* is not allowed with its opening at \(0, 0, 0\) m, 0.02 m wide: the "
               r"real particles \(from 0.004 m\) pass it, the parcels \(to 0.024 m\) do not")

    def scene():
        sim = rd.Simulation(gravity=(0, 0, -9.81))
        sim.add_material(rd.Material("m", **REAL, coarse_graining=alpha))
        return sim

    def add_parcels(sim):
        sim.insert(rd.CylinderRegion(0.09, 0.05, 0.25), int(20 * alpha ** 3), real_radius, "m", seed=1)

    def silo():
        return rd.MeshWall.shape("silo", radius=0.1, height=0.3, orifice_radius=0.01, name="silo")

    first_parcels, first_mesh = scene(), scene()
    add_parcels(first_parcels)
    first_mesh.add_wall(silo())
    add_parcels(first_mesh)
    if refused:
        with pytest.raises(rd.ParameterError, match=message):
            first_parcels.add_wall(silo())
        with pytest.raises(rd.ParameterError, match=message):
            first_mesh.run(steps=1)
    else:
        first_parcels.add_wall(silo())
        first_mesh.check_before_run()


def test_rollingdem_check_refuses_an_opening_the_inflow_s_parcels_cannot_pass(tmp_path):
    """A case file: an inflow of parcels of alpha 6 of 4 mm spheres over a silo mesh whose orifice
    (19.96 mm) the real spheres pass: ``rollingdem check`` refuses it in one line naming the wall
    (exit 2); the same case at alpha 4 is valid."""
    import yaml
    from typer.testing import CliRunner

    from rollingdem.cli import app

    def check(alpha):
        case = {"name": "cg", "materials": [dict(name="m", **REAL, coarse_graining=alpha)],
                "walls": [{"type": "mesh", "name": "silo", "material": "m", "shape": "silo",
                           "size": {"radius": 0.1, "height": 0.3, "orifice_radius": 0.01}}],
                "inflows": [{"name": "pour", "region": {"type": "box", "lo": [-0.05, -0.05, 0.2], "hi": [0.05, 0.05, 0.28]},
                             "radius": 2e-3, "material": "m", "rate": 1000}],
                "stages": [{"name": "s", "duration": 1e-4}]}
        path = tmp_path / f"cg{alpha:g}.yaml"
        path.write_text(yaml.safe_dump(case))
        return CliRunner().invoke(app, ["check", str(path)])

    out = check(6.0)
    assert out.exit_code == 2, out.output
    lines = out.output.strip().splitlines()
    assert len(lines) == 1 and "walls.0" in lines[0] and "parcels (to 0.024 m) do not" in lines[0], out.output
    assert check(4.0).exit_code == 0


# the study's runners of a point besides CoarseGraining.observe (the piles'): a test stands in for them
POINT_RUNNERS = ("drum_point", "silo_point", "slope_point", "scaled_pile_point", "scaled_drum_point")


def test_the_study_goes_on_from_the_runs_it_kept(tmp_path, monkeypatch):
    """With an output folder each run's observables are kept as it ends: the study run again there
    runs nothing it has (a study stopped goes on where it was), and reads the same numbers; runs kept
    under an earlier revision of the contact laws are run again."""
    import rollingdem.experiments.coarse_graining as cg

    calls = []

    def fake(kind):
        def run(*args, **kwargs):
            calls.append(kind)
            return {"angle": 30.0 + len(calls), "r_squared": 0.9, "parcels": 1, "flow_rate": 1.0 + len(calls),
                    "flow_rate_ci": 0.0, "particles": 100, "wall_time": 1.0, "angle_ci": 0.1, "mur_critical": 0.3640}
        return run

    monkeypatch.setattr(cg.CoarseGraining, "observe", fake("pile"))
    for name in POINT_RUNNERS:
        monkeypatch.setattr(cg, name, fake(name))
    first = cg.coarse_graining_study(quick=True, outdir=tmp_path)
    n = len(calls)
    assert n == len(first.table) and len(list((tmp_path / "coarse-graining-runs").glob("*.json"))) == n
    (tmp_path / "coarse-graining-runs" / sorted(p.name for p in (tmp_path / "coarse-graining-runs").glob("*.json"))[0]
     ).unlink()  # one run lost with the kill
    again = cg.coarse_graining_study(quick=True, outdir=tmp_path)
    assert len(calls) == n + 1
    changed = (first.table[["angle", "flow_rate"]] != again.table[["angle", "flow_rate"]]).any(axis=1)
    assert int(changed.sum()) == 1  # the rerun one; the others read back as they were
    # a new revision of the contact laws runs every point afresh
    monkeypatch.setattr(cg, "LAWS_REVISION", cg.LAWS_REVISION + 1)
    cg.coarse_graining_study(quick=True, outdir=tmp_path)
    assert len(calls) == 2 * n + 1


def test_the_full_study_s_kept_runs_give_the_figures_the_studies_doc_states(tmp_path, monkeypatch):
    """The full size's runs ship in ``benchmarks/coarse_graining_runs`` (docs/studies.md): copied into
    an output folder, the study runs none of its points again (every key is current under today's
    ``LAWS_REVISION``) and its notes give the differences docs/studies.md states. A change of the
    laws that leaves the kept runs stale, or a figure in the doc that the runs do not give, fails."""
    import re
    import shutil
    from pathlib import Path

    import rollingdem.experiments.coarse_graining as cg

    root = Path(__file__).resolve().parents[2]
    runs = tmp_path / "coarse-graining-runs"
    runs.mkdir()
    for f in (root / "benchmarks" / "coarse_graining_runs").glob("*.json"):
        shutil.copy(f, runs)

    def refuse(*args, **kwargs):
        raise AssertionError("a point of the full study is not among the kept runs")

    monkeypatch.setattr(cg.CoarseGraining, "observe", refuse)
    for name in POINT_RUNNERS:
        monkeypatch.setattr(cg, name, refuse)
    result = cg.coarse_graining_study(quick=False, outdir=tmp_path)
    notes = " ".join(result.notes)
    doc = (root / "docs" / "studies.md").read_text()
    stated = doc[doc.index("Results of the full size:"):doc.index("## Sweeps")]
    # every "difference +-interval" the doc states, to the doc's two decimals, is a note's
    for shift, spread in re.findall(r"([+−-]\d+\.\d\d)\s+±\s+(\d+\.\d\d)°", stated):
        assert f"{shift.replace('−', '-')} +- {spread} deg" in notes, (shift, spread)
    assert len(re.findall(r"±\s+\d+\.\d\d°", stated)) == 11  # 4 piles and 2 drums vs real, 5 vs smaller
    assert "-34.4 +- 11.1 %" in notes and "0.964 of that" in notes and "0.964" in stated
    # the README's summary: the ranges over the piles and the drum, against each scene
    shifts = {c.quantity: c.measured for c in result.checks if "angle, alpha" in c.quantity}
    smaller = [abs(v) for q, v in shifts.items() if "times smaller" in q]
    real = [v for q, v in shifts.items() if " - alpha 1" in q]
    assert len(smaller) == 5 and len(real) == 5
    readme = " ".join((root / "README.md").read_text().split())
    assert f"(within {min(smaller):.2f}–{max(smaller):.2f}°), {min(real):.1f}–{max(real):.1f}° steeper" in readme


def test_rollingdem_check_says_what_the_parcels_stand_for(tmp_path):
    """``rollingdem check`` of a case with a coarse-grained material: 800 particles inserted are 100
    parcels of alpha 2, and the line says so."""
    import yaml
    from typer.testing import CliRunner

    from rollingdem.cli import app

    case = {"name": "cg", "materials": [dict(name="m", **REAL, coarse_graining=ALPHA)],
            "walls": [{"type": "plane", "material": "m"}],
            "particles": [{"insert": {"type": "box", "lo": [-0.03, -0.03, 0.01], "hi": [0.03, 0.03, 0.05]},
                           "count": 800, "radius": 1e-3, "material": "m", "seed": 1}],
            "stages": [{"name": "s", "duration": 1e-4}]}
    path = tmp_path / "cg.yaml"
    path.write_text(yaml.safe_dump(case))
    out = CliRunner().invoke(app, ["check", str(path)])
    assert out.exit_code == 0, out.output
    assert "100 particles; parcels of alpha 2, standing for 800 particles" in out.output


def test_the_pile_of_parcels_stands_on_its_taller_base_and_lifts_clear_of_it():
    """``repose-rough-base`` of parcels: the column is poured from the top of the base of parcels
    (2 alpha R), and the tube's lift lasts ``coarse_graining.lift_time`` (the base's extra
    2 (alpha - 1) R at 0.1 m/s, 0.1 s at alpha 2 for R = 5 mm, longer than the real pile's); the
    material is the parcels', the walls' keeps alpha 1."""
    from rollingdem.experiments.coarse_graining import lift_time
    from rollingdem.experiments.pile import pile_case
    from rollingdem.experiments.repose import ReposeRoughBase

    args = {alpha: ReposeRoughBase().pile_arguments({"coarse_graining": alpha, "count": 4000, "clearance": 1.0})
            for alpha in (1.0, 2.0)}
    material = args[2.0]["material"]
    assert material.as_material("b").coarse_graining == 2.0 and material.wall_material("w").coarse_graining == 1.0
    cases = {a: pile_case(**{k: v for k, v in kw.items()}) for a, kw in args.items()}
    assert cases[2.0]["particles"][-1]["insert"]["z_min"] == pytest.approx(4 * 0.005, rel=1e-12)
    lifts = {a: next(s for s in c["stages"] if s["name"] == "lift")["duration"] for a, c in cases.items()}
    assert lifts[2.0] - lifts[1.0] == pytest.approx(0.1, abs=0.02 + 1e-9)  # rounded up to 0.02 s samples
    assert lift_time(4000, 2.0) - lift_time(4000, 1.0) == pytest.approx(0.1, rel=1e-9)


def test_the_silo_of_parcels_counts_real_particles_out_and_refills_a_layer_of_parcels():
    """``silo-discharge`` of parcels of alpha 2: the discharge ends at (200 + 1000) / 8 = 150 parcels
    out, the outlet lies two parcel radii below the floor and the refill layer is 2 parcel
    diameters thick from 1.5 above the fill."""
    from rollingdem.experiments.pile import PileMaterial
    from rollingdem.experiments.silo import SiloSetup, silo_case

    d, r_max = 0.01, 0.006
    data = silo_case(material=PileMaterial(coarse_graining=2.0), setup=SiloSetup(orifice_diameters=12.0))
    assert data["stages"][1]["until"]["above"] == 150
    outlet = data["outlets"][0]
    assert outlet["region"]["hi"][2] == pytest.approx(-2 * 2 * r_max, rel=1e-12)
    fill = 24 * d  # the default fill: max(20 d, 2 D0)
    assert (outlet["refill"]["z_min"], outlet["refill"]["z_max"]) == (pytest.approx(fill + 3 * d),
                                                                      pytest.approx(fill + 7 * d))


def test_a_parcel_on_the_slope_is_tilted_alpha_times_as_slowly(monkeypatch):
    """``slope_point`` at alpha 3: every tilt of the bisection lasts 0.9 s and holds 0.9 s (3 x the real
    sphere's 0.3 s), on a material of coarse_graining 3."""
    import rollingdem.experiments.single_sphere as ss
    from rollingdem.experiments.coarse_graining import slope_point

    seen = []

    def tilt(rolling, mu_r, beta_deg, tilt_time=0.3, hold=0.3, material=None, wall=None):
        seen.append((tilt_time, hold, material["coarse_graining"]))
        return 1.0 if mu_r < math.tan(math.radians(beta_deg)) else 0.0

    monkeypatch.setattr(ss, "speed_down_incline", tilt)
    res = slope_point("epsd", 3.0, 20.0)
    assert res["mur_critical"] == pytest.approx(math.tan(math.radians(20.0)), rel=1e-3)
    assert seen and all((t, h, a) == (pytest.approx(0.9), pytest.approx(0.9), 3.0) for t, h, a in seen)


def test_a_parcel_on_a_wall_rests_on_it():
    """``single_sphere.sphere_on_wall`` with coarse_graining 3: the parcel of 3 R rests on the wall at
    its Hertz static overlap, far below 1 % of its radius, not sunk to R."""
    from rollingdem.experiments.single_sphere import RADIUS, sphere_on_wall

    sim = sphere_on_wall("epsd", settle=0.05, material={"coarse_graining": 3.0})
    assert sim.radii[0] == pytest.approx(3 * RADIUS)
    assert 0.0 < 3 * RADIUS - sim.positions[0, 2] < 0.01 * 3 * RADIUS
