"""Helpers shared by the symmetry-texture tests on generated inputs (test_symtex.py) and on
textures made by others (test_symtex_real.py), as session fixtures that return functions."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from synthkit.core import symmetry as sy
from synthkit.io.images import load_image, save_image
from synthkit.runner import run_config


def write_symtex_config(folder: Path, name: str, **cfg) -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump({"method": "symmetry-texture", **cfg}))
    return path


def seam_and_interior(img: np.ndarray) -> tuple[float, float]:
    """Mean squared luminance step across the toroidal seams (column W-1 -> 0, row H-1 -> 0) and
    the mean over every interior step, computed here independently of the pipeline's metric."""
    lum = sy.f_lum(img).astype(np.float64)
    interior = 0.5 * ((np.diff(lum, axis=1) ** 2).mean() + (np.diff(lum, axis=0) ** 2).mean())
    seam = 0.5 * (((lum[:, 0] - lum[:, -1]) ** 2).mean() + ((lum[0] - lum[-1]) ** 2).mean())
    return seam, interior


def check_symmetrized_toward(folder: Path, unwarped: np.ndarray, warped: np.ndarray) -> None:
    """ARAP symmetrization of ``warped`` raises E_symm and brings the image closer to ``unwarped``
    (both compared as the pipeline reads them, after an 8-bit round trip)."""
    save_image(folder / "ref.png", unwarped)
    save_image(folder / "w.png", warped)
    cfg = dict(
        mode="symmetrize",
        source="w.png",
        symmetry={"window": 0.5},
        deform={"points": 24, "levels": 2, "step": 4.0, "max_cycles": 2, "max_evaluations": 500},
    )
    report = run_config(write_symtex_config(folder, "s", **cfg), out_dir=folder / "out", show_progress=False)
    m = report["metrics"]
    assert m["objective_end"] > m["objective_start"]
    out = load_image(folder / "out" / "result.png")
    ref = load_image(folder / "ref.png")
    w = load_image(folder / "w.png")
    assert np.abs(out - ref).mean() < np.abs(w - ref).mean()


@pytest.fixture(scope="session")
def write_config():
    """``write_config(folder, name, **cfg) -> path`` of a symmetry-texture config file."""
    return write_symtex_config


@pytest.fixture(scope="session")
def seam_steps():
    """``seam_steps(img) -> (seam, interior)``: see :func:`seam_and_interior`."""
    return seam_and_interior


@pytest.fixture(scope="session")
def symmetrized_toward():
    """``symmetrized_toward(folder, unwarped, warped)``: see :func:`check_symmetrized_toward`."""
    return check_symmetrized_toward
