"""``synthkit.segment`` and ``synthkit.transfer`` on meshes, labels and images in memory: exact
labels and colours on generated shapes, nothing written during the call, the command line's
messages, ``.save`` writing the bytes ``synthkit run`` writes, determinism and the docstring
examples."""

from __future__ import annotations

import doctest
from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml

import synthkit
import synthkit.io.atomic
import synthkit.methods.surfacing.api as api
from synthkit.errors import ConfigError, InputError
from synthkit.io.images import load_image
from synthkit.runner import run_config
from synthkit.samples import surfacing as seg_sample
from synthkit.samples import surfacing_transfer as sample

ROOT = Path(__file__).resolve().parents[2]
SAMPLES = ROOT / "data-samples"


def crease():
    V, F, part = seg_sample.crease_boxes()
    a, b = seg_sample.part_centre_vertices(V, F, part)
    return V, F, part, [{"name": "long", "vertices": [a]}, {"name": "short", "vertices": [b]}]


def write_yaml(path: Path, **cfg) -> Path:
    path.write_text(yaml.safe_dump({"method": "surface-by-numbers", "seed": 0, **cfg}))
    return path


# ------------------------------------------------------------------------------------------ segment


def test_segment_in_memory_follows_the_crease_and_writes_nothing(nothing_written):
    V, F, part, regions = crease()
    result = synthkit.segment((V, F), regions=regions)
    assert result.face_labels.dtype == np.int32 and result.face_labels.shape == (len(F),)
    np.testing.assert_array_equal(result.face_labels, part)
    assert result.region_names == ["long", "short"]
    assert result.region_colors.shape == (2, 3) and result.region_colors.dtype == np.uint8
    # the cut is the crease: every cut edge joins a face of each part
    edges = {tuple(sorted(e)) for e in result.cut_edges.tolist()}
    sides = {}
    for f, tri in enumerate(F.tolist()):
        for i in range(3):
            sides.setdefault(tuple(sorted((tri[i], tri[(i + 1) % 3]))), set()).add(int(part[f]))
    assert edges == {e for e, s in sides.items() if s == {0, 1}}
    assert sum(len(c) - 1 for c in result.cut_chains) == len(result.cut_edges)
    m = result.metrics
    assert [r["faces"] for r in m["regions"]] == np.bincount(part).tolist()
    assert m["cut_edges"] == len(edges) and result.status == "ok" and result.timings["total"] > 0
    assert len(result.region_mesh("short").faces) == int((part == 1).sum())
    assert result.cut_curves is None and result.view_images == {}


def test_segment_same_seed_same_result():
    V, F, part, regions = crease()
    mesh = trimesh.Trimesh(V, F, process=False)
    one = synthkit.segment(mesh, regions=regions, seed=3)
    two = synthkit.segment(mesh, regions=regions, seed=3)
    np.testing.assert_array_equal(one.face_labels, two.face_labels)
    np.testing.assert_array_equal(one.vertex_labels, two.vertex_labels)
    assert one.metrics["cut_cost"] == two.metrics["cut_cost"]


def test_segment_errors_are_the_command_lines(tmp_path):
    V, F, part, regions = crease()
    bad = [{"name": "long", "vertices": [10**6]}, regions[1]]
    with pytest.raises(ConfigError, match=r"^synthkit\.segment\(\): regions\[0\]\.vertices: vertex index 1000000 out"):
        synthkit.segment((V, F), regions=bad)
    trimesh.Trimesh(V, F, process=False).export(tmp_path / "boxes.ply")
    cfg = write_yaml(tmp_path / "bad.yaml", input="boxes.ply", regions=bad)
    with pytest.raises(ConfigError) as cli:
        run_config(cfg, out_dir=tmp_path / "out", show_progress=False)
    with pytest.raises(ConfigError) as api:
        synthkit.segment((V, F), regions=bad)
    assert str(cli.value).removeprefix(f"{cfg}: ") == str(api.value).removeprefix("synthkit.segment(): ")
    with pytest.raises(ConfigError, match=r"boundary\.eta"):
        synthkit.segment((V, F), regions=regions, boundary={"eta": -1})
    with pytest.raises(ConfigError, match=r"mode: 'transfer' contradicts the function .*synthkit\.transfer\(\)"):
        synthkit.segment((V, F), regions=regions, mode="transfer")
    with pytest.raises(InputError, match="input"):
        synthkit.segment((V, np.zeros((0, 3), np.int64)), regions=regions)


def test_painted_image_array_gives_the_cli_labels_and_save_writes_its_bytes(tmp_path):
    """The bundled painted config, with the mesh and the painted PNG given as objects."""
    config = ROOT / "configs/surface-by-numbers/painted.yaml"
    run_config(config, out_dir=tmp_path / "cli", show_progress=False)
    cfg = yaml.safe_load(config.read_text())
    mesh = trimesh.load(SAMPLES / "surfacing-figure.ply", process=False)
    painted = np.round(load_image(SAMPLES / "surfacing-figure-front.png") * 255).astype(np.uint8)
    images = [{**cfg["images"][0], "image": painted}]
    result = synthkit.segment(mesh, regions=cfg["regions"], images=images, views=cfg["views"])
    assert result.metrics["painted_pixels"][0]["image"] == "<memory:images.0.image>"
    assert result.region_colors.tolist() == [r["color"] for r in cfg["regions"]]
    result.save(tmp_path / "api")
    names = ["labels.ply", "labels.seg", "cut.obj", "regions.png"]
    names += [f"regions/{r['name']}.ply" for r in cfg["regions"]]
    for name in names:
        assert (tmp_path / "api" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    np.testing.assert_allclose(result.summary_image(), load_image(tmp_path / "cli" / "regions.png"), atol=0.5 / 255)


def test_views_and_smoothed_cut_in_memory():
    V, F, part, regions = crease()
    result = synthkit.segment((V, F), regions=regions, smooth_cut=5, views={"render": True, "names": ["front", "iso"],
                                                                           "size": 64})
    assert sorted(result.view_images) == ["front", "iso"] and result.view_images["iso"].shape == (64, 64, 3)
    assert result.cameras["front"].size == 64
    assert len(result.cut_curves) == len(result.cut_chains)
    assert all(c.shape[1] == 3 for c in result.cut_curves)
    assert result.metrics["cut_length_smoothed"] > 0


# ----------------------------------------------------------------------------------------- transfer


def stripes_pair(labels):
    S, G, colors = sample.stripes(40)
    source = trimesh.Trimesh(S, G, vertex_colors=colors, process=False)
    return {"target": {"labels": labels, "label": 0}, "source": {"mesh": source}, "signal": "color"}


NEAREST = {"sampling": "nearest", "blend": "none"}


def test_transfer_in_memory_colours_the_side_with_the_palette(nothing_written):
    V, F, labels = sample.cylinder(24, 8)
    result = synthkit.transfer((V, F), transfer={"pairs": [stripes_pair(labels)], "extraction": NEAREST})
    assert result.metrics["coverage"] == 1.0 and result.status == "ok"
    np.testing.assert_array_equal(result.patch_ids >= 0, labels == 0)
    assert result.patch_ids.max() + 1 == result.metrics["patches"]
    inner = np.setdiff1d(np.unique(F[labels == 0]), np.unique(F[labels != 0]))
    rgb = np.round(result.colors[inner] * 255).astype(int)
    assert {tuple(c) for c in rgb.tolist()} <= {tuple(c) for c in sample.PALETTE.tolist()}
    assert len({tuple(c) for c in rgb.tolist()}) == 3
    caps = np.setdiff1d(np.unique(F[labels != 0]), np.unique(F[labels == 0]))
    np.testing.assert_allclose(result.colors[caps], 0.75)  # the target had no colours: grey
    np.testing.assert_array_equal(result.positions, V)  # a colour signal moves nothing
    mesh = result.mesh
    assert len(mesh.faces) == len(F) and mesh.visual.vertex_colors.shape == (len(V), 4)
    asset = result.asset
    assert asset.corner_uv is None and asset.corner_color.shape == (len(F), 3, 4)
    assert np.isfinite(result.seam_field[labels == 0]).all() and np.isnan(result.seam_field[labels != 0]).all()


def test_transfer_same_seed_same_result():
    V, F, labels = sample.cylinder(24, 8)
    runs = [synthkit.transfer((V, F), seed=5, transfer={"pairs": [stripes_pair(labels)]}) for _ in range(2)]
    np.testing.assert_array_equal(runs[0].colors, runs[1].colors)
    np.testing.assert_array_equal(runs[0].patch_ids, runs[1].patch_ids)


def test_transfer_save_writes_the_bytes_of_synthkit_run(tmp_path):
    V, F, labels = sample.cylinder(24, 8)
    S, G, colors = sample.stripes(40)
    trimesh.Trimesh(V, F, process=False).export(tmp_path / "cyl.ply")
    trimesh.Trimesh(S, G, vertex_colors=colors, process=False).export(tmp_path / "stripes.ply")
    (tmp_path / "cyl.seg").write_text("".join(f"{v}\n" for v in labels.tolist()))
    pair = {"target": {"labels": "cyl.seg", "label": 0}, "source": {"mesh": "stripes.ply"}, "signal": "color"}
    cfg = write_yaml(tmp_path / "t.yaml", mode="transfer", input="cyl.ply", transfer={"pairs": [pair]})
    run_config(cfg, out_dir=tmp_path / "cli", show_progress=False, previews="summary")
    # the same numbers as the files hold (PLY stores float32 positions)
    target, source = (trimesh.load(tmp_path / name, process=False) for name in ("cyl.ply", "stripes.ply"))
    pair = {"target": {"labels": labels, "label": 0}, "source": {"mesh": source}, "signal": "color"}
    result = synthkit.transfer(target, transfer={"pairs": [pair]})
    result.save(tmp_path / "api", previews="summary")
    for name in ("transferred.ply", "patches.ply", "transfer.png"):
        assert (tmp_path / "api" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    np.testing.assert_allclose(result.summary_image(), load_image(tmp_path / "cli" / "transfer.png"), atol=0.5 / 255)


def test_transfer_texture_from_an_image_array():
    V, F, labels = sample.cylinder(24, 8)
    x = np.arange(120)
    img = sample.PALETTE[(3 * x // 20) % 3][None].repeat(60, axis=0)  # (60, 120, 3) uint8 stripes
    pair = {"target": {"labels": labels, "label": 0}, "signal": "texture", "scale": 2.0,
            "source": {"image": img, "width": 1.0}}
    result = synthkit.transfer((V, F), transfer={"pairs": [pair], "extraction": NEAREST})
    side = labels == 0
    np.testing.assert_array_equal(result.face_material[side], 1)
    assert np.isfinite(result.corner_uv[side]).all() and np.isnan(result.corner_uv[~side]).all()
    np.testing.assert_allclose(result.textures[1], img / 255.0, atol=1e-6)
    assert result.textures[0] is None
    asset = result.asset
    assert [m.name for m in asset.materials] == ["transfer_0"]  # the cylinder had no material: none is invented
    np.testing.assert_array_equal(asset.face_material, np.where(side, 0, -1))
    np.testing.assert_array_equal(asset.materials[0].image, img)
    assert asset.corner_uv.shape == (len(F), 3, 2)


def textured_plane(folder: Path, n: int = 8) -> np.ndarray:
    """``plane.obj`` (UVs = its x, y; material with ``tex.png``, random texels) in ``folder``; return
    the ``(#F,)`` labels: 0 on the left half, 1 on the right."""
    from synthkit.io.images import save_image

    xs = np.linspace(0.0, 1.0, n + 1)
    X, Y = np.meshgrid(xs, xs)
    V = np.c_[X.ravel(), Y.ravel(), np.zeros(X.size)]
    q = (np.arange(n * n) // n * (n + 1) + np.arange(n * n) % n)
    F = np.concatenate([np.c_[q, q + 1, q + n + 2], np.c_[q, q + n + 2, q + n + 1]])
    save_image(folder / "tex.png", np.random.default_rng(0).random((32, 32, 3)).astype(np.float32))
    (folder / "plane.mtl").write_text("newmtl skin\nKd 1 1 1\nmap_Kd tex.png\n")
    lines = ["mtllib plane.mtl", "usemtl skin"] + [f"v {x} {y} {z}" for x, y, z in V]
    lines += [f"vt {x} {y}" for x, y, _ in V] + [f"f {a + 1}/{a + 1} {b + 1}/{b + 1} {c + 1}/{c + 1}" for a, b, c in F]
    (folder / "plane.obj").write_text("\n".join(lines) + "\n")
    return (V[F].mean(axis=1)[:, 0] >= 0.5).astype(np.int64)


def test_textured_trimesh_target_keeps_its_texture_and_saves_the_cli_bytes(tmp_path):
    """A textured OBJ read by trimesh, an image array as the source, subdivided once: the same files
    as ``synthkit run`` on the files."""
    labels = textured_plane(tmp_path)
    (tmp_path / "half.seg").write_text("".join(f"{v}\n" for v in labels.tolist()))
    tex = load_image(tmp_path / "tex.png")
    settings = {"synthesis": {"patch_radius": 0.2, "orientation": "up"}, "extraction": {"subdivide": 1}}
    pair = {"target": {"labels": "half.seg", "label": 0}, "signal": "texture", "source": {"image": "tex.png"}}
    cfg = write_yaml(tmp_path / "t.yaml", mode="transfer", input="plane.obj", transfer={"pairs": [pair], **settings})
    run_config(cfg, out_dir=tmp_path / "cli", show_progress=False, previews="summary")
    pair = {"target": {"labels": labels, "label": 0}, "signal": "texture", "source": {"image": tex}}
    result = synthkit.transfer(trimesh.load(tmp_path / "plane.obj", process=False),
                               transfer={"pairs": [pair], **settings})
    own = result.face_material == 0
    assert own.sum() == 4 * (labels == 1).sum() and (result.face_material[~own] == 1).all()
    np.testing.assert_allclose(result.textures[0], tex, atol=1 / 255)
    assert [m.name for m in result.asset.materials] == ["original", "transfer_0"]
    result.save(tmp_path / "api", previews="summary")
    for name in ("transferred.obj", "transferred.mtl", "transferred_original.png", "transferred_transfer_0.png",
                 "transferred.ply",
                 "patches.ply", "transfer.png"):
        assert (tmp_path / "api" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name


def test_transfer_errors_name_the_key():
    V, F, labels = sample.cylinder(24, 8)
    pair = stripes_pair(labels)
    with pytest.raises(ConfigError, match=r"mode: 'segment' contradicts the function"):
        synthkit.transfer((V, F), mode="segment", transfer={"pairs": [pair]})
    with pytest.raises(ConfigError, match=r"^synthkit\.transfer\(\): transfer\.pairs\[0\]\.target: label 7 of .* is "
                                          r"empty"):
        synthkit.transfer((V, F), transfer={"pairs": [{**pair, "target": {"labels": labels, "label": 7}}]})
    with pytest.raises(InputError, match=r"transfer\.pairs\.0\.target\.labels: 3 face labels for a mesh of"):
        synthkit.transfer((V, F), transfer={"pairs": [{**pair, "target": {"labels": labels[:3], "label": 0}}]})
    with pytest.raises(ConfigError, match=r"transfer\.pairs\[0\]\.signal: color: .* has no vertex colours"):
        synthkit.transfer((V, F), transfer={"pairs": [{**pair, "source": {"mesh": (V, F)}}]})


def test_docstring_examples_run():
    failed, attempted = doctest.testmod(api, optionflags=doctest.ELLIPSIS)
    assert attempted >= 10 and failed == 0


def test_the_docs_examples_run():
    """The Python blocks of docs/surface-by-numbers.md's "From Python" section run as written."""
    text = (ROOT / "docs/surface-by-numbers.md").read_text().split("## From Python")[1]
    blocks = [block.split("```")[0] for block in text.split("```python")[1:]]
    assert len(blocks) == 2
    namespace: dict = {}
    for block in blocks:
        exec(compile(block, "docs/surface-by-numbers.md", "exec"), namespace)
    assert namespace["result"].metrics["coverage"] == 1.0


def test_strokes_as_numpy_arrays():
    V, F, part, regions = crease()
    a, b = (r["vertices"][0] for r in regions)
    as_lists = synthkit.segment((V, F), regions=regions)
    points = V[[b]] + 0.0  # (1, 3) float64: a one-point polyline on the vertex itself
    as_arrays = synthkit.segment((V, F), regions=[{"name": "long", "vertices": np.array([a], np.int64)},
                                                  {"name": "short", "points": points}])
    np.testing.assert_array_equal(as_arrays.face_labels, as_lists.face_labels)
