"""Benchmark of petri-synth (issue 5 goals).

1. Inference alone on 10^4 cells (a 250 x 2 x 20 construction space along an arc, the bundled
   building's constraints): the coloured Petri net's Algorithm 2 (net construction + firing until
   every token is 'deformed', no geometry) against plain AC-3 model synthesis (set domains, arc
   queue, textbook REVISE, same search) on the same constraints in the same run. Goal <= 2 s.
2. A full run (load, analysis, construction, inference, FFD assembly, evaluation, orthogonal
   baseline, PNML export, previews, report) on a > 200 000-vertex example into the issue's
   20 x 5 x 3 = 300 cells, i.e. S_X x S_Y x S_Z: 20 along the curve (from its length, 40 / unit 2),
   ``construction.size_y: 5`` across it and ``construction.size_z: 3`` along the sweep. The curve is
   drawn in the top view (``plane: xz``), so across is the example's Z (depth) and the sweep its Y
   (floors); the example is the building with 8 columns x 3 floors x 5 units deep (X, Y, Z),
   subdivided (detail 14: 209 468 vertices), so both counts occur in it. (The 5-floor, 3-deep
   building cannot be filled 5 deep: its single middle depth layer never neighbours itself, and
   propagation alone runs into a contradiction.) Goal <= 10 s.
3. The geometry core on that example: lattice split (split_by_planes) and weld.

Run: ``.venv/bin/python benchmarks/petri.py [--quick]``; writes bench-results/petri.json.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import median_time, print_table, record, write_results  # noqa: E402
from synthkit.core.mesh import weld  # noqa: E402
from synthkit.io.meshes import save_mesh  # noqa: E402
from synthkit.methods.petri import analysis, construction  # noqa: E402
from synthkit.methods.petri.net import ColouredPetriNet, ac3_solve, adjacency_violations  # noqa: E402
from synthkit.methods.petri.options import SpaceOptions  # noqa: E402
from synthkit.methods.petri.pipeline import origin_preference  # noqa: E402
from synthkit.runner import run_config  # noqa: E402
from synthkit.samples import petri as sample  # noqa: E402

AREA = "petri"
FULL_RUN_FLOORS, FULL_RUN_DEPTH = 3, 5
"""The full run's example: 3 floors (Y, the sweep: S_Z = 3) and 5 units deep (Z, across: S_Y = 5)."""


def constraints():
    V, F = sample.building()
    spec = analysis.resolve_lattice(V.min(0), V.max(0), unit=sample.UNIT)
    pieces = analysis.cut_pieces(V, F, spec)
    labels, reps = analysis.classify(analysis.feature_vectors(pieces), tolerance=0.01)
    grid = labels.reshape(tuple(spec.counts))
    return grid, analysis.adjacency_constraints(grid, len(reps), boundary=True), spec


def bench_inference(repeats: int) -> None:
    grid, cons, spec = constraints()
    t = np.linspace(0, np.pi / 2, 40)
    R = 500 / (np.pi / 2)
    pts = np.stack([R * np.sin(t), R * (1 - np.cos(t))], axis=1)
    opts = SpaceOptions(plane="xz", side="left", units=spec.unit[[0, 2, 1]], size_y=2, size_z=20, sweep_origin=0.0,
                        unit_key="lattice.unit[0], along X")
    space = construction.build_construction_space(pts, False, opts)
    assert space.shape[0] * space.shape[1] * space.shape[2] == 10_000, space.shape
    allowed = cons.allowed[[0, 2, 1]]
    origin = origin_preference(grid)
    result = {}

    def petri():
        net = ColouredPetriNet(space.shape, allowed, cons.n_labels, corners=None)
        result["restarts"] = net.infer(np.random.default_rng(1), origin_labels=origin, max_restarts=50)
        result["net"] = net

    def ac3():
        result["ac3"] = ac3_solve(
            space.shape, allowed, cons.n_labels, rng=np.random.default_rng(1), origin_labels=origin
        )

    t_petri = median_time(petri, repeats=repeats, warmup=0)
    t_ac3 = median_time(ac3, repeats=max(1, repeats // 2), warmup=0)
    net = result["net"]
    assert adjacency_violations(net.label_grid(), allowed, cons.n_labels) == 0
    assert adjacency_violations(result["ac3"], allowed, cons.n_labels) == 0
    record(AREA, "inference_10k_cells_petri_net", t_petri, "s", goal=2.0, baseline=t_ac3)
    record(AREA, "inference_10k_cells_ac3", t_ac3, "s")
    record(AREA, "inference_10k_updating_firings", float(net.fired["updating"]), "count")
    record(AREA, "inference_10k_forced_selections", float(net.fired["forced_selecting"]), "count")


def bench_full_run(detail: int) -> None:
    V, F = sample.building(floors=FULL_RUN_FLOORS, columns=8, depth=FULL_RUN_DEPTH, detail=detail)
    record(AREA, "full_run_example_vertices", float(len(V)), "count", goal=200_000)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        save_mesh(trimesh.Trimesh(V, F, process=False), tmp / "big.ply")
        arc = np.linspace(0, np.pi / 3, 12)
        R = 40 / (np.pi / 3)
        pts = np.round(np.stack([R * np.sin(arc), R * (1 - np.cos(arc))], axis=1), 6).tolist()
        (tmp / "big.yaml").write_text(
            "method: petri-synth\nseed: 1\nexample: big.ply\n"
            "lattice:\n  unit: [2.0, 3.0, 2.0]\n"
            f"construction:\n  plane: xz\n  points: {pts}\n  size_y: 5\n  size_z: 3\n"
            "output:\n  baseline: true\n"
        )
        start = time.perf_counter()
        report = run_config(tmp / "big.yaml", out_dir=tmp / "out", show_progress=False)
        total = time.perf_counter() - start
    m = report["metrics"]
    assert m["construction_shape"] == [20, 5, 3] and m["cells"] == 300 and m["adjacency_violations"] == 0, m
    record(AREA, "full_run_300_cells_200k_vertices", total, "s", goal=10.0)
    for stage, secs in report["timings"].items():
        if stage != "total":
            record(AREA, f"full_run_stage_{stage}", secs, "s")
    record(AREA, "full_run_result_vertices", float(m["result_vertices"]), "count")
    record(AREA, "full_run_crack_max", float(m["crack_max"]), "cell", goal=1e-6)
    record(
        AREA,
        "normal_histogram_D_curved",
        float(m["normal_histogram_D"]),
        "1",
        baseline=float(m["baseline_normal_histogram_D"]),
    )
    # geometry core on the same example
    spec = analysis.resolve_lattice(V.min(0), V.max(0), unit=sample.UNIT)
    t_split = median_time(lambda: analysis.cut_pieces(V, F, spec), repeats=3, warmup=0)
    record(AREA, "core_cut_pieces_200k_vertices", t_split, "s")
    Vd = np.concatenate([V, V + 1e-9])
    Fd = np.concatenate([F, F + len(V)])
    t_weld = median_time(lambda: weld(Vd, Fd, 1e-7), repeats=3, warmup=0)
    record(AREA, "core_weld_400k_vertices", t_weld, "s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats")
    args = ap.parse_args()
    bench_inference(3 if args.quick else 5)
    bench_full_run(14)
    print_table(AREA)
    print(f"wrote {write_results(AREA)}")


if __name__ == "__main__":
    main()
