"""Clump templates: rigid bodies of spheres (multispheres), their mass properties and principal frame.

A ``Clump`` is a set of member spheres (centres and radii, overlapping allowed) that move as one
rigid body. Its mass properties are those of the union of its spheres at a uniform density:

- exactly, where no point lies in three spheres: the union's moments are the spheres' less each
  overlapping pair's lens, a lens being the two spherical caps either side of the pair's circle of
  intersection, each cap's volume, first and second moments integrated in closed form
  (``cap_moments``);
- otherwise by a quadrature: the midpoint rule on a grid over the clump's box
  (``QUADRATURE_CELLS`` cells along its longest side), whose accuracy is stated in
  ``QUADRATURE_ACCURACY`` and tested against the exact answer (tests/scene/test_clumps.py).

The named shapes: a dimer, a trimer, a tetrahedron of four, a ring prism of n touching spheres, a
rod of n.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from rollingdem.errors import ParameterError, check_integer, check_positive, check_vector

#: cells along the longest side of a clump's box for the quadrature of its mass properties
QUADRATURE_CELLS = 200
#: the relative accuracy of that quadrature (volume, centre of mass over the clump's size, each
#: principal moment), as measured on overlapping dimers and trimers against the exact moments
QUADRATURE_ACCURACY = 2e-3
#: how far apart two members may be and still count as touching, as a fraction of the smaller radius
TOUCH_TOLERANCE = 1e-9


@dataclass(frozen=True)
class MassProperties:
    """Mass properties of a clump at a density: ``volume`` (m^3), ``mass`` (kg), ``centre`` of mass
    (m, in the template's frame), ``inertia`` (3x3 tensor about the centre of mass, kg m^2),
    ``principal_moments`` (ascending, kg m^2) and ``principal_axes`` (columns, a right-handed frame),
    and whether they are ``exact`` (else the quadrature's, to ``QUADRATURE_ACCURACY``)."""

    volume: float
    mass: float
    centre: np.ndarray
    inertia: np.ndarray
    principal_moments: np.ndarray
    principal_axes: np.ndarray
    exact: bool


def cap_moments(radius: float, height: float) -> tuple[float, float, float, float]:
    """A spherical cap of ``height`` h cut from a sphere of ``radius`` R, measured from the sphere's
    centre along the cap's axis z (the cap spans R - h <= z <= R): its volume, first moment along z,
    second moment along z (the integral of z^2 dV) and across it (the integral of x^2 dV, equal for
    y). Each is the integral over z of a disk of area pi (R^2 - z^2): dV = pi (R^2 - z^2) dz, and a
    disk's integral of x^2 is pi rho^4 / 4."""
    r2 = radius * radius
    lo = radius - height
    volume = np.polynomial.Polynomial([math.pi * r2, 0.0, -math.pi])          # pi (R^2 - z^2)
    first = volume * np.polynomial.Polynomial([0.0, 1.0])                     # z dV
    along = first * np.polynomial.Polynomial([0.0, 1.0])                      # z^2 dV
    across = np.polynomial.Polynomial([r2, 0.0, -1.0]) ** 2 * (math.pi / 4.0)  # pi (R^2 - z^2)^2 / 4

    def integral(p):
        q = p.integ()
        return float(q(radius) - q(lo))

    return integral(volume), integral(first), integral(along), integral(across)


def _moments_of_cap(centre, axis, radius, height):
    """(V, first moment vector, second moment tensor about the origin) of a cap of the sphere at
    ``centre`` facing along the unit ``axis``."""
    v, m1, szz, sxx = cap_moments(radius, height)
    e = np.asarray(axis, float)
    c = np.asarray(centre, float)
    first_local = m1 * e
    local = szz * np.outer(e, e) + sxx * (np.eye(3) - np.outer(e, e))
    second = local + np.outer(c, first_local) + np.outer(first_local, c) + v * np.outer(c, c)
    return v, v * c + first_local, second


def _moments_of_sphere(centre, radius):
    v = 4.0 / 3.0 * math.pi * radius ** 3
    c = np.asarray(centre, float)
    return v, v * c, v * (radius ** 2 / 5.0 * np.eye(3) + np.outer(c, c))


class Clump:
    """A rigid body of member spheres: ``centres`` (k, 3) and ``radii`` (k,) in m, in the template's
    own frame. Members must overlap or touch, so that the clump is one body (``connected=False``
    accepts apart ones). ``mass_properties(density)`` gives its volume, mass, centre of mass, inertia
    tensor and principal frame."""

    def __init__(self, centres, radii, name: str | None = None, connected: bool = True):
        try:
            x = np.array(centres, dtype=float, ndmin=2)
            r = np.array(radii, dtype=float, ndmin=1)
        except (TypeError, ValueError):
            raise ParameterError(f"clump centres = {centres!r}, radii = {radii!r} is not allowed: must be numbers")
        if x.size == 0:
            raise ParameterError("clump centres = [] is not allowed: a clump needs at least one sphere")
        if x.ndim != 2 or x.shape[1] != 3:
            raise ParameterError(f"clump centres with shape {x.shape} are not allowed: need (k, 3)")
        if r.size == 1 and len(x) > 1:
            r = np.full(len(x), float(r[0]))
        if r.shape != (len(x),):
            raise ParameterError(f"clump radii with {r.size} values are not allowed: need one per centre ({len(x)})")
        if not (np.isfinite(x).all() and np.isfinite(r).all()):
            raise ParameterError("clump centres / radii hold a non-finite value: must be finite")
        bad = np.flatnonzero(r <= 0.0)
        if len(bad):
            raise ParameterError(f"clump radii[{int(bad[0])}] = {r[bad[0]]:g} is not allowed: must be > 0 (m)")
        self.centres, self.radii, self.name = x, r, name
        if connected and not self.is_connected():
            raise ParameterError(f"clump {name or ''!r}: its members do not all overlap or touch (it would be "
                                 "several bodies); pass connected=False to accept it".replace("clump '': ", "clump: "))

    # --- the named shapes -----------------------------------------------------------------------
    @classmethod
    def dimer(cls, radius, distance=None) -> "Clump":
        """Two spheres of ``radius`` whose centres are ``distance`` apart along x (default 2 R: touching)."""
        r = check_positive("dimer radius", radius, "m")
        d = 2.0 * r if distance is None else check_positive("dimer distance", distance, "m")
        return cls([[-d / 2, 0, 0], [d / 2, 0, 0]], [r, r], name="dimer")

    @classmethod
    def trimer(cls, radius, distance=None) -> "Clump":
        """Three spheres at the corners of an equilateral triangle of side ``distance`` (default 2 R)
        in the xy plane."""
        r = check_positive("trimer radius", radius, "m")
        d = 2.0 * r if distance is None else check_positive("trimer distance", distance, "m")
        return cls.ring_prism(3, r, distance=d, name="trimer")

    @classmethod
    def tetrahedron(cls, radius, distance=None) -> "Clump":
        """Four spheres at the corners of a regular tetrahedron of edge ``distance`` (default 2 R)."""
        r = check_positive("tetrahedron radius", radius, "m")
        d = 2.0 * r if distance is None else check_positive("tetrahedron distance", distance, "m")
        corners = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float) * d / (2.0 * math.sqrt(2.0))
        return cls(corners, np.full(4, r), name="tetrahedron")

    @classmethod
    def ring_prism(cls, n, radius, distance=None, name=None) -> "Clump":
        """``n`` spheres around the z axis, neighbours ``distance`` apart (default 2 R: touching): their
        centres on a circle of radius distance / (2 sin(pi / n)) in the xy plane (a prism of n sides
        rolls about its axis on a slope)."""
        n = check_integer("ring_prism n", n, low=3)
        r = check_positive("ring_prism radius", radius, "m")
        d = 2.0 * r if distance is None else check_positive("ring_prism distance", distance, "m")
        a = d / (2.0 * math.sin(math.pi / n))
        phi = 2.0 * math.pi * np.arange(n) / n
        return cls(np.column_stack([a * np.cos(phi), a * np.sin(phi), np.zeros(n)]), np.full(n, r),
                   name=name or f"ring prism of {n}")

    @classmethod
    def rod(cls, n, radius, spacing=None) -> "Clump":
        """``n`` spheres in a row along x, centres ``spacing`` apart (default 2 R), centred on the origin."""
        n = check_integer("rod n", n, low=1)
        r = check_positive("rod radius", radius, "m")
        s = 2.0 * r if spacing is None else check_positive("rod spacing", spacing, "m")
        x = (np.arange(n) - (n - 1) / 2.0) * s
        return cls(np.column_stack([x, np.zeros(n), np.zeros(n)]), np.full(n, r), name=f"rod of {n}")

    # --- geometry -------------------------------------------------------------------------------
    def _gaps(self) -> np.ndarray:
        d = np.linalg.norm(self.centres[:, None, :] - self.centres[None, :, :], axis=2)
        return d - (self.radii[:, None] + self.radii[None, :])

    def is_connected(self) -> bool:
        """Whether every member reaches every other through members that overlap or touch."""
        k = len(self.radii)
        touch = self._gaps() <= TOUCH_TOLERANCE * np.minimum(self.radii[:, None], self.radii[None, :])
        seen, todo = {0}, [0]
        while todo:
            i = todo.pop()
            for j in np.flatnonzero(touch[i]):
                if int(j) not in seen:
                    seen.add(int(j))
                    todo.append(int(j))
        return len(seen) == k

    def _overlapping_pairs(self) -> list[tuple[int, int]]:
        """The pairs that overlap by more than rounding: members meant to touch (a lens of depth
        below ``TOUCH_TOLERANCE`` of the smaller radius, of relative volume below 1e-18) do not."""
        gaps = self._gaps()
        small = np.minimum(self.radii[:, None], self.radii[None, :])
        return [(i, j) for i in range(len(self.radii)) for j in range(i + 1, len(self.radii))
                if gaps[i, j] < -TOUCH_TOLERANCE * small[i, j]]

    def _triple_overlap(self, pairs) -> bool:
        """Whether some point may lie in three members (three members overlapping pairwise: a
        conservative test, the exact moments need none)."""
        partners = {}
        for i, j in pairs:
            partners.setdefault(i, set()).add(j)
            partners.setdefault(j, set()).add(i)
        return any(partners.get(j, set()) & partners.get(i, set()) for i, j in pairs)

    # --- mass properties ------------------------------------------------------------------------
    def moments(self, method: str = "auto") -> tuple[float, np.ndarray, np.ndarray, bool]:
        """(volume, first moment vector, second moment tensor about the template's origin, exact) of
        the union of the members: ``method`` 'exact' (refused where three members overlap), 'quadrature',
        or 'auto' (exact where it can be)."""
        if method not in ("auto", "exact", "quadrature"):
            raise ParameterError(f"method = {method!r} is not known: allowed are 'auto', 'exact', 'quadrature'")
        pairs = self._overlapping_pairs()
        triple = self._triple_overlap(pairs)
        if method == "exact" and triple:
            raise ParameterError("method = 'exact' is not allowed for this clump: three of its members overlap "
                                 "one another; use 'quadrature'")
        if method == "quadrature" or (method == "auto" and triple):
            return (*self._quadrature(), False)
        v, m1, m2 = 0.0, np.zeros(3), np.zeros((3, 3))
        for c, r in zip(self.centres, self.radii):
            dv, d1, d2 = _moments_of_sphere(c, r)
            v, m1, m2 = v + dv, m1 + d1, m2 + d2
        for i, j in pairs:  # less each lens: the cap of i beyond the plane of the circle, and of j
            ci, cj, ri, rj = self.centres[i], self.centres[j], self.radii[i], self.radii[j]
            d = float(np.linalg.norm(cj - ci))
            if d <= abs(ri - rj):  # one member inside the other: the smaller one adds nothing
                small = i if ri <= rj else j
                dv, d1, d2 = _moments_of_sphere(self.centres[small], self.radii[small])
                v, m1, m2 = v - dv, m1 - d1, m2 - d2
                continue
            e = (cj - ci) / d
            plane = (d * d + ri * ri - rj * rj) / (2.0 * d)  # the circle's plane, from c_i along e
            for c, r, axis, h in ((ci, ri, e, ri - plane), (cj, rj, -e, rj - (d - plane))):
                dv, d1, d2 = _moments_of_cap(c, axis, r, h)
                v, m1, m2 = v - dv, m1 - d1, m2 - d2
        return v, m1, m2, True

    def _quadrature(self) -> tuple[float, np.ndarray, np.ndarray]:
        """The midpoint rule on ``QUADRATURE_CELLS`` cells along the box's longest side."""
        lo = (self.centres - self.radii[:, None]).min(axis=0)
        hi = (self.centres + self.radii[:, None]).max(axis=0)
        h = float((hi - lo).max()) / QUADRATURE_CELLS
        n = np.maximum(np.ceil((hi - lo) / h).astype(int), 1)
        xs, ys, zs = (lo[k] + (np.arange(n[k]) + 0.5) * h for k in range(3))
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        v, m1, m2 = 0.0, np.zeros(3), np.zeros((3, 3))
        for z in zs:  # a slice at a time: the grid may hold 10^7 points
            p = np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, z)])
            inside = np.zeros(len(p), dtype=bool)
            for c, r in zip(self.centres, self.radii):
                inside |= ((p - c) ** 2).sum(axis=1) <= r * r
            q = p[inside]
            v += len(q)
            m1 += q.sum(axis=0)
            m2 += q.T @ q
        cell = h ** 3
        return v * cell, m1 * cell, m2 * cell

    def mass_properties(self, density: float, method: str = "auto") -> MassProperties:
        """The union's mass properties at ``density`` (kg/m^3); see ``MassProperties``."""
        rho = check_positive("clump density", density, "kg/m^3")
        v, m1, m2, exact = self.moments(method)
        centre = m1 / v
        central = m2 - v * np.outer(centre, centre)  # the second moment about the centre of mass
        inertia = rho * (np.trace(central) * np.eye(3) - central)
        moments, axes = np.linalg.eigh(inertia)
        if np.linalg.det(axes) < 0.0:
            axes[:, 2] = -axes[:, 2]
        return MassProperties(volume=v, mass=rho * v, centre=centre, inertia=inertia, principal_moments=moments,
                              principal_axes=axes, exact=exact)

    @functools.cached_property
    def centre_of_mass(self) -> np.ndarray:
        """The union's centre of mass in the template's frame (m; any uniform density)."""
        return self.mass_properties(1.0).centre

    def reach(self) -> float:
        """The farthest any member's surface lies from the centre of mass (m): how far the body
        reaches as it turns."""
        return float((np.linalg.norm(self.centres - self.centre_of_mass, axis=1) + self.radii).max())

    def placed(self, position, orientation) -> np.ndarray:
        """The members' centres (k, 3) with the centre of mass at ``position`` and the template
        turned by the unit quaternion ``orientation`` (w, x, y, z)."""
        q = np.asarray(orientation, dtype=float)
        q = q / np.linalg.norm(q)
        w, v = q[0], q[1:]
        offsets = self.centres - self.centre_of_mass
        t = 2.0 * np.cross(v, offsets)  # q r q* = r + w t + v x t
        return np.asarray(position, dtype=float) + offsets + w * t + np.cross(v, t)

    def __repr__(self) -> str:
        return f"Clump({self.name or 'custom'}, {len(self.radii)} spheres)"


def random_orientations(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` unit quaternions (w, x, y, z) uniform over the rotations (Shoemake, Graphics Gems III,
    1992: from three uniform numbers u, q = (sqrt(1-u1) sin 2pi u2, sqrt(1-u1) cos 2pi u2,
    sqrt(u1) sin 2pi u3, sqrt(u1) cos 2pi u3)), for clumps inserted at random orientation."""
    u1, u2, u3 = rng.random((3, int(n)))
    a, b = np.sqrt(1.0 - u1), np.sqrt(u1)
    return np.column_stack([b * np.cos(2 * math.pi * u3), a * np.sin(2 * math.pi * u2),
                            a * np.cos(2 * math.pi * u2), b * np.sin(2 * math.pi * u3)])


def onset_angle(clump: Clump, rotation=None, downhill=(1.0, 0.0, 0.0)) -> float:
    """The tilt (rad) of a plane at which ``clump``, resting on it, starts to tip over downhill, with
    friction enough that nothing slides: the clump turned by ``rotation`` (a 3x3 matrix, default
    none) rests on its lowest members on the plane z = 0; tilted by theta towards ``downhill`` (a
    horizontal direction), it tips once gravity's line through the centre of mass leaves its
    support, the convex hull of the points it stands on (each member's lowest point): tan theta =
    t / c_z, t how far the centre's footprint goes downhill before it crosses the hull's boundary,
    c_z the centre's height (the statics of a rigid body on a slope). A clump standing on one point,
    or on a line across the slope, tips at once (0). A pose whose centre of mass is not over its
    support is refused: it does not rest."""
    from scipy.spatial import ConvexHull  # deferred: slow to load, used here only

    turn = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
    if turn.shape != (3, 3) or not np.allclose(turn @ turn.T, np.eye(3), atol=1e-9):
        raise ParameterError(f"rotation = {rotation!r} is not allowed: must be a 3x3 rotation matrix")
    e = np.array(check_vector("downhill", downhill, unit=True))
    if abs(e[2]) > 1e-12:
        raise ParameterError(f"downhill = {list(e)} is not allowed: must be horizontal (no z component)")
    centres = clump.centres @ turn.T
    bottoms = centres[:, 2] - clump.radii
    floor = float(bottoms.min())
    size = float(np.ptp(centres, axis=0).max() + 2.0 * clump.radii.max())
    tol = 1e-9 * size
    support = centres[bottoms <= floor + tol][:, :2] - (clump.centre_of_mass @ turn.T)[:2]  # from the footprint
    height = float((clump.centre_of_mass @ turn.T)[2]) - floor
    e2 = e[:2]
    refuse = ParameterError(f"clump {clump.name or ''}: it does not rest in this orientation (its centre of mass "
                            "lies outside the members it stands on): turn it so that it rests")
    spread = support - support.mean(axis=0)
    _, sv, vt = np.linalg.svd(spread) if len(support) > 1 else (None, np.zeros(2), np.eye(2))
    if sv[0] <= tol:  # one point
        if np.linalg.norm(support.mean(axis=0)) > tol:
            raise refuse
        return 0.0
    if len(sv) < 2 or sv[1] <= tol * math.sqrt(len(support)):  # a line of support
        u = vt[0]
        along, across = support @ u, support @ np.array([-u[1], u[0]])
        if np.abs(across).max() > tol or not along.min() - tol <= 0.0 <= along.max() + tol:
            raise refuse
        if abs(float(e2 @ np.array([-u[1], u[0]]))) > 1e-12:
            return 0.0  # across the slope: it tips at once
        reach = along.max() if e2 @ u > 0 else -along.min()
        return math.atan2(max(float(reach), 0.0), height)
    hull = ConvexHull(support)
    # each facet: outward normal n and offset b, n . p + b <= 0 inside; the footprint is at 0
    normals, offsets = hull.equations[:, :2], hull.equations[:, 2]
    if (offsets > tol).any():
        raise refuse
    going = normals @ e2
    reach = np.min(-offsets[going > 1e-12] / going[going > 1e-12])
    return math.atan2(max(float(reach), 0.0), height)


def equivalent_rolling_friction(clump: Clump, rotation=None, downhill=(1.0, 0.0, 0.0)) -> float:
    """The rolling friction coefficient at which a sphere starts to roll on the slope at which
    ``clump`` starts to tip (``onset_angle``): mu_r = tan(theta), for the rolling models whose limit
    moment on a wall is mu_r R F_n (EPSD, CDT; a sphere on a slope rolls once m g sin(theta) R
    exceeds mu_r R m g cos(theta), docs/models.md §13, case 0)."""
    return math.tan(onset_angle(clump, rotation, downhill))


def resting_rotations(clump: Clump) -> list[np.ndarray]:
    """The rotations (3x3) that stand ``clump`` on each of its faces: each plane tangent to three
    members with every member on one side (a facet of the members' convex hull), n . c_m + r_m = h
    for the three, turned so that its outward normal n points down. Members in a line or fewer
    than three have none."""
    from scipy.spatial.transform import Rotation  # deferred: slow to load, used here only

    c, r = clump.centres, clump.radii
    size = float(np.ptp(c, axis=0).max() + 2.0 * r.max())
    found = []
    for i, j, k in combinations(range(len(r)), 3):
        a, b = c[j] - c[i], c[k] - c[i]
        normal = np.cross(a, b)
        if np.linalg.norm(normal) <= 1e-12 * size * size:
            continue
        gram = np.array([[a @ a, a @ b], [a @ b, b @ b]])
        x, y = np.linalg.solve(gram, [r[i] - r[j], r[i] - r[k]])  # n . a = r_i - r_j, n . b = r_i - r_k
        p = x * a + y * b
        if p @ p > 1.0:
            continue
        for sign in (1.0, -1.0):
            n = p + sign * math.sqrt(1.0 - p @ p) * normal / np.linalg.norm(normal)
            h = n @ c[i] + r[i]
            if (c @ n + r <= h + 1e-9 * size).all() and not any(np.allclose(n, m, atol=1e-9) for m, _ in found):
                turn, _ = Rotation.align_vectors([[0.0, 0.0, -1.0]], [n])
                found.append((n, turn.as_matrix()))
    return [turn for _, turn in found]


def stand_in_rolling_friction(clump: Clump, azimuths: int = 360) -> float:
    """The rolling friction of the sphere that stands in for ``clump`` lying at random on a slope:
    the mean over ``azimuths`` downhill directions of tan theta (``onset_angle``) on the face it
    rests on most stably (of ``resting_rotations``, the one with the largest mean; a clump with no
    face, a dimer or a rod, rolls across its line at once: 0). What a sphere of that mu_r does on a
    slope, the clump does on average over the directions it may face."""
    best = 0.0
    phi = 2.0 * math.pi * np.arange(int(azimuths)) / int(azimuths)
    for turn in resting_rotations(clump):
        try:
            tans = [math.tan(onset_angle(clump, turn, (math.cos(f), math.sin(f), 0.0))) for f in phi]
        except ParameterError:  # its centre of mass is not over that face: it does not rest there
            continue
        best = max(best, float(np.mean(tans)))
    return best

