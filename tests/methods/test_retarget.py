"""Retargeting with offset statistics: building blocks, the issue's quality checks on samples with
known lattices, end-to-end runs, bad input."""

import itertools
import json
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp
import trimesh
from click.testing import CliRunner
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from synthkit.cli.main import cli
from synthkit.core.mesh import normalize_unit, vertex_normals, weld
from synthkit.core.quality import mesh_quality
from synthkit.errors import ConfigError, InputError, KeyedError
from synthkit.io.assets import load_asset
from synthkit.io.images import load_image, save_image
from synthkit.io.meshes import load_face_labels, load_mesh, save_mesh
from synthkit.methods.retarget.analysis import (
    analyze,
    dominant_offsets,
    match_offsets,
    offset_basis,
    offset_histogram,
    reduce_to_generators,
    select_principal,
    share_in_top,
    snap_to_vertices,
    sparsity_curve,
)
from synthkit.methods.retarget.config import RetargetConfig
from synthkit.methods.retarget.corners import carry, pack, unpack
from synthkit.methods.retarget.options import Target, options_of
from synthkit.methods.retarget.outputs import label_colours
from synthkit.methods.retarget.problem import offsets_found, resolve_steps
from synthkit.methods.retarget.synthesis import (
    RetargetProblem,
    collapse_short_seam_edges,
    flip_sliver_edges,
    grid_phase,
    label_set,
    merge_coplanar_faces,
    repair_t_junctions,
    seam_planes,
    sliver_figures,
    unique_faces,
)
from synthkit.runner import load_method_config, run_config
from synthkit.samples import retarget as samples


def analysis_options(**changes):
    """The analysis options of a config with its defaults, with ``changes``."""
    return replace(options_of(RetargetConfig.model_construct())[0], **changes)

REPO = Path(__file__).resolve().parents[2]
KENNEY = REPO.parent / "shared" / "data" / "meshes" / "kenney-city"


# ---------------------------------------------------------------- building blocks


def test_offset_histogram_and_sparsity_exact():
    offs = np.array([[0.2, 0, 0], [0.21, 0.01, 0], [0.19, -0.01, 0.0], [0.0, 0.4, 0.0], [-0.6, 0.0, 0.0]])
    keys, counts = offset_histogram(offs, bin_size=0.05)
    assert counts.tolist() == [3, 1, 1]
    assert keys[0].tolist() == [4, 0, 0]
    x, y = sparsity_curve(counts)
    np.testing.assert_allclose(x, [0, 1 / 3, 2 / 3, 1])
    np.testing.assert_allclose(y, [0, 0.6, 0.8, 1.0])
    assert share_in_top(counts, 1 / 3) == pytest.approx(0.6)


def test_dominant_offsets_peaks_and_nms():
    rng = np.random.default_rng(0)
    a = np.array([0.3, 0.0, 0.0]) + rng.normal(0, 0.005, (60, 3))
    b = np.array([0.0, 0.5, 0.0]) + rng.normal(0, 0.005, (30, 3))
    noise = rng.uniform(-1, 1, (20, 3))
    peaks, mags = dominant_offsets(np.concatenate([a, b, noise]), min_count=10)
    assert len(peaks) == 2
    np.testing.assert_allclose(peaks[0], [0.3, 0, 0], atol=0.01)
    np.testing.assert_allclose(peaks[1], [0, 0.5, 0], atol=0.01)
    assert mags[0] >= 60 and mags[1] >= 30


def test_match_offsets_brute_force():
    rng = np.random.default_rng(1)
    P = rng.random((40, 3))
    D = rng.random((40, 8)).astype(np.float32)
    match, offs, dist = match_offsets(P, D, tau=0.3, chunk=7)
    for i in range(40):
        far = np.linalg.norm(P - P[i], axis=1) > 0.3
        cand = np.flatnonzero(far)
        d = np.linalg.norm(D[cand] - D[i], axis=1)
        assert match[i] == cand[np.argmin(d)]
        np.testing.assert_allclose(offs[i], P[match[i]] - P[i])


def test_select_principal_angle_and_generators():
    V = np.array([[0.3, 0, 0], [-0.3, 0, 0], [0.25, 0.1, 0], [0, 0.4, 0], [0.3, 0.4, 0], [0, 0, 0.2]])
    assert select_principal(V, min_angle=np.pi / 3) == [0, 3, 5]
    assert select_principal(V, max_count=2) == [0, 3]
    gens = reduce_to_generators(np.array([[0.6, 0, 0], [0.3, 0, 0], [0.0, 0.5, 0]]))
    assert gens.tolist() == [1, 1, 2]


def test_generators_follow_grip():
    """Issue 15: a short offset whose multiple pins far more surface is a slide and stands for that
    multiple; a multiple is reduced to its generator only when the generator pins comparably."""
    V = np.array([[0.0, -0.2, 0], [0.0, 0.8, 0], [0.5, 0, 0], [1.0, 0, 0]])
    gens = reduce_to_generators(V, grip=np.array([0.005, 0.016, 0.02, 0.015]), tol=0.05)
    assert gens.tolist() == [1, 1, 2, 2]
    assert reduce_to_generators(V, grip=np.array([0.005, 0.016, 0.02, 0.015]), grip_ratio=0).tolist() == [0, 0, 2, 2]
    assert reduce_to_generators(V).tolist() == [0, 0, 2, 2]


def test_vertex_normals_angle_weights_ignore_triangulation():
    """A cube corner whose three faces are triangulated unevenly: area weights tilt the normal
    towards the face with more area at the corner, angle weights give the diagonal exactly."""
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [4, 0, 0], [4, 1, 0]], dtype=np.float64)
    F = np.array([[0, 2, 1], [1, 2, 5], [1, 5, 4], [0, 1, 3], [0, 3, 2]], dtype=np.int64)
    n_angle = vertex_normals(V, F, weights="angle")[0]
    np.testing.assert_allclose(n_angle, -np.ones(3) / np.sqrt(3), atol=1e-12)
    assert np.abs(vertex_normals(V, F)[0] + np.ones(3) / np.sqrt(3)).max() < 1e-12  # one triangle per face here
    with pytest.raises(ValueError, match="weights"):
        vertex_normals(V, F, weights="cot")


def test_sliver_figures_tiny_fixtures():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int64)
    assert sliver_figures(V, F) == {"min_angle_deg": pytest.approx(45.0), "sliver_faces": 0}
    sliver = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1e-4, 0]])
    assert sliver_figures(sliver, np.array([[0, 1, 2]]))["sliver_faces"] == 1
    assert sliver_figures(V, np.zeros((0, 3), np.int64)) == {"min_angle_deg": None, "sliver_faces": 0}


def test_collapse_short_seam_edges_removes_the_slivers_of_a_near_cut():
    # a 1 x 2 rectangle cut along y = 1 at x = 0.5 and 0.505: faces (0, 6, 5) and (5, 6, 3) are slivers
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 2, 0], [0, 2, 0], [0, 1, 0], [0.5, 1, 0], [0.505, 1, 0], [1, 1, 0]],
                 dtype=np.float64)
    F = np.array([[0, 1, 7], [0, 7, 6], [0, 6, 5], [0, 5, 4], [4, 5, 3], [5, 6, 3], [6, 7, 2], [6, 2, 3]])
    on_seam = np.isclose(V[:, 1], 1.0)
    F2, src = collapse_short_seam_edges(V, F, on_seam, 0.01)
    assert F2.tolist() == [[0, 1, 7], [0, 7, 5], [0, 5, 4], [4, 5, 3], [5, 7, 2], [5, 2, 3]]
    assert src.tolist() == [0, 1, 3, 4, 6, 7]
    assert sliver_figures(V, F)["sliver_faces"] == 2 and sliver_figures(V, F2)["sliver_faces"] == 0
    assert mesh_quality(V, F2)["open_edges"] == mesh_quality(V, F)["open_edges"] == 6
    # not on a seam, or longer than the bound: kept as they are
    assert collapse_short_seam_edges(V, F, np.zeros(8, bool), 0.01)[0].tolist() == F.tolist()
    assert collapse_short_seam_edges(V, F, on_seam, 0.004)[0].tolist() == F.tolist()


def test_flip_sliver_edges_flips_a_cap_across_a_flat_pair_only():
    # face 0 is a cap (179 degrees at c) over the long edge a-b; face 1 lies across it in the plane
    V = np.array([[0, 0, 0], [2, 0, 0], [1, 0.01, 0], [1, -1, 0], [1, -1, 1]], dtype=np.float64)
    F = np.array([[0, 1, 2], [1, 0, 3]])
    assert flip_sliver_edges(V, F).tolist() == [[0, 3, 2], [3, 1, 2]]
    assert sliver_figures(V, flip_sliver_edges(V, F))["sliver_faces"] == 0
    assert flip_sliver_edges(V, F, np.array([0, 1])).tolist() == F.tolist()  # two labels: kept
    assert flip_sliver_edges(V, np.array([[0, 1, 2], [1, 0, 4]])).tolist() == [[0, 1, 2], [1, 0, 4]]  # a fold


def test_unique_faces_drops_a_surface_stored_twice():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1e-7, 0], [0, 1, 0]], dtype=np.float64)
    F = np.array([[0, 1, 2], [2, 0, 3], [4, 1, 0], [1, 2, 0], [0, 1, 3]])
    # face 1 is face 0 again over copies of its vertices (within 1e-6), rotated; face 2 is face 0
    # reversed (a double-sided wall: kept); face 3 is face 0 rotated; face 4 collapses onto an edge
    assert unique_faces(V, F).tolist() == [True, False, True, False, True]
    assert unique_faces(V, F, tol=1e-8).tolist() == [True, True, True, False, True]
    assert unique_faces(V, np.zeros((0, 3), np.int64)).shape == (0,)


def test_merge_coplanar_faces_keeps_area_boundary_and_labels():
    """A unit square cut into a 2 x 2 fan of 8 triangles with a straight-edge midpoint on each side:
    one region, re-triangulated as 2 faces (the side midpoints are straight and touch only it);
    with two labels (left and right halves) each half keeps its own faces, with the shared
    midline ends."""
    V = np.array([[0, 0, 0], [0.5, 0, 0], [1, 0, 0], [1, 0.5, 0], [1, 1, 0], [0.5, 1, 0], [0, 1, 0], [0, 0.5, 0],
                  [0.5, 0.5, 0]], dtype=np.float64)
    F = np.array([[8, k, (k + 1) % 8] for k in range(8)], dtype=np.int64)
    F2, src = merge_coplanar_faces(V, F)
    assert len(F2) == 2 and len(src) == 2
    area = lambda F_: 0.5 * np.linalg.norm(np.cross(V[F_[:, 1]] - V[F_[:, 0]], V[F_[:, 2]] - V[F_[:, 0]]), axis=1)  # noqa: E731
    assert area(F2).sum() == pytest.approx(1.0)
    n = np.cross(V[F2[:, 1]] - V[F2[:, 0]], V[F2[:, 2]] - V[F2[:, 0]])
    assert np.all(n[:, 2] > 0)  # orientation kept
    labels = np.where(V[F].mean(axis=1)[:, 0] < 0.5, 0, 1)
    F3, src3 = merge_coplanar_faces(V, F, labels)
    assert area(F3).sum() == pytest.approx(1.0) and len(F3) < len(F)
    assert np.all(labels[src3] == np.where(V[F3].mean(axis=1)[:, 0] < 0.5, 0, 1))
    # the midline's ends stay; its middle vertex runs straight in both halves and goes from both,
    # so the halves still share the edge 1-5 and no T-junction appears
    E = np.sort(np.concatenate([F3[:, [0, 1]], F3[:, [1, 2]], F3[:, [2, 0]]]), axis=1).tolist()
    assert E.count([1, 5]) == 2 and mesh_quality(V, F3)["open_edges"] == 6  # side midpoints 3, 7 went


def _square_fan():
    """The unit square as a fan of 8 triangles around its centre (vertex 8), side midpoints 1, 3, 5, 7."""
    V = np.array([[0, 0, 0], [0.5, 0, 0], [1, 0, 0], [1, 0.5, 0], [1, 1, 0], [0.5, 1, 0], [0, 1, 0], [0, 0.5, 0],
                  [0.5, 0.5, 0]], dtype=np.float64)
    return V, np.array([[8, k, (k + 1) % 8] for k in range(8)], dtype=np.int64)


def test_carry_evaluates_the_source_faces_affine_map():
    V = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [1, 0, 0], [1, 1, 0], [0.5, 0.5, 0], [3, 0, 0]], dtype=np.float64)
    attr = np.array([[[7, 0.1, 0.2], [7, 0.5, 0.2], [7, 0.1, 0.6]]])  # material 7; uv = (0.1 + x/5, 0.2 + y/5)
    out = carry(V, np.array([[3, 4, 5], [1, 6, 4]]), np.array([[0, 1, 2]]), np.array([0, 0]), attr)
    want = np.concatenate([np.full((2, 3, 1), 7.0), 0.1 + V[[[3, 4, 5], [1, 6, 4]]][..., :2] / 5 + [0, 0.1]], axis=2)
    np.testing.assert_allclose(out, want, atol=1e-12)  # corner 6 lies outside: extrapolated
    assert carry(V, np.array([[3, 4, 5]]), np.array([[0, 1, 2]]), np.array([0]), None) is None
    mat, uv, col = unpack(pack(np.array([2]), attr[:, :, 1:], np.full((1, 3, 4), 200, np.uint8)), True, True)
    assert mat.tolist() == [2] and uv.tolist() == attr[:, :, 1:].tolist() and col.tolist() == [[[200] * 4] * 3]


def test_merge_coplanar_faces_keeps_one_uv_map_and_never_joins_two():
    """The square fan with uv = (x, y) is one region: 2 faces whose carried UVs are still (x, y).
    With a UV seam down the middle (right half uv = (x + 5, y)) or another material on the right,
    the halves stay apart and each keeps its own map."""
    V, F = _square_fan()
    uv = V[F][:, :, :2]
    attr = pack(np.zeros(8, np.int64), uv, None)
    F2, src = merge_coplanar_faces(V, F, attr=attr)
    A2 = carry(V, F2, F, src, attr)
    assert len(F2) == 2
    np.testing.assert_allclose(A2[:, :, 1:], V[F2][:, :, :2], atol=1e-12)
    right = V[F].mean(axis=1)[:, 0] > 0.5
    for mat, shift in ((np.zeros(8, np.int64), 5.0), (right.astype(np.int64), 0.0)):
        attr = pack(mat, uv + np.where(right[:, None, None], [shift, 0.0], 0.0), None)
        F3, src3 = merge_coplanar_faces(V, F, attr=attr)
        A3 = carry(V, F3, F, src3, attr)
        side = V[F3].mean(axis=1)[:, 0] > 0.5
        assert len(F3) < len(F) and np.all(side == right[src3])
        np.testing.assert_allclose(A3[:, :, 1:], V[F3][:, :, :2] + np.where(side[:, None, None], [shift, 0], 0))
        assert np.all(np.rint(A3[:, :, 0]) == mat[src3][:, None])


def test_flip_sliver_edges_needs_one_appearance_map():
    V = np.array([[0, 0, 0], [2, 0, 0], [1, 0.01, 0], [1, -1, 0]], dtype=np.float64)
    F = np.array([[0, 1, 2], [1, 0, 3]])
    same = pack(np.zeros(2, np.int64), V[F][:, :, :2], None)
    assert flip_sliver_edges(V, F, attr=same).tolist() == [[0, 3, 2], [3, 1, 2]]
    seam = same.copy()
    seam[1, :, 1] += 0.5  # the face across has its own chart
    assert flip_sliver_edges(V, F, attr=seam).tolist() == F.tolist()


def test_repair_t_junctions_splits_only_at_the_given_vertices():
    V = np.array([[0, 0, 0], [2, 0, 0], [1, 1, 0], [1, 0, 0], [0, -1, 0], [2, -1, 0]], dtype=np.float64)
    F = np.array([[0, 1, 2], [0, 4, 3], [3, 5, 1]])  # vertex 3 hangs on edge 0-1
    assert len(repair_t_junctions(V, F, tol=1e-9)[1]) == 4
    assert repair_t_junctions(V, F, tol=1e-9, split_at=np.zeros(6, bool))[1].tolist() == F.tolist()


def test_offset_basis_dummies():
    B, k = offset_basis(np.array([[0.3, 0.0, 0.1]]), dummy_length=0.2)
    assert k == 1
    np.testing.assert_allclose(np.linalg.norm(B[:, 1:], axis=0), 0.2)
    np.testing.assert_allclose(B[:, 0] @ B[:, 1:], 0, atol=1e-12)
    np.testing.assert_allclose(B[:, 1] @ B[:, 2], 0, atol=1e-12)
    B2, k2 = offset_basis(np.array([[0.3, 0, 0], [0.1, 0.3, 0]]))
    assert k2 == 2 and abs(B2[:, 2] @ B2[:, 0]) < 1e-12 and abs(B2[:, 2] @ B2[:, 1]) < 1e-12


def test_label_set_and_26_neighbourhood():
    L = label_set([2, 0, -1])
    assert L[0].tolist() == [0, 0, 0] and len(L) == 6
    assert set(map(tuple, L.tolist())) == {(a, 0, c) for a in range(3) for c in (-1, 0)}
    sets = [np.ones((1, 4), np.float32)] * 8
    prob = RetargetProblem([2, 2, 2], [1, 1, 1], sets)
    n = prob.out_shape
    brute = sum(
        1
        for a, b in itertools.combinations(itertools.product(*[range(k) for k in n]), 2)
        if max(abs(x - y) for x, y in zip(a, b, strict=True)) == 1
    )
    assert len(prob.edges) == brute == 158


def test_pairwise_rules_empty_and_same_label():
    sets = [np.zeros((0, 2), np.float32), np.array([[1.0, 0.0]], np.float32), np.array([[0.0, 1.0]], np.float32)]
    prob = RetargetProblem([3, 1, 1], [1, 0, 0], sets)
    # labels: 0 -> shift 0, 1 -> shift +1; output voxels 0..3
    e = np.flatnonzero((prob.edges == [1, 2]).all(axis=1))
    # node 1: sources 1 (label 0) and 0 (label 1): non-empty vs empty -> inf
    assert np.isinf(prob.pairwise(e, np.array([0]), np.array([1])))[0]
    assert prob.pairwise(e, np.array([1]), np.array([1]))[0] == 0.0
    e23 = np.flatnonzero((prob.edges == [2, 3]).all(axis=1))
    # node 2: sources 2 and 1 (both non-empty, distance sqrt 2); node 3: source 3 (outside) and 2
    assert np.isinf(prob.pairwise(e23, np.array([0]), np.array([1])))[0]
    assert prob.table[1, :].max() == pytest.approx(np.sqrt(2))
    # the first and last output voxels must copy the first and last input voxels
    assert np.isfinite(prob.unary[0, 0]) and np.isinf(prob.unary[0, 1])
    assert np.isinf(prob.unary[3, 0]) and np.isfinite(prob.unary[3, 1])


def test_repair_t_junctions_splits_edge_at_hanging_vertex():
    V = np.array([[0, 0, 0], [2, 0, 0], [1, 1, 0], [1, -1, 0], [1, 0, 0]], dtype=float)
    F = np.array([[0, 1, 2], [0, 4, 3], [4, 1, 3]])
    V2, F2, src = repair_t_junctions(V, F, tol=1e-9)
    assert len(F2) == 4 and sorted(src.tolist()) == [0, 0, 1, 2]
    E = np.sort(np.concatenate([F2[:, [0, 1]], F2[:, [1, 2]], F2[:, [2, 0]]]), axis=1)
    _, counts = np.unique(E, axis=0, return_counts=True)
    assert (counts == 2).sum() == 4  # 0-4, 4-1, 4-2 (new) and 4-3 shared
    area = lambda T: 0.5 * np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1).sum()  # noqa: E731
    assert area(V2[F2]) == pytest.approx(area(V[F]))


def test_snap_to_vertices_recovers_exact_period():
    grid = np.array([[i * 0.3, j * 0.2, 0.0] for i in range(5) for j in range(3)])
    t, pairs = snap_to_vertices(grid, [0.3004, -0.0003, 0.0002], radius=0.005)
    np.testing.assert_allclose(t, [0.3, 0, 0], atol=1e-12)
    assert pairs == 12


def test_seam_planes_only_between_regions():
    regions = {0: np.array([True, True, False, False]), 1: np.array([False, False, True, True])}
    normals, offsets = seam_planes(regions, (4, 1, 1))
    assert normals.tolist() == [[1.0, 0.0, 0.0]] and offsets.tolist() == [2.0]


def test_grid_phase_avoids_parallel_surface():
    C = np.zeros((100, 3))
    C[:, 0] = np.repeat(np.arange(10) + 0.25, 10)  # planes at x = k + 0.25
    C[:, 1:] = np.random.default_rng(0).random((100, 2)) * 5
    parallel = np.zeros((100, 3), bool)
    parallel[:, 0] = True
    phase = grid_phase(C, np.array([0.05, 0.05, 0.05]), parallel=parallel)
    assert abs(phase[0] - 0.75) <= 1 / 32


# ---------------------------------------------------------------- analysis on samples with known lattices

_CACHE: dict = {}


def _analysed(name):
    if name not in _CACHE:
        V, F, truth = samples.SAMPLES[name][0]()
        Vn, _, scale = normalize_unit(V)
        _CACHE[name] = (analyze(Vn, F, analysis_options(), rng=0), truth, scale)
    return _CACHE[name]


def _match_truth(found, truth):
    """Pair each found vector with the true lattice vector it is closest to (up to sign)."""
    return [min((np.linalg.norm(f - s * t), t) for t in truth for s in (1, -1))[1] for f in found]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["railing", "bridge", "stairs", "bookshelf", "facade", "sheared_grid"])
def test_principal_offsets_match_lattice(name):
    an, truth, scale = _analysed(name)
    lattice = np.array(truth["lattice"]) / scale
    assert an.n_principal == truth["principal_offsets"] == len(lattice)
    for i, true in zip(an.principal_index, _match_truth(an.principal, lattice), strict=True):
        before = an.dominant[i]
        s = np.sign(before @ true)
        assert np.abs(before - s * true).max() <= 0.05  # within one bin before ICP
        after = an.dominant_refined[i]
        assert np.linalg.norm(after - s * true) <= 0.01 * np.linalg.norm(true)  # within 1% after ICP


@pytest.mark.slow
def test_sheared_grid_offsets_are_not_orthogonal():
    an, _, _ = _analysed("sheared_grid")
    v1, v2 = an.principal
    angle = np.degrees(np.arccos(abs(v1 @ v2) / np.linalg.norm(v1) / np.linalg.norm(v2)))
    assert 60 <= angle < 80


MAN_MADE = ("bookshelf", "facade", "railing", "stairs", "sheared_grid", "bridge")


@pytest.mark.slow
def test_sparsity_of_every_man_made_sample_under_the_section_iv_protocol():
    """Section IV's statistics (Poisson-disk features only, issue 15): every man-made sample puts
    at least 38% of its offsets in the top 7% of bins and 62% in the top 20% (measured 0.41-0.49
    and 0.65-0.74; the organic meshes of ../shared score 0.23-0.25), and the lattice's own offsets
    carry at least 90% of that share, not repeats made by the tessellation grid. (Before issue 15
    the statistics also counted the samples' grid vertices and the samples reached 0.76-0.80.)"""
    figures, failed = {}, []
    for name in MAN_MADE:
        an, truth, scale = _analysed(name)
        top7, top20 = share_in_top(an.bin_counts, 0.07), share_in_top(an.bin_counts, 0.20)
        assert top7 == pytest.approx(an.top7) and top20 == pytest.approx(an.top20)
        assert an.n_statistics_features == len(an.features.P) - an.features.n_vertex_features
        lattice = np.array(truth["lattice"]) / scale
        n_top = int(np.floor(0.07 * len(an.bin_counts)))
        top = an.bin_keys[:n_top] * 0.05
        coef = np.linalg.lstsq(lattice.T, top.T, rcond=None)[0]
        on_lattice = np.abs(top - (lattice.T @ np.rint(coef)).T).max(axis=1) <= 0.05
        lattice_share = an.bin_counts[:n_top][on_lattice].sum() / an.bin_counts.sum()
        figures[name] = (round(top7, 3), round(top20, 3), round(float(lattice_share), 3))
        if top7 < 0.38 or top20 < 0.62 or lattice_share < 0.9 * top7:
            failed.append(name)
    assert not failed, f"below 0.38 in the top 7% (or 0.62 in the top 20%): {failed}; (top7, top20, lattice) {figures}"


# ---------------------------------------------------------------- end to end


@pytest.fixture(scope="module")
def sample_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("retarget-samples")
    samples.generate(out)
    return out


def _config(tmp_path, sample_dir, name, **keys):
    suffix = samples.SAMPLES[name][1]
    cfg = {"method": "retarget", "input": str(sample_dir / f"retarget-{name}{suffix}"), "seed": 0, **keys}
    path = tmp_path / f"{name}.json.yaml"
    path.write_text(json.dumps(cfg))
    return path


def _boards(mesh, truth):
    """Complete boards: heights on the board lattice where upward faces cover a whole board top."""
    n = mesh.face_normals
    up = n[:, 1] > 0.99
    heights = np.round(mesh.triangles_center[up, 1], 5)
    areas = mesh.area_faces[up]
    w, t, d = truth["board_size"]
    pitch = truth["board_pitch"]
    on_lattice = [h for h in np.unique(heights) if abs((h - t) / pitch - round((h - t) / pitch)) < 1e-3]
    full = [h for h in on_lattice if areas[heights == h].sum() >= 0.999 * w * d]
    return len(full)


def _labels_ply(path):
    """``(mesh, labels (m,) int, colours (m, 3) uint8)`` of a retarget ``labels.ply``."""
    mesh = trimesh.load(path, process=False)
    face = mesh.metadata["_ply_raw"]["face"]["data"]
    labels = np.asarray(face["label"]).reshape(-1)
    colours = np.stack([np.asarray(face[c]).reshape(-1) for c in ("red", "green", "blue")], axis=1)
    return mesh, labels, colours


def _no_invented_geometry(report, out, input_mesh):
    """Largest distance (normalised units) of an output triangle's corners, centroid and edge
    midpoints from the input translated by its face label's offset."""
    m = report["metrics"]
    center, scale = np.array(m["normalisation"]["center"]), m["normalisation"]["scale"]
    basis = np.array(m["grid_basis_normalised"]).T
    shifts = np.array(m["label_shifts"])
    mesh, labels, _ = _labels_ply(out / "labels.ply")
    assert len(labels) == len(mesh.faces) > 0
    ref = trimesh.Trimesh((input_mesh.vertices - center) / scale, input_mesh.faces, process=False)
    worst = 0.0
    for lab in np.unique(labels):
        tri = (np.asarray(mesh.vertices)[mesh.faces[labels == lab]] - center) / scale  # (k, 3, 3)
        a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
        pts = np.concatenate([a, b, c, (a + b + c) / 3, (a + b) / 2, (b + c) / 2, (c + a) / 2])
        pts = np.unique(pts, axis=0) - basis @ shifts[lab]
        _, dist, _ = trimesh.proximity.closest_point(ref, pts)
        worst = max(worst, float(dist.max()))
    return worst


def test_no_invented_geometry_sees_inside_triangles(tmp_path):
    """A triangle whose corners lie on the input but which spans across empty space is caught."""
    inp = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 1]], [[0, 1, 2], [1, 3, 2]], process=False)
    bad = trimesh.Trimesh(inp.vertices, [[0, 1, 2], [0, 1, 3]], process=False)  # 0-1-3 is not on the input
    out = tmp_path / "o"
    out.mkdir()
    def write_labels_ply(path, mesh, labels):
        save_mesh(mesh, path, face_labels=labels, face_colors=label_colours(labels, 1))

    report = {"metrics": {"normalisation": {"center": [0, 0, 0], "scale": 1.0}, "grid_basis_normalised": np.eye(3),
                          "label_shifts": [[0, 0, 0]]}}
    write_labels_ply(out / "labels.ply", bad, np.array([0, 0]))
    assert _no_invented_geometry(report, out, inp) > 0.1
    write_labels_ply(out / "labels.ply", inp, np.array([0, 0]))
    assert _no_invented_geometry(report, out, inp) <= 1e-6


def _check_images(out, names):
    """Each PNG is a real image with non-trivial content (not one flat colour)."""
    for name in names:
        img = np.asarray(load_image(out / name), dtype=np.float64)
        assert img.ndim >= 2 and min(img.shape[:2]) >= 32, name
        flat = img.reshape(img.shape[0] * img.shape[1], -1)
        assert flat.std(axis=0).max() > 0.02 * max(flat.max(), 1e-9), name
        colours, counts = np.unique(flat, axis=0, return_counts=True)
        assert len(colours) >= 3 and counts.max() < 0.98 * len(flat), name  # not one colour on a background


@pytest.mark.slow
def test_bookshelf_grows_by_two_rows_with_baseline(tmp_path, sample_dir):
    cfg = _config(tmp_path, sample_dir, "bookshelf", target={"axis_steps": {"y": 2}}, compare_baseline=True)
    rep = run_config(cfg, out_dir=tmp_path / "out", show_progress=False)
    out = tmp_path / "out"
    truth = json.loads((sample_dir / "retarget-bookshelf.truth.json").read_text())
    inp = load_mesh(sample_dir / "retarget-bookshelf.obj")
    res = load_mesh(out / "retargeted.obj")
    grow = np.ptp(res.vertices, axis=0) - np.ptp(inp.vertices, axis=0)
    assert grow[1] == pytest.approx(2 * truth["board_pitch"], rel=0.01)
    assert abs(grow[0]) < 1e-6 and abs(grow[2]) < 1e-6
    assert _boards(inp, truth) == truth["counts"]["boards"]
    assert _boards(res, truth) == truth["counts"]["boards"] + 2
    assert _no_invented_geometry(rep, out, inp) <= 1e-6
    m = rep["metrics"]
    assert m["baseline"]["graph_nodes"] > m["graph_nodes"] and m["baseline"]["graph_labels"] > m["graph_labels"]
    assert np.isfinite(m["energy"]) and rep["timings"]["graphcut"] >= 0
    vol = np.load(out / "labels.npy")
    assert vol.shape == tuple(m["grid_out"])
    for key in ("principal_offsets", "sparsity_top7", "sparsity_top20", "graph_nodes", "graph_labels", "energy"):
        assert key in m
    np.testing.assert_allclose(np.abs(m["principal_offsets"]).max(axis=1), [0.40, 0.35], rtol=0.01)
    # labels.ply: int32 labels and a colour per face from one palette by label; its faces each lie
    # in one label's copy, so it keeps the seams the retargeted mesh re-triangulates across (issue 15)
    lm, labels, colours = _labels_ply(out / "labels.ply")
    assert labels.dtype == np.int32 and len(labels) == len(lm.faces) >= len(res.faces)
    assert m["labelled_faces"] == len(lm.faces) and m["output_faces"] == len(res.faces)
    assert set(np.unique(labels).tolist()) == set(np.unique(vol).tolist())
    np.testing.assert_array_equal(colours, label_colours(labels, m["graph_labels"]))
    np.testing.assert_array_equal(load_face_labels(out / "labels.ply"), labels)
    _, first = np.unique(labels, return_index=True)
    assert len(np.unique(colours[first], axis=0)) == len(first)  # distinct labels, distinct colours
    np.testing.assert_array_equal(np.asarray(lm.visual.face_colors)[:, :3], colours)
    _check_images(out, ["histogram.png", "histogram_xy.png", "offsets.png", "before.png", "after.png", "labels.png"])
    offsets_png = np.asarray(load_image(out / "offsets.png"))
    red = (offsets_png[..., 0] > 0.7) & (offsets_png[..., 1] < 0.3) & (offsets_png[..., 2] < 0.3)
    assert red.sum() >= 20  # the offsets are drawn over the model
    after, before = np.asarray(load_image(out / "after.png")), np.asarray(load_image(out / "before.png"))
    assert not np.array_equal(after, before)  # two rows more
    # dominant offsets: counts of the histogram, one of them per principal offset
    dom = m["dominant_offsets"]
    counts = [d["count"] for d in dom]
    assert counts == sorted(counts, reverse=True) and 0 < counts[-1] and counts[0] <= m["n_offsets"]
    principal = [d["offset"] for d in dom if d["principal"]]
    assert len(principal) == len(m["principal_offsets"]) == 2
    for p in m["principal_offsets"]:
        assert min(min(np.abs(np.subtract(p, q)).max(), np.abs(np.add(p, q)).max()) for q in principal) < 1e-9


@pytest.mark.slow
def test_bookshelf_shrinks_by_one_row(tmp_path, sample_dir):
    cfg = _config(tmp_path, sample_dir, "bookshelf", target={"axis_steps": {"y": -1}})
    rep = run_config(cfg, out_dir=tmp_path / "out", show_progress=False)
    truth = json.loads((sample_dir / "retarget-bookshelf.truth.json").read_text())
    res = load_mesh(tmp_path / "out" / "retargeted.obj")
    assert _boards(res, truth) == truth["counts"]["boards"] - 1
    inp = load_mesh(sample_dir / "retarget-bookshelf.obj")
    assert _no_invented_geometry(rep, tmp_path / "out", inp) <= 1e-6


def _windows(mesh, truth):
    """Complete windows: lattice cells whose sill front (the +z faces 0.08 in front of the wall,
    below the cornice) is whole."""
    (wx, _, _), (_, wy, _) = truth["lattice"]
    n, c, area = mesh.face_normals, mesh.triangles_center, mesh.area_faces
    sill = (n[:, 2] > 0.99) & (np.abs(c[:, 2] - 0.08) < 1e-6) & (c[:, 1] < mesh.bounds[1, 1] - 0.07)
    cells = np.floor(c[sill, :2] / [wx, wy]).astype(int)
    keys, inv = np.unique(cells, axis=0, return_inverse=True)
    per_cell = np.bincount(inv.reshape(-1), weights=area[sill])
    return int((per_cell >= 0.999 * 0.32 * 0.04).sum())


@pytest.mark.slow
def test_facade_gains_two_columns_and_loses_a_floor(tmp_path, sample_dir):
    cfg = _config(tmp_path, sample_dir, "facade", target={"axis_steps": {"x": 2, "y": -1}})
    rep = run_config(cfg, out_dir=tmp_path / "out", show_progress=False)
    truth = json.loads((sample_dir / "retarget-facade.truth.json").read_text())
    inp = load_mesh(sample_dir / "retarget-facade.ply")
    res = load_mesh(tmp_path / "out" / "retargeted.ply")
    assert _windows(inp, truth) == truth["counts"]["windows"] == 15
    assert _windows(res, truth) == (5 + 2) * (3 - 1)
    grow = np.ptp(res.vertices, axis=0) - np.ptp(inp.vertices, axis=0)
    np.testing.assert_allclose(grow, [1.0, -0.6, 0.0], atol=1e-6)
    assert _no_invented_geometry(rep, tmp_path / "out", inp) <= 1e-6


def _studs(mesh):
    """Complete stud caps: clusters of upward faces at the cap height (0.16) with a whole cap's area
    (0.14 x 0.06); returns their centres ``(k, 3)``."""
    n, c, area = mesh.face_normals, mesh.triangles_center, mesh.area_faces
    top = np.flatnonzero((n[:, 1] > 0.99) & (np.abs(c[:, 1] - 0.16) < 1e-6))
    pairs = cKDTree(c[top]).query_pairs(0.08, output_type="ndarray")
    g = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(top), len(top)))
    _, comp = connected_components(g, directed=False)
    per = np.bincount(comp, weights=area[top])
    ct, at = c[top], area[top]
    centres = np.array([np.average(ct[comp == k], axis=0, weights=at[comp == k]) for k in range(comp.max() + 1)])
    return centres[per >= 0.999 * 0.14 * 0.06]


@pytest.mark.slow
def test_sheared_grid_retargets_in_canonical_space(tmp_path, sample_dir):
    cfg = _config(tmp_path, sample_dir, "sheared_grid", target={"steps": [1, 1]})
    rep = run_config(cfg, out_dir=tmp_path / "out", show_progress=False)
    inp = load_mesh(sample_dir / "retarget-sheared_grid.ply")
    res = load_mesh(tmp_path / "out" / "retargeted.ply")
    truth = json.loads((sample_dir / "retarget-sheared_grid.truth.json").read_text())
    assert _no_invented_geometry(rep, tmp_path / "out", inp) <= 1e-6
    v1, v2 = np.array(truth["lattice"])
    # the extent across each lattice direction (along the normal of the other one, in the slab's
    # plane) grows by one lattice step: the mesh itself, not the metrics
    for a, b in ((v1, v2), (v2, v1)):
        u = np.cross(b, [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        grow = np.ptp(res.vertices @ u) - np.ptp(inp.vertices @ u)
        assert grow == pytest.approx(abs(a @ u), abs=1e-6)
    n1, n2 = truth["repeats"]
    assert len(_studs(inp)) == truth["counts"]["studs"] == n1 * n2
    studs = _studs(res)
    assert len(studs) == (n1 + 1) * (n2 + 1)
    # and they stand on the sheared lattice: integer coordinates in (v1, v2) from the first one
    coef = np.linalg.lstsq(np.stack([v1, v2], axis=1), (studs - studs[0]).T, rcond=None)[0]
    np.testing.assert_allclose(coef, np.rint(coef), atol=1e-6)
    assert {tuple(k) for k in np.rint(coef.T - coef.T.min(axis=0)).astype(int).tolist()} == {
        (i, j) for i in range(n1 + 1) for j in range(n2 + 1)
    }


@pytest.mark.slow
@pytest.mark.parametrize("steps", [3, -2])
def test_railing_copies_join_watertight(tmp_path, sample_dir, steps):
    cfg = _config(tmp_path, sample_dir, "railing", target={"steps": [steps]})
    rep = run_config(cfg, out_dir=tmp_path / "out", show_progress=False)
    written = load_asset(tmp_path / "out" / "retargeted.obj")  # OBJ vertices as written (not split by normal)
    res = trimesh.Trimesh(written.V, written.F, process=False)
    inp = load_mesh(sample_dir / "retarget-railing.obj")
    truth = json.loads((sample_dir / "retarget-railing.truth.json").read_text())
    # every seam closes (the input is closed), and each baluster is a stack of 5 closed boxes
    assert res.is_watertight
    parts = res.split(only_watertight=False)
    rails = 2
    assert len(parts) == rails + 5 * (truth["counts"]["balusters"] + steps)
    grow = np.ptp(res.vertices, axis=0)[0] - np.ptp(inp.vertices, axis=0)[0]
    assert grow == pytest.approx(steps * truth["lattice"][0][0], abs=1e-9)
    assert _no_invented_geometry(rep, tmp_path / "out", inp) <= 1e-6


@pytest.mark.slow
def test_textured_railing_keeps_its_uvs_material_and_texture(tmp_path, sample_dir):
    """The railing as an OBJ + MTL + PNG with a planar map (uv = (x, y) + (0.5, 0.5), a UV seam
    between its two halves by material): the output OBJ names an MTL beside it with the texture
    copied in, every face keeps its material, and its UVs are the input's map moved with its copy
    (uv - xy is one label shift per face, the same at its three corners)."""
    mesh = load_mesh(sample_dir / "retarget-railing.obj")
    V, F = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    half = (V[F].mean(axis=1)[:, 2] > np.median(V[:, 2])).astype(int)
    lines = ["mtllib rail.mtl"] + [f"v {x!r} {y!r} {z!r}" for x, y, z in V.tolist()]
    lines += [f"vt {x + 0.5!r} {y + 0.5!r}" for x, y, _ in V.tolist()]
    for m in (0, 1):
        lines.append(f"usemtl paint{m}")
        lines += [f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in (F[half == m] + 1).tolist()]
    (tmp_path / "rail.obj").write_text("\n".join(lines) + "\n")
    (tmp_path / "rail.mtl").write_text("newmtl paint0\nKd 1 1 1\nmap_Kd wood.png\nnewmtl paint1\nKd 0.5 0.5 0.5\n")
    save_image(tmp_path / "wood.png", np.random.default_rng(0).random((8, 8, 3)).astype(np.float32))
    cfg = tmp_path / "rail.yaml"
    cfg.write_text(json.dumps({"method": "retarget", "input": str(tmp_path / "rail.obj"), "seed": 0,
                               "target": {"steps": [2]}}))
    rep = run_config(cfg, out_dir=tmp_path / "out", show_progress=False)
    res = load_asset(tmp_path / "out" / "retargeted.obj")
    assert rep["status"] == "ok" and (tmp_path / "out" / "retargeted.mtl").is_file()
    assert [m.name for m in res.materials] == ["paint0", "paint1"] and res.materials[0].image is not None
    assert res.materials[1].image is None
    shift = res.corner_uv - 0.5 - res.V[res.F][:, :, :2]  # (k, 3, 2): minus the label's shift
    assert np.abs(shift - shift[:, :1]).max() <= 1e-5
    shifts = np.asarray(rep["metrics"]["label_shifts"]) @ np.asarray(rep["metrics"]["grid_basis_normalised"])
    shifts = shifts * rep["metrics"]["normalisation"]["scale"]
    gap = np.linalg.norm(-shift[:, 0, None, :] - shifts[None, :, :2], axis=2).min(axis=1)
    assert gap.max() <= 1e-5, gap.max()
    z_half = (res.V[res.F].mean(axis=1)[:, 2] > np.median(V[:, 2])).astype(int)
    assert np.all(res.face_material == z_half)


@pytest.mark.slow
def test_pinned_voxel_keeps_its_label(tmp_path, sample_dir):
    pin = {"voxel": [2, 3, 1], "shift": [0, 1, 0]}
    cfg = _config(tmp_path, sample_dir, "bookshelf", target={"axis_steps": {"y": 2}}, pins=[pin])
    rep = run_config(cfg, out_dir=tmp_path / "out", show_progress=False)
    vol = np.load(tmp_path / "out" / "labels.npy")
    shifts = [tuple(s) for s in rep["metrics"]["label_shifts"]]
    assert shifts[vol[2, 3, 1]] == (0, 1, 0)
    assert np.isfinite(rep["metrics"]["energy"])


def test_resolve_steps_names_the_target_entry():
    an = SimpleNamespace(n_principal=1, basis=np.diag([0.4, 0.2, 0.2]))  # one principal offset along x
    Vn = np.array([[-1.0, 0, 0], [1.0, 0.5, 0.2]])  # 5 steps of 0.4 along x
    keys: dict = {}
    assert resolve_steps(Target(None, {"x": 2, "y": 0}, None), an, Vn, keys=keys).tolist() == [2, 0, 0]
    assert keys == {0: "target.axis_steps.x=2"}
    assert resolve_steps(Target(None, None, [2.0]), an, Vn).tolist() == [5, 0, 0]
    with pytest.raises(KeyedError, match=r"^target.steps\[1\]=1: only 1 principal offset") as info:
        resolve_steps(Target([0, 1], None, None), an, Vn)
    assert isinstance(info.value, ValueError) and info.value.key == "target.steps[1]=1"
    with pytest.raises(KeyedError, match=r"^target.axis_steps.y=1: no principal offset was found"):
        resolve_steps(Target(None, {"y": 1}, None), SimpleNamespace(n_principal=0, basis=np.eye(3)), Vn)
    with pytest.raises(KeyedError, match=r"^target.axis_steps.z=1: no principal offset runs along z \(the nearest, "
                                         r"#0, is 90 degrees off it\)$"):
        resolve_steps(Target(None, {"z": 1}, None), an, Vn)


def test_offsets_found_names_each_offsets_length_and_axis():
    basis = np.array([[0.4, 0.0, 0.0], [0.0, 0.3, 0.0], [0.0, 0.1, 1.0]])  # columns: x, tilted y, z
    found = offsets_found(SimpleNamespace(n_principal=2, basis=basis))
    assert found == ("the model repeats by 2 principal offset(s) (#0 0.4 along x, #1 0.316 along y (18 degrees off); "
                     "normalised units)")


def test_options_map_every_analysis_key(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(json.dumps({"method": "retarget", "input": "m.obj", "label_margin": 1,
                               "analysis": {"tau": 0.2, "min_angle_deg": 45.0, "descriptor": "fpfh"}}))
    _, config, _ = load_method_config(cfg, check_files=False)
    analysis, synthesis, target = options_of(config)
    assert analysis == analysis_options(tau=0.2, min_angle=np.pi / 4, descriptor="fpfh")
    assert synthesis.label_margin == 1 and synthesis.descriptor == "fpfh" and target == Target([1], None, None)


def test_analysis_is_deterministic_for_a_seed():
    V, F, _ = samples.build_bridge()
    Vn, _, _ = normalize_unit(V)
    a, b = analyze(Vn, F, analysis_options(), rng=3), analyze(Vn, F, analysis_options(), rng=3)
    np.testing.assert_array_equal(a.offsets, b.offsets)
    np.testing.assert_array_equal(a.basis, b.basis)


def test_fpfh_descriptor_finds_the_railing_period():
    V, F, truth = samples.build_railing()
    Vn, _, scale = normalize_unit(V)
    an = analyze(Vn, F, analysis_options(descriptor="fpfh", descriptor_radius=0.1), rng=0)
    assert an.n_principal == 1
    np.testing.assert_allclose(np.abs(an.principal[0]) * scale, truth["lattice"][0], atol=1e-6)


def test_scale_target_rounds_to_steps(tmp_path, sample_dir):
    cfg = _config(tmp_path, sample_dir, "bridge", target={"scale": [1.45]})
    rep = run_config(cfg, out_dir=tmp_path / "out", show_progress=False, overrides=["analyze_only=false"])
    # the bridge spans about 5.4 periods (3.24 / 0.6): 45% more is round(2.43) = 2 steps
    assert rep["metrics"]["steps"] == [2, 0, 0]


@pytest.mark.slow
def test_regular_offsets_mode(tmp_path, sample_dir):
    cfg = _config(tmp_path, sample_dir, "bridge", target={"steps": [1]}, offsets="regular")
    rep = run_config(cfg, out_dir=tmp_path / "out", show_progress=False)
    m = rep["metrics"]
    # 0.6 model units = 0.37 normalised: 4 regular steps of 0.1
    assert m["steps"] == [4, 0, 0] and m["graph_labels"] == 5
    np.testing.assert_allclose(m["growth"], [0.4 * 0.6 / 0.37037037, 0, 0], rtol=1e-6)
    assert rep["timings"]["graphcut"] == rep["timings"]["regular_graphcut"]
    inp = load_mesh(sample_dir / "retarget-bridge.obj")
    assert _no_invented_geometry(rep, tmp_path / "out", inp) <= 1e-6


def test_analyze_only_writes_statistics(tmp_path, sample_dir):
    cfg = _config(tmp_path, sample_dir, "bridge")
    rep = run_config(cfg, out_dir=tmp_path / "out", show_progress=False, overrides=["analyze_only=true"])
    m = rep["metrics"]
    assert "graph_nodes" not in m and m["analyze_only"]
    np.testing.assert_allclose(np.abs(m["principal_offsets"][0]), [0.6, 0, 0], atol=0.006)
    assert 0 < m["sparsity_top7"] <= m["sparsity_top20"] <= 1
    assert (tmp_path / "out" / "sparsity.png").stat().st_size > 1000


# ---------------------------------------------------------------- bad input


def test_no_repetition_is_input_error(tmp_path):
    mesh = trimesh.creation.icosphere(subdivisions=3)
    rng = np.random.default_rng(0)
    mesh.vertices = mesh.vertices * (1 + 0.15 * rng.random((len(mesh.vertices), 1)))
    path = tmp_path / "blob.ply"
    mesh.export(path)
    cfg = tmp_path / "c.yaml"
    cfg.write_text(json.dumps({"method": "retarget", "input": str(path)}))
    with pytest.raises(InputError, match="no repetition found") as info:
        run_config(cfg, out_dir=tmp_path / "out", show_progress=False)
    assert info.value.exit_code == 3
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["status"] == "refused" and report["metrics"]["principal_offsets"] == []
    assert 0 < report["metrics"]["sparsity_top7"] <= 1
    assert (tmp_path / "out" / "sparsity.png").is_file()


def test_shrink_below_one_cell_and_dummy_steps(tmp_path, sample_dir):
    with pytest.raises(ConfigError, match=r"target.steps\[0\]=-6: would shrink below one cell") as info:
        run_config(_config(tmp_path, sample_dir, "bridge", target={"steps": [-6]}), out_dir=tmp_path / "a")
    assert info.value.exit_code == 2 and not (tmp_path / "a").exists()
    with pytest.raises(InputError, match=r"target.steps\[1\]=1: only 1 principal"):
        run_config(_config(tmp_path, sample_dir, "bridge", target={"steps": [0, 1]}), out_dir=tmp_path / "b")


def test_bad_pins_are_config_errors(tmp_path, sample_dir):
    pins = [{"voxel": [0, 0, 0], "shift": [1, 0, 0]}]
    cfg = _config(tmp_path, sample_dir, "bridge", target={"steps": [1]}, pins=pins)
    with pytest.raises(ConfigError, match=r"pins: pinned voxel \[0, 0, 0\] with shift \[1, 0, 0\] copies from outside"):
        run_config(cfg, out_dir=tmp_path / "out", show_progress=False)
    cfg = _config(
        tmp_path, sample_dir, "bridge", target={"steps": [1]}, pins=[{"voxel": [99, 0, 0], "shift": [0, 0, 0]}]
    )
    with pytest.raises(ConfigError, match="outside the output grid"):
        run_config(cfg, out_dir=tmp_path / "out2", show_progress=False)


def test_multi_mesh_scene_is_merged_and_said(tmp_path, caplog):
    V, F, truth = samples.build_bridge()
    half = len(F) // 2
    parts = [trimesh.Trimesh(V, F[:half], process=False), trimesh.Trimesh(V, F[half:], process=False)]
    for p in parts:
        p.remove_unreferenced_vertices()
    path = tmp_path / "two.glb"
    trimesh.Scene(parts).export(path)
    cfg = tmp_path / "two.yaml"
    cfg.write_text(json.dumps({"method": "retarget", "input": str(path), "analyze_only": True, "seed": 0}))
    with caplog.at_level("WARNING", logger="synthkit"):
        rep = run_config(cfg, out_dir=tmp_path / "out", show_progress=False)
    m = rep["metrics"]
    assert m["merged_meshes"] == 2 and m["input_faces"] == len(F)
    assert [r.getMessage() for r in caplog.records if r.levelname == "WARNING"] == [f"merged 2 meshes of {path}"]
    np.testing.assert_allclose(np.abs(m["principal_offsets"][0]), truth["lattice"][0], atol=0.006)


def test_single_mesh_reports_one_merged(tmp_path, sample_dir, caplog):
    with caplog.at_level("WARNING", logger="synthkit"):
        cfg = _config(tmp_path, sample_dir, "railing", analyze_only=True)
        rep = run_config(cfg, out_dir=tmp_path / "out", show_progress=False)
    assert rep["metrics"]["merged_meshes"] == 1
    assert not [r for r in caplog.records if "merged" in r.getMessage()]


def test_nan_and_empty_meshes(tmp_path):
    bad = tmp_path / "nan.obj"
    bad.write_text("v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n")
    empty = tmp_path / "empty.obj"
    empty.write_text("v 0 0 0\n")
    for path, msg in ((bad, "NaN"), (empty, "no")):
        cfg = tmp_path / f"{path.stem}.yaml"
        cfg.write_text(json.dumps({"method": "retarget", "input": str(path)}))
        with pytest.raises(InputError, match=msg):
            run_config(cfg, out_dir=tmp_path / f"out-{path.stem}", show_progress=False)


def _cli(tmp_path, mesh_text, name, suffix=".obj", **keys):
    """Run ``synthkit retarget`` through the CLI on a mesh written from ``mesh_text``."""
    mesh = tmp_path / f"{name}{suffix}"
    mesh.write_bytes(mesh_text if isinstance(mesh_text, bytes) else mesh_text.encode())
    cfg = tmp_path / f"{name}.yaml"
    cfg.write_text(json.dumps({"method": "retarget", "input": mesh.name, "seed": 0, **keys}))
    out = tmp_path / f"out-{name}"
    result = CliRunner().invoke(cli, ["retarget", str(cfg), "--out", str(out), "--no-progress"])
    return result, mesh, out


def _one_line_error(result, code, mesh, *needles):
    assert result.exit_code == code, (result.exit_code, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert str(mesh) in lines[0] and "Traceback" not in result.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]


@pytest.mark.parametrize(
    ("name", "text", "needles"),
    [
        # vertices and no faces at all: trimesh reads it as a point cloud
        ("vertices_only", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", ["mesh has no faces (3 vertices, no triangles)"]),
        ("two_corner_faces", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\nf 2 3\n",
         ["line 4: malformed OBJ statement: 'f' needs 3 corners"]),
        ("zero_area", "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3\nf 2 3 4\n",
         ["every triangle has zero area (2 faces)"]),
        ("one_point", "v 0.5 0.5 0.5\nv 0.5 0.5 0.5\nv 0.5 0.5 0.5\nf 1 2 3\n", ["every triangle has zero area"]),
        ("nan", "v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n", ["line 2: malformed OBJ statement: 'v' has a NaN"]),
    ],
)
def test_cli_bad_meshes_exit_3_one_line(tmp_path, name, text, needles):
    result, mesh, out = _cli(tmp_path, text, name)
    _one_line_error(result, 3, mesh, *needles)
    assert not out.exists() and not list(tmp_path.glob(".out-*"))


def test_cli_ply_without_faces_exit_3(tmp_path):
    text = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 0\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n")
    result, mesh, out = _cli(tmp_path, text, "no_faces", suffix=".ply")
    _one_line_error(result, 3, mesh, "file holds no triangle mesh")
    assert not out.exists()


def test_cli_no_repetition_exit_3_keeps_statistics(tmp_path):
    mesh = trimesh.creation.icosphere(subdivisions=3)
    rng = np.random.default_rng(0)
    mesh.vertices = mesh.vertices * (1 + 0.15 * rng.random((len(mesh.vertices), 1)))
    result, path, out = _cli(tmp_path, trimesh.exchange.ply.export_ply(mesh), "blob", suffix=".ply")
    _one_line_error(result, 3, path, "no repetition found", "refusing to resize")
    report = json.loads((out / "report.json").read_text())  # the documented refused-with-statistics case
    assert report["status"] == "refused" and (out / "sparsity.png").is_file()
    assert not any(n.startswith("retargeted") for n in report["outputs"].values())


@pytest.mark.slow
def test_cli_shrink_below_one_cell_exit_2(tmp_path, sample_dir):
    text = (sample_dir / "retarget-bridge.obj").read_bytes()
    result, mesh, out = _cli(tmp_path, text, "bridge", target={"steps": [-6]})
    _one_line_error(result, 2, mesh, "target.steps[0]=-6", "would shrink below one cell")
    assert not out.exists() and not list(tmp_path.glob(".out-*"))
    result, mesh, out = _cli(tmp_path, text, "bridge2", target={"axis_steps": {"x": -5}})
    _one_line_error(result, 2, mesh, "target.axis_steps.x=-5", "would shrink below one cell")
    assert not out.exists()


@pytest.mark.slow
@pytest.mark.skipif(not KENNEY.is_dir(), reason="../shared/data/meshes/kenney-city absent")
def test_kenney_building_offsets_and_output(tmp_path):
    """building-small-a along its wall slide (0.1 up). Since issue 15 the default analysis reports
    the floor height (0.4 up, tests/methods/test_retarget_real.py) and growing by a floor has no
    seamless labeling (the hollow storey between the full base slab and the full roof), so this
    stitching test turns the grip rule of ``reduce_to_generators`` off to keep the slide."""
    path = KENNEY / "building-small-a.glb"
    cfg = tmp_path / "k.yaml"
    cfg.write_text(json.dumps({"method": "retarget", "input": str(path), "target": {"steps": [1]},
                               "analysis": {"generator_grip_ratio": 0}}))
    rep = run_config(cfg, out_dir=tmp_path / "out", show_progress=False)
    m = rep["metrics"]
    offsets = np.array(m["principal_offsets"])
    found = f"building-small-a principal offsets (model units) {offsets.round(4).tolist()}"
    found += f", top7 {m['sparsity_top7']:.3f}"
    assert len(offsets) >= 1 and np.all(np.linalg.norm(offsets, axis=1) > 0.05), found
    # each principal offset maps a real share of the model onto itself (checked metrics of the report)
    principal = [d for d in m["dominant_offsets"] if d["principal"]]
    assert len(principal) == len(offsets) and all(d["overlap"] >= 0.15 and d["count"] >= 5 for d in principal), found
    res = load_mesh(tmp_path / "out" / "retargeted.glb")
    inp = load_mesh(path)
    assert len(res.faces) > len(inp.faces) // 2, found
    grow = np.ptp(res.vertices, axis=0) - np.ptp(inp.vertices, axis=0)
    np.testing.assert_allclose(grow, np.array(m["growth"]), atol=1e-5, err_msg=found)
    np.testing.assert_allclose(grow, offsets[0] * m["steps"][0], atol=1e-5, err_msg=found)

    def boundary_edges(V, F):
        Vw, Fw = weld(np.asarray(V), np.asarray(F), 1e-6)  # by position: the asset's UV seams do not count
        E = np.sort(np.concatenate([Fw[:, [0, 1]], Fw[:, [1, 2]], Fw[:, [2, 0]]]), axis=1)
        _, counts = np.unique(E, axis=0, return_counts=True)
        return int((counts == 1).sum()), len(Fw)

    # welded: the seams add few open edges: at most the input's per copy (issue 15; the output's flat
    # regions are re-triangulated with fewer faces, so the former per-face ratio no longer applies)
    b_in, f_in = boundary_edges(inp.vertices, inp.faces)
    b_out, f_out = boundary_edges(res.vertices, res.faces)
    assert b_out <= b_in * m["copies"], (found, b_in, f_in, b_out, f_out, m["copies"])
    # and no two copies meet at an unwelded vertex: of two coincident vertices, one used only by some
    # labels' faces and the other only by other labels' faces, the seam would be open (a vertex
    # shared across a seam is used by both; the asset's own duplicates share a label)
    lm, labels, _ = _labels_ply(tmp_path / "out" / "labels.ply")
    LV, LF = np.asarray(lm.vertices, dtype=np.float64), np.asarray(lm.faces)
    assert len(np.unique(labels)) >= 2 and labels.max() < 63
    used_by = np.zeros(len(LV), np.int64)
    np.bitwise_or.at(used_by, LF.reshape(-1), np.left_shift(1, np.repeat(labels.astype(np.int64), 3)))
    pairs = cKDTree(LV).query_pairs(1e-6 * m["normalisation"]["scale"] + 1e-6, output_type="ndarray")  # float32 file
    a, b = used_by[pairs[:, 0]], used_by[pairs[:, 1]]
    open_seams = int(((a != 0) & (b != 0) & ((a & b) == 0)).sum())
    assert open_seams == 0, (found, open_seams)


@pytest.mark.slow
@pytest.mark.skipif(not KENNEY.is_dir(), reason="../shared/data/meshes/kenney-city absent")
def test_kenney_other_pieces_statistics_and_refusals(tmp_path):
    """The other Kenney pieces: building-small-b repeats its 0.4-unit floor (walls slide, so no
    horizontal offset grips); growing it by a floor leaves no seamless labeling (the roof) and is
    refused with exit 3; the road tiles hold no repetition and are refused with their statistics."""
    found = {}
    for name in ("building-small-b", "road-straight", "road-corner"):
        cfg = tmp_path / f"{name}.yaml"
        spec = {"method": "retarget", "input": str(KENNEY / f"{name}.glb"), "target": {"steps": [1]}}
        cfg.write_text(json.dumps(spec))
        result = CliRunner().invoke(cli, ["retarget", str(cfg), "--out", str(tmp_path / name), "--no-progress"])
        assert result.exit_code == 3 and "Traceback" not in result.stderr, (name, result.stderr)
        found[name] = result.stderr.strip()
    assert "no seamless retargeting for steps [1, 0, 0]" in found["building-small-b"], found
    assert "; the model repeats by 1 principal offset(s) (#0 0.492 along y; normalised units); one step along any of " \
           "them, or back, has no seamless labeling either" in found["building-small-b"], found
    for road in ("road-straight", "road-corner"):
        assert "no repetition found" in found[road], found
        rep = json.loads((tmp_path / road / "report.json").read_text())
        assert rep["status"] == "refused" and rep["metrics"]["principal_offsets"] == []
        assert 0.0 < rep["metrics"]["sparsity_top7"] < 0.7, found  # less sparse than man-made repetition
    cfg = tmp_path / "b.yaml"
    cfg.write_text(json.dumps({"method": "retarget", "input": str(KENNEY / "building-small-b.glb"),
                               "analyze_only": True}))
    m = run_config(cfg, out_dir=tmp_path / "b", show_progress=False)["metrics"]
    offsets = np.array(m["principal_offsets"])
    np.testing.assert_allclose(offsets, [[0.0, 0.4, 0.0]], atol=1e-6, err_msg=str(offsets.tolist()))
    horizontal = [d for d in m["dominant_offsets"] if abs(d["offset"][1]) < 1e-3]
    assert horizontal and all(d["grip"] < 0.005 and not d["principal"] for d in horizontal)


@pytest.mark.slow
@pytest.mark.skipif(not (KENNEY.parent / "bunny_small.ply").is_file(), reason="../shared/data/meshes absent")
def test_natural_shape_is_refused_with_less_sparse_statistics(tmp_path):
    cfg = tmp_path / "b.yaml"
    cfg.write_text(json.dumps({"method": "retarget", "input": str(KENNEY.parent / "bunny_small.ply")}))
    with pytest.raises(InputError, match="no repetition found"):
        run_config(cfg, out_dir=tmp_path / "out", show_progress=False)
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    # the paper's natural objects: 40% in the top 7% against 80% for man-made ones
    assert report["metrics"]["sparsity_top7"] < min(_analysed(n)[0].top7 for n in ("railing", "bookshelf"))


def test_working_steps_is_the_nearest_seamless_request():
    """On the bookshelf (two principal offsets, both repeat seamlessly) the nearest request after a
    refused one is one step along the first offset, or the second when the first was the one tried."""
    from synthkit.methods.retarget.problem import working_steps

    an, _, _ = _analysed("bookshelf")
    V, F, _ = samples.SAMPLES["bookshelf"][0]()
    Vn = normalize_unit(V)[0]
    _, opt, _ = options_of(RetargetConfig.model_construct())
    assert an.n_principal == 2
    assert working_steps(Vn, F, an, opt, np.random.default_rng(0), np.zeros(3)).tolist() == [1, 0, 0]
    assert working_steps(Vn, F, an, opt, np.random.default_rng(0), np.array([1, 0, 0])).tolist() == [0, 1, 0]
