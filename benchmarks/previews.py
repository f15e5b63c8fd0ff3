"""Benchmark of the PNG previews' share of each bundled run (issue 16: at most 25%).

Each bundled config (``configs/*/*.yaml``) runs in a fresh process, as one ``synthkit`` command
does, twice: with ``--previews all`` (the default), timing every call into :mod:`synthkit.preview`
that renders or writes a PNG (nested calls counted once), and with ``--previews none`` as the
baseline. The figure is the rendering time over the run's ``timings.total``.

Run: ``.venv/bin/python benchmarks/previews.py [--quick]``; writes bench-results/previews.json.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks._common import print_table, record, write_results  # noqa: E402

AREA = "previews"
GOAL_SHARE = 0.25
QUICK = ("retarget/facade.yaml", "symmetry-texture/quilt.yaml")
"""The configs of ``--quick``."""


def _timed(fn, spent: list[float], depth: list[int]):
    def inner(*args, **kwargs):
        depth[0] += 1
        start = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            depth[0] -= 1
            if depth[0] == 0:
                spent[0] += time.perf_counter() - start

    return inner


def run_one(config: Path, previews: str) -> dict:
    """Run ``config`` in this process; returns its total seconds and the seconds spent drawing."""
    from synthkit import preview
    from synthkit.runner import run_config

    spent, depth = [0.0], [0]
    for name in dir(preview):
        obj = getattr(preview, name)
        if callable(obj) and not isinstance(obj, type) and (name.endswith("_png") or name == "rasterize_mesh"):
            setattr(preview, name, _timed(obj, spent, depth))
    with tempfile.TemporaryDirectory() as tmp:
        report = run_config(config, out_dir=Path(tmp) / "out", show_progress=False, previews=previews)
    return {"total": report["timings"]["total"], "rendering": spent[0]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--one", help=argparse.SUPPRESS)
    ap.add_argument("--previews", default="all", help=argparse.SUPPRESS)
    ap.add_argument("--quick", action="store_true", help=f"only {', '.join(QUICK)} (checks that it runs)")
    args = ap.parse_args()
    if args.one:
        print(json.dumps(run_one(Path(args.one), args.previews)))
        return 0
    shares = []
    configs = sorted(ROOT.glob("configs/*/*.yaml"))
    if args.quick:
        configs = [ROOT / "configs" / name for name in QUICK]
    for config in configs:
        runs = {}
        for level in ("all", "none"):
            out = subprocess.run([sys.executable, __file__, "--one", str(config), "--previews", level],
                                 capture_output=True, text=True, check=True, cwd=ROOT)
            runs[level] = json.loads(out.stdout.strip().splitlines()[-1])
        share = runs["all"]["rendering"] / runs["all"]["total"]
        shares.append(share)
        name = f"{config.parent.name}/{config.stem}"
        record(AREA, f"share_{name}", share, "1", goal=GOAL_SHARE)
        record(AREA, f"total_{name}", runs["all"]["total"], "s", baseline=runs["none"]["total"])
    record(AREA, "share_max", max(shares), "1", goal=GOAL_SHARE)
    record(AREA, "configs_over_goal", float(sum(s > GOAL_SHARE for s in shares)), "count", goal=0)
    print_table(AREA)
    print(f"wrote {write_results(AREA)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
