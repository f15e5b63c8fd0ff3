"""The command line on fuzzed inputs (issue 37), one process per case: exit 0 with a report whose
status is ok (its mesh_quality within the limits), or exit 2/3 with exactly one stderr line that
names the file (and the line or element where one applies); no traceback, within CASE_SECONDS and
within ``--max-memory``."""

from __future__ import annotations

import json
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from synthkit.io.ply import ply_bytes

from .conftest import CASE_SECONDS, REPO, SAMPLES, apply_recipe

SYNTHKIT = [sys.executable, "-c", "from synthkit.cli.main import main; main()"]
MAX_MEMORY_GIB = 2
CREASE = REPO / "configs" / "surface-by-numbers" / "crease-paper.yaml"
PAINTED = REPO / "configs" / "surface-by-numbers" / "painted.yaml"
BOOKSHELF = REPO / "configs" / "retarget" / "bookshelf.yaml"


def _crease(folder: Path, recipe) -> tuple[Path, list[str]]:
    """The crease config over the bundled crease PLY (ASCII) mutated by ``recipe``."""
    path = folder / "crease.ply"
    path.write_bytes(apply_recipe((SAMPLES / "surfacing-crease.ply").read_bytes(), recipe))
    return path, ["surface-by-numbers", str(CREASE), "--set", f"input={path}"]


def _ply_face_out_of_range(folder: Path, _recipe) -> tuple[Path, list[str]]:
    """A binary PLY of the crease mesh whose face 3 names vertex 2**20 (exit 1 before, in load_asset)."""
    mesh = trimesh.load(SAMPLES / "surfacing-crease.ply", process=False)
    faces = np.asarray(mesh.faces).copy()
    faces[3, 1] = 1 << 20
    path = folder / "crease-face.ply"
    path.write_bytes(ply_bytes(mesh.vertices, faces))
    return path, ["surface-by-numbers", str(CREASE), "--set", f"input={path}"]


def _crease_as(suffix: str, file_type: str):
    def make(folder: Path, recipe) -> tuple[Path, list[str]]:
        mesh = trimesh.load(SAMPLES / "surfacing-crease.ply", process=False)
        data = mesh.export(file_type=file_type)
        path = folder / f"crease{suffix}"
        path.write_bytes(apply_recipe(data.encode() if isinstance(data, str) else data, recipe))
        return path, ["surface-by-numbers", str(CREASE), "--set", f"input={path}"]
    return make


def _glb_face_out_of_range(folder: Path, _recipe) -> tuple[Path, list[str]]:
    """The crease mesh as GLB with face 3 naming vertex 34306 (trimesh loads it; exit 1 before)."""
    mesh = trimesh.load(SAMPLES / "surfacing-crease.ply", process=False)
    data = bytearray(mesh.export(file_type="glb"))
    faces = np.asarray(mesh.faces, np.uint32)
    start = bytes(data).find(faces.tobytes()[:36])
    faces = faces.copy()
    faces[3, 1] = 34306
    data[start:start + faces.nbytes] = faces.tobytes()
    path = folder / "crease.glb"
    path.write_bytes(bytes(data))
    return path, ["surface-by-numbers", str(CREASE), "--set", f"input={path}"]


def _painted(folder: Path, recipe) -> tuple[Path, list[str]]:
    """The painted config over the bundled stroke PNG mutated."""
    png = folder / "strokes.png"
    png.write_bytes(apply_recipe((SAMPLES / "surfacing-figure-front.png").read_bytes(), recipe))
    text = PAINTED.read_text().replace("../../data-samples/surfacing-figure-front.png", str(png))
    cfg = folder / "painted.yaml"
    cfg.write_text(text.replace("../../data-samples/", f"{SAMPLES}/") + "preview_size: 64\n")
    return png, ["surface-by-numbers", str(cfg)]


def _config(folder: Path, recipe) -> tuple[Path, list[str]]:
    """The crease config itself mutated."""
    cfg = folder / "crease.yaml"
    text = CREASE.read_bytes().replace(b"../../data-samples/", f"{SAMPLES}/".encode())
    cfg.write_bytes(apply_recipe(text, recipe))
    return cfg, ["surface-by-numbers", str(cfg)]


def _batch(folder: Path, recipe) -> tuple[Path, list[str]]:
    """A batch file over the crease config with a seed sweep, mutated."""
    path = folder / "batch.yaml"
    path.write_bytes(apply_recipe(f"configs: [{CREASE}]\nsweep:\n  seed: 0..2\n".encode(), recipe))
    return path, ["run", str(path)]


def _bookshelf_cut(folder: Path, _recipe) -> tuple[Path, list[str]]:
    """Issue 37's case: the bookshelf OBJ cut in its vertex line 1001, ``v 1.2 1.0``."""
    lines = (SAMPLES / "retarget-bookshelf.obj").read_text().splitlines()[:1000]
    path = folder / "bookshelf-cut.obj"
    path.write_text("\n".join([*lines, "v 1.2 1.0"]))
    return path, ["retarget", str(BOOKSHELF), "--set", f"input={path}"]


CASES = [
    ("ply-ascii-huge-coordinate", _crease, [("number", 0.02, b"1e30")], 0, None),
    ("ply-ascii-nan", _crease, [("number", 0.02, b"nan")], 3,
     r"1 vertices have NaN or infinite coordinates \(first: vertex \d+\)"),
    ("ply-binary-face-index", _ply_face_out_of_range, [], 3, r"face 3 names vertex 1048576, out of range \[0, 614\)"),
    ("stl-truncated", _crease_as(".stl", "stl"), [("truncate", 0.5)], 3, r"cannot read mesh: "),
    ("off-dropped-token", _crease_as(".off", "off"), [("drop_token", 0.9, 0.5)], 0, None),
    ("glb-face-index", _glb_face_out_of_range, [], 3, r"face 3 names vertex 34306, out of range \[0, 614\)"),
    ("stroke-png-truncated", _painted, [("truncate", 0.5)], 3, r"cannot read image \(corrupt or unsupported format\)"),
    ("config-repeated-line", _config, [("repeat_line", 0.3)], 2, r"line \d+"),
    ("batch-file-range", _batch, [("number", 0.9, b"-1")], 2, r"sweep\.seed: "),
    ("obj-cut-vertex-line", _bookshelf_cut, [], 3, r"line 1001\b"),
]


def run_case(args: list[str], out: Path) -> tuple[subprocess.CompletedProcess, float, int]:
    start = time.perf_counter()
    out_option = "--out-root" if args[0] == "run" else "--out"
    proc = subprocess.run([*SYNTHKIT, "--max-memory", str(MAX_MEMORY_GIB), *args, out_option, str(out),
                           "--previews", "none", "--no-progress"],
                          capture_output=True, text=True, timeout=120, cwd=REPO)
    return proc, time.perf_counter() - start, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss


@pytest.mark.parametrize("name, make, recipe, code, message",
                         [pytest.param(*case, id=case[0]) for case in CASES])
def test_the_command_line_keeps_the_promise(name, make, recipe, code, message, tmp_path):
    path, args = make(tmp_path, recipe)
    proc, seconds, peak_kib = run_case(args, tmp_path / "out")
    assert seconds < CASE_SECONDS + 5  # the interpreter's start is not the reader's
    assert peak_kib < MAX_MEMORY_GIB * 2**20
    assert "Traceback" not in proc.stderr
    assert proc.returncode == code, proc.stderr
    if code == 0:
        assert json.loads((tmp_path / "out" / "report.json").read_text())["status"] == "ok"
        return
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("error: ") and f"{path}: " in lines[0], lines[0]
    assert re.search(message, lines[0]), lines[0]
