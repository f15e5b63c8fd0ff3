"""Registry of the methods: subcommand name -> package with ``config.CONFIG`` and ``pipeline.run``.

Each method package ``synthkit.methods.<package>`` provides:

- ``config.py`` with the schema class bound to the module name ``CONFIG`` (a
  :class:`synthkit.config.RunConfig` subclass whose ``method`` is ``Literal['<name>']``);
- ``pipeline.py`` with ``run(cfg, ctx: synthkit.runner.RunContext) -> None``, which reads inputs
  through :mod:`synthkit.io`, times its stages with ``ctx.stage``, writes outputs through
  ``ctx.path`` and fills ``ctx.metrics``.

A method is available when its package imports; modules are imported lazily so that
``synthkit --help`` stays fast.
"""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

METHODS: dict[str, str] = {
    "retarget": "retarget",
    "surface-by-numbers": "surfacing",
    "reshape": "reshape",
    "petri-synth": "petri",
    "symmetry-texture": "symtex",
}
"""Subcommand name -> package name under :mod:`synthkit.methods`."""


def available_methods() -> list[str]:
    """Subcommand names whose method package is present, in registry order."""
    found = []
    for name, pkg in METHODS.items():
        if importlib.util.find_spec(f"synthkit.methods.{pkg}") is None:
            continue
        if importlib.util.find_spec(f"synthkit.methods.{pkg}.pipeline") is not None:
            found.append(name)
    return found


def config_module(name: str) -> ModuleType:
    """The ``config`` module of method ``name``."""
    return importlib.import_module(f"synthkit.methods.{METHODS[name]}.config")


def pipeline_module(name: str) -> ModuleType:
    """The ``pipeline`` module of method ``name``."""
    return importlib.import_module(f"synthkit.methods.{METHODS[name]}.pipeline")
