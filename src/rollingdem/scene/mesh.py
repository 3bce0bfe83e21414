"""Triangle-mesh walls (STL, OBJ): ``MeshWall``, the checked ``TriangleMesh`` with its edge
topology, ready-made shapes, and the compiled closest point of a triangle to a sphere's centre with
the feature (face, edge, vertex) it lies on and the contacts of a sphere with a mesh, one per
touched surface feature (docs/models.md, "Mesh walls")."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numba import njit

from rollingdem.errors import ParameterError, check_integer, check_positive, check_vector
from rollingdem.engine.layout import WALL_MESH
from rollingdem.scene.walls import Wall

# the feature of a triangle a closest point lies on
FACE = 0
EDGE_AB, EDGE_BC, EDGE_CA = 1, 2, 3
VERTEX_A, VERTEX_B, VERTEX_C = 4, 5, 6
#: relative area below which a triangle is degenerate: |(b - a) x (c - a)| / 2 < this x (longest edge)^2
DEGENERATE_AREA = 1e-10


@njit(cache=True, inline="always")
def closest_point_on_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """(qx, qy, qz, feature): the point of triangle abc closest to p, and the feature it lies on
    (``FACE``, ``EDGE_*``, ``VERTEX_*``). The Voronoi-region test of Ericson, Real-Time Collision
    Detection (2005), sec. 5.1.5: the barycentric coordinates of the projection decide the region,
    with no square root."""
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return ax, ay, az, VERTEX_A
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bx, by, bz, VERTEX_B
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return ax + v * abx, ay + v * aby, az + v * abz, EDGE_AB
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cx, cy, cz, VERTEX_C
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return ax + w * acx, ay + w * acy, az + w * acz, EDGE_CA
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return bx + w * (cx - bx), by + w * (cy - by), bz + w * (cz - bz), EDGE_BC
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    return ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w, FACE


@njit(cache=True)
def closest_points(points, vertices, triangles, out_points, out_features):
    """``closest_point_on_triangle`` of points[k] and triangle triangles[k] (for tests and checks)."""
    for k in range(points.shape[0]):
        a, b, c = triangles[k, 0], triangles[k, 1], triangles[k, 2]
        q = closest_point_on_triangle(points[k, 0], points[k, 1], points[k, 2],
                                      vertices[a, 0], vertices[a, 1], vertices[a, 2],
                                      vertices[b, 0], vertices[b, 1], vertices[b, 2],
                                      vertices[c, 0], vertices[c, 1], vertices[c, 2])
        out_points[k, 0] = q[0]
        out_points[k, 1] = q[1]
        out_points[k, 2] = q[2]
        out_features[k] = q[3]


@njit(cache=True, inline="always")
def _into_triangle(vertices, triangles, u, va, vb, qx, qy, qz, px, py, pz):
    """(p - q) . m, m the direction in triangle u's plane, normal to its edge (va, vb), pointing into
    u; and |p - q| |m|, its scale."""
    w = triangles[u, 0] + triangles[u, 1] + triangles[u, 2] - va - vb  # u's third vertex
    ex, ey, ez = vertices[vb, 0] - vertices[va, 0], vertices[vb, 1] - vertices[va, 1], vertices[vb, 2] - vertices[va, 2]
    wx, wy, wz = vertices[w, 0] - vertices[va, 0], vertices[w, 1] - vertices[va, 1], vertices[w, 2] - vertices[va, 2]
    s = (wx * ex + wy * ey + wz * ez) / (ex * ex + ey * ey + ez * ez)
    mx, my, mz = wx - s * ex, wy - s * ey, wz - s * ez
    dx, dy, dz = px - qx, py - qy, pz - qz
    scale = math.sqrt((dx * dx + dy * dy + dz * dz) * (mx * mx + my * my + mz * mz))
    return dx * mx + dy * my + dz * mz, scale


#: relative tolerance of the feature tests: p counts as in a feature's region up to this much past it
FEATURE_TOLERANCE = 1e-12
#: two contacts whose points are closer than this x the radius are one (found from two triangles)
SAME_POINT = 1e-9


@njit(cache=True)
def touching_features(px, py, pz, radius, vertices, triangles, edge_neighbors, candidates, lo, hi, out_tri,
                      out_feature, out_point):
    """The contacts of a sphere (centre p, ``radius``) with the triangles ``candidates[lo:hi]``: one per
    touched surface feature, not one per triangle. Returns their count c; ``out_tri``, ``out_feature``,
    ``out_point`` hold at lo .. lo + c - 1 each one's triangle, feature and contact point (its normal
    is p - point): a sphere's own rows of the candidate list are its scratch.

    A triangle touches when its closest point q is nearer than ``radius``. A face contact is kept.
    An edge contact is kept when p also lies outside the triangle across that edge, (p - q) . m <= 0
    with m pointing into it in its plane (on a flat or concave edge the sphere is over the
    neighbour's face instead), and once per edge. A vertex contact is kept when p lies outside
    every touching triangle around the vertex, (p - v) . (x - v) <= 0 for each of their edges
    (v, x), and once per vertex. The triangles around a touched edge or vertex are within
    ``radius`` of p, so they are among the touching ones when the candidates hold every triangle
    that near. So a sphere crossing the shared edge of coplanar triangles has one contact with the
    face normal throughout, one on a convex edge or vertex with the normal from it to the centre,
    and one per face in a concave corner (Voronoi regions of the surface's features). Two contacts
    at the same point (within ``SAME_POINT`` R, as when round-off puts a point on a shared edge
    inside both faces) count once."""
    r2 = radius * radius
    nkeep = lo
    for a in range(lo, hi):
        t = candidates[a]
        i0, i1, i2 = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        q = closest_point_on_triangle(px, py, pz, vertices[i0, 0], vertices[i0, 1], vertices[i0, 2],
                                      vertices[i1, 0], vertices[i1, 1], vertices[i1, 2],
                                      vertices[i2, 0], vertices[i2, 1], vertices[i2, 2])
        dx, dy, dz = px - q[0], py - q[1], pz - q[2]
        if dx * dx + dy * dy + dz * dz >= r2:
            continue
        out_tri[nkeep] = t
        out_feature[nkeep] = q[3]
        out_point[nkeep, 0] = q[0]
        out_point[nkeep, 1] = q[1]
        out_point[nkeep, 2] = q[2]
        nkeep += 1
    n = lo
    for a in range(lo, nkeep):
        t, feature = out_tri[a], out_feature[a]
        qx, qy, qz = out_point[a, 0], out_point[a, 1], out_point[a, 2]
        keep = True
        if EDGE_AB <= feature <= EDGE_CA:
            e = feature - EDGE_AB
            va, vb = triangles[t, e], triangles[t, (e + 1) % 3]
            u = edge_neighbors[t, e]
            if u >= 0:
                into, scale = _into_triangle(vertices, triangles, u, va, vb, qx, qy, qz, px, py, pz)
                keep = into <= FEATURE_TOLERANCE * scale
                for b in range(lo, a):  # the same edge, seen from u
                    if out_tri[b] == u and EDGE_AB <= out_feature[b] <= EDGE_CA:
                        f = out_feature[b] - EDGE_AB
                        ua, ub = triangles[u, f], triangles[u, (f + 1) % 3]
                        if (ua == va and ub == vb) or (ua == vb and ub == va):
                            keep = False
        elif feature >= VERTEX_A:
            v = triangles[t, feature - VERTEX_A]
            dx, dy, dz = px - qx, py - qy, pz - qz
            for b in range(lo, nkeep):
                u = out_tri[b]
                for c in range(3):
                    if triangles[u, c] != v:
                        continue
                    if b < a and out_feature[b] == VERTEX_A + c:
                        keep = False  # counted already
                    for x in (triangles[u, (c + 1) % 3], triangles[u, (c + 2) % 3]):
                        ex = vertices[x, 0] - qx
                        ey = vertices[x, 1] - qy
                        ez = vertices[x, 2] - qz
                        scale = math.sqrt((dx * dx + dy * dy + dz * dz) * (ex * ex + ey * ey + ez * ez))
                        if dx * ex + dy * ey + dz * ez > FEATURE_TOLERANCE * scale:
                            keep = False
        for b in range(lo, n):  # the same point from two triangles (a centre over their shared edge,
            # classed as inside both faces by round-off): one contact
            ex, ey, ez = out_point[b, 0] - qx, out_point[b, 1] - qy, out_point[b, 2] - qz
            if ex * ex + ey * ey + ez * ez <= (SAME_POINT * radius) ** 2:
                keep = False
        if keep:
            out_tri[n] = t
            out_feature[n] = feature
            out_point[n, 0] = qx
            out_point[n, 1] = qy
            out_point[n, 2] = qz
            n += 1
    return n - lo


class TriangleMesh:
    """A checked triangle mesh: ``vertices`` (n, 3) in m, ``triangles`` (m, 3) vertex indices.

    Refused with a ``ParameterError`` naming the mesh (``label``: its file, or "mesh") and the
    problem: no triangle, an index out of range, a non-finite vertex, a degenerate triangle (area
    below ``DEGENERATE_AREA`` times its longest edge squared: a needle or repeated vertex), an
    edge shared by more than two triangles (not a manifold surface).
    """

    def __init__(self, vertices, triangles, label: str = "mesh"):
        self.label = label
        try:
            vertices = np.asarray(vertices, dtype=np.float64)
            triangles = np.asarray(triangles)
        except (TypeError, ValueError) as err:
            raise ParameterError(f"{label}: vertices and triangles must be arrays of numbers ({err})") from None
        if vertices.ndim != 2 or vertices.shape[1] != 3:
            raise ParameterError(f"{label}: vertices of shape {vertices.shape} are not allowed: must be (n, 3)")
        if triangles.size == 0:
            raise ParameterError(f"{label}: the mesh has no triangle: a wall needs at least one")
        if triangles.ndim != 2 or triangles.shape[1] != 3 or not np.issubdtype(triangles.dtype, np.integer):
            raise ParameterError(f"{label}: triangles of shape {triangles.shape} ({triangles.dtype}) are not allowed: "
                                 "must be (m, 3) vertex indices")
        if not np.isfinite(vertices).all():
            k = int(np.nonzero(~np.isfinite(vertices).all(axis=1))[0][0])
            raise ParameterError(f"{label}: vertex {k} = {vertices[k].tolist()} is not finite")
        bad = (triangles < 0) | (triangles >= len(vertices))
        if bad.any():
            k = int(np.nonzero(bad.any(axis=1))[0][0])
            raise ParameterError(f"{label}: triangle {k} = {triangles[k].tolist()} names a vertex out of range "
                                 f"(the mesh has {len(vertices)} vertices)")
        self.vertices = vertices
        self.triangles = triangles.astype(np.int64)
        a, b, c = (vertices[self.triangles[:, i]] for i in range(3))
        area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
        longest = np.max([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1),
                          np.linalg.norm(a - c, axis=1)], axis=0)
        degenerate = area <= DEGENERATE_AREA * longest ** 2
        if degenerate.any():
            k = int(np.nonzero(degenerate)[0][0])
            raise ParameterError(f"{label}: triangle {k} (vertices {self.triangles[k].tolist()}) is degenerate: its area "
                                 f"{area[k]:.3g} m^2 is nil against its longest edge {longest[k]:.3g} m; remove it or "
                                 "repair the mesh")
        self.normals = np.cross(b - a, c - a) / (2.0 * area)[:, None]
        self.edge_neighbors = self._edge_neighbors()

    def _edge_neighbors(self) -> np.ndarray:
        """(m, 3): the triangle across edge ab, bc, ca of each triangle, -1 on a free edge."""
        t = self.triangles
        edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])  # edge e of triangle k at e * m + k
        key = np.sort(edges, axis=1)
        order = np.lexsort((key[:, 1], key[:, 0]))
        ks = key[order]
        same = np.all(ks[1:] == ks[:-1], axis=1)
        if (same[1:] & same[:-1]).any():
            k = int(np.nonzero(same[1:] & same[:-1])[0][0])
            raise ParameterError(f"{self.label}: edge {ks[k + 1].tolist()} is shared by more than two triangles: the "
                                 "mesh is not a manifold surface")
        m = len(t)
        neighbors = np.full(3 * m, -1, dtype=np.int64)
        first, second = order[:-1][same], order[1:][same]
        neighbors[first] = second % m
        neighbors[second] = first % m
        return neighbors.reshape(3, m).T.copy()

    @property
    def n_triangles(self) -> int:
        return len(self.triangles)

    def area(self) -> float:
        """Total area (m^2)."""
        a, b, c = (self.vertices[self.triangles[:, i]] for i in range(3))
        return float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())

    def enclosed_volume(self) -> float:
        """Signed volume (m^3) enclosed by a closed mesh with outward normals (divergence theorem)."""
        a, b, c = (self.vertices[self.triangles[:, i]] for i in range(3))
        return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)

    def moved(self, rotation=np.eye(3), translation=(0.0, 0.0, 0.0)) -> "TriangleMesh":
        """The mesh rotated by the 3x3 matrix ``rotation`` about the origin, then translated (m)."""
        try:
            matrix = np.asarray(rotation, dtype=float)
        except (TypeError, ValueError):
            matrix = np.zeros(0)
        if matrix.shape != (3, 3) or not np.isfinite(matrix).all():
            shown = rotation.tolist() if isinstance(rotation, np.ndarray) else rotation  # one line
            raise ParameterError(f"rotation = {shown!r} is not allowed: must be a 3x3 matrix of finite numbers")
        vertices = self.vertices @ matrix.T + np.array(check_vector("translation", translation))
        return TriangleMesh(vertices, self.triangles, label=self.label)

    @classmethod
    def from_file(cls, path, scale: float = 1.0) -> "TriangleMesh":
        """Read an STL (ASCII or binary) or OBJ file with meshio; coordinates times ``scale`` (e.g.
        0.001 for a file in mm). Repeated vertices (STL stores each triangle's own) are merged."""
        import meshio

        path = Path(path)
        if not path.is_file():
            raise ParameterError(f"mesh file {str(path)!r} is not found")
        scale = check_positive("mesh scale", scale)
        try:
            with np.errstate(over="ignore"):  # meshio's binary-STL size test overflows on an ASCII file
                data = meshio.read(path)
        except Exception as err:  # meshio raises many kinds: one line naming the file
            raise ParameterError(f"mesh file {str(path)!r} cannot be read as STL or OBJ: {err}") from None
        blocks = [c.data for c in data.cells if c.type == "triangle"]
        if not blocks:
            raise ParameterError(f"mesh file {str(path)!r} has no triangle")
        vertices, inverse = np.unique(np.asarray(data.points, dtype=np.float64) * scale, axis=0, return_inverse=True)
        triangles = inverse.reshape(-1)[np.concatenate(blocks)]
        return cls(vertices, triangles, label=f"mesh file {str(path)!r}")

    def write(self, path) -> Path:
        """Write the mesh as STL (or any format meshio names by the suffix), to look at in ParaView."""
        import meshio

        path = Path(path)
        meshio.write(path, meshio.Mesh(self.vertices, [("triangle", self.triangles)]))
        return path


class MeshWall(Wall):
    """A wall of triangles: ``MeshWall(vertices, triangles, material=...)``, ``MeshWall(mesh)`` of a
    ``TriangleMesh``, ``MeshWall.from_file("hopper.stl", scale=0.001)`` or ``MeshWall.shape("drum",
    radius=0.1, length=0.05)``.

    Both sides of each triangle repel; a sphere has one contact per touched surface feature
    (``touching_features``), and its springs go with it from triangle to triangle. The mesh moves as
    a rigid body: ``velocity`` (m/s) and ``angular_velocity`` (rad/s) about the axis through
    ``point`` (default: the centroid of its area), both constant during a run and changed between
    runs with ``Simulation.set_wall_velocity``; the contact uses its surface velocity at the
    contact point, v + omega x (c - point).
    """

    kind = WALL_MESH

    def __init__(self, vertices, triangles=None, material=None, velocity=(0.0, 0.0, 0.0),
                 angular_velocity=(0.0, 0.0, 0.0), point=None, name=None):
        super().__init__(material, velocity, angular_velocity, name)
        if isinstance(vertices, TriangleMesh):
            if triangles is not None:
                raise ParameterError("triangles = ... is not allowed with a TriangleMesh: it holds its triangles")
            self.mesh = vertices
        else:
            if triangles is None:
                raise ParameterError("triangles = None is not allowed: give the (m, 3) vertex indices of the "
                                     "triangles, or a TriangleMesh as the first argument")
            self.mesh = TriangleMesh(vertices, triangles, label=f"mesh {name!r}" if name else "mesh")
        self.point = self.centroid() if point is None else check_vector("mesh point", point)

    @classmethod
    def from_file(cls, path, material=None, scale: float = 1.0, name=None, **motion) -> "MeshWall":
        """A mesh wall read from an STL (ASCII or binary) or OBJ file; coordinates times ``scale``."""
        return cls(TriangleMesh.from_file(path, scale), material=material, name=name, **motion)

    @classmethod
    def shape(cls, shape: str, material=None, name=None, velocity=(0.0, 0.0, 0.0),
              angular_velocity=(0.0, 0.0, 0.0), point=None, **dimensions) -> "MeshWall":
        """A ready-made shape by name (``SHAPES``: drum, silo, hopper, disk, box, chute) with its
        dimensions as keywords, e.g. ``MeshWall.shape("hopper", top_radius=0.1, outlet_radius=0.01,
        height=0.1, segments=96)``."""
        if shape not in SHAPES:
            raise ParameterError(f"mesh shape = {shape!r} is not known: allowed are {', '.join(map(repr, SHAPES))}")
        import inspect

        allowed = list(inspect.signature(SHAPES[shape]).parameters)
        for key in dimensions:
            if key not in allowed:
                raise ParameterError(f"mesh shape {shape!r}: {key} is not one of its dimensions ({', '.join(allowed)})")
        missing = [k for k, p in inspect.signature(SHAPES[shape]).parameters.items()
                   if p.default is inspect.Parameter.empty and k not in dimensions]
        if missing:
            raise ParameterError(f"mesh shape {shape!r}: {', '.join(missing)} missing ({', '.join(allowed)} allowed)")
        return cls(SHAPES[shape](**dimensions), material=material, name=name, velocity=velocity,
                   angular_velocity=angular_velocity, point=point)

    def centroid(self) -> tuple:
        """The centroid of the mesh's area (m)."""
        v, t = self.mesh.vertices, self.mesh.triangles
        a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
        area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
        return tuple(float(x) for x in (area[:, None] * (a + b + c) / 3.0).sum(axis=0) / area.sum())

    def engine_mesh(self, material: int) -> dict:
        """What ``engine.MeshState.set_meshes`` takes of this wall."""
        return {"vertices": self.mesh.vertices, "triangles": self.mesh.triangles, "neighbors": self.mesh.edge_neighbors,
                "velocity": self.velocity, "angular_velocity": self.angular_velocity, "point": self.point,
                "material": material}

    def overlap(self, x, r) -> np.ndarray:
        """Overlap (m) of spheres (centres x, radii r) with the mesh: R minus the distance to its
        nearest point."""
        from scipy.spatial import cKDTree

        x = np.asarray(x, dtype=float).reshape(-1, 3)
        r = np.asarray(r, dtype=float).reshape(-1)
        out = np.full(len(r), -np.inf)
        if not len(r):
            return out
        v, t = self.mesh.vertices, self.mesh.triangles
        centre = v[t].mean(axis=1)
        reach = np.linalg.norm(v[t] - centre[:, None, :], axis=2).max(axis=1)  # each triangle within this of its centre
        tree = cKDTree(centre)
        pairs_p, pairs_t = [], []
        for k, near in enumerate(tree.query_ball_point(x, r + reach.max())):
            pairs_p += [k] * len(near)
            pairs_t += near
        if pairs_p:
            pp, tt = np.asarray(pairs_p), np.asarray(pairs_t, dtype=np.int64)
            q, feature = np.zeros((len(pp), 3)), np.zeros(len(pp), dtype=np.int64)
            closest_points(np.ascontiguousarray(x[pp]), v, np.ascontiguousarray(t[tt]), q, feature)
            np.maximum.at(out, pp, r[pp] - np.linalg.norm(x[pp] - q, axis=1))
        return out

    def update_from_engine(self, vertices, point):
        """Take the engine's vertices and rotation point after a run (the mesh has moved)."""
        self.mesh = _with_vertices(self.mesh, vertices)
        self.point = tuple(float(c) for c in point)

    @classmethod
    def from_description(cls, d: dict, material, mesh: TriangleMesh) -> "MeshWall":
        """The wall ``describe`` described, with its mesh as it is now (``Simulation.restore``)."""
        return cls(mesh, material=material, velocity=d["velocity"], angular_velocity=d["angular_velocity"],
                   point=d["point"], name=d.get("name"))

    def describe(self) -> dict:
        return {"type": "mesh", "point": list(self.point), "velocity": list(self.velocity),
                "angular_velocity": list(self.angular_velocity), "name": self.name,
                "triangles": self.mesh.n_triangles}

    def __repr__(self):
        return (f"MeshWall(name={self.name!r}, material={self.material!r}, triangles={self.mesh.n_triangles}, "
                f"velocity={self.velocity!r}, angular_velocity={self.angular_velocity!r}, point={self.point!r})")


def _with_vertices(mesh: TriangleMesh, vertices) -> TriangleMesh:
    """``mesh`` with new vertex positions (the same triangles, moved rigidly: no check again)."""
    out = TriangleMesh.__new__(TriangleMesh)
    out.__dict__.update(mesh.__dict__)
    out.vertices = np.array(vertices, dtype=np.float64)
    a, b, c = (out.vertices[out.triangles[:, i]] for i in range(3))
    n = np.cross(b - a, c - a)
    out.normals = n / np.linalg.norm(n, axis=1)[:, None]
    return out


# --- ready-made shapes -------------------------------------------------------------------------
def _ring(radius: float, z: float, segments: int) -> np.ndarray:
    angle = 2.0 * math.pi * np.arange(segments) / segments
    return np.column_stack([radius * np.cos(angle), radius * np.sin(angle), np.full(segments, z)])


def _band(lower: int, upper: int, segments: int) -> np.ndarray:
    """The triangles between two rings of ``segments`` vertices starting at ``lower`` and ``upper``."""
    k = np.arange(segments)
    k1 = (k + 1) % segments
    return np.concatenate([np.column_stack([lower + k, lower + k1, upper + k1]),
                           np.column_stack([lower + k, upper + k1, upper + k])])


def _fan(center: int, ring: int, segments: int, reverse: bool) -> np.ndarray:
    k = np.arange(segments)
    tri = np.column_stack([np.full(segments, center), ring + k, ring + (k + 1) % segments])
    return tri[:, [0, 2, 1]] if reverse else tri


def _rings_between(r0: float, z0: float, r1: float, z1: float, segments: int, rings: int) -> np.ndarray:
    """``rings`` + 1 rings of ``segments`` vertices from (r0, z0) to (r1, z1), evenly spaced."""
    f = np.linspace(0.0, 1.0, rings + 1)
    return np.vstack([_ring(r0 + (r1 - r0) * a, z0 + (z1 - z0) * a, segments) for a in f])


def _bands(first: int, segments: int, rings: int) -> np.ndarray:
    return np.vstack([_band(first + k * segments, first + (k + 1) * segments, segments) for k in range(rings)])


def drum(radius: float, length: float, segments: int = 48, rings: int = 1, caps: bool = True) -> TriangleMesh:
    """A closed drum: a cylinder of ``radius`` about the z axis from z = 0 to ``length`` with both end
    caps (an open tube with ``caps=False``), its side a regular polygon of ``segments`` sides in
    ``rings`` bands; normals outward."""
    radius, length, n = check_positive("radius", radius, "m"), check_positive("length", length, "m"), check_integer("segments", segments, low=3)
    rings = check_integer("rings", rings, low=1)
    side = _rings_between(radius, 0.0, radius, length, n, rings)
    if not caps:
        return TriangleMesh(side, _bands(0, n, rings), label="tube")
    top = rings * n
    vertices = np.vstack([side, [[0, 0, 0], [0, 0, length]]])
    c = len(side)
    triangles = np.vstack([_bands(0, n, rings), _fan(c, 0, n, reverse=True), _fan(c + 1, top, n, reverse=False)])
    return TriangleMesh(vertices, triangles, label="drum")


def silo(radius: float, height: float, orifice_radius: float, segments: int = 48, rings: int = 1) -> TriangleMesh:
    """A flat-bottomed cylindrical silo about the z axis, open at the top (z = ``height``), its floor
    at z = 0 an annulus around a central orifice of ``orifice_radius``; its wall in ``rings`` bands."""
    radius, height, n = check_positive("radius", radius, "m"), check_positive("height", height, "m"), check_integer("segments", segments, low=3)
    orifice_radius = check_positive("orifice_radius", orifice_radius, "m")
    rings = check_integer("rings", rings, low=1)
    if orifice_radius >= radius:
        raise ParameterError(f"orifice_radius = {orifice_radius:g} is not allowed: must be < radius = {radius:g} m")
    vertices = np.vstack([_ring(orifice_radius, 0.0, n), _rings_between(radius, 0.0, radius, height, n, rings)])
    triangles = np.vstack([_band(0, n, n)[:, [0, 2, 1]], _bands(n, n, rings)])
    return TriangleMesh(vertices, triangles, label="silo")


def hopper(top_radius: float, outlet_radius: float, height: float, segments: int = 48, rings: int = 1) -> TriangleMesh:
    """A conical hopper: the frustum about the z axis from its outlet (``outlet_radius`` at z = 0) to
    its open top (``top_radius`` at z = ``height``), in ``rings`` bands of 2 ``segments`` triangles."""
    top, height, n = check_positive("top_radius", top_radius, "m"), check_positive("height", height, "m"), check_integer("segments", segments, low=3)
    outlet = check_positive("outlet_radius", outlet_radius, "m")
    rings = check_integer("rings", rings, low=1)
    if outlet >= top:
        raise ParameterError(f"outlet_radius = {outlet:g} is not allowed: must be < top_radius = {top:g} m")
    return TriangleMesh(_rings_between(outlet, 0.0, top, height, n, rings), _bands(0, n, rings), label="hopper")


def disk(radius: float, segments: int = 48) -> TriangleMesh:
    """A flat disk of ``radius`` in the plane z = 0, centred on the origin, normal +z."""
    radius, n = check_positive("radius", radius, "m"), check_integer("segments", segments, low=3)
    vertices = np.vstack([_ring(radius, 0.0, n), [[0.0, 0.0, 0.0]]])
    return TriangleMesh(vertices, _fan(n, 0, n, reverse=False), label="disk")


def box(size) -> TriangleMesh:
    """A closed box from the origin to ``size`` = (lx, ly, lz), two triangles a face, normals outward."""
    lx, ly, lz = (check_positive(f"box size {name}", value, "m")
                  for name, value in zip(("lx", "ly", "lz"), check_vector("box size", size)))
    corners = np.array([[x, y, z] for x in (0.0, lx) for y in (0.0, ly) for z in (0.0, lz)])
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                      [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return TriangleMesh(corners, faces, label="box")


def chute(length: float, width: float, wall_height: float) -> TriangleMesh:
    """A flat chute along x from 0 to ``length``, its base (z = 0) ``width`` wide about y = 0, with
    side walls ``wall_height`` high; incline it by rotating the mesh (``TriangleMesh.moved``)."""
    length, width = check_positive("length", length, "m"), check_positive("width", width, "m")
    h, w = check_positive("wall_height", wall_height, "m"), 0.5 * width
    vertices = np.array([[0, -w, 0], [length, -w, 0], [length, w, 0], [0, w, 0],
                         [0, -w, h], [length, -w, h], [length, w, h], [0, w, h]], dtype=float)
    triangles = np.array([[0, 1, 2], [0, 2, 3], [0, 4, 5], [0, 5, 1], [3, 2, 6], [3, 6, 7]])
    return TriangleMesh(vertices, triangles, label="chute")


SHAPES = {"drum": drum, "silo": silo, "hopper": hopper, "disk": disk, "box": box, "chute": chute}

__all__ = ["MeshWall", "SHAPES", "TriangleMesh", "touching_features", "drum", "silo", "hopper", "disk", "box", "chute", "closest_point_on_triangle", "closest_points", "FACE", "EDGE_AB", "EDGE_BC", "EDGE_CA",
           "VERTEX_A", "VERTEX_B", "VERTEX_C"]
