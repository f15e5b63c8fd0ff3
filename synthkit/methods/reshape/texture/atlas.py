"""One atlas per input material.

The texture stage bakes one patch per reshaped surface, at the source's texel density. Instead of
writing each patch as its own material and PNG, :func:`pack_atlas` packs the source texture (the
untouched surfaces keep their texels) and the patches into one image on shelves (first fit,
tallest first, in the narrowest of a few widths that gives the smallest atlas), each with a
``PAD``-texel border copied from its edge so that bilinear sampling never reads a neighbour. UVs
map into the atlas with :func:`to_atlas`. Same texel density as the input, one PNG per material.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PAD", "Placement", "pack_atlas", "to_atlas"]

PAD = 2
"""Texels of edge-copied border around each patch."""


@dataclass
class Placement:
    """Where an image sits in the atlas: top-left texel ``(x, y)`` and size ``(w, h)``."""

    x: int
    y: int
    w: int
    h: int


def _shelves(sizes: list[tuple[int, int]], width: int) -> tuple[list[tuple[int, int]], int]:
    """First-fit decreasing-height shelf packing of padded ``sizes`` ``(h, w)`` into ``width``:
    top-left ``(x, y)`` of each (input order) and the total height. Each item goes on the first
    shelf with room left, else opens a shelf below."""
    order = sorted(range(len(sizes)), key=lambda i: (-sizes[i][0], -sizes[i][1], i))
    spots: list[tuple[int, int]] = [(0, 0)] * len(sizes)
    shelves: list[list[int]] = []  # [y, height, x used]
    for i in order:
        h, w = sizes[i]
        shelf = next((s for s in shelves if s[2] + w <= width), None)
        if shelf is None:
            shelf = [sum(s[1] for s in shelves), h, 0]
            shelves.append(shelf)
        spots[i] = (shelf[2], shelf[0])
        shelf[2] += w
    return spots, sum(s[1] for s in shelves)


def pack_atlas(source: np.ndarray, patches: list[np.ndarray]) -> tuple[np.ndarray, Placement, list[Placement]]:
    """Atlas ``(Ha, Wa, 3)`` of ``source (H, W, 3)`` and ``patches`` (each ``(h, w, 3)``), the
    source's placement and each patch's (in input order). Every image gets a ``PAD`` border copied
    from its edge and is packed by :func:`_shelves`; the widths tried are the widest image, 1, 1.25,
    1.5 and 2 times the side of a square of the images' area and the widths of the first k images
    tallest first (up to twice that side: a first shelf filled exactly); the smallest atlas wins
    (ties: the narrower)."""
    images = [source] + list(patches)
    sizes = [(im.shape[0] + 2 * PAD, im.shape[1] + 2 * PAD) for im in images]
    widest = max(w for _, w in sizes)
    side = float(np.sqrt(sum(h * w for h, w in sizes)))
    tallest_first = sorted(sizes, key=lambda s: (-s[0], -s[1]))
    first_shelf = {int(w) for w in np.cumsum([w for _, w in tallest_first]) if w <= 2 * side}
    best = None
    for width in sorted({max(widest, int(np.ceil(k * side))) for k in (1.0, 1.25, 1.5, 2.0)} | {widest}
                        | {w for w in first_shelf if w >= widest}):
        spots, height = _shelves(sizes, width)
        if best is None or height * width < best[0]:
            best = (height * width, width, height, spots)
    _, width, height, spots = best
    atlas = np.zeros((height, width, source.shape[2]), source.dtype)
    placed = []
    for im, (x, y) in zip(images, spots, strict=True):
        h, w = im.shape[:2]
        atlas[y:y + h + 2 * PAD, x:x + w + 2 * PAD] = np.pad(im, ((PAD, PAD), (PAD, PAD), (0, 0)), mode="edge")
        placed.append(Placement(x + PAD, y + PAD, w, h))
    return atlas, placed[0], placed[1:]


def to_atlas(UV: np.ndarray, spot: Placement, shape) -> np.ndarray:
    """UVs ``(c, 2)`` of an image (OBJ convention: v up) placed at ``spot`` in an atlas of
    ``shape (Ha, Wa, ...)``, as atlas UVs ``(c, 2)``."""
    Ha, Wa = shape[:2]
    x = spot.x + UV[:, 0] * spot.w
    row = spot.y + (1.0 - UV[:, 1]) * spot.h
    return np.column_stack([x / Wa, 1.0 - row / Ha])
