"""The cases the fuzzers found (issue 37), each fixed and pinned with its exact message."""

from __future__ import annotations

import struct
import warnings

import numpy as np
import pytest
import trimesh

from synthkit.errors import InputError
from synthkit.io.assets import load_asset
from synthkit.io.meshes import check_mesh, load_face_labels, load_mesh
from synthkit.io.ply import ply_bytes
from synthkit.io.probe import mesh_face_count
from synthkit.io.segmentation import read_seg

BOX = trimesh.creation.box()
HEADER = ("ply\nformat binary_little_endian 1.0\nelement vertex 8\nproperty float x\nproperty float y\n"
          "property float z\nelement face 12\nproperty list uchar int vertex_indices\nproperty int label\nend_header\n")


def _label_ply(header: str = HEADER) -> bytes:
    body = ply_bytes(BOX.vertices, BOX.faces, face=[("label", "int", np.zeros(12))]).split(b"end_header\n", 1)[1]
    return header.encode() + body


@pytest.mark.parametrize("edit, message", [
    (("element face 12", "element face nan"), "PLY header line 7: expected 'element <name> <count>', got "
                                              "'element face nan'"),
    (("element face 12", "element face -1"), "PLY header line 7: expected 'element <name> <count>', got "
                                             "'element face -1'"),
    (("property float z\n", "property float z\nproperty float z\n"),
     "PLY header line 7: property 'z' of element 'vertex' is declared twice"),
    (("property list uchar int vertex_indices\n", ""), "PLY element 'face' has no vertex_indices list"),
    (("property list uchar int vertex_indices", "property list uchar"), "PLY header line 8: malformed property "
                                                                        "line 'property list uchar'"),
    (("property float x\nproperty float y\nproperty float z\n", ""),
     "PLY element 'vertex' has 8 records but no properties"),
])
def test_label_ply_headers(tmp_path, edit, message):
    path = tmp_path / "labels.ply"
    path.write_bytes(_label_ply(HEADER.replace(*edit)))
    with pytest.raises(InputError) as caught:
        load_face_labels(path)
    assert str(caught.value) == f"{path}: {message}"


def test_a_label_ply_with_a_nan_label_names_the_face(tmp_path):
    path = tmp_path / "labels.ply"
    labels = np.zeros(12)
    labels[4] = np.nan
    path.write_bytes(ply_bytes(BOX.vertices, BOX.faces, face=[("label", "float", labels)]))
    with pytest.raises(InputError) as caught:
        load_face_labels(path)
    assert str(caught.value) == f"{path}: PLY face 4 has label nan; expected a finite number"


def test_an_ascii_label_ply_with_a_ragged_face_row(tmp_path):
    rows = "".join(f"3 {a} {b} {c} 0\n" for a, b, c in BOX.faces[1:])
    text = HEADER.replace("binary_little_endian", "ascii") + "".join(f"{x} {y} {z}\n" for x, y, z in BOX.vertices)
    path = tmp_path / "labels.ply"
    path.write_text(text + "3 0 1 2 0 0\n" + rows)
    with pytest.raises(InputError) as caught:
        load_face_labels(path)
    assert str(caught.value) == f"{path}: PLY face property 'label' is not one number per face"


@pytest.mark.parametrize("text, message", [
    (b"", "segmentation holds no labels"),
    (b"0\n1\nnan\n", "line 3: 'nan' is not an integer face label"),
    (b"0\n1.5\n", "line 2: '1.5' is not an integer face label"),
    (b"0\n99999999999\n", "line 2: '99999999999' is not an integer face label"),
    (b"0\n\xff\xfe\n", r"line 2: '\\xff\\xfe' is not an integer face label"),
])
def test_seg_lines(tmp_path, text, message):
    path = tmp_path / "labels.seg"
    path.write_bytes(text)
    with pytest.raises(InputError) as caught:
        read_seg(path)
    assert str(caught.value) == f"{path}: {message}"


def test_seg_comments_and_blank_lines_are_skipped(tmp_path):
    path = tmp_path / "labels.seg"
    path.write_bytes(b"# labels\n0\n\n-2  # a comment\n+3\n")
    assert read_seg(path, 3).tolist() == [0, -2, 3]


def _glb_with_face(tmp_path, index: int):
    mesh = BOX.copy()
    faces = np.asarray(mesh.faces).copy()
    faces[3, 1] = index
    data = bytearray(mesh.export(file_type="glb"))
    original = np.asarray(BOX.faces, np.uint32).tobytes()
    start = bytes(data).find(original[:36])
    assert start > 0
    data[start:start + len(original)] = faces.astype(np.uint32).tobytes()
    path = tmp_path / "box.glb"
    path.write_bytes(bytes(data))
    return path


@pytest.mark.parametrize("read", [load_mesh, load_asset])
def test_a_face_naming_a_missing_vertex_is_refused_with_the_face(tmp_path, read):
    """trimesh loads the GLB (and PLY) whose face names vertex 34306 of 8; the colours, UVs and
    sparse matrices built from it raised IndexError or ValueError (exit 1)."""
    path = _glb_with_face(tmp_path, 34306)
    with pytest.raises(InputError) as caught:
        read(path)
    assert str(caught.value) == f"{path}: face 3 names vertex 34306, out of range [0, 8) (1 such faces)"


def test_huge_coordinates_give_no_overflow_warning():
    V = np.array([[0, 0, 0], [1e308, 0, 0], [0, 1e308, 0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_mesh(V, np.array([[0, 1, 2]]))


def test_nan_vertices_name_the_first():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, np.nan, 0], [np.inf, 0, 0]])
    with pytest.raises(InputError) as caught:
        check_mesh(V, np.array([[0, 1, 2]]), source="m.ply")
    assert str(caught.value) == "m.ply: 2 vertices have NaN or infinite coordinates (first: vertex 2)"


def test_a_glb_whose_json_indexes_with_a_float_has_no_face_count(tmp_path):
    doc = b'{"accessors": [{"count": 3}], "meshes": [{"primitives": [{"indices": 0.0}]}]}'
    path = tmp_path / "x.glb"
    path.write_bytes(b"glTF" + struct.pack("<III", 2, 20 + len(doc), len(doc)) + b"JSON" + doc)
    assert mesh_face_count(path) is None
