"""The walls' candidates (``engine.wall_candidates``): the gather tests a plane or cylinder for a
sphere only where it lay within R + skin/2 of the sphere when the lists were built, or moved since,
or touched it at the last step. Skipping a wall must never miss a contact."""


import numpy as np

import rollingdem as rd
from rollingdem.physics.records import WALL_CYLINDER, WALL_PLANE
from rollingdem.physics.walls import wall_contact_geometry, wall_within

R = 0.005


def walls_and_spheres(count=20000, seed=3):
    """A tilted plane and a finite cylinder (radius 0.05 m, extent -0.02..0.03 m about a tilted
    axis, so that its rims count), and sphere centres spread over both, radii up to 2 R."""
    axis = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])
    normal = np.array([0.1, 0.2, 1.0]) / np.linalg.norm([0.1, 0.2, 1.0])
    kind = np.array([WALL_PLANE, WALL_CYLINDER], dtype=np.int32)
    geom = np.zeros((2, 9))
    geom[0, :3], geom[0, 3:6] = (0.01, 0.0, -0.005), normal
    geom[1, :3], geom[1, 3:6], geom[1, 6:9] = (0.0, 0.01, 0.0), axis, (0.05, -0.02, 0.03)
    rng = np.random.default_rng(seed)
    x = rng.uniform(-0.08, 0.08, (count, 3))
    return kind, geom, x, rng.uniform(0.1 * R, 2.0 * R, count)


def test_a_wall_that_a_sphere_overlaps_is_within_its_reach():
    """For every sphere that overlaps a wall at a radius r, ``wall_within`` at any reach >= r says
    so (on the faces, past the rims, on the axis); and a plane or the cylinder's shell farther than
    the reach from the centre (within the extent) is not within it, so the test skips the walls it
    can. A reach taken too short (R alone, without skin/2) misses overlaps of spheres a little
    larger, which the first assertion catches."""
    kind, geom, x, radii = walls_and_spheres()
    overlaps = within = beyond = 0
    for i in range(len(x)):
        for wl in range(2):
            overlap = wall_contact_geometry(i, wl, x, radii[i], kind, geom)[0]
            reach = radii[i] * 1.2
            if overlap > 0.0:
                overlaps += 1
                assert wall_within(i, wl, x, radii[i], kind, geom), (i, wl)
                assert wall_within(i, wl, x, reach, kind, geom), (i, wl)
            near = wall_within(i, wl, x, reach, kind, geom)
            within += near
            d = x[i] - geom[wl, :3]
            if wl == 0:
                far = d @ geom[0, 3:6] >= reach
            else:
                s = d @ geom[1, 3:6]
                r = np.linalg.norm(d - s * geom[1, 3:6])
                far = geom[1, 7] <= s <= geom[1, 8] and abs(r - geom[1, 6]) >= reach
            if far:
                beyond += 1
                assert not near, (i, wl)
    assert overlaps > 2000 and beyond > 10000 and within < 2 * len(x) - beyond


def resting_sphere(skin, z=0.05):
    sim = rd.Simulation(gravity=(0, 0, 0), dt=2e-6, skin=skin)
    sim.add_material(rd.Material("m", youngs_modulus=1e7, poisson_ratio=0.3, density=2500.0, friction=0.5,
                                 restitution=0.5))
    sim.add_particles([[0, 0, z]], radius=R, material="m")
    return sim


def test_a_plane_that_moves_up_to_a_resting_sphere_strikes_it():
    """A plane far below a sphere at rest (no gravity: the sphere never moves, the lists are never
    built again) rises at 1 m/s: it is not near the sphere at the build, but it moves, so the
    sphere tests it at every step and is struck. A sphere struck by a wall of infinite mass at 1 m/s
    with restitution e = 0.5 leaves at (1 + e) 1 m/s = 1.5 m/s (10 % for the Hertz contact's
    restitution at this speed); missed, it stays at rest."""
    sim = resting_sphere(skin=0.001)
    sim.add_wall(rd.Plane(point=(0, 0, 0), material="m", velocity=(0, 0, 1.0)))
    sim.run(0.04)  # the plane 5 mm below the sphere: the lists built once, at the start
    assert sim.engine_statistics()["neighbor_rebuilds"] == 1 and np.all(sim.velocities[0] == 0.0)
    sim.run(0.015)
    assert abs(sim.velocities[0, 2] - 1.5) < 0.15, sim.velocities[0]


def test_a_sphere_that_reaches_a_plane_between_two_builds_bounces():
    """A sphere at 1 m/s towards a plane at rest, with a skin of 4 R: the lists are built when it has
    moved skin/2 = 2 R, so it reaches the plane up to 2 R after a build, from where the plane is
    not within R but is within R + skin/2. It bounces back at e 1 m/s = 0.5 m/s (10 %); a
    candidate test without the skin/2 lets it pass into the plane."""
    for start in np.linspace(0.02, 0.03, 7):  # where the builds fall relative to the plane: all cases
        sim = resting_sphere(skin=4 * R, z=start)
        sim.set_velocities([0], velocity=(0, 0, -1.0))
        sim.add_wall(rd.Plane(point=(0, 0, 0), material="m"))
        sim.run((start - R) / 1.0 + 0.005)
        assert abs(sim.velocities[0, 2] - 0.5) < 0.05, (start, sim.velocities[0])


def test_a_cylinder_turning_about_its_axis_keeps_its_candidates():
    """A drum turning about its own axis keeps its geometry: it has not moved for the candidates,
    which the build made for the sphere overlapping its shell (pushed inwards by it) and not for
    the sphere at its centre (untouched)."""
    sim = resting_sphere(skin=0.001, z=0.0)
    sim.add_particles([[0.05 - R + 1e-5, 0, 0.0]], radius=R, material="m")
    sim.add_wall(rd.Cylinder(0.05, material="m", angular_velocity=(0, 0, 2.0)))
    sim.run(0.002)
    state = sim._state
    order = np.argsort(state.ids)  # storage slots of particles 0 and 1
    assert list(state.wall_near[order]) == [0, 1] and state.wall_moved[0] == 0, (state.wall_near, state.wall_moved)
    assert np.all(sim.velocities[0] == 0.0)
    assert sim.velocities[1, 0] < 0.0, sim.velocities[1]
