"""The faces retargeting writes and the figures ``report.json`` gives of them: degenerate faces
left out, mesh quality against the input with retargeting's limits, the graph cut's figures and
the offset statistics.
"""

from __future__ import annotations

import numpy as np

from synthkit.asset import Asset
from synthkit.core.mesh import weld
from synthkit.core.quality import WELD_REL_TOL, degenerate_faces, mesh_quality
from synthkit.methods.retarget.analysis import Analysis
from synthkit.methods.retarget.corners import unpack
from synthkit.methods.retarget.seams import Retargeted
from synthkit.methods.retarget.synthesis import sliver_figures, unique_faces

__all__ = ["written_faces", "degenerate", "input_quality", "output_quality", "result_metrics",
           "statistics_metrics"]


def written_faces(res: Retargeted, Vm, asset: Asset):
    """The result's faces as written: ``(F (k, 3), face_material (k,), corner_uv (k, 3, 2) or None,
    corner_color (k, 3, 4) uint8 or None, dropped)``, without its degenerate faces
    (:func:`degenerate` in model units ``Vm``; ``dropped`` counts them)."""
    keep = ~degenerate(Vm, res.F)
    if res.attr is None:
        return res.F[keep], np.zeros(int(keep.sum()), np.int64), None, None, int((~keep).sum())
    mat, uv, col = unpack(res.attr[keep], asset.corner_uv is not None, asset.corner_color is not None)
    return res.F[keep], mat, uv, col, int((~keep).sum())


def degenerate(V, F) -> np.ndarray:
    """``(#F,) bool``: the faces :func:`~synthkit.core.quality.mesh_quality` counts as degenerate,
    :func:`~synthkit.core.quality.degenerate_faces` or collapsed by its weld (an edge shorter than
    :data:`~synthkit.core.quality.WELD_REL_TOL` of the diagonal)."""
    if len(F) == 0:
        return np.zeros(0, bool)
    diag = float(np.linalg.norm(np.ptp(V[np.unique(F)], axis=0)))
    Fw = weld(V, np.zeros((0, 3), np.int64), WELD_REL_TOL * diag, return_index=True)[2][F]
    collapsed = (Fw[:, 0] == Fw[:, 1]) | (Fw[:, 1] == Fw[:, 2]) | (Fw[:, 2] == Fw[:, 0])
    return degenerate_faces(V, F) | collapsed


def input_quality(V, F) -> dict:
    """:func:`~synthkit.core.quality.mesh_quality` of the input ``V (#V, 3)``, ``F (#F, 3)`` (model
    units) with each surface stored twice counted once (the output is judged the same way, since
    the stitching drops such faces), except ``duplicate_faces``, which counts the input's own. A
    face and its duplicate close each other's edges (docs/findings/retarget.md)."""
    diag = float(np.linalg.norm(np.ptp(V[np.unique(F)], axis=0)))
    keep = unique_faces(V, F, tol=WELD_REL_TOL * diag)
    q = mesh_quality(V, F[keep])
    if not keep.all():
        q["duplicate_faces"] = mesh_quality(V, F)["duplicate_faces"]
    return q


def output_quality(res: Retargeted, F_written, center, scale, Vn, F, input_quality: dict) -> tuple[dict, dict, dict]:
    """The quality of the written mesh (``F_written`` over the result's vertices, model units
    ``res.V * scale + center``) beside the input's (:func:`input_quality`; normalised ``Vn``,
    ``F``): ``(quality figures, their limits, retargeting's own figures)``, the first two for
    :meth:`~synthkit.context.RunContext.check_quality`.

    Limits: open and non-manifold edges at most the input's times the copies used (each copy
    brings its own), no degenerate or duplicate face. Own figures: ``copies``, ``volume_ratio``
    (output bounding box over input bounding box), ``face_ratio``, ``faces_limit`` (input faces x
    volume ratio x 1.5, a figure, not a limit: docs/findings/retarget.md), the smallest angle and
    the faces below :data:`~synthkit.methods.retarget.synthesis.SLIVER_DEG` of input and output
    (:func:`~synthkit.methods.retarget.synthesis.sliver_figures`)."""
    copies = int(len(np.unique(res.labeling)))
    used = np.unique(F)
    vin = float(np.prod(np.maximum(np.ptp(Vn[used], axis=0), 1e-12)))
    vout = float(np.prod(np.maximum(np.ptp(res.V, axis=0), 1e-12))) if len(res.V) else 0.0
    ratio = vout / vin
    written = np.unique(F_written)  # the writer leaves out the vertices no written face uses
    q = mesh_quality((res.V * scale + center)[written], np.searchsorted(written, F_written))
    limits = {
        "loose_vertices": 0,
        "open_edges": int(input_quality["open_edges"] * copies),
        "nonmanifold_edges": int(input_quality["nonmanifold_edges"] * copies),
        "degenerate_faces": 0,
        "duplicate_faces": 0,
    }
    s_in, s_out = sliver_figures(Vn, F[unique_faces(Vn, F)]), sliver_figures(res.V, F_written)
    return q, limits, {
        "copies": copies,
        "volume_ratio": ratio,
        "face_ratio": q["faces"] / max(input_quality["faces"], 1),
        "faces_limit": int(np.floor(input_quality["faces"] * ratio * 1.5)),
        "min_angle_deg": s_out["min_angle_deg"],
        "input_min_angle_deg": s_in["min_angle_deg"],
        "sliver_faces": s_out["sliver_faces"],
        "input_sliver_faces": s_in["sliver_faces"],
    }


def result_metrics(res: Retargeted, steps, graphcut_seconds: float, scale: float) -> dict:
    """``report.json``'s figures of one result: its graph, labeling and energy, the steps taken
    (``growth`` in model units), and the sizes of the output."""
    p = res.problem
    lab = res.labeling
    pair = p.pairwise(np.arange(len(p.edges)), lab[p.edges[:, 0]], lab[p.edges[:, 1]]) if len(p.edges) else np.zeros(0)
    return {
        "infinite_terms": int((~np.isfinite(pair)).sum()),
        "energy_finite_part": float(pair[np.isfinite(pair)].sum()),
        "growth": (res.grid.basis @ np.asarray(steps) * scale).tolist(),
        "grid_basis_normalised": res.grid.basis.T.tolist(),
        "grid_origin": res.grid.origin.tolist(),
        "graph_nodes": int(res.problem.n_nodes),
        "graph_labels": int(res.problem.n_labels),
        "graph_edges": int(len(res.problem.edges)),
        "energy": float(res.energy),  # infinite when seams join empty to non-empty voxels (JSON null)
        "cycles": int(res.cycles),
        "graphcut_seconds": float(graphcut_seconds),
        "steps": np.asarray(steps).tolist(),
        "grid_in": res.grid.shape.tolist(),
        "grid_out": res.problem.out_shape.tolist(),
        "label_shifts": res.problem.labels.tolist(),
        "labels_used": int(len(np.unique(res.labeling))),
        "output_faces": int(len(res.F)),
        "labelled_faces": int(len(res.labelled_F)),
        "output_vertices": int(len(res.V)),
    }


def statistics_metrics(an: Analysis, center, scale: float) -> dict:
    """``report.json``'s figures of the analysis (model units unless ``_normalised``)."""
    order = np.argsort(-an.dominant_counts, kind="stable")
    return {
        "principal_offsets": (an.principal * scale).tolist(),
        "principal_offsets_normalised": an.principal.tolist(),
        "n_principal": an.n_principal,
        "basis_normalised": an.basis.T.tolist(),
        "dominant_offsets": [
            {
                "offset": (an.dominant_refined[i] * scale).tolist(),
                "offset_normalised": an.dominant_refined[i].tolist(),
                "before_icp_normalised": an.dominant[i].tolist(),
                "count": int(an.dominant_counts[i]),
                "overlap": float(an.dominant_overlap[i]),
                "grip": float(an.dominant_grip[i]),
                "principal": int(i) in an.principal_index,
            }
            for i in order
        ],
        "sparsity_top7": an.top7,
        "sparsity_top20": an.top20,
        "n_features": int(len(an.features.P)),
        "n_vertex_features": int(an.features.n_vertex_features),
        "n_dense_samples": int(len(an.features.dense_P)),
        "n_offsets": int(len(an.offsets)),
        "n_statistics_features": int(an.n_statistics_features),
        "n_statistics_offsets": int(len(an.stat_offsets)),
        "n_bins": int(len(an.bin_counts)),
        "normalisation": {"center": np.asarray(center).tolist(), "scale": float(scale)},
    }
