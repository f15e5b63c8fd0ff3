"""Benchmark of surface-by-numbers' detail transfer (section 4, synthkit.methods.surfacing.transfer).

Inputs, generated here: a 20480-face target (the whole unit icosphere, subdivision 5) and a
10082-face colour source (a flat 2 x 2 grid of 71 x 71 cells whose vertex colours are a smooth
random field, sums of sinusoids in three channels). The patch radius is automatic (0.3 sqrt of
the smaller area: 0.6 units). Measured in one process:

- fan precomputation for the 10k source faces (cloud, fan sampling, shift-stacked search matrix);
- the whole transfer (surfaces with their log-map solvers, synthesis to coverage and until the
  seam cost stops falling, extraction with the kernel blend), seconds per step kind;
- the random-matching baseline (``matching: random``, same trimming), and the random/no-trim
  baseline of the quality check with the same number of patches; their seam costs beside ours;
- the parameterization step as it was before issue 29 (an SVD per 2 x 2 Jacobian,
  :func:`svd_distortion` here, and log maps with the overlap test on the planar source grid)
  against now (closed form, the grid's own coordinates), same seed (``--only parameterize`` runs
  this alone).

The paper's figure: "usually a few minutes" offline on a 1.5 GHz PC, dominated by the
parameterization, then by patch finding. Goals on this machine: the whole transfer <= 60 s,
fan precomputation <= 10 s.

Run: ``.venv/bin/python benchmarks/surfacing_transfer.py`` (writes bench-results/surfacing_transfer.json), or with
``--only parameterize`` (the parameterization timing alone).
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import print_table, record, write_results  # noqa: E402
from synthkit.methods.surfacing.transfer import param  # noqa: E402
from synthkit.methods.surfacing.transfer.extract import corner_values, vertex_values  # noqa: E402
from synthkit.methods.surfacing.transfer.fans import build_index, make_cloud  # noqa: E402
from synthkit.methods.surfacing.transfer.surface import Signal, Surface, make_surface  # noqa: E402
from synthkit.methods.surfacing.transfer.synth import Options, Synthesis  # noqa: E402
from synthkit.samples import surfacing_transfer as sample  # noqa: E402

AREA = "surfacing_transfer"
KINDS = ("precompute", "precompute_fans", "position", "match", "parameterize", "trim")


def colour_source(rng):
    """10082-face grid with a smooth random colour field, ``(V, F, colors (#V, 3))``."""
    V, F = sample.grid(71)
    freq = rng.uniform(2, 9, size=(3, 4, 2))
    phase = rng.uniform(0, 2 * np.pi, size=(3, 4))
    c = np.stack([np.sin(V[:, :2] @ freq[ch].T + phase[ch]).mean(axis=1) for ch in range(3)], axis=1)
    return V, F, 0.5 + 0.5 * c / np.abs(c).max()


def transfer(target_mesh, source_mesh, opt: Options, seed: int):
    """Whole transfer through the stages: ``(seconds, result, step timings)``."""
    t = time.perf_counter()
    S, G = target_mesh
    V, F, colors = source_mesh
    target = make_surface(S, G, np.arange(len(G)), None, largest=False)
    source = make_surface(V, F, np.arange(len(F)), Signal("color", values=colors[F]))
    res = Synthesis(target, source, replace(opt, patch_radius=0.3 * np.sqrt(min(target.area, source.area))),
                    rng=np.random.default_rng(seed)).run()
    vals = vertex_values(target.F, corner_values(res, source, len(target.F)), target.areas, len(target.V))
    assert np.isfinite(vals).all() or (res.patch_of < 0).any()
    return time.perf_counter() - t, res


def svd_distortion(P: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`param.distortion` as it was before issue 29 (``np.linalg.svd`` per Jacobian), the
    baseline of the parameterization timing."""
    J, ok = param.jacobians(P, Q)
    s = np.linalg.svd(J, compute_uv=False)
    with np.errstate(divide="ignore"):
        dist = np.maximum(s[:, 0], 1.0 / s[:, 1])
    return np.where(ok & np.isfinite(dist), dist, np.inf), np.linalg.det(J)


def parameterize_speed(target_mesh, source_mesh, opt: Options) -> None:
    """Parameterization seconds as before issue 29 (:func:`svd_distortion`, and the planar source
    grid parameterized by log maps with the overlap test) and now (closed form, the grid's own
    coordinates), alternated twice in this process with the same seed."""
    fast, planar = param.distortion, Surface.planar
    runs: dict[str, list] = {"before": [], "now": []}
    for _ in range(2):
        for name in runs:
            if name == "before":
                param.distortion, Surface.planar = svd_distortion, property(lambda self: False)
            try:
                _, again = transfer(target_mesh, source_mesh, opt, 0)
            finally:
                param.distortion, Surface.planar = fast, planar
            runs[name].append((again.timings["parameterize"], len(again.patches)))
    print(f"parameterize (seconds, patches): before {runs['before']}, now {runs['now']}", file=sys.stderr)
    before, after = (min(t for t, _ in runs[k]) for k in ("before", "now"))
    record(AREA, "  parameterize, closed form + planar source", after, "s", baseline=before)


def main() -> int:
    rng = np.random.default_rng(0)
    target_mesh = sample.sphere(5)
    source_mesh = colour_source(rng)
    if sys.argv[1:] == ["--only", "parameterize"]:
        parameterize_speed(target_mesh, source_mesh, Options(patch_radius=1.0))
        print_table(AREA)
        return 0
    V, F, colors = source_mesh
    source = make_surface(V, F, np.arange(len(F)), Signal("color", values=colors[F]))
    t = time.perf_counter()
    cloud = make_cloud(source)
    build_index(source, cloud, source.signal.sample(cloud.faces, cloud.bary), spokes=8, steps=4, radius=0.3)
    fans = time.perf_counter() - t
    record(AREA, "fan precompute, 10082 source faces", fans, "s", goal=10.0)
    base_opt = Options(patch_radius=1.0)
    ours, res = transfer(target_mesh, source_mesh, base_opt, 0)
    rnd, res_rnd = transfer(target_mesh, source_mesh, replace(base_opt, matching="random"), 0)
    none_opt = replace(base_opt, matching="random", trimming="none", fixed_patches=True, max_patches=len(res.patches))
    untrimmed, res_none = transfer(target_mesh, source_mesh, none_opt, 0)
    record(AREA, "whole transfer, 20480 target faces (fans)", ours, "s", goal=60.0, baseline=rnd)
    record(AREA, "whole transfer, random matching", rnd, "s")
    record(AREA, "whole transfer, random + no trim", untrimmed, "s")
    for kind in KINDS:
        record(AREA, f"  step {kind} (fans)", res.timings[kind], "s", baseline=res_rnd.timings[kind] or None)
    record(AREA, "patches (fans)", len(res.patches), "", baseline=len(res_rnd.patches))
    record(AREA, "coverage (fans)", float((res.patch_of >= 0).mean()), "")
    record(AREA, "seam cost (fans)", res.seam_cost[-1], "", baseline=res_none.seam_cost[-1])
    record(AREA, "seam cost (random matching)", res_rnd.seam_cost[-1], "", baseline=res_none.seam_cost[-1])
    record(AREA, "seam cost (random + no trim)", res_none.seam_cost[-1], "")
    cov = res.patch_of >= 0
    record(AREA, "distortion max (bound 2)", float(res.distortion[cov].max()), "", goal=2.0)
    parameterize_speed(target_mesh, source_mesh, base_opt)
    print_table(AREA)
    print(f"wrote {write_results(AREA)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
