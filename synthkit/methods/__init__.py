"""Registry of the methods: subcommand name -> package with ``config.CONFIG`` and ``pipeline.run``.

This dict is the only registry: the CLI builds one subcommand per available entry, so a method
registered here appears in ``synthkit --help`` and in ``synthkit run`` at once. Each method package
provides:

- ``__init__.py`` whose docstring's first line is the subcommand's help text, and optionally
  ``CLI_FLAGS``: extra boolean options, ``{"--analyze-only": ("analyze_only=true", "help")}``, each
  adding a ``--set`` override when given;
- ``config.py`` with the schema class bound to the module name ``CONFIG`` (a
  :class:`synthkit.config.RunConfig` subclass whose ``method`` is ``Literal['<name>']``);
- ``pipeline.py`` with ``compute(cfg, inputs, ctx) -> Result`` (reads every input through the
  :class:`synthkit.io.inputs.Inputs`, runs the stages, times them with ``ctx.stage``, fills
  ``ctx.metrics`` and maps stage ``ValueError``s to ``ConfigError``/``InputError`` naming the key;
  writes nothing) and ``run(cfg, ctx: synthkit.context.RunContext) -> None`` (the command line:
  ``compute(cfg, Inputs(), ctx).write(ctx)``);
- ``outputs.py`` with the method's :class:`synthkit.api.Result` subclass: its outputs in memory and
  ``write(ctx)``, which writes the files and previews through ``ctx.path``;
- ``options.py``: the one map from config keys to the stages' arguments;
- ``api.py`` with the public function (``synthkit.<name>``, see :data:`synthkit.API_FUNCTIONS`).

A method is available when its package is present; modules are imported lazily so that
``synthkit --help`` stays fast.
"""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

METHODS: dict[str, str] = {
    "retarget": "synthkit.methods.retarget",
    "surface-by-numbers": "synthkit.methods.surfacing",
    "reshape": "synthkit.methods.reshape",
    "petri-synth": "synthkit.methods.petri",
    "symmetry-texture": "synthkit.methods.symtex",
}
"""Subcommand name -> method package."""


def available_methods() -> list[str]:
    """Subcommand names whose method package has a pipeline module, in registry order."""
    found = []
    for name, package in METHODS.items():
        try:
            present = importlib.util.find_spec(f"{package}.pipeline") is not None
        except ModuleNotFoundError:
            present = False
        if present:
            found.append(name)
    return found


def package_module(name: str) -> ModuleType:
    """The package of method ``name`` (its docstring and ``CLI_FLAGS`` describe the subcommand)."""
    return importlib.import_module(METHODS[name])


def config_module(name: str) -> ModuleType:
    """The ``config`` module of method ``name``."""
    return importlib.import_module(f"{METHODS[name]}.config")


def pipeline_module(name: str) -> ModuleType:
    """The ``pipeline`` module of method ``name``."""
    return importlib.import_module(f"{METHODS[name]}.pipeline")
