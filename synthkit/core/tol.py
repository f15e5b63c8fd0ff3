"""synthkit's tolerances in one object, :data:`tol` (as ``trimesh.tol``). Each is a share of a scale
its user names (a bounding-box diagonal, a squared extent, an energy), never an absolute length."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Tolerances", "tol"]


@dataclass(frozen=True)
class Tolerances:
    """Attributes
    ----------
    plane : a vertex within this share of the bounding-box diagonal of a clipping plane is on it
        (kept, never split: no sliver is cut off)
    ear_area : an ear whose twice-area is below this share of its polygon's squared extent is flat
    degenerate_gram : a triangle whose Gram determinant is below this share of the product of its
        squared edge lengths has no area (zero up to rounding)
    weld : positions closer than this share of the bounding-box diagonal are one vertex (the
        mesh-quality figures and the welds of results)
    degenerate_face : an edge or a height shorter than this share of the bounding-box diagonal makes
        a face degenerate
    energy : a labeling's energy lower by less than this share (of its finite part plus one) is not
        lower (alpha-expansion's moves)
    constant : a signal whose range, or a representation whose deviation, is below this (times its
        mean's size, at least 1) is constant
    """

    plane: float = 1e-12
    ear_area: float = 1e-12
    degenerate_gram: float = 1e-30
    weld: float = 1e-6
    degenerate_face: float = 1e-9
    energy: float = 1e-12
    constant: float = 1e-12


tol = Tolerances()
"""The tolerances every core module reads."""
