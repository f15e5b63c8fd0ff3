"""Objectives on symmetry representations of images: E_L2 to a target, or E_symm (paper eqs. 1, 4).

An :class:`Objective` turns an image ``(H, W[, C]) float`` into its input signals (f_lum, f_1-lum,
f_edge), computes the chosen representation of each and sums the per-signal objective. For E_L2
the representations are standardized (mean 0, variance 1) and compared with standardized
targets; E_symm is the variance of the raw representation (eq. 2 normalization), maximized.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from synthkit.core import symmetry as sy


def st_window(shape: tuple[int, int], fraction: float) -> tuple[int, int]:
    """S_T window ``(wy, wx)`` in pixels: ``fraction`` of the size, at most ``(n - 1) // 2``, at least 1."""
    return tuple(max(1, min(int(fraction * n), (n - 1) // 2)) for n in shape[:2])


class Objective:
    """Sum over ``signals`` of E_L2(S(f_s), T_s) (``kind="l2"``) or E_symm(S(f_s)) (``kind="symm"``).

    Parameters
    ----------
    representation : "translational", "rotational" or "reflective".
    signals : names accepted by :func:`synthkit.core.symmetry.signal`.
    kind : "l2" or "symm".
    targets : one standardized target per signal (kind "l2").
    window : S_T window ``(wy, wx)``; mode : S_T "toroidal" or "zero".
    center, n_angles : S_R / S_Ref parameters (centre (row, col) in pixels of the evaluated image).
    crop : ``(h, w)``: S_T of the centred ``h x w`` crop of each signal (a whole number of periods,
        :func:`synthkit.core.symmetry.whole_period_crop`); None: of the whole signal.
    """

    def __init__(
        self,
        *,
        representation: str,
        signals: Sequence[str],
        kind: str,
        targets: Sequence[np.ndarray] | None = None,
        window: tuple[int, int] | None = None,
        mode: str = "toroidal",
        center: tuple[float, float] | None = None,
        n_angles: int = 360,
        crop: tuple[int, int] | None = None,
    ):
        if kind not in ("l2", "symm"):
            raise ValueError(f"objective kind must be 'l2' or 'symm', got {kind!r}")
        if kind == "l2" and (targets is None or len(targets) != len(signals)):
            raise ValueError("E_L2 needs one target per signal")
        self.representation = representation
        self.signals = list(signals)
        self.kind = kind
        self.targets = None if targets is None else [np.asarray(t, dtype=np.float64) for t in targets]
        self.window = window
        self.mode = mode
        self.center = center
        self.n_angles = n_angles
        self.crop = None if crop is None else (int(crop[0]), int(crop[1]))

    def represent(self, f: np.ndarray, *, standardize: bool) -> np.ndarray:
        """Representation of one signal ``f (H, W)``."""
        if self.representation == "translational":
            return sy.translational(self._cropped(f), mode=self.mode, window=self.window, standardize=standardize)
        fn = sy.rotational if self.representation == "rotational" else sy.reflective
        return fn(f, center=self.center, n_angles=self.n_angles, standardize=standardize)

    def _cropped(self, f: np.ndarray) -> np.ndarray:
        """The centred ``crop`` of one signal ``f (H, W)`` (``f`` itself without a crop)."""
        if self.crop is None:
            return f
        (h, w), (H, W) = self.crop, f.shape
        return f[(H - h) // 2 : (H - h) // 2 + h, (W - w) // 2 : (W - w) // 2 + w]

    def representations(self, img: np.ndarray) -> list[np.ndarray]:
        """Per-signal representations of ``img`` (standardized for E_L2, raw for E_symm)."""
        if self.kind == "symm":
            # E_symm is the variance of a raw S close to a constant: float64 (float32 kept 3 digits
            # of a probe's change on faint line art; docs/findings/symmetry-texture.md)
            img64 = np.asarray(img, dtype=np.float64)
            return [self.represent(sy.signal(img64, s), standardize=False) for s in self.signals]
        img32 = np.asarray(img, dtype=np.float32)
        return [self.represent(sy.signal(img32, s), standardize=True) for s in self.signals]

    def value(self, img: np.ndarray) -> float:
        """The objective of ``img``: summed E_L2 (lower is better) or summed E_symm (higher is better)."""
        if self.kind == "symm" and (self.representation, self.mode) == ("translational", "toroidal"):
            # E_symm of the toroidal S_T from the power spectrum (no inverse transform), float64
            img64 = np.asarray(img, dtype=np.float64)
            fs = [self._cropped(sy.signal(img64, s)) for s in self.signals]
            return float(sum(sy.e_symm_toroidal(f, window=self.window) for f in fs))
        reps = self.representations(img)
        if self.kind == "l2":
            return float(sum(sy.e_l2(S, T) for S, T in zip(reps, self.targets, strict=True)))
        return float(sum(sy.e_symm(S) for S in reps))

    def loss(self, img: np.ndarray) -> float:
        """Quantity to minimize: E_L2, or -E_symm."""
        v = self.value(img)
        return v if self.kind == "l2" else -v
