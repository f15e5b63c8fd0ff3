"""What a run's summary shows: its headline metrics and its summary preview (imports nothing heavy,
so the command line can use it before numpy loads)."""

from __future__ import annotations

__all__ = ["HEADLINE_METRICS", "SUMMARY_KEYS", "MAIN_KEYS", "headline", "summary_preview", "main_output"]

HEADLINE_METRICS = ("n_principal", "sparsity_top7", "graph_nodes", "graph_labels", "energy", "cells", "labels",
                    "adjacency_violations", "normal_histogram_D", "objective_start", "objective_end",
                    "baseline_objective")
"""Metrics shown in the one-line run summary, batch rows and the review page, when a method reports them."""

SUMMARY_KEYS = ("before_after", "comparison", "preview_montage", "preview_regions", "preview_transfer",
                "labels_preview", "result", "after", "before")
"""Output keys of the image that shows a run's result best, most telling first (every method
registers one of them)."""


def summary_preview(outputs: dict) -> str | None:
    """The file name (relative to the run folder) of a run's summary preview among its ``outputs``
    (key -> file name): the first of :data:`SUMMARY_KEYS` present, else the first PNG, else None."""
    pngs = {k: v for k, v in outputs.items() if str(v).lower().endswith(".png")}
    for key in SUMMARY_KEYS:
        if key in pngs:
            return pngs[key]
    return next(iter(pngs.values()), None)


MAIN_KEYS = ("mesh", "transferred", "labels_ply", "result")
"""Output keys of a run's main result, first present wins (reshape's meshes are ``mesh_<piece>``)."""


def main_output(outputs: dict) -> str | None:
    """The file name of a run's main result among its ``outputs`` (key -> file name), or None."""
    for key in MAIN_KEYS:
        if key in outputs:
            return outputs[key]
    return next((v for k, v in outputs.items() if k.startswith("mesh_")), None)


def headline(metrics: dict) -> dict:
    """The scalar headline metrics of a report's ``metrics`` (:data:`HEADLINE_METRICS`; without
    any of them, the first four scalars)."""
    scalars = {k: v for k, v in metrics.items() if isinstance(v, int | float | str) and not isinstance(v, bool)}
    keys = [k for k in HEADLINE_METRICS if k in scalars] or list(scalars)[:4]
    return {k: scalars[k] for k in keys}
