"""Detail transfer by graph-cut patch synthesis over surfaces (Zelinka and Garland, section 4).

Stages over arrays (each raises ValueError on bad input): :mod:`.surface` (a region submesh with
its signal, frames and log-map solver), :mod:`.fans` (geodesic fans and their search structure,
4.2), :mod:`.param` (mutual bounded-distortion parameterization, 4.3), :mod:`.trim` (seam costs and
the dual-graph min cut with seam nodes, 4.4), :mod:`.position` (target position grading, 4.1),
:mod:`.synth` (the four steps iterated), :mod:`.extract` (extraction, kernel blending and geometry
transfer, 4.5-4.6). :mod:`.pipeline` reads and runs them, :mod:`.outputs` holds the result and
writes its files.
"""
