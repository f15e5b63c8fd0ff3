"""Toroidal tiles cut from an image: minimum-error boundary cuts and a gradient-domain seam fix.

A tile is made periodic by overlapping the image's opposite borders (as neighbouring patches
overlap in image quilting, Efros and Freeman 2001): the last ``overlap`` columns are laid over
the first ones and a minimum-error boundary cut through the overlap decides which copy each pixel
shows, then the same for the rows. Where the copies meet (the cut, and the wrap wherever the cut
runs along it) the tiling has its seams; :func:`seam_masks` finds them from the tile's source map
(each pixel's position in the image) and :func:`fix_seams` makes each step across them
interior-like by a least-squares correction of the nearby pixels. All functions are pure.
"""

from __future__ import annotations

import cv2
import numpy as np
import scipy.sparse as sparse
import scipy.sparse.linalg as sparse_linalg

from synthkit.core.quilting import min_vertical_cuts

__all__ = ["cut_tile", "seam_masks", "fix_seams"]


def _cut_columns(img: np.ndarray, src: np.ndarray, overlap: int) -> tuple[np.ndarray, np.ndarray]:
    """Tile ``(H, W - overlap, C)`` periodic across its columns, and its source map ``(H, W - overlap, 2)``.

    Columns ``W - overlap + k`` are laid over columns ``k`` (``k < overlap``); each row's pixels left
    of the minimum-error cut show the laid-over copy, which continues the tile's last column."""
    W = img.shape[1]
    a, b = img[:, :overlap], img[:, W - overlap :]
    err = ((a - b) ** 2).sum(axis=-1)
    path = min_vertical_cuts(err[None])[0]
    take_b = (np.arange(overlap)[None, :] < path[:, None])[..., None]
    tile = img[:, : W - overlap].copy()
    tile[:, :overlap] = np.where(take_b, b, a)
    source = src[:, : W - overlap].copy()
    source[:, :overlap] = np.where(take_b, src[:, W - overlap :], src[:, :overlap])
    return tile, source


def cut_tile(img: np.ndarray, overlap: int) -> tuple[np.ndarray, np.ndarray]:
    """Toroidal tile of ``img (H, W[, C])`` by minimum-error boundary cuts across both wraps.

    Returns the tile ``(H - overlap, W - overlap[, C])`` (``img``'s dtype) and its source map
    ``(H - overlap, W - overlap, 2) int64``: the (row, column) of ``img`` each pixel shows. The cut
    through the column overlap is the dynamic-programming path of least summed squared difference
    between the two copies (summed over channels); the row cut runs on the column-cut tile.
    """
    arr = np.asarray(img)
    H, W = arr.shape[:2]
    if not (overlap >= 1 and 2 * overlap < min(H, W)):
        raise ValueError(f"cut overlap {overlap} must be at least 1 and below half of the {H}x{W} image")
    flat = arr.reshape(H, W, -1)
    src = np.stack(np.mgrid[0:H, 0:W], axis=2)
    tile, source = _cut_columns(flat, src, overlap)
    tile_t, source_t = _cut_columns(tile.transpose(1, 0, 2), source.transpose(1, 0, 2), overlap)
    tile, source = tile_t.transpose(1, 0, 2), source_t.transpose(1, 0, 2)
    shape = tile.shape[:2] + arr.shape[2:]
    return np.ascontiguousarray(tile).reshape(shape), np.ascontiguousarray(source)


def seam_masks(source: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Seam steps of a toroidal tile with source map ``source (h, w, 2)``: ``(mx, my)``, ``(h, w) bool``.

    ``mx[y, x]`` marks the step from pixel ``(y, x)`` to ``(y, (x + 1) % w)`` when the two do not
    show horizontally neighbouring image pixels; ``my`` likewise for ``((y + 1) % h, x)``. For a
    plain image (the identity map) the seams are the wrap-around steps: the last column and row.
    """
    s = np.asarray(source)
    right = np.roll(s, -1, axis=1) - s
    down = np.roll(s, -1, axis=0) - s
    mx = (right[..., 0] != 0) | (right[..., 1] != 1)
    my = (down[..., 0] != 1) | (down[..., 1] != 0)
    return mx, my


def _step_equations(index, seam, axis, weight):
    """The step equations along ``axis`` (1: x, 0: y) that involve an unknown pixel (``index >= 0``):
    their pixels ``(m, 4, 2)`` (steps -1, 0, +1, +2 along the axis), coefficients ``(m, 4)`` and
    seam flags ``(m,)``. A natural step keeps its value (its correction is 0: pixels 0 and +1);
    a seam step is set to the mean of its two neighbouring steps (``weight`` times)."""
    h, w = index.shape
    yy, xx = np.mgrid[0:h, 0:w]
    offs = np.array([-1, 0, 1, 2])

    def at(k):
        return (yy, (xx + k) % w) if axis == 1 else ((yy + k) % h, xx)

    touched = (index[at(0)] >= 0) | (index[at(1)] >= 0)
    natural = np.array([0.0, -1.0, 1.0, 0.0])
    across = weight * np.array([0.5, -1.5, 1.5, -0.5])
    coefs = np.where(seam[..., None], across, natural)
    keep = touched | (seam & np.any([index[at(k)] >= 0 for k in offs], axis=0))
    pix = np.stack([np.stack(at(k), -1) for k in offs], axis=2)[keep]  # (m, 4, 2)
    return pix, coefs[keep], seam[keep]


def fix_seams(tile: np.ndarray, source: np.ndarray, *, radius: int = 8, weight: float = 30.0) -> np.ndarray:
    """Correct ``tile (h, w[, C])`` near its seams (:func:`seam_masks` of ``source``) so each step
    across a seam is the mean of its two neighbouring steps, as :func:`toroidal_blend
    <synthkit.methods.symtex.tile.toroidal_blend>` makes the wrap's.

    Unknowns are the corrections of the pixels within ``radius`` of a seam step (Chebyshev
    distance); the others are fixed. Least squares over every step touching an unknown: a seam
    step's condition (weight ``weight``: it holds to a few percent of the step) and every other
    step's own value (weight 1: the correction is as smooth as it can be), plus ``1e-9 |c|^2``,
    which picks the smallest correction when no fixed pixel anchors it (a tile within
    ``radius`` of seams everywhere). Returns float32, clipped to [0, 1].
    """
    arr = np.asarray(tile, dtype=np.float64)
    h, w = arr.shape[:2]
    flat = arr.reshape(h, w, -1)
    mx, my = seam_masks(source)
    ends = mx | np.roll(mx, 1, axis=1) | my | np.roll(my, 1, axis=0)
    r = int(radius)
    wrapped = np.pad(ends.astype(np.uint8), r, mode="wrap")
    near = cv2.dilate(wrapped, np.ones((2 * r + 1, 2 * r + 1), np.uint8))[r : r + h, r : r + w] > 0
    index = np.full((h, w), -1, dtype=np.int64)
    index[near] = np.arange(int(near.sum()))
    parts = [_step_equations(index, m, ax, weight) for m, ax in ((mx, 1), (my, 0))]
    pix, coefs, on_seam = (np.concatenate(p) for p in zip(*parts, strict=True))
    cols = index[pix[..., 0], pix[..., 1]]
    # a seam step's condition on the corrected tile, coefs . (v + c) = 0; natural steps: c1 - c0 = 0
    rhs = -np.einsum("mk,mkc->mc", coefs, flat[pix[..., 0], pix[..., 1]]) * on_seam[:, None]
    rows = np.repeat(np.arange(len(cols)), 4).reshape(-1, 4)
    known = cols >= 0
    A = sparse.csr_matrix((coefs[known], (rows[known], cols[known])), shape=(len(cols), int(near.sum())))
    normal = (A.T @ A + 1e-9 * sparse.identity(A.shape[1])).tocsc()
    c = sparse_linalg.splu(normal).solve(np.asarray(A.T @ rhs))
    out = flat.copy()
    out[near] += c
    return np.clip(out.reshape(arr.shape), 0.0, 1.0).astype(np.float32)
