"""Triangle meshes (rollingdem.scene.mesh): the closest point of a triangle and its feature against an
independent construction, the mesh checks, and reading STL and OBJ files."""

import numpy as np
import pytest

from rollingdem.errors import ParameterError
from rollingdem.physics.mesh import EDGE_AB, EDGE_BC, EDGE_CA, FACE, VERTEX_A, VERTEX_B, VERTEX_C, closest_points
from rollingdem.scene.mesh import TriangleMesh

EDGES = {(0, 1): EDGE_AB, (1, 2): EDGE_BC, (2, 0): EDGE_CA}
VERTICES = (VERTEX_A, VERTEX_B, VERTEX_C)


def reference_closest(p, tri):
    """Another construction: the projection on the plane if it falls inside (barycentric >= 0),
    else the nearest of the three edges' clamped projections. Returns (point, feature)."""
    a, b, c = tri
    n = np.cross(b - a, c - a)
    q = p - np.dot(p - a, n) / np.dot(n, n) * n
    area = np.dot(np.cross(b - a, c - a), n)
    bary = [np.dot(np.cross(c - b, q - b), n) / area, np.dot(np.cross(a - c, q - c), n) / area,
            np.dot(np.cross(b - a, q - a), n) / area]
    if min(bary) > 0.0:
        return q, FACE
    best = None
    for (i, j), edge in EDGES.items():
        s, e = tri[i], tri[j]
        t = np.clip(np.dot(p - s, e - s) / np.dot(e - s, e - s), 0.0, 1.0)
        x = s + t * (e - s)
        feature = VERTICES[i] if t == 0.0 else VERTICES[j] if t == 1.0 else edge
        d = np.linalg.norm(p - x)
        if best is None or d < best[0]:
            best = (d, x, feature)
    return best[1], best[2]


def test_closest_point_and_feature_agree_with_an_independent_construction():
    """2,000 random triangles and points (points up to 2 triangle sizes away, so every region is
    hit many times): the same point to 1e-12 of the triangle's size, the same feature."""
    rng = np.random.default_rng(7)
    n = 2000
    vertices = rng.uniform(-1, 1, (3 * n, 3))
    triangles = np.arange(3 * n).reshape(n, 3)
    points = rng.uniform(-2, 2, (n, 3))
    got, features = np.zeros((n, 3)), np.zeros(n, dtype=np.int64)
    closest_points(points, vertices, triangles, got, features)
    seen = set()
    for k in range(n):
        q, feature = reference_closest(points[k], vertices[triangles[k]])
        np.testing.assert_allclose(got[k], q, atol=1e-12 * 4)
        assert features[k] == feature, k
        seen.add(feature)
    assert seen == {FACE, EDGE_AB, EDGE_BC, EDGE_CA, VERTEX_A, VERTEX_B, VERTEX_C}


def test_the_feature_of_points_above_a_face_beyond_an_edge_and_beyond_a_vertex():
    vertices = np.array([[0.0, 0, 0], [1.0, 0, 0], [0.0, 1, 0]])
    tri = np.array([[0, 1, 2]] * 4)
    points = np.array([[0.2, 0.2, 0.5], [0.5, -0.3, 0.1], [0.6, 0.6, -0.2], [-0.2, -0.1, 0.3]])
    got, features = np.zeros((4, 3)), np.zeros(4, dtype=np.int64)
    closest_points(points, vertices, tri, got, features)
    np.testing.assert_allclose(got, [[0.2, 0.2, 0], [0.5, 0, 0], [0.5, 0.5, 0], [0, 0, 0]], atol=1e-15)
    assert features.tolist() == [FACE, EDGE_AB, EDGE_BC, VERTEX_A]


SQUARE = (np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]), np.array([[0, 1, 2], [0, 2, 3]]))


def test_edge_neighbors_of_a_square_of_two_triangles():
    mesh = TriangleMesh(*SQUARE)
    # triangle 0 (0, 1, 2) meets triangle 1 across its edge ca (2, 0); triangle 1 (0, 2, 3) across ab (0, 2)
    assert mesh.edge_neighbors.tolist() == [[-1, -1, 1], [0, -1, -1]]
    np.testing.assert_allclose(mesh.normals, [[0, 0, 1], [0, 0, 1]])


@pytest.mark.parametrize("vertices, triangles, problem", [
    (np.zeros((3, 3)), np.zeros((0, 3), dtype=int), "has no triangle"),
    (SQUARE[0], np.array([[0, 1, 7]]), "out of range"),
    (np.array([[0.0, 0, 0], [1, 0, 0], [np.nan, 1, 0]]), np.array([[0, 1, 2]]), "not finite"),
    (np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]]), np.array([[0, 1, 2]]), "degenerate"),
    (np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 1]]), "degenerate"),
    (np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]]),
     np.array([[0, 1, 2], [0, 1, 3], [0, 1, 4]]), "more than two triangles"),
    (np.zeros((3, 2)), np.array([[0, 1, 2]]), "must be (n, 3)"),
    (SQUARE[0], np.array([[0.0, 1, 2]]), "vertex indices"),
])
def test_bad_meshes_are_refused_with_their_problem(vertices, triangles, problem):
    with pytest.raises(ParameterError, match="mesh: .*" + problem.replace("(", r"\(").replace(")", r"\)")):
        TriangleMesh(vertices, triangles)


@pytest.mark.parametrize("name, options", [("box.stl", {"binary": False}), ("box.stl", {"binary": True}),
                                           ("box.obj", {})])
def test_a_mesh_file_round_trip_merges_vertices_and_scales(tmp_path, name, options):
    """A unit cube's 12 triangles written in mm (STL stores every triangle's own three vertices):
    read back at scale 0.001, 8 vertices, the same triangles, in m."""
    import meshio

    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float)
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                      [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    meshio.write(tmp_path / name, meshio.Mesh(corners * 1000.0, [("triangle", faces)]), **options)
    mesh = TriangleMesh.from_file(tmp_path / name, scale=0.001)
    assert len(mesh.vertices) == 8 and mesh.n_triangles == 12
    got = {tuple(sorted(map(tuple, np.round(mesh.vertices[t], 12)))) for t in mesh.triangles}
    want = {tuple(sorted(map(tuple, corners[f]))) for f in faces}
    assert got == want
    assert (mesh.edge_neighbors >= 0).all()  # closed: every edge has its neighbor


def test_mesh_file_mistakes_name_the_file(tmp_path):
    with pytest.raises(ParameterError, match="mesh file '.*nowhere.stl' is not found"):
        TriangleMesh.from_file(tmp_path / "nowhere.stl")
    (tmp_path / "junk.stl").write_text("this is not an STL file\n")
    with pytest.raises(ParameterError, match="mesh file '.*junk.stl' cannot be read"):
        TriangleMesh.from_file(tmp_path / "junk.stl")
    import meshio

    meshio.write(tmp_path / "tri.stl", meshio.Mesh(SQUARE[0], [("triangle", SQUARE[1])]))
    with pytest.raises(ParameterError, match="mesh scale = -1 is not allowed"):
        TriangleMesh.from_file(tmp_path / "tri.stl", scale=-1)


# --- ready-made shapes: their areas and volumes are those of the polygonal solids they approximate ---
def polygon_area(radius, n):
    """Area of the regular n-gon inscribed in a circle of ``radius``."""
    return 0.5 * n * radius ** 2 * np.sin(2 * np.pi / n)


def free_edges(mesh):
    return int((mesh.edge_neighbors < 0).sum())


def test_closed_shapes_enclose_their_volume_with_outward_normals():
    """A positive signed volume means outward normals; the drum is the n-gon prism."""
    from rollingdem.scene import mesh

    drum = mesh.drum(0.1, 0.25, segments=24)
    assert free_edges(drum) == 0
    assert abs(drum.enclosed_volume() - polygon_area(0.1, 24) * 0.25) <= 1e-12 * polygon_area(0.1, 24) * 0.25
    box = mesh.box((0.1, 0.2, 0.3))
    assert free_edges(box) == 0
    assert abs(box.enclosed_volume() - 0.006) <= 1e-15


def test_open_shapes_have_the_area_of_their_polygonal_surfaces():
    from rollingdem.scene import mesh

    n, r_out, r_in, h = 16, 0.1, 0.02, 0.3
    silo = mesh.silo(r_out, h, r_in, segments=n)
    chord = 2 * r_out * np.sin(np.pi / n)
    assert np.isclose(silo.area(), n * chord * h + polygon_area(r_out, n) - polygon_area(r_in, n), rtol=1e-12)
    assert free_edges(silo) == 2 * n  # the open top and the orifice
    hopper = mesh.hopper(r_out, r_in, 0.1, segments=n)
    slant = np.hypot(0.1, (r_out - r_in) * np.cos(np.pi / n))  # between the chords' midpoints
    trapezoids = n * 0.5 * (2 * r_out + 2 * r_in) * np.sin(np.pi / n) * slant
    assert np.isclose(hopper.area(), trapezoids, rtol=1e-12)
    assert np.isclose(mesh.disk(0.1, segments=n).area(), polygon_area(0.1, n), rtol=1e-12)
    assert np.isclose(mesh.chute(1.0, 0.2, 0.05).area(), 1.0 * 0.2 + 2 * 1.0 * 0.05, rtol=1e-12)


def test_a_shape_written_to_stl_reads_back_the_same(tmp_path):
    from rollingdem.scene import mesh

    hopper = mesh.hopper(0.1, 0.02, 0.1, segments=32)
    back = TriangleMesh.from_file(hopper.write(tmp_path / "hopper.stl"))
    assert back.n_triangles == hopper.n_triangles
    assert np.isclose(back.area(), hopper.area(), rtol=1e-6)  # binary STL stores float32


def test_a_moved_mesh_keeps_its_shape():
    """Rotated by 30 degrees about x and translated: area and enclosed volume unchanged to round-off."""
    from rollingdem.scene import mesh

    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    drum = mesh.drum(0.1, 0.25, segments=24)
    moved = drum.moved([[1, 0, 0], [0, c, -s], [0, s, c]], (1.0, 2.0, 3.0))
    assert np.isclose(moved.area(), drum.area(), rtol=1e-12)
    assert np.isclose(moved.enclosed_volume(), drum.enclosed_volume(), rtol=1e-12)


@pytest.mark.parametrize("build, problem", [
    (lambda m: m.drum(0.1, 0.2, segments=2), "segments = 2 is not allowed"),
    (lambda m: m.silo(0.1, 0.2, 0.1), "orifice_radius = 0.1 is not allowed"),
    (lambda m: m.hopper(0.1, -0.02, 0.1), "outlet_radius = -0.02 is not allowed"),
    (lambda m: m.box((1, 0, 1)), "box size ly = 0 is not allowed"),
    (lambda m: m.chute(1.0, 0.2, float("nan")), "wall_height = nan is not allowed"),
    (lambda m: m.box((1, 1, 1)).moved("x"), "rotation = 'x' is not allowed"),
    (lambda m: m.box((1, 1, 1)).moved(np.eye(2)), "rotation = .* is not allowed: must be a 3x3 matrix"),
    (lambda m: m.box((1, 1, 1)).moved(translation=(0, 1)), r"translation = \(0, 1\) is not allowed"),
])
def test_bad_shape_arguments_are_refused(build, problem):
    from rollingdem.scene import mesh

    with pytest.raises(ParameterError, match=problem):
        build(mesh)


# --- one contact per touched feature (docs: rollingdem.physics.mesh.touching_features) ---------------------
def contacts(mesh, p, radius):
    """(triangles, features, points) of the sphere at p against every triangle of the mesh."""
    from rollingdem.physics.mesh import touching_features

    m = mesh.n_triangles
    tri, feat, pts = np.zeros(m, dtype=np.int64), np.zeros(m, dtype=np.int64), np.zeros((m, 3))
    n = touching_features(*np.asarray(p, dtype=float), radius, mesh.vertices, mesh.triangles, mesh.edge_neighbors,
                          np.arange(m), 0, m, tri, feat, pts)
    return tri[:n], feat[:n], pts[:n]


def test_one_contact_with_the_face_normal_across_the_edges_and_vertices_of_a_flat_mesh():
    """A hexagonal fan of 6 triangles (a vertex shared by 6, edges shared by 2) and the 2-triangle
    square: a sphere of radius 0.1 at 0.099 above any point (a face, an edge, the centre vertex,
    exactly on them or beside) touches once, at the point below it: the force has no jump."""
    angle = np.arange(6) * np.pi / 3
    fan = TriangleMesh(np.vstack([[[0.0, 0, 0]], np.column_stack([np.cos(angle), np.sin(angle), np.zeros(6)])]),
                       np.array([[0, 1 + k, 1 + (k + 1) % 6] for k in range(6)]))
    square = TriangleMesh(*SQUARE)
    rng = np.random.default_rng(3)
    spots = [(0.0, 0.0), (1e-9, 0.0), (0.5, 0.0), (0.25, 0.25 * np.tan(np.pi / 3)), (0.3, -1e-13)]
    spots += [tuple(x) for x in rng.uniform(-0.45, 0.45, (40, 2))]  # inside both meshes
    for mesh, shift in ((fan, 0.0), (square, 0.5)):
        for x, y in spots:
            p = (x + shift, y + shift, 0.099)
            tri, feat, pts = contacts(mesh, p, 0.1)
            assert len(tri) == 1, (p, feat)
            np.testing.assert_allclose(pts[0], [p[0], p[1], 0.0], atol=1e-15)


def roof(slope):
    """Two planes meeting at a ridge along x (y = 0, z = 0), falling with ``slope`` to each side."""
    h = slope
    v = np.array([[0, -1, -h], [1, -1, -h], [1, 0, 0], [0, 0, 0], [1, 1, -h], [0, 1, -h]], dtype=float)
    return TriangleMesh(v, np.array([[0, 1, 2], [0, 2, 3], [3, 2, 4], [3, 4, 5]]))


def test_a_convex_edge_gives_one_contact_from_the_edge_and_a_face_beyond_it():
    """Over the ridge, between the two faces' normals: one contact at the ridge point nearest the
    centre, its normal from there to the centre. Past a face's normal at the ridge: one face contact."""
    mesh = roof(np.tan(np.radians(30)))
    for y in (0.0, 0.01, -0.02):
        tri, feat, pts = contacts(mesh, (0.5, y, 0.05), 0.06)
        assert len(tri) == 1 and feat[0] in (EDGE_AB, EDGE_BC, EDGE_CA), feat
        np.testing.assert_allclose(pts[0], [0.5, 0, 0], atol=1e-15)
    n_left = np.array([0, -np.sin(np.radians(30)), np.cos(np.radians(30))])
    q = np.array([0.5, -0.2, -0.2 * np.tan(np.radians(30))])
    tri, feat, pts = contacts(mesh, q + 0.05 * n_left, 0.06)
    assert len(tri) == 1 and feat[0] == FACE
    np.testing.assert_allclose(pts[0], q, atol=1e-14)


def test_a_concave_corner_gives_one_contact_per_face():
    """A floor (z = 0) and a wall (y = 0) at 90 degrees: a sphere 0.05 from both touches each
    once, at its foot on each face."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [1, 0, 1], [0, 0, 1]], dtype=float)
    mesh = TriangleMesh(v, np.array([[0, 1, 2], [0, 2, 3], [0, 5, 4], [0, 4, 1]]))
    tri, feat, pts = contacts(mesh, (0.5, 0.05, 0.05), 0.06)
    assert sorted(map(tuple, np.round(pts, 15))) == [(0.5, 0.0, 0.05), (0.5, 0.05, 0.0)]
    assert list(feat) == [FACE, FACE]


def test_a_convex_vertex_gives_one_contact_from_the_vertex():
    """The apex of a square pyramid: a sphere above it, inside the apex's region, touches once at
    the apex."""
    v = np.array([[0, 0, 1], [-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=float)
    mesh = TriangleMesh(v, np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1]]))
    for p in ((0, 0, 1.05), (0.01, -0.005, 1.05)):
        tri, feat, pts = contacts(mesh, p, 0.06)
        assert len(tri) == 1 and feat[0] >= VERTEX_A
        np.testing.assert_allclose(pts[0], [0, 0, 1], atol=1e-15)


def _write_ascii_stl(path, mesh, fmt="%.6e"):
    """Each triangle with its own corners, as CAD exporters write them (``fmt`` rounds them)."""
    lines = ["solid cad"]
    for tri in mesh.triangles:
        lines += ["facet normal 0 0 0", "outer loop"]
        lines += ["vertex " + " ".join(fmt % v for v in mesh.vertices[i]) for i in tri]
        lines += ["endloop", "endfacet"]
    path.write_text("\n".join(lines + ["endsolid cad"]) + "\n")
    return path


def test_a_cad_style_stl_is_welded_at_its_seam_and_its_free_edges_are_the_rims(tmp_path):
    """A 96-sided hopper written as a CAD exporter writes it (each corner rounded to 7 figures,
    %.6e, so the seam's cos 2 pi and sin 2 pi differ from cos 0 and sin 0 by 1e-16 and more):
    read with the default weld it has the 2 x 96 = 192 vertices and only the two rims' 192 free
    edges, all at z = 0 or at the top; read without welding, the seam splits (more vertices, more
    free edges). A closed box with one corner pulled 1 mm away (far beyond the weld, 1e-6 of the
    diagonal) has free edges only at that crack, and the report names a point on it."""
    from rollingdem.scene.mesh import box

    n = 96
    phi = 2 * np.pi * np.arange(n + 1) / n  # the seam's corners at 2 pi, as a CAD exporter computes them
    rings = [np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full(n + 1, z)]) for r, z in ((0.02, 0.0), (0.1, 0.1))]
    k = np.arange(n)
    triangles = np.vstack([np.column_stack([k, k + 1, n + 1 + k]), np.column_stack([k + 1, n + 2 + k, n + 1 + k])])
    path = _write_ascii_stl(tmp_path / "hopper.stl", TriangleMesh(np.vstack(rings), triangles))
    welded = TriangleMesh.from_file(path)
    assert len(welded.vertices) == 192 and welded.dropped == 0
    report = welded.report()
    assert report["free_edges"] == 192 and not report["closed"]
    free = np.argwhere(welded.edge_neighbors < 0)
    ends = welded.vertices[welded.triangles[free[:, 0], free[:, 1]]][:, 2]
    assert np.all(np.isclose(ends, 0.0, atol=1e-9) | np.isclose(ends, 0.1, atol=1e-9))
    raw = TriangleMesh.from_file(path, weld=0.0)
    assert len(raw.vertices) > 192 and raw.report()["free_edges"] > 192
    closed = box((0.1, 0.1, 0.1))
    vertices = closed.vertices.copy()
    corner = int(np.argmax(vertices.sum(axis=1)))  # (0.1, 0.1, 0.1)
    crack = TriangleMesh(vertices, closed.triangles)
    assert TriangleMesh.from_file(_write_ascii_stl(tmp_path / "box.stl", crack)).report()["closed"]
    split = np.vstack([vertices, vertices[corner] + [0.001, 0.0, 0.0]])
    triangles = closed.triangles.copy()
    first = np.nonzero((triangles == corner).any(axis=1))[0][0]  # one triangle at that corner moves off it
    triangles[first][triangles[first] == corner] = len(vertices)
    path = _write_ascii_stl(tmp_path / "cracked.stl", TriangleMesh(split, triangles))
    report = TriangleMesh.from_file(path).report()
    assert not report["closed"] and report["free_edges"] == 4
    assert np.linalg.norm(np.array(report["first_free_edge"]) - vertices[corner]) < 0.1


def test_a_mesh_file_with_a_collapsed_triangle_drops_and_counts_it(tmp_path):
    """Two corners of one triangle of a square within the weld tolerance: that triangle collapses
    and is dropped (counted), the rest is read."""
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [1, 1e-9, 0]], float)
    triangles = np.array([[0, 1, 2], [0, 2, 3], [1, 4, 2]])
    lines = ["solid s"]
    for tri in triangles:
        lines += ["facet normal 0 0 1", "outer loop"] + ["vertex " + " ".join("%r" % float(v) for v in vertices[i]) for i in tri] + \
            ["endloop", "endfacet"]
    (tmp_path / "s.stl").write_text("\n".join(lines + ["endsolid s"]) + "\n")
    mesh = TriangleMesh.from_file(tmp_path / "s.stl", weld=1e-6)
    assert mesh.n_triangles == 2 and mesh.dropped == 1 and mesh.welded == 1


def test_check_prints_each_mesh_and_accepts_a_large_one_when_told(tmp_path):
    """``rollingdem check`` prints each mesh wall's size, triangles and free edges; a disk 400 m
    across under spheres of 10 mm (4e4 diameters) is refused (tests/test_bad_input.py) unless its
    block says ``check_size: false``; then it is valid, and its line gives 400 x 400 x 0 m, the 48
    triangles and the 48 free edges of its rim."""
    from typer.testing import CliRunner

    from rollingdem.cli import app

    (tmp_path / "case.yaml").write_text("""\
materials:
  - {name: m, youngs_modulus: 1.0e7, poisson_ratio: 0.3, density: 1000.0, friction: 0.5, restitution: 0.5}
walls:
  - {type: mesh, name: big, material: m, shape: disk, size: {radius: 200.0}, check_size: false}
particles:
  - {positions: [[0, 0, 0.006], [0.02, 0, 0.006]], radius: 0.005, material: m}
stages:
  - {name: s, duration: 0.0002}
""")
    result = CliRunner().invoke(app, ["check", str(tmp_path / "case.yaml")])
    assert result.exit_code == 0, result.output
    assert "wall 'big', disk: 400 x 400 x 0 m, 48 triangles, 48 free edges, the first at (" in result.output


def test_damaged_mesh_files_get_one_line_each(tmp_path):
    """A file of another format, a binary STL cut short, an OBJ face naming a vertex that does not
    exist and a file in another format named .obj: each is refused with one line naming the file
    (a ParameterError), none hangs or exits."""
    import meshio

    (tmp_path / "part.ply").write_text("ply\nformat ascii 1.0\nelement vertex 3\n")
    with pytest.raises(ParameterError, match="part.ply' is not allowed: rollingdem reads STL .* and OBJ"):
        TriangleMesh.from_file(tmp_path / "part.ply")
    meshio.write(tmp_path / "whole.stl", meshio.Mesh(SQUARE[0], [("triangle", SQUARE[1])]), binary=True)
    data = (tmp_path / "whole.stl").read_bytes()
    assert len(data) == 84 + 50 * 2
    (tmp_path / "cut.stl").write_bytes(data[:-30])
    with pytest.raises(ParameterError, match=r"cut.stl' cannot be read as STL: its header counts 2 triangles, which "
                                             r"take 184 bytes, but the file has 154"):
        TriangleMesh.from_file(tmp_path / "cut.stl")
    assert TriangleMesh.from_file(tmp_path / "whole.stl").n_triangles == 2
    (tmp_path / "bad.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n")
    with pytest.raises(ParameterError, match="bad.obj'"):
        TriangleMesh.from_file(tmp_path / "bad.obj")
    (tmp_path / "other.obj").write_bytes(data)  # a binary STL named .obj
    with pytest.raises(ParameterError, match="other.obj'"):
        TriangleMesh.from_file(tmp_path / "other.obj")


def test_an_ascii_stl_cut_mid_facet_is_said_to_be_cut_and_an_obj_of_quads_is_read_as_triangles(tmp_path):
    """An ASCII STL that stops inside a facet is refused as cut short (not as a number that does not
    parse); an OBJ of one unit quad is two triangles of total area 1 m^2, and one of a pentagon face is
    refused naming the face kind."""
    import meshio

    meshio.write(tmp_path / "whole.stl", meshio.Mesh(SQUARE[0], [("triangle", SQUARE[1])]), binary=False)
    text = (tmp_path / "whole.stl").read_text()
    cut = text[:text.index("vertex", text.index("facet", text.index("endfacet"))) + 12]  # mid-number
    (tmp_path / "cut.stl").write_text(cut)
    with pytest.raises(ParameterError, match=r"cut.stl' cannot be read as STL: an ASCII STL cut short \(it does not "
                                             r"end with 'endsolid'"):
        TriangleMesh.from_file(tmp_path / "cut.stl")
    (tmp_path / "quad.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    quad = TriangleMesh.from_file(tmp_path / "quad.obj")
    a, b, c = (quad.vertices[quad.triangles[:, k]] for k in range(3))
    assert quad.n_triangles == 2
    assert 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum() == pytest.approx(1.0, rel=1e-12)
    (tmp_path / "five.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0.5 1.5 0\nv 0 1 0\nf 1 2 3 4 5\n")
    with pytest.raises(ParameterError, match=r"five.obj' has no triangle or quad face \(its faces are polygon"):
        TriangleMesh.from_file(tmp_path / "five.obj")
