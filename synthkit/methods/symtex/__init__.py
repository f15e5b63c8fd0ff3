"""Symmetry-guided texture synthesis and processing (Kim, Lipman, Funkhouser).

Rooms: :mod:`.config` (the schema), :mod:`.options` (stage arguments built from a config),
stage modules over arrays (:mod:`.common` the objective and its targets, :mod:`.objective`,
:mod:`.synth` guided quilting, :mod:`.deform` ARAP warping, :mod:`.tile` the tile candidates,
:mod:`.lens` radial undistortion), :mod:`.pipeline` (inputs, stages, error mapping; ``compute``
and ``run``), :mod:`.outputs` (the result and its files) and :mod:`.api`
(``synthkit.symmetry_texture``).
"""

from synthkit.methods.spec import MethodSpec

SPEC = MethodSpec(
    functions=("symmetry_texture",),
    headline=("objective_start", "objective_end", "baseline_objective"),
    summary_keys=("comparison", "result"),
    main_keys=("result",),
    set_example="synth.patch=24",
    init_values={"mode": "quilt"},
)
