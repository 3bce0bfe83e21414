"""Coarse-grained continuum fields (rollingdem.analysis.fields): each check holds to round-off,
because the grid's weights of every point sum to one exactly."""

import math

import numpy as np
import pytest
from scipy.integrate import quad

from helpers import settled_glass_bed
from rollingdem.analysis.fields import PROFILE_COLUMNS, Gaussian, Grid, Lucy, coarse_grain, profile
from rollingdem.errors import ParameterError


@pytest.mark.parametrize("kernel", [Gaussian(0.002), Lucy(0.002)])
def test_each_kernel_integrates_to_one_over_space(kernel):
    """4 pi int_0^c r^2 phi(r) dr = 1 (the Gaussian's normalisation is over the ball it is cut to;
    uncut, it would integrate to 1.0111 there). Quadrature to 1e-12."""
    total = quad(lambda r: 4.0 * math.pi * r * r * float(kernel(r)), 0.0, kernel.cutoff, epsabs=0.0, epsrel=1e-13)[0]
    assert total == pytest.approx(1.0, rel=1e-10)
    assert float(kernel(kernel.cutoff * 1.0001)) == 0.0


def random_scene(seed, n=40, m=25):
    """``n`` particles in a 1 cm cube, random masses and velocities, and ``m`` contacts between
    random pairs (branch x_i - x_j) and 5 wall contacts (branch from a point below to x_i)."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 0.01, (n, 3))
    mass = rng.uniform(1e-6, 3e-6, n)
    v = rng.normal(0.0, 0.1, (n, 3))
    i, j = rng.integers(0, n, (2, m))
    keep = i != j
    i, j = i[keep], j[keep]
    force = rng.normal(0.0, 1e-3, (len(i), 3))
    walls = rng.integers(0, n, 5)
    contacts = (np.concatenate([x[i], x[walls]]),
                np.concatenate([x[i] - x[j], np.column_stack([np.zeros(5), np.zeros(5), rng.uniform(1e-3, 2e-3, 5)])]),
                np.concatenate([force, rng.normal(0.0, 1e-3, (5, 3))]), rng.normal(0.0, 1e-6, (len(i) + 5, 3)))
    return x, mass, v, contacts


@pytest.mark.parametrize("kernel", [Gaussian(0.0015), Lucy(0.002)])
@pytest.mark.parametrize("periodic", [False, True])
def test_the_fields_sum_to_the_mass_momentum_and_virial(kernel, periodic):
    """Sum over the grid times a cell's volume: the density gives the particles' mass, the
    momentum theirs, the contact stress the virial sum of f (x) b over the contacts (pairs and
    walls), the couple stress that of M (x) b, all to 1e-12 of their scale, whether the kernels reach past a side (non-periodic: the
    weight stays inside) or wrap (periodic)."""
    x, mass, v, contacts = random_scene(3)
    grid = Grid((0.0, 0.0, 0.0), (0.01, 0.01, 0.01), (10, 12, 9), periodic=(periodic,) * 3)
    fields = coarse_grain(grid, kernel, x, mass, v, contacts)
    dv = grid.cell_volume
    assert fields.density.sum() * dv == pytest.approx(mass.sum(), rel=1e-12)
    np.testing.assert_allclose(fields.momentum.sum(axis=(0, 1, 2)) * dv, (mass[:, None] * v).sum(0),
                               rtol=0, atol=1e-12 * np.abs(mass[:, None] * v).sum())
    xi, branch, force, moment = contacts
    for field, load in ((fields.contact_stress, force), (fields.couple_stress, moment)):
        np.testing.assert_allclose(field.sum(axis=(0, 1, 2)) * dv, np.einsum("ca,cb->ab", load, branch), rtol=0,
                                   atol=1e-12 * np.abs(load[:, :, None] * branch[:, None, :]).sum())


def test_a_lattice_has_its_mean_density_everywhere_and_a_moving_one_no_kinetic_stress():
    """A simple cubic lattice (spacing a, mass m per site) in a periodic box, nodes at a/2: every
    node is like every other, so the density is m / a^3 at each (1e-12); moving as a whole at
    one velocity, the velocity field is that velocity and the kinetic stress zero (v' = 0)."""
    a, m = 0.002, 4e-6
    g = (np.arange(5) + 0.0) * a
    x = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    grid = Grid((0.0, 0.0, 0.0), (5 * a, 5 * a, 5 * a), (10, 10, 10), periodic=(True, True, True))
    u = np.array([0.3, -0.1, 0.2])
    fields = coarse_grain(grid, Gaussian(a), x, m, np.tile(u, (len(x), 1)))
    np.testing.assert_allclose(fields.density, m / a ** 3, rtol=1e-12)
    np.testing.assert_allclose(fields.velocity, np.broadcast_to(u, fields.velocity.shape), rtol=1e-12)
    assert np.abs(fields.kinetic_stress).max() < 1e-12 * m / a ** 3 * (u ** 2).sum()


def test_opposite_velocities_give_the_kinetic_stress_rho_u_squared():
    """Each lattice site holds two particles moving at +u and -u along x: the mean velocity is 0,
    and the kinetic stress is rho u^2 in xx (1e-12), 0 elsewhere (a gas's momentum flux)."""
    a, m, u = 0.002, 4e-6, 0.25
    g = np.arange(4) * a
    sites = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    x = np.concatenate([sites, sites])
    v = np.zeros((len(x), 3))
    v[: len(sites), 0], v[len(sites):, 0] = u, -u
    grid = Grid((0.0, 0.0, 0.0), (4 * a, 4 * a, 4 * a), (8, 8, 8), periodic=(True, True, True))
    fields = coarse_grain(grid, Lucy(a), x, m, v)
    rho = 2 * m / a ** 3
    np.testing.assert_allclose(fields.kinetic_stress[..., 0, 0], rho * u * u, rtol=1e-12)
    off = fields.kinetic_stress.copy()
    off[..., 0, 0] = 0.0
    assert np.abs(off).max() < 1e-12 * rho * u * u


def test_a_compressed_pair_carries_compressive_stress_along_its_branch():
    """Two spheres pushed apart by f along x (the force on i from j points from j to i): sigma_xx
    is positive (compressive positive), and only along the branch between them (the nodes beside
    the pair, beyond the kernel's reach of the branch, carry none)."""
    xi, xj = np.array([0.006, 0.005, 0.005]), np.array([0.004, 0.005, 0.005])
    grid = Grid((0.0, 0.0, 0.0), (0.01, 0.01, 0.01), (20, 20, 20))
    kernel = Lucy(0.001)
    f = np.array([[2.0, 0.0, 0.0]])
    fields = coarse_grain(grid, kernel, [xi, xj], 1e-6, np.zeros((2, 3)), ([xi], [xi - xj], f))
    sxx = fields.contact_stress[..., 0, 0]
    assert sxx.min() >= 0.0 and sxx.max() > 0.0
    # the line integral runs over the whole branch: mirror-symmetric about its middle (x = 5 mm)
    np.testing.assert_allclose(sxx, sxx[::-1, :, :], rtol=0, atol=1e-12 * sxx.max())
    centre = np.unravel_index(np.argmax(sxx), sxx.shape)
    assert abs(grid.axes()[0][centre[0]] - 0.005) <= grid.spacing[0]  # strongest between the centres
    assert sxx[:, :, :4].max() == 0.0  # z below 2 mm: farther than the 2 mm cutoff from the branch


@pytest.mark.parametrize("kernel", [Gaussian(0.001), Lucy(0.0015)])
def test_one_particle_spreads_as_its_kernel(kernel):
    """One particle off the nodes, on a grid a sixth of the cutoff apart: at every node within the
    cutoff the density is m phi(distance) times one factor, the same at every node (1e-12: the
    grid's weights are the kernel's, scaled to sum to one), and that factor is 1 within 2 % (the
    grid's sum standing in for the kernel's integral)."""
    m, x = 2e-6, np.array([0.00512, 0.00497, 0.00503])
    grid = Grid((0.0, 0.0, 0.0), (0.01, 0.01, 0.01), (36, 36, 36))
    fields = coarse_grain(grid, kernel, [x], m, [[0.0, 0.0, 0.0]])
    nodes = np.stack(np.meshgrid(*grid.axes(), indexing="ij"), -1)
    distance = np.linalg.norm(nodes - x, axis=-1)
    within = distance < kernel.cutoff * 0.999
    factor = fields.density[within] / (m * kernel(distance[within]))
    np.testing.assert_allclose(factor, factor[0], rtol=1e-12)
    assert factor[0] == pytest.approx(1.0, rel=0.02)
    assert fields.density[~within].max(initial=0.0) <= m * float(kernel(kernel.cutoff * 0.999)) * factor[0]


def test_bad_grids_kernels_and_arrays_are_one_line_each():
    with pytest.raises(ParameterError, match=r"grid shape = \(0, 2, 2\) is not allowed"):
        Grid((0, 0, 0), (1, 1, 1), (0, 2, 2))
    with pytest.raises(ParameterError, match="grid lower .* upper above lower"):
        Grid((0, 0, 0), (1, 0, 1), (2, 2, 2))
    with pytest.raises(ParameterError, match="kernel width"):
        Gaussian(-1.0)
    grid = Grid((0, 0, 0), (0.01, 0.01, 0.01), (5, 5, 5))
    with pytest.raises(ParameterError, match=r"cutoff \(0.0017 m\) must exceed half a cell's diagonal, 0.00173205 m"):
        coarse_grain(grid, Lucy(0.00085), [[0.005] * 3], 1.0, [[0.0] * 3])
    with pytest.raises(ParameterError, match="velocities with 2 rows is not allowed for 1 positions"):
        coarse_grain(grid, Lucy(0.002), [[0.005] * 3], 1.0, np.zeros((2, 3)))
    fields = coarse_grain(grid, Lucy(0.002), [[0.005] * 3], 1.0, [[0.0] * 3])
    with pytest.raises(ParameterError, match="profile axis = 'r' is not allowed: must be 'x', 'y' or 'z'"):
        profile(fields, "r")
    with pytest.raises(ParameterError, match="reaches no node of the grid"):
        coarse_grain(grid, Lucy(0.002), [[0.5, 0.5, 0.5]], 1.0, [[0.0] * 3])


@pytest.fixture(scope="module")
def settled_bed():
    """500 glass spheres (radius 0.9-1.1 mm, EPSD rolling resistance mu_r 0.2) settled on a floor in
    a box periodic along x and y, 16 mm wide; the engine's slots re-sorted every 1,000 steps (as a scene of 50,000 spheres is), so that
    the contacts' indices must be mapped back to the order the spheres were added."""
    from rollingdem.engine import state as engine_state

    saved = engine_state.SORT_ABOVE
    engine_state.SORT_ABOVE = 10
    try:
        sim = settled_glass_bed(0.016, 0.03, 500, seed=1)
    finally:
        engine_state.SORT_ABOVE = saved
    return sim


def test_the_contact_forces_and_the_weight_sum_to_each_spheres_force(settled_bed):
    """``Simulation.contact_forces``: over every contact a sphere takes part in (+force where it is
    i, -force where it is j, walls included) plus its weight, the force the engine summed for it
    (``forces``), to 1e-9 of the largest; the branches are the minimum images (shorter than a
    diameter and a half) or, at the floor, R - overlap along +z."""
    sim = settled_bed
    c = sim.contact_forces()
    n = sim.n_particles
    total = np.zeros((n, 3))
    np.add.at(total, c["i"], c["force"])
    pairs = c["j"] >= 0
    np.add.at(total, c["j"][pairs], -c["force"][pairs])
    total += sim.masses[:, None] * np.array(sim.gravity)
    scale = np.abs(sim.forces).max()
    np.testing.assert_allclose(total, sim.forces, rtol=0, atol=1e-9 * scale)
    assert np.linalg.norm(c["branch"][pairs], axis=1).max() < 1.5 * 2 * sim.radii.max()
    floor = c["branch"][~pairs]
    assert len(floor) > 20 and (floor[:, 2] > 0).all() and np.abs(floor[:, :2]).max() == 0.0
    np.testing.assert_allclose(sim.positions[c["i"][~pairs], 2], floor[:, 2], rtol=1e-12)  # the plane is z = 0


def test_the_contact_moments_and_levers_sum_to_each_spheres_torque(settled_bed):
    """The listed pure moments: with n = b/|b|, levers R - overlap/2 (a wall's R - overlap/2 on the
    sphere's side, 0 on its own) and c = n x F, -lever_i c + M on i and -lever_j c - M on j, summed
    over each sphere's contacts, give the torque the engine summed for it (1e-9 of the largest);
    rolling resistance makes the moments a share of it (EPSD, mu_r 0.2)."""
    sim = settled_bed
    c = sim.contact_forces()
    r = sim.radii
    pairs = c["j"] >= 0
    length = np.linalg.norm(c["branch"], axis=1)
    n = c["branch"] / length[:, None]
    overlap = np.where(pairs, r[c["i"]] + r[np.maximum(c["j"], 0)] - length, r[c["i"]] - length)
    lever_i = r[c["i"]] - 0.5 * overlap
    lever_j = r[np.maximum(c["j"], 0)] - 0.5 * overlap
    cross = np.cross(n, c["force"])
    torque = np.zeros((sim.n_particles, 3))
    np.add.at(torque, c["i"], -lever_i[:, None] * cross + c["moment"])
    np.add.at(torque, c["j"][pairs], -lever_j[pairs, None] * cross[pairs] - c["moment"][pairs])
    scale = np.abs(sim.torques).max()
    np.testing.assert_allclose(torque, sim.torques, rtol=0, atol=1e-9 * scale)
    assert np.abs(c["moment"]).max() > 1e-3 * scale


def test_a_settled_beds_vertical_stress_is_the_weight_above(settled_bed):
    """Momentum balance at rest: the coarse-grained sigma_zz(z) (Lucy, w = 1 mm, averaged over x
    and y) equals g times the coarse-grained mass per area above z, within 2 % from a kernel's
    cutoff above the floor to 2 mm below the top (0.70 % measured); the kinetic part, of spheres
    settled to below 2e-13 J each, is under 1e-4 of it (7e-6 measured)."""
    sim = settled_bed
    kernel = Lucy(0.001)
    dz = 0.00025
    top = float((sim.positions[:, 2] + sim.radii).max())
    nz = int(np.ceil((top + 3 * kernel.cutoff) / dz))
    grid = Grid((0.0, 0.0, -kernel.cutoff), (0.016, 0.016, -kernel.cutoff + nz * dz), (8, 8, nz),
                periodic=(True, True, False))
    fields = coarse_grain(grid, kernel, sim.positions, sim.masses, sim.velocities, sim.contact_forces())
    along = profile(fields, "z")
    z, szz, rho = along["z (m)"], along["stress_zz (Pa)"], along["density (kg/m^3)"]
    np.testing.assert_allclose(szz, fields.stress[..., 2, 2].mean(axis=(0, 1)), rtol=1e-14)
    weight_above = 9.81 * (np.cumsum(rho[::-1])[::-1] - 0.5 * rho) * dz
    inside = (z > kernel.cutoff) & (z < top - 0.002)
    assert inside.sum() > 40
    np.testing.assert_allclose(szz[inside], weight_above[inside], rtol=0.02)
    assert np.abs(fields.kinetic_stress).max() < 1e-4 * szz.max()


def test_a_profile_averages_the_other_two_axes_with_its_units():
    """``profile`` along y of the random scene's fields: each column is the field averaged over x
    and z (the velocity the mean momentum over the mean density), named with its unit; the
    couple stress's yx component is its own column (the tensor is not symmetric)."""
    x, mass, v, contacts = random_scene(5)
    grid = Grid((0.0, 0.0, 0.0), (0.01, 0.01, 0.01), (6, 7, 5), periodic=(True, True, True))
    fields = coarse_grain(grid, Lucy(0.003), x, mass, v, contacts)
    along = profile(fields, "y")
    assert list(along) == ["y (m)"] + [f"{name} ({unit})" for name, unit in PROFILE_COLUMNS]
    np.testing.assert_allclose(along["y (m)"], grid.axes()[1], rtol=1e-15)
    np.testing.assert_allclose(along["density (kg/m^3)"], fields.density.mean(axis=(0, 2)), rtol=1e-14)
    np.testing.assert_allclose(along["velocity_z (m/s)"], fields.momentum[..., 2].mean(axis=(0, 2))
                               / fields.density.mean(axis=(0, 2)), rtol=1e-12)
    np.testing.assert_allclose(along["stress_xy (Pa)"], fields.stress[..., 0, 1].mean(axis=(0, 2)), rtol=1e-14)
    np.testing.assert_allclose(along["couple_stress_yx (N/m)"], fields.couple_stress[..., 1, 0].mean(axis=(0, 2)),
                               rtol=1e-14)
    assert not np.allclose(along["couple_stress_yx (N/m)"], along["couple_stress_xy (N/m)"])


def test_a_periodic_grid_wraps_what_crosses_its_side():
    """On a grid periodic along x, a particle and a contact whose branch crosses the side x = 0
    give the fields of the same shifted 5 mm into the box, moved back by 5 mm (rolled by 10 nodes
    of 0.5 mm): nothing of them is lost or bent at the side (1e-12)."""
    grid = Grid((0.0, 0.0, 0.0), (0.01, 0.01, 0.01), (20, 20, 20), periodic=(True, False, False))
    kernel = Lucy(0.0012)
    xi, b = np.array([0.0005, 0.005, 0.005]), np.array([0.002, 0.0004, -0.0003])
    shift = np.array([0.005, 0.0, 0.0])
    near, far = (coarse_grain(grid, kernel, [xi + d], 2e-6, [[0.1, 0.0, 0.0]], ([xi + d], [b], [[1.0, 0.5, 0.0]],
                                                                                [[0.0, 0.0, 1e-4]]))
                 for d in (np.zeros(3), shift))
    for field in ("density", "momentum", "contact_stress", "couple_stress"):
        a, c = getattr(near, field), np.roll(getattr(far, field), -10, axis=0)
        np.testing.assert_allclose(a, c, rtol=0, atol=1e-12 * np.abs(a).max())
