"""What ``synthkit retarget`` gives: the result in memory (:class:`RetargetResult`) and the files and
previews it writes (:meth:`RetargetResult.write`).

Files: the retargeted mesh in the input's format (glTF as GLB; an input given in memory as PLY, or
GLB when it has UVs or materials) with the input's materials, textures, UVs and colours (OBJ with
its MTL and textures beside it), ``labels.npy`` (label index per output voxel), ``labels.ply``
(per-face int32 labels and their colours, :func:`label_colours`) and PNG previews (sparsity curve,
offset histogram, offsets over the model, before / after / labels renders, ``comparison.png``);
the same prefixed ``baseline_`` for the regular baseline.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import trimesh

from synthkit.asset import Asset
from synthkit.io.assets import save_asset
from synthkit.io.meshes import save_mesh
from synthkit.methods.retarget.analysis import Analysis
from synthkit.preview import (
    Appearance,
    before_after_png,
    golden_hues,
    heatmap_png,
    montage_png,
    plot_curve_png,
    render_mesh_png,
)
from synthkit.result import Result

__all__ = ["RetargetResult", "RetargetedMesh", "label_colours", "palette", "write_statistics", "write_mesh"]


def palette(n: int) -> np.ndarray:
    """``(n, 3)`` float distinct colours in [0, 1] (:func:`synthkit.preview.golden_hues` from hue 0.13)."""
    return golden_hues(max(n, 1), start=0.13, value=0.95)


def label_colours(labels, n_labels: int) -> np.ndarray:
    """``(m, 3) uint8`` colour of each face label: :func:`palette` of ``n_labels`` (by label index)."""
    pal = np.rint(palette(n_labels) * 255).astype(np.uint8)
    return pal[np.asarray(labels, dtype=np.int64)]


@dataclass(kw_only=True)
class RetargetedMesh:
    """One retargeted mesh, in the input's (model) units.

    Attributes
    ----------
    asset : :class:`~synthkit.asset.Asset` as written: ``V (#V, 3)``, ``F (#F, 3)`` (no degenerate
        face), ``face_material (#F,)`` into the input's ``materials``, ``corner_uv (#F, 3, 2)`` and
        ``corner_color (#F, 3, 4) uint8`` when the input has them.
    mesh : ``trimesh.Trimesh`` of ``asset.V``, ``asset.F`` (``process=False``).
    label_volume : ``(X, Y, Z) int32`` label index of every output voxel (``labels.npy``).
    labelled_mesh : ``trimesh.Trimesh``: the same surface with every face inside one label's copy
        (``labels.ply``).
    face_labels : ``(#F_l,)`` int label of each face of ``labelled_mesh``.
    label_shifts : ``(L, 3) int`` the shift (steps per grid axis) of each label.
    n_nodes : voxels of the graph cut.
    """

    asset: Asset
    mesh: trimesh.Trimesh
    label_volume: np.ndarray
    labelled_mesh: trimesh.Trimesh
    face_labels: np.ndarray
    label_shifts: np.ndarray
    n_nodes: int

    @property
    def n_labels(self) -> int:
        """Labels of the graph cut."""
        return len(self.label_shifts)


@dataclass(kw_only=True)
class RetargetResult(Result):
    """The result of :func:`synthkit.retarget`.

    Attributes
    ----------
    asset, mesh : the retargeted mesh (:class:`RetargetedMesh`'s), None with ``analyze_only``.
    retargeted : :class:`RetargetedMesh` or None (``analyze_only``); with ``offsets: regular`` the
        regular baseline's.
    baseline : the regular baseline's :class:`RetargetedMesh` (``compare_baseline``), else None.
    principal_offsets : ``(k, 3)`` the principal offsets found (k = 0 to 3), model units.
    dominant_offsets : ``(m, 3)`` the dominant offsets after ICP, model units, with
        ``dominant_counts (m,)`` the offsets in each peak's window.
    sparsity_curve : ``(n, 2)``: share of occupied bins (sorted by count) against the cumulative
        share of offsets (``sparsity.png``); ``metrics["sparsity_top7"]`` is its value at 7%.
    histogram_bins : ``(b, 3) int`` occupied bins of the offset histogram (``rint(offset /
        bin_size)``, normalised units) with ``histogram_counts (b,)``.
    analysis : the :class:`~synthkit.methods.retarget.analysis.Analysis` (normalised units: the
        model minus ``center (3,)``, divided by ``scale``).
    input_asset : the input as read.
    """

    method: ClassVar[str] = "retarget"
    input_asset: Asset
    analysis: Analysis
    center: np.ndarray
    scale: float
    suffix: str
    retargeted: RetargetedMesh | None = None
    baseline: RetargetedMesh | None = None

    @property
    def asset(self) -> Asset | None:
        return None if self.retargeted is None else self.retargeted.asset

    @property
    def mesh(self) -> trimesh.Trimesh | None:
        return None if self.retargeted is None else self.retargeted.mesh

    @property
    def principal_offsets(self) -> np.ndarray:
        return self.analysis.principal * self.scale

    @property
    def dominant_offsets(self) -> np.ndarray:
        return self.analysis.dominant_refined * self.scale

    @property
    def dominant_counts(self) -> np.ndarray:
        return self.analysis.dominant_counts

    @property
    def sparsity_curve(self) -> np.ndarray:
        return np.stack([self.analysis.curve_x, self.analysis.curve_y], axis=1)

    @property
    def histogram_bins(self) -> np.ndarray:
        return self.analysis.bin_keys

    @property
    def histogram_counts(self) -> np.ndarray:
        return self.analysis.bin_counts

    def write(self, ctx) -> None:
        """Write the statistics previews, then each retargeted mesh with its labels and previews,
        then ``comparison.png``; a run that stopped after the analysis writes the first only."""
        V, F = self.input_asset.V, self.input_asset.F
        cfg = self.config
        write_statistics(self.analysis, V, F, self.scale, cfg, ctx)
        before = None
        if ctx.wants_preview("all") or (ctx.wants_preview("summary") and not cfg.analyze_only):
            before = render_mesh_png(ctx.preview_path("before", "before.png"), V, F, size=cfg.preview_size,
                                     appearance=Appearance.of(self.input_asset, like_input=True))
        results = [(p, r) for p, r in (("", self.retargeted), ("baseline_", self.baseline)) if r is not None]
        if not results:
            return
        with ctx.stage("output"):
            renders, titles = [before], ["input"]
            for prefix, res in results:
                renders.append(write_mesh(res, self.input_asset, self.suffix, cfg, ctx, prefix=prefix))
                titles.append(f"{prefix.rstrip('_') or cfg.offsets}: {res.n_nodes} nodes, {res.n_labels} labels")
            if ctx.wants_preview("summary"):
                montage_png(ctx.path("comparison", "comparison.png"), renders, titles=titles)


def write_statistics(an: Analysis, V, F, scale: float, cfg, ctx) -> None:
    """Previews of the analysis (Fig. 2, Fig. 5) over the input ``V (#V, 3)``, ``F (#F, 3)``: the
    sparsity curve, the offset histogram and the offsets drawn over the model."""
    # the statistics are the summary of a run that stops after them (--analyze-only, no repetition)
    level = "summary" if cfg.analyze_only or an.n_principal == 0 else "all"
    if not ctx.wants_preview(level):
        return
    plot_curve_png(
        ctx.path("sparsity_plot", "sparsity.png"),
        an.curve_x * 100.0,
        an.curve_y * 100.0,
        xlabel="% of occupied bins (sorted)",
        ylabel="% of offsets",
        title=f"top 7%: {an.top7:.0%}  top 20%: {an.top20:.0%}",
    )
    if not ctx.wants_preview("all"):
        return
    tiles = [
        heatmap_png(ctx.path(f"histogram_{i}", f"histogram_{n}.png"), _histogram_view(an, a0, a1),
                    title=f"offsets {n} (log)")
        for i, (n, (a0, a1)) in enumerate(zip(("xy", "xz"), ((0, 1), (0, 2)), strict=True))
    ]
    montage_png(ctx.path("histogram", "histogram.png"), tiles, titles=["bins x-y", "bins x-z"])
    c0 = V.mean(axis=0)
    segs = [[c0, c0 + v * scale] for v in an.dominant_refined] + [[c0, c0 + v * scale] for v in an.principal]
    render_mesh_png(
        ctx.path("offsets_preview", "offsets.png"),
        V,
        F,
        size=cfg.preview_size,
        lines=np.array(segs).reshape(-1, 2, 3) if segs else None,
    )


def _histogram_view(an: Analysis, a0: int, a1: int) -> np.ndarray:
    """The histogram's bins summed over the third axis, log scale, axis ``a1`` up."""
    keys, counts = an.bin_keys, an.bin_counts
    if len(keys):
        lo = keys[:, [a0, a1]].min(axis=0)
        shape = keys[:, [a0, a1]].max(axis=0) - lo + 1
        img = np.zeros(tuple(shape))
        np.add.at(img, tuple((keys[:, [a0, a1]] - lo).T), counts)
    else:
        img = np.zeros((1, 1))
    return np.log1p(img.T[::-1])


def write_mesh(res: RetargetedMesh, like: Asset, suffix: str, cfg, ctx, *, prefix: str) -> np.ndarray | None:
    """Write the mesh (with the input's materials, textures, UVs and colours), the label volume,
    the labelled PLY and the renders of one result; return the label render (None when previews
    are off)."""
    a = res.asset
    names = save_asset(ctx.path(f"{prefix}mesh", f"{prefix}retargeted{suffix}"), a.V, a.F, like=like,
                       corner_uv=a.corner_uv, face_material=a.face_material, corner_color=a.corner_color)
    for k, extra in enumerate(names[1:]):
        ctx.outputs[f"{prefix}mesh_file_{k}"] = extra
    np.save(ctx.path(f"{prefix}labels_volume", f"{prefix}labels.npy"), res.label_volume)
    fl = res.face_labels
    save_mesh(res.labelled_mesh, ctx.path(f"{prefix}labels_mesh", f"{prefix}labels.ply"),
              face_labels=fl, face_colors=label_colours(fl, res.n_labels))
    look = Appearance.of(like, a.corner_uv, a.face_material, a.corner_color)
    if ctx.wants_preview("all"):
        render_mesh_png(ctx.path(f"{prefix}after", f"{prefix}after.png"), a.V, a.F, size=cfg.preview_size,
                        appearance=look)
    if (like.textured or like.corner_color is not None) and ctx.wants_preview("summary" if not prefix else "all"):
        before_after_png(ctx.path(f"{prefix}before_after", f"{prefix}before_after.png"),
                         (like.V, like.F, Appearance.of(like, like_input=True)), (a.V, a.F, look),
                         size=cfg.preview_size)
    if not ctx.wants_preview("summary"):
        return None
    colours = palette(res.n_labels)[fl] if len(fl) else None
    Vl, Fl = res.labelled_mesh.vertices, res.labelled_mesh.faces
    return render_mesh_png(ctx.preview_path(f"{prefix}labels_preview", f"{prefix}labels.png"), Vl, Fl,
                           face_colors=colours, size=cfg.preview_size)
