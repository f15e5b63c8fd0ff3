"""symmetry-texture end to end on textures made by others: skimage's gravel (installed with
scikit-image) and the lattice photographs of ../shared/data/textures/ (skipped when absent)."""

from pathlib import Path

import cv2
import numpy as np
import pytest

from synthkit.core import symmetry as sy
from synthkit.io.images import load_image, save_image
from synthkit.runner import run_config
from synthkit.samples import textures

REPO = Path(__file__).resolve().parents[2]
REAL = REPO.parent / "shared" / "data" / "textures"


def real_texture(name: str, size: int) -> np.ndarray:
    """``(size, size, 3)`` float32: the photograph ``name`` resized (area) to ``size`` pixels."""
    path = REAL / name
    if not path.is_file():
        pytest.skip(f"real data absent: {path}")
    return cv2.resize(load_image(path), (size, size), interpolation=cv2.INTER_AREA)


@pytest.mark.slow
def test_gravel_guided_by_dot_lattice_takes_its_period(tmp_path, write_config):
    """The issue's transfer check with skimage's gravel as the stochastic source (period P = 16)."""
    from skimage import data

    gravel = data.gravel()[:192, :192].astype(np.float32) / 255.0
    gravel = cv2.resize(gravel, (96, 96), interpolation=cv2.INTER_AREA)
    save_image(tmp_path / "gravel.png", np.repeat(gravel[:, :, None], 3, axis=2))
    save_image(tmp_path / "dots.png", textures.dots(96))
    cfg = dict(
        mode="transfer",
        source="gravel.png",
        target="dots.png",
        baseline=True,
        output_size=[96, 96],
        symmetry={"window": 0.25},
        synth={"patch": 16, "overlap": 6, "candidates": 12, "sweeps": 3},
    )
    report = run_config(write_config(tmp_path, "t", **cfg), out_dir=tmp_path / "out", show_progress=False)
    m = report["metrics"]
    out = load_image(tmp_path / "out" / "result.png")
    S = sy.translational(sy.f_lum(out), window=(24, 24))
    dy, dx = sy.strongest_peak(S)
    # the square lattice's first peaks (P, 0), (0, P) and (P, +-P) come out within a few percent of
    # each other on gravel, so the strongest may be a diagonal one (it is on seed 0): the strongest
    # lies on the lattice, and the axis peaks the issue names are within 10 % of it
    vy, vx = (-dy, -dx) if (dy, dx) < (0, 0) else (dy, dx)  # S_T(v) = S_T(-v): one of each pair
    lattice = [(16, 0), (0, 16), (16, 16), (16, -16)]
    assert min(np.hypot(vy - a, vx - b) for a, b in lattice) <= 1.0, (dy, dx)
    c = 24
    assert min(S[c + 16, c], S[c, c + 16]) >= 0.9 * S[c + dy, c + dx]
    assert m["objective_end"] < m["baseline_objective"]  # E_L2 below unguided quilting, same seed
    assert m["objective_end"] < m["objective_start"]


@pytest.mark.slow
@pytest.mark.xfail(
    strict=True,
    reason=(
        "lattice-p4 resampled to 96 px (a period of ~10 px, about three times the field's 3 px "
        "amplitude): the remaining field error is 3.15 px of 2.87 (2.48 without the "
        "deform.max_stretch bound); the mean absolute image difference this test used to check "
        "improved partly because bilinear rendering blurred the thin lines (issue 14)"
    ),
)
def test_real_grid_photo_warped_is_symmetrized_back(tmp_path, write_config):
    """A photographed grid (lattice-p4) resized to 96 px and warped by a known smooth field: ARAP
    symmetrization raises E_symm and removes half of the displacement error, measured against the
    field (see the 128 px native crop in test_real_photo_known_warp_has_half_its_error_removed)."""
    grid = real_texture("lattice-p4.jpg", 96)
    m, before, after = symmetrize_real(tmp_path, write_config, grid, 3.0)
    assert m["objective_end"] > m["objective_start"]
    assert after <= 0.5 * before, (before, after)


@pytest.mark.slow
def test_real_photo_crop_tiles_seamlessly(tmp_path, write_config, seam_steps):
    """A crop of a photographed facade of cars (lattice-p2-2) that does not tile as cut."""
    path = REAL / "lattice-p2-2.jpg"
    if not path.is_file():
        pytest.skip(f"real data absent: {path}")
    photo = load_image(path)
    crop = cv2.resize(photo[17:17 + 150, 9:9 + 150], (80, 80), interpolation=cv2.INTER_AREA)
    save_image(tmp_path / "c.png", crop)
    cfg = dict(
        mode="tile",
        source="c.png",
        symmetry={"signals": ["lum", "1-lum"], "window": 0.5},
        tile={"margin": 0.2, "optimize": True},
        deform={"points": 16, "levels": 2, "step": 4.0, "max_cycles": 1, "max_evaluations": 200},
    )
    report = run_config(write_config(tmp_path, "t", **cfg), out_dir=tmp_path / "out", show_progress=False)
    out = load_image(tmp_path / "out" / "result.png")
    seam, interior = seam_steps(out)
    naive, _ = seam_steps(load_image(tmp_path / "c.png"))
    assert seam <= 1.5 * interior
    assert seam < naive
    assert report["metrics"]["objective_warped"] >= report["metrics"]["objective_start"]


# ---------------------------------------------------------------------------------------------
# issue 14: tile and symmetrize on real photographs improve them and never damage them


def native_crop(name: str, size: int) -> np.ndarray:
    """``(<=size, <=size, 3)`` float32: the top-left ``size`` px of photograph ``name`` at its own
    resolution (``brick``, ``grass``, ``gravel``: skimage's, installed with scikit-image)."""
    if name in ("brick", "grass", "gravel"):
        from skimage import data

        img = getattr(data, name)().astype(np.float32) / 255.0
        img = np.repeat(img[:, :, None], 3, axis=2)
    else:
        path = REAL / name
        if not path.is_file():
            pytest.skip(f"real data absent: {path}")
        img = load_image(path)
    return np.ascontiguousarray(img[:size, :size])


TILE_REAL = dict(
    mode="tile",
    source="c.png",
    symmetry={"signals": ["lum", "1-lum"], "window": 0.5},
    tile={"optimize": True},
    deform={"points": 24, "levels": 2, "step": 4.0, "max_cycles": 2, "max_evaluations": 300},
)
TILE_PHOTOS = [
    "lattice-p3-21.jpg",  # diagonal stripes, does not tile as cut
    "lattice-p4.jpg",  # a grid that already tiles
    "lattice-p2-2.jpg",  # rows of cars
    "texture_bricks.jpg",
    "aerial_rocks_02_diff_1k.jpg",
    "brick",
    "grass",
    "gravel",
]


@pytest.mark.slow
@pytest.mark.parametrize("name", TILE_PHOTOS)
def test_real_photo_tile_never_worse_than_baseline_or_input(tmp_path, write_config, name):
    """Issue 14's tile goals on a 160 px native crop: the returned tile's seam ratio is at most the
    blended baseline's and the input's; the optimized tile is returned only when its E_symm is not
    below the input's and it keeps 90 % of the input's high-frequency energy; the warp stays
    within tile.max_stretch; result.png is the candidate report.json names. The 3x3 tilings
    (tiled_3x3.png of the result, tiled_optimized_3x3.png, tiled_baseline_3x3.png) stay in tmp_path."""
    from synthkit.core.tiling import cut_tile, seam_masks
    from synthkit.methods.symtex.tile import E_SYMM_TOL, SHARPNESS_MIN, high_frequency_energy, seam_ratio

    crop = native_crop(name, 160)
    save_image(tmp_path / "c.png", crop)
    report = run_config(write_config(tmp_path, "t", **TILE_REAL), out_dir=tmp_path / "out", show_progress=False)
    m = report["metrics"]
    c = m["tile_candidates"]
    assert m["seam_ratio"] <= m["baseline_seam_ratio"]
    assert m["seam_ratio"] <= m["seam_ratio_input"]
    assert m["max_stretch"] <= m["max_stretch_bound"] == 1.1
    assert c["optimized"]["max_stretch"] == m["max_stretch"]
    if m["tile_choice"] != "baseline" and m["tile_choice"] != "input":
        assert m["objective_end"] >= m["input_objective"] * (1 - E_SYMM_TOL)
        assert m["sharpness"] >= SHARPNESS_MIN
    if m["tile_choice"] == "optimized":
        assert m["tile_size"] == [96, 96]  # native crop: 160 less 2 x 32 px of margin, no upsampling
    out = load_image(tmp_path / "out" / "result.png")
    choice = m["tile_choice"]
    file = "../c.png" if choice == "input" else f"{choice}.png"
    np.testing.assert_array_equal(out, load_image(tmp_path / "out" / file))
    # the figures are those of the returned image (8-bit rounding aside); a cut tile's seams are
    # where its copies meet (the cuts), found from its source map
    cut = choice.startswith("cut")
    seams = seam_masks(cut_tile(load_image(tmp_path / "c.png"), int(choice[3:]))[1]) if cut else None
    assert seam_ratio(out, seams=seams) == pytest.approx(m["seam_ratio"], rel=0.1, abs=1e-3)
    assert high_frequency_energy(out) / high_frequency_energy(crop) == pytest.approx(m["sharpness"], rel=0.05)
    tiled = load_image(tmp_path / "out" / report["outputs"]["tiled"])
    assert tiled.shape[:2] == (3 * out.shape[0], 3 * out.shape[1])


TILE_E_SYMM_MISSED = pytest.mark.xfail(
    strict=True,
    reason=(
        "issue 14 goal missed: no candidate meets every goal and the blended baseline, returned, "
        "lowers E_symm (grass 160 px: 0.9% below the input's, seam ratio 0.208; the 16 px cut "
        "tile's seam ratio is 0.200 at 5% below, the 24 px one keeps E_symm at 0.225; README)"
    ),
)


@pytest.mark.slow
@pytest.mark.parametrize(
    "name",
    [pytest.param(n, marks=TILE_E_SYMM_MISSED) if n == "grass" else n for n in TILE_PHOTOS],
)
def test_real_photo_tile_keeps_the_inputs_e_symm(tmp_path, write_config, name):
    """Issue 14's remaining tile goal on the 160 px native crop: E_symm of the returned tile is not
    below the input's (within E_SYMM_TOL), whichever candidate is returned."""
    from synthkit.methods.symtex.tile import E_SYMM_TOL

    save_image(tmp_path / "c.png", native_crop(name, 160))
    report = run_config(write_config(tmp_path, "t", **TILE_REAL), out_dir=tmp_path / "out", show_progress=False)
    m = report["metrics"]
    assert m["objective_end"] >= m["input_objective"] * (1 - E_SYMM_TOL), m["tile_choice"]


def test_tile_of_rgba_photo_with_transparent_hole_composites_over_white(tmp_path, write_config, caplog):
    """A photo with a transparent hole (an inpainting mask) is read composited over white, with
    one warning (synthkit.io.images): the hole is white, not black, and the tile is the tile of
    the composited RGB image (within the 8-bit rounding of writing that image)."""
    import logging

    rgb = native_crop("texture_bricks.jpg", 64)
    alpha = np.ones(rgb.shape[:2], dtype=np.float32)
    alpha[20:36, 24:44] = 0.0  # the hole
    alpha[36:40, 24:44] = 0.5  # a translucent edge
    rgba = np.concatenate([rgb, alpha[:, :, None]], axis=2)
    save_image(tmp_path / "c.png", rgba)
    assert load_image(tmp_path / "c.png", mode="any").shape[2] == 4
    flat = np.round(rgba[..., :3] * 255) / 255 * np.round(alpha * 255)[:, :, None] / 255
    flat = flat + (1 - np.round(alpha * 255)[:, :, None] / 255)
    save_image(tmp_path / "flat.png", flat)
    cfg = dict(TILE_REAL, deform={"points": 12, "levels": 1, "step": 2.0, "max_cycles": 1, "max_evaluations": 40})
    with caplog.at_level(logging.WARNING, logger="synthkit"):
        run_config(write_config(tmp_path, "t", **cfg), out_dir=tmp_path / "out", show_progress=False)
    said = [r.getMessage() for r in caplog.records if "composited over white" in r.getMessage()]
    assert len(said) == 1 and "400 of 4096" in said[0] and "c.png" in said[0]
    read = load_image(tmp_path / "c.png")
    np.testing.assert_allclose(read[20:36, 24:44], 1.0)  # white, not black
    flat_cfg = write_config(tmp_path, "f", **dict(cfg, source="flat.png"))
    run_config(flat_cfg, out_dir=tmp_path / "outf", show_progress=False)
    np.testing.assert_allclose(
        load_image(tmp_path / "out" / "result.png"), load_image(tmp_path / "outf" / "result.png"), atol=1.5 / 255
    )


SYMMETRIZE_REAL = dict(
    mode="symmetrize",
    source="w.png",
    symmetry={"window": 0.5},
    deform={"points": 24, "levels": 2, "step": 4.0, "max_cycles": 2, "max_evaluations": 500},
)


def field_error(sample_map: np.ndarray, amplitude: float) -> float:
    """Mean remaining displacement (px) after undoing :func:`textures.smooth_warp` of ``amplitude``.

    The warped image is ``w(q) = f(q + d(q))`` with ``d(x, y) = (a sin(2 pi y / H), a sin(2 pi x / W))``
    and the result samples ``w`` at ``sample_map (H, W, 2)`` (x, y), so it shows ``f`` at
    ``s + d(s)``; the error is that position less the pixel's own, less its mean (S_T does not see
    a translation of the whole image). The identity map gives the error before.
    """
    H, W = sample_map.shape[:2]
    s = sample_map.astype(np.float64)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    ex = s[..., 0] + amplitude * np.sin(2 * np.pi * s[..., 1] / H) - xx
    ey = s[..., 1] + amplitude * np.sin(2 * np.pi * s[..., 0] / W) - yy
    return float(np.hypot(ex - ex.mean(), ey - ey.mean()).mean())


def symmetrize_real(tmp_path, write_config, photo, amplitude, **symmetry):
    tmp_path.mkdir(parents=True, exist_ok=True)
    warped = textures.smooth_warp(photo, amplitude) if amplitude else photo
    save_image(tmp_path / "w.png", warped)
    cfg = dict(SYMMETRIZE_REAL, symmetry={**SYMMETRIZE_REAL["symmetry"], **symmetry})
    report = run_config(write_config(tmp_path, "s", **cfg), out_dir=tmp_path / "out", show_progress=False)
    smap = np.load(tmp_path / "out" / report["outputs"]["sample_map"])
    H, W = smap.shape[:2]
    identity = np.stack(np.meshgrid(np.arange(W), np.arange(H)), axis=2)
    return report["metrics"], field_error(identity, amplitude), field_error(smap, amplitude)


MISSED_OBJECTIVE = pytest.mark.xfail(
    strict=True,
    reason=(
        "issue 14 goal missed by the objective, not the search: E_symm (of the whole-period crop) "
        "of the result reaches or exceeds the unwarped photograph's (brick 1.02e-4 vs 6.4e-5, cars "
        "0.0154 vs 0.0154); error removed brick -55%, cars 25%; Hann apodization, Lanczos probes "
        "and E_L2 to the sharpened S_T (paper Fig. 5a) remove at most 32% (README)"
    ),
)


UNCHANGED_MISSED = pytest.mark.xfail(
    strict=True,
    reason=(
        "issue 14 goal missed: the unwarped texture_bricks moves 2.54 px (whole-period crop 128 x "
        "128, min_gain 0.01; 2.93 px at min_gain 0): E_symm rises by warping it (README)"
    ),
)


BRICK_SEED_MISSED = pytest.mark.xfail(
    strict=True,
    reason=(
        "issue 14 goal met on seed 0 only (0.68 px; seeds 1-3 moved it 1.27-1.92 px); since issue 24 "
        "(E_symm from the power spectrum, equal to 1e-15, and deform.max_gradient) seed 0 takes "
        "other near-tie moves: 1.21 px, the result kept at E_symm above the input's by min_gain (README)"
    ),
)


@pytest.mark.slow
@pytest.mark.parametrize(
    "name",
    [
        "lattice-p4.jpg",
        "lattice-p3-21.jpg",
        "lattice-p2-2.jpg",
        pytest.param("brick", marks=BRICK_SEED_MISSED),
        pytest.param("texture_bricks.jpg", marks=UNCHANGED_MISSED),
    ],
)
def test_real_regular_photo_comes_back_nearly_unchanged(tmp_path, write_config, name):
    """An already regular photograph (128 px native crop): mean displacement at most 1 px. The
    stripes (lattice-p3-21), whose period does not divide 128 px, need symmetry.crop's
    whole-period crop (auto for symmetrize): 2.21 px on the whole crop; the cars and skimage's
    brick need min_gain's default for symmetrize, 0.01 (1.81 and 1.19 px at 0), and they meet
    the goal on this seed only: seeds 1-3 move the cars 1.16, 1.16, 0.85 px and the brick 1.27,
    1.30, 1.92 px (README)."""
    m, _, _ = symmetrize_real(tmp_path, write_config, native_crop(name, 128), 0.0)
    assert m["mean_displacement"] <= 1.0


@pytest.mark.slow
@pytest.mark.parametrize(
    "name",
    [
        "lattice-p4.jpg",
        pytest.param("brick", marks=MISSED_OBJECTIVE),
        pytest.param("lattice-p2-2.jpg", marks=MISSED_OBJECTIVE),
    ],
)
def test_real_photo_known_warp_has_half_its_error_removed(tmp_path, write_config, name):
    """A 128 px native crop warped by textures.smooth_warp (amplitude 3 px, mean error 2.87 px):
    symmetrization removes at least half of the displacement error, measured against the field."""
    m, before, after = symmetrize_real(tmp_path, write_config, native_crop(name, 128), 3.0)
    assert before == pytest.approx(2.87, abs=0.01)
    assert after <= 0.5 * before, (before, after)
    assert m["objective_end"] > m["objective_start"]


@pytest.mark.slow
def test_real_line_art_auto_signal_is_inverted_luminance_and_undoes_warp(tmp_path, write_config):
    """Dark line art on white (the negative of the photographed grid lattice-p4): E_symm of lum is
    ~1e-6, a flat S near 1; signals: auto picks 1-lum and then removes the known warp as well as
    on the original grid. With lum the optimizer moves the wrong way (recorded, not asserted)."""
    art = 1.0 - native_crop("lattice-p4.jpg", 128)
    m, before, after = symmetrize_real(tmp_path, write_config, art, 3.0)
    assert m["signals"] == ["1-lum"]
    v = m["signal_variances"]
    assert v["lum"] < 1e-5 < 1e-3 < v["1-lum"]
    assert after <= 0.5 * before
    m_lum, _, after_lum = symmetrize_real(tmp_path / "lum", write_config, art, 3.0, signals=["lum"])
    assert m_lum["signals"] == ["lum"]
    assert after < after_lum


# ---------------------------------------------------------------------------------------------
# issue 24: symmetrize never returns a worse image, on every shared photo and its negative

SHARED_PHOTOS = [
    "lattice-p4.jpg",
    "lattice-p3-21.jpg",
    "lattice-p2-2.jpg",
    "lattice-p2-4.png",
    "texture_bricks.jpg",
    "aerial_rocks_02_diff_1k.jpg",
]


@pytest.mark.slow
@pytest.mark.parametrize("negative", [False, True], ids=["photo", "negative"])
@pytest.mark.parametrize("name", SHARED_PHOTOS)
def test_symmetrize_never_returns_a_worse_image(tmp_path, write_config, name, negative):
    """Issue 24 on a 96 px native crop of each shared photo and of its luminance negative: the
    returned image's E_symm is not below the input's, the deformation is kept only when E_symm
    rose by deform.min_gain and its displacement gradient is within deform.max_gradient,
    otherwise result.png is the input and metrics.status_reason says why."""
    from synthkit.methods.symtex.config import DeformSection

    crop = native_crop(name, 96)
    photo = 1.0 - crop if negative else crop
    save_image(tmp_path / "w.png", photo)
    quick = {"points": 16, "levels": 2, "step": 4.0, "max_cycles": 1, "max_evaluations": 150}
    cfg = dict(SYMMETRIZE_REAL, deform=quick)
    report = run_config(write_config(tmp_path, "s", **cfg), out_dir=tmp_path / "out", show_progress=False)
    m = report["metrics"]
    out = load_image(tmp_path / "out" / "result.png")
    bound = DeformSection().max_gradient
    assert m["objective_end"] >= m["baseline_objective"]
    if m["status"] == "symmetrized":
        assert m["status_reason"] is None
        assert m["objective_end"] > m["baseline_objective"] * (1 + m["min_gain"])
        assert m["max_displacement_gradient"] <= bound
    else:
        assert m["status"] == "input returned" and m["status_reason"]
        assert m["mean_displacement"] == m["max_displacement_gradient"] == 0.0
        np.testing.assert_array_equal(out, load_image(tmp_path / "w.png"))
        smap = np.load(tmp_path / "out" / report["outputs"]["sample_map"])
        H, W = smap.shape[:2]
        np.testing.assert_allclose(smap, np.stack(np.meshgrid(np.arange(W), np.arange(H)), axis=2), atol=1e-4)


# ---------------------------------------------------------------------------------------------
# issue 24: guided transfer without visible patch edges (aerial_rocks guided toward each lattice)


def _rocks_toward(name: str, share: float | None, polish: int = 0):
    """aerial_rocks (256 px) guided toward photo ``name`` at 192x192 with the defaults (patch 32,
    overlap 12, 24 candidates, 4 sweeps, seed 0), the walk's ``seam_share`` ``share`` (None: the
    default) and ``polish`` polish sweeps: its E_L2 and seam energy, and unguided quilting's."""
    from synthkit.core import quilting as q
    from synthkit.methods.symtex import synth
    from synthkit.methods.symtex.objective import st_window

    src = real_texture("aerial_rocks_02_diff_1k.jpg", 256)
    path = REAL / name
    window = st_window((192, 192), 0.5)
    T = sy.translational(sy.f_lum(load_image(path)), window=window)
    base_rng, walk_rng = np.random.default_rng(0).spawn(2)
    base = q.quilt(src, (192, 192), patch=32, overlap=12, rng=base_rng)
    init = synth.random_init(src, (192, 192), patch=32, overlap=12, rng=walk_rng)
    walk = synth.guided_walk(src, init, signals=["lum"], targets=[T], window=window, patch=32, candidates=24,
                             sweeps=4, seam_share=share, polish_sweeps=polish)
    e_l2 = float(sy.e_l2(sy.translational(sy.f_lum(walk.image), window=window), T))
    return e_l2, synth.seam_energy(walk.image, walk.sources), synth.seam_energy(base.image, base.sources)


LATTICES = ["lattice-p4.jpg", "lattice-p3-21.jpg", "lattice-p2-2.jpg", "lattice-p2-4.png"]


@pytest.mark.slow
def test_guided_transfer_shows_less_patch_border():
    """Over the four lattice photos, the walk's choice of the quietest border among candidates
    keeping 85% of the best gain (synth.SEAM_SHARE) leaves less visible border (seam_energy)
    than the paper's choice (share 0) at an E_L2 within the issue's 10% on average (seed 0:
    seam energy 0.276 -> 0.190 summed, E_L2 0.79-1.13x per photo, 0.94x on average)."""
    paper = [_rocks_toward(name, 0.0) for name in LATTICES]
    ours = [_rocks_toward(name, None) for name in LATTICES]
    assert sum(o[1] for o in ours) <= 0.8 * sum(p[1] for p in paper)
    assert np.mean([o[0] / p[0] for o, p in zip(ours, paper, strict=True)]) <= 1.1


@pytest.mark.slow
def test_polish_sweep_lowers_border_and_objective():
    """The default polish sweep (``synth.polish_sweeps: 1``: among the candidates that still lower
    E_L2, the quietest border) after the walk lowers the visible border by a quarter or more over
    the four lattice photos and does not raise E_L2 on any (means of seeds 0-1: seam energy
    0.202 -> 0.129 summed, E_L2 0.79-0.97x per photo)."""
    walked = [_rocks_toward(name, None) for name in LATTICES]
    polished = [_rocks_toward(name, None, polish=1) for name in LATTICES]
    assert sum(p[1] for p in polished) <= 0.75 * sum(w[1] for w in walked)
    for p, w in zip(polished, walked, strict=True):
        assert p[0] <= w[0] * (1 + 1e-9)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="issue 24's goal not met: with the polish sweep guided seam_energy is "
                   "2.6-5x unguided quilting's (docs/findings/symmetry-texture.md, 'Patch edges, third round')")
@pytest.mark.parametrize("name", LATTICES)
def test_guided_transfer_seam_energy_within_issue_goal(name):
    """Issue 24's check: guided transfer's visible border (the defaults: one polish sweep) at most
    1.2x unguided quilting's."""
    _, seams, unguided = _rocks_toward(name, None, polish=1)
    assert seams <= 1.2 * unguided
