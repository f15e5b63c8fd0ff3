"""Synthesize a model along a user curve with a coloured Petri net and FFD (Song et al.).

Synthesis of 3D models by a coloured Petri net (Song, Sun, Zhang, Zhang 2013).

Stages: :mod:`.analysis` cuts the example by a lattice into pieces, labels them by their feature
vectors and collects the adjacency constraints; :mod:`.construction` (one curve) and :mod:`.network`
(a curve network) build the space of hexahedral cells (Algorithm 1), both behind :mod:`.spaces`;
:mod:`.net` holds the coloured Petri net and its inference (Algorithm 2) plus the plain AC-3
baseline; :mod:`.assembly` deforms the chosen pieces into their cells, :mod:`.joints` joins them,
:mod:`.evaluation` measures the result. :mod:`.options` maps the config to the stages' arguments,
:mod:`.pipeline` runs it all (:func:`synthkit.petri_synth`), :mod:`.outputs` writes the files.
"""

from synthkit.methods.spec import MethodSpec

SPEC = MethodSpec(
    functions=("petri_synth",),
    headline=("cells", "labels", "adjacency_violations", "normal_histogram_D"),
    summary_keys=("before_after", "preview_montage"),
    main_keys=("mesh",),
    set_example="inference.max_restarts=5",
    init_values={"lattice.unit": [1.0, 1.0, 1.0], "construction.points": [[0.0, 0.0], [10.0, 0.0]]},
)
