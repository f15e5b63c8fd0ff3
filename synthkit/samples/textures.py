"""Small textures with known repetition for the symmetry-texture method (``data-samples/textures/``).

Every image is ``(H, W, 3)`` 8-bit PNG, written with ``<name>.truth.json`` holding its ground truth:
``lattice`` vectors as ``[[dy, dx], [dy, dx]]`` in pixels, ``period`` along an axis, or the known
distortion. Fine-scale noise comes from fixed seeds, so the bytes are the same on every run.

- ``bricks``: running-bond bricks, courses 16 px high, bricks 32 px long, offset by half a brick.
- ``dots``: square lattice of soft dots, period 16.
- ``stripes``: horizontal stripes, period 12.
- ``wavy``: wavy rows of berry-like dots, rows every 24 px (a pattern with no simple lattice).
- ``noise``: stochastic blurred noise (no period).
- ``bricks_shaded``: bricks as a photograph would show them: courses 14 px, bricks 30 px (neither
  divides 128, so opposite borders do not match), lit more strongly on the left and at the top;
  it does not tile as it is (the input of the tiling demo).
- ``sketch_x``: a hand-drawn-like "X" on white, a target sketch (48 x 48).
- ``bricks_lens``: ``bricks`` seen through radial distortion ``k1 = 0.2`` (Tsai model).
- ``dots_warped``: ``dots`` warped by a smooth sinusoidal displacement field of amplitude 3 px.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
from scipy import ndimage

from synthkit.io.images import save_image

SIZE = 128


def _rgb(gray: np.ndarray, tint=(1.0, 0.9, 0.75)) -> np.ndarray:
    g = np.clip(gray, 0.0, 1.0).astype(np.float32)
    return np.stack([g * tint[0], g * tint[1], g * tint[2]], axis=2)


def _grain(shape, seed: int, amount: float, sigma: float = 0.7) -> np.ndarray:
    n = np.random.default_rng(seed).standard_normal(shape)
    return amount * ndimage.gaussian_filter(n, sigma, mode="wrap")


def bricks(size: int = SIZE) -> np.ndarray:
    """Running-bond bricks ``(size, size, 3)``: courses 16 px, bricks 32 px, mortar 3 px; tiles."""
    y, x = np.mgrid[0:size, 0:size]
    course = (y // 16) % 2
    xs = (x + course * 16) % 32
    mortar = ((y % 16) < 3) | (xs < 3)
    gray = np.where(mortar, 0.85, 0.45) + _grain((size, size), 11, 0.06)
    return _rgb(gray, tint=(1.0, 0.62, 0.5))


def dots(size: int = SIZE, period: int = 16, radius: float = 4.0) -> np.ndarray:
    """Square lattice of soft dark dots on a light ground ``(size, size, 3)``."""
    y, x = np.mgrid[0:size, 0:size].astype(np.float64)
    dy = (y + 0.5) % period - period / 2
    dx = (x + 0.5) % period - period / 2
    r = np.hypot(dy, dx)
    gray = 0.85 - 0.6 * np.clip(radius + 0.5 - r, 0.0, 1.0) + _grain((size, size), 12, 0.04)
    return _rgb(gray, tint=(0.9, 0.95, 1.0))


def stripes(size: int = SIZE, period: int = 12) -> np.ndarray:
    """Horizontal stripes ``(size, size, 3)`` with a sinusoidal profile of period ``period``."""
    y = np.arange(size, dtype=np.float64)[:, None]
    gray = 0.5 + 0.3 * np.sin(2 * np.pi * y / period) + _grain((size, size), 13, 0.05)
    return _rgb(np.broadcast_to(gray, (size, size)), tint=(0.8, 1.0, 0.8))


def wavy(size: int = SIZE, period: int = 24) -> np.ndarray:
    """Wavy rows of small berries ``(size, size, 3)``, rows every ``period`` px."""
    rng = np.random.default_rng(14)
    gray = np.full((size, size), 0.8)
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float64)
    for row in range(size // period):
        for k in range(size // 6):
            cx = k * 6 + rng.uniform(-1, 1)
            cy = row * period + period / 2 + 4 * np.sin(2 * np.pi * cx / size * 2) + rng.uniform(-1.5, 1.5)
            ddy = (yy - cy + size / 2) % size - size / 2
            ddx = (xx - cx + size / 2) % size - size / 2
            gray -= 0.5 * np.exp(-(ddy**2 + ddx**2) / (2 * 1.6**2))
    gray += _grain((size, size), 15, 0.04)
    return _rgb(gray, tint=(0.75, 0.45, 0.8))


def bricks_shaded(size: int = SIZE, course: int = 14, length: int = 30) -> np.ndarray:
    """Running-bond bricks ``(size, size, 3)`` of periods that do not divide ``size``, under a
    lighting gradient (brightness 1.15 at the top-left corner down to 0.8 at the bottom-right)."""
    y, x = np.mgrid[0:size, 0:size]
    row = (y // course) % 2
    xs = (x + row * (length // 2)) % length
    mortar = ((y % course) < 3) | (xs < 3)
    gray = np.where(mortar, 0.8, 0.42) + _grain((size, size), 18, 0.06)
    light = 1.15 - 0.35 * (0.6 * x + 0.4 * y) / (size - 1)
    return _rgb(gray * light, tint=(1.0, 0.66, 0.52))


def noise(size: int = SIZE) -> np.ndarray:
    """Stochastic texture ``(size, size, 3)``: blurred white noise plus fine grain (no period)."""
    n = np.random.default_rng(16).standard_normal((size, size))
    blob = ndimage.gaussian_filter(n, 2.0, mode="wrap")
    blob = (blob - blob.min()) / np.ptp(blob)
    return _rgb(0.2 + 0.6 * blob + _grain((size, size), 17, 0.05), tint=(0.9, 0.85, 0.7))


def sketch_x(size: int = 48) -> np.ndarray:
    """A dark "X" drawn with slightly wobbly 3 px strokes on white ``(size, size, 3)``."""
    img = np.full((size, size), 255, dtype=np.uint8)
    m = size // 8
    cv2.line(img, (m, m + 1), (size - m - 1, size - m - 2), 0, 3, cv2.LINE_AA)
    cv2.line(img, (size - m - 2, m), (m + 1, size - m - 1), 0, 3, cv2.LINE_AA)
    return _rgb(img.astype(np.float64) / 255.0, tint=(1.0, 1.0, 1.0))


def radial_distort(img: np.ndarray, k1: float) -> np.ndarray:
    """Tsai radial distortion about the centre: output ``p_d`` shows input ``p_d (1 + k1 |p_d|^2)``
    (coordinates relative to the centre, divided by half the larger side)."""
    H, W = img.shape[:2]
    s = max(H, W) / 2.0
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    v, u = (yy - (H - 1) / 2) / s, (xx - (W - 1) / 2) / s
    g = 1.0 + k1 * (u * u + v * v)
    mx = ((W - 1) / 2 + u * g * s).astype(np.float32)
    my = ((H - 1) / 2 + v * g * s).astype(np.float32)
    return cv2.remap(img.astype(np.float32), mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


def smooth_warp(img: np.ndarray, amplitude: float) -> np.ndarray:
    """Warp by the displacement ``(a sin(2 pi x / W) , a sin(2 pi y / H))`` (toroidal, smooth)."""
    H, W = img.shape[:2]
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    my = (yy + amplitude * np.sin(2 * np.pi * xx / W)).astype(np.float32)
    mx = (xx + amplitude * np.sin(2 * np.pi * yy / H)).astype(np.float32)
    return cv2.remap(img.astype(np.float32), mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)


def generate(out_dir: Path) -> list[Path]:
    """Write the textures and their ``.truth.json`` files into ``out_dir/textures``."""
    folder = Path(out_dir) / "textures"
    folder.mkdir(parents=True, exist_ok=True)
    base_dots = dots()
    samples = {
        "bricks": (bricks(), {"lattice": [[16, 16], [0, 32]], "period": {"y": 32, "x": 32}, "course": 16}),
        "dots": (base_dots, {"lattice": [[16, 0], [0, 16]], "period": {"y": 16, "x": 16}}),
        "stripes": (stripes(), {"lattice": [[12, 0]], "period": {"y": 12}}),
        "wavy": (wavy(), {"period": {"y": 24}, "lattice": None}),
        "noise": (noise(), {"periodic": False}),
        "bricks_shaded": (
            bricks_shaded(),
            {"lattice": [[14, 15], [0, 30]], "period": {"y": 28, "x": 30}, "periodic": False, "lighting": "gradient"},
        ),
        "sketch_x": (sketch_x(), {"shape": "X", "size": 48}),
        "bricks_lens": (radial_distort(bricks(192), 0.2), {"k1": 0.2, "center": "image centre", "source": "bricks"}),
        "dots_warped": (
            smooth_warp(base_dots, 3.0),
            {"lattice": [[16, 0], [0, 16]], "warp_amplitude": 3.0, "source": "dots"},
        ),
    }
    written: list[Path] = []
    for name, (img, truth) in samples.items():
        path = folder / f"{name}.png"
        save_image(path, img)
        truth_path = folder / f"{name}.truth.json"
        truth_path.write_text(json.dumps({"image": path.name, **truth}, indent=2) + "\n")
        written += [path, truth_path]
    return written


__all__ = [
    "generate", "bricks", "bricks_shaded", "dots", "stripes", "wavy", "noise", "sketch_x", "radial_distort",
    "smooth_warp",
]
