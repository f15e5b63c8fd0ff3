"""A Dask worker plugin for synthkit runs (imports ``distributed``: used only by :mod:`synthkit.cluster`)."""

from __future__ import annotations

from distributed.diagnostics.plugin import WorkerPlugin

MAIN_THREAD_IMPORTS = ("pymeshlab",)
"""Native libraries imported in a worker's main thread before it runs anything.

pymeshlab imported first in a worker's task thread (where Dask runs tasks) leaves a static
``std::map`` of libmeshlab-common that glibc finds corrupt when the process exits
("malloc_consolidate(): unaligned fastbin chunk detected", SIGABRT): seen with the bundled
``configs/petri-synth/street_network.yaml`` in a thread, never in a main thread."""


class MainThreadImports(WorkerPlugin):
    """Import :data:`MAIN_THREAD_IMPORTS` when a worker starts or the plugin is registered
    (``setup`` runs in the worker's event loop, its main thread)."""

    name = "synthkit-main-thread-imports"

    def setup(self, worker) -> None:
        import importlib

        for module in MAIN_THREAD_IMPORTS:
            try:
                importlib.import_module(module)
            except ImportError:  # a worker without it fails the runs that need it, with their own line
                pass
