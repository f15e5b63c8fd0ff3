"""Construction space (paper section 2.2, Algorithm 1 and eq. 2): hexahedral cells along a curve.

Axes of the construction space: ``a`` along the curve (cells i), ``b`` across it (cells j, the
offset lines), ``c`` the sweep axis (cells k). ``PLANE_AXES[plane]`` maps them to the example's
world/lattice axes. A straight curve along +a with side "left" maps every lattice axis onto itself,
and a turn of the curve is a rotation in the plane, so a piece is never mirrored.

Where the paper is open (mitre normals, S_X rounding, refused curves): ``docs/findings/petri-synth.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from synthkit.errors import KeyedError
from synthkit.methods.petri.curves import (
    PLANE_AXES,
    PLANE_POINT_AXES,
    first_crossing,
    mitre_directions,
    plane_to_world,
    point_polyline_distance,
    polyline_problem,
    resample_polyline,
    units_along,
)
from synthkit.methods.petri.options import SpaceOptions


@dataclass
class ConstructionSpace:
    """The construction space: plane grid, sweep, axes and unit sizes.

    ``grid (nI, S_Y + 1, 2)``: points p_ij in the plane's (first, second) world coordinates,
    ``nI = S_X + 1`` for an open curve and ``S_X`` for a closed one (index i wraps).
    ``axes``: world axes of (a, b, c); ``sweep (S_Z + 1,)`` world coordinates along c.
    """

    grid: np.ndarray
    sweep: np.ndarray
    closed: bool
    axes: tuple[int, int, int]
    point_axes: tuple[int, int]
    units: np.ndarray
    curve: np.ndarray
    directions: np.ndarray
    j0: float

    @property
    def shape(self) -> tuple[int, int, int]:
        """(S_X, S_Y, S_Z)."""
        nI = self.grid.shape[0]
        return (nI if self.closed else nI - 1, self.grid.shape[1] - 1, len(self.sweep) - 1)

    def world(self, uv: np.ndarray, w: np.ndarray) -> np.ndarray:
        """World points ``(..., 3)`` from plane points ``uv (..., 2)`` and sweep coordinates ``w (...)``."""
        return plane_to_world(uv, w, self.point_axes, self.axes[2])

    def hex_corners(self) -> np.ndarray:
        """Eight control points per cell, ``(S_X * S_Y * S_Z, 8, 3)`` world, cells in C order of (i, j, k).

        Corner ``ia + 2 jb + 4 kc`` is grid point ``(i + ia, j + jb)`` at sweep ``k + kc``: the
        trilinear FFD corner order of :func:`synthkit.core.ffd.trilinear_ffd` in (a, b, c).
        """
        SX, SY, SZ = self.shape
        nI = self.grid.shape[0]
        i, j, k = np.meshgrid(np.arange(SX), np.arange(SY), np.arange(SZ), indexing="ij")
        i, j, k = i.ravel(), j.ravel(), k.ravel()
        out = np.empty((len(i), 8, 3))
        for c in range(8):
            ia, jb, kc = c & 1, (c >> 1) & 1, (c >> 2) & 1
            out[:, c] = self.world(self.grid[(i + ia) % nI, j + jb], self.sweep[k + kc])
        return out

    def offset_polyline(self, t: float) -> np.ndarray:
        """The curve offset by ``t`` (world units, along the mitre directions): ``(m, 2)``."""
        return self.curve + t * self.directions

    def center_deviation(self) -> np.ndarray:
        """Per cell ``(S_X, S_Y)``: plane distance from the cell centre to the offset curve at the cell's
        middle offset ``(j + 0.5 - j0) * unit_b``, divided by the cell size across (``unit_b``)."""
        SX, SY, _ = self.shape
        nI = self.grid.shape[0]
        i = np.arange(SX)
        dev = np.zeros((SX, SY))
        for j in range(SY):
            c = (
                self.grid[i, j] + self.grid[(i + 1) % nI, j] + self.grid[i, j + 1] + self.grid[(i + 1) % nI, j + 1]
            ) / 4
            line = self.offset_polyline((j + 0.5 - self.j0) * self.units[1])
            if self.closed:
                line = np.vstack([line, line[:1]])
            dev[:, j] = point_polyline_distance(c, line) / self.units[1]
        return dev


def build_construction_space(points, closed: bool, opts: SpaceOptions, *, cells: int | None = None,
                             key: str = "points") -> ConstructionSpace:
    """Algorithm 1 plus eq. (2): the hexahedral cells along the polyline ``points (m, 2)`` (``closed``).

    ``opts`` gives the plane, side, unit sizes along (a, b, c), S_Y, S_Z and sweep origin
    (:class:`~synthkit.methods.petri.options.SpaceOptions`). ``cells`` is S_X (None:
    :func:`units_along`). Raises :class:`KeyedError` (``key``, the points' key) for the polylines
    :func:`polyline_problem` refuses, a curve shorter than one unit, a curve folding back on itself,
    and self-intersecting cells.
    """
    side, size_y, size_z = opts.side, opts.size_y, opts.size_z
    P = np.asarray(points, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 2:
        raise KeyedError(key, f"need a list of 2-D points (x, y), got shape {list(P.shape)}")
    problem, kept = polyline_problem(P.tolist(), closed)
    if problem is not None:
        raise KeyedError(key, problem)
    P = np.asarray(kept, dtype=np.float64)
    units = np.asarray(opts.units, dtype=np.float64)
    length = float(np.linalg.norm(np.diff(np.vstack([P, P[:1]]) if closed else P, axis=0), axis=1).sum())
    SX = units_along(length, float(units[0]))
    if SX >= 1 and cells is not None:
        SX = int(cells)
    if SX < 1:
        raise KeyedError(
            key, f"the curve is {length:.6g} long, shorter than one unit along it "
            f"({units[0]:.6g}, {opts.unit_key}); a curve must be at least one unit long"
        )
    _, _, D, _ = mitre_directions(P, closed, key)
    j0 = {"left": 0.0, "right": float(size_y), "center": size_y / 2.0}[side]
    grid = np.stack(
        [resample_polyline(P + (j - j0) * units[1] * D, SX, closed) for j in range(size_y + 1)],
        axis=1,
    )
    sweep = opts.sweep_origin + units[2] * np.arange(size_z + 1)
    space = ConstructionSpace(
        grid=grid,
        sweep=sweep,
        closed=closed,
        axes=PLANE_AXES[opts.plane],
        point_axes=PLANE_POINT_AXES[opts.plane],
        units=units,
        curve=P,
        directions=D,
        j0=j0,
    )
    check_cells(space, key)
    return space


def check_cells(space: ConstructionSpace, key: str = "points") -> None:
    """:class:`KeyedError` (``key``) unless every plane cell is strictly convex and counter-clockwise
    and the boundary of the construction plane does not cross itself."""
    G = space.grid
    nI = G.shape[0]
    SX, SY, _ = space.shape
    i = np.arange(SX)
    q = [G[i, :-1], G[(i + 1) % nI, :-1], G[(i + 1) % nI, 1:], G[i, 1:]]  # CCW quad corners
    tol = 1e-9 * float(np.prod(space.units[:2]))
    for c in range(4):
        a, b, d = q[c], q[(c + 1) % 4], q[(c + 3) % 4]
        e1, e2 = b - a, d - a
        cross = e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0]
        bad = np.argwhere(cross <= tol)
        if len(bad):
            ci, cj = (int(v) for v in bad[0])
            raise KeyedError(
                key, f"self-intersecting construction cells with construction.size_y = {SY}: "
                f"cell (i={ci}, j={cj}) is folded or inverted ({len(bad)} corners); reduce construction.size_y "
                f"or smooth the curve"
            )
    loops = (
        [np.vstack([G[:, 0], G[:1, 0]]), np.vstack([G[:, -1], G[:1, -1]])]
        if space.closed
        else [np.vstack([G[:, 0], G[-1, 1:], G[::-1, -1][1:], G[0, ::-1][1:]])]
    )
    segs = np.concatenate([np.stack([L[:-1], L[1:]], axis=1) for L in loops])
    hit = first_crossing(segs)
    if hit is not None:
        raise KeyedError(
            key, f"self-intersecting construction cells with construction.size_y = {SY}: the "
            f"boundary of the construction plane crosses itself near {np.round(segs[hit[0], 0], 4).tolist()}"
        )
