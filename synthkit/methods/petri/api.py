"""``synthkit.petri_synth``: Petri-net synthesis along a curve on an example mesh in memory."""

from __future__ import annotations

from synthkit.api import prepare, run_in_memory
from synthkit.methods.petri.outputs import PetriResult
from synthkit.methods.petri.pipeline import compute

__all__ = ["petri_synth"]

CALL = "synthkit.petri_synth()"


def petri_synth(example, /, *, progress: bool = False, **keys) -> PetriResult:
    """Extend and deform an example's lattice pieces along a curve (or a curve network) with a
    coloured Petri net and trilinear FFD (Song et al. 2013), in memory.

    Parameters
    ----------
    example : trimesh.Trimesh, trimesh.Scene, (V, F) arrays, Asset or path
        The example model: ``V (#V, 3)`` positions and ``F (#F, 3)`` triangles. A textured or
        coloured mesh (trimesh visuals, an :class:`~synthkit.asset.Asset`, a file) carries its
        UVs, colours and materials into the result.
    progress : bool
        Show the stage lines and progress bars on a terminal.
    **keys
        The keys of a ``petri-synth`` config, sections as dicts: ``lattice={"unit": [2, 3, 2]}``,
        ``construction={"plane": "xz", "points": [[0, 0], [12, 0]]}``, ``labels``, ``inference``,
        ``output``, ``seed``. See `docs/petri-synth.md <../docs/petri-synth.md>`_.

    Returns
    -------
    PetriResult
        ``mesh`` (trimesh, ``(#V, 3)`` / ``(#F, 3)``), ``asset`` (the same with the example's UVs,
        colours and materials), ``face_labels (#F,)``, ``label_grid`` (``(S_X, S_Y, S_Z)`` for one
        curve, ``(cells,)`` for a network), ``labels`` (what ``labels.json`` holds), ``target_net``,
        ``example_net`` and ``baseline_net`` (:class:`~synthkit.methods.petri.net.ColouredPetriNet`),
        ``metrics``, ``timings``, ``status``; ``.save(folder)`` writes the command line's folder.

    Raises
    ------
    ConfigError
        A key is unknown or out of range, the lattice does not fit the example, the curve is too short
        or its cells intersect (the command line's message, naming the key).
    InputError
        The example has no faces, or its adjacency constraints cannot fill the construction space.

    Examples
    --------
    >>> import synthkit
    >>> from synthkit.samples import petri
    >>> V, F = petri.building()
    >>> result = synthkit.petri_synth((V, F), seed=7, lattice={"unit": [2.0, 3.0, 2.0]},
    ...                               construction={"plane": "xz", "points": [[0.0, 0.0], [16.0, 0.0]]})
    >>> result.label_grid.shape
    (8, 2, 4)
    >>> result.metrics["adjacency_violations"]
    0
    """
    cfg, inputs = prepare("petri-synth", CALL, {"example": example}, keys)
    return run_in_memory("petri-synth", CALL, compute, cfg, inputs, progress=progress)
