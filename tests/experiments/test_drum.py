"""The rotating drum (rollingdem.experiments.drum): what is measured on a bed, on beds of known geometry,
and one turning drum (slow)."""

import math

import numpy as np
import pytest

import rollingdem as rd

from rollingdem.analysis.drum import com_angle, flowing_depth, flowing_layer, rotation_ratios, surface_angle

D = 0.01  # m, sphere diameter


def stacked_bed(angle_deg, drum_radius=15 * D, level=-3 * D):
    """Columns of touching spheres (centres one diameter apart vertically) at x = (k + 1/2) D,
    standing on the drum's wall, each topped exactly on the line y = level + tan(angle) x."""
    r = 0.5 * D
    tan = math.tan(math.radians(angle_deg))
    pts = []
    for k in range(-20, 20):
        xc = (k + 0.5) * D
        if abs(xc) > drum_radius - D:
            continue
        floor = -math.sqrt((drum_radius - r) ** 2 - xc ** 2)
        y = level + tan * xc - r
        while y > floor:
            pts.append((xc, y, 0.0))
            y -= D
    return np.array(pts)


@pytest.mark.parametrize("angle", [20.0, 35.0])
def test_surface_angle_of_a_bed_whose_tops_lie_on_a_line(angle):
    """Every column's top on the line: the fit returns its angle to round-off (a slope biased by
    0.1 % would miss by 0.02 degrees, far above 1e-9), through the chord's middle."""
    x = stacked_bed(angle)
    a, slope, xm, ym = surface_angle(x, 0.5 * D, D)
    assert a == pytest.approx(angle, abs=1e-9)
    assert ym == pytest.approx(-3 * D + slope * xm, abs=1e-12)


def test_a_sphere_flying_over_the_bed_is_not_its_surface():
    """A sphere far above the middle of the chord touches nothing: were it the column's top, the
    fit would tilt by degrees."""
    x = stacked_bed(30.0)
    flyer = np.array([[0.5 * D, 0.1, 0.0]])
    a = surface_angle(np.vstack([x, flyer]), 0.5 * D, D)[0]
    assert a == pytest.approx(30.0, abs=1e-9)


def test_centre_of_mass_angle_of_a_bed_symmetric_about_a_tilted_line():
    """Mirror pairs about the vertical, turned by 25 degrees about the axis: the centre of mass lies
    on the turned line, 25 degrees from below the axis, towards +x."""
    rng = np.random.default_rng(1)
    xy = np.column_stack([rng.uniform(0, 0.1, 50), rng.uniform(-0.14, -0.05, 50)])
    pairs = np.vstack([xy, xy * [-1, 1]])
    m = np.tile(rng.uniform(1, 2, 50), 2)
    t = math.radians(25.0)
    turned = pairs @ np.array([[math.cos(t), math.sin(t)], [-math.sin(t), math.cos(t)]])
    assert com_angle(np.column_stack([turned, np.zeros(100)]), m) == pytest.approx(25.0, abs=1e-12)


def test_flowing_depth_where_a_linear_profile_crosses_zero():
    """Downslope speed U (1 - depth / h) sampled evenly in depth: each half-diameter bin's mean is
    the profile at the bin's centre, so the crossing found between bin centres is h to round-off,
    for h between bin centres or on one."""
    depth = (np.arange(4800) + 0.5) * (6 * D / 4800)  # 400 in each bin, symmetric about its centre
    for h in (2.3 * D, 1.75 * D):
        assert flowing_depth(depth, 0.4 * (1 - depth / h), D) == pytest.approx(h, abs=1e-12)
    assert math.isnan(flowing_depth(depth, np.ones_like(depth), D))  # all flowing: no depth


def test_flowing_layer_takes_depth_and_downslope_speed_along_the_normal():
    """On a surface at 30 degrees through (0.01, 0.02), a sphere 3 D deep on the normal moving
    downslope at 0.2 m/s gives (3 D, 0.2); one 5 D along the surface is outside the strip."""
    s = math.tan(math.radians(30.0))
    n = np.array([-s, 1.0]) / math.hypot(1.0, s)
    u = np.array([1.0, s]) / math.hypot(1.0, s)
    at = np.array([0.01, 0.02]) - 3 * D * n
    far = np.array([0.01, 0.02]) + 5 * D * u
    x = np.array([[*at, 0.0], [*far, 0.0]])
    v = np.array([[*(-0.2 * u), 0.0], [0.0, 0.0, 0.0]])
    depth, speed = flowing_layer(x, v, s, (0.01, 0.02), D)
    assert depth == pytest.approx([3 * D], abs=1e-15) and speed == pytest.approx([0.2], abs=1e-15)



def test_rotation_ratios_take_each_zone_and_leave_out_the_rest():
    """Points on a 2.5 mm grid in a drum of radius 15 d under a level surface (y = 0), the flowing
    layer 2 d deep: the wall layer deeper than 4 d spans the arc of about +-74 deg about the bottom,
    its middle third about +-25 deg. There the passive zone (radius 7.5 d to 13.5 d) turns at 0.9 of
    omega (-y, x) and the wall layer (radius beyond 15 d - 1.05 r_max) at 1.0 of it; everything else
    moves otherwise: the flowing layer and the points 2 d to 4 d below the surface at 1 m/s
    downslope, the core inside half the radius and the band between the two zones at rest, both
    zones outside the middle third at half the drum's speed. The ratios are 0.9 and 1.0 to
    round-off; any zone's bound moved by one grid step lets in points of another speed."""
    big_r, omega, r_max, layer = 15 * D, 0.2, 0.6 * D, 2 * D
    g = np.arange(-big_r, big_r + 1e-12, 0.25 * D)
    x = np.array([(a, b, 0.0) for a in g for b in g if math.hypot(a, b) < big_r and b < 0.0])
    rho = np.hypot(x[:, 0], x[:, 1])
    solid = omega * np.column_stack([-x[:, 1], x[:, 0], np.zeros(len(x))])
    deep = x[:, 1] < -(layer + 2 * D)
    wall = deep & (rho > big_r - 1.05 * r_max)
    phi = np.arctan2(x[:, 0], -x[:, 1])
    edge = np.abs(phi[wall]).max()  # the arc is symmetric about the bottom
    assert math.degrees(edge) == pytest.approx(74.0, abs=1.0)  # arccos(4 d / (15 d - r)), on the grid
    middle = np.abs(phi) < edge / 3.0
    passive = deep & (rho > 0.5 * big_r) & (rho < big_r - 1.5 * D)
    v = np.zeros_like(x)
    v[~deep, 0] = 1.0
    v[passive | wall] = 0.5 * solid[passive | wall]
    v[passive & middle] = 0.9 * solid[passive & middle]
    v[wall & middle] = solid[wall & middle]
    assert (passive & middle).sum() > 100 and (wall & middle).sum() > 10 and (wall & ~middle).sum() > 20
    samples = [(x, v, 0.0, np.zeros(2))] * 3
    assert rotation_ratios(samples, omega, big_r, layer, D, r_max) == pytest.approx((0.9, 1.0), rel=1e-12)


@pytest.mark.slow
def test_a_turning_drum_holds_its_angle_and_the_torque_balances_the_weight():
    """The default drum (1,168 spheres, Fr = 5e-3, about 70 s on 2 cores): in steady rotation the
    driving torque equals the moment of the bed's weight about the axis (its angular momentum is
    steady), on average within 3 standard errors of 4 block means; the centre-of-mass angle and
    the surface's agree within 3 degrees (measured 36.7 and 35.9), the bed's surface being flat
    to the fit's scatter (sample-to-sample 2-3 degrees); the flowing layer is one to six diameters
    deep."""
    from rollingdem.experiments.drum import DrumSetup, drum_run
    from rollingdem.experiments.pile import PileMaterial

    r = drum_run("epsd", material=PileMaterial(friction=0.5, rolling_friction=0.2, youngs_modulus=5e6), dt=2.5e-5,
                 setup=DrumSetup())
    diff = (r.torque - r.weight_moment).reshape(4, -1).mean(axis=1)
    assert abs(diff.mean()) < 3 * diff.std(ddof=1) / 2
    assert abs(r.angle.mean() - r.com_angle.mean()) < 3.0
    assert 1 * D < r.flowing_depth < 6 * D
    assert r.measured_turn == pytest.approx(90.0, abs=90.0 / 20)  # the whole turn, to a sample's spacing


def test_a_drum_measured_until_its_angle_is_known_ends_its_last_stage_on_that():
    """``angle_within``: the measuring stage ends on ``rollingdem.Known`` of the surface angle at the
    width asked, checked at every sample, and lasts at most the ``measure`` turn; the case file
    reader takes it as such."""
    from rollingdem.experiments.drum import DrumSetup, drum_case
    from rollingdem.experiments.pile import PileMaterial
    from rollingdem.io.casefile import load_case, stage_conditions

    setup = DrumSetup(measure=180.0, samples=60, angle_within=0.5)
    data = drum_case("epsd", "none", PileMaterial(), setup, dt=2.5e-5)
    omega = data["stages"][1]["wall_motion"][0]["rotate"]["angular_velocity"]
    measuring = data["stages"][2]
    assert "duration" not in measuring and measuring["max_duration"] == pytest.approx(math.pi / omega)
    assert measuring["until"] == {"measurement": "bed.angle", "known_within": 0.5,
                                  "every": pytest.approx(math.pi / omega / 60)}
    case = load_case(data)
    bed = rd.DrumAngle("bed", center=(0, 0, 0), axis=(0, 0, 1))
    (known,) = stage_conditions(case.stages[2], {"bed": bed})
    assert isinstance(known, rd.Known) and known.within == 0.5
    assert "until" not in drum_case("epsd", "none", PileMaterial(), DrumSetup(), dt=2.5e-5)["stages"][2]


def _flowing_bed(angle=30.0, h=3 * D, speed=0.2, omega=0.5, drum_radius=15 * D, level=-3 * D):
    """The stacked bed (tops on the line y = level + tan(angle) x) and a ring of spheres touching
    the wall below it; spheres less than ``h`` below the line (centre to line, along its normal)
    flow downslope at speed (1 - depth / h), the rest turn with the drum at ``omega`` about +z."""
    r = 0.5 * D
    tan = math.tan(math.radians(angle))
    phi = np.radians(np.arange(-60.0, 61.0, 4.0))  # from below the axis
    ring = np.column_stack([(drum_radius - r) * np.sin(phi), -(drum_radius - r) * np.cos(phi), np.zeros_like(phi)])
    ring = ring[ring[:, 1] < level + tan * ring[:, 0] - h - 4 * D]  # well below the flowing layer
    x = np.vstack([stacked_bed(angle, drum_radius, level), ring])
    depth = (level + tan * x[:, 0] - x[:, 1]) * math.cos(math.radians(angle))
    up_slope = np.array([1.0, tan, 0.0]) / math.hypot(1.0, tan)
    v = omega * np.column_stack([-x[:, 1], x[:, 0], np.zeros(len(x))])
    flowing = depth < h
    v[flowing] = -np.outer(speed * (1.0 - depth[flowing] / h), up_slope)
    return x, v


def test_drum_measurements_read_the_bed_in_the_drums_own_frame(table1):
    """A drum turned to lie along x (gravity along -z) and moved off the origin, holding the
    flowing bed of ``_flowing_bed``: ``DrumFlow`` reads what the analysis functions read on the
    bed in its canonical frame (axis z, gravity -y), to round-off; the passive zone and the wall
    layer turn with the drum exactly (ratio 1 to 1e-12: their velocities are omega x r); the
    flowing layer ends between the deepest flowing spheres' depth bin (centre 2.25 d) and the first
    turning one's (3.25 d), as the stack's centres lie (0.5 + k) d cos 30 deg below the tops' line.
    ``DrumAngle``'s weight moment is |g sum m x| in the canonical frame (rel. 1e-12)."""
    import rollingdem as rd

    omega, c = 0.5, np.array([0.3, -0.2, 0.1])
    x, v = _flowing_bed(omega=omega)
    to_world = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # across -> y, up -> z, axis -> x
    sim = rd.Simulation(gravity=(0.0, 0.0, -9.81))
    sim.add_material(table1())
    drum = sim.add_wall(rd.Cylinder(15 * D, point=c, axis=(1.0, 0.0, 0.0), material="m", name="drum"))
    sim.set_wall_velocity(drum, angular_velocity=(omega, 0.0, 0.0))
    sim.add_particles(x @ to_world.T + c, 0.5 * D, "m", velocity=None, allow_overlap=True)
    sim.set_velocities(np.arange(len(x)), v @ to_world.T)
    flow = rd.DrumFlow("flow", center=c, axis=(1.0, 0.0, 0.0), radius=15 * D, wall="drum")
    bed = rd.DrumAngle("bed", center=c, axis=(1.0, 0.0, 0.0))
    flow.check(sim)
    flow.observe(sim)
    flow.observe(sim)
    depth, passive, wall = flow.pooled()
    _, slope, xm, ym = surface_angle(x, 0.5 * D, D)
    assert depth == pytest.approx(flowing_depth(*flowing_layer(x, v, slope, (xm, ym), D), D), rel=1e-9)
    assert 2.25 * D < depth < 3.25 * D
    assert passive == pytest.approx(1.0, abs=1e-12) and wall == pytest.approx(1.0, abs=1e-12)
    assert flow.summary()["flowing_depth"]["value"] == depth
    moment = bed.values(sim)[2]
    assert moment == pytest.approx(9.81 * abs(float(sim.masses @ x[:, 0])), rel=1e-12)


def test_the_shipped_drum_slice_is_what_the_validation_runs_at_its_base_point():
    """``rollingdem experiments show drum-slice`` is the case ``rotating-drum`` runs at its base
    point (mu 0.5, mu_r 0.2, the full size): every entry of ``drum_case``'s data, as the case file
    reader completes it, equals the shipped file's, numbers to the 4 to 5 figures the file writes
    them with (rel. 1e-4: omega 0.571839 rad/s is written 0.5718). The output aside."""
    from rollingdem.experiments import EXPERIMENTS
    from rollingdem.experiments.drum import DrumSetup, drum_case
    from rollingdem.experiments.pile import PileMaterial
    from helpers import assert_same_case

    p = EXPERIMENTS["rotating-drum"].resolve({"mu": 0.5, "mur": 0.2})
    assert_same_case(drum_case("epsd", "none", PileMaterial.from_parameters(p), DrumSetup(), dt=p["dt"]), "drum-slice",
                     1e-4)
