"""Reshape an architectural mesh keeping edge directions and short edges (Cabral et al.).

Structure-preserving reshape of textured architectural scenes (Cabral, Lefebvre, Dachsbacher,
Drettakis, Eurographics 2009), geometry part (sections 3 and 5): a constraint graph of the textured
surfaces, strict and soft linear constraints solved by least squares with a Cholesky factorization
cached per handle set, handles dragged in steps with a collapse check, and chains of pieces joined
at their portals. UVs and materials are kept; the texture reshape (section 4) is not part of it.
"""

SET_EXAMPLE = "solver.steps=20"
"""A real key of this method, shown in ``--set``'s help."""

INIT_VALUES = {"handles": [{"index": [0], "displacement": [0.0, 1.0, 0.0]}]}
"""Example values ``synthkit init`` writes for keys a config must give (dotted key -> value)."""

INIT_REQUIRED = ("input",)
"""Optional keys ``synthkit init`` marks REQUIRED (``input``, or ``pieces`` for a chain)."""

