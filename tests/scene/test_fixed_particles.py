"""Fixed particles and the rough base: they never move, they carry the static load of what rests on
them, they act on a free sphere as a partner of infinite mass and inertia (as a wall does), and
pairs of them never interact.
"""

import math

import numpy as np
import pytest

import rollingdem as rd
from rollingdem.errors import ParameterError

from conftest import G, R


def test_a_sphere_resting_on_three_fixed_spheres_carries_the_static_solution(table1):
    """Without friction the only forces are along the three normals: by symmetry each is
    N = m g / (3 cos theta), theta the normal's angle to the vertical (from the settled positions).
    The fixed spheres keep their positions bit for bit, and ``forces`` on them is the load -N n.
    After 0.3 s the rebound (restitution 0.5, contact period ~1e-3 s) has died out to round-off:
    1e-7 relative leaves room for its last 1e-9."""
    sim = rd.Simulation(contact=rd.ContactModel("hertz"), gravity=(0, 0, -G))
    sim.add_material(table1(friction=0.0))
    d = 1.2 * 2 * R / math.sqrt(3)  # base centres from the axis: the three do not touch one another
    base = np.array([[d * math.cos(a), d * math.sin(a), R] for a in (0.0, 2 * math.pi / 3, 4 * math.pi / 3)])
    sim.add_particles(base, R, "m", fixed=True)
    sim.add_particles([[0.0, 0.0, R + math.sqrt(4 * R * R - d * d) + 1e-5]], R, "m")
    sim.run(0.3)
    assert np.array_equal(sim.positions[:3], base)
    assert np.array_equal(sim.velocities[:3], np.zeros((3, 3)))
    assert sim.fixed.tolist() == [True, True, True, False]
    top = sim.positions[3]
    normal = (top - base) / np.linalg.norm(top - base, axis=1)[:, None]
    load = sim.masses[3] * G / (3 * normal[:, 2])
    np.testing.assert_allclose(sim.forces[:3], -load[:, None] * normal, rtol=1e-7, atol=1e-7 * load.max())
    assert np.linalg.norm(sim.velocities[3]) < 1e-9


def _collide(table1, partner_first, fixed):
    """A free sphere hits a partner obliquely, spinning (sliding and rolling in the contact;
    EPSD with rolling damping, which scales with the rolling inertia I_r): the partner fixed, or free
    and 10^12 times denser (a mass and inertia 10^12 times the free sphere's). Gravity off."""
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), gravity=(0, 0, 0))
    sim.add_material(table1("m"))
    sim.add_material(table1("heavy", density=table1().density * 1e12))
    partner = ([[0.0, 0.0, 0.0]], R, "m" if fixed else "heavy")
    free = ([[0.3 * R, 0.0, 2 * R + 1e-5]], R, "m")
    kw = dict(velocity=(0.05, 0.0, -0.3), angular_velocity=(3.0, 20.0, 5.0))
    if partner_first:
        sim.add_particles(*partner, fixed=fixed)
        k = sim.add_particles(*free, **kw)[0]
    else:
        k = sim.add_particles(*free, **kw)[0]
        sim.add_particles(*partner, fixed=fixed)
    sim.dt = 2e-6
    sim.run(steps=1500)
    return sim.velocities[k], sim.angular_velocities[k], sim.number_of_contacts()


@pytest.mark.parametrize("partner_first", [True, False], ids=["fixed-is-i", "fixed-is-j"])
def test_a_fixed_partner_acts_as_infinite_mass_and_inertia(table1, partner_first):
    """The free sphere leaves a fixed sphere as it leaves a free one 10^12 times heavier: the
    effective mass m* and rolling inertia I_r of the contact are the free sphere's own (with the
    pair formula for two equal spheres they would be half of it, and the restitution, the rolling
    dashpot and the rebound would change by order one). The heavy partner's finite mass shifts the
    result by ~1e-12 relative; 1e-9 allows for round-off over the 1,500 steps."""
    v_fixed, w_fixed, n_fixed = _collide(table1, partner_first, fixed=True)
    v_heavy, w_heavy, n_heavy = _collide(table1, partner_first, fixed=False)
    assert n_fixed == n_heavy == 0  # the collision is over
    assert v_fixed[2] > 0.05  # it bounced
    scale_v, scale_w = 0.3, 20.0
    np.testing.assert_allclose(v_fixed, v_heavy, rtol=0, atol=1e-9 * scale_v)
    np.testing.assert_allclose(w_fixed, w_heavy, rtol=0, atol=1e-9 * scale_w)


def test_fixed_pairs_never_interact(table1):
    """Overlapping fixed spheres exert no force on each other (their pairs are not in the neighbor
    list), and a free sphere near none of them feels nothing."""
    sim = rd.Simulation(gravity=(0, 0, -G))
    sim.add_material(table1())
    sim.add_particles([[0, 0, R], [1.5 * R, 0, R], [0.75 * R, 1.2 * R, R]], R, "m", fixed=True,
                      allow_overlap=True)
    sim.add_particles([[0.1, 0, R]], R, "m")
    sim.run(steps=10)
    assert np.array_equal(sim.forces[:3], np.zeros((3, 3)))
    assert sim._state.contact_list.size == 0
    assert sim.number_of_contacts() == 0


def test_the_rough_base_is_reproducible_and_never_overlaps():
    extent = ((-0.05, 0.05), (-0.04, 0.04))
    a = rd.rough_base(R, extent, seed=4)
    b = rd.rough_base(R, extent, seed=4)
    c = rd.rough_base(R, extent, seed=5)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert np.all(a[:, 2] == R)
    gaps = np.linalg.norm(a[:, None, :2] - a[None, :, :2], axis=-1) + np.eye(len(a))
    assert gaps.min() >= 2 * R * (1 - 1e-12)
    for axis, (lo, hi) in enumerate(extent):
        assert a[:, axis].min() - R >= lo - 1e-12 and a[:, axis].max() + R <= hi + 1e-12
    # a hexagonal layer of spacing 2.2 R: 2 / (sqrt(3) (2.2 R)^2) spheres per unit area; the rows
    # that fit lose at most one spacing along each side
    area_density = 2 / (math.sqrt(3) * (2.2 * R) ** 2)
    assert area_density * (0.1 - 2 * 2.2 * R) * (0.08 - 2 * 2.2 * R) < len(a) <= area_density * 0.1 * 0.08


@pytest.mark.parametrize("kwargs, words", [
    (dict(spacing=1.5 * R), "spacing = 0.0075 is not allowed"),
    (dict(spacing=2.2 * R, jitter=0.2 * R), "jitter = 0.001 is not allowed"),
    (dict(extent=((0, 0.005), (0, 1))), "extent along x"),
    (dict(extent="big"), "extent = 'big' is not allowed"),
])
def test_rough_base_refusals(kwargs, words):
    args = dict(radius=R, extent=((-0.05, 0.05), (-0.05, 0.05)))
    args.update(kwargs)
    with pytest.raises(ParameterError, match=words):
        rd.rough_base(**args)


def test_fixed_particle_refusals(table1):
    sim = rd.Simulation()
    sim.add_material(table1())
    with pytest.raises(ParameterError, match="velocity / angular_velocity of fixed particles is not allowed"):
        sim.add_particles([[0, 0, R]], R, "m", fixed=True, velocity=(1, 0, 0))
    with pytest.raises(ParameterError, match="fixed = 'yes' is not allowed"):
        sim.add_particles([[0, 0, R]], R, "m", fixed="yes")
    with pytest.raises(ParameterError, match="overlap by"):
        sim.add_particles([[0, 0, R], [R, 0, R]], R, "m", fixed=True)
    sim.add_particles([[0, 0, R]], R, "m", fixed=True)
    sim.add_particles([[0, 0, 4 * R]], R, "m")
    with pytest.raises(ParameterError, match="particle 0 is fixed"):
        sim.set_velocities([0, 1], velocity=(0, 0, 1))
    sim.set_velocities([1], velocity=(0, 0, 1))


def test_a_fixed_sphere_may_lie_across_a_wall_that_never_touches_it(table1):
    """Walls skip fixed particles, so a rough base may reach under and beyond a tube standing on
    it: added after the tube it is accepted, where a free sphere there is refused."""
    sim = rd.Simulation(contact=rd.ContactModel("hertz"), dt=1e-5)
    sim.add_material(table1())
    sim.add_wall(rd.Cylinder(radius=0.04, material="m", name="tube"))
    sim.add_particles(rd.rough_base(0.005, ((-0.1, 0.1), (-0.1, 0.1)), seed=1), 0.005, "m", fixed=True)
    assert sim.fixed.all() and sim.n_particles > 100
    with pytest.raises(ParameterError, match="overlaps wall 'tube'"):
        sim.add_particles([[0.09, 0.0, 0.02]], 0.005, "m")


@pytest.mark.parametrize("floor", [0.0, 2 * R, 2 * 1.5 * R])
def test_the_lifted_tube_clears_the_column_on_whatever_floor(floor):
    """The tube rises from the plate (z = 0); the column stands on the floor (the rough base's top,
    2 base radii; 0 on the plate) and reaches 2 radii above its nominal height. At the clearing
    time the tube's edge is the clearance above that top, whatever the floor: without the floor
    term a rough base of radius R would leave the edge level with the top at the default clearance."""
    from rollingdem.experiments.pile import column_size, tube_clearing_time

    _, height = column_size(1000, R, 0.2, 1.0)
    speed, clearance = 0.1, 2 * R
    edge = speed * tube_clearing_time(floor, height, R, clearance, speed)
    assert edge - (floor + height + 2 * R) == pytest.approx(clearance, rel=1e-12)
