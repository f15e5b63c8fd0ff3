"""symmetry-texture end to end on small generated inputs with known answers."""

import json
from pathlib import Path

import numpy as np
import pytest

from synthkit.core import symmetry as sy
from synthkit.errors import ConfigError, InputError
from synthkit.io.images import load_image, save_image
from synthkit.methods.symtex import deform, lens, synth, tile
from synthkit.runner import run_config
from synthkit.samples import textures

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def inputs(tmp_path):
    save_image(tmp_path / "noise.png", textures.noise(96))
    save_image(tmp_path / "dots.png", textures.dots(96))
    save_image(tmp_path / "wavy.png", textures.wavy())
    return tmp_path


def period_y(img: np.ndarray, w: int = 63) -> int:
    """Dominant vertical period: strongest local maximum of S_T along dx = 0 beyond the central lobe."""
    S = sy.translational(sy.f_lum(img), window=(w, 2))
    prof = S[w + 3 :, 2]
    peaks = [i for i in range(1, len(prof) - 1) if prof[i] >= prof[i - 1] and prof[i] >= prof[i + 1]]
    return max(peaks, key=lambda i: prof[i]) + 3


TRANSFER = dict(
    mode="transfer",
    source="noise.png",
    target="dots.png",
    output_size=[96, 96],
    symmetry={"window": 0.25},
    synth={"patch": 16, "overlap": 6, "candidates": 12, "sweeps": 3},
    baseline=True,
)


@pytest.mark.slow
def test_transfer_dot_lattice_period_and_beats_unguided(inputs, write_config):
    report = run_config(write_config(inputs, "t", **TRANSFER), out_dir=inputs / "out", show_progress=False)
    m = report["metrics"]
    out = load_image(inputs / "out" / "result.png")
    dy, dx = sy.strongest_peak(sy.translational(sy.f_lum(out), window=(24, 24)))
    assert min(np.hypot(abs(dy) - 16, dx), np.hypot(dy, abs(dx) - 16)) <= 1.0
    assert m["objective_end"] < m["baseline_objective"]
    assert m["objective_end"] < m["objective_start"]
    assert m["iterations"] > 0
    for key in ("result", "s_input", "s_target", "s_result", "baseline"):
        assert key in report["outputs"]
    # the recorded baseline is what plain quilting with the same seed produces
    quilt = dict(TRANSFER, mode="quilt")
    quilt.pop("target")
    run_config(write_config(inputs, "q", **quilt), out_dir=inputs / "outq", show_progress=False)
    np.testing.assert_array_equal(
        load_image(inputs / "outq" / "result.png"), load_image(inputs / "out" / "baseline.png")
    )


def test_determinism_same_seed_same_bytes(inputs, write_config):
    cfg = dict(TRANSFER, output_size=[64, 64], synth={"patch": 16, "overlap": 6, "candidates": 4, "sweeps": 1})
    path = write_config(inputs, "d", **cfg)
    run_config(path, out_dir=inputs / "a", show_progress=False)
    run_config(path, out_dir=inputs / "b", show_progress=False)
    run_config(path, out_dir=inputs / "c", seed=7, show_progress=False)
    a = (inputs / "a" / "result.png").read_bytes()
    assert a == (inputs / "b" / "result.png").read_bytes()
    assert a != (inputs / "c" / "result.png").read_bytes()


@pytest.mark.parametrize("window", [0.25, 0.5])  # 0.5: every displacement, the spectral evaluation
def test_incremental_and_full_evaluation_agree(inputs, window, write_config):
    cfg = dict(
        TRANSFER,
        output_size=[64, 64],
        symmetry={"window": window},
        synth={"patch": 16, "overlap": 6, "candidates": 4, "sweeps": 1},
    )
    run_config(write_config(inputs, "i", **cfg), out_dir=inputs / "i", show_progress=False)
    cfg["synth"] = dict(cfg["synth"], evaluation="full")
    run_config(write_config(inputs, "f", **cfg), out_dir=inputs / "f", show_progress=False)
    np.testing.assert_array_equal(load_image(inputs / "i" / "result.png"), load_image(inputs / "f" / "result.png"))


@pytest.mark.parametrize("window", [(12, 12), (31, 31)])  # grown grid; whole torus (spectral)
def test_guided_walk_threads_and_full_evaluation_agree(window):
    """One or two threads give the same walk; its objective history equals the full recompute's."""
    src = textures.noise(48)
    T = [sy.translational(sy.f_lum(textures.dots(64)), window=window)]
    runs = []
    for evaluation, workers in (("incremental", 1), ("incremental", 2), ("full", 1)):
        init = synth.random_init(src, (64, 64), patch=16, overlap=6, rng=np.random.default_rng(3))
        runs.append(
            synth.guided_walk(
                src,
                init,
                signals=["lum", "1-lum"],
                targets=T * 2,
                window=window,
                patch=16,
                candidates=5,
                sweeps=2,
                evaluation=evaluation,
                workers=workers,
            )
        )
    assert runs[0].image.tobytes() == runs[1].image.tobytes()
    assert runs[0].history == runs[1].history
    np.testing.assert_array_equal(runs[0].image, runs[2].image)
    np.testing.assert_allclose(runs[0].history, runs[2].history, rtol=1e-6)
    assert runs[0].changed > 0
    # every output pixel is the source pixel the walk's per-pixel source map names
    sources = runs[0].sources
    np.testing.assert_array_equal(runs[0].image, src[sources[..., 0], sources[..., 1]])
    assert synth.seam_visibility(src, np.stack(np.mgrid[0:48, 0:48], axis=2)) == pytest.approx(
        tile.seam_ratio(src)
    )


@pytest.mark.slow
def test_filter_scale_doubles_period(inputs, write_config):
    cfg = dict(
        mode="filter",
        source="wavy.png",
        output_size=[128, 128],
        symmetry={"window": 0.5},
        filter={"kind": "scale", "factor": 2.0},
        synth={"patch": 16, "overlap": 6, "candidates": 16, "sweeps": 3},
    )
    run_config(write_config(inputs, "s", **cfg), out_dir=inputs / "out", show_progress=False)
    p_in = period_y(load_image(inputs / "wavy.png"))
    p_out = period_y(load_image(inputs / "out" / "result.png"))
    assert p_in == 24
    assert abs(p_out - 2 * p_in) <= 0.1 * 2 * p_in


def test_lens_recovers_k1(tmp_path, write_config):
    save_image(tmp_path / "b.png", textures.radial_distort(textures.bricks(160), 0.25))
    cfg = dict(mode="symmetrize", perturbation="lens", source="b.png", lens={"samples": 21}, symmetry={"window": 0.25})
    report = run_config(write_config(tmp_path, "l", **cfg), out_dir=tmp_path / "out", show_progress=False)
    m = report["metrics"]
    assert m["k1"] == pytest.approx(0.25, rel=0.1)
    assert m["objective_end"] > m["objective_start"]


def test_undistort_inverts_distort():
    img = textures.bricks(96)
    back = lens.undistort(lens.distort(img, 0.2), 0.2)
    assert np.abs(back[20:76, 20:76] - img[20:76, 20:76]).mean() < 0.03


@pytest.mark.slow
def test_symmetrize_lattice_moves_toward_unwarped(tmp_path, symmetrized_toward):
    lattice = textures.dots(96)
    symmetrized_toward(tmp_path, lattice, textures.smooth_warp(lattice, 3.0))


TILE = dict(
    mode="tile",
    source="c.png",
    symmetry={"signals": ["lum", "1-lum"], "window": 0.5},
    tile={"optimize": True},
    deform={"points": 16, "levels": 2, "step": 4.0, "max_cycles": 1, "max_evaluations": 200},
)


@pytest.fixture(scope="module")
def tile_run(tmp_path_factory, write_config):
    tmp_path = tmp_path_factory.mktemp("tile")
    save_image(tmp_path / "c.png", textures.wavy(160)[13:109, 7:103])  # not tileable as cut
    report = run_config(write_config(tmp_path, "t", **TILE), out_dir=tmp_path / "out", show_progress=False)
    return tmp_path, report


@pytest.mark.slow
def test_tile_is_seamless(tile_run, seam_steps):
    tmp_path, report = tile_run
    out = load_image(tmp_path / "out" / "result.png")
    seam, interior = seam_steps(out)
    naive, _ = seam_steps(load_image(tmp_path / "c.png"))
    assert seam <= 1.5 * interior
    assert seam < naive
    # a genuine period (H, W): no repeated row or column at the seam (the old blend copied the
    # first column onto the last, a zero step that repeats one column at every tile boundary)
    lum = sy.f_lum(out)
    assert np.abs(lum[:, 0] - lum[:, -1]).mean() > 0.1 * np.sqrt(interior)
    assert np.abs(lum[0] - lum[-1]).mean() > 0.1 * np.sqrt(interior)
    # the discontinuity is not merely moved off the seam: the 3 steps either side of it are no
    # rougher than the same band around interior lines of the tile (content makes that band's
    # energy vary from line to line: a row of dots inside it or not)

    m = report["metrics"]
    H, W = out.shape[:2]
    band = tile.seam_ratio(out, width=3)
    inner = [
        tile.seam_ratio(np.roll(out, (dy, dx), (0, 1)), width=3)
        for dy in range(8, H - 7, 4)
        for dx in range(8, W - 7, 4)
    ]
    assert band <= max(inner)
    assert m["seam_band_ratio"] == pytest.approx(band, rel=0.05)
    assert m["seam_ratio"] == pytest.approx(seam / interior, rel=0.05)  # metric before 8-bit rounding
    assert m["seam_ratio_input"] > 1.5
    assert "tiled" in report["outputs"]
    tiled = load_image(tmp_path / "out" / report["outputs"]["tiled"])
    assert tiled.shape[:2] == (3 * out.shape[0], 3 * out.shape[1])
    np.testing.assert_array_equal(tiled[: out.shape[0], : out.shape[1]], out)


@pytest.mark.slow
def test_tile_optimization_raises_e_symm(tile_run):
    """E_symm of the tile beats its zoomed start, before and after the blend (a no-op ARAP would not)."""
    _, report = tile_run
    m = report["metrics"]
    assert m["objective_warped"] > m["objective_start"]
    assert m["objective_end"] > m["objective_start"]
    assert m["objective_history"][-1] > m["objective_history"][0]


def test_bad_inputs(tmp_path, inputs, write_config):
    save_image(tmp_path / "blank.png", np.full((32, 32, 3), 0.5, np.float32))
    save_image(tmp_path / "tiny.png", textures.dots(96)[:4, :4])
    base = dict(TRANSFER, output_size=[64, 64])
    with pytest.raises(InputError, match="blank"):
        run_config(write_config(tmp_path, "b1", **dict(base, source="blank.png")), out_dir=tmp_path / "o1")
    with pytest.raises(InputError, match="blank"):
        run_config(write_config(tmp_path, "b2", **dict(base, target="blank.png")), out_dir=tmp_path / "o2")
    with pytest.raises(InputError, match="smaller than 8x8"):
        run_config(write_config(tmp_path, "b3", **dict(base, target="tiny.png")), out_dir=tmp_path / "o3")
    with pytest.raises(InputError, match="file not found"):
        run_config(write_config(tmp_path, "b4", **dict(base, target="missing.png")), out_dir=tmp_path / "o4")
    with pytest.raises(ConfigError, match="needs 'target'"):
        cfg = dict(base)
        cfg.pop("target")
        run_config(write_config(tmp_path, "b5", **cfg), out_dir=tmp_path / "o5")
    with pytest.raises(ConfigError, match="larger than the 96x96 source"):
        run_config(
            write_config(tmp_path, "b6", **dict(base, synth={"patch": 128, "overlap": 12})), out_dir=tmp_path / "o6"
        )
    with pytest.raises(ConfigError, match="smaller than one patch"):
        run_config(write_config(tmp_path, "b7", **dict(base, output_size=[12, 64])), out_dir=tmp_path / "o7")
    with pytest.raises(ConfigError, match="unknown key"):
        run_config(write_config(tmp_path, "b8", **dict(base, synth={"patchsize": 8})), out_dir=tmp_path / "o8")
    for k in range(1, 9):
        assert not (tmp_path / f"o{k}").exists()


@pytest.mark.parametrize(
    "name", ["transfer", "transfer-sketch", "filter", "quilt", "symmetrize", "symmetrize-lens", "tile"]
)
def test_bundled_configs_validate(name):
    from synthkit.runner import load_method_config

    path = REPO / "configs" / "symmetry-texture" / f"{name}.yaml"
    if not (REPO / "data-samples" / "textures" / "noise.png").exists():
        pytest.skip("data-samples not generated")
    method, cfg, _ = load_method_config(path)
    assert method == "symmetry-texture"
    assert json.loads(cfg.model_dump_json())["mode"] in {"transfer", "filter", "quilt", "symmetrize", "tile"}


FIG14 = {
    "fig1-3 transfer synth": dict(mode="transfer", target="dots.png", symmetry={"signals": ["lum"]}),
    "fig4 S_R transfer deform": dict(
        mode="transfer", target="dots.png", perturbation="deform", symmetry={"kind": "rotational", "signals": ["1-lum"]}
    ),
    "fig5 filter deform": dict(mode="filter", perturbation="deform", filter={"kind": "blur", "sigma": 2.0}),
    "fig6 filter synth": dict(mode="filter", filter={"kind": "contrast", "amount": 2.0}),
    "fig8 lens": dict(mode="symmetrize", perturbation="lens"),
    "fig9a S_Ref edge": dict(mode="symmetrize", symmetry={"kind": "reflective", "signals": ["edge"]}),
    "fig9b S_R edge": dict(mode="symmetrize", symmetry={"kind": "rotational", "signals": ["edge"]}),
    "fig9c S_T edge": dict(mode="symmetrize", symmetry={"kind": "translational", "signals": ["edge"]}),
    "fig10 transfer deform": dict(mode="transfer", target="dots.png", perturbation="deform"),
    "fig7 tile": dict(mode="tile", symmetry={"signals": ["lum", "1-lum"]}, tile={"optimize": True}),
    "graph-cut seams": dict(
        mode="transfer",
        target="dots.png",
        synth={"patch": 12, "overlap": 4, "candidates": 4, "sweeps": 1, "seams": "graphcut"},
    ),
}

SMALL_DEFORM = {"points": 12, "levels": 1, "step": 3.0, "max_cycles": 1, "max_evaluations": 40}


@pytest.mark.parametrize("name", sorted(FIG14))
def test_fig14_combinations_run(tmp_path, name, write_config):
    save_image(tmp_path / "src.png", textures.dots(48, period=12)[:, :, :] * 0.9 + 0.05)
    save_image(tmp_path / "dots.png", textures.dots(48, period=16))
    cfg = dict(source="src.png", deform=SMALL_DEFORM, synth={"patch": 12, "overlap": 4, "candidates": 4, "sweeps": 1})
    cfg.update(FIG14[name])
    cfg.setdefault("symmetry", {})
    cfg["symmetry"] = dict(cfg["symmetry"], n_angles=90)
    report = run_config(write_config(tmp_path, "c", **cfg), out_dir=tmp_path / "out", show_progress=False)
    m = report["metrics"]
    if m["objective"] == "E_L2":
        assert m["objective_end"] <= m["objective_start"] + 1e-9
    else:
        assert m["objective_end"] >= m["objective_start"] - 1e-12
    assert m["iterations"] >= 1
    assert {"result", "s_input", "s_result"} <= set(report["outputs"])


def test_deform_determinism(tmp_path, write_config):
    save_image(tmp_path / "w.png", textures.smooth_warp(textures.dots(48, period=12), 2.0))
    cfg = dict(mode="symmetrize", source="w.png", deform=SMALL_DEFORM)
    path = write_config(tmp_path, "s", **cfg)
    run_config(path, out_dir=tmp_path / "a", show_progress=False)
    run_config(path, out_dir=tmp_path / "b", show_progress=False)
    assert (tmp_path / "a" / "result.png").read_bytes() == (tmp_path / "b" / "result.png").read_bytes()


def test_search_k1_finds_maximum_of_known_function():
    best, history = lens.search_k1(lambda k: -((k - 0.137) ** 2), k1_min=-0.5, k1_max=0.5, samples=11, tol=1e-5)
    assert best == pytest.approx(0.137, abs=1e-4)
    assert len(history) > 11


@pytest.mark.parametrize("shape", [(48, 40), (33, 50)])
def test_toroidal_blend_makes_wrap_steps_interior_like(shape):

    H, W = shape
    img = textures.wavy(96)[5 : 5 + H, 11 : 11 + W]
    out = tile.toroidal_blend(img).astype(np.float64)
    # each wrap-around step equals the central estimate from its two neighbouring interior steps
    # (exact up to float32 rounding: no clipping happens on this input), corners included
    assert 0.0 < out.min() and out.max() < 1.0
    np.testing.assert_allclose(
        out[:, 0] - out[:, -1], 0.5 * (out[:, -1] - out[:, -2] + out[:, 1] - out[:, 0]), atol=2e-6
    )
    np.testing.assert_allclose(out[0] - out[-1], 0.5 * (out[-1] - out[-2] + out[1] - out[0]), atol=2e-6)
    # and is not the zero step of copying one border onto the other
    assert np.abs(out[:, 0] - out[:, -1]).mean() > 1e-3
    assert tile.seam_ratio(out) <= 1.5 < tile.seam_ratio(img)
    assert tile.seam_ratio(out, width=3) <= 1.5
    # the correction fades towards the centre: the middle changes far less than the borders
    c = np.abs(out - img)
    assert c[H // 2 - 4 : H // 2 + 4, W // 2 - 4 : W // 2 + 4].mean() < 0.5 * c[:, 0].mean()


def test_toroidal_blend_band_evaluation_matches_exact_mvc():
    """The banded / coarse-grid spread of the border correction is the exact MVC interpolant to within 1/255."""
    from synthkit.core.warp import mean_value_coordinates

    img = textures.wavy(96)[3:67, 9:73]
    H, W = img.shape[:2]
    poly = tile._border_polygon(H, W, 1)
    c = np.random.default_rng(0).standard_normal((len(poly), 1)) * 0.05
    yy, xx = np.mgrid[0:H, 0:W]
    exact = (mean_value_coordinates(np.stack([xx.ravel(), yy.ravel()], 1).astype(float), poly) @ c).reshape(H, W, 1)
    fast = tile._spread(c, (H, W), poly, band=8, step=4)
    assert np.abs(fast - exact).max() < 1.0 / 255


def test_control_points_count_spacing_and_determinism():

    img = textures.dots(96)
    a = deform.control_points(img, 40, np.random.default_rng(3))
    b = deform.control_points(img, 40, np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
    assert len(a) == 40
    d = np.hypot(*(a[:, None] - a[None]).transpose(2, 0, 1))
    np.fill_diagonal(d, np.inf)
    assert d.min() >= np.sqrt(96 * 96 / 40) / 2 - 1e-6
    order = deform.farthest_order(a)
    assert sorted(order.tolist()) == list(range(40))


def test_control_points_shortfall_warns_and_is_recorded(tmp_path, caplog, write_config):

    img = textures.dots(24)
    with caplog.at_level("WARNING", logger="synthkit"):
        pts = deform.control_points(img, 200, np.random.default_rng(0))
    assert len(pts) < 200
    assert any("control points" in r.message and "200" in r.message for r in caplog.records)
    save_image(tmp_path / "s.png", textures.dots(32, period=8))
    cfg = dict(mode="symmetrize", source="s.png", deform=dict(SMALL_DEFORM, points=400))
    report = run_config(write_config(tmp_path, "p", **cfg), out_dir=tmp_path / "out", show_progress=False)
    m = report["metrics"]
    assert m["control_points_requested"] == 400
    assert 0 < m["control_points"] < 400


def test_zero_padded_st_rejected_for_synth(tmp_path, inputs, write_config):
    cfg = dict(TRANSFER, symmetry={"window": 0.25, "mode": "zero"})
    with pytest.raises(ConfigError, match="symmetry.mode 'zero' applies to perturbation 'deform' or 'lens'"):
        run_config(write_config(inputs, "z", **cfg), out_dir=tmp_path / "oz")
    assert not (tmp_path / "oz").exists()
    for mode in ("quilt", "filter"):
        bad = dict(cfg, mode=mode)
        bad.pop("target")
        with pytest.raises(ConfigError, match="symmetry.mode 'zero'"):
            run_config(write_config(inputs, "z2", **bad), out_dir=tmp_path / "oz2")
    # deform with zero padding stays valid
    from synthkit.runner import load_method_config

    ok = dict(mode="symmetrize", source="noise.png", symmetry={"mode": "zero"})
    load_method_config(write_config(inputs, "z3", **ok))


def test_choose_tile_rule():
    """Of the candidates meeting every goal (seam ratio at most the baseline's and the input's,
    E_symm >= the input's with 0.1% slack, sharpness >= 0.9) the lowest seam ratio; when none
    does, the lowest of the baseline, the input and the made tiles that keep E_symm and
    sharpness; ties to optimized, the cut tiles by overlap, baseline, input."""
    from synthkit.methods.symtex.tile import choose_tile

    def cand(seam, obj=1.0, sharp=1.0):
        return {"seam_ratio": seam, "objective": obj, "sharpness": sharp}

    base = {"baseline": cand(0.4, obj=0.5), "input": cand(5.0)}
    assert choose_tile({"optimized": cand(0.2), **base}, 1.0) == "optimized"
    assert choose_tile({"optimized": cand(0.2, obj=0.9995), **base}, 1.0) == "optimized"
    assert choose_tile({"optimized": cand(0.2, obj=0.99), **base}, 1.0) == "baseline"
    assert choose_tile({"optimized": cand(0.2, sharp=0.89), **base}, 1.0) == "baseline"
    assert choose_tile({"optimized": cand(0.4), **base}, 1.0) == "optimized"
    assert choose_tile({"optimized": cand(0.2), "baseline": cand(0.4), "input": cand(0.1)}, 1.0) == "input"
    assert choose_tile({"optimized": cand(0.2), "baseline": cand(0.1), "input": cand(0.1)}, 1.0) == "baseline"
    # the cut tile: a baseline that lowers E_symm gives way to a cut tile that meets every goal,
    # even one whose seam ratio is above the baseline's among the rest
    assert choose_tile({"optimized": cand(0.5), "cut16": cand(0.3), **base}, 1.0) == "cut16"
    assert choose_tile({"optimized": cand(0.2), "cut16": cand(0.2), **base}, 1.0) == "optimized"
    assert choose_tile({"optimized": cand(0.5), "cut16": cand(0.45), **base}, 1.0) == "baseline"
    assert choose_tile({"optimized": cand(0.5), "cut16": cand(0.3, obj=0.9), **base}, 1.0) == "baseline"
    assert choose_tile({"optimized": cand(0.1, obj=0.9), "cut16": cand(0.3), **base}, 1.0) == "cut16"
    cuts = {"cut8": cand(0.3), "cut16": cand(0.2, obj=0.9), "cut24": cand(0.3)}
    assert choose_tile({"optimized": cand(0.5), **cuts, **base}, 1.0) == "cut8"  # tie: the smaller overlap


def test_tile_crop_and_high_frequency_energy():
    from synthkit.methods.symtex.tile import high_frequency_energy, tile_crop

    assert tile_crop((256, 221), 0.2) == ((154, 133), (51, 44))
    assert tile_crop((10, 10), 0.0) == ((10, 10), (0, 0))
    with pytest.raises(ValueError, match="margin"):
        tile_crop((8, 8), 0.45)
    assert high_frequency_energy(np.full((16, 16), 0.3)) == pytest.approx(0.0)
    noise = textures.noise(64)
    import cv2

    blurred = cv2.GaussianBlur(noise, (0, 0), 1.5)
    assert high_frequency_energy(blurred) < 0.5 * high_frequency_energy(noise)


def test_signals_auto_picks_inverted_luminance_for_line_art(tmp_path, write_config):
    """signals: auto (the default): dark lines on white -> 1-lum for E_symm (its raw S varies
    40x more on this grid), lum for E_L2 (standardized S of lum and 1-lum are the same)."""
    from synthkit.methods.symtex.config import SymtexConfig
    from synthkit.methods.symtex.pipeline import resolve_auto_signals

    art = np.ones((48, 48, 3), dtype=np.float32)
    art[::12] = 0.1
    art[:, ::12] = 0.1
    cfg = SymtexConfig(mode="symmetrize", source=__file__)
    assert cfg.symmetry.signals == "auto"
    metrics = {}
    resolved = resolve_auto_signals(cfg, art, metrics)
    assert resolved.symmetry.signals == ["1-lum"]
    assert metrics["signal_variances"]["1-lum"] > 10 * metrics["signal_variances"]["lum"]
    assert cfg.symmetry.signals == "auto"  # the config itself is not changed
    transfer = SymtexConfig(mode="filter", source=__file__)
    assert resolve_auto_signals(transfer, art, {}).symmetry.signals == ["lum"]
    with pytest.raises(ValueError, match="signals"):
        SymtexConfig(mode="symmetrize", source=__file__, symmetry={"signals": "automatic"})


def test_tile_upsample_zoom_keeps_input_size(tmp_path, write_config):
    save_image(tmp_path / "c.png", textures.wavy(160)[13:77, 7:71])
    quick = {"points": 8, "levels": 1, "max_cycles": 1, "max_evaluations": 20}
    cfg = dict(TILE, tile={"zoom": "upsample", "optimize": True}, deform=quick)
    report = run_config(write_config(tmp_path, "t", **cfg), out_dir=tmp_path / "out", show_progress=False)
    m = report["metrics"]
    assert m["tile_candidates"]["optimized"]["size"] == [64, 64]
    crop = dict(cfg, tile={"zoom": "crop", "optimize": True})
    m2 = run_config(write_config(tmp_path, "c", **crop), out_dir=tmp_path / "out2", show_progress=False)["metrics"]
    assert m2["tile_candidates"]["optimized"]["size"] == [38, 38]
    assert m2["max_stretch"] <= 1.1 and m2["max_stretch_bound"] == 1.1


def test_tile_default_skips_the_optimization(tmp_path, write_config):
    """Issue 24: without ``tile.optimize`` no ARAP runs (no mesh or optimize stage, no optimized
    candidate); result.png is the chosen one of the blend, the cut tiles and the input."""
    save_image(tmp_path / "c.png", textures.wavy(160)[13:109, 7:103])
    cfg = dict(TILE, tile={"cut_overlaps": [8, 16]})
    report = run_config(write_config(tmp_path, "t", **cfg), out_dir=tmp_path / "out", show_progress=False)
    m = report["metrics"]
    assert m["tile_optimized"] is False and m["iterations"] == 0
    assert set(m["tile_candidates"]) == {"baseline", "input", "cut8", "cut16"}
    assert "optimize" not in report["timings"] and "mesh" not in report["timings"]
    assert not (tmp_path / "out" / "optimized.png").exists()
    choice = m["tile_choice"]
    assert m["seam_ratio"] == m["tile_candidates"][choice]["seam_ratio"]
    assert m["seam_ratio"] <= min(m["baseline_seam_ratio"], m["seam_ratio_input"])
    out = load_image(tmp_path / "out" / "result.png")
    file = tmp_path / ("c.png" if choice == "input" else f"out/{choice}.png")
    np.testing.assert_array_equal(out, load_image(file))


def test_symmetry_crop_auto_is_periods_for_symmetrize_by_deform_only():
    from synthkit.methods.symtex.config import SymtexConfig

    def crop(**kw):
        return SymtexConfig(source=__file__, **kw).period_crop()

    assert crop(mode="symmetrize")
    assert not crop(mode="symmetrize", perturbation="lens")
    assert not crop(mode="symmetrize", symmetry={"mode": "overlap"})
    assert not crop(mode="tile") and not crop(mode="filter")
    assert crop(mode="filter", perturbation="deform", symmetry={"crop": "periods"})
    assert not crop(mode="symmetrize", symmetry={"crop": "none"})
    with pytest.raises(ValueError, match="symmetry.crop"):
        SymtexConfig(source=__file__, mode="tile", symmetry={"crop": "periods"})
    with pytest.raises(ValueError, match="symmetry.crop"):
        SymtexConfig(source=__file__, mode="symmetrize", symmetry={"crop": "periods", "kind": "rotational"})


def test_cut_overlaps_that_do_not_fit_are_skipped_with_a_warning(caplog):
    import logging

    from synthkit.methods.symtex.tile import cut_overlaps

    with caplog.at_level(logging.WARNING, logger="synthkit"):
        assert cut_overlaps([24, 8, 16, 8], (40, 64)) == [8, 16]
    assert any("tile.cut_overlaps: [24]" in r.getMessage() for r in caplog.records)
    caplog.clear()
    assert cut_overlaps([], (40, 64)) == []
    assert not caplog.records



def test_only_outputs_py_writes_files():
    """Issue 27: the stage modules and the pipeline compute; outputs.py writes every file and
    preview (function length, user errors and private imports: tests/test_architecture.py)."""
    import synthkit.methods.symtex

    for path in sorted(Path(synthkit.methods.symtex.__file__).parent.glob("*.py")):
        if path.name != "outputs.py":
            text = path.read_text()
            assert not any(w in text for w in ("save_image(", "np.save(", "ctx.path(", "_png(")), path.name


@pytest.mark.parametrize(("size", "patch", "overlap"), [(512, 32, 12), (96, 16, 6), (256, 32, 12), (64, 16, 6)])
def test_tile_batches_hold_every_tile_once_in_blocks_that_do_not_meet(size, patch, overlap):
    """A batch is one row's tiles whose toroidal blocks are disjoint (a tile's candidates read its
    block only, so they can all be scored against the same image); every tile is in one batch."""
    from synthkit.core import quilting

    ys, xs = quilting.tile_grid(size, patch, overlap), quilting.tile_grid(size, patch, overlap)
    batches = synth.tile_batches(ys, xs, patch, (size, size))
    tiles = [t for b in batches for t in b]
    assert sorted(tiles) == [(i, j) for i in range(len(ys)) for j in range(len(xs))]
    for b in batches:
        assert len({i for i, _ in b}) == 1
        cover = np.zeros(size, int)
        for _, j in b:
            cover[(xs[j] + np.arange(patch)) % size] += 1
        assert cover.max() == 1
        assert len(b) == 1 or len(b) * patch * patch <= synth.BATCH_SHARE * size * size
    # every other tile (a third group when the row's count is odd: the last meets the first), cut
    # into runs of at most a 16th of the image: 512^2 (26 tiles a row) 2 batches a row, 256^2 (13)
    # 3 + 3, 3 + 3, 1; 96^2 of 16 px patches (10) 2 + 1 + 2 twice; 64^2 (7) one tile each
    assert len(batches) == len(ys) * {512: 2, 96: 6, 256: 5, 64: 7}[size]


def test_batch_accepted_together_only_when_the_exact_objective_falls():
    """Two proposals that each lower the objective alone but together overshoot it: the batch is
    undone and taken one by one, each kept only when the exact objective falls (it never rises)."""
    from synthkit.core import quilting

    ys = xs = quilting.tile_grid(64, 16, 6)
    result = synth.WalkResult(np.full((64, 64, 1), 0.4, np.float32), np.zeros((7, 7, 2), np.int64),
                              np.zeros((64, 64, 2), np.int64))

    def objective():  # each 16x16 block of 2.0 raises the mean by 0.1
        return float((result.image.mean() - 0.5) ** 2)

    block, keep = np.full((16, 16, 1), 2.0, np.float32), np.ones((16, 16), bool)
    found = [((0, 0), 0.0, np.array([3, 4]), keep, block, 5), ((0, 2), 0.0, np.array([5, 6]), keep, block, 5)]
    value, changed = synth._accept(result, found, objective(), [], ["lum"], objective, (ys, xs), 16)
    assert changed == 1 and value == pytest.approx(0.0, abs=1e-12) == objective()
    assert result.image[:16, :16].min() == 2.0 and result.image[:, 16:].max() == pytest.approx(0.4)
    assert result.origins[0, 0].tolist() == [3, 4] and result.origins[0, 2].tolist() == [0, 0]
    # from 0 both help: accepted together
    result.image[:] = 0.0
    value, changed = synth._accept(result, found, objective(), [], ["lum"], objective, (ys, xs), 16)
    assert changed == 2 and value == pytest.approx(0.0625) == objective()


# ---------------------------------------------------------------------------------------------
# issue 24, patch edges: the visible border figure and the walk's choice among candidates


def _two_patch_image(offset: float):
    """A 16x16 grey ramp image whose right half is a second patch brightened by ``offset``, with
    its source map (two patches side by side, so two vertical borders on the torus)."""
    ramp = np.tile(np.arange(16, dtype=np.float32) * 0.01, (16, 1))
    img = ramp.copy()
    img[:, 8:] += offset
    sources = np.stack(np.mgrid[0:16, 0:16], axis=2)
    sources[:, 8:, 0] += 100  # the right half comes from elsewhere in the source
    return np.repeat(img[..., None], 3, axis=2), sources


def test_seam_energy_counts_visible_border_per_step():
    """0 for a periodic triangle wave seen as one patch (its wrap steps, borders on the torus, are
    the inside's 0.01); two patches of a ramp (steps 0.01 along x), the right one 0.2 brighter:
    borders at x 7->8 (step 0.21) and across the wrap (x 15->0: -0.35; y 15->0: 0) give their
    exact excess energy per step of the image."""
    wave = np.tile(0.01 * np.minimum(np.arange(16), 16 - np.arange(16)), (16, 1)).astype(np.float32)
    one = np.stack(np.mgrid[0:16, 0:16], axis=2)
    assert synth.seam_energy(np.repeat(wave[..., None], 3, axis=2), one) == pytest.approx(0.0, abs=1e-6)
    img, sources = _two_patch_image(0.2)
    inside = 0.5 * (0.01**2 + 0.0)  # inside steps: 0.01 along x, 0 along y
    border = 16 * (0.21**2 + 0.35**2 + 0.0)
    expected = (border - 48 * inside) / (2 * 256 * inside)
    assert synth.seam_energy(img, sources) == pytest.approx(expected, rel=1e-4)
    # twice the offset: more visible
    assert synth.seam_energy(*_two_patch_image(0.4)) > synth.seam_energy(img, sources)


def test_border_energy_prices_the_cut_of_each_candidate():
    """A candidate that continues the canvas's source costs nothing; one from elsewhere, 0.3
    brighter, costs its 16 steps across the ring less the inside energy (the candidates' own
    mean squared step, 0.01^2 / 2) each."""
    canvas, sources = _two_patch_image(0.0)
    B = 4
    ring = canvas[3 : 3 + B + 2, 1 : 1 + B + 2]
    ring_src = sources[3 : 3 + B + 2, 1 : 1 + B + 2]
    block = ring[1:-1, 1:-1]
    patches = np.stack([block, block + 0.3])
    positions = np.array([ring_src[1, 1], ring_src[1, 1] + [50, 0]])
    cost = synth.border_energy(ring, ring_src, patches, np.ones((2, B, B), bool), positions)
    assert cost[0] == 0.0
    inside = 0.5 * 0.01**2
    # along x the steps into and out of the block are 0.3 + 0.01 and 0.01 - 0.3, along y +-0.3
    expected = 4 * (0.31**2 - inside) + 4 * (0.29**2 - inside) + 8 * (0.3**2 - inside)
    assert cost[1] == pytest.approx(expected, rel=1e-4)
    # a cut keeping only the block's right half: the left half shows the canvas, which continues
    # the ring; the borders are the cut (4 steps) and the right half's 2 + 2 + 4 steps to the ring
    half = np.zeros((2, B, B), bool)
    half[:, :, 2:] = True
    cut = synth.border_energy(ring, ring_src, patches, half, positions)
    assert cut[0] == 0.0
    assert cut[1] == pytest.approx(4 * (0.31**2 - inside) + 4 * (0.29**2 - inside) + 4 * (0.3**2 - inside), rel=1e-4)


def test_choose_candidate_trades_a_share_of_the_gain_for_a_quieter_border():
    values = np.array([0.90, 0.80, 0.85, 0.70])
    border = np.array([0.0, 1.0, 0.5, 9.0])
    # current 1.0: best gain 0.30 (index 3); 3/4 of it is 0.225, met by index 3 only
    assert synth.choose_candidate(values, 1.0, border, share=0.25) == 3
    # half of it (0.15): indices 1 (0.20), 2 (0.15), 3 qualify; index 2 has the quietest border
    assert synth.choose_candidate(values, 1.0, border, share=0.5) == 2
    assert synth.choose_candidate(values, 1.0, border, share=0.0) == 3
    # no candidate gains: the best by value (the walk keeps the tile)
    assert synth.choose_candidate(values, 0.6, border, share=0.5) == 3
    # the best's border is no more visible than the texture: nothing to trade its gain for
    assert synth.choose_candidate(values, 1.0, np.array([0.0, 1.0, 0.5, -0.1]), share=0.5) == 3


def test_seam_share_default_is_the_walks():
    """The config's ``synth.seam_share`` default is the library's (:data:`synth.SEAM_SHARE`), and
    the walk polishes once by default."""
    from synthkit.methods.symtex.config import SynthSection

    assert SynthSection().seam_share == synth.SEAM_SHARE
    assert SynthSection().polish_sweeps == 1
