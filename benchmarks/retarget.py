"""Retargeting benchmark: whole pipeline on a 20k-triangle sample and graph-cut time per sample,
with offset statistics against the regular-offset baseline (spacing 0.1) in the same run.

    .venv/bin/python benchmarks/retarget.py [--quick]

Figures (bench-results/retarget.json): ``pipeline_facade_large_s`` (goal 5 s, issue 22; baseline =
the same pipeline with ``offsets: regular``) and ``pipeline_facade_large_cpu_s`` (the same runs'
CPU seconds: on a shared machine the wall time grows with the load, the CPU time much less),
``graphcut_<sample>_s`` (goal 0.2 s; baseline = the regular grid's cut on the same model and
target), and the graph sizes (nodes, labels) of both.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import print_table, record, write_results  # noqa: E402

from synthkit.core import graphcut  # noqa: E402
from synthkit.runner import run_config  # noqa: E402
from synthkit.samples import retarget as samples  # noqa: E402

AREA = "retarget"
TARGETS = {
    "facade_large": {"axis_steps": {"x": 1}},
    "bookshelf": {"axis_steps": {"y": 2}},
    "facade": {"axis_steps": {"x": 2, "y": -1}},
    "railing": {"steps": [3]},
    "sheared_grid": {"steps": [1, 1]},
    "bridge": {"steps": [2]},
    "stairs": {"steps": [2]},
}


def _run(tmp: Path, name: str, offsets: str) -> tuple[dict, float, float]:
    suffix = samples.SAMPLES[name][1]
    cfg = tmp / f"{name}-{offsets}.yaml"
    cfg.write_text(
        json.dumps(
            {
                "method": "retarget",
                "input": str(tmp / f"retarget-{name}{suffix}"),
                "target": TARGETS[name],
                "offsets": offsets,
            }
        )
    )
    start, cpu = time.perf_counter(), time.process_time()
    report = run_config(cfg, out_dir=tmp / f"out-{name}-{offsets}", overwrite=True, show_progress=False)
    return report, time.perf_counter() - start, time.process_time() - cpu


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one run per figure, fewer samples")
    args = parser.parse_args()
    repeats = 1 if args.quick else 3
    graphcut.compile_kernels()  # timed runs load compiled kernels, as every run after the first does
    names = ["bookshelf", "railing"] if args.quick else [n for n in TARGETS if n != "facade_large"]
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        samples.generate(tmp)
        stat_runs = [_run(tmp, "facade_large", "statistics") for _ in range(repeats)]
        reg_runs = [_run(tmp, "facade_large", "regular") for _ in range(repeats)]
        stat_s = statistics.median(t for _, t, _ in stat_runs)
        reg_s = statistics.median(t for _, t, _ in reg_runs)
        rep, reg = stat_runs[0][0], reg_runs[0][0]
        record(AREA, "pipeline_facade_large_s", stat_s, "s", goal=5.0, baseline=reg_s)
        record(AREA, "pipeline_facade_large_cpu_s", statistics.median(c for _, _, c in stat_runs), "s", goal=5.0,
               baseline=statistics.median(c for _, _, c in reg_runs))
        record(AREA, "facade_large_faces", rep["metrics"]["output_faces"], "faces")
        for key in ("graph_nodes", "graph_labels"):
            record(AREA, f"facade_large_{key}", rep["metrics"][key], "count", baseline=reg["metrics"][key])
        record(
            AREA,
            "graphcut_facade_large_s",
            rep["timings"]["graphcut"],
            "s",
            goal=0.2,
            baseline=reg["timings"]["graphcut"],
        )
        for name in names:
            rep = _run(tmp, name, "statistics")[0]
            reg = _run(tmp, name, "regular")[0]
            if reg["metrics"]["infinite_terms"]:
                print(
                    f"{name}: regular baseline joins empty to non-empty voxels on "
                    f"{reg['metrics']['infinite_terms']} edges",
                    file=sys.stderr,
                )
            record(
                AREA,
                f"{name}_infinite_seams",
                rep["metrics"]["infinite_terms"],
                "count",
                baseline=reg["metrics"]["infinite_terms"],
            )
            cut = statistics.median(
                [rep["timings"]["graphcut"]]
                + [_run(tmp, name, "statistics")[0]["timings"]["graphcut"] for _ in range(repeats - 1)]
            )
            record(AREA, f"graphcut_{name}_s", cut, "s", goal=0.2, baseline=reg["timings"]["graphcut"])
            record(
                AREA,
                f"{name}_graph_nodes",
                rep["metrics"]["graph_nodes"],
                "count",
                baseline=reg["metrics"]["graph_nodes"],
            )
            record(
                AREA,
                f"{name}_graph_labels",
                rep["metrics"]["graph_labels"],
                "count",
                baseline=reg["metrics"]["graph_labels"],
            )
    print_table(AREA)
    print(f"wrote {write_results(AREA)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
