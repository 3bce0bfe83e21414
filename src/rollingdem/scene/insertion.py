"""Random insertion of non-overlapping spheres into a region.

    from rollingdem.scene.insertion import CylinderRegion, Uniform
    sim.insert(CylinderRegion(0.05, 0.0, 0.2), 500, Uniform(0.004, 0.005), "glass", seed=3)

Random sequential addition, reproducible from ``seed``; how, and how densely: docs/studies.md."""

from __future__ import annotations

import math

import numpy as np

from rollingdem.errors import ParameterError, check_finite, check_non_negative, check_positive, check_vector
from rollingdem.physics.records import WALL_PLANE

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


# --- regions -------------------------------------------------------------------------------------
class Region:
    """Base class of insertion regions; see ``BoxRegion`` and ``CylinderRegion``."""

    def volume(self) -> float:
        raise NotImplementedError

    def fits(self, r: float) -> bool:
        """Whether a sphere of radius ``r`` fits inside at all."""
        raise NotImplementedError

    def sample(self, rng: np.random.Generator, r: np.ndarray) -> np.ndarray:
        """One random centre per radius in ``r``, uniform over where that sphere lies wholly inside."""
        raise NotImplementedError

    def contains(self, x: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Whether each sphere (centre ``x``, radius ``r``) lies wholly inside."""
        raise NotImplementedError

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounding box (lo, hi)."""
        raise NotImplementedError


class BoxRegion(Region):
    """Axis-aligned box from corner ``lo`` to corner ``hi`` (m)."""

    def __init__(self, lo, hi):
        self.lo = np.array(check_vector("BoxRegion lo", lo))
        self.hi = np.array(check_vector("BoxRegion hi", hi))
        if not (self.lo < self.hi).all():
            raise ParameterError(f"BoxRegion lo = {self.lo.tolist()}, hi = {self.hi.tolist()} are not allowed: "
                                 "need lo < hi in every component")

    def volume(self) -> float:
        return float(np.prod(self.hi - self.lo))

    def fits(self, r: float) -> bool:
        return bool(2.0 * r <= float((self.hi - self.lo).min()))

    def sample(self, rng, r):
        r = np.asarray(r)[:, None]
        u = rng.random((r.shape[0], 3))
        return self.lo + r + u * (self.hi - self.lo - 2.0 * r)

    def contains(self, x, r):
        r = np.asarray(r)[:, None]
        return ((x - r >= self.lo) & (x + r <= self.hi)).all(axis=1)

    def bounds(self):
        return self.lo.copy(), self.hi.copy()

    def __repr__(self) -> str:
        return f"BoxRegion(lo={self.lo.tolist()}, hi={self.hi.tolist()})"


class CylinderRegion(Region):
    """Vertical cylinder (axis along z) of ``radius`` (m) about (center[0], center[1]), from z_min to z_max."""

    def __init__(self, radius, z_min, z_max, center=(0.0, 0.0)):
        self.radius = check_positive("CylinderRegion radius", radius, "m")
        self.z_min = check_finite("CylinderRegion z_min", z_min)
        self.z_max = check_finite("CylinderRegion z_max", z_max)
        if not self.z_min < self.z_max:
            raise ParameterError(f"CylinderRegion z_min = {_fmt(self.z_min)}, z_max = {_fmt(self.z_max)} are not "
                                 "allowed: need z_min < z_max")
        try:
            c = [float(v) for v in center]
        except (TypeError, ValueError):
            raise ParameterError(f"CylinderRegion center = {center!r} is not allowed: must be two numbers") from None
        if len(c) != 2 or not all(math.isfinite(v) for v in c):
            raise ParameterError(f"CylinderRegion center = {center!r} is not allowed: must be two finite numbers")
        self.center = (c[0], c[1])

    def volume(self) -> float:
        return math.pi * self.radius ** 2 * (self.z_max - self.z_min)

    def fits(self, r: float) -> bool:
        return bool(r <= self.radius and 2.0 * r <= self.z_max - self.z_min)

    def sample(self, rng, r):
        r = np.asarray(r)
        n = r.shape[0]
        u = rng.random((n, 3))
        rho = (self.radius - r) * np.sqrt(u[:, 0])
        phi = 2.0 * math.pi * u[:, 1]
        x = np.empty((n, 3))
        x[:, 0] = self.center[0] + rho * np.cos(phi)
        x[:, 1] = self.center[1] + rho * np.sin(phi)
        x[:, 2] = self.z_min + r + u[:, 2] * (self.z_max - self.z_min - 2.0 * r)
        return x

    def contains(self, x, r):
        r = np.asarray(r)
        rho = np.hypot(x[:, 0] - self.center[0], x[:, 1] - self.center[1])
        return (rho + r <= self.radius) & (x[:, 2] - r >= self.z_min) & (x[:, 2] + r <= self.z_max)

    def bounds(self):
        cx, cy = self.center
        R = self.radius
        return np.array([cx - R, cy - R, self.z_min]), np.array([cx + R, cy + R, self.z_max])

    def __repr__(self) -> str:
        return (f"CylinderRegion(radius={_fmt(self.radius)}, z_min={_fmt(self.z_min)}, z_max={_fmt(self.z_max)}, "
                f"center=({_fmt(self.center[0])}, {_fmt(self.center[1])}))")


# --- size distributions --------------------------------------------------------------------------
def _frame(normal, axis=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A right-handed frame (e1, e2, n) for a face of unit ``normal``; e1 along ``axis`` projected
    into the face (default the coordinate axis least along n)."""
    n = np.asarray(normal, dtype=float)
    a = np.eye(3)[int(np.argmin(np.abs(n)))] if axis is None else np.asarray(axis, dtype=float)
    e1 = a - (a @ n) * n
    length = float(np.linalg.norm(e1))
    if length < 1e-9:
        raise ParameterError(f"face axis = {list(a)} is not allowed: it lies along the normal {list(n)}; must lie in "
                             "the face")
    e1 = e1 / length
    return e1, np.cross(n, e1), n


class Face:
    """A flat face particles enter through (``Disk``, ``Rectangle``, ``MeshFace``), its ``normal``
    the way they go: LIGGGHTS ``insert/stream``, EDEM's factory on a surface. An inflow through it
    places each sphere wholly behind the face, within ``depth`` of it (``prism``)."""

    def prism(self, depth: float) -> "FacePrism":
        return FacePrism(self, check_positive("face depth", depth, "m"))


class Disk(Face):
    """A disk of ``radius`` (m) about ``center``, facing along ``normal``."""

    def __init__(self, center, normal, radius):
        self.center = np.array(check_vector("disk center", center))
        self.e1, self.e2, self.normal = _frame(check_vector("disk normal", normal, unit=True))
        self.radius = check_positive("disk radius", radius, "m")
        self.area = math.pi * self.radius ** 2

    def lateral_fits(self, r: float) -> bool:
        return r < self.radius

    def sample_lateral(self, rng, r):
        rho, phi = (self.radius - r) * np.sqrt(rng.random(len(r))), 2.0 * math.pi * rng.random(len(r))
        return np.column_stack([rho * np.cos(phi), rho * np.sin(phi)])

    def lateral_inside(self, uv, r):
        return np.hypot(uv[:, 0], uv[:, 1]) <= self.radius - r

    def outline(self) -> np.ndarray:
        phi = 2.0 * math.pi * np.arange(64) / 64
        return self.center + self.radius / math.cos(math.pi / 64) * (np.outer(np.cos(phi), self.e1)
                                                                      + np.outer(np.sin(phi), self.e2))

    def to_dict(self) -> dict:
        return {"type": "disk", "center": self.center.tolist(), "normal": self.normal.tolist(), "radius": self.radius}

    def __repr__(self) -> str:
        return f"Disk(center={self.center.tolist()}, normal={self.normal.tolist()}, radius={_fmt(self.radius)})"


class Rectangle(Face):
    """A rectangle of ``size`` (width, height; m) about ``center``, facing along ``normal``, its width
    along ``axis`` (projected into it; default the coordinate axis least along the normal)."""

    def __init__(self, center, normal, size, axis=None):
        self.center = np.array(check_vector("rectangle center", center))
        self.e1, self.e2, self.normal = _frame(check_vector("rectangle normal", normal, unit=True),
                                               None if axis is None else check_vector("rectangle axis", axis))
        try:
            w, h = (float(v) for v in size)
        except (TypeError, ValueError):
            raise ParameterError(f"rectangle size = {size!r} is not allowed: must be (width, height) in m") from None
        self.size = (check_positive("rectangle width", w, "m"), check_positive("rectangle height", h, "m"))
        self.area = w * h

    def lateral_fits(self, r: float) -> bool:
        return 2.0 * r < min(self.size)

    def sample_lateral(self, rng, r):
        half = 0.5 * np.array(self.size)[None, :] - r[:, None]
        return (2.0 * rng.random((len(r), 2)) - 1.0) * half

    def lateral_inside(self, uv, r):
        return (np.abs(uv) <= 0.5 * np.array(self.size)[None, :] - r[:, None]).all(axis=1)

    def outline(self) -> np.ndarray:
        w, h = 0.5 * self.size[0], 0.5 * self.size[1]
        return np.array([self.center + a * w * self.e1 + b * h * self.e2 for a in (-1, 1) for b in (-1, 1)])

    def to_dict(self) -> dict:
        return {"type": "rectangle", "center": self.center.tolist(), "normal": self.normal.tolist(),
                "size": list(self.size), "axis": self.e1.tolist()}

    def __repr__(self) -> str:
        return (f"Rectangle(center={self.center.tolist()}, normal={self.normal.tolist()}, "
                f"size=({_fmt(self.size[0])}, {_fmt(self.size[1])}))")


class MeshFace(Face):
    """A flat triangle mesh (``TriangleMesh``, or a mesh wall's) as a face: every triangle in one plane
    (within 1e-6 of the mesh's size); ``normal`` (default its triangles' own) chooses the side the
    particles go to. A sphere's centre lies over the triangles (the sphere may overhang the rim)."""

    def __init__(self, mesh, normal=None):
        mesh = getattr(mesh, "mesh", mesh)
        v, t = np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.triangles)
        cross = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
        areas = 0.5 * np.linalg.norm(cross, axis=1)
        own = cross.sum(axis=0)
        if not len(t) or np.linalg.norm(own) == 0.0:
            raise ParameterError(f"{mesh.label}: a face must be a flat mesh of some area")
        own = own / np.linalg.norm(own)
        size = float(np.ptp(v, axis=0).max())
        off = float(np.abs((v - v[0]) @ own).max())
        if off > 1e-6 * size:
            raise ParameterError(f"{mesh.label}: a face must be flat, but a vertex lies {off:.3g} m off its plane")
        n = own if normal is None else np.array(check_vector("mesh face normal", normal, unit=True))
        if abs(abs(n @ own) - 1.0) > 1e-9:
            raise ParameterError(f"mesh face normal = {list(n)} is not allowed: must be normal to the face, "
                                 f"{list(own)} or its opposite")
        self.mesh, self.label = mesh, mesh.label
        self.center = (areas[:, None] * v[t].mean(axis=1)).sum(axis=0) / areas.sum()
        self.e1, self.e2, self.normal = _frame(n)
        self.corners = np.stack([(v[t[:, k]] - self.center) @ np.column_stack([self.e1, self.e2]) for k in range(3)],
                                axis=1)  # (triangles, 3, 2) in the face's frame
        self.areas, self.area = areas, float(areas.sum())

    def lateral_fits(self, r: float) -> bool:
        return True

    def sample_lateral(self, rng, r):
        k = rng.choice(len(self.areas), size=len(r), p=self.areas / self.area)
        a, b = rng.random(len(r)), rng.random(len(r))
        flip = a + b > 1.0
        a[flip], b[flip] = 1.0 - a[flip], 1.0 - b[flip]
        c = self.corners[k]
        return c[:, 0] + a[:, None] * (c[:, 1] - c[:, 0]) + b[:, None] * (c[:, 2] - c[:, 0])

    def lateral_inside(self, uv, r):
        c = self.corners
        inside = np.zeros(len(uv), dtype=bool)
        for k in range(len(c)):
            d = [(c[k, (e + 1) % 3, 0] - c[k, e, 0]) * (uv[:, 1] - c[k, e, 1])
                 - (c[k, (e + 1) % 3, 1] - c[k, e, 1]) * (uv[:, 0] - c[k, e, 0]) for e in range(3)]
            inside |= ((d[0] >= 0) & (d[1] >= 0) & (d[2] >= 0)) | ((d[0] <= 0) & (d[1] <= 0) & (d[2] <= 0))
        return inside

    def outline(self) -> np.ndarray:
        return np.asarray(self.mesh.vertices, dtype=float)

    def to_dict(self) -> dict:
        return {"type": "mesh_face", "vertices": np.asarray(self.mesh.vertices).tolist(),
                "triangles": np.asarray(self.mesh.triangles).tolist(), "normal": self.normal.tolist(),
                "label": self.label}

    def __repr__(self) -> str:
        return f"MeshFace({self.label}, {len(self.areas)} triangles, normal={self.normal.tolist()})"


class FacePrism(Region):
    """Where an inflow through a ``Face`` places its spheres: over the face and behind it (against its
    normal) by up to ``depth`` (m), each sphere wholly so."""

    def __init__(self, face: Face, depth: float):
        self.face, self.depth = face, depth

    def volume(self) -> float:
        return self.face.area * self.depth

    def fits(self, r: float) -> bool:
        return self.face.lateral_fits(r) and 2.0 * r <= self.depth

    def sample(self, rng, r):
        r = np.asarray(r, dtype=float).reshape(-1)
        f = self.face
        uv = f.sample_lateral(rng, r)
        behind = r + rng.random(len(r)) * np.maximum(self.depth - 2.0 * r, 0.0)
        return f.center + uv[:, :1] * f.e1 + uv[:, 1:] * f.e2 - behind[:, None] * f.normal

    def contains(self, x, r):
        x = np.asarray(x, dtype=float).reshape(-1, 3)
        r = np.broadcast_to(np.asarray(r, dtype=float), (len(x),))
        f = self.face
        d = x - f.center
        behind = -(d @ f.normal)
        return (behind >= r) & (behind <= self.depth - r) & f.lateral_inside(np.column_stack([d @ f.e1, d @ f.e2]), r)

    def bounds(self):
        corners = np.vstack([self.face.outline(), self.face.outline() - self.depth * self.face.normal])
        return corners.min(axis=0), corners.max(axis=0)

    def to_dict(self) -> dict:
        return {"type": "face", "face": self.face.to_dict(), "depth": self.depth}

    def __repr__(self) -> str:
        return f"{self.face!r} (placing within {_fmt(self.depth)} m behind it)"


class SizeDistribution:
    """Base class of radius distributions; ``sample(rng, n)`` gives n radii (m)."""

    max_radius: float
    min_radius: float

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        raise NotImplementedError


class Constant(SizeDistribution):
    """All spheres of the same ``radius`` (m); what a plain number means."""

    def __init__(self, radius):
        self.radius = check_positive("radius", radius, "m")
        self.max_radius = self.min_radius = self.radius

    def sample(self, rng, n):
        return np.full(int(n), self.radius)

    def __repr__(self) -> str:
        return f"Constant({_fmt(self.radius)})"


class Uniform(SizeDistribution):
    """Radius uniform in [low, high] (m)."""

    def __init__(self, low, high):
        self.low = check_positive("Uniform low", low, "m")
        self.high = check_positive("Uniform high", high, "m")
        if self.low > self.high:
            raise ParameterError(f"Uniform low = {_fmt(self.low)} is not allowed: must be <= high "
                                 f"= {_fmt(self.high)} (m)")
        self.max_radius = self.high
        self.min_radius = self.low

    def sample(self, rng, n):
        return rng.uniform(self.low, self.high, int(n))

    def __repr__(self) -> str:
        return f"Uniform({_fmt(self.low)}, {_fmt(self.high)})"


class Normal(SizeDistribution):
    """Normal radius distribution (m) truncated to [low, high] by resampling.

    ``low`` defaults to max(mean - 3 std, 0) and ``high`` to mean + 3 std; radii are always > 0.
    """

    def __init__(self, mean, std, low=None, high=None):
        self.mean = check_positive("Normal mean", mean, "m")
        self.std = check_non_negative("Normal std", std, "m")
        self.low = (max(self.mean - 3.0 * self.std, 0.0) if low is None
                    else check_positive("Normal low", low, "m"))
        self.high = self.mean + 3.0 * self.std if high is None else check_positive("Normal high", high, "m")
        if self.low > self.high:
            raise ParameterError(f"Normal low = {_fmt(self.low)} is not allowed: must be <= high "
                                 f"= {_fmt(self.high)} (m)")
        if self.std == 0.0:
            if not self.low <= self.mean <= self.high:
                raise ParameterError(f"Normal mean = {_fmt(self.mean)} with std = 0 is not allowed: must lie in "
                                     f"[low, high] = [{_fmt(self.low)}, {_fmt(self.high)}] (m)")
            self._p = 1.0
        else:
            a = (self.low - self.mean) / (self.std * math.sqrt(2.0))
            b = (self.high - self.mean) / (self.std * math.sqrt(2.0))
            self._p = 0.5 * (math.erf(b) - math.erf(a))
            if self._p < 1e-4:
                raise ParameterError(f"Normal [low, high] = [{_fmt(self.low)}, {_fmt(self.high)}] is not allowed: it "
                                     f"lies too far in the tail of mean = {_fmt(self.mean)}, std = {_fmt(self.std)} "
                                     f"(probability {self._p:.2g} < 1e-4)")
        self.max_radius = self.high
        self.min_radius = self.low

    def sample(self, rng, n):
        n = int(n)
        if self.std == 0.0:
            return np.full(n, self.mean)
        out = np.empty(0)
        while out.size < n:
            need = n - out.size
            draw = rng.normal(self.mean, self.std, int(need / self._p * 1.1) + 16)
            keep = draw[(draw >= self.low) & (draw <= self.high) & (draw > 0.0)]
            out = np.concatenate([out, keep[:need]])
        return out

    def __repr__(self) -> str:
        return f"Normal({_fmt(self.mean)}, {_fmt(self.std)}, low={_fmt(self.low)}, high={_fmt(self.high)})"


class Discrete(SizeDistribution):
    """Radii drawn from ``values`` (m) with relative ``weights`` (default: equal)."""

    def __init__(self, values, weights=None):
        try:
            vals = [float(v) for v in values]
        except (TypeError, ValueError):
            raise ParameterError(f"Discrete values = {values!r} is not allowed: must be a sequence of radii") from None
        if not vals:
            raise ParameterError("Discrete values = [] is not allowed: need at least one radius")
        for k, v in enumerate(vals):
            check_positive(f"Discrete values[{k}]", v, "m")
        if weights is None:
            w = [1.0] * len(vals)
        else:
            try:
                w = [float(v) for v in weights]
            except (TypeError, ValueError):
                raise ParameterError(f"Discrete weights = {weights!r} is not allowed: must be numbers") from None
            if len(w) != len(vals):
                raise ParameterError(f"Discrete weights = {weights!r} is not allowed: need one per value "
                                     f"({len(vals)}), got {len(w)}")
            for k, v in enumerate(w):
                check_non_negative(f"Discrete weights[{k}]", v)
            if sum(w) <= 0.0:
                raise ParameterError(f"Discrete weights = {weights!r} is not allowed: must have a positive sum")
        self.values = np.array(vals)
        self.weights = np.array(w) / sum(w)
        self.max_radius = float(self.values[self.weights > 0].max())
        self.min_radius = float(self.values[self.weights > 0].min())

    def sample(self, rng, n):
        return rng.choice(self.values, size=int(n), p=self.weights)

    def __repr__(self) -> str:
        return f"Discrete({self.values.tolist()}, weights={self.weights.tolist()})"


class MassFractions(Discrete):
    """Radii ``radii`` (m) making up the given ``fractions`` of the mass (a bulk solid's size classes):
    each drawn with the number weight f_k / r_k^3 (so N_k m_k is in proportion to f_k). The realised
    mass fractions are ``realised(radii)``."""

    def __init__(self, radii, fractions):
        super().__init__(radii, fractions)
        self.fractions = self.weights.copy()
        number = self.fractions / self.values ** 3
        self.weights = number / number.sum()
        self.classes = [(float(v), float(v)) for v in self.values]

    def class_volumes(self, radii) -> np.ndarray:
        """The volume (m^3) of ``radii``'s spheres of each radius."""
        r = np.asarray(radii, dtype=float)
        return np.array([4.0 / 3.0 * math.pi * np.sum(r[np.isclose(r, v, rtol=1e-12, atol=0.0)] ** 3)
                         for v in self.values])

    def realised(self, radii) -> np.ndarray:
        """The mass fraction of each radius among ``radii`` (equal density)."""
        volume = self.class_volumes(radii)
        return volume / max(float(volume.sum()), 1e-300)

    asked = property(lambda self: self.fractions)

    def __repr__(self) -> str:
        return f"MassFractions({self.values.tolist()}, {self.fractions.tolist()})"


class SieveCurve(SizeDistribution):
    """A grading curve: the mass fraction ``passing`` (0 to 1, not decreasing, from 0 to 1) at each of
    the sieve ``diameters`` (m, increasing), as a sieve analysis gives it. Between two sieves the
    passing fraction is taken linear in the diameter: a constant mass per unit of diameter, so a
    number density c / d^3, drawn by inverting its distribution; the class takes the number share
    (P_k+1 - P_k) / (d_k+1 - d_k) (d_k^-2 - d_k+1^-2) / 2 (up to a common factor), which gives it
    the mass share P_k+1 - P_k. ``realised(radii)``: the mass fraction in each class."""

    def __init__(self, diameters, passing):
        try:
            d = np.asarray(diameters, dtype=float).reshape(-1)
            p = np.asarray(passing, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise ParameterError(f"SieveCurve diameters = {diameters!r}, passing = {passing!r} is not allowed: must "
                                 "be numbers") from None
        if len(d) < 2 or len(p) != len(d):
            raise ParameterError(f"SieveCurve passing = {p.tolist()} is not allowed: need one per diameter "
                                 f"({len(d)}), and at least two")
        if not (np.all(np.isfinite(d)) and d[0] > 0.0 and np.all(np.diff(d) > 0.0)):
            raise ParameterError(f"SieveCurve diameters = {d.tolist()} is not allowed: must be > 0 (m) and increasing")
        if not (np.all(np.isfinite(p)) and np.all(np.diff(p) >= 0.0) and p[0] == 0.0 and p[-1] == 1.0):
            raise ParameterError(f"SieveCurve passing = {p.tolist()} is not allowed: the fraction of the mass passing "
                                 "each sieve must not decrease, from 0 at the first to 1 at the last")
        self.diameters, self.passing = d, p
        self.mass_shares = np.diff(p)
        inv2 = 1.0 / d ** 2
        number = self.mass_shares / np.diff(d) * 0.5 * (inv2[:-1] - inv2[1:])
        self.number_shares = number / number.sum()
        self.min_radius = 0.5 * float(d[np.argmax(self.mass_shares > 0)])
        self.max_radius = 0.5 * float(d[len(self.mass_shares) - np.argmax(self.mass_shares[::-1] > 0)])
        self.classes = [(0.5 * float(a), 0.5 * float(b)) for a, b in zip(d[:-1], d[1:])]

    def sample(self, rng, n):
        n = int(n)
        k = rng.choice(len(self.number_shares), size=n, p=self.number_shares)
        u = rng.random(n)
        lo2, hi2 = self.diameters[k] ** -2.0, self.diameters[k + 1] ** -2.0
        return 0.5 / np.sqrt(lo2 - u * (lo2 - hi2))  # the inverse of F(d) = (d_k^-2 - d^-2) / (d_k^-2 - d_k+1^-2)

    def class_volumes(self, radii) -> np.ndarray:
        """The volume (m^3) of ``radii``'s spheres in each class between two sieves."""
        d = 2.0 * np.asarray(radii, dtype=float)
        k = np.clip(np.searchsorted(self.diameters, d, side="right") - 1, 0, len(self.mass_shares) - 1)
        return np.bincount(k, weights=math.pi / 6.0 * d ** 3, minlength=len(self.mass_shares))

    def realised(self, radii) -> np.ndarray:
        """The mass fraction of ``radii`` in each class between two sieves (equal density)."""
        volume = self.class_volumes(radii)
        return volume / max(float(volume.sum()), 1e-300)

    asked = property(lambda self: self.mass_shares)

    def __repr__(self) -> str:
        return f"SieveCurve({self.diameters.tolist()}, {self.passing.tolist()})"


class Parcels(SizeDistribution):
    """Coarse-grained parcels of the ``real`` particles' distribution: each radius ``alpha`` times one
    drawn from it, from the same random numbers (docs/models.md §18). A distribution by mass keeps its
    classes: ``realised`` and ``class_volumes`` take parcels' radii and answer for the real ones."""

    def __init__(self, real: SizeDistribution, alpha: float):
        self.real, self.alpha = real, float(alpha)
        self.min_radius, self.max_radius = self.alpha * real.min_radius, self.alpha * real.max_radius

    def sample(self, rng, n):
        return self.alpha * np.asarray(self.real.sample(rng, n), dtype=float)

    def __getattr__(self, name):
        if name in ("realised", "class_volumes"):  # only where the real distribution has them
            of_real = getattr(self.__dict__["real"], name)
            return lambda radii: of_real(np.asarray(radii, dtype=float) / self.alpha)
        if name == "asked":
            return self.__dict__["real"].asked
        raise AttributeError(name)

    def __repr__(self) -> str:
        return f"Parcels({self.real!r}, alpha={self.alpha:g})"


def parcels_of(radius, alpha: float) -> SizeDistribution:
    """The distribution of the spheres placed for ``radius`` (a number or a distribution, the real
    particles') of a material coarse-grained by ``alpha``."""
    real = as_distribution(radius)
    return real if alpha == 1.0 else Parcels(real, alpha)


def realised_line(distribution, radii) -> str:
    """The realised mass fraction of each class beside the one asked for, for a distribution by mass;
    for another, the radii's range and mean."""
    r = np.asarray(radii, dtype=float)
    if not len(r):
        return "no spheres"
    if hasattr(distribution, "realised"):
        return fractions_line(distribution.realised(r), distribution.asked)
    return f"radius {r.min():.4g}-{r.max():.4g} m, mean {r.mean():.4g} m"


def fractions_line(got, asked) -> str:
    return "mass fractions " + " ".join(f"{g:.3f}" for g in got) + " (asked " + " ".join(f"{a:.3f}" for a in asked) + ")"


def as_distribution(radius) -> SizeDistribution:
    """A ``SizeDistribution`` as is; a plain number as ``Constant``."""
    if isinstance(radius, SizeDistribution):
        return radius
    if isinstance(radius, (bool, np.bool_)):
        raise ParameterError(f"radius = {radius!r} is not allowed: must be a number (m) or a size distribution")
    try:
        float(radius)
    except (TypeError, ValueError):
        raise ParameterError(f"radius = {radius!r} is not allowed: must be a number (m) or a size distribution "
                             "(Uniform, Normal, Discrete, MassFractions, SieveCurve)") from None
    return Constant(radius)


# --- filling -------------------------------------------------------------------------------------
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
        from scipy.spatial import cKDTree

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
    from scipy.spatial import cKDTree

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
