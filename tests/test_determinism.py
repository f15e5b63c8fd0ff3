"""Same config and seed give the same output bytes for every method (report.json aside: it holds timings)."""

from pathlib import Path

import pytest

from synthkit.runner import run_config

REPO = Path(__file__).resolve().parents[1]

SMALL_CONFIGS = [
    "petri-synth/building_ring.yaml",
    "retarget/sheared.yaml",
    "symmetry-texture/transfer.yaml",
    "symmetry-texture/symmetrize.yaml",
]


def _files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.name != "report.json"}


@pytest.mark.slow
@pytest.mark.parametrize("config", SMALL_CONFIGS)
def test_same_seed_same_bytes(tmp_path, config):
    path = REPO / "configs" / config
    first = run_config(path, out_dir=tmp_path / "a", seed=11, show_progress=False)
    second = run_config(path, out_dir=tmp_path / "b", seed=11, show_progress=False)
    a, b = _files(tmp_path / "a"), _files(tmp_path / "b")
    assert a.keys() == b.keys() and len(a) >= 2
    differing = [name for name in a if a[name] != b[name]]
    assert not differing, f"outputs differ between identical runs: {differing}"
    untimed = [{k: v for k, v in r["metrics"].items() if not k.endswith("seconds")} for r in (first, second)]
    assert untimed[0] == untimed[1]
