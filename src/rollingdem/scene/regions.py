"""Where spheres go: regions of space (a box, a cylinder, a prism behind a face) and the faces an
inflow enters through (a disk, a rectangle, a mesh's triangles).

    sim.insert(CylinderRegion(0.05, 0.0, 0.2), 500, 0.005, "glass", seed=3)

Each region draws uniform points inside itself and tells whether a point lies within; random
insertion into them: ``rollingdem.scene.insertion``."""

from __future__ import annotations

import math

import numpy as np

from rollingdem.errors import Declared, ParameterError, check_finite, check_positive, check_vector


def _fmt(x: float) -> str:
    return f"{x:g}"


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

    declared = {"lo": Declared("the corner of smallest x, y, z", "m", "vector"),
                "hi": Declared("the corner of largest x, y, z", "m", "vector")}

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

    declared = {"radius": Declared("radius", "m", low=0.0, low_open=True),
                "z_min": Declared("bottom", "m"), "z_max": Declared("top", "m"),
                "center": Declared("(x, y) of the axis", "m", "pair")}

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

    declared = {"center": Declared("centre of the disk", "m", "vector"),
                "normal": Declared("direction the particles go in (made unit length)", "-", "vector"),
                "radius": Declared("radius of the disk", "m", low=0.0, low_open=True)}

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

    declared = {"center": Declared("centre of the rectangle", "m", "vector"),
                "normal": Declared("direction the particles go in (made unit length)", "-", "vector"),
                "size": Declared("(width, height)", "m", "pair"),
                "axis": Declared("direction of the width, projected into the face (default the coordinate axis "
                                 "least along the normal)", "-", "vector")}

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
