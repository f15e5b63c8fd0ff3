"""A commented YAML config holding every key of a method's schema (``synthkit init``).

Each key is written with its default and a comment giving its description and its range or
choices. Sub-sections are nested mappings (their comment is the section's description, or its
class docstring). An optional section that is off by default (``null``) is followed by its keys
commented out, ready to uncomment; a list of sections (such as painted views or pairs) that is
empty by default is followed by one commented example item with every key.

Keys without a default, and keys a method needs one of (such as petri-synth's ``lattice.unit``
or ``construction.points``), take the method's ``init_values`` (dotted key -> value, from its
spec) marked ``example value``; input files left to the user (required ones, and the
spec's ``init_required``) are ``null`` marked ``REQUIRED``.
"""

from __future__ import annotations

import json
import math
import types
import typing
from typing import Any

import annotated_types
from pydantic import BaseModel
from pydantic.fields import FieldInfo

INDENT = "  "
_REQUIRED = object()
"""Marks a key of ``required`` among the values."""


def config_template(
    model: type[BaseModel], *, method: str, values: dict[str, Any] | None = None, required: tuple[str, ...] = ()
) -> str:
    """The commented YAML text of ``model`` (a RunConfig subclass) for subcommand ``method``.

    ``values`` (dotted key -> value) are written as example values; ``required`` names optional
    keys a usable config must give all the same (such as one of two alternatives), marked REQUIRED.
    """
    values = dict(values or {})
    values.update({key: _REQUIRED for key in required})
    lines = [f"# synthkit {method} config: every key with its default (synthkit init {method}).",
             "# Relative paths resolve against this file's folder.", ""]
    lines += _model_lines(model, values, prefix="", depth=0, method=method)
    return "\n".join(lines) + "\n"


def _model_lines(model: type[BaseModel], values: dict, *, prefix: str, depth: int, method: str,
                 defaults: dict | None = None) -> list[str]:
    """The lines of ``model``'s keys; ``defaults`` are the values of the section's own default (a
    section whose default is not its keys' defaults, such as retarget's ``target``), by key."""
    lines: list[str] = []
    for name, field in model.model_fields.items():
        key = field.alias or name
        dotted = prefix + key
        pad = INDENT * depth
        if dotted == "method":
            lines.append(f"{pad}method: {method}")
            continue
        sub = _sub_model(field.annotation)
        item = _list_item_model(field.annotation)
        if item is not None and field.is_required() and dotted not in values:
            lines.append(f"{pad}{key}:  # REQUIRED: {_comment(field)}; a list of items like this one:")
            body = _model_lines(item, values, prefix=dotted + ".", depth=depth + 1, method=method)
            lines += [f"{pad}  - {body[0].strip()}"]
            lines += [f"{pad}    {line[len(pad) + len(INDENT):]}" for line in body[1:]]
        elif values.get(dotted) is _REQUIRED:
            lines.append(f"{pad}{key}: null  # REQUIRED: {_comment(field)}")
        elif dotted in values:
            lines.append(f"{pad}{key}: {_flow(values[dotted])}  # example value; {_comment(field)}")
        elif sub is not None and (field.is_required() or field.default_factory is not None
                                  or any(k.startswith(dotted + ".") for k in values)):
            own = field.get_default(call_default_factory=True) if field.default_factory is not None else None
            lines.append(f"{pad}{key}:  # {_comment(field, sub)}")
            lines += _model_lines(sub, values, prefix=dotted + ".", depth=depth + 1, method=method,
                                  defaults=own.model_dump(mode="json") if isinstance(own, BaseModel) else None)
        elif sub is not None:
            lines.append(f"{pad}{key}: null  # {_comment(field, sub)}; null: off. Its keys, to uncomment:")
            lines.append(f"{pad}# {key}:")
            body = _model_lines(sub, values, prefix=dotted + ".", depth=depth + 1, method=method)
            lines += [f"{pad}# {line[len(pad):]}" for line in body]
        elif item is not None and not field.is_required() and field.get_default(call_default_factory=True) == []:
            lines.append(f"{pad}{key}: []  # {_comment(field)}; an item, to uncomment:")
            body = _model_lines(item, values, prefix=dotted + ".", depth=depth + 1, method=method)
            lines += [f"{pad}#   - {body[0].strip()}"] + [f"{pad}#     {line[len(pad) + len(INDENT):]}"
                                                      for line in body[1:]]
        elif field.is_required():
            lines.append(f"{pad}{key}: null  # REQUIRED: {_comment(field)}")
        else:
            default = defaults[name] if defaults and name in defaults else field.get_default(call_default_factory=True)
            if isinstance(default, BaseModel):
                default = default.model_dump(mode="json")
            lines.append(f"{pad}{key}: {_flow(default)}  # {_comment(field)}")
    return lines


def _list_item_model(annotation: Any) -> type[BaseModel] | None:
    """The StrictModel class of a field that is a list of sections (``list[Model]``)."""
    if typing.get_origin(annotation) is list:
        args = typing.get_args(annotation)
        if len(args) == 1:
            return _sub_model(args[0])
    return None


def _sub_model(annotation: Any) -> type[BaseModel] | None:
    """The StrictModel class of a field that is a section (``Model`` or ``Model | None``)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        models = [a for a in typing.get_args(annotation) if isinstance(a, type) and issubclass(a, BaseModel)]
        return models[0] if len(models) == 1 else None
    return None


def _flow(value: Any) -> str:
    """``value`` as one line of YAML flow style (JSON, which is valid YAML, but for floats written
    with a point before their exponent: YAML 1.1 readers, PyYAML's among them, read ``1e-06`` as a
    string and ``1.0e-06`` as a number)."""
    if hasattr(value, "__fspath__"):
        value = str(value)
    if isinstance(value, float) and math.isfinite(value):
        mantissa, e, exponent = repr(value).partition("e")
        return f"{mantissa}.0e{exponent}" if e and "." not in mantissa else repr(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_flow(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))}: {_flow(v)}" for k, v in value.items()) + "}"
    return json.dumps(value, default=str)


def _comment(field: FieldInfo, section: type[BaseModel] | None = None) -> str:
    """Description (a section without one: its class docstring's first line), then range and
    choices, on one line."""
    text = field.description
    if not text and section is not None:
        text = ((section.__doc__ or "").strip().splitlines() or [""])[0]
    parts = [(text or "").replace("\n", " ").rstrip(".")]
    bounds = []
    for meta in field.metadata:
        for attr, sign in (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<")):
            if isinstance(meta, getattr(annotated_types, attr.capitalize())):
                bounds.append(f"{sign} {getattr(meta, attr)}")
    if bounds:
        parts.append("range " + ", ".join(bounds))
    choices = _choices(field.annotation)
    if choices:
        parts.append("one of " + ", ".join(map(str, choices)))
    return "; ".join(p for p in parts if p)


def _choices(annotation: Any) -> list[Any]:
    if typing.get_origin(annotation) is typing.Literal:
        return list(typing.get_args(annotation))
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        found = []
        for arg in typing.get_args(annotation):
            found += _choices(arg)
        return found
    return []


__all__ = ["config_template"]
