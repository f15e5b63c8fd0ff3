"""One atlas per input material (issue 22 item 3, issue 23 item 5).

The texture stage bakes one patch per reshaped surface, at the source's texel density. Instead of
writing each patch as its own material and PNG, :func:`pack_atlas` stacks the source texture and
the patches into one image: the source on top at its own size (the untouched surfaces keep their
texels), the patches below it on shelves (tallest first, left to right), each with a
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


def pack_atlas(source: np.ndarray, patches: list[np.ndarray]) -> tuple[np.ndarray, Placement, list[Placement]]:
    """Atlas ``(Ha, Wa, 3)`` of ``source (H, W, 3)`` on top and ``patches`` (each ``(h, w, 3)``) on
    shelves below, the source's placement and each patch's (in input order)."""
    H, W = source.shape[:2]
    width = max([W] + [p.shape[1] + 2 * PAD for p in patches])
    order = sorted(range(len(patches)), key=lambda i: (-patches[i].shape[0], i))
    spots: list[Placement | None] = [None] * len(patches)
    x, y, shelf = 0, H, 0
    for i in order:
        h, w = patches[i].shape[:2]
        if x + w + 2 * PAD > width:
            x, y, shelf = 0, y + shelf, 0
        spots[i] = Placement(x + PAD, y + PAD, w, h)
        x += w + 2 * PAD
        shelf = max(shelf, h + 2 * PAD)
    atlas = np.zeros((y + shelf, width, source.shape[2]), source.dtype)
    atlas[:H, :W] = source
    for p, s in zip(patches, spots, strict=True):
        padded = np.pad(p, ((PAD, PAD), (PAD, PAD), (0, 0)), mode="edge")
        atlas[s.y - PAD:s.y + s.h + PAD, s.x - PAD:s.x + s.w + PAD] = padded
    return atlas, Placement(0, 0, W, H), spots


def to_atlas(UV: np.ndarray, spot: Placement, shape) -> np.ndarray:
    """UVs ``(c, 2)`` of an image (OBJ convention: v up) placed at ``spot`` in an atlas of
    ``shape (Ha, Wa, ...)``, as atlas UVs ``(c, 2)``."""
    Ha, Wa = shape[:2]
    x = spot.x + UV[:, 0] * spot.w
    row = spot.y + (1.0 - UV[:, 1]) * spot.h
    return np.column_stack([x / Wa, 1.0 - row / Ha])
