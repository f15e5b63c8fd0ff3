"""The shared layer of the in-memory functions: synthkit.api and synthkit.io.inputs."""

import json
import os

import numpy as np
import pytest
import trimesh

from synthkit.api import prepare, run_in_memory
from synthkit.asset import Asset, Material
from synthkit.errors import ConfigError, InputError
from synthkit.io.assets import asset_from_trimesh
from synthkit.io.images import load_image, save_image
from synthkit.io.inputs import Inputs, image_from_array, memory_name


def _echo_compute():
    from echo_method.pipeline import compute

    return compute


# ---------------------------------------------------------------- prepare


def test_prepare_puts_a_stand_in_where_the_object_goes(echo_method):
    img = np.zeros((2, 3), np.uint8)
    cfg, inputs = prepare("echo", "synthkit.echo()", {"image": img}, {"mode": "invert", "filter": {"sigma": 2.0}})
    assert str(cfg.image) == "<memory:image>" == memory_name("image")
    assert inputs.is_memory(cfg.image) and inputs.objects["<memory:image>"] is img
    assert (cfg.mode, cfg.filter.sigma, cfg.gain) == ("invert", 2.0, 1.0)
    assert inputs.files == []


def test_prepare_gives_the_command_lines_messages(echo_method):
    img = np.zeros((2, 3), np.uint8)
    with pytest.raises(ConfigError, match=r"^synthkit.echo\(\): unknown key 'mdoe' \(did you mean 'mode'\?\)$"):
        prepare("echo", "synthkit.echo()", {"image": img}, {"mdoe": "invert"})
    with pytest.raises(ConfigError, match=r"^synthkit.echo\(\): gain: Input should be less than or equal to 10"):
        prepare("echo", "synthkit.echo()", {"image": img}, {"gain": 11})
    with pytest.raises(ConfigError, match=r"filter.sigma: Input should be greater than or equal to 0"):
        prepare("echo", "synthkit.echo()", {"image": img}, {"filter": {"sigma": -1}})


@pytest.mark.parametrize(("value", "kind"), [([[0, 1]], "list"), (42, "int")])
def test_prepare_refuses_what_is_neither_an_object_nor_a_path(echo_method, value, kind):
    expected = rf"^synthkit.echo\(\): image: expected a mesh, an image array or a path, got {kind}$"
    with pytest.raises(ConfigError, match=expected):
        prepare("echo", "synthkit.echo()", {"image": value}, {})


def test_prepare_reads_paths_against_the_current_folder(echo_method, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    save_image(tmp_path / "in.png", np.full((2, 2), 0.5, np.float32))
    cfg, inputs = prepare("echo", "synthkit.echo()", {"image": "in.png"}, {})
    assert cfg.image == tmp_path / "in.png" and inputs.files == [tmp_path / "in.png"]
    with pytest.raises(InputError, match=r"^synthkit.echo\(\): image: file not found: .*missing.png"):
        prepare("echo", "synthkit.echo()", {"image": "missing.png"}, {})


def test_prepare_reads_arrays_at_other_keys_as_lists():
    box = trimesh.creation.box()
    regions = [{"name": "a", "faces": np.array([0, 1])}, {"name": "b", "faces": [np.int64(5)]}]
    cfg, inputs = prepare("surface-by-numbers", "synthkit.segment()", {"input": box}, {"regions": regions})
    assert [r.faces for r in cfg.regions] == [[0, 1], [5]]
    assert list(inputs.objects) == ["<memory:input>"]


# ---------------------------------------------------------------- Inputs: images


def test_image_arrays_are_converted_like_files(tmp_path):
    rgba = np.array([[[255, 0, 0, 255], [0, 0, 255, 0]], [[0, 255, 0, 128], [10, 20, 30, 255]]], np.uint8)
    save_image(tmp_path / "a.png", rgba)
    for mode in ("rgb", "gray", "any"):
        from_file = load_image(tmp_path / "a.png", mode=mode)
        given = image_from_array(rgba, "image", mode=mode)
        assert given.dtype == np.float32 and given.shape == from_file.shape
        np.testing.assert_allclose(given, from_file, atol=1e-6)
    np.testing.assert_allclose(image_from_array(rgba, "image")[0, 1], [1.0, 1.0, 1.0])  # transparent: white


def test_image_arrays_of_every_depth():
    gray16 = np.array([[0, 65535]], np.uint16)
    np.testing.assert_allclose(image_from_array(gray16, "k", mode="rgb"), [[[0, 0, 0], [1, 1, 1]]])
    floats = np.array([[-0.5, 0.25, 2.0]])
    np.testing.assert_allclose(image_from_array(floats, "k", mode="gray"), [[0.0, 0.25, 1.0]])
    rgb = np.array([[[1.0, 0.0, 0.0]]], np.float32)
    assert image_from_array(rgb, "k", mode="gray")[0, 0] == pytest.approx(0.299)


@pytest.mark.parametrize(("array", "message"), [
    (np.zeros((0, 4, 3), np.uint8), r"^source: image is empty$"),
    (np.zeros((4, 4, 5), np.uint8), r"^source: an image is \(H, W\) or \(H, W, 1-4\), got shape \(4, 4, 5\)$"),
    (np.full((2, 2), np.nan), r"^source: image has non-finite values$"),
    (np.zeros((2, 2), np.int32), r"^source: image dtype int32 is not uint8, uint16 or float$"),
    ([[0, 1]], r"^source: expected an image array, got list$"),
])
def test_bad_image_arrays_name_their_key(array, message):
    with pytest.raises(InputError, match=message):
        image_from_array(array, "source")


# ---------------------------------------------------------------- Inputs: meshes


def test_meshes_in_memory_are_copied_and_checked():
    box = trimesh.creation.box()
    inputs = Inputs({"<memory:input>": box, "<memory:pair>": (np.asarray(box.vertices), np.asarray(box.faces))})
    mesh = inputs.mesh("<memory:input>")
    mesh.vertices += 1.0
    assert np.abs(box.vertices).max() == 0.5  # the caller's mesh is not changed
    pair = inputs.mesh("<memory:pair>")
    assert pair.faces.shape == (12, 3) and np.array_equal(pair.vertices, box.vertices)
    looped = Inputs({"<memory:input>": (np.eye(3), np.array([[0, 0, 1]]))})
    with pytest.raises(InputError, match=r"^input: 1 of 1 faces name one vertex twice"):
        looped.mesh("<memory:input>")
    with pytest.raises(InputError, match=r"^input: expected a mesh, got ndarray$"):
        Inputs({"<memory:input>": np.zeros((3, 3))}).mesh("<memory:input>")


def test_assets_keep_uvs_and_textures_of_a_trimesh():
    box = trimesh.creation.box()
    uv = np.random.default_rng(0).random((len(box.vertices), 2))
    texture = np.zeros((4, 4, 3), np.uint8)
    texture[..., 1] = 200
    from PIL import Image

    material = trimesh.visual.material.SimpleMaterial(image=Image.fromarray(texture))
    box.visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    asset = Inputs({"<memory:input>": box}).asset("<memory:input>")
    assert asset.textured and asset.F.shape == (12, 3)
    np.testing.assert_array_equal(asset.corner_uv, uv[box.faces])
    assert asset.materials[0].image[0, 0].tolist() == [0, 200, 0]
    scene = asset_from_trimesh(trimesh.Scene({"wall": box}))
    assert scene.name == "wall" and scene.textured


def test_an_asset_is_used_as_given():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    asset = Asset(V=V, F=np.array([[0, 1, 2]]), corner_uv=None, corner_color=None,
                  face_material=np.array([0]), materials=[Material(name="red")], name="tri", source=None)
    inputs = Inputs({"<memory:input>": asset})
    assert inputs.asset("<memory:input>") is asset
    assert inputs.mesh("<memory:input>").faces.tolist() == [[0, 1, 2]]


def test_face_labels_in_memory():
    inputs = Inputs({"<memory:labels>": np.array([0, 1, 1], np.int64)})
    assert inputs.face_labels("<memory:labels>", n_faces=3).dtype == np.int32
    with pytest.raises(InputError, match=r"^labels: 3 face labels for a mesh of 4 faces$"):
        inputs.face_labels("<memory:labels>", n_faces=4)


# ---------------------------------------------------------------- running and saving


def test_run_in_memory_writes_nothing(echo_method, nothing_written):
    img = np.array([[0, 255]], np.uint8)
    cfg, inputs = prepare("echo", "synthkit.echo()", {"image": img}, {"mode": "invert"})
    result = run_in_memory("echo", "synthkit.echo()", _echo_compute(), cfg, inputs)
    np.testing.assert_array_equal(result.image, [[1.0, 0.0]])
    assert result.metrics == {"mean": 0.5, "noise": 850} and result.status == "ok"  # noise: default_rng(0)
    assert set(result.timings) == {"load", "process", "total"}


def test_errors_of_a_run_in_memory_name_the_call(echo_method):
    cfg, inputs = prepare("echo", "synthkit.echo()", {"image": np.zeros((1, 1))}, {"fail": "input"})
    with pytest.raises(InputError, match=r"^synthkit.echo\(\): image: deliberately refused$"):
        run_in_memory("echo", "synthkit.echo()", _echo_compute(), cfg, inputs)


def test_save_writes_the_output_folder_whole(echo_method, tmp_path):
    cfg, inputs = prepare("echo", "synthkit.echo()", {"image": np.array([[0, 255]], np.uint8)}, {})
    result = run_in_memory("echo", "synthkit.echo()", _echo_compute(), cfg, inputs)
    report = result.save(tmp_path / "out")
    files = sorted(os.listdir(tmp_path / "out"))
    assert files == [".synthkit-output", "report.json", "result.png"]
    np.testing.assert_allclose(load_image(tmp_path / "out" / "result.png", mode="gray"), [[0.0, 1.0]])
    on_disk = json.loads((tmp_path / "out" / "report.json").read_text())
    assert on_disk == report and report["config_file"] is None and report["metrics"] == {"mean": 0.5, "noise": 850}
    assert report["timings"]["total"] >= report["timings"]["process"]
    with pytest.raises(ConfigError, match=r"output folder exists; pass --overwrite"):
        result.save(tmp_path / "out")
    (tmp_path / "mine").mkdir()
    with pytest.raises(ConfigError, match=r"is not a synthkit output"):
        result.save(tmp_path / "mine")
    assert result.save(tmp_path / "out", overwrite=True, previews="none")["previews"] == "none"


def test_a_scene_in_memory_counts_its_meshes_and_names_its_key():
    scene = trimesh.Scene([trimesh.creation.box(), trimesh.creation.icosphere()])
    inputs = Inputs({"<memory:input>": scene})
    assert inputs.mesh("<memory:input>").metadata["merged_geometries"] == 2
    assert inputs.source("<memory:input>") == "input" and inputs.source("/a/b.obj") == "/a/b.obj"


def test_a_result_class_must_write_its_outputs():
    from synthkit.api import Result

    class Silent(Result):
        pass

    with pytest.raises(TypeError, match="abstract method 'write'|abstract method write"):
        Silent(config=None)


def test_a_keyed_error_reads_key_then_message():
    from synthkit.errors import KeyedError

    named = KeyedError("chain[0].b", "piece 'b' is placed already")
    assert str(named) == "chain[0].b: piece 'b' is placed already" and named.message == "piece 'b' is placed already"
    assert isinstance(named, ValueError) and named.key == "chain[0].b"
    assert str(KeyedError(None, "x.obj: no UVs")) == "x.obj: no UVs"
