"""Samples for surface-by-numbers' transfer (section 4), with known answers.

- ``surfacing-transfer-stripes.ply``: a flat 2 x 2 grid whose vertex colours are stripes of
  period ``PERIOD`` along x in a three-colour palette (each stripe one colour);
- ``surfacing-transfer-cylinder.ply`` with ``.seg``: a capped cylinder (radius 0.6, height 2);
  label 0 is the side (the target region), 1 the caps;
- :func:`bumps` (a flat grid displaced along +z by ``AMPLITUDE`` sin-bumps of wavelength
  ``WAVELENGTH`` in x and y) and :func:`sphere` for the geometry tests, which generate them.

Each written input has its ``<name>.truth.json`` beside it.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import trimesh

__all__ = ["PERIOD", "PALETTE", "AMPLITUDE", "WAVELENGTH", "grid", "stripes", "cylinder", "bumps", "sphere", "generate"]

PERIOD = 0.5
PALETTE = np.array([[220, 50, 40], [250, 210, 60], [40, 80, 200]], dtype=np.uint8)
AMPLITUDE = 0.02
WAVELENGTH = 0.2


def grid(n: int, size: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """A flat ``n x n``-cell grid over ``[0, size]^2`` in z = 0: ``V ((n+1)^2, 3)``, ``F (2 n^2, 3)``,
    cells split along alternating diagonals."""
    xs = np.linspace(0.0, size, n + 1)
    gx, gy = np.meshgrid(xs, xs)
    V = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], 1)
    idx = np.arange(gx.size).reshape(gx.shape)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    flip = ((np.arange(n)[:, None] + np.arange(n)[None, :]) % 2).astype(bool)
    t1 = np.where(flip[..., None], np.stack([a, b, d], -1), np.stack([a, b, c], -1))
    t2 = np.where(flip[..., None], np.stack([a, d, c], -1), np.stack([b, d, c], -1))
    return V, np.concatenate([t1.reshape(-1, 3), t2.reshape(-1, 3)]).astype(np.int64)


def stripes(n: int = 80, period: float = PERIOD) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The stripe source: ``V``, ``F`` and ``colors (#V, 3) uint8``: palette colour
    ``floor(3 x / period) mod 3``, three equal stripes per period."""
    V, F = grid(n)
    k = np.floor(3 * V[:, 0] / period + 1e-9).astype(np.int64) % 3
    return V, F, PALETTE[k]


def cylinder(n_around: int = 96, n_up: int = 48, radius: float = 0.6, height: float = 2.0):
    """Capped cylinder about z: ``V``, ``F`` (outward) and ``labels (#F,)`` (0 side, 1 caps)."""
    a = 2 * np.pi * np.arange(n_around) / n_around
    z = np.linspace(0.0, height, n_up + 1)
    ring = np.stack([radius * np.cos(a), radius * np.sin(a)], 1)
    V = np.concatenate([np.c_[np.tile(ring, (n_up + 1, 1)), np.repeat(z, n_around)], [[0, 0, 0], [0, 0, height]]])
    i = np.arange(n_around)
    j = (i + 1) % n_around
    side = []
    for r in range(n_up):
        lo, hi = r * n_around, (r + 1) * n_around
        side += [np.stack([lo + i, lo + j, hi + j], 1), np.stack([lo + i, hi + j, hi + i], 1)]
    bottom, top = len(V) - 2, len(V) - 1
    caps = [np.stack([np.full(n_around, bottom), j, i], 1),
            np.stack([np.full(n_around, top), n_up * n_around + i, n_up * n_around + j], 1)]
    F = np.concatenate(side + caps).astype(np.int64)
    labels = np.r_[np.zeros(2 * n_up * n_around, np.int64), np.ones(2 * n_around, np.int64)]
    return V, F, labels


def bumps(n: int = 100, amplitude: float = AMPLITUDE, wavelength: float = WAVELENGTH):
    """The bump source: a grid with ``z = amplitude sin(2 pi x / wl) sin(2 pi y / wl)``."""
    V, F = grid(n)
    V[:, 2] = amplitude * np.sin(2 * np.pi * V[:, 0] / wavelength) * np.sin(2 * np.pi * V[:, 1] / wavelength)
    return V, F


def sphere(subdivisions: int = 5, radius: float = 1.0):
    """A smooth icosphere ``V``, ``F``."""
    m = trimesh.creation.icosphere(subdivisions, radius)
    return np.asarray(m.vertices), np.asarray(m.faces, np.int64)


def _ply(path: Path, V, F, colors=None, truth: dict | None = None) -> list[Path]:
    mesh = trimesh.Trimesh(V, F, vertex_colors=colors, process=False)
    path.write_bytes(trimesh.exchange.ply.export_ply(mesh, encoding="binary", vertex_normal=False))
    tpath = path.with_name(path.stem + ".truth.json")
    tpath.write_text(json.dumps({"faces": int(len(F)), "vertices": int(len(V)), **(truth or {})}) + "\n")
    return [path, tpath]


def generate(out_dir: Path) -> list[Path]:
    """Write the stripe source and the cylinder target (with its labels) into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    V, F, colors = stripes()
    written = _ply(out_dir / "surfacing-transfer-stripes.ply", V, F, colors,
                   {"period": PERIOD, "palette": PALETTE.tolist(), "stripes_per_period": 3})
    V, F, labels = cylinder()
    written += _ply(out_dir / "surfacing-transfer-cylinder.ply", V, F, None,
                    {"radius": 0.6, "height": 2.0, "side_label": 0, "side_faces": int((labels == 0).sum())})
    seg = out_dir / "surfacing-transfer-cylinder.seg"
    seg.write_text("".join(f"{v}\n" for v in labels.tolist()))
    written.append(seg)
    return written
