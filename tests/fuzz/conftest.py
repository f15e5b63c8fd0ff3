"""Fuzzing the readers (issue 37): valid files, mutation recipes drawn by hypothesis, the promise.

A recipe is a short list of mutations applied in turn to a valid file's bytes: truncate, flip bytes,
drop or repeat a line or a token, write a number token as NaN, infinity, a huge or a negative
number, or write a 4-byte NaN/infinity/huge/out-of-range word into a binary file. Hypothesis prints
the failing recipe, which reproduces the case (``apply_recipe(valid bytes, recipe)``).

Profiles: ``ci`` (``make test``: derandomized, :data:`CI_EXAMPLES` examples per format) and
``fuzz`` (``make fuzz``, ``SYNTHKIT_FUZZ=1``: ``SYNTHKIT_FUZZ_EXAMPLES`` per format, default
:data:`FUZZ_EXAMPLES`, still derandomized so that a failure found once is found again).
"""

from __future__ import annotations

import os
import re
import shutil
import struct
from pathlib import Path

import cv2
import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from synthkit.errors import SynthkitError
from synthkit.io.ply import ply_bytes

REPO = Path(__file__).resolve().parents[2]
SAMPLES = REPO / "data-samples"
CI_EXAMPLES = 20
FUZZ_EXAMPLES = 400
CASE_SECONDS = 10.0
"""The promise: every case (one file through its readers) within this many seconds."""

_COMMON = dict(derandomize=True, deadline=None, database=None, print_blob=True,
               suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                      HealthCheck.data_too_large])
settings.register_profile("ci", max_examples=CI_EXAMPLES, **_COMMON)
settings.register_profile("fuzz", max_examples=int(os.environ.get("SYNTHKIT_FUZZ_EXAMPLES", FUZZ_EXAMPLES)),
                          **_COMMON)
settings.load_profile("fuzz" if os.environ.get("SYNTHKIT_FUZZ") else "ci")

NUMBER = re.compile(rb"(?<![A-Za-z_])-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")
HOSTILE_TOKENS = [b"nan", b"inf", b"-inf", b"1e308", b"1e400", b"-1", b"0", b"99999999999", b"2147483648",
                  b"4294967295", b"1.5", b"", b"x"]
HOSTILE_WORDS = [struct.pack("<f", v) for v in (float("nan"), float("inf"), 3.0e38, -1.0)] + [
    struct.pack("<i", v) for v in (-1, 2**31 - 1, 1 << 20, 3)]


def _mutation():
    where = st.floats(0, 1, allow_nan=False)
    return st.one_of(
        st.tuples(st.just("truncate"), where),
        st.tuples(st.just("flip"), where, st.integers(0, 255)),
        st.tuples(st.just("drop_line"), where),
        st.tuples(st.just("repeat_line"), where),
        st.tuples(st.just("drop_token"), where, where),
        st.tuples(st.just("repeat_token"), where, where),
        st.tuples(st.just("number"), where, st.sampled_from(HOSTILE_TOKENS)),
        st.tuples(st.just("word"), where, st.sampled_from(HOSTILE_WORDS)),
    )


RECIPES = st.lists(_mutation(), min_size=1, max_size=3)
"""Hypothesis strategy of mutation recipes."""


def _at(fraction: float, n: int) -> int:
    return min(int(fraction * n), max(n - 1, 0))


def _token_edit(line: bytes, fraction: float, repeat: bool) -> bytes:
    tokens = line.split(b" ")
    k = _at(fraction, len(tokens))
    tokens[k:k + 1] = [tokens[k]] * 2 if repeat else []
    return b" ".join(tokens)


def _mutate(data: bytes, step: tuple) -> bytes:
    kind, where = step[0], step[1]
    if kind == "truncate":
        return data[:int(where * len(data))]
    if kind in ("flip", "word") and data:
        k = _at(where, len(data))
        patch = bytes([step[2]]) if kind == "flip" else step[2]
        return data[:k] + patch + data[k + len(patch):]
    if kind == "number":
        found = list(NUMBER.finditer(data))
        if found:
            m = found[_at(where, len(found))]
            return data[:m.start()] + step[2] + data[m.end():]
        return data
    lines = data.split(b"\n")
    k = _at(where, len(lines))
    if kind == "drop_line":
        del lines[k]
    elif kind == "repeat_line":
        lines.insert(k, lines[k])
    elif kind in ("drop_token", "repeat_token"):
        lines[k] = _token_edit(lines[k], step[2], kind == "repeat_token")
    return b"\n".join(lines)


def apply_recipe(data: bytes, recipe: list[tuple]) -> bytes:
    """``data`` with the mutations of ``recipe`` applied in turn."""
    for step in recipe:
        data = _mutate(data, step)
    return data


@pytest.fixture(scope="session")
def mutate():
    """``mutate(data, recipe) -> bytes`` (:func:`apply_recipe`)."""
    return apply_recipe


def promise(call, path: Path, also: tuple[Path, ...] = ()):
    """``call(path)``'s result, or None when it refused the file as the promise allows: a
    SynthkitError of exit code 2 or 3 whose message is one line that starts with the file (or with
    one of the files ``also``, that ``path`` names: an OBJ's MTL)."""
    try:
        return call(path)
    except SynthkitError as exc:
        line = str(exc)
        assert exc.exit_code in (2, 3), line
        assert any(line.startswith(f"{p}: ") for p in (path, *also)) and "\n" not in line, line
        return None


@pytest.fixture(scope="session")
def keeps_promise():
    """``keeps_promise(call, path)``: see :func:`promise`."""
    return promise


def _box_files(folder: Path) -> dict[str, Path]:
    mesh = trimesh.creation.box()
    mesh.visual.face_colors = [200, 40, 40, 255]
    labels = np.arange(len(mesh.faces)) % 3
    ascii_labels = ("ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\nproperty float z\n"
                    "element face 12\nproperty list uchar int vertex_indices\nproperty int label\nend_header\n"
                    + "".join(f"{x:g} {y:g} {z:g}\n" for x, y, z in mesh.vertices)
                    + "".join(f"3 {a} {b} {c} {k}\n" for (a, b, c), k in zip(mesh.faces, labels, strict=True)))
    data = {
        "box.off": mesh.export(file_type="off").encode(),
        "box.stl": mesh.export(file_type="stl"),
        "box-ascii.stl": mesh.export(file_type="stl_ascii").encode(),
        "box.glb": mesh.export(file_type="glb"),
        "box.gltf": mesh.export(file_type="gltf", embed_buffers=True)["model.gltf"],
        "labels.ply": ply_bytes(mesh.vertices, mesh.faces, face=[("label", "int", labels)]),
        "labels-ascii.ply": ascii_labels.encode(),
        "labels.seg": "".join(f"{k}\n" for k in labels).encode(),
    }
    for name, content in data.items():
        (folder / name).write_bytes(content)
    return {name: folder / name for name in data}


def _image_files(folder: Path) -> dict[str, Path]:
    bricks = cv2.imread(str(SAMPLES / "textures" / "bricks.png"), cv2.IMREAD_COLOR)[:48, :48]
    encoded = {
        "bricks16.png": cv2.imencode(".png", bricks.astype(np.uint16) * 257)[1],
        "bricks.jpg": cv2.imencode(".jpg", bricks)[1],
        "bricks.tif": cv2.imencode(".tif", bricks)[1],
        "bricks-alpha.png": cv2.imencode(".png", np.dstack([bricks, np.full(bricks.shape[:2], 128, np.uint8)]))[1],
    }
    for name, content in encoded.items():
        (folder / name).write_bytes(content.tobytes())
    return {name: folder / name for name in encoded}


@pytest.fixture(scope="session")
def valid_files(tmp_path_factory) -> dict[str, Path]:
    """Format name -> a valid file: bundled samples and fixtures generated here."""
    folder = tmp_path_factory.mktemp("fuzz-valid")
    files = {
        "ply-ascii": SAMPLES / "surfacing-crease.ply",
        "ply-binary": SAMPLES / "retarget-stairs.ply",
        "png8": SAMPLES / "textures" / "bricks.png",
        "stroke-png": SAMPLES / "surfacing-figure-front.png",
        "obj": SAMPLES / "reshape-wall.obj",
    }
    for name in ("reshape-facade.obj", "reshape-facade.mtl", "reshape-facade.png"):
        shutil.copy(SAMPLES / name, folder / name)
    files["mtl"] = folder / "reshape-facade.mtl"
    boxes, images = _box_files(folder), _image_files(folder)
    files |= {"off": boxes["box.off"], "stl-binary": boxes["box.stl"], "stl-ascii": boxes["box-ascii.stl"],
              "glb": boxes["box.glb"], "gltf": boxes["box.gltf"], "label-ply": boxes["labels.ply"],
              "label-ply-ascii": boxes["labels-ascii.ply"], "seg": boxes["labels.seg"],
              "png16": images["bricks16.png"], "jpeg": images["bricks.jpg"], "tiff": images["bricks.tif"],
              "png-alpha": images["bricks-alpha.png"]}
    return files
