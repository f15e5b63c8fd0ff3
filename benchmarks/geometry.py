"""Benchmark of the geometry core (synthkit.core.mesh, lsq, ffd) against peers in the same run.

- Poisson-disk sampling of fandisk (normalised to [-1, 1]) at radius 0.02: ours (seeded,
  deterministic) against pymeshlab's ``generate_sampling_poisson_disk`` (not seedable).
- Sparse least squares on a 40 962-vertex sphere Laplacian with anchors: factor once + solve 3
  right-hand sides, against ``scipy.sparse.linalg.spsolve`` solving the same normal equations three
  times (no cached factorization); both backends of ours when cholespy is installed.
- Clipping a 100k-face mesh by a box, splitting it by 20 lattice planes, welding 200k vertices.
- Trilinear FFD of 10^6 points.

Run: ``.venv/bin/python benchmarks/geometry.py [--quick]``; writes bench-results/geometry.json.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import trimesh
from scipy.sparse.linalg import spsolve

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import median_time, print_table, record, write_results  # noqa: E402
from synthkit.core import mesh as M  # noqa: E402
from synthkit.core.ffd import trilinear_ffd  # noqa: E402
from synthkit.core.lsq import LeastSquares, have_cholespy  # noqa: E402

AREA = "geometry"
FANDISK = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes" / "fandisk.obj"


def bench_poisson(repeats: int) -> None:
    import pymeshlab

    if FANDISK.is_file():
        m = trimesh.load(FANDISK, force="mesh", process=False)
        name = "fandisk"
    else:
        m = trimesh.creation.icosphere(5)
        name = "icosphere5"
    V, _, _ = M.normalize_unit(m.vertices)
    F = np.asarray(m.faces)
    r = 0.02
    ours = median_time(lambda: M.poisson_disk_sample(V, F, r, seed=0), repeats=repeats, warmup=0)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=V, face_matrix=F))

    def peer():
        ms.set_current_mesh(0)
        ms.generate_sampling_poisson_disk(radius=pymeshlab.PureValue(r))

    theirs = median_time(peer, repeats=repeats, warmup=0)
    n = len(M.poisson_disk_sample(V, F, r, seed=0)[0])
    record(AREA, f"poisson_disk_{name}_r0.02", ours, "s", baseline=theirs)
    record(AREA, f"poisson_disk_{name}_r0.02_pymeshlab", theirs, "s")
    record(AREA, f"poisson_disk_{name}_r0.02_samples", float(n), "count")


def laplacian_system(level: int):
    m = trimesh.creation.icosphere(level)
    E = M.vertex_graph_edges(m.faces)
    n = len(m.vertices)
    k = np.arange(len(E))
    D = sp.coo_matrix(
        (np.r_[np.ones(len(E)), -np.ones(len(E))], (np.r_[k, k], np.r_[E[:, 0], E[:, 1]])), shape=(len(E), n)
    )
    anchors = np.arange(0, n, 97)
    S = sp.coo_matrix((np.ones(len(anchors)), (np.arange(len(anchors)), anchors)), shape=(len(anchors), n))
    return sp.vstack([D, S]).tocsr()


def bench_lsq(repeats: int) -> None:
    A = laplacian_system(6)
    B = np.random.default_rng(0).normal(size=(A.shape[0], 3))

    def factor_solve(backend):
        return lambda: LeastSquares(A, backend=backend).solve(B)

    N = (A.T @ A).tocsc()
    R = A.T @ B

    def peer():
        return [spsolve(N, R[:, j]) for j in range(3)]

    theirs = median_time(peer, repeats=max(1, repeats // 2), warmup=0)
    backends = ["splu"] + (["cholespy"] if have_cholespy() else [])
    for backend in backends:
        t = median_time(factor_solve(backend), repeats=max(1, repeats // 2), warmup=0)
        record(AREA, f"lsq_41k_unknowns_factor_plus_3_solves_{backend}", t, "s", baseline=theirs)
        solver = LeastSquares(A, backend=backend)
        record(
            AREA,
            f"lsq_41k_unknowns_one_solve_3rhs_{backend}",
            median_time(lambda s=solver: s.solve(B), repeats=repeats),
            "s",
        )
    record(AREA, "lsq_41k_unknowns_spsolve_3_times", theirs, "s")


def bench_clip_split_weld(repeats: int) -> None:
    m = trimesh.creation.icosphere(6)  # 81 920 faces
    V, F = np.asarray(m.vertices), np.asarray(m.faces)
    record(
        AREA,
        "clip_by_box_82k_faces",
        median_time(lambda: M.clip_by_box(V, F, [-0.5] * 3, [0.7] * 3), repeats=repeats),
        "s",
    )
    record(
        AREA,
        "clip_by_box_capped_82k_faces",
        median_time(lambda: M.clip_by_box(V, F, [-0.5] * 3, [0.7] * 3, cap=True), repeats=repeats),
        "s",
    )
    xs = np.linspace(-0.9, 0.9, 20)
    normals = np.tile([1.0, 0.0, 0.0], (20, 1))
    record(
        AREA,
        "split_by_20_planes_82k_faces",
        median_time(lambda: M.split_by_planes(V, F, normals, xs), repeats=repeats),
        "s",
    )
    Vd = np.concatenate([V, V + 1e-9])
    Fd = np.concatenate([F, F + len(V)])
    record(AREA, "weld_82k_duplicated_vertices", median_time(lambda: M.weld(Vd, Fd, 1e-7), repeats=repeats), "s")


def bench_ffd(repeats: int) -> None:
    P = np.random.default_rng(0).random((1_000_000, 3))
    C = np.random.default_rng(1).random((8, 3))
    record(AREA, "trilinear_ffd_1M_points", median_time(lambda: trilinear_ffd(P, C), repeats=repeats), "s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats")
    args = ap.parse_args()
    repeats = 3 if args.quick else 7
    bench_poisson(repeats)
    bench_lsq(repeats)
    bench_clip_split_weld(repeats)
    bench_ffd(repeats)
    print_table(AREA)
    print(f"wrote {write_results(AREA)}")


if __name__ == "__main__":
    main()
