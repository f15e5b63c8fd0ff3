"""Local shape descriptors of oriented point sets: SHOT with a world-aligned frame, and FPFH.

Points are ``P (n, 3) float64`` with unit normals ``N (n, 3)``. A descriptor is computed at each
keypoint from the neighbours in a *support* cloud (the dense samples) within a radius, found with a
:class:`scipy.spatial.cKDTree`. Everything is vectorised over keypoint/neighbour pairs, processed in
chunks of keypoints to bound memory.

SHOT (Tombari, Salti and Di Stefano, ECCV 2010) with the frame fixed to the world axes, as the
retargeting paper prescribes (only translations are matched, so no covariance frame and no sign
disambiguation): 8 azimuth sectors x 2 elevation halves x 2 radial shells = 32 volumes, each an
11-bin histogram of ``cos(theta) = n_q . n_p``; 352 values normalised to unit L2 length.

FPFH (Rusu, Blodow and Beetz, ICRA 2009): three Darboux-frame angles in 11 bins each (33 values).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

__all__ = ["SHOT_SIZE", "FPFH_SIZE", "shot", "fpfh", "descriptor_distances"]

SHOT_SIZE = 352
FPFH_SIZE = 33
_N_AZ, _N_EL, _N_RAD, _N_COS = 8, 2, 2, 11


def _check_points(P, N, name: str) -> tuple[np.ndarray, np.ndarray]:
    P = np.asarray(P, dtype=np.float64)
    N = np.asarray(N, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 3:
        raise ValueError(f"{name} points must have shape (n, 3), got {P.shape}")
    if N.shape != P.shape:
        raise ValueError(f"{name} normals must have shape {P.shape}, got {N.shape}")
    if not (np.isfinite(P).all() and np.isfinite(N).all()):
        raise ValueError(f"{name} points or normals hold NaN or infinite values")
    return P, N


def _pairs(tree: cKDTree, keys: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """All (keypoint index, support index) pairs closer than ``radius``, as two int64 arrays."""
    lists = tree.query_ball_point(keys, radius, return_sorted=False)
    counts = np.fromiter((len(x) for x in lists), dtype=np.int64, count=len(lists))
    rows = np.repeat(np.arange(len(keys), dtype=np.int64), counts)
    cols = np.fromiter((j for x in lists for j in x), dtype=np.int64, count=int(counts.sum()))
    return rows, cols


def _linear_split(coord: np.ndarray, n_bins: int, *, wrap: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split a continuous bin coordinate (bin centres at 0, 1, ..., n_bins - 1) between its two
    nearest bins. Returns ``(lower bin, upper bin, weight of the upper bin)``. With ``wrap`` the
    coordinate is periodic with period ``n_bins``; otherwise it is clamped to ``[0, n_bins - 1]`` so
    values beyond the outer centres go wholly to the outer bin."""
    if wrap:
        lo = np.floor(coord)
        frac = coord - lo
        lo = lo.astype(np.int64) % n_bins
        return lo, (lo + 1) % n_bins, frac
    c = np.clip(coord, 0.0, n_bins - 1.0)
    lo = np.minimum(np.floor(c).astype(np.int64), n_bins - 2) if n_bins > 1 else np.zeros(c.shape, np.int64)
    frac = c - lo
    return lo, np.minimum(lo + 1, n_bins - 1), frac


def shot(keypoints, key_normals, support, support_normals, *, radius: float = 0.2, chunk: int = 1024) -> np.ndarray:
    """SHOT descriptors with the local frame fixed to the world axes.

    Parameters
    ----------
    keypoints : (k, 3) float, key_normals : (k, 3) float unit normals at the keypoints.
    support : (n, 3) float, support_normals : (n, 3) float: the dense cloud the histograms count.
    radius : support radius R.
    chunk : keypoints processed at once (memory bound only; results do not depend on it).

    Returns
    -------
    (k, 352) float32, rows of unit L2 length (all zeros when no support point lies within R).

    Binning, for a neighbour ``q`` of keypoint ``p`` with ``d = q - p`` in world coordinates:
    azimuth ``atan2(d_y, d_x)`` in 8 sectors of 45 degrees (periodic), elevation ``asin(d_z / |d|)``
    in 2 halves, distance ``|d|`` in 2 shells split at ``R / 2``, and ``cos = n_q . n_p`` in 11 equal
    bins over [-1, 1]. Quadrilinear interpolation: along each of the four dimensions the unit vote
    is split linearly between the two bins whose centres enclose the value (azimuth wraps; the
    others clamp beyond the outermost centres), so each neighbour adds to 16 bins with weights
    summing to 1. The index is ``((azimuth * 2 + elevation) * 2 + shell) * 11 + cos_bin``. A neighbour
    at the keypoint itself (``|d| = 0``) falls in azimuth 0, elevation upper half, inner shell.
    """
    keys, kn = _check_points(keypoints, key_normals, "keypoint")
    sup, sn = _check_points(support, support_normals, "support")
    if not radius > 0:
        raise ValueError(f"radius must be > 0, got {radius}")
    out = np.zeros((len(keys), SHOT_SIZE), dtype=np.float64)
    if len(keys) == 0 or len(sup) == 0:
        return out.astype(np.float32)
    tree = cKDTree(sup)
    for start in range(0, len(keys), chunk):
        stop = min(start + chunk, len(keys))
        rows, cols = _pairs(tree, keys[start:stop], radius)
        if len(rows) == 0:
            continue
        d = sup[cols] - keys[start + rows]
        dist = np.linalg.norm(d, axis=1)
        safe = np.where(dist > 0, dist, 1.0)
        azim = np.mod(np.arctan2(d[:, 1], d[:, 0]), 2 * np.pi)
        elev = np.arcsin(np.clip(d[:, 2] / safe, -1.0, 1.0))
        cosang = np.clip(np.einsum("ij,ij->i", sn[cols], kn[start + rows]), -1.0, 1.0)
        splits = [
            _linear_split(azim / (2 * np.pi / _N_AZ) - 0.5, _N_AZ, wrap=True),
            _linear_split(elev / (np.pi / 2) + 0.5, _N_EL, wrap=False),
            _linear_split(dist / (radius / 2) - 0.5, _N_RAD, wrap=False),
            _linear_split((cosang + 1.0) / (2.0 / _N_COS) - 0.5, _N_COS, wrap=False),
        ]
        hist = np.zeros((stop - start) * SHOT_SIZE)
        for corner in range(16):
            idx = np.zeros(len(rows), dtype=np.int64)
            w = np.ones(len(rows))
            for dim, (lo, hi, frac) in enumerate(splits):
                upper = (corner >> dim) & 1
                idx = idx * (_N_AZ, _N_EL, _N_RAD, _N_COS)[dim] + (hi if upper else lo)
                w = w * (frac if upper else 1.0 - frac)
            hist += np.bincount(rows * SHOT_SIZE + idx, weights=w, minlength=len(hist))
        out[start:stop] = hist.reshape(stop - start, SHOT_SIZE)
    norms = np.linalg.norm(out, axis=1, keepdims=True)
    out = np.divide(out, norms, out=np.zeros_like(out), where=norms > 0)
    return out.astype(np.float32)


def _spfh(P, N, rows, cols, n_rows) -> np.ndarray:
    """Simplified point feature histograms ``(n_rows, 33)`` of the pairs ``(P[rows], P[cols])``
    (``rows`` index the first ``n_rows`` of ``P``), each 11-bin block normalised to sum 1."""
    keep = rows != cols
    rows, cols = rows[keep], cols[keep]
    d = P[cols] - P[rows]
    dist = np.linalg.norm(d, axis=1)
    ok = dist > 0
    rows, cols, d, dist = rows[ok], cols[ok], d[ok], dist[ok]
    d = d / dist[:, None]
    u = N[rows]
    v = np.cross(u, d)
    vn = np.linalg.norm(v, axis=1, keepdims=True)
    v = np.divide(v, vn, out=np.zeros_like(v), where=vn > 0)
    w = np.cross(u, v)
    nt = N[cols]
    alpha = np.einsum("ij,ij->i", v, nt)
    phi = np.einsum("ij,ij->i", u, d)
    theta = np.arctan2(np.einsum("ij,ij->i", w, nt), np.einsum("ij,ij->i", u, nt))
    hist = np.zeros((n_rows, FPFH_SIZE))
    for block, (val, lo, hi) in enumerate([(alpha, -1.0, 1.0), (phi, -1.0, 1.0), (theta, -np.pi, np.pi)]):
        b = np.clip(((val - lo) / (hi - lo) * 11).astype(np.int64), 0, 10)
        hist[:, block * 11 : (block + 1) * 11] = np.bincount(rows * 11 + b, minlength=n_rows * 11).reshape(n_rows, 11)
    for block in range(3):
        part = hist[:, block * 11 : (block + 1) * 11]
        s = part.sum(axis=1, keepdims=True)
        hist[:, block * 11 : (block + 1) * 11] = np.divide(part, s, out=np.zeros_like(part), where=s > 0)
    return hist


def fpfh(keypoints, key_normals, support, support_normals, *, radius: float = 0.1) -> np.ndarray:
    """Fast point feature histograms of the keypoints over the support cloud.

    ``FPFH(p) = SPFH(p) + (1 / k) sum_i SPFH(q_i) / |q_i - p|`` over the ``k`` support points
    ``q_i`` within ``radius`` of ``p``; ``SPFH`` holds the Darboux-frame angles (alpha, phi, theta)
    of a point against its own neighbours within ``radius``, 11 bins each (alpha and phi over
    [-1, 1], theta over [-pi, pi]), each block normalised to sum 1. The source of every pair is the
    point whose histogram is being built (no swap by normal angle, a choice that keeps it
    vectorised). Returns ``(k, 33) float32`` rows of unit L2 length (zeros when isolated).
    """
    keys, kn = _check_points(keypoints, key_normals, "keypoint")
    sup, sn = _check_points(support, support_normals, "support")
    if not radius > 0:
        raise ValueError(f"radius must be > 0, got {radius}")
    if len(keys) == 0 or len(sup) == 0:
        return np.zeros((len(keys), FPFH_SIZE), dtype=np.float32)
    tree = cKDTree(sup)
    r_sup, c_sup = _pairs(tree, sup, radius)
    spfh_sup = _spfh(sup, sn, r_sup, c_sup, len(sup))
    allP, allN = np.concatenate([keys, sup]), np.concatenate([kn, sn])
    rows, cols = _pairs(tree, keys, radius)
    spfh_key = _spfh(allP, allN, rows, cols + len(keys), len(keys))
    dist = np.linalg.norm(sup[cols] - keys[rows], axis=1)
    ok = dist > 0
    wts = np.zeros(len(rows))
    wts[ok] = 1.0 / dist[ok]
    k = np.bincount(rows[ok], minlength=len(keys)).astype(np.float64)
    weights = sp.csr_matrix((wts, (rows, cols)), shape=(len(keys), len(sup)))
    acc = np.asarray(weights @ spfh_sup)
    out = spfh_key + np.divide(acc, k[:, None], out=np.zeros_like(acc), where=k[:, None] > 0)
    norms = np.linalg.norm(out, axis=1, keepdims=True)
    out = np.divide(out, norms, out=np.zeros_like(out), where=norms > 0)
    return out.astype(np.float32)


def descriptor_distances(A, B) -> np.ndarray:
    """Euclidean distances ``(len(A), len(B)) float64`` between descriptor rows ``A (a, d)``, ``B (b, d)``
    (computed as ``|a|^2 + |b|^2 - 2 a.b`` and clamped at 0 before the square root)."""
    A = np.asarray(A, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    d2 = (A * A).sum(1)[:, None] + (B * B).sum(1)[None, :] - 2.0 * (A @ B.T)
    return np.sqrt(np.maximum(d2, 0.0))
