"""--previews all|summary|none: which PNG previews a run renders; results and metrics stay the same."""

import json
from pathlib import Path

import pytest

from synthkit.cli.main import cli

CONFIGS = Path(__file__).resolve().parents[2] / "configs"


def _run(runner, tmp_path, config, level):
    out = tmp_path / level
    result = runner.invoke(cli, ["run", str(config), "--out-root", str(out), "--previews", level,
                                 "--no-progress"])
    assert result.exit_code == 0, result.stderr
    return out / config.stem


@pytest.mark.parametrize(
    ("config", "summary", "every"),
    [
        ("petri-synth/building_ring.yaml", {"result.png"}, {"result.png", "construction_space.png", "montage.png"}),
        ("retarget/railing-analysis.yaml", {"sparsity.png"},
         {"sparsity.png", "histogram.png", "histogram_xy.png", "histogram_xz.png", "offsets.png", "before.png"}),
        ("reshape/wall.yaml", {"comparison.png"}, {"comparison.png", "before.png", "after.png", "baseline.png"}),
    ],
)
def test_preview_levels(runner, tmp_path, config, summary, every):
    config = CONFIGS / config
    folders = {level: _run(runner, tmp_path, config, level) for level in ("all", "summary", "none")}
    pngs = {level: {p.name for p in folder.glob("*.png")} - {"bricks_wall.png"} for level, folder in folders.items()}
    assert pngs == {"all": every, "summary": summary, "none": set()}
    reports = {level: json.loads((folder / "report.json").read_text()) for level, folder in folders.items()}
    assert [reports[level]["previews"] for level in ("all", "summary", "none")] == ["all", "summary", "none"]
    timed = {"factor_ms", "solve_ms", "normal_ms"}  # reshape reports timings among its metrics (Table 4)
    metrics = [{k: v for k, v in reports[level]["metrics"].items() if k not in timed} for level in reports]
    assert metrics[0] == metrics[1] == metrics[2]
    for name in {p.name for p in folders["all"].iterdir()} - every - {"report.json", ".synthkit-output"}:
        assert (folders["all"] / name).read_bytes() == (folders["none"] / name).read_bytes(), name
    for name in summary:
        assert (folders["all"] / name).read_bytes() == (folders["summary"] / name).read_bytes(), name
