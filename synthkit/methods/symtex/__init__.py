"""Symmetry-guided texture synthesis and processing (Kim, Lipman, Funkhouser).

Rooms: :mod:`.config` (the schema), :mod:`.options` (stage arguments built from a config),
stage modules over arrays (:mod:`.common` the objective and its targets, :mod:`.objective`,
:mod:`.synth` guided quilting, :mod:`.deform` ARAP warping, :mod:`.tile` the tile candidates,
:mod:`.lens` radial undistortion), :mod:`.pipeline` (inputs, stages, error mapping; ``compute``
and ``run``), :mod:`.outputs` (the result and its files) and :mod:`.api`
(``synthkit.symmetry_texture``).
"""

SET_EXAMPLE = "synth.patch=24"
"""A real key of this method, shown in ``--set``'s help."""

INIT_VALUES = {"mode": "quilt"}
"""Example values ``synthkit init`` writes for keys a config must give (dotted key -> value)."""
