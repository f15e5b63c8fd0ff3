"""synthkit.petri_synth: the petri-synth pipeline on an example in memory."""

from __future__ import annotations

import doctest
import json

import numpy as np
import pytest
import trimesh

import synthkit
from synthkit.context import to_jsonable
from synthkit.errors import ConfigError, InputError
from synthkit.io.assets import load_asset
from synthkit.methods.petri import api
from synthkit.runner import run_config
from synthkit.samples import petri as sample

KEYS = {
    "seed": 7,
    "lattice": {"unit": [2.0, 3.0, 2.0]},
    "construction": {"plane": "xz", "points": [[0.0, 0.0], [12.0, 0.0], [20.0, 5.0]], "size_z": 3},
    "output": {"export_net": "both"},
}

CONFIG = """method: petri-synth
seed: 7
example: building_modular.obj
lattice:
  unit: [2.0, 3.0, 2.0]
construction:
  plane: xz
  points: [[0.0, 0.0], [12.0, 0.0], [20.0, 5.0]]
  size_z: 3
output:
  export_net: both
"""


@pytest.fixture(scope="module")
def building():
    return sample.building()


def test_petri_synth_in_memory_writes_nothing(building, nothing_written):
    V, F = building
    result = synthkit.petri_synth((V, F), **KEYS)
    # 12 units along X, then a segment of length sqrt(89) = 9.43: 6 + 5 = 11 cells of 2
    assert result.label_grid.shape == (11, 2, 3)
    assert result.metrics["cells"] == 66 and result.metrics["construction_shape"] == [11, 2, 3]
    assert result.metrics["adjacency_violations"] == 0 and result.metrics["unfilled_cells"] == 0
    assert result.status == "ok" and result.quality_warnings == []
    assert len(result.mesh.faces) == result.metrics["result_faces"] == len(result.face_labels)
    assert len(result.mesh.vertices) == result.metrics["result_vertices"]
    assert np.array_equal(result.asset.V, result.mesh.vertices) and np.array_equal(result.asset.F, result.mesh.faces)
    assert result.face_labels.min() >= 0 and result.face_labels.max() < result.metrics["labels"]
    assert result.labels["shape"] == [11, 2, 3] and result.labels["grid"] == result.label_grid.tolist()
    assert result.target_net.n_cells == 66 and result.example_net.n_cells == 6 * 4 * 2
    assert result.baseline_net is None
    assert {"load", "analysis", "construction", "inference", "assembly", "evaluation", "total"} == set(result.timings)
    # the example's cells, as the net holds them
    assert np.array_equal(result.example_net.label_grid(), np.asarray(result.labels["example"]["grid"]))


def test_meshes_in_memory_agree(building):
    V, F = building
    a = synthkit.petri_synth((V, F), **KEYS)
    b = synthkit.petri_synth(trimesh.Trimesh(V, F, process=False), **KEYS)
    np.testing.assert_array_equal(a.mesh.vertices, b.mesh.vertices)
    np.testing.assert_array_equal(a.mesh.faces, b.mesh.faces)
    np.testing.assert_array_equal(a.label_grid, b.label_grid)


def test_same_seed_same_result_other_seed_other_labels(building):
    V, F = building
    keys = {**KEYS, "lattice": {"unit": [1.0, 3.0, 2.0]}}
    a = synthkit.petri_synth((V, F), **keys)
    b = synthkit.petri_synth((V, F), **keys)
    np.testing.assert_array_equal(a.label_grid, b.label_grid)
    np.testing.assert_array_equal(a.mesh.vertices, b.mesh.vertices)
    assert json.dumps(to_jsonable(a.metrics)) == json.dumps(to_jsonable(b.metrics))
    grids = {synthkit.petri_synth((V, F), **{**keys, "seed": s}).label_grid.tobytes() for s in range(4)}
    assert len(grids) > 1


def test_key_errors_give_the_command_lines_message(building, tmp_path):
    V, F = building
    restarts = r"^synthkit\.petri_synth\(\): inference\.max_restarts: .*greater than or equal"
    with pytest.raises(ConfigError, match=restarts):
        synthkit.petri_synth((V, F), **{**KEYS, "inference": {"max_restarts": -1}})
    fit = r"lattice\.unit: \[2\.5, 3\.0, 2\.0\] does not fit the model: along X"
    with pytest.raises(ConfigError, match=r"^synthkit\.petri_synth\(\): .*" + fit):
        synthkit.petri_synth((V, F), **{**KEYS, "lattice": {"unit": [2.5, 3.0, 2.0]}})
    short = r"^synthkit\.petri_synth\(\): construction\.points: the curve is 1\.5 long, shorter than one unit"
    with pytest.raises(ConfigError, match=short):
        synthkit.petri_synth((V, F), **{**KEYS, "construction": {"plane": "xz", "points": [[0, 0], [1.5, 0]]}})
    # the command line says the same after the config file's name
    sample.generate(tmp_path)
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(CONFIG.replace("[2.0, 3.0, 2.0]", "[2.5, 3.0, 2.0]"))
    with pytest.raises(ConfigError, match=fit):
        run_config(cfg, out_dir=tmp_path / "out", show_progress=False)


def test_network_errors_name_the_curve(building):
    V, F = building
    con = {"plane": "xz", "size_y": 2, "curves": [{"points": [[-8.0, 0.0], [8.0, 0.0]]},
                                                  {"points": [[-8.0, -1.0], [8.0, 1.0]]}]}
    shallow = (r"^synthkit\.petri_synth\(\): construction\.curves\[0\]: crosses construction\.curves\[1\] at "
               r"\[0\.0, 0\.0\] at 7\.13 degrees, less than 30$")
    with pytest.raises(ConfigError, match=shallow):
        synthkit.petri_synth((V, F), **{**KEYS, "construction": con})


def test_an_unfillable_space_is_an_input_error(building):
    V, F = building
    keys = {**KEYS, "labels": {"join_ends": "never"}, "construction": {"plane": "xz", "points": [[0, 0], [4, 0]]},
            "lattice": {"unit": [1.0, 3.0, 2.0]}}
    V2 = V.copy()
    V2[:, 0] *= 0.25  # a one-bay example: every piece along X is a corner, so it cannot grow
    with pytest.raises(InputError, match=r"^synthkit\.petri_synth\(\): petri-synth: .*cannot fill"):
        synthkit.petri_synth((V2, F), **keys)


def test_save_writes_what_the_command_line_writes(tmp_path):
    sample.generate(tmp_path)
    cfg = tmp_path / "run.yaml"
    cfg.write_text(CONFIG)
    run_config(cfg, out_dir=tmp_path / "cli", show_progress=False)
    example = load_asset(tmp_path / "building_modular.obj")
    result = synthkit.petri_synth(example, **KEYS)
    report = result.save(tmp_path / "api")
    for name in ("result.ply", "labels.json", "target_net.pnml", "example_net.pnml", "target_net.dot",
                 "example_net.dot", "result.png", "construction_space.png", "montage.png"):
        assert (tmp_path / "api" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    cli = json.loads((tmp_path / "cli" / "report.json").read_text())
    assert report["metrics"] == cli["metrics"] and report["outputs"] == cli["outputs"]
    assert report["config_file"] is None and report["status"] == "ok"
    assert set(cli["timings"]) == set(report["timings"])


def test_colours_of_the_example_reach_the_result(building):
    V, F = building
    colors = np.tile(np.array([200, 120, 40, 255], np.uint8), (len(V), 1))
    mesh = trimesh.Trimesh(V, F, vertex_colors=colors, process=False)
    result = synthkit.petri_synth(mesh, **KEYS)
    cc = result.asset.corner_color
    assert cc is not None and cc.shape == (len(result.mesh.faces), 3, 4) and cc.dtype == np.uint8
    assert {tuple(c) for c in cc.reshape(-1, 4).tolist()} == {(200, 120, 40, 255)}


def test_a_curve_network_in_memory(building):
    V, F = building
    result = synthkit.petri_synth(
        (V, F), seed=5, lattice={"unit": [1.0, 3.0, 1.0], "origin": [0.0, 0.0, 0.0]}, labels={"boundary": False},
        construction={"plane": "xz", "side": "center", "size_y": 4, "size_z": 2,
                      "curves": [{"points": [[-8.0, 0.0], [8.0, 0.0]]}, {"points": [[0.0, -6.0], [0.0, 6.0]]}]})
    parts = result.labels["parts"]
    assert [p["kind"] for p in parts].count("junction") == 1 and result.metrics["junctions"] == 1
    assert result.label_grid.shape == (result.metrics["cells"],)
    assert sum(int(np.prod(p["shape"])) for p in parts) * 2 == result.metrics["cells"]
    assert result.metrics["adjacency_violations"] == 0 and result.metrics["junction_adjacency_violations"] == 0


def test_the_docstring_example_runs():
    failures, tried = doctest.testmod(api, verbose=False)
    assert tried >= 4 and failures == 0
