"""Symmetry-guided texture synthesis and processing (Kim, Lipman, Funkhouser).

Stages: :mod:`.common` builds the objective and its targets; :mod:`.synth` (guided quilting),
:mod:`.deform` (ARAP warping, tiling) and :mod:`.lens` (radial undistortion) optimize it;
:mod:`.pipeline` runs a config's mode.
"""

SET_EXAMPLE = "synth.patch=24"
"""A real key of this method, shown in ``--set``'s help."""

INIT_VALUES = {"mode": "quilt"}
"""Example values ``synthkit init`` writes for keys a config must give (dotted key -> value)."""
