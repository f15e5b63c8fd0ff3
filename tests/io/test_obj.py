"""The one OBJ/MTL codec: what DCC tools need of a written OBJ, and malformed files named by line."""

import json
import struct

import numpy as np
import pytest

from synthkit.asset import Material
from synthkit.errors import InputError
from synthkit.io.assets import load_asset, save_asset
from synthkit.io.obj import obj_text, read_obj

from ..conftest import SHARED_DATA
from .test_assets import QUAD_OBJ, _quad, _texture

HOUSE1 = SHARED_DATA / "architecture" / "houses" / "house1_baked.obj"
KENNEY_A = SHARED_DATA / "meshes" / "kenney-city" / "building-small-a.glb"


def forward_references(text: str) -> list[int]:
    """Line numbers of ``f`` statements that name a ``v``, ``vt`` or ``vn`` not defined above them."""
    counts = {"v": 0, "vt": 0, "vn": 0}
    bad = []
    for number, line in enumerate(text.splitlines(), start=1):
        tokens = line.split()
        if tokens and tokens[0] in counts:
            counts[tokens[0]] += 1
        elif tokens and tokens[0] == "f":
            for corner in tokens[1:]:
                for value, tag in zip(corner.split("/"), ("v", "vt", "vn"), strict=False):
                    if value and int(value) > counts[tag]:
                        bad.append(number)
    return bad


def save(path, asset, **changes):
    V = changes.pop("V", asset.V)
    arrays = dict(corner_uv=asset.corner_uv, face_material=asset.face_material, corner_color=asset.corner_color,
                  face_polygon=asset.face_polygon, face_group=asset.face_group) | changes
    return save_asset(path, V, asset.F, like=asset, **arrays)


def test_new_texture_coordinates_are_written_before_any_face_uses_them(tmp_path):
    obj = _quad(tmp_path, "b.png", tmp_path / "model" / "b.png")
    asset = load_asset(obj)
    asset.materials.append(Material("baked", image=np.full((2, 2, 3), 99, np.uint8)))
    new_uv = asset.corner_uv * 0.5 + 0.25
    save(tmp_path / "out.obj", asset, corner_uv=new_uv, face_material=np.array([1, 1]))
    text = (tmp_path / "out.obj").read_text()
    assert forward_references(text) == []
    assert text.index("\nvt ") < text.index("\nf ")
    again = load_asset(tmp_path / "out.obj")
    np.testing.assert_allclose(again.corner_uv, new_uv, atol=1e-15)
    assert [m.name for m in again.materials] == ["baked"] and (again.materials[0].image == 99).all()


def test_polygons_objects_and_groups_come_back_as_read(tmp_path):
    src = tmp_path / "parts.obj"
    src.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\n"
                   "o house\ng wall\nf 1 2 3 4\ng roof\nf 2 5 6 3\nf 1 2 3\n")
    asset = load_asset(src)
    assert asset.name == "house" and len(asset.F) == 5
    assert asset.groups == [(None, None), ("house", None), ("house", "wall"), ("house", "roof")]
    save(tmp_path / "out.obj", asset)
    statements = [line for line in (tmp_path / "out.obj").read_text().splitlines() if line[:2] in ("o ", "g ", "f ")]
    assert [s.split()[0] + (f" {len(s.split()) - 1}" if s[0] == "f" else f" {s.split()[1]}") for s in statements] == [
        "o house", "g wall", "f 4", "g roof", "f 4", "f 3"]


def test_a_material_name_with_a_space_is_one_name(tmp_path):
    (tmp_path / "a.mtl").write_text("newmtl red paint\nKd 1 0 0\n")
    (tmp_path / "a.obj").write_text("mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red paint\nf 1 2 3\n")
    asset = load_asset(tmp_path / "a.obj")
    assert [m.name for m in asset.materials] == ["red paint"]
    np.testing.assert_allclose(asset.materials[0].color, [1, 0, 0, 1])
    save(tmp_path / "out.obj", asset)
    assert "usemtl red paint" in (tmp_path / "out.obj").read_text()
    assert (tmp_path / "out.mtl").read_text().splitlines()[:2] == ["newmtl red paint", "Kd 1 0 0"]


@pytest.mark.parametrize("text, message", [
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nv 1.2 1.0\n",
     r"a.obj: line 5: malformed OBJ statement: 'v' needs 3 numbers, got 2"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", r"a.obj: line 4: vertex index out of range \(3 defined\)"),
    ("v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n", r"a.obj: line 2: malformed OBJ statement: 'v' has a NaN or infinite"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n", r"a.obj: line 5: texture index out of range \(1 defined\)"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", r"a.obj: line 4: malformed OBJ statement: vertex index 0 is out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999999\n", r"line 4: .*vertex index 9+ is out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", r"a.obj: line 4: malformed OBJ statement: 'f' needs 3 corners, got 2"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/-1 2 3\n", r"a.obj: line 4: malformed OBJ statement: texture index -1 is out"),
    ("v 0 0 0\nv 1 0 0\n", r"a.obj: mesh has no faces \(2 vertices, no triangles\)"),
])
def test_malformed_statements_name_the_file_and_line(tmp_path, text, message):
    (tmp_path / "a.obj").write_text(text)
    with pytest.raises(InputError, match=message):
        load_asset(tmp_path / "a.obj")


def test_relative_indices(tmp_path):
    (tmp_path / "a.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 1 1 0\nf -3 -4 -1\n")
    np.testing.assert_array_equal(read_obj(tmp_path / "a.obj").corners[..., 0], [[0, 1, 2], [1, 0, 3]])


def test_only_the_vertices_faces_use_are_written(tmp_path):
    src = tmp_path / "a.obj"
    src.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nv 1 1 0\nf 1 2 3\nf 2 5 3\n")
    for suffix in (".obj", ".ply", ".glb", ".off", ".stl"):
        save(tmp_path / f"out{suffix}", load_asset(src))
        again = load_asset(tmp_path / f"out{suffix}")
        assert len(np.unique(again.F)) == len(again.V), suffix
        assert not np.isclose(again.V, 5).all(axis=1).any(), suffix


def test_uvs_without_a_material_invent_none(tmp_path):
    (tmp_path / "a.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
    names = save(tmp_path / "out.obj", load_asset(tmp_path / "a.obj"))
    assert names == ["out.obj"]
    text = (tmp_path / "out.obj").read_text()
    assert "mtllib" not in text and "usemtl" not in text and text.count("\nvt ") == 3


def test_every_texture_map_is_copied_and_renamed(tmp_path):
    model = tmp_path / "model"
    model.mkdir()
    _texture(model / "c.png")
    _texture(model / "n.png")
    (model / "wall.mtl").write_text("newmtl bricks\nKd 1 1 1\nmap_Kd c.png\nmap_Bump -bm 0.5 n.png\nbump n.png\n")
    (model / "wall.obj").write_text(QUAD_OBJ.format(mtl="wall.mtl"))
    (tmp_path / "out").mkdir()
    names = save(tmp_path / "out" / "wall.obj", load_asset(model / "wall.obj"))
    assert names == ["wall.obj", "wall.mtl", "wall_c.png", "wall_n.png"]
    assert (tmp_path / "out" / "wall.mtl").read_text().splitlines() == [
        "newmtl bricks", "Kd 1 1 1", "map_Kd wall_c.png", "map_Bump -bm 0.5 wall_n.png", "bump wall_n.png"]


def test_obj_text_writes_polygon_fans_back_and_splits_broken_ones():
    corners = np.zeros((3, 3, 3), np.int64) - 1
    corners[..., 0] = [[0, 1, 2], [0, 2, 3], [4, 5, 6]]
    text = obj_text(np.zeros((7, 3)), corners, face_polygon=np.array([0, 0, 1]))
    assert [line for line in text.splitlines() if line.startswith("f")] == ["f 1 2 3 4", "f 5 6 7"]
    corners[1, 0, 0] = 5  # no longer a fan of the first polygon
    text = obj_text(np.zeros((7, 3)), corners, face_polygon=np.array([0, 0, 1]))
    assert [line for line in text.splitlines() if line.startswith("f")] == ["f 1 2 3", "f 6 3 4", "f 5 6 7"]


@pytest.mark.skipif(not HOUSE1.is_file(), reason="../shared/data/architecture not present")
def test_house1_written_again_keeps_its_284_polygons_and_defines_before_use(tmp_path):
    asset = load_asset(HOUSE1)
    names = save(tmp_path / "house1.obj", asset, V=asset.V * [1.3, 1, 1])
    assert names == ["house1.obj", "house1.mtl", "house1_house_a_bake.png"]
    text = (tmp_path / "house1.obj").read_text()
    assert forward_references(text) == []
    assert sum(line.startswith("f ") for line in text.splitlines()) == 284
    assert "o house1_baked_Cube.029" in text
    again = load_asset(tmp_path / "house1.obj")
    np.testing.assert_allclose(again.corner_uv, asset.corner_uv, atol=1e-15)
    np.testing.assert_allclose(again.V[again.F], (asset.V * [1.3, 1, 1])[asset.F], atol=1e-12)


def _glb_json(path):
    data = path.read_bytes()
    return json.loads(data[20:20 + struct.unpack_from("<I", data, 12)[0]])


@pytest.mark.skipif(not KENNEY_A.is_file(), reason="../shared/data/meshes/kenney-city not present")
def test_glb_keeps_names_normals_tangents_sampler_and_image(tmp_path):
    asset = load_asset(KENNEY_A)
    save(tmp_path / "out.glb", asset)
    src, out = _glb_json(KENNEY_A), _glb_json(tmp_path / "out.glb")
    assert out["scenes"][0]["name"] == src["scenes"][0]["name"] == "building-small-a"
    assert out["nodes"][0]["name"] == src["nodes"][0]["name"]
    assert out["meshes"][0]["name"] == src["meshes"][0]["name"]
    assert out["materials"] == src["materials"]
    assert out["samplers"] == src["samplers"] and out["textures"] == src["textures"]
    assert out["images"][0]["name"] == "colormap" and out["images"][0]["mimeType"] == "image/png"
    assert out["extensionsUsed"] == ["KHR_texture_transform"]
    attributes = out["meshes"][0]["primitives"][0]["attributes"]
    assert sorted(attributes) == ["NORMAL", "POSITION", "TANGENT", "TEXCOORD_0"]
    again = load_asset(tmp_path / "out.glb")
    assert again.materials[0].image.shape == asset.materials[0].image.shape
    np.testing.assert_allclose(again.corner_uv, asset.corner_uv, atol=1e-6)


def test_a_malformed_mtl_number_names_the_mtl_and_its_line(tmp_path):
    (tmp_path / "a.mtl").write_text("newmtl red\nNs 10\nKd 1 x 0\n")
    (tmp_path / "a.obj").write_text("mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n")
    with pytest.raises(InputError, match=r"a.mtl: line 3: malformed MTL statement: could not convert string"):
        load_asset(tmp_path / "a.obj")


def test_a_gltf_with_external_buffers_keeps_its_image_bytes(tmp_path):
    import trimesh
    from PIL import Image

    texture = (np.arange(4 * 4 * 3) % 251).astype(np.uint8).reshape(4, 4, 3)
    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(
        uv=(box.vertices[:, :2] + 0.5) * 0.9,
        material=trimesh.visual.material.PBRMaterial(name="paint", baseColorTexture=Image.fromarray(texture)))
    for name, data in trimesh.Scene(box).export(file_type="gltf").items():
        (tmp_path / name).write_bytes(data)
    asset = load_asset(tmp_path / "model.gltf")
    assert asset.materials[0].gltf_index == 0 and asset.gltf.images[0][1].startswith(b"\x89PNG")
    save(tmp_path / "out.glb", asset)
    out = _glb_json(tmp_path / "out.glb")
    assert out["materials"][0]["name"] == "paint" and out["images"][0]["mimeType"] == "image/png"
    np.testing.assert_array_equal(load_asset(tmp_path / "out.glb").materials[0].image[..., :3], texture)


def test_polygon_and_group_arrays_of_the_wrong_shape_are_refused(tmp_path):
    (tmp_path / "a.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\no one\nf 1 2 3\n")
    asset = load_asset(tmp_path / "a.obj")
    with pytest.raises(ValueError, match=r"face_polygon must have shape \(1,\), got \(2,\)"):
        save(tmp_path / "out.obj", asset, face_polygon=np.zeros(2, np.int64))
    with pytest.raises(ValueError, match=r"face_group indexes 2 groups"):
        save(tmp_path / "out.obj", asset, face_group=np.array([5]))
