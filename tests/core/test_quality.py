"""Mesh-quality figures on tiny meshes with known answers."""

import numpy as np
import pytest

from synthkit.core.quality import QUALITY_FIGURES, degenerate_faces, mesh_quality

TETRA_V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
TETRA_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def test_closed_tetrahedron_is_clean():
    q = mesh_quality(TETRA_V, TETRA_F)
    assert q == {"faces": 4, "open_edges": 0, "nonmanifold_edges": 0, "degenerate_faces": 0,
                 "duplicate_faces": 0, "components": 1, "loose_vertices": 0}
    assert tuple(q) == QUALITY_FIGURES


def test_loose_vertices_are_counted():
    V = np.vstack([TETRA_V, [[5.0, 5, 5], [6.0, 5, 5]]])
    assert mesh_quality(V, TETRA_F)["loose_vertices"] == 2


def test_open_square_and_two_components():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    F = np.array([[0, 1, 2], [0, 2, 3]])
    assert mesh_quality(V, F)["open_edges"] == 4
    V2 = np.vstack([V, V + [5, 0, 0]])
    F2 = np.vstack([F, F + 4])
    q = mesh_quality(V2, F2)
    assert (q["open_edges"], q["components"]) == (8, 2)


def test_uv_seam_copies_are_welded():
    """A tetrahedron whose vertex 0 is stored twice (a UV seam) is still closed."""
    V = np.vstack([TETRA_V, TETRA_V[:1]])
    F = TETRA_F.copy()
    F[2, 0] = 4
    assert mesh_quality(V, F)["open_edges"] == 0


def test_nonmanifold_duplicate_and_degenerate_faces():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [2, 0, 0]])
    fan = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])  # three faces on edge 0-1
    q = mesh_quality(V, fan)
    assert q["nonmanifold_edges"] == 1
    dup = np.vstack([TETRA_F, [[2, 1, 0]]])  # face 0 again, rotated: a surface stored twice
    assert mesh_quality(TETRA_V, dup)["duplicate_faces"] == 1
    back = np.vstack([TETRA_F, [[0, 1, 2]]])  # the opposite side: a double-sided wall, not a duplicate
    assert mesh_quality(TETRA_V, back)["duplicate_faces"] == 0
    flat = np.array([[0, 1, 5]])  # three collinear points
    assert degenerate_faces(V, flat).tolist() == [True]
    assert mesh_quality(V, flat)["degenerate_faces"] == 1


def test_needle_below_tolerance_is_degenerate_and_above_is_not():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 1e-12, 0], [0.5, 1e-6, 0], [0, 1, 0]])
    F = np.array([[0, 1, 2], [0, 1, 3], [0, 1, 4]])
    assert degenerate_faces(V, F).tolist() == [True, False, False]


@pytest.mark.parametrize("F", [np.zeros((0, 3), int)])
def test_empty_mesh(F):
    assert mesh_quality(np.zeros((0, 3)), F)["faces"] == 0
