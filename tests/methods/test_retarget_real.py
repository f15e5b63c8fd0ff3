"""Retargeting on real meshes made by other people (issue 15), read from ../shared/data (see its
SOURCES.md); every test skips when a file is absent. The sparsity table and its figures are in the
README's retarget section."""

import itertools
import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner

from synthkit.cli.main import cli
from synthkit.core.mesh import normalize_unit
from synthkit.core.quality import mesh_quality
from synthkit.io.assets import load_asset
from synthkit.io.meshes import load_mesh
from synthkit.methods.retarget.analysis import analyze
from synthkit.methods.retarget.config import RetargetConfig
from synthkit.methods.retarget.options import options_of

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
        _CACHE[name] = (analyze((V - center) / scale, F, options_of(RetargetConfig.model_construct())[0], rng=0), scale)
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


def _source_points(inp, V, F, shifts):
    """Every input face of ``inp`` (an Asset) that the centroid of a face of ``V``, ``F`` (a result)
    lies on after one of the label ``shifts (s, 3)`` (model units), facing the same way: ``(k (p,),
    face (p,), W (p, 3))``, result face, input face and barycentric weights per candidate. A
    repeating model offers several (the wall slide maps a wall onto itself), so a check holds when
    one candidate of each face passes it."""
    A, B, C = (inp.V[inp.F[:, i]] for i in range(3))
    n_in = np.cross(B - A, C - A)
    n_in /= np.maximum(np.linalg.norm(n_in, axis=1, keepdims=True), 1e-300)
    n_out = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n_out /= np.maximum(np.linalg.norm(n_out, axis=1, keepdims=True), 1e-300)
    tol = 1e-5 * float(np.linalg.norm(np.ptp(inp.V, axis=0)))
    e1, e2 = B - A, C - A
    d11, d12, d22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
    den = np.where(d11 * d22 - d12 * d12 > 0, d11 * d22 - d12 * d12, np.inf)
    ks, fs, Ws = [], [], []
    for s in shifts:
        q = V[F].mean(axis=1)[:, None, :] - s - A[None]  # (k, m, 3)
        r1, r2 = (q * e1).sum(2), (q * e2).sum(2)
        v, w = (d22 * r1 - d12 * r2) / den, (d11 * r2 - d12 * r1) / den
        on = (np.abs((q * n_in).sum(2)) <= tol) & (v >= -1e-6) & (w >= -1e-6) & (v + w <= 1 + 1e-6)
        k, f = np.nonzero(on & (n_out @ n_in.T > 0.99))
        ks.append(k)
        fs.append(f)
        Ws.append(np.stack([1 - v[k, f] - w[k, f], v[k, f], w[k, f]], axis=1))
    return np.concatenate(ks), np.concatenate(fs), np.concatenate(Ws)


def _each(k, ok, n) -> np.ndarray:
    """``(n,) bool``: some candidate of each result face (``k (p,)``) is ``ok (p,)`` (or True)."""
    out = np.zeros(n, bool)
    out[k[np.broadcast_to(ok, k.shape)]] = True
    return out


def _texel(image, uv):
    """Nearest texel colours ``(k, 3)`` of ``image (H, W, C)`` at ``uv (k, 2)`` (wrapped, v up)."""
    H, W = image.shape[:2]
    x = np.floor(np.mod(uv[:, 0], 1.0) * W).astype(int) % W
    y = np.floor((1.0 - np.mod(uv[:, 1], 1.0)) * H).astype(int) % H
    return image[y, x, :3]


def _shifts(m):
    """The label shifts of a report's metrics in model units ``(M, 3)``."""
    basis = np.asarray(m["grid_basis_normalised"])  # rows: the basis columns
    return np.asarray(m["label_shifts"]) @ basis * m["normalisation"]["scale"]


@pytest.mark.slow
@pytest.mark.parametrize("steps", [1, 2])
def test_kenney_grown_keeps_its_look_and_closes_its_seams(tmp_path, steps):
    """building-small-a grown by one and two steps of its wall slide (0.1 up; the floor height has no
    seamless labeling, see test_kenney_floor_growth_is_refused): the GLB comes back with its mesh
    name, its colormap material with the texture embedded and UVs on every face, and each face shows
    the colour the input shows at the same point of the copy it came from (texture sampled at the
    face's UV centroid against the input's texture at the input's UVs there); open edges within
    the input's times the copies, no non-manifold edge (the input has none), no degenerate face.
    Measured (+1 / +2): open edges 94 / 117 (limits 116 / 174; before issue 22 76 / 110 with 7 / 7
    non-manifold edges and flat faces of float noise, issue 22's report 225 against 126)."""
    name = "meshes/kenney-city/building-small-a.glb"
    _need(name)
    result, out = _grow(tmp_path, name, [steps], analysis={"generator_grip_ratio": 0})
    assert result.exit_code == 0, result.stderr
    rep = json.loads((out / "report.json").read_text())
    m, q = rep["metrics"], rep["metrics"]["mesh_quality"]["mesh"]
    assert rep["status"] == "ok" and m["copies"] == steps + 1, q
    assert q["output"]["open_edges"] <= q["limits"]["open_edges"] == q["input"]["open_edges"] * (steps + 1), q
    assert q["output"]["nonmanifold_edges"] == 0 and q["output"]["degenerate_faces"] == 0, q
    inp, res = load_asset(DATA / name), load_asset(out / "retargeted.glb")
    assert res.name == inp.name and [x.name for x in res.materials] == [x.name for x in inp.materials]
    assert res.corner_uv is not None and res.materials[0].image is not None
    np.testing.assert_array_equal(res.materials[0].image, inp.materials[0].image)
    wq = mesh_quality(res.V, res.F)
    assert wq["degenerate_faces"] == 0 and wq["open_edges"] <= q["limits"]["open_edges"], wq
    k, face, W = _source_points(inp, res.V, res.F, _shifts(m))
    uv_in = np.einsum("pc,pcj->pj", W, inp.corner_uv[face])
    shown = _texel(res.materials[0].image, res.corner_uv.mean(axis=1))[k]
    # a UV on a texel border (0.0625 of 512 px) shows either texel: look a hair to each side
    same = np.zeros(len(k), bool)
    for d in itertools.product((-1e-5, 0.0, 1e-5), repeat=2):
        same |= np.all(_texel(inp.materials[0].image, uv_in + d) == shown, axis=1)
    same = _each(k, same, len(res.F))
    assert same.all(), f"{int((~same).sum())} of {len(res.F)} faces show another colour"


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
def test_house1_grown_two_floors_keeps_its_atlas(tmp_path):
    """house1_baked (56 of its polygons stored twice, 106 of 528 triangles) grown by two steps of
    its 0.383 floor offset: OBJ + MTL + its atlas copied beside it; every face lies on an input
    face of one of the copies with the same texel density (UV area over surface area) and the same
    UVs there, except those a seam collapse moved (within 0.1% of the diagonal); no duplicate,
    degenerate or non-manifold face, open edges within the limit of the
    input's 422 distinct faces and their 128 open edges. Measured: 332 open edges (limit 384),
    1,132 faces (849 before issue 22 merged flat regions across atlas charts), 3 faces below 1
    degree (smallest 0.57)."""
    name = "architecture/houses/house1_baked.obj"
    _need(name)
    result, out = _grow(tmp_path, name, [2])
    assert result.exit_code == 0, result.stderr
    rep = json.loads((out / "report.json").read_text())
    m, q = rep["metrics"], rep["metrics"]["mesh_quality"]["mesh"]
    assert (q["input"]["duplicate_faces"], q["input"]["faces"], q["input"]["open_edges"]) == (106, 422, 128), q
    assert m["copies"] == 3 and q["limits"]["open_edges"] == 3 * 128 and rep["status"] == "ok", q
    assert q["output"]["open_edges"] <= 384 and q["output"]["duplicate_faces"] == 0, q
    assert q["output"]["nonmanifold_edges"] == 0 and q["output"]["degenerate_faces"] == 0, q
    assert {"retargeted.obj", "retargeted.mtl", "retargeted_house_a_bake.png"} <= {p.name for p in out.iterdir()}
    inp, res = load_asset(DATA / name), load_asset(out / "retargeted.obj")
    assert res.materials[0].image is not None and res.materials[0].image.shape == inp.materials[0].image.shape
    k, face, W = _source_points(inp, res.V, res.F, _shifts(m))

    def density(V, F, uv):
        a3 = np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
        d = uv[:, 1:] - uv[:, :1]
        return np.abs(d[:, 0, 0] * d[:, 1, 1] - d[:, 0, 1] * d[:, 1, 0]) / np.maximum(a3, 1e-300)

    d_out, d_in = density(res.V, res.F, res.corner_uv)[k], density(inp.V, inp.F, inp.corner_uv)[face]
    uv_in = np.einsum("pc,pcj->pj", W, inp.corner_uv[face])
    same_uv = np.abs(res.corner_uv.mean(axis=1)[k] - uv_in).max(axis=1) <= 1e-5
    same = _each(k, same_uv & (np.abs(d_out - d_in) <= 1e-3 * np.maximum(d_in, 1e-12)), len(res.F))
    # faces next to a collapsed seam edge (a vertex moved along the seam, up to 0.01 normalised)
    # lie up to 0.004 off the input; measured: 27 of 1,132
    moved = np.flatnonzero(~_each(k, np.ones(len(k), bool), len(res.F)))
    surface = trimesh.Trimesh(inp.V, inp.F, process=False)
    C = res.V[res.F[moved]].mean(axis=1)
    off = np.min([trimesh.proximity.closest_point(surface, C - s)[1] for s in _shifts(m)], axis=0)
    assert np.all(off <= 1e-3 * np.linalg.norm(np.ptp(inp.V, axis=0))) and len(moved) <= 0.03 * len(res.F), off
    same[moved] = True
    assert same.all(), f"{int((~same).sum())} of {len(res.F)} faces have other UVs or texel density"
