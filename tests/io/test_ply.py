"""The one binary PLY writer and reader (synthkit.io.ply)."""

import numpy as np
import pytest
import trimesh

from synthkit.errors import InputError
from synthkit.io.ply import ply_bytes, read_face_property

V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
F = np.array([[0, 1, 2], [0, 1, 3], [1, 2, 3]])


def test_header_and_records_are_exact():
    data = ply_bytes(V, F, vertex=[("w", "float", [0.5, 1, 2, 3])], face=[("label", "int", [7, -1, 2])])
    header, body = data.split(b"end_header\n")
    assert header.decode().splitlines() == [
        "ply", "format binary_little_endian 1.0", "element vertex 4", "property float x", "property float y",
        "property float z", "property float w", "element face 3", "property list uchar int vertex_indices",
        "property int label"]
    assert len(body) == 4 * 16 + 3 * (1 + 12 + 4)
    assert body[:16] == np.array([0, 0, 0, 0.5], "<f4").tobytes()


def test_trimesh_reads_what_we_write(tmp_path):
    colors = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255]], np.uint8)
    face = [("label", "int", [3, 1, 4]), *[(c, "uchar", colors[:, k]) for k, c in enumerate(("red", "green", "blue"))]]
    (tmp_path / "a.ply").write_bytes(ply_bytes(V, F, face=face))
    mesh = trimesh.load(tmp_path / "a.ply", process=False)
    np.testing.assert_array_equal(mesh.faces, F)
    np.testing.assert_array_equal(mesh.metadata["_ply_raw"]["face"]["data"]["label"].ravel(), [3, 1, 4])
    labels = read_face_property(tmp_path / "a.ply", "label")
    assert labels.dtype == np.dtype("<i4") and labels.tolist() == [3, 1, 4]
    assert read_face_property(tmp_path / "a.ply", "green").tolist() == [0, 255, 0]


def test_other_plys_are_read_through_trimesh(tmp_path):
    text = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 2\nproperty list uchar int vertex_indices\nproperty int label\nend_header\n"
            "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2 5\n3 0 1 3 6\n")
    (tmp_path / "a.ply").write_text(text)
    assert read_face_property(tmp_path / "a.ply", "label").tolist() == [5, 6]


def test_errors_name_the_file(tmp_path):
    data = ply_bytes(V, F, face=[("label", "int", [1, 2, 3])])
    (tmp_path / "cut.ply").write_bytes(data[:-5])
    with pytest.raises(InputError, match=r"cut.ply: truncated PLY \(\d+ bytes of data, \d+ expected\)"):
        read_face_property(tmp_path / "cut.ply", "label")
    with pytest.raises(InputError, match=r"cut.ply: PLY has no per-face 'part' property"):
        read_face_property(tmp_path / "cut.ply", "part")
    (tmp_path / "x.ply").write_bytes(b"solid x\n")
    with pytest.raises(InputError, match=r"x.ply: not a PLY file"):
        read_face_property(tmp_path / "x.ply", "label")
    (tmp_path / "h.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement face 2\n")
    with pytest.raises(InputError, match=r"h.ply: truncated PLY header"):
        read_face_property(tmp_path / "h.ply", "label")
