"""Bad input gets a clear error naming the parameter, its value and what is allowed."""

import math

import numpy as np
import pytest

import rollingdem as rd
from rollingdem.io.casefile import load_case
from conftest import TABLE1, R


def material(**kw):
    params = dict(TABLE1)
    params.update(kw)
    return rd.Material("m", **params)


@pytest.mark.parametrize("key,value,allowed", [
    ("youngs_modulus", 0.0, "> 0"), ("youngs_modulus", -1e6, "> 0"),
    ("density", 0.0, "> 0"), ("density", -5.0, "> 0"),
    ("poisson_ratio", 0.5, "(-1, 0.5)"), ("poisson_ratio", -1.0, "(-1, 0.5)"), ("poisson_ratio", 0.7, "(-1, 0.5)"),
    ("restitution", 0.0, "(0, 1]"), ("restitution", 1.2, "(0, 1]"),
    ("friction", -0.1, ">= 0"), ("rolling_friction", -0.2, ">= 0"), ("rolling_damping", -0.3, ">= 0"),
    ("youngs_modulus", math.nan, "finite"),
])
def test_material_errors_name_parameter_value_and_range(key, value, allowed):
    with pytest.raises(rd.ParameterError) as err:
        material(**{key: value})
    msg = str(err.value)
    assert key in msg and allowed in msg and f"{value:g}" in msg


@pytest.mark.parametrize("radius", [0.0, -0.005, math.nan])
def test_bad_radius(radius):
    sim = rd.Simulation(dt=1e-5)
    sim.add_material(material())
    with pytest.raises(rd.ParameterError, match="radius of particle 0"):
        sim.add_particles([[0, 0, 0]], radius, "m")


def test_nan_position():
    sim = rd.Simulation(dt=1e-5)
    sim.add_material(material())
    with pytest.raises(rd.ParameterError, match=r"position of particle 1 .* finite"):
        sim.add_particles([[0, 0, 0], [math.nan, 0, 1]], R, "m")


def test_overlapping_insertion_refused():
    sim = rd.Simulation(dt=1e-5)
    sim.add_material(material())
    with pytest.raises(rd.ParameterError, match="particles 0 and 1 overlap"):
        sim.add_particles([[0, 0, 0], [1.5 * R, 0, 0]], R, "m")
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    with pytest.raises(rd.ParameterError, match="overlaps wall"):
        sim.add_particles([[0, 0, 0.5 * R]], R, "m")


def test_coincident_centres_stop_with_the_reason():
    """allow_overlap lets spheres overlap, but two at one centre have no contact normal: the run
    stops at its first step and names both (the kernel's 0/0 becomes NaN, never a crash)."""
    sim = rd.Simulation(dt=1e-5)
    sim.add_material(material())
    sim.add_particles([[0, 0, 0], [3 * R, 0, 0], [0, 0, 0]], R, "m", allow_overlap=True)
    with pytest.raises(rd.SimulationError, match="particle 0 is not finite.*shares its centre with particle 2"):
        sim.run(steps=5)
    assert sim.step == 0


@pytest.mark.parametrize("slot,name", [("normal", "hretz"), ("rolling", "epsd9"), ("tangential", "nope"),
                                       ("twisting", "marshal")])
def test_unknown_model_name(slot, name):
    with pytest.raises(rd.ParameterError) as err:
        rd.ContactModel(**{slot: name})
    assert repr(name) in str(err.value) and "allowed are" in str(err.value)


def test_unknown_material_name():
    sim = rd.Simulation(dt=1e-5)
    sim.add_material(material())
    with pytest.raises(rd.ParameterError, match="'steel' is not known: known materials are 'm'"):
        sim.add_particles([[0, 0, 0]], R, "steel")


def test_dt_above_stable_limit_is_refused():
    sim = rd.Simulation(dt=1e-4)
    sim.add_material(material())
    sim.add_particles([[0, 0, 0]], R, "m")
    # Table 1 material: Rayleigh time 1.4566e-4 s (docs/models.md §13 T8), so the limit is 2.91e-5 s
    with pytest.raises(rd.ParameterError) as err:
        sim.run(steps=1)
    msg = str(err.value)
    assert "dt = 0.0001 s" in msg and "2.913e-05" in msg and "check_timestep=False" in msg
    relaxed = rd.Simulation(dt=1e-4, check_timestep=False)
    relaxed.add_material(material())
    relaxed.add_particles([[0, 0, 0]], R, "m")
    relaxed.run(steps=1)  # the override is honoured


def test_rayleigh_time_step_matches_models_md():
    """docs/models.md §13 T8 / §2 worked values, within 1e-4 relative."""
    assert rd.rayleigh_time_step(0.005, 1056, 40e6, 0.49) == pytest.approx(1.4566e-4, rel=1e-4)
    assert rd.rayleigh_time_step(0.005, 2500, 10e6, 0.3) == pytest.approx(4.3270e-4, rel=1e-4)
    assert rd.rayleigh_time_step(0.001, 2500, 70e9, 0.25) == pytest.approx(1.02e-6, rel=5e-3)  # given to 3 digits
    with pytest.raises(rd.ParameterError, match="radius = -1"):
        rd.rayleigh_time_step(-1, 2500, 70e9, 0.25)


def test_bad_wall_and_gravity():
    with pytest.raises(rd.ParameterError, match="plane normal"):
        rd.Plane(normal=(0, 0, 0))
    with pytest.raises(rd.ParameterError, match="cylinder radius = -0.1"):
        rd.Cylinder(radius=-0.1)
    with pytest.raises(rd.ParameterError, match="gravity"):
        rd.Simulation(gravity=(0, math.nan, 0))
    with pytest.raises(rd.ParameterError, match="dt = -1"):
        rd.Simulation(dt=-1)


def test_unstable_run_stops_with_clear_error_and_keeps_outputs(tmp_path):
    """A dt far above the limit (checks off) blows up; the error says so and the series is readable."""
    import pandas as pd

    sim = rd.Simulation(dt=3e-4, check_timestep=False)
    sim.add_material(material(restitution=0.9))
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    sim.add_particles([[0, 0, R * 1.001], [0, 0, 3.01 * R]], R, "m", velocity=[[0, 0, -3], [0, 0, -3]])
    series = rd.TimeSeries(tmp_path / "s.csv", interval=3e-4)
    with pytest.raises(rd.SimulationError, match="reduce dt|skin"):
        sim.run(1.0, observers=[series])
    assert len(pd.read_csv(tmp_path / "s.csv")) >= 1


@pytest.mark.parametrize("name,value", [("w", math.nan), ("v", math.inf), ("x", -math.inf)])
def test_non_finite_state_is_refused_before_the_kernel(name, value):
    """A value that is not finite in x, v or omega (here put in from outside, as a wrong restart
    or a user's array could) stops the run before the kernel sees it, naming the particle; the
    test of the state is a sum over all values, exact for NaN and inf of either sign."""
    sim = rd.Simulation(dt=1e-5)
    sim.add_material(material())
    sim.add_particles([[0, 0, 0], [4 * R, 0, 0], [8 * R, 0, 0]], R, "m")
    st = sim._state
    getattr(st, name)[st.slots([1])[0], 2] = value
    with pytest.raises(rd.SimulationError, match="non-finite at t = 0 s.*particle 1") as err:
        sim.run(steps=5)
    assert sim.step == 0
    # the stable dt it suggests comes from the finite part of the state (an infinite speed gave 0 s)
    assert float(str(err.value).split("stable estimate ")[1].split(" s")[0]) > 1e-6


def test_too_fast_mid_chunk_leaves_a_state_at_one_time():
    """A sphere in free fall outruns the skin in the middle of one run call (one kernel chunk).
    The step loop drifts the next step in the same pass as it closes the last one, so the stop must
    take that drift back: positions and velocities are left at the last whole step. Velocity Verlet
    is exact for a constant force, so z = z0 - g t^2/2 and v = -g t there, to round-off (1e-12 m
    and 1e-12 m/s over 10^3 steps: the undo adds one rounding per component)."""
    g, dt, skin = 9.81, 2e-5, 1e-5
    sim = rd.Simulation(dt=dt, skin=skin)
    sim.add_material(material())
    z0 = 10.0
    sim.add_particles([[0, 0, z0]], R, "m")
    # the stop comes once dt (|v| + dt g / 2) >= skin/2, i.e. after about skin / (2 g dt^2) steps
    expected = math.ceil((0.5 * skin / dt - 0.5 * dt * g) / (g * dt))
    with pytest.raises(rd.SimulationError, match="half the neighbor skin"):
        sim.run(steps=2 * expected)
    steps = sim.step
    assert abs(steps - expected) <= 1
    t = steps * dt
    assert sim.positions[0, 2] == pytest.approx(z0 - 0.5 * g * t * t, abs=1e-12)
    assert sim.velocities[0, 2] == pytest.approx(-g * t, abs=1e-12)


CASE = """
name: t
dt: 1.0e-5
materials:
  - {name: m, youngs_modulus: 4.0e7, poisson_ratio: 0.49, density: 1056}
walls:
  - {type: plane, material: m}
particles:
  - positions: [[0, 0, 0.006]]
    radius: 0.005
    material: m
stages:
  - {duration: 0.001}
"""


def test_case_file_missing_key(tmp_path):
    p = tmp_path / "c.yaml"
    p.write_text(CASE.replace(", density: 1056", ""))
    with pytest.raises(rd.ParameterError, match=r"key 'materials.0.density': missing"):
        load_case(p)


def test_case_file_misspelled_key(tmp_path):
    p = tmp_path / "c.yaml"
    p.write_text(CASE.replace("poisson_ratio", "poison_ratio"))
    with pytest.raises(rd.ParameterError) as err:
        load_case(p)
    assert "materials.0.poison_ratio': not a known key" in str(err.value)


def test_case_file_bad_value(tmp_path):
    p = tmp_path / "c.yaml"
    p.write_text(CASE.replace("radius: 0.005", "radius: -0.005"))
    from rollingdem.io.casefile import build_simulation

    with pytest.raises(rd.ParameterError, match="radius of particle 0 = -0.005"):
        build_simulation(load_case(p))
    p.write_text(CASE.replace("dt: 1.0e-5", "dt: fast"))
    with pytest.raises(rd.ParameterError, match="key 'dt' = \"fast\""):
        load_case(p)


def test_pair_override_validated():
    sim = rd.Simulation(dt=1e-5)
    sim.add_material(material())
    with pytest.raises(rd.ParameterError, match="friction = -1"):
        sim.set_pair("m", "m", friction=-1)
    with pytest.raises(rd.ParameterError, match="'stickiness' is not known"):
        sim.set_pair("m", "m", stickiness=1)
    sim.set_pair("m", "m", friction=0.3)
    assert sim.materials.pair(0, 0).friction == 0.3
    assert np.isclose(sim.pair_parameters()[0, 0, 2], 0.3)


def test_rotational_springs_enter_the_time_step_check():
    """docs/models.md §2: every rolling and twisting spring must be resolved; the Iwashita-Oda spring
    (k_t R*^2) never limits dt, a stiff LAMMPS sds spring does."""
    def limits(rolling):
        sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling=rolling, twisting="marshall"), dt=1e-5)
        sim.add_material(material(rolling_friction=0.2))
        sim.add_particles([[0, 0, 0]], R, "m")
        return sim, dict((label.split(" period")[0], v) for label, v in sim.time_step_limits())

    sim, lim = limits("epsd2")
    assert lim["rolling spring (epsd2)"] > sim.stable_time_step() == pytest.approx(2.913e-5, rel=1e-3)
    assert "twisting spring (marshall)" in lim
    sim, lim = limits({"model": "sds", "rolling_stiffness": 1e9})
    with pytest.raises(rd.ParameterError, match=r"dt = 1e-05 s exceeds .*rolling spring \(sds\)"):
        sim.run(steps=1)


def test_each_normal_law_reports_its_own_time_step_limits():
    """docs/models.md §2, worked by hand for the Table 1 sphere (one material, so E* = E / (2 (1 -
    nu^2)), G* = E / (4 (2 - nu)(1 + nu)), R* = R/2, m* = m/2, I = 0.4 m R^2): Hertz's time at
    twice the fastest speed / 20 and, through EPSD's and Marshall's rotational springs, Hertz's
    normal and tangential stiffness at an overlap of R/100; Hooke's stiffness from V_c and the spring periods / 10 of Hooke and linear.
    Each value to 1e-12: any factor wrong by 1 % moves it by 0.2 % or more."""
    E, nu, rho, mu_r = TABLE1["youngs_modulus"], TABLE1["poisson_ratio"], TABLE1["density"], 0.2
    m = rho * 4.0 / 3.0 * math.pi * R ** 3
    e_star, g_star = E / (2 * (1 - nu ** 2)), E / (4 * (2 - nu) * (1 + nu))
    r_eff, m_eff, inertia = R / 2, m / 2, 0.4 * m * R ** 2

    def limits(normal, rolling="none", speed=0.0, twisting="none"):
        sim = rd.Simulation(contact=rd.ContactModel(normal, rolling=rolling, twisting=twisting), dt=1e-7)
        sim.add_material(material(rolling_friction=mu_r))
        sim.add_particles([[0, 0, 0]], R, "m", velocity=(speed, 0, 0))
        return {label.split(" ")[0] + " " + label.split(" ")[1]: v for label, v in sim.time_step_limits()}

    def period(k, mass):
        return 2 * math.pi * math.sqrt(mass / k)

    hertz = limits("hertz", "epsd", speed=0.5, twisting="marshall")
    t_hertz = 2.87 * (m_eff ** 2 / (r_eff * e_star ** 2 * 1.0)) ** 0.2
    assert hertz["Hertz time"] == pytest.approx(t_hertz / 20, rel=1e-12)
    kn = 4.0 / 3.0 * e_star * math.sqrt(r_eff * 0.01 * R)
    k_roll = 2.25 * kn * mu_r ** 2 * r_eff ** 2
    assert hertz["rolling spring"] == pytest.approx(period(k_roll * 2 / inertia, 1.0) / 10, rel=1e-12)
    kt = 8.0 * g_star * math.sqrt(r_eff * 0.01 * R)
    k_twist = 0.5 * kt * r_eff * 0.01 * R  # Marshall: k_t a^2 / 2
    assert hertz["twisting spring"] == pytest.approx(period(k_twist * 2 / inertia, 1.0) / 10, rel=1e-12)
    assert "normal spring" not in hertz

    vc, ratio = 2.0, 0.4
    hooke = limits(rd.Hooke(characteristic_velocity=vc, tangential_stiffness_ratio=ratio))
    kn = 16 / 15 * math.sqrt(r_eff) * e_star * (15 * m_eff * vc ** 2 / (16 * math.sqrt(r_eff) * e_star)) ** 0.2
    assert hooke["normal spring"] == pytest.approx(period(kn, m_eff) / 10, rel=1e-12)
    assert hooke["tangential spring"] == pytest.approx(period(ratio * kn, m_eff) / 10, rel=1e-12)
    assert "0.2 x" in hooke

    linear = limits(rd.Linear(normal_stiffness=2e4, shear_stiffness=5e3))
    assert linear["normal spring"] == pytest.approx(period(2e4, m_eff) / 10, rel=1e-12)
    assert linear["tangential spring"] == pytest.approx(period(5e3, m_eff) / 10, rel=1e-12)
    assert "0.2 x" not in linear  # PFC's linear contact has no Rayleigh criterion
