"""Retarget a mesh by offset statistics and a multi-label graph cut (Wu et al.).

3-D model retargeting with sparse offset statistics (Wu, Li, Wand, Hildebrandt, Jansen, Seidel)."""

CLI_FLAGS = {"--analyze-only": ("analyze_only=true", "Stop after the offset statistics; write the report.")}
"""Extra boolean options of ``synthkit retarget``: flag -> (--set override, help)."""

SET_EXAMPLE = "analysis.dense_radius=0.03"
"""A real key of this method, shown in ``--set``'s help."""
