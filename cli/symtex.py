"""``synthkit symmetry-texture``: symmetry-guided texture synthesis, filtering, tiling, symmetrization."""

from .options import method_command

command = method_command(
    "symmetry-texture",
    "Symmetry-guided texture synthesis and processing (Kim, Lipman, Funkhouser).",
)
