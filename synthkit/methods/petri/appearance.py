"""The example's look carried through petri-synth: per-corner UVs and colours, per-face materials.

Arrays in the form of :class:`synthkit.asset.Asset`: ``corner_uv (m, 3, 2) float64``,
``corner_color (m, 3, 4) float64`` (kept as floats while interpolated, rounded to uint8 when
written), ``face_material (m,) int64``. A face cut out of an example face takes, at each corner, the
example face's values interpolated at that corner (barycentric coordinates in the source triangle),
so a cut point between two corners gets the values between theirs; deformation moves positions only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from synthkit.core.mesh import barycentric


@dataclass
class Look:
    """Per-face appearance of ``m`` faces (any field None when the example has none of it)."""

    corner_uv: np.ndarray | None
    corner_color: np.ndarray | None
    face_material: np.ndarray

    def take(self, idx) -> Look:
        """The look of the faces ``idx`` (an index array or a boolean mask)."""
        return Look(
            None if self.corner_uv is None else self.corner_uv[idx],
            None if self.corner_color is None else self.corner_color[idx],
            self.face_material[idx],
        )

    def corners(self) -> list[np.ndarray | None]:
        """The per-corner arrays ``[corner_uv, corner_color]``."""
        return [self.corner_uv, self.corner_color]

    def written(self) -> dict:
        """Keyword arguments of :func:`synthkit.io.assets.save_asset` for these faces."""
        color = None
        if self.corner_color is not None:
            color = np.clip(np.round(self.corner_color), 0, 255).astype(np.uint8)
        return {"corner_uv": self.corner_uv, "corner_color": color, "face_material": self.face_material}


def concat(looks: list[Look], like: Look) -> Look:
    """One look of the faces of ``looks`` in order (``like`` gives which fields exist when empty)."""
    if not looks:
        return like.take(np.zeros(0, np.int64))
    uv = None if like.corner_uv is None else np.concatenate([lk.corner_uv for lk in looks])
    col = None if like.corner_color is None else np.concatenate([lk.corner_color for lk in looks])
    return Look(uv, col, np.concatenate([lk.face_material for lk in looks]))


def example_look(corner_uv, corner_color, face_material, n_faces: int) -> Look:
    """The look of an example's ``n_faces`` faces from an asset's arrays (colours as floats)."""
    col = None if corner_color is None else np.asarray(corner_color, np.float64)
    uv = None if corner_uv is None else np.asarray(corner_uv, np.float64)
    mat = np.zeros(n_faces, np.int64) if face_material is None else np.asarray(face_material, np.int64)
    return Look(uv, col, mat)


def carry(look: Look, V: np.ndarray, F: np.ndarray, src: np.ndarray, V2: np.ndarray, F2: np.ndarray) -> Look:
    """The look of faces ``F2 (m, 3)`` over ``V2`` cut out of the example faces ``src (m,)`` of ``V, F``
    (``src = -1``: a cap face, which takes at each corner the values some non-cap face has at that
    vertex, and the material of the example's first face when no such face exists)."""
    real = src >= 0
    s = np.where(real, src, 0)
    out = [None, None]
    if any(arr is not None for arr in look.corners()):
        B = barycentric(np.asarray(V, np.float64)[F[s]], np.asarray(V2, np.float64)[F2])
        out = [None if arr is None else np.einsum("mcb,mbk->mck", B, arr[s]) for arr in look.corners()]
    mat = look.face_material[s].copy()
    if not real.all():
        _fill_caps(F2, real, out, mat)
    return Look(out[0], out[1], mat)


def _fill_caps(F2: np.ndarray, real: np.ndarray, arrays: list, mat: np.ndarray) -> None:
    """Give the cap faces (``~real``) per-corner values from a non-cap face at the same vertex and
    the material of one such face (in place)."""
    corner_face = np.repeat(np.arange(len(F2)), 3)
    corner_vertex = F2.ravel()
    good = np.repeat(real, 3)
    first = np.full(int(F2.max()) + 1 if len(F2) else 0, -1, np.int64)
    first[corner_vertex[good][::-1]] = np.flatnonzero(good)[::-1]
    caps = np.flatnonzero(~real)
    for arr in arrays:
        if arr is None:
            continue
        flat = arr.reshape(-1, arr.shape[2])
        src_corner = first[F2[caps].ravel()]
        vals = np.where((src_corner >= 0)[:, None], flat[np.maximum(src_corner, 0)], 0.0)
        arr[caps] = vals.reshape(len(caps), 3, -1)
    src_corner = first[F2[caps]].max(axis=1)
    mat[caps] = np.where(src_corner >= 0, mat[corner_face[np.maximum(src_corner, 0)]], mat[caps])
