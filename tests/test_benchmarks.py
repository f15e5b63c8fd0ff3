"""Every benchmark's ``--quick`` mode runs whole and writes its figures (their values are not judged
here: ``make bench`` and docs/performance.md do that)."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO, SHARED_DATA

BENCHMARKS = sorted(p.stem for p in (REPO / "benchmarks").glob("[a-z]*.py"))
NEEDS_SHARED = {"segmentation": SHARED_DATA / "psb", "reshape_texture": SHARED_DATA / "architecture" / "houses"}
"""Benchmarks that measure only shared inputs, and the folder each needs; they write no figures
without it."""
FIGURE_KEYS = {"value", "unit", "goal", "baseline", "ratio"}
QUICK_TIMEOUT_S = 600


def test_every_benchmark_is_listed():
    assert len(BENCHMARKS) == 12, BENCHMARKS


@pytest.mark.slow
@pytest.mark.parametrize("name", BENCHMARKS)
def test_quick_mode_runs_and_writes_figures(name, tmp_path):
    needs = NEEDS_SHARED.get(name)
    if needs is not None and not needs.is_dir():
        pytest.skip(f"benchmarks/{name}.py measures {needs}, absent here")
    env = {**os.environ, "SYNTHKIT_BENCH_RESULTS": str(tmp_path)}
    done = subprocess.run([sys.executable, str(REPO / "benchmarks" / f"{name}.py"), "--quick"], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=QUICK_TIMEOUT_S)
    assert done.returncode == 0, done.stderr[-2000:]
    figures = json.loads((tmp_path / f"{name}.json").read_text())
    assert figures, f"benchmarks/{name}.py --quick recorded no figure"
    for label, figure in figures.items():
        assert set(figure) == FIGURE_KEYS, label
        assert isinstance(figure["unit"], str), label
        for key in ("value", "goal", "baseline", "ratio"):
            value = figure[key]
            assert value is None or (isinstance(value, int | float) and math.isfinite(value)), (label, key, value)
        assert figure["value"] is not None, label


def test_results_folder_follows_the_environment(tmp_path):
    code = ("from benchmarks import _common as c; c.record('x', 'f', 1.5, 's', baseline=3.0); "
            "print(c.write_results('x'))")
    env = {**os.environ, "SYNTHKIT_BENCH_RESULTS": str(tmp_path / "deep" / "er")}
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, env=env, capture_output=True, text=True, check=True)
    path = Path(done.stdout.strip())
    assert path == tmp_path / "deep" / "er" / "x.json"
    assert json.loads(path.read_text()) == {"f": {"value": 1.5, "unit": "s", "goal": None, "baseline": 3.0,
                                                  "ratio": 0.5}}
