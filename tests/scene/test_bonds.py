"""The parallel bond (rollingdem.scene.bonds, docs/models.md §1.7). Its law driven through prescribed
motions of a bonded pair: the section and stiffnesses of the reference set B1, the pure-mode and
combined break loads of Potyondy & Cundall's criteria, the bond frame carried through a rigid
rotation. Bonds in a simulation: a pair's mode frequencies (BP-1), its energy (BP-4), breaking,
checkpoints, outputs, refusals."""

import math

import numpy as np
import pytest

from rollingdem.physics.bonds import BOND_BROKEN_SHEAR, BOND_BROKEN_TENSION, BOND_INPUTS, BOND_INTACT, bond_energy, parallel_bond
from rollingdem.physics.records import BOND_PARAMETERS, BOND_STATE
from rollingdem.scene.bonds import ParallelBond
from rollingdem.errors import ParameterError

# B1: equal spheres of R = 1 cm, lambda = 1, E = 1e8 Pa (k_n = E / 2R = 5e9 Pa/m), kappa = 2.5,
# sigma_c = c = 1 MPa, phi = 0, beta = 1
R = 0.01
B1 = ParallelBond(youngs_modulus=1e8, stiffness_ratio=2.5, tensile_strength=1e6, cohesion=1e6)
N = (1.0, 0.0, 0.0)  # the bond normal, from j to i


def test_b1_section_and_stiffnesses():
    """A = pi R^2 = 3.14159e-4 m^2, I = 7.85398e-9, J = 1.57080e-8 m^4; K_n = k_n A = 1.57080e6 N/m,
    K_s = 6.28319e5 N/m, K_b = k_n I = 39.2699 N m/rad, K_t = k_s J = 31.4159 N m/rad (to 6
    digits)."""
    p = dict(zip(BOND_PARAMETERS._fields, B1.parameter_row(R, R)))
    expected = dict(area=3.14159e-4, bending_inertia=7.85398e-9, polar_inertia=1.57080e-8, normal_stiffness=1.57080e6,
                    shear_stiffness=6.28319e5, bending_stiffness=39.2699, twisting_stiffness=31.4159, bond_radius=R)
    for key, value in expected.items():
        assert p[key] == pytest.approx(value, rel=1e-5), key


def drive(rv=(0, 0, 0), wi=(0, 0, 0), wj=(0, 0, 0), steps=100000, bond=B1, state=None, normal=N):
    """Bond b = 0 driven at constant relative velocity and spins, dt = 1 s, until it breaks: (the
    load before the breaking step, the steps taken, the mode, the last forces)."""
    p = np.array(bond.parameter_row(R, R))
    state = np.zeros((1, len(BOND_STATE))) if state is None else state
    g = np.array([*normal, *rv, *wi, *wj, R, R])
    assert len(g) == len(BOND_INPUTS)
    for step in range(1, steps + 1):
        before = state[0].copy()
        out = parallel_bond(state, 0, p, g, 1.0)
        if out[-1] != BOND_INTACT:
            return before, step, out[-1], out
    return state[0].copy(), steps, BOND_INTACT, out


def test_pure_tension_breaks_at_sigma_c_a():
    """Pulled apart at 1e-7 m per step: F_n = K_n u grows to sigma_c A = 314.16 N at u = sigma_c / k_n
    = 2.0e-4 m (one step is 0.157 N); the force on i pulls it back towards j; the strain energy
    before the break is F_n^2 / (2 K_n)."""
    load, steps, mode, _ = drive(rv=(1e-7, 0, 0))
    assert mode == BOND_BROKEN_TENSION
    assert load[BOND_STATE.normal_force] == pytest.approx(314.159, abs=0.16)
    assert steps * 1e-7 == pytest.approx(2.0e-4, abs=1e-7)
    state = np.zeros((1, len(BOND_STATE)))
    out = parallel_bond(state, 0, np.array(B1.parameter_row(R, R)), np.array([*N, 1e-5, 0, 0, *[0.0] * 6, R, R]), 1.0)
    assert out[0] == pytest.approx(-1.5708e6 * 1e-5, rel=1e-5)  # on i, towards j
    assert bond_energy(state, 0, np.array(B1.parameter_row(R, R))) == pytest.approx(15.708 ** 2 / (2 * 1.5708e6),
                                                                                     rel=1e-5)


def test_pure_shear_breaks_at_c_a():
    """Slid across n (no spin, so no bending): |F_s| = K_s u reaches c A = 314.16 N at u = 5.0e-4 m;
    the shear force on i opposes the slip and its torque on i is -R n x F_s."""
    load, steps, mode, out = drive(rv=(0, 1e-7, 0))
    assert mode == BOND_BROKEN_SHEAR
    assert -load[BOND_STATE.shear_y] == pytest.approx(314.159, abs=0.1)
    assert steps * 1e-7 == pytest.approx(5.0e-4, abs=1e-7)
    state = np.zeros((1, len(BOND_STATE)))
    out = parallel_bond(state, 0, np.array(B1.parameter_row(R, R)), np.array([*N, 0, 1e-6, 0, *[0.0] * 6, R, R]), 1.0)
    fy = -6.28319e5 * 1e-6
    assert out[1] == pytest.approx(fy, rel=1e-5)
    assert out[5] == pytest.approx(-R * fy, rel=1e-5) and out[8] == pytest.approx(-R * fy, rel=1e-5)  # z: -R (n x F)_z


def test_pure_bending_breaks_at_sigma_c_i_over_r():
    """Opposite spins across n (w_i = -w_j, centres still: no shear at the contact point): |M_b| =
    K_b theta reaches sigma_c I / (beta R) = 0.7854 N m at theta = 0.0200 rad."""
    load, steps, mode, _ = drive(wi=(0, 0, 1e-6), wj=(0, 0, -1e-6))
    assert mode == BOND_BROKEN_TENSION
    assert abs(load[BOND_STATE.bending_z]) == pytest.approx(0.785398, abs=1e-4)
    assert abs(load[BOND_STATE.shear_y]) < 1e-9
    assert steps * 2e-6 == pytest.approx(0.0200, abs=2e-6)


def test_pure_twisting_breaks_at_c_j_over_r():
    """A spin about n: |M_t| = K_t psi reaches c J / (beta R) = 1.5708 N m at psi = 0.0500 rad."""
    load, steps, mode, _ = drive(wi=(1e-6, 0, 0))
    assert mode == BOND_BROKEN_SHEAR
    assert abs(load[BOND_STATE.twisting_moment]) == pytest.approx(1.570796, abs=1e-4)
    assert steps * 1e-6 == pytest.approx(0.0500, abs=1e-6)


def test_tension_and_bending_together():
    """Pulled at v = 2 w R while bent at w_i = -w_j = w, so that F_n / A and M_b R / I grow alike: the
    bond breaks when they sum to sigma_c, at F_n = 157.08 N and M_b = 0.3927 N m (each half)."""
    w = 1e-6
    load, _, mode, _ = drive(rv=(2 * w * R, 0, 0), wi=(0, 0, w), wj=(0, 0, -w))
    assert mode == BOND_BROKEN_TENSION
    assert load[BOND_STATE.normal_force] == pytest.approx(157.08, abs=0.05)
    assert abs(load[BOND_STATE.bending_z]) == pytest.approx(0.39270, abs=1e-4)


def test_compression_strengthens_in_shear():
    """With phi = 30 degrees a bond compressed to F_n = -157.08 N holds shear up to
    (c + 157.08/A tan 30) A = 404.86 N (tau_c = 1.2887 MPa)."""
    bond = ParallelBond(youngs_modulus=1e8, stiffness_ratio=2.5, tensile_strength=1e6, cohesion=1e6,
                        friction_angle=30.0)
    state = np.zeros((1, len(BOND_STATE)))
    p = np.array(bond.parameter_row(R, R))
    push = -157.08 / 1.5707963e6  # m of approach
    parallel_bond(state, 0, p, np.array([*N, push, 0, 0, *[0.0] * 6, R, R]), 1.0)
    assert state[0, BOND_STATE.normal_force] == pytest.approx(-157.08, rel=1e-6)
    load, _, mode, _ = drive(rv=(0, 1e-7, 0), bond=bond, state=state)
    assert mode == BOND_BROKEN_SHEAR
    assert -load[BOND_STATE.shear_y] == pytest.approx(404.86, abs=0.1)
    assert -load[BOND_STATE.shear_y] / 3.14159265e-4 == pytest.approx(1.2887e6, rel=1e-4)


def test_a_rigid_rotation_carries_the_load_along():
    """A pre-loaded bond (shear and bending across n) turned rigidly at 20 rad/s about an axis across
    it for 2 rad (dt = 1e-4 s, the normal and the centres' velocities those of the rigid turn):
    no relative motion at the contact point, so |F_s| and |M_b| keep their values to 1e-6 and turn
    with the pair (F_s stays across n and along the turned direction)."""
    p = np.array(B1.parameter_row(R, R))
    state = np.zeros((1, len(BOND_STATE)))
    parallel_bond(state, 0, p, np.array([*N, 0, 1e-4, 0, 0, 0, 1e-3, 0, 0, -1e-3, R, R]), 1.0)
    fs0 = state[0, [BOND_STATE.shear_x, BOND_STATE.shear_y, BOND_STATE.shear_z]].copy()
    mb0 = state[0, [BOND_STATE.bending_x, BOND_STATE.bending_y, BOND_STATE.bending_z]].copy()
    omega, dt, steps = np.array([0.0, 0.0, 20.0]), 1e-4, 1000
    d = 2 * R
    for s in range(1, steps + 1):
        angle = 20.0 * s * dt
        n = np.array([math.cos(angle), math.sin(angle), 0.0])
        rv = np.cross(omega, d * n)  # v_i - v_j of the rigid turn
        parallel_bond(state, 0, p, np.array([*n, *rv, *omega, *omega, R, R]), dt)
    fs = state[0, [BOND_STATE.shear_x, BOND_STATE.shear_y, BOND_STATE.shear_z]]
    mb = state[0, [BOND_STATE.bending_x, BOND_STATE.bending_y, BOND_STATE.bending_z]]
    assert np.linalg.norm(fs) == pytest.approx(np.linalg.norm(fs0), rel=1e-6)
    assert np.linalg.norm(mb) == pytest.approx(np.linalg.norm(mb0), rel=1e-6)
    turn = np.array([[math.cos(2.0), -math.sin(2.0), 0], [math.sin(2.0), math.cos(2.0), 0], [0, 0, 1]])
    np.testing.assert_allclose(fs, turn @ fs0, atol=1e-6 * np.linalg.norm(fs0))
    assert abs(fs @ n) < 1e-9 * np.linalg.norm(fs0)


def test_bond_refusals():
    with pytest.raises(ParameterError, match="bond radius_multiplier = 0"):
        ParallelBond(youngs_modulus=1e8, radius_multiplier=0.0)
    with pytest.raises(ParameterError, match="bond friction_angle = 90"):
        ParallelBond(youngs_modulus=1e8, friction_angle=90.0)
    with pytest.raises(ParameterError, match="bond youngs_modulus"):
        ParallelBond(youngs_modulus=-1.0)


# --- bonds in a simulation ----------------------------------------------------------------------------
RHO = 2500.0
MASS = RHO * 4 / 3 * math.pi * R ** 3  # 1.04720e-2 kg
INERTIA = 0.4 * MASS * R ** 2
GAP = 1e-4  # the spheres start this far apart, so that their contact stays out of the way
LEVER = R + GAP / 2  # from each centre to the contact point


def bonded_pair(velocity=((0, 0, 0), (0, 0, 0)), angular_velocity=((0, 0, 0), (0, 0, 0)), bond=B1, dt=1e-6):
    import rollingdem as rd

    sim = rd.Simulation(gravity=(0, 0, 0), dt=dt)
    sim.add_material(rd.Material("m", youngs_modulus=1e8, poisson_ratio=0.3, density=RHO, restitution=0.5))
    sim.add_particles([[R + GAP / 2, 0, 0], [-R - GAP / 2, 0, 0]], radius=R, material="m", velocity=velocity,
                      angular_velocity=angular_velocity)
    assert sim.add_bonds(bond, gap=2 * GAP) == 1
    return sim


def period(signal, dt):
    """The mean period of ``signal`` (sampled every dt) from its upward crossings of its mean,
    interpolated within the step."""
    d = np.asarray(signal) - np.mean(signal)
    up = np.where((d[:-1] < 0) & (d[1:] >= 0))[0]
    times = (up + d[up] / (d[up] - d[up + 1])) * dt
    return np.diff(times).mean()


@pytest.mark.parametrize("mode", ["axial", "bending", "twisting", "shear"])
def test_a_bonded_pair_oscillates_at_its_mode_frequencies(mode):
    """BP-1: two B1 spheres (m = 1.0472e-2 kg, I = 0.4 m R^2) oscillate, each mode started alone, at
    omega^2 = 2 K_n / m (axial, T = 3.6276e-4 s), 2 K_b / I (bending: opposite spins across the
    bond), 2 K_t / I (twisting: opposite spins about it) and K_s (2/m + 2 L^2 / I) (shear with
    rotation: opposite velocities across the bond; L = R + gap/2 the lever to the contact point, so
    7 K_s / m for touching spheres, 0.36 % more here); the period measured over about ten cycles at
    dt = 1e-6 s within 0.2 % (the integrator's phase error is of order (omega dt)^2)."""
    k = dict(zip(BOND_PARAMETERS._fields, B1.parameter_row(R, R)))
    start, signal, omega2 = {
        "axial": (dict(velocity=((1e-3, 0, 0), (-1e-3, 0, 0))), lambda s: s.positions[0, 0],
                  2 * k["normal_stiffness"] / MASS),
        "bending": (dict(angular_velocity=((0, 0, 0.1), (0, 0, -0.1))), lambda s: s.angular_velocities[0, 2],
                    2 * k["bending_stiffness"] / INERTIA),
        "twisting": (dict(angular_velocity=((0.1, 0, 0), (-0.1, 0, 0))), lambda s: s.angular_velocities[0, 0],
                     2 * k["twisting_stiffness"] / INERTIA),
        "shear": (dict(velocity=((0, 1e-3, 0), (0, -1e-3, 0))), lambda s: s.forces[0, 1],
                  k["shear_stiffness"] * (2 / MASS + 2 * LEVER ** 2 / INERTIA))}[mode]
    sim = bonded_pair(**start)
    expected = 2 * math.pi / math.sqrt(omega2)
    samples = []
    for _ in range(int(10 * expected / sim.dt)):
        sim.run(steps=1)
        samples.append(signal(sim))
    assert period(samples, sim.dt) == pytest.approx(expected, rel=2e-3)
    if mode == "axial":
        assert expected == pytest.approx(3.6276e-4, rel=1e-4)


def energy_drift(dt, spin=0.0):
    """BP-4's pair (the first sphere at -x) run for 0.2 s: the largest relative
    change of kinetic plus bond strain energy, sampled 200 times."""
    import rollingdem as rd

    x = np.array([[-R - GAP / 2, 0, 0], [R + GAP / 2, 0, 0]])
    sim = rd.Simulation(gravity=(0, 0, 0), dt=dt)
    sim.add_material(rd.Material("m", youngs_modulus=1e8, poisson_ratio=0.3, density=RHO, restitution=0.5))
    sim.add_particles(x, radius=R, material="m",
                      velocity=np.array([[0, 0, -0.02], [0.01, 0.03, 0.01]]) + np.cross([0, 0, spin], x),
                      angular_velocity=np.array([[3.0, -2, 5], [-4, 1, 2]]) + [0, 0, spin])
    sim.add_bonds(ParallelBond(youngs_modulus=1e8, stiffness_ratio=2.5, tensile_strength=1e9, cohesion=1e9), gap=2 * GAP)
    e0 = sum(sim.kinetic_energy())
    drift = 0.0
    for _ in range(200):
        sim.run(steps=int(round(0.2 / dt / 200)))
        drift = max(drift, abs(sum(sim.kinetic_energy()) + sim.bond_energy() - e0) / e0)
    assert sim.number_of_contacts() == 0  # the contact stayed out of it
    return drift


def test_a_free_bonded_pair_keeps_its_energy():
    """BP-4: B1 pair with velocities (0, 0, -0.02), (0.01, 0.03, 0.01) m/s and spins (3, -2, 5),
    (-4, 1, 2) rad/s, no damping, 0.2 s: kinetic plus bond strain energy stays within 1e-4 of the
    start at dt = 2e-6 s (measured 9.0e-5), and the error is of second order:
    over 3 times smaller at 1e-6 s (measured 2.4e-5). With a rigid spin of 20 rad/s across the bond
    added, within 2e-4 at 2e-6 s (first order there: the mid-step velocity
    meets the end-of-step normal)."""
    coarse = energy_drift(2e-6)
    assert coarse < 1e-4
    assert energy_drift(1e-6) < coarse / 3
    assert energy_drift(2e-6, spin=20.0) < 2e-4


def test_a_bond_pulled_hard_enough_breaks():
    """Pulled apart at a relative speed v, a B1 bond takes up to (sigma_c A)^2 / (2 K_n) = 0.0314 J of
    the pair's 1/2 m* v^2: at 2 m/s (0.0105 J) it holds and the pair comes back; at 5 m/s (0.065 J)
    it breaks in tension, the spheres fly apart, and the bond's load is gone."""
    for speed, holds in ((2.0, True), (5.0, False)):
        sim = bonded_pair(velocity=((speed / 2, 0, 0), (-speed / 2, 0, 0)))
        sim.run(steps=250)  # 0.69 of a period (3.63e-4 s): past the turn, on the way back
        table = sim.bonds()
        assert (table["status"][0] == "intact") == holds, table
        if holds:
            assert sim.velocities[0, 0] < 0  # on its way back
        else:
            assert table["normal_force"][0] == 0.0 and sim.bond_energy() == 0.0
            assert sim.velocities[0, 0] > 0


def test_bonds_survive_a_checkpoint_bit_for_bit(tmp_path):
    """A run checkpointed halfway and restored ends where the uninterrupted one does, bit for bit."""
    import rollingdem as rd

    def fresh():
        return bonded_pair(velocity=((0, 0, -0.02), (0.01, 0.03, 0.01)), angular_velocity=((3, -2, 5), (-4, 1, 2)))

    whole = fresh()
    whole.run(steps=2000)
    half = fresh()
    half.run(steps=1000)
    half.checkpoint(tmp_path / "c.npz")
    restored = rd.Simulation.restore(tmp_path / "c.npz")
    restored.run(steps=1000)
    assert np.array_equal(restored.positions, whole.positions)
    assert np.array_equal(restored.angular_velocities, whole.angular_velocities)
    assert restored.bonds().equals(whole.bonds())


def test_bond_requests_refused():
    import rollingdem as rd

    sim = bonded_pair()
    sim.add_particles([[0, 3 * R, 0]], radius=R, material="m")
    with pytest.raises(ParameterError, match=r"pairs: \[2, 2\] is not allowed: a bond between a particle and itself"):
        sim.add_bonds(B1, pairs=[[0, 2], [2, 2]])
    with pytest.raises(ParameterError, match="pairs: particle 5 is not allowed"):
        sim.add_bonds(B1, pairs=[[0, 5]])
    with pytest.raises(ParameterError, match="bonded twice"):
        sim.add_bonds(B1, pairs=[[1, 0]])
    with pytest.raises(ParameterError, match="give exactly one of pairs"):
        sim.add_bonds(B1)
    with pytest.raises(ParameterError, match="must be a rollingdem.ParallelBond"):
        sim.add_bonds("pbond", gap=0.0)
    assert sim.add_bonds(B1, pairs=[[0, 2]]) == 1
    assert list(sim.bonds()["j"]) == [1, 2]
    assert isinstance(rd.ParallelBond(youngs_modulus=1e8), ParallelBond)


def test_bonds_in_the_outputs(tmp_path):
    """The time series counts the intact and broken bonds; the snapshots hold the bonds as lines
    between their particles with their forces (read back with meshio)."""
    import meshio
    import pandas as pd

    import rollingdem as rd

    sim = bonded_pair(velocity=((2.5, 0, 0), (-2.5, 0, 0)))  # breaks in tension (above)
    sim.run(steps=200, observers=[rd.TimeSeries(tmp_path / "series.csv", interval=5e-5),
                                  rd.VTKSnapshots(tmp_path / "vtk", interval=1e-4)])
    series = pd.read_csv(tmp_path / "series.csv")
    assert series["bonds_intact"].iloc[0] == 1 and series["bonds_intact"].iloc[-1] == 0
    assert series["bonds_broken_tension"].iloc[-1] == 1
    first = meshio.read(sorted((tmp_path / "vtk").glob("bonds_*.vtu"))[0])
    assert first.cells[0].type == "line" and first.cells[0].data.tolist() == [[0, 1]]
    assert first.cell_data["status"][0][0] == 0
    assert (tmp_path / "vtk" / "bonds.pvd").exists()


def test_bonds_follow_their_particles_through_an_outlet_and_a_sort():
    """A chain of three bonded spheres and a fourth that falls into an outlet: the outlet takes the
    fourth and its bond to the chain's end, the others keep theirs under the closed-up indices; the
    storage re-sort that follows keeps each bond on its two particles (the bond's length, the
    particles' distance, unchanged)."""
    import rollingdem as rd

    sim = rd.Simulation(gravity=(0, 0, -9.81), dt=1e-6)
    sim.add_material(rd.Material("m", youngs_modulus=1e8, poisson_ratio=0.3, density=RHO, restitution=0.5))
    # the chain from +x to -x, so that the re-sort (along x) reverses its slots
    x = [[3 * (2 * R + GAP), 0, -0.1], [2 * (2 * R + GAP), 0, 0], [2 * R + GAP, 0, 0], [0, 0, 0]]
    sim.add_particles(x, radius=R, material="m")
    sim.add_bonds(B1, pairs=[[1, 2], [2, 3], [3, 0]])
    sim.add_outlet(rd.BoxRegion((-1, -1, -1), (1, 1, -0.05)), interval=1e-5)
    sim.run(steps=20)
    assert sim.n_particles == 3
    table = sim.bonds()
    assert table[["i", "j"]].to_numpy().tolist() == [[0, 1], [1, 2]]
    sim._state.sort(4 * R)
    assert sim._state._slots is not None and not np.array_equal(sim._state.bond_pairs, [[0, 1], [1, 2]])
    table = sim.bonds()
    assert table[["i", "j"]].to_numpy().tolist() == [[0, 1], [1, 2]]  # by id, as before
    d = np.linalg.norm(sim.positions[table["i"]] - sim.positions[table["j"]], axis=1)
    np.testing.assert_allclose(d, 2 * R + GAP, rtol=1e-6)


def pressed_pair(mode, rolling, tensile_strength=1e6, steps=300):
    """Two spheres pressed 10 um into each other, bonded (B1's stiffness), spun against each other
    at 1 rad/s (bending the bond), with rolling resistance ``rolling`` (mu_r = 0.3), run ``steps``."""
    import rollingdem as rd

    sim = rd.Simulation(contact=rd.ContactModel(rolling=rolling), gravity=(0, 0, 0), dt=1e-6)
    sim.add_material(rd.Material("m", youngs_modulus=1e8, poisson_ratio=0.3, density=RHO, restitution=0.5,
                                 rolling_friction=0.3))
    sim.add_particles([[R - 5e-6, 0, 0], [-R + 5e-6, 0, 0]], radius=R, material="m",
                      angular_velocity=[[0, 0, 0.5], [0, 0, -0.5]], allow_overlap=True)
    sim.add_bonds(ParallelBond(youngs_modulus=1e8, tensile_strength=tensile_strength, cohesion=1e6,
                               contact_while_bonded=mode), gap=0.0)
    sim.run(steps=steps)
    return sim


def rolling_spring(sim):
    """The spring moment M_k (``SPRING_HISTORY``) of the pair's contact, or zeros without one."""
    lists = sim._state.contact_list
    hist = lists.entry_history()
    at = sim.contact.layout()["ROLLING_HISTORY"]
    touching = np.nonzero(lists.contact_row[:lists.size] >= 0)[0]
    return hist[touching[0], at:at + 3] if len(touching) else np.zeros(3)


def test_a_bond_keeps_rolling_resistance_off_while_it_holds():
    """BP-5's hand-over, on the pressed pair with EPSD rolling resistance. While the bond holds, no
    rolling moment acts between the pair in either mode: with ``exclusive`` there is no contact,
    and the motion is bit for bit that of the pair without rolling resistance; with ``parallel``
    (PFC) Hertz and sliding act beside the bond, the rolling spring stays at exactly zero, and the
    motion is again bit for bit that without rolling resistance. Pulled apart at 5 m/s the
    exclusive bond breaks."""
    exclusive_alone = pressed_pair("exclusive", "none")
    exclusive = pressed_pair("exclusive", "epsd")
    parallel_alone = pressed_pair("parallel", "none")
    parallel = pressed_pair("parallel", "epsd")
    assert exclusive.number_of_contacts() == 0 and parallel.number_of_contacts() == 1
    for a, b in ((exclusive, exclusive_alone), (parallel, parallel_alone)):
        assert np.array_equal(a.torques, b.torques)
        assert np.array_equal(a.positions, b.positions)
        assert np.array_equal(a.angular_velocities, b.angular_velocities)
    assert np.array_equal(rolling_spring(parallel), np.zeros(3))
    assert parallel.positions[0, 0] > exclusive.positions[0, 0]  # Hertz pushed them apart
    exclusive.set_velocities([0, 1], velocity=[[2.5, 0, 0], [-2.5, 0, 0]])
    exclusive.run(steps=100)
    assert exclusive.bonds()["status"][0] == "tension"


def test_rolling_resistance_starts_from_zero_when_a_parallel_bond_breaks():
    """BP-5 after the break. A weak parallel bond (sigma_c = 2 kPa) on the pressed pair breaks in
    bending: its bending mode (omega = sqrt(2 K_b / I) = 1.37e4 rad/s) turns the 1 rad/s relative
    spin into a moment K_b theta that reaches sigma_c I/R = 1.57e-3 N m after about 40 steps. Up to
    the break the contact's rolling spring is zero; one step after it, EPSD's spring holds one
    increment, k_r |w_i - w_j| dt with k_r = 2.25 k_n mu_r^2 R*^2 and k_n = 4/3 E* sqrt(R* delta):
    it starts from zero (an accumulated spring would hold tens of increments). Tolerance 2 %: over
    the step the overlap and spins change by less than 1e-3."""
    sim = pressed_pair("parallel", "epsd", tensile_strength=2e3, steps=1)
    for _ in range(200):
        if sim.bonds()["status"][0] != "intact":
            break
        assert np.array_equal(rolling_spring(sim), np.zeros(3))
        sim.run(steps=1)
    assert sim.bonds()["status"][0] == "tension"  # bending counts in the tensile criterion
    assert np.array_equal(rolling_spring(sim), np.zeros(3))
    w = sim.angular_velocities
    sim.run(steps=1)
    w = 0.5 * (w + sim.angular_velocities)
    e_star = 1e8 / (2 * (1 - 0.3 ** 2))
    r_star = R / 2
    overlap = 2 * R - np.linalg.norm(sim.positions[0] - sim.positions[1])
    k_r = 2.25 * (4 / 3) * e_star * math.sqrt(r_star * overlap) * 0.3 ** 2 * r_star ** 2
    spring = rolling_spring(sim)
    assert np.linalg.norm(spring) == pytest.approx(k_r * abs(w[0, 2] - w[1, 2]) * 1e-6, rel=0.02)


def test_bonds_from_a_case_file(tmp_path):
    """A case file's stage makes bonds (by gap) before it runs; the time series counts them; a
    stage's bad bond gets one line naming it, exit status 2."""
    import pandas as pd
    from typer.testing import CliRunner

    from rollingdem.cli import app

    text = f"""\
name: pair
gravity: [0, 0, 0]
dt: 1.0e-6
materials:
  - {{name: m, youngs_modulus: 1.0e8, poisson_ratio: 0.3, density: 2500.0}}
particles:
  - positions: [[{-R - GAP / 2}, 0, 0], [{R + GAP / 2}, 0, 0]]
    radius: {R}
    material: m
    velocity: [[-2.5, 0, 0], [2.5, 0, 0]]
stages:
  - {{name: pull, duration: 2.0e-4, bonds: {{gap: {2 * GAP}, youngs_modulus: 1.0e8}}}}
output:
  time_series: {{interval: 1.0e-5}}
  plot: false
"""
    case = tmp_path / "case.yaml"
    case.write_text(text)
    ran = CliRunner().invoke(app, ["run", str(case), "--out", str(tmp_path / "out"), "--no-progress"])
    assert ran.exit_code == 0, ran.output
    assert "1 bonds" in ran.output
    series = pd.read_csv(tmp_path / "out" / "series.csv")
    assert series["bonds_intact"].iloc[0] == 1 and series["bonds_broken_tension"].iloc[-1] == 1
    case.write_text(text.replace("youngs_modulus: 1.0e8}}", "youngs_modulus: 1.0e8, radius_multiplier: 0}}"))
    bad = CliRunner().invoke(app, ["run", str(case), "--out", str(tmp_path / "bad"), "--no-progress"])
    assert bad.exit_code == 2 and "stage 'pull': bonds: bond radius_multiplier = 0" in bad.output, bad.output


def test_the_bond_dashpot_damps_the_axial_mode_at_its_ratio():
    """With damping_ratio zeta = 0.05 the pair's axial mode (c_n = 2 zeta sqrt(m* K_n)) is a damped
    oscillator: successive separations' peaks fall by exp(-2 pi zeta / sqrt(1 - zeta^2)) = 0.7301
    per period, within 1 % (peaks found to a step, 1/360 of the period)."""
    damped = ParallelBond(youngs_modulus=1e8, stiffness_ratio=2.5, tensile_strength=1e6, cohesion=1e6,
                          damping_ratio=0.05)
    sim = bonded_pair(velocity=((1e-3, 0, 0), (-1e-3, 0, 0)), bond=damped)
    gap = []
    for _ in range(1200):
        sim.run(steps=1)
        gap.append(sim.positions[0, 0] - sim.positions[1, 0] - 2 * R - GAP)
    gap = np.array(gap)
    peaks = [gap[k] for k in range(1, len(gap) - 1) if gap[k] > gap[k - 1] and gap[k] >= gap[k + 1]]
    ratio = np.array(peaks[1:3]) / np.array(peaks[0:2])
    np.testing.assert_allclose(ratio, math.exp(-2 * math.pi * 0.05 / math.sqrt(1 - 0.05 ** 2)), rtol=0.01)


def test_a_bonded_cantilever_bends_as_the_hinged_chain():
    """BP-3: a chain of N = 10 B1 bonds from a fixed sphere (exclusive bonds, dashpots zeta = 0.7,
    16 s) under its own weight across it: the tip's mean over the last 2 s sinks as the statically
    determinate chain of hinged springs (``hinged_chain_deflection``: each bond turns about its
    contact point by M/K_b and shifts by V/K_s) does, 1.5058 mm (delta / L = 0.75 %), within 1e-3,
    ample for a deflection of 0.75 % of the length."""
    from rollingdem.experiments.contact_laws import bonded_chain, hinged_chain_deflection

    (dx, dy, dz), k, lb = bonded_chain((0, -9.81, 0))
    expected = hinged_chain_deflection(MASS * 9.81, 10, lb, k["bending_stiffness"], k["shear_stiffness"])
    assert -dy == pytest.approx(expected, rel=1e-3)
    assert expected == pytest.approx(1.5058e-3, rel=1e-4)
    # one force at the tip: the sum is the closed form F L^3/(3 E I) (1 - 1/(4 N^2)) + N F / K_s
    one = hinged_chain_deflection(1.0, 1, lb, k["bending_stiffness"], k["shear_stiffness"])
    assert one == pytest.approx(lb ** 3 / (3 * 1e8 / (2 * R) * lb * k["bending_inertia"]) * (1 - 1 / 4)
                                + 1 / k["shear_stiffness"], rel=1e-12)


def test_a_bonded_chain_stretches_under_its_weight():
    """BP-3b: the chain hanging along its axis from its fixed sphere (gravity along +x, away from it):
    bond k carries (N - k + 1) m g, so the free end moves m g N (N + 1) / (2 K_n) out, within 1e-3."""
    from rollingdem.experiments.contact_laws import bonded_chain

    (dx, dy, dz), k, lb = bonded_chain((9.81, 0, 0))
    assert dx == pytest.approx(MASS * 9.81 * 10 * 11 / (2 * k["normal_stiffness"]), rel=1e-3)


def test_a_bonded_chain_twists_as_torsion_springs_in_series():
    """BP-3c: the chain of 10 bonds from its fixed sphere, started in its slowest twisting mode,
    turns with the period 2 pi / (2 sqrt(K_t / I) sin(pi / 42)) = 4.854e-3 s of ten torsion
    springs in series (each bond's twisting moment on both of its spheres, with opposite signs).
    Tolerance 1e-4: at 1000 steps per period the integrator's period error is (omega dt)^2 / 24,
    2e-6, and the crossings are interpolated linearly."""
    from rollingdem.experiments.contact_laws import twisting_chain_period

    period, expected = twisting_chain_period()
    assert expected == pytest.approx(4.854e-3, rel=1e-4)
    assert period == pytest.approx(expected, rel=1e-4)


def test_the_time_step_check_takes_the_stiffest_bond_mode():
    """For the B1 pair the stiffest mode is shear with rotation, omega^2 = K_s (2/m + 2 R^2 / I) =
    7 K_s / m (20,494 rad/s): the bond limit is a tenth of its period, 3.066e-5 s."""
    sim = bonded_pair()
    (label, limit), = [x for x in sim.time_step_limits() if x[0].startswith("bond")]
    k = dict(zip(BOND_PARAMETERS._fields, B1.parameter_row(R, R)))
    assert limit == pytest.approx(0.1 * 2 * math.pi / math.sqrt(7 * k["shear_stiffness"] / MASS), rel=1e-12)
    assert math.sqrt(7 * k["shear_stiffness"] / MASS) == pytest.approx(20494, rel=1e-4)


def test_a_gap_that_bonds_nothing_says_so_once(table1):
    """Two spheres 1 mm apart: gap = -0.0001 m (asking for an overlap of 0.1 mm) bonds none and
    warns that it made no bond; gap = 0.002 m bonds the pair, silently."""
    import warnings

    import rollingdem as rd

    sim = rd.Simulation()
    sim.add_material(table1())
    sim.add_particles([[0, 0, 0], [0.011, 0, 0]], 0.005, "m")
    bond = ParallelBond(youngs_modulus=1e8, tensile_strength=2e5, cohesion=2e5)
    with pytest.warns(RuntimeWarning, match=r"bonds: gap = -0.0001 m made no bond"):
        assert sim.add_bonds(bond, gap=-1e-4) == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert sim.add_bonds(bond, gap=0.002) == 1


def test_a_bonds_load_is_among_the_contact_forces():
    """``Simulation.contact_forces`` lists an intact bond as a force between its two spheres: a
    bonded pair pulled apart and spun, no gravity, no contact: the listed force on each (+ on i,
    - on j) is the force the engine summed for it (1e-12 of it), its branch the centres' difference,
    and its moment with the levers gives each sphere's torque."""
    sim = bonded_pair(velocity=((0.01, 0.002, 0), (-0.01, 0, 0.001)), angular_velocity=((0, 0, 5), (3, 0, 0)))
    sim.run(steps=200)
    c = sim.contact_forces()
    assert len(c["i"]) == 1 and c["j"][0] >= 0
    total = np.zeros((2, 3))
    total[c["i"][0]] += c["force"][0]
    total[c["j"][0]] -= c["force"][0]
    assert np.abs(sim.forces).max() > 0.0
    np.testing.assert_allclose(total, sim.forces, rtol=0, atol=1e-12 * np.abs(sim.forces).max())
    np.testing.assert_allclose(c["branch"][0], sim.positions[c["i"][0]] - sim.positions[c["j"][0]], rtol=1e-14)
    # the bond's pure moment (bending, twisting) and the shear force's levers R - overlap/2 give each torque
    b = c["branch"][0]
    n, overlap = b / np.linalg.norm(b), 2 * R - np.linalg.norm(b)
    lever_torque = -(R - 0.5 * overlap) * np.cross(n, c["force"][0])
    torque = np.zeros((2, 3))
    torque[c["i"][0]], torque[c["j"][0]] = lever_torque + c["moment"][0], lever_torque - c["moment"][0]
    assert np.abs(c["moment"][0]).max() > 0.0
    np.testing.assert_allclose(torque, sim.torques, rtol=0, atol=1e-12 * np.abs(sim.torques).max())
