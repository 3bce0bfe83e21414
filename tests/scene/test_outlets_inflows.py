"""Outlets and inflows: a draining silo's mass balance, the counted discharge, the inflow's rate and
its non-overlapping insertion, and a restart in the middle of both (with fixed particles) that
continues bit for bit.
"""

import csv
import math
import re

import numpy as np
import pytest

import rollingdem as rd
from rollingdem.errors import ParameterError

from conftest import G

RP = 0.0015  # particle radius (m)


def _silo(table1, count=300):
    sim = rd.Simulation(gravity=(0, 0, -G))
    sim.add_material(table1(friction=0.3, rolling_friction=0.0))
    sim.add_wall(rd.MeshWall.shape("silo", radius=0.02, height=0.08, orifice_radius=0.0075, material="m",
                                   name="silo"))
    sim.insert(rd.CylinderRegion(0.0175, 0.002, 0.07), count, RP, "m", seed=2)
    return sim


def test_a_draining_silo_loses_exactly_what_its_outlet_counts(table1, tmp_path):
    """Mass taken out + mass left = mass put in (to the last bit of the float sums), and at every
    row of the time series the outlet's count equals the particles gone (to the particle)."""
    sim = _silo(table1)
    n0, m0 = sim.n_particles, float(sim.masses.sum())
    outlet = sim.add_outlet(rd.BoxRegion((-0.05, -0.05, -0.2), (0.05, 0.05, -0.01)), name="orifice")
    counted = []
    sim.run(0.3, observers=[rd.TimeSeries(tmp_path / "ts.csv", interval=0.01),
                            rd.Callback(lambda s: counted.append((s.n_particles, outlet.count)), interval=0.01)])
    assert 50 < outlet.count < n0  # it drained, and not all of it
    assert outlet.count + sim.n_particles == n0
    assert math.isclose(outlet.mass + float(sim.masses.sum()), m0, rel_tol=1e-14)
    assert all(n + c == n0 for n, c in counted)
    with open(tmp_path / "ts.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [int(r["outlet_orifice_count"]) for r in rows] == [c for _, c in counted]
    assert math.isclose(float(rows[-1]["outlet_orifice_mass"]), outlet.mass, rel_tol=1e-15)
    assert (sim.positions[:, 2] > -0.01).all()  # nothing is left inside the outlet
    assert len(np.unique(sim.particle_ids)) == sim.n_particles and sim.particle_ids.max() < n0


def test_an_inflow_inserts_at_its_rate_without_overlap(table1):
    """Count after t = floor(rate t) within one interval's worth (rate x interval = 5 particles);
    the spheres never overlap anything at insertion (0 overlap, where 1 % of a radius is allowed)."""
    sim = rd.Simulation(gravity=(0, 0, -G))
    sim.add_material(table1(friction=0.3, rolling_friction=0.0))
    sim.add_wall(rd.Plane((0, 0, 0), (0, 0, 1), material="m"))
    inflow = sim.add_inflow(rd.BoxRegion((-0.02, -0.02, 0.03), (0.02, 0.02, 0.05)), RP, "m", rate=5000,
                            interval=1e-3, seed=7, name="pour")
    worst = []

    def overlap(s):
        x, r = s.positions, s.radii
        d = np.linalg.norm(x[:, None] - x[None], axis=-1) + np.eye(len(x)) * 1e9
        new = x[:, 2] > 0.03  # just inserted, or falling through the region
        worst.append(float(((r[:, None] + r[None]) - d)[new].max(initial=-1.0) / RP) if new.any() else -1.0)

    sim.run(0.05, observers=[rd.Callback(overlap, interval=1e-3)])
    assert inflow.shortfall == 0
    assert abs(inflow.count - 5000 * 0.05) <= 5000 * 1e-3
    assert inflow.count == sim.n_particles
    assert max(worst) < 0.01
    assert math.isclose(inflow.mass, float(sim.masses.sum()), rel_tol=1e-14)


def test_an_inflow_with_no_room_says_so_once_and_counts_the_shortfall(table1):
    sim = rd.Simulation(gravity=(0, 0, 0))
    sim.add_material(table1())
    inflow = sim.add_inflow(rd.BoxRegion((0, 0, 0), (0.004, 0.004, 0.004)), RP, "m", rate=1e5, interval=1e-3)
    with pytest.warns(RuntimeWarning, match="found no room") as record:
        sim.run(0.004)
    assert len(record) == 1
    assert inflow.count == sim.n_particles >= 1
    # what was due at the last action is what it inserted plus what it could not: rate x t, within
    # the one interval (100 particles) that may separate the last action from the end of the run
    assert inflow.shortfall > 0 and abs(inflow.count + inflow.shortfall - 1e5 * sim.time) <= 1e5 * 1e-3


def test_a_restart_with_fixed_particles_an_outlet_an_inflow_and_a_periodic_axis_continues_bit_for_bit(table1,
                                                                                                       tmp_path):
    """The checkpoint written in the middle holds the outlet's and inflow's counts, the inflow's
    random stream position and the periodic box with each particle's images: the restored run
    inserts and removes the same particles at the same steps, to the last bit."""
    def scene():
        sim = rd.Simulation(gravity=(0, 0, -G), dt=4e-6, periodic={"y": (-0.02, 0.02)})
        sim.add_material(table1(friction=0.5, rolling_friction=0.1))
        sim.add_particles(rd.rough_base(RP, ((-0.02, 0.02), (-0.02, 0.02)), seed=1), RP, "m", fixed=True)
        sim.add_inflow(rd.CylinderRegion(0.015, 0.015, 0.03), RP, "m", rate=3000, interval=5e-4, seed=3,
                       velocity=(0, 0.4, 0))  # along the periodic axis
        # it catches what falls on the side x > 5 mm
        sim.add_outlet(rd.BoxRegion((0.005, -0.03, 0.004), (0.03, 0.03, 0.01)), name="edge")
        return sim

    whole = scene()
    whole.run(0.03)
    whole.run(0.03)
    first = scene()
    first.run(0.03)
    first.checkpoint(tmp_path / "mid.npz")
    again = rd.Simulation.restore(tmp_path / "mid.npz")
    again.run(0.03)
    assert whole.n_particles == again.n_particles and whole.inflows[0].count == again.inflows[0].count
    assert whole._state.image[:, 1].any()  # particles crossed the periodic ends
    for name in ("positions", "velocities", "angular_velocities", "particle_ids", "fixed", "unwrapped_positions"):
        assert np.array_equal(getattr(whole, name), getattr(again, name)), name
    assert whole.outlets[0].count == again.outlets[0].count > 0  # the outlet took some out after the restart
    assert first.outlets[0].count < whole.outlets[0].count


@pytest.mark.parametrize("call, words", [
    (lambda s: s.add_outlet(rd.BoxRegion((-1, -1, -1), (1, 1, 1))), "it contains every free particle"),
    (lambda s: s.add_outlet("below"), "outlet region = 'below' is not allowed"),
    (lambda s: s.add_outlet(rd.BoxRegion((0, 0, -1), (1, 1, 0)), name="a b"), "outlet name = 'a b' is not allowed"),
    (lambda s: s.add_inflow(rd.BoxRegion((0, 0, 0), (0.002, 0.1, 0.1)), RP, "m", rate=10),
     "a sphere of radius 0.0015 m does not fit"),
    (lambda s: s.add_inflow(rd.BoxRegion((0, 0, 0), (0.1, 0.1, 0.1)), RP, "m"), "give exactly one"),
    (lambda s: s.add_inflow(rd.BoxRegion((0, 0, 0), (0.1, 0.1, 0.1)), RP, "m", rate=-1), "inflow rate = -1"),
    (lambda s: s.add_inflow(rd.BoxRegion((0, 0, 0), (0.1, 0.1, 0.1)), RP, "sand", rate=1), "sand"),
])
def test_outlet_and_inflow_refusals(table1, call, words):
    sim = rd.Simulation()
    sim.add_material(table1())
    sim.add_particles([[0, 0, 0.01], [0, 0, 0.02]], RP, "m")
    with pytest.raises(ParameterError, match=words):
        call(sim)


def test_an_inflow_reaching_out_of_the_periodic_box_is_refused(table1):
    sim = rd.Simulation(periodic={"x": (0.0, 0.05)})
    sim.add_material(table1())
    with pytest.raises(ParameterError, match=r"along the periodic x it reaches \[0, 0.1\], outside the box"):
        sim.add_inflow(rd.BoxRegion((0, 0, 0), (0.1, 0.1, 0.1)), RP, "m", rate=10)


def test_the_command_line_prints_a_warning_on_one_line():
    import warnings

    import rollingdem.cli  # noqa: F401 - it sets the format

    line = warnings.formatwarning("an inflow at t = 0.1 s: 3 particle(s) found no room", RuntimeWarning, "x.py", 1)
    assert line == "warning: an inflow at t = 0.1 s: 3 particle(s) found no room\n"


def test_an_outlet_over_an_inflow_is_refused(table1):
    sim = rd.Simulation()
    sim.add_material(table1())
    sim.add_inflow(rd.BoxRegion((0, 0, 0), (0.1, 0.1, 0.1)), RP, "m", rate=10)
    with pytest.raises(ParameterError, match="contains the whole inflow region"):
        sim.add_outlet(rd.BoxRegion((-1, -1, -1), (1, 1, 1)))


CASE = """\
name: chute-slice
materials:
  - {name: m, youngs_modulus: 4.0e7, poisson_ratio: 0.49, density: 1056.0, friction: 0.5, restitution: 0.5}
periodic: {x: [-0.02, 0.02]}
walls:
  - {type: plane, name: floor, material: m}
particles:
  - {rough_base: {radius: 0.0015, extent: [[-0.02, 0.02], [-0.02, 0.02]], seed: 1}, material: m}
inflows:
  - {name: pour, region: {type: box, lo: [-0.015, -0.015, 0.02], hi: [0.015, 0.015, 0.03]}, radius: 0.0015,
     material: m, rate: 3000, velocity: [0.5, 0, 0]}
outlets:
  - {name: side, region: {type: box, lo: [-0.03, 0.012, 0.004], hi: [0.03, 0.03, 0.04]}}
stages:
  - {name: pour, duration: 0.03}
output:
  time_series: {interval: 0.005}
  snapshots: {interval: 0.015}
  plot: false
"""


def test_a_case_file_with_a_rough_base_an_inflow_an_outlet_and_a_periodic_axis_runs(tmp_path):
    """The four from a case file, through ``rollingdem run``: the counts in the time series, the
    fixed flag and the ids in the snapshots, the box in the final checkpoint."""
    from typer.testing import CliRunner

    from rollingdem.cli import app
    import meshio

    case = tmp_path / "case.yaml"
    case.write_text(CASE)
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(out), "--no-progress"])
    assert result.exit_code == 0, result.output
    with open(out / "series.csv") as fh:
        rows = list(csv.DictReader(fh))
    last = rows[-1]
    assert int(last["inflow_pour_count"]) == pytest.approx(3000 * float(last["time"]), abs=3000 * 1e-3)
    final = rd.Simulation.restore(out / "final.npz")
    assert final.periodic == {"x": (-0.02, 0.02)}
    n_base = int(final.fixed.sum())
    assert final.n_particles == n_base + int(last["inflow_pour_count"]) - int(last["outlet_side_count"])
    snap = meshio.read(sorted((out / "snapshots").glob("particles_*.vtu"))[-1])
    assert snap.point_data["fixed"].sum() == n_base and np.array_equal(snap.point_data["id"], final.particle_ids)
    assert snap.field_data["periodic_box"][:2].tolist() == [-0.02, 0.02]
    assert snap.field_data["removed"][0] == int(last["outlet_side_count"]) and float(last["time"]) == final.time


def _refilled_silo(table1):
    """The silo of two materials of different density, radii uniform in RP (1 +- 0.2), draining
    through its orifice into an outlet whose refill region lies above the bed."""
    sim = rd.Simulation(gravity=(0, 0, -G), dt=4e-6)  # the Hertz limit at the 1.9 m/s of a sphere falling from the top
    sim.add_material(table1(friction=0.3, rolling_friction=0.0))
    sim.add_material(table1("heavy", friction=0.3, rolling_friction=0.0, density=3000.0))
    sim.add_wall(rd.MeshWall.shape("silo", radius=0.02, height=0.1, orifice_radius=0.0075, material="m",
                                   name="silo"))
    sim.insert(rd.CylinderRegion(0.0175, 0.002, 0.035), 120, rd.Uniform(0.8 * RP, 1.2 * RP), "m", seed=2)
    sim.insert(rd.CylinderRegion(0.0175, 0.035, 0.07), 120, rd.Uniform(0.8 * RP, 1.2 * RP), "heavy", seed=3)
    refill = rd.CylinderRegion(0.0175, 0.075, 0.095)
    outlet = sim.add_outlet(rd.BoxRegion((-0.05, -0.05, -0.2), (0.05, 0.05, -0.01)), name="orifice", refill=refill,
                            seed=5)
    return sim, outlet, refill


def test_a_refilled_outlet_puts_back_each_sphere_it_takes_out_with_its_radius_and_material(table1):
    """With a refill region the bed keeps every sphere: the same count of each material, the same
    radii (as a sorted list, to the bit) and the same mass (to round-off of the sums, 1e-13),
    while the outlet counts what went through the orifice. Each sphere put back appears at rest,
    inside the refill region, overlapping nothing (0 overlap, where 1 % of a radius is allowed)."""
    sim, outlet, refill = _refilled_silo(table1)
    n0, m0 = sim.n_particles, float(sim.masses.sum())
    radii0 = np.sort(sim.radii)
    heavy0 = int((sim.material_indices == 1).sum())
    seen = set(sim.particle_ids.tolist())
    checked = []

    def new_spheres(s):
        ids = s.particle_ids
        new = np.array([i not in seen for i in ids.tolist()])
        seen.update(ids.tolist())
        if new.any():
            x, r = s.positions, s.radii
            assert (np.abs(s.velocities[new]) == 0).all() and (np.abs(s.angular_velocities[new]) == 0).all()
            assert refill.contains(x[new], np.zeros(new.sum())).all()
            d = np.linalg.norm(x[new][:, None, :] - x[None, :, :], axis=-1) + np.eye(len(x))[new] * 1.0
            assert (d >= (r[new][:, None] + r[None, :]) * (1 - 1e-12)).all()
            checked.append(int(new.sum()))

    sim.run(0.4, observers=[rd.Callback(new_spheres, interval=outlet.interval)])
    assert outlet.count > 50 and sum(checked) == outlet.count  # every sphere out came back, once
    assert sim.n_particles == n0 and int((sim.material_indices == 1).sum()) == heavy0
    assert np.array_equal(np.sort(sim.radii), radii0)
    assert math.isclose(float(sim.masses.sum()), m0, rel_tol=1e-13)
    assert outlet.mass > 0.0 and not outlet.waiting_radius.size


def test_a_refilled_outlet_that_finds_no_room_says_so_once_and_puts_the_rest_back_later(table1):
    """A refill region with room for a few spheres at a time: one warning, the spheres that did
    not fit wait (none is lost: count + waiting = the spheres at the start)."""
    sim, outlet, _ = _refilled_silo(table1)
    n0 = sim.n_particles
    outlet.refill = rd.CylinderRegion(0.004, 0.09, 0.097)
    with pytest.warns(RuntimeWarning, match="found no room in its refill region"):
        sim.run(0.25)
    assert outlet.count > 20
    assert sim.n_particles + len(outlet.waiting_radius) == n0


def test_a_restart_of_a_refilled_outlet_continues_bit_for_bit(table1, tmp_path):
    """The checkpoint keeps the refill region, its random stream's position and the spheres still
    waiting: the restored run puts back the same spheres at the same places."""
    whole, _, _ = _refilled_silo(table1)
    whole.run(0.15)
    whole.run(0.15)
    first, _, _ = _refilled_silo(table1)
    first.run(0.15)
    first.checkpoint(tmp_path / "mid.npz")
    again = rd.Simulation.restore(tmp_path / "mid.npz")
    again.run(0.15)
    assert first.outlets[0].count > 0 and whole.outlets[0].count > first.outlets[0].count
    for name in ("positions", "velocities", "radii", "particle_ids", "material_indices"):
        assert np.array_equal(getattr(whole, name), getattr(again, name)), name
    assert whole.outlets[0].count == again.outlets[0].count


def test_a_refill_region_over_its_outlet_is_refused(table1):
    sim = rd.Simulation()
    sim.add_material(table1())
    sim.add_particles([[0, 0, 0.01], [0, 0, 0.02]], RP, "m")
    with pytest.raises(ParameterError, match="outlet refill region .* overlaps the outlet region"):
        sim.add_outlet(rd.BoxRegion((0, 0, -1), (1, 1, 0)), refill=rd.BoxRegion((0.5, 0.5, -0.5), (0.9, 0.9, 0.5)))
    with pytest.raises(ParameterError, match="outlet seed = -1 is not allowed"):
        sim.add_outlet(rd.BoxRegion((0, 0, -1), (1, 1, 0)), refill=rd.BoxRegion((0, 0, 0.5), (1, 1, 1)), seed=-1)


@pytest.mark.parametrize("refill,words", [
    (rd.BoxRegion((-0.1, -0.1, -0.3), (0.1, 0.1, -0.25)), "the walls leave no room in it for a sphere of radius 0.0015 m "
                                                          "(wall 'floor' covers all of it)"),
    (rd.BoxRegion((0, 0, 0.05), (0.002, 0.002, 0.06)), "a sphere of radius 0.0015 m does not fit in it"),
])
def test_an_outlet_refill_region_behind_a_wall_or_smaller_than_a_sphere_is_refused_before_the_run(table1, refill, words):
    """A refill region the spheres taken out could never be put back in (behind the floor, or 2 mm
    wide for spheres of 3 mm): refused in one line before a step, as an inflow's region is; the
    silo would otherwise lose its head while the run goes on."""
    sim = rd.Simulation(gravity=(0, 0, -G))
    sim.add_material(table1())
    sim.add_wall(rd.Plane((0, 0, -0.2), (0, 0, 1), material="m", name="floor"))
    sim.add_particles([[0, 0, 0.01], [0, 0, 0.02]], RP, "m")
    sim.add_outlet(rd.BoxRegion((-1, -1, -0.2), (1, 1, -0.1)), name="out", refill=refill)
    with pytest.raises(ParameterError, match=rf"outlet out refill region .* is not allowed: {re.escape(words)}"):
        sim.run(steps=1)
    assert sim.step == 0


def test_an_inflow_the_walls_leave_no_room_in_is_refused_before_the_run():
    """An inflow region below the floor plane: every centre drawn in it is behind the floor, so
    nothing could ever be inserted; ``run`` refuses it in one line naming the floor, before a step.
    The same region raised to straddle the floor leaves room above it and runs."""
    sim = rd.Simulation()
    sim.add_material(rd.Material("m", 1e7, 0.3, 2500.0))
    sim.add_wall(rd.Plane(material="m", name="floor"))
    sim.add_particles([[0, 0, 0.01]], 0.002, "m")
    sim.add_inflow(rd.BoxRegion((0, 0, -0.02), (0.02, 0.02, -0.005)), radius=0.002, material="m", rate=100)
    with pytest.raises(rd.ParameterError, match="the walls leave no room in it for a sphere of radius 0.002 m "
                                                 r"\(wall 'floor' covers all of it\)"):
        sim.run(steps=1)
    assert sim.step == 0
    ok = rd.Simulation()
    ok.add_material(rd.Material("m", 1e7, 0.3, 2500.0))
    ok.add_wall(rd.Plane(material="m", name="floor"))
    ok.add_particles([[0, 0, 0.01]], 0.002, "m")
    ok.add_inflow(rd.BoxRegion((0, 0, -0.02), (0.02, 0.02, 0.02)), radius=0.002, material="m", rate=100)
    ok.run(steps=1)


@pytest.mark.parametrize("face", ["disk", "rectangle", "mesh face"])
def test_an_inflow_through_a_face_streams_its_mass_rate_through_it(face):
    """With no gravity, spheres streamed through a face at 0.5 m/s along its normal: each is placed
    wholly behind the face (its centre r to 3 r behind: the layer is 4 r deep, more than the
    0.5 m/s x 1 ms = 0.5 mm the stream moves in an interval), laterally within it, moving at the
    stream's velocity (so at most 0.5 m/s x t nearer the face by t); and the mass crossing the face's
    plane over 0.1 to 0.3 s (``MassFlow``'s least-squares rate) is the inflow's 0.05 kg/s: the
    inflow has asked for mass_rate x t to the nearest sphere by each action, so the rate is off by
    at most two spheres' mass over the 0.2 s window (1.7 %)."""
    from rollingdem.scene.mesh import TriangleMesh

    r = 0.002
    if face == "disk":
        region = rd.Disk(center=(0, 0, 0.1), normal=(0, 0, -1), radius=0.02)
    elif face == "rectangle":
        region = rd.Rectangle(center=(0, 0, 0.1), normal=(0, 0, -1), size=(0.04, 0.03), axis=(1, 1, 0))
    else:
        square = TriangleMesh([[-0.02, -0.02, 0.1], [0.02, -0.02, 0.1], [0.02, 0.02, 0.1], [-0.02, 0.02, 0.1]],
                              [[0, 1, 2], [0, 2, 3]], label="inlet")
        region = rd.MeshFace(square, normal=(0, 0, -1))
    sim = rd.Simulation(gravity=(0, 0, 0))
    sim.add_material(rd.Material("m", 1e7, 0.3, 2500.0))
    sim.add_inflow(region, radius=r, material="m", mass_rate=0.05, velocity=(0, 0, -0.5), seed=1)
    sim.run(2e-3)
    x = sim.positions
    assert sim.n_particles > 0
    assert np.all(x[:, 2] >= 0.1 + r - 0.5 * sim.time - 1e-12) and np.all(x[:, 2] <= 0.1 + 3 * r + 1e-12)
    if face == "disk":
        assert np.all(np.hypot(x[:, 0], x[:, 1]) <= 0.02 - r + 1e-12)
    elif face == "rectangle":
        e1 = np.array([1, 1, 0]) / math.sqrt(2)
        e2 = np.cross([0, 0, -1], e1)
        assert np.all(np.abs(x @ e1) <= 0.02 - r + 1e-12) and np.all(np.abs(x @ e2) <= 0.015 - r + 1e-12)
    else:
        assert np.all(np.abs(x[:, :2]) <= 0.02 + 1e-12)
    assert np.allclose(sim.velocities, [0, 0, -0.5])
    flow = rd.MassFlow("face", point=(0, 0, 0.1), normal=(0, 0, -1), interval=1e-3, window=(0.1, 0.3))
    sim.run(0.3, observers=[flow])
    one = 2500.0 * 4.0 / 3.0 * math.pi * r ** 3
    assert flow.summary()["rate"]["mean"] == pytest.approx(0.05, abs=2 * one / 0.2)


def test_an_inflow_through_a_face_is_refused_going_back_through_it():
    sim = rd.Simulation(gravity=(0, 0, 0))
    sim.add_material(rd.Material("m", 1e7, 0.3, 2500.0))
    with pytest.raises(ParameterError, match=r"inflow velocity = \[0.0, 0.0, 0.5\] is not allowed through Disk\(.*\): "
                                             "it points back through the face"):
        sim.add_inflow(rd.Disk((0, 0, 0.1), (0, 0, -1), 0.02), radius=0.002, material="m", rate=10,
                       velocity=(0, 0, 0.5))


def test_an_inflow_reports_the_mass_fractions_it_realised():
    """An inflow of 1 and 2 mm spheres making up half the mass each, streamed through a rectangle:
    its realised fractions are those of the spheres it put in the scene (none has left), exactly,
    and lie within 4 standard deviations of a half (the delta method, as in test_insertion: the
    2 mm class holds 1/9 of the spheres by number, so over n spheres sigma = 0.5 sqrt(sum p_k v_k^2)
    / (sqrt(n) E[v])). The run's line says so beside the fractions asked."""
    dist = rd.MassFractions([0.001, 0.002], [0.5, 0.5])
    sim = rd.Simulation(gravity=(0, 0, 0))
    sim.add_material(rd.Material("m", 1e7, 0.3, 2500.0))
    inflow = sim.add_inflow(rd.Rectangle((0, 0, 0), (0, 0, -1), (0.06, 0.06)), radius=dist, material="m",
                            mass_rate=0.05, velocity=(0, 0, -1.0), seed=2, name="feed")
    sim.run(0.2)
    got = inflow.class_volume / inflow.class_volume.sum()
    np.testing.assert_allclose(got, dist.realised(sim.radii), rtol=1e-12)
    n = sim.n_particles
    v = np.array([1.0, 8.0])
    p = (0.5 / v) / np.sum(0.5 / v)
    sigma = 0.5 * math.sqrt(np.sum(p * v ** 2)) / (math.sqrt(n) * np.sum(p * v))
    assert np.all(np.abs(got - 0.5) < 4 * sigma), (got, sigma, n)
    assert inflow.realised().startswith(f"inflow 'feed': {n} spheres") and "(asked 0.500 0.500)" in inflow.realised()


def test_the_dissipated_energy_never_falls_while_an_outlet_takes_spheres_out_and_refills_them(table1, tmp_path):
    """Each channel sums the work of a dissipative force (a damper, a slip against friction), so over
    the run it never decreases: the spheres the outlet takes out leave their share in the run's account,
    not with them (at 0.01 s intervals, with 60+ spheres out and put back). A checkpoint keeps that
    account: the restored run ends on the same sums, to the bit."""
    whole, outlet, _ = _refilled_silo(table1)
    whole.track_energy = True
    tallies = []
    whole.run(0.15, observers=[rd.Callback(lambda s: tallies.append(list(s.dissipated_energy().values())),
                                           interval=0.01)])
    whole.checkpoint(tmp_path / "mid.npz")
    whole.run(0.15, observers=[rd.Callback(lambda s: tallies.append(list(s.dissipated_energy().values())),
                                           interval=0.01)])
    tallies = np.array(tallies)
    assert outlet.count > 60
    assert tallies[-1, :2].min() > 0  # damping and sliding both dissipated
    assert (np.diff(tallies, axis=0) >= 0).all(), np.diff(tallies, axis=0).min(axis=0)
    again = rd.Simulation.restore(tmp_path / "mid.npz")
    again.run(0.15)
    assert again.dissipated_energy() == whole.dissipated_energy()


@pytest.mark.parametrize("dt", [4e-6, 1e-6])
def test_energy_is_conserved_over_a_silo_discharging_onto_a_floor(table1, dt):
    """A closed discharge (nothing leaves the scene), from rest: the potential energy released equals
    the kinetic energy plus every channel dissipated. The dissipation is summed step by step, a
    first-order quadrature over each collision of about 20 Hertz-time steps at 4e-6 s, so the balance
    holds to O(dt / t_Hertz): within 4 % of the released energy at 4e-6 s and 1.2 % at 1e-6 s (measured:
    -2.6 % and -0.8 %, and -0.36 % at 2.5e-7 s, where the spheres' stored elastic energy and the order
    of the sums are what is left). A channel summed twice, or half, breaks the balance by 20 % or more."""
    sim = rd.Simulation(gravity=(0, 0, -G), dt=dt, track_energy=True)
    sim.add_material(table1(friction=0.3, rolling_friction=0.0))
    sim.add_wall(rd.MeshWall.shape("silo", radius=0.02, height=0.08, orifice_radius=0.0075, material="m",
                                   name="silo"))
    sim.add_wall(rd.Plane((0, 0, -0.03), (0, 0, 1), material="m"))
    sim.insert(rd.CylinderRegion(0.0175, 0.002, 0.07), 100, RP, "m", seed=2)

    def potential():
        return G * float(np.dot(sim.masses, sim.positions[:, 2]))

    start = potential()
    sim.run(0.2)
    released = start - potential()
    assert (sim.positions[:, 2] < 0).sum() > 25  # it discharged onto the floor
    dissipated = sum(sim.dissipated_energy().values())
    balance = (released - sum(sim.kinetic_energy()) - dissipated) / released
    assert abs(balance) < (0.04 if dt > 2e-6 else 0.012), balance


def test_an_outlet_keeps_exactly_what_a_sphere_dissipated_before_it_took_it_out(table1):
    """A sphere bounces once off a plane with no gravity (e = 0.5: its normal damper and sliding
    dissipate), then flies on into an outlet; a second one floats apart, touching nothing. Between
    the bounce and the removal nothing dissipates, so the run's account after the sphere is gone
    equals the account before (to the last bit of the sums): neither lost nor counted twice."""
    sim = rd.Simulation(gravity=(0, 0, 0), dt=1e-6, track_energy=True)
    sim.add_material(table1(friction=0.3, rolling_friction=0.0))
    sim.add_wall(rd.Plane((0, 0, 0), (0, 0, 1), material="m"))
    sim.add_particles([[0, 0, 0.002], [-0.5, 0.5, 0.5]], RP, "m", velocity=[[0.2, 0, -0.5], [0, 0, 0]])
    sim.add_outlet(rd.BoxRegion((0.02, -1, -1), (1, 1, 1)), interval=1e-4)
    sim.run(0.01)  # the bounce is over in well under 1 ms; the sphere is then at x ~ 2 mm
    before = sim.dissipated_energy()
    assert sim.n_particles == 2 and before["normal_damping"] > 0 and before["sliding"] > 0
    sim.run(0.2)  # it reaches x = 0.02 m after about 0.1 s
    assert sim.n_particles == 1
    assert sim.dissipated_energy() == before
