"""Benchmark of the reshape solver (synthkit.methods.reshape) against scipy and the paper's Table 4.

The test meshes tile the generated wall with a door and a window (data-samples/reshape-wall.obj,
6 x 3 units) into a facade; co-located tile corners weld into shared nodes. Handles: the facade's
top row moves up by half a tile; fixed: its bottom row. For each size the full constraint system
of section 3.2 is built (edge groups on, contacts and hole rows), then:

- ours: ``ReshapeSolver`` (normal matrix ``A_u^T A_u`` and its sparse Cholesky once, timed apart
  from the solves: "factor" is forming and factoring ``A_u^T A_u``; then one solve per step), with
  cholespy and with the tuned SuperLU backend;
- scipy: ``scipy.sparse.linalg.spsolve`` on the same normal equations for every solve (no
  factorization kept), the usual way without a cached factor.

The four real houses of ../shared/data/architecture (when present) are measured too, widened by
30 % along x, with Table 4's columns (vars, nnz A, nnz A'A, nodes, edges, equations, factor, solve).

Sizes: about 1314 unknowns (the paper's 1314-variable piece: factor 2155 ms, solve 10 ms with
TAUCS in 2009; its 909-variable piece: 175 ms and 3 ms) and a 100k-vertex facade. Goals on this
machine: factor <= 10 ms and solve <= 0.5 ms at 1314 unknowns; factor <= 1.5 s and solve <= 50 ms
at 100k vertices. scikit-sparse (CHOLMOD) is not measured: it has no wheel and needs SuiteSparse
headers to build (see ../shared/ARCHITECTURE.md), which the project's install does not provide.

Run: ``.venv/bin/python benchmarks/reshape.py [--quick]``; writes bench-results/reshape.json.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from scipy.sparse.linalg import spsolve

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import median_time, print_table, record, write_results  # noqa: E402
from synthkit.core.lsq import have_cholespy  # noqa: E402
from synthkit.methods.reshape.config import ReshapeConfig  # noqa: E402
from synthkit.methods.reshape.graph import build_graph  # noqa: E402
from synthkit.methods.reshape.options import options_of  # noqa: E402
from synthkit.methods.reshape.pipeline import load_textured  # noqa: E402
from synthkit.methods.reshape.solver import ReshapeSolver, floating_anchors, known_columns  # noqa: E402
from synthkit.methods.reshape.system import build_system  # noqa: E402

AREA = "reshape"
WALL = Path(__file__).resolve().parent.parent / "data-samples" / "reshape-wall.obj"
HOUSES = Path(__file__).resolve().parents[2] / "shared" / "data" / "architecture"
REAL = ["houses/house1_baked.obj", "houses/house2_baked.obj", "houses/house4_baked.obj", "tudorhouse/tudorhouse.obj"]
"""Real textured houses (made by others; skipped when absent), in Table 4's columns."""
PAPER = {"1314 vars": (2155.0, 10.0), "909 vars": (175.0, 3.0)}
"""Table 4 of the paper: (factor ms, solve ms) with TAUCS."""


def tiled_wall(nx: int, ny: int):
    """Render vertices ``V``, triangles ``F`` and materials of ``nx`` x ``ny`` wall tiles."""
    m = load_textured(WALL)
    w, h = np.ptp(m.V[:, 0]), np.ptp(m.V[:, 1])
    shifts = np.array([[i * w, j * h, 0.0] for j in range(ny) for i in range(nx)])
    V = (m.V[None] + shifts[:, None]).reshape(-1, 3)
    F = (m.F[None] + len(m.V) * np.arange(len(shifts))[:, None, None]).reshape(-1, 3)
    return V, F, np.tile(m.face_material, len(shifts)), h


def problem(nx: int, ny: int):
    """The solver inputs of a tiled facade: system, known nodes and their targets, timings."""
    V, F, fm, h = tiled_wall(nx, ny)
    start = time.perf_counter()
    size = float(np.linalg.norm(np.ptp(V, axis=0)))
    graph = build_graph(V, F, fm, weld_tol=1e-6 * size)
    cfg = ReshapeConfig.model_validate({"input": str(WALL), "handles": [{"index": [0], "displacement": [0, 1, 0]}]})
    system = build_system(graph, np.zeros((0, 2), np.int64), options=options_of(cfg).system, size=size)
    build_s = time.perf_counter() - start
    X0 = graph.X0
    top = np.flatnonzero(X0[:, 1] >= X0[:, 1].max() - 1e-9)
    bottom = np.flatnonzero(X0[:, 1] <= X0[:, 1].min() + 1e-9)
    used = np.zeros(len(X0), bool)
    used[graph.Fn.reshape(-1)] = True
    pairs = np.vstack([graph.edges, graph.bridges])
    anchors = floating_anchors(len(X0), pairs, np.r_[top, bottom], used)
    known = np.concatenate([top, bottom, anchors])
    X_known = X0[known].copy()
    X_known[: len(top), 1] += 0.5 * h
    return SimpleNamespace(V=V, graph=graph, system=system, known=known, X_known=X_known, build_s=build_s)


def bench_size(label: str, p, *, repeats: int, goal_factor_ms: float, goal_solve_ms: float, spsolve_ok: bool):
    """Record factor and solve times of both backends and scipy's spsolve for problem ``p``."""
    A, b = p.system.A, p.system.b
    backends = ["cholespy", "splu"] if have_cholespy() else ["splu"]
    solver = None
    for backend in backends:
        runs = [ReshapeSolver(A, p.known, backend=backend) for _ in range(repeats + 1)][1:]
        solver = runs[-1]
        solve = median_time(lambda s=solver: s.solve(b, p.X_known), repeats=max(repeats, 10), warmup=2)
        suffix = "" if backend == backends[0] else f"_{backend}"
        record(AREA, f"{label}_factor{suffix}", float(np.median([r.factor_ms for r in runs])), "ms",
               goal=goal_factor_ms)
        record(AREA, f"{label}_solve{suffix}", 1e3 * solve, "ms", goal=goal_solve_ms)
    solver = ReshapeSolver(A, p.known, backend=backends[0])
    free = np.setdiff1d(np.arange(A.shape[1]), known_columns(p.known))
    A_u = A.tocsc()[:, free]
    N = (A_u.T @ A_u).tocsc()
    rhs = A_u.T @ (b - A.tocsc()[:, known_columns(p.known)] @ p.X_known.ravel())
    if spsolve_ok:
        peer = median_time(lambda: spsolve(N, rhs), repeats=max(1, repeats // 2), warmup=0)
        x_ref = spsolve(N, rhs)
        x = solver.solve(b, p.X_known).ravel()[free]
        record(AREA, f"{label}_spsolve_per_solve", 1e3 * peer, "ms")
        record(AREA, f"{label}_solve_vs_spsolve", 1e3 * median_time(lambda: solver.solve(b, p.X_known), repeats=10),
               "ms", baseline=1e3 * peer)
        size = float(np.linalg.norm(np.ptp(p.V, axis=0)))
        record(AREA, f"{label}_difference_to_spsolve", float(np.abs(x - x_ref).max() / size), "share of model size")
    record(AREA, f"{label}_vars", float(solver.vars), "count")
    record(AREA, f"{label}_vertices", float(len(p.V)), "count")
    record(AREA, f"{label}_nodes", float(p.graph.n_nodes), "count")
    record(AREA, f"{label}_equations", float(A.shape[0]), "count")
    record(AREA, f"{label}_nnz_A", float(solver.nnz_A), "count")
    record(AREA, f"{label}_nnz_AtA", float(solver.nnz_AtA), "count")
    record(AREA, f"{label}_graph_and_constraints", p.build_s, "s")


def bench_real(repeats: int) -> None:
    """Table 4's columns for the real houses, widened by 30 % along x (ends as handles / fixed; the
    parts they do not hold are carried by their nearest surface)."""
    from synthkit.methods.reshape.pipeline import _known

    for name in REAL:
        path = HOUSES / name
        if not path.is_file():
            print(f"skipped {name}: not present", file=sys.stderr)
            continue
        m = load_textured(path)
        size = float(np.linalg.norm(np.ptp(m.V, axis=0)))
        graph = build_graph(m.V, m.F, m.face_material, weld_tol=1e-6 * size)
        cfg = ReshapeConfig.model_validate({"input": str(path), "contacts": {"tol": 1e-4},
                                            "handles": [{"index": [0], "displacement": [0, 1, 0]}]})
        X0 = graph.X0
        lo, hi = X0[:, 0].min(), X0[:, 0].max()
        right = np.flatnonzero(X0[:, 0] >= hi - 0.01 * (hi - lo))
        left = np.flatnonzero(X0[:, 0] <= lo + 0.01 * (hi - lo))
        system = build_system(graph, np.zeros((0, 2), np.int64), options=options_of(cfg).system, size=size,
                              known=np.r_[right, left])
        known = _known(graph, right, left)
        X_known = X0[known].copy()
        X_known[: len(right), 0] += 0.3 * (hi - lo)
        runs = [ReshapeSolver(system.A, known) for _ in range(repeats + 1)][1:]
        solver = runs[-1]
        solve = median_time(lambda s=solver, b=system.b, xk=X_known: s.solve(b, xk), repeats=10, warmup=2)
        label = Path(name).stem
        record(AREA, f"{label}_vars", float(solver.vars), "count")
        record(AREA, f"{label}_nnz_A", float(solver.nnz_A), "count")
        record(AREA, f"{label}_nnz_AtA", float(solver.nnz_AtA), "count")
        record(AREA, f"{label}_nodes", float(graph.counts["nodes"]), "count")
        record(AREA, f"{label}_edges", float(len(graph.edges)), "count")
        record(AREA, f"{label}_equations", float(system.A.shape[0]), "count")
        record(AREA, f"{label}_factor", float(np.median([r.factor_ms for r in runs])), "ms")
        record(AREA, f"{label}_solve", 1e3 * solve, "ms")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats, 25k-vertex facade instead of 100k")
    args = parser.parse_args()
    repeats = 3 if args.quick else 7
    for name, (f_ms, s_ms) in PAPER.items():
        record(AREA, f"paper_table4_{name.replace(' ', '_')}_factor", f_ms, "ms")
        record(AREA, f"paper_table4_{name.replace(' ', '_')}_solve", s_ms, "ms")
    small = problem(9, 3)  # 1308 unknowns, beside the paper's 1314
    bench_size("facade_9x3", small, repeats=repeats, goal_factor_ms=10.0, goal_solve_ms=0.5, spsolve_ok=True)
    nx, ny = (20, 18) if args.quick else (40, 35)
    large = problem(nx, ny)
    bench_size(f"facade_{nx}x{ny}", large, repeats=max(2, repeats // 2), goal_factor_ms=1500.0, goal_solve_ms=50.0,
               spsolve_ok=True)
    bench_real(repeats)
    print_table(AREA)
    print(f"wrote {write_results(AREA)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
