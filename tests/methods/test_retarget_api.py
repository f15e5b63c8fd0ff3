"""``synthkit.retarget`` on meshes in memory: outputs, no file written, errors, save, determinism."""

from __future__ import annotations

import doctest
import json
import os

import numpy as np
import pytest
import trimesh
from PIL import Image

import synthkit
from synthkit.errors import ConfigError, InputError
from synthkit.io.assets import load_asset
from synthkit.methods.retarget import api
from synthkit.runner import load_method_config, run_config
from synthkit.samples.retarget import build_bookshelf

COARSE = {"dense_radius": 0.04, "feature_radius": 0.1}
"""Coarser sampling than the paper's, so that a run takes a few seconds; the bookshelf's lattice
is still found exactly."""


@pytest.fixture(scope="module")
def shelf():
    V, F, _ = build_bookshelf(cols=3, rows=2, step=None)
    return V.astype(np.float32).astype(np.float64), F  # as a PLY file stores it


@pytest.fixture(scope="module")
def grown(shelf, tmp_path_factory, refuse_writes):
    """The shelf grown by one row, computed with every writer refusing, in an empty folder."""
    folder = tmp_path_factory.mktemp("cwd")
    with pytest.MonkeyPatch.context() as mp:
        refuse_writes(mp, folder)
        result = synthkit.retarget(shelf, target={"axis_steps": {"y": 1}}, analysis=COARSE, seed=0)
    assert os.listdir(folder) == []
    return result


def test_grown_shelf_outputs(shelf, grown):
    V, F = shelf
    m = grown.metrics
    assert grown.status == "ok" and m["n_principal"] == 2 and grown.method == "retarget"
    np.testing.assert_allclose(np.abs(grown.principal_offsets), [[0.4, 0, 0], [0, 0.35, 0]], atol=1e-9)
    assert isinstance(grown.mesh, trimesh.Trimesh)
    np.testing.assert_array_equal(grown.mesh.faces, grown.asset.F)
    np.testing.assert_allclose(grown.mesh.extents - np.ptp(V, axis=0), [0, 0.35, 0], atol=1e-9)
    assert len(grown.mesh.faces) == m["output_faces"] - sum(m["degenerate_faces_dropped"].values())
    assert grown.asset.corner_uv is None and grown.asset.materials == []
    r = grown.retargeted
    assert r.label_volume.dtype == np.int32 and list(r.label_volume.shape) == m["grid_out"]
    assert r.n_labels == m["graph_labels"] and r.label_shifts.tolist() == m["label_shifts"]
    assert len(r.face_labels) == len(r.labelled_mesh.faces) and set(np.unique(r.face_labels)) <= set(range(r.n_labels))
    assert m["mesh_quality"]["mesh"]["output"]["degenerate_faces"] == 0 and grown.baseline is None
    curve = grown.sparsity_curve
    assert curve.shape[1] == 2 and np.all(np.diff(curve[:, 1]) >= 0) and curve[-1, 1] == pytest.approx(1.0)
    assert grown.histogram_counts.sum() == m["n_statistics_offsets"] and grown.histogram_bins.shape[1] == 3
    assert grown.dominant_offsets.shape == (len(m["dominant_offsets"]), 3) == (len(grown.dominant_counts), 3)
    assert set(grown.timings) >= {"load", "analysis", "synthesis", "graphcut", "assemble", "total"}


def test_same_seed_same_result(shelf, grown):
    again = synthkit.retarget(shelf, target={"axis_steps": {"y": 1}}, analysis=COARSE, seed=0)
    np.testing.assert_array_equal(again.mesh.vertices, grown.mesh.vertices)
    np.testing.assert_array_equal(again.mesh.faces, grown.mesh.faces)
    np.testing.assert_array_equal(again.retargeted.label_volume, grown.retargeted.label_volume)
    assert again.metrics["energy"] == grown.metrics["energy"]


def test_save_writes_what_the_command_line_writes(shelf, grown, tmp_path):
    V, F = shelf
    trimesh.Trimesh(V, F, process=False).export(tmp_path / "shelf.ply")
    cfg = tmp_path / "shelf.yaml"
    cfg.write_text(json.dumps({"method": "retarget", "input": "shelf.ply", "seed": 0, "analysis": COARSE,
                               "target": {"axis_steps": {"y": 1}}}))
    cli = run_config(cfg, out_dir=tmp_path / "cli", show_progress=False, previews="none")
    saved = grown.save(tmp_path / "api", previews="none")
    assert saved["outputs"] == cli["outputs"] and saved["config_file"] is None
    for name in ("retargeted.ply", "labels.ply", "labels.npy"):
        assert (tmp_path / "api" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    drop = {"graphcut_seconds"}
    assert {k: v for k, v in saved["metrics"].items() if k not in drop} == {
        k: v for k, v in cli["metrics"].items() if k not in drop}


@pytest.mark.parametrize("keys", [{"analysis": {"tua": 0.1}}, {"analysis": {"dense_radius": -1}},
                                  {"target": {"steps": [1], "scale": [2.0]}}], ids=["typo", "range", "target"])
def test_key_errors_carry_the_command_lines_messages(shelf, tmp_path, keys):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(json.dumps({"method": "retarget", "input": "m.obj", **keys}))
    with pytest.raises(ConfigError) as cli:
        load_method_config(cfg, check_files=False)
    with pytest.raises(ConfigError) as api_error:
        synthkit.retarget(shelf, **keys)
    assert str(api_error.value) == str(cli.value).replace(str(cfg), "synthkit.retarget()")
    assert list(keys)[0] in str(api_error.value)


def test_steps_error_names_the_key(shelf):
    with pytest.raises(ConfigError, match=r"target.steps\[1\]=-6: would shrink below one cell"):
        synthkit.retarget(shelf, target={"steps": [0, -6]}, analysis=COARSE, seed=0)


def test_no_repetition_is_refused_and_analyze_only_says_why():
    blob = trimesh.creation.icosphere(subdivisions=2)
    blob.vertices = blob.vertices * (1 + 0.15 * np.random.default_rng(0).random((len(blob.vertices), 1)))
    with pytest.raises(InputError, match=r"^synthkit.retarget\(\): input: no repetition found") as refused:
        synthkit.retarget(blob, seed=0)
    assert refused.value.result.metrics["n_principal"] == 0  # the statistics come with the refusal
    stats = synthkit.retarget(blob, analyze_only=True, seed=0)
    assert stats.mesh is None and stats.asset is None and stats.retargeted is None
    assert stats.principal_offsets.shape == (0, 3) and stats.metrics["n_principal"] == 0
    assert 0 < stats.metrics["sparsity_top7"] <= 1 and stats.metrics["analyze_only"] is True


def test_textured_mesh_keeps_its_uvs_and_saves_as_glb(shelf, tmp_path):
    V, F = shelf
    texture = Image.fromarray(np.arange(48, dtype=np.uint8).reshape(4, 4, 3))
    uv = (V[:, :2] - V[:, :2].min(axis=0)) / np.ptp(V[:, :2], axis=0)
    visual = trimesh.visual.TextureVisuals(uv=uv, material=trimesh.visual.material.SimpleMaterial(image=texture))
    mesh = trimesh.Trimesh(V, F, visual=visual, process=False)
    result = synthkit.retarget(mesh, target={"axis_steps": {"y": 1}}, analysis=COARSE, seed=0)
    a = result.asset
    assert a.corner_uv.shape == (len(a.F), 3, 2) and len(a.materials) == 1 and a.materials[0].image is not None
    assert np.all((a.corner_uv >= -1e-9) & (a.corner_uv <= 1 + 1e-9))
    result.save(tmp_path / "out", previews="none")
    back = load_asset(tmp_path / "out" / "retargeted.glb")
    assert len(back.F) == len(a.F) and back.textured


def test_docstring_example_runs():
    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
    for test in finder.find(api.retarget, "retarget", globs={}):
        runner.run(test)
    outcome = runner.summarize(verbose=False)
    assert outcome.attempted >= 4 and outcome.failed == 0
