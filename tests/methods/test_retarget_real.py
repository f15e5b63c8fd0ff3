"""Retargeting on real meshes made by other people (issue 15), read from ../shared/data (see its
SOURCES.md); every test skips when a file is absent. The sparsity table and its figures are in the
README's retarget section."""

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner

from synthkit.cli.main import cli
from synthkit.core.mesh import normalize_unit
from synthkit.io.meshes import load_mesh
from synthkit.methods.retarget.analysis import analyze
from synthkit.methods.retarget.synthesis import mesh_quality

REPO = Path(__file__).resolve().parents[2]
DATA = REPO.parent / "shared" / "data"
KENNEY = DATA / "meshes" / "kenney-city"

TABLE = {  # file under ../shared/data -> kind (the issue's table)
    "meshes/kenney-city/building-small-a.glb": "building",
    "meshes/kenney-city/building-small-b.glb": "building",
    "architecture/houses/house1_baked.obj": "building",
    "architecture/tudorhouse/tudorhouse.obj": "building",
    "meshes/fandisk.obj": "CAD",
    "psb/102.off": "chair",
    "psb/2.off": "human",
    "meshes/spot/spot_triangulated.obj": "organic",
    "meshes/bunny_small.ply": "organic",
}
ORGANIC = ("human", "organic")

_CACHE: dict = {}


def _need(*names):
    missing = [n for n in names if not (DATA / n).is_file()]
    if missing:
        pytest.skip(f"../shared/data absent: {', '.join(missing)}")


def _analysed(name):
    """The analysis ``run`` performs (default settings, seed 0) and the model scale."""
    if name not in _CACHE:
        mesh = load_mesh(DATA / name)
        V, F = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)
        _, center, scale = normalize_unit(V[np.unique(F)])
        _CACHE[name] = (analyze((V - center) / scale, F, rng=0), scale)
    return _CACHE[name]


def _table():
    _need(*TABLE)
    return {name: _analysed(name)[0].top7 for name in TABLE}


def _means(top7):
    man = [v for n, v in top7.items() if TABLE[n] not in ORGANIC]
    org = [v for n, v in top7.items() if TABLE[n] in ORGANIC]
    return float(np.mean(man)), float(np.mean(org))


@pytest.mark.slow
def test_sparsity_separates_man_made_from_organic():
    """Section IV's statistics on the issue's nine meshes: every building, CAD part and the chair
    scores above every organic mesh, no organic mesh reaches the lower Kenney piece, and the means
    are at least 0.15 apart (measured seed 0: man-made 0.403, organic 0.238)."""
    top7 = _table()
    figures = {Path(n).name: round(v, 3) for n, v in top7.items()}
    man, org = _means(top7)
    lowest_man = min(v for n, v in top7.items() if TABLE[n] not in ORGANIC)
    highest_org = max(v for n, v in top7.items() if TABLE[n] in ORGANIC)
    kenney = min(top7[n] for n in TABLE if "kenney" in n)
    assert highest_org < lowest_man, figures
    assert highest_org < kenney, figures
    assert man >= org + 0.15, (man, org, figures)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="issue 15 goal not met: the means are 0.164 apart (0.403 against 0.238)")
def test_sparsity_means_are_the_issues_0_2_apart():
    man, org = _means(_table())
    assert man >= org + 0.2, (man, org)


@pytest.mark.slow
def test_analyze_only_reports_the_same_statistics(tmp_path):
    """``--analyze-only`` writes the figure of the table (same seed, same code path)."""
    name = "meshes/kenney-city/building-small-b.glb"
    _need(name)
    cfg = tmp_path / "b.yaml"
    cfg.write_text(json.dumps({"method": "retarget", "input": str(DATA / name), "seed": 0, "analyze_only": True}))
    result = CliRunner().invoke(cli, ["retarget", str(cfg), "--out", str(tmp_path / "out"), "--no-progress"])
    assert result.exit_code == 0, result.stderr
    m = json.loads((tmp_path / "out" / "report.json").read_text())["metrics"]
    an, _ = _analysed(name)
    assert m["sparsity_top7"] == pytest.approx(an.top7)
    assert m["n_statistics_features"] == m["n_features"] - m["n_vertex_features"]
    assert m["n_statistics_offsets"] <= m["n_statistics_features"] < m["n_features"]


@pytest.mark.slow
def test_kenney_pieces_get_their_floor_height():
    """Both Kenney pieces repeat floors 0.4 apart (their 0.315/0.715/1.115 window sills): a
    principal offset is that floor height, not the 0.1 wall slide."""
    names = ["meshes/kenney-city/building-small-a.glb", "meshes/kenney-city/building-small-b.glb"]
    _need(*names)
    for name in names:
        an, scale = _analysed(name)
        offsets = an.principal * scale
        found = f"{Path(name).name}: principal offsets {offsets.round(4).tolist()}"
        assert any(np.abs(v - [0.0, 0.4, 0.0]).max() <= 0.01 for v in offsets), found


def _grow(tmp_path, name, steps, **keys):
    cfg = tmp_path / f"{Path(name).stem}.yaml"
    spec = {"method": "retarget", "input": str(DATA / name), "seed": 0, "target": {"steps": steps}, **keys}
    cfg.write_text(json.dumps(spec))
    out = tmp_path / f"out-{Path(name).stem}"
    result = CliRunner().invoke(cli, ["retarget", str(cfg), "--out", str(out), "--no-progress"])
    return result, out


@pytest.mark.slow
def test_kenney_grown_two_steps_is_clean(tmp_path):
    """building-small-a grown by two steps of its wall slide (0.1 up; the floor height has no
    seamless labeling, see the next test): open edges at most the input's times the copies used,
    faces at most the input's times the volume ratio times 1.5, no duplicate faces, and the
    figures in ``metrics`` agree with the written mesh. Measured: 110 open edges (limit 3 x 58),
    595 faces (limit 820; 10,401 before issue 15), smallest angle 0 as in the input, 13 faces below 1
    degree against the input's 14."""
    name = "meshes/kenney-city/building-small-a.glb"
    _need(name)
    result, out = _grow(tmp_path, name, [2], analysis={"generator_grip_ratio": 0})
    assert result.exit_code == 0, result.stderr
    m = json.loads((out / "report.json").read_text())["metrics"]
    found = {k: m[k] for k in ("boundary_edges", "input_boundary_edges", "copies", "welded_faces", "faces_limit",
                               "volume_ratio", "duplicate_faces", "min_angle_deg", "sliver_faces")}
    assert m["copies"] >= 2 and m["volume_ratio"] > 1.1, found
    assert m["boundary_edges"] <= m["input_boundary_edges"] * m["copies"] == m["boundary_edges_limit"], found
    assert m["welded_faces"] <= m["input_welded_faces"] * m["volume_ratio"] * 1.5, found
    assert m["duplicate_faces"] == 0 and m["nonmanifold_edges"] <= 10, found  # measured 6 (input 0)
    assert m["min_angle_deg"] is not None and 0 <= m["min_angle_deg"] <= 60, found
    assert m["sliver_faces"] <= m["input_sliver_faces"], found  # measured 13 against the input's 14
    # the figures are those of the written mesh (model units, float32 file: weld a little wider)
    res = trimesh.load(out / "retargeted.glb", force="mesh", process=False)
    q = mesh_quality(np.asarray(res.vertices) / m["normalisation"]["scale"], np.asarray(res.faces), tol=1e-5)
    assert q["faces"] == m["welded_faces"] and q["duplicate_faces"] == 0, (q, found)
    assert abs(q["boundary_edges"] - m["boundary_edges"]) <= 4, (q, found)
    grow = np.ptp(np.asarray(res.vertices), axis=0) - np.ptp(load_mesh(DATA / name).vertices, axis=0)
    np.testing.assert_allclose(grow, [0.0, 0.2, 0.0], atol=1e-5)


@pytest.mark.slow
def test_kenney_floor_growth_is_refused(tmp_path):
    """Growing either Kenney piece by two floors is refused with exit 3: each is a hollow shell
    whose storeys sit between a full base slab and a full roof, so every seam between two
    copies joins an empty voxel to a non-empty one (infinite cost in the paper's eq. 4)."""
    names = ["meshes/kenney-city/building-small-a.glb", "meshes/kenney-city/building-small-b.glb"]
    _need(*names)
    for name in names:
        result, _ = _grow(tmp_path, name, [2])
        assert result.exit_code == 3, result.stderr
        assert "no seamless retargeting for steps [2, 0, 0]" in result.stderr, result.stderr


@pytest.mark.slow
def test_house1_grown_two_floors_is_clean(tmp_path):
    """house1_baked (56 of its polygons stored twice, 106 of 528 triangles) grown by two steps of
    its 0.383 floor offset: no duplicate face left, open edges and faces within the limits of the
    input's 422 distinct faces and their 128 open edges. Measured: 319 open edges (limit 384),
    849 faces (limit 892), 1 face below 1 degree (smallest 0.91; the input has none, the cut pieces
    before re-triangulation 140, 13 without the collapse of short seam edges); before issue 15's
    weld at 1e-6, duplicate removal, best-ear re-triangulation and seam-edge collapse: 220 open
    edges over 74, 1,468 faces, 366 duplicates, smallest angle 0."""
    name = "architecture/houses/house1_baked.obj"
    _need(name)
    result, out = _grow(tmp_path, name, [2])
    assert result.exit_code == 0, result.stderr
    m = json.loads((out / "report.json").read_text())["metrics"]
    found = {k: m[k] for k in ("boundary_edges", "boundary_edges_limit", "input_boundary_edges", "welded_faces",
                               "faces_limit", "input_welded_faces", "duplicate_faces", "input_duplicate_faces",
                               "min_angle_deg", "sliver_faces", "copies")}
    assert (m["input_duplicate_faces"], m["input_welded_faces"], m["input_boundary_edges"]) == (106, 422, 128), found
    assert m["copies"] == 3 and m["duplicate_faces"] == 0 and m["nonmanifold_edges"] == 0, found
    assert m["boundary_edges"] <= m["boundary_edges_limit"] == 3 * 128, found
    assert m["welded_faces"] <= m["faces_limit"], found
    assert m["sliver_faces"] <= 1 and m["min_angle_deg"] > 0.9, found
    res = trimesh.load(out / "retargeted.obj", force="mesh", process=False)
    q = mesh_quality(np.asarray(res.vertices) / m["normalisation"]["scale"], np.asarray(res.faces))
    assert q["duplicate_faces"] == 0 and q["faces"] == m["welded_faces"], (q, found)
