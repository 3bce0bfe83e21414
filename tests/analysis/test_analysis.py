"""rd.analysis: angle of repose of a conical pile, on synthetic piles of known angle.

Synthetic pile (``make_pile``): spheres of radius 2 mm whose centres fill a cone of angle alpha
and base radius 40 diameters, standing on a first layer on the floor. Centres lie on a square
lattice of spacing one diameter d in x, y (jittered by +-0.1 d), stacked in columns at spacing d,
each column shifted up by its own random phase in [0, d) so that the free surface is a random
envelope (no staircase common to every column, which would bias a line fit over a finite range).
The tops of the surface particles then lie on a cone of exactly alpha, up to the envelope scatter.
Variants: Gaussian noise of 0.2 radius on every coordinate; a rough surface (30 % of the surface
particles removed, bumps: one particle put on top of 5 % of the others); polydisperse radii
(+-25 %); an off-centre pile with a toe spread 10 diameters further on one side.

Tolerances:
* angle (cone fit and slice mean) within 0.5 degree of the true angle: the accuracy the issue asks
  for. Measured on these piles: at most 0.14 degree for the seeds below (printed with ``-s``),
  at most 0.23 degree (slice mean of a rough 20-degree pile) over 10 seeds of every case.
* apex within half a radius of the true axis: the surface is resolved at the particle scale (bins
  one diameter wide), so half a radius means the right particles were chosen; measured < 0.1 radius.

Ideal piles (``ideal_pile``, below): the surface tops lie exactly on the cone, or evenly spread up
to one diameter below it. On those the angle is exact to the solver's tolerance (0.01 degree, far
below the 0.28-0.42 degree of a 1.5 % slope bias), or within a statistical bound of the envelope's
depth scatter, and each safeguard of the estimator is made to matter: stacks of spheres on the
outer surface (robust loss, MAD cut), a flat foot around the heap (toe clearance).
"""

import json
import math

import matplotlib
import numpy as np
import pytest

from rollingdem.analysis.repose import ReposeAngle, default_max_speed, plot_pile, repose_angle, settled
from rollingdem.errors import ParameterError, SimulationError
from helpers import D, RADIUS, column_lattice, ideal_pile

matplotlib.use("Agg")

N_BASE = 40  # pile base radius in diameters
TOL_ANGLE = 0.5  # degrees: the requirement




def make_pile(alpha_deg, *, radius=RADIUS, n_base=N_BASE, noise=0.0, rough=0.0, bumps=0.0,
              center=(0.0, 0.0), floor=0.0, poly=0.0, toe=False, seed=0):
    """Spheres filling a cone of angle alpha_deg (degrees); returns (positions (N, 3) m, radii)."""
    rng = np.random.default_rng(seed)
    d = 2 * radius
    big_r = n_base * d
    tan_a = np.tan(np.radians(alpha_deg))
    cx, cy, rho = column_lattice(rng, n_base + 11, d)
    phase = rng.uniform(0.0, d, cx.size)  # random vertical phase of each column
    room = big_r * tan_a - rho * tan_a - phase  # height available above the column's lowest centre
    nz = np.where(room >= 0, np.floor(room / d).astype(int) + 1, 0)
    col = np.repeat(np.arange(cx.size), nz)
    lev = np.arange(col.size) - np.repeat(np.cumsum(nz) - nz, nz)
    pos = np.column_stack([cx[col], cy[col], radius + phase[col] + lev * d])
    base = rho < big_r
    layers = [np.column_stack([cx[base], cy[base], np.full(base.sum(), radius)]), pos]
    if toe:  # first-layer spread 10 diameters beyond the cone on the +x side only
        m = (rho >= big_r) & (rho < big_r + 10 * d) & (cx > 0.3 * big_r)
        layers.append(np.column_stack([cx[m], cy[m], np.full(m.sum(), radius)]))
    pos = np.vstack(layers)
    depth = radius + (big_r - np.hypot(pos[:, 0], pos[:, 1])) * tan_a - pos[:, 2]
    surf = depth < d
    keep = ~(surf & (rng.random(len(pos)) < rough))
    on_top = pos[surf & keep & (rng.random(len(pos)) < bumps)] + [0.0, 0.0, d]
    pos = np.vstack([pos[keep], on_top])
    pos += rng.normal(0.0, noise * radius, pos.shape)
    pos += [center[0], center[1], floor]
    radii = radius * (1 + poly * rng.uniform(-1, 1, len(pos))) if poly else radius
    return pos, radii


VARIANTS = {
    "clean": dict(),
    "noisy": dict(noise=0.2),
    "rough": dict(noise=0.2, rough=0.3, bumps=0.05),
    "polydisperse": dict(noise=0.2, poly=0.25),
}


@pytest.mark.parametrize("variant", list(VARIANTS))
@pytest.mark.parametrize("alpha", [20.0, 30.0, 40.0])
def test_recovers_known_angle(alpha, variant):
    pos, radii = make_pile(alpha, seed=int(alpha), **VARIANTS[variant])
    res = repose_angle(pos, radii)  # centre estimated: the harder, default case
    print(f"\n{variant:13s} alpha {alpha:4.1f}: cone {res.angle - alpha:+.3f}, slices {res.slice_mean - alpha:+.3f} "
          f"+- {res.slice_std:.3f} deg, R^2 {res.r_squared:.3f}, {res.surface.sum()} surface particles")
    assert isinstance(res, ReposeAngle)
    assert abs(res.angle - alpha) <= TOL_ANGLE
    assert abs(res.slice_mean - alpha) <= TOL_ANGLE
    assert res.slice_angles.shape == (8,)
    # each slice fits 1/8 of the surface, so it scatters more: 1.5 degree (3x the pile tolerance;
    # worst slice measured over 10 seeds of every case: 0.71 degree, rough 20-degree pile)
    assert np.all(np.abs(res.slice_angles - alpha) <= 1.5)
    # the surface mask holds only the envelope: far fewer than all particles, each inside the fit range
    assert 500 < res.surface.sum() < 0.2 * len(pos)
    rho = np.hypot(pos[res.surface, 0] - res.apex[0], pos[res.surface, 1] - res.apex[1])
    assert res.fit_range[0] - RADIUS <= rho.min() and rho.max() <= res.fit_range[1] + RADIUS
    # the cone explains the surface heights (the envelope scatter is ~d over a height of ~10-30 d)
    assert res.r_squared > 0.85


def test_given_center_and_raised_floor():
    pos, radii = make_pile(30.0, noise=0.2, center=(1.0, -2.0), floor=0.5, seed=3)
    res = repose_angle(pos, radii, floor=0.5, center=(1.0, -2.0))
    assert res.apex[:2] == (1.0, -2.0)  # a given centre is kept, not fitted
    assert abs(res.angle - 30.0) <= TOL_ANGLE
    assert abs(res.slice_mean - 30.0) <= TOL_ANGLE


@pytest.mark.parametrize("alpha", [20.0, 40.0])
def test_off_centre_pile_with_asymmetric_toe_is_found(alpha):
    true_c = np.array([0.05, -0.03])
    pos, radii = make_pile(alpha, noise=0.2, center=true_c, toe=True, seed=7)
    # the toe is one-sided enough to matter: the plain centroid misses by more than twice the tolerance
    assert np.hypot(*(pos[:, :2].mean(axis=0) - true_c)) > RADIUS
    res = repose_angle(pos, radii)
    assert np.hypot(res.apex[0] - true_c[0], res.apex[1] - true_c[1]) <= 0.5 * RADIUS
    assert abs(res.angle - alpha) <= TOL_ANGLE
    assert abs(res.slice_mean - alpha) <= TOL_ANGLE


@pytest.mark.parametrize("alpha", [20.0, 30.0])
def test_spread_monolayer_and_runaway_spheres_are_not_the_pile(alpha):
    # A collapsed column leaves a monolayer over the floor all around the heap and single spheres
    # far out. Before the pile radius ignored them (step 3), the largest radius per sector was the
    # runaways' and the fit range fell outside the heap.
    pos, radii = make_pile(alpha, n_base=25, noise=0.2, seed=11)
    rng = np.random.default_rng(5)
    big_r = 25 * D
    ring = rng.uniform(big_r, 2.5 * big_r, 4000)  # monolayer out to 2.5 pile radii (overlaps do not matter here)
    phi = rng.uniform(0, 2 * np.pi, ring.size)
    far = rng.uniform(3 * big_r, 6 * big_r, 60)  # runaways
    phf = rng.uniform(0, 2 * np.pi, far.size)
    # a few spheres resting on the monolayer far out, in a dimple (bottom 0.82 d up)
    dimer = rng.uniform(1.5 * big_r, 2.5 * big_r, 5)
    phd = rng.uniform(0, 2 * np.pi, dimer.size)
    extra = np.vstack([
        np.column_stack([np.r_[ring, far] * np.cos(np.r_[phi, phf]), np.r_[ring, far] * np.sin(np.r_[phi, phf]),
                         np.full(ring.size + far.size, RADIUS)]),
        np.column_stack([dimer * np.cos(phd), dimer * np.sin(phd), np.full(dimer.size, RADIUS + 1.63 * RADIUS)])])
    res = repose_angle(np.vstack([pos, extra]), RADIUS)
    assert abs(res.angle - alpha) <= TOL_ANGLE
    assert abs(res.slice_mean - alpha) <= TOL_ANGLE
    assert res.fit_range[1] < big_r  # the fit stays on the heap


# --------------------------------------------------------------------------------------------
# Ideal piles: the tops of the surface spheres lie exactly on (or evenly below) a cone of known
# angle. Each test makes one safeguard of the estimator matter: without it the angle is off by far
# more than the test's tolerance (mutations checked by hand, see the report of issue 25).
# --------------------------------------------------------------------------------------------

#: Tolerance on an exact pile (every surface top on the cone, so no discretisation error at all):
#: what is left is the least-squares convergence (scipy's default xtol = ftol = 1e-8, relative),
#: ~1e-6 degree; 0.01 degree is 1/28 of a 1.5 % bias of tan(alpha) at 20 degrees (0.28 degree:
#: d(alpha) = 0.015 sin(alpha) cos(alpha) rad). Measured: below 1e-6 degree.
TOL_EXACT = 0.01




def envelope_tolerance(pos, res, alpha):
    """Tolerance (degrees) on the cone angle of an "even" pile: four standard deviations of the slope
    of a line fitted through N tops whose depths below the cone were independent and uniform in
    [0, d) (sd d/sqrt(12)): sd(tan) = (d / sqrt(12)) / (sqrt(N) sd(rho)), d(alpha) = cos^2(alpha)
    d(tan). Evenly spread depths scatter less than independent ones, so this bounds them: 0.16 to
    0.35 degree here, measured errors at most 0.1 degree."""
    rho = np.hypot(pos[res.surface, 0] - res.apex[0], pos[res.surface, 1] - res.apex[1])
    sd_tan = (D / math.sqrt(12.0)) / (math.sqrt(res.surface.sum()) * rho.std())
    return math.degrees(4.0 * sd_tan * math.cos(math.radians(alpha)) ** 2)


@pytest.mark.parametrize("alpha", [20.0, 30.0, 40.0])
def test_exact_pile_gives_the_exact_angle(alpha):
    """Every surface top on the cone: the cone fit and the slices return alpha to TOL_EXACT, so a
    slope biased by 1.5 % (0.28 to 0.42 degree over 20-40 degrees) cannot pass; nor can a bias of
    the slices alone, or of the apex (it is fitted with the slope)."""
    pos = ideal_pile(alpha, center=(0.013, -0.021), seed=int(alpha))
    free = repose_angle(pos, RADIUS)
    given = repose_angle(pos, RADIUS, center=(0.013, -0.021))
    print(f"\nexact {alpha}: {free.angle - alpha:+.2e} (centre fitted), {given.angle - alpha:+.2e} (given)")
    for res in (free, given):
        assert abs(res.angle - alpha) < TOL_EXACT
        assert abs(res.slice_mean - alpha) < TOL_EXACT
        assert np.all(np.abs(res.slice_angles - alpha) < TOL_EXACT)
        assert res.r_squared > 1 - 1e-9
    # the tops lie on t = h - tan(alpha) rho with h = 2 a + R tan(alpha) (R = 30 d), to xtol
    assert free.apex[2] == pytest.approx(2 * RADIUS + 30 * D * math.tan(math.radians(alpha)), abs=1e-3 * RADIUS)
    assert math.hypot(free.apex[0] - 0.013, free.apex[1] + 0.021) < 1e-3 * RADIUS


@pytest.mark.parametrize("alpha", [20.0, 30.0, 40.0])
def test_a_sector_bare_to_the_floor_is_not_taken_for_the_surface(alpha):
    """A pile that ran off one side: in a 90 degree sector only the first layer is left on the
    floor. The first-layer cut keeps those spheres out of the surface, so the rest of the cone gives
    alpha to TOL_EXACT, in the cone fit and in every slice. Taken for the surface, the bare floor
    pulls the cone steeper (+0.16 to +0.5 degree here) and the slices across the sector by 3 to 6
    degrees."""
    pos = ideal_pile(alpha, seed=1)
    azimuth = np.degrees(np.arctan2(pos[:, 1], pos[:, 0]))
    pos = pos[~((np.abs(azimuth) < 45.0) & (pos[:, 2] > 1.5 * RADIUS))]  # the first layer stays
    res = repose_angle(pos, RADIUS, n_slices=4)
    assert abs(res.angle - alpha) < TOL_EXACT
    assert np.all(np.abs(res.slice_angles - alpha) < TOL_EXACT)


def angle_within_tolerance(pos, alpha, envelope):
    """Measure the pile; assert the cone and the slices' mean give alpha to TOL_EXACT (exact
    envelope) or to the envelope tolerance (even); return the result."""
    res = repose_angle(pos, RADIUS)
    tol = TOL_EXACT if envelope == "exact" else envelope_tolerance(pos, res, alpha)
    assert abs(res.angle - alpha) < tol, f"{res.angle - alpha:+.3f} deg off (tolerance {tol:.3f})"
    assert abs(res.slice_mean - alpha) < tol, f"slices {res.slice_mean - alpha:+.3f} deg off (tolerance {tol:.3f})"
    return res


@pytest.mark.parametrize("envelope", ["exact", "even"])
@pytest.mark.parametrize("alpha", [20.0, 40.0])
def test_stacks_on_the_outer_surface_do_not_pull_the_cone(alpha, envelope):
    """30 % of the columns of the outer half carry a stack of three spheres (bumps 1-3 d high). The
    robust loss (soft_l1) keeps the first fit on the surface, so that the 3-sigma MAD cut then drops
    the stacks: the angle stays within TOL_EXACT (exact surface) or the envelope tolerance (even
    surface, measured <= 0.08 degree). A plain least-squares first fit, or no MAD cut, lets the
    stacks lift the outer surface: 0.5-2 degree too shallow."""
    pos = ideal_pile(alpha, envelope=envelope, stacks=0.3, seed=1)
    res = angle_within_tolerance(pos, alpha, envelope)
    # no stacked sphere is taken for the surface: every surface top is at most one diameter off the cone
    top = pos[:, 2] + RADIUS
    rho = np.hypot(pos[:, 0] - res.apex[0], pos[:, 1] - res.apex[1])
    cone = res.apex[2] - math.tan(math.radians(res.angle)) * rho
    assert np.all(np.abs(top[res.surface] - cone[res.surface]) < D)


@pytest.mark.parametrize("envelope", ["exact", "even"])
@pytest.mark.parametrize("alpha", [20.0, 30.0, 40.0])
def test_flat_foot_is_left_out_of_the_fit(alpha, envelope):
    """A foot of two layers on the first (tops 2.64 d above the floor, bottoms of its top layer 1.64 d
    up, so it counts for the pile radius) reaches 10 d beyond the cone. The fit range ends where the
    fitted cone of tops comes within three diameters of the floor, before the foot: the angle is
    within TOL_EXACT (exact) or the envelope tolerance (even; measured <= 0.08 degree). Without that
    toe clearance the fit runs on to 0.85 of the pile radius, over the foot: 3-8 degrees too shallow."""
    pos = ideal_pile(alpha, envelope=envelope, foot_layers=2, seed=2)
    res = angle_within_tolerance(pos, alpha, envelope)
    # the fit range ends where the fitted tops are 3 d above the floor (to the 0.25 d of its convergence)
    h, tan_a = res.apex[2], math.tan(math.radians(res.angle))
    assert res.fit_range[1] == pytest.approx((h - 3 * D) / tan_a, abs=0.25 * D / tan_a)


def test_a_few_tufts_far_out_do_not_set_the_pile_radius():
    """Three small tufts (a sphere on the third layer of a little heap, bottom 1.64 d up, so it counts
    as lying on others) stand 4-6 pile radii out in three of the 16 sectors. The pile radius is the
    median over the sectors, so they do not move it: the fit range starts at 0.15 of the heap's radius
    and the angle is exact (TOL_EXACT). Were the radius the largest over the sectors, 6 pile radii,
    the apex cut alone (0.9 of the heap's radius) would leave too few surface spheres to fit."""
    pos = ideal_pile(30.0, seed=4)
    big_r = 30 * D
    tufts = []
    for phi, r in ((0.3, 4.0), (2.5, 5.0), (4.4, 6.0)):
        x, y = r * big_r * math.cos(phi), r * big_r * math.sin(phi)
        tufts += [[x, y, RADIUS], [x + D, y, RADIUS], [x + RADIUS, y + 0.87 * D, RADIUS],
                  [x + RADIUS, y + 0.29 * D, RADIUS + 0.82 * D], [x + RADIUS, y + 0.29 * D, RADIUS + 1.64 * D]]
    res = repose_angle(np.vstack([pos, tufts]), RADIUS)
    assert abs(res.angle - 30.0) < TOL_EXACT
    # the heap's radius from its lifted spheres (bottom >= 1.25 d up): they reach out to where the cone's
    # top sphere is that high, rho + a = 30 d - 1.25 d / tan(30) + a = 28.3 d, to a lattice spacing d
    heap = big_r - 1.25 * D / math.tan(math.radians(30.0)) + RADIUS
    assert res.fit_range[0] == pytest.approx(0.15 * heap, abs=0.15 * D)


def test_unsettled_pile_is_refused():
    pos, radii = make_pile(30.0, n_base=20, seed=1)
    rng = np.random.default_rng(0)
    moving = rng.normal(0.0, 0.05, pos.shape)  # m/s: a pile still flowing
    limit = default_max_speed(radii)
    assert limit == pytest.approx(1e-3 * np.sqrt(9.81 * D))
    ok, vmax = settled(moving, radii)
    assert not ok and vmax > limit
    with pytest.raises(SimulationError, match=r"not settled.*m/s.*limit.*run the simulation longer"):
        repose_angle(pos, radii, velocities=moving)
    # a pile at rest (speeds well under the limit) is measured; a custom limit is honoured
    still = moving * (0.1 * limit / vmax)
    assert settled(still, radii)[0]
    assert abs(repose_angle(pos, radii, velocities=still).angle - 30.0) <= TOL_ANGLE
    with pytest.raises(SimulationError, match="max_speed = 1e-06"):
        repose_angle(pos, radii, velocities=still, max_speed=1e-6)


@pytest.fixture(scope="module")
def small_pile():
    return make_pile(30.0, n_base=20, seed=2)


@pytest.mark.parametrize("change, name", [
    (dict(positions=np.zeros((100, 2))), "positions"),
    (dict(positions="nan"), "positions"),
    (dict(positions=np.full((100, 3), np.nan)), "positions"),
    (dict(positions=np.zeros((5, 3)), radii=1e-3), "positions"),
    (dict(radii=-1e-3), "radii"),
    (dict(radii=np.full(7, 1e-3)), "radii"),
    (dict(radii=np.nan), "radii"),
    (dict(floor=np.nan), "floor"),
    (dict(floor=1.0), "floor"),
    (dict(center=(0.0,)), "center"),
    (dict(center=(0.0, np.inf)), "center"),
    (dict(velocities=np.zeros((3, 3))), "velocities"),
    (dict(max_speed=-1.0), "max_speed"),
    (dict(max_speed=1e-3), "max_speed"),  # without velocities there is nothing to check
    (dict(n_slices=0), "n_slices"),
    (dict(n_slices=2.5), "n_slices"),
    (dict(n_slices=100000), "n_slices"),  # more slices than surface particles
    (dict(exclude_apex=0.5), "exclude_apex"),
    (dict(exclude_apex=-0.01), "exclude_apex"),
    (dict(exclude_toe=0.7), "exclude_toe"),
    (dict(exclude_toe=np.nan), "exclude_toe"),
])
def test_bad_input_names_the_parameter(small_pile, change, name):
    pos, radii = small_pile
    kw = dict(positions=pos, radii=radii)
    kw.update(change)
    with pytest.raises(ParameterError, match=name):
        repose_angle(kw.pop("positions"), kw.pop("radii"), **kw)


def test_flat_layer_is_refused():
    pos, _ = make_pile(30.0, n_base=20, seed=2)
    pos = pos[pos[:, 2] < 1.5 * RADIUS]  # the first layer only: no cone to fit
    with pytest.raises(ParameterError, match="positions"):
        repose_angle(pos, RADIUS)


def test_single_slice_and_json(small_pile):
    pos, radii = small_pile
    res = repose_angle(pos, radii, n_slices=1)
    assert res.slice_angles.shape == (1,) and res.slice_std == 0.0
    d = json.loads(json.dumps(res.as_dict()))
    assert d["angle"] == res.angle and d["n_surface"] == res.surface.sum() == len(d["surface_indices"])
    assert len(d["apex"]) == 3 and len(d["fit_range"]) == 2


def test_plot_pile_writes_png(tmp_path, small_pile):
    pos, radii = small_pile
    res = repose_angle(pos, radii)
    path = tmp_path / "pile.png"
    fig = plot_pile(pos, radii, res, path=path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert path.stat().st_size > 1024
    assert len(fig.axes) == 1
    # drawing into a given axes returns that axes' figure
    from matplotlib.figure import Figure
    ax = Figure().add_subplot()
    assert plot_pile(pos, radii, res, ax=ax) is ax.figure
    with pytest.raises(ParameterError, match="surface"):
        plot_pile(pos[:-1], radii, res)


def test_touching_marks_spheres_in_contact_only():
    from rollingdem.analysis.repose import touching

    d = 2 * RADIUS
    pos = np.array([[0, 0, RADIUS], [d * 1.01, 0, RADIUS],  # a pair with a gap of 1 % of d: touching
                    [0.5, 0, RADIUS],                        # alone on the floor, far away
                    [1.0, 0, RADIUS], [1.0 + d * 1.2, 0, RADIUS]])  # gap of 20 % of d: not touching
    assert touching(pos, RADIUS).tolist() == [True, True, False, False, False]
    with pytest.raises(ParameterError, match="gap"):
        touching(pos, RADIUS, gap=-1.0)
