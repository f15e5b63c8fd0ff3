"""What a symmetry-texture run gives back (:class:`SymmetryTextureResult`) and the files it writes.

``result.png`` (every mode), the S previews ``s_input.png``, ``s_target.png``, ``s_result.png``,
then per mode: ``baseline.png`` and ``comparison.png`` (transfer, filter by synth),
``k1_search.png`` (lens), ``sample_map.npy`` (deform), the tiles ``optimized.png``,
``baseline.png``, ``cut<overlap>.png`` with their 3x3 tilings (tile) and ``comparison.png``.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from synthkit.io.images import save_image
from synthkit.methods.symtex.tile import tile_order
from synthkit.preview import heatmap_png, montage_png, plot_curve_png
from synthkit.result import Result

REPRESENTATION_NAMES = {"translational": "S_T", "rotational": "S_R", "reflective": "S_Ref"}


@dataclass(kw_only=True)
class SymmetryTextureResult(Result):
    """The outputs of ``synthkit.symmetry_texture`` in memory.

    Attributes
    ----------
    image : (H, W, 3) float32
        The mode's result (``result.png``): the synthesized texture (transfer, filter, quilt), the
        symmetrized image (symmetrize; the input itself when the deformation was refused, see
        ``metrics["status"]``) or the chosen tile (tile, ``metrics["tile_choice"]``).
    source : (Hs, Ws, 3) float32
        The source image as the run read it.
    s_input, s_target, s_result : ndarray or None
        The standardized symmetry representation of the first signal of the input, of the target
        (E_L2 modes; None otherwise) and of the result: ``(2 wy + 1, 2 wx + 1)`` for S_T (the
        displacement lattice, zero displacement at the centre), ``(n_angles,)`` for S_R / S_Ref.
    baseline : (H, W, 3) float32 or None
        Unguided quilting of the source from the same seed (transfer / filter with ``baseline``).
    sample_map : (H, W, 2) float32 or None
        Perturbation ``deform``: the backward map, the input position (x, y) each output pixel
        shows.
    tiles : dict[str, (h, w, 3) float32]
        Mode ``tile``: every candidate tile by name (``optimized``, ``baseline``, ``cut<overlap>``,
        ``input``); ``image`` is ``tiles[metrics["tile_choice"]]``.
    k1_search : (n, 2) float64 or None
        Perturbation ``lens``: every evaluated ``(k1, E_symm)``, in order of evaluation.
    """

    method: ClassVar[str] = "symmetry-texture"
    image: np.ndarray
    source: np.ndarray
    s_input: np.ndarray | None = None
    s_target: np.ndarray | None = None
    s_result: np.ndarray | None = None
    baseline: np.ndarray | None = None
    sample_map: np.ndarray | None = None
    tiles: dict[str, np.ndarray] = field(default_factory=dict)
    k1_search: np.ndarray | None = None

    @property
    def representation_name(self) -> str:
        """``S_T``, ``S_R`` or ``S_Ref``."""
        return REPRESENTATION_NAMES[self.config.symmetry.kind]

    def comparison(self) -> np.ndarray | None:
        """The ``comparison.png`` montage ``(256, w, 3) float32``: source and result (with the
        unguided baseline, or every tile); None in the modes that write none (quilt, lens)."""
        shown = self._comparison()
        return None if shown is None else montage_png(None, shown[0], titles=shown[1])

    def _comparison(self) -> tuple[list[np.ndarray], list[str]] | None:
        cfg = self.config
        pert = cfg.resolved_perturbation()
        if pert == "lens" or cfg.mode == "quilt":
            return None
        if pert == "synth":
            if self.baseline is None:
                return [self.source, self.image], ["source", "guided"]
            return [self.source, self.baseline, self.image], ["source", "unguided", "guided"]
        if not self.tiles:
            return [self.source, self.image], ["input", "result"]
        names = sorted((k for k in self.tiles if k != "input"), key=lambda k: (k != "baseline", tile_order(k)))
        titles = {"baseline": "blended, not optimized", "optimized": "optimized"}
        return ([self.source] + [self.tiles[k] for k in names],
                ["input"] + [titles.get(k, f"cut {k[3:]} px, not optimized") for k in names])

    def write(self, ctx) -> None:
        """Write the run's files and previews through ``ctx`` (see the module docstring)."""
        with ctx.stage("write"):
            self._write_common(ctx)
            pert = self.config.resolved_perturbation()
            if pert == "synth" and self.baseline is not None:
                save_image(ctx.path("baseline", "baseline.png"), self.baseline)
            if pert == "lens":
                ks, vals = np.array(sorted(map(tuple, self.k1_search.tolist()))).T
                plot_curve_png(ctx.preview_path("k1_search", "k1_search.png"), ks, vals, xlabel="k1",
                               ylabel="E_symm", title="lens search")
            if self.sample_map is not None:
                np.save(ctx.path("sample_map", "sample_map.npy"), self.sample_map)
            if self.tiles:
                self._write_tiles(ctx)
            shown = self._comparison()
            if shown is not None and ctx.wants_preview("summary"):
                montage_png(ctx.path("comparison", "comparison.png"), shown[0], titles=shown[1])

    def _write_common(self, ctx) -> None:
        """``result.png`` and the previews of S of the input, the target and the result."""
        save_image(ctx.path("result", "result.png"), self.image)
        name = self.representation_name
        if ctx.wants_preview("all"):
            preview_rep(ctx.path("s_input", "s_input.png"), self.s_input, f"{name} input")
            if self.s_target is not None:
                preview_rep(ctx.path("s_target", "s_target.png"), self.s_target, f"{name} target")
        path = ctx.preview_path("s_result", "s_result.png")
        if path is not None:
            preview_rep(path, self.s_result, f"{name} result")

    def _write_tiles(self, ctx) -> None:
        """The tile images and their 3x3 tilings; the PNGs are encoded by two threads (a 640x480
        input has five 1440x1920 tilings)."""
        tiles = self.tiles
        cuts = sorted((k for k in tiles if k.startswith("cut")), key=tile_order)
        jobs = [(ctx.path(k, f"{k}.png"), lambda k=k: tiles[k]) for k in ("optimized", "baseline") if k in tiles]
        jobs += [(ctx.path(name, f"{name}.png"), lambda name=name: tiles[name]) for name in cuts]
        if ctx.wants_preview("all"):
            jobs.append((ctx.path("tiled", "tiled_3x3.png"), lambda: np.tile(self.image, (3, 3, 1))))
            for name in [n for n in ("optimized", "input", "baseline") if n in tiles] + cuts:
                tiled = lambda name=name: np.tile(tiles[name], (3, 3, 1))  # noqa: E731
                jobs.append((ctx.path(f"tiled_{name}", f"tiled_{name}_3x3.png"), tiled))
        with ThreadPoolExecutor(max_workers=min(2, os.cpu_count() or 1)) as pool:
            written = pool.map(lambda job: save_image(job[0], job[1]()), jobs)
            list(ctx.progress(written, total=len(jobs), desc="writing tiles"))


def preview_rep(path, S: np.ndarray, title: str) -> None:
    """A heatmap of an S_T lattice ``(a, b)``, or the curve of S_R / S_Ref ``(n,)`` over degrees."""
    if S.ndim == 2:
        heatmap_png(path, S, title=title)
    else:
        deg = np.arange(S.shape[0]) * (360.0 if title.startswith("S_R") else 180.0) / S.shape[0]
        plot_curve_png(path, deg, S, xlabel="degrees", ylabel="S", title=title)

