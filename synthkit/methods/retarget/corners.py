"""Per-corner appearance carried through retargeting's geometry (issue 22).

Every face retargeting writes lies in the plane of one input face (a copy of it, a piece of it cut
by a seam plane or split at a T-junction, or a face of a flat region re-triangulated from faces
with one affine appearance map), so its corners' values (texture coordinates, vertex colours) are
those of that input face's affine map at the corner: barycentric coordinates of the corner in the
source triangle (least squares in its plane, extrapolated when a seam collapse moved a corner a
little outside) weight the source corners' values. Values are stacked as ``attr (m, 3, k)``
float64 (:func:`pack`): the material index, then 2 columns for UVs and 4 for colours in [0, 1]
when the input has them.
"""

from __future__ import annotations

import numpy as np

from synthkit.core.mesh import barycentric

__all__ = ["ATTR_TOL", "carry", "carry_at", "same_map", "pack", "unpack"]

ATTR_TOL = 1e-5
"""Two corner values agree within this (UV units, colours scaled to [0, 1]): glTF stores float32
texture coordinates, so an affine map read back from a file is exact only to about 1e-6."""


def carry(V, F_new, F_old, src, attr_old) -> np.ndarray | None:
    """``attr (m2, 3, k)`` of the faces ``F_new (m2, 3)`` of ``V (n, 3)``, each in the plane of the
    face ``F_old[src]`` (``src (m2,)``) whose corner values are ``attr_old (m1, 3, k)``: the source
    face's affine map evaluated at the new corners. None when ``attr_old`` is None."""
    if attr_old is None:
        return None
    V = np.asarray(V, dtype=np.float64)
    F_new = np.asarray(F_new, dtype=np.int64).reshape(-1, 3)
    src = np.asarray(src, dtype=np.int64).reshape(-1)
    return carry_at(V[F_new], V[np.asarray(F_old, dtype=np.int64).reshape(-1, 3)[src]], attr_old[src])


def carry_at(P, T, X) -> np.ndarray:
    """``(m, j, k)`` values at the points ``P (m, j, 3)`` of the affine maps of the triangles
    ``T (m, 3, 3)`` with corner values ``X (m, 3, k)``."""
    if len(P) == 0:
        return np.zeros((0, np.shape(P)[1], X.shape[2]))
    return np.einsum("mjc,mck->mjk", barycentric(T, P), X)


def same_map(PA, XA, PB, XB, *, tol: float = ATTR_TOL) -> np.ndarray:
    """``(m,) bool``: face B's corner values ``XB (m, 3, k)`` at its corners ``PB (m, 3, 3)`` are
    those of face A's affine map (corners ``PA (m, 3, 3)``, values ``XA (m, 3, k)``), within
    ``tol``: the two faces show one continuous, affine appearance (a flat region of one texture
    chart, a palette swatch, one colour gradient)."""
    if XA is None or XA.shape[2] == 0 or len(PA) == 0:
        return np.ones(len(PA), bool)
    return np.abs(carry_at(PB, PA, XA) - XB).max(axis=(1, 2)) <= tol


def pack(face_material, corner_uv, corner_color) -> np.ndarray:
    """``attr (m, 3, k)``: per corner the face's material index (constant over the face, so two
    faces share an affine map only when they share a material, and every carried value of it is the
    index again), then ``corner_uv (m, 3, 2)`` and ``corner_color (m, 3, 4) uint8`` scaled to
    [0, 1] when given (either may be None)."""
    mat = np.asarray(face_material, dtype=np.float64).reshape(-1)
    parts = [np.repeat(mat[:, None, None], 3, axis=1)]
    if corner_uv is not None:
        parts.append(np.asarray(corner_uv, dtype=np.float64))
    if corner_color is not None:
        parts.append(np.asarray(corner_color, dtype=np.float64) / 255.0)
    return np.concatenate(parts, axis=2)


def unpack(attr, has_uv: bool, has_color: bool) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """``(face_material (m,) int64, corner_uv (m, 3, 2) or None, corner_color (m, 3, 4) uint8 or
    None)`` from :func:`pack`'s layout; the material is the rounded mean over the corners, colours
    are rounded and clipped to 0..255."""
    mat = np.rint(attr[:, :, 0].mean(axis=1)).astype(np.int64)
    uv = attr[:, :, 1:3] if has_uv else None
    color = None
    if has_color:
        start = 3 if has_uv else 1
        color = np.clip(np.rint(attr[:, :, start : start + 4] * 255.0), 0, 255).astype(np.uint8)
    return mat, uv, color
