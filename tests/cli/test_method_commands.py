"""The real method subcommands through the CLI group: dispatch, flags, exit codes, nothing written on error."""

import json
from pathlib import Path

import numpy as np
import pytest

from synthkit.cli.main import cli
from synthkit.io.images import save_image

REPO = Path(__file__).resolve().parents[2]
CONFIGS = REPO / "configs"


def test_help_lists_implemented_methods(runner):
    result = runner.invoke(cli, ["--help"])
    assert result.exit_code == 0
    for name in ("retarget", "petri-synth", "symmetry-texture", "validate", "run"):
        assert f"  {name} " in result.output


def test_validate_every_bundled_config(runner):
    configs = sorted(str(p) for p in CONFIGS.glob("*/*.yaml"))
    result = runner.invoke(cli, ["validate", *configs])
    assert result.exit_code == 0, result.stderr
    assert result.stderr.count("ok: ") == len(configs)


def test_symmetry_texture_quilt_json(runner, tmp_path):
    out = tmp_path / "quilt"
    result = runner.invoke(
        cli, ["symmetry-texture", str(CONFIGS / "symmetry-texture" / "quilt.yaml"), "--out", str(out), "--json",
              "--seed", "4", "--no-progress"])
    assert result.exit_code == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["method"] == "symmetry-texture" and report["seed"] == 4 and report["status"] == "ok"
    assert report["config"]["mode"] == "quilt"
    assert report == json.loads((out / "report.json").read_text())
    assert result.stderr.startswith(f"symmetry-texture: wrote {out} in ")
    objective = report["metrics"]["objective_end"]
    assert f"objective_end={objective:.4g}" in result.stderr


def test_symmetry_texture_blank_image_exit_3(runner, tmp_path):
    save_image(tmp_path / "blank.png", np.full((64, 64), 0.5, dtype=np.float32))
    cfg = tmp_path / "blank.yaml"
    cfg.write_text("method: symmetry-texture\nmode: quilt\nsource: blank.png\noutput_size: [64, 64]\n"
                   "synth: {patch: 16, overlap: 6}\n")
    result = runner.invoke(cli, ["symmetry-texture", str(cfg), "--out", str(tmp_path / "o")])
    assert result.exit_code == 3
    assert "blank" in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / "o").exists()


def test_retarget_typo_exit_2_with_suggestion(runner, tmp_path):
    cfg = CONFIGS / "retarget" / "railing-analysis.yaml"
    result = runner.invoke(cli, ["retarget", str(cfg), "--set", "analysis.tua=0.1", "--out", str(tmp_path / "o")])
    assert result.exit_code == 2
    assert "unknown key 'analysis.tua' (did you mean 'analysis.tau'?)" in result.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_retarget_analyze_only_flag(runner, tmp_path):
    cfg = CONFIGS / "retarget" / "bookshelf.yaml"
    out = tmp_path / "o"
    result = runner.invoke(cli, ["retarget", str(cfg), "--analyze-only", "--out", str(out), "--json"])
    assert result.exit_code == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["config"]["analyze_only"] is True
    assert len(report["metrics"]["principal_offsets"]) == 2
    assert "graphcut" not in report["timings"]
    assert not any(name.endswith((".obj", ".npy")) for name in report["outputs"].values())


def test_petri_missing_example_exit_3(runner, tmp_path):
    text = (CONFIGS / "petri-synth" / "building_curve.yaml").read_text()
    cfg = tmp_path / "petri.yaml"
    cfg.write_text(text.replace("../../data-samples/building_modular.obj", "nowhere.obj"))
    result = runner.invoke(cli, ["petri-synth", str(cfg), "--out", str(tmp_path / "o")])
    assert result.exit_code == 3
    assert not (tmp_path / "o").exists()
    assert "Traceback" not in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert "example: file not found" in result.stderr and "nowhere.obj" in result.stderr


def test_method_subcommand_rejects_other_methods_config(runner, tmp_path):
    cfg = CONFIGS / "symmetry-texture" / "quilt.yaml"
    result = runner.invoke(cli, ["retarget", str(cfg), "--out", str(tmp_path / "o")])
    assert result.exit_code == 2
    assert "method: 'symmetry-texture' does not match the subcommand 'retarget'" in result.stderr
