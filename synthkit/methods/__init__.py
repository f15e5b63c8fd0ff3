"""Registry of the methods: subcommand name -> package.

This dict is the only registry: the CLI builds one subcommand per available entry, so a method
registered here appears in ``synthkit --help`` and in ``synthkit run`` at once. Each method package
provides:

- ``__init__.py`` whose docstring's first line is the subcommand's help text, and ``SPEC``: the
  method's :class:`~synthkit.methods.spec.MethodSpec` (its Python functions, headline metrics,
  summary and main output keys, CLI flags, examples), from which the command line, the Python
  functions, the summary and the review page are built;
- ``config.py`` with the schema class bound to the module name ``CONFIG`` (a
  :class:`synthkit.config.RunConfig` subclass whose ``method`` is ``Literal['<name>']``);
- ``pipeline.py`` with ``compute(cfg, inputs, ctx) -> Result`` (reads every input through the
  :class:`synthkit.io.inputs.Inputs`, runs the stages, times them with ``ctx.stage``, fills
  ``ctx.metrics`` and maps stage ``ValueError``s to ``ConfigError``/``InputError`` naming the key;
  writes nothing). The runner writes its result (``result.write(ctx)``), and a refusal's
  ``result`` (a partial result it carries, such as retarget's statistics) before raising it;
- ``outputs.py`` with the method's :class:`synthkit.result.Result` subclass: its outputs in memory
  and ``write(ctx)``, which writes the files and previews through ``ctx.path``;
- ``options.py``: the one map from config keys to the stages' arguments;
- ``api.py`` with the public functions (``synthkit.<name>``, see :data:`synthkit.API_FUNCTIONS`).

A method is available when its package is present; modules are imported lazily so that
``synthkit --help`` stays fast (``__init__`` and its spec import nothing heavy).
"""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

from synthkit.methods.spec import MethodSpec

__all__ = ["METHODS", "MethodSpec", "available_methods", "package_module", "spec"]

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
    """The package of method ``name`` (its docstring's first line is the subcommand's help)."""
    return importlib.import_module(METHODS[name])


def spec(name: str) -> MethodSpec:
    """The :class:`MethodSpec` of method ``name``."""
    return package_module(name).SPEC
