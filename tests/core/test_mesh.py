"""Geometry core: exact values on a 2-triangle square, a tetrahedron and a cube; invariants."""

import numpy as np
import pytest

from synthkit.core import mesh as M


@pytest.fixture
def square():
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=np.float64)
    F = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64)
    return V, F


@pytest.fixture
def tet():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int64)
    return V, F


@pytest.fixture
def cube():
    import trimesh

    m = trimesh.creation.box(extents=(2, 2, 2))
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


def _area(V, F):
    return M.face_areas(V, F).sum()


def test_normalize_unit_exact():
    V = np.array([[0, 0, 0], [4, 2, 1], [2, 1, 0.5]], dtype=np.float64)
    Vn, c, s = M.normalize_unit(V)
    np.testing.assert_allclose(c, [2, 1, 0.5])
    assert s == 2.0
    np.testing.assert_allclose(Vn[1], [1, 0.5, 0.25])
    np.testing.assert_allclose(Vn * s + c, V)
    assert np.ptp(Vn, axis=0).max() == 2.0


def test_normalize_unit_errors():
    with pytest.raises(ValueError, match="zero extent"):
        M.normalize_unit(np.ones((3, 3)))
    with pytest.raises(ValueError, match="shape"):
        M.normalize_unit(np.zeros((0, 3)))


def test_areas_and_lengths_square(square):
    V, F = square
    np.testing.assert_allclose(M.face_areas(V, F), [0.5, 0.5])
    np.testing.assert_allclose(M.vertex_areas(V, F), [1 / 3, 1 / 6, 1 / 3, 1 / 6])
    np.testing.assert_allclose(M.edge_lengths(V, F), [[1, np.sqrt(2), 1], [1, 1, np.sqrt(2)]])
    np.testing.assert_allclose(M.face_normals(V, F), [[0, 0, 1], [0, 0, 1]])


def test_vertex_graph_edges_tet(tet):
    V, F = tet
    E = M.vertex_graph_edges(F)
    assert E.tolist() == [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]


def test_face_adjacency_square_and_tet(square, tet):
    pairs, edges = M.face_adjacency(square[1])
    assert pairs.tolist() == [[0, 1]] and edges.tolist() == [[0, 2]]
    pairs, edges = M.face_adjacency(tet[1])
    assert len(pairs) == 6
    # every pair of the four faces shares exactly one edge
    assert sorted(map(tuple, pairs.tolist())) == [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]


def test_face_adjacency_nonmanifold_edge():
    F = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    pairs, edges = M.face_adjacency(F)
    assert pairs.tolist() == [[0, 1], [0, 2], [1, 2]]
    assert edges.tolist() == [[0, 1]] * 3


def test_dihedral_angles(square, cube, tet):
    _, ang = M.dihedral_angles(*square)
    np.testing.assert_allclose(ang, [0.0], atol=1e-15)
    pairs, ang = M.dihedral_angles(*cube)
    flat = np.isclose(ang, 0, atol=1e-12)
    assert flat.sum() == 6  # one diagonal per square side
    np.testing.assert_allclose(ang[~flat], np.pi / 2)  # 12 convex edges
    assert (~flat).sum() == 12
    _, ang = M.dihedral_angles(*tet)
    # the three edges at the right-angle corner have a 90 degree interior angle
    assert np.isclose(ang, np.pi / 2).sum() == 3
    assert np.all(ang > 0)


def test_dihedral_concave_sign():
    # a valley: two triangles folded upward along the y axis
    V = np.array([[0, 0, 0], [0, 1, 0], [1, 0, 1], [-1, 0, 1]], dtype=np.float64)
    F = np.array([[0, 2, 1], [0, 1, 3]])
    _, ang = M.dihedral_angles(V, F)
    np.testing.assert_allclose(ang, [-np.pi / 2])


def test_clip_square_exact(square):
    V, F = square
    V2, F2, src = M.clip_by_planes(V, F, [[1, 0, 0]], [0.5])
    assert np.isclose(_area(V2, F2), 0.5)
    assert V2[:, 0].max() == 0.5
    assert set(src.tolist()) == {0, 1}
    # the diagonal's crossing point is shared: 4 original-left + 2 new points at x=0.5 (y=0 and y=1)
    # plus the diagonal point (0.5, 0.5)
    assert len(V2) == 5
    assert np.isclose(M.face_areas(V2, F2)[src == 0].sum(), 0.125)


def test_clip_keeps_side_and_area_cube(cube):
    V, F = cube
    V2, F2, src = M.clip_by_box(V, F, [-1, -1, -1], [0.25, 1, 1])
    # faces x=-1 (4), y=+-1 and z=+-1 strips (4 * 2 * 1.25): total 4 + 10 = 14
    assert np.isclose(_area(V2, F2), 14.0)
    assert V2[:, 0].max() <= 0.25
    n_src = M.face_normals(V, F)[src]
    np.testing.assert_allclose(M.face_normals(V2, F2), n_src, atol=1e-12)


def test_clip_by_planes_equals_brute_force_area():
    import trimesh

    m = trimesh.creation.icosphere(2)
    V, F = np.asarray(m.vertices), np.asarray(m.faces)
    n, d = np.array([[0.3, -0.2, 0.9]]), np.array([0.1])
    V2, F2, src = M.clip_by_planes(V, F, n, d)
    assert np.all(V2 @ n[0] <= d[0] + 1e-12)
    # brute force: dense Monte Carlo on every face, counting the kept part
    rng = np.random.default_rng(0)
    u = rng.random((4000, 2))
    u[u.sum(1) > 1] = 1 - u[u.sum(1) > 1]
    T = V[F]
    P = (
        T[:, None, 0]
        + u[None, :, :1] * (T[:, None, 1] - T[:, None, 0])
        + u[None, :, 1:] * (T[:, None, 2] - T[:, None, 0])
    )
    frac = ((P @ n[0]) <= d[0]).mean(axis=1)
    expect = (M.face_areas(V, F) * frac).sum()
    assert abs(_area(V2, F2) - expect) < 0.01 * expect
    # per source face the kept area never exceeds the original
    kept = np.bincount(src, M.face_areas(V2, F2), minlength=len(F))
    assert np.all(kept <= M.face_areas(V, F) + 1e-12)


def test_clip_vertex_on_plane_no_slivers(square):
    V, F = square
    V2, F2, _ = M.clip_by_planes(V, F, [[1, 1, 0]], [1.0])  # through vertices 1 and 3
    # vertices 1 and 3 are reused, only the diagonal's midpoint is new; no zero-area faces
    assert len(V2) == 4 and len(F2) == 2
    assert sorted(V2.tolist()) == [[0, 0, 0], [0, 1, 0], [0.5, 0.5, 0], [1, 0, 0]]
    assert np.all(M.face_areas(V2, F2) > 0.1)
    assert np.isclose(_area(V2, F2), 0.5)


def test_clip_errors(square):
    V, F = square
    with pytest.raises(ValueError, match="normals but"):
        M.clip_by_planes(V, F, [[1, 0, 0]], [0.5, 1.0])
    with pytest.raises(ValueError, match="zero vector"):
        M.clip_by_planes(V, F, [[0, 0, 0]], [0.5])
    with pytest.raises(ValueError, match="exceeds"):
        M.clip_by_box(V, F, [1, 0, 0], [0, 1, 1])
    with pytest.raises(ValueError, match="indices"):
        M.clip_by_planes(V, np.array([[0, 1, 7]]), [[1, 0, 0]], [0.5])


def test_split_by_planes_partitions_surface(cube):
    V, F = cube
    xs = np.array([-0.5, 0.0, 0.5])
    V2, F2, src = M.split_by_planes(V, F, np.tile([1.0, 0, 0], (3, 1)), xs)
    assert np.isclose(_area(V2, F2), 24.0)
    c = V2[F2].mean(axis=1)[:, 0]
    cell = np.searchsorted(xs, c)
    # every face lies within one slab
    lo = np.r_[-np.inf, xs][cell]
    hi = np.r_[xs, np.inf][cell]
    assert np.all(V2[F2][:, :, 0].min(1) >= lo - 1e-12) and np.all(V2[F2][:, :, 0].max(1) <= hi + 1e-12)
    # slabs share cut vertices: no duplicates positions
    assert len(np.unique(V2.round(12), axis=0)) == len(V2)


def test_weld(square):
    V, F = square
    V3 = np.concatenate([V, V[[0, 2]] + 1e-9])
    F3 = np.concatenate([F, [[4, 1, 5]]])
    V2, F2, idx = M.weld(V3, F3, 1e-6, return_index=True)
    assert len(V2) == 4
    assert idx.tolist() == [0, 1, 2, 3, 0, 2]
    assert F2.tolist() == [[0, 1, 2], [0, 2, 3], [0, 1, 2]]
    # a face collapsing to an edge is dropped
    V2, F2 = M.weld(np.array([[0, 0, 0], [1, 0, 0], [1e-9, 0, 0]]), np.array([[0, 1, 2]]), 1e-6)
    assert len(F2) == 0 and len(V2) == 2
    with pytest.raises(ValueError, match="tol"):
        M.weld(V, F, -1)


def test_poisson_disk_sample(cube):
    V, F = cube
    P, N = M.poisson_disk_sample(V, F, 0.3, seed=3)
    P2, N2 = M.poisson_disk_sample(V, F, 0.3, seed=3)
    np.testing.assert_array_equal(P, P2)
    np.testing.assert_array_equal(N, N2)
    P3, _ = M.poisson_disk_sample(V, F, 0.3, seed=4)
    assert not np.array_equal(P, P3[: len(P)]) if len(P3) >= len(P) else True
    from scipy.spatial import cKDTree

    d, _ = cKDTree(P).query(P, k=2)
    assert d[:, 1].min() >= 0.3 * (1 - 1e-9)
    # on the surface: one coordinate at +-1, normal along that axis
    assert np.all(np.isclose(np.abs(P).max(axis=1), 1.0))
    np.testing.assert_allclose(np.linalg.norm(N, axis=1), 1.0)
    ax = np.argmax(np.abs(N), axis=1)
    np.testing.assert_allclose(P[np.arange(len(P)), ax], N[np.arange(len(N)), ax])
    # maximal: dense enough that every surface point is within 2r (6 faces of area 4, disks r^2 pi / 4)
    assert len(P) > 24 / (np.pi * 0.3**2)
    with pytest.raises(ValueError, match="radius"):
        M.poisson_disk_sample(V, F, 0.0)


def test_greedy_independent_set_matches_sequential():
    rng = np.random.default_rng(1)
    pts = rng.random((400, 3))
    prio = rng.permutation(400)
    got = M._greedy_independent_set(pts, 0.15, prio)
    kept = []
    for i in np.argsort(prio):
        if all(np.linalg.norm(pts[i] - pts[j]) >= 0.15 for j in kept):
            kept.append(i)
    assert got.tolist() == kept


def test_simplify_correspondence():
    import trimesh

    m = trimesh.creation.icosphere(3)
    V, F = np.asarray(m.vertices), np.asarray(m.faces)
    Vc, Fc, f2c = M.simplify(V, F, 200)
    assert len(Fc) <= 220 and len(Fc) >= 150
    assert f2c.shape == (len(V),) and f2c.max() < len(Vc)
    nearest = np.argmin(((V[:, None] - Vc[None]) ** 2).sum(-1), axis=1)
    np.testing.assert_array_equal(f2c, nearest)
    Vs, Fs, ident = M.simplify(V, F, len(F) + 5)
    np.testing.assert_array_equal(ident, np.arange(len(V)))


def test_boundary_loops_square_and_closed(square, cube):
    loops = M.boundary_loops(square[1])
    assert len(loops) == 1
    loop = loops[0].tolist()
    k = loop.index(0)
    assert loop[k:] + loop[:k] == [0, 1, 2, 3]  # in the faces' (counter-clockwise) orientation
    assert M.boundary_loops(cube[1]) == []


def test_triangulate_polygon_with_hole():
    outer = np.array([[0, 0], [4, 0], [4, 4], [0, 4]], float)
    hole = np.array([[1, 1], [1, 3], [3, 3], [3, 1]], float)  # clockwise
    P = np.concatenate([outer, hole])
    T = M.triangulate_polygons(P, [np.arange(4), np.arange(4, 8)])
    a = P[T[:, 1]] - P[T[:, 0]]
    b = P[T[:, 2]] - P[T[:, 0]]
    area = 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    assert np.all(area > 0)
    assert np.isclose(area.sum(), 16 - 4)
    # an L-shaped (non-convex) polygon
    L = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], float)
    T = M.triangulate_polygons(L, [np.arange(6)])
    assert len(T) == 4
    assert np.isclose(M.face_areas(np.c_[L, np.zeros(6)], T).sum(), 3.0)


def _twice_areas(P, T):
    a, b = P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]]
    return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]


def test_best_ear_never_clips_a_flat_ear():
    """A unit square with three extra vertices on one side, turned through every whole degree:
    the plain clipper makes a triangle of area ~1e-17 on some turns (7 degrees is one), the
    best-ear clipper always gives 5 triangles of area 1/8 or more that cover the square."""
    base = np.array([(0.5, 0), (0.75, 0), (1, 0), (1, 1), (0, 1), (0, 0), (0.25, 0)], float)

    def turned(deg):
        t = np.radians(deg)
        return base @ np.array([[np.cos(t), np.sin(t)], [-np.sin(t), np.cos(t)]]) + [0.3, 0.7]

    assert np.abs(_twice_areas(turned(7), M.triangulate_polygons(turned(7), [np.arange(7)]))).min() < 1e-15
    for deg in range(360):
        P = turned(deg)
        T = M.triangulate_polygons(P, [np.arange(7)], best_ear=True)
        area2 = _twice_areas(P, T)
        assert len(T) == 5 and area2.min() > 0.25 - 1e-9, (deg, area2)
        assert np.isclose(area2.sum(), 2.0)


def test_clip_with_caps_is_closed(cube):
    import trimesh

    V, F = cube
    V2, F2, src = M.clip_by_box(V, F, [-1, -1, -1], [0.25, 0.5, 1], cap=True)
    m = trimesh.Trimesh(V2, F2)
    assert m.is_watertight and m.is_winding_consistent
    assert np.isclose(m.volume, 1.25 * 1.5 * 2)
    assert np.isclose(M.face_areas(V2, F2)[src < 0].sum(), 1.5 * 2 + 1.25 * 2)
    # a ring cut across its axis: the cap is an annulus (a polygon with a hole)
    ring = trimesh.creation.annulus(r_min=0.5, r_max=1.0, height=1.0)
    V3, F3, src3 = M.clip_by_planes(ring.vertices, ring.faces, [[0, 0, 1]], [0.1], cap=True)
    m3 = trimesh.Trimesh(V3, F3)
    assert m3.is_watertight
    assert np.isclose(m3.volume, ring.volume * 0.6)
    cap_area = M.face_areas(V3, F3)[src3 < 0].sum()
    assert np.isclose(cap_area, ring.volume / 1.0, rtol=1e-9)  # section area = volume / height


def test_poisson_prune_is_a_maximal_disk_set():
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(7)
    pts = rng.random((5000, 3)) * [1.0, 1.0, 0.1]
    keep = M._poisson_prune(pts, 0.08)
    d, _ = cKDTree(pts[keep]).query(pts[keep], k=2)
    assert d[:, 1].min() >= 0.08 * (1 - 1e-9)
    # maximal: every dropped point has a kept point closer than the radius
    d_all, _ = cKDTree(pts[keep]).query(pts)
    assert d_all.max() < 0.08
    np.testing.assert_array_equal(keep, M._poisson_prune(pts, 0.08))


def test_merge_vertices_exact(square):
    V, F = square
    V3 = np.concatenate([V, V[[2]]])
    F3 = np.array([[0, 1, 2], [0, 4, 3], [1, 2, 4]])
    V2, F2, idx = M.merge_vertices(V3, F3, [[4, 2]], return_index=True)
    assert idx.tolist() == [0, 1, 2, 3, 2]
    assert F2.tolist() == [[0, 1, 2], [0, 2, 3]]  # the third face collapsed
    np.testing.assert_array_equal(V2, V)


def test_barycentric_exact_projected_and_degenerate():
    """Points in 3-D are projected onto their triangle's plane; a degenerate triangle gives each point
    its nearest corner; 2-D points give the exact weights (outside: some negative)."""
    T = np.array([[[0, 0, 0], [2, 0, 0], [0, 2, 0]], [[0, 0, 0], [1, 0, 0], [2, 0, 0]]], np.float64)
    P = np.array([[[1, 0, 0], [0.5, 0.5, 3.0], [0, 2, 0]], [[1.9, 0, 0], [0, 0, 0], [1.1, 0, 0]]], np.float64)
    B = M.barycentric(T, P)
    np.testing.assert_allclose(B[0], [[0.5, 0.5, 0], [0.5, 0.25, 0.25], [0, 0, 1]], atol=1e-15)
    np.testing.assert_array_equal(B[1], np.eye(3)[[2, 0, 1]])
    flat = M.barycentric(T[:1, :, :2], np.array([[[3.0, 1.0]]]))
    np.testing.assert_allclose(flat, [[[-1.0, 1.5, 0.5]]], atol=1e-15)
