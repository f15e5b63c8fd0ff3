"""synthkit: example-based 3D model and texture synthesis from five graphics papers.

Each method is one function over meshes and images in memory (:mod:`synthkit.api`):

- :func:`synthkit.retarget` -- retarget a mesh by offset statistics;
- :func:`synthkit.segment` and :func:`synthkit.transfer` -- surfacing by numbers;
- :func:`synthkit.reshape` -- reshape textured architecture;
- :func:`synthkit.petri_synth` -- Petri-net synthesis;
- :func:`synthkit.symmetry_texture` -- symmetry-guided texture synthesis.

They are imported on first use, so that ``import synthkit`` stays fast.
"""

import importlib

from synthkit import methods as _registry
from synthkit.version import __version__

API_FUNCTIONS = {
    function: f"{_registry.METHODS[name]}.api"
    for name in _registry.available_methods()
    for function in _registry.spec(name).functions
}
"""Public function name -> the module that defines it, from each method's spec."""

__all__ = ["__version__", *API_FUNCTIONS]


def __getattr__(name: str):
    module = API_FUNCTIONS.get(name)
    if module is None:
        raise AttributeError(f"module 'synthkit' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)


def __dir__() -> list[str]:
    return sorted({*globals(), *API_FUNCTIONS})
