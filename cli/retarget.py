"""``synthkit retarget``: resize a man-made mesh along its dominant repetitions."""

from .options import method_command

command = method_command(
    "retarget",
    "Retarget a mesh by offset statistics and a multi-label graph cut (Wu et al.).",
    flags={"--analyze-only": ("analyze_only=true", "Stop after the offset statistics; write the report.")},
)
