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
- the parameterization step of the code before issue 29 (:data:`BASE_COMMIT`, from ``git archive``,
  or ``--base COMMIT``) against today's, the same transfer alternated three times in this process:
  wall seconds of the step and CPU seconds spent in ``mutual_patch`` (``--only parameterize`` runs
  this alone).

The paper's figure: "usually a few minutes" offline on a 1.5 GHz PC, dominated by the
parameterization, then by patch finding. Goals on this machine: the whole transfer <= 60 s,
fan precomputation <= 10 s.

Run: ``.venv/bin/python benchmarks/surfacing_transfer.py`` (writes bench-results/surfacing_transfer.json), or with
``--only parameterize`` (the parameterization timing alone), ``--base COMMIT``.
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import base_synthkit, print_table, record, write_results  # noqa: E402
from synthkit.methods.surfacing.transfer import surface as surface_module  # noqa: E402
from synthkit.methods.surfacing.transfer import synth as synth_module  # noqa: E402
from synthkit.methods.surfacing.transfer.extract import corner_values, vertex_values  # noqa: E402
from synthkit.methods.surfacing.transfer.fans import build_index, make_cloud  # noqa: E402
from synthkit.methods.surfacing.transfer.surface import Signal, make_surface  # noqa: E402
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


BASE_COMMIT = "2342190d9de31856f0a084ff02480fdd8ec7b70b"
"""The code before issue 29 (the parent of its first transfer commit), the baseline of the
parameterization timing."""


def base_transfer(folder: Path, commit: str):
    """:func:`transfer` run by ``synthkit`` as of ``commit`` (its files from ``git archive``, imported
    as ``synthkit_base``) with the step's CPU seconds: a function like :func:`timed_transfer`."""
    import importlib

    base_synthkit(folder, commit)
    mods = {name: importlib.import_module(f"synthkit_base.methods.surfacing.transfer.{name}")
            for name in ("surface", "synth")}
    return lambda target_mesh, source_mesh, opt, seed: timed_transfer(target_mesh, source_mesh, opt, seed, mods)


def timed_transfer(target_mesh, source_mesh, opt: Options, seed: int, mods=None):
    """:func:`transfer` through the modules ``mods`` (``surface``, ``synth``; default today's) with
    the process CPU seconds spent in ``mutual_patch``: ``(result, cpu)``."""
    sf, sy = (mods["surface"], mods["synth"]) if mods else (surface_module, synth_module)
    inner, cpu = sy.mutual_patch, [0.0]

    def counted(*args, **kw):
        c = time.process_time()
        try:
            return inner(*args, **kw)
        finally:
            cpu[0] += time.process_time() - c

    sy.mutual_patch = counted
    try:
        S, G = target_mesh
        V, F, colors = source_mesh
        target = sf.make_surface(S, G, np.arange(len(G)), None, largest=False)
        source = sf.make_surface(V, F, np.arange(len(F)), sf.Signal("color", values=colors[F]))
        radius = 0.3 * np.sqrt(min(target.area, source.area))
        o = sy.Options(**{k: getattr(opt, k) for k in ("bound", "matching", "trimming")}, patch_radius=radius)
        res = sy.Synthesis(target, source, o, rng=np.random.default_rng(seed)).run()
    finally:
        sy.mutual_patch = inner
    return res, cpu[0]


def parameterize_speed(target_mesh, source_mesh, opt: Options, base: str = BASE_COMMIT) -> None:
    """Parameterization seconds (wall, and CPU in ``mutual_patch``) of the code before issue 29
    (``base``) and today's, alternated three times in this process with the same seed; the
    patches, coverage and final seam cost of both."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        runs = {"before": base_transfer(Path(tmp), base), "now": timed_transfer}
        rows: dict[str, list] = {k: [] for k in runs}
        for _ in range(3):
            for name, run in runs.items():
                res, cpu = run(target_mesh, source_mesh, opt, 0)
                rows[name].append((res.timings["parameterize"], cpu, len(res.patches),
                                   float((res.patch_of >= 0).mean()), res.seam_cost[-1]))
    for name, r in rows.items():
        wall, cpu = [x[0] for x in r], [x[1] for x in r]
        print(f"parameterize {name} ({base[:7] if name == 'before' else 'today'}): wall {np.round(wall, 2).tolist()} "
              f"(mean {np.mean(wall):.2f}), CPU {np.round(cpu, 2).tolist()} (mean {np.mean(cpu):.2f}); patches "
              f"{r[0][2]}, coverage {r[0][3]:.4f}, seam cost {r[0][4]:.4f}", file=sys.stderr)
    for i, what in ((0, "wall"), (1, "CPU")):
        best = {k: min(x[i] for x in r) for k, r in rows.items()}
        mean = {k: float(np.mean([x[i] for x in r])) for k, r in rows.items()}
        record(AREA, f"  parameterize {what}, best of 3 (vs {base[:7]})", best["now"], "s", baseline=best["before"])
        record(AREA, f"  parameterize {what}, mean of 3 (vs {base[:7]})", mean["now"], "s", baseline=mean["before"])


def parse_args():
    """``--only parameterize`` and ``--base COMMIT`` (default :data:`BASE_COMMIT`)."""
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=["parameterize"], help="run only the parameterization timing")
    ap.add_argument("--base", default=BASE_COMMIT, help="commit whose code is the timing's baseline")
    return ap.parse_args()


def main() -> int:
    rng = np.random.default_rng(0)
    target_mesh = sample.sphere(5)
    source_mesh = colour_source(rng)
    args = parse_args()
    if args.only == "parameterize":
        parameterize_speed(target_mesh, source_mesh, Options(patch_radius=1.0), args.base)
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
    parameterize_speed(target_mesh, source_mesh, base_opt, args.base)
    print_table(AREA)
    print(f"wrote {write_results(AREA)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
