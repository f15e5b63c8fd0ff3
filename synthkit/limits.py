"""Work budgets: every method estimates the size of its work before it allocates.

A pipeline calls :meth:`Budget.require` with the config key that drives a size (a sampling
radius, an output size, a curve length), that key's value, the estimated count of work items
(samples, cells, pixels, graph nodes) and the bytes each item costs. When ``count *
bytes_each`` exceeds the run's memory budget the run stops before any allocation with one
:class:`~synthkit.errors.ConfigError` line (exit 2), e.g.::

    analysis.dense_radius: 0.0001 needs about 4.1e+07 samples (limit 1.2e+07 at 12 GiB; --max-memory raises it)

The budget defaults to :data:`DEFAULT_MEMORY_SHARE` of the machine's physical memory; the global
``--max-memory`` option sets it in GiB.
"""

from __future__ import annotations

import math
import os

from synthkit.errors import ConfigError

DEFAULT_MEMORY_SHARE = 0.5
"""Share of physical memory one run may plan to use when ``--max-memory`` is not given."""

_FALLBACK_MEMORY = 8 * 2**30
"""Physical memory assumed where the OS does not report it (bytes)."""


def physical_memory() -> int:
    """Bytes of physical memory of this machine (``_FALLBACK_MEMORY`` when unknown)."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return _FALLBACK_MEMORY


def default_max_bytes() -> int:
    """The default memory budget of one run: ``DEFAULT_MEMORY_SHARE`` of physical memory."""
    return int(physical_memory() * DEFAULT_MEMORY_SHARE)


class Budget:
    """The memory budget of one run, in bytes, checked against estimates before work starts."""

    def __init__(self, max_bytes: int | None = None):
        self.max_bytes = int(max_bytes) if max_bytes is not None else default_max_bytes()
        if self.max_bytes <= 0:
            raise ValueError(f"memory budget must be positive, got {max_bytes}")

    def limit(self, bytes_each: float) -> int:
        """How many items of ``bytes_each`` bytes fit in the budget."""
        return int(self.max_bytes // max(float(bytes_each), 1.0))

    def require(self, key: str, value, count: float, unit: str, *, bytes_each: float) -> None:
        """Refuse (ConfigError naming ``key`` and ``value``) when ``count`` items of ``unit``, each
        ``bytes_each`` bytes, exceed the budget. A non-finite ``count`` is refused as well."""
        limit = self.limit(bytes_each)
        if math.isfinite(count) and count <= limit:
            return
        shown = f"about {count:.2g}" if math.isfinite(count) else "unboundedly many"
        raise ConfigError(
            f"{key}: {value} needs {shown} {unit} (limit {limit:.2g} at "
            f"{self.max_bytes / 2**30:.3g} GiB; --max-memory raises it)"
        )


__all__ = ["Budget", "DEFAULT_MEMORY_SHARE", "default_max_bytes", "physical_memory"]
