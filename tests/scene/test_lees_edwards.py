"""Lees-Edwards boundaries: a pair meeting across the sheared end is the same pair in the open, an
affine start keeps its linear velocity profile, the shift is resumed from a checkpoint, and the
refusals.
"""

import numpy as np
import pytest

import rollingdem as rd
from rollingdem.engine.state import minimum_image_branch
from rollingdem.errors import ParameterError

from conftest import R

L = 0.1  # box length along each periodic axis (m)
U = 2.0  # the shear velocity across the gradient end (m/s)
DRIFT = 3.35  # m/s along z, both spheres: the lower one crosses the upper end while the contact lasts


def _pair(table1, sheared):
    """The oblique, spinning collision of tests/scene/test_periodic.py turned along z, drifting along
    z; in the open, or straddling the upper end z = 0.05 of a box periodic along x and z and sheared
    along x (gradient z): the upper sphere starts as its wrapped self (z - L, v_x - U)."""
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), gravity=(0, 0, 0), dt=2e-6,
                        periodic={"x": (-0.05, 0.05), "z": (-0.05, 0.05)} if sheared else None,
                        lees_edwards=rd.LeesEdwards(shear_velocity=U, gradient="z") if sheared else None)
    sim.add_material(table1())
    centre = 0.05 if sheared else 0.0
    a = np.array([0.3 * R, 0.3 * R, centre - 1.2 * R])
    b = np.array([-0.2 * R, -0.2 * R, centre + 1.2 * R])
    va, vb = np.array([0.05, 0.0, DRIFT + 0.4]), np.array([0.0, 0.02, DRIFT - 0.3])
    if sheared:
        b[2] -= L
        vb[0] -= U
    sim.add_particles([a], R, "m", velocity=va, angular_velocity=(5.0, 0.0, 30.0))
    sim.add_particles([b], R, "m", velocity=vb, angular_velocity=(0.0, 10.0, -20.0))
    trace = []
    for _ in range(30):
        sim.run(steps=100)
        x, v = sim.positions, sim.velocities
        # the relative position and velocity of b seen from a, and a's velocity, as in the open
        rel = (minimum_image_branch((x[1] - x[0])[None], sim._state.contact_list.box)[0] if sheared
               else x[1] - x[0])
        k = np.round((x[1, 2] - x[0, 2]) / L) if sheared else 0.0
        rv = v[1] - v[0] - np.array([k * U, 0, 0])
        va_open = v[0] + np.array([U * sim._state.image[0, 2] if sheared else 0.0, 0, 0])
        trace.append(np.concatenate([rel, rv, va_open, sim.angular_velocities.ravel(), sim.forces.ravel(),
                                     sim.torques.ravel()]))
    return np.array(trace), sim


def test_a_pair_across_the_sheared_end_is_the_pair_in_the_open(table1):
    """The pair straddling the sheared end z = 0.05 (the upper sphere wrapped to z - L with v_x - U)
    follows the same pair in the open: the same forces and torques, so the same tangential and rolling
    history, while the image it meets moves at U and the lower sphere crosses the end (its x less the
    shift, its v_x less U). Equal to 1e-9 of each quantity's scale (round-off grown by the contact,
    as for the unsheared periodic pair)."""
    open_pair, _ = _pair(table1, sheared=False)
    across, sim = _pair(table1, sheared=True)
    forces = open_pair[:, 15:21]
    assert np.abs(forces).max() > 0.1 and np.abs(forces[-1]).max() == 0.0  # a collision, over by the end
    assert sim._state.image[0, 2] == 1 and sim.shear.shift > 0.0  # the lower sphere crossed the upper end
    scale = np.abs(open_pair).max(axis=0) + 1e-30
    np.testing.assert_array_less(np.abs(across - open_pair) / scale, 1e-9)


def _sheared_gas(table1, rate, steps, lees_edwards=True):
    """About 1,100 spheres of R = 2 mm (solid fraction 0.3) in a 5 cm periodic cube, gravity off,
    started on the affine profile v_x = rate (z - z_mid) plus a random 5 % of the shear velocity."""
    side, r = 0.05, 0.002
    sim = rd.Simulation(gravity=(0, 0, 0), periodic={a: (0.0, side) for a in "xyz"},
                        lees_edwards=rd.LeesEdwards(shear_rate=rate, gradient="z") if lees_edwards else None)
    sim.add_material(table1())
    sim.insert(rd.BoxRegion((0, 0, 0), (side, side, side)), 1100, r, "m", seed=3)
    rng = np.random.default_rng(4)
    x = sim.positions
    v = 0.05 * rate * side * rng.standard_normal((len(x), 3))
    v[:, 0] += rate * (x[:, 2] - 0.5 * side)
    sim.set_velocities(np.arange(len(x)), velocity=v)
    sim.run(steps=steps)
    return sim, side


def _slab_means(sim, side, slabs=5):
    """The mean v_x of ``slabs`` slabs along z less the affine profile's at their centres, in units of
    the shear velocity."""
    x, v = sim.positions, sim.velocities
    rate = 100.0
    which = np.minimum((x[:, 2] / side * slabs).astype(int), slabs - 1)
    centres = (np.arange(slabs) + 0.5) * side / slabs
    mean = np.array([v[which == s, 0].mean() for s in range(slabs)])
    return (mean - rate * (centres - 0.5 * side)) / (rate * side)


def test_an_affine_start_keeps_its_linear_velocity_profile(table1):
    """Sheared at 100 /s to a strain of 2, the inelastic gas keeps v_x = rate (z - z_mid): each of 5
    slabs' mean v_x within 0.03 U of the line (about 220 spheres per slab, whose v_x scatter by ~0.1 U
    about it: the slab means by ~0.01 U; 0.014 U measured). In a box periodic but not sheared the
    ends meet at rest relative to each other and the profile bends there: the outer slabs lag the
    line by more than 0.1 U (0.12-0.14 U measured)."""
    rate = 100.0
    sim, side = _sheared_gas(table1, rate, 1)
    steps = int(round(2.0 / rate / sim.dt))
    sim.run(steps=steps)
    np.testing.assert_array_less(np.abs(_slab_means(sim, side)), 0.03)
    assert sim.shear.shift == pytest.approx((rate * side * (steps + 1) * sim.dt) % side, rel=1e-9)
    plain, _ = _sheared_gas(table1, rate, steps + 1, lees_edwards=False)
    off = _slab_means(plain, side)
    assert off[0] > 0.1 and off[-1] < -0.1


def test_a_resumed_sheared_run_continues_bit_for_bit(table1, tmp_path):
    """Checkpointed mid-run and restored, the sheared gas steps to the same state as the run that
    went on: the shift and the shear velocity are part of the checkpoint."""
    sim, side = _sheared_gas(table1, 100.0, 300)
    sim.checkpoint(tmp_path / "c.npz")
    sim.run(steps=300)
    again = rd.Simulation.restore(tmp_path / "c.npz")
    assert again.shear.shear_rate == pytest.approx(100.0, rel=1e-15)
    again.run(steps=300)
    np.testing.assert_array_equal(again.positions, sim.positions)
    np.testing.assert_array_equal(again.velocities, sim.velocities)
    assert again.shear.shift == sim.shear.shift


@pytest.mark.parametrize("kwargs, words", [
    (dict(periodic={"x": (0, 1)}, lees_edwards=rd.LeesEdwards(shear_rate=1.0, gradient="z")),
     "the flow axis x and the gradient axis z must be periodic, and z is not"),
    (dict(periodic={"x": (0, 1), "z": (0, 1)}, lees_edwards=rd.LeesEdwards(shear_rate=1.0, gradient="x")),
     "lees_edwards gradient = 'x' is not known"),
    (dict(periodic={"x": (0, 1), "z": (0, 1)}, lees_edwards=rd.LeesEdwards()),
     "give one of shear_rate"),
    (dict(periodic={"x": (0, 1), "z": (0, 1)}, lees_edwards=rd.LeesEdwards(shear_rate=float("nan"))),
     "lees_edwards shear_rate = nan is not allowed"),
    (dict(periodic={"x": (0, 1), "z": (0, 1)}, lees_edwards={"shear_rate": 1.0}),
     "must be rd.LeesEdwards"),
])
def test_lees_edwards_refusals(kwargs, words):
    with pytest.raises(ParameterError, match=words):
        rd.Simulation(**kwargs)


def test_walls_and_rigid_bodies_in_a_sheared_box_are_refused(table1):
    sim = rd.Simulation(periodic={"x": (0, 0.1), "z": (0, 0.1)}, lees_edwards=rd.LeesEdwards(shear_rate=1.0))
    sim.add_material(table1())
    sim.add_particles([[0.05, 0.0, 0.05]], R, "m")
    sim.add_wall(rd.Cylinder(0.04, point=(0.05, 0, 0.05), axis=(0, 1, 0), material="m"))
    with pytest.raises(ParameterError, match="lees_edwards = .* is not allowed with a cylinder wall"):
        sim.run(steps=1)
    with pytest.raises(ParameterError, match="no Lees-Edwards boundaries"):
        rd.Simulation().shear.shear_rate = 1.0


def test_every_touching_pair_across_the_moving_images_is_a_contact(table1):
    """At 20 checks over a strain of 4 at 200 /s (the images move 0.2 box lengths, two cells, between
    checks, so that the shift takes many offsets against the cell rows), the pairs the step computed are exactly the pairs that
    overlap by the sheared minimum image, found by brute force over all pairs: the cell search
    across the sheared end and the rebuild as the images move miss none."""
    sim, side = _sheared_gas(table1, 200.0, 1)
    for _ in range(20):
        sim.run(steps=int(round(0.2 / 200.0 / sim.dt)))
        x, r = sim.positions, sim.radii
        i, j = np.triu_indices(len(x), 1)
        branch = minimum_image_branch(x[i] - x[j], sim._state.contact_list.box)
        touching = np.linalg.norm(branch, axis=1) < r[i] + r[j]
        expected = {(a, b) for a, b in zip(i[touching], j[touching])}
        c = sim.contact_forces()
        found = {(min(a, b), max(a, b)) for a, b in zip(c["i"], c["j"])}
        assert found == expected


def test_between_builds_spheres_and_images_come_at_most_a_skin_closer():
    """Between two builds of the list each sphere drifts less than its share of the skin and the
    images across the sheared end move less than the shift at which ``move_images`` asks for a
    build; two spheres across that end then come at most 2 drift + shift closer, which must not
    exceed the skin, or a pair outside the list could touch. In a box not sheared each may drift
    skin/2."""
    from rollingdem.engine.integrator import move_images
    from rollingdem.engine.layout import DRIFT_SHARE, SHEARED_DRIFT_SHARE
    from rollingdem.engine.state import periodic_box

    skin, dt, velocity = 1e-3, 1e-6, 3.0
    box = periodic_box({"x": (0.0, 1.0), "z": (0.0, 1.0)}, "z", velocity)
    limit = SHEARED_DRIFT_SHARE * skin
    moves = 1
    while move_images(dt, box, limit) == 0:
        moves += 1
    shift_before_build = (moves - 1) * dt * velocity
    assert 2 * limit + shift_before_build <= skin * (1 + 1e-9)
    assert shift_before_build > skin - 2 * limit - dt * velocity  # the build is asked for no later than needed
    assert shift_before_build > 0.25 * skin  # the images may move: a build is not asked at every step
    assert DRIFT_SHARE == 0.5


SHEAR_CASE = """\
name: sheared-gas
materials:
  - {name: m, youngs_modulus: 5.0e6, poisson_ratio: 0.3, density: 2500.0, friction: 0.5, restitution: 0.5}
gravity: [0, 0, 0]
periodic: {x: [0.0, 0.03], y: [0.0, 0.03], z: [0.0, 0.03], shear_rate: 50.0, gradient: z}
particles:
  - insert: {type: box, lo: [0, 0, 0], hi: [0.03, 0.03, 0.03]}
    count: 300
    radius: 0.001
    material: m
    seed: 1
stages:
  - {name: shear, duration: 0.02}
"""


def test_a_case_file_shears_its_periodic_box(tmp_path):
    """``periodic`` with ``shear_rate`` and ``gradient`` in a case file: ``rollingdem run`` shears the
    box (the shift after 0.02 s is 50 /s x 0.03 m x 0.02 s = 0.03 m, one box length: back to 0 within
    a step's move), and the run's final checkpoint restores the shear."""
    from typer.testing import CliRunner

    from rollingdem.cli import app

    (tmp_path / "case.yaml").write_text(SHEAR_CASE)
    result = CliRunner().invoke(app, ["run", str(tmp_path / "case.yaml"), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 0, result.output
    sim = rd.Simulation.restore(tmp_path / "o" / "final.npz")
    assert sim.shear.shear_rate == pytest.approx(50.0, rel=1e-12)
    assert sim.shear.lees_edwards == rd.LeesEdwards(shear_rate=50.0, gradient="z")
    step_move = 50.0 * 0.03 * sim.dt
    assert min(sim.shear.shift, 0.03 - sim.shear.shift) < step_move + 1e-12


def test_fields_in_a_sheared_box_are_refused(table1):
    """The fields' kernels would wrap across the gradient's ends without the images' shift and
    velocity jump: refused, naming the measurement."""
    sim = rd.Simulation(periodic={"x": (0, 0.1), "z": (0, 0.1)}, lees_edwards=rd.LeesEdwards(shear_rate=1.0))
    sim.add_material(table1())
    sim.add_particles([[0.05, 0.0, 0.05]], R, "m")
    with pytest.raises(ParameterError, match="fields 'f' is not allowed in a sheared"):
        sim.run(steps=1, observers=[rd.ContinuumFields("f", width=0.01)])


def _one_near_the_upper_end(table1, z):
    """One sphere at (0.05, 0, z) in a box sheared at U = 1 m/s (gradient z, 0.1 m), after 0.01 s:
    (the simulation, the shift)."""
    sim = rd.Simulation(gravity=(0, 0, 0), periodic={"x": (0.0, 0.1), "z": (0.0, 0.1)},
                        lees_edwards=rd.LeesEdwards(shear_velocity=1.0))
    sim.add_material(table1())
    sim.add_particles([[0.05, 0.0, z]], R, "m")
    sim.run(steps=int(round(0.01 / sim.dt)))
    return sim, sim.shear.shift


def test_a_new_sphere_is_checked_against_the_shifted_images(table1):
    """After 0.01 s at U = 1 m/s the image of a sphere near the upper end lies 0.01 m along x from
    where an unsheared box would put it: a sphere added under that image overlaps it and is
    refused; one under the unshifted place (clear of the image by 2.8 mm) is accepted."""
    sim, shift = _one_near_the_upper_end(table1, 0.095)
    assert shift == pytest.approx(0.01, rel=0.01)
    with pytest.raises(ParameterError, match="overlap"):
        sim.add_particles([[0.05 - shift, 0.0, 0.003]], R, "m")
    sim.add_particles([[0.05, 0.0, 0.003]], R, "m")


@pytest.mark.parametrize("gradient", ["y", "z"])
def test_set_length_moves_the_gradient_only_along_the_gradient(gradient):
    """Changing the length across the flow and the gradient leaves the shear alone; changing the
    gradient's length moves the image's length with it and keeps the rate (U scales); x's scales the
    shift with it. Positions move affinely about the low end."""
    from rollingdem.engine.layout import PERIODIC_BOX as PB

    other = "y" if gradient == "z" else "z"
    sim = rd.Simulation(periodic={a: (0.0, 0.1) for a in "xyz"},
                        lees_edwards=rd.LeesEdwards(shear_rate=2.0, gradient=gradient))
    box = sim._state.contact_list.box
    sim.shear.set_length(other, 0.08)
    assert box[PB.lg] == 0.1 and sim.shear.shear_velocity == pytest.approx(0.2, rel=1e-15)
    sim.shear.set_length(gradient, 0.125)
    assert box[PB.lg] == 0.125 and box[PB.inv_lg] == 1 / 0.125
    assert sim.shear.shear_rate == pytest.approx(2.0, rel=1e-15)
    box[PB.shift] = 0.04
    sim.shear.set_length("x", 0.05)
    assert sim.shear.shift == pytest.approx(0.02, rel=1e-15)
    assert sim.periodic == {"x": (0.0, 0.05), gradient: (0.0, 0.125), other: (0.0, 0.08)}


def test_the_probes_coordination_counts_pairs_across_the_shifted_end(table1):
    """Two spheres touching across the sheared end through the shifted image (the only pair): each
    touches one, as the engine's contact says; unshifted images would find none."""
    from rollingdem.io.measurements import coordination

    sim, shift = _one_near_the_upper_end(table1, 0.0955)
    sim.add_particles([[0.05 - shift, 0.0, 0.0035]], R, "m", allow_overlap=True)  # 8 mm from its image below
    sim.run(steps=1)
    assert len(sim.contact_forces()["i"]) == 1
    assert coordination(sim, np.ones(2, dtype=bool)) == 1.0


def test_timing_the_passes_leaves_the_sheared_box_as_it_was(table1):
    """``Simulation.passes`` times a rebuild, which puts centres back into the box (images, shift,
    velocity jump) and zeroes the shift moved since the list was built: ``restore`` puts the box and
    the images back with the rest, so that the next run knows when to build the list again."""
    from rollingdem.engine.layout import PERIODIC_BOX as PB

    sim, _ = _sheared_gas(table1, 200.0, 7)
    box, image = sim._state.contact_list.box.copy(), sim._state.image.copy()
    assert box[PB.shift_since_build] > 0.0
    passes = sim.passes()
    passes.rebuild()
    assert sim._state.contact_list.box[PB.shift_since_build] == 0.0
    passes.restore()
    np.testing.assert_array_equal(sim._state.contact_list.box, box)
    np.testing.assert_array_equal(sim._state.image, image)
