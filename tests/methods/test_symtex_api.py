"""synthkit.symmetry_texture on images in memory: outputs, nothing written, the CLI's messages and bytes."""

import json

import numpy as np
import pytest
import yaml

import synthkit
import synthkit.runner  # noqa: F401 (imported before a test patches the writers it binds)
from synthkit.core import symmetry as sy
from synthkit.errors import ConfigError, InputError
from synthkit.io.images import load_image, save_image
from synthkit.runner import run_config
from synthkit.samples import textures

CALL = r"^synthkit.symmetry_texture\(\): "
SYNTH = {"patch": 16, "overlap": 6, "candidates": 4, "sweeps": 1}
COMPARISON_HEIGHT = 256 + 24  # the montage of comparison.png: images 256 px high under a title
DEFORM = {"points": 12, "levels": 1, "step": 2.0, "min_step": 1.0, "max_cycles": 1, "max_evaluations": 80}


def _u8(img):
    return np.round(np.clip(img, 0, 1) * 255).astype(np.uint8)


def test_transfer_in_memory_writes_nothing_and_lowers_e_l2(nothing_written):
    src, tgt = _u8(textures.noise(64)), _u8(textures.dots(64))
    r = synthkit.symmetry_texture(src, tgt, mode="transfer", output_size=(48, 48), baseline=True,
                                  symmetry={"signals": ["lum"]}, synth=SYNTH)
    assert r.image.shape == (48, 48, 3) and r.image.dtype == np.float32
    assert r.source.shape == (64, 64, 3) and r.baseline.shape == (48, 48, 3)
    assert r.s_input.shape == r.s_target.shape == r.s_result.shape == (2 * 23 + 1, 2 * 23 + 1)
    m = r.metrics
    assert m["objective"] == "E_L2" and m["objective_end"] < m["objective_start"]
    assert m["objective_end"] < m["baseline_objective"]
    assert m["output_size"] == [48, 48] and m["window"] == [23, 23] and m["signals"] == ["lum"]
    # the reported figures are those of the returned arrays
    T = sy.translational(sy.f_lum(_u8(textures.dots(64)).astype(np.float32) / 255), window=(23, 23))
    S = sy.translational(sy.f_lum(r.image), window=(23, 23))
    assert sy.e_l2(S, T) == pytest.approx(m["objective_end"], rel=1e-4)
    np.testing.assert_allclose(r.s_result, sy.standardize(S), atol=1e-4)
    assert set(r.timings) >= {"load", "target", "baseline", "optimize", "total"}
    assert r.status == "ok" and r.input_files == []
    assert r.comparison().shape == (COMPARISON_HEIGHT, 3 * 256 + 2 * 6, 3)


def test_same_seed_same_result_and_another_seed_differs():
    src, tgt = textures.noise(64), textures.dots(64)
    runs = [synthkit.symmetry_texture(src, tgt, mode="transfer", output_size=(48, 48), seed=s,
                                      symmetry={"signals": ["lum"]}, synth=SYNTH) for s in (3, 3, 4)]
    np.testing.assert_array_equal(runs[0].image, runs[1].image)
    assert runs[0].metrics == runs[1].metrics
    assert not np.array_equal(runs[0].image, runs[2].image)


def test_quilt_gives_no_target_no_baseline_and_no_comparison():
    r = synthkit.symmetry_texture(textures.wavy(64), mode="quilt", output_size=(40, 40),
                                  synth={"patch": 16, "overlap": 6})
    assert r.image.shape == (40, 40, 3) and r.baseline is None and r.comparison() is None
    assert r.metrics["tiles"] == 16 and r.metrics["objective_start"] == r.metrics["objective_end"]


def test_key_errors_give_the_command_lines_message():
    src = textures.noise(64)
    with pytest.raises(ConfigError, match=CALL + r"synth.patch: Input should be greater"):
        synthkit.symmetry_texture(src, mode="quilt", synth={"patch": 2})
    with pytest.raises(ConfigError, match=CALL + r".*mode 'transfer' needs 'target'"):
        synthkit.symmetry_texture(src, mode="transfer")
    with pytest.raises(ConfigError, match=r"unknown key 'synht' \(did you mean 'synth'\?\)"):
        synthkit.symmetry_texture(src, mode="quilt", synht={})
    with pytest.raises(ConfigError, match=CALL + r"synth.patch 32 is larger than the 24x24 source image source$"):
        synthkit.symmetry_texture(src[:24, :24], mode="quilt")
    with pytest.raises(ConfigError, match=CALL + r"tile.margin 0.45 leaves a 2x2 tile of the 30x30 input$"):
        synthkit.symmetry_texture(src[:30, :30], mode="tile", tile={"margin": 0.45})


def test_input_errors_name_the_key():
    with pytest.raises(InputError, match=CALL + r"source: source image is blank"):
        synthkit.symmetry_texture(np.full((16, 16), 0.5), mode="quilt", synth={"patch": 8, "overlap": 2})
    with pytest.raises(InputError, match=CALL + r"target: target image is 4x4, smaller"):
        synthkit.symmetry_texture(textures.noise(32), np.eye(4), mode="transfer")


def test_symmetrize_save_writes_the_clis_bytes(tmp_path, write_config):
    warped = textures.smooth_warp(textures.dots(64), 2.0)
    save_image(tmp_path / "w.png", warped)
    keys = dict(mode="symmetrize", symmetry={"signals": ["lum"]}, deform=DEFORM, seed=5)
    report = run_config(write_config(tmp_path, "s", source="w.png", **keys), out_dir=tmp_path / "cli",
                        show_progress=False)
    r = synthkit.symmetry_texture(load_image(tmp_path / "w.png"), **keys)
    assert r.sample_map.shape == (64, 64, 2) and r.sample_map.dtype == np.float32
    assert r.metrics["status"] in ("symmetrized", "input returned")
    assert r.metrics == report["metrics"]
    saved = r.save(tmp_path / "api")
    for name in ("result.png", "sample_map.npy", "s_input.png", "s_result.png", "comparison.png"):
        assert (tmp_path / "api" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    assert saved["outputs"] == report["outputs"] and saved["metrics"] == report["metrics"]
    assert json.loads((tmp_path / "api" / "report.json").read_text())["config_file"] is None


def test_tile_returns_every_candidate_and_the_chosen_one():
    r = synthkit.symmetry_texture(textures.bricks_shaded(64), mode="tile", tile={"cut_overlaps": [8]})
    assert set(r.tiles) == {"baseline", "input", "cut8"}
    assert r.image is r.tiles[r.metrics["tile_choice"]]
    assert r.tiles["cut8"].shape == (56, 56, 3) and r.tiles["baseline"].shape == (64, 64, 3)
    assert r.sample_map is None and len(r.comparison()) == COMPARISON_HEIGHT


def test_lens_search_is_returned(tmp_path):
    src = textures.radial_distort(textures.bricks(64), 0.2)
    r = synthkit.symmetry_texture(src, mode="symmetrize", perturbation="lens", symmetry={"signals": ["lum"]},
                                  lens={"samples": 5, "tol": 0.05})
    assert r.k1_search.ndim == 2 and r.k1_search.shape[1] == 2 and len(r.k1_search) >= 7
    best = r.k1_search[np.argmax(r.k1_search[:, 1])]
    assert r.metrics["k1_searched"] == best[0]
    assert r.comparison() is None and r.s_target is None


def test_config_file_as_yaml_keys_matches(tmp_path):
    """The keyword arguments are the config's keys: a config file's mapping may be passed as it is."""
    cfg = yaml.safe_load("mode: quilt\noutput_size: [32, 32]\nsynth: {patch: 16, overlap: 6}\n")
    r = synthkit.symmetry_texture(textures.noise(48), **cfg)
    assert r.config.output_size == (32, 32) and r.image.shape == (32, 32, 3)


def test_the_docstring_example_runs():
    import doctest

    from synthkit.methods.symtex import api

    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    for test in finder.find(api.symmetry_texture, "symmetry_texture", globs={}):
        runner.run(test)
    assert runner.summarize(verbose=False).failed == 0 and runner.summarize(verbose=False).attempted >= 4


def test_symmetrize_reports_the_ssim_of_what_it_returns():
    """ssim_to_input is skimage's SSIM of the returned image to the input: 1 when the input comes
    back; a symmetrized warped lattice is nearer (SSIM) the unwarped one than its input was."""
    from skimage.metrics import structural_similarity

    truth = textures.dots(64)
    warped = textures.smooth_warp(truth, 2.0)
    r = synthkit.symmetry_texture(warped, mode="symmetrize", symmetry={"signals": ["lum"]},
                                  deform=dict(DEFORM, max_evaluations=300, levels=2))
    ssim = structural_similarity(r.image, r.source, channel_axis=2, data_range=1.0)
    assert r.metrics["status"] == "symmetrized" and r.metrics["ssim_to_input"] == pytest.approx(ssim)
    assert ssim < 0.9
    gain = [structural_similarity(img, truth, channel_axis=2, data_range=1.0) for img in (r.image, r.source)]
    assert gain[0] > gain[1]
    refused = synthkit.symmetry_texture(truth, mode="symmetrize", symmetry={"signals": ["lum"]}, deform=DEFORM,
                                        seed=1)
    assert refused.metrics["status"] == "input returned" and refused.image is refused.source
    assert refused.metrics["ssim_to_input"] == 1.0


def test_transfer_save_writes_the_clis_bytes(tmp_path, write_config):
    save_image(tmp_path / "src.png", textures.noise(64))
    save_image(tmp_path / "tgt.png", textures.dots(64))
    keys = dict(mode="transfer", output_size=[48, 48], baseline=True, symmetry={"signals": ["lum"]}, synth=SYNTH)
    report = run_config(write_config(tmp_path, "t", source="src.png", target="tgt.png", **keys),
                        out_dir=tmp_path / "cli", show_progress=False)
    r = synthkit.symmetry_texture(load_image(tmp_path / "src.png"), load_image(tmp_path / "tgt.png"), **keys)
    # comparison() is the montage comparison.png holds, before its 8-bit rounding
    assert np.abs(r.comparison() - load_image(tmp_path / "cli" / "comparison.png")).max() <= 0.5 / 255 + 1e-6
    saved = r.save(tmp_path / "api", previews="summary")
    assert saved["outputs"] == {k: v for k, v in report["outputs"].items() if k in ("result", "baseline",
                                                                                    "comparison", "report")}
    for name in ("result.png", "baseline.png", "comparison.png"):
        assert (tmp_path / "api" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    assert saved["metrics"] == report["metrics"]


def test_a_bad_key_gives_the_same_line_as_the_command_line(tmp_path, write_config):
    from synthkit.runner import load_method_config

    save_image(tmp_path / "src.png", textures.noise(32))
    path = write_config(tmp_path, "bad", mode="quilt", source="src.png", synth={"patch": 2, "overlap": 1})
    with pytest.raises(ConfigError) as cli:
        load_method_config(path)
    with pytest.raises(ConfigError) as api:
        synthkit.symmetry_texture(textures.noise(32), mode="quilt", synth={"patch": 2, "overlap": 1})
    assert str(cli.value).removeprefix(f"{path}: ") == str(api.value).removeprefix("synthkit.symmetry_texture(): ")
    assert "synth.patch" in str(api.value)
