"""Triangle-mesh walls in the engine: the contact against analytic geometry and against planes,
history carried across triangles, rigid motion, wall loads, and refusals.

A mesh wall whose triangles tile a plane must act as that plane: every test below that compares
with a ``Plane`` allows 1e-9 relative, the round-off of computing the contact point from a
triangle's vertices (1e-16 relative per step) grown over the run's steps, far below any physics
factor (a rolling spring that restarts at an edge, or a doubled contact, changes the force by
order one).
"""

import math

import numpy as np
import pytest
from scipy.spatial import Delaunay

import rollingdem as rd
from rollingdem.experiments import single_sphere as ss
from rollingdem.errors import ParameterError, SimulationError

R = ss.RADIUS


def tessellated_plane(x_range, y_range, spacing=R, jitter=0.15, angle_deg=17.0, seed=1):
    """A random triangulation of the plane z = 0 over x_range x y_range (normals +z): a jittered
    grid of ``spacing`` turned by ``angle_deg`` (no edge lines up with x), Delaunay-triangulated,
    keeping triangles whose edges are all shorter than 2 ``spacing`` (the hull's slivers go)."""
    rng = np.random.default_rng(seed)
    a = math.radians(angle_deg)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    centre = np.array([0.5 * sum(x_range), 0.5 * sum(y_range)])
    half = 0.5 * math.hypot(x_range[1] - x_range[0], y_range[1] - y_range[0]) + 2 * spacing
    k = np.arange(-half, half + spacing, spacing)
    u, v = np.meshgrid(k, k, indexing="ij")
    pts = np.column_stack([u.ravel(), v.ravel()]) + rng.uniform(-jitter, jitter, (u.size, 2)) * spacing
    pts = pts @ rot.T + centre
    keep = ((pts[:, 0] > x_range[0] - spacing) & (pts[:, 0] < x_range[1] + spacing)
            & (pts[:, 1] > y_range[0] - spacing) & (pts[:, 1] < y_range[1] + spacing))
    pts = pts[keep]
    tri = Delaunay(pts).simplices
    edge = np.stack([np.linalg.norm(pts[tri[:, p]] - pts[tri[:, q]], axis=1) for p, q in ((0, 1), (1, 2), (2, 0))])
    tri = tri[edge.max(axis=0) < 2 * spacing]
    a, b, c = (pts[tri[:, i]] for i in range(3))
    up = (b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0] > 0
    tri[~up] = tri[~up][:, [0, 2, 1]]
    return np.column_stack([pts, np.zeros(len(pts))]), tri


TESSELLATION = tessellated_plane((-0.03, 0.26), (-0.03, 0.03))


def tessellated_wall(material):
    return rd.MeshWall(*TESSELLATION, material=material, name="tessellated")


def test_the_tessellation_is_what_the_seed_cases_ask_for():
    """Edges of 0.5-2 sphere radii where the sphere goes (|y| < 0.02 m); the grid's directions are
    turned 17 degrees from x, so the edges run every way and few of them near x (under 2 % within
    2 degrees of it: the sphere crosses edges, it does not roll along them)."""
    v, t = TESSELLATION
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    length = np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1)
    near = (np.abs(v[e, 1]).max(axis=1) < 0.02) & (v[e, 0].min(axis=1) > -0.01) & (v[e, 0].max(axis=1) < 0.25)
    assert 0.5 * R <= length[near].min() and length[near].max() <= 2 * R
    direction = (v[e[near, 1]] - v[e[near, 0]]) / length[near, None]
    assert np.mean(np.abs(direction[:, 1]) < math.sin(math.radians(2.0))) < 0.02


@pytest.mark.parametrize("rolling", [pytest.param("cdt", marks=pytest.mark.slow), "epsd"])
def test_case_1_on_a_random_tessellation_stops_where_the_plane_does(rolling):
    """Case 1 (rolling on a flat, docs/models.md §13 T2) on ~1,000 random triangles: the sphere
    crosses ~80 edges and passes by vertices; its stop distance equals the analytic 0.18836 m
    within 0.5 % and the plane's run to 1e-9 relative, its velocity the plane's at every sample:
    a rolling spring that restarted at each edge would move the stop (EPSD) and a contact counted
    twice would double the friction."""
    mesh = ss.rolling_flat_run(rolling, wall=tessellated_wall)
    plane = ss.rolling_flat_run(rolling)
    distance = ss.analytic_flat()[3]
    assert mesh.x[-1] == pytest.approx(distance, rel=5e-3)
    assert mesh.x[-1] == pytest.approx(plane.x[-1], rel=1e-9)
    np.testing.assert_allclose(mesh.v, plane.v, rtol=0, atol=1e-9 * 1.0)  # v0 = 1 m/s
    np.testing.assert_allclose(mesh.torque, plane.torque, rtol=0, atol=1e-9 * np.abs(plane.torque).max())


def test_forces_are_continuous_across_coplanar_edges():
    """A sphere sliding (no rotation, friction 0.8) across the tessellation: at every step its
    force equals the plane's to 1e-9 relative, so there is no jump where it crosses an edge or a
    vertex, and exactly one contact throughout."""
    runs = []
    for wall in (tessellated_wall, None):
        sim = ss.sphere_on_wall("none", settle=0.05, wall=wall)
        sim.set_velocities([0], velocity=(0.5, 0.2, 0), angular_velocity=(0, 0, 0))
        forces, contacts = [], []
        for _ in range(400):
            sim.run(steps=5)
            forces.append(sim.forces[0].copy())
            contacts.append(sim.number_of_contacts())
        runs.append((np.array(forces), np.array(contacts)))
    (fm, cm), (fp, cp) = runs
    scale = np.abs(fp).max()
    np.testing.assert_allclose(fm, fp, rtol=0, atol=1e-9 * scale)
    assert (cm == 1).all() and (cp == 1).all()


def ridge(angle_deg=30.0):
    """A roof: two unit squares meeting along the x axis, each sloping down by ``angle_deg``."""
    s, c = math.sin(math.radians(angle_deg)), math.cos(math.radians(angle_deg))
    v = np.array([[0, 0, 0], [1, 0, 0], [1, c, -s], [0, c, -s], [1, -c, -s], [0, -c, -s]], dtype=float) - [0.5, 0, 0]
    return v, np.array([[0, 1, 2], [0, 2, 3], [0, 5, 4], [0, 4, 1]])


def force_on(wall_or_walls, position, radius=0.01, material=None):
    """The contact force on one sphere held at ``position`` (no gravity, at rest), after one step."""
    sim = rd.Simulation(gravity=(0, 0, 0), dt=1e-9, check_timestep=False)
    sim.add_material(rd.Material("m", 1e7, 0.3, 1000.0, friction=0.5, **(material or {})))
    for wall in (wall_or_walls if isinstance(wall_or_walls, list) else [wall_or_walls]):
        sim.add_wall(wall)
    sim.add_particles([position], radius, "m", allow_overlap=True)
    sim.run(steps=1)
    return sim.forces[0].copy(), sim.number_of_contacts()


def test_on_a_convex_edge_the_normal_points_from_the_edge_to_the_centre():
    """A sphere of radius 0.01 whose centre is 0.009 from the ridge line, in a direction between
    the two faces' normals: one contact, its force along (centre - closest point on the ridge)
    to 1e-9, with the Hertz magnitude of the 0.001 overlap."""
    for tilt in (0.0, 0.2, -0.25):  # radians from the vertical, within the edge's normal cone (+-30 deg)
        direction = np.array([0.0, math.sin(tilt), math.cos(tilt)])
        force, n = force_on(rd.MeshWall(*ridge(), material="m"), 0.009 * direction + [0.1, 0, 0])
        assert n == 1
        assert np.linalg.norm(force / np.linalg.norm(force) - direction) < 1e-9
        plane, _ = force_on(rd.Plane(point=(0, 0, 0), normal=direction, material="m"), 0.009 * direction)
        assert np.linalg.norm(force) == pytest.approx(np.linalg.norm(plane), rel=1e-9)


def test_at_a_vertex_the_normal_points_from_the_vertex_to_the_centre():
    """A square pyramid's apex (the sphere above it, off the faces' normal cones): one contact
    along (centre - apex)."""
    v = np.array([[0, 0, 0.5], [1, 1, 0], [-1, 1, 0], [-1, -1, 0], [1, -1, 0]], dtype=float)
    t = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1]])
    direction = np.array([0.1, -0.05, 1.0]) / np.linalg.norm([0.1, -0.05, 1.0])
    force, n = force_on(rd.MeshWall(v, t, material="m"), v[0] + 0.0095 * direction)
    assert n == 1
    assert np.linalg.norm(force / np.linalg.norm(force) - direction) < 1e-9


def test_in_a_concave_corner_the_force_is_two_planes_forces():
    """A 90-degree concave corner (floor z = 0 and wall x = 0 as four triangles): a sphere
    pressed into both has two contacts and the force of the two planes, to 1e-12 relative."""
    v = np.array([[0, -1, 0], [1, -1, 0], [1, 1, 0], [0, 1, 0], [0, -1, 1], [0, 1, 1]], dtype=float)
    t = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 5], [0, 5, 4]])
    position = [0.0093, 0.2, 0.0097]
    mesh, n = force_on(rd.MeshWall(v, t, material="m"), position)
    planes, n2 = force_on([rd.Plane(normal=(0, 0, 1), material="m"), rd.Plane(normal=(1, 0, 0), material="m")],
                          position)
    assert n == n2 == 2
    np.testing.assert_allclose(mesh, planes, rtol=0, atol=1e-12 * np.linalg.norm(planes))


def test_a_rotated_mesh_gives_the_forces_of_the_mesh_built_there():
    """A tessellated square turned about the axis (1, 1, 0) through (0.1, 0, 0) at 2 rad/s while
    moving at (0.04, 0, 0.02) m/s for 0.25 s (no sphere near), then stopped: its vertices are the
    reference's rotated by 0.5 rad about the moving axis and moved by (0.01, 0, 0.005) m, to
    1e-12 m, and a sphere pressed onto it feels the force it feels on the mesh built there."""
    from scipy.spatial.transform import Rotation

    v, t = tessellated_plane((-0.05, 0.05), (-0.05, 0.05), spacing=0.01)
    axis = np.array([1.0, 1.0, 0.0]) / math.sqrt(2)
    point = np.array([0.1, 0.0, 0.0])
    turned = Rotation.from_rotvec(0.5 * axis).apply(v - point) + point + [0.01, 0, 0.005]
    normal = Rotation.from_rotvec(0.5 * axis).apply([0, 0, 1.0])
    position = turned[len(v) // 2] + 0.004 * normal + [1e-4, 0, 0]

    def setup(wall):
        sim = rd.Simulation(gravity=(0, 0, 0), dt=1e-5, check_timestep=False)
        sim.add_material(rd.Material("m", 1e7, 0.3, 1000.0, friction=0.5))
        sim.add_wall(wall)
        sim.add_particles([[5.0, 5.0, 5.0]], 0.005, "m")  # far away while the mesh turns
        return sim

    moving = setup(rd.MeshWall(v, t, material="m", velocity=(0.04, 0, 0.02), angular_velocity=2.0 * axis,
                               point=point, name="m1"))
    moving.run(steps=25_000)
    moving.set_wall_velocity("m1", velocity=(0, 0, 0), angular_velocity=(0, 0, 0))
    np.testing.assert_allclose(moving.walls[0].mesh.vertices, turned, rtol=0, atol=1e-12)
    built = setup(rd.MeshWall(turned, t, material="m"))
    forces = []
    for sim in (moving, built):
        sim.set_velocities([0], velocity=(0, 0, 0))
        sim._state.x[sim._state.slots([0])] = position
        sim._state.info[:] = 0
        sim.run(steps=3)
        forces.append(sim.forces[0].copy())
    assert np.linalg.norm(forces[1]) > 0
    np.testing.assert_allclose(forces[0], forces[1], rtol=1e-9)


def test_a_rotating_disk_drags_a_resting_sphere_with_its_surface_velocity():
    """A turntable (a disk mesh spinning at 3 rad/s about its axis, z) under a sphere at r = 0.05:
    friction brings the sphere's contact point to the surface velocity there, omega x r = 0.15 m/s
    (it then rolls without slip, its velocity at the contact point v + w x (-R z) equals the
    surface's within 1 %), and the disk's load is the contact force, reversed."""
    sim = rd.Simulation(gravity=(0, 0, -9.81), dt=2e-6)
    sim.add_material(rd.Material("m", 1e7, 0.3, 1000.0, friction=0.5, restitution=0.5))
    disk = sim.add_wall(rd.MeshWall.shape("disk", radius=0.2, segments=24, material="m",
                                          angular_velocity=(0, 0, 3.0), name="disk"))
    sim.add_particles([[0.05, 0.0, 0.005]], 0.005, "m")
    sim.run(0.1)
    loads = sim.wall_loads()["disk"]
    r = sim.positions[0, :2]
    assert disk.point == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    v_contact = sim.velocities[0] + np.cross(sim.angular_velocities[0], [0, 0, -0.005])
    surface = np.cross([0, 0, 3.0], [*r, 0.0])
    assert np.linalg.norm(v_contact - surface) < 0.01 * np.linalg.norm(surface)
    contact_force = sim.forces[0] - sim.masses[0] * np.array([0, 0, -9.81])
    assert loads["force"] == pytest.approx(tuple(-contact_force), rel=1e-9, abs=1e-12)


def test_wall_loads_of_a_plane_carry_the_weight_and_its_moment():
    """Ten spheres at rest on a plane: the plane's force is their weight, its torque about its
    point the weight's moment, sum of x_k x (-m_k g), each to 1e-6 (the bed settles to 1e-6)."""
    sim = rd.Simulation(gravity=(0, 0, -9.81))
    sim.add_material(rd.Material("m", 1e7, 0.3, 1000.0, friction=0.5, restitution=0.3))
    sim.add_wall(rd.Plane(material="m", name="floor"))
    x = np.column_stack([np.linspace(-0.1, 0.1, 10), np.linspace(0, 0.05, 10), np.full(10, 0.005)])
    sim.add_particles(x, 0.005, "m")
    sim.run(0.2)
    loads = sim.wall_loads()["floor"]
    weight = sim.masses.sum() * 9.81
    assert loads["force"] == pytest.approx((0, 0, -weight), rel=1e-6, abs=1e-6 * weight)
    moment = np.cross(sim.positions * [1, 1, 0], sim.masses[:, None] * np.array([0, 0, -9.81])).sum(axis=0)
    assert loads["torque"] == pytest.approx(tuple(moment), rel=1e-6, abs=1e-6 * abs(moment).max())


def test_case_2_up_a_10_degree_tessellated_slope_reaches_the_analytic_height():
    """Case 2 (docs/models.md §13 T4) with EPSD on the random tessellation: x_max within 0.5 % of
    the analytic 0.104204 m, and then the sphere holds (drift below 1e-7 m/s over the last second):
    the rolling spring is not lost at the edges it rolls over."""
    traj = ss.rolling_slope_run("epsd", wall=tessellated_wall)
    x_max = ss.analytic_slope()[0]
    assert x_max == pytest.approx(0.104204, abs=1e-6)
    assert traj.x.max() == pytest.approx(x_max, rel=5e-3)
    assert abs(ss.creep_speed(traj)) < 1e-7


@pytest.mark.slow
def test_case_0_critical_rolling_friction_on_the_tessellation_is_tan_beta():
    """Case 0 (docs/models.md §13 T3) with EPSD at 20 degrees on the random tessellation: the
    critical mu_r by bisection within 0.5 % of tan 20 deg."""
    mu_c = ss.critical_rolling_friction("epsd", 20.0, wall=tessellated_wall)
    assert mu_c / math.tan(math.radians(20.0)) == pytest.approx(1.0, abs=5e-3)


@pytest.mark.parametrize("where", ["vertex", "edge", "face"])
def test_epsd_holds_a_sphere_on_a_10_degree_tessellated_slope(where):
    """Case 2's hold (docs/models.md §13 T4): EPSD at mu_r = 0.2 > tan 10 deg holds a sphere at
    rest on the tessellated plane, gravity tilted to 10 deg, with drift below 1e-7 m/s over 1 s,
    when it rests on a vertex, on an edge and on a face (a rolling spring that reset when the
    contact moved to another triangle would let it creep)."""
    v, t = TESSELLATION
    centre = np.abs(v[:, :2] - [0.1, 0.0]).sum(axis=1).argmin()
    tri = np.nonzero((t == centre).any(axis=1))[0][0]
    a, b, c = v[t[tri]]
    at = {"vertex": v[centre], "edge": 0.5 * (a + b), "face": (a + b + c) / 3}[where][:2]
    sim = ss.sphere_on_wall("epsd", settle=0.05, wall=tessellated_wall, at=at)
    for k in range(1, 201):
        b = ss.SLOPE * k / 200
        sim.gravity = (ss.G * math.sin(b), 0.0, -ss.G * math.cos(b))
        sim.run(steps=100)
    sim.run(0.1)
    x0 = sim.positions[0, 0]
    sim.run(1.0)
    assert abs(sim.positions[0, 0] - x0) / 1.0 < 1e-7


def test_bad_mesh_walls_are_refused_with_one_line(tmp_path):
    """A missing file, a shape that does not exist or lacks a dimension, and a mesh smaller than one
    particle (a file in mm read as m, or the reverse) each get one line naming what is wrong."""
    with pytest.raises(ParameterError, match="not found"):
        rd.MeshWall.from_file(tmp_path / "nothing.stl")
    with pytest.raises(ParameterError, match="'cone' is not known"):
        rd.MeshWall.shape("cone", radius=1.0)
    with pytest.raises(ParameterError, match="length missing"):
        rd.MeshWall.shape("drum", radius=1.0)
    path = rd.MeshWall.shape("box", size=(1.0, 1.0, 1.0)).mesh.write(tmp_path / "box_mm.stl")
    sim = rd.Simulation()
    sim.add_material(rd.Material("m", 1e7, 0.3, 1000.0))
    sim.add_particles([[0.5, 0.5, 0.5]], 0.005, "m")
    with pytest.raises(ParameterError, match="smaller than one particle"):
        sim.add_wall(rd.MeshWall.from_file(path, scale=0.001, material="m"))


def test_a_sphere_shot_through_a_thin_mesh_is_an_error_naming_it():
    """A sphere at 20 m/s against a single sheet, with a skin large enough that the speed check
    lets it through: the run stops with the particle, the wall and the step, not a silent pass."""
    sim = rd.Simulation(gravity=(0, 0, 0), dt=1e-4, skin=0.05, check_timestep=False)
    sim.add_material(rd.Material("m", 1e5, 0.3, 1000.0))
    sim.add_wall(rd.MeshWall([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], [[0, 1, 2]], material="m", name="sheet"))
    sim.add_particles([[0, 0, 0.02]], 0.005, "m", velocity=(0, 0, -20.0))
    with pytest.raises(SimulationError, match="particle 0 passed through mesh wall 'sheet'"):
        sim.run(steps=100)


def test_a_checkpoint_of_a_turning_mesh_continues_bit_for_bit(tmp_path):
    """Spheres on a tilted, turning tessellated plate: a run of 2 x 2000 steps with a checkpoint
    and restore between equals one run of 4000 steps exactly (positions, mesh vertices, load)."""
    v, t = tessellated_plane((-0.03, 0.03), (-0.03, 0.03), spacing=0.006)

    def scene():
        sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), gravity=(1.0, 0, -9.81), dt=2e-6)
        sim.add_material(rd.Material("m", 1e7, 0.3, 1000.0, friction=0.5, rolling_friction=0.1))
        sim.add_wall(rd.MeshWall(v, t, material="m", angular_velocity=(0, 0.5, 0.3), point=(0, 0, -0.01),
                                 name="plate"))
        sim.add_particles([[x, y, 0.00399] for x in (-0.01, 0.0, 0.01) for y in (-0.01, 0.01)], 0.004, "m",
                          allow_overlap=True)
        return sim

    one = scene()
    one.run(steps=4000)
    two = scene()
    two.run(steps=2000)
    two.checkpoint(tmp_path / "c.npz")
    three = rd.Simulation.restore(tmp_path / "c.npz")
    three.run(steps=2000)
    assert one.number_of_contacts() >= 6
    np.testing.assert_array_equal(three.positions, one.positions)
    np.testing.assert_array_equal(three.walls[0].mesh.vertices, one.walls[0].mesh.vertices)
    assert three.wall_loads() == one.wall_loads()


CASE = """\
name: dish
dt: 1.0e-5
materials:
  - {name: m, youngs_modulus: 1.0e7, poisson_ratio: 0.3, density: 1000.0, friction: 0.5, restitution: 0.5}
walls:
  - type: mesh
    name: dish
    material: m
    file: dish.stl
    scale: 0.001
    motion: {rotate: {axis: [0, 0, 1], point: [0, 0, 0], angular_velocity: 2.0}}
particles:
  - positions: [[0.02, 0, 0.00499], [-0.02, 0, 0.00499]]
    radius: 0.005
    material: m
    allow_overlap: true
stages:
  - {name: turn, duration: 0.01}
  - name: stop
    duration: 0.01
    wall_motion: [{wall: dish, velocity: [0, 0, 0]}]
output:
  time_series: {interval: 0.005}
  snapshots: {interval: 0.005}
  plot: false
"""


def test_a_case_file_runs_a_turning_mesh_from_an_stl_in_mm_and_writes_its_series(tmp_path):
    """A disk written as STL in mm, read at scale 0.001 next to the case file, turning at 2 rad/s
    for 0.01 s, then stopped (the stage's wall_motion): the snapshots hold the dish's own VTU series,
    turned by 0.02 rad at t = 0.01 s, and no file after it (the dish no longer moves); the time series holds the dish's force,
    the two spheres' weight to 1 %."""
    import meshio
    from typer.testing import CliRunner

    from rollingdem.cli import app
    from rollingdem.scene.mesh import disk

    disk(100.0, segments=12).write(tmp_path / "dish.stl")  # in mm
    reference = rd.TriangleMesh.from_file(tmp_path / "dish.stl", scale=0.001)  # its vertices in the wall's order
    (tmp_path / "case.yaml").write_text(CASE)
    result = CliRunner().invoke(app, ["run", str(tmp_path / "case.yaml"), "--out", str(tmp_path / "out"),
                                      "--no-progress"])
    assert result.exit_code == 0, result.output
    snaps = tmp_path / "out" / "snapshots"
    assert (snaps / "wall_dish.pvd").exists()
    turned = meshio.read(snaps / "wall_dish_000001000.vtu").points
    import xml.etree.ElementTree as ET

    files = [d.get("file") for d in ET.parse(snaps / "wall_dish.pvd").getroot().iter("DataSet")]
    assert files[-1] == "wall_dish_000001000.vtu"  # stopped: no file after, ParaView holds this one
    angle = np.arctan2(turned[:, 1], turned[:, 0]) - np.arctan2(reference.vertices[:, 1], reference.vertices[:, 0])
    rim = np.linalg.norm(reference.vertices, axis=1) > 0
    np.testing.assert_allclose(np.mod(angle[rim] + np.pi, 2 * np.pi) - np.pi, 0.02, atol=1e-9)
    import pandas as pd

    series = pd.read_csv(tmp_path / "out" / "series.csv")
    weight = 2 * 1000.0 * 4 / 3 * np.pi * 0.005 ** 3 * 9.81
    assert series["wall_dish_fz"].iloc[-1] == pytest.approx(-weight, rel=0.01)


@pytest.mark.parametrize("problem,vertices,triangles,expected", [
    ("non-manifold", [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]], [[0, 1, 2], [0, 1, 3], [0, 1, 4]],
     "is shared by more than two triangles"),
])
def test_a_case_file_refuses_a_broken_mesh_file_naming_it(tmp_path, problem, vertices, triangles, expected):
    """A mesh file with an edge of three triangles: exit status 2, one line naming the file and the
    problem. (A triangle of no area is dropped and counted: the next test.)"""
    import meshio
    from typer.testing import CliRunner

    from rollingdem.cli import app

    meshio.write(tmp_path / "dish.stl", meshio.Mesh(np.array(vertices, dtype=float), [("triangle", np.array(triangles))]))
    (tmp_path / "case.yaml").write_text(CASE)
    result = CliRunner().invoke(app, ["check", str(tmp_path / "case.yaml")])
    assert result.exit_code == 2
    assert result.output.count("\n") == 1 and "dish.stl" in result.output and expected in result.output, result.output


def test_check_drops_and_counts_a_triangle_of_no_area_in_a_mesh_file(tmp_path):
    """A mesh file whose second triangle has its three corners on a line: ``check`` says valid and
    that one degenerate triangle was dropped, leaving one."""
    import meshio
    from typer.testing import CliRunner

    from rollingdem.cli import app

    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], dtype=float) * 50.0  # mm
    meshio.write(tmp_path / "dish.stl", meshio.Mesh(vertices, [("triangle", np.array([[0, 1, 2], [0, 1, 3]]))]))
    (tmp_path / "case.yaml").write_text(CASE)
    result = CliRunner().invoke(app, ["check", str(tmp_path / "case.yaml")])
    assert result.exit_code == 0, result.output
    assert ", 1 triangles, 3 free edges" in result.output and "degenerate triangles dropped: 1" in result.output


# --- acceptance runs (slow: their figures are in issue 27's closing note) ------------------------
def default_case_with_a_mesh_tube(segments):
    """The built-in default case (4,000 spheres settle in a tube on a rough base, the tube is lifted
    off the pile), its tube the analytic cylinder (``segments`` None) or an open mesh tube of
    ``segments`` flat sides through the cylinder's radius."""
    from rollingdem.io.casefile import default_case_path, load_case
    from rollingdem.io.mapping_file import read_mapping

    data = read_mapping(default_case_path())[0]
    if segments is not None:
        data["walls"][1] = {"type": "mesh", "name": "tube", "material": "table1", "shape": "drum",
                            "size": {"radius": data["walls"][1]["radius"], "length": 1.3, "segments": segments,
                                     "caps": False}}
    data["output"] = {"time_series": None, "plot": False}
    return load_case(data)


@pytest.mark.slow
def test_a_96_sided_mesh_tube_settles_the_default_column_as_the_cylinder_does():
    """The default case's settle stage with the tube as 96 triangles' strips: the settled column's
    height (mean top of its highest 50 spheres) within 2 % of the analytic cylinder's. The mesh's
    flat sides lie 0.05 % inside the circle (1 - cos(pi/96)); a contact counted twice, or lost at
    the strips' edges, would change the wall friction that holds the column up by far more."""
    from rollingdem.io.casefile import build_simulation

    heights = []
    for segments in (None, 96):
        sim = build_simulation(default_case_with_a_mesh_tube(segments))
        sim.run(0.6)
        top = np.sort(sim.positions[:, 2] + sim.radii)[-50:]
        heights.append(top.mean())
    assert heights[1] == pytest.approx(heights[0], rel=0.02)


@pytest.mark.slow
def test_a_turning_drum_carries_its_bed_as_a_solid_body_and_reports_the_driving_torque():
    """A closed 96-sided drum (radius 0.1 m, 0.012 m long, its axis z, gravity along -y) a quarter
    full of 1,800 spheres of 2 mm, its wall friction 1.0 (the bed does not slide on it), turned at
    0.8 rad/s from rest. With mu_r = 0.2 the bed is in the slumping regime: it turns with the drum
    as a solid body until its surface passes its angle of stability (the first 0.4 s, 18 degrees,
    are well before), then avalanches. In that solid-body phase the spheres between 0.5 R and
    0.95 R move at omega x r within 2 % (the mean projection at each of 8 samples), and the torque
    the bed puts on the drum about its axis equals the moment of the bed's weight about the axis
    at each sample (the bed's angular momentum is steady) within 0.5 % of M g R, the moment of the
    whole bed's weight at the drum's radius (the contacts' chatter). Over the following second
    of avalanches the two agree on average within 3 standard errors (10 blocks of 0.1 s)."""
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), gravity=(0, -9.81, 0), dt=1e-5)
    sim.add_material(rd.Material("glass", 1e7, 0.3, 2500.0, friction=0.5, rolling_friction=0.2, restitution=0.5))
    sim.add_material(rd.Material("steel", 1e7, 0.3, 2500.0, friction=0.5, rolling_friction=0.2, restitution=0.5))
    sim.set_pair("glass", "steel", friction=1.0)
    drum = sim.add_wall(rd.MeshWall.shape("drum", radius=0.1, length=0.012, segments=96, material="steel",
                                          name="drum"))
    sim.insert(rd.CylinderRegion(0.095, 0.0021, 0.0099), 1800, 0.002, "glass", seed=3)
    sim.run(0.3)
    omega = np.array([0.0, 0.0, 0.8])
    sim.set_wall_velocity("drum", angular_velocity=omega)
    axis_point = np.array(drum.point)
    assert axis_point[:2] == pytest.approx((0.0, 0.0), abs=1e-12)

    def sample():
        d = sim.positions - axis_point
        d[:, 2] = 0.0
        r = np.hypot(d[:, 0], d[:, 1])
        bed = (r > 0.5 * 0.1) & (r < 0.95 * 0.1)
        solid = np.cross(omega, d)
        ratio = np.sum(sim.velocities[bed] * solid[bed]) / np.sum(solid[bed] ** 2)
        weight_moment = np.cross(d, sim.masses[:, None] * np.array([0, -9.81, 0])).sum(axis=0)[2]
        return ratio, sim.wall_loads()["drum"]["torque"][2], weight_moment

    sim.run(0.05)
    for _ in range(8):
        sim.run(0.05)
        ratio, torque, weight_moment = sample()
        assert ratio == pytest.approx(1.0, abs=0.02)
        assert abs(torque - weight_moment) < 0.005 * sim.masses.sum() * 9.81 * 0.1
    sim.run(0.6)
    torque, weight_moment = [], []
    for _ in range(100):
        sim.run(0.01)
        _, t, m = sample()
        torque.append(t)
        weight_moment.append(m)
    blocks = (np.array(torque) - np.array(weight_moment)).reshape(10, 10).mean(axis=1)
    assert abs(blocks.mean()) < 3 * blocks.std(ddof=1) / math.sqrt(len(blocks))
    assert abs(np.mean(weight_moment)) > 0.05 * 1800 * sim.masses[0] * 9.81 * 0.1  # the bed leans


def test_re_sorting_the_storage_slots_keeps_every_mesh_contact():
    """The engine re-sorts large scenes' storage slots in space: the mesh contact slots and the
    candidate rows go with their spheres, so a run with a re-sort in the middle equals one
    without, bit for bit."""
    v, t = tessellated_plane((-0.03, 0.03), (-0.03, 0.03), spacing=0.006)

    def scene():
        sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), gravity=(2.0, 1.0, -9.81), dt=2e-6)
        sim.add_material(rd.Material("m", 1e7, 0.3, 1000.0, friction=0.5, rolling_friction=0.1))
        sim.add_wall(rd.MeshWall(v, t, material="m", name="plate"))
        rng = np.random.default_rng(4)
        xy = np.array([[x, y] for x in np.linspace(-0.02, 0.02, 6) for y in np.linspace(-0.02, 0.02, 6)])
        sim.add_particles(np.column_stack([xy[rng.permutation(36)], np.full(36, 0.00299)]), 0.003, "m",
                          allow_overlap=True)
        return sim

    plain, sorted_ = scene(), scene()
    plain.run(steps=15000)
    sorted_.run(steps=15000)
    assert plain.number_of_contacts() > 20
    sorted_._state.sort(0.007)
    assert sorted_._state._slots is not None and not np.array_equal(sorted_._state.ids, np.arange(36))
    plain.run(steps=1500)
    sorted_.run(steps=1500)
    np.testing.assert_array_equal(sorted_.positions, plain.positions)
    np.testing.assert_array_equal(sorted_.angular_velocities, plain.angular_velocities)


def test_contact_forces_refuse_a_scene_touching_a_mesh_in_one_line():
    """``Simulation.contact_forces`` does not list mesh contacts (their contact points are not kept):
    with a sphere on a mesh it is refused, rather than a list that silently lacks them."""
    sim = rd.Simulation(gravity=(0, 0, 0), dt=1e-9, check_timestep=False)
    sim.add_material(rd.Material("m", 1e7, 0.3, 1000.0, friction=0.5))
    sim.add_wall(rd.MeshWall(*ridge()))
    sim.add_particles([[0.1, 0.0, 0.009]], 0.01, "m", allow_overlap=True)
    sim.run(steps=1)
    assert sim.number_of_contacts() == 1
    with pytest.raises(rd.SimulationError, match="not available while spheres touch a triangle-mesh wall"):
        sim.contact_forces()
