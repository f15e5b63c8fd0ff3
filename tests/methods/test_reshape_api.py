"""synthkit.reshape() over meshes in memory: exact results, nothing written, the CLI's messages,
save() equal to ``synthkit run``, determinism."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

import synthkit
from synthkit.errors import ConfigError, InputError
from synthkit.io.assets import load_asset
from synthkit.runner import run_config

ROOT = Path(__file__).resolve().parents[2]
SAMPLES = ROOT / "data-samples"
FACADE = dict(texture="reshape", handles=[{"half_space": {"axis": "x", "above": 3.99}, "displacement": [4, 0, 0]}],
              fixed=[{"half_space": {"axis": "x", "below": 0.01}}])
"""configs/reshape/facade-texture.yaml's keys."""


def test_box_resize_exact_and_writes_nothing(nothing_written):
    box = trimesh.creation.box(extents=(4.0, 3.0, 0.2))
    result = synthkit.reshape(box, scale={"x": 1.5}, texture="stretch")
    assert result.status == "ok"
    assert list(result.meshes) == ["mesh"]
    np.testing.assert_allclose(result.mesh.extents, [6.0, 3.0, 0.2], atol=1e-9)
    np.testing.assert_array_equal(result.mesh.faces, box.faces)
    # every vertex moves along x only: the lower end (x = -2) stays, the box is 1.5 times as long
    moved = result.mesh.vertices
    np.testing.assert_allclose(moved[:, 1:], box.vertices[:, 1:], atol=1e-9)
    np.testing.assert_allclose(moved[:, 0] + 2.0, 1.5 * (box.vertices[:, 0] + 2.0), atol=1e-9)
    m = result.metrics
    assert m["steps_done"] == 1 and m["max_angle_error_deg"] < 1e-6
    assert m["resize"]["factors"] == [1.5, 1.0, 1.0]
    np.testing.assert_allclose(m["resize"]["extent_ratio"], [1.5, 1.0, 1.0], atol=1e-9)
    assert result.retexture == {"mesh": []} and result.images == {}
    assert result.timings["total"] > 0 and result.input_files == []
    asset = result.asset()
    np.testing.assert_array_equal(asset.V, moved)


def test_vertex_face_arrays_and_index_selection(nothing_written):
    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    V, F = np.asarray(box.vertices), np.asarray(box.faces)
    top = np.flatnonzero(V[:, 2] > 0).tolist()
    bottom = np.flatnonzero(V[:, 2] < 0).tolist()
    result = synthkit.reshape((V, F), handles=[{"index": top, "displacement": [0, 0, 1.0]}],
                              fixed=[{"index": bottom}], texture="stretch", solver={"steps": 4})
    out = result.mesh.vertices
    np.testing.assert_allclose(out[top], V[top] + [0, 0, 1.0], atol=1e-9)
    np.testing.assert_allclose(out[bottom], V[bottom], atol=1e-12)
    assert result.metrics["handles"] == 4 and result.metrics["fixed"] == 4 and result.metrics["steps_done"] == 4


def test_asset_in_memory_equals_the_file(nothing_written):
    """The facade as an Asset in memory gives the file's reshape: positions and baked atlas."""
    path = SAMPLES / "reshape-facade.obj"
    asset = load_asset(path)
    memory = synthkit.reshape(asset, **FACADE)
    from_file = synthkit.reshape(path, **FACADE)
    np.testing.assert_array_equal(memory.mesh.vertices, from_file.mesh.vertices)
    np.testing.assert_array_equal(memory.mesh.faces, from_file.mesh.faces)
    assert list(memory.images) == list(from_file.images) == ["facade_atlas.png"]
    np.testing.assert_array_equal(memory.images["facade_atlas.png"], from_file.images["facade_atlas.png"])
    assert memory.images["facade_atlas.png"].shape == (516, 1544, 3)
    assert memory.metrics["rigid_scale_error"] == from_file.metrics["rigid_scale_error"]
    assert memory.metrics["texture_surfaces"] == 1
    assert from_file.input_files == [path]
    reshaped = memory.asset()
    assert [m.name for m in reshaped.materials] == ["facade", "facade_end", "facade_atlas"]
    assert reshaped.materials[2].image.shape == (516, 1544, 3)
    assert from_file.asset() is None


def test_textured_trimesh_keeps_its_texture(nothing_written):
    """A trimesh with a texture image is reshaped with its texture (trimesh orders faces its own way)."""
    mesh = trimesh.load(SAMPLES / "reshape-facade.obj", process=False, force="mesh")
    result = synthkit.reshape(mesh, **FACADE)
    np.testing.assert_allclose(result.mesh.extents, [8.0, 4.0, 0.2], atol=1e-9)
    assert result.metrics["texture_surfaces"] == 1
    (image,) = result.images.values()
    assert image.dtype == np.float32 and image.shape[2] == 3


def test_pieces_in_memory_equal_the_files(nothing_written):
    chain = [{"a": "road-a", "a_portal": "x+", "b": "road-b", "b_portal": "x-"}]
    keys = dict(chain=chain, handles=[{"piece": "road-b", "half_space": {"axis": "x", "above": 3.49},
                                       "displacement": [1.0, 0, 0]}],
                fixed=[{"piece": "road-a", "half_space": {"axis": "x", "below": 0.01}}])
    files = [SAMPLES / "reshape-road-a.obj", SAMPLES / "reshape-road-b.obj"]
    memory = synthkit.reshape(pieces=[{"name": n, "input": load_asset(f)} for n, f in zip(("road-a", "road-b"), files,
                                                                                          strict=True)], **keys)
    from_file = synthkit.reshape(pieces=[{"name": n, "input": f} for n, f in zip(("road-a", "road-b"), files,
                                                                                 strict=True)], **keys)
    assert list(memory.meshes) == ["road-a", "road-b"]
    for name in memory.meshes:
        np.testing.assert_array_equal(memory.meshes[name].vertices, from_file.meshes[name].vertices)
    assert memory.metrics["joins"][0]["gap"] == from_file.metrics["joins"][0]["gap"] < 1e-9


def test_key_errors_give_the_command_lines_message(nothing_written):
    box = trimesh.creation.box()
    with pytest.raises(ConfigError, match=r"synthkit\.reshape\(\).*give exactly one of handles, scale, size"):
        synthkit.reshape(box)
    with pytest.raises(ConfigError, match=r"stifness"):
        synthkit.reshape(box, scale={"x": 2.0}, stifness={"l_min": 1.0})
    with pytest.raises(ConfigError, match=r"scale\.x"):
        synthkit.reshape(box, scale={"x": -1.0})
    with pytest.raises(ConfigError, match=r"scale\.x: 1000000\.0 moves vertices by .* model sizes; at most 100"):
        synthkit.reshape(box, scale={"x": 1e6})
    with pytest.raises(InputError, match=r"synthkit\.reshape\(\): input: .*no faces"):
        synthkit.reshape((np.zeros((3, 3)), np.zeros((0, 3), np.int64)), scale={"x": 2.0})


def test_save_writes_what_synthkit_run_writes(tmp_path):
    """``save`` of a file's reshape writes the bytes ``synthkit run`` writes for the same keys."""
    config = ROOT / "configs" / "reshape" / "wall-resize.yaml"
    run_config(config, out_dir=tmp_path / "run", show_progress=False)
    result = synthkit.reshape(SAMPLES / "reshape-wall.obj", stiffness={"l_min": 2.5}, scale={"x": 2.0})
    report = result.save(tmp_path / "saved")
    assert report["config_file"] is None and report["status"] == "ok"
    for name in ("reshape-wall.obj", "reshape-wall.mtl", "reshape-wall_bricks_tiled.png",
                 "after.png", "comparison.png", "before_after.png"):
        assert (tmp_path / "saved" / name).read_bytes() == (tmp_path / "run" / name).read_bytes(), name


def test_save_of_a_mesh_in_memory_writes_an_obj(tmp_path):
    result = synthkit.reshape(load_asset(SAMPLES / "reshape-facade.obj"), **FACADE)
    result.save(tmp_path / "out")
    written = load_asset(tmp_path / "out" / "mesh.obj")
    np.testing.assert_allclose(written.V, result.mesh.vertices, atol=1e-12)
    atlas = {m.name: m for m in written.materials}["facade_atlas"]
    assert atlas.image.shape == (516, 1544, 3)
    assert (tmp_path / "out" / "before_after.png").is_file()


def test_same_seed_same_result():
    """texture: continue quilts plaster from its own texels with the run's rng."""
    asset = load_asset(SAMPLES / "reshape-facade.obj")
    keys = {**FACADE, "texture": "continue", "seed": 3}
    a, b = synthkit.reshape(asset, **keys), synthkit.reshape(asset, **keys)
    np.testing.assert_array_equal(a.X, b.X)
    assert list(a.images) == list(b.images) and a.images
    for name in a.images:
        np.testing.assert_array_equal(a.images[name], b.images[name])


def test_docstring_example_runs():
    import doctest

    from synthkit.methods.reshape import api

    failed, tried = doctest.testmod(api)
    assert tried >= 4 and failed == 0


def test_textured_from_asset_render_vertices_and_back():
    """A UV seam splits a position into two render vertices; faces without a material get ``""``;
    reshaped_asset moves the positions and gives a retextured face its UVs and material."""
    from synthkit.asset import Asset, Material
    from synthkit.io.inputs import image_from_array
    from synthkit.methods.reshape.textured import Retexture, reshaped_asset, textured_from_asset

    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    uv = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [0.5, 0.5], [0, 1]]], float)  # vertex 2: two UVs
    image = np.full((4, 4, 3), 128, np.uint8)
    asset = Asset(V=V, F=F, corner_uv=uv, corner_color=None, face_material=np.array([0, -1]),
                  materials=[Material("brick", image=image)], name="quad", source=Path("input"))
    mesh = textured_from_asset(asset, "input", {"brick": image_from_array(image, "input: material brick")})
    assert len(mesh.V) == 5 and mesh.materials == ["brick", ""]
    np.testing.assert_array_equal(mesh.V, V[mesh.position_index])
    np.testing.assert_array_equal(mesh.position_index[mesh.F], F)
    np.testing.assert_array_equal(mesh.UV[mesh.F], uv)
    np.testing.assert_allclose(mesh.textures["brick"], 128 / 255, atol=1e-7)
    UV = np.zeros((5, 2))
    UV[mesh.F[1]] = [[0.1, 0.2], [0.3, 0.4], [0.5, 0.6]]
    entry = Retexture(np.array([1]), UV, "brick_retex1", "brick_retex1.png", np.full((2, 2, 3), 0.5, np.float32))
    out = reshaped_asset(mesh, 2 * V, [entry])
    np.testing.assert_array_equal(out.V, 2 * V)
    assert out.face_material.tolist() == [0, 1] and out.materials[1].name == "brick_retex1"
    np.testing.assert_array_equal(out.corner_uv[1], [[0.1, 0.2], [0.3, 0.4], [0.5, 0.6]])
    np.testing.assert_array_equal(out.corner_uv[0], uv[0])
    assert out.materials[1].image.dtype == np.uint8 and (out.materials[1].image == 128).all()
