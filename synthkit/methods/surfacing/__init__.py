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

from synthkit.methods.spec import MethodSpec

SPEC = MethodSpec(
    functions=("segment", "transfer"),
    headline=("graph_nodes",),
    summary_keys=("preview_regions", "preview_transfer"),
    main_keys=("transferred", "labels_ply"),
    cli_flags={
        "--render-views": ("views.render=true", "Also write the named views and their cameras, to paint strokes on.")
    },
    set_example="boundary.eta=2",
    init_values={"regions": [{"name": "a", "vertices": [0]}, {"name": "b", "vertices": [1]}]},
)
