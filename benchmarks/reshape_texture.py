"""Benchmark of the texture reshape (synthkit.methods.reshape.texture; Cabral et al. 2009, section 4).

Inputs are generated in the run: the bundled facade texture (data-samples/generate.py: a plank
door, two windows and a plinth over plaster noise, 512^2) and its 2x upscale (1024^2).

- autosimilarity: both directional maps of eq. 9 on a 1024^2 texture (goal <= 0.3 s). Baseline: the
  same maps with one ``scipy.ndimage.uniform_filter`` box per shift (``2 Delta`` boxes per
  direction), the direct vectorised form without the shared box.
- grid factor and solve: the interior system (eqs. 11-13) of one surface covering a 1024^2 texture
  at spacing 1/32 (goals: factor <= 20 ms, solve <= 1 ms). Baseline: ``scipy.sparse.linalg.spsolve``
  on the same normal equations for each solve. The paper: texture factorization 20-330 ms for up
  to about 5000 equations (2009, TAUCS).
- bake: distortion map and shader bake of a 1024^2 output (goal <= 0.5 s); the naive stretch
  (``cv2.resize``, bilinear) beside it.
- quality beside the peers: the 512^2 facade widened 2x by ours, by the naive stretch and by
  seam-carving (PyPI ``seam-carving``, the ``bench`` extra; Avidan and Shamir 2007): door width
  change and detail energy (variance of the Laplacian over the plaster above the windows, output
  over input), and the time of each.

- real houses (../shared/data/architecture/houses, skipped when absent): house1, 2 and 4 widened by
  30 % and raised by 20 % through whole ``synthkit reshape`` runs with ``texture: reshape``; over the
  surfaces that map a door, window or garage rectangle of their atlas (the fixture rectangles of
  tests/methods/test_reshape_texture.py), the mean rigid scale error of ours and of the naive
  stretch, and the texture stage's time.

Run: ``.venv/bin/python benchmarks/reshape_texture.py [--quick]``; writes
bench-results/reshape_texture.json.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import scipy.sparse as sp
from scipy import ndimage
from scipy.sparse.linalg import spsolve

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "data-samples"))

from generate import FACADE, facade_texture  # noqa: E402

from benchmarks._common import median_time, print_table, record, write_results  # noqa: E402
from synthkit.methods.reshape.texture import autosim, bake  # noqa: E402
from synthkit.methods.reshape.texture.grid import build_grid  # noqa: E402
from synthkit.methods.reshape.texture.solve import InteriorSolver, edge_stiffness  # noqa: E402
from synthkit.methods.reshape.texture.surface import TextureParams, analyse_texture, reshape_surface  # noqa: E402

AREA = "reshape_texture"
QUAD_F = np.array([[0, 1, 2], [0, 2, 3]])
QUAD_S = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])


def autosim_baseline(L, delta=10, size=5):
    """Eq. 9 with one box filter per shift (reflected borders)."""
    out = []
    for dx, dy in ((1, 0), (0, 1)):
        acc = np.zeros_like(L)
        for s in range(-delta, delta + 1):
            if s:
                q = np.roll(L, (-s * dy, -s * dx), axis=(0, 1))
                acc += ndimage.uniform_filter((q - L) ** 2, size, mode="reflect")
        out.append(acc / (2 * delta))
    return np.stack(out)


def stretch_x(C, factor):
    def ratio(i, k):
        d = C[i] - C[k]
        return np.linalg.norm(d * [factor, 1.0], axis=1) / np.linalg.norm(d, axis=1)
    return ratio


def door_width(img, row: int) -> int:
    found = np.zeros(img.shape[1], bool)
    for colour in ([0.55, 0.36, 0.2], [0.12, 0.07, 0.04], [0.2, 0.2, 0.2]):
        found |= np.abs(img[row] - colour).sum(axis=1) < 0.12
    xs = np.flatnonzero(found)
    return int(xs.max() - xs.min() + 1)


def bench_autosim(img1024, repeats):
    L = autosim.equalize_luminance(img1024)
    ours = median_time(lambda: autosim.directional_autosimilarity(L), repeats=repeats)
    base = median_time(lambda: autosim_baseline(L), repeats=max(1, repeats // 2))
    record(AREA, "autosimilarity_1024_two_directions_baseline", base, "s")
    record(AREA, "autosimilarity_1024_two_directions", ours, "s", goal=0.3, baseline=base)


def bench_grid(tex1024, repeats):
    n = 1024.0
    C = np.array([[0, 0], [n, 0], [n, n], [0, n]])
    g = build_grid(C, QUAD_S, (n / 32, n / 32))
    s = edge_stiffness(tex1024.T, g.X, g.edges, s_min=0.01, s_align=1.0)
    factor = median_time(lambda: InteriorSolver(g, s), repeats=repeats)
    solver = InteriorSolver(g, s)
    target = C * [2, 1]
    solve = median_time(lambda: solver.solve(target), repeats=repeats * 4)
    N = (solver.A.T @ sp.diags(solver.weights) @ solver.A).tocsc()
    rhs = np.ones(N.shape[0])
    base = median_time(lambda: spsolve(N, rhs), repeats=repeats)
    record(AREA, "grid_nodes", float(len(g.X)), "nodes")
    record(AREA, "grid_equations", float(solver.equations), "rows")
    record(AREA, "grid_solve_spsolve_baseline", 1e3 * base, "ms")
    record(AREA, "grid_solve", 1e3 * solve, "ms", goal=1.0, baseline=1e3 * base)
    record(AREA, "grid_factor", 1e3 * factor, "ms", goal=20.0, baseline=1e3 * base)
    record(AREA, "paper_texture_factor_min", 20.0, "ms")
    record(AREA, "paper_texture_factor_max", 330.0, "ms")


def bench_bake(tex1024, repeats):
    C = np.array([[0, 0], [512, 0], [512, 1024], [0, 1024]], float)  # left half, widened 2x -> 1024^2
    res = reshape_surface(C, QUAD_F, QUAD_S, stretch_x(C, 2.0), tex1024, toroidal=False, params=TextureParams())
    g, Y = res.grid, res.Y
    shape = res.texture.shape[:2]

    def run():
        dm = bake.distortion_map(g.X, Y, g.triangles, shape)
        smax = bake.triangle_stretch(g.X, Y, g.triangles)[:, 0][dm.triangle]
        amount = np.clip((smax - 1) / 0.25, 0, 1)
        return bake.bake(tex1024.base, tex1024.detail, tex1024.tile_ids, tex1024.tiles, dm, amount)

    t = median_time(run, repeats=repeats)
    src = tex1024.img[:, :512]
    naive = median_time(lambda: cv2.resize(src, (1024, 1024), interpolation=cv2.INTER_LINEAR), repeats=repeats)
    record(AREA, "bake_1024_naive_stretch", naive, "s")
    record(AREA, "bake_1024", t, "s", goal=0.5, baseline=naive)
    record(AREA, "bake_output_texels", float(shape[0] * shape[1]), "texels")


def bench_quality(img, repeats):
    n = FACADE["size"]
    C = np.array([[0, 0], [n, 0], [n, n], [0, n]], float)
    params = TextureParams()
    start = time.perf_counter()
    tex = analyse_texture(img, wrap=False, params=params, rng=np.random.default_rng(0))
    res = reshape_surface(C, QUAD_F, QUAD_S, stretch_x(C, 2.0), tex, toroidal=False, params=params)
    ours_t = time.perf_counter() - start
    naive_t = median_time(lambda: cv2.resize(img, (2 * n, n), interpolation=cv2.INTER_LINEAR), repeats=repeats)
    naive = cv2.resize(img, (2 * n, n), interpolation=cv2.INTER_LINEAR)
    before = door_width(img, 330)
    x0, y0, x1, y1 = FACADE["plaster"]
    e_in = bake.laplacian_energy(img[y0:y1, x0:x1])
    outs = {"ours": (res.texture, ours_t), "naive": (naive, naive_t)}
    try:
        import seam_carving
    except ImportError:
        print("seam-carving not installed (pip install -e '.[bench]'): peer skipped", file=sys.stderr)
    else:
        start = time.perf_counter()
        sc = seam_carving.resize((img * 255).round().astype(np.uint8), (2 * n, n))
        outs["seam_carving"] = (sc.astype(np.float32) / 255.0, time.perf_counter() - start)
    for name, (out, t) in outs.items():
        change = door_width(out, 330) / before - 1
        energy = bake.laplacian_energy(out[y0:y1, 2 * x0:2 * x1]) / e_in
        record(AREA, f"facade_2x_{name}_door_width_change", abs(change), "ratio", goal=0.05 if name == "ours" else None)
        record(AREA, f"facade_2x_{name}_detail_energy", energy, "ratio", goal=0.8 if name == "ours" else None)
        record(AREA, f"facade_2x_{name}_time", t, "s", baseline=outs["naive"][1] if name != "naive" else None)


def bench_real(quick: bool) -> None:
    import tempfile

    import yaml

    from synthkit.methods.reshape.pipeline import load_textured
    from synthkit.runner import run_config
    from tests.methods.test_reshape_texture import HOUSE_ATLAS, HOUSES, door_window_rows, house_motion

    if not HOUSES.is_dir():
        print(f"skipped real houses: {HOUSES} not present", file=sys.stderr)
        return
    cases = [("house1_baked.obj", "widen")] if quick else [(h, m) for h in HOUSE_ATLAS for m in ("widen", "raise")]
    for name, mode in cases:
        mesh = load_textured(HOUSES / name)
        cfg = {"method": "reshape", "input": str(HOUSES / name), "contacts": {"tol": 1e-4}, "texture": "reshape",
               **house_motion(mesh.V, mode)}
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "house.yaml"
            path.write_text(yaml.safe_dump(cfg))
            report = run_config(path, out_dir=Path(tmp) / "out", show_progress=False, previews="none")
        rows = door_window_rows(report, mesh, HOUSE_ATLAS[name])
        key = f"real_{name.split('_')[0]}_{mode}"
        record(AREA, f"{key}_texture_stage", report["timings"]["texture"], "s")
        record(AREA, f"{key}_surfaces", float(report["metrics"]["texture_surfaces"]), "count")
        if rows:
            naive = float(np.mean([r[3] for r in rows]))
            record(AREA, f"{key}_door_window_naive_scale_error", naive, "ratio")
            record(AREA, f"{key}_door_window_scale_error", float(np.mean([r[2] for r in rows])), "ratio",
                   baseline=naive)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats")
    args = parser.parse_args()
    repeats = 2 if args.quick else 5
    img, _ = facade_texture()
    img1024 = cv2.resize(img, (1024, 1024), interpolation=cv2.INTER_LINEAR)
    tex1024 = analyse_texture(img1024, wrap=False, params=TextureParams(), rng=np.random.default_rng(0))
    bench_autosim(img1024, repeats)
    bench_grid(tex1024, repeats)
    bench_bake(tex1024, repeats)
    bench_quality(img, repeats)
    bench_real(args.quick)
    print_table(AREA)
    print(f"wrote {write_results(AREA)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
