"""Benchmark of ``synthkit run`` on Dask (issue 16 goals).

The bundled configs (configs/*/*.yaml) repeated to about 30 runs (each repeat a symbolic link with
its own name, so every run has its own output folder), run in the same process:

1. one after another in this process, as ``synthkit run --workers 1`` does (``run_config`` per run);
2. on a local cluster of 2 single-threaded workers, as ``synthkit run --workers 2`` does
   (``synthkit.cluster.local_cluster`` + ``run_on_dask``), cluster start and shutdown included.

Figures: the wall-clock speedup of 2 workers over 1 (goal >= 1.7x on a 2-core machine) and the
scheduling overhead per run (goal <= 50 ms): the time from submitting a run to having its result in
the client, minus the seconds the run took on its worker, averaged over the runs. Also the cluster's
start-up, and the worker time lost per run (2 x wall - sum of run seconds) / runs, which counts
start-up, imports in fresh workers and the idle tail. Before timing, one run of each method warms
this process's imports and numba cache, so that the sequential side is not charged for them.

Run: ``.venv/bin/python benchmarks/batch.py [--quick] [--runs N]``; writes bench-results/batch.json.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import print_table, record, write_results  # noqa: E402
from synthkit import batch, cluster  # noqa: E402
from synthkit.plan import Job  # noqa: E402
from synthkit.runner import RunSettings, run_config  # noqa: E402

AREA = "batch"
REPO = Path(__file__).resolve().parent.parent
QUICK = ["symmetry-texture/quilt", "symmetry-texture/symmetrize-lens", "retarget/railing-analysis",
         "petri-synth/building_ring"]


def repeated_configs(folder: Path, configs: list[Path], runs: int) -> list[Path]:
    """``runs`` symbolic links to ``configs`` in turn, named ``<stem>-<k>.yaml`` (paths inside a config
    resolve against the file it links to)."""
    links = []
    for k in range(runs):
        source = configs[k % len(configs)]
        link = folder / f"{source.stem}-{k // len(configs)}.yaml"
        link.symlink_to(source)
        links.append(link)
    return links


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the four fastest configs, one run each")
    ap.add_argument("--runs", type=int, default=None, help="number of runs (default 30, 4 with --quick)")
    args = ap.parse_args()
    if cluster.dask_missing():
        sys.exit(f"benchmarks/batch.py needs Dask distributed: pip install '{cluster.DIST_EXTRA}'")
    if args.quick:
        configs = [REPO / "configs" / f"{name}.yaml" for name in QUICK]
    else:
        configs = sorted((REPO / "configs").glob("*/*.yaml"))
    runs = args.runs or (4 if args.quick else 30)
    work = Path(tempfile.mkdtemp(prefix="synthkit-bench-batch-"))
    try:
        links = repeated_configs(work, configs, runs)
        for name in QUICK:  # warm this process: imports, numba kernels from the cache
            run_config(REPO / "configs" / f"{name}.yaml", out_dir=work / "warm" / Path(name).name,
                       show_progress=False)

        settings = RunSettings(show_progress=False)
        seq_root = work / "seq"
        start = time.perf_counter()
        seq_seconds = []
        for link in links:
            outcome = batch.execute(Job(str(link), [], out=str(seq_root / link.stem)), settings)
            assert outcome["status"] == "ok", outcome["error"]
            seq_seconds.append(outcome["seconds"])
        t_seq = time.perf_counter() - start

        from distributed import Client

        par_root = work / "par"
        start = time.perf_counter()
        local = cluster.local_cluster(2)
        client = Client(local, set_as_default=False)
        cluster.prepare_workers(client)
        t_start = time.perf_counter() - start
        outcomes: dict[int, dict] = {}
        tasks = [(Job(str(link), [], out=str(par_root / link.stem)), settings) for link in links]
        try:
            stats = cluster.run_on_dask(client, tasks, retries=0, on_done=outcomes.__setitem__)
        finally:
            client.close()
            local.close()
        t_par = time.perf_counter() - start
        assert all(o["status"] == "ok" for o in outcomes.values()), [o["error"] for o in outcomes.values()]
        par_seconds = [o["seconds"] for o in outcomes.values()]
        overheads = sorted(max(o["latency"] - o["seconds"], 0.0) for o in outcomes.values())

        record(AREA, f"runs ({len(configs)} configs repeated)", float(runs), "count")
        record(AREA, "wall, 1 worker (in process)", t_seq, "s")
        record(AREA, "wall, 2 workers (LocalCluster, start included)", t_par, "s", baseline=t_seq)
        record(AREA, "speedup, 2 workers over 1", t_seq / t_par, "x", goal=1.7)
        record(AREA, "scheduling overhead per run, mean", stats["overhead"] * 1e3, "ms", goal=50.0)
        record(AREA, "scheduling overhead per run, max", overheads[-1] * 1e3, "ms")
        record(AREA, "cluster start (2 workers)", t_start, "s")
        record(AREA, "sum of run seconds, 1 worker", sum(seq_seconds), "s")
        record(AREA, "sum of run seconds, 2 workers", sum(par_seconds), "s", baseline=sum(seq_seconds))
        lost = (2 * t_par - sum(par_seconds)) / runs
        record(AREA, "worker time lost per run (start, idle tail)", lost * 1e3, "ms")
        print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} "
              "(shared: timings are noisy; both sides ran in this process, one after the other)")
        print_table(AREA)
        print(f"wrote {write_results(AREA)}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
