"""Segment a mesh into the regions stroked by the user, by graph cut (Zelinka and Garland).

Surfacing by numbers, section 3: region-centric interactive surface segmentation (mode: segment).

Stages: :mod:`.strokes` turns vertex, face and polyline strokes into fixed nodes; :mod:`.graph`
builds the vertex or face graph with the area-weighted boundary cost of eq. 1; :mod:`.regions`
adds the optional region term; :mod:`.lod` builds the quadric level-of-detail hierarchy and
:mod:`.solve` cuts it (s-t min cut for two regions, alpha-expansion for more, refined in bands);
:mod:`.segment` ties them together over arrays; :mod:`.pipeline` reads, runs and writes.
"""
