"""Random insertion of non-overlapping spheres into a region.

    from rollingdem.scene.regions import CylinderRegion
    from rollingdem.scene.size_distributions import Uniform
    sim.insert(CylinderRegion(0.05, 0.0, 0.2), 500, Uniform(0.004, 0.005), "glass", seed=3)

Random sequential addition, reproducible from ``seed``; how, and how densely: docs/studies.md. The
regions: ``rollingdem.scene.regions``; the radii: ``rollingdem.scene.size_distributions``."""

from __future__ import annotations

import math

import numpy as np

from rollingdem.errors import Declared, ParameterError, check_finite, check_non_negative, check_positive
from rollingdem.physics.records import WALL_PLANE
from rollingdem.scene.regions import BoxRegion, CylinderRegion, Region
from rollingdem.scene.size_distributions import SizeDistribution, as_distribution

MAX_PACKING_FRACTION = 0.55
"""Requests above this packing fraction are refused before any attempt (random insertion tops out
near 0.3-0.35; even a random close packing is only ~0.64)."""

_ROUND_CANDIDATES = 8192
"""Fewest candidates drawn per round once few spheres are left (and most spheres per round)."""

_EXPECT = 10.0
"""Sampling adapts (free cells, then split cells) once a sphere can expect fewer free candidates than
this in the attempts it has left."""

_SIZE_BAND = 0.9
"""A round takes the spheres at least this fraction of the largest one still waiting."""



def _fmt(x: float) -> str:
    return f"{x:g}"


def check_count(name, value) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ParameterError(f"{name} = {value!r} is not allowed: must be a positive integer")
    v = int(value)
    if v < 1:
        raise ParameterError(f"{name} = {v} is not allowed: must be a positive integer (>= 1)")
    return v


class _FreeCells:
    """Cells that may still hold a free centre for the smallest radius ``rho0`` (all cells one size).

    A cell is dropped once it lies wholly inside the exclusion ball of one placed sphere j (radius
    r_j + rho0 about its centre), wholly outside where a centre of radius rho0 may lie in the region,
    or wholly behind a plane wall: no centre of a sphere still to place can lie there. Candidates drawn
    uniformly from the cells left are uniform over a superset of the free space, as with plain
    sampling, but far fewer are wasted once the region fills up. Cells start on a dense grid; when
    candidates keep failing, every cell left is split in eight and the children are checked against
    all placed spheres (a list of cells from then on), so that cells covered only by several balls
    together get dropped too.
    """

    MAX_DENSE = 16_000_000  # cells of the first, dense grid
    MAX_SPLIT = 400_000  # most cells split in eight at once
    CELL = 0.4  # first cell size / rho0
    MIN_CELL = 0.02  # no split below this cell size / rho0

    def __init__(self, region: Region, rho0: float, walls):
        lo, hi = region.bounds()
        self.region = region
        self.rho0 = rho0
        self.origin = lo + rho0
        ext = np.maximum(hi - lo - 2.0 * rho0, 0.0)
        h = self.CELL * rho0
        h = max(h, float(np.prod(np.maximum(ext, 1e-300)) / self.MAX_DENSE) ** (1.0 / 3.0))
        self.h = h
        self.shape = np.maximum(np.ceil(ext / h).astype(np.int64), 1)
        self.planes = [(w.geometry()[0:3], w.geometry()[3:6]) for w in walls if w.kind == WALL_PLANE]
        # A cell must fit in an exclusion ball, and the region must be at least a cell thick.
        self.usable = bool(h * math.sqrt(3.0) < 2.0 * rho0 and (ext >= h).all())
        self.dense = None  # flags of the dense grid, flattened
        self._flat = None  # indices of the dense cells left, as of the last sample
        self.cells = None  # (M, 3) cell indices once split, their centres' k-d tree, and which are left
        self.tree = None
        self.alive = None
        if self.usable:
            ax = [self.origin[d] + np.arange(self.shape[d]) * h for d in range(3)]  # cell lower corners
            keep = np.ones(tuple(self.shape), dtype=bool)
            if isinstance(region, CylinderRegion):
                keep &= self._xy_inside(ax[0][:, None], ax[1][None, :], h)[:, :, None]
            for p, nrm in self.planes:
                reach = [np.maximum(nrm[d] * (ax[d] - p[d]), nrm[d] * (ax[d] + h - p[d])) for d in range(3)]
                keep &= reach[0][:, None, None] + reach[1][None, :, None] + reach[2][None, None, :] >= rho0
            self.dense = keep.reshape(-1)

    def _xy_inside(self, x0, y0, h):
        """Whether a cell with lower corner (x0, y0) reaches within R - rho0 of the cylinder axis."""
        reg = self.region
        cx = np.maximum(np.abs(x0 + 0.5 * h - reg.center[0]) - 0.5 * h, 0.0)
        cy = np.maximum(np.abs(y0 + 0.5 * h - reg.center[1]) - 0.5 * h, 0.0)
        return cx ** 2 + cy ** 2 <= (reg.radius - self.rho0) ** 2

    def _left(self) -> np.ndarray:
        """Indices of the cells left (flat indices of the dense grid, or rows of ``cells``)."""
        if self.cells is None:
            self._flat = np.flatnonzero(self.dense) if self._flat is None else self._flat[self.dense[self._flat]]
            return self._flat
        return np.flatnonzero(self.alive)

    def _ijk(self, left: np.ndarray) -> np.ndarray:
        if self.cells is not None:
            return self.cells[left]
        ny, nz = self.shape[1], self.shape[2]
        return np.stack([left // (ny * nz), (left // nz) % ny, left % nz], axis=1)

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray | None:
        """n points uniform over the cells left; None when none is left."""
        left = self._left()
        if left.size == 0:
            return None
        ijk = self._ijk(left[rng.integers(0, left.size, n)])
        return self.origin + (ijk + rng.random((n, 3))) * self.h

    def cover(self, x: np.ndarray, r: np.ndarray) -> None:
        """Drop the cells lying wholly within distance r + rho0 of any of the centres ``x``."""
        if x.shape[0] == 0:
            return
        h, rho = self.h, r + self.rho0
        if self.cells is not None:
            near = self.tree.query_ball_point(x, rho, return_sorted=False)
            cnt = np.fromiter((len(c) for c in near), dtype=np.int64, count=len(near))
            if cnt.sum() == 0:
                return
            ci = np.concatenate([np.asarray(c, dtype=np.int64) for c in near])
            pj = np.repeat(np.arange(x.shape[0]), cnt)
            lc = self.origin + self.cells[ci] * h
            far = (np.maximum(np.abs(x[pj] - lc), np.abs(x[pj] - lc - h)) ** 2).sum(axis=1)
            self.alive[ci[far < rho[pj] ** 2]] = False
            return
        ny, nz = self.shape[1], self.shape[2]
        m = np.ceil(2.0 * rho / h).astype(np.int64) + 1
        for mm in np.unique(m[m <= 64]):  # (leaving a few cells of a much larger sphere is harmless)
            sel = np.nonzero(m == mm)[0]
            chunk = max(1, 4_000_000 // int(mm) ** 3)
            off = np.arange(mm)
            for a in range(0, sel.size, chunk):
                s = sel[a:a + chunk]
                xs, rs = x[s], rho[s]
                base = np.floor((xs - rs[:, None] - self.origin) / h).astype(np.int64)
                c = base[:, :, None] + off  # (n, 3, mm) cell index per dimension
                lo = self.origin[None, :, None] + c * h
                far = np.maximum(np.abs(xs[:, :, None] - lo), np.abs(xs[:, :, None] - lo - h)) ** 2
                valid = (c >= 0) & (c < self.shape[None, :, None])
                far = np.where(valid, far, np.inf)
                d2 = far[:, 0, :, None, None] + far[:, 1, None, :, None] + far[:, 2, None, None, :]
                k, i, j, l = np.nonzero(d2 < (rs ** 2)[:, None, None, None])
                self.dense[(c[k, 0, i] * ny + c[k, 1, j]) * nz + c[k, 2, l]] = False

    def split(self, x: np.ndarray, r: np.ndarray) -> bool:
        """Split every cell left in eight and keep the children not covered by the spheres (x, r).

        Returns False (and does nothing) when there are too many cells or they are small already.
        """
        from scipy.spatial import cKDTree  # deferred: slow to load, used here only

        left = self._left()
        if left.size > self.MAX_SPLIT or self.h < 2.0 * self.MIN_CELL * self.rho0:
            return False
        par = self._ijk(left)
        off = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=np.int64)
        h = 0.5 * self.h
        children = (2 * par[:, None, :] + off[None, :, :]).reshape(-1, 3)
        lo = self.origin + children * h
        keep = np.ones(children.shape[0], dtype=bool)
        if isinstance(self.region, CylinderRegion):
            keep &= self._xy_inside(lo[:, 0], lo[:, 1], h)
        for p, nrm in self.planes:
            keep &= np.maximum(nrm * (lo - p), nrm * (lo + h - p)).sum(axis=1) >= self.rho0
        if x.shape[0] and par.shape[0]:
            # A child wholly inside the ball of radius r_j + rho0 about x_j has its parent's centre
            # inside that ball too: find the (parent, sphere) pairs, then test the eight children.
            ptree = cKDTree(self.origin + (par + 0.5) * self.h, balanced_tree=False, compact_nodes=False)
            sdm = ptree.sparse_distance_matrix(cKDTree(x), self.rho0 + float(r.max()), output_type="ndarray")
            if sdm.size:
                ci, pj = sdm["i"], sdm["j"]
                xp, rho2 = x[pj], (r[pj] + self.rho0) ** 2
                for o in range(8):
                    k = ci * 8 + o
                    lc = lo[k]
                    far = (np.maximum(np.abs(xp - lc), np.abs(xp - lc - h)) ** 2).sum(axis=1)
                    keep[k[far < rho2]] = False
        self.cells = children[keep]
        self.alive = np.ones(self.cells.shape[0], dtype=bool)
        self.h = h
        self.tree = (cKDTree(self.origin + (self.cells + 0.5) * h, balanced_tree=False, compact_nodes=False)
                     if self.cells.shape[0] else None)
        if self.tree is None:
            self.cells = np.zeros((0, 3), dtype=np.int64)
            self.alive = np.zeros(0, dtype=bool)
        self.dense = self._flat = None
        return True


def radii_to_volume(dist: SizeDistribution, rng, volume: float) -> np.ndarray:
    """Radii drawn from ``dist`` one after another until their spheres' volume comes nearest
    ``volume`` (m^3): the first k, k the count whose total is nearest."""
    drawn, total, size = [], 0.0, 64
    while total < volume:
        batch = np.asarray(dist.sample(rng, size), dtype=float)
        drawn.append(batch)
        total += float(np.sum(4.0 / 3.0 * math.pi * batch ** 3))
        mean = total / sum(len(b) for b in drawn)
        size = int(min(1.1 * max(volume - total, 0.0) / mean + 64, 1e7))  # what is left, and a margin
    r = np.concatenate(drawn)
    cum = np.cumsum(4.0 / 3.0 * math.pi * r ** 3)
    k = int(np.searchsorted(cum, volume))  # cum[k] >= volume > cum[k - 1]
    if k > 0 and volume - cum[k - 1] < cum[k] - volume:
        k -= 1
    return r[:k + 1]


def fill_region(region: Region, count: int | None, radius, seed=0, existing_positions=None, existing_radii=None,
                walls=(), max_attempts: int = 200, volume: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Place ``count`` non-overlapping spheres wholly inside ``region`` by random sequential addition;
    or, with ``volume`` (m^3) instead, as many as bring their volume nearest it (``radii_to_volume``).

    ``radius`` is a number (m) or a distribution (``Uniform``, ``Normal``, ``Discrete``,
    ``MassFractions``, ``SieveCurve``). The spheres overlap neither each other, the
    ``existing_positions`` / ``existing_radii`` particles nor any of ``walls``. Each sphere gets up
    to ``max_attempts`` random candidate positions. Same ``seed``, same result. Returns (positions
    (count, 3), radii (count,)).
    """
    if not isinstance(region, Region):
        raise ParameterError(f"region = {region!r} is not allowed: must be a BoxRegion, CylinderRegion or MeshRegion")
    max_attempts = check_count("max_attempts", max_attempts)
    dist = as_distribution(radius)
    rng = np.random.default_rng(seed)
    if volume is None:
        n = check_count("count", count)
        r_all = np.asarray(dist.sample(rng, n), dtype=np.float64)
    else:
        r_all = radii_to_volume(dist, rng, check_positive("volume", volume, "m^3"))
        n = len(r_all)

    # Existing particles.
    if existing_positions is None or np.size(existing_positions) == 0:
        ex = np.zeros((0, 3))
    else:
        ex = np.array(existing_positions, dtype=np.float64, ndmin=2)
        if ex.ndim != 2 or ex.shape[1] != 3:
            raise ParameterError(f"existing_positions with shape {ex.shape} are not allowed: need (N, 3)")
    if existing_radii is None:
        if ex.shape[0]:
            raise ParameterError("existing_radii = None is not allowed when existing_positions are given")
        er = np.zeros(0)
    else:
        er = np.asarray(existing_radii, dtype=np.float64).reshape(-1)
        if er.size == 1 and ex.shape[0] != 1:
            er = np.full(ex.shape[0], float(er[0]))
        if er.shape[0] != ex.shape[0]:
            raise ParameterError(f"existing_radii with {er.shape[0]} values are not allowed: need one per "
                                 f"existing position ({ex.shape[0]})")
    if not (np.isfinite(ex).all() and np.isfinite(er).all()):
        raise ParameterError("existing_positions / existing_radii contain a non-finite value: must be finite")

    walls = [w for w in (walls or ()) if getattr(w, "kind", -1) >= 0]

    # the checks that need no attempt
    rmax = float(r_all.max())
    vol = region.volume()
    fraction = float((4.0 / 3.0) * math.pi * np.sum(r_all ** 3) / vol)
    if not region.fits(rmax):
        raise ParameterError(f"a sphere of radius {_fmt(rmax)} m does not fit in {region!r} at all: "
                             "use a larger region or smaller spheres")
    if fraction > MAX_PACKING_FRACTION:
        raise ParameterError(f"{n} spheres in {region!r} would need a packing fraction of {fraction:.3f} "
                             f"(sum of sphere volumes / region volume), above the {MAX_PACKING_FRACTION} "
                             "that can be asked of random insertion, which tops out near 0.3-0.35 packing "
                             "fraction: use a larger region or fewer spheres (and let them settle)")

    x_out = np.empty((n, 3))
    placed, why = 0, None
    known = np.zeros(n, dtype=bool)  # the new spheres placed so far
    for sub, idx in _slab_plan(region, float(r_all.min()), rmax, n, r_all):
        # each slab sees everything placed before it as existing particles
        known_x = np.concatenate([ex, x_out[known]])
        known_r = np.concatenate([er, r_all[known]])
        x_sub, done, why = _fill(sub, r_all[idx], rng, known_x, known_r, walls, max_attempts)
        placed += done
        if why is not None:
            break
        x_out[idx] = x_sub
        known[idx] = True
    if why is not None:
        raise ParameterError(
            f"could place only {placed} of {n} spheres in {region!r}: {why}. The requested packing "
            f"fraction is {fraction:.3f} (sum of sphere volumes / region volume); random insertion tops out "
            "near 0.3-0.35 packing fraction (less with walls or particles already in the region): use a "
            "larger region or fewer spheres (and let them settle), or raise max_attempts")
    return x_out, r_all.copy()


SLAB_PASSES = 4
"""Passes over the slabs of a large region, each with a quarter of the spheres and its seams a
quarter of a slab higher (``_slab_plan``)."""


def _slab_plan(region: Region, rho0: float, rmax: float, n: int,
               radii: np.ndarray | None = None) -> list[tuple[Region, np.ndarray]]:
    """(sub-region, indices of the spheres it takes) in the order to fill them: ``[(region, all)]``
    when the free-cell grid of the whole region at its finest cell size (``_FreeCells.CELL`` rho0)
    holds at most ``_FreeCells.MAX_DENSE`` cells. A larger region's grid would have cells too
    coarse to be dropped as covered, and insertion of 10^6 spheres ran out of attempts at a packing
    fraction of 0.24; it is cut across its longest axis (z for a cylinder) into slabs small enough.

    Neighbouring slabs overlap by 2 rmax, so that the centres a sphere of radius rmax may take
    tile the region's exactly. A slab filled before its neighbour packs denser against their seam
    (as random insertion does against any wall: ~10 % more centres in the diameter below the seam
    and ~10 % fewer above it, measured at a packing fraction of 0.27). So the spheres go in
    ``SLAB_PASSES`` passes, each over all the slabs with an equal share of the spheres, the seams of
    each pass shifted by 1/SLAB_PASSES of a slab: each seam is met at a quarter of the density.
    With ``radii``, the passes take the spheres largest first (the first pass the largest quarter),
    as one region's insertion does (a last pass's large spheres find no room in a bed already at a
    packing fraction of 0.21), and each slab of a pass sizes from all over the pass's range."""
    lo, hi = region.bounds()
    h = _FreeCells.CELL * rho0
    ext = np.maximum(hi - lo - 2.0 * rho0, h)
    axis = 2 if isinstance(region, CylinderRegion) else int(np.argmax(hi - lo))
    across = float(np.prod(np.delete(ext, axis))) / h ** 2  # cells in a layer one cell thick
    length = float(hi[axis] - lo[axis]) - 2.0 * rmax  # the centres' range for the largest sphere
    per_slab = _FreeCells.MAX_DENSE / across * h - 2.0 * (rmax - rho0)  # the most a slab's centres may span
    if across * ext[axis] / h <= _FreeCells.MAX_DENSE or per_slab <= 0.0 or length <= 0.0:
        return [(region, np.arange(n))]  # (too wide across to help: one coarse grid, as before)
    k = math.ceil(length / per_slab)
    plan = []
    largest_first = np.arange(n) if radii is None else np.argsort(-np.asarray(radii), kind="stable")
    for p, share in enumerate(np.array_split(largest_first, SLAB_PASSES)):
        inner = (np.arange(1 if p == 0 else 0, k) + p / SLAB_PASSES) * length / k
        seams = np.concatenate([[0.0], inner, [length]])
        # spheres per slab in proportion to the centres' range, by largest remainders
        want = share.size * np.diff(seams) / length
        count = np.floor(want).astype(np.int64)
        count[np.argsort(count - want)[:share.size - count.sum()]] += 1
        # the share's j-th sphere to the slab whose evenly spaced quantiles come j-th: each slab's
        # sizes spread over the share's range
        quantile = np.concatenate([(np.arange(c) + 0.5) / c for c in count if c] or [np.zeros(0)])
        slab = np.repeat(np.arange(len(count)), count)[np.argsort(quantile, kind="stable")]
        by_slab = np.argsort(slab, kind="stable")  # the share's positions, slab by slab, in order within each
        for s_lo, s_hi, idx in zip(seams[:-1], seams[1:], np.split(share[by_slab], np.cumsum(count)[:-1])):
            if idx.size == 0:
                continue
            z_lo, z_hi = lo[axis] + s_lo, lo[axis] + s_hi + 2.0 * rmax
            if isinstance(region, CylinderRegion):
                plan.append((CylinderRegion(region.radius, z_lo, z_hi, region.center), idx))
            elif hasattr(region, "clipped"):  # a mesh's volume, cut into slabs of its box
                b_lo, b_hi = lo.copy(), hi.copy()
                b_lo[axis], b_hi[axis] = z_lo, z_hi
                plan.append((region.clipped(b_lo, b_hi), idx))
            else:
                b_lo, b_hi = lo.copy(), hi.copy()
                b_lo[axis], b_hi[axis] = z_lo, z_hi
                plan.append((BoxRegion(b_lo, b_hi), idx))
    return plan


def _fill(region: Region, r_all: np.ndarray, rng, ex: np.ndarray, er: np.ndarray, walls, max_attempts: int):
    """Random sequential addition of spheres of radii ``r_all`` into ``region`` (see ``fill_region``).
    Returns (positions in the order of ``r_all``, spheres placed, None), or (None, spheres placed,
    why) when one ran out of attempts."""
    from scipy.spatial import cKDTree  # deferred: slow to load, used here only

    # Only existing particles that can touch a sphere in the region matter.
    rmax = float(r_all.max())
    n = r_all.shape[0]
    lo, hi = region.bounds()
    if ex.shape[0]:
        gap = np.maximum(lo - ex, 0.0) + np.maximum(ex - hi, 0.0)
        near = np.linalg.norm(gap, axis=1) < er + rmax
        ex, er = ex[near], er[near]

    order = np.argsort(-r_all, kind="stable")  # largest first
    r_sorted = r_all[order]
    placed_x = np.empty((n, 3))
    done = np.zeros(n, dtype=bool)
    attempts = np.zeros(n, dtype=np.int64)
    n_placed = 0
    # Placed spheres so far: existing (near) first, then new ones in the order they were accepted.
    fixed_x, fixed_r = ex, er
    rmax_fixed = float(er.max()) if er.size else 0.0
    new_x = np.empty((n, 3))
    new_r = np.empty(n)
    n_new = 0

    rho0 = float(r_all.min())
    grid = None
    grid_tried = False
    split_at = -1  # spheres placed at the last split
    full = False
    while n_placed < n:
        # The largest spheres still waiting (at most _ROUND_CANDIDATES, and none much smaller than
        # the largest, so that large spheres are placed before small ones fill the gaps), k
        # candidates each.
        waiting = np.nonzero(~done)[0][:_ROUND_CANDIDATES]
        waiting = waiting[r_sorted[waiting] >= _SIZE_BAND * r_sorted[waiting[0]]]
        m = waiting.size
        # At most a tenth of the attempts per round, so that the sampling can adapt (switch to the
        # free cells, split them) before a sphere runs out of attempts.
        k = max(1, min(-(-_ROUND_CANDIDATES // m), max_attempts // 10,
                       int((max_attempts - attempts[waiting]).min())))
        sph = np.repeat(waiting, k)  # candidate -> sphere (sorted index), grouped by sphere in order
        rc = r_sorted[sph]
        attempts[waiting] += k
        if grid is None:
            xc = region.sample(rng, rc)
            ok = np.isfinite(xc[:, 0])  # a region drawn by rejection marks a candidate it found no place for
        else:
            xc = grid.sample(rng, sph.size)
            if xc is None:  # no free place left anywhere: no attempt can succeed
                attempts[waiting] = max_attempts
                xc = np.zeros((0, 3))
                sph, rc = sph[:0], rc[:0]
                full = True
            ok = region.contains(xc, rc)
        for w in walls:
            ok &= w.overlap(xc, rc) <= 0.0
        # Against everything placed before this round.
        all_x = np.concatenate([fixed_x, new_x[:n_new]]) if n_new else fixed_x
        all_r = np.concatenate([fixed_r, new_r[:n_new]]) if n_new else fixed_r
        if all_x.shape[0] and ok.any():
            idx = np.nonzero(ok)[0]
            ctree = cKDTree(xc[idx])
            ptree = cKDTree(all_x)
            reach = float(rc[idx].max()) + max(rmax_fixed, float(new_r[:n_new].max()) if n_new else 0.0)
            sdm = ctree.sparse_distance_matrix(ptree, reach, output_type="ndarray")
            if sdm.size:
                ci, pj, dd = sdm["i"], sdm["j"], sdm["v"]
                hit = dd < rc[idx][ci] + all_r[pj]
                ok[idx[np.unique(ci[hit])]] = False
        # Among this round's candidates: accept in order, skipping overlaps with ones accepted before.
        idx = np.nonzero(ok)[0]
        if idx.size:
            ctree = cKDTree(xc[idx])
            pairs = ctree.query_pairs(2.0 * float(rc[idx].max()), output_type="ndarray")
            if pairs.size:
                a, b = pairs[:, 0], pairs[:, 1]
                dd = np.linalg.norm(xc[idx[a]] - xc[idx[b]], axis=1)
                clash = dd < rc[idx[a]] + rc[idx[b]]
                a, b = a[clash], b[clash]
            else:
                a = b = np.zeros(0, dtype=np.int64)
            # Conflicts only matter with an earlier candidate (lower index = higher priority).
            lo_i, hi_i = np.minimum(a, b), np.maximum(a, b)
            accepted = np.zeros(idx.size, dtype=bool)
            sph_ok = sph[idx]
            if lo_i.size == 0:
                # Keep the first candidate of each sphere.
                first = np.ones(idx.size, dtype=bool)
                first[1:] = sph_ok[1:] != sph_ok[:-1]
                accepted = first
            else:
                srt = np.argsort(hi_i, kind="stable")
                hi_s, lo_s = hi_i[srt], lo_i[srt]
                starts = np.searchsorted(hi_s, np.arange(idx.size + 1))
                taken = set()
                for c in range(idx.size):
                    s = int(sph_ok[c])
                    if s in taken:
                        continue
                    s0, s1 = starts[c], starts[c + 1]
                    if s1 > s0 and accepted[lo_s[s0:s1]].any():
                        continue
                    accepted[c] = True
                    taken.add(s)
            acc = idx[accepted]
            sp = sph[acc]
            done[sp] = True
            placed_x[sp] = xc[acc]
            new_x[n_new:n_new + acc.size] = xc[acc]
            new_r[n_new:n_new + acc.size] = rc[acc]
            n_new += acc.size
            n_placed += acc.size
            if grid is not None:
                grid.cover(xc[acc], rc[acc])
        # Once candidates fail so often that a sphere might run out of attempts, draw them only
        # from the cells that may still be free, and split those cells when that is not enough:
        # ``rate`` is the share of this round's candidates that were free of what was placed
        # before it, ``expect`` the number of free candidates the sphere with the fewest attempts
        # left can expect at that rate.
        rate = idx.size / max(sph.size, 1)
        expect = rate * (max_attempts - int(attempts[waiting].max()))
        if n_placed < n and grid is None and not grid_tried and expect < _EXPECT:
            grid_tried = True
            g = _FreeCells(region, rho0, walls)
            if g.usable:
                g.cover(fixed_x, fixed_r)
                g.cover(new_x[:n_new], new_r[:n_new])
                grid = g
        elif n_placed < n and grid is not None and expect < _EXPECT and n_new > split_at:
            if grid.split(np.concatenate([fixed_x, new_x[:n_new]]), np.concatenate([fixed_r, new_r[:n_new]])):
                split_at = n_new

        failed = ~done & (attempts >= max_attempts)
        if failed.any():
            if full:
                why = "no free place is left in it (walls or particles already there may take it all)"
            else:
                r_fail = float(r_sorted[np.nonzero(failed)[0][0]])
                why = f"a sphere of radius {_fmt(r_fail)} m found no free place in {max_attempts} attempts"
            return None, n_placed, why

    x_out = np.empty((n, 3))
    x_out[order] = placed_x
    return x_out, n_placed, None


# --- a rough base --------------------------------------------------------------------------------
ROUGH_BASE_SPACING = 2.2
"""Default centre spacing of ``rough_base``, in radii: gaps of 0.2 R, too narrow for a sphere of the
same size to sink in, wide enough for the default jitter."""


#: ``rough_base``'s parameters (the case file's ``rough_base`` block follows them)
ROUGH_BASE_DECLARED = {
    "radius": Declared("radius of the base's spheres", "m", low=0.0, low_open=True),
    "extent": Declared("((x_min, x_max), (y_min, y_max)): every sphere lies inside it", "m", "extent"),
    "spacing": Declared("distance between neighbouring centres (default 2.2 radius)", "m", low=0.0, low_open=True),
    "jitter": Declared("the largest random shift of a centre in the plane (default half the gap)", "m", low=0.0),
    "seed": Declared("seed of the shifts", kind="whole", low=0),
    "z": Declared("height of the plane the spheres rest on", "m"),
}


def rough_base(radius, extent, spacing=None, jitter=None, seed=0, z=0.0) -> np.ndarray:
    """Centres of a jittered hexagonal layer of spheres resting on the plane at height ``z``: a rough
    base to add with ``sim.add_particles(base, radius, material, fixed=True)``, as the repose studies
    in PFC and LIGGGHTS glue a layer of particles to the floor.

    ``extent`` = ((x_min, x_max), (y_min, y_max)) (m): every sphere lies inside it. Rows of spheres
    ``spacing`` apart (default 2.2 ``radius``), every other row shifted half a spacing; each centre
    moved in the plane by a random vector of length up to ``jitter`` (default: half the gap,
    (spacing - 2 radius) / 2, the most that keeps the spheres apart). Centres at z + radius.
    Reproducible from ``seed``. Returns (N, 3) positions.
    """
    r = check_positive("radius", radius, "m")
    try:
        ext = np.array(extent, dtype=np.float64)
    except (TypeError, ValueError):
        ext = None
    if ext is None or ext.shape != (2, 2) or not np.isfinite(ext).all():
        raise ParameterError(f"extent = {extent!r} is not allowed: must be ((x_min, x_max), (y_min, y_max)) in m")
    a = ROUGH_BASE_SPACING * r if spacing is None else check_positive("spacing", spacing, "m")
    if a < 2.0 * r:
        raise ParameterError(f"spacing = {a:g} is not allowed: must be >= 2 radius = {2 * r:g} m (the spheres "
                             "would overlap)")
    jit = 0.5 * (a - 2.0 * r) if jitter is None else check_non_negative("jitter", jitter, "m")
    if a - 2.0 * jit < 2.0 * r * (1.0 - 1e-12):
        raise ParameterError(f"jitter = {jit:g} is not allowed with spacing = {a:g} m and radius = {r:g} m: must be "
                             f"<= (spacing - 2 radius) / 2 = {0.5 * (a - 2 * r):g} m, or neighbors could overlap")
    z0 = check_finite("z", z)
    for axis, (lo, hi) in zip("xy", ext):
        if hi - lo < 2.0 * (r + jit):
            raise ParameterError(f"extent along {axis} = ({lo:g}, {hi:g}) is not allowed: must be at least "
                                 f"2 (radius + jitter) = {2 * (r + jit):g} m wide to hold one sphere")
    row = a * math.sqrt(3.0) / 2.0
    margin = r + jit
    ys = np.arange(ext[1, 0] + margin, ext[1, 1] - margin + 1e-12 * a, row)
    points = []
    for k, y in enumerate(ys):
        xs = np.arange(ext[0, 0] + margin + (0.5 * a if k % 2 else 0.0), ext[0, 1] - margin + 1e-12 * a, a)
        points.append(np.column_stack([xs, np.full(len(xs), y)]))
    xy = np.concatenate(points) if points else np.zeros((0, 2))
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0.0, 2.0 * math.pi, len(xy))
    length = jit * np.sqrt(rng.uniform(0.0, 1.0, len(xy)))  # uniform over the disk of radius jitter
    xy = xy + np.column_stack([length * np.cos(angle), length * np.sin(angle)])
    return np.column_stack([xy, np.full(len(xy), z0 + r)])
