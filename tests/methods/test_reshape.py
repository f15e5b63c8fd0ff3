"""Structure-preserving reshape (Cabral et al. 2009): building blocks on tiny fixtures, the issue's
quality checks on the generated pieces (data-samples/reshape-*), chains of real Kenney road tiles,
and bad input through the CLI."""

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from synthkit.cli.main import cli
from synthkit.io.assets import save_asset
from synthkit.methods.reshape import constraints as C
from synthkit.methods.reshape.baseline import angle_errors_deg, laplacian_rows, mesh_edges
from synthkit.methods.reshape.graph import ANGLE, CONTOUR, build_graph, contour_loops
from synthkit.methods.reshape.pipeline import load_textured
from synthkit.methods.reshape.portals import align_portals, boundary_portals, detect_portals, portal_positions
from synthkit.methods.reshape.previews import COMPRESSED, ELONGATED, edge_colours
from synthkit.methods.reshape.solver import ReshapeSolver, floating_anchors
from synthkit.methods.reshape.textured import reshaped_asset
from synthkit.runner import run_config

REPO = Path(__file__).resolve().parents[2]
SAMPLES = REPO / "data-samples"
KENNEY = REPO.parent / "shared" / "data" / "meshes" / "kenney-city"
HOUSES = REPO.parent / "shared" / "data" / "architecture"
STRICT_TOL = 1e-7
"""Largest strict-constraint residual accepted (direction, coplanarity, hole plane, link), as a share
of the model size, with the default strict weight 1e4 (at most 2.2e-8 measured on the samples)."""


def save_textured(mesh, positions, path):
    """``mesh`` at ``positions (#P, 3)`` written to ``path`` as reshape writes a piece."""
    a = reshaped_asset(mesh, positions)
    save_asset(path, a.V, a.F, like=a, corner_uv=a.corner_uv, face_material=a.face_material,
               corner_color=a.corner_color, face_polygon=a.face_polygon, face_group=a.face_group)


def truth(name: str) -> dict:
    return json.loads((SAMPLES / f"{name}.truth.json").read_text())


def reshape(tmp_path: Path, name: str, **cfg) -> tuple[dict, Path]:
    """Run ``synthkit reshape`` with ``cfg`` (small previews, no baseline, ``texture: stretch``
    unless asked: these tests check the geometry reshape, the texture reshape has its own tests in
    test_reshape_texture.py); returns the report and the output folder."""
    cfg = {"method": "reshape", "preview_size": 64, "baseline": False, "texture": "stretch", **cfg}
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(cfg))
    out = tmp_path / f"out-{name}"
    return run_config(path, out_dir=out, show_progress=False), out


def above(axis: str, value: float, **extra) -> dict:
    return {"half_space": {"axis": axis, "above": float(value)}, **extra}


def below(axis: str, value: float, **extra) -> dict:
    return {"half_space": {"axis": axis, "below": float(value)}, **extra}


def node_positions(mesh_path: Path, source: Path, points) -> np.ndarray:
    """Positions ``(k, 3)`` in ``mesh_path`` of the render vertices that sat at ``points`` in ``source``."""
    V0 = load_textured(source).V
    idx = [int(np.flatnonzero(np.linalg.norm(V0 - np.asarray(p), axis=1) < 1e-6)[0]) for p in points]
    return load_textured(mesh_path).V[idx]


@pytest.fixture
def runner():
    """A click test runner; ``result.stdout`` and ``result.stderr`` are kept apart."""
    return CliRunner()


# ---------------------------------------------------------------- building blocks


def square_box():
    """Two unit squares folded at 90 degrees along x = 0 (one surface each), (6, 3) and (4, 3)."""
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1]], float)
    F = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]], np.int64)
    return V, F, np.array([0, 0, 1, 1])


def test_graph_of_two_folded_squares():
    V, F, fm = square_box()
    g = build_graph(V, F, fm, weld_tol=1e-9)
    c = g.counts
    assert (c["surfaces"], c["nodes"], c["edges"], c["flat_edges"], c["components"]) == (2, 6, 7, 2, 1)
    # the shared edge is a contour edge of both squares; the diagonals are flat and ignored
    assert set(g.edge_kind.tolist()) == {CONTOUR}
    assert c["contour_loops"] == 2 and c["ill_formed_contour_vertices"] == 0


def test_graph_angle_edge_inside_one_surface():
    V, F, _ = square_box()
    V, F = V[:4].copy(), F[:2].copy()
    V[3, 2] = 1.0  # fold the square along its diagonal 0-2
    g = build_graph(V, F, np.zeros(2, np.int64), weld_tol=1e-9)
    assert g.counts["angle_edges"] == 1 and g.counts["flat_edges"] == 0
    assert g.edges[g.edge_kind == ANGLE].tolist() == [[0, 2]]


def test_graph_counts_of_generated_wall_match_truth():
    mesh = load_textured(SAMPLES / "reshape-wall.obj")
    g = build_graph(mesh.V, mesh.F, mesh.face_material, weld_tol=1e-9)
    t = truth("reshape-wall")
    assert g.counts["components"] == t["components"]
    assert g.counts["vertices"] == t["vertices"] and g.counts["surfaces"] == t["surfaces"]
    assert g.counts["holes"] == 2  # the window, on the front and on the back face
    assert g.counts["hole_bridges"] > 0


def test_contour_loops_count_a_hole_and_ill_formed_vertices():
    square = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
    hole = square + 4
    loops, holes, ill = contour_loops(np.vstack([square, hole]), np.zeros(8, np.int64), 8)
    assert (loops, holes, ill) == (2, 1, 0)
    loops, holes, ill = contour_loops(square[:3], np.zeros(3, np.int64), 4)  # an open chain
    assert ill == 2


def test_angle_errors_and_edge_colours_exact():
    X0 = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    edges = np.array([[0, 1], [0, 2]])
    X = X0.copy()
    X[1] = [1, 1, 0]  # edge 0-1 turns by 45 degrees, edge 0-2 keeps its direction
    np.testing.assert_allclose(angle_errors_deg(X0, X, edges), [45.0, 0.0], atol=1e-12)
    colours = edge_colours(np.array([1.5, 0.5, 1.0]))
    np.testing.assert_array_equal(colours[0], ELONGATED)
    np.testing.assert_array_equal(colours[1], COMPRESSED)
    assert tuple(colours[2]) not in (ELONGATED, COMPRESSED)


def test_laplacian_baseline_translates_with_its_handles():
    V, F, _ = square_box()
    X0, F2 = V[[0, 1, 2, 3, 6, 7]], np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]])
    A, b = laplacian_rows(X0, mesh_edges(F2))
    assert A.shape == (3 * len(mesh_edges(F2)), 18)
    d = np.array([0.3, -0.2, 0.5])
    X = ReshapeSolver(A, np.array([0, 4])).solve(b, X0[[0, 4]] + d)
    np.testing.assert_allclose(X, X0 + d, atol=1e-12)


def test_stiffness_eq3_exact():
    w = C.stiffness(np.array([0.5, 1.0, 2.0, 3.0]), l_min=1.0, w_small=1e-3, w_long=1e-5)
    np.testing.assert_allclose(w, [1.0, 1e-3, 1e-3 + (1e-5 - 1e-3) * 0.5, 1e-5])


@pytest.mark.parametrize("form", ["vertex", "edge"])
def test_direction_and_stress_rows_vanish_at_rest(form):
    rng = np.random.default_rng(0)
    X0 = rng.normal(size=(6, 3))
    edges = np.array([[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [0, 5]])
    _, length = C.edge_frames(X0, edges)
    A, b, where = C.stack_rows(
        {"d": C.direction_rows(X0, edges, weight=3.0, form=form), "s": C.stress_rows(X0, edges, np.ones(6))}, 6
    )
    np.testing.assert_allclose(A @ X0.ravel() - b, 0, atol=1e-12)
    # a uniform stretch keeps every direction, and changes only the stress rows
    r = A @ (2 * X0).ravel() - b
    np.testing.assert_allclose(r[where["d"]], 0, atol=1e-12)
    np.testing.assert_allclose(r[where["s"]], length, atol=1e-12)


def test_group_rows_compare_with_the_reference_edge():
    X0 = np.array([[0, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0]], float)
    edges = np.array([[0, 1], [3, 2]])  # the second edge runs the other way
    groups = C.edge_groups(X0, edges, angle_deg=1.0, length_tol=0.01, distance=2.0)
    assert [g.tolist() for g in groups] == [[0, 1]]
    rows = C.group_rows(X0, edges, groups, w_g=1.0)
    A, b, _ = C.stack_rows({"g": rows}, 4)
    X = X0.copy()
    X[1, 1] = 2.0  # lengthen the reference edge by 1
    np.testing.assert_allclose(A @ X.ravel() - b, [-1.0])


def test_contacts_of_pillar_and_house_match_truth():
    for name in ("reshape-pillar", "reshape-house"):
        mesh = load_textured(SAMPLES / f"{name}.obj")
        g = build_graph(mesh.V, mesh.F, mesh.face_material, weld_tol=1e-9)
        size = np.linalg.norm(np.ptp(mesh.V, axis=0))
        contacts = C.find_contacts(g.X0, g.Fn, g.component, tol=1e-6 * size)  # OBJ keeps 6 decimals
        assert len(contacts) == truth(name)["contacts"], name
        assert g.counts["components"] == truth(name)["components"], name


def test_portals_detect_align_and_refuse():
    mesh = load_textured(SAMPLES / "reshape-road-a.obj")
    found = detect_portals(mesh.V, tol=1e-9)
    Pa = portal_positions(mesh.V, found["x+"], tol=1e-9)
    Pb = portal_positions(mesh.V, found["x-"], tol=1e-9)
    assert len(Pa) == len(Pb) == truth("reshape-road-a")["portal_vertices"]
    t, gap = align_portals(Pa, Pb, tol=1e-9)
    np.testing.assert_allclose(t, [2.0, 0, 0])
    assert gap < 1e-12
    with pytest.raises(ValueError, match="different vertex counts"):
        align_portals(Pa, Pb[:-1], tol=1e-9)
    with pytest.raises(ValueError, match="do not match"):
        align_portals(Pa, Pb * [1, 2, 1], tol=1e-9)


def test_boundary_loops_of_an_open_road_piece_are_portals():
    mesh = load_textured(SAMPLES / "reshape-road-a.obj")
    caps = np.all(np.isin(mesh.V[mesh.F][:, :, 0], [0.0, 2.0]), axis=1) & (np.ptp(mesh.V[mesh.F][:, :, 0], axis=1) == 0)
    loops = boundary_portals(mesh.V, mesh.F[~caps], tol=1e-9)
    assert sorted(loops) == ["loop0", "loop1"]
    ends = sorted(float(mesh.V[idx, 0].mean()) for idx in loops.values())
    assert ends == [0.0, 2.0]
    assert all(len(portal_positions(mesh.V, idx, tol=1e-9)) == 8 for idx in loops.values())
    assert boundary_portals(mesh.V, mesh.F, tol=1e-9) == {}  # closed piece: no open end


def test_floating_anchors_one_per_unheld_cluster():
    pairs = np.array([[0, 1], [2, 3], [4, 5]])
    anchors = floating_anchors(7, pairs, known=[1], used=np.array([1, 1, 1, 1, 1, 1, 0], bool))
    assert anchors.tolist() == [2, 4]


def test_solver_eliminates_known_nodes_and_reuses_its_factor():
    # a chain 0-1-2 along x with stress rows; nodes 0 and 2 known: node 1 lands halfway
    X0 = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], float)
    edges = np.array([[0, 1], [1, 2]])
    A, b, _ = C.stack_rows(
        {"d": C.direction_rows(X0, edges, weight=10.0), "s": C.stress_rows(X0, edges, np.ones(2))}, 3
    )
    solver = ReshapeSolver(A, np.array([0, 2]))
    assert solver.vars == 3
    for end in (3.0, 4.0):
        X = solver.solve(b, np.array([[0, 0, 0], [end, 0, 0]]))
        np.testing.assert_allclose(X[1], [end / 2, 0, 0], atol=1e-12)
    assert len(solver.solve_ms) == 2


def test_closest_points_on_a_triangle_exact():
    from synthkit.methods.reshape.parts import closest_points

    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[5, 5, 5], [5, 5, 5], [5, 5, 5]]], float)  # one degenerate
    P = np.array([[0.2, 0.2, 1.0], [2.0, 0.0, 0.0], [0.5, -1.0, 0.0], [-1.0, -1.0, 0.0]])
    d, t, lam = closest_points(P, tri)
    np.testing.assert_allclose(d, [1.0, 1.0, 1.0, np.sqrt(2.0)])
    np.testing.assert_array_equal(t, [0, 0, 0, 0])
    np.testing.assert_allclose(lam, [[0.6, 0.2, 0.2], [0, 1, 0], [0.5, 0.5, 0], [1, 0, 0]], atol=1e-12)


def test_attach_clusters_hang_each_free_part_on_the_nearest_held_one():
    from synthkit.methods.reshape.parts import attach_clusters, mesh_parts, part_distances

    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    X = np.vstack([square, square + [0, 0, 0.1], square + [0, 0, 0.15], square + [0, 0, 5.0]])
    quad = np.array([[0, 1, 2], [0, 2, 3]])
    Fn = np.vstack([quad + 4 * k for k in range(4)])
    part = mesh_parts(Fn, len(X))
    np.testing.assert_array_equal(part, np.repeat([0, 1, 2, 3], 4))
    np.testing.assert_allclose(part_distances(X, Fn, part), [0.1, 0.05, 0.05, 4.85])
    pairs = np.vstack([Fn[:, :2], Fn[:, 1:]])
    att = attach_clusters(X, Fn, pairs, known=[0])
    hosts = [int(part[Fn[t, 0]]) for t in att.tri]
    assert [int(part[n[0]]) for n in att.nodes] == [1, 2, 3] and hosts == [0, 1, 2]
    np.testing.assert_allclose(att.gap, [0.1, 0.05, 4.85])


def test_wall_doubled_in_one_line_keeps_door_and_window_widths(tmp_path):
    t = truth("reshape-wall")
    report, out = reshape(tmp_path, "wide", input=str(SAMPLES / "reshape-wall.obj"),
                          stiffness={"l_min": t["l_min"]}, scale={"x": 2.0})
    m = report["metrics"]
    np.testing.assert_allclose(m["resize"]["extent_ratio"], [2, 1, 1], atol=1e-9)
    assert m["status"] == "ok" and m["handles"] > 0 and m["fixed"] > 0 and m["free_parts"] == []
    (x0, y0, x1, _), (wx0, wy0, wx1, _) = t["door"], t["window"]
    src = SAMPLES / "reshape-wall.obj"
    door = node_positions(out / src.name, src, [[x0, y0, 0], [x1, y0, 0]])
    window = node_positions(out / src.name, src, [[wx0, wy0, 0], [wx1, wy0, 0]])
    assert abs(door[1, 0] - door[0, 0] - (x1 - x0)) < 0.02 and abs(window[1, 0] - window[0, 0] - (wx1 - wx0)) < 0.02


def test_selections_and_handle_targets():
    from synthkit.methods.reshape.config import Handle, Selection
    from synthkit.methods.reshape.handles import PieceRange, resolve_fixed, resolve_handles, select_nodes

    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [1, 1, 0]], float)  # 4 is 2's twin
    node = np.array([0, 1, 2, 3, 2])
    pieces = [PieceRange("p", 0, 5, np.arange(5), 5)]
    X0 = V[:4]
    pick = lambda **kw: select_nodes(Selection(**kw), pieces, V, node, key="k").tolist()  # noqa: E731
    assert pick(index=[4]) == [2]
    assert pick(nearest=[[0.9, 0.1, 0]]) == [1]
    assert pick(box={"min": [0.5, -1, -1], "max": [2, 2, 1]}) == [1, 2]
    assert pick(half_space={"axis": "y", "below": 0.5}) == [0, 1]
    nodes, targets = resolve_handles([Handle(index=[2, 3], target=[0.5, 3.0, 0])], pieces, V, node, X0)
    np.testing.assert_allclose(targets.mean(axis=0), [0.5, 3.0, 0])  # the centroid goes to the target
    np.testing.assert_allclose(targets[1] - targets[0], X0[3] - X0[2])
    with pytest.raises(ValueError, match="also handles"):
        resolve_fixed([Selection(index=[4])], nodes, pieces, V, node)
    with pytest.raises(ValueError, match="selects no vertex"):
        pick(half_space={"axis": "x", "above": 5.0})


def test_factor_cache_and_drag_with_a_frozen_node():
    from synthkit.methods.reshape.options import DragOptions
    from synthkit.methods.reshape.solver import FactorCache, drag

    X0 = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], float)
    edges = np.array([[0, 1], [1, 2], [2, 3]])
    A, b, where = C.stack_rows(
        {"d": C.direction_rows(X0, edges, weight=10.0), "s": C.stress_rows(X0, edges, np.ones(3))}, 4
    )
    cache = FactorCache(A)
    full, limited = cache.get([0, 3]), cache.get([0, 2, 3])
    assert cache.get([3, 0]) is full and cache.hits == 1 and len(cache) == 2
    T = X0.copy()
    T[3, 0] = 6.0
    kw = dict(X0=X0, T=T, edges=edges, stress_slice=where["s"], stress_weights=np.ones(3),
              options=DragOptions(steps=3, short_ratio=0.2, raise_factor=1.5, flip_ratio=1e-3, backend="auto",
                                  propagation=None, allow_partial=False))
    dragging = drag(lambda s: limited, b, **kw)
    np.testing.assert_allclose(dragging.X[:, 0], [0, 1, 2, 6], atol=1e-9)  # node 2 frozen: 2-3 takes it all
    released = drag(lambda s: full if s == 3 else limited, b, **kw)
    np.testing.assert_allclose(released.X[:, 0], [0, 2, 4, 6], atol=1e-9)  # release spreads the stretch


def test_textured_obj_round_trip_keeps_uvs_and_materials(tmp_path):
    mesh = load_textured(SAMPLES / "reshape-stairs.obj")
    P = mesh.positions * 2.0
    save_textured(mesh, P, tmp_path / "stairs.obj")
    again = load_textured(tmp_path / "stairs.obj")
    np.testing.assert_allclose(again.V, mesh.V * 2.0, atol=1e-6)
    np.testing.assert_array_equal(again.UV, mesh.UV)
    np.testing.assert_array_equal(again.F, mesh.F)
    assert again.materials == mesh.materials
    assert (tmp_path / "stairs.mtl").is_file() and (tmp_path / "stairs_bricks_wall.png").is_file()


# ---------------------------------------------------------------- quality checks of the issue


def wall_config(**extra) -> dict:
    t = truth("reshape-wall")
    return {
        "input": str(SAMPLES / "reshape-wall.obj"),
        "stiffness": {"l_min": t["l_min"]},
        "handles": [above("y", t["height"] - 0.01, displacement=[0, 0.5 * t["height"], 0])],
        "fixed": [below("y", 0.01)],
        **extra,
    }


def test_wall_raised_by_half_keeps_directions_and_door(tmp_path):
    report, out = reshape(tmp_path, "wall", **wall_config(baseline=True))
    m = report["metrics"]
    assert m["status"] == "ok" and m["steps_done"] == 10
    assert m["max_angle_error_deg"] < 0.5
    assert m["rigid_length_error"] < 0.01
    assert all(v < STRICT_TOL for v in m["strict_residuals"].values()), m["strict_residuals"]
    t = truth("reshape-wall")
    x0, _, x1, y1 = t["door"]
    wall = SAMPLES / "reshape-wall.obj"
    door = node_positions(out / "reshape-wall.obj", wall, [[x0, 0, 0], [x0, y1, 0], [x1, y1, 0]])
    assert abs(np.linalg.norm(door[1] - door[0]) / y1 - 1) < 0.01
    assert abs(np.linalg.norm(door[2] - door[1]) / (x1 - x0) - 1) < 0.01
    side = node_positions(out / "reshape-wall.obj", wall, [[0, 0, 0], [0, t["height"], 0]])
    assert np.linalg.norm(side[1] - side[0]) == pytest.approx(1.5 * t["height"], rel=1e-6)  # long edges stretch
    assert m["baseline"]["max_angle_error_deg"] >= 10 * m["max_angle_error_deg"]
    for key in ("vars", "nnz_A", "nnz_AtA", "nodes", "edges", "equations", "factor_ms", "solve_ms",
                "handle_residual", "contact_residual", "edge_groups"):
        assert key in m
    assert m["handle_residual"] == 0.0


def test_wall_with_per_edge_direction_constraints(tmp_path):
    vertex, _ = reshape(tmp_path, "vertex", **wall_config())
    edge, _ = reshape(tmp_path, "edge", **wall_config(strict={"direction_form": "edge"}))
    v, e = vertex["metrics"], edge["metrics"]
    assert e["equations"] > v["equations"]  # 3 rows per edge instead of 3 per node
    assert e["max_angle_error_deg"] < 0.5 and e["rigid_length_error"] < 0.01
    assert e["strict_residuals"]["direction"] < STRICT_TOL


def riser_heights(out_mesh: Path) -> np.ndarray:
    t = truth("reshape-stairs")
    h, d = t["riser"], t["tread"]
    src = SAMPLES / "reshape-stairs.obj"
    bottoms = node_positions(out_mesh, src, [[k * d, k * h, 0] for k in range(t["steps"])])
    tops = node_positions(out_mesh, src, [[k * d, (k + 1) * h, 0] for k in range(t["steps"])])
    return tops[:, 1] - bottoms[:, 1]


def stairs_config(**extra) -> dict:
    t = truth("reshape-stairs")
    top = t["steps"] * t["riser"]
    return {
        "input": str(SAMPLES / "reshape-stairs.obj"),
        "stiffness": {"l_min": 0.05},
        "handles": [above("y", top - 0.01, displacement=[0, 0.6, 0])],
        "fixed": [below("y", 0.01)],
        **extra,
    }


def test_stairs_risers_equal_with_edge_groups_only(tmp_path):
    on, out_on = reshape(tmp_path, "on", **stairs_config(baseline=True))
    off, out_off = reshape(tmp_path, "off", **stairs_config(groups={"enabled": False}))
    h_on, h_off = riser_heights(out_on / "reshape-stairs.obj"), riser_heights(out_off / "reshape-stairs.obj")
    assert h_on.sum() == pytest.approx(truth("reshape-stairs")["steps"] * 0.25 + 0.6, rel=1e-6)
    assert (h_on.max() - h_on.min()) / h_on.mean() < 0.01
    assert (h_off.max() - h_off.min()) / h_off.mean() > 0.05  # Fig. 5: the banded riser lags
    assert on["metrics"]["edge_groups"] > 0 and off["metrics"]["edge_groups"] == 0
    assert on["metrics"]["max_angle_error_deg"] < 0.5
    assert all(v < STRICT_TOL for v in on["metrics"]["strict_residuals"].values())
    assert on["metrics"]["baseline"]["max_angle_error_deg"] >= 10 * on["metrics"]["max_angle_error_deg"]


def test_pillar_foot_stays_on_the_floor(tmp_path):
    report, out = reshape(
        tmp_path, "pillar", input=str(SAMPLES / "reshape-pillar.obj"),
        handles=[above("y", 1.99, displacement=[0.5, 1.0, 0.3])], fixed=[below("y", -0.19)],
    )
    m = report["metrics"]
    assert m["contacts"] == 4
    assert m["contact_residual"] < 1e-6
    assert set(m["strict_residuals"]) == {"direction", "coplanarity"}
    assert all(v < STRICT_TOL for v in m["strict_residuals"].values()), m["strict_residuals"]
    V = load_textured(out / "reshape-pillar.obj").V
    V0 = load_textured(SAMPLES / "reshape-pillar.obj").V
    on_top = np.abs(V0[:, 1]) < 1e-9
    near_centre = np.all(np.abs(V0[:, [0, 2]] - 2.0) < 0.21, axis=1)
    foot, floor_top = np.flatnonzero(on_top & near_centre), np.flatnonzero(on_top & ~near_centre)
    assert len(foot) and len(floor_top)
    # the floor's top stays flat and the foot stays in its plane (the slab itself may rise a little)
    size = np.linalg.norm(np.ptp(V0, axis=0))
    plane_y = V[floor_top, 1].mean()
    assert np.ptp(V[floor_top, 1]) < 1e-6 * size
    assert np.abs(V[foot, 1] - plane_y).max() < 1e-6 * size
    assert V[foot, 0].mean() > 2.0 + 0.1  # the foot slid with the top


def house_config(**extra) -> dict:
    return {
        "input": str(SAMPLES / "reshape-house.obj"),
        "handles": [above("y", truth("reshape-house")["ridge"] - 0.01, displacement=[0, 0.6, 0])],
        "fixed": [below("y", 0.01)],
        **extra,
    }


def test_roof_frame_free_post_is_carried_and_a_link_ties_it(tmp_path):
    tie, post = truth("reshape-house")["link"]
    src = SAMPLES / "reshape-house.obj"
    rest = node_positions(src, src, [tie, post])
    moved = {}
    for name, links in (("free", []), ("linked", [{"nearest": [tie, post]}])):
        report, out = reshape(tmp_path, name, **house_config(links=links, parts={"attach_distance": 1e-3}))
        moved[name] = node_positions(out / "reshape-house.obj", src, [tie, post]) - rest
        m = report["metrics"]
        assert m["links"] == len(links) and m["contacts"] == truth("reshape-house")["contacts"]
        assert all(v < STRICT_TOL for v in m["strict_residuals"].values()), m["strict_residuals"]
        assert [f["nodes"] for f in m["free_parts"]] == ([8] if not links else [])
    # without the link the post (0.008 of the model size from the roof) is still carried, never left behind
    assert moved["free"][0, 1] > 0.3 and moved["free"][1, 1] > 0.3
    np.testing.assert_allclose(moved["linked"][1], moved["linked"][0], atol=1e-8)  # they move together


def collapse_config(**solver) -> dict:
    return wall_config(
        handles=[{"box": {"min": [5.99, -1, -1], "max": [7, 4, 1]}, "displacement": [-7, 0, 0]}],
        fixed=[below("x", 0.01)], solver=solver,
    )


def test_collapse_refused_with_exit_3_naming_edge_and_step(tmp_path, runner):
    cfg = tmp_path / "collapse.yaml"
    cfg.write_text(yaml.safe_dump({"method": "reshape", **collapse_config()}))
    result = runner.invoke(cli, ["reshape", str(cfg), "--out", str(tmp_path / "o")])
    assert result.exit_code == 3
    line = result.stderr.strip().splitlines()[-1]
    assert "would flip at step 6 of 10" in line and "the edge between vertex" in line and "last valid step 5" in line
    assert not (tmp_path / "o").exists()


def test_collapse_partial_writes_last_valid_step(tmp_path):
    report, out = reshape(tmp_path, "partial", **collapse_config(allow_partial=True))
    m = report["metrics"]
    assert m["status"] == "partial" and m["steps_done"] == 5 and m["refused_step"] == 6
    assert report["status"] == "partial"
    assert m["length_raises"] > 0  # edges grew short before the flip: their l_ki was raised
    assert m["min_stretch"] > 0 and m["max_angle_error_deg"] < 0.5
    assert (out / "reshape-wall.obj").is_file()


def road_chain_config(a: str, b: str, **extra) -> dict:
    return {
        "pieces": [{"name": "a", "input": a}, {"name": "b", "input": b}],
        "chain": [{"a": "a", "a_portal": "x+", "b": "b", "b_portal": "x-"}],
        **extra,
    }


def test_chain_of_two_road_pieces_stays_joined(tmp_path):
    report, out = reshape(tmp_path, "road", **road_chain_config(
        str(SAMPLES / "reshape-road-a.obj"), str(SAMPLES / "reshape-road-b.obj"),
        handles=[{"piece": "b", **above("x", 3.49), "displacement": [1.0, 0, 0]}],
        fixed=[{"piece": "a", **below("x", 0.01)}],
    ))
    m = report["metrics"]
    assert m["joins"][0]["vertices"] == 8 and m["steps_done"] == 10
    assert m["joins"][0]["gap"] < 1e-9
    A, B = load_textured(out / "a.obj").V, load_textured(out / "b.obj").V
    A0 = load_textured(SAMPLES / "reshape-road-a.obj").V
    B0 = load_textured(SAMPLES / "reshape-road-b.obj").V
    pa, pb = A[np.abs(A0[:, 0] - 2.0) < 1e-9], B[np.abs(B0[:, 0]) < 1e-9] + [2.0, 0, 0]  # b sits 2.0 along x
    gap = np.min(np.linalg.norm(pa[:, None] - pb[None], axis=2), axis=1).max()
    assert gap < 1e-9 * np.linalg.norm(np.ptp(np.vstack([A, B]), axis=0))
    assert A[:, 0].max() > 2.0 + 1e-3  # the deformation propagated into piece a
    assert m["max_angle_error_deg"] < 0.5


def three_roads(**solver) -> dict:
    road = str(SAMPLES / "reshape-road-a.obj")
    return {
        "pieces": [{"name": n, "input": road} for n in ("r1", "r2", "r3")],
        "chain": [{"a": "r1", "a_portal": "x+", "b": "r2", "b_portal": "x-"},
                  {"a": "r2", "a_portal": "x+", "b": "r3", "b_portal": "x-"}],
        "handles": [{"piece": "r3", **above("x", 5.99), "displacement": [1.5, 0, 0]}],
        "fixed": [{"piece": "r1", **below("x", 0.01)}],
        "solver": {"steps": 4, **solver},
    }


def test_chain_joins_portals_that_differ_by_more_than_the_weld_tolerance(tmp_path):
    mesh = load_textured(SAMPLES / "reshape-road-b.obj")
    P = mesh.positions.copy()
    corner = np.all(np.abs(P) < 1e-9, axis=1)  # every copy of the portal corner at the origin
    P[corner, 2] += 2e-5  # one portal vertex off by 2e-5 (weld tolerance about 4e-6)
    save_textured(mesh, P, tmp_path / "b.obj")
    report, out = reshape(tmp_path, "offset", **road_chain_config(
        str(SAMPLES / "reshape-road-a.obj"), str(tmp_path / "b.obj"),
        handles=[{"piece": "b", **above("x", 3.49), "displacement": [1.0, 0, 0]}],
        fixed=[{"piece": "a", **below("x", 0.01)}], graph={"portal_tol": 1e-5},
    ))
    m = report["metrics"]
    assert m["joins"][0]["placed_gap"] > 1e-6 and m["joins"][0]["gap"] < 1e-9
    assert m["graph"]["components"] == 1


def test_limited_propagation_factors_twice_and_releases_to_the_full_solve(tmp_path):
    full, out_full = reshape(tmp_path, "full", **three_roads())
    lim, out_lim = reshape(tmp_path, "limited", **three_roads(propagation=0))
    assert full["metrics"]["factorizations"] == 1 and full["metrics"]["factor_cache_hits"] == 0
    assert lim["metrics"]["factorizations"] == 2 and lim["metrics"]["frozen_nodes"] > 0
    for name in ("r1", "r2", "r3"):  # the release step solves the whole chain: same result
        np.testing.assert_allclose(load_textured(out_lim / f"{name}.obj").V, load_textured(out_full / f"{name}.obj").V,
                                   atol=1e-9)
    assert load_textured(out_full / "r1.obj").V[:, 0].max() > 2.0 + 1e-3  # the first piece stretched too


@pytest.mark.skipif(not KENNEY.is_dir(), reason="../shared/data/meshes/kenney-city not present")
def test_chain_of_kenney_road_tiles(tmp_path):
    road, corner = str(KENNEY / "road-straight.glb"), str(KENNEY / "road-corner.glb")
    report, out = reshape(
        tmp_path, "kenney",
        pieces=[{"name": "s1", "input": road}, {"name": "s2", "input": road}, {"name": "c", "input": corner}],
        chain=[{"a": "s1", "a_portal": "z-", "b": "s2", "b_portal": "z+"},
               {"a": "s2", "a_portal": "z-", "b": "c", "b_portal": "z+"}],
        handles=[{"piece": "c", **below("z", -2.499), "displacement": [0, 0, -0.5]}],
        fixed=[{"piece": "s1", **above("z", 0.499)}],
    )
    m = report["metrics"]
    assert [j["vertices"] for j in m["joins"]] == [14, 14]
    assert m["status"] == "ok" and m["max_angle_error_deg"] < 0.5
    s1, s2 = load_textured(out / "s1.glb"), load_textured(out / "s2.glb")
    end1 = s1.V[s1.V[:, 2] < s1.V[:, 2].min() + 1e-6]  # the -z end of s1, the +z end of s2
    end2 = s2.V[s2.V[:, 2] > s2.V[:, 2].max() - 1e-6]
    assert max(j["gap"] for j in m["joins"]) < 1e-9
    # s2 sits one tile further along -z, its file in its own frame; GLB stores float32 positions
    gap = np.min(np.linalg.norm(end1[:, None] - (end2[None] + [0, 0, -1.0]), axis=2), axis=1).max()
    assert gap < 1e-6
    assert np.array_equal(np.unique(s1.UV, axis=0), np.unique(load_textured(road).UV, axis=0))


def house_motion(V, mode: str) -> dict:
    """Widen a house by 30 % along x (both end walls selected by half-spaces), or raise everything
    above its middle by 20 % of its height with the foot fixed."""
    lo, hi = V.min(axis=0), V.max(axis=0)
    ext = hi - lo
    if mode == "widen":
        return {"handles": [above("x", hi[0] - 0.01 * ext[0], displacement=[float(0.3 * ext[0]), 0, 0])],
                "fixed": [below("x", lo[0] + 0.01 * ext[0])]}
    return {"handles": [above("y", lo[1] + 0.59 * ext[1], displacement=[0, float(0.2 * ext[1]), 0])],
            "fixed": [below("y", lo[1] + 0.01 * ext[1])]}


@pytest.mark.skipif(not HOUSES.is_dir(), reason="../shared/data/architecture not present")
@pytest.mark.parametrize("name, mode", [
    ("houses/house1_baked.obj", "widen"), ("houses/house2_baked.obj", "widen"),
    ("houses/house4_baked.obj", "widen"), ("tudorhouse/tudorhouse.obj", "raise"),
])
def test_real_houses(tmp_path, name, mode):
    mesh = load_textured(HOUSES / name)
    report, out = reshape(tmp_path, "house", input=str(HOUSES / name), baseline=True,
                          contacts={"tol": 1e-4}, **house_motion(mesh.V, mode))
    m = report["metrics"]
    assert m["status"] == "ok" and m["nodes"] > 250
    assert m["max_angle_error_deg"] < 1.0
    assert m["baseline"]["max_angle_error_deg"] >= 10 * m["max_angle_error_deg"]
    again = load_textured(out / Path(name).name)
    np.testing.assert_array_equal(again.UV, mesh.UV)
    assert again.materials == mesh.materials


def _nodes_of(path):
    """Graph nodes ``(n, 3)``, triangles over nodes and part labels of a house (the file's vertex
    order, so input and output nodes correspond)."""
    from synthkit.methods.reshape.parts import mesh_parts

    mesh = load_textured(path)
    size = float(np.linalg.norm(mesh.V.max(axis=0) - mesh.V.min(axis=0)))
    g = build_graph(mesh.V, mesh.F, mesh.face_material, weld_tol=1e-6 * size)
    return g, mesh_parts(g.Fn, g.n_nodes), size


def _attachment_error(X0, X1, Fn, part) -> float:
    """Largest, over the parts but the root, of the smallest mismatch between the motion of the
    part's centroid or of one of its nodes and the motion of the host point beneath it (the nearest
    point of another part's triangles, same barycentric coordinates after)."""
    from synthkit.methods.reshape.parts import closest_points

    root = np.argmax(np.bincount(part[part >= 0]))
    worst = 0.0
    for k in set(np.unique(part[part >= 0]).tolist()) - {int(root)}:
        nodes = np.flatnonzero(part == k)
        other = np.flatnonzero(part[Fn[:, 0]] != k)
        P0 = np.vstack([X0[nodes].mean(axis=0), X0[nodes]])
        P1 = np.vstack([X1[nodes].mean(axis=0), X1[nodes]])
        _, t, lam = closest_points(P0, X0[Fn[other]])
        host0 = np.einsum("kj,kjc->kc", lam, X0[Fn[other[t]]])
        host1 = np.einsum("kj,kjc->kc", lam, X1[Fn[other[t]]])
        worst = max(worst, float(np.linalg.norm((P1 - P0) - (host1 - host0), axis=1).min()))
    return worst


def _storey_ratios(X0, X1, part, size, axis=1) -> np.ndarray:
    """After / before height of each band (> 10 % of the height) between the levels of the root's
    nodes along ``axis``, leaving out nodes inside another part's box (the rim of a window's hole)."""
    root = np.argmax(np.bincount(part[part >= 0]))
    keep = part == root
    for k in set(np.unique(part[part >= 0]).tolist()) - {int(root)}:
        lo, hi = X0[part == k].min(axis=0) - 2e-3 * size, X0[part == k].max(axis=0) + 2e-3 * size
        keep &= ~np.all((X0 >= lo) & (X0 <= hi), axis=1)
    y0, y1 = X0[keep, axis], X1[keep, axis]
    order = np.argsort(y0)
    height = y0.max() - y0.min()
    cuts = np.flatnonzero(np.diff(y0[order]) > 0.02 * height) + 1
    levels = [(y0[order][g].mean(), y1[order][g].mean()) for g in np.split(np.arange(len(y0)), cuts)]
    bands = [(b[0] - a[0], b[1] - a[1]) for a, b in zip(levels[:-1], levels[1:], strict=True)]
    return np.array([after / before for before, after in bands if before > 0.1 * height])


@pytest.mark.slow
@pytest.mark.skipif(not HOUSES.is_dir(), reason="../shared/data/architecture not present")
@pytest.mark.parametrize("name", ["house1", "house2", "house4"])
@pytest.mark.parametrize("axis, factor", [("x", 1.3), ("y", 1.5)])
def test_real_houses_resized_in_one_line(tmp_path, name, axis, factor):
    src = HOUSES / "houses" / f"{name}_baked.obj"
    report, out = reshape(tmp_path, name, input=str(src), scale={axis: factor})
    m = report["metrics"]
    a = "xyz".index(axis)
    assert m["status"] == "ok" and m["free_parts"] == [] and m["attached_parts"] > 10
    want = np.where(np.arange(3) == a, factor, 1.0)
    np.testing.assert_allclose(m["resize"]["extent_ratio"], want, rtol=0.02)
    g, part, size = _nodes_of(src)
    X1 = np.zeros_like(g.X0)
    X1[g.node_of_vertex] = load_textured(out / src.name).V
    assert _attachment_error(g.X0, X1, g.Fn, part) < 0.005 * size
    root = np.argmax(np.bincount(part[part >= 0]))
    top, extent = g.X0.max(axis=0)[a], np.ptp(g.X0, axis=0)[a]
    for k in set(np.unique(part).tolist()) - {int(root), -1}:  # doors, windows, frames keep their size
        e0, e1 = np.ptp(g.X0[part == k], axis=0), np.ptp(X1[part == k], axis=0)
        if e0[a] < 0.45 * extent and g.X0[part == k, a].max() < top - 1e-3 * extent:  # not the chimney
            assert abs(e1[a] / e0[a] - 1) < 0.03, (k, e0, e1)
    if axis == "y":
        ratios = _storey_ratios(g.X0, X1, part, size)
        assert len(ratios) >= 2 and np.all(np.abs(ratios / factor - 1) < 0.05), ratios


@pytest.mark.slow
@pytest.mark.skipif(not HOUSES.is_dir(), reason="../shared/data/architecture not present")
def test_tudor_house_resized_in_one_line(tmp_path):
    report, _ = reshape(tmp_path, "tudor", input=str(HOUSES / "tudorhouse" / "tudorhouse.obj"),
                        size={"x": 862.0}, scale=None)
    m = report["metrics"]
    assert m["status"] == "ok" and m["free_parts"] == []
    np.testing.assert_allclose(m["resize"]["extent_ratio"], [862.0 / 662.72998, 1, 1], rtol=0.02)


# ---------------------------------------------------------------- bad input through the CLI


def _invoke(runner, tmp_path, cfg: dict):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({"method": "reshape", **cfg}))
    result = runner.invoke(cli, ["reshape", str(path), "--out", str(tmp_path / "o")])
    assert not (tmp_path / "o").exists()
    assert "Traceback" not in result.stderr
    return result.exit_code, result.stderr.strip().splitlines()[-1]


@pytest.mark.parametrize(
    "change, code, message",
    [
        ({"handles": [{"index": [999], "displacement": [0, 1, 0]}]}, 2,
         "handles[0].index: vertex 999 is out of range (piece reshape-wall has 72 vertices)"),
        ({"handles": [above("y", 50.0, displacement=[0, 1, 0])]}, 2, "handles[0]: selects no vertex"),
        ({"fixed": [below("y", 10.0)]}, 2, "fixed[0]: 4 vertices are also handles"),
        ({"handles": []}, 2, "give exactly one of handles, scale, size (got none)"),
        ({"scale": {"x": 1.3}}, 2, "give exactly one of handles, scale, size (got handles, scale)"),
        ({"handles": [], "fixed": [], "scale": {}}, 2, "scale: give at least one of x, y, z"),
        ({"handles": [above("y", -1.0, displacement=[0, 1, 0])], "fixed": []}, 2,
         "handles: the recipe stretches nothing (every edge keeps its length within 1e-6"),
        ({"handles": [above("y", 2.0, displacement=[0, 1, 0])], "fixed": []}, 2,
         "handles: the recipe stretches nothing (every edge keeps its length within 1e-6"),
        ({"handles": [], "fixed": [], "scale": {"x": 1.0}}, 2, "scale: the recipe stretches nothing"),
        ({"stiffness": {"l_min": 0}}, 2, "stiffness.l_min: Input should be greater than 0"),
        ({"stiffness": {"l_min": -1.0}}, 2, "stiffness.l_min: Input should be greater than 0"),
    ],
    ids=["index-out-of-range", "selects-nothing", "handle-also-fixed", "no-handle", "handles-and-scale", "empty-scale",
         "selects-everything", "translates-only", "scale-one", "l_min-zero", "l_min-negative"],
)
def test_bad_input_exit_codes(runner, tmp_path, change, code, message):
    got, line = _invoke(runner, tmp_path, {**wall_config(), **change})
    assert got == code
    assert message in line and line.startswith("error: ")


def test_mesh_without_faces_exit_3(runner, tmp_path):
    (tmp_path / "empty.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    code, line = _invoke(runner, tmp_path, {**wall_config(), "input": str(tmp_path / "empty.obj")})
    assert code == 3 and "empty.obj: mesh has no faces" in line


def test_zero_area_mesh_exit_3(runner, tmp_path):
    (tmp_path / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    code, line = _invoke(runner, tmp_path, {**wall_config(), "input": str(tmp_path / "flat.obj")})
    assert code == 3 and "flat.obj: every triangle has zero area" in line


def test_memory_budget_refuses_before_building(tmp_path):
    from synthkit.context import RunContext
    from synthkit.errors import ConfigError
    from synthkit.io.inputs import Inputs
    from synthkit.limits import Budget
    from synthkit.methods.reshape import pipeline
    from synthkit.methods.reshape.config import ReshapeConfig

    cfg = ReshapeConfig.model_validate({"method": "reshape", **wall_config()})
    ctx = RunContext(tmp_path, seed=0, show_progress=False, budget=Budget(10_000))
    with pytest.raises(ConfigError, match=r"^input: .*reshape-wall.obj needs about .* matrix entries"):
        pipeline.compute(cfg, Inputs(), ctx)
    assert not ctx.outputs


def test_missing_handles_key_exit_2(runner, tmp_path):
    cfg = wall_config()
    del cfg["handles"]
    code, line = _invoke(runner, tmp_path, cfg)
    assert code == 2 and "give exactly one of handles, scale, size (got none)" in line


@pytest.mark.parametrize(
    "chain, message",
    [
        ([{"a": "a", "a_portal": "x+", "b": "b", "b_portal": "y-"}],
         "chain[0]: a.x+ and b.y-: portals have different vertex counts (8 and 4)"),
        ([{"a": "a", "a_portal": "x+", "b": "b", "b_portal": "door"}],
         "chain[0].b_portal: piece b has no portal 'door'"),
    ],
    ids=["different-counts", "no-such-portal"],
)
def test_bad_chain_exit_2(runner, tmp_path, chain, message):
    cfg = road_chain_config(str(SAMPLES / "reshape-road-a.obj"), str(SAMPLES / "reshape-road-b.obj"),
                            handles=[{"piece": "b", **above("x", 3.49), "displacement": [1.0, 0, 0]}])
    code, line = _invoke(runner, tmp_path, {**cfg, "chain": chain})
    assert code == 2 and message in line


def test_same_seed_same_bytes(tmp_path):
    _, a = reshape(tmp_path, "one", **wall_config())
    _, b = reshape(tmp_path, "two", **wall_config())
    assert (a / "reshape-wall.obj").read_bytes() == (b / "reshape-wall.obj").read_bytes()


def _tree(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` with its bytes (folders as b'dir')."""
    return {p.relative_to(root).as_posix(): b"dir" if p.is_dir() else p.read_bytes() for p in sorted(root.rglob("*"))}


def _refused_alone(runner, tmp_path, cfg: dict) -> tuple[int, str]:
    """Run ``cfg`` with its output folder three levels down; returns the exit code and the one stderr
    line after checking that nothing under ``tmp_path`` changed (no output folder, no escaped file)."""
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({"method": "reshape", **cfg}))
    (tmp_path / "a" / "b").mkdir(parents=True)
    before = _tree(tmp_path)
    result = runner.invoke(cli, ["reshape", str(path), "--out", str(tmp_path / "a" / "b" / "o")])
    assert _tree(tmp_path) == before
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    return result.exit_code, lines[0]


@pytest.mark.parametrize("name", ["../../escaped", "sub/piece", "..", "a\\b"])
def test_piece_name_with_a_folder_part_exit_2(runner, tmp_path, name):
    cfg = road_chain_config(str(SAMPLES / "reshape-road-a.obj"), str(SAMPLES / "reshape-road-b.obj"),
                            handles=[{"piece": "b", **above("x", 3.49), "displacement": [1.0, 0, 0]}])
    cfg["pieces"][0]["name"] = name
    cfg["chain"][0]["a"] = name
    code, line = _refused_alone(runner, tmp_path, cfg)
    assert code == 2
    assert f"bad.yaml: pieces.0.name: must be a plain file name (no '/', '\\', '..' or surrounding spaces) " \
           f"(got {name!r})" in line


@pytest.mark.parametrize(
    "change, message",
    [
        ({"handles": [above("y", 2.99, displacement=[0, 1e30, 0])]},
         "handles[0].displacement: [0.0, 1e+30, 0.0] moves vertices by 1.49e+29 model sizes; at most 100"),
        ({"handles": [above("y", 2.99, target=[0, 1e4, 0])]},
         "handles[0].target: [0.0, 10000.0, 0.0] moves vertices by 1.49e+03 model sizes; at most 100"),
        ({"handles": [], "fixed": [], "scale": {"x": 1e6}},
         "scale.x: 1000000.0 moves vertices by 8.94e+05 model sizes; at most 100"),
        ({"handles": [], "fixed": [], "size": {"x": 1e5}},
         "size.x: 100000.0 moves vertices by 1.49e+04 model sizes; at most 100"),
    ],
    ids=["displacement-1e30", "target-far", "scale-1e6", "size-1e5"],
)
def test_motion_out_of_the_model_range_exit_2(runner, tmp_path, change, message):
    code, line = _refused_alone(runner, tmp_path, {**wall_config(), **change})
    assert code == 2 and message in line


def test_motion_of_a_hundred_model_sizes_is_still_exact(tmp_path):
    report, _ = reshape(tmp_path, "far", **wall_config(handles=[above("y", 2.99, displacement=[0, 671.0, 0])]))
    m = report["metrics"]
    assert m["status"] == "ok" and max(m["strict_residuals"].values()) < STRICT_TOL
