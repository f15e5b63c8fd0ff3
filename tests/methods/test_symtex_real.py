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
def test_real_grid_photo_warped_is_symmetrized_back(tmp_path, symmetrized_toward):
    """A photographed grid (lattice-p4) warped by a known smooth field: ARAP symmetrization raises
    E_symm and brings the image closer to the unwarped photograph."""
    grid = real_texture("lattice-p4.jpg", 96)
    symmetrized_toward(tmp_path, grid, textures.smooth_warp(grid, 3.0))


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
        tile={"margin": 0.2},
        deform={"points": 16, "levels": 2, "step": 4.0, "max_cycles": 1, "max_evaluations": 200},
    )
    report = run_config(write_config(tmp_path, "t", **cfg), out_dir=tmp_path / "out", show_progress=False)
    out = load_image(tmp_path / "out" / "result.png")
    seam, interior = seam_steps(out)
    naive, _ = seam_steps(load_image(tmp_path / "c.png"))
    assert seam <= 1.5 * interior
    assert seam < naive
    assert report["metrics"]["objective_warped"] >= report["metrics"]["objective_start"]
