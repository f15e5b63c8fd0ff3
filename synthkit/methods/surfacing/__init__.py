"""Segment a mesh into the regions stroked by the user, by graph cut (Zelinka and Garland).

Surfacing by numbers, section 3: region-centric interactive surface segmentation (mode: segment).

Stages: :mod:`.strokes` turns vertex, face and polyline strokes into fixed nodes; :mod:`.graph`
builds the vertex or face graph with the area-weighted boundary cost of eq. 1; :mod:`.regions`
adds the optional region term; :mod:`.lod` builds the quadric level-of-detail hierarchy and
:mod:`.solve` cuts it (s-t min cut for two regions, alpha-expansion for more, refined in bands);
:mod:`.segment` ties them together over arrays. Around them: :mod:`.config` (the schema),
:mod:`.options` (config keys to stage options), :mod:`.prepare` (strokes and segmentation, for
both modes), :mod:`.pipeline` (reads and runs; mode transfer in :mod:`.transfer.pipeline`),
:mod:`.outputs` (the result and its files) and :mod:`.api` (``synthkit.segment`` and
``synthkit.transfer``).
"""

CLI_FLAGS = {
    "--render-views": ("views.render=true", "Also write the named views and their cameras, to paint strokes on.")
}
"""Extra boolean options of ``synthkit surface-by-numbers``: flag -> (--set override, help)."""

SET_EXAMPLE = "boundary.eta=2"
"""A real key of this method, shown in ``--set``'s help."""

INIT_VALUES = {"regions": [{"name": "a", "vertices": [0]}, {"name": "b", "vertices": [1]}]}
"""Example values ``synthkit init`` writes for keys a config must give (dotted key -> value)."""
