"""The weighted constraint system of one reshape (section 3.2) and the quality figures of a solve.

:func:`build_system` stacks every row block of :mod:`constraints` for a constraint graph into
``A (m, 3 n)`` and ``b (m,)`` (:class:`System`); :func:`quality_figures` and
:func:`strict_residuals` measure node positions against it; :func:`baseline_positions` solves the
Laplacian baseline with the same known nodes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from synthkit.methods.reshape import constraints as C
from synthkit.methods.reshape.baseline import angle_errors_deg, laplacian_rows, mesh_edges
from synthkit.methods.reshape.graph import ConstraintGraph
from synthkit.methods.reshape.options import SystemOptions
from synthkit.methods.reshape.parts import attach_clusters
from synthkit.methods.reshape.solver import ReshapeSolver, floating_anchors

__all__ = ["System", "build_system", "quality_figures", "strict_residuals", "baseline_positions"]


@dataclass
class System:
    """The weighted rows of one reshape: ``A (m, 3 n)``, ``b (m,)``, each block's row slice, the
    stress weights ``(E,)``, the rigid-edge mask ``(E,)``, contacts ``(k, 2)``, groups, l_min,
    the stress targets ``lengths (E,)`` and the parts carried by a host (``attachment``)."""

    A: object
    b: np.ndarray
    slices: dict
    stress_weights: np.ndarray
    rigid: np.ndarray
    contacts: np.ndarray
    groups: list
    l_min: float
    lengths: np.ndarray
    attachment: object


def build_system(graph: ConstraintGraph, links: np.ndarray, *, options: SystemOptions, size: float, known=(),
                 rest=None, factors=None) -> System:
    """All weighted rows of section 3.2 for ``graph`` with ``options`` (lengths relative to ``size``
    resolved).

    The paper's weights weight squared residuals (weighted least squares, ``A^T W A`` as in
    :class:`synthkit.core.lsq.LeastSquares`), so each row is scaled by the square root of its weight:
    stiffness eq. 3 (rigid edges 1), ``w_c``, ``w_g`` and ``strict.weight``. ``rest (n, 3)`` (a
    resize's rest shape, :mod:`resize`; default the model) is what the rows keep, except the rest
    lengths of rigid edges, measured on the model like ``l_min``, contacts and groups, and hole-plane
    normals, mapped by the per-node scale ``factors (n, 3)`` of the rest shape (plane rows keep the
    rest shape's offset along the normal: a hole's rim may move with its window). Clusters that hold
    none of the ``known`` nodes and no contact are carried by the nearest surface
    (:func:`parts.attach_clusters`, strict rows).
    """
    X0, edges = graph.X0, graph.edges
    R = X0 if rest is None else np.asarray(rest, np.float64)
    _, length = C.edge_frames(X0, edges)
    o = options
    l_min = o.l_min if o.l_min is not None else float(np.quantile(length, o.l_min_quantile))
    w = np.sqrt(C.stiffness(length, l_min=l_min, w_small=o.w_small, w_long=o.w_long))
    targets = np.where(length < l_min, length, C.edge_frames(R, edges)[1])
    W = float(np.sqrt(o.strict_weight))
    w_c = float(np.sqrt(o.w_c))
    blocks = {
        "direction": C.direction_rows(R, edges, weight=W, form=o.direction_form),
        "stress": C.stress_rows(R, edges, w, targets),
    }
    contacts = np.zeros((0, 2), np.int64)
    if o.contacts:
        contacts = C.find_contacts(X0, graph.Fn, graph.component, tol=o.contact_tol * size)
        blocks["coplanarity"], blocks["contact_position"] = C.contact_rows(
            R, graph.Fn, contacts, strict_weight=W, w_c=w_c
        )
    normals = graph.bridge_normals / (1.0 if factors is None else np.asarray(factors)[graph.bridges[:, 0]])
    normals = normals / np.maximum(np.linalg.norm(normals, axis=1), 1e-300)[:, None]
    blocks["hole_plane"], blocks["hole_position"] = C.bridge_rows(R, graph.bridges, normals, strict_weight=W, w_c=w_c)
    groups = []
    if o.groups:
        groups = C.edge_groups(X0, edges, angle_deg=o.group_angle_deg, length_tol=o.group_length_tol,
                               distance=o.group_distance)
        blocks["groups"] = C.group_rows(R, edges, groups, w_g=float(np.sqrt(o.w_g)))
    blocks["links"] = C.link_rows(R, links, strict_weight=W)
    pairs = np.vstack([edges, links, graph.bridges, np.column_stack([contacts[:, 0], graph.Fn[contacts[:, 1], 0]])])
    attachment = attach_clusters(X0, graph.Fn, pairs, np.asarray(known, np.int64))
    blocks["attach"] = C.attach_rows(R, graph.Fn, attachment, strict_weight=W)
    A, b, slices = C.stack_rows(blocks, graph.n_nodes)
    if rest is not None:
        for name in ("coplanarity", "hole_plane"):
            b[slices[name]] = A[slices[name]] @ R.ravel()
    return System(A, b, slices, w, length < l_min, contacts, groups, l_min, targets, attachment)


def quality_figures(graph, system, X, known, targets_all, size, rest=None) -> dict:
    """Angle (against ``rest (n, 3)``, default the model), rigid-length, handle, contact and stretch
    (against the model) figures of node positions ``X (n, 3)``."""
    X0, edges = graph.X0, graph.edges
    ang = angle_errors_deg(X0 if rest is None else rest, X, edges)
    _, rest_len = C.edge_frames(X0, edges)
    new = np.linalg.norm(X[edges[:, 1]] - X[edges[:, 0]], axis=1)
    rigid = system.rigid
    contact = 0.0
    if len(system.contacts):
        i, t = system.contacts[:, 0], system.contacts[:, 1]
        T = graph.Fn[t]
        n = np.cross(X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]])
        n /= np.linalg.norm(n, axis=1)[:, None]
        contact = float(np.abs(np.einsum("ij,ij->i", X[i] - X[T[:, 0]], n)).max() / size)
    return {
        "max_angle_error_deg": float(ang.max()) if len(ang) else 0.0,
        "mean_angle_error_deg": float(ang.mean()) if len(ang) else 0.0,
        "rigid_length_error": float(np.abs(new[rigid] / rest_len[rigid] - 1).max()) if rigid.any() else 0.0,
        "handle_residual": float(np.linalg.norm(X[known] - targets_all, axis=1).max() / size),
        "contact_residual": contact,
        "max_stretch": float((new / rest_len).max()),
        "min_stretch": float((new / rest_len).min()),
    }


def strict_residuals(system: System, X: np.ndarray, weight: float, size: float) -> dict:
    """Largest residual of each strict block, unweighted and relative to the model size."""
    r = system.A @ X.ravel() - system.b
    out = {}
    for name in ("direction", "coplanarity", "hole_plane", "links", "attach"):
        sl = system.slices.get(name)
        if sl is not None and sl.stop > sl.start:
            out[name] = float(np.abs(r[sl]).max() / np.sqrt(weight) / size)
    return out


def baseline_positions(graph, known, X_known, backend) -> np.ndarray:
    """Laplacian baseline positions ``(n, 3)``; floating mesh components get their own anchor."""
    edges = mesh_edges(graph.Fn)
    used = np.zeros(graph.n_nodes, bool)
    used[graph.Fn.reshape(-1)] = True
    extra = floating_anchors(graph.n_nodes, edges, known, used)
    A, b = laplacian_rows(graph.X0, edges)
    Xk = np.vstack([X_known, graph.X0[extra]])
    return ReshapeSolver(A, np.concatenate([known, extra]), backend=backend).solve(b, Xk)
