"""The rooms of a registered method that the framework imports by name: its config schema and its
pipeline (apart from the registry, whose specs the summary reads without loading any method)."""

from __future__ import annotations

import importlib
from types import ModuleType

from synthkit.methods import METHODS

__all__ = ["config_module", "pipeline_module"]


def config_module(name: str) -> ModuleType:
    """The ``config`` module of method ``name``."""
    return importlib.import_module(f"{METHODS[name]}.config")


def pipeline_module(name: str) -> ModuleType:
    """The ``pipeline`` module of method ``name``."""
    return importlib.import_module(f"{METHODS[name]}.pipeline")
