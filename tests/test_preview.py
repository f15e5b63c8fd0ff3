"""Previews: the rasterizer covers what it should, nearest surface wins, heatmaps map min/max."""

import numpy as np
import pytest

from synthkit.io.images import load_image
from synthkit.preview import colorize, heatmap_png, montage_png, plot_curve_png, rasterize_mesh, view_rotation


def _square(z, color_index=0):
    V = np.array([[-1, -1, z], [1, -1, z], [1, 1, z], [-1, 1, z]], dtype=np.float64)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    return V, F


def test_view_rotations_are_orthonormal():
    for view in ("front", "back", "left", "right", "side", "top", "bottom", "iso"):
        R = view_rotation(view)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(view_rotation("front"), np.eye(3))
    np.testing.assert_allclose(view_rotation("top") @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(view_rotation("side"), view_rotation("right"))
    with pytest.raises(ValueError, match="unknown view 'rear'"):
        view_rotation("rear")


def test_front_square_fills_the_frame_centre():
    V, F = _square(0.0)
    img = rasterize_mesh(V, F, view="front", size=64, face_colors=np.array([[1.0, 0.0, 0.0]] * 2))
    assert img.shape == (64, 64, 3)
    centre = img[32, 32]
    assert centre[0] > 0.5 and centre[1] == 0.0 and centre[2] == 0.0
    np.testing.assert_array_equal(img[0, 0], [1.0, 1.0, 1.0])
    covered = (img != 1.0).any(axis=2)
    assert 0.75 < covered.mean() < 0.85  # (1 - 2 * 0.06)^2 of the frame


def test_nearest_surface_wins():
    Va, F = _square(0.0)
    Vb, _ = _square(1.0)
    V = np.vstack([Va, Vb])
    F2 = np.vstack([F, F + 4])
    colors = np.array([[1.0, 0, 0], [1.0, 0, 0], [0, 0, 1.0], [0, 0, 1.0]])
    img = rasterize_mesh(V, F2, view="front", size=32, face_colors=colors)
    assert img[16, 16, 2] > 0 and img[16, 16, 0] == 0  # z = 1 is nearer the viewer (+z)


def test_colorize_extremes_and_nan():
    field = np.array([[0.0, 1.0], [np.nan, 0.5]])
    rgb = colorize(field)
    np.testing.assert_allclose(rgb[0, 0], [68 / 255, 1 / 255, 84 / 255], atol=2 / 255)  # viridis start
    np.testing.assert_allclose(rgb[0, 1], [253 / 255, 231 / 255, 37 / 255], atol=2 / 255)  # viridis end
    np.testing.assert_allclose(rgb[1, 0], [0.5, 0.5, 0.5])


def test_png_writers(tmp_path):
    heat = heatmap_png(tmp_path / "h.png", np.eye(8), title="S_T", min_size=64)
    assert load_image(tmp_path / "h.png").shape == heat.shape == (24 + 64, 64, 3)
    plot = plot_curve_png(tmp_path / "c.png", np.arange(5), np.arange(5) ** 2, title="t")
    assert plot.shape == (360, 480, 3) and (plot < 1).any()
    mont = montage_png(tmp_path / "m.png", [np.zeros((10, 20)), np.ones((5, 5, 3))], height=20)
    assert mont.shape == (20, 40 + 6 + 20, 3)


def test_rasterizer_covers_pixel_centres_and_keeps_tiny_faces():
    from synthkit.preview import _rasterize

    size = 8
    pix = np.array([[[1.0, 1.0], [5.0, 1.0], [1.0, 5.0]],  # right triangle: centres with x + y <= 6
                    [[6.2, 6.2], [6.4, 6.2], [6.2, 6.4]]])  # holds no centre: marks its centroid's pixel
    z = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    depth = np.full(size * size, -np.inf)
    face_at = np.full(size * size, -1, dtype=np.int64)
    _rasterize(pix, z, size, depth, face_at)
    grid = face_at.reshape(size, size)
    ys, xs = np.nonzero(grid == 0)
    assert set(zip(xs.tolist(), ys.tolist(), strict=True)) == {
        (x, y) for x in range(1, 6) for y in range(1, 6) if x + y <= 6
    }
    assert np.argwhere(grid == 1).tolist() == [[6, 6]]
    # a nearer face drawn later replaces, an equally near one does not
    _rasterize(pix[:1], z[:1] + 1.0, size, depth, face_at)
    assert (face_at.reshape(size, size)[1:6, 1:6][grid[1:6, 1:6] == 0] == 0).all()


def _reference_raster(pix, z, size):
    """The rasterizer's rule pixel by pixel: nearest face holding the centre (tolerance 1e-9),
    first face among equal depths, centroid pixel for a face holding no centre."""
    depth = np.full((size, size), -np.inf)
    face = np.full((size, size), -1)
    for f, (t, zt) in enumerate(zip(pix, z, strict=True)):
        (x0, y0), (x1, y1), (x2, y2) = t
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        hit = False
        for py in range(size):
            for px in range(size):
                if area == 0:
                    continue
                w0 = ((x1 - px) * (y2 - py) - (x2 - px) * (y1 - py)) / area
                w1 = ((x2 - px) * (y0 - py) - (x0 - px) * (y2 - py)) / area
                w2 = 1 - w0 - w1
                if min(w0, w1, w2) >= -1e-9:
                    hit = True
                    d = w0 * zt[0] + w1 * zt[1] + w2 * zt[2]
                    if d > depth[py, px] + 1e-12:
                        depth[py, px], face[py, px] = d, f
        if not hit:
            cx, cy = (int(np.clip(np.round(t[:, k].mean()), 0, size - 1)) for k in (0, 1))
            if zt.mean() > depth[cy, cx] + 1e-12:
                depth[cy, cx], face[cy, cx] = zt.mean(), f
    return face


def test_rasterizer_matches_a_per_pixel_reference_on_random_triangles():
    from synthkit.preview import _rasterize

    rng = np.random.default_rng(3)
    size = 24
    # big, small, sliver and off-screen triangles at distinct depths (no ties to break)
    pix = np.concatenate([rng.uniform(-6, size + 6, (25, 3, 2)), rng.uniform(5, 9, (25, 3, 2))])
    pix[0] = [[2.0, 2.0], [2.0, 20.0], [2.0 + 1e-7, 11.0]]
    z = rng.permutation(np.arange(150.0)).reshape(50, 3)
    depth = np.full(size * size, -np.inf)
    face_at = np.full(size * size, -1, dtype=np.int64)
    _rasterize(pix, z, size, depth, face_at)
    assert np.array_equal(face_at.reshape(size, size), _reference_raster(pix, z, size))


def test_textured_quad_shows_its_texture_quadrants():
    """A front-facing quad with a 2x2 texture: each quarter of the render shows its texel (times
    the shading of a face turned to the light as the plain quad is)."""
    from synthkit.preview import Appearance

    V = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    F = np.array([[0, 1, 2], [0, 2, 3]])
    uv = V[:, :2][F]
    texture = np.array([[[1, 0, 0], [0, 1, 0]], [[0, 0, 1], [1, 1, 1]]], np.float32)  # top row: red, green
    app = Appearance(corner_uv=uv, face_image=np.zeros(2, np.int64), images=[texture], face_tint=np.ones((2, 3)))
    plain = rasterize_mesh(V, F, view="front", size=64)
    img = rasterize_mesh(V, F, view="front", size=64, appearance=app)
    shade = plain[32, 32] / np.array([0.72, 0.76, 0.84], np.float32)
    quarters = {(12, 12): [1, 0, 0], (12, 50): [0, 1, 0], (50, 12): [0, 0, 1], (50, 50): [1, 1, 1]}
    for (row, col), texel in quarters.items():
        assert np.allclose(img[row, col], np.array(texel) * shade, atol=1e-5)
    assert np.allclose(img[0, 0], 1.0)  # background untouched
