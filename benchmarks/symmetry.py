"""Benchmark of the translational symmetry transform S_T (issue 2 goals).

Measures the median time of ``synthkit.core.symmetry.translational`` (float32, standardized,
toroidal) on 250x250 and 512x512 images against a naive baseline in the same run (float64
``numpy.fft`` autocorrelation with the same normalization) and against the paper's 43 ms
(250x250). Also the zero-padded variant and the incremental update of one 32x32 block.

Run: ``.venv/bin/python benchmarks/symmetry.py [--quick]``; writes bench-results/symmetry.json.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import median_time, print_table, record, write_results  # noqa: E402
from synthkit.core import symmetry as sy  # noqa: E402
from synthkit.core.autocorrelation import IncrementalAutocorrelation  # noqa: E402

AREA = "symmetry"
PAPER_MS_250 = 43.0


def naive_st(f: np.ndarray) -> np.ndarray:
    """Float64 numpy.fft toroidal autocorrelation, standardized (the straightforward way)."""
    F = np.fft.fft2(f.astype(np.float64))
    ac = np.real(np.fft.ifft2(F * np.conj(F)))
    ac = np.fft.fftshift(ac) / ac[0, 0]
    return (ac - ac.mean()) / ac.std()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats")
    args = ap.parse_args()
    repeats = 15 if args.quick else 51
    rng = np.random.default_rng(0)
    goals = {250: 5.0, 512: 15.0}
    for n in (250, 512):
        f32 = rng.random((n, n)).astype(np.float32)
        ours = median_time(lambda f=f32: sy.translational(f, workers=1), repeats=repeats, warmup=3) * 1e3
        base = median_time(lambda f=f32: naive_st(f), repeats=repeats, warmup=1) * 1e3
        record(AREA, f"S_T {n}x{n} median (vs numpy float64)", ours, "ms", goal=goals[n], baseline=base)
        if n == 250:
            record(AREA, "S_T 250x250 median (vs paper 43 ms)", ours, "ms", goal=goals[n], baseline=PAPER_MS_250)
        zero = median_time(lambda f=f32: sy.translational(f, mode="zero", workers=1), repeats=repeats) * 1e3
        record(AREA, f"S_T zero-padded {n}x{n} median", zero, "ms", baseline=base)
    # incremental update: one 32x32 block, window 64, against the full float64 recompute
    f = rng.random((512, 512))
    inc = IncrementalAutocorrelation(f, window=(64, 64))
    deltas = rng.standard_normal((32, 32, 32))
    batch = median_time(lambda: inc.delta(100, 200, deltas), repeats=max(5, repeats // 5)) * 1e3 / 32
    full = median_time(
        lambda: sy.translational(f, window=(64, 64), standardize=False), repeats=max(5, repeats // 5)
    ) * 1e3
    record(AREA, "dS_T one 32px block, per candidate (batch 32)", batch, "ms", baseline=full)
    print_table(AREA)
    path = write_results(AREA)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
