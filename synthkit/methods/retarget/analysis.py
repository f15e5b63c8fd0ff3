"""Offset statistics of a normalised mesh (Wu et al., sections III-A, IV and V).

Pure functions over arrays. Positions are in *normalised* units (the model's longest bounding-box
side spans [-1, 1]); ``P (n, 3)`` points, ``N (n, 3)`` unit normals, ``D (n, d) float32`` descriptors.

Pipeline: :func:`sample_features` (two Poisson-disk scales plus mesh vertices) ->
:func:`describe` (SHOT or FPFH) -> :func:`match_offsets` (eq. 1) -> :func:`offset_histogram`,
:func:`sparsity_curve` (Fig. 5) -> :func:`dominant_offsets` (non-maximum suppression) ->
:func:`refine_offset` (translation-only ICP) -> :func:`select_principal` (greedy, minimum angle)
-> :func:`offset_basis` (dummy directions, canonical space). :func:`analyze` runs them all.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import maximum_filter, uniform_filter
from scipy.spatial import cKDTree

from synthkit.core.descriptors import fpfh, shot
from synthkit.core.mesh import poisson_disk_sample, vertex_normals
from synthkit.methods.retarget.options import AnalysisOptions

__all__ = [
    "FeatureSet",
    "Analysis",
    "sample_features",
    "describe",
    "match_offsets",
    "offset_histogram",
    "sparsity_curve",
    "share_in_top",
    "dominant_offsets",
    "refine_offset",
    "reduce_to_generators",
    "snap_to_vertices",
    "select_principal",
    "offset_basis",
    "analyze",
]


@dataclass
class FeatureSet:
    """Dense support cloud and features of a normalised mesh.

    dense_P, dense_N : (n, 3) Poisson-disk samples at the dense radius and their normals.
    P, N : (k, 3) features (coarse Poisson-disk samples, then de-duplicated mesh vertices).
    D : (k, d) float32 descriptors of the features.
    n_vertex_features : how many of the features are mesh vertices (the last ones).
    """

    dense_P: np.ndarray
    dense_N: np.ndarray
    P: np.ndarray
    N: np.ndarray
    D: np.ndarray | None = None
    n_vertex_features: int = 0


@dataclass
class Analysis:
    """Everything the analysis found, in normalised units.

    offsets : (k, 3) per-feature offset to its best match (eq. 1); match : (k,) index of the match.
    bin_keys : (b, 3) int occupied bins of the *statistics* histogram (Fig. 5, section IV),
    ``rint(offset / bin_size)`` (bins centred on the multiples of ``bin_size``, see
    :func:`offset_histogram`), sorted by decreasing count; bin_counts : (b,) int, the offsets in each.
    curve_x, curve_y : the sparsity curve (share of bins, cumulative share of offsets).
    top7, top20 : share of offsets in the top 7% / 20% of occupied bins.
    stat_offsets : (s, 3) the offsets the statistics are taken over (see :func:`analyze`);
    n_statistics_features : the features they come from.
    dominant : (m, 3) dominant offsets before refinement; dominant_refined : (m, 3) after ICP;
    dominant_counts : (m,) offsets in each peak's window; dominant_overlap : (m,) share of the
    dense cloud that the refined offset maps onto the surface; dominant_grip : (m,) how firmly the
    matched surface pins the offset along itself (see :func:`refine_offset`).
    principal_index : indices into ``dominant`` of the principal offsets (0 to 3 of them).
    basis : (3, 3) columns = principal offsets then dummy directions; n_principal : int.
    """

    features: FeatureSet
    offsets: np.ndarray
    match: np.ndarray
    bin_keys: np.ndarray
    bin_counts: np.ndarray
    curve_x: np.ndarray
    curve_y: np.ndarray
    top7: float
    top20: float
    dominant: np.ndarray
    dominant_refined: np.ndarray
    dominant_counts: np.ndarray
    dominant_overlap: np.ndarray
    dominant_grip: np.ndarray
    principal_index: list[int] = field(default_factory=list)
    basis: np.ndarray | None = None
    n_principal: int = 0
    stat_offsets: np.ndarray | None = None
    n_statistics_features: int = 0

    @property
    def principal(self) -> np.ndarray:
        """(n_principal, 3) refined principal offsets, normalised units."""
        return self.basis[:, : self.n_principal].T.copy() if self.basis is not None else np.zeros((0, 3))


def sample_features(
    Vn,
    F,
    *,
    dense_radius: float = 0.02,
    feature_radius: float = 0.06,
    use_vertices: bool = True,
    vertex_merge: float = 0.01,
    oversample: int = 3,
    seed: int = 0,
) -> FeatureSet:
    """Dense and feature samples of a normalised mesh (Fig. 3).

    Two Poisson-disk sets (``dense_radius`` for the descriptor support, ``feature_radius`` for the
    features), then all mesh vertices as extra features. Choices the paper leaves open: vertices
    with no incident face are ignored, vertices are merged on a grid of ``vertex_merge`` (finer
    detail than half the dense spacing cannot be told apart by descriptors built on it, and
    duplicates of unwelded meshes would only repeat features), and a vertex's normal is the
    angle-weighted normal of all faces incident to its merged cell, the same for every copy of a
    vertex whatever the triangulation (docs/findings/retarget.md, "Vertex normals").
    ``oversample`` is the Poisson pool size per disk (why 3: the findings, "Poisson pool").
    ``seed`` feeds the two samplers (``seed`` and ``seed + 1``).
    """
    Vn = np.asarray(Vn, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    dP, dN = poisson_disk_sample(Vn, F, dense_radius, seed=seed, oversample=oversample)
    fP, fN = poisson_disk_sample(Vn, F, feature_radius, seed=seed + 1, oversample=oversample)
    n_vert = 0
    if use_vertices:
        used = np.unique(F)
        _, first, inv = np.unique(
            np.floor(Vn[used] / vertex_merge).astype(np.int64), axis=0, return_index=True, return_inverse=True
        )
        cell = np.full(len(Vn), -1, np.int64)
        cell[used] = inv.reshape(-1)  # merged vertex of each used vertex
        vp = Vn[used[first]]  # (m, 3) one representative per merged cell
        vn = vertex_normals(vp, cell[F], weights="angle")
        order = np.argsort(first, kind="stable")  # merged vertices in vertex order
        ok = np.linalg.norm(vn[order], axis=1) > 0
        vp, vn = vp[order][ok], vn[order][ok]
        fP, fN = np.concatenate([fP, vp]), np.concatenate([fN, vn])
        n_vert = len(vp)
    fN = fN / np.maximum(np.linalg.norm(fN, axis=1, keepdims=True), 1e-300)
    return FeatureSet(dP, dN, fP, fN, None, n_vert)


def describe(P, N, dense_P, dense_N, *, descriptor: str = "shot", radius: float = 0.2) -> np.ndarray:
    """Descriptors ``(k, 352|33) float32`` of points ``P`` over the dense cloud (``shot`` or ``fpfh``)."""
    if descriptor == "shot":
        return shot(P, N, dense_P, dense_N, radius=radius)
    if descriptor == "fpfh":
        return fpfh(P, N, dense_P, dense_N, radius=radius)
    raise ValueError(f"unknown descriptor {descriptor!r} (shot or fpfh)")


def match_offsets(P, D, *, tau: float = 0.15, chunk: int = 1024) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Best match of every feature farther than ``tau`` (eq. 1), by brute force in descriptor space.

    Returns ``(match (k,) int64, offsets (k, 3) = P[match] - P, dist (k,) descriptor distance)``.
    A feature with no other feature farther than ``tau`` gets ``match = -1``, a zero offset and an
    infinite distance. Ties go to the lowest index.
    """
    P = np.asarray(P, dtype=np.float64)
    D = np.asarray(D, dtype=np.float32)
    k = len(P)
    match = np.full(k, -1, dtype=np.int64)
    best = np.full(k, np.inf)
    sq = (D.astype(np.float64) ** 2).sum(1).astype(np.float32)
    psq = (P * P).sum(1)
    for start in range(0, k, chunk):
        stop = min(start + chunk, k)
        d2 = sq[start:stop, None] + sq[None, :] - 2.0 * (D[start:stop] @ D.T)
        near = psq[start:stop, None] + psq[None, :] - 2.0 * (P[start:stop] @ P.T) <= tau * tau
        d2[near] = np.inf
        j = np.argmin(d2, axis=1)
        val = d2[np.arange(stop - start), j]
        ok = np.isfinite(val)
        match[start:stop][ok] = j[ok]
        best[start:stop][ok] = np.sqrt(np.maximum(val[ok], 0.0))
    offsets = np.zeros_like(P)
    has = match >= 0
    offsets[has] = P[match[has]] - P[has]
    return match, offsets, best


def offset_histogram(offsets, *, bin_size: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """Occupied bins of the 3-D offset histogram: ``(keys (b, 3) int64, counts (b,) int64)``, sorted
    by decreasing count (ties by key).

    Bins are cubes of side ``bin_size`` centred on the multiples of ``bin_size`` (``key =
    round(offset / bin_size)``), so that the axis-aligned offsets of man-made models, whose other
    components are zero up to rounding, are not split by a bin boundary at 0."""
    offsets = np.asarray(offsets, dtype=np.float64).reshape(-1, 3)
    if len(offsets) == 0:
        return np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    keys = np.rint(offsets / bin_size).astype(np.int64)
    uniq, counts = np.unique(keys, axis=0, return_counts=True)
    order = np.argsort(-counts, kind="stable")
    return uniq[order], counts[order]


def sparsity_curve(counts) -> tuple[np.ndarray, np.ndarray]:
    """Fig. 5: bins sorted by decreasing count; ``x (b + 1,)`` share of the occupied bins taken,
    ``y (b + 1,)`` cumulative share of the offsets in them (both start at 0 and end at 1)."""
    c = np.sort(np.asarray(counts, dtype=np.float64))[::-1]
    if len(c) == 0 or c.sum() == 0:
        return np.array([0.0, 1.0]), np.array([0.0, 0.0])
    x = np.arange(len(c) + 1) / len(c)
    y = np.concatenate([[0.0], np.cumsum(c) / c.sum()])
    return x, y


def share_in_top(counts, fraction: float) -> float:
    """Share of the offsets that fall in the ``fraction`` most populated occupied bins, the
    sparsity curve read at ``fraction`` (linear between whole bins)."""
    x, y = sparsity_curve(counts)
    return float(np.interp(fraction, x, y))


def dominant_offsets(
    offsets, *, bin_size: float = 0.05, window: float = 0.15, min_count: int = 5, max_peaks: int = 20
) -> tuple[np.ndarray, np.ndarray]:
    """Peaks of the offset histogram by non-maximum suppression (Fig. 2-c).

    The histogram is summed over a cubic window of ``round(window / bin_size)`` bins (3 by
    default) centred on each bin; the magnitude of a bin is that window sum. Candidates are the
    local maxima of the magnitude over the window; greedy NMS then keeps them in decreasing
    magnitude unless a kept bin lies within the window (Chebyshev distance ``<= window // 2``
    bins; ties of the window sum are broken by the centre bin's own count); stops at ``max_peaks``
    or below ``min_count``. The offset of a peak is the mean of the offsets in its window (finer
    than the bin centre).

    Returns ``(peaks (m, 3) float64, magnitudes (m,) int64)`` in decreasing magnitude.
    """
    offsets = np.asarray(offsets, dtype=np.float64).reshape(-1, 3)
    if len(offsets) == 0:
        return np.zeros((0, 3)), np.zeros(0, np.int64)
    half = max(int(round(window / bin_size)) // 2, 0)
    keys = np.rint(offsets / bin_size).astype(np.int64)
    lo = keys.min(axis=0) - half
    shape = keys.max(axis=0) + half - lo + 1
    flat = np.ravel_multi_index((keys - lo).T, shape)
    hist = np.bincount(flat, minlength=int(np.prod(shape))).reshape(shape)
    size = 2 * half + 1
    mag = np.rint(uniform_filter(hist.astype(np.float64), size=size, mode="constant") * size**3).astype(np.int64)
    score = mag + hist / (hist.max() + 1.0)  # ties of the window sum go to the fuller centre bin
    local_max = score == maximum_filter(score, size=size, mode="constant")
    cand = np.flatnonzero(local_max.reshape(-1) & (mag.reshape(-1) >= max(min_count, 1)))
    cand = cand[np.argsort(-score.reshape(-1)[cand], kind="stable")]
    kept: list[np.ndarray] = []
    peaks, mags = [], []
    for c in cand:
        idx = np.array(np.unravel_index(c, shape))
        if any(np.abs(idx - k).max() <= half for k in kept):
            continue
        kept.append(idx)
        inwin = np.abs(keys - (idx + lo)).max(axis=1) <= half
        peaks.append(offsets[inwin].mean(axis=0))
        mags.append(int(mag.reshape(-1)[c]))
        if len(kept) >= max_peaks:
            break
    if not peaks:
        return np.zeros((0, 3)), np.zeros(0, np.int64)
    return np.array(peaks), np.array(mags, dtype=np.int64)


def refine_offset(
    P,
    N,
    t0,
    *,
    tree: cKDTree | None = None,
    sources: np.ndarray | None = None,
    radii: tuple[float, ...] = (0.05, 0.05, 0.03, 0.02),
    inlier_radius: float = 0.02,
    max_iter: int = 40,
    tol: float = 1e-9,
) -> tuple[np.ndarray, float, float]:
    """Translation-only ICP of the cloud onto itself, starting at offset ``t0 (3,)``.

    Each iteration moves ``sources`` (indices into ``P``, default all) by the current ``t``, pairs
    each with its nearest point of ``P`` within the current radius (``radii`` per iteration, the
    last one repeated) whose normal agrees (dot > 0.8), and solves the point-to-plane least squares
    for the update, regularised by a point-to-point term of weight 0.01 so that directions no plane
    constrains still converge. Stops when the update is below ``tol``.

    Returns ``(t (3,), overlap, grip)``: the refined offset, the share of sources that land within
    ``inlier_radius`` of a compatible point (how much of the model the offset maps onto itself),
    and the ``grip``: the share of sources that land on a compatible point whose normal is within
    60 degrees of ``t``, i.e. surface that pins the offset along ``t``. It is near 0 when the
    matched surface could slide along ``t`` (a continuous symmetry such as a long plank, not a
    repetition), however small the pinning parts (window jambs, dividers) are otherwise.
    """
    P = np.asarray(P, dtype=np.float64)
    N = np.asarray(N, dtype=np.float64)
    t = np.asarray(t0, dtype=np.float64).copy()
    tree = tree if tree is not None else cKDTree(P)
    S = P if sources is None else P[sources]
    SN = N if sources is None else N[sources]
    for it in range(max_iter):
        r = radii[min(it, len(radii) - 1)]
        d, j = tree.query(S + t, distance_upper_bound=r)
        ok = np.isfinite(d)
        ok[ok] &= np.einsum("ij,ij->i", SN[ok], N[j[ok]]) > 0.8
        if ok.sum() < 3:
            break
        q = S[ok] + t
        p, n = P[j[ok]], N[j[ok]]
        res = np.einsum("ij,ij->i", q - p, n)
        w = 0.01
        A = n.T @ n + w * len(q) * np.eye(3)
        b = -(n.T @ res) - w * (q - p).sum(axis=0)
        delta = np.linalg.solve(A, b)
        t += delta
        if np.linalg.norm(delta) < tol and r == radii[-1]:
            break
    d, j = tree.query(S + t, distance_upper_bound=inlier_radius)
    ok = np.isfinite(d)
    ok[ok] &= np.einsum("ij,ij->i", SN[ok], N[j[ok]]) > 0.8
    if not ok.any():
        return t, 0.0, 0.0
    u = t / max(np.linalg.norm(t), 1e-300)
    pinned = np.zeros(len(S), bool)
    pinned[ok] = np.abs(N[j[ok]] @ u) >= 0.5
    return t, float(ok.mean()), float(pinned.mean())


def reduce_to_generators(
    vectors, *, eligible=None, grip=None, tol: float = 0.05, max_multiple: int = 6, grip_ratio: float = 2.0
) -> np.ndarray:
    """For each vector ``(m, 3)``, the index of the eligible vector it stands for in the greedy
    choice: the shortest eligible ``u`` with ``v ~ k u`` for an integer ``2 <= |k| <= max_multiple``
    (within ``tol``), else itself.

    A choice beyond the paper's greedy rule: on a 1-D grid of n copies the peaks at v and 2v hold
    about (n - 1) and (n - 2) matches, so sampling noise can rank 2v first; the paper's principal
    offsets are the generators, of which 2v is a combination.

    With ``grip (m,)`` (:func:`refine_offset`) the rule also looks the other way. On a true grid
    a generator pins at least as much surface as its multiples, so ``v`` is reduced to ``u`` only
    when ``grip[u] >= grip[v] / grip_ratio``; and an eligible ``u`` whose eligible multiple ``v``
    pins more than ``grip_ratio`` times as much stands for that multiple (the best-gripping one).
    ``grip_ratio = 0`` (or no ``grip``) turns both grip rules off. Why the grip rules: docs/findings/retarget.md,
    "Slides and generators".
    """
    V = np.asarray(vectors, dtype=np.float64).reshape(-1, 3)
    ok = np.ones(len(V), bool) if eligible is None else np.asarray(eligible, bool)
    G = None if grip is None or not grip_ratio > 0 else np.asarray(grip, dtype=np.float64).reshape(-1)
    lengths = np.linalg.norm(V, axis=1)

    def multiple(v, u_index):  # is v an integer multiple (2..max_multiple) of V[u_index]?
        lu = lengths[u_index]
        if lu == 0:
            return False
        k = np.rint((v @ V[u_index]) / lu**2)
        return bool(2 <= abs(k) <= max_multiple and np.linalg.norm(v - k * V[u_index]) <= tol)

    out = np.arange(len(V))
    for i, v in enumerate(V):
        best = i
        for j in np.flatnonzero(ok):
            if lengths[j] >= lengths[best] or not multiple(v, j):
                continue
            if G is not None and G[j] * grip_ratio < G[i]:
                continue  # the shorter vector pins far less: a slide, not this vector's generator
            best = j
        out[i] = best
    if G is not None:
        for i in np.flatnonzero(ok):
            if out[i] != i:
                continue
            shadow = [m for m in np.flatnonzero(ok) if lengths[m] > lengths[i] and multiple(V[m], i)]
            shadow = [m for m in shadow if G[m] > grip_ratio * G[i]]
            if shadow:
                out[i] = max(shadow, key=lambda m: (G[m], -m))
    return out


def snap_to_vertices(vertices, t, *, radius: float = 0.005, rounds: int = 3) -> tuple[np.ndarray, int]:
    """Last ICP step on the mesh vertices: ``t (3,)`` moved to the mean of ``q - p`` over vertex
    pairs with ``|p + t - q| <= radius`` (``vertices (n, 3)``), repeated ``rounds`` times.

    Dense samples pin an offset to about 1e-4; exactly repeated vertices pin it to rounding error,
    which copies need to meet vertex to vertex at a seam several steps away. Returns ``(t,
    pairs)``; with fewer than 3 pairs ``t`` is returned unchanged.
    """
    P = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64).copy()
    tree = cKDTree(P)
    pairs = 0
    for _ in range(rounds):
        d, j = tree.query(P + t, distance_upper_bound=radius)
        ok = np.isfinite(d)
        if ok.sum() < 3:
            break
        pairs = int(ok.sum())
        t = (P[j[ok]] - P[ok]).mean(axis=0)
    return t, pairs


def select_principal(vectors, *, min_angle: float = np.pi / 3, max_count: int = 3, eligible=None) -> list[int]:
    """Greedy choice of up to ``max_count`` principal offsets (section V).

    ``vectors (m, 3)`` are dominant offsets in decreasing order of magnitude. The first eligible
    one is taken; each next one is the first remaining vector whose angle to every chosen one
    satisfies ``|cos| <= cos(min_angle)`` (``-cos t <= v1.v2 / |v1||v2| <= cos t``) and, for the
    third, that is not in the plane of the first two (a third vector must add a dimension).
    ``eligible (m,) bool`` masks out candidates. Returns indices into ``vectors``.
    """
    V = np.asarray(vectors, dtype=np.float64).reshape(-1, 3)
    ok = np.ones(len(V), bool) if eligible is None else np.asarray(eligible, bool)
    limit = np.cos(min_angle)
    chosen: list[int] = []
    for i, v in enumerate(V):
        if len(chosen) >= max_count:
            break
        nv = np.linalg.norm(v)
        if not ok[i] or nv == 0:
            continue
        cos = [abs(v @ V[c]) / (nv * np.linalg.norm(V[c])) for c in chosen]
        if any(c > limit + 1e-12 for c in cos):
            continue
        if len(chosen) == 2:
            normal = np.cross(V[chosen[0]], V[chosen[1]])
            if abs(normal @ v) <= 1e-3 * np.linalg.norm(normal) * nv:
                continue
        chosen.append(i)
    return chosen


def offset_basis(principal, *, dummy_length: float = 0.2) -> tuple[np.ndarray, int]:
    """Complete 0-3 principal offsets ``(k, 3)`` to a basis ``(3, 3)`` (columns) with orthogonal
    dummy directions of length ``dummy_length`` (section V).

    One principal offset: the dummy directions are the world axis least aligned with it, made
    orthogonal to it, and their cross product. Two: their cross product. None: the world axes
    scaled to ``dummy_length``. Returns ``(basis, k)``. The canonical coordinates of a point ``x`` are
    ``basis^-1 x``: the principal offsets become unit steps along the canonical axes (Fig. 7).
    """
    Pr = np.asarray(principal, dtype=np.float64).reshape(-1, 3)
    k = len(Pr)
    if k > 3:
        raise ValueError(f"at most 3 principal offsets, got {k}")
    cols = [v for v in Pr]
    if k == 1:
        u = Pr[0] / np.linalg.norm(Pr[0])
        axis = np.eye(3)[int(np.argmin(np.abs(u)))]
        d1 = axis - (axis @ u) * u
        d1 /= np.linalg.norm(d1)
        d2 = np.cross(u, d1)
        cols += [dummy_length * d1, dummy_length * d2]
    elif k == 2:
        n = np.cross(Pr[0], Pr[1])
        cols.append(dummy_length * n / np.linalg.norm(n))
    elif k == 0:
        cols = list(dummy_length * np.eye(3))
    B = np.stack(cols, axis=1)
    if abs(np.linalg.det(B)) < 1e-12:
        raise ValueError("principal offsets are linearly dependent")
    return B, k


def _canonical_sign(v: np.ndarray) -> np.ndarray:
    """``v`` or ``-v``, whichever has its largest-magnitude component positive."""
    return v if v[int(np.argmax(np.abs(v)))] >= 0 else -v


def _statistics_offsets(feats: FeatureSet, offsets, statistics_features: str, tau: float):
    """``(n_stat, stat_offsets (s, 3))``: the features the sparsity statistics count and their
    offsets; ``"samples"``: the Poisson-disk features matched among themselves (section IV),
    ``"all"``: every feature's ``offsets`` (vertices included)."""
    if statistics_features == "samples":
        n_stat = len(feats.P) - feats.n_vertex_features
        smatch, soffsets, _ = match_offsets(feats.P[:n_stat], feats.D[:n_stat], tau=tau)
        return n_stat, soffsets[smatch >= 0]
    if statistics_features == "all":
        return len(feats.P), offsets
    raise ValueError(f"statistics_features must be 'samples' or 'all', got {statistics_features!r}")


def _refine_dominant(feats: FeatureSet, dom, gen, *, icp_sources: int, dense_radius: float):
    """ICP refinement of each dominant offset ``dom (d, 3)`` on the dense cloud, from at most
    ``icp_sources`` source points drawn by ``gen``: ``(refined (d, 3), overlap (d,), grip (d,))``."""
    tree = cKDTree(feats.dense_P)
    n_src = min(icp_sources, len(feats.dense_P))
    src = np.sort(gen.choice(len(feats.dense_P), size=n_src, replace=False)) if n_src else None
    refined = np.zeros_like(dom)
    overlap = np.zeros(len(dom))
    grip = np.zeros(len(dom))
    for i, t0 in enumerate(dom):
        refined[i], overlap[i], grip[i] = refine_offset(
            feats.dense_P, feats.dense_N, t0, tree=tree, sources=src, inlier_radius=dense_radius
        )
    return refined, overlap, grip


def analyze(Vn, F, opt: AnalysisOptions, *, rng=None) -> Analysis:
    """Offset statistics of the normalised mesh ``Vn (#V, 3)``, ``F (#F, 3)`` (sections III-A, V)
    under the settings ``opt`` (:class:`~synthkit.methods.retarget.options.AnalysisOptions`, whose
    names the text below uses; the config's defaults are the paper's).

    Eligible refined offsets get a last ICP step on the mesh vertices (:func:`snap_to_vertices`,
    radius ``dense_radius / 4``) when vertices are features. Randomness enters through the
    Poisson-disk seeds and the ICP source subset, both drawn from
    ``np.random.default_rng(rng)``. A dominant offset needs at least ``max(5, min_peak_share x
    #offsets)`` offsets in its window; only refined offsets whose ICP ``overlap`` reaches
    ``min_overlap`` and whose ``grip`` reaches ``min_grip`` can become principal (a peak that does
    not map a real part of the surface onto itself, or only slides a plank along itself, is not a
    repetition; nor is one that ICP moves out of its NMS window or below ``tau``). Each dominant
    offset stands for its generator (:func:`reduce_to_generators`, with ``generator_grip_ratio``) in the
    greedy choice.
    Principal offsets are signed so their largest component is positive.

    The sparsity statistics (``top7``, ``top20``, the curve and the histogram bins, Fig. 5) follow
    section IV's protocol: with ``statistics_features="samples"`` (default) they are taken over the
    Poisson-disk features only, each matched (eq. 1) among those features alone; ``"all"`` takes
    them over the offsets of every feature, vertices included, as the dominant offsets are. Why,
    and the candidates measured and not adopted: docs/findings/retarget.md, "Sparsity statistics".
    """
    gen = np.random.default_rng(rng)
    seed = int(gen.integers(0, 2**31 - 1))
    feats = sample_features(Vn, F, dense_radius=opt.dense_radius, feature_radius=opt.feature_radius,
                            use_vertices=opt.use_vertices, seed=seed)
    feats.D = describe(feats.P, feats.N, feats.dense_P, feats.dense_N, descriptor=opt.descriptor,
                       radius=opt.descriptor_radius)
    match, offsets, _ = match_offsets(feats.P, feats.D, tau=opt.tau)
    offsets = offsets[match >= 0]
    n_stat, stat_offsets = _statistics_offsets(feats, offsets, opt.statistics_features, opt.tau)
    keys, counts = offset_histogram(stat_offsets, bin_size=opt.bin_size)
    cx, cy = sparsity_curve(counts)
    min_count = max(5, int(np.ceil(opt.min_peak_share * len(offsets))))
    dom, mags = dominant_offsets(
        offsets, bin_size=opt.bin_size, window=opt.nms_window, min_count=min_count, max_peaks=opt.max_dominant
    )
    refined, overlap, grip = _refine_dominant(feats, dom, gen, icp_sources=opt.icp_sources,
                                              dense_radius=opt.dense_radius)
    stayed = (np.linalg.norm(refined, axis=1) > opt.tau) & (np.linalg.norm(refined - dom, axis=1) <= opt.nms_window)
    eligible = (overlap >= opt.min_overlap) & (grip >= opt.min_grip) & stayed
    if opt.use_vertices:
        verts = np.unique(np.asarray(Vn, dtype=np.float64)[np.unique(np.asarray(F))], axis=0)
        for i in np.flatnonzero(eligible):
            refined[i] = snap_to_vertices(verts, refined[i], radius=opt.dense_radius / 4)[0]
    gen_index = reduce_to_generators(
        refined, eligible=eligible, grip=grip, tol=opt.bin_size, grip_ratio=opt.generator_grip_ratio
    )
    cand = select_principal(refined[gen_index], min_angle=opt.min_angle, max_count=opt.max_principal,
                            eligible=eligible)
    chosen = [int(gen_index[i]) for i in cand]
    principal = np.array([_canonical_sign(refined[i]) for i in chosen]).reshape(-1, 3)
    basis, k = offset_basis(principal, dummy_length=opt.dummy_length)
    return Analysis(
        features=feats,
        offsets=offsets,
        match=match,
        bin_keys=keys,
        bin_counts=counts,
        curve_x=cx,
        curve_y=cy,
        top7=share_in_top(counts, 0.07),
        top20=share_in_top(counts, 0.20),
        dominant=dom,
        dominant_refined=refined,
        dominant_counts=mags,
        dominant_overlap=overlap,
        dominant_grip=grip,
        principal_index=chosen,
        basis=basis,
        n_principal=k,
        stat_offsets=stat_offsets,
        n_statistics_features=int(n_stat),
    )
