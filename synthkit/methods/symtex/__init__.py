"""Symmetry-guided texture synthesis and processing (Kim, Lipman, Funkhouser).

Stages: :mod:`.common` builds the objective and its targets; :mod:`.synth` (guided quilting),
:mod:`.deform` (ARAP warping, tiling) and :mod:`.lens` (radial undistortion) optimize it;
:mod:`.pipeline` runs a config's mode.
"""
