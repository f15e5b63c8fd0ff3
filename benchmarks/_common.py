"""Helpers shared by the benchmark scripts: timing, recording figures, writing bench-results/<area>.json.

Every figure is ``{"value", "unit", "goal", "baseline", "ratio"}``; ``ratio`` is ``value / baseline``
when a baseline or peer was measured in the same run (below 1 means faster than the baseline).
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

RESULTS_DIR = Path(os.environ.get("SYNTHKIT_BENCH_RESULTS", Path(__file__).resolve().parent.parent / "bench-results"))
"""Where :func:`write_results` writes: ``bench-results/``, or ``$SYNTHKIT_BENCH_RESULTS`` (the tests'
quick runs)."""
_FIGURES: dict[str, dict[str, dict[str, Any]]] = {}


def median_time(fn: Callable[[], Any], *, repeats: int = 5, warmup: int = 1) -> float:
    """Median wall-clock seconds of ``fn()`` over ``repeats`` calls after ``warmup`` calls."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def record(
    area: str,
    name: str,
    value: float,
    unit: str,
    *,
    goal: float | None = None,
    baseline: float | None = None,
) -> dict[str, Any]:
    """Record one figure of ``area``; returns the stored entry."""
    ratio = value / baseline if baseline not in (None, 0) else None
    entry = {"value": value, "unit": unit, "goal": goal, "baseline": baseline, "ratio": ratio}
    _FIGURES.setdefault(area, {})[name] = entry
    return entry


def print_table(area: str, file=sys.stdout) -> None:
    """Print the figures of ``area`` as an aligned table, with goal status."""
    rows = _FIGURES.get(area, {})
    print(f"\n== {area} ==", file=file)
    print(f"{'figure':48s} {'value':>12s} {'unit':6s} {'goal':>10s} {'baseline':>12s} {'ratio':>8s}", file=file)
    for name, e in rows.items():
        goal = "" if e["goal"] is None else f"{e['goal']:.4g}"
        base = "" if e["baseline"] is None else f"{e['baseline']:.4g}"
        ratio = "" if e["ratio"] is None else f"{e['ratio']:.3g}"
        print(f"{name:48s} {e['value']:12.4g} {e['unit']:6s} {goal:>10s} {base:>12s} {ratio:>8s}", file=file)


def write_results(area: str) -> Path:
    """Write ``bench-results/<area>.json`` and return its path."""
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    path = RESULTS_DIR / f"{area}.json"
    path.write_text(json.dumps(_FIGURES.get(area, {}), indent=2) + "\n")
    return path


def base_synthkit(folder: Path, commit: str):
    """Import ``synthkit`` as of ``commit`` under the name ``synthkit_base`` (its files
    from ``git archive``, the package's own imports renamed), beside today's ``synthkit``."""
    import importlib
    import re
    import subprocess

    repo = Path(__file__).resolve().parents[1]
    data = subprocess.run(["git", "-C", str(repo), "archive", commit, "synthkit"], capture_output=True, check=True)
    folder.mkdir(parents=True, exist_ok=True)
    subprocess.run(["tar", "-x", "-C", str(folder)], input=data.stdout, check=True)
    (folder / "synthkit").rename(folder / "synthkit_base")
    for f in (folder / "synthkit_base").rglob("*.py"):
        f.write_text(re.sub(r"\bsynthkit\b(?=[. ])", "synthkit_base", f.read_text()))
    sys.path.insert(0, str(folder))
    return importlib.import_module("synthkit_base.runner")
