"""Programmed wall motion (issue 45, item 2): an oscillation, a table of times and a servo, on planes
and meshes, in Python and case files; each against its analytic trajectory or target, and resumed
from a checkpoint bit for bit."""

import hashlib
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

import rollingdem as rd
from rollingdem.cli import app

G = 9.81
R = 1e-3


def material(sim, friction=0.5):
    sim.add_material(rd.Material("m", youngs_modulus=1e7, poisson_ratio=0.3, density=2500.0, friction=friction,
                                 restitution=0.5))


def sphere_on_floor(motion=None, friction=0.5):
    """One sphere at rest on a plane at z = 0 (Hertz, no rolling resistance)."""
    sim = rd.Simulation(gravity=(0, 0, -G), dt=5e-6)
    material(sim, friction)
    floor = sim.add_wall(rd.Plane(material="m", name="floor"))
    sim.add_particles([[0, 0, R]], radius=R, material="m")
    sim.run(0.02)
    if motion is not None:
        sim.set_wall_motion(floor, motion)
    return sim, floor


@pytest.mark.parametrize("gamma,leaves", [(0.8, False), (1.5, True)])
def test_a_sphere_leaves_a_plate_shaken_above_one_g(gamma, leaves):
    """A plate shaken vertically at peak acceleration Gamma g (Gamma = A (2 pi f)^2 / g) holds a
    resting sphere below Gamma = 1 and throws it off above: the plate can pull the sphere down no
    faster than g. Gamma = 0.8 and 1.5 leave a margin of 20 % and 50 % either side for the contact's
    compliance (its spring's natural frequency, some 2 kHz here, is 100 times the shaking's 20 Hz,
    which changes the sphere's response by 1e-4). A factor lost on the amplitude or the 2 pi of the
    frequency moves Gamma across 1."""
    f = 20.0
    amplitude = gamma * G / (2.0 * math.pi * f) ** 2
    # phase pi/2: the plate starts at rest (at phase 0 it would strike the sphere at A 2 pi f)
    sim, floor = sphere_on_floor(rd.Oscillation(frequency=f, amplitude=(0, 0, amplitude), phase=math.pi / 2))
    t0, touching = sim.time, []
    for k in range(150):  # three periods, every 1 ms
        sim.run(1e-3)
        if k >= 50:  # after the first period: the plate's jump to -Gamma g at the start sets the contact ringing
            touching.append(sim.wall_loads()["floor"]["force"][2] < 0.0)  # the sphere presses on the plate
        expected = amplitude * (math.cos(2.0 * math.pi * f * (sim.time - t0)) - 1.0)
        # the plate is where sin puts it, but for the rounding of the time summed step by step
        assert abs(floor.point[2] - expected) < 1e-9 * amplitude
    assert (not all(touching)) == leaves, touching


def test_a_sphere_rolls_two_sevenths_of_a_plate_shaken_sideways():
    """A plate oscillating horizontally, x_p = A (cos(2 pi f t) - 1) (phase pi/2: at rest at first),
    drags a resting sphere only through its contact's surface velocity (the plane's geometry does not
    change as it slides in itself). Rolling without slip, m a = F and (2/5) m R^2 alpha = F R give a
    = (2/7) a_p, so the sphere's centre moves (2/7) x_p. Slip needs (2/7) A (2 pi f)^2 > mu g: 0.56
    against 4.9 m/s^2 here. The tangential spring's stretch (F / k_t, 1e-9 m) and the contact's
    damping are 1e-6 of A: the tolerance, 1 % of the sphere's travel, leaves room for them and
    catches a contact that sees the plate's velocity wrong by more than 1 %."""
    f, amplitude = 5.0, 2e-3
    sim, floor = sphere_on_floor(rd.Oscillation(frequency=f, amplitude=(amplitude, 0, 0), phase=math.pi / 2))
    t0, x0 = sim.time, sim.positions[0, 0]
    worst = 0.0
    for _ in range(20):
        sim.run(0.01)
        plate = amplitude * (math.cos(2.0 * math.pi * f * (sim.time - t0)) - 1.0)
        assert floor.point[0] == pytest.approx(plate, abs=1e-9 * amplitude)
        worst = max(worst, abs((sim.positions[0, 0] - x0) - 2.0 / 7.0 * plate))
    assert worst < 0.01 * (2.0 / 7.0) * 2.0 * amplitude, worst


def test_a_sphere_rolls_two_sevenths_of_a_mesh_plate_shaken_sideways():
    """The same on a flat mesh plate (two triangles, 0.2 m square) moved by the same program: the
    mesh's contact sees the step's velocity of its surface (``surface_velocity``), so the sphere
    rolls 2/7 of the plate's travel within the same 1 %."""
    f, amplitude = 5.0, 2e-3
    sim = rd.Simulation(gravity=(0, 0, -G), dt=5e-6)
    material(sim)
    square = [[-0.1, -0.1, 0], [0.1, -0.1, 0], [0.1, 0.1, 0], [-0.1, 0.1, 0]]
    plate = sim.add_wall(rd.MeshWall(square, [[0, 1, 2], [0, 2, 3]], material="m", name="plate"))
    sim.add_particles([[0.01, 0.01, R]], radius=R, material="m")  # off the diagonal: a face contact
    sim.run(0.02)
    sim.set_wall_motion(plate, rd.Oscillation(frequency=f, amplitude=(amplitude, 0, 0), phase=math.pi / 2))
    t0, x0, p0 = sim.time, sim.positions[0, 0], plate.point[0]
    worst = 0.0
    for _ in range(20):
        sim.run(0.01)
        travel = amplitude * (math.cos(2.0 * math.pi * f * (sim.time - t0)) - 1.0)
        assert plate.point[0] - p0 == pytest.approx(travel, abs=1e-9 * amplitude)
        worst = max(worst, abs((sim.positions[0, 0] - x0) - 2.0 / 7.0 * travel))
    assert worst < 0.01 * (2.0 / 7.0) * 2.0 * amplitude, worst


def mesh_tray(sim, motion, angular_velocity=(0, 0, 0)):
    return sim.add_wall(rd.MeshWall.shape("box", material="m", name="tray", size=(0.05, 0.05, 0.02),
                                          point=(0.025, 0.025, 0.0), angular_velocity=angular_velocity,
                                          motion=motion))


@pytest.mark.parametrize("program", ["oscillation", "table", "table, repeated"])
def test_a_mesh_follows_its_program_exactly(program):
    """Every vertex of a turning, moving mesh where the program puts it, p + v t + d(t) + R(theta(t))
    (x0 - p), theta about the program's axis (the steady turn along it added), computed here with
    scipy's rotations and numpy's interpolation: to 1e-14 m, the rounding of 0.05 m coordinates
    (positions come from t, not from summed steps)."""
    sim = rd.Simulation(gravity=(0, 0, -G), dt=1e-5)
    material(sim)
    spin = 0.0
    if program == "oscillation":
        motion, spin = rd.Oscillation(frequency=5.0, amplitude=(1e-3, -2e-3, 0), angle=0.2, axis=(0, 0, 1),
                                      phase=0.4), 1.0
    else:
        motion = rd.MotionTable([0, 0.01, 0.03, 0.04], [[0, 0, 0], [0, 0, 1e-3], [2e-3, 0, 1e-3], [0, 0, 0]],
                                [0, 0.1, 0.1, 0], axis=(0, 0, 1), repeat=program.endswith("repeated"))
    tray = mesh_tray(sim, motion, (0, 0, spin))
    start, p = tray.mesh.vertices.copy(), np.array(tray.point)
    sim.add_particles([[0.025, 0.025, 0.0025]], radius=2e-3, material="m")
    for _ in range(4):
        sim.run(0.013)
        t = sim.time
        shift, angle = motion.position(t)
        turn = Rotation.from_rotvec(np.array([0, 0, 1.0]) * (angle + spin * t))
        expected = p + np.array(shift) + turn.apply(start - p)
        assert np.abs(sim.mesh_walls()["tray"].vertices - expected).max() < 1e-14
    if program == "table":  # past its last row the table holds
        assert np.abs(sim.mesh_walls()["tray"].vertices - start).max() < 1e-14


def test_the_table_interpolates_and_repeats():
    """The table's own position against values worked by hand: halfway between rows, held after the
    last, and with repeat one period on."""
    table = rd.MotionTable([1.0, 2.0, 4.0], [[0, 0, 0], [2, 0, 0], [2, 4, 0]], repeat=False)
    assert table.position(0.5)[0] == pytest.approx((1, 0, 0))
    assert table.position(2.0)[0] == pytest.approx((2, 2, 0))
    assert table.position(10.0)[0] == pytest.approx((2, 4, 0))
    loop = rd.MotionTable([0, 1, 2], [[0, 0, 0], [0, 0, 1], [0, 0, 0]], repeat=True)
    assert loop.position(2.5)[0] == pytest.approx((0, 0, 0.5))


def servo_box(target=None, pressure=2000.0):
    """300 spheres of 1 mm settled in a 20 mm square box, under a lid 1 mm above the packing that a
    servo presses down to hold ``pressure`` (Pa) on the box's area."""
    sim = rd.Simulation(contact=rd.ContactModel("hooke"), gravity=(0, 0, -G))
    material(sim, 0.3)
    side = 0.02
    for point, normal in [((0, 0, 0), (0, 0, 1)), ((-side / 2, 0, 0), (1, 0, 0)), ((side / 2, 0, 0), (-1, 0, 0)),
                          ((0, -side / 2, 0), (0, 1, 0)), ((0, side / 2, 0), (0, -1, 0))]:
        sim.add_wall(rd.Plane(point=point, normal=normal, material="m"))
    sim.insert(rd.BoxRegion((-side / 2, -side / 2, 0), (side / 2, side / 2, 0.04)), 300, R, "m", seed=1)
    sim.run(0.3)
    top = float((sim.positions[:, 2] + R).max())
    servo = rd.Servo(direction=(0, 0, -1), pressure=pressure, area=side * side, max_speed=0.05)
    lid = sim.add_wall(rd.Plane(point=(0, 0, top + 1e-3), normal=(0, 0, -1), material="m", name="lid", motion=servo))
    return sim, lid, servo, side * side


def test_a_servo_lid_holds_its_pressure():
    """The lid comes down at its speed limit while nothing touches it (1e-3 m in 0.02 s at 0.05 m/s:
    the clamp), then holds the target: its load, sampled every 1 ms over the last 0.05 s of 0.2 s,
    within 1 % of 2000 Pa on 4 cm^2 (the issue's tolerance; with the default gain the loop's
    per-step gain G k dt is 1e-3 or so, and the load settles to the target as 1 - exp(-t / 10 ms)).
    Asked for twice the pressure it moves further down and holds that."""
    sim, lid, servo, area = servo_box()
    z0, t0 = lid.point[2], sim.time
    sim.run(0.01)
    assert sim.wall_loads()["lid"]["force"][2] == 0.0
    assert z0 - lid.point[2] == pytest.approx(0.05 * (sim.time - t0), rel=1e-9)
    sim.run(0.14)
    held = []
    for _ in range(50):
        sim.run(1e-3)
        held.append(sim.wall_loads()["lid"]["force"][2] / area)
    assert np.abs(np.array(held) / 2000.0 - 1.0).max() < 0.01, (min(held), max(held))
    z1 = lid.point[2]
    sim.set_wall_motion("lid", rd.Servo(direction=(0, 0, -1), pressure=4000.0, area=area, max_speed=0.05))
    sim.run(0.15)
    assert lid.point[2] < z1
    assert sim.wall_loads()["lid"]["force"][2] / area == pytest.approx(4000.0, rel=0.01)


def programmed_scene():
    """A shaken floor, a box mesh following a repeated table, 200 spheres; after 0.2 s a servo lid."""
    sim = rd.Simulation(contact=rd.ContactModel("hooke"), gravity=(0, 0, -G))
    material(sim, 0.3)
    side = 0.02
    sim.add_wall(rd.Plane(material="m", name="floor", motion=rd.Oscillation(30.0, amplitude=(0, 0, 1e-4))))
    table = rd.MotionTable([0, 0.02, 0.04], [[0, 0, 0], [2e-3, 0, 0], [0, 0, 0]], [0, 0.05, 0], axis=(0, 0, 1),
                           repeat=True)
    sim.add_wall(rd.MeshWall.shape("box", material="m", name="box", size=(side, side, 0.05), point=(0.01, 0.01, 0),
                                   motion=table))
    sim.insert(rd.BoxRegion((1e-3, 1e-3, 1e-3), (side - 1e-3, side - 1e-3, 0.04)), 200, R, "m", seed=1)
    sim.run(0.2)
    sim.add_wall(rd.Plane(point=(0, 0, 0.007), normal=(0, 0, -1), material="m", name="lid",
                          motion=rd.Servo((0, 0, -1), 0.05, force=0.5)))
    return sim


def test_programs_resume_from_a_checkpoint_bit_for_bit(tmp_path):
    """A run resumed from a checkpoint taken while an oscillation, a repeating table and a servo are
    under way ends where the uninterrupted run ends, bit for bit; removing another wall between runs
    leaves the floor's oscillation on its sine (it goes on, it does not start again)."""
    sim = programmed_scene()
    sim.run(0.03)
    sim.checkpoint(tmp_path / "c.npz")
    sim.run(0.03)
    resumed = rd.Simulation.restore(tmp_path / "c.npz")
    resumed.run(0.03)
    digest = [hashlib.sha1(s.positions.tobytes()).hexdigest() for s in (sim, resumed)]
    assert digest[0] == digest[1]
    assert resumed.walls[2].point == sim.walls[2].point
    assert sim.wall_loads()["lid"]["force"][2] > 0.0  # the servo has reached the packing
    sim.remove_wall("lid")
    sim.run(0.011)
    assert sim.walls[0].point[2] == pytest.approx(1e-4 * math.sin(2 * math.pi * 30.0 * sim.time), abs=1e-15)


CASE = """\
name: shaken
materials:
  - {name: m, youngs_modulus: 1.0e7, poisson_ratio: 0.3, density: 2500.0, friction: 0.5, restitution: 0.5}
walls:
  - {type: plane, name: floor, material: m, oscillate: {frequency: 20, amplitude: [0, 0, 0.0002], phase: 90}}
  - type: mesh
    name: tray
    material: m
    shape: box
    size: {size: [0.05, 0.05, 0.02]}
    place: {translate: [-0.025, -0.025, -0.01]}
    motion: {table: {file: tray.csv, axis: [0, 0, 1]}}
  - {type: plane, name: lid, material: m, point: [0, 0, 0.0045], normal: [0, 0, -1]}
particles:
  - {positions: [[0, 0, 0.001]], radius: 0.001, material: m}
stages:
  - {name: shake, duration: 0.02}
  - {name: press, duration: 0.01, wall_motion: [{wall: lid, servo: {direction: [0, 0, -1], max_speed: 0.05, force: 1.0}}]}
output:
  plot: false
"""


def test_a_case_file_moves_its_walls_as_the_python_api_does(tmp_path):
    """A case file's oscillate (phase in degrees), table (a CSV file, angles in degrees) and a stage's
    servo build the same programs as Python's, and the run leaves each wall where its program puts
    it: the floor at A (sin(2 pi f t + 90 deg) - 1) (to 1e-13 m: the time summed step by step), the tray's table held at its last row, the lid
    down by its speed limit times the stage (it touches nothing)."""
    from rollingdem.io.casefile import build_simulation, load_case
    from rollingdem.io.runner import run_case

    (tmp_path / "tray.csv").write_text("t, dx, dz, angle\n0, 0, 0, 0\n0.01, 0.001, 0, 5\n0.015, 0.001, 0, 5\n")
    (tmp_path / "case.yaml").write_text(CASE)
    sim = build_simulation(load_case(tmp_path / "case.yaml"))
    floor, tray = sim.walls[0], sim.walls[1]
    assert floor.motion.describe() == rd.Oscillation(20.0, (0, 0, 2e-4), phase=math.pi / 2).describe()
    assert tray.motion.describe() == rd.MotionTable([0, 0.01, 0.015], [[0, 0, 0], [1e-3, 0, 0], [1e-3, 0, 0]],
                                                    np.radians([0, 5, 5]), axis=(0, 0, 1)).describe()
    checked = CliRunner().invoke(app, ["check", str(tmp_path / "case.yaml")])
    assert checked.exit_code == 0, checked.output
    ran = run_case(load_case(tmp_path / "case.yaml"), tmp_path / "out", progress=False, echo=lambda *a: None)
    end = rd.Simulation.restore(tmp_path / "out" / "final.npz")
    t = end.time
    assert t == pytest.approx(0.03, abs=2 * end.dt)  # each stage a whole number of steps
    assert end.walls[0].point[2] == pytest.approx(2e-4 * (math.cos(2 * math.pi * 20.0 * t) - 1.0), abs=1e-13)
    assert end.walls[2].point[2] == pytest.approx(0.0045 - 0.05 * 0.01, abs=0.05 * end.dt)
    centre = end.mesh_walls()["tray"].vertices.mean(axis=0)
    placed = sim.mesh_walls()["tray"].vertices
    turn = Rotation.from_rotvec([0, 0, math.radians(5)])
    point = np.array(sim.walls[1].point)
    expected = (point + [1e-3, 0, 0] + turn.apply(placed - point)).mean(axis=0)
    assert np.abs(centre - expected).max() < 1e-14
    assert ran["status"] == "ok"


def test_a_wall_measurement_reads_a_programmed_floor_s_power_and_travel():
    """A floor raised by a table at 0.02 m/s (one row at t = 1 s, 0.02 m up) carries a resting
    sphere: the power it gives the sphere is m g v averaged over the window, as for a floor with a
    steady velocity (the measurement takes the program's velocity, not the steady one, which is 0),
    and the measurement's z is the floor's travel, 0.02 t, at each sample (the time summed step by
    step: to 1e-12 m)."""
    sim = rd.Simulation(gravity=(0, 0, -G))
    sim.add_material(rd.Material("m", 1e7, 0.3, 2500.0, friction=0.5, restitution=0.1))
    sim.add_wall(rd.Plane(material="m", name="floor", motion=rd.MotionTable([0, 1], [[0, 0, 0], [0, 0, 0.02]])))
    sim.add_particles([[0, 0, R * 0.999]], R, "m", allow_overlap=True)
    load = rd.WallLoad("floor", wall="floor", interval=1e-3, window=(0.1, 0.3))
    sim.run(0.3, observers=[load])
    m = float(sim.masses[0])
    s = load.summary()
    assert s["power"]["mean"] == pytest.approx(m * G * 0.02, rel=2e-3)
    frame = load.series()
    assert np.abs(frame["z"] - 0.02 * frame["time"]).max() < 1e-12


def test_the_time_step_check_counts_the_walls_speed():
    """The Hertz time at impact falls with the impact speed (as v^-1/5), and a sphere at rest meets a
    moving wall at the wall's speed: a mesh drum turning at 1e5 rad/s (its farthest vertex 0.0539 m
    from the axis: 5.39e3 m/s) and a plate oscillating at 1 kHz by 1 mm (2 pi f A = 6.28 m/s) each
    set the impact speed of the limit; a dt above it is refused, naming it."""
    from rollingdem.scene.mesh import SHAPES

    drum = rd.Simulation(dt=1e-5)
    material(drum)
    drum.add_wall(rd.MeshWall(SHAPES["drum"](radius=0.05, length=0.02), material="m", angular_velocity=(0, 0, 1e5),
                              point=(0, 0, 0)))
    drum.add_particles([[0, 0, 0.01]], 2e-3, "m")
    with pytest.raises(rd.ParameterError, match=r"dt = 1e-05 s exceeds the stable limit .* at impact speed 5.39e\+03 m/s"):
        drum.run(steps=1)
    plate = rd.Simulation()
    material(plate)
    plate.add_wall(rd.Plane(material="m", motion=rd.Oscillation(1000.0, amplitude=(0, 0, 1e-3))))
    plate.add_particles([[0, 0, 2e-3]], 2e-3, "m")
    assert any("at impact speed 6.28 m/s" in label for label, _ in plate.time_step_limits())


def test_an_automatic_dt_is_lowered_when_the_speeds_outgrow_it():
    """A dt the checks chose follows the scene: a sphere launched at 20 m/s after it was chosen
    (the Hertz time at twice that speed now binds) lowers it to the new stable limit, with a warning
    that names both, and the run's duration is counted in the new steps; a dt the user gave is
    refused instead, as before."""
    sim = rd.Simulation()
    material(sim)
    sim.add_wall(rd.Plane(material="m"))
    sim.add_particles([[0, 0, 0.01]], 2e-3, "m")
    chosen = sim.dt
    sim.set_velocities([0], velocity=(0, 0, -20.0))
    limit = sim.stable_time_step()
    with pytest.warns(RuntimeWarning, match=f"dt is lowered from {chosen:.4g} s to .* at impact speed 40 m/s"):
        sim.run(1e-4)
    assert sim.dt < chosen and sim.dt == limit
    assert sim.time == pytest.approx(1e-4, abs=sim.dt)
    given = rd.Simulation(dt=chosen)
    material(given)
    given.add_wall(rd.Plane(material="m"))
    given.add_particles([[0, 0, 0.01]], 2e-3, "m", velocity=[[0, 0, -20.0]])
    with pytest.raises(rd.ParameterError, match=f"dt = {chosen:.4g} s exceeds the stable limit"):
        given.run(1e-4)


TWO_STAGES = """
name: fall-then-rest
gravity: [0, 0, 0]
materials:
  - {name: m, youngs_modulus: 1.0e7, poisson_ratio: 0.3, density: 2500.0, friction: 0.5, restitution: 0.5}
walls:
  - {type: plane, name: floor, material: m}
particles:
  - {positions: [[0, 0, 0.05]], radius: 0.002, material: m}
stages:
  - {name: launch, duration: 0.001, set_velocity: {particles: all, velocity: [0, 0, -20.0]}}
  - {name: still, duration: 0.001, set_velocity: {particles: all, velocity: [0, 0, 0]}}
output:
  plot: false
  report: null
"""


def test_each_stage_of_a_case_starts_at_its_own_stable_time_step(tmp_path):
    """An automatic dt is chosen again when a stage starts: the launch at 20 m/s steps at the Hertz
    time at impact (40 m/s) / 20, and the stage that stops the sphere goes back up to the step of a
    scene at rest (0.2 x the Rayleigh time), instead of keeping the launch's; each stage's duration is
    counted in its own steps. A dt the case gives stays through every stage."""
    from rollingdem.io.casefile import load_case
    from rollingdem.io.runner import run_case

    (tmp_path / "case.yaml").write_text(TWO_STAGES)
    ran = run_case(load_case(tmp_path / "case.yaml"), tmp_path / "out", progress=False, echo=lambda *a: None)
    launch, still = ran["stages"]
    sphere = rd.Simulation()
    material(sphere)
    sphere.add_wall(rd.Plane(material="m"))
    sphere.add_particles([[0, 0, 0.05]], 2e-3, "m")
    at_rest = sphere.stable_time_step()
    sphere.set_velocities([0], velocity=(0, 0, -20.0))
    launched = sphere.stable_time_step()
    assert launched < 0.75 * at_rest
    assert launch["steps"] == round(1e-3 / launched) and still["steps"] == round(1e-3 / at_rest)
    end = rd.Simulation.restore(tmp_path / "out" / "final.npz")
    assert end.dt == at_rest and end.time == pytest.approx(2e-3, abs=at_rest)
    given = TWO_STAGES.replace("gravity:", f"dt: {launched!r}\ngravity:")
    (tmp_path / "given.yaml").write_text(given)
    ran = run_case(load_case(tmp_path / "given.yaml"), tmp_path / "given", progress=False, echo=lambda *a: None)
    assert [s["steps"] for s in ran["stages"]] == [round(1e-3 / launched)] * 2


@pytest.mark.parametrize("make,match", [
    (lambda: rd.MotionTable([0, 1, 2], [[0, 0, 0], [0, 0, 1]]),
     r"motion table displacements = .* must be finite, three numbers \(x, y, z\) per time \(3 times\)"),
    (lambda: rd.MotionTable([0, 1], None, [0, float("nan")], axis=(0, 0, 1)),
     r"motion table angles = \[0.0, nan\] is not allowed: must be finite, one number per time"),
    (lambda: rd.MotionTable([0, 1], [[0, 0, 0], [0, 0, 1]], repeat=True),
     "motion table repeat = True is not allowed: the last row differs from the first"),
    (lambda: rd.Oscillation(10.0), r"oscillation amplitude = \(0, 0, 0\) is not allowed with angle = 0"),
    (lambda: rd.Oscillation(10.0, angle=0.1), "oscillation axis = None is not allowed with angle = 0.1 rad"),
    (lambda: rd.Servo((0, 0, -1), 0.1, force=1.0, area=0.01), "servo area = 0.01 is not allowed with force"),
    (lambda: rd.Plane(motion="shake"), "motion = 'shake' is not allowed: must be a rollingdem.Oscillation"),
])
def test_a_bad_program_is_refused_in_one_line(make, match):
    with pytest.raises(rd.ParameterError, match=match):
        make()


def test_observers_mid_run_see_each_wall_where_the_engine_has_it():
    """A floor moving sideways at 0.1 m/s, read by an observer every 1 ms during one run of 20 ms:
    its object is where the engine has moved it at each observation, p = p0 + v (t - t0), as the
    objects follow the engine after every call of the step loop. Tolerance 1e-12 m: the position is
    summed step by step (4,000 steps of 5e-7 m); a stale object would lag by at least a call's
    steps (1e-4 m at the observer's interval)."""
    sim, floor = sphere_on_floor()
    sim.set_wall_velocity(floor, velocity=(0.1, 0.0, 0.0))
    t0, x0, seen = sim.time, floor.point[0], []
    sim.run(0.02, observers=[rd.Callback(lambda s: seen.append((s.time, floor.point[0])), 1e-3)])
    assert len(seen) >= 20
    for t, x in seen:
        assert abs(x - (x0 + 0.1 * (t - t0))) < 1e-12, (t, x)
