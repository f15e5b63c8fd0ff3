"""YAML configs validated into strict pydantic schemas.

A config file is a YAML mapping with a ``method:`` key naming the subcommand and the method's
parameters. Every method schema derives from :class:`RunConfig`, itself a :class:`StrictModel`
(unknown keys are errors). File fields use :data:`InputFile`: relative paths resolve against
the config file's folder and the file must exist.

Errors come out as one :class:`~synthkit.errors.ConfigError` line that names the file, the
dotted key path and the value, with a "did you mean" for misspelt keys.
"""

from __future__ import annotations

import difflib
import os
import types
import typing
from pathlib import Path
from typing import Annotated, Any

import yaml
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, ValidationInfo

from synthkit.errors import ConfigError, InputError

__all__ = [
    "StrictModel",
    "RunConfig",
    "InputFile",
    "load_yaml",
    "apply_overrides",
    "validate_config",
]


class StrictModel(BaseModel):
    """A pydantic model that refuses unknown keys and non-finite floats (NaN, infinities, in fields
    and in lists of points alike), and re-validates on assignment."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True, allow_inf_nan=False)


class MissingInputFile(ValueError):
    """An :data:`InputFile` that does not exist (reported as an InputError, exit 3)."""


def _resolve_input_file(value: Path, info: ValidationInfo) -> Path:
    """Resolve ``value`` against the config's folder (``context['base_dir']``); it must exist. A name
    in ``context['memory_inputs']`` stands for an object given in memory (:mod:`synthkit.api`) and is
    kept as it is."""
    context = info.context or {}
    if str(value) in context.get("memory_inputs", ()):
        return Path(value)
    base_dir = context.get("base_dir")
    path = Path(value).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    named = Path(os.path.abspath(path))
    path = path.resolve()
    if context.get("check_files", True) and not path.is_file():
        raise MissingInputFile(f"file not found: {path}")
    inputs = context.get("inputs")
    if inputs is not None:
        inputs.append(path)
    input_fields = context.get("input_fields")
    if input_fields is not None:
        input_fields.append(info.field_name)
    named_inputs = context.get("named_inputs")
    if named_inputs is not None:
        named_inputs.append(named)
    return path


InputFile = Annotated[Path, AfterValidator(_resolve_input_file)]
"""A path to an existing input file, relative to the config file's folder."""


def _usd_installed(value: str) -> str:
    """``value``, a mesh format, refused when it is ``usd`` or ``usda`` and usd-core (the ``usd``
    extra) is not installed: the run stops at once, not after its synthesis."""
    if value in ("usd", "usda"):
        from synthkit.io.usd import USD_MISSING, usd_installed

        if not usd_installed():
            raise ValueError(USD_MISSING)
    return value


USD_NEEDS_EXTRA = AfterValidator(_usd_installed)
"""Annotate a ``mesh_format`` field with this (``Annotated[Literal[..., "usd", "usda"], USD_NEEDS_EXTRA]``)."""


class RunConfig(StrictModel):
    """Keys every method config has."""

    method: str = Field(description="Subcommand this config is for (e.g. 'retarget').")
    seed: int = Field(0, ge=0, le=2**32 - 1, description="Seed of every random choice; --seed overrides.")


YAML_NODE_BUDGET = 100_000
"""Most YAML nodes a config may hold, and expand to once aliases are followed (a real config has
hundreds; an alias bomb of 1 KB expands to billions)."""

CONFIG_MAX_BYTES = 1 << 20
"""Largest config or batch file read (1 MiB; real configs are a few KB). Checked before parsing, so
a 50 MB file is refused at once instead of after minutes of YAML parsing."""


class _DuplicateKey(yaml.constructor.ConstructorError):
    """A mapping that names one key twice (YAML would silently keep the last)."""


class _ConfigLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses duplicate keys in a mapping."""

    def construct_mapping(self, node, deep=False):
        seen: dict[Any, int] = {}
        for key_node, _value in node.value:
            key = self.construct_object(key_node, deep=True)
            if isinstance(key, typing.Hashable) and key in seen:
                raise _DuplicateKey(
                    None, None, f"duplicate key {key!r} (first at line {seen[key] + 1})", key_node.start_mark
                )
            if isinstance(key, typing.Hashable):
                seen[key] = key_node.start_mark.line
        return super().construct_mapping(node, deep=deep)


def _distinct_nodes(root: yaml.Node, budget: int) -> int:
    """Distinct nodes of the YAML graph under ``root`` (an alias counted once), stopping past ``budget``."""
    seen: set[int] = set()
    stack = [root]
    while stack and len(seen) <= budget:
        node = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, yaml.SequenceNode):
            stack.extend(node.value)
        elif isinstance(node, yaml.MappingNode):
            stack.extend(item for pair in node.value for item in pair)
    return len(seen)


def _expanded_size(root: yaml.Node, budget: int) -> int:
    """Nodes of the YAML graph under ``root`` counted as a tree (every alias expanded), stopping
    past ``budget``; a recursive alias counts as unbounded."""
    sizes: dict[int, int] = {}
    on_path: set[int] = set()

    def size(node: yaml.Node) -> int:
        key = id(node)
        if key in sizes:
            return sizes[key]
        if key in on_path:
            return budget + 1
        on_path.add(key)
        total = 1
        if isinstance(node, yaml.SequenceNode):
            children = node.value
        elif isinstance(node, yaml.MappingNode):
            children = [item for pair in node.value for item in pair]
        else:
            children = []
        for child in children:
            total += size(child)
            if total > budget:
                break
        on_path.discard(key)
        sizes[key] = total
        return total

    return size(root)


def _parse_yaml(text: str, path: Path) -> Any:
    """Compose ``text``, refuse an alias expansion past :data:`YAML_NODE_BUDGET`, then construct it."""
    loader = _ConfigLoader(text)
    try:
        root = loader.get_single_node()
        if root is None:
            return None
        if _distinct_nodes(root, YAML_NODE_BUDGET) > YAML_NODE_BUDGET:
            raise ConfigError(f"{path}: config holds more than {YAML_NODE_BUDGET} YAML values; "
                              "large data (strokes, labels) belongs in the files a config names")
        if _expanded_size(root, YAML_NODE_BUDGET) > YAML_NODE_BUDGET:
            raise ConfigError(
                f"{path}: YAML aliases expand past {YAML_NODE_BUDGET} nodes; refusing to expand them"
            )
        return loader.construct_document(root)
    finally:
        loader.dispose()


def load_yaml(path: Path) -> dict[str, Any]:
    """Read ``path`` as a YAML mapping; raise ConfigError for a missing, empty or malformed file, a
    duplicate key in a mapping, or aliases that expand past :data:`YAML_NODE_BUDGET` nodes."""
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"{path}: config is a folder, not a YAML file")
    if not path.is_file():
        raise ConfigError(f"{path}: config file not found")
    try:
        size = path.stat().st_size
        if size > CONFIG_MAX_BYTES:
            raise ConfigError(f"{path}: config file is {size / 2**20:.1f} MiB; the limit is "
                              f"{CONFIG_MAX_BYTES / 2**20:.0f} MiB (large data such as strokes or labels "
                              "belongs in the files a config names)")
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read config file: {exc}") from None
    try:
        data = _parse_yaml(text, path)
    except RecursionError:
        raise ConfigError(f"{path}: YAML nesting is too deep") from None
    except _DuplicateKey as exc:
        mark = exc.problem_mark
        raise ConfigError(f"{path}: line {mark.line + 1}: {exc.problem}") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ConfigError(f"{path}: YAML syntax error{where}: {problem}") from None
    if data is None:
        raise ConfigError(f"{path}: config file is empty (expected a mapping with a 'method:' key)")
    if not isinstance(data, dict):
        raise ConfigError(
            f"{path}: top level must be a mapping of keys to values, not a {type(data).__name__}"
        )
    return data


def apply_overrides(data: dict[str, Any], overrides: typing.Iterable[str]) -> dict[str, Any]:
    """Return a copy of ``data`` with ``key.path=value`` overrides applied (values parsed as YAML).

    Intermediate mappings are created as needed; validation of the result is left to the schema,
    so an override goes through the same checks as a key in the file.
    """
    result = _deep_copy(data)
    for item in overrides:
        key, sep, raw = item.partition("=")
        key = key.strip()
        if not sep or not key or any(not part for part in key.split(".")):
            raise ConfigError(f"--set {item!r}: expected key.path=value")
        try:
            value = yaml.safe_load(raw) if raw.strip() else ""
        except yaml.YAMLError:
            value = raw
        node = result
        parts = key.split(".")
        for part in parts[:-1]:
            child = node.get(part)
            if not isinstance(child, dict):
                child = {}
                node[part] = child
            node = child
        node[parts[-1]] = value
    return result


def _deep_copy(data: Any) -> Any:
    if isinstance(data, dict):
        return {k: _deep_copy(v) for k, v in data.items()}
    if isinstance(data, list):
        return [_deep_copy(v) for v in data]
    return data


def validate_config(
    model: type[RunConfig],
    data: dict[str, Any],
    *,
    source: Path | str,
    base_dir: Path | None = None,
    check_files: bool = True,
    inputs: list[Path] | None = None,
    named_inputs: list[Path] | None = None,
    input_fields: list[str] | None = None,
    memory_inputs: typing.Collection[str] = (),
) -> RunConfig:
    """Validate ``data`` into ``model``; raise one ConfigError line naming ``source`` and the key.

    Config problems come first: only when every problem is an input file that does not exist is
    the line an InputError (about the first such file). ``inputs``, when given, collects the
    resolved paths of every :data:`InputFile` field; ``named_inputs`` their absolute paths as the
    config names them (symbolic links not followed). ``memory_inputs`` are the names that stand for
    objects given in memory (kept as they are, never looked up).
    """
    context = {"base_dir": base_dir, "check_files": check_files, "inputs": inputs, "named_inputs": named_inputs,
               "input_fields": input_fields, "memory_inputs": frozenset(memory_inputs)}
    try:
        return model.model_validate(data, context=context)
    except ValidationError as exc:
        errors = exc.errors(include_url=False)
        missing = [isinstance(e.get("ctx", {}).get("error"), MissingInputFile) for e in errors]
        if all(missing):
            raise InputError(f"{source}: {_describe(errors[0], model)}") from None
        problems = [e for e, is_file in zip(errors, missing, strict=True) if not is_file]
        hints = [_misspelt_hint(e, errors) for e in problems]
        first = next((i for i, hint in enumerate(hints) if hint), 0)
        raise ConfigError(f"{source}: {_describe(problems[first], model)}{hints[first]}") from None


def _misspelt_hint(err: dict[str, Any], errors: list[dict[str, Any]]) -> str:
    """For a missing key, " (found unknown key 'inptu': did you mean 'input'?)" when an unknown key
    beside it is a close spelling; empty otherwise."""
    if err["type"] != "missing":
        return ""
    loc = tuple(err["loc"])
    strays = [tuple(e["loc"]) for e in errors if e["type"] == "extra_forbidden" and tuple(e["loc"])[:-1] == loc[:-1]]
    names = [str(stray[-1]) for stray in strays]
    close = difflib.get_close_matches(str(loc[-1]), names, n=1, cutoff=0.6)
    if not close:
        return ""
    return f" (found unknown key '{close[0]}': did you mean '{loc[-1]}'?)"


def _describe(err: dict[str, Any], model: type[BaseModel]) -> str:
    """One pydantic validation error (an item of ``ValidationError.errors()``) as
    'key.path: problem (got value)'."""
    loc = tuple(err["loc"])
    dotted = ".".join(str(p) for p in loc) or "(top level)"
    if err["type"] == "extra_forbidden":
        known = _field_names(model, loc[:-1])
        hint = difflib.get_close_matches(str(loc[-1]), known, n=1, cutoff=0.6)
        msg = f"unknown key '{dotted}'"
        if hint:
            parent = ".".join(str(p) for p in loc[:-1])
            msg += f" (did you mean '{parent + '.' if parent else ''}{hint[0]}'?)"
        elif known:
            msg += f" (known keys: {', '.join(sorted(known))})"
        return msg
    if err["type"] == "missing":
        return f"missing required key '{dotted}'"
    text = err["msg"]
    text = text.removeprefix("Value error, ")
    value = err.get("input")
    shown = "" if isinstance(value, dict) else f" (got {value!r})"
    return f"{dotted}: {text}{shown}"


def sub_models(annotation: Any) -> list[Any]:
    """Candidate model classes inside an annotation (Optional, Union, list, dict, Annotated)."""
    origin = typing.get_origin(annotation)
    if origin is Annotated:
        return sub_models(typing.get_args(annotation)[0])
    if origin in (typing.Union, types.UnionType, list, tuple, dict):
        found = []
        for arg in typing.get_args(annotation):
            found.extend(sub_models(arg))
        return found
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return []


def schema_has_key(model: type[BaseModel], dotted: str) -> bool:
    """Whether ``dotted`` (``key.path``, aliases allowed) names a key of ``model``'s schema: every
    part but the last a section (a sub-model, possibly optional or in a list), the last a field."""
    candidates: list[type[BaseModel]] = [model]
    parts = dotted.split(".")
    for i, part in enumerate(parts):
        fields = [f for cls in candidates for name, f in cls.model_fields.items() if part in (name, f.alias)]
        if not fields:
            return False
        if i == len(parts) - 1:
            return True
        candidates = [m for f in fields for m in sub_models(f.annotation)]
    return False


def _field_names(model: type[BaseModel], loc: tuple) -> list[str]:
    """Field names (and aliases) of the sub-model reached by ``loc`` from ``model``."""
    candidates: list[type[BaseModel]] = [model]
    for part in loc:
        if not isinstance(part, str):
            continue
        nxt: list[type[BaseModel]] = []
        for cls in candidates:
            field = cls.model_fields.get(part)
            if field is not None:
                nxt.extend(sub_models(field.annotation))
        if not nxt:
            # a discriminated-union tag or list index: keep the current candidates
            continue
        candidates = nxt
    names: list[str] = []
    for cls in candidates:
        for name, field in cls.model_fields.items():
            names.append(field.alias or name)
    return names
