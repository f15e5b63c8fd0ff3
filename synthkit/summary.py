"""What a run's summary shows: its headline metrics, its summary preview and its main result, from
the method's spec (:class:`~synthkit.methods.spec.MethodSpec`; imports nothing heavy, so the command
line can use it before numpy loads)."""

from __future__ import annotations

from synthkit.methods import METHODS, MethodSpec, spec

__all__ = ["headline", "summary_preview", "main_output"]

NO_SPEC = MethodSpec(functions=())
"""What a report of a method this version does not register is summarised by: no named keys."""


def _spec(method: str | None) -> MethodSpec:
    return spec(method) if method in METHODS else NO_SPEC


def summary_preview(outputs: dict, method: str | None) -> str | None:
    """The file name (relative to the run folder) of a run's summary preview among its ``outputs``
    (key -> file name): the first of the method's ``summary_keys`` present, else the first PNG,
    else None."""
    pngs = {k: v for k, v in outputs.items() if str(v).lower().endswith(".png")}
    for key in _spec(method).summary_keys:
        if key in pngs:
            return pngs[key]
    return next(iter(pngs.values()), None)


def main_output(outputs: dict, method: str | None) -> str | None:
    """The file name of a run's main result among its ``outputs`` (key -> file name): the first of
    the method's ``main_keys`` present (a key ending in ``_`` matches as a prefix), or None."""
    for key in _spec(method).main_keys:
        found = [v for k, v in outputs.items() if k == key or (key.endswith("_") and k.startswith(key))]
        if found:
            return found[0]
    return None


def headline(metrics: dict, method: str | None) -> dict:
    """The scalar headline metrics of a report's ``metrics`` (the method's ``headline``; without
    any of them, the first four scalars)."""
    scalars = {k: v for k, v in metrics.items() if isinstance(v, int | float | str) and not isinstance(v, bool)}
    keys = [k for k in _spec(method).headline if k in scalars] or list(scalars)[:4]
    return {k: scalars[k] for k in keys}
