"""Triangle-mesh walls (STL, OBJ): ``MeshWall``, the checked ``TriangleMesh`` with its edge
topology, and ready-made shapes. The contact geometry is ``rollingdem.physics.mesh``
(docs/models.md, "Mesh walls")."""

from __future__ import annotations

import copy
import inspect
import math
from pathlib import Path

import numpy as np

from rollingdem.errors import ParameterError, check_integer, check_non_negative, check_positive, check_vector
from rollingdem.physics.mesh import closest_points, inside_closed_mesh
from rollingdem.physics.records import WALL_MESH
from rollingdem.scene.regions import Region
from rollingdem.scene.walls import Wall

#: relative area below which a triangle is degenerate: |(b - a) x (c - a)| / 2 < this x (longest edge)^2
DEGENERATE_AREA = 1e-10
#: a mesh file's vertices nearer than this fraction of its bounding-box diagonal are one vertex:
#: far above the rounding of a CAD export (1e-7 relative for 6 significant figures), far below a
#: feature a sphere could meet
WELD_FRACTION = 1e-6


def weld_vertices(points, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """(the merged vertices, the index of each point's): points within ``tolerance`` (m) of each
    other, directly or through a chain of such neighbours, become one vertex at their mean."""
    from scipy.sparse import coo_matrix  # deferred: slow to load, used here only
    from scipy.sparse.csgraph import connected_components  # deferred: slow to load, used here only
    from scipy.spatial import cKDTree  # deferred: slow to load, used here only

    points = np.asarray(points, dtype=np.float64)
    unique, inverse = np.unique(points, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    if tolerance <= 0.0 or len(unique) < 2:
        return unique, inverse
    pairs = cKDTree(unique).query_pairs(tolerance, output_type="ndarray")
    if not len(pairs):
        return unique, inverse
    n = len(unique)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    count, label = connected_components(graph, directed=False)
    merged = np.zeros((count, 3))
    np.add.at(merged, label, unique)
    merged /= np.bincount(label, minlength=count)[:, None]
    return merged, label[inverse]


def _check_binary_stl(path: Path, label: str) -> None:
    """Refuse a binary STL whose length is not that of the triangles its header counts (84 bytes and
    50 per triangle): a file cut short, or not an STL. An ASCII STL starts with "solid" and is text."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(84)
    try:
        if head[:5].lower() == b"solid" and head.decode("ascii"):
            return  # an ASCII STL: meshio parses it and says where it fails
    except UnicodeDecodeError:
        pass
    if len(head) < 84:
        raise ParameterError(f"{label} cannot be read as STL: {size} bytes, shorter than a binary STL's 84-byte header")
    count = int(np.frombuffer(head[80:84], dtype="<u4")[0])
    if size != 84 + 50 * count:
        raise ParameterError(f"{label} cannot be read as STL: its header counts {count} triangles, which take "
                             f"{84 + 50 * count} bytes, but the file has {size}: cut short, or not a binary STL")


def _ascii_stl_cut_short(path: Path) -> bool:
    """Whether ``path`` is an ASCII STL (it starts with "solid" and is text) whose last word is not
    "endsolid" (nor "endsolid NAME")."""
    with open(path, "rb") as fh:
        if fh.read(5).lower() != b"solid":
            return False
        fh.seek(max(0, path.stat().st_size - 512))
        tail = fh.read().decode("ascii", errors="replace").split("\n")
    last = [line.strip() for line in tail if line.strip()]
    return not last or not last[-1].lower().startswith("endsolid")


def _not_degenerate(vertices, triangles) -> np.ndarray:
    """Which triangles have three distinct corners and an area above ``DEGENERATE_AREA``."""
    a, b, c = (vertices[triangles[:, i]] for i in range(3))
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    longest = np.max([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1),
                      np.linalg.norm(a - c, axis=1)], axis=0)
    distinct = (triangles[:, 0] != triangles[:, 1]) & (triangles[:, 1] != triangles[:, 2]) & \
        (triangles[:, 2] != triangles[:, 0])
    return distinct & (area > DEGENERATE_AREA * longest ** 2)


class TriangleMesh:
    """A checked triangle mesh: ``vertices`` (n, 3) in m, ``triangles`` (m, 3) vertex indices.

    Refused with a ``ParameterError`` naming the mesh (``label``: its file, or "mesh") and the
    problem: no triangle, an index out of range, a non-finite vertex, a degenerate triangle (area
    below ``DEGENERATE_AREA`` times its longest edge squared: a needle or repeated vertex), an
    edge shared by more than two triangles (not a manifold surface).
    """

    welded = dropped = 0  # what reading a file merged and dropped (from_file)
    weld = None  # the tolerance it merged within (m); None: not read from a file

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
        out = TriangleMesh(vertices, self.triangles, label=self.label)
        out.welded, out.dropped, out.weld = self.welded, self.dropped, self.weld
        return out

    @classmethod
    def from_file(cls, path, scale: float = 1.0, weld: float | None = None) -> "TriangleMesh":
        """Read an STL (ASCII or binary) or OBJ file with meshio; coordinates times ``scale`` (e.g.
        0.001 for a file in mm). Vertices nearer than ``weld`` (m, after scaling; default
        ``WELD_FRACTION`` of the mesh's bounding-box diagonal) are merged into one, so that a seam
        written with rounded coordinates (STL stores each triangle's own corners) is one edge; the
        triangles this collapses, and those already degenerate, are dropped. ``welded`` and
        ``dropped`` count them."""
        import meshio  # deferred: mesh files only

        path = Path(path)
        label = f"mesh file {str(path)!r}"
        if not path.is_file():
            raise ParameterError(f"{label} is not found")
        scale = check_positive("mesh scale", scale)
        suffix = path.suffix.lower()
        if suffix not in (".stl", ".obj"):
            raise ParameterError(f"{label} is not allowed: rollingdem reads STL (.stl) and OBJ (.obj) files; convert "
                                 f"the {suffix or 'suffix-less'} file to one of them")
        if suffix == ".stl":
            _check_binary_stl(path, label)
        try:
            with np.errstate(over="ignore"):  # meshio's binary-STL size test overflows on an ASCII file
                data = meshio.read(path, file_format="stl" if suffix == ".stl" else "obj")
        except (Exception, SystemExit) as err:  # meshio raises many kinds, and exits on some: one line naming the file
            if suffix == ".stl" and _ascii_stl_cut_short(path):
                raise ParameterError(f"{label} cannot be read as STL: an ASCII STL cut short (it does not end with "
                                     "'endsolid', so its last facet is incomplete); write the file again") from None
            raise ParameterError(f"{label} cannot be read as {suffix[1:].upper()}: {err}") from None
        blocks = [c.data for c in data.cells if c.type == "triangle"]
        # a quad face (OBJ) is two triangles, split along its first diagonal
        blocks += [np.concatenate([c.data[:, [0, 1, 2]], c.data[:, [0, 2, 3]]]) for c in data.cells if c.type == "quad"]
        if not blocks:
            kinds = sorted({c.type for c in data.cells})
            raise ParameterError(f"{label} has no triangle or quad face" + (
                f" (its faces are {', '.join(kinds)}, which rollingdem does not read: triangulate them)" if kinds else
                ""))
        points = np.asarray(data.points, dtype=np.float64) * scale
        if not np.isfinite(points).all():
            k = int(np.nonzero(~np.isfinite(points).all(axis=1))[0][0])
            raise ParameterError(f"{label}: vertex {k} = {points[k].tolist()} is not finite")
        triangles = np.concatenate(blocks)
        if triangles.min() < 0 or triangles.max() >= len(points):
            raise ParameterError(f"{label}: a triangle names a vertex out of range (the file has {len(points)} "
                                 "vertices)")
        exact = len(np.unique(points, axis=0))
        if weld is None:
            weld = WELD_FRACTION * float(np.linalg.norm(np.ptp(points, axis=0)))
        weld = check_non_negative("mesh weld", weld, "m")
        vertices, index = weld_vertices(points, weld)
        triangles = index[triangles]
        keep = _not_degenerate(vertices, triangles)
        mesh = cls(vertices, triangles[keep], label=label)
        mesh.welded, mesh.dropped, mesh.weld = exact - len(vertices), int((~keep).sum()), weld
        return mesh

    def report(self) -> dict:
        """The mesh in numbers: its extent (m), triangles, free edges (and the first's midpoint, m),
        whether it is closed, and what reading it merged and dropped."""
        free = np.argwhere(self.edge_neighbors < 0)
        first = None
        if len(free):
            k, e = free[0]
            a, b = self.triangles[k, e], self.triangles[k, (e + 1) % 3]
            first = (0.5 * (self.vertices[a] + self.vertices[b])).tolist()
        lo, hi = self.vertices.min(axis=0), self.vertices.max(axis=0)
        return {"extent": (hi - lo).tolist(), "lo": lo.tolist(), "hi": hi.tolist(), "triangles": self.n_triangles,
                "free_edges": len(free), "first_free_edge": first, "closed": not len(free),
                "welded": self.welded, "dropped": self.dropped, "weld": self.weld}

    def report_line(self) -> str:
        """``report`` in one line of words."""
        r = self.report()
        size = " x ".join(f"{v:.4g}" for v in r["extent"])
        edges = ("closed" if r["closed"] else
                 f"{r['free_edges']} free edges, the first at ({', '.join(f'{v:.4g}' for v in r['first_free_edge'])}) m")
        read = ""
        if r["weld"] is not None:
            read = (f"; vertices merged within {r['weld']:.2g} m: {r['welded']}, degenerate triangles dropped: "
                    f"{r['dropped']}")
        return f"{self.label}: {size} m, {r['triangles']} triangles, {edges}{read}"

    def openings(self) -> list[tuple[np.ndarray, float]]:
        """The holes in the mesh, as (centre, width): each loop of free edges whose centre (the mean
        of its edges' midpoints, weighted by length) lies off the mesh, farther from it than half its
        distance to the loop (a sheet's outer rim has its centre on the sheet). The width is twice
        the distance from the centre to the loop's nearest edge: a circle's diameter, a slot's width."""
        from scipy.sparse import coo_matrix  # deferred: slow to load, used here only
        from scipy.sparse.csgraph import connected_components  # deferred: slow to load, used here only

        k, e = np.nonzero(self.edge_neighbors < 0)
        if not len(k):
            return []
        a, b = self.triangles[k, e], self.triangles[k, (e + 1) % 3]
        n = len(self.vertices)
        _, label = connected_components(coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n)), directed=False)
        holes = []
        for loop in np.unique(label[a]):
            pa, pb = self.vertices[a[label[a] == loop]], self.vertices[b[label[a] == loop]]
            length = np.linalg.norm(pb - pa, axis=1)
            centre = (0.5 * (pa + pb) * length[:, None]).sum(axis=0) / length.sum()
            t = np.clip(np.einsum("ij,ij->i", centre - pa, pb - pa) / length ** 2, 0.0, 1.0)
            half = float(np.linalg.norm(pa + t[:, None] * (pb - pa) - centre, axis=1).min())
            if half > 0.0 and sphere_overlap(self, centre, half)[0] < 0.5 * half:  # off the mesh by more than half
                holes.append((centre, 2.0 * half))
        return holes

    def write(self, path) -> Path:
        """Write the mesh as STL (or any format meshio names by the suffix), to look at in ParaView."""
        import meshio  # deferred: mesh files only

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
    ``point`` (default: the centroid of its area), plus a ``motion`` program (``Oscillation``,
    ``MotionTable``, ``Servo``), changed between runs with ``Simulation.set_wall_velocity`` and
    ``set_wall_motion``; the contact uses its surface velocity at the contact point,
    v + omega x (c - point).
    """

    kind = WALL_MESH

    #: whether the mesh's size is checked against the particles' (``wall_set.check_mesh_size``)
    check_size = True

    def __init__(self, vertices, triangles=None, material=None, velocity=(0.0, 0.0, 0.0),
                 angular_velocity=(0.0, 0.0, 0.0), point=None, name=None, motion=None):
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
        self.set_motion(motion)

    @classmethod
    def from_file(cls, path, material=None, scale: float = 1.0, name=None, weld: float | None = None,
                  **motion) -> "MeshWall":
        """A mesh wall read from an STL (ASCII or binary) or OBJ file; coordinates times ``scale``,
        vertices within ``weld`` merged (``TriangleMesh.from_file``)."""
        return cls(TriangleMesh.from_file(path, scale, weld), material=material, name=name, **motion)

    @classmethod
    def shape(cls, shape: str, material=None, name=None, velocity=(0.0, 0.0, 0.0),
              angular_velocity=(0.0, 0.0, 0.0), point=None, motion=None, **dimensions) -> "MeshWall":
        """A ready-made shape by name (``SHAPES``: drum, silo, hopper, disk, box, chute) with its
        dimensions as keywords, e.g. ``MeshWall.shape("hopper", top_radius=0.1, outlet_radius=0.01,
        height=0.1, segments=96)``."""
        if shape not in SHAPES:
            raise ParameterError(f"mesh shape = {shape!r} is not known: allowed are {', '.join(map(repr, SHAPES))}")

        allowed = list(inspect.signature(SHAPES[shape]).parameters)
        for key in dimensions:
            if key not in allowed:
                raise ParameterError(f"mesh shape {shape!r}: {key} is not one of its dimensions ({', '.join(allowed)})")
        missing = [k for k, p in inspect.signature(SHAPES[shape]).parameters.items()
                   if p.default is inspect.Parameter.empty and k not in dimensions]
        if missing:
            raise ParameterError(f"mesh shape {shape!r}: {', '.join(missing)} missing ({', '.join(allowed)} allowed)")
        return cls(SHAPES[shape](**dimensions), material=material, name=name, velocity=velocity,
                   angular_velocity=angular_velocity, point=point, motion=motion)

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
                "material": material, "motion": None}

    def overlap(self, x, r) -> np.ndarray:
        """Overlap (m) of spheres (centres x, radii r) with the mesh: R minus the distance to its
        nearest point."""
        return sphere_overlap(self.mesh, x, r)

    def reach(self, x) -> float:
        """The farthest a vertex lies from the point the mesh turns about (m)."""
        return float(np.linalg.norm(self.mesh.vertices - np.asarray(self.point, float), axis=1).max())

    def update_from_engine(self, vertices, point):
        """Take the engine's vertices and rotation point after a run (the mesh has moved)."""
        self.mesh = _with_vertices(self.mesh, vertices)
        self.point = tuple(float(c) for c in point)

    @classmethod
    def from_description(cls, d: dict, material, mesh: TriangleMesh) -> "MeshWall":
        """The wall ``describe`` described, with its mesh as it is now (``Simulation.restore``)."""
        wall = cls(mesh, material=material, velocity=d["velocity"], angular_velocity=d["angular_velocity"],
                   point=d["point"], name=d.get("name"), motion=d.get("motion"))
        wall.check_size = d.get("check_size", True)
        return wall

    def describe(self) -> dict:
        return {"type": "mesh", "point": list(self.point), "velocity": list(self.velocity),
                "angular_velocity": list(self.angular_velocity), "name": self.name,
                "triangles": self.mesh.n_triangles, "check_size": self.check_size, **self.describe_motion()}

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


def sphere_overlap(mesh: TriangleMesh, x, r) -> np.ndarray:
    """Overlap (m) of spheres (centres ``x``, radii ``r``) with ``mesh``: the radius minus the
    distance to the mesh's nearest point (-inf beyond a triangle's reach)."""
    from scipy.spatial import cKDTree  # deferred: slow to load, used here only

    x = np.asarray(x, dtype=float).reshape(-1, 3)
    r = np.asarray(r, dtype=float).reshape(-1)
    out = np.full(len(r), -np.inf)
    if not len(r):
        return out
    v, t = mesh.vertices, mesh.triangles
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


#: centres drawn to see whether a sphere fits in a mesh region, and rounds of drawing its centres
FIT_TRIES, SAMPLE_ROUNDS = 2000, 50


class MeshRegion(Region):
    """The volume a closed triangle ``mesh`` (a ``TriangleMesh``, or a ``MeshWall``'s) encloses: a
    probe's region, a region to fill. A point is inside where a ray from it crosses the mesh an odd
    number of times (``physics.mesh.inside_closed_mesh``); a sphere, where its centre is inside and no
    point of the mesh is nearer than its radius.
    Refused in one line when the mesh is not closed (an edge of one triangle only)."""

    def __init__(self, mesh):
        mesh = getattr(mesh, "mesh", mesh)
        if not isinstance(mesh, TriangleMesh):
            raise ParameterError(f"MeshRegion mesh = {mesh!r} is not allowed: must be a TriangleMesh or MeshWall")
        free = np.argwhere(mesh.edge_neighbors < 0)
        if len(free):
            k, e = (int(i) for i in free[0])
            t = mesh.triangles[k]
            raise ParameterError(f"{mesh.label}: a region's mesh must be closed, but edge {[int(t[e]), int(t[(e + 1) % 3])]} "
                                 f"of triangle {k} belongs to no other triangle ({len(free)} such edges)")
        self.mesh = mesh
        self._volume = abs(mesh.enclosed_volume())
        self._clip = None
        self._bin_triangles()

    def _bin_triangles(self):
        """The triangles binned by their xy boxes on a grid of about four cells a triangle (the ray
        test's, ``physics.mesh.inside_closed_mesh``)."""
        v, t = self.mesh.vertices, self.mesh.triangles
        lo, hi = v[:, :2].min(axis=0), v[:, :2].max(axis=0)
        span = np.maximum(hi - lo, 1e-12 * max(float((hi - lo).max()), 1e-300))
        h = float(math.sqrt(span[0] * span[1] / (4.0 * len(t))))
        n = np.maximum(np.ceil(span / h).astype(np.int64), 1)
        corners = v[t][:, :, :2]
        first = np.clip(np.floor((corners.min(axis=1) - lo) / h).astype(np.int64), 0, n - 1)
        last = np.clip(np.floor((corners.max(axis=1) - lo) / h).astype(np.int64), 0, n - 1)
        cells, items = [], []
        for k in range(len(t)):
            ii, jj = np.meshgrid(np.arange(first[k, 0], last[k, 0] + 1), np.arange(first[k, 1], last[k, 1] + 1),
                                 indexing="ij")
            cells.append((ii * n[1] + jj).reshape(-1))
            items.append(np.full(cells[-1].size, k, dtype=np.int64))
        cells, items = np.concatenate(cells), np.concatenate(items)
        order = np.argsort(cells, kind="stable")
        self._grid = (np.concatenate([[0], np.cumsum(np.bincount(cells, minlength=int(n[0] * n[1])))]).astype(np.int64),
                      items[order], float(lo[0]), float(lo[1]), h, int(n[0]), int(n[1]))

    def volume(self) -> float:
        return self._volume

    def inside(self, x) -> np.ndarray:
        """Whether each point of ``x`` (n, 3) lies inside the mesh (the parity of a ray's crossings)."""
        x = np.ascontiguousarray(np.asarray(x, dtype=float).reshape(-1, 3))
        out = np.zeros(len(x), dtype=np.bool_)
        inside_closed_mesh(x, self.mesh.vertices, self.mesh.triangles, *self._grid, out)
        return out

    def contains(self, x, r):
        x = np.asarray(x, dtype=float).reshape(-1, 3)
        r = np.broadcast_to(np.asarray(r, dtype=float), (len(x),))
        lo, hi = self.bounds()
        inside = ((x - r[:, None] >= lo) & (x + r[:, None] <= hi)).all(axis=1)  # the box first: most points are out
        k = np.nonzero(inside)[0]
        inside[k] = self.inside(x[k])
        k = k[inside[k] & (r[k] > 0)]
        if len(k):
            inside[k] = sphere_overlap(self.mesh, x[k], r[k]) <= 0.0
        return inside

    def fits(self, r: float) -> bool:
        """Whether a sphere of radius r fits inside: one of ``FIT_TRIES`` centres drawn in the box does."""
        rng = np.random.default_rng(0)
        lo, hi = self.bounds()
        if np.any(hi - lo <= 2.0 * r):
            return False
        x = lo + r + rng.random((FIT_TRIES, 3)) * (hi - lo - 2.0 * r)
        return bool(self.contains(x, np.full(FIT_TRIES, r)).any())

    def sample(self, rng, r):
        """Centres uniform over where each sphere (radius r) fits, drawn in the box and kept inside."""
        r = np.asarray(r, dtype=float).reshape(-1)
        lo, hi = self.bounds()
        out = np.empty((len(r), 3))
        todo = np.arange(len(r))
        for _ in range(SAMPLE_ROUNDS):
            if not len(todo):
                return out
            x = lo + r[todo, None] + rng.random((len(todo), 3)) * np.maximum(hi - lo - 2.0 * r[todo, None], 0.0)
            ok = self.contains(x, r[todo])
            out[todo[ok]] = x[ok]
            todo = todo[~ok]
        out[todo] = np.nan  # no place found: a candidate that fails
        return out

    def bounds(self):
        lo, hi = self.mesh.vertices.min(axis=0), self.mesh.vertices.max(axis=0)
        if self._clip is not None:
            lo, hi = np.maximum(lo, self._clip[0]), np.minimum(hi, self._clip[1])
        return lo, hi

    def to_dict(self) -> dict:
        return {"type": "mesh", "vertices": self.mesh.vertices.tolist(), "triangles": self.mesh.triangles.tolist(),
                "label": self.mesh.label}

    def clipped(self, lo, hi) -> "MeshRegion":
        """The part of the region inside the box [lo, hi] (a slab of a large fill, ``insertion._slab_plan``)."""
        part = copy.copy(self)
        part._clip = (np.asarray(lo, dtype=float), np.asarray(hi, dtype=float))
        return part

    def __repr__(self) -> str:
        return f"MeshRegion({self.mesh.label}, {self.mesh.n_triangles} triangles, volume {self._volume:.6g} m^3)"


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

__all__ = ["MeshRegion", "MeshWall", "SHAPES", "TriangleMesh", "drum", "silo", "hopper", "disk", "box", "chute"]
