"""``synthkit petri-synth``: build a large model from an example's lattice pieces along a curve."""

from .options import method_command

command = method_command(
    "petri-synth",
    "Synthesize a model along a user curve with a coloured Petri net and FFD (Song et al.).",
)
