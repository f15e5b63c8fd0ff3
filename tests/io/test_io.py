"""Mesh and image IO: formats, labels, and one-line errors for bad files."""

import numpy as np
import pytest
import trimesh

from synthkit.errors import InputError
from synthkit.io.images import load_image, save_image
from synthkit.io.meshes import load_face_labels, load_mesh, save_mesh


@pytest.fixture
def tetra():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int64)
    return trimesh.Trimesh(V, F, process=False)


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".off", ".stl", ".glb"])
def test_roundtrip_formats(tmp_path, tetra, suffix):
    path = tmp_path / f"t{suffix}"
    save_mesh(tetra, path)
    mesh = load_mesh(path, process=True)
    assert len(mesh.faces) == 4
    assert mesh.metadata["merged_geometries"] == 1
    assert mesh.volume == pytest.approx(1 / 6)


def test_ply_face_labels_int32(tmp_path, tetra):
    path = tmp_path / "labels.ply"
    save_mesh(tetra, path, face_labels=np.array([3, 1, 4, 1]))
    labels = load_face_labels(path)
    assert labels.dtype == np.int32 and labels.tolist() == [3, 1, 4, 1]
    np.testing.assert_allclose(load_mesh(path).vertices, tetra.vertices)


def test_ply_face_labels_with_colours(tmp_path, tetra):
    path = tmp_path / "coloured.ply"
    colours = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [9, 8, 7]], np.uint8)
    save_mesh(tetra, path, face_labels=np.array([3, 1, 4, 1]), face_colors=colours)
    np.testing.assert_array_equal(load_face_labels(path), [3, 1, 4, 1])
    face = trimesh.load(path, process=False).metadata["_ply_raw"]["face"]["data"]
    np.testing.assert_array_equal(np.stack([face[c].ravel() for c in ("red", "green", "blue")], 1), colours)
    with pytest.raises(ValueError, match="face colours are stored beside face labels only"):
        save_mesh(tetra, path, face_colors=colours)
    with pytest.raises(ValueError, match=r"face_colors has shape \(3, 3\), expected \(4, 3\)"):
        save_mesh(tetra, path, face_labels=np.zeros(4), face_colors=colours[:3])


def test_face_labels_shape_and_format_checked(tmp_path, tetra):
    with pytest.raises(ValueError, match=r"face_labels has shape \(3,\), expected \(4,\)"):
        save_mesh(tetra, tmp_path / "a.ply", face_labels=np.zeros(3))
    with pytest.raises(ValueError, match="PLY files only"):
        save_mesh(tetra, tmp_path / "a.obj", face_labels=np.zeros(4))


def test_scene_is_merged(tmp_path, tetra):
    other = tetra.copy()
    other.apply_translation([5, 0, 0])
    scene = trimesh.Scene([tetra, other])
    path = tmp_path / "scene.glb"
    scene.export(path)
    mesh = load_mesh(path)
    assert len(mesh.faces) == 8
    assert mesh.metadata["merged_geometries"] == 2
    assert mesh.bounds[1][0] == pytest.approx(6.0)


def test_missing_mesh(tmp_path):
    with pytest.raises(InputError, match=r"nope\.obj: mesh file not found"):
        load_mesh(tmp_path / "nope.obj")


def test_corrupt_mesh(tmp_path):
    path = tmp_path / "bad.ply"
    path.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 99\nend_header\n\x00")
    with pytest.raises(InputError, match=r"bad\.ply: cannot read mesh"):
        load_mesh(path)


def test_empty_mesh(tmp_path):
    path = tmp_path / "empty.obj"
    path.write_text("# nothing\n")
    with pytest.raises(InputError, match=r"empty\.obj: (mesh has no faces|file holds no triangle mesh)"):
        load_mesh(path)


def test_vertices_without_faces(tmp_path):
    path = tmp_path / "cloud.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n")
    with pytest.raises(InputError, match=r"cloud\.obj: mesh has no faces \(4 vertices, no triangles\)$"):
        load_mesh(path)


def test_nan_vertices(tmp_path):
    path = tmp_path / "nan.obj"
    path.write_text("v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(InputError, match=r"nan\.obj: 1 vertices have NaN or infinite coordinates"):
        load_mesh(path)


def test_unsupported_suffix(tmp_path):
    path = tmp_path / "x.fbx"
    path.write_text("x")
    with pytest.raises(InputError, match="unsupported mesh format '.fbx'"):
        load_mesh(path)


@pytest.mark.parametrize("suffix", [".png", ".tif"])
def test_image_16bit_roundtrip(tmp_path, suffix):
    img = (np.arange(12, dtype=np.uint16).reshape(3, 4) * 5000).astype(np.uint16)
    path = tmp_path / f"a{suffix}"
    save_image(path, img)
    back = load_image(path, mode="any")
    np.testing.assert_allclose(back, img / 65535.0, atol=1e-6)


def test_image_modes(tmp_path):
    rgba = np.zeros((2, 3, 4), dtype=np.float32)
    rgba[..., 0] = 1.0
    rgba[..., 3] = 0.5
    path = tmp_path / "c.png"
    save_image(path, rgba)
    assert load_image(path, mode="any").shape == (2, 3, 4)
    rgb = load_image(path, mode="rgb")  # half-transparent red over white
    white = 1.0 - 128 / 255
    assert rgb.shape == (2, 3, 3) and rgb[0, 0].tolist() == pytest.approx([1.0, white, white], abs=1e-6)
    gray = load_image(path, mode="gray")
    assert gray.shape == (2, 3) and gray[0, 0] == pytest.approx(0.299 + 0.701 * white, abs=1e-6)
    grey_path = tmp_path / "g.jpg"
    save_image(grey_path, np.full((8, 8), 0.5, dtype=np.float32))
    assert load_image(grey_path).shape == (8, 8, 3)
    assert load_image(grey_path, mode="gray").mean() == pytest.approx(128 / 255, abs=2 / 255)


def test_bad_images(tmp_path):
    with pytest.raises(InputError, match=r"no\.png: image file not found"):
        load_image(tmp_path / "no.png")
    path = tmp_path / "corrupt.png"
    path.write_bytes(b"\x89PNG\r\n\x1a\nnot really")
    with pytest.raises(InputError, match=r"corrupt\.png: corrupt image: "):
        load_image(path)
    empty = tmp_path / "empty.png"
    empty.write_bytes(b"")
    with pytest.raises(InputError, match=r"empty\.png: image file is empty \(0 bytes\)$"):
        load_image(empty)
