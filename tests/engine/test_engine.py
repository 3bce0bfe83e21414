"""Engine invariants: equal and opposite forces, momentum, neighbor list, history, restart, determinism."""

import json

import numba
import numpy as np
import pytest

import rollingdem as rd
from rollingdem.engine import backends
from rollingdem.engine.state import EngineState
from rollingdem.engine.layout import I_REBUILDS
from rollingdem.engine.neighbors import POOL_GROUP, brute_force_pairs
from conftest import R
from helpers import cluster




def momenta(sim):
    m = sim.masses[:, None]
    p = (m * sim.velocities).sum(0)
    inertia = 0.4 * sim.masses * sim.radii ** 2
    ang = (np.cross(sim.positions, m * sim.velocities) + inertia[:, None] * sim.angular_velocities).sum(0)
    return p, ang


def test_isolated_packing_conserves_momentum(table1):
    """No gravity, no walls: every contact force acts equal and opposite at one contact point and the
    rolling couple is pure, so linear and angular momentum change only by round-off."""
    sim = cluster(table1)
    p0, l0 = momenta(sim)
    sim.run(steps=3000)
    assert sim.dissipated_energy()["normal_damping"] > 0  # collisions did happen
    assert sim.dissipated_energy()["rolling"] > 0
    p1, l1 = momenta(sim)
    scale_p = (sim.masses[:, None] * np.abs(sim.velocities)).sum()
    scale_l = np.abs(np.cross(sim.positions, sim.masses[:, None] * sim.velocities)).sum()
    # round-off: ~1e-16 per operation, accumulated over 3000 steps and ~1000 contacts
    assert np.abs(p1 - p0).max() < 1e-12 * scale_p
    assert np.abs(l1 - l0).max() < 1e-12 * scale_l


def test_forces_equal_and_opposite(table1):
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="cdt"), gravity=(0, 0, 0), dt=2e-6)
    sim.add_material(table1())
    sim.add_particles([[0, 0, 0], [2 * R - 1e-5, 1e-4, 0]], R, "m", velocity=[[0.1, 0.05, 0], [0, 0, 0]],
                      angular_velocity=[[0, 0, 30], [10, 0, 0]], allow_overlap=True)
    sim.run(steps=50)
    assert sim.number_of_contacts() == 1
    np.testing.assert_array_equal(sim.forces[0], -sim.forces[1])


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("skin", [0.0, 1e-3, 4e-3])
@pytest.mark.parametrize("shuffled", [False, True])
def test_neighbor_list_equals_brute_force(seed, skin, shuffled):
    """Each pair once, in the row of the partner with the smaller id, rows sorted by partner id
    (ids shuffled against the slots as after a spatial re-sort)."""
    rng = np.random.default_rng(seed)
    n = 400
    x = rng.uniform(0, 0.08, (n, 3))
    x[:50] *= 0.2  # a dense corner and a sparse rest
    radius = rng.uniform(0.001, 0.004, n)
    st = EngineState(history_size=6)
    st.append_particles(x=x, radius=radius, mass=np.ones(n), inertia=np.ones(n))
    if shuffled:
        st.ids = rng.permutation(n).astype(np.int64)
    ids = st.ids
    total = st.rebuild_list(skin)
    rows = [(i, int(st.contact_list.j[k])) for i in range(n) for k in range(st.contact_list.start[i], st.contact_list.start[i + 1])]
    assert all(ids[j] > ids[i] for i, j in rows)
    listed = {(min(i, j), max(i, j)) for i, j in rows}
    assert total == len(listed) == len(rows)
    assert listed == brute_force_pairs(x, radius, skin)
    for i in range(n):  # rows sorted by partner id, which the history merge relies on
        row = st.contact_list.j[st.contact_list.start[i]:st.contact_list.start[i + 1]]
        assert np.all(np.diff(ids[row]) > 0)
    # transposed index: for each j the entries k where it is second, ascending in i
    for j in range(n):
        ks = st.contact_list.tr_k[st.contact_list.tr_start[j]:st.contact_list.tr_start[j + 1]]
        assert all(st.contact_list.j[k] == j for k in ks)
        assert np.all(np.diff(ks) > 0)


def settled_trio(table1, skin):
    """Three spheres in a row on a plane, the first pushed into the others: long-lived contacts
    with loaded tangential springs, sliding and rolling."""
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="cdt"), dt=5e-6, skin=skin)
    sim.add_material(table1())
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    sim.add_particles([[0, 0, R], [2 * R, 0, R], [R, 0, R + np.sqrt(3) * R]], R, "m", allow_overlap=True)
    sim.run(steps=4000)
    sim.set_velocities([2], velocity=(0.05, 0.01, 0), angular_velocity=(0, 5, 0))
    return sim


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_rebuild_carries_each_contacts_history_in_place_and_drops_lost_pairs(seed):
    """The in-place carry: every pair listed before and after a rebuild keeps its history row bit
    for bit, a new pair starts from zeros, and a contact whose pair left the list (positions moved
    from outside) is dropped without disturbing its neighbors' rows."""
    rng = np.random.default_rng(seed)
    n, skin = 300, 2e-3
    x = rng.uniform(0, 0.05, (n, 3))
    radius = rng.uniform(0.001, 0.003, n)
    st = EngineState(history_size=6)
    st.append_particles(x=x, radius=radius, mass=np.ones(n), inertia=np.ones(n))
    st.ids = rng.permutation(n).astype(np.int64)

    def by_pair(total):
        hist = st.contact_list.entry_history()
        return {(int(st.ids[i]), int(st.ids[st.contact_list.j[k]])): hist[k] for i in range(n)
                for k in range(st.contact_list.start[i], st.contact_list.start[i + 1])}

    total = st.rebuild_list(skin)
    # about half the entries carry a history (a contact normal and values), the rest zeros
    active = rng.random(total) < 0.5
    st.contact_list.set_entry_history(np.where(active[:, None], rng.uniform(-1, 1, (total, 6)) + 2.0, 0.0))
    before = by_pair(total)
    st.x[rng.random(n) < 0.3] += rng.uniform(-0.01, 0.01, (3,))  # some particles jump: pairs come and go
    after = by_pair(st.rebuild_list(skin))
    kept = set(before) & set(after)
    assert len(kept) > 50 and len(set(after) - set(before)) > 10 and len(set(before) - set(after)) > 10
    for pair, row in after.items():
        np.testing.assert_array_equal(row, before[pair] if pair in before else np.zeros(6))


def test_history_survives_rebuilds(table1):
    """Rebuilding every step or only on displacement gives the same trajectory, bit for bit: the
    contacts in a row are summed in ascending j either way and history is carried by the merge."""
    every = settled_trio(table1, skin=6e-7)  # just above 2 x the fastest step: rebuilds nearly every step
    lazy = settled_trio(table1, skin=2e-3)
    every.run(steps=4000)
    lazy.run(steps=4000)
    assert every._state.info[I_REBUILDS] > 1000 > 100 > lazy._state.info[I_REBUILDS]
    assert every.number_of_contacts() == lazy.number_of_contacts() >= 3
    np.testing.assert_array_equal(every.positions, lazy.positions)
    np.testing.assert_array_equal(every.angular_velocities, lazy.angular_velocities)


def test_contact_history_dropped_when_contact_opens(table1):
    sim = rd.Simulation(contact=rd.ContactModel("hertz"), gravity=(0, 0, 0), dt=2e-6, skin=5e-3)
    sim.add_material(table1())
    sim.add_particles([[0, 0, 0], [2.1 * R, 0, 0]], R, "m", velocity=[[0.2, 0.2, 0], [-0.2, 0, 0]])
    sim.run(steps=1500)  # approach 625 steps, contact ~150 steps
    assert sim.number_of_contacts() == 0 and sim.velocities[1, 0] > 0  # they bounced apart
    st = sim._state
    assert st.contact_list.size == 1  # still neighbors within the skin ...
    assert st.contact_list.contact_row[0] == -1 and np.all(st.contact_list.entry_history() == 0.0)  # ... but the closed contact's springs are gone


def test_restart_is_bit_identical(table1, tmp_path):
    a = cluster(table1, n_side=4, gravity=(0, 0, -9.81))
    a.add_wall(rd.Plane(point=(0, 0, -2 * R), normal=(0, 0, 1), material="m"))
    b = cluster(table1, n_side=4, gravity=(0, 0, -9.81))
    b.add_wall(rd.Plane(point=(0, 0, -2 * R), normal=(0, 0, 1), material="m"))
    a.run(steps=3000)
    b.run(steps=1500)
    path = b.checkpoint(tmp_path / "cp.npz")
    c = rd.Simulation.restore(path)
    c.run(steps=1500)
    assert c.step == a.step == 3000
    for name in ("positions", "velocities", "angular_velocities", "forces", "torques"):
        np.testing.assert_array_equal(getattr(a, name), getattr(c, name))
    assert a.dissipated_energy() == c.dissipated_energy()


def test_energy_bookkeeping_changes_no_trajectory(table1, tmp_path):
    """``track_energy`` only adds sums of the dissipated energies: the forces are the same either way,
    to round-off (the compiler may fuse multiply-adds differently in the two kernels: measured
    1e-14 relative after 1500 steps of collisions; 1e-9 leaves room for their chaotic growth and
    still catches any change of the force law, which would be O(1)). Without it the dissipated
    energy is refused (not reported as zero)."""
    tracked = cluster(table1, n_side=4, rolling="epsd")
    plain = cluster(table1, n_side=4, rolling="epsd")
    plain.track_energy = False
    tracked.run(steps=1500)
    plain.run(steps=1500)
    for name in ("positions", "velocities", "angular_velocities", "forces", "torques"):
        ref = getattr(tracked, name)
        np.testing.assert_allclose(getattr(plain, name), ref, rtol=0, atol=1e-9 * np.abs(ref).max())
    assert tracked.dissipated_energy()["normal_damping"] > 0
    # untracked, the state holds no energy sums (32 B per sphere); turned on mid-run, they start
    # at zero: the sums over the next 1500 steps are the tracked run's growth over them (the same
    # collisions, to the 1e-9 above; 1e-6 leaves room for the difference of two sums)
    assert plain._state.energy.shape[0] == 0
    before = tracked.dissipated_energy()
    plain.track_energy = True
    tracked.run(steps=1500)
    plain.run(steps=1500)
    assert plain._state.energy.shape == (plain.n_particles, 4)
    for channel, value in tracked.dissipated_energy().items():
        grown = value - before[channel]
        assert plain.dissipated_energy()[channel] == pytest.approx(grown, rel=1e-6, abs=1e-15)
    assert plain.dissipated_energy()["normal_damping"] > 0
    fresh = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"))
    with pytest.raises(rd.ParameterError, match="track_energy"):
        fresh.dissipated_energy()
    # a time series holds the dissipated energies, so it turns the bookkeeping on
    observed = cluster(table1, n_side=4, rolling="epsd")
    observed.track_energy = False
    observed.run(steps=500, observers=[rd.TimeSeries(tmp_path / "series.csv", interval=250 * observed.dt)])
    last = np.genfromtxt(tmp_path / "series.csv", delimiter=",", names=True)[-1]
    assert observed.track_energy and last["dissipated_normal_damping"] > 0


def test_same_result_for_any_thread_count(table1, monkeypatch):
    """Forces are gathered per particle in a fixed order: the serial path (small scenes, one
    thread) and the parallel path on all threads give the same bits."""
    import rollingdem.engine.layout as ek

    results = []
    for threads, serial_below in ((1, ek.SERIAL_BELOW), (numba.config.NUMBA_NUM_THREADS, 0)):
        numba.set_num_threads(threads)
        monkeypatch.setattr(ek, "SERIAL_BELOW", serial_below)
        try:
            sim = cluster(table1, n_side=4)
            assert sim._state.serial() == (serial_below > 0)
            sim.run(steps=1000)
            results.append(sim.positions.copy())
        finally:
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    np.testing.assert_array_equal(results[0], results[1])
    monkeypatch.undo()
    again = cluster(table1, n_side=4)
    again.run(steps=1000)
    np.testing.assert_array_equal(results[1], again.positions)


def test_the_threads_share_the_gather_by_free_spheres():
    """``free_run_bound``: 1,000 fixed spheres then 1,000 free ones, in 8 runs of 256: runs 0-3 hold
    24 free spheres (slots 1000-1023), each later run 256 more (280, 536, 792, 1000 behind runs 4-7).
    Half the free spheres lie behind the first 6 runs, a quarter behind the first 5, all behind 8:
    two threads split at run 6, not at run 4 as equal counts of runs would (one thread would gather
    744 free spheres, the other 256)."""
    from rollingdem.engine.template.gather import GATHER_RUN, free_run_bound

    fixed = np.r_[np.ones(1000, np.uint8), np.zeros(1000, np.uint8)]
    assert GATHER_RUN == 256
    assert [free_run_bound(fixed, 8, share * 1000) for share in (0.0, 0.25, 0.5, 1.0)] == [0, 5, 6, 8]


def test_same_result_for_any_thread_count_on_a_rough_base(table1, monkeypatch):
    """A cube of spheres falling onto a rough base of fixed spheres (added first, so that the base
    fills the first slots): the threads share the gather by free spheres, not by slots, and every
    sphere is gathered once whichever thread takes it: the serial path and the parallel path give
    the same bits, and the base stays where it was."""
    import rollingdem.engine.layout as ek

    results = []
    for threads, serial_below in ((1, ek.SERIAL_BELOW), (numba.config.NUMBA_NUM_THREADS, 0)):
        numba.set_num_threads(threads)
        monkeypatch.setattr(ek, "SERIAL_BELOW", serial_below)
        try:
            sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), dt=2e-6)
            sim.add_material(table1())
            base = rd.rough_base(R, ((-0.07, 0.07), (-0.07, 0.07)), seed=2)
            sim.add_particles(base, R, "m", fixed=True)
            g = np.arange(5) * 2.05 * R - 4 * R
            x = np.stack(np.meshgrid(g, g, g + 8 * R, indexing="ij"), -1).reshape(-1, 3)
            sim.add_particles(x, R, "m", velocity=(0, 0, -2.0))
            assert len(base) > 100 and sim._state.serial() == (serial_below > 0)
            sim.run(steps=2000)  # 4 ms: the cube's bottom layer strikes the base at 2.5 ms
            results.append(sim.positions.copy())
            np.testing.assert_array_equal(sim.positions[:len(base)], base)
            assert sim.number_of_contacts() > 50
        finally:
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    np.testing.assert_array_equal(results[0], results[1])


def test_moving_and_removed_walls(table1):
    """A plate pushed up at constant speed lifts a resting sphere; removing it lets the sphere fall."""
    sim = rd.Simulation(contact=rd.ContactModel("hertz"), dt=5e-6)
    sim.add_material(table1())
    plate = sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    sim.add_particles([[0, 0, R]], R, "m", allow_overlap=True)
    sim.run(0.05)
    sim.set_wall_velocity(plate, velocity=(0, 0, 0.1))
    sim.run(0.1)
    assert sim.velocities[0, 2] == pytest.approx(0.1, rel=0.02)  # carried along
    assert sim.positions[0, 2] == pytest.approx(R + 0.01, abs=2e-4)  # plate moved 0.1 m/s x 0.1 s
    assert plate.point[2] == pytest.approx(0.01, rel=1e-9)  # the Wall object knows where it is
    with pytest.raises(rd.ParameterError, match="overlaps wall"):  # so insertion checks the moved plate
        sim.add_particles([[0.05, 0, 0.008]], R, "m")
    sim.remove_wall(plate)
    z = sim.positions[0, 2]
    sim.run(0.1)
    # free flight from v = 0.1 m/s: z + 0.1 t - g t^2 / 2 (contact had only elastic forces at launch)
    assert sim.positions[0, 2] == pytest.approx(z + 0.01 - 0.5 * 9.81 * 0.01, abs=5e-5)


def _sticking_on_second_wall(table1):
    """A sphere held by static friction on a plate (wall 2 of 2) under gravity tilted 10 deg, far
    from a plate above it (wall 1): its tangential spring with the plate is loaded."""
    g = 9.81
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), dt=2e-6,
                        gravity=(g * np.sin(np.radians(10)), 0.0, -g * np.cos(np.radians(10))))
    sim.add_material(table1())
    far = sim.add_wall(rd.Plane(point=(0, 0, 0.5), normal=(0, 0, -1), material="m", name="far"))
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m", name="plate"))
    sim.add_particles([[0, 0, R]], R, "m")
    sim.run(0.02)
    return sim, far


def test_removed_wall_leaves_the_engine_and_the_others_keep_their_history(table1):
    """Removing a wall drops its per-sphere slot (memory and the gather's test of it) and moves the
    history of the walls after it with them. The far wall never touched the sphere, so the run
    goes on exactly as if it were still there (same sums in the same order): bit for bit. A reset
    plate spring would let the sphere slip until the spring rebuilds (6e-7 m in 1 ms)."""
    sim, far = _sticking_on_second_wall(table1)
    kept, _ = _sticking_on_second_wall(table1)
    st = sim._state
    spring = st.whist.reshape(1, 2, -1)[0, 1].copy()
    assert np.abs(spring[3:6]).max() > 0  # the tangential spring holds the sphere
    sim.remove_wall(far)
    assert st.n_walls == 1 and st.whist.shape[0] == 1
    np.testing.assert_array_equal(st.whist[0], spring)
    # any change of the walls re-evaluates the forces at the present state; a change that is none
    kept.set_wall_velocity(kept.walls[0], velocity=(0.0, 0.0, 0.0))
    sim.run(0.001)
    kept.run(0.001)
    np.testing.assert_array_equal(sim.positions, kept.positions)
    np.testing.assert_array_equal(sim.angular_velocities, kept.angular_velocities)
    assert [w.name for w in sim.walls] == ["plate"]


def test_checkpoint_that_kept_a_removed_wall_restores_without_it(table1, tmp_path):
    """Checkpoints of before 2026-12-02 kept a removed wall's slot (kind -1) in the wall arrays."""
    sim, far = _sticking_on_second_wall(table1)
    spring = sim._state.whist.reshape(1, 2, -1)[0, 1].copy()
    path = sim.checkpoint(tmp_path / "old.npz")
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    meta = json.loads(str(arrays["meta"]))
    meta["walls"][0] = None
    arrays["meta"] = np.array(json.dumps(meta))
    arrays["wall_kind"] = arrays["wall_kind"].copy()
    arrays["wall_kind"][0] = -1
    np.savez(path, **arrays)
    back = rd.Simulation.restore(path)
    assert back._state.n_walls == 1
    np.testing.assert_array_equal(back._state.whist[0], spring)
    assert [w.name for w in back.walls] == ["plate"]
    back.run(0.001)
    sim.set_wall_velocity(sim.walls[0], velocity=(0.0, 0.0, 0.0))  # forces re-evaluated, as at removal
    sim.run(0.001)  # the far wall still in place: it never touched the sphere
    np.testing.assert_array_equal(back.positions, sim.positions)


def test_cylinder_wall_holds_particles(table1):
    """A sphere pulled sideways (g along x) against the inside of a cylinder of radius 0.02 m comes to
    rest at the Hertz static overlap under its weight, delta = (3 m g / (4 E* sqrt(R*)))^(2/3), with
    the wall a partner of infinite radius and stiffness-matched material (R* = R, E* = E / (2 (1 -
    nu^2)); docs/models.md section 0): 1.68e-6 m for Table 1. At rest the damping force vanishes, so what
    is left of the overlap error is an oscillation of amplitude v / omega, omega = sqrt(1.5 m g /
    (delta m)) ~ 3000 rad/s: with v < 1e-6 m/s that is below 4e-10 m, 2e-4 delta. Tolerance 1 % of
    delta (17 nm; measured 5e-12 delta): a wall taken as concave (R* = R Rc / (Rc - R), delta 9 %
    smaller), a wrong E* or a Hooke law would all fail it."""
    from conftest import TABLE1, sphere_mass

    sim = rd.Simulation(contact=rd.ContactModel("hertz"), gravity=(9.81, 0, 0), dt=5e-6)
    sim.add_material(table1(friction=0.0))
    sim.add_wall(rd.Cylinder(radius=0.02, point=(0, 0, 0), axis=(0, 0, 1), material="m"))
    sim.add_particles([[0, 0, 0]], R, "m")
    sim.run(0.3)
    e_star = TABLE1["youngs_modulus"] / (2 * (1 - TABLE1["poisson_ratio"] ** 2))
    delta = (3 * sphere_mass() * 9.81 / (4 * e_star * np.sqrt(R))) ** (2 / 3)
    assert np.abs(sim.velocities[0]).max() < 1e-6
    overlap = np.hypot(*sim.positions[0, :2]) - (0.02 - R)
    assert overlap == pytest.approx(delta, rel=0.01)
    assert abs(sim.positions[0, 2]) < 1e-12  # nothing pulls it along the axis



def _static_overlap():
    from conftest import TABLE1, sphere_mass

    e_star = TABLE1["youngs_modulus"] / (2 * (1 - TABLE1["poisson_ratio"] ** 2))
    return (3 * sphere_mass() * 9.81 / (4 * e_star * np.sqrt(R))) ** (2 / 3)


def test_cylinder_wall_outer_face_and_rim(table1):
    """A cylinder is a thin shell (docs/models.md section 0). (1) A sphere outside it, pulled against
    it by g along +x, rests on the outer face at the Hertz static overlap, 1 % as the inner-face test
    above: were the inner face's overlap r + R - Rc taken there (2R - delta, 10 mm), the sphere would
    be thrown through the wall. (2) A sphere centred over the top rim (r = Rc exactly, so the
    normal is the axis) rests on the rim at the same static overlap: delta = R - |centre - rim|.
    (3) A frictionless sphere dropped beside the rim, its centre R/2 outside it, glances off it
    outward and falls past the outer face: its centre ends below the rim with r >= Rc + R - delta
    (a normal the wrong way round, or the inner face's pull, puts it inside)."""
    delta = _static_overlap()
    rc, top = 0.02, 0.05
    sim = rd.Simulation(contact=rd.ContactModel("hertz"), gravity=(9.81, 0, 0), dt=5e-6)
    sim.add_material(table1(friction=0.0))
    sim.add_wall(rd.Cylinder(radius=rc, point=(0, 0, 0), axis=(0, 0, 1), extent=(0.0, top), material="m"))
    sim.add_particles([[-(rc + R), 0, 0.02]], R, "m", allow_overlap=True)
    sim.run(0.3)
    assert np.abs(sim.velocities[0]).max() < 1e-6
    assert (rc + R) - np.hypot(*sim.positions[0, :2]) == pytest.approx(delta, rel=0.01)

    sim = rd.Simulation(contact=rd.ContactModel("hertz"), dt=5e-6)
    sim.add_material(table1(friction=0.0))
    sim.add_wall(rd.Cylinder(radius=rc, point=(0, 0, 0), axis=(0, 0, 1), extent=(0.0, top), material="m"))
    sim.add_particles([[rc, 0, top + R], [-(rc + 0.5 * R), 0, top + 1.2 * R]], R, "m")
    sim.run(0.3)
    on_rim, beside = sim.positions
    assert abs(sim.velocities[0]).max() < 1e-6
    assert (top + R) - on_rim[2] == pytest.approx(delta, rel=0.01)
    assert beside[2] < top and np.hypot(*beside[:2]) >= rc + R - delta


def _bed(table1, n=600, seed=5, skin=0.002):
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), dt=1e-5, skin=skin, track_energy=True)
    sim.add_material(table1())
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    sim.insert(rd.BoxRegion((-0.06, -0.06, 0.0), (0.06, 0.06, 0.12)), n, 0.005, "m", seed=seed)
    return sim


def test_spatial_resort_keeps_particles_history_and_physics(table1, monkeypatch, tmp_path):
    """Re-sorting the storage slots changes only the order of summation: the same particle keeps
    its index, every open contact keeps its springs. Right after a re-sort the forces agree to
    round-off (a lost spring would change them by O(1)); 1000 steps later, re-sorting every 50,
    positions agree to 1e-10 m (R = 5 mm: round-off grows, measured 2e-14 m)."""
    import rollingdem.engine.state as eng

    monkeypatch.setattr(eng, "SORT_ABOVE", 1 << 40)
    bed = _bed(table1)
    bed.run(0.25)  # a resting bed, springs loaded
    assert bed.number_of_contacts() > bed.n_particles
    settled = bed.checkpoint(tmp_path / "bed.npz")
    ref, mixed = rd.Simulation.restore(settled), rd.Simulation.restore(settled)
    mixed._state.sort(2 * R + mixed.skin)
    assert not np.array_equal(mixed._state.ids, np.arange(mixed.n_particles))
    ref.run(steps=1)
    mixed.run(steps=1)
    np.testing.assert_allclose(mixed.forces, ref.forces, rtol=0, atol=1e-12 * np.abs(ref.forces).max())
    np.testing.assert_allclose(mixed.torques, ref.torques, rtol=0, atol=1e-12 * np.abs(ref.torques).max())
    monkeypatch.setattr(eng, "SORT_ABOVE", 0)
    monkeypatch.setattr(eng, "SORT_EVERY", 50)
    mixed.run(steps=1000)
    monkeypatch.setattr(eng, "SORT_ABOVE", 1 << 40)
    ref.run(steps=1000)
    np.testing.assert_allclose(mixed.positions, ref.positions, rtol=0, atol=1e-10)
    for channel, value in ref.dissipated_energy().items():
        assert mixed.dissipated_energy()[channel] == pytest.approx(value, rel=1e-9, abs=1e-15)
    # velocities are set by the user's index, whatever the slot
    mixed.set_velocities([7], velocity=(0.3, 0, 0))
    assert mixed.velocities[7].tolist() == [0.3, 0, 0]
    assert mixed._state.v[mixed._state.slots([7])[0]].tolist() == [0.3, 0, 0]
    # a checkpoint of the re-sorted state continues bit for bit
    again = rd.Simulation.restore(mixed.checkpoint(tmp_path / "m.npz"))
    mixed.run(steps=200)
    again.run(steps=200)
    np.testing.assert_array_equal(again.positions, mixed.positions)


def pool_rows(st):
    """Check the contact pool's bookkeeping (``rollingdem.engine.neighbors``) and return, per group, (the
    rows of its contacts in list order, its free rows, its first row): each contact has a row of
    its own among its group's rows, below the group's next unused row; the free list holds the
    group's other rows below it, so no row is lost and none is shared."""
    n, total = st.n, st.contact_list.size
    rows_of = st.contact_list.contact_row[:total]
    out = []
    for g in range(len(st.contact_list.groups)):
        first, last = st.contact_list.start[min(g * POOL_GROUP, n)], st.contact_list.start[min((g + 1) * POOL_GROUP, n)]
        rows = rows_of[first:last][rows_of[first:last] >= 0]
        fill = int(st.contact_list.groups[g, 1])
        free, r = [], int(st.contact_list.groups[g, 0])
        while r >= 0:
            free.append(r)
            r = int(st.contact_list.pool[r, 0])
        assert first <= fill <= last
        assert all(first <= r < fill for r in [*rows.tolist(), *free])
        assert len(set(rows.tolist()) | set(free)) == len(rows) + len(free) == fill - first
        out.append((rows, free, first))
    return out


def test_pool_rows_packed_in_list_order_after_a_rebuild(table1):
    """Right after a rebuild each group's contacts sit at the front of its rows in list order, with
    no free row, and an entry has a row exactly when its contact keeps a contact normal; a
    stale row (entries move at a rebuild) would leave the spring of a contact that opens in the
    next step behind, and a later contact of the same pair would start pre-loaded."""
    sim = _bed(table1, n=800, seed=2)  # 4 groups of the pool
    sim.run(0.08)  # the first spheres land
    kernel = sim.engine_module()
    checked = 0
    for _ in range(20):
        sim.run(steps=500)
        st = sim._state
        particles, walls, lists, _ = st.records()
        kernel.rebuild(particles, walls, lists, sim.skin, st.info)
        for rows, free, first in pool_rows(st):
            np.testing.assert_array_equal(rows, first + np.arange(len(rows)))
            assert free == []
        total = st.contact_list.size
        in_contact = np.any(st.contact_list.entry_history()[:, :3] != 0.0, axis=1)
        np.testing.assert_array_equal(st.contact_list.contact_row[:total] >= 0, in_contact)
        checked += int(in_contact.sum())
    assert checked > 100


def test_pool_rows_reused_between_rebuilds(table1):
    """With a skin so large that the list is never rebuilt, contacts open and close for thousands
    of steps: each one that opens takes a row of its group (a freed one first), each one that
    closes frees its row, and the bookkeeping holds throughout; the run is bit for bit the run that
    rebuilds its list (and so packs its rows anew) every few steps."""
    lazy = _bed(table1, n=600, seed=4, skin=0.03)
    eager = _bed(table1, n=600, seed=4, skin=1.2e-4)
    reused = 0
    for _ in range(12):
        lazy.run(steps=400)
        eager.run(steps=400)
        reused += sum(len(free) for _, free, _ in pool_rows(lazy._state))
        pool_rows(eager._state)
    assert lazy._state.info[I_REBUILDS] <= 2 and eager._state.info[I_REBUILDS] > 100
    assert reused > 0  # some contacts closed and left rows to their free lists
    np.testing.assert_array_equal(lazy.positions, eager.positions)
    np.testing.assert_array_equal(lazy.angular_velocities, eager.angular_velocities)


def test_list_growth_in_mid_step_changes_nothing(table1):
    """The list arrays grow when a rebuild finds them too small; that rebuild comes after the step's
    drift, so the kernel stops mid-step and the call after the growth goes on from there, without
    drifting again. A loose cube of spheres squeezed inwards outgrows its list during the run; it must
    end bit-identical to the same run started with room to spare."""
    def run(capacity):
        sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), dt=2e-6, gravity=(0, 0, 0))
        sim.add_material(table1())
        g = np.arange(6) * 2.5 * R  # beyond the cutoff 2 R + skin: the list starts empty
        x = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
        sim.add_particles(x, R, "m", velocity=-40.0 * (x - x.mean(0)))  # a cube squeezed inwards
        sim.run(steps=1)
        st = sim._state
        st.grow(capacity or st.contact_list.size)  # the list after the first step, kept, in arrays this big
        first = st.contact_list.capacity
        sim.run(steps=5000)
        return sim, first, st.contact_list.capacity

    small, first, grown = run(None)
    roomy, roomy_first, roomy_last = run(100_000)
    assert grown > first and roomy_last == roomy_first
    assert np.array_equal(small.positions, roomy.positions)
    assert np.array_equal(small.velocities, roomy.velocities)
    assert np.array_equal(small.angular_velocities, roomy.angular_velocities)


def test_blocked_pair_pass_matches_one_contact_at_a_time(table1, monkeypatch, tmp_path):
    """Spheres of one material have their pair contacts computed 64 at a time, one per SIMD lane
    (``block_contacts``); a contact spinning by 1e-3 rad or more in the step goes through the
    scalar ``contact`` (libm cos and sin) and keeps its lane. Both must give what the scalar pass,
    one contact at a time, gives: the same arithmetic, except that the compiler may fuse
    multiply-adds differently in vector code, so from the same state the forces agree to 1e-12 of
    their largest value (round-off is 1e-16 per operation), and after 300 more steps of collisions
    to 1e-8 (the chaotic growth of that round-off; any change of the force law would be O(1))."""
    from rollingdem.engine.state import EngineState
    from rollingdem.physics.contact.frame import SERIES_ANGLE

    blocked = cluster(table1, n_side=7, rolling="epsd", fast_spin=3000.0)  # 6e-3 rad per step
    assert 3000.0 * blocked.dt * 0.5 > SERIES_ANGLE  # so some contacts do take the scalar lane
    blocked.run(steps=400)
    assert blocked.number_of_contacts() > 64  # more than one block
    blocked.checkpoint(tmp_path / "state.npz")
    one_at_a_time = rd.Simulation.restore(tmp_path / "state.npz")
    original = EngineState.contact_blocks

    def empty_blocks(self):
        blocks, lanes = original(self)
        return blocks[:, :0], lanes
    for steps, rtol in ((1, 1e-12), (300, 1e-8)):
        blocked.run(steps=steps)
        with monkeypatch.context() as m:
            m.setattr(EngineState, "contact_blocks", empty_blocks)
            one_at_a_time.run(steps=steps)
        for name in ("forces", "torques", "velocities", "angular_velocities"):
            ref = getattr(one_at_a_time, name)
            np.testing.assert_allclose(getattr(blocked, name), ref, rtol=0, atol=rtol * np.abs(ref).max(),
                                       err_msg=name)
    # Two spheres in contact along x, spinning about x at 1e5 rad/s: 0.2 rad per step about the
    # normal, where the vector lanes' series for cos and sin would be 1e-7 off, while their sliding
    # spring builds up. The scalar lane keeps them exact to round-off.
    pairs = []
    for blocks in (original, empty_blocks):
        with monkeypatch.context() as m:
            m.setattr(EngineState, "contact_blocks", blocks)
            sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), gravity=(0, 0, 0), dt=2e-6)
            sim.add_material(table1())
            sim.add_particles([[0, 0, 0], [2 * R - 2e-6, 0, 0]], R, "m", velocity=[[0, 0.01, 0], [0, -0.01, 0]],
                              angular_velocity=[[1e5, 0, 0], [1e5, 0, 0]], allow_overlap=True)
            sim.run(steps=20)
            assert sim.number_of_contacts() == 1
            pairs.append((sim.forces.copy(), sim.torques.copy()))
    for got, ref in zip(*pairs):
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_spheres_of_several_materials_are_computed_one_contact_at_a_time(table1):
    sim = cluster(table1, n_side=2)
    blocks, _ = sim._state.contact_blocks()
    assert blocks.shape[1] > 0
    sim.add_material(table1("other"))
    sim.add_particles([[1.0, 1.0, 1.0]], R, "other")
    blocks, _ = sim._state.contact_blocks()
    assert blocks.shape[1] == 0


def test_clock_does_not_depend_on_how_the_steps_are_cut(table1):
    """t = t0 + (step - s0) dt from where the present dt took over: 1024 steps in one run, in runs of
    4, or through a checkpoint give the same time bit for bit (a running sum of dt did not: 0.01024
    against 0.010240000000000023), and the state too. After a change of dt the clock goes on from
    there."""
    def scene():
        sim = rd.Simulation(contact=rd.ContactModel("hertz"), dt=1e-5, gravity=(0, 0, 0))
        sim.add_material(table1())
        sim.add_particles([[0, 0, 0], [2.01 * R, 0, 0]], R, "m", velocity=[[0.05, 0, 0], [0, 0, 0]])
        return sim

    one = scene()
    one.run(steps=1024)
    cut = scene()
    for _ in range(256):
        cut.run(steps=4)
    assert cut.time == one.time == 1024 * 1e-5
    np.testing.assert_array_equal(cut.velocities, one.velocities)
    one.dt = 2e-5
    one.run(steps=10)
    assert one.time == 1024 * 1e-5 + 10 * 2e-5


class PythonControl(backends.CpuBackend):
    """The CPU's step loop with its control run as Python: ``advance``'s body calling the compiled
    phases, as the GPU runs it (``engine/cuda/step_loop.py``)."""
    name = "python-control"

    def step_loop(self, state, module):
        return super().step_loop(state, module).py_func


def falling_onto_a_rising_floor(table1, backend):
    """The cube of ``cluster`` falling onto a floor that rises at 0.05 m/s, with a skin of 0.1 mm: the list
    is rebuilt every few tens of steps."""
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="cdt"), gravity=(0, 0, -9.81), dt=2e-6, skin=1e-4, backend=backend)
    sim.add_material(table1())
    source = cluster(table1, n_side=3)
    sim.add_particles(source.positions, source.radii, "m", velocity=source.velocities,
                      angular_velocity=source.angular_velocities)
    sim.add_wall(rd.Plane(point=(0, 0, -1.02 * R), normal=(0, 0, 1), velocity=(0, 0, 0.05)))
    return sim


def test_the_step_control_run_as_python_steps_as_the_compiled_loop(table1, monkeypatch):
    """The step's control is written once (``advance``); the GPU runs its Python body with the
    phases bound to kernel launches. Run here with the CPU's compiled phases, it gives the compiled
    loop's bits: spheres colliding and falling onto a moving floor, in calls of 37 steps (each ends
    after the closing kick, the next opens the step), with neighbor-list rebuilds; and a free fall
    with a skin so small that a sphere becomes too fast: the same step refused, the same drift taken
    back."""
    monkeypatch.setitem(backends.BACKENDS, PythonControl.name, PythonControl())
    runs = {}
    for backend in ("cpu", PythonControl.name):
        sim = falling_onto_a_rising_floor(table1, backend)
        for _ in range(8):
            sim.run(steps=37)
        fall = rd.Simulation(contact=rd.ContactModel("hertz", rolling="cdt"), gravity=(0, 0, -9.81), dt=1e-4,
                             skin=2e-6, backend=backend, check_timestep=False)
        fall.add_material(table1())
        fall.add_particles([[0, 0, 0]], R, "m")
        with pytest.raises(rd.SimulationError, match="more than half the neighbor skin") as refused:
            fall.run(steps=100)
        runs[backend] = (sim.positions, sim.velocities, sim.angular_velocities, sim.engine_statistics()["neighbor_rebuilds"],
                         sim.number_of_contacts(), fall.positions, fall.velocities, fall.step, str(refused.value))
    compiled, python = runs.values()
    assert compiled[3] > 1 and compiled[4] > 0  # the lists were rebuilt, the spheres touch
    assert 0 < compiled[7] < 100  # the fall was refused part way
    for a, b in zip(compiled, python):
        np.testing.assert_array_equal(a, b)
