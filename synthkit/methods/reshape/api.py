"""``synthkit.reshape``: structure-preserving reshape of a textured mesh in memory."""

from __future__ import annotations

from synthkit.api import prepare, run_in_memory
from synthkit.methods.reshape.outputs import ReshapeResult
from synthkit.methods.reshape.pipeline import compute

__all__ = ["reshape"]


def reshape(mesh=None, /, *, progress: bool = False, **keys) -> ReshapeResult:
    """Reshape an architectural mesh keeping edge directions and short edges (Cabral et al. 2009),
    and its textures with it.

    Parameters
    ----------
    mesh : trimesh.Trimesh, trimesh.Scene, (V, F) arrays, Asset or path, optional
        The mesh to reshape: the config's ``input`` key. A trimesh's UVs and texture images (a
        ``TextureVisuals`` with a material image) are kept and reshaped like an OBJ's; ``(V, F)``
        is ``V (#V, 3)`` float positions and ``F (#F, 3)`` int triangles, without texture. Leave it
        out to give ``pieces`` (a chain), whose ``input`` keys may hold mesh objects too.
    progress : bool
        Show stage lines and a progress bar on a terminal.
    **keys
        The config's keys (see ``docs/reshape.md``), sections as dicts: exactly one of ``scale``
        (``{"x": 1.3}``), ``size`` or ``handles`` (with ``fixed``), and ``texture``, ``stiffness``,
        ``solver``, ``chain``, ... A selection by ``index`` counts the mesh's vertices.

    Returns
    -------
    ReshapeResult
        ``meshes`` (piece name -> reshaped ``trimesh.Trimesh``; ``mesh`` for an ``input`` given in
        memory, else the file's stem; ``.mesh`` is the first), ``textured`` (piece name -> the
        reshaped TexturedMesh, render vertices ``V (#V, 3)`` and ``UV (#V, 2)``), ``retexture``
        (piece name -> the reshaped surfaces' entries, each a baked ``image (H, W, 3) float32``;
        ``.images`` gathers them by file name), ``asset(name)`` (a piece given in memory as an
        Asset with its new materials), ``X (n, 3)`` graph node positions, ``metrics`` (as in
        ``report.json``), ``timings``, ``status``; ``save(folder)`` writes what ``synthkit run``
        writes.

    Raises
    ------
    ConfigError
        A key is unknown or out of range, or the recipe cannot be solved as asked (the command
        line's message, naming the key).
    InputError
        A mesh has no faces, a file is missing, or the motion would flip an edge.

    Examples
    --------
    >>> import trimesh, synthkit
    >>> box = trimesh.creation.box(extents=(4.0, 3.0, 0.2))
    >>> result = synthkit.reshape(box, scale={"x": 1.5}, texture="stretch")
    >>> [round(float(e), 6) for e in result.mesh.extents]
    [6.0, 3.0, 0.2]
    >>> result.status
    'ok'
    """
    given = {} if mesh is None else {"input": mesh}
    cfg, inputs = prepare("reshape", "synthkit.reshape()", given, keys)
    return run_in_memory("reshape", "synthkit.reshape()", compute, cfg, inputs, progress=progress)
