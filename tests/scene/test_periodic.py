"""Periodic boundaries: a pair across the boundary is the same contact as in the middle, an elastic
periodic gas keeps its energy and momentum, a sphere rolls across the boundary to the analytic stop,
and the refusals.
"""

import math

import numpy as np
import pytest

import rollingdem as rd
from rollingdem.experiments import single_sphere as ss
from rollingdem.errors import ParameterError

from conftest import R, TABLE1

BOX = (-0.05, 0.05)


DRIFT = 3.35  # m/s along x, both spheres: the first crosses x = 0.05 while the contact lasts


def _pair(table1, shift, periodic):
    """Two spheres in an oblique, spinning collision (sliding and rolling in the contact), their
    centres moved along x by ``shift``, drifting along x together; gravity off."""
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), gravity=(0, 0, 0),
                        periodic={"x": BOX} if periodic else None, dt=2e-6)
    sim.add_material(table1())
    a = np.array([-1.2 * R, 0.3 * R, 0.0])
    b = np.array([1.2 * R, -0.2 * R, 0.1 * R])
    wrap = (lambda p: (p - BOX[0]) % (BOX[1] - BOX[0]) + BOX[0]) if periodic else (lambda p: p)
    for p, v, w in ((a, (DRIFT + 0.4, 0.0, 0.05), (0.0, 5.0, 30.0)), (b, (DRIFT - 0.3, 0.02, 0.0), (10.0, 0.0, -20.0))):
        sim.add_particles([[wrap(p[0] + shift), p[1], p[2]]], R, "m", velocity=v, angular_velocity=w)
    trace = []
    for _ in range(30):
        sim.run(steps=100)
        trace.append(np.concatenate([sim.unwrapped_positions.ravel(), sim.velocities.ravel(),
                                     sim.angular_velocities.ravel(), sim.forces.ravel(), sim.torques.ravel()]))
    return np.array(trace), sim


def test_a_pair_across_the_boundary_is_the_pair_in_the_middle(table1):
    """The pair straddling x = 0.05 (one sphere at x = +0.0488, the other wrapped to -0.0488) follows
    the trajectory of the same pair at x = 0 without periodic boundaries: the same forces and
    torques, so the same tangential and rolling history, while the spheres cross the boundary. The
    positions differ by the box length's rounding (1e-17 m); over 3,000 steps the contact grows that
    to round-off, 1e-9 of each quantity's scale."""
    middle, _ = _pair(table1, 0.0, periodic=False)
    across, sim = _pair(table1, BOX[1], periodic=True)
    diff = across - middle
    diff[:, [0, 3]] -= BOX[1]  # the unwrapped x of each sphere, moved back to the middle
    diff[:, [0, 3]] -= 0.1 * np.round(diff[:, [0, 3]] / 0.1)  # the second was put in the box at the start
    forces = middle[:, 18:24]
    assert np.abs(forces).max() > 0.1 and np.abs(forces[-1]).max() == 0.0  # a collision, over by the end
    assert sim._state.image[:, 0].any()  # a sphere crossed
    scale = np.abs(middle).max(axis=0) + 1e-30
    np.testing.assert_array_less(np.abs(diff) / scale, 1e-9)
    assert (np.abs(sim.positions[:, 0]) <= BOX[1] + 0.01).all()


def _hertz_energy(sim, radius, length):
    """Elastic energy of the contacts, U = (8/15) E* sqrt(R*) delta^(5/2) per pair (E* = E / (2 (1 -
    nu^2)), R* = R / 2 for equal spheres), pairs by the minimum image."""
    x = sim.positions
    d = x[:, None] - x[None]
    d -= length * np.round(d / length)
    overlap = np.triu(np.clip(2 * radius - np.linalg.norm(d, axis=-1), 0, None), 1)
    e_star = TABLE1["youngs_modulus"] / (2 * (1 - TABLE1["poisson_ratio"] ** 2))
    return float((8 / 15 * e_star * math.sqrt(radius / 2) * overlap ** 2.5).sum())


def test_an_elastic_periodic_gas_keeps_its_energy_and_momentum(table1):
    """1,000 spheres, restitution 1, no friction, periodic along x, y and z, no gravity, 10^4 steps:
    kinetic plus contact energy within 1e-4 (velocity Verlet's error at this dt, 3e-5 measured), momentum
    to round-off (each pair's force is added to one sphere and subtracted from the other)."""
    L, r = 0.1, 0.4 * R
    sim = rd.Simulation(gravity=(0, 0, 0), periodic={a: (0.0, L) for a in "xyz"}, dt=4e-6)
    sim.add_material(table1(friction=0.0, rolling_friction=0.0, restitution=1.0))
    sim.insert(rd.BoxRegion((0, 0, 0), (L, L, L)), 1000, r, "m", seed=1)  # solid fraction 0.034
    rng = np.random.default_rng(2)
    v = rng.normal(0.0, 0.5, (1000, 3))
    sim.set_velocities(np.arange(1000), velocity=v - v.mean(axis=0))
    e0 = sum(sim.kinetic_energy()) + _hertz_energy(sim, r, L)
    p0 = (sim.masses[:, None] * sim.velocities).sum(axis=0)
    scale = float((sim.masses[:, None] * np.abs(sim.velocities)).sum())
    sim.run(steps=10_000)
    e1 = sum(sim.kinetic_energy()) + _hertz_energy(sim, r, L)
    p1 = (sim.masses[:, None] * sim.velocities).sum(axis=0)
    assert sim._state.image.any()  # particles crossed the boundaries
    assert sim._state.info[3] > 10  # and the list was rebuilt: collisions happened along the way
    assert abs(e1 - e0) / e0 < 1e-4
    assert np.abs(p1 - p0).max() < 1e-12 * scale


def test_a_sphere_rolls_across_the_boundary_to_the_analytic_stop():
    """Case 1 (EPSD, v0 = 1 m/s) on a plane, periodic along x every 0.1 m: the sphere crosses the
    boundary once and stops at the analytic 0.18836 m (within 0.5 %, as on the plane without it)."""
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), gravity=(0, 0, -ss.G), dt=ss.DT,
                        periodic={"x": (-0.02, 0.08)})
    sim.add_material(rd.Material("table1", **ss.TABLE1))
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="table1"))
    sim.add_particles([[0.0, 0.0, ss.RADIUS]], ss.RADIUS, "table1")
    sim.run(0.2)
    sim.set_velocities([0], velocity=(1.0, 0, 0), angular_velocity=(0, 0, 0))
    x0 = sim.unwrapped_positions[0, 0]
    sim.run(0.8)
    distance = sim.unwrapped_positions[0, 0] - x0
    assert -0.02 <= sim.positions[0, 0] < 0.08
    assert distance == pytest.approx(ss.analytic_flat()[3], rel=5e-3)
    assert abs(sim.velocities[0, 0]) < 1e-3


@pytest.mark.parametrize("periodic, words", [
    ({"w": (0, 1)}, "periodic axis = 'w' is not allowed"),
    ({"x": (1, 0)}, "periodic x = \\(1, 0\\) is not allowed"),
    ({"x": 5}, "periodic x = 5 is not allowed"),
    ([0, 1], "periodic = \\[0, 1\\] is not allowed"),
])
def test_periodic_refusals(periodic, words):
    with pytest.raises(ParameterError, match=words):
        rd.Simulation(periodic=periodic)


def test_a_periodic_length_below_two_cutoffs_is_refused(table1):
    sim = rd.Simulation(periodic={"y": (0.0, 0.02)})
    sim.add_material(table1())
    sim.add_particles([[0, 0.01, 0.01]], R, "m")
    with pytest.raises(ParameterError, match=r"periodic y length = 0.02 m is not allowed: must be at least 2 \(2 R_max"):
        sim.run(steps=1)


def test_particles_outside_the_box_and_overlapping_across_it_are_refused(table1):
    sim = rd.Simulation(periodic={"x": BOX})
    sim.add_material(table1())
    with pytest.raises(ParameterError, match=r"x must be in the periodic box \[-0.05, 0.05\)"):
        sim.add_particles([[0.06, 0, 0]], R, "m")
    sim.add_particles([[0.049, 0, 0]], R, "m")
    with pytest.raises(ParameterError, match="overlap by"):
        sim.add_particles([[-0.049, 0, 0]], R, "m")
