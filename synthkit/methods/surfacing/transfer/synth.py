"""The four steps of section 4 iterated over one (target region, source region) pair.

State per target face: its patch id (-1 uncovered) and the domain coordinates of its corners in
that patch (``corner_uv (#F, 3, 2)``); per dual edge and side, the signal sampled along the edge
through that side's patch (``samples (E, 2, ns, C)``), from which seam costs follow.

Each iteration: grade and choose a target face (:mod:`.position`); match its (partial) fan or draw
a random source face and rotation (:mod:`.fans`); grow the mutual patch (:mod:`.param`, retried
twice with a random match when the seed cannot be placed, after which the face is skipped); trim
it by the min cut (:mod:`.trim`) or take it whole (``trimming: none``). Once every face is covered,
a patch that does not lower the total seam cost is undone. The loop ends when every face is
covered (or given up on) and the seam cost has not fallen for ``patience`` iterations, or after
``max_patches`` kept patches (``3 max_patches`` iterations at most).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from synthkit.methods.surfacing.transfer import position
from synthkit.methods.surfacing.transfer.fans import build_index, fan_points, make_cloud
from synthkit.methods.surfacing.transfer.param import Patch, mutual_patch
from synthkit.methods.surfacing.transfer.surface import Surface
from synthkit.methods.surfacing.transfer.trim import seam_costs, trim_cut

__all__ = ["Options", "Result", "Synthesis", "synthesize", "GRADE_SHARE"]

GRADE_SHARE = 0.25
"""Radius of the grading neighbourhood (4.1) as a share of the patch radius."""


@dataclass
class Options:
    """Synthesis settings; lengths in target units (see the config schema for their meaning)."""

    patch_radius: float
    scale: float
    bound: float
    matching: str
    parameterization: str
    trimming: str
    spokes: int
    steps: int
    fan_share: float
    tolerance: float
    edge_samples: int
    max_patches: int
    patience: int
    fixed_orientation: bool
    fixed_patches: bool = False


@dataclass
class Result:
    """``patch_of (#F,)``, ``corner_uv (#F, 3, 2)``, ``patches``, per-face ``distortion (#F,)``,
    ``seam_cost`` per iteration, timings per step kind, ``failed (#F,) bool`` skipped faces and the
    final edge ``samples (E, 2, ns, C)``."""

    patch_of: np.ndarray
    corner_uv: np.ndarray
    patches: list[Patch]
    distortion: np.ndarray
    seam_cost: list[float]
    timings: dict
    failed: np.ndarray
    iterations: int
    samples: np.ndarray


def _corner_index(F: np.ndarray, faces: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Corner (0-2) of ``vertices (E,)`` in ``faces (E,)``."""
    return np.argmax(F[faces] == vertices[:, None], axis=1)


class Synthesis:
    """Patch synthesis of ``source``'s signal over ``target`` (see the module docstring).
    Randomness enters through ``rng`` (positions, matches among near-ties, random matches)."""

    def __init__(self, target: Surface, source: Surface, opt: Options, *, rng, channels=None):
        t0 = time.perf_counter()
        self.t, self.s, self.opt, self.rng = target, source, opt, rng
        self.channels = channels
        nF = len(target.F)
        self.patch_of = np.full(nF, -1, np.int64)
        self.corner_uv = np.zeros((nF, 3, 2))
        self.dist = np.zeros(nF)
        self.failed = np.zeros(nF, bool)
        self.patches: list[Patch] = []
        pairs, edges = target.pairs, target.edges
        self.lengths = np.linalg.norm(target.V[edges[:, 0]] - target.V[edges[:, 1]], axis=1)
        self.ci = np.stack([_corner_index(target.F, pairs[:, s], edges[:, 0]) for s in (0, 1)], 1)
        self.cj = np.stack([_corner_index(target.F, pairs[:, s], edges[:, 1]) for s in (0, 1)], 1)
        self.cloud_t = make_cloud(target)
        self.timings = {"precompute_fans": 0.0, "position": 0.0, "match": 0.0, "parameterize": 0.0, "trim": 0.0}
        C = len(channels) if channels is not None else source.signal.channels
        self.samples = np.zeros((len(pairs), 2, opt.edge_samples, C))
        mid = 0.5 * (target.V[edges[:, 0]] + target.V[edges[:, 1]])
        self.W = position.grading_matrix(target.centroids, mid, GRADE_SHARE * opt.patch_radius)
        t1 = time.perf_counter()
        cloud_s = make_cloud(source)
        vals = self._source_values(cloud_s.faces, cloud_s.bary)
        self.index = build_index(source, cloud_s, vals, spokes=opt.spokes, steps=opt.steps,
                                 radius=opt.fan_share * opt.patch_radius / opt.scale)
        self.max_difference = float(np.linalg.norm(vals.max(axis=0) - vals.min(axis=0))) or 1.0
        self.timings["precompute_fans"] = time.perf_counter() - t1
        self.timings["precompute"] = t1 - t0
        self.seam_history: list[float] = []

    # ---------------------------------------------------------------------------------------------
    # signals

    def _source_values(self, faces, bary) -> np.ndarray:
        v = self.s.signal.sample(faces, bary)
        return v if self.channels is None else v[:, self.channels]

    def _through(self, patch: Patch, Q: np.ndarray) -> np.ndarray:
        """Signal ``(n, C)`` at domain points ``Q (n, 2)`` of ``patch``."""
        if not len(Q):
            return np.zeros((0, self.samples.shape[3]))
        f, b, _ = patch.to_source(Q)
        return self._source_values(f, b)

    def _edge_uv(self, corner_uv, faces, ci, cj) -> np.ndarray:
        """Domain points ``(E, ns, 2)`` at the arclength fractions of the edges ``(ci, cj)`` of ``faces``."""
        t = (np.arange(self.opt.edge_samples) + 0.5) / self.opt.edge_samples
        a, b = corner_uv[faces, ci], corner_uv[faces, cj]
        return a[:, None] * (1 - t)[None, :, None] + b[:, None] * t[None, :, None]

    def target_values(self, faces, bary) -> np.ndarray:
        """Current signal ``(n, C)`` at target points (``faces (n,)``, ``bary (n, 3)``); NaN uncovered."""
        out = np.full((len(faces), self.samples.shape[3]), np.nan)
        pid = self.patch_of[faces]
        for p in np.unique(pid[pid >= 0]):
            sel = pid == p
            Q = np.einsum("nk,nkc->nc", bary[sel], self.corner_uv[faces[sel]])
            out[sel] = self._through(self.patches[p], Q)
        return out

    def covered(self) -> bool:
        """Whether every face is covered, or was given up on (no patch could be placed at it)."""
        return bool(((self.patch_of >= 0) | self.failed).all())

    def seams(self) -> np.ndarray:
        """Seam cost ``(E,)`` of every dual edge (0 inside a patch or next to an uncovered face)."""
        a, b = self.patch_of[self.t.pairs[:, 0]], self.patch_of[self.t.pairs[:, 1]]
        on = (a >= 0) & (b >= 0) & (a != b)
        out = np.zeros(len(a))
        out[on] = seam_costs(self.samples[on, 0], self.samples[on, 1], self.lengths[on])
        return out

    # ---------------------------------------------------------------------------------------------
    # the four steps

    def _position(self) -> int | None:
        g = position.edge_grades(self.patch_of, self.t.pairs, self.seams(), self.lengths, self.max_difference)
        allowed = ~self.failed
        open_faces = allowed & (self.patch_of < 0)
        return position.choose_position(self.W @ g, self.patch_of < 0, open_faces if open_faces.any() else allowed,
                                        rng=self.rng, tolerance=self.opt.tolerance)

    def _fan(self, seed: int):
        o = self.opt
        idx, mask = fan_points(self.t, self.cloud_t, [seed], spokes=o.spokes, steps=o.steps,
                               radius=o.fan_share * o.patch_radius)
        idx, mask = idx[0], mask[0]
        faces = self.cloud_t.faces[idx]
        mask = mask & (self.patch_of[faces] >= 0)
        fan = np.zeros((o.spokes, o.steps, self.samples.shape[3]))
        fan[mask] = self.target_values(faces[mask], self.cloud_t.bary[idx[mask]])
        return fan, mask

    def _place(self, seed: int) -> Patch | None:
        o = self.opt
        for attempt in range(3):
            t = time.perf_counter()
            if o.matching == "fans" and attempt == 0:
                face, theta = self.index.match(*self._fan(seed), rng=self.rng, tolerance=o.tolerance,
                                               fixed=o.fixed_orientation)
            else:
                face, theta = self.index.random(self.rng, fixed=o.fixed_orientation)
            t1 = time.perf_counter()
            self.timings["match"] += t1 - t
            patch = mutual_patch(self.t, seed, self.s, face, theta, radius=o.patch_radius, bound=o.bound,
                                 scale=o.scale, method=o.parameterization)
            self.timings["parameterize"] += time.perf_counter() - t1
            if patch is not None:
                return patch
        return None

    def _proposal(self, patch: Patch):
        """Dual-edge rows touching the patch, the patch's edge samples there ``(R, ns, C)``, the
        faces-in-patch mask and each face's row in ``patch.faces``."""
        pairs = self.t.pairs
        inq = np.zeros(len(self.t.F), bool)
        inq[patch.faces] = True
        pos = np.full(len(self.t.F), -1, np.int64)
        pos[patch.faces] = np.arange(len(patch.faces))
        rows = np.flatnonzero(inq[pairs].any(axis=1))
        side = np.where(inq[pairs[rows, 0]], 0, 1)
        f = pairs[rows, side]
        uv = self._edge_uv(patch.corner_uv, pos[f], self.ci[rows, side], self.cj[rows, side])
        C = self.samples.shape[3]
        sp = self._through(patch, uv.reshape(-1, 2)).reshape(len(rows), self.opt.edge_samples, C)
        return rows, sp, inq, pos

    def _trim(self, patch: Patch, rows, sp, inq, pos) -> np.ndarray:
        """Mask over ``patch.faces`` of the faces that take the patch (the min cut of :mod:`.trim`)."""
        n = len(patch.faces)
        if self.opt.trimming == "none":
            return np.ones(n, bool)
        pr = self.t.pairs[rows]
        L = self.lengths[rows]
        s0, s1 = self.samples[rows, 0], self.samples[rows, 1]
        ma, mb, old = seam_costs(s0, sp, L), seam_costs(sp, s1, L), seam_costs(s0, s1, L)
        a, b = self.patch_of[pr[:, 0]], self.patch_of[pr[:, 1]]
        on_seam = (a >= 0) & (b >= 0) & (a != b)
        keep_cost, take_cost = np.zeros(n), np.zeros(n)
        qa, qb = inq[pr[:, 0]], inq[pr[:, 1]]
        for mine, other, m_take, cov in ((qa & ~qb, 0, mb, b >= 0), (qb & ~qa, 1, ma, a >= 0)):
            node = pos[pr[mine, other]]
            np.add.at(take_cost, node, np.where(cov[mine], m_take[mine], 0.0))
            np.add.at(keep_cost, node, np.where(on_seam[mine], old[mine], 0.0))
        both = qa & qb
        cost_a = np.where(a[both] < 0, np.where(b[both] < 0, 0.0, mb[both]), ma[both])
        forced = self.patch_of[patch.faces] < 0
        forced[pos[patch.seed]] = True
        take, _ = trim_cut(n, forced, keep_cost, take_cost, pos[pr[both]], cost_a, mb[both], old[both],
                           on_seam[both])
        return take

    def _apply(self, pid: int, patch: Patch, take: np.ndarray, rows, sp) -> tuple:
        """Give the taken faces the patch; returns what :meth:`_undo` needs."""
        faces = patch.faces[take]
        saved = (faces, self.patch_of[faces].copy(), self.corner_uv[faces].copy(), self.dist[faces].copy(),
                 rows, self.samples[rows].copy())
        self.patch_of[faces] = pid
        self.corner_uv[faces] = patch.corner_uv[take]
        self.dist[faces] = patch.distortion[take]
        taken = np.zeros(len(self.t.F), bool)
        taken[faces] = True
        for s in (0, 1):
            sel = taken[self.t.pairs[rows, s]]
            self.samples[rows[sel], s] = sp[sel]
        return saved

    def _undo(self, saved: tuple) -> None:
        faces, patch_of, corner_uv, dist, rows, samples = saved
        self.patch_of[faces], self.corner_uv[faces], self.dist[faces] = patch_of, corner_uv, dist
        self.samples[rows] = samples

    def step(self) -> bool:
        """One iteration; False when no face is left to place a patch at."""
        t = time.perf_counter()
        seed = self._position()
        self.timings["position"] += time.perf_counter() - t
        if seed is None:
            return False
        patch = self._place(seed)
        if patch is None:
            self.failed[seed] = True
            return True
        t = time.perf_counter()
        rows, sp, inq, pos = self._proposal(patch)
        take = self._trim(patch, rows, sp, inq, pos)
        was_covered = self.covered()
        before = float(self.seams().sum())
        saved = self._apply(len(self.patches), patch, take, rows, sp)
        self.patches.append(patch)
        if was_covered and not self.opt.fixed_patches and self.seams().sum() >= before - 1e-12:
            self._undo(saved)
            self.patches.pop()
        self.timings["trim"] += time.perf_counter() - t
        return True

    def run(self) -> Result:
        """Iterate (module docstring) and return the result."""
        o = self.opt
        stall, iterations = 0, 0
        while len(self.patches) < o.max_patches and iterations < 3 * o.max_patches:
            iterations += 1
            before = self.seam_history[-1] if self.seam_history else np.inf
            if not self.step():
                break
            cost = float(self.seams().sum())
            self.seam_history.append(cost)
            covered = self.covered()
            stall = stall + 1 if covered and cost >= before - 1e-12 else 0
            if covered and not o.fixed_patches and stall >= o.patience:
                break
        return Result(self.patch_of, self.corner_uv, self.patches, self.dist, self.seam_history,
                      self.timings, self.failed, iterations, self.samples)


def synthesize(target: Surface, source: Surface, opt: Options, *, rng, channels=None) -> Result:
    """One-shot :class:`Synthesis` run."""
    return Synthesis(target, source, opt, rng=rng, channels=channels).run()
