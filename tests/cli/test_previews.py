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


def _previews(folder: Path) -> set[str]:
    """Top-level preview PNGs of an output folder, and its preview folders as ``name/``."""
    names = {p.name for p in folder.glob("*.png") if not p.name.endswith("bricks_wall.png") and "_retex" not in p.name}
    return names | {f"{p.name}/" for p in folder.iterdir() if p.is_dir() and any(p.glob("*.png"))}


def _untimed(value):
    """``value`` with every mapping entry whose key ends in ``_ms`` dropped, at any depth."""
    if isinstance(value, dict):
        return {k: _untimed(v) for k, v in value.items() if not k.endswith("_ms")}
    if isinstance(value, list):
        return [_untimed(v) for v in value]
    return value


@pytest.mark.parametrize(
    ("config", "summary", "every"),
    [
        ("petri-synth/building_ring.yaml", {"result.png"}, {"result.png", "construction_space.png", "montage.png"}),
        ("retarget/railing-analysis.yaml", {"sparsity.png"},
         {"sparsity.png", "histogram.png", "histogram_xy.png", "histogram_xz.png", "offsets.png", "before.png"}),
        ("reshape/wall.yaml", {"before_after.png"},
         {"comparison.png", "before_after.png", "before.png", "after.png", "baseline.png"}),
        ("reshape/wall-texture.yaml", {"before_after.png"},
         {"comparison.png", "before_after.png", "before.png", "after.png", "texture/"}),
    ],
)
def test_preview_levels(runner, tmp_path, config, summary, every):
    """Each level writes its previews and nothing else changes: the same files (the input's texture
    copied and the baked ``*_retex*.png`` textures are results, not previews), the same metrics but
    for the timings reshape reports among them (keys ending in ``_ms``)."""
    config = CONFIGS / config
    folders = {level: _run(runner, tmp_path, config, level) for level in ("all", "summary", "none")}
    pngs = {level: _previews(folder) for level, folder in folders.items()}
    assert pngs == {"all": every, "summary": summary, "none": set()}
    reports = {level: json.loads((folder / "report.json").read_text()) for level, folder in folders.items()}
    assert [reports[level]["previews"] for level in ("all", "summary", "none")] == ["all", "summary", "none"]
    metrics = [_untimed(reports[level]["metrics"]) for level in reports]
    assert metrics[0] == metrics[1] == metrics[2]
    results = {p.name for p in folders["all"].iterdir() if p.is_file()} - every - {"report.json", ".synthkit-output"}
    assert results == {p.name for p in folders["none"].iterdir() if p.is_file()} - {"report.json", ".synthkit-output"}
    for name in results:
        assert (folders["all"] / name).read_bytes() == (folders["none"] / name).read_bytes(), name
    for name in summary:
        assert (folders["all"] / name).read_bytes() == (folders["summary"] / name).read_bytes(), name
