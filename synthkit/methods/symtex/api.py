"""``synthkit.symmetry_texture``: symmetry-guided texture synthesis on images in memory."""

from __future__ import annotations

from typing import Any

from synthkit.api import prepare, run_in_memory
from synthkit.methods.symtex.outputs import SymmetryTextureResult
from synthkit.methods.symtex.pipeline import compute

__all__ = ["symmetry_texture", "SymmetryTextureResult"]


def symmetry_texture(source, /, target=None, *, progress: bool = False, **keys: Any) -> SymmetryTextureResult:
    """Synthesize, filter, tile or symmetrize a texture by its symmetry representation.

    The same run as ``synthkit symmetry-texture`` on a config with these keys (Kim, Lipman and
    Funkhouser 2012); nothing is written until :meth:`~synthkit.api.Result.save`.

    Parameters
    ----------
    source : (H, W[, C]) ndarray or path
        The source image f: ``uint8``, ``uint16`` or float in [0, 1], grey, RGB or RGBA (alpha
        over white), or a file name. At least 8x8 and not blank.
    target : (H, W[, C]) ndarray or path, optional
        The target image or sketch g of ``mode="transfer"``.
    progress : bool
        Show stage lines and progress bars on a terminal.
    **keys
        The config's keys (docs/symmetry-texture.md), sections as dicts: ``mode`` (required:
        ``"transfer"``, ``"filter"``, ``"tile"``, ``"symmetrize"`` or ``"quilt"``),
        ``output_size=(h, w)``, ``perturbation``, ``symmetry={"signals": ["lum"]}``,
        ``synth={"patch": 16, "overlap": 6}``, ``filter={"kind": "scale"}``, ``deform``,
        ``lens``, ``tile``, ``baseline``, ``seed``.

    Returns
    -------
    SymmetryTextureResult
        ``image (H, W, 3) float32`` (the mode's result), ``source``, ``s_input``, ``s_target``,
        ``s_result`` (S_T lattices ``(2 wy + 1, 2 wx + 1)`` or S_R / S_Ref curves
        ``(n_angles,)``), ``baseline`` (unguided quilting, with ``baseline=True``),
        ``sample_map (H, W, 2) float32`` (deform), ``tiles`` (mode tile, by name),
        ``k1_search (n, 2)`` (lens), ``comparison()`` (the montage of ``comparison.png``),
        ``metrics`` (``objective_start``, ``objective_end``, ... as in ``report.json``),
        ``timings``, ``status``, and ``save(folder)``.

    Raises
    ------
    ConfigError
        A key is unknown or out of range, or the keys do not fit together (``mode: transfer``
        without a target, a patch larger than the source): the command line's message, naming
        the key.
    InputError
        An image is smaller than 8x8, blank, or has a constant signal; a path does not exist.

    Examples
    --------
    >>> import synthkit
    >>> from synthkit.samples import textures
    >>> r = synthkit.symmetry_texture(textures.noise(64), textures.dots(64), mode="transfer",
    ...                               output_size=(48, 48), symmetry={"signals": ["lum"]},
    ...                               synth={"patch": 16, "overlap": 6, "candidates": 4, "sweeps": 1})
    >>> r.image.shape, r.image.dtype.name
    ((48, 48, 3), 'float32')
    >>> r.metrics["objective_end"] <= r.metrics["objective_start"]
    True
    """
    given = {"source": source} if target is None else {"source": source, "target": target}
    cfg, inputs = prepare("symmetry-texture", "synthkit.symmetry_texture()", given, keys)
    return run_in_memory("symmetry-texture", "synthkit.symmetry_texture()", compute, cfg, inputs,
                         progress=progress)
