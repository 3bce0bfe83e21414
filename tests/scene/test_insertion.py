"""Random insertion of spheres (rollingdem.scene.insertion): no overlaps, inside the region, clear walls,
reproducible, size distributions, and clear errors. No simulation is run here."""

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

import rollingdem as rd
from rollingdem.scene import insertion
from rollingdem.errors import ParameterError
from rollingdem.scene.insertion import fill_region
from rollingdem.scene.regions import BoxRegion, CylinderRegion
from rollingdem.scene.size_distributions import Discrete, Normal, Uniform

# Gaps are computed in float64 from coordinates of order 0.1 m: rounding is ~1e-17 m, so a gap
# below -1e-12 m is a real overlap, not rounding.
GAP_TOL = 1e-12


def min_gap(x, r, x_other=None, r_other=None):
    """Smallest surface gap (m) over all pairs of spheres in (x, r), or between (x, r) and the others."""
    if x_other is None:
        tree = cKDTree(x)
        # Any overlapping pair has centre distance < 2 max(r); the margin lets the test see the
        # closest pairs too (a gap of +inf would hide that nothing was compared at all).
        pairs = tree.query_pairs(2.0 * r.max() + 0.01, output_type="ndarray")
        assert len(pairs), "no pairs compared"
        i, j = pairs[:, 0], pairs[:, 1]
        return float((np.linalg.norm(x[i] - x[j], axis=1) - r[i] - r[j]).min())
    d = np.linalg.norm(x[:, None, :] - x_other[None, :, :], axis=2)
    return float((d - r[:, None] - r_other[None, :]).min())


def packing_fraction(r, region):
    return 4.0 / 3.0 * math.pi * float(np.sum(r ** 3)) / region.volume()


# --- geometry -----------------------------------------------------------------------------------
def test_box_fill_no_overlap_and_inside():
    box = BoxRegion((0.0, -0.02, 0.1), (0.04, 0.02, 0.16))
    x, r = fill_region(box, 400, Uniform(0.002, 0.003), seed=1)
    assert x.shape == (400, 3) and r.shape == (400,)
    assert min_gap(x, r) >= -GAP_TOL
    assert (x - r[:, None] >= box.lo - GAP_TOL).all() and (x + r[:, None] <= box.hi + GAP_TOL).all()


def test_cylinder_fill_no_overlap_and_inside():
    cyl = CylinderRegion(0.03, -0.05, 0.05, center=(0.1, -0.2))
    x, r = fill_region(cyl, 500, 0.002, seed=2)
    assert min_gap(x, r) >= -GAP_TOL
    rho = np.hypot(x[:, 0] - 0.1, x[:, 1] + 0.2)
    assert (rho + r <= 0.03 + GAP_TOL).all()
    assert (x[:, 2] - r >= -0.05 - GAP_TOL).all() and (x[:, 2] + r <= 0.05 + GAP_TOL).all()


def test_dense_fill_near_the_random_insertion_limit(monkeypatch):
    # 0.33 packing fraction of equal spheres in a box: beyond what plain random candidates reach
    # with 200 attempts, so this goes through the free-cell sampling (and its cell splitting,
    # checked by a spy); it must stay exact.
    splits = []
    real_split = insertion._FreeCells.split
    monkeypatch.setattr(insertion._FreeCells, "split", lambda self, x, r: splits.append(1) or real_split(self, x, r))
    box = BoxRegion((0.0, 0.0, 0.0), (0.05, 0.05, 0.05))
    n = int(0.33 * box.volume() / (4.0 / 3.0 * math.pi * 0.002 ** 3))
    x, r = fill_region(box, n, 0.002, seed=5)
    assert splits
    assert packing_fraction(r, box) == pytest.approx(0.33, abs=0.002)
    assert min_gap(x, r) >= -GAP_TOL
    assert box.contains(x, r).all()
    # Still spread over the whole box: each half holds about half of the spheres. A binomial
    # count has standard deviation sqrt(n)/2 (~12 here); a dense packing spreads more evenly
    # than that, so 5 such deviations only fail if one side is really favoured.
    for d in range(3):
        left = int((x[:, d] < 0.025).sum())
        assert abs(left - n / 2) < 5 * math.sqrt(n) / 2


def test_dense_bimodal_fill():
    # Two sizes at 0.3 packing fraction: the large ones go first, the small ones fill the gaps.
    cyl = CylinderRegion(0.04, 0.0, 0.06)
    dist = Discrete([0.0015, 0.003], weights=[4, 1])
    v = 4.0 / 3.0 * math.pi * (0.8 * 0.0015 ** 3 + 0.2 * 0.003 ** 3)
    n = int(0.3 * cyl.volume() / v)
    x, r = fill_region(cyl, n, dist, seed=7)
    # The mix drawn is random: the count of large spheres (~2/3 of the volume) is binomial with a
    # relative spread of ~4%, so the packing fraction spreads by ~0.008 about 0.3; 0.03 allowed.
    assert packing_fraction(r, cyl) == pytest.approx(0.3, abs=0.03)
    assert set(np.unique(r)) == {0.0015, 0.003}
    assert min_gap(x, r) >= -GAP_TOL
    assert cyl.contains(x, r).all()


def test_free_cells_never_drop_free_space():
    # The free-cell sampler may only drop cells where no centre of radius >= rho0 can go; if it
    # dropped free space the fill would stop being uniform (or fail early). Check the invariant on
    # random points, on the dense grid, after splits and after covering in the split state.
    box = BoxRegion((0.0, 0.0, 0.0), (0.03, 0.03, 0.03))
    rho0 = 0.002
    x, r = fill_region(box, 120, rho0, seed=1)  # packing fraction 0.15: free space is left
    cells = insertion._FreeCells(box, rho0, [])
    rng = np.random.default_rng(0)

    def check(n_covered):
        p = rng.uniform(box.lo + rho0, box.hi - rho0, (20000, 3))
        d = np.linalg.norm(p[:, None, :] - x[None, :n_covered, :], axis=2) - r[None, :n_covered] - rho0
        free = p[d.min(axis=1) >= 0.0]
        assert len(free) > 100
        ijk = np.floor((free - cells.origin) / cells.h).astype(np.int64)
        left = {tuple(c) for c in cells._ijk(cells._left())}
        assert all(tuple(c) in left for c in ijk)
        return len(left)

    cells.cover(x[:80], r[:80])
    n0 = check(80)
    assert n0 < 0.6 * np.prod(cells.shape)  # it does drop much of the space
    assert cells.split(x[:80], r[:80])
    check(80)
    cells.cover(x[80:], r[80:])
    check(120)
    assert cells.split(x, r)
    check(120)


def test_cylinder_positions_uniform_over_the_cross_section():
    # Sparse fill (~2% packing): centres uniform over the disc of radius R - r, so half of them lie
    # within (R - r)/sqrt(2). Binomial standard error sqrt(0.25/n) = 0.011; 5 of them allowed.
    cyl = CylinderRegion(0.1, 0.0, 0.1)
    n = 2000
    x, r = fill_region(cyl, n, 0.002, seed=4)
    inner = np.hypot(x[:, 0], x[:, 1]) < (0.1 - 0.002) / math.sqrt(2.0)
    assert abs(inner.mean() - 0.5) < 5 * math.sqrt(0.25 / n)


def test_plane_and_cylinder_walls_are_not_overlapped():
    box = BoxRegion((-0.05, -0.05, 0.0), (0.05, 0.05, 0.1))
    normal = np.array([1.0, 0.0, 1.0]) / math.sqrt(2.0)  # tilted plane through the box
    plane = rd.Plane(point=(0.0, 0.0, 0.03), normal=tuple(normal), material="m")
    # A cylinder wall (particles inside) only over the lower part of the box.
    wall_cyl = rd.Cylinder(0.03, point=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0), extent=(0.0, 0.05), material="m")
    x, r = fill_region(box, 300, Uniform(0.002, 0.003), seed=6, walls=[plane, wall_cyl])
    assert min_gap(x, r) >= -GAP_TOL
    assert box.contains(x, r).all()
    assert ((x - np.array(plane.point)) @ normal - r >= -GAP_TOL).all()
    s = x[:, 2]
    rho = np.hypot(x[:, 0], x[:, 1])
    within = (s >= 0.0) & (s <= 0.05)
    assert within.any()
    assert (rho[within] + r[within] <= 0.03 + GAP_TOL).all()
    # Above its extent the cylinder does not constrain: spheres do lie outside its radius there.
    assert (rho[~within] + r[~within] > 0.03).any()


def test_dense_fill_with_a_plane_through_the_region():
    # The free-cell sampling drops cells behind a plane; the result must still clear it.
    box = BoxRegion((0.0, 0.0, 0.0), (0.04, 0.04, 0.08))
    plane = rd.Plane(point=(0.0, 0.0, 0.04), normal=(0.0, 0.0, 1.0), material="m")
    n = int(0.3 * 0.5 * box.volume() / (4.0 / 3.0 * math.pi * 0.002 ** 3))  # 0.3 of the upper half
    x, r = fill_region(box, n, 0.002, seed=8, walls=[plane])
    assert min_gap(x, r) >= -GAP_TOL
    assert (x[:, 2] - r >= 0.04 - GAP_TOL).all()


def test_existing_particles_are_respected():
    box = BoxRegion((0.0, 0.0, 0.0), (0.06, 0.06, 0.06))
    ex = np.array([[0.03, 0.03, 0.03], [0.0, 0.0, 0.0], [0.06, 0.06, 0.10]])
    er = np.array([0.015, 0.01, 0.005])
    x, r = fill_region(box, 600, 0.002, seed=9, existing_positions=ex, existing_radii=er)
    assert min_gap(x, r) >= -GAP_TOL
    assert min_gap(x, r, ex, er) >= -GAP_TOL
    # The big one in the middle is a real obstacle: some spheres sit close to it.
    d = np.linalg.norm(x - ex[0], axis=1) - r - er[0]
    assert d.min() < 0.002


def test_reproducible_from_seed():
    cyl = CylinderRegion(0.04, 0.0, 0.1)
    a = fill_region(cyl, 300, Normal(0.003, 0.0005), seed=11)
    b = fill_region(cyl, 300, Normal(0.003, 0.0005), seed=11)
    c = fill_region(cyl, 300, Normal(0.003, 0.0005), seed=12)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    assert not np.array_equal(a[0], c[0])
    assert not np.array_equal(a[1], c[1])


# --- size distributions -------------------------------------------------------------------------
def test_uniform_mean_and_bounds():
    rng = np.random.default_rng(0)
    s = Uniform(0.001, 0.002).sample(rng, 5000)
    assert s.min() >= 0.001 and s.max() <= 0.002
    # Standard error of the mean of U(a, b): (b - a) / sqrt(12 n); 3 of them (fails ~0.3% by chance
    # for a correct sampler, but the seed is fixed).
    se = 0.001 / math.sqrt(12 * 5000)
    assert abs(s.mean() - 0.0015) < 3 * se
    # Spread over the interval, not piled up: the standard deviation of U is (b - a)/sqrt(12);
    # 5% allowed (its sampling error at n = 5000 is about 1%).
    assert s.std() == pytest.approx(0.001 / math.sqrt(12), rel=0.05)
    assert Uniform(0.001, 0.002).max_radius == 0.002


def test_normal_truncated_to_its_bounds():
    rng = np.random.default_rng(1)
    dist = Normal(0.003, 0.001, low=0.0025, high=0.004)
    s = dist.sample(rng, 4000)
    assert s.min() >= 0.0025 and s.max() <= 0.004
    assert dist.max_radius == 0.004
    # Default truncation at mean +- 3 std keeps radii positive and bounded.
    s = Normal(0.003, 0.002).sample(rng, 4000)
    assert (s > 0).all() and s.max() <= 0.003 + 3 * 0.002


def test_discrete_weights_respected():
    rng = np.random.default_rng(2)
    n = 10000
    s = Discrete([0.001, 0.002, 0.003], weights=[1, 3, 0]).sample(rng, n)
    assert set(np.unique(s)) == {0.001, 0.002}  # zero weight never drawn
    # Share of 2 mm spheres is binomial with p = 0.75: standard error sqrt(p(1-p)/n) ~ 0.0043;
    # 4 of them allowed.
    p = (s == 0.002).mean()
    assert abs(p - 0.75) < 4 * math.sqrt(0.75 * 0.25 / n)
    assert Discrete([0.001, 0.002, 0.003], weights=[1, 3, 0]).max_radius == 0.002


def test_fill_with_distribution_keeps_radii_in_bounds():
    x, r = fill_region(BoxRegion((0, 0, 0), (0.05, 0.05, 0.05)), 300, Uniform(0.002, 0.0025), seed=3)
    assert r.min() >= 0.002 and r.max() <= 0.0025
    assert len(np.unique(r)) == 300  # really drawn, not one radius


# --- errors -------------------------------------------------------------------------------------
def test_refuses_packing_fraction_above_limit_up_front():
    box = BoxRegion((0, 0, 0), (0.02, 0.02, 0.02))
    n = int(0.6 * box.volume() / (4.0 / 3.0 * math.pi * 0.002 ** 3))
    with pytest.raises(ParameterError, match="packing fraction") as err:
        fill_region(box, n, 0.002)
    assert "0.3-0.35" in str(err.value) and "larger region or fewer spheres" in str(err.value)


def test_region_too_small_for_count_reports_how_far_it_got():
    # 0.45 is allowed to be asked (below 0.55) but random insertion cannot reach it.
    box = BoxRegion((0, 0, 0), (0.02, 0.02, 0.02))
    n = int(0.45 * box.volume() / (4.0 / 3.0 * math.pi * 0.002 ** 3))
    with pytest.raises(ParameterError, match="packing fraction") as err:
        fill_region(box, n, 0.002, max_attempts=50)
    msg = str(err.value)
    assert f"of {n} spheres" in msg and "could place only" in msg and "BoxRegion" in msg
    assert "0.3-0.35" in msg


def test_walls_that_exclude_the_region():
    box = BoxRegion((0, 0, 0), (0.02, 0.02, 0.02))
    plane = rd.Plane(point=(0, 0, 1.0), normal=(0, 0, 1), material="m")  # all of the box is behind it
    with pytest.raises(ParameterError, match="could place only 0 of 5"):
        fill_region(box, 5, 0.001, walls=[plane], max_attempts=20)


@pytest.mark.parametrize("radius, match", [
    (-0.001, "radius = -0.001 is not allowed: must be > 0"),
    (0.0, "radius = 0 is not allowed"),
    (float("nan"), "radius"),
    ("big", "radius = 'big' is not allowed"),
])
def test_bad_radius(radius, match):
    with pytest.raises(ParameterError, match=match):
        fill_region(BoxRegion((0, 0, 0), (1, 1, 1)), 3, radius)


def test_bad_distributions():
    with pytest.raises(ParameterError, match="Uniform low = 0.002 is not allowed: must be <= high = 0.001"):
        Uniform(0.002, 0.001)
    with pytest.raises(ParameterError, match="Uniform low = -0.001 is not allowed"):
        Uniform(-0.001, 0.001)
    with pytest.raises(ParameterError, match="Normal std = -1 is not allowed: must be >= 0"):
        Normal(0.003, -1)
    with pytest.raises(ParameterError, match="Normal low"):
        Normal(0.003, 0.001, low=0.004, high=0.002)
    with pytest.raises(ParameterError, match=r"Discrete values\[1\] = -0.002 is not allowed"):
        Discrete([0.001, -0.002])
    with pytest.raises(ParameterError, match=r"Discrete weights\[0\] = -1 is not allowed"):
        Discrete([0.001, 0.002], weights=[-1, 2])
    with pytest.raises(ParameterError, match="positive sum"):
        Discrete([0.001, 0.002], weights=[0, 0])
    with pytest.raises(ParameterError, match="need one per value"):
        Discrete([0.001, 0.002], weights=[1])


@pytest.mark.parametrize("count", [0, -5, 2.5, True, "10", None])
def test_bad_count(count):
    with pytest.raises(ParameterError, match="count = .* is not allowed: must be a positive integer"):
        fill_region(BoxRegion((0, 0, 0), (1, 1, 1)), count, 0.01)


def test_numpy_integer_count_accepted():
    x, r = fill_region(BoxRegion((0, 0, 0), (1, 1, 1)), np.int64(3), 0.01)
    assert x.shape == (3, 3)


def test_sphere_larger_than_region():
    with pytest.raises(ParameterError, match="does not fit"):
        fill_region(BoxRegion((0, 0, 0), (0.1, 0.1, 0.01)), 1, 0.006)  # 12 mm sphere, 10 mm thick box
    with pytest.raises(ParameterError, match="does not fit"):
        fill_region(CylinderRegion(0.005, 0.0, 1.0), 1, Discrete([0.001, 0.0051]))


def test_bad_regions():
    with pytest.raises(ParameterError, match="need lo < hi"):
        BoxRegion((0, 0, 0), (1, 0, 1))
    with pytest.raises(ParameterError, match="BoxRegion lo"):
        BoxRegion((0, 0), (1, 1, 1))
    with pytest.raises(ParameterError, match="CylinderRegion radius = -1 is not allowed"):
        CylinderRegion(-1, 0, 1)
    with pytest.raises(ParameterError, match="need z_min < z_max"):
        CylinderRegion(1, 1, 0)
    with pytest.raises(ParameterError, match="CylinderRegion center"):
        CylinderRegion(1, 0, 1, center=(0, 0, 0))
    with pytest.raises(ParameterError, match="must be a BoxRegion, CylinderRegion or MeshRegion"):
        fill_region((0, 0, 0, 1, 1, 1), 3, 0.01)


# --- through the public API ---------------------------------------------------------------------
def test_simulation_insert():
    sim = rd.Simulation(dt=1e-5)
    sim.add_material(rd.Material("m", 40e6, 0.49, 1056))
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    idx = sim.insert(CylinderRegion(0.05, 0.0, 0.2), 500, Uniform(0.004, 0.005), "m", seed=3)
    assert sim.n_particles == 500
    np.testing.assert_array_equal(idx, np.arange(500))
    r = sim._state.radius
    assert r.min() >= 0.004 and r.max() <= 0.005
    x = sim._state.x
    assert min_gap(x, r) >= -GAP_TOL
    assert (x[:, 2] - r >= -GAP_TOL).all()
    # A second insertion into the same region respects the first one.
    sim.insert(CylinderRegion(0.05, 0.0, 0.2), 100, 0.003, "m", seed=4)
    assert sim.n_particles == 600
    assert min_gap(sim._state.x, sim._state.radius) >= -GAP_TOL


def test_inserted_spheres_are_numbered_in_space_filling_order(table1):
    """Neighbors in space get nearby indices (cache locality of the contact loop): the index gap of
    touching-distance pairs is far below the N/3 a random numbering gives on average."""
    sim = rd.Simulation()
    sim.add_material(table1())
    sim.insert(rd.BoxRegion((0, 0, 0), (0.2, 0.2, 0.2)), 2000, 0.005, "m", seed=4)
    pairs = cKDTree(sim.positions).query_pairs(0.025, output_type="ndarray")
    gap = np.abs(pairs[:, 0] - pairs[:, 1])
    assert np.median(gap) < 0.1 * sim.n_particles / 3


# --- large regions: slabs ------------------------------------------------------------------------
@pytest.mark.parametrize("region, spread", [(CylinderRegion(0.03, 0.0, 0.24), 0.0),
                                            (BoxRegion((0, 0, 0), (0.24, 0.05, 0.05)), 0.0),
                                            (CylinderRegion(0.03, 0.0, 0.24), 0.2)],
                         ids=["cylinder", "box", "cylinder, sizes +-20 %"])
def test_a_region_too_large_for_one_fine_grid_is_filled_in_slabs_uniformly(monkeypatch, region, spread):
    """A region whose free-cell grid would exceed MAX_DENSE cells is filled slab by slab (here
    MAX_DENSE is lowered so that ~40,000 spheres need 10 slabs; 10^6 spheres in the bench's column
    need 20). At a packing fraction of 0.27, where one coarse grid ran out of attempts at 10^6,
    every sphere is placed, inside the region, without overlaps. The seams must leave no layer
    denser or sparser: bins one diameter wide along the cut axis (away from the region's ends, ~350
    centres each) may scatter no more than Poisson counts, 1/sqrt(mean) relative. That bound is
    generous (a random sequential packing at 0.27 is more even than independent points: the bins
    scatter by 2.4-3.1 % against 5.2-5.6 % Poisson), and one pass over the slabs breaks it (6.6-7.5 %:
    a slab filled before its neighbour packs ~11 % denser below their seam and sparser above).
    Radii uniform in 1 mm +-20 % at 0.30, the repose experiments' fill (passes taking the spheres
    unsorted ran out of attempts at 0.27 with ~34,000 of 42,000 placed): all placed, and each bin's
    mean radius within 4.5 sigma_r / sqrt(count) of the fill's (of ~100 bins, one beyond 4.5 sigma
    by chance has p ~ 1e-3; slabs given the large end of their pass's sizes put a bin 5.5 % off,
    8.9 sigma)."""
    monkeypatch.setattr(insertion._FreeCells, "MAX_DENSE", 400_000)
    r0 = 0.001
    radius = Uniform(r0 * (1 - spread), r0 * (1 + spread)) if spread else r0
    fraction = 0.30 if spread else 0.27
    n = int(fraction * region.volume() / (4.0 / 3.0 * math.pi * r0 ** 3 * (1 + spread ** 2)))
    plan = insertion._slab_plan(region, r0 * (1 - spread), r0 * (1 + spread), n)
    assert len(plan) >= 4 * insertion.SLAB_PASSES
    x, r = fill_region(region, n, radius, seed=4)
    assert x.shape == (n, 3) and np.isfinite(x).all()
    assert region.contains(x, r + 1e-12).all()
    assert min_gap(x, r) > -GAP_TOL
    axis = 2 if isinstance(region, CylinderRegion) else 0
    lo, hi = region.bounds()
    edges = np.arange(lo[axis] + 4 * r0, hi[axis] - 4 * r0 + 1e-12, 2 * r0)
    counts, _ = np.histogram(x[:, axis], bins=edges)
    mean = counts.mean()
    assert mean > 300
    assert (counts / mean).std() < 1.0 / math.sqrt(mean)
    if spread:
        sums, _ = np.histogram(x[:, axis], bins=edges, weights=r)
        sigma = r0 * spread / math.sqrt(3.0)  # a uniform distribution's standard deviation
        assert np.abs(sums / counts - r.mean()).max() < 4.5 * sigma / math.sqrt(counts.min()), (sums / counts - r.mean()).max() / (sigma / math.sqrt(counts.min()))


# --- filling a closed mesh, and size distributions by mass (issue 45, item 3) ----------------------
def box_with_cavity():
    """A closed mesh of two shells: the unit cube, and a cube of side 0.4 at its middle with its
    triangles turned inward (a hollow block): inside is the outer cube less the inner one."""
    from rollingdem.scene.mesh import SHAPES, TriangleMesh

    outer = SHAPES["box"]((1.0, 1.0, 1.0))
    inner = SHAPES["box"]((0.4, 0.4, 0.4))
    v = np.vstack([outer.vertices, inner.vertices + 0.3])
    t = np.vstack([outer.triangles, inner.triangles[:, ::-1] + len(outer.vertices)])
    return TriangleMesh(v, t, label="hollow block")


def test_a_point_is_inside_a_closed_mesh_by_the_parity_of_a_ray():
    """The ray test against what the shapes are: a hollow block (two shells; a point in the cavity
    crosses two triangles above it, so is outside), with points whose vertical rays pass exactly
    through the triangles' shared diagonals and corners (the grid of sixteenths lies on them), and
    a 64-sided prism against its 64 half-planes. Every point is decided as the shape says; a point
    on the surface itself is left out (either answer is right)."""
    from rollingdem.scene.mesh import SHAPES, MeshRegion

    region = MeshRegion(box_with_cavity())
    g = np.arange(1, 16) / 16.0
    x = np.array([[a, b, c] for a in g for b in g for c in np.arange(-1, 17) / 16.0 + 1 / 32.0])
    expected = (np.all((x > 0) & (x < 1), axis=1) & ~np.all((x > 0.3) & (x < 0.7), axis=1))
    assert np.array_equal(region.inside(x), expected)
    assert expected.sum() > 500 and (~expected).sum() > 500
    prism = MeshRegion(SHAPES["drum"](radius=0.05, length=0.1, segments=64))
    rng = np.random.default_rng(4)
    y = np.column_stack([rng.uniform(-0.06, 0.06, 20000), rng.uniform(-0.06, 0.06, 20000), rng.uniform(-0.02, 0.12, 20000)])
    phi = 2 * np.pi * (np.arange(64) + 0.5) / 64  # the sides' outward normals
    apothem = 0.05 * np.cos(np.pi / 64)
    side = (y[:, :2] @ np.vstack([np.cos(phi), np.sin(phi)])).max(axis=1)
    expected = (side < apothem) & (y[:, 2] > 0) & (y[:, 2] < 0.1)
    assert np.array_equal(prism.inside(y), expected)


@pytest.mark.parametrize("amount", ["count", "mass", "fraction"])
def test_a_closed_mesh_is_filled_to_a_count_a_mass_or_a_fraction(amount):
    """A closed drum mesh (radius 50 mm, 40 mm long) filled with spheres of 2 to 3 mm: to 800 of
    them, to 0.15 kg, or to a solid fraction of 0.25 of its enclosed volume. The count is exact; the
    mass and the fraction come within half a sphere's of the target (the nearest count is taken);
    every sphere lies wholly inside the mesh, clear of its triangles and of every other sphere."""
    from rollingdem.scene.mesh import SHAPES

    sim = rd.Simulation()
    sim.add_material(rd.Material("m", 1e7, 0.3, 2500.0))
    drum = sim.add_wall(rd.MeshWall(SHAPES["drum"](radius=0.05, length=0.04, segments=64), material="m"))
    region = rd.MeshRegion(drum)
    target = {"count": 800, "mass": 0.15, "fraction": 0.25}[amount]
    sim.insert(region, radius=rd.Uniform(0.002, 0.003), material="m", seed=5, **{amount: target})
    x, r = sim.positions, sim.radii
    biggest = 4.0 / 3.0 * math.pi * 0.003 ** 3
    if amount == "count":
        assert len(r) == 800
    elif amount == "mass":
        assert abs(sim.masses.sum() - 0.15) <= 0.5 * 2500.0 * biggest
    else:
        assert abs(np.sum(4 / 3 * np.pi * r ** 3) / region.volume() - 0.25) <= 0.5 * biggest / region.volume()
    assert region.contains(x, r).all()
    assert drum.overlap(x, r).max() < 0.0
    assert min_gap(x, r) > -GAP_TOL


def mass_fraction_sigma(p, v, f, n):
    """The standard deviation of the realised mass fraction of each class among n spheres, by the
    delta method: f_k = sum v_i 1_k(i) / sum v_i, Var f_k ~ E[v^2 (1_k - f_k)^2] / (n E[v]^2), for a
    class k drawn with probability p_k and a sphere of volume v_k (``v`` may hold, per class, E[v^2]
    in place of v^2 and E[v] in place of v: pass them as (mean, mean square))."""
    mean_v, mean_v2 = v if isinstance(v, tuple) else (v, v ** 2)
    ev = np.sum(p * mean_v)
    k = np.arange(len(p))
    return np.array([math.sqrt(np.sum(p * mean_v2 * ((k == j) - f[j]) ** 2) / (n * ev ** 2)) for j in k])


def test_mass_fractions_are_realised_within_their_sampling_error():
    """Radii 1, 2 and 4 mm making up 0.2, 0.5 and 0.3 of the mass, 20,000 spheres: each class's
    realised mass fraction lies within 4 standard deviations of its share (the delta method's,
    ``mass_fraction_sigma``; the number of each drawn in proportion to f_k / r_k^3). Counted by
    number, as a Discrete with these weights would, the 1 mm class would hold 0.2 of the spheres
    but 0.002 of the mass: far outside."""
    dist = rd.MassFractions([0.001, 0.002, 0.004], [0.2, 0.5, 0.3])
    r = dist.sample(np.random.default_rng(6), 20000)
    f = np.array([0.2, 0.5, 0.3])
    v = np.array([0.001, 0.002, 0.004]) ** 3
    p = f / v / np.sum(f / v)
    sigma = mass_fraction_sigma(p, v, f, 20000)
    assert np.all(np.abs(dist.realised(r) - f) < 4 * sigma), (dist.realised(r), sigma)


def test_a_sieve_curve_is_realised_within_its_sampling_error():
    """A grading curve, 0/0.3/0.7/1 of the mass passing sieves of 2/3/4/6 mm, 20,000 spheres: each
    class between sieves holds its mass share within 4 standard deviations (the delta method's,
    with the class's mean volume and mean square volume from its number density c / d^3 by
    quadrature), and the mass passing 3.5 mm, halfway up the middle class where the curve is linear
    in d, is 0.5 within 4 of its own standard deviations. Every diameter lies within 2 to 6 mm."""
    d = np.array([0.002, 0.003, 0.004, 0.006])
    passing = np.array([0.0, 0.3, 0.7, 1.0])
    dist = rd.SieveCurve(d, passing)
    n = 20000
    r = dist.sample(np.random.default_rng(7), n)
    assert 2 * r.min() >= 0.002 and 2 * r.max() <= 0.006
    share = np.diff(passing)
    # per class: number density c_k / d^3 with c_k = share / width: number, E[v], E[v^2] by quadrature
    number, mean_v, mean_v2 = [], [], []
    for k in range(3):
        s = np.linspace(d[k], d[k + 1], 20001)
        density = share[k] / (d[k + 1] - d[k]) / s ** 3
        vol = np.pi / 6 * s ** 3
        total = np.trapezoid(density, s)
        number.append(total)
        mean_v.append(np.trapezoid(density * vol, s) / total)
        mean_v2.append(np.trapezoid(density * vol ** 2, s) / total)
    p = np.array(number) / np.sum(number)
    sigma = mass_fraction_sigma(p, (np.array(mean_v), np.array(mean_v2)), share, n)
    assert np.all(np.abs(dist.realised(r) - share) < 4 * sigma), (dist.realised(r), sigma)
    below = 2 * r < 0.0035
    passed = np.sum(r[below] ** 3) / np.sum(r ** 3)
    assert abs(passed - 0.5) < 4 * math.sqrt(0.5 * 0.5 / n) * 3, passed  # a loose bound: 3x the binomial's


def test_a_case_file_fills_a_mesh_wall_and_prints_the_realised_distribution(tmp_path):
    """A case that fills its drum wall's volume to a fraction of 0.25 with mass fractions 0.3/0.7 of
    2 and 3 mm spheres: ``check`` prints the count and the realised mass fractions beside those asked
    for (within 0.02: some 1,200 spheres), and every sphere is inside the drum."""
    from typer.testing import CliRunner

    from rollingdem.cli import app
    from rollingdem.io.casefile import build_simulation, load_case

    case = tmp_path / "fill.yaml"
    case.write_text("""\
name: fill
materials:
  - {name: m, youngs_modulus: 1.0e7, poisson_ratio: 0.3, density: 2500.0, friction: 0.5, restitution: 0.5}
walls:
  - {type: mesh, name: drum, material: m, shape: drum, size: {radius: 0.05, length: 0.04, segments: 64}}
particles:
  - insert: {type: mesh, wall: drum}
    fraction: 0.25
    radius: {distribution: mass_fractions, radii: [0.002, 0.003], fractions: [0.3, 0.7]}
    material: m
    seed: 3
stages:
  - {name: s, duration: 0.001}
""")
    result = CliRunner().invoke(app, ["check", str(case)])
    assert result.exit_code == 0, result.output
    line = next(s for s in result.output.splitlines() if "inserted" in s)
    got = [float(v) for v in line.split("mass fractions ")[1].split(" (asked")[0].split()]
    assert got == pytest.approx([0.3, 0.7], abs=0.02) and "(asked 0.300 0.700)" in line
    sim = build_simulation(load_case(case))
    assert rd.MeshRegion(sim.walls[0]).contains(sim.positions, sim.radii).all()
