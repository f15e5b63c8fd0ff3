"""synthkit from Python: each method as one function over meshes and images in memory.

``synthkit.retarget``, ``synthkit.segment``, ``synthkit.transfer``, ``synthkit.reshape``,
``synthkit.petri_synth`` and ``synthkit.symmetry_texture`` take their inputs as objects
(``trimesh.Trimesh``, ``(V, F)`` arrays, :class:`~synthkit.asset.Asset`, image arrays; paths
are read as from a config) and the config's keys as keyword arguments, validated by the method's
config schema with the command line's messages (a section is a ``dict``:
``segment(mesh, regions=[...], boundary={"eta": 2.0})``). They run the same pipeline as the
command line, write nothing, and return a :class:`Result` with the outputs in memory, the
``metrics``, ``timings`` and ``status`` that ``report.json`` would hold, and :meth:`Result.save`,
which writes the command line's output folder.

This module holds what the six have in common: :func:`prepare` (keys and objects to a validated
config and an :class:`~synthkit.io.inputs.Inputs`), :func:`run_in_memory` and the :class:`Result`
base class. Each method's own function lives in ``synthkit/methods/<method>/api.py``.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from synthkit.config import RunConfig, sub_models, validate_config
from synthkit.errors import ConfigError, SynthkitError
from synthkit.io.inputs import Inputs, is_memory_object, memory_name
from synthkit.methods.rooms import config_module
from synthkit.result import Result, result_fields

__all__ = ["Result", "prepare", "run_in_memory", "result_fields"]


def prepare(method: str, call: str, given: Mapping[str, object], keys: Mapping[str, Any]) -> tuple[RunConfig, Inputs]:
    """Validate a method's keyword arguments into its config; return it with the run's inputs.

    Parameters
    ----------
    method : the subcommand name (``"retarget"``)
    call : what error lines start with (``"synthkit.retarget()"``)
    given : config key (dotted) -> object, for the function's positional inputs (``{"input": mesh}``)
    keys : the keyword arguments: config keys, sections as dicts, lists of sections as lists. A mesh
        or image object (see :mod:`synthkit.io.inputs`) may stand wherever the config names an input
        file; other arrays (points, colours) are read as lists.

    Raises
    ------
    ConfigError : a key is unknown or a value is out of range (the command line's message,
        naming the key and value).
    InputError : a file named by a path does not exist.
    """
    model = config_module(method).CONFIG
    data: dict[str, Any] = {**keys, "method": method}
    for dotted, obj in given.items():
        _put(data, dotted.split("."), obj)
    objects: dict[str, object] = {}
    try:
        data = _stand_ins(data, [model], (), objects)
    except ConfigError as exc:
        raise ConfigError(f"{call}: {exc}") from None
    files: list[Path] = []
    cfg = validate_config(model, data, source=call, base_dir=Path.cwd(), inputs=files,
                          memory_inputs=objects.keys())
    inputs = Inputs(objects)
    inputs.files = files
    return cfg, inputs


def _put(data: dict, parts: list[str], obj: object) -> None:
    """Set ``data[parts[0]][parts[1]]... = obj``, creating the sections on the way."""
    for part in parts[:-1]:
        data = data.setdefault(part, {})
    data[parts[-1]] = obj


def _is_input_file(annotation: Any, metadata: list) -> bool:
    """Whether a schema field holds an input file (:data:`synthkit.config.InputFile`)."""
    return "_resolve_input_file" in repr(annotation) + repr(metadata)


def _stand_ins(value: Any, models: list, loc: tuple, objects: dict[str, object]) -> Any:
    """``value`` with every mesh or image object at an input-file key replaced by its stand-in name
    (recorded in ``objects``) and every other array turned into lists; ``models`` are the schema
    classes the value may be validated as."""
    if isinstance(value, Mapping):
        out = {}
        for key, item in value.items():
            fields = [m.model_fields[key] for m in models if key in getattr(m, "model_fields", {})]
            if fields and any(_is_input_file(f.annotation, f.metadata) for f in fields):
                dotted = ".".join(str(p) for p in (*loc, key))
                if is_memory_object(item):
                    objects[memory_name(dotted)] = item
                    out[key] = memory_name(dotted)
                    continue
                if item is not None and not isinstance(item, str | os.PathLike):
                    raise ConfigError(f"{dotted}: expected a mesh, an image array or a path, got {type(item).__name__}")
            inner = [m for f in fields for m in sub_models(f.annotation)]
            out[key] = _stand_ins(item, inner, (*loc, key), objects)
        return out
    if isinstance(value, list | tuple) and not is_memory_object(value):
        return [_stand_ins(item, models, (*loc, i), objects) for i, item in enumerate(value)]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def run_in_memory(method: str, call: str, compute: Callable, cfg: RunConfig, inputs: Inputs, *,
                  progress: bool = False) -> Result:
    """Run ``compute(cfg, inputs, ctx)`` (a method pipeline's compute step) with a context that
    writes nothing; return its :class:`Result` with ``timings["total"]``. An error's line starts
    with ``call`` instead of a config file's name (the error object is kept, with what it carries,
    such as retarget's statistics of a mesh without repetition)."""
    from synthkit.context import RunContext

    ctx = RunContext(None, seed=cfg.seed, show_progress=progress, previews="none")
    ctx.label = method
    start = time.perf_counter()
    try:
        result = compute(cfg, inputs, ctx)
    except SynthkitError as exc:
        if not str(exc).startswith(call):
            exc.args = (f"{call}: {exc}", *exc.args[1:])  # the same error, with what it carries
        raise exc from None
    result.timings["total"] = time.perf_counter() - start
    return result
