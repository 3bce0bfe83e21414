"""Cohesion laws (rollingdem.physics.contact.cohesion, docs/models.md §1.6): JKR against its parametric
force-overlap curve, its pull-off force, zero-load overlap, separation and sticking velocity;
SJKR against the geometry of the contact circle; the refusals."""

import math

import numpy as np
import pytest
from scipy.integrate import quad

import rollingdem as rd
from rollingdem.physics.contact.cohesion import JKR_HISTORY, contact_area, jkr_cohesion, sjkr_cohesion
from rollingdem.errors import ParameterError
from rollingdem.physics.records import contact_inputs

# 100 um spheres of a soft solid with a strong adhesion, so that the sticking velocity is cm/s
R, E, NU, RHO, W = 1e-4, 1e7, 0.3, 2500.0, 0.1
E_STAR = E / (2 * (1 - NU ** 2))
R_EFF = R / 2
M_EFF = RHO * 4 / 3 * math.pi * R ** 3 / 2
PULL_OFF = 1.5 * math.pi * W * R_EFF
A_F = (math.pi * W * R_EFF ** 2 / (8 * E_STAR)) ** (1 / 3)  # contact radius at the separation
A_TOUCH = (2 * math.pi * W * R_EFF ** 2 / E_STAR) ** (1 / 3)  # ... at zero overlap


def jkr_force(a):
    """JKR in parametric form (Johnson, Kendall & Roberts 1971): F(a), delta(a)."""
    return 4 * E_STAR * a ** 3 / (3 * R_EFF) - math.sqrt(8 * math.pi * W * E_STAR * a ** 3)


def jkr_overlap(a):
    return a * a / R_EFF - math.sqrt(2 * math.pi * W * a / E_STAR)


def law_force(overlap, hist=None):
    """The pair's elastic normal force with JKR on Hertz: the law's part plus Hertz's."""
    hertz = 4 / 3 * E_STAR * math.sqrt(R_EFF) * max(overlap, 0.0) ** 1.5
    p = np.array([E_STAR, 0, 0, 0, 0, 0, W])
    hist = np.zeros((1, len(JKR_HISTORY))) if hist is None else hist
    g = contact_inputs(overlap=overlap, r_eff=R_EFF, lever_i=R - overlap / 2, lever_j=R - overlap / 2)
    force, _ = jkr_cohesion(hist, 0, 0, g, (hertz, hertz, 0.0, 0.0, 0.0), p, 6)
    return force + hertz


def test_jkr_follows_its_force_overlap_curve():
    """Along the stable branch, from the separation (a_f) to 30 a_f, the force at delta(a) is F(a)
    to 1e-9 of the pull-off force (the law solves delta(a) for a by Newton's method)."""
    for a in A_F * np.geomspace(1.001, 30, 40):
        assert law_force(jkr_overlap(a)) == pytest.approx(jkr_force(a), abs=1e-9 * PULL_OFF)


def test_jkr_pull_off_zero_load_and_separation():
    """The least force along the curve is the pull-off, -3/2 pi w R*, within 1 % (sampled every
    1/2000 of the range); at the zero-load overlap delta_0 = a_0^2 / (3 R*), a_0 = (9 pi w R*^2 /
    (2 E*))^(1/3), the force is 0 to 1e-9 of the pull-off; the contact lasts to the separation
    delta_c = -3/4 (pi^2 w^2 R* / E*^2)^(1/3) (kept in its history)."""
    delta_c = -0.75 * (math.pi ** 2 * W ** 2 * R_EFF / E_STAR ** 2) ** (1 / 3)
    forces = [law_force(d) for d in np.linspace(delta_c, -2 * delta_c, 2000)]
    assert min(forces) == pytest.approx(-PULL_OFF, rel=0.01)
    a0 = (9 * math.pi * W * R_EFF ** 2 / (2 * E_STAR)) ** (1 / 3)
    assert law_force(a0 ** 2 / (3 * R_EFF)) == pytest.approx(0.0, abs=1e-9 * PULL_OFF)
    hist = np.zeros((1, len(JKR_HISTORY)))
    law_force(0.0, hist)
    assert hist[0, JKR_HISTORY.separation_limit] == pytest.approx(-delta_c, rel=1e-12)


def jkr_pair(speed, dt_fraction=400, approach=True):
    """Two equal spheres meeting head on (or, with approach False, leaving a fresh contact) at a
    relative speed ``speed``, no dashpot (e = 1), dt a ``dt_fraction``-th of the zero-load period."""
    # energy summed in every JKR run: one kernel for all of them
    sim = rd.Simulation(contact=rd.ContactModel(cohesion="jkr"), gravity=(0, 0, 0), track_energy=True)
    sim.add_material(rd.Material("m", youngs_modulus=E, poisson_ratio=NU, density=RHO, restitution=1.0,
                                 friction=0.5, surface_energy=W))
    gap = 1e-7 if approach else -2.5e-7  # parting from about the zero-load overlap
    v = 0.5 * speed if approach else -0.5 * speed
    sim.add_particles([[-R - gap, 0, 0], [R + gap, 0, 0]], radius=R, material="m", velocity=[[v, 0, 0], [-v, 0, 0]],
                      allow_overlap=not approach)
    (label, limit), = [x for x in sim.time_step_limits() if x[0].startswith("JKR")]
    sim.dt = limit * 50 / dt_fraction
    return sim


def tail_work():
    """The work of separating from touching to delta_c, int |F| d(delta), by quadrature over a."""
    return -quad(lambda a: jkr_force(a) * (2 * a / R_EFF - 0.5 * math.sqrt(2 * math.pi * W / (E_STAR * a))),
                 A_F, A_TOUCH, epsabs=0, epsrel=1e-12)[0]


def test_jkr_sticking_velocity():
    """Without a dashpot a JKR impact loses the tail's work, int_delta_c^0 |F| d(delta) (the
    approach feels no force before touching, the separation is pulled back out to delta_c), so
    pairs slower than v_s = sqrt(2 W / m*) stick. At 0.95 v_s the pair is still in contact after
    40 oscillation periods, and the energy counted in the normal channel is W; at 1.05 v_s it has
    parted, having lost W: the kinetic energy lost and the energy counted both equal W within 3 %
    (the snap-in and the last step before the separation each err by up to F v dt, 1 % of W at
    dt = T/400)."""
    w_tail = tail_work()
    v_s = math.sqrt(2 * w_tail / M_EFF)
    stuck = jkr_pair(0.95 * v_s)
    stuck.track_energy = True
    stuck.run(steps=16000)
    assert stuck.number_of_contacts() == 1
    # the stuck pair oscillates without loss: what is counted is the loss taken at the snap-in, W,
    # whatever the phase of the oscillation (the law's energy V(a) tracks the work along the curve)
    assert stuck.dissipated_energy()["normal_damping"] == pytest.approx(w_tail, rel=0.03)
    parted = jkr_pair(1.05 * v_s)
    parted.track_energy = True
    ke0 = sum(parted.kinetic_energy())
    parted.run(steps=16000)
    assert parted.number_of_contacts() == 0
    assert ke0 - sum(parted.kinetic_energy()) == pytest.approx(w_tail, rel=0.03)
    assert parted.dissipated_energy()["normal_damping"] == pytest.approx(w_tail, rel=0.03)


def test_a_jkr_contact_lasts_until_the_separation():
    """Spheres parting from a fresh contact at the zero-load overlap at 2 v_s hold it while less than delta_c apart and drop
    it once farther: the largest gap with a contact is |delta_c| within one step's travel."""
    v_s = math.sqrt(2 * tail_work() / M_EFF)
    sim = jkr_pair(2 * v_s, approach=False)
    delta_c = 0.75 * (math.pi ** 2 * W ** 2 * R_EFF / E_STAR ** 2) ** (1 / 3)
    widest = 0.0
    for _ in range(2000):
        sim.run(steps=1)
        gap = sim.positions[1, 0] - sim.positions[0, 0] - 2 * R
        if sim.number_of_contacts() == 0:
            break
        widest = max(widest, gap)
    assert sim.number_of_contacts() == 0
    travel = abs(sim.velocities[1, 0] - sim.velocities[0, 0]) * sim.dt
    assert widest == pytest.approx(delta_c, abs=2 * travel)
    assert widest > 0.5 * delta_c


def test_sjkr_takes_the_area_of_the_contact_circle():
    """F = -k_c pi a^2 with a the radius of the circle where the spheres' surfaces cross: for radii
    1 and 2 mm at 40 um overlap, a^2 = R_i^2 - x^2, x = (d^2 + R_i^2 - R_j^2) / (2 d) the circle's
    distance from i's centre; against a wall, a^2 = R^2 - (R - delta)^2."""
    ri, rj, overlap, kc = 1e-3, 2e-3, 4e-5, 3e5
    d = ri + rj - overlap
    x = (d * d + ri * ri - rj * rj) / (2 * d)
    p = np.array([0, 0, 0, 0, 0, 0, kc])
    g = contact_inputs(overlap=overlap, lever_i=ri - overlap / 2, lever_j=rj - overlap / 2)
    force, dissipated = sjkr_cohesion(np.zeros((1, 0)), 0, 0, g, (0.0,) * 5, p, 6)
    assert force == pytest.approx(-kc * math.pi * (ri * ri - x * x), rel=1e-9)
    assert dissipated == 0.0
    wall = contact_inputs(overlap=overlap, lever_i=ri - overlap / 2, lever_j=0.0)
    assert contact_area(wall) == pytest.approx(math.pi * (ri ** 2 - (ri - overlap) ** 2), rel=1e-12)


def test_sjkr_holds_a_sphere_under_a_ceiling():
    """Against a wall, cohesion 2 pi k_c R delta (to first order in delta) minus Hertz's
    4/3 E* sqrt(R) delta^(3/2) pulls hardest, (2/3) pi^3 k_c^3 R^2 / E*^2, at delta* = (pi k_c
    sqrt(R) / E*)^2; it equals the weight m g at k_crit = (3 m g E*^2 / (2 pi^3 R^2))^(1/3) = 2.5e4
    J/m^3. A sphere put at delta* under a ceiling hangs at 2 k_crit (pulled by 8 times its weight)
    and falls at k_crit / 2 (1/8 of it)."""
    mass = RHO * 4 / 3 * math.pi * R ** 3
    k_crit = (3 * mass * 9.81 * E_STAR ** 2 / (2 * math.pi ** 3 * R ** 2)) ** (1 / 3)
    for kc, hangs in ((2 * k_crit, True), (0.5 * k_crit, False)):
        sim = rd.Simulation(contact=rd.ContactModel(cohesion="sjkr"), gravity=(0, 0, -9.81))
        sim.add_material(rd.Material("m", youngs_modulus=E, poisson_ratio=NU, density=RHO, restitution=0.3,
                                     cohesion_energy_density=kc))
        sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, -1), material="m"))
        pull_at = (math.pi * kc * math.sqrt(R) / E_STAR) ** 2
        sim.add_particles([[0, 0, -R + pull_at]], radius=R, material="m", allow_overlap=True)
        sim.run(0.01)
        assert (sim.positions[0, 2] > -R) == hangs


def test_cohesion_refusals():
    with pytest.raises(ParameterError, match="surface_energy = -0.1 is not allowed"):
        rd.Material("m", youngs_modulus=E, poisson_ratio=NU, density=RHO, surface_energy=-0.1)
    with pytest.raises(ParameterError, match="cohesion_energy_density"):
        rd.Material("m", youngs_modulus=E, poisson_ratio=NU, density=RHO, cohesion_energy_density=-1.0)
    with pytest.raises(ParameterError, match="cohesion model 'jkr' with normal model 'hooke' is not allowed"):
        rd.ContactModel(normal="hooke", cohesion="jkr")
    with pytest.raises(ParameterError, match="cohesion model = 'dmt' is not known"):
        rd.ContactModel(cohesion="dmt")
    sim = rd.Simulation(contact=rd.ContactModel(cohesion="jkr"), gravity=(0, 0, 0), skin=1e-9, dt=1e-9)
    sim.add_material(rd.Material("m", youngs_modulus=E, poisson_ratio=NU, density=RHO, surface_energy=W))
    sim.add_particles([[0, 0, 0], [3 * R, 0, 0]], radius=R, material="m")
    with pytest.raises(ParameterError, match="skin = 1e-09 m is not allowed with cohesion 'jkr'"):
        sim.run(steps=1)


@pytest.mark.slow
def test_a_cohesive_pile_stands_steeper():
    """The angle-of-repose case (600 spheres of R = 5 mm on a rough base, EPSD, mu = 0.5, mu_r =
    0.1, tube lifted at 0.2 m/s), 6 seeds, dry and with SJKR cohesion at k_c = 7e4 J/m^3 (the
    largest pair pull, (2/3) pi^3 k_c^3 R*^2 / E*^2, about 0.8 of a sphere's weight): the cohesive
    piles are steeper, seed by seed, by a mean larger than the 95 % Student-t half-width of the
    differences (measured: 7.7 +- 4.9 degrees, on 21.4 dry). Six seeds, as piles this small scatter
    widely when dry (18.0-27.1 degrees, the cone fit's R^2 about 0.6)."""
    from rollingdem.experiments import EXPERIMENTS
    from rollingdem.analysis.intervals import confidence_interval

    angles = {}
    for kc in (0.0, 7e4):
        angles[kc] = [EXPERIMENTS["angle-of-repose"].observe(dict(model="epsd", mu=0.5, mur=0.1, count=600, seed=seed,
                                                        lift_speed=0.2, rough_base=1,
                                                        cohesion="sjkr" if kc else "none",
                                                        cohesion_energy_density=kc))["angle"]
                      for seed in (1, 2, 3, 4, 5, 6)]
    mean, half = confidence_interval(np.array(angles[7e4]) - np.array(angles[0.0]))
    assert mean > half > 0, angles


def test_the_experiments_take_a_cohesion_law():
    """The granular cases take the law and its parameters (so that calibrate can fit them), refuse
    an unknown law or a negative energy by name, and keep the walls free of cohesion."""
    from rollingdem.experiments import EXPERIMENTS
    from rollingdem.experiments.pile import PileMaterial

    for case in ("angle-of-repose", "repose-rough-base", "rotating-drum", "silo-discharge"):
        p = EXPERIMENTS[case].resolve({"cohesion": "sjkr", "cohesion_energy_density": 2e4})
        material = PileMaterial.from_parameters(p)
        assert (material.cohesion, material.as_material("m").cohesion_energy_density) == ("sjkr", 2e4)
        wall = material.wall_material("wall")
        assert (wall.cohesion_energy_density, wall.surface_energy, wall.friction) == (0.0, 0.0, material.friction)
        with pytest.raises(ParameterError, match="cohesion = 'dmt' is not known"):
            EXPERIMENTS[case].resolve({"cohesion": "dmt"})
        with pytest.raises(ParameterError, match="surface_energy"):
            EXPERIMENTS[case].resolve({"surface_energy": -1.0})


def test_the_jkr_time_step_is_a_fiftieth_of_the_zero_load_period():
    """The JKR limit: T = 2 pi sqrt(m* / k) at the zero-load contact radius a_0, k = dF/d(delta) =
    F'(a) / delta'(a) from the parametric curve, over 50."""
    a0 = (9 * math.pi * W * R_EFF ** 2 / (2 * E_STAR)) ** (1 / 3)
    h = 1e-6 * a0
    slope = (jkr_force(a0 + h) - jkr_force(a0 - h)) / (jkr_overlap(a0 + h) - jkr_overlap(a0 - h))
    sim = jkr_pair(1.0)
    (label, limit), = [x for x in sim.time_step_limits() if x[0].startswith("JKR")]
    assert limit == pytest.approx(2 * math.pi * math.sqrt(M_EFF / slope) / 50, rel=1e-6)
