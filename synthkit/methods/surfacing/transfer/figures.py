"""The figures of a transfer's ``report.json`` and previews: per pair the patches, coverage,
distortion and seam costs, the seam visibility of vertex values and textures, and the seam cost
per face."""

from __future__ import annotations

import numpy as np

from synthkit.methods.surfacing.transfer.bake import texture_seam_visibility
from synthkit.methods.surfacing.transfer.extract import corner_values, seam_visibility, vertex_values
from synthkit.methods.surfacing.transfer.extraction import Prepared, texture_blend
from synthkit.methods.surfacing.transfer.surface import texel_size
from synthkit.methods.surfacing.transfer.synth import Result as Synthesized
from synthkit.methods.surfacing.transfer.trim import seam_costs

__all__ = ["STEP_KINDS", "seam_figures", "pair_metrics", "seam_field", "patch_domains"]


STEP_KINDS = ("precompute", "precompute_fans", "position", "match", "parameterize", "trim")


def seam_figures(prep: Prepared, res: Synthesized, base: Synthesized | None, ex) -> dict:
    """``seam_visibility`` of the pair's vertex values (:func:`seam_visibility`, with ``ex.blend``) and,
    with a baseline, ``baseline_seam_visibility`` (the random/no-trim baseline, the same blend);
    colour, texture and attribute signals; texture pairs add the same of their texture
    (:func:`texture_seam_figures`)."""
    if prep.source.signal.kind == "displacement":
        return {}
    t = prep.target
    out = {}
    for key, r in (("seam_visibility", res), ("baseline_seam_visibility", base)):
        if r is None:
            continue
        corner = corner_values(r, prep.source, len(t.F))
        vals = vertex_values(t.F, corner, t.areas, len(t.V), blend=ex.blend, V=t.V)
        out[key] = finite(seam_visibility(t.V, t.F, r.patch_of, vals))
        if prep.source.signal.kind == "texture":
            out |= texture_seam_figures(key, prep, r, ex)
    return out


def finite(x: float) -> float | None:
    return None if not np.isfinite(x) else float(x)


def texture_seam_figures(key: str, prep: Prepared, r: Synthesized, ex) -> dict:
    """``<key>_texture`` (and ``..._unblended``): :func:`.bake.texture_seam_visibility` of the texture
    the output shows (:func:`texture_blend` with ``blend``) and of the source texture read through
    each face's own patch alone, at a step of two source texels."""
    t, step = prep.target, 2.0 * texel_size(prep.source) * prep.scale
    texture = key.replace("seam_visibility", "texture_seam_visibility")
    figure = {}
    for name, how in ((texture, ex.blend), (f"{texture}_unblended", "none")):
        if name == texture or ex.blend != "none":
            tex = texture_blend(prep, r, ex, blend=how)
            figure[name] = finite(texture_seam_visibility(t.V, t.F, r.patch_of, tex.colour, step))
    return figure


def pair_metrics(prep: Prepared, res: Synthesized, base: Synthesized | None) -> dict:
    cov = res.patch_of >= 0
    used = np.unique(res.patch_of[cov])
    src_max = max((float(res.patches[p].src_distortion.max()) for p in used), default=0.0)
    final = float(res.seam_cost[-1]) if res.seam_cost else 0.0
    out = {
        "target_faces": int(len(prep.target.F)), "source_faces": int(len(prep.source.F)),
        "patch_radius": prep.radius, "patches": int(len(res.patches)), "patches_visible": int(len(used)),
        "iterations": res.iterations, "coverage": float(cov.mean()),
        "uncovered_faces": prep.target.face_ids[~cov].tolist(),
        "seam_cost": {"per_iteration": [float(c) for c in res.seam_cost], "final": final},
        "distortion_mean": float(res.distortion[cov].mean()) if cov.any() else 0.0,
        "distortion_max": max(float(res.distortion[cov].max()) if cov.any() else 0.0, src_max),
        "seconds": {k: float(res.timings[k]) for k in STEP_KINDS},
    }
    if base is not None:
        out["baseline_seam_cost"] = float(base.seam_cost[-1]) if base.seam_cost else 0.0
        out["baseline_patches"] = int(len(base.patches))
        out["baseline_coverage"] = float((base.patch_of >= 0).mean())
    return out


def seam_field(preps, results, n_faces: int) -> np.ndarray:
    """Seam cost per face of the full mesh (half of each incident seam), NaN outside the regions."""
    out = np.full(n_faces, np.nan)
    for prep, (res, _) in zip(preps, results, strict=True):
        t = prep.target
        a, b = res.patch_of[t.pairs[:, 0]], res.patch_of[t.pairs[:, 1]]
        on = (a >= 0) & (b >= 0) & (a != b)
        lengths = np.linalg.norm(t.V[t.edges[:, 0]] - t.V[t.edges[:, 1]], axis=1)
        cost = np.zeros(len(a))
        cost[on] = seam_costs(res.samples[on, 0], res.samples[on, 1], lengths[on])
        per = np.zeros(len(t.F))
        np.add.at(per, t.pairs[:, 0], 0.5 * cost)
        np.add.at(per, t.pairs[:, 1], 0.5 * cost)
        out[t.face_ids] = per
    return out


def patch_domains(results) -> list[tuple[np.ndarray, np.ndarray]]:
    """Fig. 4: the source domain ``(n, 3, 2)`` and target domain ``(m, 3, 2)`` of the first patches
    of the first pair."""
    return [(patch.locator.T, patch.corner_uv) for patch in results[0][0].patches[:3]]
