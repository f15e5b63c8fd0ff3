"""``synthkit.segment`` and ``synthkit.transfer``: surfacing by numbers over meshes in memory."""

from __future__ import annotations

from synthkit.api import prepare, run_in_memory
from synthkit.methods.surfacing.outputs import SegmentResult
from synthkit.methods.surfacing.pipeline import compute, with_mode
from synthkit.methods.surfacing.transfer.outputs import TransferResult

__all__ = ["segment", "transfer"]

METHOD = "surface-by-numbers"


def segment(mesh, /, *, progress: bool = False, **keys) -> SegmentResult:
    """Segment ``mesh`` into the regions stroked by the user, by graph cut (Zelinka and Garland,
    section 3), as ``synthkit surface-by-numbers`` does with ``mode: segment``; nothing is written.

    Parameters
    ----------
    mesh : trimesh.Trimesh, trimesh.Scene, ``(V, F)`` arrays (``V (#V, 3)`` float, ``F (#F, 3)`` int),
        :class:`~synthkit.asset.Asset` or a path to a mesh file
    progress : show stage lines and progress bars on a terminal's stderr
    **keys : the config's keys (docs/surface-by-numbers.md), a section as a dict:
        ``regions=[{"name": "body", "vertices": [730]}, ...]`` (at least two regions, each with
        ``vertices``, ``faces``, ``points`` polylines or paint), ``boundary={"eta": 1.0}``,
        ``region_term={"model": "none"}``, ``graph="vertex"``, ``seed=0``, ... Painted stroke images
        may be arrays: ``images=[{"image": img, "view": "front", "colors": {"body": [220, 40, 40]}}]``
        with ``img`` ``(S, S, 3)`` uint8 or float in [0, 1], ``S = views.size``. ``mode`` is
        ``"segment"`` (another value is refused).

    Returns
    -------
    SegmentResult
        ``face_labels (#F,) int32`` (index into ``region_names``), ``vertex_labels (#V,) int32``,
        ``region_names`` (L), ``region_colors (L, 3) uint8``, ``cut_edges (E, 2)`` vertex pairs,
        ``cut_chains`` (vertex-index polylines), ``cut_curves`` (smoothed ``(n, 3)`` polylines with
        ``smooth_cut``, else None), ``stroked_faces (#F,) bool``, ``levels``, ``view_images`` and
        ``cameras`` (with ``views={"render": True}``), ``region_mesh(name)``, ``summary_image()``
        (``regions.png`` as an array), the input ``mesh``,
        ``metrics``, ``timings``, ``status``; ``.save(folder)`` writes the command line's outputs
        (labels.ply, labels.seg, cut.obj, regions/, regions.png, report.json).

    Raises
    ------
    ConfigError
        A key unknown or out of range, fewer than two regions, a stroke index out of range, a point
        off the surface, a region without strokes, a painted image of the wrong size (the command
        line's message, naming the key).
    InputError
        A mesh without faces or non-finite positions, an unreadable file.

    Examples
    --------
    Two boxes glued along a concave crease, one stroke on each; the cut follows the crease:

    >>> import numpy as np, synthkit
    >>> from synthkit.samples.surfacing import crease_boxes, part_centre_vertices
    >>> V, F, part = crease_boxes()
    >>> a, b = part_centre_vertices(V, F, part)
    >>> result = synthkit.segment((V, F), regions=[{"name": "long", "vertices": [a]},
    ...                                            {"name": "short", "vertices": [b]}])
    >>> result.face_labels.shape == (len(F),), result.region_names
    (True, ['long', 'short'])
    >>> bool((result.face_labels == part).all())
    True
    """
    call = "synthkit.segment()"
    cfg, inputs = prepare(METHOD, call, {"input": mesh}, with_mode(keys, "segment", call))
    return run_in_memory(METHOD, call, compute, cfg, inputs, progress=progress)


def transfer(mesh, /, *, progress: bool = False, **keys) -> TransferResult:
    """Synthesize detail (colour, texture, displacement or a vertex property) from source regions
    over target regions of ``mesh`` by graph-cut patch synthesis (Zelinka and Garland, section 4),
    as ``synthkit surface-by-numbers`` does with ``mode: transfer``; nothing is written.

    Parameters
    ----------
    mesh : the target: trimesh.Trimesh (its vertex colours or texture are kept outside the target
        regions), trimesh.Scene, ``(V, F)`` arrays, :class:`~synthkit.asset.Asset` or a path
    progress : show stage lines and progress bars on a terminal's stderr
    **keys : the config's keys (docs/surface-by-numbers.md), sections as dicts:
        ``transfer={"pairs": [{"target": ..., "source": ..., "signal": "color"}], "synthesis": {...},
        "extraction": {...}, "baseline": False}``, and ``regions`` when a target or source region
        is given by strokes. In memory: a pair's ``target.labels`` or ``source.labels`` may be a
        ``(#F,)`` integer array of face labels, ``source.mesh`` a mesh (as ``mesh``),
        ``source.image`` an ``(H, W, 3)`` image array and ``source.mask`` an ``(H, W)`` array.
        ``mode`` is ``"transfer"`` (another value is refused).

    Returns
    -------
    TransferResult
        ``mesh`` (trimesh.Trimesh with the transferred vertex colours and displaced positions),
        ``asset`` (:class:`~synthkit.asset.Asset` with corner UVs into ``textures`` for texture
        pairs), ``positions (#V, 3)``, ``faces (#F, 3)``, ``colors (#V, 3)`` in [0, 1],
        ``attributes`` (name -> ``(#V, C)``), ``patch_ids (#F,)`` (-1 outside the targets),
        ``corner_uv (#F, 3, 2)`` and ``face_material (#F,)`` or None, ``textures`` (the images the
        materials use, ``(H, W, 3)`` float), ``seam_field (#F,)``, ``summary_image()`` (``transfer.png``
        as an array), ``metrics`` (coverage, seam cost,
        distortion, per pair), ``timings``, ``status`` (``partial`` when faces stayed uncovered);
        ``.save(folder)`` writes transferred.ply, patches.ply, transferred.obj, the previews and
        report.json.

    Raises
    ------
    ConfigError
        A key unknown or out of range, an empty target or source region, a source without the
        signal, a source region smaller than one patch (the command line's message, naming the key).
    InputError
        A mesh without faces, an unreadable file, a labels array of the wrong length.

    Examples
    --------
    Three-colour stripes from a flat grid onto the side of a capped cylinder (label 0):

    >>> import numpy as np, trimesh, synthkit
    >>> from synthkit.samples import surfacing_transfer as sample
    >>> S, G, colors = sample.stripes(40)
    >>> V, F, labels = sample.cylinder(24, 8)
    >>> stripes = trimesh.Trimesh(S, G, vertex_colors=colors, process=False)
    >>> pair = {"target": {"labels": labels, "label": 0}, "source": {"mesh": stripes}, "signal": "color"}
    >>> nearest = {"sampling": "nearest", "blend": "none"}  # each vertex takes one source colour
    >>> result = synthkit.transfer((V, F), transfer={"pairs": [pair], "extraction": nearest})
    >>> result.metrics["coverage"], result.colors.shape == (len(V), 3)
    (1.0, True)
    >>> side = np.round(result.colors[np.unique(F[labels == 0])] * 255).astype(int)
    >>> {tuple(c) for c in side.tolist()} <= {tuple(c) for c in sample.PALETTE.tolist()}
    True
    """
    call = "synthkit.transfer()"
    cfg, inputs = prepare(METHOD, call, {"input": mesh}, with_mode(keys, "transfer", call))
    return run_in_memory(METHOD, call, compute, cfg, inputs, progress=progress)
