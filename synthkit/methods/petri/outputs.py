"""What a ``petri-synth`` run gives back (:class:`PetriResult`) and how it writes its files and previews."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import trimesh

from synthkit import preview
from synthkit.asset import Asset
from synthkit.io.assets import save_asset
from synthkit.io.atomic import write_bytes_atomic, write_text_atomic
from synthkit.io.meshes import save_mesh
from synthkit.io.usd import mesh_suffix
from synthkit.methods.petri.appearance import Look
from synthkit.methods.petri.assembly import PieceLibrary, assemble, label_colors, preview_library, reorder_library
from synthkit.methods.petri.net import ColouredPetriNet, to_dot, to_pnml
from synthkit.result import Result

__all__ = ["PetriResult", "PreviewScene", "result_asset", "write_mesh", "export_nets", "write_previews",
           "VIEW_OF_PLANE", "PREVIEW_FACES"]

VIEW_OF_PLANE = {"xy": "front", "xz": "top", "yz": "side"}
"""Construction plane -> the view ``construction_space.png`` is drawn in."""

PREVIEW_FACES = 400_000
"""Previews draw pieces decimated to about this many triangles in all (the meshes written are full)."""


@dataclass
class PreviewScene:
    """What the previews draw besides the nets: the example's pieces by label in lattice axis order
    (X, Y, Z), its label grid ``(nx, ny, nz)``, the construction's world axes (a, b, c), the
    construction plane's cell edges and curves ``lines (k, 2, 3)`` and the plane's name."""

    library: PieceLibrary
    example_grid: np.ndarray
    axes: tuple[int, int, int]
    lines: np.ndarray
    plane: str


@dataclass(kw_only=True)
class PetriResult(Result):
    """The result of ``petri-synth`` (:func:`synthkit.petri_synth`).

    Attributes
    ----------
    mesh : trimesh.Trimesh
        The synthesized model's geometry, ``(#V, 3)`` vertices and ``(#F, 3)`` faces (not processed).
    asset : Asset
        The same model with the example's appearance: ``corner_uv (#F, 3, 2)``, ``corner_color
        (#F, 3, 4) uint8`` (None when the example has none), ``face_material (#F,)`` into the
        example's ``materials`` (textures included).
    face_labels : (#F,) int64
        The label of the piece each face comes from.
    label_grid : int64 array
        The label of every construction cell: ``(S_X, S_Y, S_Z)`` for one curve, ``(cells,)`` for a
        curve network (cells of each part in turn, see ``labels``).
    labels : dict
        What ``labels.json`` holds: the label grid (per arm and junction for a network), the example's
        lattice, label grid, representative pieces, feature vectors and adjacency constraints.
    target_net, example_net : ColouredPetriNet
        The target net after inference and the example's net (written as PNML/DOT, ``output.export_net``).
    baseline_net : ColouredPetriNet or None
        The orthogonal-lattice baseline's net (``output.baseline``).
    example : Asset
        The example as read (its materials and textures are the result's).
    look : Look or None
        The result faces' appearance as carried through the pieces (float colours).
    scene : PreviewScene
        What the previews draw.
    """

    method: ClassVar[str] = "petri-synth"
    mesh: trimesh.Trimesh
    asset: Asset
    face_labels: np.ndarray
    label_grid: np.ndarray
    labels: dict
    target_net: ColouredPetriNet
    example_net: ColouredPetriNet
    baseline_net: ColouredPetriNet | None = None
    example: Asset
    look: Look | None = None
    scene: PreviewScene = field(repr=False)

    def write(self, ctx) -> None:
        """Write ``result.<mesh_format>`` (with ``before_after.png`` for an example with an appearance),
        ``labels.json``, the nets and the previews, as the command line does."""
        write_mesh(ctx, self.config.output.mesh_format, self.example, self.asset, self.face_labels, self.look)
        write_text_atomic(ctx.path("labels", "labels.json"), json.dumps(self.labels) + "\n")
        with ctx.stage("export"):
            export_nets(ctx, self.config.output.export_net, self.target_net, self.example_net)
        with ctx.stage("previews"):
            write_previews(ctx, self.target_net, self.baseline_net, self.example_net, self.label_grid, self.scene)


def result_asset(example: Asset, V: np.ndarray, F: np.ndarray, look: Look | None) -> Asset:
    """The result ``V, F`` with the faces' ``look`` and the example's materials."""
    written = {} if look is None else look.written()
    fm = written.get("face_material")
    return Asset(V=V, F=F, corner_uv=written.get("corner_uv"), corner_color=written.get("corner_color"),
                 face_material=np.zeros(len(F), np.int64) if fm is None else fm, materials=example.materials,
                 name="petri-synth result", source=example.source)


def write_mesh(ctx, mesh_format: str, example: Asset, asset: Asset, face_label, look: Look | None) -> None:
    """Write the result mesh (``output.mesh_format``) with the example's appearance: GLB with its PBR
    materials and textures, OBJ with an MTL and texture copies, USD with UsdPreviewSurface materials
    and texture copies, PLY with colours; a PLY of an example
    without colours stores each face's label instead. An example with an appearance also gets
    ``before_after.png``: example above result, textured, from three views (the summary)."""
    V, F = asset.V, asset.F
    out_mesh = ctx.path("mesh", f"result{mesh_suffix(mesh_format)}")
    if mesh_format == "ply" and (look is None or look.corner_color is None):
        save_mesh(trimesh.Trimesh(V, F, process=False), out_mesh, face_labels=face_label)
        return
    appearance = {} if look is None else look.written()
    written = save_asset(out_mesh, V, F, like=example, **appearance)
    for k, name in enumerate(written[1:]):
        ctx.outputs[f"mesh_file_{k}"] = name
    if look is not None and (example.textured or example.corner_color is not None) and ctx.wants_preview("summary"):
        before = (example.V, example.F, preview.Appearance.of(example, like_input=True))
        after = (V, F, preview.Appearance.of(example, **appearance))
        preview.before_after_png(ctx.path("before_after", "before_after.png"), before, after, size=320)


def export_nets(ctx, export: str, net: ColouredPetriNet, ex_net: ColouredPetriNet) -> None:
    """Write the target net and the example net as PNML and/or DOT (``output.export_net``)."""
    if export in ("pnml", "both"):
        write_bytes_atomic(ctx.path("net_pnml", "target_net.pnml"), to_pnml(net, net_id="target"))
        write_bytes_atomic(ctx.path("example_net_pnml", "example_net.pnml"), to_pnml(ex_net, net_id="example"))
    if export in ("dot", "both"):
        write_text_atomic(ctx.path("net_dot", "target_net.dot"), to_dot(net, name="target"))
        write_text_atomic(ctx.path("example_net_dot", "example_net.dot"), to_dot(ex_net, name="example"))


def write_previews(ctx, net, bnet, ex_net, labels_out, scene: PreviewScene) -> None:
    """``result.png`` (the summary preview), ``construction_space.png`` (the example in the curve's view
    with the scene's lines drawn over it) and ``montage.png`` (example, space, result and, when run,
    the baseline ``bnet``), from pieces decimated to about :data:`PREVIEW_FACES` triangles in all."""
    if not ctx.wants_preview("summary"):
        return
    grid = scene.example_grid
    colors = label_colors(max(net.n_labels, 1))
    n_max = max(net.n_cells, grid.size)
    lib_xyz = preview_library(scene.library, max(PREVIEW_FACES // n_max, 64))
    lib_abc = reorder_library(lib_xyz, scene.axes)
    PV, PF, p_label = assemble(lib_abc, labels_out, net.corners)
    small, large = {"size": 320}, {"size": 512}
    img_res = preview.rasterize_mesh(PV, PF, face_colors=colors[p_label], view="iso", **large)
    preview.image_png(ctx.path("preview_result", "result.png"), img_res)
    if not ctx.wants_preview("all"):
        return
    EV, EF, e_label = assemble(lib_xyz, grid, ex_net.corners)
    img_ex = preview.rasterize_mesh(EV, EF, face_colors=colors[e_label], view="iso", **small)
    img_space = preview.rasterize_mesh(EV, EF, view=VIEW_OF_PLANE[scene.plane], lines=scene.lines, **large)
    preview.image_png(ctx.path("preview_space", "construction_space.png"), img_space)
    images = [img_ex, img_space[::2, ::2][:320, :320], img_res[::2, ::2][:320, :320]]
    if bnet is not None:
        BPV, BPF, bp_label = assemble(lib_abc, bnet.label_grid(), bnet.corners)
        images.append(preview.rasterize_mesh(BPV, BPF, face_colors=colors[bp_label], view="iso", **small))
    preview.montage_png(ctx.path("preview_montage", "montage.png"), images)
