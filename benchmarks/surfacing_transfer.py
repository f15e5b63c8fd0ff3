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
  or ``--base COMMIT``) against today's with ``parameterization: vector_heat`` (potpourri3d's log
  maps, the code path of commit e8c0275) and today's default ``exp_map`` (the local discrete
  exponential map), the same transfer alternated three times in this process: wall seconds of the
  step and CPU seconds spent in ``mutual_patch`` (``--only parameterize`` runs this alone);
- with ``--only accuracy`` only: both log maps against exact geodesic polar coordinates on the
  sphere, the bundled cylinder's side and spot (:func:`accuracy`).

The paper's figure: "usually a few minutes" offline on a 1.5 GHz PC, dominated by the
parameterization, then by patch finding. Goals on this machine: the whole transfer <= 60 s,
fan precomputation <= 10 s.

Run: ``.venv/bin/python benchmarks/surfacing_transfer.py`` (writes bench-results/surfacing_transfer.json), or with
``--only parameterize`` (the parameterization timing alone), ``--only accuracy``, ``--base COMMIT``;
``--quick``: a 1280-face target and one parameterization round (checks that it runs).
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import base_synthkit, print_table, record, write_results  # noqa: E402
from synthkit.methods.surfacing.config import SurfacingConfig, TransferPair, TransferSection  # noqa: E402
from synthkit.methods.surfacing.options import options_of  # noqa: E402
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


def default_options(radius: float) -> Options:
    """One pair's synthesis options of a config with its defaults, patch radius ``radius``."""
    transfer = TransferSection.model_construct(pairs=[TransferPair.model_construct()])
    return options_of(SurfacingConfig.model_construct(transfer=transfer)).synthesis(0, radius)


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
        keys = ("bound", "matching", "trimming") + (("parameterization",) if mods is None else ())
        given = {k: getattr(opt, k) for k in keys}
        o = sy.Options(**given, patch_radius=radius) if mods else replace(default_options(radius), **given)
        res = sy.Synthesis(target, source, o, rng=np.random.default_rng(seed)).run()
    finally:
        sy.mutual_patch = inner
    return res, cpu[0]


def parameterize_speed(target_mesh, source_mesh, opt: Options, base: str = BASE_COMMIT, rounds: int = 3) -> None:
    """Parameterization seconds (wall, and CPU in ``mutual_patch``) of the code before issue 29
    (``base``) and today's with each log map, alternated ``rounds`` times in this process with the
    same seed; the patches, coverage and final seam cost of each."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        runs = {"before": base_transfer(Path(tmp), base),
                "vector_heat": lambda *a: timed_transfer(*a[:2], replace(a[2], parameterization="vector_heat"), a[3]),
                "now": lambda *a: timed_transfer(*a[:2], replace(a[2], parameterization="exp_map"), a[3])}
        rows: dict[str, list] = {k: [] for k in runs}
        for _ in range(rounds):
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
        for name in ("vector_heat", "now"):
            label = "exp_map" if name == "now" else name
            record(AREA, f"  parameterize {what} {label}, best of {rounds} (vs {base[:7]})", best[name], "s",
                   baseline=best["before"])
            record(AREA, f"  parameterize {what} {label}, mean of {rounds} (vs {base[:7]})", mean[name], "s",
                   baseline=mean["before"])


def polar_errors(U: np.ndarray, r: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Radial errors ``| |U| - r |`` ``(n,)`` and angular errors in degrees ``(n,)`` of the log map
    ``U (n, 2)`` against exact geodesic polar coordinates ``r (n,)``, ``a (n,)`` (radians), the
    angles after removing the map's median turn (the frames differ by a constant rotation)."""
    d = np.angle(np.exp(1j * (np.arctan2(U[:, 1], U[:, 0]) - a)))
    d = np.angle(np.exp(1j * (d - np.median(d))))
    return np.abs(np.linalg.norm(U, axis=1) - r), np.degrees(np.abs(d))


def _exact_sphere(surface, v):
    P = surface.V / np.linalg.norm(surface.V, axis=1, keepdims=True)
    return np.arccos(np.clip(P @ P[v], -1, 1)), P


def _exact_cylinder(surface, v, radius=0.6):
    ang = np.arctan2(surface.V[:, 1], surface.V[:, 0])
    D = np.stack([radius * np.angle(np.exp(1j * (ang - ang[v]))), surface.V[:, 2] - surface.V[v, 2]], 1)
    return np.linalg.norm(D, axis=1), D


def exact_polar(surface, v: int, kind: str, verts: np.ndarray):
    """Exact geodesic polar coordinates ``(r (n,), a (n,))`` of ``verts (n,)`` from vertex ``v`` in its
    frame ``surface.vertex_frames[v]``: on the unit sphere and the cylinder of radius 0.6 in closed
    form (angles of the initial direction: the great circle's tangent, the unrolled offset), on a
    mesh by potpourri3d's edge-flip geodesics (the polyhedral surface's locally shortest path,
    whose first segment, projected on the vertex's tangent plane, gives the angle)."""
    e1, e2, n = surface.vertex_frames[v]
    if kind == "sphere":
        r, P = _exact_sphere(surface, v)
        t = P[verts] - np.outer(P[verts] @ n, n)
        return r[verts], np.arctan2(t @ e2, t @ e1)
    if kind == "cylinder":
        r, D = _exact_cylinder(surface, v)
        up = np.array([0.0, 0.0, 1.0])
        side = np.cross(up, n)
        t = D[verts, :1] * side + D[verts, 1:] * up
        return r[verts], np.arctan2(t @ e2, t @ e1)
    import potpourri3d as pp3d

    solver = surface.__dict__.setdefault("_edge_flip", pp3d.EdgeFlipGeodesicSolver(surface.V, surface.F))
    r, a = np.empty(len(verts)), np.empty(len(verts))
    for i, w in enumerate(verts):
        path = solver.find_geodesic_path(int(v), int(w))
        r[i] = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
        k = np.argmax(np.linalg.norm(path - path[0], axis=1) > 1e-12)
        t = path[k] - path[0]
        a[i] = np.arctan2(t @ e2, t @ e1)
    return r, a


def log_map_accuracy(name: str, surface, kind: str, reach: float, seeds: int = 5, samples: int = 300) -> None:
    """Radial and angular errors of both log maps from ``seeds`` random vertices against
    :func:`exact_polar` at up to ``samples`` vertices each within ``reach`` (1.5 patch radii: the
    source patch's extent; sampled among the vertices either map puts within 1.2 ``reach``, kept
    where the exact distance is below ``reach``), and their CPU seconds per map (vector heat: first
    and later maps; the local map stops at 1.2 ``reach``)."""
    from synthkit.methods.surfacing.transfer.param import centred_log_map  # noqa: F401  (warms numba)

    rng = np.random.default_rng(1)
    errs: dict[str, list] = {"exp_map": [], "vector_heat": []}
    cpu: dict[str, list] = {"exp_map": [], "vector_heat": []}
    surface.local_log_map(0, reach)  # compile
    for v in rng.choice(len(surface.V), seeds, replace=False):
        maps = {}
        for method in ("vector_heat", "exp_map"):
            c = time.process_time()
            maps[method] = surface.log_map(v) if method == "vector_heat" else surface.local_log_map(v, 1.2 * reach)
            cpu[method].append(time.process_time() - c)
        with np.errstate(invalid="ignore"):
            near = (np.linalg.norm(maps["vector_heat"], axis=1) < 1.2 * reach) | np.isfinite(maps["exp_map"][:, 0])
        near = np.flatnonzero(near & (np.arange(len(near)) != v))
        near = rng.choice(near, min(samples, len(near)), replace=False)
        r, a = exact_polar(surface, v, kind, near)
        near, r, a = near[r < reach], r[r < reach], a[r < reach]
        for method, U in maps.items():
            dr, da = polar_errors(U[near], r, a)
            errs[method].append((dr / reach, da))
    for method, e in errs.items():
        dr, da = np.concatenate([x[0] for x in e]), np.concatenate([x[1] for x in e])
        timing = (f"first {cpu[method][0]:.3f} s, later median {np.median(cpu[method][1:]):.4f} s"
                  if method == "vector_heat" else f"median {np.median(cpu[method]):.4f} s")
        print(f"{name} {method}: radial error / reach median {np.median(dr):.4f} p95 {np.percentile(dr, 95):.4f} "
              f"max {dr.max():.4f}; angle deg median {np.median(da):.2f} p95 {np.percentile(da, 95):.2f} "
              f"max {da.max():.2f}; CPU per map {timing}", file=sys.stderr)
        record(AREA, f"log map {name} {method}: radial error p95 / reach", float(np.percentile(dr, 95)), "")
        record(AREA, f"log map {name} {method}: angle error p95", float(np.percentile(da, 95)), "deg")


def accuracy(target_mesh) -> None:
    """:func:`log_map_accuracy` on the benchmark's sphere (patch radius 0.6, reach 0.9), the bundled
    cylinder's side (sample, radius 0.6) and, when ../shared/data is there, spot with reaches of
    0.15 and 0.3 sqrt(area) (0.3 sqrt(area): the automatic patch radius of a whole-mesh region)."""
    S, G = target_mesh
    log_map_accuracy("sphere", make_surface(S, G, np.arange(len(G)), None, largest=False), "sphere", 0.9)
    V, F, labels = sample.cylinder()
    log_map_accuracy("cylinder", make_surface(V, F, np.flatnonzero(labels == 0), None), "cylinder", 0.6)
    spot = Path(__file__).resolve().parents[2] / "shared/data/meshes/spot/spot_triangulated.obj"
    if spot.exists():
        import trimesh

        m = trimesh.load(spot, process=False, force="mesh")
        V, back = np.unique(np.asarray(m.vertices), axis=0, return_inverse=True)  # split at its UV seams: welded
        F = back.ravel()[np.asarray(m.faces)]
        surf = make_surface(V, F, np.arange(len(F)), None, largest=False)
        for share in (0.15, 0.3):
            log_map_accuracy(f"spot {share}", surf, "mesh", share * np.sqrt(surf.area), samples=150)


def whole_transfer(target_mesh, source_mesh) -> None:
    """Fan precomputation, the whole transfer and its baselines (module docstring)."""
    V, F, colors = source_mesh
    source = make_surface(V, F, np.arange(len(F)), Signal("color", values=colors[F]))
    t = time.perf_counter()
    cloud = make_cloud(source)
    build_index(source, cloud, source.signal.sample(cloud.faces, cloud.bary), spokes=8, steps=4, radius=0.3)
    fans = time.perf_counter() - t
    record(AREA, f"fan precompute, {len(F)} source faces", fans, "s", goal=10.0)
    base_opt = default_options(1.0)
    ours, res = transfer(target_mesh, source_mesh, base_opt, 0)
    rnd, res_rnd = transfer(target_mesh, source_mesh, replace(base_opt, matching="random"), 0)
    none_opt = replace(base_opt, matching="random", trimming="none", fixed_patches=True, max_patches=len(res.patches))
    untrimmed, res_none = transfer(target_mesh, source_mesh, none_opt, 0)
    record(AREA, f"whole transfer, {len(target_mesh[1])} target faces (fans)", ours, "s", goal=60.0, baseline=rnd)
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



def parse_args():
    """``--only parameterize`` and ``--base COMMIT`` (default :data:`BASE_COMMIT`)."""
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=["parameterize", "accuracy"],
                    help="run only the parameterization timing, or only the log maps' accuracy")
    ap.add_argument("--base", default=BASE_COMMIT, help="commit whose code is the timing's baseline")
    ap.add_argument("--quick", action="store_true",
                    help="a 1280-face target (icosphere subdivision 3) and one parameterization round")
    return ap.parse_args()


def main() -> int:
    args = parse_args()
    rng = np.random.default_rng(0)
    target_mesh = sample.sphere(3 if args.quick else 5)
    source_mesh = colour_source(rng)
    rounds = 1 if args.quick else 3
    if args.only == "parameterize":
        parameterize_speed(target_mesh, source_mesh, default_options(1.0), args.base, rounds)
    elif args.only == "accuracy":
        accuracy(target_mesh)
    else:
        whole_transfer(target_mesh, source_mesh)
        parameterize_speed(target_mesh, source_mesh, default_options(1.0), args.base, rounds)
    print_table(AREA)
    print(f"wrote {write_results(AREA)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
