"""Texture reshape (Cabral et al. 2009, section 4): directional autosimilarity, deformation grid,
corner and interior solves, toroidal repetitions, distortion map and detail reintroduction.

Modules work on arrays in *texel coordinates*: ``x`` along image columns, ``y`` along image rows
(down), pixel centres at ``+0.5``; a UV ``(u, v)`` is the texel point ``(u W, (1 - v) H)``.

- :mod:`.autosim`: luminance equalization and the directional autosimilarity maps (eq. 9).
- :mod:`.grid`: the deformation grid of one surface, intersected with its contour by a DDA (4.3).
- :mod:`.solve`: corner solve (eq. 10 with 2-D eq. 1), interior solve (eqs. 11-13), both
  prefactored (4.4), and the toroidal repetitions.
- :mod:`.detail`: rigid/stochastic segmentation [BJ01], spiral tile growth, tile map, bilateral
  base/detail split (4.5).
- :mod:`.bake`: distortion map, stretch map and the offline evaluation of the paper's shader.
- :mod:`.surface`: one textured surface through every stage.
"""
