"""Retarget a mesh by offset statistics and a multi-label graph cut (Wu et al.).

3-D model retargeting with sparse offset statistics (Wu, Li, Wand, Hildebrandt, Jansen, Seidel)."""

from synthkit.methods.spec import MethodSpec

SPEC = MethodSpec(
    functions=("retarget",),
    headline=("n_principal", "sparsity_top7", "graph_nodes", "graph_labels", "energy"),
    summary_keys=("comparison", "before"),
    main_keys=("mesh",),
    cli_flags={"--analyze-only": ("analyze_only=true", "Stop after the offset statistics; write the report.")},
    set_example="analysis.dense_radius=0.03",
)
