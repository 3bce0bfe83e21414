"""``rollingdem bench``: what it reports, that timing leaves the physics alone, and its refusals."""

import json
import math
import time

import numpy as np
import pytest
from typer.testing import CliRunner

import rollingdem as rd
from rollingdem import bench
from rollingdem.cli import app
from rollingdem.errors import ParameterError


def test_bench_json_reports_the_scene(tmp_path):
    out = tmp_path / "b.json"
    tic = time.perf_counter()
    res = CliRunner().invoke(app, ["bench", "--scene", "single-particle", "--steps", "3000", "--json", str(out)])
    outside = time.perf_counter() - tic  # the whole command, timed here: compile, warm-up, timed steps, split
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    r = doc["results"][0]
    assert (r["scene"], r["particles"], r["steps"]) == ("single-particle", 1, 3000)
    # the timed steps and the compilation are parts of the command, so each takes less than it, and
    # the figure is at least the particle-steps over the whole command's time
    assert 0 < r["wall_s"] and 0 <= r["compile_s"] and r["wall_s"] + r["compile_s"] < outside
    assert r["particle_steps_per_s"] >= r["particles"] * r["steps"] / outside
    # and it is the particle-steps over the timed part alone (compile/load is reported apart)
    assert r["particle_steps_per_s"] == pytest.approx(r["particles"] * r["steps"] / r["wall_s"], rel=1e-12) and set(r["split_s_per_step"]) == {"contact forces", "walls",
                                                                  "integration and gathering", "neighbor search"}
    # one sphere resting on the plate: exactly one (wall) contact, no neighbors
    assert r["contacts_per_particle"] == 1.0 and r["neighbors_per_particle"] == 0.0


def test_slab_figures_agree_with_the_simulation_state(monkeypatch):
    """The slab scene (300 spheres falling onto the plate, 2000 timed steps): the reported steps are
    the steps the state went through (one warm-up step before them), the figure is bounded by the
    wall time measured here around the call, and the contacts per sphere are those of the final
    state counted here from positions and radii alone (pairs closer than r_i + r_j by a k-d tree over
    all spheres, counted for both; spheres below their radius from the plate z = 0): the engine's
    count, from its neighbor list, must agree exactly. Every touching pair must be in the neighbor
    list, so the neighbors per sphere are at least twice the pairs per sphere."""
    from scipy.spatial import cKDTree

    seen = {}
    real = bench._result
    monkeypatch.setattr(bench, "_result", lambda scene, model, sim, *a, **k: seen.setdefault("sim", sim) and
                        real(scene, model, sim, *a, **k))
    tic = time.perf_counter()
    r = bench.slab(particles=300, steps=2000, threads=1, echo=lambda *a: None)
    outside = time.perf_counter() - tic
    sim = seen["sim"]
    assert (r.particles, r.steps) == (sim.n_particles, 2000) == (300, 2000)
    assert sim.step == 1 + 2000
    # the compilation and the timed steps are separate parts of the call
    assert 0 < r.wall_s and r.wall_s + r.compile_s < outside and r.particle_steps_per_s >= 300 * 2000 / outside
    x, a = sim.positions, sim.radii
    pairs = cKDTree(x).query_pairs(2 * a.max(), output_type="ndarray")
    touching = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1) < a[pairs[:, 0]] + a[pairs[:, 1]]
    on_plate = np.count_nonzero(x[:, 2] < a)
    # the slab has landed: at least half of its bottom layer (ceil(sqrt(300 / 8))^2 = 49 spheres) is on the plate
    assert touching.sum() > 100 and on_plate >= 25
    assert r.contacts_per_particle == (2 * touching.sum() + on_plate) / 300
    assert r.neighbors_per_particle >= 2 * touching.sum() / 300


def _bed(table1):
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), dt=1e-5, skin=0.002, track_energy=True)
    sim.add_material(table1())
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    sim.insert(rd.BoxRegion((-0.03, -0.03, 0.0), (0.03, 0.03, 0.06)), 80, 0.005, "m", seed=3)
    return sim


def test_time_split_leaves_the_state_as_it_was(table1):
    """The split times each phase on the live state; the run must go on as if it had not."""
    a, b = _bed(table1), _bed(table1)
    a.run(steps=2000)
    split = a.phase_seconds(repeats=3, rebuilds_per_step=1.0)
    # the passes timed on their own take time; the walls are a difference of two gathers (with and
    # without them), clipped at 0, which on a loaded machine may come out 0 for one plane
    assert all(split[p] > 0 for p in ("contact forces", "integration and gathering", "neighbor search"))
    assert split["walls"] >= 0
    a.run(steps=2000)
    b.run(steps=4000)
    assert a.number_of_contacts() > 0
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.angular_velocities, b.angular_velocities)
    assert a.dissipated_energy() == b.dissipated_energy()


def test_force_pass_costs_leave_the_states_as_they_were(table1):
    """dense-bed times the models' force passes call by call on their live states; each run must go
    on as if it had not been timed, and every round gives a positive cost for every model."""
    a, b, c = _bed(table1), _bed(table1), _bed(table1)
    for sim in (a, b, c):
        sim.run(steps=2000)
    costs = bench._force_pass_costs({"a": a, "b": b}, rounds=2)
    assert set(costs) == {"a", "b"} and all(len(v) == 2 and min(v) > 0 for v in costs.values())
    for sim in (a, b, c):
        sim.run(steps=2000)
    for sim in (a, b):
        np.testing.assert_array_equal(sim.positions, c.positions)
        np.testing.assert_array_equal(sim.angular_velocities, c.angular_velocities)
        assert sim.dissipated_energy() == c.dissipated_energy()


def test_settled_state_from_a_liggghts_dump(tmp_path):
    dump = tmp_path / "c.dump"
    dump.write_text("ITEM: TIMESTEP\n60000\nITEM: NUMBER OF ATOMS\n2\nITEM: BOX BOUNDS ff ff ff\n-1 1\n-1 1\n0 1\n"
                    "ITEM: ATOMS id type x y z vx vy vz radius\n"
                    "7 1 0.01 0.0 0.005 0.1 0 0 0.005\n3 1 -0.01 0.0 0.005 0 0 -0.2 0.005\n")
    sim = bench.column_from_dump(dump)
    np.testing.assert_array_equal(sim.positions, [[0.01, 0.0, 0.005], [-0.01, 0.0, 0.005]])
    np.testing.assert_array_equal(sim.velocities, [[0.1, 0, 0], [0, 0, -0.2]])
    assert [w.name for w in sim.walls] == ["plate", "cylinder"]
    # the cylinder is scaled with sqrt(N) from 0.125 m at 20,000 spheres
    assert sim.walls[1].radius == pytest.approx(0.125 * np.sqrt(2 / 20000))


def test_slab_dump_for_the_peers_is_the_slab(tmp_path):
    """The dump the LIGGGHTS slab input reads holds the bench's slab state to the 10 digits written
    (relative 5e-10 at most)."""
    x, v = bench.slab_state(300)
    assert len(x) == 300 and x[:, 2].min() > bench.RADIUS  # every sphere starts above the plate
    sim = bench.column_from_dump(bench.write_liggghts_dump(tmp_path / "s.dump", x, v, bench.RADIUS))
    np.testing.assert_allclose(sim.positions, x, rtol=5e-10, atol=0)
    np.testing.assert_allclose(sim.velocities, v, rtol=5e-10, atol=0)
    np.testing.assert_array_equal(sim.radii, bench.RADIUS)


def test_a_rough_bed_dumped_for_the_peers_reads_back_as_the_same_bed(monkeypatch, tmp_path):
    """The rough-bed state benchmarks/peers_dense.sh gives the peers (fixed spheres of type 2) reads back
    with ``rough_bed_from_dump`` as the same bed, even from rows out of id order (as several
    processes write them): the same spheres fixed, positions to the 10 digits written, the same box;
    and one step on from both, the same contacts per sphere, the base's unmoved."""
    monkeypatch.setattr(bench, "ROUGH_BED_SETTLE", 0.1)
    monkeypatch.setattr(bench, "_cache_dir", lambda: tmp_path)
    bed = bench.rough_bed_simulation(300, True, echo=lambda *a: None)
    fixed = bed.fixed.astype(bool)
    dump = bench.write_liggghts_dump(tmp_path / "r.dump", bed.positions, bed.velocities, bench.RADIUS, fixed=fixed)
    lines = dump.read_text().splitlines()
    head = next(k for k, line in enumerate(lines) if line.startswith("ITEM: ATOMS")) + 1
    rows = np.array(lines[head:])[np.random.default_rng(1).permutation(len(lines) - head)]
    dump.write_text("\n".join(lines[:head] + list(rows)) + "\n")
    back = bench.rough_bed_from_dump(dump)
    assert (~fixed).sum() == 300 and fixed.sum() > 100
    np.testing.assert_array_equal(back.fixed.astype(bool), fixed)
    np.testing.assert_allclose(back.positions, bed.positions, rtol=5e-10, atol=0)
    np.testing.assert_allclose(back.velocities, bed.velocities, rtol=5e-10, atol=1e-300)
    assert [(w.point, w.normal) for w in back.walls] == [(w.point, w.normal) for w in bed.walls]
    base = back.positions[fixed]
    for sim in (bed, back):
        sim.run(steps=1, progress=False)
    # settled 0.1 s, the free spheres rest on the base and on each other: ~3 contacts each
    assert bench._contacts_per_particle(back)[0] == bench._contacts_per_particle(bed)[0] > 1.5
    np.testing.assert_array_equal(back.positions[fixed], base)


@pytest.mark.parametrize("args, words", [(["--scene", "nope"], ["scene = nope", "column-collapse"]),
                                         (["--particles", "0"], ["particles = 0", ">= 1"]),
                                         (["--scene", "dense-bed", "--model", "magic"], ["model = magic", "epsd"]),
                                         (["--from-dump", "/nonexistent.dump"], ["does not exist"])])
def test_bad_bench_input_is_refused(args, words):
    res = CliRunner().invoke(app, ["bench", *args])
    assert res.exit_code == 2
    for w in words:
        assert w in res.output


def test_a_dump_that_is_not_one(tmp_path):
    bad = tmp_path / "x.dump"
    bad.write_text("hello\n")
    with pytest.raises(rd.ParameterError, match="not a LIGGGHTS custom dump"):
        bench.column_from_dump(bad)


def test_scaling_scene_times_two_slabs_in_turn(monkeypatch):
    """The scaling scene steps a small and a large slab through the same steps, chunk by chunk, and
    its figure is the ratio of their costs per particle-step over the whole run."""
    monkeypatch.setattr(bench, "SCALING_SMALL", 300)
    small, large = bench.scaling(particles=1200, steps=12, threads=1, echo=lambda *a: None)
    assert (small.particles, large.particles) == (300, 1200) and small.steps == large.steps == 12
    assert small.scene == large.scene == "slab"
    whole = (large.wall_s / large.particles) / (small.wall_s / small.particles)
    assert f"cost per particle-step {whole:.2f}x that at 300" in large.note


def test_collapse_scaling_scene_times_two_collapses_in_turn(monkeypatch, tmp_path):
    """collapse-scaling does the same with the column-collapse: two settled columns (here barely
    settled, from a cache in tmp_path), each with its cylinder removed."""
    monkeypatch.setattr(bench, "SCALING_SMALL", 300)
    monkeypatch.setattr(bench, "SETTLE", 0.002)
    monkeypatch.setattr(bench, "_cache_dir", lambda: tmp_path)
    small, large = bench.run_bench(["collapse-scaling"], particles=1200, steps=12, threads=1, echo=lambda *a: None)
    assert (small.particles, large.particles) == (300, 1200) and small.steps == large.steps == 12
    assert small.scene == large.scene == "column-collapse"
    assert len(list(tmp_path.glob("column_*.npz"))) == 2  # both settled states cached
    whole = (large.wall_s / large.particles) / (small.wall_s / small.particles)
    assert f"cost per particle-step {whole:.2f}x that at 300" in large.note


def test_column_bed_scaling_keeps_the_cylinder(monkeypatch, tmp_path):
    """The column-bed scene times the same settled columns at rest: unlike the collapse, both keep
    their cylinder through the timed steps. An unknown scaling scene is refused by name."""
    monkeypatch.setattr(bench, "SCALING_SMALL", 300)
    monkeypatch.setattr(bench, "SETTLE", 0.002)
    monkeypatch.setattr(bench, "_cache_dir", lambda: tmp_path)
    columns = []
    real = bench.settled_column
    monkeypatch.setattr(bench, "settled_column", lambda *a, **k: columns.append(real(*a, **k)) or columns[-1])
    small, large = bench.scaling(1200, steps=12, threads=1, echo=lambda *a: None, scene="column-bed")
    assert (small.particles, large.particles) == (300, 1200) and "cylinder kept" in large.note
    assert [sim.step for sim in columns] == [213, 213]  # 200 settling, 1 warm-up, 12 timed
    assert all(any(w.name == "cylinder" for w in sim.walls) for sim in columns)
    with pytest.raises(ParameterError, match="scene = 'heap'"):
        bench.scaling(1200, steps=12, threads=1, scene="heap")


def test_an_interrupted_settle_resumes_from_its_checkpoint(monkeypatch, tmp_path):
    """A long settle (hours for 10^6 spheres) is checkpointed every SETTLE_CHECKPOINT s; stopped
    after its first checkpoint and called again, it resumes there, and the settled state is the
    same bit for bit as that of a settle run through in one go (a checkpoint continues bit for bit)."""
    monkeypatch.setattr(bench, "SETTLE", 0.01)
    monkeypatch.setattr(bench, "SETTLE_CHECKPOINT", 1.0)
    monkeypatch.setattr(bench, "_cache_dir", lambda: tmp_path / "whole")
    whole = bench.settled_column(300, echo=lambda *a: None)

    monkeypatch.setattr(bench, "SETTLE_CHECKPOINT", 0.004)
    monkeypatch.setattr(bench, "_cache_dir", lambda: tmp_path / "parts")
    real_run = rd.Simulation.run
    calls = []

    def stop_at_the_second_part(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real_run(self, *args, **kwargs)

    monkeypatch.setattr(rd.Simulation, "run", stop_at_the_second_part)
    with pytest.raises(KeyboardInterrupt):
        bench.settled_column(300, echo=lambda *a: None)
    partial = list((tmp_path / "parts").glob("*_partial.npz"))
    assert len(partial) == 1 and not list((tmp_path / "parts").glob("column_300_seed1_epsd_v*[0-9].npz"))
    monkeypatch.setattr(rd.Simulation, "run", real_run)
    said = []
    resumed = bench.settled_column(300, echo=said.append)
    assert "resuming" in said[0] and "t = 0.004" in said[0]
    assert not partial[0].exists()
    assert resumed.step == whole.step == 1000
    np.testing.assert_array_equal(resumed.positions, whole.positions)
    np.testing.assert_array_equal(resumed.angular_velocities, whole.angular_velocities)


def test_the_clumps_scene_times_clumps_against_their_members_count_of_spheres(monkeypatch, tmp_path):
    """100 tetrahedra (400 members) and 400 spheres, settled 0.02 s, 60 steps in turn: the note's
    clump-step cost in sphere-steps is the two reported times per body, and a clump adds its own
    23 numbers (centre, velocity, quaternion, angular momentum, mass, moments, force, torque: 184 B),
    its members' clump index and offset (4 x 32 B) and its index rows (8 B per member and per
    clump): 352 B."""
    monkeypatch.setattr(bench, "_cache_dir", lambda: tmp_path)
    monkeypatch.setattr(bench, "CLUMP_BED_SETTLE", 0.02)
    clumps, spheres = bench.clump_bed(members=400, steps=60, threads=1, echo=lambda *a: None)
    assert (clumps.particles, spheres.particles) == (400, 400) and clumps.scene == spheres.scene == "clumps"
    cost = (clumps.wall_s / 100) / (spheres.wall_s / 400)
    assert f"a clump-step costs {cost:.2f} sphere-steps" in clumps.note
    assert "a clump adds 352 B to its members'" in clumps.note
    assert "100 tetrahedra of 4 spheres" in clumps.note and "400 spheres at rest" in spheres.note


def test_the_coarse_graining_scene_times_parcels_against_the_real_particles_over_the_same_time(monkeypatch, tmp_path):
    """A drum 6 d in radius (374 real spheres; the scene's own is the study's 30 d): the parcels of
    alpha 3 are round(374 / 27) = 14 standing for 14 x 27 = 378, step at 3 dt and so take a third of
    the real particles' 600 steps for the same 0.015 s, in a drum turning at the same angular velocity
    (the same Froude number in the same drum); the note's ratio is the two runs' particles represented
    x simulated time per reported second of wall time."""
    monkeypatch.setattr(bench, "_cache_dir", lambda: tmp_path)
    monkeypatch.setattr(bench, "CG_SPIN_UP", 0.02)
    real, parcels = bench.coarse_graining_bench(steps=600, threads=1, echo=lambda *a: None, drum_diameters=6.0)
    assert (real.particles, parcels.particles) == (374, 14) and real.scene == parcels.scene == "coarse-graining"
    assert (real.steps, parcels.steps) == (600, 200)
    assert "374 real particles standing for 374 particles, dt 2.5e-05 s" in real.note
    assert "14 parcels of alpha 3 standing for 378 particles, dt 7.5e-05 s, 200 steps (0.015 s simulated)" in parcels.note
    ratio = (378 * 200 * 7.5e-5 / parcels.wall_s) / (374 * 600 * 2.5e-5 / real.wall_s)
    assert f": {ratio:.3g}x the real particles'" in parcels.note
    drums = [bench.coarse_graining_drum(a, drum_diameters=6.0) for a in (1.0, 3.0)]
    spins = [sim.walls[0].angular_velocity for sim in drums]
    assert spins[0] == spins[1] and spins[0][2] == pytest.approx(math.sqrt(5e-3 * 9.81 / (6 * 0.01)), rel=1e-12)
