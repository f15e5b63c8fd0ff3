"""Assets keep their appearance: UVs, materials, textures, colours and names, in and out."""

import logging

import numpy as np
import pytest
import trimesh

from synthkit.errors import InputError
from synthkit.io.assets import corner_normals, load_asset, save_asset
from synthkit.io.images import save_image

from ..conftest import SHARED_DATA

QUAD_OBJ = """mtllib {mtl}
o wall
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
usemtl bricks
f 1/1 2/2 3/3 4/4
"""


def _texture(path, shape=(8, 16, 3)):
    img = np.zeros(shape, np.float32)
    img[..., 0] = np.linspace(0, 1, shape[1])[None, :]
    img[..., 1] = np.linspace(0, 1, shape[0])[:, None]
    save_image(path, img)
    return img


def _quad(tmp_path, map_kd, texture_at=None):
    """A textured quad in tmp/model/ whose MTL names ``map_kd``; the texture written at ``texture_at``."""
    model = tmp_path / "model"
    model.mkdir()
    (model / "wall.mtl").write_text(f"newmtl bricks\nKd 0.8 0.7 0.6\nNs 10\nmap_Kd {map_kd}\n")
    (model / "wall.obj").write_text(QUAD_OBJ.format(mtl="wall.mtl"))
    if texture_at is not None:
        texture_at.parent.mkdir(parents=True, exist_ok=True)
        _texture(texture_at)
    return model / "wall.obj"


def _tree(root):
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


@pytest.mark.parametrize("where", ["same", "sibling", "absolute"])
def test_obj_texture_found_and_copied_inside_output(tmp_path, where):
    texture = {"same": tmp_path / "model" / "b.png", "sibling": tmp_path / "textures" / "b.png",
               "absolute": tmp_path / "abs" / "b.png"}[where]
    name = {"same": "b.png", "sibling": "../textures/b.png", "absolute": str(texture)}[where]
    obj = _quad(tmp_path, name, texture)
    asset = load_asset(obj)
    assert asset.name == "wall"
    assert asset.corner_uv.shape == (2, 3, 2)
    assert asset.materials[0].image.shape == (8, 16, 3)
    out = tmp_path / "out"
    out.mkdir()
    before = _tree(tmp_path)
    written = save_asset(out / "result.obj", asset.V, asset.F, like=asset, corner_uv=asset.corner_uv,
                         face_material=asset.face_material)
    assert written == ["result.obj", "result.mtl", "result_b.png"]
    assert sorted(set(_tree(tmp_path)) - set(before)) == ["out/result.mtl", "out/result.obj", "out/result_b.png"]
    mtl = (out / "result.mtl").read_text().splitlines()
    assert mtl[:4] == ["newmtl bricks", "Kd 0.8 0.7 0.6", "Ns 10", "map_Kd result_b.png"]
    again = load_asset(out / "result.obj")
    assert np.array_equal(again.materials[0].image, asset.materials[0].image)
    assert np.allclose(np.sort(again.corner_uv.reshape(-1, 2), axis=0), np.sort(asset.corner_uv.reshape(-1, 2), axis=0))
    assert (again.name, again.materials[0].name) == ("wall", "bricks")


def test_missing_texture_is_one_warning_and_no_invented_material(tmp_path, caplog):
    obj = _quad(tmp_path, "gone.png")
    with caplog.at_level(logging.WARNING, logger="synthkit"):
        asset = load_asset(obj)
    lines = [r.getMessage() for r in caplog.records]
    assert lines == [f"{tmp_path / 'model' / 'wall.mtl'}: texture file gone.png of material bricks is missing; "
                     "loading without texture"]
    assert asset.materials[0].image is None
    out = tmp_path / "out"
    out.mkdir()
    assert save_asset(out / "r.obj", asset.V, asset.F, like=asset, corner_uv=asset.corner_uv) == ["r.obj", "r.mtl"]
    assert "map_Kd" not in (out / "r.mtl").read_text()


def test_texture_that_is_not_an_image_is_an_input_error(tmp_path):
    model = tmp_path / "model"
    model.mkdir()
    (tmp_path / "notes.txt").write_text("root:x:0:0\n")
    (model / "wall.mtl").write_text(f"newmtl bricks\nmap_Kd {tmp_path / 'notes.txt'}\n")
    obj = model / "wall.obj"
    obj.write_text(QUAD_OBJ.format(mtl="wall.mtl"))
    with pytest.raises(InputError, match=r"wall.mtl: texture .*notes.txt is not an image file"):
        load_asset(obj)


def test_uvs_without_material_warn_once(tmp_path, caplog):
    obj = tmp_path / "plain.obj"
    obj.write_text(QUAD_OBJ.replace("mtllib {mtl}\n", "").replace("usemtl bricks\n", ""))
    with caplog.at_level(logging.WARNING, logger="synthkit"):
        asset = load_asset(obj)
    assert [r.getMessage() for r in caplog.records] == [
        f"{obj}: has texture coordinates but no material; UVs kept, no texture applied"]
    assert asset.materials == [] and asset.corner_uv is not None
    out = tmp_path / "o.obj"
    assert save_asset(out, asset.V, asset.F, like=asset, corner_uv=asset.corner_uv) == ["o.obj"]
    assert "mtllib" not in out.read_text() and out.read_text().count("vt ") == 4


def test_glb_keeps_pbr_material_texture_uvs_and_name(tmp_path):
    from PIL import Image

    texture = (np.arange(4 * 4 * 3) % 251).astype(np.uint8).reshape(4, 4, 3)
    material = trimesh.visual.material.PBRMaterial(name="paint", baseColorTexture=Image.fromarray(texture),
                                                   metallicFactor=0.0, roughnessFactor=0.5)
    box = trimesh.creation.box()
    uv = (box.vertices[:, :2] + 0.5) * 0.9
    box.visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    scene = trimesh.Scene()
    scene.add_geometry(box, geom_name="crate", node_name="crate")
    src = tmp_path / "crate.glb"
    src.write_bytes(scene.export(file_type="glb"))
    asset = load_asset(src)
    assert asset.name == "crate"
    out = tmp_path / "out.glb"
    assert save_asset(out, asset.V, asset.F, like=asset, corner_uv=asset.corner_uv) == ["out.glb"]
    again = load_asset(out)
    assert again.name == "crate"
    assert again.materials[0].name == "paint"
    assert again.gltf.materials[0]["pbrMetallicRoughness"]["roughnessFactor"] == pytest.approx(0.5)
    assert np.array_equal(again.materials[0].image[..., :3], texture)
    assert np.allclose(again.corner_uv, asset.corner_uv, atol=1e-6)


def test_ply_colours_round_trip(tmp_path):
    box = trimesh.creation.box()
    colors = np.tile([[200, 10, 30, 255]], (len(box.vertices), 1)).astype(np.uint8)
    colors[0] = [0, 255, 0, 255]
    src = tmp_path / "c.ply"
    colored = trimesh.Trimesh(box.vertices, box.faces, vertex_colors=colors, process=False)
    src.write_bytes(colored.export(file_type="ply"))
    asset = load_asset(src)
    assert asset.corner_color.shape == (12, 3, 4)
    save_asset(tmp_path / "d.ply", asset.V, asset.F, like=asset, corner_color=asset.corner_color)
    again = load_asset(tmp_path / "d.ply")
    rows = [np.sort(a.corner_color.reshape(-1, 4), axis=0) for a in (again, asset)]
    assert np.array_equal(*rows)


def test_save_refuses_wrong_shapes(tmp_path):
    box = trimesh.creation.box()
    like = load_asset(_write(tmp_path / "b.stl", box))
    with pytest.raises(ValueError, match=r"corner_uv must have shape \(12, 3, 2\), got \(12, 2\)"):
        save_asset(tmp_path / "x.obj", box.vertices, box.faces, like=like, corner_uv=np.zeros((12, 2)))
    with pytest.raises(ValueError, match=r"unsupported mesh format '.fbx'"):
        save_asset(tmp_path / "x.fbx", box.vertices, box.faces, like=like)


def _write(path, mesh):
    path.write_bytes(mesh.export(file_type=path.suffix[1:]))
    return path


def test_corner_normals_keep_hard_edges_and_smooth_soft_ones():
    box = trimesh.creation.box()
    N = corner_normals(np.asarray(box.vertices), np.asarray(box.faces))
    assert np.allclose(N, np.repeat(box.face_normals[:, None], 3, axis=1))
    sphere = trimesh.creation.icosphere(3)
    Ns = corner_normals(np.asarray(sphere.vertices), np.asarray(sphere.faces))
    expected = sphere.vertices[sphere.faces] / np.linalg.norm(sphere.vertices[sphere.faces], axis=2, keepdims=True)
    assert np.abs(Ns - expected).max() < 0.02


KENNEY = SHARED_DATA / "meshes" / "kenney-city" / "building-small-a.glb"


@pytest.mark.skipif(not KENNEY.is_file(), reason=f"{KENNEY} not present (../shared/data)")
@pytest.mark.parametrize("suffix", [".glb", ".obj"])
def test_kenney_palette_survives_a_round_trip(tmp_path, suffix):
    asset = load_asset(KENNEY)
    written = save_asset(tmp_path / f"k{suffix}", asset.V, asset.F, like=asset, corner_uv=asset.corner_uv,
                         face_material=asset.face_material)
    again = load_asset(tmp_path / written[0])
    assert len(again.F) == len(asset.F)

    def centroid_colours(a):
        img = a.materials[0].image
        uv = a.corner_uv.mean(axis=1)
        px = np.clip((uv[:, 0] * img.shape[1]).astype(int), 0, img.shape[1] - 1)
        py = np.clip(((1 - uv[:, 1]) * img.shape[0]).astype(int), 0, img.shape[0] - 1)
        return img[py, px, :3]

    def table(a):  # (face centroid, colour) rows, as a sorted multiset
        rows = np.concatenate([a.V[a.F].mean(axis=1).round(5), centroid_colours(a)], axis=1)
        return rows[np.lexsort(rows.T[::-1])]

    assert np.array_equal(table(again), table(asset))


@pytest.mark.parametrize("line, name", [("map_Kd a.png", "a.png"), ("map_Kd my bricks.png", "my bricks.png"),
                                        ("map_Kd -s 1 1 1 -clamp on ../t/b.jpg", "../t/b.jpg"),
                                        ("map_Kd -mm 0 1 c.png", "c.png")])
def test_map_file_name(line, name):
    from synthkit.io.obj import map_file_name

    assert map_file_name(line) == name
