"""``synthkit.retarget``: retarget a mesh in memory (:mod:`synthkit.api`)."""

from __future__ import annotations

from typing import Any

from synthkit.api import prepare, run_in_memory
from synthkit.methods.retarget.outputs import RetargetResult
from synthkit.methods.retarget.pipeline import compute

__all__ = ["retarget"]


def retarget(mesh, /, *, progress: bool = False, **keys: Any) -> RetargetResult:
    """Resize a man-made mesh along its repetitions by offset statistics and a multi-label graph
    cut (Wu et al., *3-D model retargeting with sparse offset statistics*).

    Parameters
    ----------
    mesh : trimesh.Trimesh, trimesh.Scene, (V, F) arrays, Asset or path
        The input: ``V (#V, 3)`` float positions and ``F (#F, 3)`` int triangles; a
        ``trimesh.Trimesh`` or :class:`~synthkit.asset.Asset` keeps its UVs, vertex colours,
        materials and textures on every retargeted face; a path is read as from a config.
    progress : bool
        Show stage lines and progress bars on a terminal's stderr.
    **keys
        The keys of a ``retarget`` config (docs/retarget.md), validated with the command line's
        messages: ``target={"axis_steps": {"x": 2}}`` (or ``{"steps": [1]}``, ``{"scale": [1.5]}``),
        ``analysis={"dense_radius": 0.03, ...}``, ``analyze_only=True``, ``offsets="regular"``,
        ``compare_baseline=True``, ``pins=[...]``, ``seed=0``, ...

    Returns
    -------
    RetargetResult
        ``mesh`` (``trimesh.Trimesh``, ``process=False``) and ``asset``
        (:class:`~synthkit.asset.Asset` with ``corner_uv (#F, 3, 2)``, ``face_material (#F,)``,
        ``corner_color (#F, 3, 4)`` and the input's materials): the retargeted mesh in the input's
        units, None with ``analyze_only``; ``retargeted`` and ``baseline``
        (:class:`~synthkit.methods.retarget.outputs.RetargetedMesh`: also ``label_volume (X, Y, Z)
        int32``, ``labelled_mesh`` and its ``face_labels``); the statistics as arrays:
        ``principal_offsets (k, 3)``, ``dominant_offsets (m, 3)``, ``dominant_counts (m,)``,
        ``sparsity_curve (n, 2)``, ``histogram_bins (b, 3)``, ``histogram_counts (b,)`` and
        ``analysis``; ``metrics`` (as ``report.json``: ``n_principal``, ``sparsity_top7``,
        ``graph_nodes``, ``energy``, ``mesh_quality``, ...), ``timings``, ``status``.
        :meth:`~synthkit.api.Result.save` writes the command line's output folder.

    Raises
    ------
    ConfigError
        An unknown key or a value out of range; steps that would leave fewer than two cells along
        an offset (``target.steps[0]=-6: would shrink below one cell``); bad ``pins``.
    InputError
        A mesh without faces or of zero area; no repetition found (unless ``analyze_only``: the
        statistics then say why); steps along an axis without a principal offset; no seamless
        labeling for the steps.

    Examples
    --------
    A bookshelf of 3 x 2 cells grows by one row of shelves (its lattice steps are 0.40 across and
    0.35 up; the sampling is coarser than the paper's, so that this runs in a few seconds):

    >>> import synthkit
    >>> from synthkit.samples.retarget import build_bookshelf
    >>> V, F, truth = build_bookshelf(cols=3, rows=2, step=None)
    >>> result = synthkit.retarget((V, F), target={"axis_steps": {"y": 1}},
    ...                            analysis={"dense_radius": 0.04, "feature_radius": 0.1}, seed=0)
    >>> result.metrics["n_principal"], (result.principal_offsets.round(2) + 0.0).tolist()
    (2, [[0.4, 0.0, 0.0], [0.0, 0.35, 0.0]])
    >>> ((result.mesh.extents - (V.max(axis=0) - V.min(axis=0))).round(2) + 0.0).tolist()
    [0.0, 0.35, 0.0]
    >>> result.save("shelf-taller")  # doctest: +SKIP
    """
    cfg, inputs = prepare("retarget", "synthkit.retarget()", {"input": mesh}, keys)
    return run_in_memory("retarget", "synthkit.retarget()", compute, cfg, inputs, progress=progress)
