"""Measurements (rollingdem.io.measurements) and stage conditions (rollingdem.scene.conditions):
each quantity against a value known without the code under test: a mass balance, a lattice's
counts, an elevator's power, a tilted bed's angle, the first time a criterion holds in a series."""

import math

import numpy as np
import pytest

import rollingdem as rd
from rollingdem.errors import ParameterError
from rollingdem.io.measurements import batch_standard_error, slope_with_error

from conftest import G
from helpers import measurement_material as _material

RP = 0.0015  # m




def test_mass_through_a_plane_equals_the_mass_balance_of_its_two_sides():
    """Spheres pour onto a floor in a box periodic in x and y, pushed along x so that they cross the
    periodic boundary; the sensor plane goes through the centres of the spheres resting on the
    floor, so they cross it back and forth. At every sample the net mass through the plane equals
    the change of the mass below it to round-off (a sum of ~100 masses of 1.5e-5 kg: 1e-18 kg)."""
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), gravity=(3.0, 0, -G),
                        periodic={"x": (0, 0.03), "y": (0, 0.03)})
    sim.add_material(_material())
    sim.add_wall(rd.Plane((0, 0, 0), (0, 0, 1), material="m"))
    sim.insert(rd.BoxRegion((0, 0, 0), (0.03, 0.03, 0.04)), 300, RP, "m", seed=1)
    flow = rd.MassFlow("down", point=(0.015, 0.015, RP), normal=(0, 0, -1), interval=2e-4)

    def below(s):
        return float(s.masses[s.positions[:, 2] < RP].sum())

    start = below(sim)
    rows = []
    sim.run(0.2, observers=[flow, rd.Callback(lambda s: rows.append((flow.mass, below(s) - start, flow.count)),
                                              interval=2e-4)])
    rows = np.array(rows)
    assert rows[-1, 0] > 20 * sim.masses.mean()  # a bed formed below the plane
    assert np.abs(rows[:, 0] - rows[:, 1]).max() < 1e-18
    assert (np.diff(rows[:, 2]) < 0).any()  # spheres on the plane crossed it back
    assert np.ptp(sim.unwrapped_positions[:, 0]) > 0.03  # and spheres crossed the periodic boundary
    series = flow.series()
    assert list(series.columns) == ["time", "step", "count", "mass", "rate"]
    assert series["mass"].iloc[-1] == flow.mass


def test_a_disk_counts_only_what_passes_within_its_radius():
    """Spheres fall freely through a disk of radius 5 mm at lateral distances 0 to 9 mm: the count
    is the number of spheres within 5 mm (4 of 10), each counted once."""
    sim = rd.Simulation(gravity=(0, 0, -G))
    sim.add_material(_material())
    x = np.column_stack([np.arange(10) * 0.001 + 1e-4, np.zeros(10), np.full(10, 0.02)])
    x[:, 1] = np.arange(10) * 0.004  # 4 mm apart along y: no contacts
    sim.add_particles(x, RP, "m")
    flow = rd.MassFlow("disk", point=(0, 0, 0.0), normal=(0, 0, -1), radius=0.005, interval=1e-3)
    sim.run(0.1, observers=[flow])
    inside = np.hypot(x[:, 0], x[:, 1]) <= 0.005
    assert (sim.positions[:, 2] < 0).all()
    assert flow.count == int(inside.sum()) == 2  # (0.0001, 0) and (0.0011, 0.004)
    assert math.isclose(flow.mass, float(sim.masses[inside].sum()), rel_tol=1e-14)


def test_a_probe_reads_a_lattices_counts_density_velocity_energy_and_contacts():
    """A 4 x 4 x 4 simple-cubic lattice of touching spheres (pitch 2r(1 - 1e-4)) moving and spinning
    as one, probed by a box around its middle 2 x 2 x 2: count 8, mass 8 m, bulk density 8 m / V,
    solid fraction 8 (4/3 pi r^3) / V, mean velocity the lattice's, kinetic energy 8 (m v^2 + I w^2)
    / 2, and 6 contacts each (the inner spheres of a simple-cubic lattice)."""
    sim = rd.Simulation(gravity=(0, 0, 0))
    sim.add_material(_material())
    pitch = 2 * RP * (1 - 1e-4)
    grid = np.array([(i, j, k) for i in range(4) for j in range(4) for k in range(4)], float) * pitch
    v, w = np.array([0.1, -0.2, 0.05]), np.array([0.0, 0.0, 3.0])
    sim.add_particles(grid, RP, "m", velocity=v, angular_velocity=w, allow_overlap=True)
    lo, hi = np.full(3, 0.5 * pitch), np.full(3, 2.5 * pitch)
    probe = rd.Probe("middle", rd.BoxRegion(lo, hi))
    sim.run(steps=1, observers=[probe])
    got = dict(zip(probe.QUANTITIES, probe.series().iloc[-1, 2:]))
    m = 1056.0 * 4 / 3 * math.pi * RP ** 3
    volume = float(np.prod(hi - lo))
    assert got["count"] == 8
    assert got["mass"] == pytest.approx(8 * m, rel=1e-12)
    assert got["bulk_density"] == pytest.approx(8 * m / volume, rel=1e-12)
    assert got["solid_fraction"] == pytest.approx(8 * 4 / 3 * math.pi * RP ** 3 / volume, rel=1e-12)
    # one step of overlap forces (1e-4 of the radius) changes the velocities by far less than 1e-6
    assert [got["vx"], got["vy"], got["vz"]] == pytest.approx(v, abs=1e-6)
    assert got["kinetic_energy"] == pytest.approx(8 * 0.5 * (m * v @ v + 0.4 * m * RP ** 2 * w @ w), rel=1e-4)
    assert got["coordination"] == 6


def test_an_elevator_floor_gives_a_resting_sphere_its_weight_times_its_speed():
    """A plane rising at v = 0.02 m/s carries a sphere resting on it: the force on the plane is -m g
    (z), and the power it gives the sphere m g v, averaged over the window (the sphere's bounce
    decays in a few ms of the 0.2 s)."""
    sim = rd.Simulation(gravity=(0, 0, -G))
    sim.add_material(_material(restitution=0.1))
    floor = sim.add_wall(rd.Plane((0, 0, 0), (0, 0, 1), material="m", velocity=(0, 0, 0.02), name="floor"))
    sim.add_particles([[0, 0, RP * 0.999]], RP, "m", allow_overlap=True)
    load = rd.WallLoad("floor", wall="floor", interval=1e-3, window=(0.1, 0.3))
    sim.run(0.3, observers=[load])
    m = float(sim.masses[0])
    s = load.summary()
    assert s["fz"]["mean"] == pytest.approx(-m * G, rel=2e-3)
    assert s["power"]["mean"] == pytest.approx(m * G * 0.02, rel=2e-3)
    assert floor.name == "floor"


def test_a_tilted_bed_in_a_drum_turned_along_x_reads_its_tilt():
    """A bed whose surface is the plane z = tan(25 deg) y, in a drum whose axis is x (gravity -z):
    the surface angle is 25 deg within the columns' one-diameter roughness (0.5 deg for a chord of
    some 60 diameters), in the viewing window that leaves out two end layers."""
    sim = rd.Simulation(gravity=(0, 0, -G))
    sim.add_material(_material())
    d = 2 * RP * 1.001
    ys, zs = np.meshgrid(np.arange(-0.09, 0.09, d), np.arange(-0.09, 0.09, d))
    keep = (np.hypot(ys, zs) < 0.09) & (zs < math.tan(math.radians(25)) * ys)
    cross = np.column_stack([ys[keep], zs[keep]])
    x = np.vstack([np.column_stack([np.full(len(cross), k * d), cross]) for k in range(5)])
    sim.add_particles(x, RP, "m")
    drum = rd.DrumAngle("drum", center=(0, 0, 0), axis=(1, 0, 0), extent=(0.5 * d, 3.5 * d))
    angle, com, _ = drum.values(sim)
    assert angle == pytest.approx(25.0, abs=0.5)
    assert 10 < com < 40


def test_batch_errors_and_slopes_on_made_up_series():
    """White noise of sigma 1 in 1000 samples: the batch-means error is sigma / sqrt(1000) within
    the error of a standard deviation from 10 batches (about a quarter); a line of slope 2 with
    noise reads 2 within 3 of its errors."""
    rng = np.random.default_rng(4)
    assert batch_standard_error(rng.normal(size=1000)) == pytest.approx(1 / math.sqrt(1000), rel=0.5)
    assert math.isnan(batch_standard_error(np.ones(15)))
    t = np.linspace(0, 1, 500)
    slope, err = slope_with_error(t, 2 * t + rng.normal(scale=0.01, size=500))
    assert abs(slope - 2) < 3 * err and err < 0.05


def test_settled_ends_the_run_where_the_criterion_first_holds_in_the_series():
    """A bed settles in a periodic box; the translational kinetic energy per particle, recorded at
    the condition's own checks, first stays below the threshold for the hold time at the step the
    run ended."""
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), gravity=(0, 0, -G),
                        periodic={"x": (0, 0.03), "y": (0, 0.03)})
    sim.add_material(_material(friction=0.5, rolling_friction=0.2))
    sim.add_wall(rd.Plane((0, 0, 0), (0, 0, 1), material="m"))
    sim.insert(rd.BoxRegion((0, 0, 0), (0.03, 0.03, 0.03)), 200, RP, "m", seed=1)
    kinetic = []
    every = 1e-3
    sim.run(0.0)
    threshold = 1e-6 * float(sim.masses.mean()) * G * 2 * RP
    record = rd.Callback(lambda s: kinetic.append((s.time, s.kinetic_energy()[0] / s.n_particles)), interval=every)
    ended = sim.run(2.0, observers=[record], until=rd.Settled(hold=0.02, every=every))
    assert ended.startswith("settled")
    first, since = None, None  # the first sample that ends 0.02 s of samples all below the threshold
    for ti, ki in kinetic:
        since = None if ki >= threshold else (ti if since is None else since)
        if since is not None and ti - since >= 0.02 - 0.5 * sim.dt:
            first = ti
            break
    assert first == pytest.approx(sim.time, abs=0.5 * sim.dt)
    assert sim.time < 1.0


def test_reaches_ends_a_discharge_at_the_count_and_empty_at_the_last_particle(table1):
    """An outlet takes out spheres falling through it: ``Reaches`` ends the run at the first check
    with 50 out (and fewer at the check before); ``Empty`` ends the next run once none is left."""
    sim = rd.Simulation(gravity=(0, 0, -G), dt=1e-5)  # the Hertz limit at the 5 m/s they reach
    sim.add_material(table1(friction=0.3, rolling_friction=0.0))
    x = np.column_stack([np.zeros(80), np.zeros(80), 0.011 * (1 + np.arange(80))])
    sim.add_particles(x, 0.005, "m")
    sim.add_outlet(rd.BoxRegion((-1, -1, -2), (1, 1, -0.05)), name="bin")
    out = rd.OutletTotals("out", outlet="bin", interval=1e-3)
    seen = []
    until = rd.Reaches(out, "count", above=50, every=1e-3)
    ended = sim.run(5.0, observers=[out, rd.Callback(lambda s: seen.append(sim.outlets[0].count), interval=1e-3)],
                    until=until)
    assert "out.count >= 50" in ended
    assert sim.outlets[0].count >= 50 and seen[-2] < 50
    assert sim.run(5.0, until=rd.Empty()).startswith("empty") and sim.n_particles == 0


def test_a_rate_below_a_value_for_a_hold_ends_a_run_once_the_flow_has_stopped(table1):
    """80 spheres in a column fall through an outlet, the first after about 0.11 s (nothing flows
    before). ``Reaches(rate, below=1e-6, hold=0.2)``: the wait before the first arrival is shorter
    than the hold, so the run goes on; it ends 0.2 s (to a check of 1 ms) after the last sphere is
    out, not at the first check that reads no flow."""
    sim = rd.Simulation(gravity=(0, 0, -G), dt=1e-5)
    sim.add_material(table1(friction=0.3, rolling_friction=0.0))
    x = np.column_stack([np.zeros(80), np.zeros(80), 0.011 * (1 + np.arange(80))])
    sim.add_particles(x, 0.005, "m")
    sim.add_outlet(rd.BoxRegion((-1, -1, -2), (1, 1, -0.05)), name="bin", interval=1e-3)
    out = rd.OutletTotals("out", outlet="bin", interval=1e-3)
    counts = []
    until = rd.Reaches(out, "rate", below=1e-6, hold=0.2, every=1e-3)
    ended = sim.run(5.0, observers=[out, rd.Callback(lambda s: counts.append((s.time, s.outlets[0].count)),
                                                     interval=1e-3)], until=until)
    assert "out.rate <= 1e-06 for 0.2 s" in ended
    assert sim.outlets[0].count == 80
    last = next(t for t, c in counts if c == 80)
    assert 0.2 - 1e-3 <= sim.time - last <= 0.2 + 2e-3, (sim.time, last)
    assert math.sqrt(2 * (0.011 + 0.05 - 0.005) / G) < last - 0.2  # the flow started later than the hold


def _half_width_95(values) -> float:
    """The 95 % half-width of the mean of ``values`` by batch means, as docs/measurements.md defines
    it: 10 consecutive batches of len // 10 samples (the rest left out), Student's t at 97.5 % with
    9 degrees of freedom times the batch means' standard deviation over sqrt(10)."""
    from scipy.stats import t

    per = len(values) // 10
    means = np.asarray(values[:10 * per]).reshape(10, per).mean(axis=1)
    return float(t.ppf(0.975, 9) * means.std(ddof=1) / math.sqrt(10))


def test_known_ends_a_run_at_the_first_sample_whose_mean_is_known_to_the_width_asked():
    """A measurement of independent normal noise (sd 1, one value per sample) around 5: ``Known``
    with ± 0.3 ends the run at the first sample, 20 or later, whose 95 % half-width reaches 0.3
    (computed here from the recorded series). For independent samples the half-width is about
    t sigma / sqrt(n), so n is near (2.262 / 0.3)^2 = 57; the batch estimate of sigma has 9 degrees
    of freedom (relative scatter ~ 0.24), hence the bounds 0.4-2.5 times 57. The mean it reports is
    within its own half-width of 5 (a 95 % statement, true for this seed)."""
    sim = rd.Simulation(gravity=(0, 0, -G))
    sim.add_material(_material())
    sim.add_wall(rd.Plane((0, 0, 0), (0, 0, 1), material="m"))
    sim.add_particles([[0, 0, RP]], RP, "m")
    noise = iter(np.random.default_rng(7).normal(5.0, 1.0, size=100_000))
    m = rd.Function("noise", lambda s: next(noise), interval=1e-3)
    until = rd.Known(m, "value", 0.3, every=1e-3)
    ended = sim.run(1.0, observers=[m], until=until)
    assert ended.startswith("noise.value known to +- 0.3")
    values = m.series()["value"].to_numpy()
    n = len(values)
    widths = [_half_width_95(values[:k]) for k in range(20, n + 1)]
    assert widths[-1] <= 0.3 and all(w > 0.3 for w in widths[:-1])
    assert 0.4 * 57 < n < 2.5 * 57
    assert abs(until.mean - 5.0) < until.half_width and until.samples == n


def test_known_within_is_a_case_file_stage_condition_and_what_has_no_mean_is_refused(tmp_path):
    """A case file stage takes ``until: {measurement: NAME.QUANTITY, known_within: W}`` as ``Known``; beside above
    or below, on a cumulative quantity, with W <= 0 or fewer than 20 samples it is refused in one line."""
    from rollingdem.io.casefile import load_case, stage_conditions

    case = load_case({"dt": 1e-5, "gravity": [0, 0, -9.81],
                      "materials": [{"name": "m", "youngs_modulus": 4e7, "poisson_ratio": 0.49, "density": 1056,
                                     "friction": 0.3, "rolling_friction": 0.1, "restitution": 0.5}],
                      "walls": [{"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1], "material": "m"}],
                      "particles": [{"positions": [[0, 0, 0.0015]], "radius": 0.0015, "material": "m"}],
                      "measurements": [{"name": "out", "type": "probe", "region": {"type": "box", "lo": [-1, -1, -1],
                                                                               "hi": [1, 1, 1]}, "interval": 1e-3}],
                      "stages": [{"name": "rest", "until": {"measurement": "out.mass", "known_within": 1e-3},
                                  "max_duration": 1.0}]})
    measurements = {"out": rd.Probe("out", rd.BoxRegion((-1, -1, -1), (1, 1, 1)), interval=1e-3),
                    "bin": rd.OutletTotals("bin", outlet="bin")}
    (known,) = stage_conditions(case.stages[0], measurements)
    assert isinstance(known, rd.Known) and known.within == 1e-3 and known.min_samples == 20
    bad = {"above": 1.0, "known_within": 0.1}
    with pytest.raises(ParameterError, match="known_within is not allowed beside above, below or hold"):
        stage_conditions(case.stages[0].model_copy(update={"until": case.stages[0].until.model_copy(
            update={"measurement": "out.mass", **bad})}), measurements)
    with pytest.raises(ParameterError, match="bin.count known_within is not allowed: its value is the last sample's"):
        rd.Known(measurements["bin"], "count", 1.0)
    with pytest.raises(ParameterError, match="until known_within = 0 is not allowed"):
        rd.Known(measurements["out"], "mass", 0.0)
    with pytest.raises(ParameterError, match="until min_samples = 10 is not allowed: must be an integer >= 20"):
        rd.Known(measurements["out"], "mass", 1.0, min_samples=10)


def test_conditions_and_measurements_refuse_bad_input():
    out = rd.OutletTotals("out", outlet="bin")
    with pytest.raises(ParameterError, match="give exactly one of above and below"):
        rd.Reaches(out, "count")
    with pytest.raises(ParameterError, match="'out' measures count, mass, rate"):
        rd.Reaches(out, "speed", above=1)
    with pytest.raises(ParameterError, match="settled hold = -1 is not allowed"):
        rd.Settled(hold=-1)
    with pytest.raises(ParameterError, match="until hold = -1 is not allowed"):
        rd.Reaches(out, "rate", below=0.0, hold=-1)
    with pytest.raises(ParameterError, match="until = 3 is not allowed"):
        rd.Simulation(dt=1e-5).run(1.0, until=3)
    with pytest.raises(ParameterError, match="measurement name = 'a b' is not allowed"):
        rd.Probe("a b", rd.BoxRegion((0, 0, 0), (1, 1, 1)))
    with pytest.raises(ParameterError, match=r"measurement window = \[2.0, 1.0\] is not allowed"):
        rd.Probe("p", rd.BoxRegion((0, 0, 0), (1, 1, 1)), window=(2.0, 1.0))
    sim = rd.Simulation(gravity=(0, 0, -G))
    sim.add_material(_material())
    sim.add_particles([[0, 0, 0.01]], RP, "m")
    flow = rd.MassFlow("far", point=(0, 0, 10.0), normal=(0, 0, 1))  # 10 m: a length in mm written as m
    with pytest.raises(ParameterError, match=r"mass flow 'far' point = \(0, 0, 10\) is not allowed: it is outside "
                                             "the scene"):
        sim.run(0.001, observers=[flow])
    with pytest.raises(ParameterError, match="wall = 'lid' is not allowed: no wall in place has that name"):
        sim.run(0.001, observers=[rd.WallLoad("lid", wall="lid")])


def test_a_steady_stream_through_a_plane_reads_its_mass_rate():
    """50 spheres in a column 1 cm apart move down at 1 m/s through a plane, without gravity or
    contacts: the mass rate is m v / spacing = 100 m per second. The summary's rate (the slope of
    the cumulative mass over 0.1-0.4 s, 30 crossings) reads it within the staircase's one
    crossing over the window (1/30), and every row's rate is a whole number of spheres per 10 ms."""
    sim = rd.Simulation(gravity=(0, 0, 0), dt=5e-6)
    sim.add_material(_material())
    sim.add_particles(np.column_stack([np.zeros(50), np.zeros(50), 0.005 + 0.01 * np.arange(50)]), RP, "m",
                      velocity=(0, 0, -1.0))
    flow = rd.MassFlow("stream", point=(0, 0, 0), normal=(0, 0, -1), interval=0.01, window=(0.1, 0.4))
    sim.run(0.5, observers=[flow])
    m = float(sim.masses[0])
    s = flow.summary()
    assert s["rate"]["mean"] == pytest.approx(100 * m, rel=1 / 30)
    assert s["count"]["final"] == 50 and s["mass"]["final"] == pytest.approx(50 * m, rel=1e-12)
    rows = flow.series()["rate"].to_numpy()[1:]
    assert np.allclose(rows * 0.01 / m, np.round(rows * 0.01 / m), atol=1e-9)


def test_a_function_of_the_state_is_measured_with_its_units():
    """``rd.Function``: a free-falling sphere's height from a dict, sampled every 1 ms: each row
    is z0 - g t^2 / 2 to the integrator's exactness for constant gravity (velocity Verlet: 1e-12 m),
    the unit named is kept, and a function that returns a string is refused in one line."""
    sim = rd.Simulation(gravity=(0, 0, -G), dt=5e-6)
    sim.add_material(_material())
    sim.add_particles([[0, 0, 1.0]], RP, "m")
    height = rd.Function("fall", lambda s: {"z": float(s.positions[0, 2])}, interval=1e-3, units={"z": "m"})
    sim.run(0.05, observers=[height])
    rows = height.series()
    assert list(rows.columns) == ["time", "step", "z"] and height.QUANTITIES == {"z": "m"}
    assert np.allclose(rows["z"], 1.0 - 0.5 * G * rows["time"] ** 2, atol=1e-12, rtol=0)
    bad = rd.Function("bad", lambda s: "high")
    with pytest.raises(ParameterError, match="measurement 'bad': function returned 'high': must be a number"):
        sim.run(0.001, observers=[bad])


def _flat_drum_bed(lift=0.0):
    """Three rows along x of a drum's lower half (radius 9 cm), in a square lattice, raised by
    ``lift``; and the height of its surface (the top of its highest row)."""
    sim = rd.Simulation(gravity=(0, 0, -G))
    sim.add_material(_material())
    d = 2 * RP * 1.001
    ys, zs = np.meshgrid(np.arange(-0.09, 0.09, d), np.arange(-0.09, 0.09, d))
    keep = (np.hypot(ys, zs) < 0.09) & (zs < 0)
    cross = np.column_stack([ys[keep], zs[keep] + lift])
    sim.add_particles(np.vstack([np.column_stack([np.full(len(cross), k * d), cross]) for k in range(3)]), RP, "m")
    return sim, float(zs[keep].max()) + lift + RP


def test_a_drum_profile_reads_the_misfit_of_a_flat_bed_to_its_height():
    """A flat bed in a drum turned along x (gravity -z), its surface the top of its highest row:
    measured at that height the misfit is 0; measured 1 mm higher, rmse 1 mm and bias -1 mm (the
    simulated surface lies below the measured one)."""
    sim, top = _flat_drum_bed()
    xs = np.linspace(-0.05, 0.05, 11)
    for shift, (rmse, bias) in ((0.0, (0.0, 0.0)), (0.001, (0.001, -0.001))):
        # across = up x axis = z x x = y: the points' first coordinate is y
        profile = rd.SurfaceProfile("p", np.column_stack([xs, np.full(11, top + shift)]), shape="drum",
                                    center=(0, 0, 0), axis=(1, 0, 0))
        got = profile.values(sim)
        assert got == pytest.approx([rmse, bias], abs=1e-12)


def test_a_drum_profile_compares_the_surface_averaged_over_its_window():
    """A drum's surface 1 mm above and 1 mm below the measured line, sample after sample: each
    sample's rmse is 1 mm (the series' mean), the surface averaged over the window lies on the line
    (the summary's value and the printed line: 0, to round-off), as a GranuDrum averages its images."""
    (low, top), (high, _) = _flat_drum_bed(-0.001), _flat_drum_bed(0.001)
    xs = np.linspace(-0.05, 0.05, 11)
    profile = rd.SurfaceProfile("p", np.column_stack([xs, np.full(11, top + 0.001)]), shape="drum",
                                center=(0, 0, 0), axis=(1, 0, 0), window=(0.0, 1.0))
    for sim in (low, high, low, high):
        profile.observe(sim)
    s = profile.summary()
    assert s["samples"] == 4 and s["rmse"]["mean"] == pytest.approx(0.001, rel=1e-9)
    assert abs(s["rmse"]["value"]) < 1e-12 and abs(s["bias"]["value"]) < 1e-12
    line = profile.summary_line()
    assert "rmse 0 m, bias 0 m (the surface averaged over 0-1 s; each sample's rmse 0.001 m on average)" in line


def test_a_mesh_surface_counts_what_passes_through_its_triangles_by_their_normal():
    """A square of two triangles at z = 0, 2 cm wide, its normal up: of ten spheres falling through
    z = 0 at (x, y) = (0.1 + k mm, 4 k mm), the three with y <= 1 cm pass through it, each counted
    once against the normal (-3) though one falls through the square's diagonal edge; a closed
    box around the square's centre 5 mm high, which the same three enter and leave, nets 0."""
    from rollingdem.scene.mesh import TriangleMesh, box

    sim = rd.Simulation(gravity=(0, 0, -G))
    sim.add_material(_material())
    x = np.column_stack([np.arange(10) * 0.001 + 1e-4, np.arange(10) * 0.004, np.full(10, 0.02)])
    x[0, :2] = (0.0, 0.0)  # on the diagonal the two triangles share
    sim.add_particles(x, RP, "m")
    square = TriangleMesh(np.array([[-0.01, -0.01, 0], [0.01, -0.01, 0], [0.01, 0.01, 0], [-0.01, 0.01, 0]]),
                          np.array([[0, 1, 2], [0, 2, 3]]))
    through = rd.MeshFlow("square", square, interval=1e-3)
    closed = rd.MeshFlow("box", box((0.02, 0.02, 0.005)).moved(translation=(-0.01, -0.01, -0.0025)), interval=1e-3)
    sim.run(0.1, observers=[through, closed])
    assert (sim.positions[:, 2] < -0.01).all()
    assert through.count == -3
    assert math.isclose(through.mass, -3 * float(sim.masses[0]), rel_tol=1e-14)
    assert closed.count == 0


# 200 spheres of 1.5 mm in a flat-bottomed silo 40 mm wide, its orifice ORIFICE m in radius
# (a closed drum standing upright in its place, as a silo with no orifice, when SHAPE is replaced)
SILO_SHAPE = "shape: silo, size: {radius: 0.02, height: 0.08, orifice_radius: ORIFICE}"
SMALL_SILO = """\
name: small-silo
materials:
  - {name: glass, youngs_modulus: 5.0e6, poisson_ratio: 0.3, density: 2500.0, friction: 0.5}
walls:
  - {type: mesh, name: silo, material: glass, SHAPE}
particles:
  - insert: {type: cylinder, radius: 0.0175, z_min: 0.002, z_max: 0.07}
    count: 200
    radius: 0.0015
    material: glass
    seed: 2
outlets:
  - {name: bin, region: {type: box, lo: [-1, -1, -2], hi: [1, 1, -0.05]}}
"""


def test_a_mesh_disk_in_a_case_file_counts_what_the_analytic_disk_counts(tmp_path):
    """A silo drains 0.3 s through a 48-sided mesh disk (``type: mesh_flow``, ``shape: disk``) and an
    analytic disk of the same radius in the same plane, 1 cm under the orifice: every sphere that
    falls through one falls through the other (the polygon leaves out only its rim, where none
    falls), so the counts and masses agree exactly. A probe whose region is a closed mesh box
    (``region: {type: mesh, shape: box}``) reads at every sample what the box region it encloses
    reads: counts, masses and densities (the same volume) equal."""
    import json

    import pandas as pd

    from typer.testing import CliRunner

    from rollingdem.cli import app

    (tmp_path / "case.yaml").write_text(SMALL_SILO.replace("SHAPE", SILO_SHAPE).replace("ORIFICE", "0.008") + """\
measurements:
  - {name: mesh, type: mesh_flow, shape: disk, size: {radius: 0.03}, place: {translate: [0, 0, -0.01]}}
  - {name: disk, type: mass_flow, point: [0, 0, -0.01], normal: [0, 0, 1], radius: 0.03}
  - {name: box, type: probe, region: {type: box, lo: [-0.01, -0.012, 0.0], hi: [0.012, 0.01, 0.03]}, interval: 0.01}
  - {name: mesh_box, type: probe, interval: 0.01,
     region: {type: mesh, shape: box, size: {size: [0.022, 0.022, 0.03]}, place: {translate: [-0.01, -0.012, 0.0]}}}
stages:
  - {name: drain, duration: 0.3}
output: {plot: false, report: null}
""")
    result = CliRunner().invoke(app, ["run", str(tmp_path / "case.yaml"), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 0, result.output
    m = json.loads((tmp_path / "o" / "summary.json").read_text())["measurements"]
    assert m["mesh"]["count"]["final"] == m["disk"]["count"]["final"] < -50
    assert m["mesh"]["mass"]["final"] == m["disk"]["mass"]["final"]
    box, mesh_box = (pd.read_csv(tmp_path / "o" / "measurements" / f"{n}.csv", comment="#") for n in ("box", "mesh_box"))
    assert len(box) == 32 and box["count"].max() > 50 and box["count"].min() < box["count"].max()  # it drains
    pd.testing.assert_frame_equal(box, mesh_box, rtol=1e-12)


def test_coordination_counts_the_contacts_across_a_periodic_boundary_once():
    """A ring of 10 spheres along a periodic x, each overlapping its two neighbours by 1e-4 of a
    radius (the first and the last across the boundary): 2 contacts each; the same row without
    the periodic box has 1 at its ends, 18 / 10 = 1.8 on average."""
    from rollingdem.io.measurements import coordination

    pitch = 2 * RP * (1 - 1e-4)
    for periodic, expected in (({"x": (0.0, 10 * pitch)}, 2.0), (None, 1.8)):
        sim = rd.Simulation(gravity=(0, 0, 0), periodic=periodic)
        sim.add_material(_material())
        sim.add_particles(np.column_stack([(np.arange(10) + 0.5) * pitch, np.zeros(10), np.zeros(10)]), RP, "m",
                          allow_overlap=True)
        assert coordination(sim, np.ones(10, bool)) == expected


def test_a_closed_mesh_region_holds_what_its_polygon_prism_holds():
    """A 48-sided closed drum mesh (radius R, length L), turned to lie along x and moved, as a
    probe's region: a point is inside exactly where it lies within the regular 48-gon (every edge's
    inward distance, R cos(pi/48) minus its projection on the edge normal, >= 0) and between the
    caps, checked on 20,000 random points (none nearer the surface than 1e-9 m, where round-off
    could decide); the volume is the prism's, 24 R^2 sin(2 pi / 48) L, to round-off; a sphere is
    inside only where no point of the mesh is nearer than its radius; an open tube is refused."""
    from scipy.spatial.transform import Rotation

    from rollingdem.scene.mesh import MeshRegion, drum

    R, L, n = 0.05, 0.12, 48
    turn, shift = Rotation.from_rotvec([0, np.pi / 2, 0]).as_matrix(), np.array([0.1, -0.02, 0.3])
    region = MeshRegion(drum(R, L, segments=n).moved(turn, shift))
    assert region.volume() == pytest.approx(0.5 * n * R ** 2 * math.sin(2 * math.pi / n) * L, rel=1e-12)
    local = np.random.default_rng(3).uniform([-0.06, -0.06, -0.01], [0.06, 0.06, L + 0.01], (20000, 3))
    x = local @ turn.T + shift
    edges = 2 * math.pi * (np.arange(n) + 0.5) / n
    inward = R * math.cos(math.pi / n) - (local[:, :2] @ np.array([np.cos(edges), np.sin(edges)]))
    margin = np.minimum(inward.min(axis=1), np.minimum(local[:, 2], L - local[:, 2]))
    clear = np.abs(margin) > 1e-9
    got = region.contains(x, np.zeros(len(x)))
    assert 8000 < (margin > 0).sum() < 12000 and (got[clear] == (margin[clear] > 0)).all()
    # spheres at the axis's middle: inside while their radius is below the polygon's inradius
    centre = shift + turn @ np.array([0, 0, L / 2])
    inradius = R * math.cos(math.pi / n)
    assert region.contains([centre, centre], [0.999 * inradius, 1.001 * inradius]).tolist() == [True, False]
    with pytest.raises(ParameterError, match="must be closed.*belongs to no other triangle"):
        MeshRegion(drum(R, L, segments=n, caps=False))


SILO_TWO_CONDITIONS = SMALL_SILO + """\
measurements:
  - {name: out, type: outlet, outlet: bin, interval: 0.002}
stages:
  - {name: drain, until: {measurement: out.count, above: 10, settled: {}}, max_duration: 1.5}
output: {plot: false, report: null, time_series: null}
"""


@pytest.mark.parametrize("shape, ends", [(SILO_SHAPE.replace("ORIFICE", "0.008"), "out.count"),
                                         ("shape: drum, size: {radius: 0.02, length: 0.08}", "settled")])
def test_a_stage_with_two_conditions_ends_at_the_first_met(tmp_path, shape, ends):
    """The poured silo's stage waits for 10 spheres out or for the bed to settle: through an
    orifice 5 sphere diameters wide they flow out before the bed has settled; from a closed drum
    standing in its place none can, and the bed settles, well within the 1.5 s allowed."""
    from typer.testing import CliRunner

    from rollingdem.cli import app

    import json

    (tmp_path / "case.yaml").write_text(SILO_TWO_CONDITIONS.replace("SHAPE", shape))
    result = CliRunner().invoke(app, ["run", str(tmp_path / "case.yaml"), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    stage = summary["stages"][0]
    assert stage["ended"].startswith(ends) and stage["end_time"] < 1.5
    count = summary["measurements"]["out"]["count"]["final"]
    assert count >= 10 if ends == "out.count" else count == 0


SILO_STAGE_WINDOW = SMALL_SILO.replace("SHAPE", SILO_SHAPE.replace("ORIFICE", "0.008")).replace(
    "walls:\n", "walls:\n  - {type: plane, name: gate, material: glass, point: [0, 0, 0], normal: [0, 0, 1]}\n") + """\
measurements:
  - {name: out, type: outlet, outlet: bin, interval: 0.002, window: {stage: drain, start: 0.05, duration: 0.1}}
  - {name: early, type: outlet, outlet: bin, interval: 0.002, window: {stage: pour, start: 0.02}}
stages:
  - {name: pour, until: settled, max_duration: 1.5}
  - {name: drain, duration: 0.2, remove_walls: [gate]}
output: {plot: false, report: null, time_series: null}
"""


def test_a_window_from_a_stages_start_moves_with_the_stage_before_it(tmp_path):
    """The pour ends when the bed settles, at a time no one can give beforehand; the outlet's window
    starts 0.05 s after the drain starts and lasts 0.1 s, and the other's runs from 0.02 s after the
    pour's start to the pour's longest end (1.5 s): each summary's window is that."""
    import json

    from typer.testing import CliRunner

    from rollingdem.cli import app

    (tmp_path / "case.yaml").write_text(SILO_STAGE_WINDOW)
    result = CliRunner().invoke(app, ["run", str(tmp_path / "case.yaml"), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    poured = summary["stages"][0]["end_time"]
    assert summary["stages"][0]["ended"].startswith("settled") and 0.1 < poured < 1.5
    assert summary["measurements"]["out"]["window"] == pytest.approx([poured + 0.05, poured + 0.15], abs=1e-9)
    assert summary["measurements"]["early"]["window"] == pytest.approx([0.02, 1.5], abs=1e-9)


@pytest.mark.parametrize("shape", ["cylinder", "prism", "cavity"])
def test_a_probe_divides_by_the_exact_volume_of_a_cylinder_or_a_closed_mesh(shape):
    """Spheres on a grid 4 mm apart (no contacts, no gravity), probed by a cylinder (pi R^2 h), a
    64-sided prism mesh (N/2 R^2 sin(2 pi / N) h) and a closed box with a cube cavity (a^3 - b^3):
    count = the centres inside by the shape's own test, bulk density = their mass / that volume, solid
    fraction = their volume / it, and bulk density = solid fraction x rho for one material (to
    round-off). A volume off by any factor, or the bounding box's taken instead, fails."""
    from rollingdem.scene.mesh import SHAPES, MeshRegion, TriangleMesh

    sim = rd.Simulation(gravity=(0, 0, 0))
    sim.add_material(_material())
    g = np.arange(-0.05, 0.1501, 0.004)
    x = np.array([(a, b, c) for a in g for b in g for c in g])
    x = x[np.linalg.norm(x - 0.05, axis=1) < 0.09] + 1e-4  # no centre on a surface
    if shape == "cylinder":
        region, volume = rd.CylinderRegion(0.04, 0.01, 0.07, center=(0.05, 0.05)), math.pi * 0.04 ** 2 * 0.06
        inside = (np.hypot(x[:, 0] - 0.05, x[:, 1] - 0.05) <= 0.04) & (x[:, 2] >= 0.01) & (x[:, 2] <= 0.07)
    elif shape == "prism":
        mesh = SHAPES["drum"](radius=0.05, length=0.1, segments=64)
        region = MeshRegion(TriangleMesh(mesh.vertices + [0.05, 0.05, 0.0], mesh.triangles))
        volume = 0.5 * 64 * 0.05 ** 2 * math.sin(2 * math.pi / 64) * 0.1
        phi = 2 * np.pi * (np.arange(64) + 0.5) / 64
        d = (x[:, :2] - 0.05) @ np.array([np.cos(phi), np.sin(phi)])
        inside = (d < 0.05 * np.cos(np.pi / 64)).all(axis=1) & (x[:, 2] > 0) & (x[:, 2] < 0.1)
    else:
        outer, inner = SHAPES["box"]((0.1, 0.1, 0.1)), SHAPES["box"]((0.04, 0.04, 0.04))
        cavity = TriangleMesh(np.vstack([outer.vertices, inner.vertices + 0.03]),
                              np.vstack([outer.triangles, inner.triangles[:, ::-1] + 8]))
        region, volume = MeshRegion(cavity), 0.1 ** 3 - 0.04 ** 3
        inside = ((x > 0) & (x < 0.1)).all(axis=1) & ~((x > 0.03) & (x < 0.07)).all(axis=1)
    assert np.array_equal(region.contains(x, np.zeros(len(x))), inside)
    sim.add_particles(x, RP, "m")
    probe = rd.Probe(shape, region)
    sim.run(steps=1, observers=[probe])
    got = dict(zip(probe.QUANTITIES, probe.series().iloc[-1, 2:]))
    n = int(inside.sum())
    m = 1056.0 * 4 / 3 * math.pi * RP ** 3
    assert region.volume() == pytest.approx(volume, rel=1e-12)
    assert got["count"] == n and n > 100
    assert got["bulk_density"] == pytest.approx(n * m / volume, rel=1e-12)
    assert got["solid_fraction"] == pytest.approx(n * 4 / 3 * math.pi * RP ** 3 / volume, rel=1e-12)
    assert got["bulk_density"] == pytest.approx(got["solid_fraction"] * 1056.0, rel=1e-12)
